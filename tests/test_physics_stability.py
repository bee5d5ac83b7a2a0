"""Saturated actions keep the physics sound, and a diverging state is flagged before it is observed."""

from __future__ import annotations

import importlib.util
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import stairenv
from stairenv.environments.base import MAX_JOINT_SPEED, MAX_ROOT_SPEED


def _load_soak():
    path = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_saturated.py"
    spec = importlib.util.spec_from_file_location("bench_saturated", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.soak


soak = _load_soak()


@pytest.mark.slow
@pytest.mark.parametrize("env_id", stairenv.ENV_IDS)
@pytest.mark.parametrize("mode", ["bang", "gauss3"])
def test_saturated_actions_never_diverge(env_id, mode):
    """Random +-1 on every DoF every step (and clipped std-3 Gaussians), falls stepped through:
    before the model fix, 0.6% of such InterLevel steps diverged, SIMS-GetUp and SIMS-Lie 0.6% too."""
    steps = 1500
    result = soak(env_id, mode, steps=steps, seed=1)
    assert result["unstable"] == 0, result
    if gym.spec(env_id).max_episode_steps <= steps:  # the time limit was reached: falls were stepped through
        assert result["episodes"] >= 1, result
    # what a normaliser sees stays of the order of the body's real speeds
    assert result["max_obs"] < MAX_JOINT_SPEED, result
    assert 5.0 < result["max_joint_speed"] < MAX_JOINT_SPEED, result


@pytest.mark.parametrize("where, value", [("joint", MAX_JOINT_SPEED * 4), ("root_linear", MAX_ROOT_SPEED * 4),
                                          ("root_angular", MAX_JOINT_SPEED * 4)])
def test_implausible_speed_truncates_with_the_last_finite_observation(where, value):
    env = gym.make("InterLevel-v0")
    obs, _ = env.reset(seed=3)
    env.step(np.zeros(28))
    unwrapped = env.unwrapped
    previous, _, _, _, _ = env.step(np.zeros(28))
    index = {"joint": unwrapped._idx.qvel_joints.start + 10, "root_linear": unwrapped._idx.qvel_root.start,
             "root_angular": unwrapped._idx.qvel_root.start + 4}[where]
    # a state far beyond what the body reaches, but far below MuJoCo's own 1e10 check
    unwrapped.data.qvel[index] = value
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        obs, reward, terminated, truncated, info = env.step(np.zeros(28))
    assert info["physics_unstable"] and truncated and not terminated
    np.testing.assert_array_equal(obs, previous)
    with pytest.raises(gym.error.ResetNeeded):
        env.step(np.zeros(28))
    env.reset()
    _, _, _, _, info = env.step(np.zeros(28))
    assert not info["physics_unstable"]


def test_ordinary_fast_motion_is_not_flagged():
    """A run of saturated actions from a standing start: fast, but within the body's speeds."""
    env = gym.make("InterLevel-v0")
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    peak = 0.0
    for _ in range(90):
        _, _, _, truncated, info = env.step(np.sign(rng.standard_normal(28)))
        assert not info["physics_unstable"]
        peak = max(peak, float(np.abs(env.unwrapped.data.qvel).max()))
        if truncated:
            break
    assert peak > 10.0


@pytest.mark.parametrize("mutate_at", ["reset", "step"])
def test_a_caller_changing_the_returned_observation_changes_nothing_in_the_env(mutate_at):
    """``reset`` and ``step`` hand out arrays of the caller's own: normalising one in place (as an observation
    normaliser may) leaves the env's last observation, which an unstable step returns, as it was."""
    env = gym.make("InterLevel-v0")
    obs, _ = env.reset(seed=3)
    if mutate_at == "step":
        obs, *_ = env.step(np.zeros(28))
    kept = obs.copy()
    obs *= 0.0
    unwrapped = env.unwrapped
    unwrapped.data.qvel[unwrapped._idx.qvel_root.start] = MAX_ROOT_SPEED * 4    # an unstable step next
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        unstable_obs, _, _, truncated, info = env.step(np.zeros(28))
    assert info["physics_unstable"] and truncated
    np.testing.assert_array_equal(unstable_obs, kept)
    assert info["distance_to_target"] > 0.0
