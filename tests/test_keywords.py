"""Every env keyword is checked at construction, with its type: a bad value raises TypeError or
ValueError naming the keyword (issue #13, item 6), nothing else ever escapes a constructor, and
a valid value is accepted (issue #26, item 6: the check can fail both ways)."""

from __future__ import annotations

import importlib
import inspect
import math
import numbers
import re
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest

from stairenv.environments.base import INITS
from stairenv.environments.interlevel import REWARDS, STAIRS_RANGES, InterLevelEnv
from stairenv.environments.plamo import MAX_TERRAIN_CELLS, PATH_GENERATORS, PlaMoEnv
from stairenv.environments.plamo_scene import SCENE_KINDS, SPEED_PROFILES, PlaMoSceneEnv
from stairenv.environments.sims import (
    CURRICULUM_SKILLS,
    GETUP_FROM,
    MAX_TEXT_DIM,
    NEAR_START_SKILLS,
    SCENES,
    TEXT_ENCODERS,
    SIMSEnv,
    host_families,
    skill_captions,
)
from stairenv.humanoid import PD_GAINS
from stairenv.planning.locomotion import LOCOMOTIONS
from stairenv.registration import load_presets
from stairenv.tasks.curriculum import DEMOTE_BELOW
from stairenv.tasks.sims import SKILLS
from stairenv.validation import check_bool, check_grid, check_int, check_pair
from stairenv.world.terrain import TERRAIN_KINDS

FAST_SIMS = {"text_encoder": "hashing"}


def names_keyword(error: Exception, keyword: str) -> bool:
    """The message holds ``keyword`` as a name of its own ("height", not "heightmap_size")."""
    return re.search(rf"(?<!\w){re.escape(keyword)}(?!\w)", str(error)) is not None


def assert_rejected(make, keyword: str, error_types=(TypeError, ValueError)):
    with pytest.raises(error_types) as caught:
        make()
    assert names_keyword(caught.value, keyword), str(caught.value)


# --- the typed checks ------------------------------------------------------------------------
def test_check_bool_takes_only_bools():
    assert check_bool("flag", np.bool_(False)) is False
    for value in ("False", 0, 1, None, 1.0):
        with pytest.raises(TypeError, match="flag must be a bool"):
            check_bool("flag", value)


def test_check_int_never_truncates():
    assert check_int("n", 4.0, 1, 10) == 4 and check_int("n", np.int64(3), 1, 10) == 3
    with pytest.raises(ValueError, match=r"n must be an integer in \[1, 10\], got 2.5"):
        check_int("n", 2.5, 1, 10)
    for value in ("4", True, None, [4]):
        with pytest.raises(TypeError, match="n must be an integer"):
            check_int("n", value, 1, 10)


def test_check_pair_checks_type_and_order():
    assert check_pair("p", [1, 2], 0, 5, integer=True) == (1, 2)
    with pytest.raises(TypeError, match="p must be a"):
        check_pair("p", "ab", 0, 5)
    with pytest.raises(ValueError, match="p: min"):
        check_pair("p", (3, 1), 0, 5)


def test_check_grid_accepts_the_bound_and_refuses_beyond():
    assert check_grid(("size", "cell"), (200.0, 200.0), 0.1, MAX_TERRAIN_CELLS, 52) == MAX_TERRAIN_CELLS
    with pytest.raises(ValueError, match=r"size=200.0 with cell=0.01 .* 20001 x 20001 grid .*GB"):
        check_grid(("size", "cell"), (200.0, 200.0), 0.01, MAX_TERRAIN_CELLS, 52)


# --- item by item ----------------------------------------------------------------------------
BOOL_KEYWORDS = [
    (InterLevelEnv, "progress_scaling"), (InterLevelEnv, "terminate_on_success"),
    (InterLevelEnv, "random_start_heading"), (SIMSEnv, "details"), (SIMSEnv, "text_conditioned"),
    (SIMSEnv, "speed_from_style"), (SIMSEnv, "terminate_on_success"), (PlaMoEnv, "matched_starts"),
]


@pytest.mark.parametrize("value", ["False", 0, 1, None])
@pytest.mark.parametrize("env_cls, keyword", BOOL_KEYWORDS)
def test_bool_keywords_take_only_bools(env_cls, keyword, value):
    extra = FAST_SIMS if env_cls is SIMSEnv else {}
    with pytest.raises(TypeError, match=f"{keyword} must be a bool"):
        env_cls(**extra, **{keyword: value})


