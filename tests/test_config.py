"""One frozen, typed config per env family (issue #26, item 1): InterLevel's keywords map onto
``InterLevelConfig`` (PlaMo's onto ``PlaMoConfig``, PlaMoScene's onto ``PlaMoSceneConfig``, SIMS' onto
``SIMSConfig``), ``env.unwrapped.config`` is the resolved config, ``config=`` builds the same env as the
keywords, presets are configs, the errors are those of the keywords, the final evaluation drops the
config's training aids, and the env docstrings' keyword tables are the configs' fields."""

from __future__ import annotations

import ast
import dataclasses
import inspect
import re

import gymnasium as gym
import numpy as np
import pytest

import stairenv  # noqa: F401  (registers the envs)
from stairenv.assets import asset_dir
from stairenv.environments.config import (
    InterLevelConfig,
    InterLevelTrainingAids,
    PlaMoConfig,
    PlaMoSceneConfig,
    PlaMoTrainingAids,
    group_keywords,
    keyword_paths,
    keyword_table,
)
from stairenv.environments.interlevel import STAIRS_RANGES, InterLevelEnv
from stairenv.environments.plamo import PlaMoEnv
from stairenv.environments.plamo_scene import PlaMoSceneEnv
from stairenv.environments.sims import SIMSEnv
from stairenv.environments.sims_config import SIMSConfig, SIMSScene, SIMSTask, SIMSTrainingAids
from stairenv.planning.errors import InstructionError
from stairenv.planning.locomotion import LOCOMOTIONS
from stairenv.training import cli
from stairenv.validation import field_check
from stairenv.world.scenes import SceneConfig
from stairenv.world.stairs import StairsConfig

INTERLEVEL_IDS = ("InterLevel-v0", "InterLevel2D-v0", "InterSceneStairs-v0")
KEYWORDS = {"w_velocity": 0.5, "sigma_after": 1.0, "success_reward": 5, "frame_skip": 4.0,
            "step_height": [0.1, 0.15], "num_steps": (3, 5), "stairs_distance": (2.5, 3.0),
            "termination_height": 0.3, "random_start_heading": np.bool_(False), "stall_seconds": 4,
            "step_height_levels": 3, "curriculum_promote_at": 0.8}


def test_the_config_holds_the_keywords_resolved():
    env = gym.make("InterLevel2D-v0", **KEYWORDS)
    config = env.unwrapped.config
    assert isinstance(config, InterLevelConfig)
    assert config.reward.terms.w_velocity == 0.5 and config.reward.terms.progress_scaling is False  # the preset's
    assert config.reward.terms.w_scale == 0.5  # None resolved: sigma_after / sigma_before
    assert config.reward.success_reward == 5.0 and config.physics.frame_skip == 4
    assert type(config.physics.frame_skip) is int and config.start.random_start_heading is False
    assert config.stairs.step_height == (0.1, 0.15) and config.stairs.distance == (2.5, 3.0)
    assert config.termination.termination_height == 0.3
    assert config.training_aids.stall_seconds == 4.0 and config.training_aids.curriculum_promote_at == 0.8
    keywords = config.keywords()
    assert list(keywords) == list(inspect.signature(InterLevelEnv.__init__).parameters)[1:]
    assert InterLevelConfig.from_keywords(**keywords) == config
    # the attributes other code reads are the config's values
    unwrapped = env.unwrapped
    assert unwrapped.reward_config is config.reward.terms and unwrapped.stairs_config is config.stairs
    assert unwrapped.stall_seconds == 4.0 and unwrapped.frame_skip == 4 and unwrapped.success_reward == 5.0
    env.close()


ENV_CONFIGS = [(InterLevelEnv, InterLevelConfig), (PlaMoEnv, PlaMoConfig), (PlaMoSceneEnv, PlaMoSceneConfig)]
# keywords whose default None the config resolves (w_scale: sigma_after / sigma_before; scene: SceneConfig())
RESOLVED_NONE = ("w_scale", "scene")


@pytest.mark.parametrize("env_cls, config_cls", ENV_CONFIGS + [(SIMSEnv, SIMSConfig)])
def test_the_signature_is_the_configs_fields(env_cls, config_cls):
    """The defaults live in the config alone; the env's keywords are its fields."""
    parameters = inspect.signature(env_cls.__init__).parameters
    defaults = config_cls().keywords()
    assert set(parameters) - {"self"} == set(defaults) == set(keyword_paths(config_cls))
    for name, value in defaults.items():
        default = parameters[name].default
        assert default == value or (name in RESOLVED_NONE and default is None), name


