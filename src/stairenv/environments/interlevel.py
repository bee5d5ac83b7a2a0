"""InterLevel: a humanoid climbs a procedurally generated staircase to a target on the top floor."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium import spaces

from stairenv.environments.base import HumanoidEnv, StepOutcome, row_of
from stairenv.environments.config import KEYWORD_NAMES, InterLevelConfig, document_keywords, keyword_signature, resolve
from stairenv.environments.config import REWARDS  # noqa: F401 (importable from here, as before)
from stairenv.humanoid import NUM_DOFS, STANDING_ROOT_HEIGHT, load_humanoid_spec
from stairenv.humanoid.placement import PLACEMENT_CLEARANCE, place_state_in_frame
from stairenv.humanoid.state import PELVIS
from stairenv.motion import stair_starts
from stairenv.motion.tracking import ReferenceTrack, frames_in_world, track_of_frames
from stairenv.rotations import yaw_to_quat_wxyz
from stairenv.tasks import curriculum
from stairenv.tasks.stall import StallWatch
from stairenv.tasks.terms import TRACKING_TERMS, tracking_terms
from stairenv.tasks import interlevel as task
from stairenv.tasks import interscene
from stairenv.world.stairs import STAIRS_CONFIG_RANGES, Staircase, StairsConfig, StairsSlots, generate_stairs

# Columns of the step kernel's results (``task.STEP_RESULTS``) and of the end flags (``task.END_FLAGS``) that
# a step outcome reports.
_PROGRESS, _HEIGHT_PROGRESS, _DISTANCE_TO_TARGET = (task.STEP_RESULTS.index(name) for name in (
    "progress", "height_progress", "distance_to_target"))
_FELL, _SUCCESS, _STALLED, _ENDED = (task.END_FLAGS.index(name) for name in ("fell", "success", "stalled", "ended"))


def _named_results(results, flags) -> dict[str, Any]:
    """A step outcome's named results from the step kernel's results and the end flags, each indexed by
    column: one world's rows (lists) or the batch's columns (the arrays transposed)."""
    return {"progress": results[_PROGRESS], "height_progress": results[_HEIGHT_PROGRESS], "success": flags[_SUCCESS],
            "fell": flags[_FELL], "stalled": flags[_STALLED], "distance_to_target": results[_DISTANCE_TO_TARGET]}


#: the ranges of a given staircase's fields (``options={"stairs": ...}``): a drawn one's, but for the distance,
#: which may be 0 (a clip's staircase at the origin; its caller places the character)
STAIRCASE_RANGES = {name: STAIRS_CONFIG_RANGES[config_name] for name, config_name in (
    ("step_height", "step_height"), ("step_depth", "step_depth"), ("width", "step_width"),
    ("num_steps", "num_steps"), ("landing_depth", "landing_depth"))} | {
    "distance": (0.0, STAIRS_CONFIG_RANGES["distance"][1])}

# The follow camera looks along the ascent, turned 30 deg: character, stairs and M_T in view.
CAMERA_AZIMUTH_FROM_STAIRS = 30.0
# StairsConfig's valid ranges under the env's keyword names (its own errors say "distance", "yaw"),
# read from its fields' checks.
STAIRS_RANGES = {keyword: bounds for keyword, bounds in (
    (KEYWORD_NAMES.get(("stairs", name), name), bounds) for name, bounds in STAIRS_CONFIG_RANGES.items())
    if keyword in ("step_height", "step_depth", "step_width", "stairs_distance", "stairs_yaw")}


@document_keywords(InterLevelConfig)
class InterLevelEnv(HumanoidEnv):
    r"""Stair climbing with the InterLevel 3-D reward (Shilton et al., AAAI 2025).

    A 28-DoF humanoid starts near the arena centre; a staircase of random step
    height, depth, width, count and orientation faces the centre. The target M_T
    is on the top floor. Every reset draws a new staircase from the env's seed.

    **Action** (28,): in [-1, 1], mapped to PD targets ``offset + scale * a``
    (``stairenv.humanoid.pd_action_offset_scale``); MuJoCo clamps targets to that range.
    Wrong shapes, non-real dtypes (complex, strings, objects) and non-finite values raise ``ValueError``.

    **Observation** (118,): the paper's layout, see ``observation_structure``
    (root height, root rotation 6-D, root linear and angular velocity, 12 local
    joint rotations 6-D, 28 joint velocities, offset to M_T, |M_T - M_B|, angle
    between the heading and the ascent direction). Vectors are in the heading frame.

    **Reward** (``reward="interlevel"``), per policy step:

        r = w_location R_location + w_facing R_facing + w_velocity R_velocity
            + success_reward [on success] ;  r = failure_reward on a fall

    with R_location the ReLU-scaled 3-D threshold Gaussian (paper Eq. 2-4, see
    ``stairenv.tasks.interlevel``), R_facing = ReLU(F_tar . F_cur), R_velocity =
    exp(-2 ReLU(S_tar - S_cur)^2), S_cur the root speed towards M_T.
    ``progress_scaling=False`` is the InterLevel-2D ablation (Eq. 9).
    ``reward="interscene"`` replaces the task terms by the InterScene 2-D reward
    (0.7 near + 0.3 far, ``stairenv.tasks.interscene``). Each term is in ``info`` as
    ``reward_*``; the terms sum to the reward.

    **Keywords** are checked at construction, each with its type: ``TypeError`` for a wrong type
    (``progress_scaling="False"``, ``frame_skip="4"``), ``ValueError`` for a value out of its range or
    not integral (``frame_skip=2.5``); both name the keyword. ``reference_motion`` is checked (its
    files loaded) whatever ``init`` is. The keywords are the fields of ``InterLevelConfig``
    (``stairenv.environments.config``: defaults and ranges live there), and ``config=InterLevelConfig(...)``
    may be given instead (keywords beside it must agree with it); ``env.unwrapped.config`` is the
    resolved config. The training aids below are its ``training_aids`` group.

    **Episode end**: terminated on success (root within ``success_radius`` of M_T,
    standing on the top floor) or a fall (head or a foot within
    ``termination_height`` of the hips, vertically); truncated by the TimeLimit
    wrapper (600 steps = 20 s in the presets) or when the physics becomes unstable
    (``info["physics_unstable"] = True``; the last finite observation is returned).

    **Info**: ``reward_*``, ``progress`` (how far up the stairs the character is: the
    tread under its root as a fraction of the risers, 0 on the floor, 1 on the landing;
    the evaluation's progress), ``height_progress`` (the root's height progress 0-1
    between M_B and M_T, the factor of the location reward, clipped),
    ``success``, ``fell``, ``time`` (s), ``distance_to_target`` (m),
    ``physics_unstable``, ``stairs`` (the staircase's parameters), ``amp_obs`` (the
    last ``amp_history`` frames of style features, ``stairenv.style.features``).

    {keyword table}

    Reward defaults (the paper gives none): the location term is an unnormalised
    product of two normal densities whose peak is 1 / (2 pi s1 s3) = 0.16 with the
    default sigmas; w_location = 3 brings its peak to 0.48, so that location,
    velocity (0.4) and facing (0.1) weigh like InterScene's far reward (0.5/0.4/0.1)
    and a perfect step earns about 1. s1 = 2 m gives a gradient over a staircase
    of up to ~4 m; s2 = 0.5 m penalises overshooting M_T more sharply; s3 = 0.5 m is
    about half a stair width. S_tar = 1 m/s is a relaxed climbing pace (the paper's
    climbs take 8-13 s).

    Training aids (off by default, the paper's protocol; outcomes leave them off):

    - Staircase starts (``stairs_start_fraction``): in that share of the episodes the character
      starts in a frame of a climb synthesised for the episode's own staircase
      (``stairenv.motion.stair_starts``), anywhere from 0.6 m before the first riser to just onto
      the landing, feet on the treads the climb planned. The staircase of such an episode has its
      step height and depth rounded to 1 cm (the grid the climbs are cached on). The other
      episodes start as ``init`` says; ``info["stairs_start"]`` tells which.
    - Stall termination (``stall_seconds``): an episode whose distance to M_T has not come
      ``stall_distance`` below the distance of its last such approach (the first: its start) for
      ``stall_seconds`` is terminated (``info["stalled"] = True``, no reward of its own). Standing
      still then ends the stream of style reward as a fall does, so it no longer pays more than
      trying to climb.
    - Holding the target (``hold_target_reward``): success no longer ends the episode; every step with
      the root within ``success_radius`` of M_T is paid this reward instead of the one ``success_reward``.
      With the paper's end, standing just outside the radius keeps earning task and style reward, which
      is worth more than the bonus that ends the episode; the climber learns to stop short
      (``docs/interlevel_training.md``, "Arriving at M_T"). As InterScene's interaction early termination,
      holding the goal becomes the best thing to do.
    - Step-height curriculum (``step_height_levels``, ``stairenv.tasks.curriculum``): the
      ``step_height`` range is split into that many equal bands; the env holds a level
      (``curriculum_level``, first drawn from the easier half at the first reset) and draws its
      staircases' heights from that level's band. An episode that started on the floor moves the
      level up on success or at ``curriculum_promote_at`` progress (from the top level: to a random
      level) and down when it ended below ``curriculum_demote_below`` progress. The level carries
      over resets, seeded ones too: training state, like a normaliser's, that a trainer saves with
      its checkpoints (``baselines/train_ppo.py`` does).
    - Pushes (``push_speed``, ``push_interval``; every family's, ``HumanoidEnv._setup_pushes``): a kick
      of a speed drawn from ``push_speed`` (m/s) added to the root's horizontal velocity in a random
      direction every ``push_interval`` seconds (drawn), so that the policy learns to recover, as the
      evaluations' ``--push-speed`` tests it.
    - Clip tracking (``track_reward`` w, ``max_track_error``; with stair starts): a stair start follows its
      climb on from the start frame, placed as the start was (imitation first, for a step-over-step gait):
      the reward gains ``reward_track_root``, ``reward_track_velocity`` and ``reward_track_bodies``
      (``stairenv.tasks.terms.tracking_terms``, weight w; 0 on floor starts) and the episode ends
      (``info["track_lost"]``) once the bodies are on average ``max_track_error`` from the climb's.
    """

    def __init__(self, *, config: InterLevelConfig | None = None, **keywords) -> None:
        # the keywords (signature below: InterLevelConfig's fields) -> the one resolved, checked config
        self.config = config = resolve(InterLevelConfig, config, keywords)
        # attributes of the config's values, as before there was one (read by the kernel, the batched
        # env and the trainers)
        physics, render, rewards, aids = config.physics, config.render, config.reward, config.training_aids
        self.reward_name = rewards.kind
        self._term_names = task.REWARD_TERMS if rewards.kind == "interlevel" else interscene.REWARD_TERMS
        #: a step outcome's reward terms, in ``info`` and in the order they are summed
        self._outcome_terms = (*self._term_names, "reward_success", "reward_failure",
                               *(TRACKING_TERMS if aids.track_reward else ()))
        self.track_reward, self.max_track_error = aids.track_reward, aids.max_track_error
        self._tracking_on = bool(aids.track_reward) or aids.max_track_error is not None
        self._track: ReferenceTrack | None = None
        self._apply_config(config)
        self.stairs_config = config.stairs
        self.stairs_start_fraction = aids.stairs_start_fraction
        self._stairs_start = False
        self.step_height_levels = aids.step_height_levels
        #: this world's level of the step-height curriculum (None until the first reset draws it)
        self.curriculum_level: int | None = None
        # starts on the floor in front of the stairs: level-ground clips only (walks, not climbs)
        self._setup_family_aids(aids)

        spec = load_humanoid_spec(physics.pd_gains)
        self._slots = StairsSlots(spec, self.stairs_config.max_steps)
        self._setup(spec, physics.frame_skip, config.amp_history, render.render_mode, render.width, render.height)
        self._slots.bind(self.model)
        self._camera_distance, self._camera_elevation = 6.0, -20.0
        self.observation_space = spaces.Box(-np.inf, np.inf, shape=(task.OBSERVATION_SIZE,), dtype=np.float64)
        self.observation_structure = dict(task.OBSERVATION_STRUCTURE)
        self.stairs: Staircase | None = None
        # what a step carries to the next (ROW_ARRAYS), written in place from here on
        self._prev_root = np.zeros((1, 3))
        self._packed_goal = np.zeros((1, task.GOAL_SIZE))
        self._stall = StallWatch(self.stall_seconds, self.stall_distance, self.dt)

    # the keywords: InterLevelConfig's fields, defaults included (``config=`` stays out of the signature, which
    # lists the keywords)
    __init__.__signature__ = keyword_signature(InterLevelConfig)

    #: what a built env takes (``configure``, ``set_attr``): the reward's weights and bonuses, the episode's end,
    #: the start's spread and the training aids' stall and curriculum thresholds
    LIVE_KEYWORDS = frozenset((
        "w_location", "w_facing", "w_velocity", "sigma_before", "sigma_after", "sigma_across", "w_scale",
        "target_speed", "progress_scaling", "success_reward", "failure_reward", "success_radius",
        "terminate_on_success", "termination_height", "start_radius", "random_start_heading", "reset_noise_scale",
        "stall_seconds", "stall_distance", "hold_target_reward", "curriculum_demote_below", "curriculum_promote_at"))

    def _apply_config(self, config: InterLevelConfig) -> None:
        super()._apply_config(config)    # an attribute per live keyword, as the config has it
        object.__setattr__(self, "reward_config", config.reward.terms)
        object.__setattr__(self, "_reward_array", config.reward.terms.as_array())  # what the compiled step takes

    # --- episode ------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """New staircase and start pose. ``options={"stairs": Staircase}`` fixes the staircase;
        ``options={"episode_cut": True}`` says the episode in progress was cut short by the trainer (a
        checkpoint), not ended by the task: the step-height curriculum does not judge it."""
        return super().reset(seed=seed, options=options)

    @classmethod
    def _build_worlds(cls, envs: list[InterLevelEnv], options: Sequence[dict[str, Any] | None]) -> None:
        """Each world's staircase drawn with its own generator, then all written as one layout (this class's
        ``_build_world``: a single env's reset is a group of one)."""
        cls._set_stairs(envs, [env._draw_stairs(env.np_random, world_options)
                               for env, world_options in zip(envs, options)])

    def _draw_stairs(self, rng: np.random.Generator, options: dict[str, Any] | None) -> Staircase:
        """The episode's staircase (and whether it starts on the stairs)."""
        # options={"episode_cut": True}: the episode in progress was cut short (a trainer's checkpoint),
        # not ended by the task, so the curriculum does not judge it
        config = self._episode_stairs_config(rng, judge_last=not (options or {}).get("episode_cut", False))
        stairs = generate_stairs(config, rng)
        # drawn only when asked for, so that the default episodes' random stream is unchanged
        self._stairs_start = self.stairs_start_fraction > 0.0 and rng.uniform() < self.stairs_start_fraction
        if options and "stairs" in options:
            stairs = self._check_stairs_option(options["stairs"])
            self._stairs_start = False
        if self._stairs_start:
            stairs = dataclasses.replace(
                stairs, step_height=stair_starts.snap(stairs.step_height, *config.height_range),
                step_depth=stair_starts.snap(stairs.step_depth, *config.step_depth))
        return stairs

    def _episode_stairs_config(self, rng: np.random.Generator, judge_last: bool = True) -> StairsConfig:
        """``stairs_config``, its step heights narrowed to the curriculum level's band when there is a
        curriculum; the level first moved by the outcome of the episode that just ended (if it started on
        the floor and ``judge_last``)."""
        levels = self.step_height_levels
        if not levels:
            return self.stairs_config
        # the episode that just ended: its last step outcome, if it took a step (reset has not yet cleared them)
        last = getattr(self, "_outcome", None) if getattr(self, "_steps", 0) > 0 else None
        if self.curriculum_level is None:
            self.curriculum_level = curriculum.initial_level(levels, rng)
        elif last is not None and not self._stairs_start and judge_last:
            self.curriculum_level = curriculum.next_level(
                self.curriculum_level, levels, bool(last.results["success"]), last.results["progress"], rng,
                demote_below=self.curriculum_demote_below, promote_at=self.curriculum_promote_at)
        band = curriculum.level_band(self.curriculum_level, levels, *self.stairs_config.step_height)
        return dataclasses.replace(self.stairs_config, step_height=band)

    def _place_character(self, rng: np.random.Generator, options: dict[str, Any] | None) -> bool:
        """In a disc of ``start_radius`` around the centre; standing with joint noise or a reference state."""
        model, data = self.model, self.data
        self._track = None
        if self._stairs_start:
            stairs = self.stairs
            climb, qvel = stair_starts.climb_start(stairs.step_height, stairs.step_depth, stairs.num_steps, rng)
            place_state_in_frame(model, data, self._idx, climb[0], qvel, stairs.yaw, stairs.origin)
            if self._tracking_on:    # the training aid: the climb followed on from the start frame, placed alike
                frames = frames_in_world(climb, stairs.yaw, stairs.origin)
                frames[:, 2] += PLACEMENT_CLEARANCE
                self._track = track_of_frames(frames, self.dt)
            self._hold_pose_ctrl()
            self._reset_forward(model, data)
            return True
        radius = self.start_radius * math.sqrt(rng.uniform())
        angle = rng.uniform(0.0, 2.0 * math.pi)
        heading = rng.uniform(-math.pi, math.pi) if self.random_start_heading else self.stairs.yaw
        start_xy = (radius * math.cos(angle), radius * math.sin(angle))
        reference = self._reference_pose(rng)
        if reference is not None:
            self._place_at(start_xy, heading, reference)
            return True
        data.qpos[self._idx.qpos_root] = (*start_xy, STANDING_ROOT_HEIGHT, *yaw_to_quat_wxyz(heading))
        noise = rng.uniform(-self.reset_noise_scale, self.reset_noise_scale, NUM_DOFS)
        low, high = self._joint_limits
        data.qpos[self._idx.qpos_joints] = np.minimum(np.maximum(noise, low), high)    # np.clip's operations
        self._hold_pose_ctrl()
        self._reset_forward(model, data)
        return False

    def _start_tracking(self, state) -> None:
        self._start_tracking_batch([self], state)

    @classmethod
    def _start_tracking_worlds(cls, envs: list[InterLevelEnv], state) -> None:
        if cls._start_tracking is not InterLevelEnv._start_tracking:    # a subclass's override is called
            super()._start_tracking_worlds(envs, state)
            return
        cls._start_tracking_batch(envs, state)

    @classmethod
    def _start_tracking_batch(cls, envs: list[InterLevelEnv], state) -> None:
        """``_start_tracking`` of each of ``envs`` over the batch ``state`` (row k: world k's)."""
        for env, root in zip(envs, state.body_pos[:, PELVIS]):
            env._prev_root[...] = root
            stall = env._stall    # the env's settings as they are now, the clock from zero
            stall.seconds, stall.distance, stall.dt = env.stall_seconds, env.stall_distance, env.dt
            stall.restart()
            hold = env.hold_target_reward    # a training aid: success pays each step and does not end
            env._end_parameters = task.end_parameters(env.stall_distance, env.stall_seconds, env.dt,
                                                      env.success_reward if hold is None else hold,
                                                      env.failure_reward, env.terminate_on_success and hold is None)

    BATCH_OUTCOMES = True
    ROW_ARRAYS = ("_prev_root", "_packed_goal", "_stall.approach", "_stall.approach_at")

    def _step_outcome(self, state) -> StepOutcome:
        """``_step_outcomes`` of this world alone."""
        return self._step_outcomes([self], state)[0]

    @classmethod
    def _step_outcomes(cls, envs: list[InterLevelEnv], state) -> list[StepOutcome]:
        """``_outcome_arrays`` as one ``StepOutcome`` per world, its numbers as Python numbers."""
        obs, reward, terms, flags, results, lost = cls._outcome_arrays(envs, state)
        names = envs[0]._outcome_terms
        rewards, flag_rows, result_rows = reward.tolist(), flags.tolist(), results.tolist()
        outcomes = [StepOutcome(obs[k], rewards[k], dict(zip(names, world_terms)), flag_rows[k][_ENDED],
                                _named_results(result_rows[k], flag_rows[k]))
                    for k, world_terms in enumerate(terms.tolist())]
        if lost is not None and envs[0].max_track_error is not None:
            for outcome, world_lost in zip(outcomes, lost.tolist()):
                outcome.results["track_lost"] = world_lost
        return outcomes

    @classmethod
    def _step_outcome_batch(cls, envs: list[InterLevelEnv], state, rows: np.ndarray | None = None) -> StepOutcome:
        """``_outcome_arrays`` as one ``StepOutcome`` of arrays (each term and result a column over the
        worlds)."""
        obs, reward, terms, flags, results, lost = cls._outcome_arrays(envs, state, rows)
        named = _named_results(results.T, flags.T)
        if lost is not None and envs[0].max_track_error is not None:
            named["track_lost"] = lost
        return StepOutcome(obs, reward, dict(zip(envs[0]._outcome_terms, terms.T)), flags[:, _ENDED], named)

    @classmethod
    def _outcome_arrays(cls, envs: list[InterLevelEnv], state, rows: np.ndarray | None = None):
        """The step outcomes of ``envs`` (worlds of one configuration; row k of the batch ``state`` is world
        k) in two compiled calls: the observation and the task's results (``task.interlevel_outcome_columns``),
        then the reward and the episode's end with the stall clocks (``task.interlevel_reward_and_end``).
        Returns ``(obs, reward, terms, flags, results)``: the terms in ``_outcome_terms`` order, the flags
        ``task.END_FLAGS``, the results ``task.STEP_RESULTS``. What a world carries from step to step
        (``ROW_ARRAYS``) is read and written by ``rows`` where a batched env shares it
        (``HumanoidEnv._share_rows``)."""
        first = envs[0]
        carry = cls._take_carry(envs, rows)
        prev_root, packed = carry["_prev_root"], carry["_packed_goal"]
        goal = first._goal if len(envs) == 1 else task.StairsGoal.unpack(packed)
        obs, results = task.interlevel_outcome_columns(
            state, prev_root, packed, goal.rotation, first._reward_array, first.dt, first.termination_height,
            first.success_radius,
        )
        if first.reward_name == "interlevel":
            terms = results[:, :task.NUM_REWARD_TERMS]
        else:
            terms = interscene.interscene_reward_terms(state, prev_root, goal.target, first.dt)
        steps = (envs[0]._rows["_step_count"][rows] if rows is not None else
                 np.array([env._steps for env in envs], dtype=np.int64))
        reward, terms, flags = task.interlevel_reward_and_end(
            terms, results, steps, carry["_stall.approach"], carry["_stall.approach_at"], first._end_parameters)
        prev_root[...] = state.body_pos[:, PELVIS]
        cls._put_carry(envs, rows, carry)
        lost = None
        if first._tracking_on:    # the training aid: each stair start's climb tracked (zeros for the others)
            tracked, lost = np.zeros((len(envs), 3)), np.zeros(len(envs), dtype=bool)
            for k, env in enumerate(envs):
                track = env._track
                if track is not None:
                    i = track.frame(int(steps[k]))
                    root, velocity, bodies, error = tracking_terms(
                        state.body_pos[k], track.body_pos[i], state.root_lin_vel[k], track.root_vel[i],
                        env.track_reward, PELVIS)
                    tracked[k] = root, velocity, bodies
                    lost[k] = env.max_track_error is not None and error > env.max_track_error
            if first.track_reward:
                reward = reward + tracked.sum(axis=1)
                terms = np.concatenate((terms, tracked), axis=1)
            flags[:, _ENDED] |= lost
        return obs, reward, terms, flags, results, lost

    def _info(self, results: dict[str, Any]) -> dict[str, Any]:
        return {**results, **self._episode_info()}

    def _episode_info(self) -> dict[str, Any]:
        return {"stairs": dict(self._stairs_info), "stairs_start": self._stairs_start}

    def _unstable_results(self, last: StepOutcome) -> dict[str, Any]:
        return {"progress": last.results["progress"], "height_progress": 0.0, "success": False, "fell": False,
                "stalled": False,
                "distance_to_target": float(np.linalg.norm(last.obs[task.OBSERVATION_STRUCTURE["target_offset"]]))}

    # --- pieces -------------------------------------------------------------
    def climb_keys(self) -> list[tuple[int, int, int, str]]:
        """The grid staircases this env's stair starts can draw (``stair_starts.grid_keys``; none without
        stair starts): what ``stair_starts.fill_cache`` synthesises ahead of training."""
        if self.stairs_start_fraction <= 0.0:
            return []
        config = self.stairs_config
        return stair_starts.grid_keys(config.height_range, config.step_depth, config.num_steps)

    def _check_stairs_option(self, stairs: Any) -> Staircase:
        """A given staircase within ``STAIRCASE_RANGES``, else a ``ValueError`` naming the field (a zero height
        or depth would divide by zero in the progress, a negative width build inverted boxes)."""
        if not isinstance(stairs, Staircase):
            raise ValueError(f"options['stairs'] must be a Staircase, got {type(stairs).__name__}")
        if isinstance(stairs.num_steps, bool) or not isinstance(stairs.num_steps, (int, np.integer)):
            raise ValueError(f"options['stairs'].num_steps must be an integer, got {stairs.num_steps!r}")
        if stairs.num_steps > self.stairs_config.max_steps:
            raise ValueError(
                f"options['stairs'] has {stairs.num_steps} steps; this env holds at most "
                f"{self.stairs_config.max_steps} (the num_steps maximum)"
            )
        for name, (low, high) in STAIRCASE_RANGES.items():
            value = getattr(stairs, name)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.number)) or not low <= value <= high:
                raise ValueError(f"options['stairs'].{name} must be a number in [{low}, {high}], got {value!r}")
        if not math.isfinite(stairs.yaw):
            raise ValueError(f"options['stairs'].yaw must be finite, got {stairs.yaw!r}")
        return stairs

    @staticmethod
    def _set_stairs(envs: list[InterLevelEnv], stairs: list[Staircase]) -> None:
        """Write ``stairs[k]`` into world k's model and goal, the geometry of all of them as one layout."""
        layout = envs[0]._slots.layout(stairs)
        goals = task.StairsGoal.of_layout(layout)
        packed = goals.pack()
        for k, (env, world_stairs) in enumerate(zip(envs, stairs)):
            env.stairs = world_stairs
            env._slots.place_layout(env.model, layout, k)
            env._goal = goals if len(envs) == 1 else row_of(goals, k)
            env._packed_goal[...] = packed[k]
            env._stairs_info = world_stairs.as_dict()
            env._camera_azimuth = math.degrees(world_stairs.yaw) + CAMERA_AZIMUTH_FROM_STAIRS

    # --- rendering ----------------------------------------------------------
    def _render_lines(self) -> tuple:
        if self.stairs is None:
            return ()
        hips = self.data.xpos[self._idx.pelvis_id]
        return ((hips, self._goal.target[0], (0.1, 0.9, 0.2, 1.0)),)
