"""Discriminator-free style measures and the checkpoint ranking script."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import stairenv  # noqa: F401
from stairenv.evaluation.policies import load_policy, normalizer_beside
from stairenv.style.metrics import MIN_SPREAD, nearest_reference_distance, reference_spread, rollout_windows


def test_nearest_reference_distance_by_hand():
    reference = np.array([[0.0, 0.0], [2.0, 0.0], [0.0, 2.0], [2.0, 2.0]])
    mean, spread = reference_spread(reference)
    np.testing.assert_allclose(mean, [1.0, 1.0])
    np.testing.assert_allclose(spread, [1.0, 1.0])
    # (4, 1) standardises to (3, 0); the nearest reference points are (1, +-1): sqrt(4 + 1) over sqrt(2) numbers.
    got = nearest_reference_distance(np.array([[4.0, 1.0], [2.0, 2.0]]), reference)
    np.testing.assert_allclose(got, [np.sqrt(5.0) / np.sqrt(2.0), 0.0])
    # A number the reference never varies is measured in MIN_SPREAD units, not divided by zero.
    flat = np.array([[0.0, 5.0], [2.0, 5.0]])
    got = nearest_reference_distance(np.array([[0.0, 5.02]]), flat)
    np.testing.assert_allclose(got, [0.02 / MIN_SPREAD / np.sqrt(2.0)])
    with pytest.raises(ValueError, match=r"shape \(N, 2\)"):
        nearest_reference_distance(np.zeros((3, 5)), reference)
    with pytest.raises(ValueError, match="finite"):
        nearest_reference_distance(np.array([[np.nan, 0.0]]), reference)


def test_rollout_windows_are_the_envs_amp_obs():
    env = gym.make("InterLevel-v0", amp_history=2)
    policy = load_policy("zero", env)
    windows, conditions, lengths = rollout_windows(policy, env, episodes=2, seed=3, max_steps=5)
    assert windows.shape == (10, 2 * 105) and conditions is None
    np.testing.assert_array_equal(lengths, [5, 5])
    _, info = env.reset(seed=3)
    _, _, _, _, info = env.step(np.zeros(28))
    np.testing.assert_array_equal(windows[0], np.asarray(info["amp_obs"], dtype=np.float32).ravel())
    with pytest.raises(ValueError, match="episodes"):
        rollout_windows(policy, env, episodes=0)


def test_checkpoints_are_ranked_with_their_own_normalisers(tmp_path, baseline_script):
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from stairenv.motion.rsi import load_reference_library
    from stairenv.style.discriminator import DiscriminatorConfig
    from stairenv.style.reference import ReferenceWindows
    from stairenv.style.wrappers import AMPStyleReward

    run = tmp_path / "InterLevel-v0" / "seed0"
    (run / "checkpoints").mkdir(parents=True)
    venv = VecNormalize(DummyVecEnv([lambda: gym.make("InterLevel-v0")]))
    model = PPO("MlpPolicy", venv, policy_kwargs={"net_arch": [8]}, n_steps=64, batch_size=64, seed=0)
    for steps in (100, 300):
        model.save(run / "checkpoints" / f"ppo_{steps}_steps.zip")
        venv.save(str(run / "checkpoints" / f"ppo_vecnormalize_{steps}_steps.pkl"))
    library = load_reference_library("builtin:stairs")
    reference = ReferenceWindows(library, num_frames=2, fps=30.0)
    AMPStyleReward(reference, config=DiscriminatorConfig(hidden=(16,))).save(run / "checkpoints" / "amp_300_steps.pt")

    assert normalizer_beside(run / "checkpoints" / "ppo_300_steps.zip").name == "ppo_vecnormalize_300_steps.pkl"
    assert normalizer_beside(tmp_path / "model.zip") is None

    evaluate_style = baseline_script("evaluate_style")
    rows = evaluate_style.main([str(run), "--episodes", "1", "--max-episode-steps", "4", "--baselines", "zero",
                                "--csv", str(tmp_path / "style.csv"), "--json", str(tmp_path / "style.json")])
    assert [r["checkpoint"] for r in rows] == ["zero", "ppo_100_steps.zip", "ppo_300_steps.zip"]
    assert [r["steps"] for r in rows] == [None, 100, 300]
    for row in rows:
        assert 0.0 <= row["style"] <= 1.0 and row["ref_dist"] > 0.0 and row["episode_length"] == 4.0
    assert (tmp_path / "style.csv").read_text().startswith("checkpoint,steps,")
    with pytest.raises(SystemExit):
        evaluate_style.main([str(tmp_path / "nowhere")])


def test_a_lean_runs_checkpoints_are_ranked(tmp_path, baseline_script):
    """evaluate_style.py reads a lean-trainer run: checkpoint_<n>.pt and final_policy.npz as policies,
    the discriminator inside its newest checkpoint."""
    from stairenv.style.wrappers import default_reference
    from stairenv.training import TrainConfig, Trainer, build_style, make_env

    run = tmp_path / "InterLevel-v0" / "seed0"
    config = TrainConfig(num_envs=2, physics="serial", rollout_steps=8, minibatch_size=8, epochs=1, total_steps=32,
                         checkpoint_every=16, disc_hidden=(16,), disc_replay_size=64, disc_update_interval=16,
                         disc_batch_size=8)
    venv = make_env(config)
    trainer = Trainer(config, build_style(config, default_reference(venv)), venv)
    trainer.learn(checkpoint_dir=run / "checkpoints")
    trainer.policy().save(run / "final_policy.npz")
    trainer.close()
    evaluate_style = baseline_script("evaluate_style")
    assert evaluate_style.newest_discriminator(run) == run / "checkpoints" / "checkpoint_32.pt"
    rows = evaluate_style.main([str(run), "--episodes", "1", "--max-episode-steps", "4", "--baselines", "zero"])
    assert [r["checkpoint"] for r in rows] == ["zero", "checkpoint_16.pt", "checkpoint_32.pt", "final_policy.npz"]
    assert [r["steps"] for r in rows] == [None, 16, 32, None]
    assert rows[2]["style"] == rows[3]["style"]    # the last checkpoint and the final policy act alike
    for row in rows:
        assert 0.0 <= row["style"] <= 1.0 and row["episode_length"] == 4.0
