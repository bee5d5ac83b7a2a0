"""PlaMoScene-v0: instructions planned in a generated scene, the path followed, replanning, success."""

from __future__ import annotations

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import stairenv  # noqa: F401
from stairenv.environments.plamo_scene import PlaMoSceneEnv, random_instructions
from stairenv.planning.errors import InstructionError
from stairenv.planning.instructions import parse_instructions


def test_check_env_and_determinism():
    env = gym.make("PlaMoScene-v0")
    check_env(env.unwrapped, skip_render_check=True)
    a, info_a = env.reset(seed=3)
    b, info_b = env.reset(seed=3)
    np.testing.assert_array_equal(a, b)
    assert info_a["instructions"] == info_b["instructions"]


def test_random_instructions_parse():
    rng = np.random.default_rng(0)
    names = ["tree", "swing", "car", "bench"]
    start, text = random_instructions(names, rng)
    segments = parse_instructions(text, {n: np.zeros((1, 2), int) for n in names})
    assert start in names and len(segments) == 2
    assert segments[1].source == segments[0].target


def test_path_follows_the_plan_and_user_instructions():
    env = gym.make("PlaMoScene-v0").unwrapped
    env.reset(seed=1)
    names = env.scene.landmark_names
    env2 = PlaMoSceneEnv(instructions=f"Walk to the {names[1]}")
    _, info = env2.reset(seed=1)
    assert info["instructions"] == f"Walk to the {names[1]}"
    # The sampled path is the planned trajectory.
    t = np.arange(0, env2._trajectory.end_time, 0.5)
    np.testing.assert_allclose(env2.path.at(t), env2._trajectory.position(t), atol=0.05)
    # It ends at the target landmark.
    end = env2._trajectory.position(env2._trajectory.end_time)[:2]
    assert np.hypot(*(end - env2._goal_xy)) < env2.scene.landmark(names[1]).radius + 0.6
    with pytest.raises(InstructionError, match="known landmarks"):
        PlaMoSceneEnv(instructions="Walk to the moon").reset(seed=1)


def test_success_when_the_head_arrives_after_the_planned_time():
    env = gym.make("PlaMoScene-v0", max_xy_error=100.0).unwrapped
    env.reset(seed=2)
    env._steps = int(np.ceil(env._trajectory.end_time / env.dt))  # the planned arrival has passed
    data = env.data
    head, _ = env._head()
    data.qpos[:2] += env._goal_xy - head[:2]  # put the head over the goal's centre
    mujoco.mj_forward(env.model, data)
    _, _, terminated, _, info = env.step(np.zeros(28))
    assert info["success"] and terminated
