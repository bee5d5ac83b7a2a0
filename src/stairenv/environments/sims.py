"""SIMS interaction skills: walk, sit, lie, reach and get up with generated furniture."""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from functools import cache
from typing import Any

import mujoco
import numpy as np
from gymnasium import spaces

from stairenv.environments.base import DIVERGENCE_WARNING_ROWS, HumanoidEnv, StepOutcome
from stairenv.environments.config import document_keywords, keyword_signature, resolve

# the checks of SIMS' keywords are SIMSConfig's; named here too, as before
from stairenv.environments.sims_config import (  # noqa: F401
    CURRICULUM_SKILLS,
    GETUP_FROM,
    HASHING_DIMS,
    MAX_TEXT_DIM,
    NEAR_START_SKILLS,
    SCENES,
    SKILL_FAMILIES,
    TEXT_ENCODERS,
    SIMSConfig,
    check_captions,
    check_families,
    check_room_hosts,
    check_text_encoder,
    host_families,
)

# the env's jobs beside the template: the pose API the stories use, and the starts (named here too, as before)
from stairenv.environments.sims_pose import ScenePoseAPI, seated_joint_angles, surface_hi  # noqa: F401
from stairenv.environments.sims_starts import (  # noqa: F401
    CONTACT_NAMES,
    REACH_TURNS,
    START_PENETRATION,
    START_TRIES,
    SIMSStarts,
)
from stairenv.humanoid import load_humanoid_spec
from stairenv.humanoid.state import PELVIS
from stairenv.motion.rsi import standing_clips
from stairenv.motion.synthesis import WALK_STYLES
from stairenv.motion.tracking import ReferenceTrack
from stairenv.style.features import push_amp_features
from stairenv.tasks import curriculum
from stairenv.tasks import sims as task
from stairenv.tasks.kernels import PROPRIOCEPTION_SIZE, jit, no_warnings_within_limits
from stairenv.tasks.stall import StallWatch
from stairenv.tasks.terms import TRACKING_TERMS, tracking_terms
from stairenv.validation import check_choice
from stairenv.world.furniture import (
    LYING_FAMILIES,
    PlacedFurniture,
    add_furniture_to_spec,
    make_furniture,
)
from stairenv.world.rooms import Room, RoomConfig, add_room_to_spec, generate_room

GOAL_SIZE = 4 * task.NUM_CONTACT_JOINTS  # 15 target offsets (3) + 15 mask bits
_NEAR, _FAR, _STILL = task.WALK_REWARD_TERMS    # the reward terms' info keys (a contact goal's: the first two)
if task.CONTACT_REWARD_TERMS != (_NEAR, _FAR):
    raise ImportError("SIMSEnv._world_outcome expects the contact reward's terms to be the walk reward's first two")


@cache
def skill_captions(skill: str) -> tuple[tuple[str, str], ...]:
    """(style, caption) pairs of the shipped script database's keyframes of ``skill``."""
    from stairenv.screenplays import load_database

    pairs = {(kf.style, kf.caption) for script in load_database() for kf in script.keyframes if kf.skill == skill}
    return tuple(sorted(pairs))


def captions_for(captions: Sequence[tuple[str, str]], family: str | None) -> tuple[tuple[str, str], ...]:
    """The captions that name no furniture other than ``family`` (None: no furniture at all),
    so that "sits on the stool" is not drawn for a sofa; all of them if none is left."""
    from stairenv.screenplays.schema import FURNITURE

    target = None if family is None else family.replace("_", " ")
    words = {c: re.compile(rf"\b{c}s?\b") for c in FURNITURE}
    fitting = tuple((style, text) for style, text in captions
                    if all(c == target or (target is not None and c in target) or not w.search(text)
                           for c, w in words.items()))
    return fitting or tuple(captions)


def reference_captions(library, skill: str) -> tuple[tuple[str, str], ...]:
    """(style, text) pairs of a motion library's clips of ``skill`` (``meta["skill"]``; text by
    ``stairenv.style.reference.clip_text``): the captions to train a text-conditioned
    discriminator with, so the env's conditions are the reference's."""
    from stairenv.style.reference import clip_text

    check_choice("skill", skill, task.SKILLS)
    pairs = {(str(clip.meta.get("style", "neutral")), clip_text(clip))
             for clip in library.clips if clip.meta.get("skill") == skill}
    if not pairs:
        raise ValueError(f"the motion library has no clip with meta['skill'] == {skill!r}")
    return tuple(sorted(pairs))



