"""Env configs: one frozen, typed config per env family, its keywords mapped onto its fields.

A config is a tree of small frozen dataclasses. Each field declares its default and its check (type
and range, or choices) once, beside it (``stairenv.validation.checked``); a group's ``__post_init__``
runs them (``check_fields``), so a config is valid however it is built. The groups of the world and
the task are their own layers' dataclasses (``StairsConfig``, ``InterLevelReward``); their fields get
the same checks, typed, under the env's keyword names (``from_keywords``).

Keywords. Every leaf field is one keyword of ``gym.make`` / the env's constructor, named as the field
unless ``KEYWORD_NAMES`` renames it (``stairs_distance`` is ``stairs.distance``). ``keyword_paths``
lists them in order; ``from_keywords`` builds the config from the given ones, the defaults being the
fields', each checked once under its keyword (TypeError for a wrong type, ValueError out of range,
both naming the keyword: the messages of ``stairenv.validation``). ``keywords()`` goes back. The env's
signature is made from the fields (``keyword_signature``), and so is the keyword table of its docstring
(``keyword_table``, ``document_keywords``: keyword, default, valid values, help), so defaults live in one place.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
import os
import tomllib
import zipfile
from dataclasses import fields
from pathlib import Path
from typing import Any, Self

from stairenv.environments.base import INITS, check_reference_motion
from stairenv.humanoid import PD_GAINS
from stairenv.motion import stair_starts
from stairenv.motion.library import MotionLibrary
from stairenv.planning.locomotion import LOCOMOTIONS, Locomotion, get_locomotion
from stairenv.rendering import RENDER_MODES
from stairenv.tasks import curriculum
from stairenv.tasks.interlevel import InterLevelReward
from stairenv.planning.errors import InstructionError, quote
from stairenv.planning.instructions import parse_instructions
from stairenv.validation import (
    Check,
    check_fields,
    check_grid,
    check_mapping,
    check_str,
    checked,
    checked_config,
    field_check,
)
from stairenv.world.scenes import SceneConfig
from stairenv.world.stairs import StairsConfig
from stairenv.world.terrain import TERRAIN_KINDS

REWARDS = ("interlevel", "interscene")
UNIT = Check("float", 0.0, 1.0)
GROUP_KEY = "stairenv.environments.config.group"


def group(cls: type, checks_keywords: bool = True) -> Any:
    """A field holding a nested config (a group of fields), by default ``cls()``. ``checks_keywords``:
    its ``__post_init__`` runs ``check_fields`` (typed, under the keywords' names); else it is another
    layer's dataclass that checks only the ranges under its own names, and ``from_keywords`` checks its
    keywords first."""
    return dataclasses.field(default_factory=cls, metadata={GROUP_KEY: cls, "checks_keywords": checks_keywords})


def _group_of(field: dataclasses.Field) -> type | None:
    return field.metadata.get(GROUP_KEY)


def _reference_motion(value):
    check_reference_motion(value)
    return value


def _standing_clip(value):
    """``standing_clip``: None, one readable ``.npz`` clip or a folder of them (loaded at construction, never
    run)."""
    if value is None:
        return None
    if not isinstance(value, (str, os.PathLike)):
        raise TypeError(f"standing_clip must be None or the path of a .npz clip or folder of them, "
                        f"got {type(value).__name__}")
    try:
        MotionLibrary.load(value)
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as error:
        raise ValueError(f"standing_clip {str(value)!r} could not be loaded as clips: {error}") from error
    return value


class EnvConfig:
    """What every family's config does: built from keywords (or a preset), and back."""

    @classmethod
    def from_keywords(cls, **keywords) -> Self:
        return from_keywords(cls, keywords)

    @classmethod
    def from_toml(cls, path: str | Path) -> Self:
        """The config of a preset (``envs/*.toml``): its ``[kwargs]`` as keywords."""
        with Path(path).open("rb") as f:
            return from_keywords(cls, tomllib.load(f).get("kwargs", {}))

    @classmethod
    def keyword_names(cls) -> tuple[str, ...]:
        """The keywords of this config, in field order."""
        return tuple(keyword_paths(cls))

    def keywords(self) -> dict[str, Any]:
        """Every keyword and its resolved value (``from_keywords(**config.keywords()) == config``)."""
        return {keyword: _get(self, path) for keyword, path in keyword_paths(type(self)).items()}

    def replace(self, **keywords) -> Self:
        """This config with some keywords changed (checked as ``from_keywords`` checks them)."""
        return from_keywords(type(self), {**self.keywords(), **keywords})


# --- the groups ------------------------------------------------------------------------------
@checked_config
class PhysicsConfig:
    """The character's servos and the policy rate."""

    pd_gains: str = checked("soft", Check("choice", options=tuple(PD_GAINS)), "PD gain preset of the servos")
    frame_skip: int = checked(8, Check("int", 1, 100), "physics steps per action (240 Hz physics -> 30 Hz policy)")


@checked_config
class RenderConfig:
    render_mode: str | None = checked(None, Check("choice", options=RENDER_MODES, optional=True),
                                     '"rgb_array" (frames from render()) or "human" (a window); None = no rendering')
    width: int = checked(640, Check("int", 16, 4096), "rgb_array frame width")
    height: int = checked(480, Check("int", 16, 4096), "rgb_array frame height")


@checked_config
class InterLevelRewardConfig:
    """Which reward, its terms' weights (``InterLevelReward``, the kernels' array) and the bonuses."""

    kind: str = checked("interlevel", Check("choice", options=REWARDS, keyword="reward"),
                        '"interlevel" or "interscene" (2-D baseline)')
    terms: InterLevelReward = group(InterLevelReward, checks_keywords=False)
    success_reward: float = checked(10.0, Check("float"), "bonus on reaching M_T")
    failure_reward: float = checked(-1.0, Check("float"), "reward of the step that ends in a fall")


@checked_config
class InterLevelTermination:
    success_radius: float = checked(0.5, Check("float", 0.0, 10.0, low_open=True),
                                    "horizontal distance to M_T that counts as arrived (m)")
    terminate_on_success: bool = checked(True, Check("bool"), "end the episode on success")
    termination_height: float = checked(0.2, UNIT, "min vertical head-hips and hips-foot gap (m)")


@checked_config
class InterLevelStart:
    start_radius: float = checked(1.0, Check("float", 0.0, 10.0),
                                  "start position uniform in this disc around the centre (m)")
    random_start_heading: bool = checked(True, Check("bool"), "start heading uniform; False = facing the stairs")
    reset_noise_scale: float = checked(0.05, UNIT, "uniform noise on joint angles at reset (rad)")


@checked_config
class ReferenceStarts:
    """Reference-state starts (``HumanoidEnv._setup_starts``), a training aid of every family."""

    init: str = checked("default", Check("choice", options=INITS),
                        'start pose: "default" (standing), "reference" (a frame of a level-ground clip), "hybrid"')
    reference_motion: str | None = checked(None, Check("call", call=_reference_motion, optional=True),
                                           "folder / .npz of reference clips; None = the env's built-in set "
                                           "(InterLevel's synthesised walks, PlaMo's builtin:plamo, SIMS' builtin:sims)")
    hybrid_fraction: float = checked(0.5, UNIT,
                                     'share of episodes that start from a reference frame with init="hybrid"')


@checked_config
class FamilyTrainingAids(ReferenceStarts):
    """The training aids of every family: reference-state starts and pushes (``HumanoidEnv._setup_pushes``):
    kicks of ``push_speed`` m/s (drawn from the range) added to the root's horizontal velocity in a random
    direction, one every ``push_interval`` seconds (drawn from the range; the first that long after the
    start), so that a policy learns to recover (legged_gym's ``push_robots``). Off by default."""

    push_speed: tuple[float, float] | None = checked(
        None, Check("pair", 0.0, 10.0, optional=True),
        "training pushes: each kick's speed (m/s) drawn from this (min, max), in a random direction; None = none")
    push_interval: tuple[float, float] = checked(
        (2.0, 5.0), Check("pair", 0.05, 3600.0),
        "seconds between training pushes, drawn from this (min, max) (the first: after the start)")


@checked_config
class ClipTracking(FamilyTrainingAids):
    """DeepMimic's imitation, a training aid of every family whose starts can come from a clip (PlaMo: a
    reference start or its ``standing_clip``; SIMS: an interaction start; InterLevel: a stair start): on such
    a start the clip is played on from the start frame and the reward gains its tracking terms
    (``tasks.terms.tracking_terms``: the root's position and velocity, the bodies' positions about the root),
    the episode ends once the bodies are on average ``max_track_error`` from the clip's. Off by default."""

    track_reward: float = checked(0.0, Check("float", 0.0, 10.0),
                                  "weight of the clip-tracking terms on starts from a clip (reward_track_root, "
                                  "_velocity, _bodies: the start clip played on, placed where the character "
                                  "started; tasks.terms.tracking_terms); 0 = off")
    max_track_error: float | None = checked(
        None, Check("float", 0.0, 10.0, low_open=True, optional=True),
        "mean distance (m) of the bodies from the played-on start clip's that ends the episode of a start from "
        "a clip (info track_lost): a pose-distance termination; None = off")


@checked_config
class InterLevelTrainingAids(ClipTracking):
    """What only shapes training: the final evaluation builds its env without these keywords
    (``baselines/train_ppo.py``'s ``evaluation_kwargs``). All off by default (the paper's protocol)."""

    stairs_start_fraction: float = checked(0.0, UNIT, "share of episodes that start from a frame of a climb "
                                           "synthesised for their staircase")
    stall_seconds: float | None = checked(None, Check("float", 0.0, 3600.0, low_open=True, optional=True),
                                          "end an episode that has not come stall_distance closer "
                                          "to M_T for this long; None = never")
    stall_distance: float = checked(0.2, Check("float", 0.0, 100.0),
                                    "least approach to M_T (m) that counts as progress for stall_seconds")
    hold_target_reward: float | None = checked(
        None, Check("float", 0.0, 1000.0, optional=True),
        "episodes go on after success, each step with the root at M_T paid this instead of one success_reward "
        "and the end; None = the paper's end")
    step_height_levels: int = checked(0, Check("int", 0, 100),
                                      "split step_height into this many levels of a success-driven curriculum; "
                                      "0 = off")
    curriculum_demote_below: float = checked(curriculum.DEMOTE_BELOW, UNIT,
                                             "move a level down when a floor-start episode ends below this "
                                             "progress without success")
    curriculum_promote_at: float | None = checked(
        None, Check("float", 0.0, 1.0, optional=True, low_from="curriculum_demote_below"),
        "also move a level up when a floor-start episode ends at this progress; None = success only")


# the stairs' fields under the env's keywords (StairsConfig's own errors say "distance", "yaw")
KEYWORD_NAMES = {("stairs", "distance"): "stairs_distance", ("stairs", "yaw"): "stairs_yaw"}


@checked_config
class HumanoidConfig(EnvConfig):
    """What every family's config holds first: the character's physics, rendering and style history."""

    physics: PhysicsConfig = group(PhysicsConfig)
    render: RenderConfig = group(RenderConfig)
    amp_history: int = checked(2, Check("int", 1, 100),
                                "frames of AMP features in info['amp_obs'] (K x 105, oldest first)")


@checked_config
class InterLevelConfig(HumanoidConfig):
    """The whole configuration of an ``InterLevelEnv`` (InterLevel-v0, InterLevel2D-v0,
    InterSceneStairs-v0); ``env.unwrapped.config``. See the module docstring for the keywords."""

    reward: InterLevelRewardConfig = group(InterLevelRewardConfig)
    termination: InterLevelTermination = group(InterLevelTermination)
    start: InterLevelStart = group(InterLevelStart)
    stairs: StairsConfig = group(StairsConfig, checks_keywords=False)
    training_aids: InterLevelTrainingAids = group(InterLevelTrainingAids)

    def __post_init__(self) -> None:
        check_fields(self)
        start_radius, stairs, aids = self.start.start_radius, self.stairs, self.training_aids
        # The character (a disc of ~0.35 m around its root) must start clear of the stairs.
        if stairs.distance[0] < start_radius + 0.5:
            raise ValueError(
                f"stairs_distance min {stairs.distance[0]} must be at least "
                f"start_radius + 0.5 = {start_radius + 0.5} so the character starts clear of the stairs"
            )
        if aids.step_height_levels and stairs.step_height_set is not None:
            raise ValueError("step_height_levels needs a step_height range; it cannot split step_height_set")
        if aids.stairs_start_fraction > 0.0:
            stair_starts.check_staircases(stairs.step_height_set or stairs.step_height, stairs.step_depth)
        if (aids.track_reward or aids.max_track_error is not None) and not aids.stairs_start_fraction > 0.0:
            raise ValueError("track_reward and max_track_error act on stair starts (the climb tracked from the "
                             "start frame): they need stairs_start_fraction > 0; leave them 0.0 and None")

# --- PlaMo ------------------------------------------------------------------------------------
PATH_GENERATORS = ("coupled", "naive")
# Bound on a height field's samples (terrain_size / terrain_cell_size + 1 per side, squared): 2001^2,
# e.g. 200 m at 0.1 m or 20 m at 0.01 m. Building one costs ~52 bytes a sample (the spec's
# zero list, the model's field, the heights; measured), so ~200 MB at the bound.
MAX_TERRAIN_CELLS = 2001 ** 2
TERRAIN_BYTES_PER_CELL = 52


def _locomotion(value) -> Locomotion:
    if not isinstance(value, (str, Locomotion)):
        raise TypeError(f"locomotion must be None, a name ({sorted(LOCOMOTIONS)}) or a Locomotion, "
                        f"got {type(value).__name__}")
    return get_locomotion(value)  # ValueError names it


@checked_config
class PlaMoTerrain:
    """The terrain: its kind, size and resolution of its height samples ([2, 200] and [0.01, 1] m, checked
    when the env builds its model), at most ``MAX_TERRAIN_CELLS`` samples (checked first: it allocates)."""

    kind: str = checked("mixed", Check("choice", options=TERRAIN_KINDS, keyword="terrain"),
                        '"flat", "slope", "rough", "stairs" or "mixed"')
    size: float = checked(16.0, Check("float", 0.0, math.inf, low_open=True, keyword="terrain_size"),
                          "height field side (m), in [2, 200]; at most 2001^2 samples")
    cell_size: float = checked(0.1, Check("float", 0.0, math.inf, low_open=True, keyword="terrain_cell_size"),
                               "height field resolution (m), in [0.01, 1]")

    def __post_init__(self) -> None:
        check_fields(self)
        check_grid(("terrain_size", "terrain_cell_size"), (self.size,) * 2, self.cell_size, MAX_TERRAIN_CELLS,
                   TERRAIN_BYTES_PER_CELL)


@checked_config
class PlaMoPaths:
    locomotion: str | Locomotion | None = checked(None, Check("call", call=_locomotion, optional=True),
                                                  f"restrict paths to one locomotion ({', '.join(LOCOMOTIONS)}"
                                                  "; a name or a Locomotion); None = any head height 0.4-1.47 m")
    path_generator: str = checked("coupled", Check("choice", options=PATH_GENERATORS),
                                  '"coupled" (PlaMo) or "naive" (speed independent of height)')
    episode_seconds: float = checked(10.0, Check("float", 1.0, 600.0),
                                     "path length in time (s; the preset's time limit matches)")
    constant_paths: bool = checked(False, Check("bool"), "one head height, speed and turn rate per path "
                                   "(PlaMo's Table 2 protocol); False = new ones every 2-5 s")


@checked_config
class PlaMoObservation:
    heightmap_size: int = checked(16, Check("int", 1, 128), "egocentric heightmap samples per side")
    heightmap_extent: float = checked(2.0, Check("float", 0.1, 10.0), "egocentric heightmap extent (m)")


@checked_config
class PlaMoTermination:
    max_xy_error: float = checked(2.0, Check("float", 0.0, 100.0, low_open=True),
                                  "head-target distance on the ground that ends the episode (m)")
    min_head_height: float = checked(0.15, UNIT, "head height above the terrain that ends the episode (m)")


@checked_config
class PlaMoTrainingAids(ClipTracking):
    """What only shapes training (dropped by the final evaluation); off by default."""

    matched_starts: bool = checked(True, Check("bool"), "a reference start is a frame of the path's opening "
                                   "locomotion (acts only with reference starts)")
    speed_levels: int = checked(0, Check("int", 0, 100),
                                "levels of a success-driven curriculum scaling path speeds by (k + 1) / N; 0 = off")
    speed_levels_by_locomotion: bool = checked(
        False, Check("bool"), "with speed_levels: a level per locomotion type in each world, each path sample's "
        "speed scaled by its locomotion's level, instead of one level per world")
    min_root_height: float | None = checked(
        None, Check("float", 0.0, 2.0, low_open=True, optional=True),
        "pelvis height above the terrain that ends an episode while the path asks for more than a crawl; "
        "None = off")
    max_z_error: float | None = checked(
        None, Check("float", 0.0, 10.0, low_open=True, optional=True),
        "head height (m) below its target that ends an episode: no going on all fours where the path asks "
        "to walk; None = off")
    max_z_above: float | None = checked(
        None, Check("float", 0.0, 10.0, low_open=True, optional=True),
        "head height (m) above its target that ends an episode: no walking upright where the path asks to "
        "crouch or crawl; None = off")
    z_above_grace: float = checked(1.0, Check("float", 0.0, 10.0),
                                   "seconds to get down: max_z_above acts from this far into an episode and "
                                   "judges the highest head the path asked for over the last this many")
    aid_grace: float = checked(0.0, Check("float", 0.0, 10.0),
                               "seconds over which min_root_height and max_z_error judge the lowest head the "
                               "path asked for, so a rise from a crawl has time; 0 = the target of the instant")
    pose_reward: float = checked(0.0, Check("float", 0.0, 10.0),
                                 "weight of a pose-imitation term (reward_pose) on reference starts: the start "
                                 "clip played on from the start frame; 0 = off")
    pose_sharpness: float = checked(2.0, Check("float", 0.0, 100.0, low_open=True),
                                    "k of reward_pose = pose_reward exp(-k sum_j (q_ref_j - q_j)^2) (rad^-2; "
                                    "DeepMimic's 2)")
    clip_paths: bool = checked(False, Check("bool"), "on a reference start the path is the start clip's own "
                               "head, played on from the start frame (a looping clip cycle after cycle), so "
                               "the path asks for the clip's travel")
    track_rate: tuple[float, float] = checked(
        (1.0, 1.0), Check("pair", 0.25, 5.0),
        "each tracked clip (a reference start's, a standing_clip) is played this many times as fast, drawn per "
        "episode from (min, max): the same poses at another cadence and speed")
    track_turn_rate: float = checked(
        0.0, Check("float", 0.0, 3.0),
        "each tracked clip is bent to turn at a rate (rad/s) drawn per episode from [-this, this] "
        "(motion.tracking.bend); 0 = as captured")
    standing_clip: str | None = checked(
        None, Check("call", call=_standing_clip, optional=True),
        "a clip (.npz), or a folder of them (one drawn per episode), that a standing start tracks from its "
        "first frame (a get-down into a crawl): the pose and tracking aids and clip_paths act on it as on a "
        "reference start's clip; None = off")


@checked_config
class PlaMoConfig(HumanoidConfig):
    """The whole configuration of a ``PlaMoEnv`` (PlaMo-v0, PlaMoNaivePaths-v0); ``env.unwrapped.config``.
    (``PlaMoSceneEnv``'s is a ``PlaMoSceneConfig``, whose ``path_follower()`` is one of these.)"""

    terrain: PlaMoTerrain = group(PlaMoTerrain)
    paths: PlaMoPaths = group(PlaMoPaths)
    observation: PlaMoObservation = group(PlaMoObservation)
    termination: PlaMoTermination = group(PlaMoTermination)
    training_aids: PlaMoTrainingAids = group(PlaMoTrainingAids)


# --- PlaMo in a scene (PlaMoSceneEnv) -----------------------------------------------------------
SCENE_KINDS = ("random", "slalom")
SPEED_PROFILES = ("planned", "constant")
SLALOM_LANDMARKS = ("start", "goal")
# Bound on the scene's height-map samples, as PlaMoEnv's on its height field (2001^2, e.g. 100 m
# at 0.05 m); a scene costs ~175 bytes a sample (height map, costmaps, the model's field; measured),
# so ~670 MB at the bound.
SCENE_BYTES_PER_CELL = 175


def scene_config(scene: dict[str, Any] | SceneConfig | None) -> SceneConfig:
    """The ``scene`` keyword (``SceneConfig`` fields, or a ``SceneConfig``) as a config; errors name the
    keyword, and a height map over ``MAX_TERRAIN_CELLS`` samples is refused before anything allocates it."""
    if isinstance(scene, SceneConfig):
        config = scene
    else:
        names = [field.name for field in fields(SceneConfig)]
        try:
            config = SceneConfig(**check_mapping("scene", {} if scene is None else scene, names))
        except (TypeError, ValueError) as error:
            if str(error).startswith("scene"):
                raise
            raise type(error)(f"scene: {error}") from error  # SceneConfig names only its field
    check_grid(("scene['size']", "scene['cell_size']"), config.size, config.cell_size,
               MAX_TERRAIN_CELLS, SCENE_BYTES_PER_CELL)
    return config


def check_landmark_room(config: SceneConfig) -> None:
    """``ValueError`` naming the ``scene`` keywords when ``num_landmarks`` discs ``landmark_separation``
    apart cannot fit in ``size`` at all (generation would fail at every reset). A necessary condition
    only: half-open squares of side ``separation / sqrt(2)`` each hold at most one centre."""
    if config.landmark_separation <= 0.0:
        return
    side = config.landmark_separation / math.sqrt(2.0)
    margin = max(config.landmark_radius - config.cell_size, 0.0)  # centres keep their disc in the scene
    fits = 1
    for extent in config.size:
        fits *= max(math.ceil(max(extent - 2.0 * margin, 0.0) / side), 1)
    if fits < config.num_landmarks:
        # the least square size that passes this check: ceil(sqrt(n)) squares along each side
        per_side = math.isqrt(config.num_landmarks - 1) + 1
        least = math.ceil((2.0 * margin + (per_side - 1) * side) * 100.0) / 100.0  # rounded up to cm
        raise ValueError(f"scene: {config.num_landmarks} landmarks (scene['num_landmarks']) "
                         f"{config.landmark_separation:g} m apart (scene['landmark_separation']) cannot fit in a "
                         f"scene of size {config.size} (scene['size']): at most {fits} do; a square scene's "
                         f"size must exceed ({least:g}, {least:g}) m (a minimum: generation may need more)")


def check_instructions(text: str, landmarks) -> None:
    """``InstructionError`` (a ``ValueError``) naming the ``instructions`` keyword unless ``text`` parses
    with ``landmarks``."""
    try:
        parse_instructions(text, landmarks)
    except InstructionError as error:
        raise InstructionError(f"instructions {quote(text)}: {error}") from None


def _scene(value) -> SceneConfig:
    config = scene_config(value)
    check_landmark_room(config)
    return config


def _instructions(value) -> str:
    return check_str("instructions", value)


@checked_config
class PlaMoSceneWorld:
    """The scenes: generated ones (``scene``: ``SceneConfig``'s fields) or the slalom, and how often a new
    one is built."""

    # None resolved: SceneConfig() (the config holds the scene's whole SceneConfig)
    config: dict[str, Any] | SceneConfig | None = checked(
        None, Check("call", call=_scene, keyword="scene"),
        "keyword arguments of stairenv.world.scenes.SceneConfig (a dict, or a SceneConfig); None = its "
        "defaults; at most 2001^2 height-map samples (scene['size'] / scene['cell_size'] + 1 per side)")
    kind: str = checked("random", Check("choice", options=SCENE_KINDS, keyword="scene_kind"),
                        '"random" (generated) or "slalom" (the paper\'s test, "Run to the goal")')
    resample_every: int = checked(10, Check("int", 1, 10**9, keyword="scene_resample_every"),
                                  "resets between new random scenes (building one costs ~40 ms, planning ~15 ms); "
                                  "a seeded reset builds one too")


@checked_config
class PlaMoScenePlanner:
    """What is planned (the instructions) and how: the speed profile and the replanning around the ball."""

    instructions: str | None = checked(
        None, Check("call", call=_instructions, optional=True),
        'instruction text, e.g. "Walk to the tree, then crawl from the tree to the swing", checked against '
        "the scene's landmark names; None = random over the scene's landmarks")
    speed_profile: str = checked("planned", Check("choice", options=SPEED_PROFILES),
                                 '"planned" (the speed QP) or "constant" (constant_speed along the same path; '
                                 "a detour around the moving ball is timed by the speed QP)")
    constant_speed: float = checked(1.5, Check("float", 0.0, 10.0, low_open=True),
                                    'speed with speed_profile="constant" (m/s)')
    replan_horizon: float = checked(1.5, Check("float", 0.0, 10.0, low_open=True),
                                    "collision look-ahead along the planned route (s)")
    replan_every: float = checked(0.5, Check("float", 0.0, 10.0, low_open=True),
                                  "period of the collision check, and of replanning around the ball (s)")


@checked_config
class PlaMoSceneTermination:
    success_radius: float = checked(0.75, Check("float", 0.0, 10.0, low_open=True),
                                    "head distance on the ground to the last landmark's centre that counts as "
                                    "arrived, after the planned arrival time (m)")
    max_xy_error: float = checked(3.0, Check("float", 0.0, 100.0, low_open=True),
                                  "head-target distance on the ground that ends the episode (m)")


@checked_config
class PlaMoSceneConfig(HumanoidConfig):
    """The whole configuration of a ``PlaMoSceneEnv`` (PlaMoScene-v0); ``env.unwrapped.config``. Its path
    follower is the ``PlaMoEnv`` of ``path_follower()`` (flat terrain, the other fields at their defaults:
    the scene replaces the terrain)."""

    scene: PlaMoSceneWorld = group(PlaMoSceneWorld)
    planner: PlaMoScenePlanner = group(PlaMoScenePlanner)
    observation: PlaMoObservation = group(PlaMoObservation)
    termination: PlaMoSceneTermination = group(PlaMoSceneTermination)

    def __post_init__(self) -> None:
        check_fields(self)
        if self.planner.instructions is not None:  # unknown verbs and landmarks fail now, not at reset
            check_instructions(self.planner.instructions, SLALOM_LANDMARKS if self.scene.kind == "slalom"
                               else self.scene.config.landmark_names)

    def path_follower(self) -> PlaMoConfig:
        """The ``PlaMoConfig`` of the path follower: these physics, rendering, style history, observation
        and ``max_xy_error``, on flat terrain."""
        return PlaMoConfig(physics=self.physics, render=self.render, amp_history=self.amp_history,
                           terrain=PlaMoTerrain(kind="flat"), observation=self.observation,
                           termination=PlaMoTermination(max_xy_error=self.termination.max_xy_error))


# --- the keyword tables of the env docstrings ------------------------------------------------------
KEYWORD_TABLE = "{keyword table}"  # the line of an env's docstring that ``document_keywords`` replaces


def _shown_default(value) -> str:
    """A default as a docstring table shows it (a Python literal: ``"soft"``, ``(0.05, 0.2)``, ``6.283``)."""
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, float):
        text = repr(value)
        return text if len(text) <= 8 else f"{value:.4g}"
    if isinstance(value, tuple):
        return "(" + ", ".join(map(_shown_default, value)) + ")"
    return repr(value)


