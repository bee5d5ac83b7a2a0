"""``reset(seed=s)`` fixes everything after it, whatever the env did before (Gymnasium's contract):
a used env re-seeded acts exactly as a fresh env with the same seed, single and batched, every id."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import stairenv

EPISODE = 6  # short episodes: many resets (past SIMS' and PlaMoScene's scene resampling, every 10) in few steps
STEPS = 70


def _actions(count: int, size: int, shape=()) -> np.ndarray:
    return np.random.default_rng(5).uniform(-1, 1, (count, *shape, size)).astype(np.float32)


def _single_run(env, seed: int, steps: int) -> list[np.ndarray]:
    obs, _ = env.reset(seed=seed)
    seen = [obs]
    for action in _actions(steps, env.action_space.shape[0]):
        obs, reward, terminated, truncated, _ = env.step(action)
        seen += [obs, np.float64(reward)]
        if terminated or truncated:
            obs, _ = env.reset()
            seen.append(obs)
    return seen


def _vector_run(env, seed: int, steps: int) -> list[np.ndarray]:
    obs, _ = env.reset(seed=seed)
    seen = [obs]
    for action in _actions(steps, env.single_action_space.shape[0], (env.num_envs,)):
        obs, reward, terminated, truncated, _ = env.step(action)
        seen += [obs, reward, terminated, truncated]
    return seen


def _assert_same(used: list, fresh: list, env_id: str) -> None:
    assert len(used) == len(fresh), env_id
    for k, (a, b) in enumerate(zip(used, fresh)):
        np.testing.assert_array_equal(a, b, err_msg=f"{env_id}: item {k} after the seeded reset")


@pytest.mark.slow
@pytest.mark.parametrize("env_id", stairenv.ENV_IDS)
def test_a_used_env_reseeded_acts_as_a_fresh_one(env_id):
    used = gym.make(env_id, max_episode_steps=EPISODE)
    _single_run(used, seed=7, steps=3 * EPISODE + 2)  # some history: 3-4 resets, none of them a multiple of 10
    used_run = _single_run(used, seed=123, steps=STEPS)
    used.close()
    fresh = gym.make(env_id, max_episode_steps=EPISODE)
    fresh_run = _single_run(fresh, seed=123, steps=STEPS)
    fresh.close()
    _assert_same(used_run, fresh_run, env_id)


@pytest.mark.slow
@pytest.mark.parametrize("env_id", stairenv.ENV_IDS)
def test_a_used_batched_env_reseeded_acts_as_a_fresh_one(env_id):
    def make():
        return gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point",
                            max_episode_steps=EPISODE, physics="serial")

    used = make()
    _vector_run(used, seed=7, steps=3 * EPISODE + 2)
    used_run = _vector_run(used, seed=123, steps=STEPS)
    used.close()
    fresh = make()
    fresh_run = _vector_run(fresh, seed=123, steps=STEPS)
    fresh.close()
    _assert_same(used_run, fresh_run, env_id)
