"""A natively batched ``gymnasium.vector.VectorEnv`` over N worlds of one stairenv env.

``gym.make_vec("InterLevel-v0", num_envs=64, vectorization_mode="vector_entry_point")`` builds one
(``registration`` registers a ``vector_entry_point`` for every id). The vector env holds N template envs
(``HumanoidEnv`` instances, one per world: each keeps its own ``MjModel``, which InterLevel writes its
staircase into, and ``MjData``) and runs the phases of ``HumanoidEnv.step`` over the batch:

1. every world's action checked first (shape, a non-real dtype, NaN/inf: ``ValueError`` naming the worlds),
   nothing applied if one is bad;
2. ``HumanoidEnv._prepare_worlds``: the action map of all worlds in one array operation (each world's row
   then copied into its ctrl), per world ``_before_physics``;
3. the physics of all worlds in one ``BatchPhysics.step`` call (``batch_physics``: a pool of
   ``os.cpu_count()`` threads taking the worlds one at a time and calling ``mujoco.mj_step``, GIL
   released). Meanwhile, in the calling thread: the worlds whose episode ended at the last step are
   reset together (``NEXT_STEP``; ``reset_worlds``), then each group of worlds whose physics is done is
   finished while the pool steps the rest (``collect``): the divergence and speed check,
   ``_step_outcome``, the style features, ``info``, the episode limit, and with ``SAME_STEP`` the reset of
   the group's worlds whose episode just ended, together.
   For InterLevel, PlaMo and SIMS (``BATCH_OUTCOMES``) a group is finished batch-first, ``HumanoidEnv._finish_batch``:
   the divergence and speed check over the batch (``_sound_worlds``: the times, MuJoCo's warnings and the
   speeds as arrays; each world's body poses were brought up to its ``qpos`` by ``mj_kinematics`` in the
   physics thread right after its physics, ``_bring_up_poses``), the stable worlds' state
   read as one batch (``_read_worlds``: each world's state views, made once per ``MjData``, stacked),
   the task in one call (``InterLevelEnv._step_outcome_batch``: compiled calls over arrays in and out, what
   each world carries from step to step held as rows of arrays over the batch, ``HumanoidEnv._share_rows``,
   and its ``info`` as columns, ``infos.WorldInfos``, with no dict per world;
   ``PlaMoEnv._step_outcomes``: arrays over the batch, then each world's own terrain and path;
   ``SIMSEnv._step_outcomes``: arrays over the batch, then each world's own scene heights and goal; the
   single env calls them with one world) and the style features in one; the other envs run ``_finish_step``
   per world in the physics thread right after its physics. Either way the code of the single env's
   ``step``, so a world's trajectory is bit-identical to a single env's with the same seed.

Resets: ``HumanoidEnv._reset_worlds`` over the worlds reset together; each world draws from its own
generator in the order of its own ``reset`` (so a world is the same reset alone or with others), and what
needs no draw goes over them (InterLevel: the staircases' geometry and goals as one ``StairsLayout``, the
first step outcomes in one call).

Per-world parts (Python, one world at a time): the copy of each world's PD targets into its ctrl,
``_before_physics``, a reset's draws, ``mj_resetData`` and start pose, the reads of each world's
``MjData`` (its time, warnings, speeds and state views); for PlaMoScene (its worlds' models differ) the
whole finish; for InterLevel ``mj_kinematics`` (in the physics threads) and a few attribute reads (step
count, start flags); for PlaMo also its heightmap and path targets (compiled, on the world's own height
field and path) and reward terms; for SIMS also its goal targets and heightmap (compiled, on the world's
own goal and scene heights), the reward's scalars and the ends. Batched: the action checks, the action
map, the physics, the divergence and speed check (InterLevel, PlaMo, SIMS), their step outcomes, the
assembly of obs / reward / flags / info.

Autoreset follows Gymnasium 1.x: by default ``AutoresetMode.NEXT_STEP`` (the step after a world's
episode ends resets that world and returns its reset observation with reward 0, terminated and
truncated False; its action is ignored); ``autoreset_mode=AutoresetMode.SAME_STEP`` resets it within
the step that ends it (the reset observation returned, the ended step's in ``info["final_obs"]``, its
info in ``info["final_info"]``, as ``SyncVectorEnv`` gives; the SB3 adapter uses this). The episode
limit (``max_episode_steps``, the registration's TimeLimit) truncates in the vector env. A world whose
physics blows up is truncated alone, with ``info["physics_unstable"]`` set for it. ``info`` is a dict
of arrays with ``_key`` masks, as ``SyncVectorEnv`` gives (``step_worlds`` gives the per-world dicts, as a
``WorldInfos`` that makes a world's dict only when it is read). ``reset(seed=s)`` seeds world i with
``s + i`` (as ``SyncVectorEnv``).
"""