def keyword_table(cls: type) -> str:
    """The markdown table of the keywords of config ``cls``: keyword, default, valid values and meaning,
    all read from the fields (``checked``: default, ``Check``, help), in keyword order."""
    rows = ["| keyword | default | valid | meaning |", "|---|---|---|---|"]
    for keyword, path in keyword_paths(cls).items():
        field = _leaf_field(cls, path)
        check = field_check(field)
        valid = check.valid()
        meaning = field.metadata.get("doc", "") + (" (training aid)" if path[0] == "training_aids" else "")
        rows.append(f"| {keyword} | {_shown_default(field.default)} | {valid} | {meaning} |")
    return "\n".join(rows)


def document_keywords(cls: type):
    """Class decorator: the line ``{keyword table}`` of the class's docstring becomes ``keyword_table(cls)``
    (at that line's indent), so an env's docstring lists its config's keywords and defaults."""
    def decorate(env_cls: type) -> type:
        doc = env_cls.__doc__
        if doc is None:  # python -OO
            return env_cls
        lines = doc.split("\n")
        at = [i for i, line in enumerate(lines) if line.strip() == KEYWORD_TABLE]
        if len(at) != 1:
            raise ValueError(f"{env_cls.__name__}'s docstring must hold one line {KEYWORD_TABLE}")
        indent = lines[at[0]][:len(lines[at[0]]) - len(lines[at[0]].lstrip())]
        table = [indent + row for row in keyword_table(cls).split("\n")]
        env_cls.__doc__ = "\n".join(lines[:at[0]] + table + lines[at[0] + 1:])
        return env_cls
    return decorate


