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
from stairenv.pretrained import NumpyPolicy, PolicyFileError, load, load_file, shipped_policy_path


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


def test_a_lean_checkpoint_exports_as_its_trainer_acts(tmp_path, baseline_script):
    """``export_policy.py`` on a lean trainer's ``.pt``: the trainer's own deterministic policy, bit for bit,
    with the run's settings, the notes and the evaluation in its config; another env id is refused."""
    from stairenv.training import TrainConfig, Trainer

    trainer = Trainer(TrainConfig(num_envs=2, physics="serial", rollout_steps=8, minibatch_size=8, epochs=1,
                                  style="none", total_steps=16))
    trainer.collect()
    trainer.update()  # the weights and statistics move away from their start
    checkpoint = trainer.save(tmp_path / "checkpoint_16.pt")
    expected = trainer.policy()
    trainer.close()
    notes, evaluation = tmp_path / "notes.json", tmp_path / "evaluation.json"
    notes.write_text(json.dumps({"lineage": ["a test run"], "wall_clock_training_hours": 0.0}))
    evaluation.write_text(json.dumps({"success_pct": 1.0}))
    out = tmp_path / "policy.npz"
    assert baseline_script("export_policy").main([str(checkpoint), "--out", str(out), "--config", str(notes),
                                                  "--evaluation", str(evaluation)]) == 0
    policy = load_file(out, gym.make("InterLevel-v0").unwrapped)
    assert policy.config["env_id"] == "InterLevel-v0" and policy.config["steps"] == 16
    assert policy.config["source"] == "checkpoint_16.pt" and policy.config["evaluation"] == {"success_pct": 1.0}
    assert policy.config["training"]["lineage"] == ["a test run"] and policy.config["training"]["num_envs"] == 2
    obs = np.random.default_rng(0).normal(size=(5, policy.obs_size))
    np.testing.assert_array_equal(policy(obs), expected(obs))
    with pytest.raises(SystemExit):
        baseline_script("export_policy").main([str(checkpoint), "--out", str(out), "--env", "PlaMo-v0"])


def test_an_id_that_shares_a_controller_runs_its_policy():
    """``PlaMoScene-v0`` and ``PlaMoNaivePaths-v0`` name ``policy = "PlaMo-v0"`` in their presets: they run the
    path follower trained on ``PlaMo-v0`` (same observation and actions); other ids run their own."""
    from stairenv.pretrained import policy_id

    assert policy_id("PlaMoScene-v0") == policy_id("PlaMoNaivePaths-v0") == "PlaMo-v0"
    assert policy_id("SIMS-Walk-v0") == "SIMS-Walk-v0" and policy_id("NoSuchEnv-v0") == "NoSuchEnv-v0"
    assert shipped_policy_path("PlaMoScene-v0") == shipped_policy_path("PlaMo-v0")
    for env_id in ("PlaMoScene-v0", "PlaMoNaivePaths-v0"):
        policy = load(env_id)  # the sizes checked against this id's spaces
        assert policy.config["env_id"] == "PlaMo-v0"


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


@pytest.mark.parametrize("env_id", ["InterLevel2D-v0", "InterSceneStairs-v0"])
def test_the_table_1_ablation_policies_ship_and_climb_low_steps(env_id):
    """Table 1's ablation rows (2026-12-07: the InterLevel-v0 recipe from scratch, 8.0M steps on the
    ablation's reward) ship beside the main policy: ``load(env_id)`` is its own policy, trained on that id,
    and it gets up 5 cm steps from a standing start, where the zero policy never leaves the floor."""
    policy = load(env_id)
    assert policy.config["env_id"] == env_id and "Table 1" in policy.config["training"]["run"]
    env = gym.make(env_id, step_height_set=(0.05,), max_episode_steps=300)
    seeds = range(500_000, 500_012)
    zero = [_top_progress(lambda o: np.zeros(28), env, seed, 300) for seed in seeds]
    trained = [_top_progress(policy, env, seed, 300) for seed in seeds]
    env.close()
    assert max(zero) == 0.0
    # (their 1,000-staircase progress at 0.05 m: 69.8% and 20.4%; the best on these 12: 74% and 10% on average)
    assert sum(top > 0.0 for top in trained) >= 2 and np.mean(trained) >= 0.05, trained


def _episode(policy, env, seed: int) -> tuple[int, dict, dict]:
    """(steps survived, the last info, the first info) of one episode."""
    obs, first = env.reset(seed=seed)
    for step in range(1, 10**6):
        obs, _, terminated, truncated, info = env.step(policy(obs))
        if terminated or truncated:
            return step, info, first
    raise AssertionError("no time limit")


