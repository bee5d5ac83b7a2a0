"""Exported numpy policies act exactly as the SB3 policy they came from, and bad files are refused."""

from __future__ import annotations

import json
import pickle

import gymnasium as gym
import numpy as np
import pytest
import torch

import stairenv  # noqa: F401
from stairenv.evaluation.policies import load_policy
from stairenv.pretrained import NumpyPolicy, PolicyFileError, load, load_file


@pytest.fixture(scope="module")
def sb3_run(tmp_path_factory):
    """A small PPO on InterLevel-v0 with observation normalisation, saved as train_ppo.py saves it."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    folder = tmp_path_factory.mktemp("run")
    venv = VecNormalize(DummyVecEnv([lambda: gym.make("InterLevel-v0")] * 2), norm_obs=True, norm_reward=True)
    model = PPO("MlpPolicy", venv, n_steps=64, batch_size=64, n_epochs=1, seed=0, device="cpu",
                policy_kwargs={"net_arch": {"pi": [64, 32], "vf": [64, 32]}, "activation_fn": torch.nn.ReLU})
    model.learn(128)  # the weights and the normaliser's statistics move away from their start
    model.save(folder / "final_model.zip")
    venv.save(folder / "vecnormalize.pkl")
    return folder / "final_model.zip"


def test_exported_policy_acts_as_the_sb3_policy(sb3_run, tmp_path, baseline_script):
    out = tmp_path / "policy.npz"
    evaluation = tmp_path / "evaluation.json"
    evaluation.write_text(json.dumps({"progress": 0.0}))
    assert baseline_script("export_policy").main([str(sb3_run), "--out", str(out),
                                                  "--evaluation", str(evaluation)]) == 0
    env = gym.make("InterLevel-v0")
    sb3 = load_policy(str(sb3_run), env)
    numpy_policy = load_file(out)
    assert numpy_policy.config["env_id"] == "InterLevel-v0" and numpy_policy.config["evaluation"] == {"progress": 0.0}
    assert np.abs(numpy_policy.obs_mean).max() > 0.0  # real statistics, not an identity map
    obs, _ = env.reset(seed=0)
    rng = np.random.default_rng(0)
    for _ in range(40):
        expected = sb3(obs)
        np.testing.assert_allclose(numpy_policy(obs), expected, atol=1e-5)
        obs, _, terminated, truncated, _ = env.step(rng.uniform(-1, 1, 28))
        if terminated or truncated:
            obs, _ = env.reset()
    # a batch gives the rows of single calls; load_policy takes the .npz too
    batch = np.stack([env.observation_space.sample() * 0.1 for _ in range(5)])
    np.testing.assert_allclose(numpy_policy(batch), np.stack([numpy_policy(o) for o in batch]), atol=1e-6)
    assert isinstance(load_policy(str(out), env), NumpyPolicy)


def test_policy_for_another_env_is_refused(sb3_run, tmp_path, baseline_script):
    out = tmp_path / "policy.npz"
    baseline_script("export_policy").main([str(sb3_run), "--out", str(out)])
    with pytest.raises(ValueError, match="policy.npz"):
        load_policy(str(out), gym.make("PlaMo-v0"))


def _write(path, **arrays):
    np.savez(path, **arrays)
    return path


def _valid_arrays():
    return {"obs_mean": np.zeros(4), "obs_var": np.ones(4), "obs_clip": np.float64(10), "obs_epsilon": np.float64(1e-8),
            "weight_0": np.ones((3, 4)), "bias_0": np.zeros(3), "weight_1": np.ones((2, 3)), "bias_1": np.zeros(2)}


@pytest.mark.parametrize("fault", ["pickled_object", "truncated", "not_npz", "missing_stats", "no_layers",
                                   "shape_chain", "nan", "negative_var", "bad_config"])
def test_bad_policy_files_are_refused_naming_the_file(fault, tmp_path):
    path = tmp_path / f"{fault}.npz"
    arrays = _valid_arrays()
    if fault == "pickled_object":  # an object array would be unpickled by allow_pickle=True
        marker = tmp_path / "ran"

        class Payload:
            def __reduce__(self):
                return (open, (str(marker), "w"))

        arrays["config"] = np.array([Payload()], dtype=object)
        _write(path, **arrays)
    elif fault == "truncated":
        _write(path, **arrays)
        path.write_bytes(path.read_bytes()[:100])
    elif fault == "not_npz":
        path.write_bytes(pickle.dumps({"weights": 1}))
    else:
        if fault == "missing_stats":
            del arrays["obs_var"]
        elif fault == "no_layers":
            del arrays["weight_0"], arrays["weight_1"]
        elif fault == "shape_chain":
            arrays["weight_1"] = np.ones((2, 5))
        elif fault == "nan":
            arrays["bias_0"] = np.array([0.0, np.nan, 0.0])
        elif fault == "negative_var":
            arrays["obs_var"] = -np.ones(4)
        elif fault == "bad_config":
            arrays["config"] = np.array("{not json")
        _write(path, **arrays)
    with pytest.raises(PolicyFileError, match=fault):
        load_file(path)
    if fault == "pickled_object":
        assert not marker.exists()


def test_valid_arrays_make_a_policy(tmp_path):
    policy = load_file(_write(tmp_path / "ok.npz", **_valid_arrays()))
    np.testing.assert_allclose(policy(np.zeros(4)), [0.0, 0.0])  # ReLU(0) -> 0 -> mean 0
    np.testing.assert_allclose(policy(np.ones(4)), [1.0, 1.0])  # 12 before clipping to the action space


def test_an_env_without_a_shipped_policy_is_named():
    with pytest.raises(FileNotFoundError, match="NoSuchEnv-v0"):
        load("NoSuchEnv-v0")


def test_a_policy_file_that_unpacks_to_too_much_is_refused_before_reading(tmp_path):
    import zipfile

    from stairenv.pretrained import MAX_UNPACKED_BYTES

    path = tmp_path / "bomb.npz"
    chunk = bytes(2**20)
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        with archive.open("weight_0.npy", "w", force_zip64=True) as member:
            for _ in range(MAX_UNPACKED_BYTES // len(chunk) + 1):
                member.write(chunk)
    assert path.stat().st_size < 2 * 2**20  # a small file ...
    with pytest.raises(PolicyFileError, match="unpacks to"):  # ... that would unpack to over 512 MiB
        load_file(path)


def _top_progress(policy, env, seed: int, steps: int) -> float:
    obs, _ = env.reset(seed=seed)
    top = 0.0
    for _ in range(steps):
        obs, _, terminated, truncated, info = env.step(policy(obs))
        top = max(top, info["progress"])
        if terminated or truncated:
            break
    return top


def test_the_shipped_interlevel_policy_climbs_where_the_zero_policy_does_not():
    """The policy in the package (``stairenv/policies/InterLevel-v0.npz``): numpy only, deterministic, its
    evaluation stored beside it, and it gets up staircases of 5 cm steps from a standing start, where
    the zero policy never leaves the floor."""
    policy = load("InterLevel-v0")
    assert policy.config["env_id"] == "InterLevel-v0"
    assert policy.config["evaluation"]["groups"]  # the table it was shipped with
    env = gym.make("InterLevel-v0", step_height_set=(0.05,), max_episode_steps=300)
    obs, _ = env.reset(seed=0)
    action = policy(obs)
    assert action.shape == (28,) and np.all(np.abs(action) <= 1.0)
    np.testing.assert_array_equal(action, policy(obs.copy()))
    seeds = range(500_000, 500_006)
    zero = [_top_progress(lambda o: np.zeros(28), env, seed, 300) for seed in seeds]
    shipped = [_top_progress(policy, env, seed, 300) for seed in seeds]
    env.close()
    assert max(zero) == 0.0
    assert np.mean(shipped) >= 0.25, shipped