# --- keywords <-> fields ----------------------------------------------------------------------
def keyword_paths(cls: type) -> dict[str, tuple[str, ...]]:
    """keyword -> path of field names from the config ``cls`` to the leaf, in field order."""
    paths = {}

    def walk(klass: type, prefix: tuple[str, ...]) -> None:
        for field in fields(klass):
            path = (*prefix, field.name)
            nested = _group_of(field)
            if nested is not None:
                walk(nested, path)
            else:
                check = field_check(field)
                keyword = KEYWORD_NAMES.get(path) or (check.keyword if check else None) or field.name
                paths[keyword] = path
    walk(cls, ())
    return paths


def _leaf_field(cls: type, path: tuple[str, ...]) -> dataclasses.Field:
    for name in path[:-1]:
        cls = _group_of({f.name: f for f in fields(cls)}[name])
    return {f.name: f for f in fields(cls)}[path[-1]]


def _get(config, path: tuple[str, ...]):
    for name in path:
        config = getattr(config, name)
    return config


def group_keywords(cls: type, group_name: str) -> tuple[str, ...]:
    """The keywords of the fields of group ``group_name`` (``"training_aids"``) of config ``cls``."""
    return tuple(k for k, path in keyword_paths(cls).items() if path[0] == group_name)


def keyword_signature(cls: type) -> inspect.Signature:
    """``(self, *, keyword=default, ...)`` of config ``cls``: an env's constructor's signature."""
    parameters = [inspect.Parameter("self", inspect.Parameter.POSITIONAL_OR_KEYWORD)]
    for keyword, path in keyword_paths(cls).items():
        field = _leaf_field(cls, path)
        parameters.append(inspect.Parameter(keyword, inspect.Parameter.KEYWORD_ONLY, default=field.default,
                                            annotation=field.type))
    return inspect.Signature(parameters)