def test_the_shipped_path_follower_walks_a_walk_path_where_the_zero_policy_falls():
    """``PlaMo-v0``'s shipped policy (an interim one: it walks, issue #24) follows flat walk paths at the
    paper's one height and speed per path: 5 s paths, six unseen seeds. The zero policy falls in about
    a second on every one."""
    policy = load("PlaMo-v0")
    assert policy.config["env_id"] == "PlaMo-v0" and policy.config["evaluation"]["table2"]["rows"]
    env = gym.make("PlaMo-v0", locomotion="walk", terrain="flat", constant_paths=True, max_episode_steps=150)
    seeds = range(500_000, 500_006)
    zero = [_episode(lambda o: np.zeros(28), env, seed)[0] for seed in seeds]
    shipped = [_episode(policy, env, seed)[0] for seed in seeds]
    env.close()
    assert max(zero) < 40, zero
    assert np.mean(shipped) >= 100 and sum(steps == 150 for steps in shipped) >= 3, shipped


def test_the_shipped_walker_stays_up_and_nears_its_goals():
    """``SIMS-Walk-v0``'s shipped policy (interim, issue #25): text-conditioned, trained with the MiniLM
    embeddings and the captions it records; on six unseen goals over 5 s, told in its captions, it stays
    up (at most one trip) where the zero policy falls, and ends nearer its goals than it started, on average."""
    from stairenv.pretrained import with_trained_captions

    policy = load("SIMS-Walk-v0")
    assert policy.config["text_encoder_id"].startswith("all-MiniLM-L6-v2")
    env = gym.make("SIMS-Walk-v0", **with_trained_captions({"max_episode_steps": 150}, policy))
    seeds = range(500_000, 500_006)
    zero = [_episode(lambda o: np.zeros(28), env, seed) for seed in seeds]
    shipped = [_episode(policy, env, seed) for seed in seeds]
    env.close()
    assert all(info["fell"] for _, info, _ in zero), [steps for steps, _, _ in zero]
    assert sum(info["fell"] for _, info, _ in shipped) <= 1, [steps for steps, _, _ in shipped]
    start = np.mean([first["contact_error"] for _, _, first in shipped])
    end = np.mean([info["contact_error"] for _, info, _ in shipped])
    assert end < start - 0.3, (start, end)


def test_a_text_conditioned_policy_refuses_another_encoder(tmp_path, monkeypatch):
    """A policy trained on MiniLM embeddings, loaded where the env embeds with the hashing encoder, is
    refused with both encoders named (it would read the text input as noise)."""
    from stairenv import pretrained

    arrays = dict(np.load(shipped_policy_path("SIMS-Walk-v0")))
    config = json.loads(str(arrays["config"]))
    config["text_encoder_id"] = "another-encoder"
    arrays["config"] = np.array(json.dumps(config))
    path = _write(tmp_path / "SIMS-Walk-v0.npz", **arrays)
    monkeypatch.setattr(pretrained, "shipped_policy_path", lambda env_id: path)
    with pytest.raises(PolicyFileError, match="another-encoder"):
        load("SIMS-Walk-v0")


def _shipped_arrays():
    with np.load(shipped_policy_path("InterLevel-v0")) as z:
        return {k: z[k] for k in z.files}


def _npy_bomb(path):
    """A policy whose weight_0 header declares a (100000, 100000) float64 array (80 GB) in 64 real bytes."""
    import io
    import zipfile

    from numpy.lib import format as npy

    with zipfile.ZipFile(path, "w") as archive:
        for name, value in _valid_arrays().items():
            buffer = io.BytesIO()
            if name == "weight_0":
                npy.write_array_header_1_0(buffer, {"descr": "<f8", "fortran_order": False,
                                                    "shape": (100_000, 100_000)})
                buffer.write(bytes(64))
            else:
                np.save(buffer, value)
            archive.writestr(f"{name}.npy", buffer.getvalue())
    return path