INT_KEYWORDS = [
    (InterLevelEnv, "frame_skip", {}), (InterLevelEnv, "amp_history", {}), (InterLevelEnv, "width", {}),
    (InterLevelEnv, "height", {}), (PlaMoEnv, "heightmap_size", {}), (SIMSEnv, "heightmap_size", FAST_SIMS),
    (SIMSEnv, "scene_resample_every", FAST_SIMS), (SIMSEnv, "text_dim", FAST_SIMS),
    (PlaMoSceneEnv, "scene_resample_every", {}),
]


@pytest.mark.parametrize("env_cls, keyword, extra", INT_KEYWORDS)
def test_int_keywords_are_not_truncated(env_cls, keyword, extra):
    assert_rejected(lambda: env_cls(**extra, **{keyword: 16.5}), keyword, ValueError)
    assert_rejected(lambda: env_cls(**extra, **{keyword: "16"}), keyword, TypeError)


@pytest.mark.parametrize("value", [(3.5, 5), ("3", 5), 5])
def test_num_steps_are_integers(value):
    assert_rejected(lambda: InterLevelEnv(num_steps=value), "num_steps")


@pytest.mark.parametrize("keyword, value", [
    ("stairs_distance", (0.1, 3.0)), ("stairs_distance", (3.0, 2.0)), ("stairs_distance", "far"),
    ("stairs_yaw", (0.0, 10.0)), ("stairs_yaw", 1.0), ("stairs_yaw", (0.0, float("nan"))),
])
def test_stairs_errors_name_the_env_keyword(keyword, value):
    assert_rejected(lambda: InterLevelEnv(**{keyword: value}), keyword)


@pytest.mark.parametrize("env_cls, extra", [(InterLevelEnv, {}), (PlaMoEnv, {}), (SIMSEnv, FAST_SIMS)])
@pytest.mark.parametrize("value", ["no/such/clips", "builtin:nothing", 3, ["a.npz"]])
def test_reference_motion_is_checked_whatever_init(env_cls, extra, value):
    assert_rejected(lambda: env_cls(init="default", reference_motion=value, **extra), "reference_motion")


def test_unreadable_reference_motion_fails_at_construction(tmp_path):
    (tmp_path / "clip.npz").write_text("not a clip")
    assert_rejected(lambda: InterLevelEnv(reference_motion=str(tmp_path / "clip.npz")), "reference_motion", ValueError)
    assert_rejected(lambda: PlaMoEnv(reference_motion=tmp_path / "none"), "reference_motion", ValueError)


class _Encoder:
    model_id, dim = "test-encoder", 32

    def encode(self, texts):
        return np.ones((len(texts), self.dim), dtype=np.float32) / np.sqrt(self.dim)


@pytest.mark.parametrize("kwargs, keyword", [
    ({"text_encoder": "clip"}, "text_encoder"),
    ({"text_encoder": 3}, "text_encoder"),
    ({"text_encoder": object()}, "text_encoder"),
    ({"text_encoder": _Encoder(), "text_dim": 64}, "text_dim"),
    ({"text_encoder": "hashing", "text_dim": 4}, "text_dim"),
    ({"text_encoder": "hashing", "text_dim": 0}, "text_dim"),
    ({"text_encoder": "hashing", "text_dim": "64"}, "text_dim"),
    ({"captions": "walks over"}, "captions"),
    ({"captions": []}, "captions"),
    ({"captions": [("neutral",)]}, "captions"),
    ({"captions": [("neutral", 3)]}, "captions"),
    ({"captions": [("neutral", "")]}, "captions"),
    ({"condition_captions": "walk"}, "condition_captions"),
    ({"condition_captions": [("happy", "walk"), ("happy", "skip")]}, "condition_captions"),
    ({"condition_captions": [("happy", "walk")]}, "condition_captions"),  # the other styles have no text
    ({"condition_captions": [("happy", "walk")], "captions": [("happy", "skips")], "text_conditioned": False},
     "condition_captions"),
    ({"skill": "sit", "families": ("table",)}, "families"),
    ({"skill": "lie", "families": ("chair",)}, "families"),
    ({"skill": "getup", "getup_from": "lie", "families": ("stool",)}, "families"),
    ({"families": "chair"}, "families"),
    ({"families": {"chair", "stool"}}, "families"),  # no fixed order: seeded scenes would differ
    ({"families": ()}, "families"),
    ({"room": "kitchen"}, "room"),
])
def test_sims_text_captions_and_families_fail_at_construction(kwargs, keyword):
    assert_rejected(lambda: SIMSEnv(**{"text_encoder": "hashing", **kwargs}), keyword)


