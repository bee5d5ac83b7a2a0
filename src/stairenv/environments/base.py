"""What every humanoid env shares: the model, the action map, stepping, style features, rendering."""

from __future__ import annotations

import copy
import functools
import math
import operator
import os
import warnings
import zipfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NamedTuple

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces

from stairenv.environments.infos import columns_of_rows, flatten, take_rows, write_rows
from stairenv.humanoid import NUM_DOFS, PD_GAINS, STANDING_ROOT_HEIGHT, HumanoidIndices
from stairenv.humanoid.kinematics import humanoid_geoms, humanoid_lowest_z
from stairenv.humanoid.model import dof_ranges
from stairenv.humanoid.placement import place_reference_state
from stairenv.humanoid.state import push_root, read_state, stack_states, states_from_arrays
from stairenv.motion.rsi import BUILTIN_REFERENCE_SETS, level_clips, load_reference_library
from stairenv.rendering import RENDER_MODES, FollowCamera, HumanViewer
from stairenv.rotations import yaw_to_quat_wxyz
from stairenv.style.features import FeatureHistory, amp_features
from stairenv.style.reference import ReferenceWindows
from stairenv.tasks.kernels import all_finite, finite_pd_targets, no_warnings_within_limits, pd_targets
from stairenv.validation import check_choice, check_float, check_int

_BADQACC, _BADQVEL, _BADQPOS = (int(w) for w in (
    mujoco.mjtWarning.mjWARN_BADQACC, mujoco.mjtWarning.mjWARN_BADQVEL, mujoco.mjtWarning.mjWARN_BADQPOS))
_DIVERGENCE_WARNINGS = [_BADQACC, _BADQVEL, _BADQPOS]
#: the rows of ``MjData.warning`` that flag a divergence, for compiled checks (``_state_sound``)
DIVERGENCE_WARNING_ROWS = np.array(_DIVERGENCE_WARNINGS, dtype=np.int64)

# Speeds no body of this character reaches while the physics is sound. Saturated
# actions (bang-bang, clipped Gaussians) peak below ~90 rad/s at the joints and the
# root stays far below 20 m/s (benchmarks/bench_saturated.py); a state beyond these
# is a divergence on its way, flagged long before MuJoCo's own 1e10 check fires.
MAX_JOINT_SPEED = 250.0        # rad/s, every hinge and the root's angular velocity
MAX_ROOT_SPEED = 50.0          # m/s, the root's linear velocity
# dtype kinds an action may have (bool, integers, floats): complex, strings and objects are refused
# rather than converted (float64 would drop an imaginary part silently).
NUMERIC_KINDS = frozenset("biuf")
_FLOAT64 = np.dtype(np.float64)    # numpy's one native float64 dtype (an array's dtype is this very object)
_ACTION_DTYPES = (_FLOAT64, np.dtype(np.float32))    # what step's one-call path takes (float32 widens exactly)
_ACTION_SHAPE = (NUM_DOFS,)
#: start poses: standing, a frame of a reference clip, or either (``hybrid_fraction`` of them reference)
INITS = ("default", "reference", "hybrid")


def check_humanoid_keywords(frame_skip, amp_history, render_mode, width, height,
                            pd_gains: str = "soft") -> tuple[int, int, str | None, int, int]:
    """The keywords every env hands to ``load_humanoid_spec`` and ``_setup``, checked; the envs call it
    first in ``__init__`` so that a bad value fails before any model is built."""
    check_choice("pd_gains", pd_gains, tuple(PD_GAINS))
    if render_mode is not None:
        check_choice("render_mode", render_mode, RENDER_MODES)
    return (check_int("frame_skip", frame_skip, 1, 100), check_int("amp_history", amp_history, 1, 100),
            render_mode, check_int("width", width, 16, 4096), check_int("height", height, 16, 4096))


def check_reference_motion(source) -> None:
    """``reference_motion``: None, a built-in set or an existing ``.npz`` clip or folder of them. Files are
    loaded now (``load_reference_library`` caches them), whatever ``init`` is, so that a bad file fails
    at construction and not when AMP or a reference start first needs it."""
    if source is None:
        return
    if not isinstance(source, (str, os.PathLike)):
        raise TypeError(f"reference_motion must be None, a path or one of {list(BUILTIN_REFERENCE_SETS)}, "
                        f"got {type(source).__name__}")
    if str(source) in BUILTIN_REFERENCE_SETS:
        return
    if not Path(source).exists():
        raise ValueError(f"reference_motion {str(source)!r} is neither one of {list(BUILTIN_REFERENCE_SETS)} "
                         "nor an existing .npz file or folder of them")
    try:
        load_reference_library(source)
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as error:
        raise ValueError(f"reference_motion {str(source)!r} could not be loaded: {error}") from error


def speed_limits(idx: HumanoidIndices) -> np.ndarray:
    """The most each of the character's velocities may be, from the root's first: ``MAX_ROOT_SPEED`` for
    the root's linear velocity, ``MAX_JOINT_SPEED`` for its angular velocity and every joint."""
    if idx.qvel_joints.start != idx.qvel_root.stop:
        raise ValueError("the speed check expects the joints' velocities right after the root's")
    limits = np.full(idx.qvel_joints.stop - idx.qvel_root.start, MAX_JOINT_SPEED)
    limits[:3] = MAX_ROOT_SPEED
    return limits


class StepOutcome(NamedTuple):
    """What a task makes of its world after a step (or at the episode's start): ``_step_outcome``'s result.
    (Named for what it is, the outcome of one step, so that "evaluation" means only the papers' protocol,
    ``stairenv.evaluation``; ``Evaluation`` is its old name, a deprecated alias for one release.)

    ``results`` are the task's named per-world numbers (``progress``, ``success``, ``contact_error``...)
    that ``_info`` presents; ``terms`` the reward terms by their ``info`` key (``reward_*``), which
    add up to ``reward``. ``truncated``: the episode is cut without a terminal state (a training aid's end,
    whose value the trainer bootstraps). A batched env holds the same fields with a leading world dimension
    (``truncated`` may stay a plain False for every world).
    """

    obs: np.ndarray
    reward: float
    terms: dict[str, float]
    terminated: bool
    results: dict[str, Any]
    truncated: bool = False

    def world(self, k: int) -> StepOutcome:
        """World ``k``'s outcome of a batched one, its numbers as Python numbers (as a single env's)."""
        return StepOutcome(self.obs[k], self.reward.item(k), {key: value.item(k) for key, value in self.terms.items()},
                           self.terminated.item(k), {key: value.item(k) for key, value in self.results.items()},
                           bool(np.ndim(self.truncated) and self.truncated[k]))


class BatchStep(NamedTuple):
    """What ``HumanoidEnv._finish_batch`` makes of a batch of B worlds after their physics: the step's
    ``obs`` (B, ...), ``reward``, ``terminated`` and ``truncated`` (B,), and its info as ``columns``
    (``stairenv.environments.infos``) for the worlds ``column_rows`` (indices into the batch; None: all),
    and as whole dicts, ``dicts`` {k: info}, for the others (an unstable step, a world-by-world finish)."""

    obs: np.ndarray
    reward: np.ndarray
    terminated: np.ndarray
    truncated: np.ndarray
    columns: dict[str, Any]
    column_rows: np.ndarray | None
    dicts: dict[int, dict[str, Any]]

    @classmethod
    def of_worlds(cls, results: list[tuple]) -> BatchStep:
        """The per-world ``step`` results ``(obs, reward, terminated, truncated, info)`` of a batch."""
        obs, rewards, terminated, truncated, infos = zip(*results)
        return cls(np.array(obs), np.array(rewards, dtype=np.float64), np.array(terminated, dtype=bool),
                   np.array(truncated, dtype=bool), {}, None, dict(enumerate(infos)))