# each crafted file -> the field its PolicyFileError must name
CRAFTED = {
    "weight_1_removed": "bias_1",  # would load as one layer of 256 actions
    "nan_clip": "obs_clip",
    "nan_epsilon": "obs_epsilon",
    "negative_epsilon_zero_var": "obs_epsilon",
    "weights_1e300": "weight_0",
    "scalar_mean": "obs_mean",
    "clip_list": "obs_clip",
    "clip_text": "obs_clip",
    "text_weights": "weight_1",
    "text_bias": "bias_0",
    "complex_weights": "weight_0",
    "header_bomb": "weight_0",
    "layer_gap": "weight_2",
    "config_array": "config",
    "bias_short": "bias_1 has shape (255,); expected (256,)",
    "bias_missing": "bias_0 missing",
    "obs_size_chain": "weight_0 has shape (256, 118); expected (outputs, 117)",
    "var_shape": "obs_var (117,)",
    "clip_missing": "obs_clip missing",
    "clip_negative": "obs_clip is -1.0",
    "epsilon_inf": "obs_epsilon is inf",
    "mean_inf": "obs_mean has 118 NaN or infinite",
    "bool_weights": "weight_0 has dtype bool",
    "int_weights": "weight_0 has dtype int64, not floats",
    "too_many_layers": "weight_16 present",
}


@pytest.mark.parametrize("fault", sorted(CRAFTED))
def test_crafted_policy_files_name_the_file_and_the_field(fault, tmp_path):
    path = tmp_path / f"{fault}.npz"
    arrays = _shipped_arrays()
    if fault == "header_bomb":
        _npy_bomb(path)
    else:
        if fault == "weight_1_removed":
            del arrays["weight_1"]
        elif fault == "nan_clip":
            arrays["obs_clip"] = np.float64(np.nan)
        elif fault == "nan_epsilon":
            arrays["obs_epsilon"] = np.float64(np.nan)
        elif fault == "negative_epsilon_zero_var":
            arrays["obs_var"][3] = 0.0
            arrays["obs_epsilon"] = np.float64(-1e-8)
        elif fault == "weights_1e300":
            arrays["weight_0"] = arrays["weight_0"] * 1e300
        elif fault == "scalar_mean":
            arrays["obs_mean"] = np.float64(0.0)
        elif fault == "clip_list":
            arrays["obs_clip"] = np.array([1.0, 2.0, 3.0])
        elif fault == "clip_text":
            arrays["obs_clip"] = np.array("ten")
        elif fault == "text_weights":
            arrays["weight_1"] = arrays["weight_1"].astype(str)
        elif fault == "text_bias":
            arrays["bias_0"] = arrays["bias_0"].astype(str)
        elif fault == "complex_weights":
            arrays["weight_0"] = arrays["weight_0"].astype(complex)
        elif fault == "layer_gap":
            del arrays["weight_1"], arrays["bias_1"]
        elif fault == "config_array":
            arrays["config"] = np.array(["{}", "{}"])
        elif fault == "bias_short":
            arrays["bias_1"] = arrays["bias_1"][:-1]
        elif fault == "bias_missing":
            del arrays["bias_0"]
        elif fault == "obs_size_chain":  # statistics for 117 observations, a first layer taking 118
            arrays["obs_mean"], arrays["obs_var"] = arrays["obs_mean"][:-1], arrays["obs_var"][:-1]
        elif fault == "var_shape":
            arrays["obs_var"] = arrays["obs_var"][:-1]
        elif fault == "clip_missing":
            del arrays["obs_clip"]
        elif fault == "clip_negative":
            arrays["obs_clip"] = np.float64(-1.0)
        elif fault == "epsilon_inf":
            arrays["obs_epsilon"] = np.float64(np.inf)
        elif fault == "mean_inf":
            arrays["obs_mean"] = np.full(118, np.inf)
        elif fault == "bool_weights":
            arrays["weight_0"] = arrays["weight_0"] > 0
        elif fault == "int_weights":
            arrays["weight_0"] = arrays["weight_0"].astype(np.int64)
        elif fault == "too_many_layers":
            for i in range(3, 17):
                arrays[f"weight_{i}"], arrays[f"bias_{i}"] = np.eye(28), np.zeros(28)
        _write(path, **arrays)
    with pytest.raises(PolicyFileError) as caught:
        load_file(path)
    assert str(path) in str(caught.value) and CRAFTED[fault] in str(caught.value), caught.value