def test_sims_fixed_room_must_hold_a_host():
    from stairenv.world.rooms import RoomConfig, generate_room

    room = generate_room(RoomConfig(), np.random.default_rng(0), categories=["table", "lamp"])
    room = type(room)(**{**room.__dict__, "furniture": [p for p in room.furniture if p.family in ("table", "lamp")]})
    assert_rejected(lambda: SIMSEnv(skill="sit", room=room, **FAST_SIMS), "room", ValueError)
    SIMSEnv(skill="walk", room=room, **FAST_SIMS).close()  # walking needs no furniture


def test_getup_from_lying_defaults_to_lying_families():
    env = SIMSEnv(skill="getup", getup_from="lie", **FAST_SIMS)
    assert set(env.families) == {"bed", "double_bed", "sofa"}
    for seed in range(3):  # every scene has something to get up from
        env.reset(seed=seed)
    env.close()


def test_sims_encoder_object_of_the_right_size_is_used():
    env = SIMSEnv(skill="walk", text_encoder=_Encoder(), text_dim=32)
    obs, _ = env.reset(seed=0)
    np.testing.assert_allclose(obs[env.observation_structure["text"]], 1 / np.sqrt(32), rtol=1e-6)
    env.close()


@pytest.mark.parametrize("size, cell", [(200, 0.01), (100, 0.02), (50.0, 0.01)])
def test_plamo_terrain_grid_is_bounded(size, cell):
    with pytest.raises(ValueError) as caught:
        PlaMoEnv(terrain_size=size, terrain_cell_size=cell)
    message = str(caught.value)
    assert "terrain_size" in message and "terrain_cell_size" in message and re.search(r"~[\d.]+ (GB|MB)", message)


def test_plamo_scene_grid_is_bounded():
    assert_rejected(lambda: PlaMoSceneEnv(scene={"size": (200.0, 200.0), "cell_size": 0.01}), "scene['size']")
    assert_rejected(lambda: PlaMoSceneEnv(scene={"no_such_field": 1}), "scene", TypeError)
    assert_rejected(lambda: PlaMoSceneEnv(scene={"cell_size": "fine"}), "scene")


def test_valid_values_of_other_types_still_work():
    # TOML lists, numpy scalars and integral floats are what configs hand over.
    env = InterLevelEnv(progress_scaling=np.bool_(False), frame_skip=4.0, num_steps=[3, 5],
                        step_height=np.array([0.05, 0.1]), width=np.int64(320))
    assert env.frame_skip == 4 and isinstance(env.frame_skip, int) and env.width == 320
    assert env.reward_config.progress_scaling is False
    env.close()


# --- every keyword of every registered id: wrong values refused, valid ones accepted ---------------
# What each keyword takes. The constructors check their keywords in code (``check_float(name, value,
# low, high)`` and the like), with no table to read, so the table is here: the range each keyword
# is checked against, and where another keyword narrows it under the presets' defaults, that
# narrower range (said beside it). Every value a check tries is decided by the kind: valid values
# must be accepted, and every other value refused with a TypeError or ValueError naming the keyword.
def _real(value) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


@dataclass(frozen=True)
class Number:
    """A finite real (not a bool), in [low, high] ((low, high] with ``low_open``); integral with ``integer``
    (an integral float such as 4.0 too)."""

    low: float = -math.inf
    high: float = math.inf
    low_open: bool = False
    integer: bool = False

    def valid(self, value) -> bool:
        if not _real(value) or not math.isfinite(value) or (self.integer and not float(value).is_integer()):
            return False
        return (self.low < value if self.low_open else self.low <= value) and value <= self.high

    def probes(self) -> list:
        """Each finite bound (as a numpy scalar or an integral float) and a step beyond it."""
        step = 1 if self.integer else 0.01
        out = [np.bool_(True)]
        if math.isfinite(self.low):
            out += [float(self.low), self.low - step] + ([self.low + 0.5] if self.integer else [])
        if math.isfinite(self.high):
            out += [np.int64(self.high) if self.integer else np.float64(self.high), self.high + step]
        return out


