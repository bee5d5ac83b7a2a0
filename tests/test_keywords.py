"""Every env keyword is checked at construction, with its type: a bad value raises TypeError or
ValueError naming the keyword (issue #13, item 6), and nothing else ever escapes a constructor."""

from __future__ import annotations

import importlib
import inspect
import re

import numpy as np
import pytest

from stairenv.environments.interlevel import InterLevelEnv
from stairenv.environments.plamo import MAX_TERRAIN_CELLS, PlaMoEnv
from stairenv.environments.plamo_scene import PlaMoSceneEnv
from stairenv.environments.sims import SIMSEnv
from stairenv.registration import load_presets
from stairenv.validation import check_bool, check_grid, check_int, check_pair

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


# --- wrong types for every keyword of every registered id --------------------------------------
WRONG_VALUES = ["garbage", 2.5, -1, True, None, [1, 2, 3], {"key": 1}, object(), float("nan"),
                np.array([1.0, 2.0])]


def _entry_point(path: str):
    module, name = path.split(":")
    return getattr(importlib.import_module(module), name)


def _fuzz_cases():
    for env_id, preset in sorted(load_presets().items()):
        cls = _entry_point(preset["entry_point"])
        for keyword in inspect.signature(cls.__init__).parameters:
            if keyword != "self":
                for k, value in enumerate(WRONG_VALUES):
                    yield pytest.param(cls, preset["kwargs"], keyword, value, id=f"{env_id}-{keyword}-{k}")


@pytest.mark.parametrize("cls, preset_kwargs, keyword, value", list(_fuzz_cases()))
def test_wrong_types_raise_naming_the_keyword(cls, preset_kwargs, keyword, value):
    kwargs = {**preset_kwargs, keyword: value}
    if cls is SIMSEnv and keyword != "text_encoder":
        kwargs.setdefault("text_encoder", "hashing")  # no MiniLM needed to check the others
    try:
        env = cls(**kwargs)
    except (TypeError, ValueError) as error:
        assert names_keyword(error, keyword), f"{type(error).__name__}: {error}"
    else:
        env.close()
