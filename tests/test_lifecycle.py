"""The batched env's lifecycle and reset arguments: wrong-length or non-bool reset masks, seeds as numpy
arrays, and use after ``close()`` each have a defined outcome (#23)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import stairenv  # noqa: F401
from stairenv.vec_sb3 import make_sb3_vec_env


def batched(n: int = 8, **kwargs):
    return gym.make_vec("InterLevel-v0", num_envs=n, vectorization_mode="vector_entry_point", **kwargs)


@pytest.fixture(scope="module")
def vec():
    env = batched(8)
    env.reset(seed=0)
    yield env
    env.close()


@pytest.mark.parametrize("mask", [[True] * 3, [True] * 9, np.ones((8, 1), dtype=bool), np.ones(8, dtype=int),
                                  [1] * 8, np.True_])
def test_a_reset_mask_that_is_not_one_bool_per_world_is_refused(vec, mask):
    before = vec.reset(seed=0)[0]
    with pytest.raises(ValueError, match="reset_mask must be 8 bools"):
        vec.reset(options={"reset_mask": mask})
    after, _ = vec.reset(options={"reset_mask": np.zeros(8, dtype=bool)})  # nothing was reset
    np.testing.assert_array_equal(after, before)


def test_numpy_seeds_are_seeds(vec):
    as_list, _ = vec.reset(seed=list(range(8)))
    np.testing.assert_array_equal(vec.reset(seed=np.arange(8))[0], as_list)
    np.testing.assert_array_equal(vec.reset(seed=np.int64(0))[0], as_list)
    np.testing.assert_array_equal(vec.reset(seed=np.array(0))[0], as_list)
    with pytest.raises(ValueError, match="one seed per world"):
        vec.reset(seed=np.arange(3))
    with pytest.raises(ValueError, match=r"seed\[2\] must be >= 0"):
        vec.reset(seed=[0, 1, -2, 3, 4, 5, 6, 7])
    with pytest.raises(TypeError, match=r"seed\[1\] must be None or an integer"):
        vec.reset(seed=[0, 1.5, 2, 3, 4, 5, 6, 7])
    with pytest.raises(TypeError, match="seed must be None, an integer"):
        vec.reset(seed="7")
    with pytest.raises(ValueError, match="seed must be >= 0"):
        vec.reset(seed=-1)


@pytest.mark.parametrize("physics", ["mujoco", "threads", "serial", pytest.param("warp", marks=pytest.mark.skipif(
    __import__("importlib").util.find_spec("mujoco_warp") is None, reason="mujoco_warp not installed (.[gpu])"))])
def test_a_closed_batched_env_refuses_steps_and_resets(physics):
    env = batched(2, physics=physics)
    env.reset(seed=0)
    env.step(np.zeros((2, 28)))
    env.close()
    env.close()  # closing twice is fine
    with pytest.raises(gym.error.ClosedEnvironmentError, match="closed"):
        env.step(np.zeros((2, 28)))
    with pytest.raises(gym.error.ClosedEnvironmentError, match="closed"):
        env.reset(seed=0)
    with pytest.raises(gym.error.ClosedEnvironmentError, match="closed"):
        env.unwrapped.reset_world(0)


def test_a_closed_sb3_vec_env_refuses_steps_and_resets():
    venv = make_sb3_vec_env("InterLevel-v0", 2, seed=0)
    venv.reset()
    venv.close()
    with pytest.raises(gym.error.ClosedEnvironmentError):
        venv.step(np.zeros((2, 28)))
    with pytest.raises(gym.error.ClosedEnvironmentError):
        venv.reset()


def test_an_env_that_rebuilds_its_scene_gives_freed_memory_back(monkeypatch):
    """A SIMS env with ``scene_resample_every=1`` compiles a model at every reset; among a busy process's
    other allocations the freed models leave holes the C allocator keeps (RSS grew ~15 MB over 1,500
    resets here, +89 MB in a user's process). Every ``TRIM_EVERY_COMPILES`` compiles the allocator's free
    memory is given back (glibc's ``malloc_trim``), after the previous model and data are released."""
    from stairenv.environments import base

    trims = []
    monkeypatch.setattr(base, "_malloc_trim", lambda: trims.append)
    monkeypatch.setattr(base, "TRIM_EVERY_COMPILES", 4)
    monkeypatch.setattr(base, "_compiles", 0)
    env = gym.make("SIMS-Sit-v0", text_encoder="hashing", scene_resample_every=1)
    env.reset(seed=0)
    compiles = base._compiles
    for _ in range(8):
        env.reset()
    assert base._compiles - compiles == 8 and len(trims) == base._compiles // 4 and trims[-1] == 0
    env.close()