def test_stairs_ranges_are_stairs_configs():
    # every leaf field declares its check, and StairsConfig's ranges are the env's (STAIRS_RANGES)
    stairs_fields = {field.name: field for field in dataclasses.fields(StairsConfig)}
    assert all(field_check(field) is not None for field in stairs_fields.values())
    distance = field_check(stairs_fields["distance"])
    assert STAIRS_RANGES["stairs_distance"] == (distance.low, distance.high) == (0.5, 20.0)


CHANGES = {InterLevelConfig: {"w_velocity": 0.5, "num_steps": (3, 5)},
           PlaMoConfig: {"terrain_size": 12.0, "max_xy_error": 1.5, "locomotion": "walk"},  # (not a preset keyword)
           PlaMoSceneConfig: {"max_xy_error": 2.5, "scene": {"num_walls": (1, 2)}, "speed_profile": "constant"},
           SIMSConfig: {"text_encoder": "hashing", "fall_height": 0.3, "families": ["chair", "sofa"]}}


@pytest.mark.parametrize("env_id, config_cls", [(env_id, InterLevelConfig) for env_id in INTERLEVEL_IDS]
                         + [("PlaMo-v0", PlaMoConfig), ("PlaMoNaivePaths-v0", PlaMoConfig),
                            ("PlaMoScene-v0", PlaMoSceneConfig)]
                         + [("SIMS-Walk-v0", SIMSConfig), ("SIMS-GetUp-v0", SIMSConfig)])
def test_presets_are_configs_and_config_equals_keywords(env_id, config_cls):
    preset = asset_dir("envs") / f"{env_id}.toml"
    fast = {"text_encoder": "hashing"} if config_cls is SIMSConfig else {}  # (no MiniLM needed)
    plain = gym.make(env_id, **fast)
    assert config_cls.from_toml(preset).replace(**fast) == plain.unwrapped.config
    plain.close()
    changes = CHANGES[config_cls]
    config = config_cls.from_toml(preset).replace(**changes)
    by_config, by_keywords = gym.make(env_id, config=config), gym.make(env_id, **changes)
    assert by_config.unwrapped.config == by_keywords.unwrapped.config == config
    obs_a, _ = by_config.reset(seed=3)
    obs_b, _ = by_keywords.reset(seed=3)
    np.testing.assert_array_equal(obs_a, obs_b)
    action = np.full(by_config.action_space.shape, 0.3)
    for _ in range(3):
        a, b = by_config.step(action), by_keywords.step(action)
        np.testing.assert_array_equal(a[0], b[0])
        assert a[1] == b[1]
    by_config.close(), by_keywords.close()