# The task (stairenv.tasks.sims) and the style features (stairenv.style.features) of one world's step in one
# compiled call: here, where the env brings its layers together (a task does not import the style).
@jit
def skill_step_and_style(step_count, warnings, warning_rows, speeds, speed_limits, body_pos, body_mat, root_lin_vel,
                         root_ang_vel, dof_pos, dof_vel, params, points, owner, heights, text, prev_root_vel, obs,
                         targets, values, frames, amp_obs):
    """A single world's step after its physics in one compiled call: the step counted (``step_count[0]``);
    the divergence and speed checks (``stairenv.tasks.kernels.no_warnings_within_limits`` of MuJoCo's
    ``warnings`` at ``warning_rows`` and the ``speeds``); if they pass, ``task.skill_step`` of the world (its state
    arrays a batch of one; ``obs`` (size,), ``targets`` (15, 3), ``values`` (STEP_VALUES_SIZE,) its own), its
    root's ground velocity kept in ``prev_root_vel`` (in place) for the next step and its style features pushed
    onto the history ``frames`` (K, 105) with their ``flat()`` in ``amp_obs``
    (``stairenv.style.features.push_amp_features``). Returns whether the checks passed and, if so, the
    ``STEP_VALUES`` that the env reads (the reward terms, the error, the root's position, the head's height)."""
    step_count[0] += 1
    if not no_warnings_within_limits(warnings, warning_rows, speeds, speed_limits):
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    task.skill_step(0, body_pos, body_mat, root_lin_vel, root_ang_vel, dof_vel, params, points, owner, heights, text,
               prev_root_vel, obs.reshape((1, obs.shape[0])), targets.reshape((1, task.NUM_CONTACT_JOINTS, 3)),
               values.reshape((1, task.STEP_VALUES_SIZE)))
    prev_root_vel[0], prev_root_vel[1] = values[4], values[5]
    push_amp_features(0, frames, body_pos, body_mat, root_lin_vel, root_ang_vel, dof_pos, dof_vel, amp_obs)
    return True, values[0], values[1], values[2], values[3], values[6], values[7], values[8], values[9]


