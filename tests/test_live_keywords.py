"""A keyword set on a built env (``set_attr`` on a batched env, assigning ``env.unwrapped.<keyword>``) goes
through the checks ``gym.make`` runs, and takes effect or is refused naming it; ``config`` and ``get_attr``
tell the truth afterwards."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import stairenv  # noqa: F401


def _first_step_info(env, seed=0):
    env.reset(seed=seed)
    _, reward, _, _, info = env.step(np.zeros(env.action_space.shape))
    return {**info, "reward": reward}


def test_a_reward_weight_assigned_on_a_single_env_takes_effect():
    """``env.unwrapped.w_velocity = 0`` used to set an attribute nothing read (the reward kernel takes an array
    made at construction): the velocity term is now 0, as with ``gym.make(..., w_velocity=0)``, and the config
    says 0."""
    env = gym.make("InterLevel-v0")
    assert _first_step_info(env)["reward_velocity"] > 0
    env.unwrapped.w_velocity = 0.0
    info = _first_step_info(env)
    made = _first_step_info(gym.make("InterLevel-v0", w_velocity=0.0))
    assert info["reward_velocity"] == 0.0 and info["reward"] == made["reward"]
    assert env.unwrapped.config.reward.terms.w_velocity == 0.0 and env.unwrapped.w_velocity == 0.0


def test_set_attr_on_a_batched_env_takes_effect_or_is_refused_by_name():
    envs = gym.make_vec("InterLevel-v0", num_envs=2, vectorization_mode="vector_entry_point")
    envs.reset(seed=0)
    before = envs.step(np.zeros((2, 28)))[4]["reward_velocity"]
    assert np.all(before > 0)
    envs.set_attr("w_velocity", 0.0)
    assert envs.get_attr("w_velocity") == (0.0, 0.0)
    envs.reset(seed=0)
    assert np.all(envs.step(np.zeros((2, 28)))[4]["reward_velocity"] == 0.0)
    # refused at construction, refused here: the same checks, naming the keyword
    with pytest.raises(ValueError, match=r"termination_height must lie in \[0.0, 1.0\], got 5.0"):
        envs.set_attr("termination_height", 5.0)
    with pytest.raises(TypeError, match="termination_height must be a finite number"):
        envs.set_attr("termination_height", "abc")
    height = envs.envs[0].config.termination.termination_height
    assert envs.get_attr("termination_height") == (height, height)        # unchanged
    # a keyword that shapes the model is fixed once built: refused by name, unless unchanged
    with pytest.raises(ValueError, match="'frame_skip' of InterLevelEnv is fixed once the env is built"):
        envs.set_attr("frame_skip", 4)
    envs.set_attr("frame_skip", envs.get_attr("frame_skip")[0])
    envs.set_attr("termination_height", 0.95)             # every standing start is now a fall
    envs.reset(seed=0)
    terminated, info = envs.step(np.zeros((2, 28)))[2:5:2]
    assert np.all(terminated) and np.all(info["fell"])
    assert all(env.config.termination.termination_height == 0.95 for env in envs.envs)
    envs.close()


def test_path_and_skill_envs_take_their_live_keywords_and_refuse_the_rest():
    plamo = gym.make("PlaMo-v0", locomotion="walk", terrain="flat")
    plamo.unwrapped.max_xy_error = 1e-6                   # every step loses the path at once
    plamo.reset(seed=1)
    terminated, info = plamo.step(np.zeros(28))[2:5:2]
    assert terminated and info["off_path"] and plamo.unwrapped.config.termination.max_xy_error == 1e-6
    with pytest.raises(ValueError, match="'terrain' of PlaMoEnv is fixed once the env is built"):
        plamo.unwrapped.terrain = "rough"
    with pytest.raises(ValueError, match="max_xy_error must lie in"):
        plamo.unwrapped.max_xy_error = -1.0
    sims = gym.make("SIMS-Walk-v0", text_encoder="hashing")
    sims.unwrapped.fall_height = 0.2
    assert sims.unwrapped.config.termination.fall_height == 0.2 and sims.unwrapped.fall_height == 0.2
    with pytest.raises(ValueError, match="'text_dim' of SIMSEnv is fixed"):
        sims.unwrapped.text_dim = 32


def test_an_instruction_keyword_error_quotes_a_bounded_text():
    """``gym.make(..., instructions=<1 MB>)`` that does not parse names the keyword and shows at most ~80
    characters of the text (it used to echo the whole megabyte)."""
    text = "Walk to the moon. " * 60_000
    with pytest.raises(ValueError, match="instructions") as caught:
        gym.make("PlaMoScene-v0", instructions=text)
    assert len(str(caught.value)) < 1000 and "characters)" in str(caught.value)