from __future__ import annotations

import functools
import inspect
import warnings
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space

from stairenv.environments.base import NUMERIC_KINDS, BatchStep, HumanoidEnv
from stairenv.environments.batch_physics import BatchPhysics, check_physics_device, check_state_on_device, make_physics
from stairenv.environments.infos import WorldInfos, stack_infos


class HumanoidVectorEnv(gym.vector.VectorEnv):
    """N worlds of ``env_class(**kwargs)`` stepped as one batch (see the module docstring).

    ``physics``: "mujoco" (default: MuJoCo's C library on a pool of threads; "threads" is the same),
    "serial" (one core), "warp" (MuJoCo Warp on a GPU: ``warp_physics``; InterLevel ids only, others
    refused with a ``ValueError`` saying why) or a ``BatchPhysics``; ``physics_threads``: the pool's
    threads (default ``os.cpu_count()``; ``nthread`` is its older name); ``max_episode_steps``: the
    truncation limit (None: none); ``physics_device``: where "warp" runs ("cuda:1", "cpu"; default Warp's
    first GPU; a data-parallel rank of the trainer passes its own); ``state_on_device``: with "warp", the
    device's state is the truth between resets (opt-in: each world's ``MjData`` then lags until
    ``physics.sync_worlds()``, and a write into one must follow ``physics.sync_worlds([i])`` and be announced
    with ``physics.world_changed(i)``;
    ``warp_physics.WarpPhysics``);
    ``batch_outcomes``: the task's step outcomes over the batch in one call (default: where the env class can;
    ``batch_evaluation`` is its older name, deprecated).
    """

    env_class: type[HumanoidEnv] | None = None

    def __init__(self, num_envs: int = 1, *, env_class: type[HumanoidEnv] | None = None,
                 max_episode_steps: int | None = None, physics: str | BatchPhysics = "mujoco",
                 physics_threads: int | None = None, nthread: int | None = None, physics_device: str | None = None,
                 state_on_device: bool = False,
                 batch_outcomes: bool | None = None, batch_evaluation: bool | None = None,
                 autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP,
                 **kwargs: Any) -> None:
        env_class = env_class or self.env_class
        if env_class is None:
            raise TypeError("HumanoidVectorEnv needs env_class (or a subclass that sets it)")
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs must be a positive integer, got {num_envs!r}")
        try:
            self.autoreset_mode = AutoresetMode(autoreset_mode)
        except ValueError:
            self.autoreset_mode = None
        if self.autoreset_mode not in (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP):
            raise ValueError(f"autoreset_mode must be AutoresetMode.NEXT_STEP or SAME_STEP, got {autoreset_mode!r}")
        if max_episode_steps is not None and (isinstance(max_episode_steps, bool) or max_episode_steps < 1):
            raise ValueError(f"max_episode_steps must be None or a positive integer, got {max_episode_steps!r}")
        if nthread is not None and physics_threads is not None and nthread != physics_threads:
            raise ValueError(f"physics_threads={physics_threads!r} and its older name nthread={nthread!r} differ")
        physics_threads = nthread if physics_threads is None else physics_threads
        if batch_evaluation is not None:
            warnings.warn("batch_evaluation is deprecated (it names the per-step outcome, not the papers' "
                          "evaluation): use batch_outcomes", DeprecationWarning, stacklevel=2)
            if batch_outcomes is not None and batch_outcomes != batch_evaluation:
                raise ValueError(f"batch_outcomes={batch_outcomes!r} and its older name "
                                 f"batch_evaluation={batch_evaluation!r} differ")
            batch_outcomes = batch_evaluation if batch_outcomes is None else batch_outcomes
        device = physics == "warp" or hasattr(physics, "bind")
        # refused before any world is built: a device for a host back-end, an id the device cannot hold
        check_physics_device(physics, physics_device)
        check_state_on_device(physics, state_on_device)
        if device:
            from stairenv.environments.warp_physics import check_supported
            check_supported(env_class)
        self.num_envs = int(num_envs)
        if device:    # thousands of worlds: copies of the first (~10x faster than building each), all unseeded
            first = env_class(**kwargs)
            # a reset computes the poses only: the host reads no more, the device computes the rest
            first._reset_forward = mujoco.mj_kinematics
            self.envs: list[HumanoidEnv] = [first, *(first.replicate() for _ in range(self.num_envs - 1))]
        else:
            self.envs = [env_class(**kwargs) for _ in range(self.num_envs)]
        first = self.envs[0]
        self.max_episode_steps = max_episode_steps
        self.single_observation_space = first.observation_space
        self.single_action_space = first.action_space
        self.observation_space = batch_space(first.observation_space, self.num_envs)
        self.action_space = batch_space(first.action_space, self.num_envs)
        self.metadata = {**first.metadata, "autoreset_mode": self.autoreset_mode}
        self.render_mode = first.render_mode
        self.physics = make_physics(physics, physics_threads, physics_device, state_on_device)
        if hasattr(self.physics, "bind"):    # a device back-end: every world's model and data, once
            #: the worlds as the device back-end holds them (one structure, never recompiled): what a step of
            #: every world hands it
            self._bound_worlds = [(env.model, env.data) for env in self.envs]
            self.physics.bind(self._bound_worlds)
        #: tells a device back-end that a world was reset on the host (its new staircase is copied up)
        self._world_reset = getattr(self.physics, "world_reset", None)
        #: a device back-end that keeps the state (``WarpPhysics(state_on_device=True)``): the step hands it the
        #: ctrl as one array and finishes from its arrays; the worlds' ``MjData`` lag until ``sync_worlds``
        self._state_on_device = bool(getattr(self.physics, "state_on_device", False))
        #: the task's step outcomes over the batch (``HumanoidEnv._finish_batch``) where the env class can
        #: (``BATCH_OUTCOMES``: InterLevel, PlaMo, SIMS), else world by world
        self.batch_outcomes = bool(env_class.BATCH_OUTCOMES) if batch_outcomes is None else batch_outcomes
        #: the worlds' carry shared as rows of arrays over the batch, where the class computes its outcomes as
        #: arrays (``HumanoidEnv._share_rows``): a group's carry is then read and written by its rows
        self._shared_rows = self.batch_outcomes and env_class._step_outcome_batch is not None
        if self._shared_rows:
            env_class._share_rows(self.envs)
        if self._state_on_device and not self._shared_rows:
            raise ValueError(f"a back-end with the state on the device needs a task that finishes over arrays "
                             f"(InterLevel ids, batch_outcomes=True); {env_class.__name__} does not")
        self._elapsed = np.zeros(self.num_envs, dtype=np.int64)
        self._autoreset = np.zeros(self.num_envs, dtype=bool)
        self._was_reset = False
        self._results: list[tuple | None] = [None] * self.num_envs
        self._last_obs = self._obs_buffer()

    # --- gymnasium.vector API -------------------------------------------------
    def reset(self, *, seed: int | Sequence[int | None] | None = None, options: dict[str, Any] | None = None):
        self.check_open()
        seeds = self._seeds(seed)
        options = dict(options) if options else {}
        mask = options.pop("reset_mask", None)
        if mask is not None:
            mask = np.asarray(mask)
            if mask.dtype != np.bool_ or mask.shape != (self.num_envs,):
                raise ValueError(f"reset_mask must be {self.num_envs} bools, one per world; got {mask.dtype} "
                                 f"of shape {mask.shape}")
        worlds = range(self.num_envs) if mask is None else np.flatnonzero(mask)
        if mask is not None and not self._was_reset:
            raise gym.error.ResetNeeded("reset() with a reset_mask needs a full reset() first")
        obs = self._obs_buffer() if mask is None else self._last_obs.copy()
        infos: list[dict[str, Any]] = [{}] * self.num_envs
        self._last_obs = obs
        worlds = list(worlds)
        obs[worlds], reset_infos = self.reset_worlds(worlds, [seeds[i] for i in worlds],
                                                     [options or None] * len(worlds))
        for i, info in zip(worlds, reset_infos):
            infos[i] = info
        self._was_reset = True
        return obs.copy(), self.batch_infos(infos)

    def reset_each(self, seeds: Sequence[int | None], options: Sequence[dict[str, Any] | None]):
        """A full reset with a seed and options per world (SB3's ``VecEnv`` convention); returns the
        observations and the list of per-world infos."""
        self.check_open()
        obs, infos = self.reset_worlds(range(self.num_envs), seeds, [each or None for each in options])
        self._was_reset = True
        return obs, infos

    def reset_world(self, i: int, seed: int | None = None, options: dict[str, Any] | None = None):
        """Reset world ``i`` alone (its episode count and autoreset flag too); its ``(obs, info)``."""
        obs, infos = self.reset_worlds([i], [seed], [options])
        return obs[0], infos[0]

    def reset_worlds(self, worlds: Sequence[int], seeds: Sequence[int | None] | None = None,
                     options: Sequence[dict[str, Any] | None] | None = None) -> tuple[np.ndarray, list[dict[str, Any]]]:
        """Reset ``worlds`` together (each as ``reset_world`` would: the same draws, the same result), what
        needs no draw done over them at once; their observations (row k: ``worlds[k]``) and infos."""
        self.check_open()
        worlds = [int(i) for i in worlds]
        if any(not 0 <= i < self.num_envs for i in worlds) or len(set(worlds)) != len(worlds):
            raise ValueError(f"reset_worlds needs distinct world indices in [0, {self.num_envs - 1}], got {worlds}")
        seeds = [None] * len(worlds) if seeds is None else list(seeds)
        options = [None] * len(worlds) if options is None else list(options)
        if len(seeds) != len(worlds) or len(options) != len(worlds):
            raise ValueError(f"reset_worlds needs one seed and one options per world ({len(worlds)}), got "
                             f"{len(seeds)} seeds and {len(options)} options")
        results = type(self.envs[0])._reset_worlds([self.envs[i] for i in worlds], seeds, options)
        obs = np.array([result[0] for result in results], dtype=self.single_observation_space.dtype)
        obs = obs.reshape(len(worlds), *self.single_observation_space.shape)
        if self._world_reset is not None:
            self._world_reset(worlds)    # (the reset's own terrain writes included: nothing left to announce)
            for i in worlds:
                self.envs[i]._model_written = False
        self._elapsed[worlds] = 0
        self._autoreset[worlds] = False
        self._last_obs[worlds] = obs
        return obs, [result[1] for result in results]

    def step(self, actions):
        self.check_open()
        same_step = self.autoreset_mode == AutoresetMode.SAME_STEP
        obs, rewards, terminated, truncated, infos, finals = self.step_worlds(actions, reset_ended=same_step)
        for i, (final_obs, reset_info) in finals.items():    # SyncVectorEnv's SAME_STEP layout
            infos[i] = {"final_obs": final_obs, "final_info": infos[i], **reset_info}
        return obs, rewards, terminated, truncated, self.batch_infos(infos)

    # --- the batch step ----------------------------------------------------------
    def step_worlds(self, actions, reset_ended: bool = False):
        """``step`` with ``info`` as the per-world dicts (a ``WorldInfos``: a sequence of dicts, each made when
        first read; ``infos.column(infos, key)`` reads one key of every world as an array), and a sixth
        result ``finals``.

        ``reset_ended=False`` (``NEXT_STEP``): a world whose episode ended at the last step is reset now
        (its action ignored, reward 0, flags False), while the other worlds' physics runs; ``finals`` is
        empty. ``reset_ended=True`` (``SAME_STEP``, SB3's convention): a world whose episode ends in this
        step is reset within it, as soon as its own step is finished (the other worlds' physics still
        running); its row of ``obs`` is then the reset observation, ``infos[i]`` the ended step's info and
        ``finals[i] = (the ended step's observation, the reset's info)``."""
        if not self._was_reset:
            raise gym.error.ResetNeeded("call reset() before step()")
        actions = self.check_actions(actions)
        n = self.num_envs
        obs = self._obs_buffer()
        rewards = np.zeros(n, dtype=np.float64)
        terminated = np.zeros(n, dtype=bool)
        truncated = np.zeros(n, dtype=bool)
        infos = WorldInfos(n)
        finals: dict[int, tuple[np.ndarray, dict[str, Any]]] = {}
        self._last_obs = obs
        resetting = np.flatnonzero(self._autoreset)
        stepping = np.flatnonzero(~self._autoreset).tolist()
        envs = self.envs
        everyone = len(stepping) == n    # the usual step (SAME_STEP always): no per-world lists to make
        stepping_envs = envs if everyone else [envs[i] for i in stepping]
        on_device = self._state_on_device
        stepping_rows = np.array(stepping, dtype=np.int64)
        rows = stepping_rows if self._shared_rows else None
        if on_device:    # the PD targets go to the device as one array
            ctrl = type(envs[0])._action_targets(stepping_envs, actions[stepping], rows) if stepping else None
        else:
            type(envs[0])._prepare_worlds(stepping_envs, actions[stepping], rows)
            if self._world_reset is not None:    # a device back-end: the worlds whose model a step wrote
                written = [i for i, env in zip(stepping, stepping_envs) if env._model_written]
                if written:
                    for i in written:
                        envs[i]._model_written = False
                    self.physics.world_changed(written)

        def reset_ended_before() -> None:    # NEXT_STEP: this step resets the world, its action is ignored
            if len(resetting):
                obs[resetting], reset_infos = self.reset_worlds(resetting)
                for i, info in zip(resetting.tolist(), reset_infos):
                    infos[i] = info

        results = self._results
        limit = self.max_episode_steps

        def collect(ks: list[int]) -> None:    # in the calling thread, while other worlds' physics runs
            if not ks:
                return
            whole = len(ks) == len(stepping) and ks == list(range(len(stepping)))
            group = stepping_rows if whole else stepping_rows[ks]
            if self.batch_outcomes:    # the task over this group of worlds in one call
                state = None if not on_device else self.physics.state if whole else {
                    key: value[ks] for key, value in self.physics.state.items()}
                group_envs = stepping_envs if whole else [envs[i] for i in group.tolist()]
                finished = type(envs[0])._finish_batch(group_envs, poses_current=True,
                                                       rows=group if self._shared_rows else None,
                                                       device_state=state)
            else:
                finished = BatchStep.of_worlds([results[k] for k in ks])
                for k in ks:
                    results[k] = None
            # the group's results as array assignments (its info as columns where the task gives them); then
            # the ended worlds' resets
            obs[group], rewards[group] = finished.obs, finished.reward
            terminated[group], truncated[group] = finished.terminated, finished.truncated
            if finished.columns:
                infos.put(group if finished.column_rows is None else group[finished.column_rows], finished.columns)
            for k, info in finished.dicts.items():
                infos[group[k]] = info
            self._elapsed[group] += 1
            if limit is not None:
                truncated[group] |= self._elapsed[group] >= limit
            ended = group[terminated[group] | truncated[group]]
            if not reset_ended:
                self._autoreset[ended] = True
            elif len(ended):    # reset together (a reset touches only its own world's rows)
                final_obs = obs[ended]
                obs[ended], reset_infos = self.reset_worlds(ended)
                for k, i in enumerate(ended.tolist()):
                    finals[i] = (final_obs[k], reset_infos[k])

        if on_device and everyone:
            worlds = self._bound_worlds
        else:    # a world's model and data as they are now (SIMS compiles a new model at a reset)
            worlds = [(envs[i].model, envs[i].data) for i in stepping]

        def finish(k: int) -> None:    # per world, in the physics thread, right after its physics
            results[k] = envs[stepping[k]]._finish_step()

        def bring_up_poses(k: int) -> None:    # also in the physics thread: collect then finds them current
            envs[0]._bring_up_poses(*worlds[k])

        if on_device:
            self.physics.step(worlds, envs[0].frame_skip, None, reset_ended_before, collect, ctrl=ctrl)
        else:
            self.physics.step(worlds, envs[0].frame_skip, bring_up_poses if self.batch_outcomes else finish,
                              reset_ended_before, collect)
        return obs.copy(), rewards, terminated, truncated, infos, finals

    def check_actions(self, actions) -> np.ndarray:
        """``actions`` as float64 (N, A); ``ValueError`` for a wrong shape, a non-numeric dtype (complex,
        strings, objects: refused before any conversion) or NaN/inf, naming the worlds."""
        actions = np.asarray(actions)
        if actions.dtype.kind not in NUMERIC_KINDS:
            raise ValueError(f"actions must be real numbers, got dtype {actions.dtype}{_non_real_worlds(actions)}; "
                             "no world was stepped")
        actions = actions.astype(np.float64, copy=False)
        expected = (self.num_envs, *self.single_action_space.shape)
        if actions.shape != expected:
            raise ValueError(f"actions must have shape {expected} (num_envs, action size), got {actions.shape}")
        finite = np.isfinite(actions).reshape(self.num_envs, -1).all(axis=1)
        if not finite.all():
            bad = np.flatnonzero(~finite)
            where = {int(i): np.flatnonzero(~np.isfinite(actions[i])).tolist() for i in bad[:8]}
            raise ValueError(f"actions must be finite: NaN or inf in world(s) {bad.tolist()} "
                             f"(world: action indices {where}); no world was stepped")
        return actions

    def batch_infos(self, infos: Sequence[dict[str, Any]]) -> dict[str, Any]:
        """Per-world info dicts as one dict of arrays with ``_key`` masks (``SyncVectorEnv``'s layout): a
        step's ``WorldInfos`` from its columns, a list dict by dict."""
        return infos.stacked() if isinstance(infos, WorldInfos) else stack_infos(infos)

    # --- helpers -------------------------------------------------------------------
    def _obs_buffer(self) -> np.ndarray:
        space = self.single_observation_space
        return np.zeros((self.num_envs, *space.shape), dtype=space.dtype)

    def check_open(self) -> None:
        """``gymnasium.error.ClosedEnvironmentError`` once ``close()`` has run: its worlds are gone."""
        if self.closed:
            raise gym.error.ClosedEnvironmentError(f"{type(self).__name__} is closed; make a new one")

    def _seeds(self, seed) -> list[int | None]:
        if seed is None:
            return [None] * self.num_envs
        if isinstance(seed, np.ndarray) and seed.ndim == 0:
            seed = seed.item()
        if isinstance(seed, (int, np.integer)) and not isinstance(seed, (bool, np.bool_)):
            return [_seed(seed, "seed") + i for i in range(self.num_envs)]
        if isinstance(seed, (str, bytes, dict)) or not hasattr(seed, "__iter__"):
            raise TypeError(f"seed must be None, an integer or one seed per world ({self.num_envs}), got {seed!r:.80}")
        seeds = list(np.asarray(seed).tolist() if isinstance(seed, np.ndarray) else seed)
        if len(seeds) != self.num_envs:
            raise ValueError(f"reset needs one seed per world ({self.num_envs}), got {len(seeds)}")
        return [None if s is None else _seed(s, f"seed[{i}]") for i, s in enumerate(seeds)]

    @property
    def amp_observation_space(self) -> gym.spaces.Box:
        """One world's ``info["amp_obs"]`` space (Isaac Lab's AMP convention; see ``HumanoidEnv``)."""
        return self.envs[0].amp_observation_space

    def collect_reference_motions(self, num_samples: int, rng: np.random.Generator | None = None) -> np.ndarray:
        """Reference windows shaped as one world's ``info["amp_obs"]`` (``HumanoidEnv.collect_reference_motions``)."""
        return self.envs[0].collect_reference_motions(num_samples, rng)

    def get_attr(self, name: str) -> tuple:
        return tuple(getattr(env, name) for env in self.envs)

    def set_attr(self, name: str, values) -> None:
        if not isinstance(values, (list, tuple)):
            values = [values] * self.num_envs
        if len(values) != self.num_envs:
            raise ValueError(f"set_attr needs one value per world ({self.num_envs}), got {len(values)}")
        self.set_world_attrs(name, dict(enumerate(values)))

    def set_world_attrs(self, name: str, values: dict[int, Any]) -> None:
        """``setattr(world i, name, values[i])`` for each world i given (``set_attr`` for all; SB3's ``indices``
        for some). The worlds share one configuration, since the task runs over them as one batch: a keyword
        of the env class (``termination_height``, ``stall_seconds``...) must end with one value in every
        world, else a ``ValueError`` naming it (a value per world, such as ``curriculum_level``, is free)."""
        env_class = type(self.envs[0])
        if name in _keywords(env_class):
            after = [values[i] if i in values else getattr(env, name, _UNSET) for i, env in enumerate(self.envs)]
            for i, value in enumerate(after):
                if not _equal(value, after[0]):
                    raise ValueError(
                        f"set_attr({name!r}): {name!r} is a keyword of {env_class.__name__}, and a batched env's "
                        f"worlds share one configuration (the task runs over them as one batch), so it takes one "
                        f"value for every world; world 0 would have {after[0]!r}, world {i} {value!r}. Give one "
                        f"value, or build separate envs for separate settings")
        for i, value in values.items():
            setattr(self.envs[i], name, value)

    def call(self, name: str, *args, **kwargs) -> tuple:
        results = []
        for env in self.envs:
            attr = getattr(env, name)
            results.append(attr(*args, **kwargs) if callable(attr) else attr)
        return tuple(results)

    def __getstate__(self):
        # a copy would share the worlds' rows of arrays (the batch's carry) and the physics back-end (threads,
        # a device) with this env, or lose them: refused with the way out rather than made half-working
        raise TypeError(f"a batched env ({type(self).__name__}) cannot be copied or pickled: its worlds share "
                        f"arrays and a physics back-end; build another with gym.make_vec(...) (a single world, "
                        f"venv.envs[i], can be copied)")

    def close_extras(self, **kwargs) -> None:
        self.physics.close()
        for env in self.envs:
            env.close()