def unchecked_keywords(cls: type) -> tuple[str, ...]:
    """The keywords of config ``cls`` whose group does not check them typed under their names
    (``group(..., checks_keywords=False)``): ``from_keywords`` checks these itself."""
    def within(klass: type, path: tuple[str, ...]) -> bool:
        for name in path[:-1]:
            field = {f.name: f for f in fields(klass)}[name]
            if not field.metadata.get("checks_keywords", True):
                return True
            klass = _group_of(field)
        return False
    return tuple(k for k, path in keyword_paths(cls).items() if within(cls, path))


def from_keywords(cls: type, keywords: dict[str, Any]):
    """The config ``cls`` of these keywords (the rest at their defaults). Each keyword is checked once
    under its name, by its field's ``Check`` (typed): by its group's ``check_fields``, or here first
    where the group is another layer's dataclass (``unchecked_keywords``: the stairs, the reward terms),
    which then checks the ranges under its own names."""
    paths = keyword_paths(cls)
    unknown = [k for k in keywords if k not in paths]
    if unknown:
        raise TypeError(f"{cls.__name__} got unexpected keyword argument(s) {unknown}; valid: {list(paths)}")
    values = dict(keywords)
    for keyword in unchecked_keywords(cls):
        if keyword in values:
            values[keyword] = field_check(_leaf_field(cls, paths[keyword]))(keyword, values[keyword])
    by_path = {path: keyword for keyword, path in paths.items()}

    def build(klass: type, prefix: tuple[str, ...]):
        kwargs = {}
        for field in fields(klass):
            path = (*prefix, field.name)
            nested = _group_of(field)
            if nested is not None:
                kwargs[field.name] = build(nested, path)
            elif by_path[path] in values:
                kwargs[field.name] = values[by_path[path]]
        return klass(**kwargs)
    return build(cls, ())