def test_keywords_beside_a_config_must_agree_with_it():
    config = InterLevelConfig.from_keywords(progress_scaling=False)
    with pytest.raises(ValueError, match="progress_scaling=True disagree with config"):
        gym.make("InterLevel-v0", config=config)  # the preset's keyword
    gym.make("InterLevel2D-v0", config=config).close()
    # judged over the config: its other fields stand (start_radius 2.0 needs stairs 2.5 m away or more)
    far = InterLevelConfig.from_keywords(start_radius=2.0, stairs_distance=(3.0, 4.0))
    assert InterLevelEnv(config=far, start_radius=2, frame_skip=8.0).config is far
    with pytest.raises(TypeError, match="config must be a InterLevelConfig"):
        InterLevelEnv(config={"w_velocity": 0.5})
    with pytest.raises(TypeError, match="unexpected keyword"):
        InterLevelConfig.from_keywords(w_speed=1.0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        config.reward = None


# messages as main gave them before the config (issue #26, item 1: the same errors)
ERRORS = [
    ({"w_velocity": "garbage"}, TypeError, "w_velocity must be a finite number, got 'garbage' (str)"),
    ({"w_velocity": -1}, ValueError, "w_velocity must lie in [0.0, inf], got -1.0"),
    ({"frame_skip": 2.5}, ValueError, "frame_skip must be an integer in [1, 100], got 2.5"),
    ({"stairs_distance": (0.1, 0.2)}, ValueError, "stairs_distance must lie within [0.5, 20.0], got (0.1, 0.2)"),
    ({"step_height": (0.5, 0.2)}, ValueError, "step_height: min 0.5 > max 0.2; expected min <= max within [0.01, 0.4]"),
    ({"progress_scaling": None}, TypeError, "progress_scaling must be a bool (True or False), got None (NoneType)"),
    ({"reward": "garbage"}, ValueError, "reward must be one of ['interlevel', 'interscene'], got 'garbage'"),
    ({"curriculum_demote_below": 0.7, "curriculum_promote_at": 0.6}, ValueError,
     "curriculum_promote_at must lie in [0.7, 1.0], got 0.6"),
    ({"start_radius": 2.0}, ValueError, "stairs_distance min 2.0 must be at least start_radius + 0.5 = 2.5 so the "
                                        "character starts clear of the stairs"),
]


@pytest.mark.parametrize("kwargs, error, message", ERRORS)
def test_errors_are_the_keywords(kwargs, error, message):
    for make in (lambda: InterLevelEnv(**kwargs), lambda: InterLevelConfig.from_keywords(**kwargs)):
        with pytest.raises(error, match=re.escape(message) + "$"):
            make()


def test_a_config_built_directly_is_checked_too():
    with pytest.raises(ValueError, match=re.escape("termination_height must lie in [0.0, 1.0], got 2.0")):
        dataclasses.replace(InterLevelConfig().termination, termination_height=2.0)
    with pytest.raises(ValueError, match="stairs_distance min 1.0"):
        InterLevelConfig(stairs=StairsConfig(distance=(1.0, 2.0)))


@pytest.mark.parametrize("config_cls, aids_cls, kwargs, evaluated", [
    (InterLevelConfig, InterLevelTrainingAids,
     {"init": "hybrid", "hybrid_fraction": 0.3, "stairs_start_fraction": 0.5, "stall_seconds": 4.0,
      "step_height_levels": 3, "curriculum_promote_at": 0.8, "push_speed": (0.5, 1.0), "w_velocity": 0.5},
     {"w_velocity": 0.5}),
    (SIMSConfig, SIMSTrainingAids,
     {"init": "hybrid", "interaction_start_fraction": 0.5, "start_distance_levels": 3, "stall_seconds": 2.0,
      "push_interval": (1.0, 3.0), "text_encoder": "hashing", "fall_height": 0.3},
     {"text_encoder": "hashing", "fall_height": 0.3}),
])
def test_the_evaluation_drops_the_configs_training_aids(baseline_script, config_cls, aids_cls, kwargs, evaluated):
    aids = group_keywords(config_cls, "training_aids")
    assert aids == tuple(f.name for f in dataclasses.fields(aids_cls))
    assert set(aids) <= set(cli.TRAINING_AIDS)
    assert cli.evaluation_kwargs(kwargs) == evaluated
    # the evaluated env: the training config with its aids at their defaults (the paper's protocol)
    trained = config_cls.from_keywords(**kwargs)
    assert config_cls.from_keywords(**evaluated) == dataclasses.replace(trained, training_aids=aids_cls())


def test_plamo_config_holds_the_keywords_resolved():
    env = gym.make("PlaMoNaivePaths-v0", locomotion="crouch_walk", terrain_size=20, heightmap_size=8.0,
                   matched_starts=np.bool_(False), speed_levels=4)
    config = env.unwrapped.config
    assert config.paths.path_generator == "naive" and config.paths.locomotion is LOCOMOTIONS["crouch-walk"]
    assert config.terrain.size == 20.0 and config.observation.heightmap_size == 8
    assert config.training_aids.matched_starts is False and config.training_aids.speed_levels == 4
    assert PlaMoConfig.from_keywords(**config.keywords()) == config
    assert env.unwrapped.locomotion is config.paths.locomotion and env.unwrapped.speed_levels == 4
    env.close()
    with pytest.raises(ValueError, match=re.escape("terrain_size=200.0 with terrain_cell_size=0.01 makes a")):
        PlaMoEnv(terrain_size=200.0, terrain_cell_size=0.01)
    with pytest.raises(TypeError, match=re.escape("locomotion must be None, a name")):
        PlaMoConfig.from_keywords(locomotion=3)


def test_the_evaluation_drops_plamos_training_aids(baseline_script):
    aids = group_keywords(PlaMoConfig, "training_aids")
    assert set(aids) <= set(cli.TRAINING_AIDS)
    kwargs = {"init": "hybrid", "matched_starts": False, "speed_levels": 3, "terrain": "rough"}
    evaluated = cli.evaluation_kwargs(kwargs)
    assert evaluated == {"terrain": "rough"}
    assert PlaMoConfig.from_keywords(**evaluated) == dataclasses.replace(
        PlaMoConfig.from_keywords(**kwargs), training_aids=PlaMoTrainingAids())


def test_plamo_scene_config_holds_the_keywords_resolved():
    env = gym.make("PlaMoScene-v0", scene={"num_walls": [1, 2]}, scene_resample_every=4.0, max_xy_error=2.5,
                   heightmap_size=8, speed_profile="constant", constant_speed=2)
    unwrapped = env.unwrapped
    config = unwrapped.config
    assert isinstance(config, PlaMoSceneConfig)
    assert config.scene.config == SceneConfig(num_walls=(1, 2)) and config.scene.kind == "random"
    assert config.scene.resample_every == 4 and type(config.scene.resample_every) is int
    assert config.planner.speed_profile == "constant" and config.planner.constant_speed == 2.0
    assert config.termination.max_xy_error == 2.5 and config.observation.heightmap_size == 8
    assert PlaMoSceneConfig.from_keywords(**config.keywords()) == config
    assert list(config.keywords()) == list(inspect.signature(PlaMoSceneEnv.__init__).parameters)[1:]
    # the attributes other code reads are the config's values
    assert unwrapped.scene_config is config.scene.config and unwrapped.scene_resample_every == 4
    assert unwrapped.max_xy_error == 2.5 and unwrapped.heightmap_size == 8 and unwrapped.terrain == "flat"
    # its path follower: PlaMo's config of these physics, observation and max_xy_error, on flat terrain
    follower = config.path_follower()
    assert isinstance(follower, PlaMoConfig) and follower.terrain.kind == "flat"
    assert follower.termination.max_xy_error == 2.5 and follower.observation is config.observation
    assert follower == PlaMoConfig.from_keywords(terrain="flat", max_xy_error=2.5, heightmap_size=8)
    env.close()
    assert PlaMoSceneConfig().scene.config == SceneConfig()  # scene=None: SceneConfig's defaults


def test_plamo_scene_keywords_beside_a_config_must_agree_with_it():
    config = PlaMoSceneConfig.from_keywords(scene_kind="slalom", success_radius=1.0)
    env = PlaMoSceneEnv(config=config, success_radius=1, scene={})
    assert env.config is config and env.scene_kind == "slalom" and env.success_radius == 1.0
    env.close()
    with pytest.raises(ValueError, match="success_radius=0.5 disagree with config"):
        PlaMoSceneEnv(config=config, success_radius=0.5)
    with pytest.raises(TypeError, match="config must be a PlaMoSceneConfig"):
        PlaMoSceneEnv(config=PlaMoConfig())


def test_plamo_scene_instructions_fail_in_the_config_naming_the_keyword():
    """Issue #23, item 4: instructions the parser cannot read fail when the config is built (keywords, a
    config built directly, or replaced), not at reset, and the error names ``instructions``."""
    for make in (lambda: PlaMoSceneConfig.from_keywords(instructions="fly to the moon"),
                 lambda: PlaMoSceneConfig().replace(instructions="fly to the moon"),
                 lambda: dataclasses.replace(PlaMoSceneConfig(), planner=dataclasses.replace(
                     PlaMoSceneConfig().planner, instructions="fly to the moon"))):
        with pytest.raises(InstructionError, match=re.escape("instructions 'fly to the moon': unknown locomotion "
                                                             "verb 'fly'")):
            make()
    assert issubclass(InstructionError, ValueError)
    # the landmarks are the scene's: the slalom's start and goal, or the scene keyword's names
    with pytest.raises(InstructionError, match="instructions 'Walk to the tree'"):
        PlaMoSceneConfig.from_keywords(scene_kind="slalom", instructions="Walk to the tree")
    PlaMoSceneConfig.from_keywords(scene_kind="slalom", instructions="Run to the goal")
    PlaMoSceneConfig.from_keywords(scene={"landmark_names": ("well", "gate"), "num_landmarks": 2},
                                   instructions="Walk to the well")
    with pytest.raises(InstructionError, match="unknown landmark 'tree'"):
        PlaMoSceneConfig.from_keywords(scene={"landmark_names": ("well", "gate"), "num_landmarks": 2},
                                       instructions="Walk to the tree")
    with pytest.raises(TypeError, match="instructions must be a str"):
        PlaMoSceneConfig.from_keywords(instructions=3)


def _table_rows(doc: str) -> list[list[str]]:
    """The rows of the docstring's keyword table (header and rule left out), cell by cell."""
    lines = [line.strip() for line in inspect.cleandoc(doc).splitlines()]
    start = lines.index("| keyword | default | valid | meaning |")
    rows = []
    for line in lines[start + 2:]:
        if not line.startswith("|"):
            break
        rows.append([cell.strip() for cell in line.strip("|").split(" | ")])
    return rows


@pytest.mark.parametrize("env_cls, config_cls", ENV_CONFIGS + [(SIMSEnv, SIMSConfig)])
def test_the_docstring_table_is_the_configs_keywords_and_defaults(env_cls, config_cls):
    """One row per keyword, in the config's order, with its field's default, valid values and help: the
    defaults live in the config alone."""
    rows = _table_rows(env_cls.__doc__)
    assert [row[0] for row in rows] == list(keyword_paths(config_cls))
    defaults = {k: p.default for k, p in inspect.signature(env_cls.__init__).parameters.items() if k != "self"}
    for keyword, default, valid, meaning in rows:
        shown = ast.literal_eval(default)
        if isinstance(shown, tuple):
            assert shown == pytest.approx(defaults[keyword], rel=1e-3), keyword
        else:
            assert shown == defaults[keyword] and type(shown) is type(defaults[keyword]), keyword
        assert valid and len(meaning) > 10, keyword
    assert keyword_table(config_cls) in inspect.cleandoc(env_cls.__doc__)
    assert "{keyword table}" not in env_cls.__doc__


# --- SIMS ---------------------------------------------------------------------------------------------
def test_sims_config_holds_the_keywords_resolved():
    env = gym.make("SIMS-Lie-v0", text_encoder="hashing", text_dim=32.0, families=["bed"],
                   captions=[["sad", "lies down slowly"]], start_distance=np.array([1.0, 2.0]), stall_seconds=2,
                   start_distance_levels=3, frame_skip=4.0)
    config, unwrapped = env.unwrapped.config, env.unwrapped
    assert isinstance(config, SIMSConfig) and config.task.skill == "lie" and config.text.text_conditioned is True
    # sequences stored as tuples (the config is hashable), numbers as their type
    assert config.scene.families == ("bed",) and config.text.captions == (("sad", "lies down slowly"),)
    assert config.task.start_distance == (1.0, 2.0) and type(config.text.text_dim) is int
    assert config.training_aids.stall_seconds == 2.0 and config.physics.frame_skip == 4
    hash(config)
    assert SIMSConfig.from_keywords(**config.keywords()) == config
    # the attributes other code reads are the config's values
    assert unwrapped.families == ("bed",) and unwrapped.captions == config.text.captions
    assert unwrapped.start_distance == (1.0, 2.0) and unwrapped.text_dim == 32 and unwrapped.frame_skip == 4
    assert unwrapped.start_distance_levels == 3 and unwrapped.stall_seconds == 2.0
    env.close()
    # families and captions left None follow the skill
    getup = SIMSConfig.from_keywords(text_encoder="hashing").replace(skill="getup", getup_from="lie")
    assert getup.scene.families is None and getup.families == ("sofa", "bed", "double_bed")


@pytest.mark.parametrize("kwargs, error, message", [
    ({"skill": "lie", "families": ("chair",)}, ValueError, "families ['chair'] cannot host lie"),
    ({"families": ()}, ValueError, "families must name at least one of"),
    ({"families": "chair"}, TypeError, "families must be None or a list or tuple"),
    ({"text_dim": 4}, ValueError, "text_dim must lie in [8, 4096] with the hashing text_encoder, got 4"),
    ({"skill": "walk", "interaction_start_fraction": 0.5}, ValueError, "interaction_start_fraction applies to"),
    ({"scene": "room", "start_distance_levels": 2}, ValueError, "start_distance_levels needs scene='object'"),
    ({"start_distance": (4.0, 1.0)}, ValueError, "start_distance: min 4.0 > max 1.0"),
])
def test_sims_errors_are_the_keywords(kwargs, error, message):
    kwargs = {"text_encoder": "hashing", **kwargs}
    for make in (lambda: SIMSEnv(**kwargs), lambda: SIMSConfig.from_keywords(**kwargs)):
        with pytest.raises(error, match=re.escape(message)):
            make()


def test_a_sims_config_built_directly_is_checked_too():
    with pytest.raises(ValueError, match=re.escape("families ['chair'] cannot host lie")):
        SIMSConfig(task=SIMSTask(skill="lie"), scene=SIMSScene(families=("chair",)))
    config = SIMSConfig.from_keywords(text_encoder="hashing", interaction_start_fraction=0.5)
    with pytest.raises(ValueError, match="interaction_start_fraction applies to"):
        dataclasses.replace(config, task=SIMSTask(skill="getup"))


def test_keywords_beside_a_sims_config_must_agree_with_it():
    config = SIMSConfig.from_keywords(skill="walk", text_encoder="hashing", text_conditioned=True)
    with pytest.raises(ValueError, match="skill='sit' disagree with config"):
        gym.make("SIMS-Sit-v0", config=config)  # the preset's keyword
    env = gym.make("SIMS-Walk-v0", config=config)
    assert env.unwrapped.config is config and env.unwrapped.skill == "walk"
    env.close()
    with pytest.raises(TypeError, match="config must be a SIMSConfig"):
        SIMSEnv(config=PlaMoConfig())