_UNSET = object()    # a world without the attribute: unequal to any value


@functools.cache
def _keywords(env_class: type[HumanoidEnv]) -> frozenset[str]:
    """The keywords ``env_class`` is built with: its configuration, which a batched env's worlds share."""
    return frozenset(name for name, parameter in inspect.signature(env_class.__init__).parameters.items()
                     if name != "self" and parameter.kind is not inspect.Parameter.VAR_KEYWORD)


def _equal(a, b) -> bool:
    try:
        return bool(np.array_equal(a, b))
    except Exception:    # values numpy cannot compare as arrays
        return a is b or a == b


def _non_real_worlds(actions: np.ndarray) -> str:
    """Which worlds' rows hold something other than a real number (a complex number with an imaginary
    part, a string, an object that is not a real number), as a phrase for ``check_actions``' error
    (every world when each is only of a non-real dtype, e.g. complex with no imaginary parts)."""
    if actions.ndim != 2:
        return ""

    def real(value) -> bool:
        return isinstance(value, (bool, int, float, np.bool_, np.integer, np.floating)) or (
            isinstance(value, (complex, np.complexfloating)) and value.imag == 0)

    bad = [i for i, row in enumerate(actions.tolist()) if not all(real(value) for value in row)]
    return f" in world(s) {bad}" if bad else " in every world"


def _seed(value, name: str) -> int:
    """A seed as a non-negative Python int (numpy integers too); errors name the world's seed."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name} must be None or an integer, got {value!r:.80}")
    if value < 0:
        raise ValueError(f"{name} must be >= 0, got {value}")
    return int(value)


def _vector_class(env_class: type[HumanoidEnv]) -> type[HumanoidVectorEnv]:
    name = env_class.__name__.removesuffix("Env") + "VectorEnv"
    return type(name, (HumanoidVectorEnv,), {"env_class": env_class, "__module__": __name__,
                                             "__doc__": f"``HumanoidVectorEnv`` of ``{env_class.__name__}``."})


def _classes():
    from stairenv.environments.interlevel import InterLevelEnv
    from stairenv.environments.plamo import PlaMoEnv
    from stairenv.environments.plamo_scene import PlaMoSceneEnv
    from stairenv.environments.sims import SIMSEnv
    return [_vector_class(c) for c in (InterLevelEnv, PlaMoEnv, PlaMoSceneEnv, SIMSEnv)]


InterLevelVectorEnv, PlaMoVectorEnv, PlaMoSceneVectorEnv, SIMSVectorEnv = _classes()