def resolve(cls: type, config, keywords: dict[str, Any]):
    """An env's config: ``config`` (an instance of ``cls``) or, without one, the keywords' config.

    Keywords given beside a config (``gym.make(id, config=...)`` adds the preset's) must agree with it:
    a config is the whole configuration, so a keyword that would change it is an error, not silently
    dropped or applied. A preset's config is ``cls.from_toml(path)``."""
    if config is None:
        return from_keywords(cls, keywords)
    if not isinstance(config, cls):
        raise TypeError(f"config must be a {cls.__name__}, got {type(config).__name__}")
    if keywords:
        given = config.keywords()
        # the keywords resolved as they would be over the config (4.0 is 4, None w_scale the ratio)
        changed = from_keywords(cls, {**given, **keywords}).keywords()
        disagree = [k for k in keywords if changed[k] != given[k]]
        if disagree:
            raise ValueError(
                f"keywords {', '.join(f'{k}={keywords[k]!r}' for k in disagree)} disagree with config "
                f"({', '.join(f'{k}={given[k]!r}' for k in disagree)}); give the config alone, or one that "
                f"has them (a preset's keywords come with its id: {cls.__name__}.from_toml(envs/<id>.toml))")
    return config


__all__ = ["EnvConfig", "FamilyTrainingAids", "HumanoidConfig", "InterLevelConfig", "InterLevelRewardConfig",
           "InterLevelStart", "InterLevelTermination", "InterLevelTrainingAids", "PhysicsConfig", "PlaMoConfig",
           "PlaMoObservation", "PlaMoPaths", "PlaMoSceneConfig", "PlaMoScenePlanner", "PlaMoSceneTermination",
           "PlaMoSceneWorld", "PlaMoTerrain", "PlaMoTermination", "PlaMoTrainingAids", "ReferenceStarts",
           "RenderConfig", "document_keywords", "from_keywords", "group_keywords", "keyword_paths",
           "keyword_signature", "keyword_table", "resolve", "unchecked_keywords"]
