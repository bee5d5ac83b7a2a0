"""AMP at batch: the wrappers' default style (no ``style`` argument) on the batched env and on a
``SyncVectorEnv``, and scoring a step's N windows in one call against scoring them one by one."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import torch
from stable_baselines3.common.env_util import make_vec_env

import stairenv  # noqa: F401
from stairenv.motion.rsi import load_reference_library
from stairenv.style.discriminator import AMPDiscriminator, DiscriminatorConfig, style_reward
from stairenv.style.reference import ReferenceWindows
from stairenv.style.wrappers import AMPStyleReward, AMPVecEnvWrapper, AMPVectorWrapper, default_reference
from stairenv.vec_sb3 import make_sb3_vec_env

# Scoring N windows in one call groups the products differently from one window at a time (and
# the numba kernels reassociate sums): float32 rounding only, measured <= 5e-6 on logits of
# O(1)-O(10); allowed: |batched - one by one| <= 1e-5 + 1e-5 |one by one|.
LOGIT_RTOL, LOGIT_ATOL = 1e-5, 1e-5


def steps(wrapper, n: int, seed: int = 0):
    """``n`` random steps through an SB3 or gymnasium vector wrapper; the infos of each."""
    rng = np.random.default_rng(seed)
    shape = (wrapper.num_envs, 28)
    out = []
    if isinstance(wrapper, AMPVecEnvWrapper):
        wrapper.seed(seed)
        wrapper.reset()
        for _ in range(n):
            _, reward, _, infos = wrapper.step(rng.uniform(-1, 1, shape).astype(np.float32))
            out.append((reward, infos))
    else:
        wrapper.reset(seed=seed)
        for _ in range(n):
            _, reward, _, _, info = wrapper.step(rng.uniform(-1, 1, shape).astype(np.float32))
            out.append((reward, info))
    return out


def test_default_style_on_the_batched_sb3_env():
    venv = AMPVecEnvWrapper(make_sb3_vec_env("InterLevel-v0", n_envs=4, seed=0, amp_history=3))
    style = venv.style
    assert style.reference.num_frames == 3 and style.reference.fps == pytest.approx(30.0)
    assert style.reference.condition_dim == 0 and style.background_training
    assert style.config == DiscriminatorConfig()
    expected = ReferenceWindows(load_reference_library(None), num_frames=3, fps=30.0)
    np.testing.assert_array_equal(style.reference.windows, expected.windows)
    for reward, infos in steps(venv, 5):
        assert reward.shape == (4,) and np.all(np.isfinite(reward))
        assert all(0.0 <= info["style_reward"] <= 1.0 for info in infos)
    venv.close()


@pytest.mark.parametrize("mode", ["sync", "vector_entry_point"])
def test_default_style_on_gymnasium_vector_envs(mode):
    envs = gym.make_vec("InterLevel-v0", num_envs=2, vectorization_mode=mode)
    wrapper = AMPVectorWrapper(gym.wrappers.vector.RecordEpisodeStatistics(envs))  # found through the wrapper
    assert wrapper.style.reference.num_frames == 2
    assert wrapper.style.reference.dim == len(envs.reset(seed=1)[1]["amp_obs"][0])
    for reward, info in steps(wrapper, 4):
        assert reward.shape == (2,) and np.all(np.isfinite(reward))
        assert info["style_reward"].shape == (2,)
    wrapper.close()


def test_default_reference_follows_the_envs_reference_motion():
    venv = make_sb3_vec_env("InterLevel-v0", n_envs=1, reference_motion="builtin:sims")
    expected = ReferenceWindows(load_reference_library("builtin:sims"), num_frames=2, fps=30.0)
    np.testing.assert_array_equal(default_reference(venv).windows, expected.windows)
    venv.close()


def test_default_style_needs_amp_features():
    with pytest.raises(TypeError, match="no AMP features"):
        AMPVecEnvWrapper(make_vec_env("CartPole-v1", n_envs=2))
    with pytest.raises(TypeError, match="no AMP features"):
        AMPVectorWrapper(gym.make_vec("CartPole-v1", num_envs=2, vectorization_mode="sync"))


def scaled_discriminator(dim: int, scoring: str = "auto") -> AMPDiscriminator:
    """A discriminator whose logits are O(1)-O(10) (the fresh one's output layer is scaled by 0.01),
    with a non-trivial input normaliser."""
    torch.manual_seed(0)
    disc = AMPDiscriminator(dim, DiscriminatorConfig(), scoring=scoring)
    rng = np.random.default_rng(3)
    with torch.no_grad():
        disc.logit.weight.normal_(0.0, 1.0)
    disc.norm.update(torch.as_tensor(rng.normal(0.5, 2.0, (512, dim)), dtype=torch.float32))
    return disc


@pytest.mark.parametrize("scoring", ["auto", "numba", "torch"])
@pytest.mark.parametrize("n", [1, 7, 64, 100])
def test_scoring_n_windows_in_one_call_equals_one_by_one(scoring, n):
    disc = scaled_discriminator(210, scoring)
    x = np.random.default_rng(n).normal(0.5, 2.0, (n, 210)).astype(np.float32)
    batched = disc.logits(x)
    one_by_one = np.array([disc.logits(x[i: i + 1])[0] for i in range(n)])
    assert n == 1 or np.abs(batched).max() > 1.0  # logits of a useful scale
    np.testing.assert_allclose(batched, one_by_one, rtol=LOGIT_RTOL, atol=LOGIT_ATOL)
    with torch.no_grad():
        np.testing.assert_allclose(batched, disc(torch.from_numpy(x)).numpy(), rtol=LOGIT_RTOL, atol=LOGIT_ATOL)


def test_batched_env_is_scored_in_one_call_per_step():
    venv = make_sb3_vec_env("InterLevel-v0", n_envs=8, seed=0)
    reference = default_reference(venv)
    style = AMPStyleReward(reference, train=False, discriminator=scaled_discriminator(reference.dim))
    wrapper = AMPVecEnvWrapper(venv, style)
    calls = []
    logits = style.disc.logits

    def recorded(features):
        calls.append((features.copy(), logits(features)))
        return calls[-1][1]
    style.disc.logits = recorded
    for (_, infos), (windows, batched) in zip(steps(wrapper, 6), calls, strict=True):
        np.testing.assert_array_equal(windows, np.stack([info["amp_obs"] for info in infos]).astype(np.float32))
        one_by_one = [logits(windows[i: i + 1])[0] for i in range(len(windows))]
        np.testing.assert_allclose(batched, one_by_one, rtol=LOGIT_RTOL, atol=LOGIT_ATOL)
        np.testing.assert_array_equal([info["style_reward"] for info in infos],
                                      style_reward(batched, style.config.loss))
    assert [len(windows) for windows, _ in calls] == [8] * 6  # one call of all 8 windows per step
    wrapper.close()


def test_pushing_a_batch_of_feature_histories_equals_one_by_one():
    """``FeatureHistory.push_each`` (the batched env's style features) leaves each history and its
    ``flat()`` as ``push_features`` world by world does."""
    from stairenv.style.features import AMP_FEATURE_SIZE, FeatureHistory

    rng = np.random.default_rng(0)
    batched, single = [FeatureHistory(3) for _ in range(4)], [FeatureHistory(3) for _ in range(4)]
    for _ in range(5):
        features = rng.normal(size=(4, AMP_FEATURE_SIZE))
        flat = FeatureHistory.push_each(batched, features)
        for k, (history, alone) in enumerate(zip(batched, single)):
            alone.push_features(features[k])
            assert np.array_equal(history.frames, alone.frames)
            assert np.array_equal(flat[k], alone.flat())


@pytest.mark.parametrize("rows", [[0, 1, 2, 3], [2, 0, 3], [1, 0, 2, 3]])
def test_pushing_rows_of_shared_histories_equals_one_by_one(rows):
    """``FeatureHistory.push_rows`` (the histories as rows of one array, a batched env's): every row in order
    (shifted in place), some rows, all rows out of order; the pushed rows and their ``flat()`` as
    ``push_features`` one by one, the other rows untouched, the flat rows a copy."""
    from stairenv.style.features import AMP_FEATURE_SIZE, FeatureHistory

    rng = np.random.default_rng(1)
    frames = rng.normal(size=(4, 3, AMP_FEATURE_SIZE))
    single = []
    for row in frames:
        history = FeatureHistory(3)
        history.frames[:] = row
        single.append(history)
    for _ in range(3):
        features = rng.normal(size=(len(rows), AMP_FEATURE_SIZE))
        flat = FeatureHistory.push_rows(frames, np.array(rows), features)
        for k, row in enumerate(rows):
            single[row].push_features(features[k])
            assert np.array_equal(flat[k], single[row].flat())
        for row, alone in enumerate(single):
            assert np.array_equal(frames[row], alone.frames)
        assert not np.shares_memory(flat, frames)