def __getattr__(name: str):
    if name == "Evaluation":  # the old name of ``StepOutcome``; deprecated, for one release
        warnings.warn("stairenv.environments.base.Evaluation is deprecated: use StepOutcome (the per-step result; "
                      "'evaluation' now means only the papers' protocol, stairenv.evaluation)",
                      DeprecationWarning, stacklevel=2)
        return StepOutcome
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


class HumanoidEnv(gym.Env):
    """Base class: owns the episode template; subclasses supply their world, task and info.

    ``reset`` (``_reset_worlds`` of one world; a batched env resets many together, each with its own
    draws): gymnasium's seeding -> ``_build_world(rng, options)`` (a new staircase, terrain or scene; may
    recompile the model with ``_compile``; ``_build_worlds`` over many) -> ``mj_resetData`` ->
    ``_place_character(rng, options)`` (returns whether it started from a reference state;
    ``_reference_pose`` draws one as ``init`` asks, ``_place_at`` places a standing or reference
    character on a floor; ``_reset_forward`` at the end) -> ``_new_goal(rng, options)`` (what the task
    draws once the character stands, optional) -> ``_begin_episodes`` (bookkeeping,
    ``_start_tracking(state)``, the first ``_step_outcomes``, style features filled).

    ``step``: ``_check_action`` (wrong shapes, non-real dtypes and NaN/inf raise ``ValueError``, a needed reset
    ``ResetNeeded``) -> ``_apply_action`` (PD targets ``offset + scale * a``, the range
    ``load_humanoid_spec`` wrote into the actuators' ctrlrange; MuJoCo clamps to it) ->
    ``_before_physics`` (optional: moving obstacles, replanning) -> ``_physics`` (``frame_skip``
    physics steps) -> ``_physics_sound`` (divergence, i.e. MuJoCo resetting the data, or a speed no
    body reaches, ``MAX_JOINT_SPEED`` / ``MAX_ROOT_SPEED`` checked in one compiled pass over qvel,
    takes the one unstable branch: truncated, the last good observation,
    ``info["physics_unstable"]``) -> ``_step_outcome(state)`` -> the style
    features (``self._amp``, the last ``amp_history`` frames) -> ``_info(results)`` plus what every
    env reports (``time``, ``physics_unstable``, ``amp_obs``, ``reference_start``, the reward terms).

    ``render()`` follows the pelvis; subclasses may override ``_render_lines``.
    """

    metadata = {"render_modes": list(RENDER_MODES), "render_fps": 30}
    #: the keywords a built env takes (``configure``, a batched env's ``set_attr``, or assigning
    #: ``env.unwrapped.<keyword>``): checked as ``gym.make`` checks them, written into ``config`` and re-derived
    #: by ``_apply_config``. Every other keyword is fixed once the env is built (it shapes the model, the
    #: spaces or what was loaded for it): changing one is refused, naming it.
    LIVE_KEYWORDS: frozenset[str] = frozenset()
    #: set when a step's ``_before_physics`` wrote this world's model (PlaMo's terrain tiles): a batched env
    #: on a device back-end copies the world's model up (``world_changed``) and clears it
    _model_written = False
    #: attributes named as a keyword that hold the env's state instead (PlaMoScene's ``scene``, the episode's
    #: scene; SIMS's ``room``): set freely, never through ``configure``
    STATE_ATTRIBUTES: frozenset[str] = frozenset()

    #: whether the class checks and applies actions as this class does (``step``'s one-call path for them)
    _plain_action = True

    def __init_subclass__(cls, **kwargs) -> None:
        """Each subclass's ``__init__`` counts as construction: until the outermost returns, keyword attributes
        are set as plain attributes; afterwards assigning one goes through ``configure``."""
        super().__init_subclass__(**kwargs)
        cls._plain_action = (cls._check_action is HumanoidEnv._check_action and cls._prepare_step is
                             HumanoidEnv._prepare_step and cls._apply_action is HumanoidEnv._apply_action)
        init = cls.__dict__.get("__init__")
        if init is None or getattr(init, "_counts_construction", False):
            return

        @functools.wraps(init)
        def constructing(self, *args, **kw):
            depth = self.__dict__.get("_init_depth", 0)
            object.__setattr__(self, "_init_depth", depth + 1)
            try:
                init(self, *args, **kw)
            finally:
                object.__setattr__(self, "_init_depth", depth)

        constructing._counts_construction = True
        cls.__init__ = constructing

    def __setattr__(self, name: str, value) -> None:
        if name[0] != "_":    # keywords are public names: a private attribute (a step sets several) is just set
            state = self.__dict__
            if (state.get("_init_depth", 1) == 0 and name in _config_keywords(state.get("config"))
                    and name not in self.STATE_ATTRIBUTES):
                self.configure(**{name: value})
                return
        object.__setattr__(self, name, value)

    def __getattr__(self, name: str):
        # only for names not found otherwise: a keyword the env keeps no attribute of reads its config
        config = self.__dict__.get("config")
        if config is not None and name in _config_keywords(config):
            return config.keywords()[name]
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    def configure(self, **keywords) -> None:
        """Change keywords of this built env: each checked as ``gym.make`` checks it (``TypeError`` /
        ``ValueError`` naming it and its range), then ``config`` is the new one and what depends on it is
        re-derived (in effect from the next step; a start's or a staircase's from the next reset). Only
        ``LIVE_KEYWORDS`` may change: another keyword given a new value is refused with a ``ValueError``
        naming it (build another env with it); given its current value it is a no-op."""
        before = self.config.keywords()
        config = self.config.replace(**keywords)
        after = config.keywords()
        changed = [name for name in keywords if not _same_value(after[name], before[name])]
        fixed = [name for name in changed if name not in self.LIVE_KEYWORDS]
        if fixed:
            live = ", ".join(sorted(self.LIVE_KEYWORDS)) or "none"
            raise ValueError(f"{fixed[0]!r} of {type(self).__name__} is fixed once the env is built (it shapes the "
                             f"model, the spaces or what was loaded for them): build another env with "
                             f"gym.make(..., {fixed[0]}=...). The keywords a built env takes: {live}")
        if changed:
            object.__setattr__(self, "config", config)
            self._apply_config(config)

    def _apply_config(self, config) -> None:
        """Derive this env's working attributes of its ``LIVE_KEYWORDS`` from ``config`` (after ``configure``;
        an env may call it at construction too). Here: an attribute of each, named as the keyword, which the
        env reads where it uses it; an env whose attributes are derived otherwise overrides it."""
        values = config.keywords()
        for name in self.LIVE_KEYWORDS:
            object.__setattr__(self, name, values[name])

    #: ``load_reference_library`` source used when ``reference_motion`` is None (RSI and AMP reference).
    DEFAULT_REFERENCE_MOTION: str | None = None
    #: the clips of the reference library that starts are drawn from (``init`` "reference" or "hybrid").
    start_clips = staticmethod(level_clips)

    @property
    def amp_history(self) -> int:
        """Frames of style features in ``info["amp_obs"]`` (the ``amp_history`` keyword): the
        ``num_frames`` of the reference windows a discriminator compares them with."""
        return len(self._amp.frames)

    #: the arrays over a batched env's worlds that this world's bookkeeping is a row of (``_share_rows``; None:
    #: the world's own), and its row
    _rows: dict[str, Any] | None = None
    _row = 0

    @property
    def _outcome(self) -> StepOutcome:
        """The last step outcome. A batched finish leaves its batch's outcome in the worlds' rows
        (``_finish_batch``); the world's own ``StepOutcome`` is made the first time it is read."""
        shared = self._rows
        if shared is not None and shared["_outcome_batch"][self._row] is not None:
            batch = shared["_outcome_batch"][self._row].outcome
            self._outcome = batch.world(int(shared["_outcome_index"][self._row]))
        return self._last_outcome

    @_outcome.setter
    def _outcome(self, outcome: StepOutcome) -> None:
        self._last_outcome = outcome
        if self._rows is not None:
            self._rows["_outcome_batch"][self._row] = None

    @property
    def _steps(self) -> int:
        """The steps of the current episode (a row of the batch's counts where they are shared)."""
        return int(self._step_count[0])

    @_steps.setter
    def _steps(self, steps: int) -> None:
        self._step_count[0] = steps

    @property
    def _reference_start(self) -> bool:
        """Whether the episode started from a reference state (``info["reference_start"]``)."""
        return bool(self._reference_flag[0])

    @_reference_start.setter
    def _reference_start(self, flag: bool) -> None:
        self._reference_flag[0] = flag

    # Isaac Lab's AMP convention (``amp_observation_space``, ``collect_reference_motions``, ``amp_obs`` in
    # the step's info), so that skrl's AMP agent and Isaac Lab-style trainers run against these envs.
    @property
    def amp_observation_space(self) -> spaces.Box:
        """The space of ``info["amp_obs"]``: ``amp_history`` frames of style features, oldest first."""
        return spaces.Box(-np.inf, np.inf, shape=(self._amp.frames.size,), dtype=np.float64)

    def collect_reference_motions(self, num_samples: int, rng: np.random.Generator | None = None) -> np.ndarray:
        """``num_samples`` reference windows shaped as ``info["amp_obs"]`` (float64, numpy where Isaac Lab
        gives torch): the env's reference clips (``reference_motion``, else ``DEFAULT_REFERENCE_MOTION``)
        in windows of ``amp_history`` frames at the control rate, each clip weighted as its library
        says. Drawn from ``rng`` (default: a generator of this method's own, so that calling it changes
        no episode)."""
        num_samples = check_int("num_samples", num_samples, 1, 10**8)
        if getattr(self, "_reference_windows", None) is None:
            source = getattr(self, "reference_motion", None) or self.DEFAULT_REFERENCE_MOTION  # None: builtin:stairs
            self._reference_windows = ReferenceWindows(load_reference_library(source), num_frames=self.amp_history,
                                                       fps=1.0 / self.dt)
            self._reference_rng = np.random.default_rng(0)
        rng = self._reference_rng if rng is None else rng
        return self._reference_windows.sample(num_samples, rng).astype(np.float64)

    # --- construction ---------------------------------------------------------
    def _setup(self, spec: mujoco.MjSpec, frame_skip: int, amp_history: int, render_mode: str | None,
               width: int, height: int) -> None:
        """``_init_humanoid`` and ``_compile`` in one (an env whose world is fixed at construction)."""
        self._init_humanoid(frame_skip, amp_history, render_mode, width, height)
        self._compile(spec)

    def _init_humanoid(self, frame_skip: int, amp_history: int, render_mode: str | None, width: int,
                       height: int) -> None:
        """What does not depend on the world: the keywords, the action space, the render settings."""
        frame_skip, amp_history, render_mode, width, height = check_humanoid_keywords(
            frame_skip, amp_history, render_mode, width, height)
        self.frame_skip = frame_skip
        self._amp = FeatureHistory(amp_history)
        self.render_mode = render_mode
        self.width, self.height = width, height
        self.action_space = spaces.Box(-1.0, 1.0, shape=(NUM_DOFS,), dtype=np.float32)
        self._needs_reset = True
        self._camera: FollowCamera | None = None
        self._viewer: HumanViewer | None = None
        self._camera_distance, self._camera_elevation, self._camera_azimuth = 4.5, -18.0, 135.0
        self._camera_choice: tuple[float, float] | None = None    # set_camera's, kept over scene rebuilds
        #: what ``_steps`` and ``_reference_start`` read: arrays of one row that ``_share_rows`` makes rows of the
        #: batch's, so that a batched step counts and reports them as arrays
        self._step_count = np.zeros(1, dtype=np.int64)
        self._reference_flag = np.zeros(1, dtype=bool)
        self._reference_clip = None
        self.model: mujoco.MjModel | None = None

    def _compile(self, spec: mujoco.MjSpec) -> None:
        """Compile the humanoid and its world into ``self.model`` (again after a world rebuild)."""
        spec.visual.global_.offwidth = max(self.width, spec.visual.global_.offwidth)
        spec.visual.global_.offheight = max(self.height, spec.visual.global_.offheight)
        self.model = spec.compile()
        self.data = mujoco.MjData(self.model)
        self._idx = HumanoidIndices.from_model(self.model)
        self._geoms = humanoid_geoms(self.model, self._idx)
        low, high = self.model.actuator_ctrlrange.T.copy()
        self._ctrl_offset, self._ctrl_scale = 0.5 * (low + high), 0.5 * (high - low)
        #: the servo targets' and the actuated joints' ranges as (low, high), for the start pose
        self._ctrl_limits = (low, high)
        self._joint_limits = tuple(dof_ranges(self.model).T.copy())    # DOF_NAMES order, the actuators' too
        self._bind_data_views()
        self._speed_limits = speed_limits(self._idx)
        self.dt = self.model.opt.timestep * self.frame_skip
        self.metadata = {**self.metadata, "render_fps": int(round(1.0 / self.dt))}
        self._needs_reset = True
        self._camera = None
        self._viewer = None
        self._camera_distance, self._camera_elevation, self._camera_azimuth = 4.5, -18.0, 135.0
        _after_compile()    # the previous model and data are released by now (views rebound)

    # Views into ``self.data`` that each step reads or writes, made once per MjData (its buffers never
    # move). A copy of the env (``copy.deepcopy``, pickle) gets its own views of its own data.
    _DATA_VIEWS = ("_warning_counts", "_ctrl", "_speeds", "_state_views")

    def _bind_data_views(self) -> None:
        data = self.data
        self._warning_counts = data.warning.number
        self._ctrl = data.ctrl
        #: the character's velocities, root first, as ``speed_limits`` bounds them
        self._speeds = data.qvel[self._idx.qvel_root.start:self._idx.qvel_joints.stop]
        self._state_views = read_state(data, self._idx) if self._idx.body_slice is not None else None

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        for name in self._DATA_VIEWS:
            state.pop(name, None)
        if self._rows is not None:    # a copy holds its own carry and last outcome, not its batch's rows
            state.pop("_rows")
            if "_last_outcome" in state:
                state["_last_outcome"] = self._outcome
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        if getattr(self, "data", None) is not None:
            self._bind_data_views()

    def replicate(self) -> HumanoidEnv:
        """A copy of this env with its own model and data (``copy.deepcopy``, the ``MjData`` made anew and
        its state copied: ~4x faster than a deep copy of the data's arena, ~10x faster than building the
        env again). A batched env on a device back-end makes its thousands of worlds this way."""
        data = self.data
        views = {name: self.__dict__.pop(name) for name in self._DATA_VIEWS if name in self.__dict__}
        self.data = None
        try:
            clone = copy.deepcopy(self)
        finally:
            self.data = data
            self.__dict__.update(views)
        if data is not None:
            clone.data = mujoco.MjData(clone.model)
            mujoco.mj_copyData(clone.data, clone.model, data)
            clone._bind_data_views()
        return clone

    def _setup_starts(self, init: str, hybrid_fraction: float, reference_motion) -> None:
        """Check ``init``, ``hybrid_fraction`` and ``reference_motion`` (its files loaded whatever ``init``
        is) and load the clips starts are drawn from (``start_clips`` of the library; none for "default")."""
        self.init = check_choice("init", init, INITS)
        self.hybrid_fraction = check_float("hybrid_fraction", hybrid_fraction, 0.0, 1.0)
        check_reference_motion(reference_motion)
        self.reference_motion = reference_motion
        self._library = None if self.init == "default" else self.start_clips(load_reference_library(
            self.DEFAULT_REFERENCE_MOTION if reference_motion is None else reference_motion))

    def _setup_family_aids(self, aids) -> None:
        """The training aids every family has (``config.FamilyTrainingAids``): reference-state starts
        (``_setup_starts``) and pushes (``_setup_pushes``)."""
        self._setup_starts(aids.init, aids.hybrid_fraction, aids.reference_motion)
        self._setup_pushes(aids.push_speed, aids.push_interval)

    #: training pushes (``_setup_pushes``): each kick's speed range (m/s), None = none
    _push_speed: tuple[float, float] | None = None

    def _setup_pushes(self, push_speed: tuple[float, float] | None, push_interval: tuple[float, float]) -> None:
        """Training pushes (the ``push_speed`` and ``push_interval`` keywords, checked by the config): from
        the first step of an episode, a kick (``push_root``) of a speed drawn from ``push_speed`` in a
        direction drawn uniformly every ``push_interval`` seconds (each interval drawn, in whole steps);
        the draws come from the env's ``np_random``, so a seeded episode meets the same kicks. Only a
        training aid: the evaluations push with their own plan (``stairenv.evaluation.pushes``)."""
        self._push_speed = push_speed
        self._push_interval = push_interval
        self._next_push = 0

    def _push_if_due(self) -> None:
        """Before the physics of a step: at an episode's first step draw when its first push comes; at that
        step kick the root and draw the next."""
        steps, rng = self._steps, self.np_random
        if steps == 0 or steps == self._next_push:
            if steps:
                push_root(self.model, self.data, float(rng.uniform(*self._push_speed)),
                          float(rng.uniform(-math.pi, math.pi)))
            low, high = (max(1, round(seconds / self.dt)) for seconds in self._push_interval)
            self._next_push = steps + int(rng.integers(low, high, endpoint=True))

    # --- the episode template ---------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        obs, info = type(self)._reset_worlds([self], [seed], [options])[0]
        return obs.copy(), info    # the caller's own: the env keeps its last observation (an unstable step's)

    @classmethod
    def _reset_worlds(cls, envs: list[HumanoidEnv], seeds: Sequence[int | None],
                      options: Sequence[dict[str, Any] | None]) -> list[tuple]:
        """``reset`` of many worlds of this class (a batched env's resets): ``reset``'s ``(obs, info)`` per
        world. Each world draws from its own generator in the order its own ``reset`` would, so the result is
        the same world by world or together; what needs no draw goes over the batch where the class can
        (``_build_worlds``, ``_begin_episodes``)."""
        if not envs:
            return []
        for env, seed in zip(envs, seeds):
            gym.Env.reset(env, seed=seed)
            # A world kept between resets is rebuilt on a seed: a seeded episode depends on no earlier one.
            env._seeded_reset = seed is not None
        cls._build_worlds(envs, options)
        for env, world_options in zip(envs, options):
            rng = env.np_random
            mujoco.mj_resetData(env.model, env.data)
            env._reference_start = bool(env._place_character(rng, world_options))
            env._new_goal(rng, world_options)
        return cls._begin_episodes(envs)

    @classmethod
    def _build_worlds(cls, envs: list[HumanoidEnv], options: Sequence[dict[str, Any] | None]) -> None:
        """Each world's ``_build_world`` with its own generator (a class may write them over the batch)."""
        for env, world_options in zip(envs, options):
            env._build_world(env.np_random, world_options)

    def _build_world(self, rng: np.random.Generator, options: dict[str, Any] | None) -> None:
        """The episode's world: write it into the model, or rebuild the model (``_compile``). A class that
        writes many worlds at once overrides ``_build_worlds`` instead."""
        raise NotImplementedError

    def _place_character(self, rng: np.random.Generator, options: dict[str, Any] | None) -> bool:
        """Place the character (servos holding its pose, ``_reset_forward`` run); True if it starts
        from a reference state."""
        raise NotImplementedError

    #: what a reset runs once the character is placed: ``mj_forward``, every derived quantity (as Gymnasium's
    #: MuJoCo envs leave ``MjData`` after a reset). A batched env on a device back-end makes it
    #: ``mj_kinematics`` (a quarter of a reset's time on one core): the poses are all the host reads, the device
    #: computes the rest at its step, and after a step there the host's ``MjData`` holds the kinematics only too.
    _reset_forward = staticmethod(mujoco.mj_forward)

    def _new_goal(self, rng: np.random.Generator, options: dict[str, Any] | None) -> None:
        """What the task draws once the character is placed (a path from its start, a contact goal)."""

    def _read_state(self):
        """``read_state`` of this env's data: the views ``_bind_data_views`` made where the bodies are
        consecutive (the same arrays ``read_state`` would return), else a fresh read."""
        views = self._state_views
        return read_state(self.data, self._idx) if views is None else views

    def _begin_episode(self):
        """Start counting from the current state: the first step outcome, the style history filled.
        Returns ``reset``'s ``(obs, info)``."""
        return type(self)._begin_episodes([self])[0]

    @classmethod
    def _begin_episodes(cls, envs: list[HumanoidEnv]) -> list[tuple]:
        """``_begin_episode`` of many worlds of this class, their state read and their first step outcomes
        made as one batch (``_step_outcomes``)."""
        for env in envs:
            env._needs_reset = False
            env._steps = 0
            env._episode_paths, env._episode_values = flatten(env._episode_info())
        if envs[0]._rows is not None:
            _share_episode_infos(envs)
        state = envs[0]._read_state() if len(envs) == 1 else cls._read_worlds(envs)
        features = amp_features(state)
        for k, env in enumerate(envs):
            env._amp.fill_features(features[k])
        cls._start_tracking_worlds(envs, state)
        outcomes = cls._step_outcomes(envs, state)
        results = []
        for env, outcome in zip(envs, outcomes):
            env._outcome = outcome
            results.append((outcome.obs, env._full_info(outcome, unstable=False, terms=False)))
        return results

    def _start_tracking(self, state) -> None:
        """Reset what ``_step_outcome`` carries from step to step (the previous root position...)."""

    @classmethod
    def _start_tracking_worlds(cls, envs: list[HumanoidEnv], state) -> None:
        """``_start_tracking`` of each of ``envs`` (row k of the batch ``state``: world k's); a class may do it
        over the batch."""
        if len(envs) == 1:
            envs[0]._start_tracking(state)
            return
        for k, env in enumerate(envs):
            env._start_tracking(row_of(state, k))

    def _step_outcome(self, state) -> StepOutcome:
        """The task's view of ``state`` (``read_state``): observation, reward, end, named results."""
        raise NotImplementedError

    def _info(self, results: dict[str, Any]) -> dict[str, Any]:
        """The task's part of ``info`` from a step outcome's results."""
        return dict(results)

    def _unstable_results(self, last: StepOutcome) -> dict[str, Any]:
        """The results an unstable step reports, from the last good step outcome (default: its results)."""
        return dict(last.results)

    def step(self, action):
        if (self._plain_action and type(action) is np.ndarray and action.dtype in _ACTION_DTYPES
                and action.shape == _ACTION_SHAPE and not self._needs_reset
                and finite_pd_targets(self._ctrl_offset, self._ctrl_scale, action, self._ctrl)):
            # the usual action (a float array, finite, after a reset): checked and its PD targets written in one
            # compiled call, as _check_action then _apply_action would; anything else takes those two
            self._after_action()
        else:
            self._prepare_step(self._check_action(action))
        self._physics()
        obs, reward, terminated, truncated, info = self._finish_step()
        return obs.copy(), reward, terminated, truncated, info    # as reset's: the caller's own array

    # The phases of ``step``: a batched env (``stairenv.environments.vector``) calls them over its
    # worlds, the physics of all worlds at once between ``_prepare_step`` and ``_finish_step``.
    def _prepare_step(self, action: np.ndarray) -> None:
        """What comes before the physics: the (checked) action applied, ``_before_physics``."""
        self._apply_action(action)
        self._after_action()

    def _after_action(self) -> None:
        """``_prepare_step`` once the action is applied: a training push where one is due, ``_before_physics``,
        the time the physics must reach."""
        if self._push_speed is not None:
            self._push_if_due()
        self._before_physics()
        self._expected_time = self.data.time + self.dt    # dt: frame_skip timesteps

    @classmethod
    def _prepare_worlds(cls, envs: list[HumanoidEnv], actions: np.ndarray, rows: np.ndarray | None = None) -> None:
        """``_prepare_step`` of many worlds of this class (row k of ``actions``: world k's checked action),
        each world's ctrl as its ``_prepare_step`` writes it: where the class keeps this action map, the PD
        targets of all worlds in one array operation, then copied into each world's ctrl. ``rows``: see
        ``_share_rows``."""
        if cls._apply_action is not HumanoidEnv._apply_action or not envs:
            for env, action in zip(envs, actions):
                env._prepare_step(action)
            return
        for env, ctrl in zip(envs, _pd_targets(envs, actions, rows)):    # _apply_action's operations, row by row
            env._ctrl[:] = ctrl
            env._after_action()

    @classmethod
    def _action_targets(cls, envs: list[HumanoidEnv], actions: np.ndarray,
                        rows: np.ndarray | None = None) -> np.ndarray:
        """The PD targets of many worlds as one array (row k: world k), for a back-end that takes the ctrl
        of all worlds at once (``WarpPhysics(state_on_device=True)``): ``_prepare_worlds``' action map with
        no world's ctrl written. Only for classes with the plain action map and no ``_before_physics``."""
        if cls._apply_action is not HumanoidEnv._apply_action or cls._before_physics is not HumanoidEnv._before_physics:
            raise ValueError(f"{cls.__name__} changes its ctrl world by world; its state cannot stay on the device")
        if any(env._push_speed is not None for env in envs):
            raise ValueError("push_speed (training pushes) kicks a world's velocity world by world; its state cannot "
                             "stay on the device: train with push_speed=None there, or without state_on_device")
        return _pd_targets(envs, actions, rows)

    def _physics(self) -> None:
        """``frame_skip`` physics steps (a batched env runs them for all its worlds instead)."""
        mujoco.mj_step(self.model, self.data, self.frame_skip)

    def _finish_step(self):
        """What comes after the physics: the divergence check, the step outcome, the style features and
        ``info``; ``step``'s result."""
        stable = self._physics_sound(self._expected_time)
        self._step_count[0] += 1    # _steps += 1
        if not stable:
            return self._unstable_step()
        state = self._read_state()
        outcome = self._outcome = self._step_outcome(state)
        self._amp.push(state)
        info = self._full_info(outcome, unstable=False, terms=True)
        if self.render_mode == "human":
            self.render()
        return outcome.obs, outcome.reward, bool(outcome.terminated), bool(outcome.truncated), info

    #: True where ``_step_outcomes`` computes a batch's outcomes in one call: a batched env then finishes all its
    #: worlds with ``_finish_batch`` after the physics instead of ``_finish_step`` world by world.
    BATCH_OUTCOMES = False

    @classmethod
    def _finish_worlds(cls, envs: list[HumanoidEnv], poses_current: bool = False) -> list[tuple]:
        """``_finish_step`` of many worlds of this class, batch-first: each world's result equals its
        ``_finish_step``. The divergence and speed check over the batch (``_sound_worlds``), the state of
        the stable worlds read as one batch, ``_step_outcomes`` and the style features in one call each.
        ``poses_current``: every world's ``mj_kinematics`` already ran after its physics (``_bring_up_poses``)."""
        results: list[tuple | None] = [None] * len(envs)
        unstable = _count_steps(envs, cls._sound_worlds(envs, poses_current))
        for k, result in unstable.items():
            results[k] = result
        stable = [k for k in range(len(envs)) if k not in unstable]
        if stable:
            worlds = [envs[k] for k in stable]
            state = cls._read_worlds(worlds)
            outcomes = cls._step_outcomes(worlds, state)
            amp_obs = FeatureHistory.push_each([env._amp for env in worlds], amp_features(state))
            for k, env, outcome, world_amp_obs in zip(stable, worlds, outcomes, amp_obs):
                env._outcome = outcome
                results[k] = (outcome.obs, outcome.reward, bool(outcome.terminated), bool(outcome.truncated),
                              env._full_info(outcome, unstable=False, terms=True, amp_obs=world_amp_obs))
        return results

    @classmethod
    def _finish_batch(cls, envs: list[HumanoidEnv], poses_current: bool = False,
                      rows: np.ndarray | None = None, device_state: dict[str, np.ndarray] | None = None) -> BatchStep:
        """``_finish_step`` of many worlds of this class as a ``BatchStep``: where the class computes its
        outcomes as arrays (``_step_outcome_batch``), the info too, as columns, with no dict per world;
        otherwise ``_finish_worlds``' per-world results. Each world's info equals its ``_finish_step``'s:
        the task's results and its ``_episode_info`` (``_info`` is those two for such a class), then what
        every env reports, then the reward terms. ``rows``: the worlds' rows of the arrays ``_share_rows``
        made (None: each world's own carry). ``device_state``: the worlds' state as a device back-end left it
        (``WarpPhysics.state``: ``qpos``, ``qvel``, ``xpos``, ``xmat``, ``diverged``; row k: world k), read
        instead of each world's ``MjData``."""
        if cls._step_outcome_batch is HumanoidEnv._step_outcome_batch:
            return BatchStep.of_worlds(cls._finish_worlds(envs, poses_current))
        n = len(envs)
        sound = cls._sound_worlds(envs, poses_current) if device_state is None else cls._sound_arrays(envs, device_state)
        unstable = _count_steps(envs, sound, rows)
        obs = reward = terminated = truncated = None
        stable = None if not unstable else np.flatnonzero(sound)
        worlds = envs if stable is None else [envs[k] for k in stable]
        columns: dict[str, Any] = {}
        if worlds:
            world_rows = rows if rows is None or stable is None else rows[stable]
            if device_state is None:
                state = cls._read_worlds(worlds)
            else:
                fields = [device_state[name] if stable is None else device_state[name][stable]
                          for name in ("xpos", "xmat", "qpos", "qvel")]
                state = states_from_arrays(*fields, worlds[0]._idx)
            outcome = cls._step_outcome_batch(worlds, state, world_rows)
            if world_rows is None:
                amp_obs = FeatureHistory.push_each([env._amp for env in worlds], amp_features(state))
            else:
                amp_obs = FeatureHistory.push_rows(worlds[0]._rows["amp"], world_rows, amp_features(state))
            first = worlds[0]
            shared = first._rows
            if world_rows is None:
                for j, env in enumerate(worlds):
                    env._outcome = outcome.world(j)
                episode_columns = columns_of_rows(first._episode_paths, [env._episode_values for env in worlds])
                steps = np.array([env._steps for env in worlds], dtype=np.int64)
                reference_start = np.array([env._reference_start for env in worlds], dtype=bool)
            else:    # the worlds' rows: no per-world Python
                shared["_outcome_batch"][world_rows] = _OutcomeOfBatch(outcome)    # a world's made when read
                shared["_outcome_index"][world_rows] = np.arange(len(worlds))
                episode_columns = take_rows(shared["_episode"], world_rows)
                steps, reference_start = shared["_step_count"][world_rows], shared["_reference_flag"][world_rows]
            columns = {**outcome.results, **episode_columns, "time": steps * first.dt,
                       "physics_unstable": np.zeros(len(worlds), dtype=bool), "amp_obs": amp_obs,
                       "reference_start": reference_start, **outcome.terms}
            obs, reward, terminated = outcome.obs, outcome.reward, outcome.terminated
            truncated = np.zeros(len(worlds), dtype=bool) | outcome.truncated
        if unstable:    # the unstable worlds' rows, from their whole results
            rows_unstable = np.array(list(unstable), dtype=np.int64)
            results = list(unstable.values())
            obs = _rows_into(n, stable, obs, rows_unstable, np.array([result[0] for result in results]))
            reward = _rows_into(n, stable, reward, rows_unstable,
                                np.array([result[1] for result in results], dtype=np.float64))
            terminated = _rows_into(n, stable, terminated, rows_unstable,
                                    np.array([result[2] for result in results], dtype=bool))
            truncated = _rows_into(n, stable, truncated, rows_unstable,
                                   np.array([result[3] for result in results], dtype=bool))
        return BatchStep(obs, reward, terminated, truncated, columns, stable,
                         {k: result[4] for k, result in unstable.items()})

    #: the task's step outcomes of a batch as one ``StepOutcome`` of arrays: a classmethod
    #: ``(envs, state, rows=None) -> StepOutcome`` where a class has it (InterLevel), which ``_finish_batch``
    #: then uses (``rows``: see ``_share_rows``)
    _step_outcome_batch = None

    #: what the task carries from step to step (InterLevel: the last root position, the packed goal, the stall
    #: clock), as attribute paths of arrays of shape (1, ...) (a batch of one) that are written in place,
    #: never rebound, so that ``_share_rows`` can make them rows of one array per path
    ROW_ARRAYS: tuple[str, ...] = ()

    @classmethod
    def _share_rows(cls, envs: list[HumanoidEnv]) -> None:
        """Make each world's ``ROW_ARRAYS``, style history and action map rows (views) of one array over ``envs``
        (row i: ``envs[i]``), held in ``env._rows`` by path (the history as "amp"). A batched env does so once;
        ``_finish_batch(envs, rows=...)`` then reads and writes the carry of a group of worlds by their rows
        (``_take_carry``, ``_put_carry``) instead of world by world. A world's own code keeps working on its
        views."""
        shared: dict[str, Any] = {}
        for path in (*_WORLD_ROWS, *cls.ROW_ARRAYS):
            array = shared[path] = np.concatenate([_attribute(env, path) for env in envs])
            for i, env in enumerate(envs):
                _set_attribute(env, path, array[i:i + 1])
        # the last step outcome, as the batch's that a batched finish left (an ``_OutcomeOfBatch``) and the
        # world's index into it; None: the world's own (see ``_outcome``)
        shared["_outcome_batch"] = np.full(len(envs), None, dtype=object)
        shared["_outcome_index"] = np.zeros(len(envs), dtype=np.int64)
        #: the episode's info (``_episode_info``, the same keys in every world) as columns over the worlds,
        #: written at their resets, and its flattened keys (None until the first reset)
        shared["_episode"], shared["_episode_paths"] = {}, None
        amp = shared["amp"] = np.array([env._amp.frames for env in envs])
        # the action map too (read only; set when the model is compiled, which such a class does once), so that
        # the PD targets of a group are two row reads, not two stacks of the worlds' arrays
        offset = shared["_ctrl_offset"] = np.array([env._ctrl_offset for env in envs])
        scale = shared["_ctrl_scale"] = np.array([env._ctrl_scale for env in envs])
        for i, env in enumerate(envs):
            env._amp.frames, env._ctrl_offset, env._ctrl_scale = amp[i], offset[i], scale[i]
            env._rows, env._row = shared, i

    @classmethod
    def _take_carry(cls, envs: list[HumanoidEnv], rows: np.ndarray | None) -> dict[str, np.ndarray]:
        """The ``ROW_ARRAYS`` of ``envs``, one array per path (row k: world k), for the task to read and write in
        place: a single world's own arrays, else the worlds' rows of the shared arrays (``rows``; by default
        their own rows where they share them, as at a batched env's resets) or each world's own, concatenated;
        ``_put_carry`` writes the latter back."""
        if rows is None and len(envs) == 1:
            return {path: _attribute(envs[0], path) for path in cls.ROW_ARRAYS}
        rows = _shared_rows_of(envs) if rows is None else rows
        if rows is not None:
            shared = envs[0]._rows
            return {path: shared[path][rows] for path in cls.ROW_ARRAYS}
        return {path: np.concatenate([_attribute(env, path) for env in envs]) for path in cls.ROW_ARRAYS}

    @classmethod
    def _put_carry(cls, envs: list[HumanoidEnv], rows: np.ndarray | None, carry: dict[str, np.ndarray]) -> None:
        """Write ``carry`` (``_take_carry``'s, changed) back to the worlds (nothing to do for a single world's own)."""
        if rows is None and len(envs) == 1:
            return
        rows = _shared_rows_of(envs) if rows is None else rows
        for path, values in carry.items():
            if rows is not None:
                envs[0]._rows[path][rows] = values
            else:
                for k, env in enumerate(envs):
                    _attribute(env, path)[...] = values[k:k + 1]

    def _episode_info(self) -> dict[str, Any]:
        """What ``info`` reports of the episode that does not change from step to step (InterLevel: its
        staircase): ``_begin_episode`` keeps it flattened, which ``_finish_batch`` stacks as columns."""
        return {}

    @classmethod
    def _read_worlds(cls, envs: list[HumanoidEnv]):
        """The state of ``envs`` as one batch (row k: world k) for ``_finish_worlds``: each world's
        ``_read_state`` stacked. Those are views made once per ``MjData``, so no ``MjData`` attribute is
        read per world and step; worlds whose models differ in structure (SIMS) stack alike."""
        return stack_states([env._read_state() for env in envs])

    @classmethod
    def _step_outcomes(cls, envs: list[HumanoidEnv], state) -> list[StepOutcome]:
        """``_step_outcome`` of each world of ``envs`` (row k of the batch ``state`` is world k's state)."""
        return [env._step_outcome(row_of(state, k)) for k, env in enumerate(envs)]

    def _before_physics(self) -> None:
        """Called by ``step`` after the action is applied, before the physics."""

    def _unstable_step(self):
        """The simulation diverged (MuJoCo reset the data) or went faster than a body can: truncate,
        keep the last good observation, reward 0, every reward term 0; the env needs a reset."""
        last = self._outcome
        outcome = StepOutcome(last.obs.copy(), 0.0, dict.fromkeys(last.terms, 0.0), False,
                                self._unstable_results(last))
        return outcome.obs, 0.0, False, True, self._full_info(outcome, unstable=True, terms=True)

    def _full_info(self, outcome: StepOutcome, unstable: bool, terms: bool,
                   amp_obs: np.ndarray | None = None) -> dict[str, Any]:
        """``info``: the task's part, then what every env reports. ``amp_obs``: the style history's
        ``flat()`` where the caller has it already (``_finish_worlds``: a row of the batch's)."""
        info = self._info(outcome.results)
        info["time"] = self._steps * self.dt
        info["physics_unstable"] = unstable
        info["amp_obs"] = self._amp.flat() if amp_obs is None else amp_obs
        info["reference_start"] = self._reference_start
        if terms:
            info.update(outcome.terms)
        return info

    # --- pieces -----------------------------------------------------------------
    def _reference_pose(self, rng: np.random.Generator, library=None) -> tuple[np.ndarray, np.ndarray] | None:
        """A reference state ``(qpos (35,), qvel (34,))`` to start from, or None to start standing:
        always with ``init="reference"``, in ``hybrid_fraction`` of the episodes with "hybrid". Drawn
        from ``library`` (a ``MotionLibrary``), by default the env's start clips."""
        self._reference_clip = None
        if not (self.init == "reference" or (self.init == "hybrid" and rng.uniform() < self.hybrid_fraction)):
            return None
        library = self._library if library is None else library
        clip_ids, times = library.sample(1, rng)
        qpos, qvel = library.states(clip_ids, times)
        #: the clip and time the episode started from (a task may imitate the clip on from there)
        self._reference_clip = (library.clips[int(clip_ids[0])], float(times[0]))
        return qpos[0], qvel[0]

    def _place_at(self, xy, heading: float, reference: tuple[np.ndarray, np.ndarray] | None,
                  floor: float = 0.0) -> None:
        """Put the character at ``xy`` facing ``heading``, its lowest point just above ``floor``: in the
        ``reference`` state, or standing. Servos hold the pose; runs ``_reset_forward``."""
        model, data = self.model, self.data
        if reference is not None:
            place_reference_state(model, data, self._idx, reference[0], reference[1], xy, heading, floor)
        else:
            data.qpos[self._idx.qpos_root] = (*xy, STANDING_ROOT_HEIGHT, *yaw_to_quat_wxyz(heading))
            mujoco.mj_kinematics(model, data)
            data.qpos[self._idx.qpos_root.start + 2] += floor + 0.002 - humanoid_lowest_z(model, data, self._geoms)
        self._hold_pose_ctrl()
        self._reset_forward(model, data)

    def _hold_pose_ctrl(self) -> None:
        """Servo targets = the current joint angles (an episode starts holding its pose)."""
        low, high = self._ctrl_limits    # np.clip's operations, without its wrapper's cost
        np.minimum(np.maximum(self.data.qpos[self._idx.qpos_joints], low), high, out=self._ctrl)

    def _check_action(self, action) -> np.ndarray:
        """``action`` as float64 (28,); ``ValueError`` for a wrong shape, a non-numeric dtype (complex,
        strings, objects) or NaN/inf, ``ResetNeeded`` before a reset."""
        if type(action) is not np.ndarray or action.dtype is not _FLOAT64:    # the usual float64 array skips this
            action = np.asarray(action)
            if action.dtype.kind not in NUMERIC_KINDS:
                raise ValueError(f"action must be real numbers, got dtype {action.dtype}")
            action = action.astype(np.float64, copy=False)
        if action.shape != (NUM_DOFS,):
            raise ValueError(f"action must have shape ({NUM_DOFS},), got {action.shape}")
        if not all_finite(action):
            bad = np.flatnonzero(~np.isfinite(action)).tolist()
            raise ValueError(f"action must be finite, got NaN or inf at indices {bad}")
        if self._needs_reset:
            raise gym.error.ResetNeeded("call reset() before step() (after an unstable-physics truncation too)")
        return action

    def _apply_action(self, action: np.ndarray) -> None:
        """PD targets ``offset + scale * action`` (numpy's two operations, in one compiled call)."""
        pd_targets(self._ctrl_offset, self._ctrl_scale, action, self._ctrl)

    def action_of_targets(self, joint_targets: np.ndarray) -> np.ndarray:
        """The action whose PD targets are ``joint_targets`` (28 joint angles; ``_apply_action`` inverted),
        clipped to the action range: how a clip is played back through the servos."""
        return np.clip((joint_targets - self._ctrl_offset) / self._ctrl_scale, -1.0, 1.0)

    def _physics_sound(self, expected_time: float) -> bool:
        """After the physics: False (and a reset needed) if it diverged or went faster than a body can
        (``_state_sound``); otherwise body poses brought up to qpos."""
        data = self.data
        # MuJoCo resets the data when positions, velocities or accelerations blow up:
        # the time jumps back and the warning counts (zeroed at every episode reset by
        # mj_resetData) go up. Otherwise qpos and qvel are finite by its checks.
        if data.time < expected_time - 1e-9 or not self._state_sound():
            self._mark_unstable()
            return False
        # mj_step leaves body poses at the start of its last substep: bring them up to qpos.
        self._bring_up_poses(self.model, data)
        return True

    @classmethod
    def _sound_worlds(cls, envs: list[HumanoidEnv], poses_current: bool = False) -> np.ndarray:
        """``_physics_sound(env._expected_time)`` of each of ``envs`` (worlds of one configuration), with the
        same effects: its checks as arrays over the batch where the class keeps them (else world by world).
        ``poses_current``: the worlds' ``mj_kinematics`` already ran (``_bring_up_poses``), so it is not run
        again for the stable worlds."""
        if cls._physics_sound is not HumanoidEnv._physics_sound or cls._state_sound is not HumanoidEnv._state_sound:
            return np.array([env._physics_sound(env._expected_time) for env in envs], dtype=bool)
        times = np.array([env.data.time for env in envs])
        expected = np.array([env._expected_time for env in envs])
        warned = np.array([env._warning_counts for env in envs])[:, _DIVERGENCE_WARNINGS].any(axis=1)
        speeds = np.array([env._speeds for env in envs])
        # as _physics_sound's scalar tests: a NaN time or speed compares False
        plausible = (np.abs(speeds) <= envs[0]._speed_limits).all(axis=1)
        sound = ~(times < expected - 1e-9) & ~warned & plausible
        for env, world_sound in zip(envs, sound.tolist()):
            if not world_sound:
                env._mark_unstable()
            elif not poses_current:
                env._bring_up_poses(env.model, env.data)
        return sound

    @classmethod
    def _sound_arrays(cls, envs: list[HumanoidEnv], device_state: dict[str, np.ndarray]) -> np.ndarray:
        """``_sound_worlds`` from a device back-end's arrays: a world is sound unless the device flagged it
        diverged (non-finite or beyond MuJoCo's bound) or it moves faster than a body can; an unsound world
        is marked as ``_physics_sound`` marks it."""
        idx = envs[0]._idx
        speeds = device_state["qvel"][:, idx.qvel_root.start:idx.qvel_joints.stop]
        sound = ~device_state["diverged"] & (np.abs(speeds) <= envs[0]._speed_limits).all(axis=1)
        for k in np.flatnonzero(~sound).tolist():
            envs[k]._mark_unstable()
        return sound

    @staticmethod
    def _bring_up_poses(model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """What ``_physics_sound`` does for a stable world: body poses brought up to ``qpos``. A batched
        env runs it in the physics thread right after each world's physics (MuJoCo releases the GIL, so
        on several cores it leaves the calling thread), then finishes with ``poses_current``. It also runs
        for a world that failed the checks; nothing of such a step reads the poses."""
        mujoco.mj_kinematics(model, data)

    def _mark_unstable(self) -> None:
        """The physics failed the divergence or speed check: a reset needed, and a warning."""
        self._needs_reset = True
        gym.logger.warn("physics became unstable; episode truncated (info['physics_unstable'] = True)")

    def _state_sound(self) -> bool:
        """False once MuJoCo has flagged a divergence (its warnings of bad accelerations, velocities or
        positions, counted since the episode's reset) or the character moves faster than its body can
        (``MAX_JOINT_SPEED``, ``MAX_ROOT_SPEED``): one compiled pass."""
        return no_warnings_within_limits(self._warning_counts, DIVERGENCE_WARNING_ROWS, self._speeds,
                                         self._speed_limits)

    # --- rendering ----------------------------------------------------------
    def _render_lines(self) -> tuple:
        """(from, to, rgba) segments drawn over the frame."""
        return ()

    def set_camera(self, elevation: float, distance: float) -> None:
        """Point the ``rgb_array`` follow camera: ``elevation`` (deg) and ``distance`` (m) from the
        pelvis, now and after later rebuilds of the camera or the scene (over a scene's own default view)."""
        self._camera_choice = (float(elevation), float(distance))
        self._camera_elevation, self._camera_distance = self._camera_choice
        if self._camera is not None:
            self._camera.camera.elevation, self._camera.camera.distance = self._camera_elevation, self._camera_distance

    def render(self):
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human'")
            return None
        if self.render_mode == "human":
            if self._viewer is None:
                self._viewer = HumanViewer(self.model, self.data, self._idx.pelvis_id)
            self._viewer.sync()
            return None
        if self._camera is None:
            if self._camera_choice is not None:    # the caller's view over the rebuilt scene's default
                self._camera_elevation, self._camera_distance = self._camera_choice
            self._camera = FollowCamera(self.model, self._idx.pelvis_id, self.width, self.height,
                                        distance=self._camera_distance, elevation=self._camera_elevation)
        self._camera.camera.azimuth = self._camera_azimuth
        return self._camera.render(self.data, self._render_lines())

    def close(self) -> None:
        if self._camera is not None:
            self._camera.close()
            self._camera = None
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None


def _pd_targets(envs: list[HumanoidEnv], actions: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
    """Each world's PD targets ``offset + scale * action`` (``_apply_action``'s map), one row per world; the
    worlds' maps read by ``rows`` where they are shared (``_share_rows``)."""
    if rows is not None:
        shared = envs[0]._rows
        return shared["_ctrl_offset"][rows] + shared["_ctrl_scale"][rows] * actions
    return np.array([env._ctrl_offset for env in envs]) + np.array([env._ctrl_scale for env in envs]) * actions


def _count_steps(envs: list[HumanoidEnv], sound: np.ndarray, rows: np.ndarray | None = None) -> dict[int, tuple]:
    """A batch's step counted in each world (by its ``rows`` where the counts are shared), then
    ``_unstable_step``'s result of each unsound world k."""
    if rows is None:
        for env in envs:
            env._steps += 1
    else:
        envs[0]._rows["_step_count"][rows] += 1
    return {k: envs[k]._unstable_step() for k in np.flatnonzero(~sound).tolist()}


def _shared_rows_of(envs: list[HumanoidEnv]) -> np.ndarray | None:
    """The rows of ``envs`` in the arrays they share (``_share_rows``; a batched env's resets), else None."""
    return None if envs[0]._rows is None else np.array([env._row for env in envs], dtype=np.int64)


#: each world's bookkeeping that a batched step reads or writes for every world (the episode's step count,
#: whether it started from a reference state): arrays of one row, shared as rows like ``ROW_ARRAYS``
_WORLD_ROWS = ("_step_count", "_reference_flag")


class _OutcomeOfBatch:
    """A batch's ``StepOutcome`` as one object (a NamedTuple would be spread over an object array's rows)."""

    __slots__ = ("outcome",)

    def __init__(self, outcome: StepOutcome) -> None:
        self.outcome = outcome


def _share_episode_infos(envs: list[HumanoidEnv]) -> None:
    """The worlds' episode infos (flattened by ``_begin_episodes``) into their rows of the batch's columns
    (``_share_rows``), which ``_finish_batch`` then reads by rows. A step's infos are columns, so every
    world's episode info must have the same keys: ``ValueError`` naming the worlds whose keys differ."""
    shared = envs[0]._rows
    if shared["_episode_paths"] is None:
        shared["_episode_paths"] = envs[0]._episode_paths
    paths = shared["_episode_paths"]
    differ = [env._row for env in envs if env._episode_paths != paths]
    if differ:
        raise ValueError(f"{type(envs[0]).__name__}._episode_info must give every world of a batched env the same "
                         f"keys {['.'.join(path) for path in paths]}; world(s) {differ} gave other keys")
    rows = _shared_rows_of(envs)
    write_rows(shared["_episode"], columns_of_rows(paths, [env._episode_values for env in envs]), rows,
               len(shared["_step_count"]))


def _rows_into(n: int, rows_a, values_a, rows_b, values_b) -> np.ndarray:
    """An array of ``n`` rows from two row sets (``rows_a`` None with ``values_a`` None: none)."""
    out = np.empty((n, *values_b.shape[1:]), dtype=values_b.dtype)
    if values_a is not None:
        out[rows_a] = values_a
    out[rows_b] = values_b
    return out


#: how many model compiles (an env that rebuilds its world at reset compiles one each time) between two
#: returns of the C allocator's freed memory to the system
TRIM_EVERY_COMPILES = 32
_compiles = 0


@functools.cache
def _malloc_trim():
    """glibc's ``malloc_trim`` (None elsewhere)."""
    import ctypes
    import ctypes.util

    try:
        trim = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6").malloc_trim
    except (OSError, AttributeError):
        return None
    trim.argtypes, trim.restype = [ctypes.c_size_t], ctypes.c_int
    return trim


def _after_compile() -> None:
    """Every ``TRIM_EVERY_COMPILES`` compiles, give the C allocator's free memory back (glibc): models and
    data of varying sizes freed among a busy process's other allocations leave holes that malloc keeps, so a
    SIMS env rebuilding its scene at every reset grew by 14-16 MB over 1,500 resets (6.6-7.8 MB with this,
    the rest being the process's own allocations; the trim costs well under a reset's time)."""
    global _compiles
    _compiles += 1
    if _compiles % TRIM_EVERY_COMPILES == 0 and (trim := _malloc_trim()) is not None:
        trim(0)


@functools.cache
def _keywords_of(config_type: type) -> frozenset[str]:
    names = frozenset(config_type.keyword_names())
    private = sorted(name for name in names if name.startswith("_"))
    if private:    # HumanoidEnv.__setattr__ sets private names without the keyword check
        raise TypeError(f"{config_type.__name__}'s keywords must be public names, not {private}")
    return names


def _config_keywords(config) -> frozenset[str]:
    """The keywords of an env's config (none before it has one)."""
    return frozenset() if config is None else _keywords_of(type(config))


def _same_value(a, b) -> bool:
    try:
        return bool(np.array_equal(a, b))
    except Exception:    # values numpy cannot compare as arrays
        return a is b or a == b


def _attribute(env: HumanoidEnv, path: str):
    """``env.a.b`` for the path "a.b"."""
    return _getter(path)(env)


@functools.cache
def _getter(path: str) -> operator.attrgetter:
    return operator.attrgetter(path)


def _set_attribute(env: HumanoidEnv, path: str, value) -> None:
    owner, _, name = path.rpartition(".")
    setattr(_attribute(env, owner) if owner else env, name, value)


def row_of(batch, k: int):
    """Row ``k`` of a batch (a NamedTuple of arrays, row i: world i: a state, a goal), as a batch of one
    (views)."""
    return type(batch)(*(field[k:k + 1] for field in batch))
