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
signature is made from the fields (``keyword_signature``), so defaults live in one place.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
import tomllib
from dataclasses import fields
from pathlib import Path
from typing import Any, Self

from stairenv.environments.base import INITS, check_reference_motion
from stairenv.humanoid import PD_GAINS
from stairenv.motion import stair_starts
from stairenv.planning.locomotion import LOCOMOTIONS, Locomotion, get_locomotion
from stairenv.rendering import RENDER_MODES
from stairenv.tasks import curriculum
from stairenv.tasks.interlevel import InterLevelReward
from stairenv.validation import Check, check_fields, check_grid, checked, checked_config, field_check
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

    pd_gains: str = checked("soft", Check("choice", options=tuple(PD_GAINS)), "PD gain preset")
    frame_skip: int = checked(8, Check("int", 1, 100), "physics steps per action (240 Hz physics -> 30 Hz)")


@checked_config
class RenderConfig:
    render_mode: str | None = checked(None, Check("choice", options=RENDER_MODES, optional=True))
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
    start_radius: float = checked(1.0, Check("float", 0.0, 10.0), "start position uniform in this disc (m)")
    random_start_heading: bool = checked(True, Check("bool"), "start heading uniform; False = facing the stairs")
    reset_noise_scale: float = checked(0.05, UNIT, "uniform noise on joint angles at reset (rad)")


@checked_config
class ReferenceStarts:
    """Reference-state starts (``HumanoidEnv._setup_starts``), a training aid of every family."""

    init: str = checked("default", Check("choice", options=INITS),
                        'start pose: "default" (standing), "reference", "hybrid"')
    reference_motion: str | None = checked(None, Check("call", call=_reference_motion, optional=True),
                                           "folder / .npz of reference clips; None = the env's built-in set")
    hybrid_fraction: float = checked(0.5, UNIT, 'share of reference starts with init="hybrid"')


@checked_config
class InterLevelTrainingAids(ReferenceStarts):
    """What only shapes training: the final evaluation builds its env without these keywords
    (``baselines/train_ppo.py``'s ``evaluation_kwargs``). All off by default (the paper's protocol)."""

    stairs_start_fraction: float = checked(0.0, UNIT, "share of episodes that start on a climb of their stairs")
    stall_seconds: float | None = checked(None, Check("float", 0.0, 3600.0, low_open=True, optional=True),
                                          "end an episode that has not come closer to M_T for this long")
    stall_distance: float = checked(0.2, Check("float", 0.0, 100.0), "least approach (m) that counts")
    step_height_levels: int = checked(0, Check("int", 0, 100), "levels of the step-height curriculum; 0 = off")
    curriculum_demote_below: float = checked(curriculum.DEMOTE_BELOW, UNIT,
                                             "a level down when a floor start ends below this progress")
    curriculum_promote_at: float | None = checked(
        None, Check("float", 0.0, 1.0, optional=True, low_from="curriculum_demote_below"),
        "also a level up at this progress; None = success only")


# the stairs' fields under the env's keywords (StairsConfig's own errors say "distance", "yaw")
KEYWORD_NAMES = {("stairs", "distance"): "stairs_distance", ("stairs", "yaw"): "stairs_yaw"}


@checked_config
class HumanoidConfig(EnvConfig):
    """What every family's config holds first: the character's physics, rendering and style history."""

    physics: PhysicsConfig = group(PhysicsConfig)
    render: RenderConfig = group(RenderConfig)
    amp_history: int = checked(2, Check("int", 1, 100), "frames of AMP features in info['amp_obs']")


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
    """The height field: its kind, size and resolution ([2, 200] and [0.01, 1] m, checked by
    ``HeightfieldSlot``), at most ``MAX_TERRAIN_CELLS`` samples (checked first: it allocates)."""

    kind: str = checked("mixed", Check("choice", options=TERRAIN_KINDS, keyword="terrain"),
                        '"flat", "slope", "rough", "stairs" or "mixed"')
    size: float = checked(16.0, Check("float", 0.0, math.inf, low_open=True, keyword="terrain_size"),
                          "height field side (m)")
    cell_size: float = checked(0.1, Check("float", 0.0, math.inf, low_open=True, keyword="terrain_cell_size"),
                               "height field resolution (m)")

    def __post_init__(self) -> None:
        check_fields(self)
        check_grid(("terrain_size", "terrain_cell_size"), (self.size,) * 2, self.cell_size, MAX_TERRAIN_CELLS,
                   TERRAIN_BYTES_PER_CELL)


@checked_config
class PlaMoPaths:
    locomotion: str | Locomotion | None = checked(None, Check("call", call=_locomotion, optional=True),
                                                  "restrict paths to one locomotion; None = any")
    path_generator: str = checked("coupled", Check("choice", options=PATH_GENERATORS),
                                  '"coupled" (PlaMo) or "naive" (speed independent of height)')
    episode_seconds: float = checked(10.0, Check("float", 1.0, 600.0), "path length in time (s)")
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
class PlaMoTrainingAids(ReferenceStarts):
    """What only shapes training (dropped by the final evaluation); off by default."""

    matched_starts: bool = checked(True, Check("bool"), "a reference start is a frame of the path's opening "
                                   "locomotion (acts only with reference starts)")
    speed_levels: int = checked(0, Check("int", 0, 100), "levels of the speed curriculum; 0 = off")
    min_root_height: float | None = checked(
        None, Check("float", 0.0, 2.0, low_open=True, optional=True),
        "pelvis height above the terrain that ends an episode while the path asks for more than a crawl; "
        "None = off")


@checked_config
class PlaMoConfig(HumanoidConfig):
    """The whole configuration of a ``PlaMoEnv`` (PlaMo-v0, PlaMoNaivePaths-v0); ``env.unwrapped.config``.
    (``PlaMoSceneEnv`` builds its path follower from one; its own keywords are not in it yet.)"""

    terrain: PlaMoTerrain = group(PlaMoTerrain)
    paths: PlaMoPaths = group(PlaMoPaths)
    observation: PlaMoObservation = group(PlaMoObservation)
    termination: PlaMoTermination = group(PlaMoTermination)
    training_aids: PlaMoTrainingAids = group(PlaMoTrainingAids)


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


__all__ = ["EnvConfig", "HumanoidConfig", "InterLevelConfig", "InterLevelRewardConfig", "InterLevelStart",
           "InterLevelTermination", "InterLevelTrainingAids", "PhysicsConfig", "PlaMoConfig", "PlaMoObservation",
           "PlaMoPaths", "PlaMoTerrain", "PlaMoTermination", "PlaMoTrainingAids", "ReferenceStarts", "RenderConfig",
           "from_keywords", "group_keywords", "keyword_paths", "keyword_signature", "resolve", "unchecked_keywords"]
