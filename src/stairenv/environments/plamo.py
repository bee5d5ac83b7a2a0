"""PlaMo path following: the humanoid's head tracks a random 3-D path over flat, sloped, rough or stair terrain."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import mujoco
import numpy as np
from gymnasium import spaces

from stairenv.environments.base import HumanoidEnv, StepOutcome
from stairenv.environments.config import PlaMoConfig, document_keywords, keyword_signature, resolve
# named here too, as before (the height field's bound is PlaMoTerrain's)
from stairenv.environments.config import MAX_TERRAIN_CELLS, PATH_GENERATORS, TERRAIN_BYTES_PER_CELL  # noqa: F401
from stairenv.humanoid import load_humanoid_spec
from stairenv.humanoid.model import HEAD_CENTRE_OFFSET
from stairenv.humanoid.state import HEAD, PELVIS
from stairenv.motion.library import MotionLibrary
from stairenv.motion.tracking import ReferenceTrack, reference_track, track_speed
from stairenv.planning.locomotion import LOCOMOTIONS, locomotion_labels, nearest_locomotion
from stairenv.tasks import curriculum
from stairenv.tasks.terms import TRACKING_TERMS, tracking_terms
from stairenv.tasks import plamo as task
from stairenv.tasks.kernels import PROPRIOCEPTION_SIZE, proprioception
from stairenv.validation import check_number
from stairenv.world.terrain import MAX_STAIRS_LEVELS, MAX_TERRAIN_HEIGHT, bilinear_height, terrain_tiles
from stairenv.world.tiles import FOCUS_RADIUS, TILE_KINDS, TerrainSlots, TerrainView, slot_contents

NUM_WAYPOINTS, WAYPOINT_SPACING = 10, 0.5  # the next 5 s of path, every 0.5 s
# Where ``_floor_under`` looks around a start: 9 points 0.5 m away (the first and last the same).
FLOOR_RING = 0.5 * np.array([[math.cos(a), math.sin(a)] for a in np.linspace(0, 2 * math.pi, 9)])
FLOOR_RING.flags.writeable = False
# ``min_root_height`` acts where the path's head height is above this: midway between the highest crawl
# and the lowest crouch-walk (0.525 m), so a crawl keeps its low pelvis and a sit on a walk path ends.
ABOVE_CRAWL_HEAD = (LOCOMOTIONS["crawl"].head_range[1] + LOCOMOTIONS["crouch-walk"].head_range[0]) / 2


@document_keywords(PlaMoConfig)
class PlaMoEnv(HumanoidEnv):
    r"""Path following (PlaMo, Sec. 3.2): the head tracks a timed 3-D path over generated terrain.

    Every reset draws a terrain (``terrain``: flat, slope, rough, stairs or mixed
    patches of 4 m; the task reads its height samples, the model holds it as tiles near
    the character: the ground plane, stairs as boxes, a height field per slope or rough
    patch, ``stairenv.world.tiles``, ``docs/terrain_layout.md``) and a random head path from the
    character's start: head heights first (smooth changes within ``head_range``),
    then speeds, coupled to the height as in PlaMo (``path_generator="coupled"``,
    v_max(z) = min(1 + 4 (z - 0.4) / 0.8, 5) m/s) or not (``"naive"``, the paper's
    ablation). ``locomotion`` ("crawl", "crouch-walk", "walk", "run", "sprint")
    restricts heights and speeds to that row of ``stairenv.planning.locomotion``.

    **Observation** (113 + heightmap_size^2 + 30): proprioception (root height above
    the terrain, root rotation, velocities, joint rotations and velocities, as in
    InterLevel), an egocentric heightmap (``heightmap_size`` x ``heightmap_size``
    samples over ``heightmap_extent`` metres, turned with the root's heading, terrain
    height minus root height), and the next 10 head targets over 5 s (every 0.5 s),
    relative to the head, in the heading frame. ``observation_structure`` names the slices.

    **Reward** r^tau (``stairenv.tasks.plamo``): exp(-2 |dxy|^2) + exp(-10 dz^2) +
    exp(-20 |d(yaw, pitch)|^2) + 0.1 (z_head - max body z), each term in ``info`` as
    ``reward_*``; the head is the centre of the head sphere and its direction the
    head's forward axis; max body z includes the head, so the body term is <= 0.

    **Episode**: terminated when the head is more than ``max_xy_error`` from its
    target on the ground plane (``info["off_path"]``) or within ``min_head_height`` of the terrain
    (``info["fell"]``);
    truncated by the TimeLimit (300 steps = 10 s in the preset) or on diverging
    physics (``info["physics_unstable"]``). ``info`` has ``xy_error``, ``z_error``,
    the reward terms, ``terrain`` and ``amp_obs``.

    **Reference starts** (``init`` "reference" or "hybrid") are frames of the reference clips
    (``reference_motion``, by default ``builtin:plamo``: crawls, crouch-walks, walks and runs).
    With ``matched_starts`` (default) the path is drawn first and the frame comes from the clips of
    the locomotion its first segment asks for (``planning.locomotion.nearest_locomotion`` of its
    opening head height and speed, among the types the clips are labelled with,
    ``meta["locomotion"]``): a path that opens with a crawl starts crawling, not upright 1 m above
    its target. Off, or where a clip has no such label (a folder of the user's clips): any clip, the
    path drawn after the character is placed.

    **Speed curriculum** (``speed_levels`` N, a training aid; 0 = off): each world holds a level
    (``curriculum_level``, 0 at its first reset); level k draws its paths with every speed scaled by
    (k + 1) / N (``PathConfig.speed_scale``; head heights unchanged), so the top level is the paper's
    distribution. After an episode that took a step, the world moves up a level when the episode
    lasted ``episode_seconds`` without ending early (success), down one when it ended early before
    half of them (``stairenv.tasks.curriculum.next_growing_level``); an episode cut by the trainer
    (``reset(options={"episode_cut": True})``) is not judged. Trainers log and checkpoint the level.
    With ``speed_levels_by_locomotion`` a world holds a level per locomotion type instead
    (``curriculum_level`` is a tuple in the order of ``curriculum_level_names``, the rows of
    ``planning.locomotion.LOCOMOTIONS``): each path sample's speed is scaled by the level of the
    locomotion its drawn head height and speed ask for (``nearest_locomotion``, before scaling); a
    success moves up every locomotion the episode asked for, an early end before half the episode moves
    down the one asked for when it ended. So walking reaches the paper's speeds while crawling stays slow.

    **Grounded termination** (``min_root_height``, a training aid; None = off): an episode also ends
    (``info["grounded"]``, present only with the aid) when the pelvis is less than ``min_root_height``
    above the terrain while the path's head height is above ``ABOVE_CRAWL_HEAD`` (0.525 m, between the
    highest crawl and the lowest crouch-walk): sitting and scooting along an upright path ends there.

    **Height termination** (``max_z_error``, a training aid; None = off): an episode also ends
    (``info["z_off_path"]``, present only with the aid) when the head is more than ``max_z_error`` below
    its target: going on all fours along a walk path (which the grounded termination lets pass while the
    pelvis stays up) ends there. Above the target it does not act, so a standing start on a crawl path
    has time to get down. With ``aid_grace`` > 0 both aids judge the lowest head height the path asked
    for over the last ``aid_grace`` seconds instead of this instant's, so a segment that rises (crawl ->
    walk, a ``transition``-second blend) leaves a crawling character time to get up.

    **Upright termination** (``max_z_above``, a training aid; None = off): an episode also ends
    (``info["z_above_path"]``, present only with the aid) when the head is more than ``max_z_above`` above
    its target: walking upright along a crouch-walk or crawl path ends there. It acts from
    ``z_above_grace`` seconds into the episode (a standing start on a crawl path has that long to get
    down) and judges the highest head the path asked for over the last ``z_above_grace`` seconds, so a
    segment that drops (walk -> crawl) leaves the character that long to follow it down.

    **Pose imitation** (``pose_reward`` w, a training aid; 0 = off): the reward gains
    ``reward_pose`` = w exp(-k sum_j (q_ref_j - q_j)^2) over the 28 joint angles (DeepMimic's pose reward;
    k = ``pose_sharpness``, DeepMimic's 2 by default),
    q_ref the start clip played on from the start frame (0 on a standing start): a character started
    in a crawl is paid for going on crawling while the path steers it.

    **Clip tracking** (``track_reward`` w, ``max_track_error``, ``clip_paths``; training aids, off by
    default; DeepMimic's imitation for per-locomotion specialists): on a reference start the start clip
    is played on from the start frame (a looping clip cycle after cycle, each moved on by the cycle's
    travel) and placed where the character started (``stairenv.motion.tracking.reference_track``). The
    reward gains ``reward_track_root`` = 0.4 w exp(-5 |p_root - p^_root|^2), ``reward_track_velocity`` =
    0.3 w exp(-2 |v_root - v^_root|^2) and ``reward_track_bodies`` = 0.3 w exp(-10 mean_b |(p_b - p_root) -
    (p^_b - p^_root)|^2) (``stairenv.tasks.terms.tracking_terms``: the clip's travel, not only its pose);
    the episode ends (``info["track_lost"]``) when the bodies are on average more than ``max_track_error``
    from the clip's; with ``clip_paths`` the path is the clip's own head, so that following the path is
    following the clip. On a standing start the terms are 0 and the path is drawn, unless
    ``standing_clip`` names a clip (or a folder of them, one drawn per episode): a standing start then
    tracks that clip from its first frame (a get-down into a crawl, ``stairenv.motion.stitch``), and every
    aid above acts on it as on a start clip.
    ``track_rate`` (min, max) plays each tracked clip faster or slower by a factor drawn per episode, and
    ``track_turn_rate`` bends its course to turn at a rate drawn from [-it, it] rad/s
    (``motion.tracking.bend``): with ``clip_paths`` the paths then ask for the speeds and turns the
    evaluation's do.

    **Pushes** (``push_speed``, ``push_interval``, a training aid of every family; None = off): a kick of a
    speed drawn from ``push_speed`` (m/s) added to the root's horizontal velocity in a random direction
    every ``push_interval`` seconds (drawn), so that the policy learns to recover
    (``HumanoidEnv._setup_pushes``).

    **Keywords** are checked at construction (``TypeError`` for a wrong type, ``ValueError`` for a
    value out of range, both naming the keyword). They are the fields of ``PlaMoConfig``
    (``stairenv.environments.config``: defaults and ranges live there); ``config=PlaMoConfig(...)`` may be
    given instead (keywords beside it must agree with it), and ``env.unwrapped.config`` is the resolved
    config. The table below is made from the config's fields.

    **Memory bound**: the terrain has ``terrain_size / terrain_cell_size + 1`` height samples per side
    and may hold at most ``MAX_TERRAIN_CELLS`` = 2001^2 (about 4 million) samples, e.g. 200 m at 0.1 m
    or 20 m at 0.01 m; building it costs ~52 bytes a sample, ~200 MB at the bound. A larger grid (200 m at 0.01 m would
    need ~20 GB) raises ``ValueError`` naming both keywords and the memory it would need.

    {keyword table}
    """

    #: PlaMo's reference motion (AMP and reference-state starts): all four locomotion types
    DEFAULT_REFERENCE_MOTION = "builtin:plamo"

    #: what a built env takes (``configure``, ``set_attr``): the episode's end bounds and the aids' graces
    LIVE_KEYWORDS = frozenset(("max_xy_error", "min_head_height", "aid_grace", "z_above_grace"))

    def __init__(self, *, config: PlaMoConfig | None = None, **keywords) -> None:
        # the keywords (signature below: PlaMoConfig's fields) -> the one resolved, checked config
        self.config = config = resolve(PlaMoConfig, config, keywords)
        terrain, paths, aids = config.terrain, config.paths, config.training_aids
        self.terrain, self.path_generator, self.locomotion = terrain.kind, paths.path_generator, paths.locomotion
        self.episode_seconds = paths.episode_seconds
        self.heightmap_size = config.observation.heightmap_size
        self.heightmap_extent = config.observation.heightmap_extent
        self.max_xy_error = config.termination.max_xy_error
        self.min_head_height = config.termination.min_head_height
        # starts on the ground: level-ground clips only (a climb's frame would start on no step)
        self._setup_family_aids(aids)
        self.matched_starts = aids.matched_starts
        self._starts_by_locomotion = self._group_starts() if self.matched_starts else None
        self.speed_levels = aids.speed_levels
        self.speed_levels_by_locomotion = bool(aids.speed_levels and aids.speed_levels_by_locomotion)
        #: what each entry of a per-locomotion ``curriculum_level`` is the level of (None: one level per world)
        self.curriculum_level_names = tuple(LOCOMOTIONS) if self.speed_levels_by_locomotion else None
        self._speed_labels: np.ndarray | None = None   # the path samples' locomotions (indices into the names)
        self.min_root_height = aids.min_root_height
        self.max_z_error = aids.max_z_error
        self.aid_grace = aids.aid_grace
        self.max_z_above, self.z_above_grace = aids.max_z_above, aids.z_above_grace
        self.pose_reward, self.pose_sharpness = aids.pose_reward, aids.pose_sharpness
        self.track_reward, self.max_track_error, self.clip_paths = (aids.track_reward, aids.max_track_error,
                                                                    aids.clip_paths)
        self.standing_clip = aids.standing_clip
        self.track_rate, self.track_turn_rate = aids.track_rate, aids.track_turn_rate
        self._standing_clips = None if aids.standing_clip is None else MotionLibrary.load(aids.standing_clip).clips
        #: the reference a reference start tracks (``motion.tracking.reference_track``; None: no clip aid
        #: is on, or a standing start)
        self._track: ReferenceTrack | None = None
        #: this world's level of the speed curriculum (None until the first reset draws it)
        self.curriculum_level = None
        if self.locomotion is not None:
            path_config = task.PathConfig(head_range=self.locomotion.head_range,
                                          speed_range=self.locomotion.speed_range)
        else:
            path_config = task.PathConfig(coupled=self.path_generator == "coupled")
        self.constant_paths = config.paths.constant_paths
        if self.constant_paths:  # one segment longer than any path this env draws: levels drawn once
            once = self.episode_seconds + NUM_WAYPOINTS * WAYPOINT_SPACING + 2.0
            path_config = dataclasses.replace(path_config, segment_duration=(once, once), transition=0.0)
        self.path_config = path_config

        render = config.render
        self._init_humanoid(config.physics.frame_skip, config.amp_history, render.render_mode, render.width,
                            render.height)
        self._terrain_dirty = False
        self._build_initial_world(config.physics.pd_gains, terrain.size, terrain.cell_size)

        hm = self.heightmap_size ** 2
        size = PROPRIOCEPTION_SIZE + hm + 3 * NUM_WAYPOINTS
        self.observation_space = spaces.Box(-np.inf, np.inf, shape=(size,), dtype=np.float64)
        self.observation_structure = {
            "proprioception": slice(0, PROPRIOCEPTION_SIZE),
            "heightmap": slice(PROPRIOCEPTION_SIZE, PROPRIOCEPTION_SIZE + hm),
            "path": slice(PROPRIOCEPTION_SIZE + hm, size),
        }
        self.path: task.PathSamples | None = None

    # the keywords: PlaMoConfig's fields, defaults included (``config=`` stays out of the signature)
    __init__.__signature__ = keyword_signature(PlaMoConfig)

    # --- terrain --------------------------------------------------------------
    def _build_initial_world(self, pd_gains: str, terrain_size: float, terrain_cell_size: float) -> None:
        """The model: the terrain's tile slots (``stairenv.world.tiles``) on the humanoid's ground plane, and
        (to render) the whole terrain drawn as a height field that touches nothing; every reset rewrites them."""
        self._terrain_size = check_number("terrain_size", terrain_size, 2.0, 200.0)
        self._terrain_cell_size = check_number("terrain_cell_size", terrain_cell_size, 0.01, 1.0)
        spec = load_humanoid_spec(pd_gains)
        self._tiles = terrain_tiles("flat", np.random.default_rng(0), self._terrain_size, self._terrain_cell_size)
        n = self._tiles.heights.shape[0]
        # slots for the tiles within reach, holding what this env's terrain kind needs (none on flat ground)
        boxes, field = slot_contents(TILE_KINDS if self.terrain == "mixed" else (self.terrain,))
        self._terrain_slots = TerrainSlots(spec, self._tiles.tile_samples, self._tiles.cell_size,
                                           MAX_STAIRS_LEVELS if boxes else 0,
                                           min(self._tiles.max_tiles_near(FOCUS_RADIUS), self._tiles.kinds.size), field)
        # what a film shows of the terrain beyond the slots (the slots' geoms draw over it); not built
        # without a render mode: a body that no contact needs still costs every substep a little
        self._terrain_view = None if self.render_mode is None else TerrainView(
            spec, n, n, self._tiles.cell_size, max_height=MAX_TERRAIN_HEIGHT)
        self._compile(spec)
        self._terrain_slots.bind(self.model)
        self._terrain_slots.set_terrain(self.model, self._tiles)
        if self._terrain_view is not None:
            self._terrain_view.bind(self.model)
        self._heights = self._tiles.heights

    def ground_height(self, xy: np.ndarray) -> np.ndarray:
        return bilinear_height(self._heights, self._terrain_size, xy)

    # --- episode ------------------------------------------------------------
    def _build_world(self, rng: np.random.Generator, options: dict[str, Any] | None) -> None:
        if self.speed_levels:
            # options={"episode_cut": True}: the episode in progress was cut short (a trainer's checkpoint)
            self._judge_speed_level(judge_last=not (options or {}).get("episode_cut", False))
        self._tiles = terrain_tiles(self.terrain, rng, self._terrain_size, self._terrain_cell_size)
        self._heights = self._tiles.heights
        self._terrain_slots.set_terrain(self.model, self._tiles)
        if self._terrain_view is not None:
            self._terrain_view.write(self.model, self._heights, self._tiles.origin)
        self._terrain_dirty = True

    def _focus_terrain(self, xy) -> None:
        """The terrain's tiles within reach of ``xy`` (the root) in the model's slots (where it has them)."""
        if self._terrain_slots is not None and self._terrain_slots.focus(self.model, xy):
            self._model_written = True    # (a device back-end copies the world's terrain up: the batched env)

    def _before_physics(self) -> None:
        """The tiles the character can reach during this step in the model (a new one as it comes near)."""
        self._focus_terrain(self.data.qpos[:2])

    def _place_character(self, rng: np.random.Generator, options: dict[str, Any] | None) -> bool:
        start = rng.uniform(-1.0, 1.0, 2)
        heading = rng.uniform(-math.pi, math.pi)
        if self._starts_by_locomotion is None:
            reference = self._reference_pose(rng)
            self._start = start, heading
        else:  # the path first: the locomotion it opens with picks the clips to start from
            self._start = start, heading
            self._draw_path(rng)
            kind = nearest_locomotion(float(self.path.head[0]), float(self.path.speed[0]), self._starts_by_locomotion)
            reference = self._reference_pose(rng, self._starts_by_locomotion[kind])
        self._focus_terrain(start)
        self._place_at(start, heading, reference, self._floor_under(start))
        if reference is None and self._standing_clips is not None:  # the training aid: a get-down to track
            clips = self._standing_clips    # (one clip: nothing drawn)
            self._reference_clip = (clips[int(rng.integers(len(clips)))] if len(clips) > 1 else clips[0], 0.0)
        self._track = None
        if self._reference_clip is not None and (self.track_reward or self.max_track_error is not None
                                                 or self.clip_paths):
            clip, start_time = self._reference_clip
            steps = math.ceil((self.episode_seconds + NUM_WAYPOINTS * WAYPOINT_SPACING + 1.0) / self.dt)
            # a drawn cadence and bend (training aids; drawn only where asked, so other episodes draw as before)
            rate = 1.0 if self.track_rate[0] == self.track_rate[1] == 1.0 else float(rng.uniform(*self.track_rate))
            turn = float(rng.uniform(-1.0, 1.0)) * self.track_turn_rate if self.track_turn_rate else 0.0
            self._track = reference_track(clip, start_time, steps, self.dt, self.data.qpos[self._idx.qpos_root],
                                          rate, turn)
        return reference is not None

    def _new_goal(self, rng: np.random.Generator, options: dict[str, Any] | None) -> None:
        if self._starts_by_locomotion is None:  # (matched starts drew it before placing the character)
            self._draw_path(rng)
        if self.clip_paths and self._track is not None:  # the training aid: the clip's own head as the path
            track = self._track
            self.path = task.PathSamples(points=track.head, head=track.head[:, 2] - self.ground_height(track.head[:, :2]),
                                         speed=track_speed(track), yaw=track.head_yaw, pitch=track.head_pitch,
                                         dt=track.dt)

    @property
    def curriculum_level(self) -> int | tuple[int, ...] | None:
        """This world's speed-curriculum level: an int, a tuple of ints (one per ``curriculum_level_names``)
        with ``speed_levels_by_locomotion``, or None before the first reset."""
        return self._curriculum_level

    @curriculum_level.setter
    def curriculum_level(self, level) -> None:
        # a trainer's saved levels: an int (a per-locomotion world takes it for every locomotion), or a
        # sequence of ints, one per locomotion (JSON gives it back as a list)
        if level is None or not self.curriculum_level_names:
            if level is not None and not isinstance(level, (int, np.integer)):
                raise ValueError(f"curriculum_level must be an int (one level per world), got {level!r}")
            self._curriculum_level = None if level is None else int(level)
            return
        names = self.curriculum_level_names
        levels = (level,) * len(names) if isinstance(level, (int, np.integer)) else tuple(level)
        if len(levels) != len(names) or not all(isinstance(k, (int, np.integer)) for k in levels):
            raise ValueError(f"curriculum_level must be an int or {len(names)} ints (one per {names}), got {level!r}")
        self._curriculum_level = tuple(min(max(int(k), 0), self.speed_levels - 1) for k in levels)

    def _judge_speed_level(self, judge_last: bool) -> None:
        """The speed curriculum's level: 0 at the first reset, then moved by the outcome of the episode
        that just ended, if it took a step and ``judge_last`` (reset has not yet cleared ``_steps``)."""
        if self.curriculum_level is None:
            self.curriculum_level = 0
            return
        steps = getattr(self, "_steps", 0)
        if not judge_last or steps == 0:
            return
        progress = steps * self.dt / self.episode_seconds
        success = not self._outcome.terminated and progress >= 1.0 - 1e-9
        if not self.speed_levels_by_locomotion:
            self.curriculum_level = curriculum.next_growing_level(self.curriculum_level, self.speed_levels,
                                                                  success, progress)
            return
        # a success: up every locomotion the episode asked for; an early end: the one asked for at the end
        asked = self._speed_labels[:self.path.index(steps * self.dt) + 1]
        judged = set(asked.tolist()) if success else {int(asked[-1])}
        self.curriculum_level = tuple(
            curriculum.next_growing_level(level, self.speed_levels, success, progress) if k in judged else level
            for k, level in enumerate(self.curriculum_level))

    def episode_path_config(self) -> task.PathConfig:
        """``path_config``, its speeds scaled to this world's speed-curriculum level when there is one
        (per locomotion, ``_locomotion_speed_scales`` scales them instead)."""
        if not self.speed_levels or self.curriculum_level is None or self.speed_levels_by_locomotion:
            return self.path_config
        return dataclasses.replace(self.path_config,
                                   speed_scale=(self.curriculum_level + 1) / self.speed_levels)

    def _locomotion_speed_scales(self, head: np.ndarray, speed: np.ndarray) -> np.ndarray:
        """Each path sample's speed factor: (level + 1) / N of the locomotion its drawn head height and
        speed ask for (kept in ``_speed_labels`` for judging the episode)."""
        self._speed_labels = locomotion_labels(head, speed, self.curriculum_level_names)
        scales = (np.asarray(self.curriculum_level, dtype=np.float64) + 1.0) / self.speed_levels
        return scales[self._speed_labels]

    def _draw_path(self, rng: np.random.Generator) -> None:
        start, heading = self._start
        by_locomotion = self.speed_levels_by_locomotion and self.curriculum_level is not None
        self.path = task.random_head_path(
            self.episode_path_config(), rng, self.episode_seconds + NUM_WAYPOINTS * WAYPOINT_SPACING + 1.0, start, heading,
            self.ground_height, arena_half=self._terrain_size / 2 - 1.5,
            scale_speeds=self._locomotion_speed_scales if by_locomotion else None,
        )

    def _group_starts(self) -> dict[str, MotionLibrary] | None:
        """The start clips by ``meta["locomotion"]`` (weights kept), or None where starts cannot be
        matched: no reference starts, or a clip without a locomotion the planner knows."""
        if self._library is None:
            return None
        kinds = [clip.meta.get("locomotion") for clip in self._library.clips]
        if not all(kind in LOCOMOTIONS for kind in kinds):
            return None
        groups = {}
        for kind in dict.fromkeys(kinds):
            keep = [i for i, k in enumerate(kinds) if k == kind]
            groups[kind] = MotionLibrary([self._library.clips[i] for i in keep], self._library.probabilities[keep])
        return groups

    # --- pieces -------------------------------------------------------------
    def _floor_under(self, xy: np.ndarray) -> float:
        """The highest ground under a body standing at ``xy`` (so nothing starts inside a slope or a step)."""
        return float(np.max(self.ground_height(np.vstack((xy, xy + FLOOR_RING)))))

    def _head(self) -> tuple[np.ndarray, np.ndarray]:
        head_mat = self.data.xmat[self._idx.head_id].reshape(3, 3)
        return self.data.xpos[self._idx.head_id] + head_mat @ HEAD_CENTRE_OFFSET, head_mat

    BATCH_OUTCOMES = True

    def _step_outcome(self, state) -> StepOutcome:
        """``_step_outcomes`` of this world alone."""
        return self._step_outcomes([self], state)[0]

    @classmethod
    def _step_outcomes(cls, envs: list[PlaMoEnv], state) -> list[StepOutcome]:
        """The step outcomes of ``envs`` (worlds of one configuration; row k of the batch ``state`` is world
        k): what is the same for every world as arrays over the batch (the head centres, the highest
        bodies, the proprioception in one compiled call), then per world, each with its own terrain and
        path, its heightmap and path targets (compiled, written into its row of the observations) and its
        reward terms and ends in Python floats: the operations of the numpy forms in their order
        (``stairenv.tasks.plamo``), so a world's outcome has the same bits alone or in any batch."""
        first = envs[0]
        n, hm = len(envs), first.heightmap_size ** 2
        body_pos, body_mat = state.body_pos, state.body_mat
        heads = body_pos[:, HEAD] + np.matmul(body_mat[:, HEAD], HEAD_CENTRE_OFFSET)
        max_body_z = np.maximum(body_pos[:, :, 2].max(axis=1), heads[:, 2]).tolist()
        obs = np.empty((n, PROPRIOCEPTION_SIZE + hm + 3 * NUM_WAYPOINTS))
        heightmaps, path_obs = obs[:, PROPRIOCEPTION_SIZE:PROPRIOCEPTION_SIZE + hm], obs[:, PROPRIOCEPTION_SIZE + hm:]
        root_height = np.empty(n)
        roots = body_pos[:, PELVIS]
        root_axes = body_mat[:, PELVIS, :2, 0].tolist()   # (R00, R10): the root's yaw
        forwards = body_mat[:, HEAD, :, 0].tolist()      # the head's forward axis
        head_rows = heads.tolist()
        rows = []
        for k, env in enumerate(envs):
            t = env._steps * env.dt
            root, head = roots[k], heads[k]
            r00, r10 = root_axes[k]
            root_yaw = math.atan2(r10, r00)
            c, s = math.cos(root_yaw), math.sin(root_yaw)
            root_ground, head_ground = env._terrain_samples(heightmaps[k], root, c, s, head)
            root_height[k] = root[2] - root_ground
            path = env.path
            target = task.write_path_observation(path_obs[k], path.points, path.dt, t, head, c, s, WAYPOINT_SPACING)
            i = path.index(t)
            fx, fy, fz = forwards[k]
            head_yaw = math.atan2(fy, fx)
            head_pitch = math.atan2(fz, math.hypot(fx, fy))
            hx, hy, hz = head_rows[k]
            terms = task.path_reward_values(target, head_rows[k], float(path.yaw[i]), float(path.pitch[i]),
                                            head_yaw, head_pitch, max_body_z[k])
            path_head = float(path.head[i])
            # aid_grace: the aids judge the lowest head the path asked for lately (0 = this instant's)
            rise = 0.0
            if env.aid_grace:
                rise = path_head - float(path.head[path.index(t - env.aid_grace):i + 1].min())
            # max_z_above: judged from z_above_grace into the episode, against the highest head asked lately
            above = None
            if env.max_z_above is not None:
                grace = env.z_above_grace
                drop = float(path.head[path.index(t - grace):i + 1].max()) - path_head if grace else 0.0
                above = t > grace and (hz - target[2]) - drop > env.max_z_above
            rows.append((terms, target[0] - hx, target[1] - hy, target[2] - hz, hz - head_ground, path_head,
                         rise, above))
        obs[:, :PROPRIOCEPTION_SIZE] = proprioception(body_mat, state.root_lin_vel, state.root_ang_vel, state.dof_vel,
                                                      root_height, np.empty((n, PROPRIOCEPTION_SIZE)))
        xy_errors = np.hypot([row[1] for row in rows], [row[2] for row in rows]).tolist()
        outcomes = []
        for k, env in enumerate(envs):
            terms, _, _, head_below, head_clearance, path_head, rise, above = rows[k]
            xy_error, z_error = xy_errors[k], abs(head_below)
            # the two reasons an episode ends early, each in info: the head at the ground, the path lost
            fell, off_path = head_clearance < env.min_head_height, xy_error > env.max_xy_error
            results = {"xy_error": xy_error, "z_error": z_error, "fell": fell, "off_path": off_path}
            ended = fell or off_path
            if env.min_root_height is not None:  # the training aid: no sitting where the path asks to stand
                results["grounded"] = bool(path_head - rise > ABOVE_CRAWL_HEAD
                                           and root_height[k] < env.min_root_height)
                ended = ended or results["grounded"]
            if env.max_z_error is not None:  # the training aid: no going on all fours where the path asks to walk
                results["z_off_path"] = bool(head_below - rise > env.max_z_error)
                ended = ended or results["z_off_path"]
            if above is not None:  # the training aid: no walking upright where the path asks to crouch or crawl
                results["z_above_path"] = bool(above)
                ended = ended or results["z_above_path"]
            reward, named_terms = terms[0] + terms[1] + terms[2] + terms[3], dict(zip(task.REWARD_TERMS, terms))
            if env.pose_reward:  # the training aid: imitate the start clip, played on from the start frame
                pose = env._pose_term(state.dof_pos[k])
                named_terms["reward_pose"] = pose
                reward += pose
            if env.track_reward or env.max_track_error is not None:  # the training aid: track the start clip
                tracked, lost = env._tracking(state.body_pos[k], state.root_lin_vel[k])
                if env.track_reward:
                    named_terms.update(zip(TRACKING_TERMS, tracked))
                    reward += tracked[0] + tracked[1] + tracked[2]
                if env.max_track_error is not None:
                    results["track_lost"] = lost
                    ended = ended or lost
            outcomes.append(StepOutcome(obs[k], reward, named_terms, ended, results))
        return outcomes

    def _pose_term(self, joints: np.ndarray) -> float:
        """``pose_reward`` times ``task.pose_imitation_term`` against the start clip at the start time plus
        the episode's time; 0 on a standing start (no clip to imitate)."""
        if self._reference_clip is None:
            return 0.0
        if self._track is not None and (self.track_rate != (1.0, 1.0) or self.track_turn_rate):
            reference = self._track.qpos[self._track.frame(self._steps), 7:]   # the clip at its drawn cadence
        else:
            clip, start_time = self._reference_clip
            reference = clip.sample(start_time + self._steps * self.dt)[0, 7:]  # a clip row: root (7), joints
        return self.pose_reward * task.pose_imitation_term(reference, joints, self.pose_sharpness)

    def _tracking(self, body_pos: np.ndarray, root_vel: np.ndarray) -> tuple[tuple[float, float, float], bool]:
        """``tracking_terms`` against this episode's reference track at this step (zeros on a standing
        start, which has no clip to track), and whether the bodies are more than ``max_track_error`` from it."""
        track = self._track
        if track is None:
            return (0.0, 0.0, 0.0), False
        i = track.frame(self._steps)
        root, velocity, bodies, error = tracking_terms(body_pos, track.body_pos[i], root_vel, track.root_vel[i],
                                                       self.track_reward, PELVIS)
        return (root, velocity, bodies), self.max_track_error is not None and error > self.max_track_error

    def _terrain_samples(self, out: np.ndarray, root: np.ndarray, c: float, s: float,
                         head: np.ndarray) -> tuple[float, float]:
        """The heightmap around ``root`` (c, s: the cosine and sine of its yaw; terrain height minus root
        height) written to ``out``, and the terrain height under the root and under ``head``: compiled on
        this env's height field, else (a subclass's own ``ground_height``) one ``ground_height`` call."""
        if type(self).ground_height is PlaMoEnv.ground_height:
            return task.write_terrain_heightmap(out, self._heights, self._terrain_size, root, c, s,
                                                self.heightmap_size, self.heightmap_extent, head)
        if getattr(self, "_heightmap_offsets", None) is None:
            self._heightmap_offsets = task.heightmap_offsets(self.heightmap_size, self.heightmap_extent)
        gx, gy = self._heightmap_offsets
        points = np.empty((len(gx) + 2, 2))
        points[0], points[-1] = root[:2], head[:2]
        points[1:-1, 0] = root[0] + c * gx - s * gy
        points[1:-1, 1] = root[1] + s * gx + c * gy
        ground = self.ground_height(points)
        out[:] = ground[1:-1] - root[2]
        return float(ground[0]), float(ground[-1])

    def _info(self, results: dict[str, Any]) -> dict[str, Any]:
        return {**results, "terrain": self.terrain,
                "locomotion": None if self.locomotion is None else self.locomotion.name}

    # --- rendering ----------------------------------------------------------
    def render(self):
        # A renderer made now uploads the height fields itself; an existing one still holds what they
        # held when it last drew (the previous episode's terrain, the tiles the slots held then).
        slots, view = self._terrain_slots, self._terrain_view
        if self._camera is not None:
            context = self._camera.renderer._mjr_context
            if self._terrain_dirty and view is not None:
                mujoco.mjr_uploadHField(self.model, context, view.hfield_id)
            for hfield in (slots.dirty if slots is not None else ()):
                mujoco.mjr_uploadHField(self.model, context, hfield)
        self._terrain_dirty = False
        if slots is not None:
            slots.dirty.clear()
        return super().render()

    def _render_lines(self) -> tuple:
        if self.path is None:
            return ()
        t = self._steps * self.dt
        points = self.path.at(t + WAYPOINT_SPACING * np.arange(0, NUM_WAYPOINTS + 1))
        return tuple((a, b, (0.1, 0.9, 0.2, 1.0)) for a, b in zip(points[:-1], points[1:]))