@document_keywords(SIMSConfig)
class SIMSEnv(SIMSStarts, ScenePoseAPI, HumanoidEnv):
    r"""A SIMS interaction skill (Sec. 3.3 and supplement): walk, sit, lie, reach or get up.

    Every reset places the character in a scene (``scene="object"``: one generated piece of
    furniture of the skill's families, as SIMS trains its skills; ``"room"``: a generated
    furnished room; or a fixed ``room``), picks the furniture to interact with, a contact
    goal (``stairenv.tasks.sims.contact_goal``), a caption of the skill from the shipped
    script database and its text embedding z. The scene is rebuilt (a new MuJoCo model)
    every ``scene_resample_every`` resets; in between the character's start and the goal change.

    **Observation** (113 + heightmap_size^2 + 60 + text_dim): proprioception as in
    InterLevel (root height above the floor), an egocentric heightmap of the surrounding
    objects (``heightmap_size``^2 samples over ``heightmap_extent`` m turned with the root's
    heading: the highest surface minus the root height; SIMS' pre-generated object heights),
    the contact goal (for each of the 15 bodies its target g_j minus the root, heading frame,
    zeros where masked out; then the 15-bit mask) and z (zeros when ``text_conditioned`` is
    False: SIMS does not condition reach and get up on text). ``observation_structure`` names the slices.

    **Reward** (supplement Eq. 7-13, ``stairenv.tasks.sims``): walk
    r = 0.4 near + 0.5 far (|x* - x|^2 > 0.5 m^2) or 0.4 near + 0.5 + 0.1 still;
    sit, lie, reach and get up: r = 0.6 near + 0.4 far or 0.6 near + 0.4, with
    near = exp(-10 sum_j m_j |g_j - x_j|^2). Terms in ``info`` as ``reward_near``,
    ``reward_far`` (and ``reward_still``) sum to the reward. The style reward comes from the
    AMP wrapper: ``info["amp_obs"]`` and, for a text-conditioned discriminator, ``info["amp_condition"]`` (z).

    **Episode**: success when the primary contact (the pelvis; the hand for reach) is within
    20 cm (sit, reach, walk on the ground, get up) or 30 cm (lie) of its target (``info["success"]``,
    ``info["success_once"]``, ``info["contact_error"]``); terminated when the head falls below
    ``fall_height`` (or on success with ``terminate_on_success``); truncated by the TimeLimit or on
    diverging physics (``info["physics_unstable"]``). Get up starts seated or lying on the piece.

    **Keywords** are checked at construction (``TypeError`` for a wrong type, ``ValueError`` for a bad
    value, both naming the keyword), among them ``text_encoder`` / ``text_dim`` (a size the encoder
    gives), ``captions`` and ``families``: every family must be able to host the skill (a fixed ``room``
    must hold one such piece), so ``reset`` always finds a target. They are the fields of ``SIMSConfig``
    (``stairenv.environments.sims_config``: defaults, ranges and the checks of keywords together live
    there; groups ``task``, ``scene``, ``text``, ``observation``, ``termination``, ``training_aids`` and
    the shared ``physics``, ``render``); ``config=SIMSConfig(...)`` may be given instead (keywords beside
    it must agree with it), and ``env.unwrapped.config`` is the resolved config.

    {keyword table}

    Training aids (off by default; evaluations leave them off, ``baselines/train_ppo.py``'s
    ``TRAINING_AIDS``):

    - Interaction starts (``interaction_start_fraction``, sit, lie and reach): in that share of the
      episodes the character starts in a frame of the skill's clip synthesised for the episode's
      piece (``stairenv.motion.interaction_starts``), with the clip's velocities, drawn uniformly in
      time: sit, standing right in front of the seat with the back to it, sitting down, seated (the
      clip's seat edge on the piece's front edge, its seat height the piece's); lie, that on the edge
      of the bed or sofa and then lying down on it, the head ending on the pillow; reach, standing
      0.45-0.75 m from the goal's target (drawn first; facing it from the piece's outside, else turned
      round it), reaching to it and holding it there. A frame
      that would press more than ``START_PENETRATION`` into the furniture or the floor is redrawn
      (``START_TRIES`` frames, then the episode starts as the others do); ``info["interaction_start"]``
      (present only with the aid) tells which.
    - Start-distance curriculum (``start_distance_levels`` N, object scenes): each world holds a level
      (``curriculum_level``, 0 at its first reset); level k draws the start distance from the first
      (k + 1) / N of the ``start_distance`` range (walk: the goal's distance from the first part of
      ``walk_distance``, its start placed as without the aid; the top level: all of it). An episode that
      started
      standing moves its world up a level when it succeeded (``success_once``), down one when it ended
      without success having closed less than half the distance (on the ground) between its start and
      the goal's root target; episodes cut by the trainer (``reset(options={"episode_cut": True})``)
      and interaction starts are not judged. The level carries over resets, seeded ones too: training
      state that the trainers log (``curriculum/level``) and save with their checkpoints.
    - Start-from-front curriculum (``start_from_front``; sit, lie, with ``start_distance_levels``): a
      standing start at level k of N also has its bearing, from the spot where an interaction start
      stands (the seat's front edge), within +-180 deg x (k + 1) / N of the direction out of the front, and
      its heading within as much of facing away from the piece: level 0 starts a step in front of the
      seat with the back to it, the top level anywhere around that spot facing anywhere.
    - Stall termination (``stall_seconds``, ``stairenv.tasks.stall``), as InterLevel's: an episode whose
      contact error (``info["contact_error"]``; walk: the root's distance to its target) has not come
      ``stall_distance`` below that of its last such approach (the first: its start) for
      ``stall_seconds`` ends (terminated, ``info["stalled"] = True``, present only with the aid), unless
      it is succeeding at that step. Standing still then no longer pays for the whole episode.
    - Grounded termination (``min_root_height``; every skill but getup): an episode ends (terminated,
      ``info["grounded"] = True``, present only with the aid) when the pelvis is less than
      ``min_root_height`` above the floor, i.e. the character sits or lies on the floor. Seated or lying
      on a piece the pelvis is higher (seats and beds are 0.25 m high at least: keep the threshold below
      that). Sitting down on the spot then no longer earns the style reward of a sit.
    - Style conditions (``condition_captions``, text-conditioned): ``info["amp_condition"]`` is the
      embedding of one text per style (the reference clips' texts) instead of the drawn caption's, while
      the observation keeps the caption's. A policy then trains on every caption of a style (the
      evaluation draws from them all) against a discriminator conditioned as its reference clips are.
    - Near zone (``near_distance`` d): the reward counts as near (far term 1, the walk's still term on)
      within d of x* on the ground instead of the paper's sqrt(0.5) = 0.71 m. Inside 0.71 m the paper's walk
      reward grows only through 0.4 exp(-10 |x* - x|^2), which is nearly flat from 0.45 to 0.71 m (the
      shipped walker stopped there); with d at the success radius the far term's speed and facing terms
      keep paying the approach until the goal is reached.
    - Clip tracking (``track_reward`` w, ``max_track_error``; with interaction starts): an interaction start
      follows its clip on from the start frame, placed as the start was (``motion.tracking.track_of_frames``):
      the reward gains DeepMimic's ``reward_track_root``, ``reward_track_velocity`` and
      ``reward_track_bodies`` (``stairenv.tasks.terms.tracking_terms``, weight w; 0 on other starts) and the
      episode ends (``info["track_lost"]``) once the bodies are on average ``max_track_error`` from the
      clip's: imitation first, the contact goal's reward beside it (issue #55's sit, lie and reach).
    - Interaction early termination (``hold_seconds`` h; InterScene's): once the contact goal has been held
      (``info["success"]`` at the end of h x 30 steps in a row), the episode is cut (truncated,
      ``info["held"] = True``, present only with the aid), so the trainer bootstraps the value of holding on
      and the samples go to new starts, while holding stays the best thing to do.
    - Pushes (``push_speed``, ``push_interval``; every family's, ``HumanoidEnv._setup_pushes``): a kick
      of a speed drawn from ``push_speed`` (m/s) added to the root's horizontal velocity in a random
      direction every ``push_interval`` seconds (drawn), so that the policy learns to recover, as the
      evaluations' ``--push-speed`` tests it.
    """

    DEFAULT_REFERENCE_MOTION = "builtin:sims"
    #: Standing starts only: the walk and idle clips (a seated frame would start in mid-air).
    start_clips = staticmethod(standing_clips)

    #: what a built env takes (``configure``, ``set_attr``): the episode's end bounds
    LIVE_KEYWORDS = frozenset(("fall_height", "terminate_on_success", "stall_distance"))
    STATE_ATTRIBUTES = frozenset(("room",))    # the episode's room (the keyword: a fixed room to use)

    def __init__(self, *, config: SIMSConfig | None = None, **keywords) -> None:
        # the keywords (signature below: SIMSConfig's fields) -> the one resolved, checked config
        self.config = config = resolve(SIMSConfig, config, keywords)
        goal, scene, text, aids = config.task, config.scene, config.text, config.training_aids
        self.skill, self.scene, self.getup_from = goal.skill, scene.kind, goal.getup_from
        self.fixed_room = scene.room
        self.families = config.families
        self.scene_resample_every = scene.scene_resample_every
        self.details = goal.details
        self.text_conditioned = text.text_conditioned
        self.text_dim = text.text_dim
        self._encoder_spec = text.text_encoder
        self._encoder = None
        self.captions = skill_captions(self.skill) if text.captions is None else text.captions
        self.condition_texts = None if aids.condition_captions is None else dict(aids.condition_captions)
        if self.condition_texts is not None:
            missing = sorted({style for style, _ in self.captions} - set(self.condition_texts))
            if missing:
                raise ValueError(f"condition_captions has no text for the captions' style(s) {missing}")
        self._condition_z: dict[str, np.ndarray] = {}
        self.start_distance, self.walk_distance = goal.start_distance, goal.walk_distance
        self.target_speed, self.speed_from_style = goal.target_speed, goal.speed_from_style
        observation, termination = config.observation, config.termination
        self.heightmap_size, self.heightmap_extent = observation.heightmap_size, observation.heightmap_extent
        self.fall_height, self.terminate_on_success = termination.fall_height, termination.terminate_on_success
        self._setup_family_aids(aids)
        self.interaction_start_fraction = aids.interaction_start_fraction
        self.start_distance_levels = aids.start_distance_levels
        self.start_from_front = aids.start_from_front
        #: this world's level of the start-distance curriculum (None until the first reset draws it)
        self.curriculum_level: int | None = None
        self.stall_seconds, self.stall_distance = aids.stall_seconds, aids.stall_distance
        self.hold_seconds = aids.hold_seconds
        self.min_root_height = aids.min_root_height
        self.track_reward, self.max_track_error = aids.track_reward, aids.max_track_error
        self._tracking_on = bool(self.track_reward) or self.max_track_error is not None
        self._track: ReferenceTrack | None = None
        #: the reward's near-zone bound |x* - x|^2 (m^2): the paper's, or the ``near_distance`` aid's
        self._near_squared_distance = (task.NEAR_SQUARED_DISTANCE if aids.near_distance is None
                                       else aids.near_distance ** 2)
        self._interaction_start = False
        self._start_goal: task.ContactGoal | None = None
        self._root_distance = self._start_root_distance = 0.0
        self._pd_gains = config.physics.pd_gains
        render = config.render
        self._init_humanoid(config.physics.frame_skip, config.amp_history, render.render_mode, render.width,
                            render.height)
        self._resets = 0
        self._caption_pools: dict[str | None, tuple[tuple[str, str], ...]] = {}
        self.furniture: dict[str, PlacedFurniture] = {}
        self.room: Room | None = None

        # A first scene (any rng: reset rebuilds it with the episode's rng) gives the spaces.
        self._build_scene(np.random.default_rng(0))
        hm = self.heightmap_size ** 2
        size = PROPRIOCEPTION_SIZE + hm + GOAL_SIZE + self.text_dim
        self.observation_space = spaces.Box(-np.inf, np.inf, shape=(size,), dtype=np.float64)
        g0 = PROPRIOCEPTION_SIZE + hm
        self.observation_structure = {
            "proprioception": slice(0, PROPRIOCEPTION_SIZE),
            "heightmap": slice(PROPRIOCEPTION_SIZE, g0),
            "goal_positions": slice(g0, g0 + 3 * task.NUM_CONTACT_JOINTS),
            "goal_mask": slice(g0 + 3 * task.NUM_CONTACT_JOINTS, g0 + GOAL_SIZE),
            "text": slice(g0 + GOAL_SIZE, size),
        }
        self.goal: task.ContactGoal | None = None
        self._targets: np.ndarray | None = None
        #: what a single world's step writes (``_finish_step``): the observation, the goal's targets and
        #: ``task.STEP_VALUES``
        self._step_buffers = (np.empty(size), np.empty((task.NUM_CONTACT_JOINTS, 3)), np.empty(task.STEP_VALUES_SIZE))
        #: no training aid adds to a step's results or info (those keywords are fixed once the env is built)
        self._plain_outcomes = (self.stall_seconds is None and self.min_root_height is None
                                and self.hold_seconds is None and not self.interaction_start_fraction > 0.0
                                and not self._tracking_on)

    # the keywords: SIMSConfig's fields, defaults included (``config=`` stays out of the signature)
    __init__.__signature__ = keyword_signature(SIMSConfig)

    # --- scene --------------------------------------------------------------------------------
    def _build_scene(self, rng: np.random.Generator) -> None:
        """Generate furniture (or a room) and compile the model with it."""
        if getattr(self, "_camera", None) is not None:
            self._camera.close()
        spec = load_humanoid_spec(self._pd_gains)
        if self.fixed_room is not None or self.scene == "room":
            room = self.fixed_room if self.fixed_room is not None else self._random_room(rng)
            add_room_to_spec(spec, room)
            self.room = room
            placed = list(room.furniture)
            walls = room.walls
            # the interior and the walls around it (which stand outside the interior's bounds): a character
            # near a wall sees it
            corners = np.concatenate([np.reshape(room.bounds, (2, 2)), *(w.corners_xy() for w in walls)])
            bounds = (*corners.min(axis=0), *corners.max(axis=0))
            self._heights = task.SceneHeights.build(placed, walls, bounds=bounds)
            free = room.free_space()
            ii, jj = np.nonzero(free.free)
            self._free_xy = np.column_stack((free.origin[0] + (jj + 0.5) * free.cell_size,
                                             free.origin[1] + (ii + 0.5) * free.cell_size))
            self._free_cell = float(free.cell_size)
        else:
            family = self.families[int(rng.integers(0, len(self.families)))]
            piece = PlacedFurniture(family, make_furniture(family, rng), (0.0, 0.0, float(rng.uniform(-math.pi, math.pi))))
            add_furniture_to_spec(spec, piece.furniture, piece.pose, piece.name)
            self.room = None
            placed = [piece]
            self._heights = task.SceneHeights.build(placed, margin=self.heightmap_extent + max(self.start_distance[1], 1.0))
            self._free_xy = None
        self.furniture = {p.name: p for p in placed}
        self._compile(spec)
        if self.room is not None:  # look down over the walls
            self._camera_distance, self._camera_elevation = 5.0, -65.0
        self._humanoid_geom_mask = np.zeros(self.model.ngeom, dtype=bool)
        self._humanoid_geom_mask[self._geoms] = True

    def _random_room(self, rng: np.random.Generator) -> Room:
        config = RoomConfig()
        for _ in range(10):
            room = generate_room(config, rng)
            if self.skill == "walk" or any(p.family in self.families for p in room.furniture):
                return room
        return generate_room(config, rng, categories=[self.families[int(rng.integers(0, len(self.families)))]])

    def _caption_pool(self, family: str | None) -> tuple[tuple[str, str], ...]:
        if family not in self._caption_pools:
            self._caption_pools[family] = captions_for(self.captions, family)
        return self._caption_pools[family]

    def _candidates(self, skill: str) -> list[PlacedFurniture]:
        families = set(self.families) & set(host_families(skill, self.getup_from))
        return [p for p in self.furniture.values() if p.family in families]

    # --- episode ------------------------------------------------------------------------------
    def _build_world(self, rng: np.random.Generator, options: dict[str, Any] | None) -> None:
        """The scene (a fixed room is built once; generated scenes change every ``scene_resample_every``
        resets and on a seed) and the piece of furniture to use."""
        if self.start_distance_levels:
            # options={"episode_cut": True}: the episode in progress was cut short (a trainer's checkpoint)
            self._judge_start_distance(judge_last=not (options or {}).get("episode_cut", False))
        if self._seeded_reset:  # the resample count restarts: a seeded reset fixes every episode after it
            self._resets = 0
        if self.fixed_room is None and (self._seeded_reset or self._resets % self.scene_resample_every == 0):
            self._build_scene(rng)
        self._resets += 1
        candidates = self._candidates(self.skill)
        target = candidates[int(rng.integers(0, len(candidates)))] if candidates else None
        if self.skill != "walk" and target is None:
            raise RuntimeError(f"the scene has no furniture to {self.skill} on among {sorted(self.furniture)}")
        self._target = target
        # drawn only when asked for, so that the default episodes' random stream is unchanged
        self._interaction_start = (self.interaction_start_fraction > 0.0
                                   and rng.uniform() < self.interaction_start_fraction)
        self._start_goal = None

    def _judge_start_distance(self, judge_last: bool) -> None:
        """The start-distance curriculum's level: 0 at the first reset, then moved by the outcome of the
        episode that just ended if it started standing, took a step and ``judge_last``."""
        if self.curriculum_level is None:
            self.curriculum_level = 0
            return
        if not judge_last or self._interaction_start or getattr(self, "_steps", 0) == 0 or self.goal is None:
            return
        progress = 1.0 - self._root_distance / max(self._start_root_distance, 1e-6)
        self.curriculum_level = curriculum.next_growing_level(self.curriculum_level, self.start_distance_levels,
                                                              bool(self._success_once), progress)

    def episode_start_distance(self) -> tuple[float, float]:
        """The start distance range (m) of this world's episodes: ``start_distance``, or with
        ``start_distance_levels`` its curriculum level's part of it."""
        if not self.start_distance_levels or self.curriculum_level is None or self.skill == "walk":
            return self.start_distance
        return curriculum.growing_range(self.curriculum_level, self.start_distance_levels, *self.start_distance)

    def episode_walk_distance(self) -> tuple[float, float]:
        """The walk goal's distance range (m): ``walk_distance``, or with ``start_distance_levels`` its
        curriculum level's part of it."""
        if not self.start_distance_levels or self.curriculum_level is None:
            return self.walk_distance
        return curriculum.growing_range(self.curriculum_level, self.start_distance_levels, *self.walk_distance)

    def _place_character(self, rng: np.random.Generator, options: dict[str, Any] | None) -> bool:
        """Get up: seated or lying on the piece; otherwise standing (or in a reference state) on the floor."""
        target = self._target
        self._track = None
        if self.skill == "getup":
            pose = self.getup_from
            if pose == "any":
                pose = "lie" if target.family in LYING_FAMILIES and rng.uniform() < 0.5 else "sit"
            self.place_on(target, pose)
            return False
        if self._interaction_start:
            if self._place_interaction_start(rng, target):
                return True
            # no frame fits this piece: a start as the others, from the state reset left (the frames
            # tried wrote joint angles and velocities)
            self._interaction_start = False
            mujoco.mj_resetData(self.model, self.data)
        if self.start_from_front:
            self._start, heading = self._front_start(rng, target)
        else:
            self._start = self._random_start(rng, target, self.episode_start_distance())
            heading = float(rng.uniform(-math.pi, math.pi))
        reference = self._reference_pose(rng)
        self._place_at(self._start, heading, reference, 0.0)
        return reference is not None

    def _new_goal(self, rng: np.random.Generator, options: dict[str, Any] | None) -> None:
        """The contact goal, a caption of the skill and the target speed."""
        target = self._target
        if self.skill == "getup":
            goal = task.contact_goal("getup", target, rng, details=self.details, stand_at=self.free_floor_point)
        elif self._start_goal is not None:  # drawn before the character was placed (a reach start)
            goal = self._start_goal
        else:
            walk_target = self.random_walk_target(rng, self._start) if self.skill == "walk" else None
            goal = task.contact_goal(self.skill, target, rng, walk_target=walk_target, details=self.details)
        pool = self._caption_pool(None if target is None or self.skill == "walk" else target.family)
        style, caption = pool[int(rng.integers(0, len(pool)))]
        self._set_goal(goal, caption, style, float(rng.uniform(*self.speed_range(style))))

    def set_task(self, skill: str, furniture: str | None = None, *, part: str | None = None,
                 hand: str | None = None, caption: str | None = None, style: str = "neutral",
                 walk_target: Sequence[float] | None = None, target_speed: float | None = None,
                 rng: np.random.Generator | None = None):
        """Switch to a new goal without touching the physics (the state machine's transition).

        ``furniture``: an instance name of ``self.furniture``; ``walk_target`` (x, y) for walk
        (default: in front of ``furniture``). Returns ``(obs, info)`` like ``reset``.
        """
        if self._needs_reset:
            raise RuntimeError("call reset() before set_task()")
        check_choice("skill", skill, task.SKILLS)
        rng = self.np_random if rng is None else rng
        placed = None
        if furniture is not None:
            if furniture not in self.furniture:
                raise KeyError(f"no furniture named {furniture!r}; the scene has {sorted(self.furniture)}")
            placed = self.furniture[furniture]
        if skill == "walk" and walk_target is None:
            if placed is None:
                raise ValueError("a walk needs walk_target or furniture")
            walk_target = self.approach_point(placed)
        goal = task.contact_goal(skill, placed, rng, part=part, hand=hand, walk_target=walk_target,
                                 details=self.details, stand_at=self.free_floor_point)
        # self.skill stays the episode skill that reset() draws; the goal carries the current one
        speed = float(np.mean(self.speed_range(style))) if target_speed is None else float(target_speed)
        self._set_goal(goal, caption if caption is not None else skill, style, speed)
        return self._begin_episode()

    def speed_range(self, style: str) -> tuple[float, float]:
        """The target speeds (m/s) an episode in ``style`` draws from: +-20% around the style's
        walking speed with ``speed_from_style`` (the styles of ``synthesis.WALK_STYLES`` but
        neutral), else ``target_speed``."""
        if self.speed_from_style and style in WALK_STYLES and style != "neutral":
            speed = WALK_STYLES[style].speed
            return (0.8 * speed, 1.2 * speed)
        return self.target_speed


    def _set_goal(self, goal: task.ContactGoal, caption: str, style: str, speed: float) -> None:
        self.goal = goal
        self.caption, self.style = caption, style
        self._z = self.embed_text(f"{caption}") if self.text_conditioned else np.zeros(self.text_dim)
        self._amp_z = self._z
        if self.condition_texts is not None and style in self.condition_texts:
            if style not in self._condition_z:
                self._condition_z[style] = self.embed_text(self.condition_texts[style])
            self._amp_z = self._condition_z[style]
        self._target_speed = speed
        #: the goal's, the scene's and the speed's constants of the compiled step (``task.skill_step``)
        self._step_parameters = task.step_parameters(goal, self._heights, speed, self.heightmap_size,
                                                     self.heightmap_extent, self._near_squared_distance)
        self._root_target_xy = (float(goal.root_target[0]), float(goal.root_target[1]))
        self._amp_condition = self._amp_z.astype(np.float32)    # info["amp_condition"]: a copy each step

    def _start_tracking(self, state) -> None:
        self._success_once = False
        self._prev_root_vel = state.root_lin_vel[0, :2].copy()
        root, target = state.body_pos[0, PELVIS], self.goal.root_target
        self._start_root_distance = self._root_distance = math.hypot(target[0] - root[0], target[1] - root[1])
        self._stall = StallWatch(self.stall_seconds, self.stall_distance, self.dt)
        self._held_steps = 0

    def embed_text(self, text: str) -> np.ndarray:
        """The env's text embedding (``text_encoder`` reduced to ``text_dim``) of ``text``; use it for
        the reference clips' conditions of a text-conditioned discriminator."""
        return np.asarray(self._text_encoder().encode([text])[0], dtype=np.float64)

    @property
    def text_encoder_id(self) -> str:
        """The ``model_id`` of the encoder the observation's text embedding comes from (a policy trained
        with one encoder reads another's embeddings as noise: ``stairenv.pretrained.load`` compares them)."""
        return str(self._text_encoder().model_id)

    def _text_encoder(self):
        if self._encoder is None:
            if isinstance(self._encoder_spec, str):
                from stairenv.screenplays.embeddings import get_encoder

                self._encoder = get_encoder(self._encoder_spec, dim=self.text_dim)
            else:
                self._encoder = self._encoder_spec
            if self._encoder.dim != self.text_dim:
                raise ValueError(f"text_encoder gives {self._encoder.dim}-d vectors, text_dim is {self.text_dim}")
        return self._encoder






    # --- observation and reward ---------------------------------------------------------------
    BATCH_OUTCOMES = True

    def _step_outcome(self, state) -> StepOutcome:
        """``_step_outcomes`` of this world alone."""
        return self._step_outcomes([self], state)[0]

    @classmethod
    def _step_outcomes(cls, envs: list[SIMSEnv], state) -> list[StepOutcome]:
        """The step outcomes of ``envs`` (worlds of one configuration; row k of the batch ``state`` is world
        k): each world's observation, goal targets, reward terms and error in one compiled call
        (``task.skill_step``, with the bits of ``stairenv.tasks.sims``' batch functions), then per world the
        ends and the bookkeeping in Python floats (``_world_outcome``), so a world's outcome has the same bits
        alone or in any batch."""
        n = len(envs)
        obs = np.empty((n, envs[0].observation_space.shape[0]))
        targets = np.empty((n, task.NUM_CONTACT_JOINTS, 3))
        values = np.empty((n, task.STEP_VALUES_SIZE))
        body_pos, body_mat, root_lin_vel, root_ang_vel, dof_vel = (state.body_pos, state.body_mat, state.root_lin_vel,
                                                                    state.root_ang_vel, state.dof_vel)
        for k, env in enumerate(envs):
            goal = env.goal
            task.skill_step(k, body_pos, body_mat, root_lin_vel, root_ang_vel, dof_vel, env._step_parameters,
                            goal._flat, goal._owner, env._heights.heights, env._z, env._prev_root_vel, obs, targets,
                            values)
        outcomes = []
        for k, (env, row) in enumerate(zip(envs, values.tolist())):
            env._prev_root_vel = values[k, 4:6]
            near, far, still, error, _, _, x, y, z, head_z = row
            outcomes.append(env._world_outcome(obs[k], targets[k], near, far, still, error, x, y, z, head_z,
                                               body_pos[k], root_lin_vel[k]))
        return outcomes

    def _finish_step(self):
        """``HumanoidEnv._finish_step`` of a single world written out for SIMS, the same results in fewer Python
        steps (what a step costs over its physics: ``benchmarks/bench_sims_step.py``): the time check, the
        poses brought up to qpos, then one compiled call (``task.skill_step_and_style``) counts the step, runs
        ``_physics_sound``'s other checks (``_state_sound``) and, where they pass, the task and the style
        features, into this world's own arrays (``_step_buffers``; a step returns a copy of the observation, an
        unstable step keeps one). Then the outcome and the info: ``_world_outcome`` and ``_full_info``, written
        out here where no training aid adds to them (``_plain_outcomes``). (The poses come up before the
        checks, as a batched env brings them up: an unsound step reads none of them.)"""
        data = self.data
        if data.time < self._expected_time - 1e-9:    # MuJoCo reset the data (_physics_sound)
            self._step_count[0] += 1
            self._mark_unstable()
            return self._unstable_step()
        mujoco.mj_kinematics(self.model, data)    # _bring_up_poses
        state = self._read_state()
        obs, targets, values = self._step_buffers
        goal, frames, count = self.goal, self._amp.frames, self._step_count
        amp_obs = np.empty(frames.size)
        sound, near, far, still, error, x, y, z, head_z = skill_step_and_style(
            count, self._warning_counts, DIVERGENCE_WARNING_ROWS, self._speeds, self._speed_limits,
            state.body_pos, state.body_mat, state.root_lin_vel, state.root_ang_vel, state.dof_pos, state.dof_vel,
            self._step_parameters, goal._flat, goal._owner, self._heights.heights, self._z, self._prev_root_vel, obs,
            targets, values, frames, amp_obs)
        if not sound:
            self._mark_unstable()
            return self._unstable_step()
        attributes = self.__dict__    # private attributes, set directly (HumanoidEnv.__setattr__ checks keywords)
        if not self._plain_outcomes:
            outcome = attributes["_last_outcome"] = self._world_outcome(obs, targets, near, far, still, error, x, y,
                                                                        z, head_z, state.body_pos[0],
                                                                        state.root_lin_vel[0])
            info = self._full_info(outcome, unstable=False, terms=True, amp_obs=amp_obs)
        else:    # _world_outcome and _full_info without the aids (tests/test_sims_skills.py compares them)
            skill = goal.skill
            success = error < task.SUCCESS_DISTANCE[skill]
            fell = head_z < self.fall_height
            target_x, target_y = self._root_target_xy
            attributes["_root_distance"] = math.hypot(target_x - x, target_y - y)
            attributes["_targets"] = targets
            success_once = attributes["_success_once"] = self._success_once or success
            results = {"contact_error": error, "success": success, "fell": fell}
            ended = fell or (self.terminate_on_success and success)
            if skill == "walk":
                terms = {_NEAR: near, _FAR: far, _STILL: still}
                reward = sum((near, far, still))
            else:
                terms = {_NEAR: near, _FAR: far}
                reward = sum((near, far))
            # the ``_outcome`` setter's work: a SIMS world's last outcome is its own (no ``_step_outcome_batch``,
            # so a batched env never shares its rows)
            outcome = attributes["_last_outcome"] = StepOutcome(obs, reward, terms, ended, results)
            info = {"skill": skill, "furniture": goal.furniture, "part": goal.part, "caption": self.caption,
                    "style": self.style, **results, "success_once": success_once,
                    "amp_condition": self._amp_condition.copy(), "time": int(count[0]) * self.dt,
                    "physics_unstable": False, "amp_obs": amp_obs, "reference_start": bool(self._reference_flag[0]),
                    **terms}
        if self.render_mode == "human":
            self.render()
        return outcome.obs, outcome.reward, bool(outcome.terminated), bool(outcome.truncated), info

    def _world_outcome(self, obs: np.ndarray, targets: np.ndarray, near: float, far: float, still: float,
                       error: float, x: float, y: float, z: float, head_z: float, body_pos: np.ndarray | None = None,
                       root_vel: np.ndarray | None = None) -> StepOutcome:
        """The step outcome of this world from ``task.skill_step``'s results (the weighted reward terms, the
        error, the root's position and the head's height, Python floats): success, the fall and the aids' ends,
        the bookkeeping. ``body_pos`` (15, 3) and ``root_vel`` (3,): the state the tracking aid compares with
        its clip."""
        goal = self.goal
        skill = goal.skill
        success = error < task.SUCCESS_DISTANCE[skill]
        fell = head_z < self.fall_height
        target_x, target_y = self._root_target_xy
        attributes = self.__dict__    # private attributes, set directly (HumanoidEnv.__setattr__ checks keywords)
        attributes["_root_distance"] = math.hypot(target_x - x, target_y - y)
        attributes["_targets"] = targets
        attributes["_success_once"] = self._success_once or success
        results = {"contact_error": error, "success": success, "fell": fell}
        ended = fell or (self.terminate_on_success and success)
        if self.stall_seconds is not None:  # only with the aid: the default info is unchanged
            results["stalled"] = self._stall.stalled(error, self._steps) and not (fell or success)
            ended = ended or results["stalled"]
        if self.min_root_height is not None:  # only with the aid: no sitting on the floor
            results["grounded"] = bool(z < self.min_root_height) and not fell
            ended = ended or results["grounded"]
        held = False
        if self.hold_seconds is not None:  # only with the aid: InterScene's interaction early termination
            # steps that ended succeeding, in a row (the reset's outcome, at step 0, is not a step held)
            attributes["_held_steps"] = steps_held = self._held_steps + 1 if success and self._steps else 0
            results["held"] = held = steps_held * self.dt >= self.hold_seconds - 1e-9 and not ended
        # the terms (task.WALK_REWARD_TERMS, CONTACT_REWARD_TERMS) and their sum, left to right as numpy's sum of
        # fewer than 8 numbers
        if skill == "walk":
            outcome = StepOutcome(obs, sum((near, far, still)), {_NEAR: near, _FAR: far, _STILL: still}, ended,
                                  results, held)
        else:
            outcome = StepOutcome(obs, sum((near, far)), {_NEAR: near, _FAR: far}, ended, results, held)
        if self._tracking_on:  # the training aid: track the interaction start's clip (zeros on other starts)
            tracked, lost = (0.0, 0.0, 0.0), False
            if self._track is not None:
                i = self._track.frame(self._steps)
                *tracked, track_error = tracking_terms(body_pos, self._track.body_pos[i], root_vel,
                                                       self._track.root_vel[i], self.track_reward, PELVIS)
                lost = self.max_track_error is not None and track_error > self.max_track_error
            terms = dict(outcome.terms)
            if self.track_reward:
                terms.update(zip(TRACKING_TERMS, tracked))
            if self.max_track_error is not None:
                results["track_lost"] = bool(lost)
            outcome = StepOutcome(obs, outcome.reward + sum(tracked) if self.track_reward else outcome.reward, terms,
                                  ended or lost, results, held and not lost)
        return outcome

    def _full_info(self, outcome: StepOutcome, unstable: bool, terms: bool,
                   amp_obs: np.ndarray | None = None) -> dict[str, Any]:
        """``HumanoidEnv._full_info`` in one dict: the task's part (the goal, the caption, the outcome's
        results, ``success_once``, ``amp_condition``; ``interaction_start`` with that aid), then what every
        env reports, then the reward terms."""
        goal = self.goal
        info = {"skill": goal.skill, "furniture": goal.furniture, "part": goal.part, "caption": self.caption,
                "style": self.style, **outcome.results, "success_once": self._success_once,
                "amp_condition": self._amp_condition.copy()}
        if self.interaction_start_fraction > 0.0:  # only with the aid: the default info is unchanged
            info["interaction_start"] = self._interaction_start
        info["time"] = int(self._step_count[0]) * self.dt    # _steps * dt
        info["physics_unstable"] = unstable
        info["amp_obs"] = self._amp.flat() if amp_obs is None else amp_obs
        info["reference_start"] = bool(self._reference_flag[0])    # _reference_start
        if terms:
            info.update(outcome.terms)
        return info

    # --- rendering ----------------------------------------------------------------------------
    def _render_lines(self) -> tuple:
        if self.goal is None or self._targets is None:
            return ()
        joints = self.data.xpos[self._idx.body_ids]
        targets = self._targets
        return tuple((joints[j], targets[j], (1.0, 0.5, 0.1, 1.0)) for j in np.flatnonzero(self.goal.mask))