def test_the_shipped_policy_loads_and_acts_bit_identically(tmp_path):
    """The checks change nothing for a valid file: the actions are, bit for bit, the forward pass of the
    arrays as stored, and a save / load round trip keeps them."""
    arrays = _shipped_arrays()
    policy = load_file(shipped_policy_path("InterLevel-v0"), gym.make("InterLevel-v0").unwrapped)
    obs = np.random.default_rng(0).normal(0.0, 3.0, size=(64, 118))
    x = np.clip((obs - arrays["obs_mean"]) * (1.0 / np.sqrt(arrays["obs_var"] + arrays["obs_epsilon"])),
                -arrays["obs_clip"], arrays["obs_clip"])
    for i in range(2):
        x = np.maximum(x @ arrays[f"weight_{i}"].T + arrays[f"bias_{i}"], 0.0)
    expected = np.clip(x @ arrays["weight_2"].T + arrays["bias_2"], -1.0, 1.0).astype(np.float32)
    np.testing.assert_array_equal(policy(obs), expected)
    policy.save(tmp_path / "again.npz")
    np.testing.assert_array_equal(load_file(tmp_path / "again.npz")(obs), expected)


def test_zero_variance_with_a_positive_epsilon_and_an_unclipped_identity_map_load(tmp_path):
    arrays = _shipped_arrays()
    arrays["obs_var"][3] = 0.0  # a constant observation: VecNormalize's epsilon keeps the scale finite
    policy = load_file(_write(tmp_path / "zero_var.npz", **arrays))
    assert np.isfinite(policy(np.zeros(118))).all()
    arrays.update(obs_mean=np.zeros(118), obs_var=np.ones(118), obs_clip=np.float64(np.inf),
                  obs_epsilon=np.float64(0.0))  # from_sb3 without a normaliser
    assert load_file(_write(tmp_path / "identity.npz", **arrays)).obs_clip == np.inf


def test_policy_sizes_are_checked_against_the_env(tmp_path, monkeypatch):
    from stairenv import pretrained

    arrays = _shipped_arrays()
    arrays["weight_2"] = np.zeros((1000, 256))  # a last layer of 1,000 outputs
    arrays["bias_2"] = np.zeros(1000)
    path = _write(tmp_path / "wide.npz", **arrays)
    assert load_file(path).action_size == 1000  # a well-formed network on its own ...
    env = gym.make("InterLevel-v0")
    with pytest.raises(PolicyFileError, match=r"wide\.npz.*\(1000,\) actions"):  # ... not for this env
        load_file(path, env)
    monkeypatch.setattr(pretrained, "shipped_policy_path", lambda env_id: path)
    with pytest.raises(PolicyFileError, match=r"wide\.npz.*weight_2.*\(28,\)"):
        load("InterLevel-v0")
    with pytest.raises(ValueError, match="wide.npz"):
        load_policy(str(path), env)
    env.close()


def _traced_peak(call) -> int:
    """The peak of Python's and numpy's allocations (``tracemalloc``) while ``call()`` runs."""
    import gc
    import tracemalloc

    gc.collect()
    tracemalloc.start()
    try:
        call()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_a_zip_bomb_under_the_size_limit_is_refused_in_little_memory(tmp_path):
    """A member declaring 256 MiB (under the 512 MiB limit) in a few hundred KB of deflated zeros was unpacked
    whole, and copied once more (+0.5 GB peak; +1.2 GB at the limit): its ratio is refused before reading."""
    import zipfile

    from numpy.lib import format as npy

    path = tmp_path / "bomb.npz"
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        with archive.open("weight_0.npy", "w") as member:
            npy.write_array_header_1_0(member, {"descr": "<f8", "fortran_order": False, "shape": (2**25,)})
            chunk = bytes(2**20)
            for _ in range(256):
                member.write(chunk)
    assert path.stat().st_size < 2**20

    def read():
        with pytest.raises(PolicyFileError, match=r"bomb\.npz: member 'weight_0\.npy' unpacks \d+ bytes to "
                                                  r"268435\d+, over 50 times"):
            load_file(path)

    assert _traced_peak(read) < 16 * 2**20


def test_a_large_member_is_read_without_a_second_copy(tmp_path):
    """Members are read a chunk at a time into their arrays: reading 32 MiB of weights costs about 32 MiB
    (it cost twice that: the member's bytes, then the array copied from them), and the arrays are the file's."""
    from stairenv.pretrained import _read_arrays

    weights = np.random.default_rng(0).normal(size=(2048, 2048)).astype(np.float64)
    path = tmp_path / "large.npz"
    np.savez(path, weight_0=weights, fortran=np.asfortranarray(weights[:3, :5]), text=np.array("config"))
    arrays = {}
    peak = _traced_peak(lambda: arrays.update(_read_arrays(path)))
    assert peak < 1.25 * weights.nbytes, peak / weights.nbytes
    np.testing.assert_array_equal(arrays["weight_0"], weights)
    np.testing.assert_array_equal(arrays["fortran"], weights[:3, :5])
    assert arrays["text"].item() == "config"