@dataclass(frozen=True)
class Pair:
    """A (min, max) list, tuple or 1-D array of two reals, low <= min <= max <= high (integers with ``integer``)."""

    low: float
    high: float
    integer: bool = False

    def valid(self, value) -> bool:
        if isinstance(value, np.ndarray) and value.ndim != 1:
            return False
        if not isinstance(value, (list, tuple, np.ndarray)) or len(value) != 2 or not all(map(_real, value)):
            return False
        number = Number(self.low, self.high, integer=self.integer)
        return number.valid(value[0]) and number.valid(value[1]) and value[0] <= value[1]

    def probes(self) -> list:
        step = 1 if self.integer else 0.01
        return [(self.low, self.high), np.array([self.low, self.low], dtype=float),
                (self.high, self.low), (self.low - step, self.high), (self.low, self.high + step),
                (self.low, self.high, self.high), (self.low,), (True, self.high)]


@dataclass(frozen=True)
class Numbers:
    """A non-empty list, tuple or 1-D array of reals in [low, high]."""

    low: float
    high: float

    def valid(self, value) -> bool:
        if isinstance(value, np.ndarray) and value.ndim != 1:
            return False
        return (isinstance(value, (list, tuple, np.ndarray)) and len(value) > 0
                and all(Number(self.low, self.high).valid(v) for v in value))

    def probes(self) -> list:
        return [[self.low], (self.low, self.high, self.high), np.array([self.high]), [], [self.high + 0.01]]


@dataclass(frozen=True)
class Bool:
    def valid(self, value) -> bool:
        return isinstance(value, (bool, np.bool_))

    def probes(self) -> list:
        return [np.bool_(False), "True"]


@dataclass(frozen=True)
class Choice:
    """One of ``choices`` (a str)."""

    choices: tuple[str, ...]

    def valid(self, value) -> bool:
        return isinstance(value, str) and value in self.choices

    def probes(self) -> list:
        return [*self.choices, self.choices[0].upper() + "?", ""]


@dataclass(frozen=True)
class Examples:
    """A structured value (a mapping, a path, a text, objects): the generic probes are all wrong
    for it; ``examples`` are valid ones."""

    examples: tuple = ()

    def valid(self, value) -> bool:
        return any(value is example for example in self.examples)

    def probes(self) -> list:
        return list(self.examples)


@dataclass(frozen=True)
class Optional:
    """None, or a value of ``kind``."""

    kind: Any

    def valid(self, value) -> bool:
        return value is None or self.kind.valid(value)

    def probes(self) -> list:
        return [None, *self.kind.probes()]


