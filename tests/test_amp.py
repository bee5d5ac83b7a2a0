"""AMP: features shared by env and reference, discriminator losses and training, the wrappers."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation
from stable_baselines3 import PPO
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import VecEnvWrapper

import stairenv  # noqa: F401
from stairenv.humanoid import DOF_NAMES, STANDING_ROOT_HEIGHT
from stairenv.motion import MotionClip, MotionLibrary
from stairenv.style.discriminator import AMPDiscriminator, DiscriminatorConfig, ReplayBuffer, RunningNorm, style_reward
from stairenv.style.features import AMP_FEATURE_SIZE, AMP_FEATURE_STRUCTURE, state_features
from stairenv.style.reference import ReferenceWindows
from stairenv.style.wrappers import AMPStyleReward, AMPVecEnvWrapper, AMPVectorWrapper


def gait_clip(seconds: float = 3.0, fps: float = 30.0, speed: float = 1.0) -> MotionClip:
    """A simple periodic stepping motion: hips and knees swing in antiphase while the root moves forward."""
    t = np.arange(int(seconds * fps)) / fps
    phase = 2 * math.pi * 1.0 * t
    q = np.zeros((len(t), 35))
    q[:, 0] = speed * t
    q[:, 2] = STANDING_ROOT_HEIGHT - 0.03
    q[:, 3] = 1.0
    dof = {name: 7 + i for i, name in enumerate(DOF_NAMES)}
    q[:, dof["right_hip_y"]] = -0.4 * np.sin(phase)
    q[:, dof["left_hip_y"]] = 0.4 * np.sin(phase)
    q[:, dof["right_knee"]] = 0.3 + 0.3 * np.maximum(np.sin(phase), 0)
    q[:, dof["left_knee"]] = 0.3 + 0.3 * np.maximum(-np.sin(phase), 0)
    q[:, dof["right_shoulder_y"]] = 0.3 * np.sin(phase)
    q[:, dof["left_shoulder_y"]] = -0.3 * np.sin(phase)
    q[:, dof["right_elbow"]] = -0.4
    q[:, dof["left_elbow"]] = -0.4
    return MotionClip(q, fps, "test_gait")


@pytest.fixture(scope="module")
def reference() -> ReferenceWindows:
    return ReferenceWindows(MotionLibrary([gait_clip()]), num_frames=2, fps=30.0)


def random_action_windows(n_steps: int, seed: int = 0) -> np.ndarray:
    env = gym.make("InterLevel-v0")
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n_steps):
        _, _, terminated, truncated, info = env.step(rng.uniform(-1, 1, 28))
        out.append(info["amp_obs"])
        if terminated or truncated:
            env.reset()
    return np.array(out)


# --- features --------------------------------------------------------------------
def test_feature_layout():
    sizes = [s.stop - s.start for s in AMP_FEATURE_STRUCTURE.values()]
    assert sum(sizes) == AMP_FEATURE_SIZE == 105
    assert [s.start for s in AMP_FEATURE_STRUCTURE.values()] == list(np.cumsum([0] + sizes[:-1]))


def test_env_amp_obs_equals_reference_features_of_the_same_state():
    env = gym.make("InterLevel-v0", amp_history=3)
    env.reset(seed=4)
    frames = []
    u = env.unwrapped
    for _ in range(4):
        _, _, _, _, info = env.step(np.full(28, 0.3))
        frames.append(state_features(u.data.qpos.copy(), u.data.qvel.copy())[0])
    assert info["amp_obs"].shape == (3 * 105,)
    np.testing.assert_allclose(info["amp_obs"].reshape(3, 105), np.array(frames[-3:]), atol=1e-12)


def test_features_are_heading_invariant_and_hinges_are_angles():
    clip = gait_clip(seconds=0.5)
    qpos, qvel = clip.qpos[5].copy(), clip.qvel()[5].copy()
    f0 = state_features(qpos, qvel)[0]
    turn = Rotation.from_euler("z", 2.0)
    qpos2, qvel2 = qpos.copy(), qvel.copy()
    qpos2[:3] = turn.apply(qpos[:3])
    qpos2[3:7] = (turn * Rotation.from_quat(qpos[3:7], scalar_first=True)).as_quat(scalar_first=True)
    qvel2[:3] = turn.apply(qvel[:3])
    np.testing.assert_allclose(state_features(qpos2, qvel2)[0], f0, atol=1e-12)
    knee = 7 + DOF_NAMES.index("right_knee")
    assert f0[AMP_FEATURE_STRUCTURE["hinge_angles"]][2] == pytest.approx(qpos[knee])
    # Root height is measured from the lower foot: the same on any floor height.
    qpos3 = qpos.copy()
    qpos3[2] += 0.7
    assert state_features(qpos3, qvel)[0][0] == pytest.approx(f0[0])


# --- discriminator -----------------------------------------------------------------
def test_style_reward_formulas():
    d = np.array([-1.0, 0.0, 1.0, 3.0])
    np.testing.assert_allclose(style_reward(d, "lsgan"), [0.0, 0.75, 1.0, 0.0])
    sig = 1 / (1 + np.exp(-d))
    np.testing.assert_allclose(style_reward(d, "bce"), -np.log(np.maximum(1 - sig, 1e-4)))
    assert style_reward(np.array([50.0]), "bce")[0] == pytest.approx(-math.log(1e-4))
    with pytest.raises(ValueError, match="loss"):
        style_reward(d, "hinge")


def test_running_norm_matches_numpy():
    rng = np.random.default_rng(0)
    norm = RunningNorm(3)
    data = [rng.normal(2.0, 3.0, (50, 3)) for _ in range(4)]
    for batch in data:
        norm.update(torch.as_tensor(batch))
    allx = np.concatenate(data)
    np.testing.assert_allclose(norm.mean.numpy(), allx.mean(0), rtol=1e-4)
    np.testing.assert_allclose(norm.var.numpy(), allx.var(0), rtol=1e-4)


def test_replay_buffer_wraps():
    buf = ReplayBuffer(5, 2)
    buf.add(np.arange(6).reshape(3, 2))
    buf.add(np.arange(6, 14).reshape(4, 2))
    assert len(buf) == 5
    assert {tuple(r) for r in buf.data} == {(4, 5), (6, 7), (8, 9), (10, 11), (12, 13)}
    with pytest.raises(ValueError):
        ReplayBuffer(3, 2).sample(1, np.random.default_rng())


def test_bad_discriminator_config():
    with pytest.raises(ValueError, match="loss"):
        DiscriminatorConfig(loss="wgan")
    with pytest.raises(ValueError, match="grad_penalty"):
        DiscriminatorConfig(grad_penalty=-1)


@pytest.mark.parametrize("loss", ["lsgan", "bce"])
def test_discriminator_separates_reference_from_random_actions(reference, loss):
    torch.manual_seed(0)
    rng = np.random.default_rng(0)
    agent = random_action_windows(600, seed=1)
    train_agent, held_agent = agent[:400], agent[400:]
    ref_idx = rng.permutation(len(reference.windows))
    train_ref, held_ref = reference.windows[ref_idx[:40]], reference.windows[ref_idx[40:]]
    disc = AMPDiscriminator(reference.dim, DiscriminatorConfig(loss=loss, batch_size=128))
    for _ in range(200):
        disc.update(train_ref[rng.integers(0, len(train_ref), 128)], train_agent[rng.integers(0, 400, 128)])
    d_ref, d_agent = disc.logits(held_ref), disc.logits(held_agent)
    accuracy = 0.5 * ((d_ref > 0).mean() + (d_agent < 0).mean())
    assert accuracy > 0.9
    assert disc.reward(held_ref).mean() > disc.reward(held_agent).mean() + 0.1


# --- wrappers --------------------------------------------------------------------
def test_sb3_ppo_trains_through_the_wrapper(reference):
    style = AMPStyleReward(reference, w_task=0.5, w_style=0.5, update_interval=512, updates_per_round=2,
                           config=DiscriminatorConfig(batch_size=128))
    venv = AMPVecEnvWrapper(make_vec_env("InterLevel-v0", n_envs=2, seed=0), style)
    seen = []

    class Probe(VecEnvWrapper):
        """Records what the AMP wrapper hands to PPO."""

        def reset(self):
            return self.venv.reset()

        def step_wait(self):
            obs, reward, dones, infos = self.venv.step_wait()
            seen.append((reward, infos))
            return obs, reward, dones, infos

    probe = Probe(venv)
    model = PPO("MlpPolicy", probe, n_steps=256, batch_size=128, n_epochs=1, verbose=0, seed=0)
    model.learn(2048)
    assert style.rounds >= 3 and "disc_loss" in style.last_stats
    assert len(seen) == 1024
    for reward, infos in seen[-50:]:
        for r, info in zip(reward, infos):
            assert r == pytest.approx(0.5 * info["task_reward"] + 0.5 * info["style_reward"], rel=1e-5, abs=1e-6)
            assert 0.0 <= info["style_reward"] <= 1.0
            # The task part is the env's own reward: its reward_* terms sum to it.
            assert info["task_reward"] == pytest.approx(
                sum(v for k, v in info.items() if k.startswith("reward_")), abs=1e-5)  # SB3 keeps rewards as float32


def test_save_load_round_trip_gives_identical_rewards(reference, tmp_path):
    style = AMPStyleReward(reference, config=DiscriminatorConfig(batch_size=64), update_interval=10**9)
    agent = random_action_windows(100, seed=2)
    style.replay.add(agent)
    style.train_round(5)
    path = style.save(tmp_path / "amp.pt")
    loaded = AMPStyleReward.load(path, reference)
    task = np.linspace(0, 1, len(agent))
    np.testing.assert_array_equal(style(agent, task)[0], loaded(agent, task)[0])
    assert loaded.config == style.config and loaded.w_style == style.w_style


def test_mismatched_history_is_a_clear_error(reference):
    style = AMPStyleReward(reference)
    with pytest.raises(ValueError, match="amp_history"):
        style(np.zeros((2, 3 * 105)), np.zeros(2))


def test_gymnasium_vector_wrapper(reference):
    envs = gym.make_vec("InterLevel-v0", num_envs=2, vectorization_mode="sync")
    wrapped = AMPVectorWrapper(envs, AMPStyleReward(reference, w_task=1.0, w_style=1.0))
    wrapped.reset(seed=0)
    rng = np.random.default_rng(0)
    saw_reset_step = False
    prev_done = np.zeros(2, dtype=bool)
    for _ in range(80):
        _, reward, terminated, truncated, info = wrapped.step(rng.uniform(-1, 1, (2, 28)))
        live = ~prev_done
        np.testing.assert_allclose(reward[live], info["task_reward"][live] + info["style_reward"][live])
        if prev_done.any():
            saw_reset_step = True
            assert np.all(info["style_reward"][prev_done] == 0.0)
        prev_done = terminated | truncated
    assert saw_reset_step