UNIT = Number(0.0, 1.0)
COMMON_KINDS = {  # the humanoid keywords every env takes (environments/base.py)
    "pd_gains": Choice(tuple(PD_GAINS)), "frame_skip": Number(1, 100, integer=True),
    "amp_history": Number(1, 100, integer=True), "width": Number(16, 4096, integer=True),
    "height": Number(16, 4096, integer=True),
    "render_mode": Optional(Choice(("rgb_array",))),  # "human" would open a window: left out
    "init": Choice(INITS), "hybrid_fraction": UNIT, "reference_motion": Optional(Examples()),
    # training pushes: every family with training aids (config.FamilyTrainingAids)
    "push_speed": Optional(Pair(0.0, 10.0)), "push_interval": Pair(0.05, 3600.0),
}
KINDS = {
    InterLevelEnv: {
        "reward": Choice(REWARDS), "progress_scaling": Bool(),
        "w_location": Number(0.0), "w_facing": Number(0.0), "w_velocity": Number(0.0),
        "sigma_before": Number(0.0, low_open=True), "sigma_after": Number(0.0, low_open=True),
        "sigma_across": Number(0.0, low_open=True), "w_scale": Optional(Number(0.0)),
        "target_speed": Number(0.0, 10.0), "success_reward": Number(), "failure_reward": Number(),
        "success_radius": Number(0.0, 10.0, low_open=True), "terminate_on_success": Bool(),
        "termination_height": UNIT,
        # checked in [0, 10]; the character must start 0.5 m clear of the stairs (stairs_distance >= 2.0)
        "start_radius": Number(0.0, 1.5),
        "random_start_heading": Bool(),
        "step_height": Pair(*STAIRS_RANGES["step_height"]),
        "step_height_set": Optional(Numbers(*STAIRS_RANGES["step_height"])),
        "step_depth": Pair(*STAIRS_RANGES["step_depth"]), "step_width": Pair(*STAIRS_RANGES["step_width"]),
        "num_steps": Pair(1, 30, integer=True), "landing_depth": Number(1.0, 10.0),
        # checked in [0.5, 20]; its min must be start_radius + 0.5 = 1.5 or more
        "stairs_distance": Pair(1.5, STAIRS_RANGES["stairs_distance"][1]),
        "stairs_yaw": Pair(*STAIRS_RANGES["stairs_yaw"]), "reset_noise_scale": UNIT,
        "stairs_start_fraction": UNIT, "stall_seconds": Optional(Number(0.0, 3600.0, low_open=True)),
        "stall_distance": Number(0.0, 100.0), "hold_target_reward": Optional(Number(0.0, 1000.0)),
        "step_height_levels": Number(0, 100, integer=True),
        "curriculum_promote_at": Optional(Number(DEMOTE_BELOW, 1.0)),  # at least curriculum_demote_below
        "curriculum_demote_below": UNIT,
        # act on stair starts, which no preset has: only the defaults
        "track_reward": Number(0.0, 0.0), "max_track_error": Optional(Number(0.0, 0.0, low_open=True)),
    },
    PlaMoEnv: {
        "terrain": Choice(TERRAIN_KINDS), "locomotion": Optional(Choice(tuple(LOCOMOTIONS))),
        "path_generator": Choice(PATH_GENERATORS), "episode_seconds": Number(1.0, 600.0),
        "terrain_size": Number(2.0, 200.0), "terrain_cell_size": Number(0.01, 1.0),
        "heightmap_size": Number(1, 128, integer=True), "heightmap_extent": Number(0.1, 10.0),
        "max_xy_error": Number(0.0, 100.0, low_open=True), "min_head_height": UNIT, "matched_starts": Bool(),
        "speed_levels": Number(0, 100, integer=True), "speed_levels_by_locomotion": Bool(), "constant_paths": Bool(),
        "min_root_height": Optional(Number(0.0, 2.0, low_open=True)),
        "max_z_error": Optional(Number(0.0, 10.0, low_open=True)), "aid_grace": Number(0.0, 10.0),
        "max_z_above": Optional(Number(0.0, 10.0, low_open=True)), "z_above_grace": Number(0.0, 10.0),
        "pose_reward": Number(0.0, 10.0), "pose_sharpness": Number(0.0, 100.0, low_open=True),
        "track_reward": Number(0.0, 10.0), "max_track_error": Optional(Number(0.0, 10.0, low_open=True)),
        "clip_paths": Bool(), "standing_clip": Optional(Examples()),
        "track_rate": Pair(0.25, 5.0), "track_turn_rate": Number(0.0, 3.0),
    },
    PlaMoSceneEnv: {
        "instructions": Optional(Examples()), "scene": Optional(Examples(({},))),
        "scene_kind": Choice(SCENE_KINDS), "scene_resample_every": Number(1, 10**9, integer=True),
        "speed_profile": Choice(SPEED_PROFILES), "constant_speed": Number(0.0, 10.0, low_open=True),
        "replan_horizon": Number(0.0, 10.0, low_open=True), "replan_every": Number(0.0, 10.0, low_open=True),
        "success_radius": Number(0.0, 10.0, low_open=True), "max_xy_error": Number(0.0, 100.0, low_open=True),
        "heightmap_size": Number(1, 128, integer=True), "heightmap_extent": Number(0.1, 10.0),
    },
    SIMSEnv: {
        "skill": Choice(SKILLS), "scene": Choice(SCENES), "room": Optional(Examples()),
        "families": lambda s: Optional(Examples((list(host_families(s["skill"], s["getup_from"])),))),
        "scene_resample_every": Number(1, 10**9, integer=True), "details": Bool(), "text_conditioned": Bool(),
        "text_encoder": Choice(TEXT_ENCODERS), "text_dim": Number(8, MAX_TEXT_DIM, integer=True),  # hashing
        "captions": lambda s: Optional(Examples((list(skill_captions(s["skill"])),))),
        "start_distance": Pair(0.0, 50.0), "walk_distance": Pair(0.0, 50.0), "target_speed": Pair(0.0, 10.0),
        "speed_from_style": Bool(), "getup_from": Choice(GETUP_FROM),
        "heightmap_size": Number(1, 128, integer=True), "heightmap_extent": Number(0.1, 10.0),
        "fall_height": Number(0.0, 1.5), "terminate_on_success": Bool(),
        # only the near-start skills take near starts, and levels only in object scenes
        "interaction_start_fraction": lambda s: UNIT if s["skill"] in NEAR_START_SKILLS else Number(0.0, 0.0),
        "start_distance_levels": lambda s: Number(0, 100 if s["skill"] in CURRICULUM_SKILLS
                                                  and s["scene"] == "object" else 0, integer=True),
        "stall_seconds": Optional(Number(0.0, 3600.0, low_open=True)), "stall_distance": Number(0.0, 100.0),
        "hold_seconds": Optional(Number(0.0, 3600.0, low_open=True)),
        "near_distance": Optional(Number(0.0, 10.0, low_open=True)),
        # act on interaction starts, which no preset has: only the defaults
        "track_reward": Number(0.0, 0.0), "max_track_error": Optional(Number(0.0, 0.0, low_open=True)),
        # needs start_distance_levels, which no preset sets: only False
        "start_from_front": Examples((False,)),
        # getup starts low: only None (an empty number range) there
        "min_root_height": lambda s: Optional(Number(0.0, 2.0 if s["skill"] != "getup" else 0.0, low_open=True)),
        # one text for each style of the skill's captions, and only where z is observed
        "condition_captions": lambda s: Optional(Examples(
            (sorted({(style, "walk") for style, _ in skill_captions(s["skill"])}),) if s["text_conditioned"] else ())),
    },
}
# Tried on every keyword: wrong for most, valid for some (True for a bool, None for an optional, ...).
VALUES = ["garbage", 2.5, -1, True, None, [1, 2, 3], {"key": 1}, object(), float("nan"), np.array([1.0, 2.0]),
          float("inf"), np.zeros((2, 2))]


def _entry_point(path: str):
    module, name = path.split(":")
    return getattr(importlib.import_module(module), name)


def _keywords(cls) -> dict[str, inspect.Parameter]:
    return {k: p for k, p in inspect.signature(cls.__init__).parameters.items() if k != "self"}


def _kind(cls, keyword: str, settings: dict):
    kind = KINDS[cls].get(keyword) or COMMON_KINDS[keyword]
    return kind(settings) if callable(kind) and not hasattr(kind, "valid") else kind


def _cases():
    """(class, preset kwargs, keyword, edges) for every keyword of every id. ``edges``: also try the
    kind's own values (the bounds and just beyond, every choice); a class's keyword's range does not
    change with the preset, so that is done on the first id of each class, and on every id where the
    preset sets the keyword or the kind depends on the preset."""
    seen = set()
    for env_id, preset in sorted(load_presets().items()):
        cls = _entry_point(preset["entry_point"])
        for keyword in _keywords(cls):
            kind = KINDS[cls].get(keyword) or COMMON_KINDS[keyword]
            edges = (cls, keyword) not in seen or keyword in preset["kwargs"] or not hasattr(kind, "valid")
            seen.add((cls, keyword))
            yield pytest.param(cls, preset["kwargs"], keyword, edges, id=f"{env_id}-{keyword}")


def test_every_keyword_has_a_kind_and_none_only_where_the_signature_allows_it():
    for cls in KINDS:
        for keyword, parameter in _keywords(cls).items():
            settings = {k: p.default for k, p in _keywords(cls).items()}
            kind = _kind(cls, keyword, settings)
            takes_none = "None" in str(parameter.annotation) or parameter.default is None
            assert isinstance(kind, Optional) == takes_none, f"{cls.__name__}.{keyword}: {kind}"
            assert kind.valid(parameter.default), f"{cls.__name__}.{keyword}: default {parameter.default!r}"


@pytest.mark.parametrize("cls, preset_kwargs, keyword, edges", list(_cases()))
def test_keyword_refuses_wrong_values_and_accepts_valid_ones(cls, preset_kwargs, keyword, edges):
    """Every value in turn, all failures reported together."""
    settings = {**{k: p.default for k, p in _keywords(cls).items()}, **preset_kwargs}
    kind = _kind(cls, keyword, settings)
    failures = []
    for value in VALUES + (kind.probes() if edges else []):
        kwargs = {**preset_kwargs, keyword: value}
        if cls is SIMSEnv and keyword != "text_encoder":
            kwargs.setdefault("text_encoder", "hashing")  # no MiniLM needed to check the others
        try:
            env = cls(**kwargs)
        except (TypeError, ValueError) as error:
            if kind.valid(value):
                failures.append(f"refused valid {value!r}: {type(error).__name__}: {error}")
            elif not names_keyword(error, keyword):
                failures.append(f"refused {value!r} without naming {keyword}: {type(error).__name__}: {error}")
        else:
            env.close()
            if not kind.valid(value):
                failures.append(f"accepted wrong {value!r}")
    assert not failures, f"{keyword} ({kind}):\n" + "\n".join(failures)
