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
from stairenv.motion.rsi import load_reference_library
from stairenv.style.discriminator import (
    AMPDiscriminator,
    DiscriminatorConfig,
    ReplayBuffer,
    RunningNorm,
    onednn_available,
    style_reward,
)
from stairenv.style.features import AMP_FEATURE_SIZE, AMP_FEATURE_STRUCTURE, state_features
from stairenv.style.reference import ReferenceWindows
from stairenv.style.wrappers import AMPStyleReward, AMPVecEnvWrapper, AMPVectorWrapper
from stairenv.training import cli


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


@pytest.mark.slow
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


def plain_update(disc: AMPDiscriminator, optimizer, reference: np.ndarray, agent: np.ndarray) -> dict[str, float]:
    """The discriminator step written out plainly (everything through autograd, ATen kernels)."""
    cfg = disc.config
    ref, fake = torch.as_tensor(reference, dtype=torch.float32), torch.as_tensor(agent, dtype=torch.float32)
    disc.norm.update(torch.cat((ref, fake)))

    def mlp(x):
        for layer in disc.linears[:-1]:
            x = torch.relu(torch.nn.functional.linear(x, layer.weight, layer.bias))
        return torch.nn.functional.linear(x, disc.logit.weight, disc.logit.bias).squeeze(-1)

    ref_n = disc.norm(ref).requires_grad_(True)
    d_ref, d_fake = mlp(ref_n), mlp(disc.norm(fake))
    (grad,) = torch.autograd.grad(d_ref.sum(), ref_n, create_graph=True)
    penalty = grad.square().sum(-1).mean()
    decay = sum(layer.weight.square().sum() for layer in disc.linears)
    loss = (0.5 * torch.mean((d_ref - 1.0) ** 2) + 0.5 * torch.mean((d_fake + 1.0) ** 2)
            + cfg.grad_penalty * penalty + cfg.logit_reg * disc.logit.weight.square().sum()
            + cfg.weight_decay * decay)
    optimizer.zero_grad(set_to_none=True)
    loss.backward()
    optimizer.step()
    return {"disc_loss": loss.item(), "disc_grad_penalty": penalty.item()}


@pytest.mark.parametrize("backend", ["auto", "aten"])
def test_fast_update_equals_the_plain_formulation(backend):
    """oneDNN products, in-place decay gradients and fused Adam change nothing but rounding."""
    rng = np.random.default_rng(3)
    config = DiscriminatorConfig(batch_size=64, weight_decay=1e-2)  # decay large enough to matter
    torch.manual_seed(0)
    fast = AMPDiscriminator(210, config, backend=backend)
    torch.manual_seed(0)
    plain = AMPDiscriminator(210, config, backend="aten")
    optimizer = torch.optim.Adam(plain.parameters(), lr=config.learning_rate, foreach=False)
    for _ in range(5):
        ref, agent = rng.normal(size=(64, 210)), rng.normal(0.5, 2.0, size=(64, 210))
        got, want = fast.update(ref, agent), plain_update(plain, optimizer, ref, agent)
        for key in want:
            assert got[key] == pytest.approx(want[key], rel=1e-4, abs=1e-6), key
    for (name, a), b in zip(fast.named_parameters(), plain.parameters()):
        np.testing.assert_allclose(a.detach().numpy(), b.detach().numpy(), atol=2e-6, err_msg=name)
    for name in ("mean", "var", "count"):
        np.testing.assert_allclose(getattr(fast.norm, name).numpy(), getattr(plain.norm, name).numpy(), rtol=1e-12)


def test_onednn_backend_is_used_where_it_works():
    disc = AMPDiscriminator(210)
    assert disc.onednn == onednn_available()
    assert not AMPDiscriminator(210, backend="aten").onednn
    with pytest.raises(ValueError, match="backend"):
        AMPDiscriminator(210, backend="cuda")


@pytest.mark.parametrize("scoring", ["auto", "numba", "numba-parallel", "torch"])
def test_scoring_follows_training_loading_and_edits(scoring):
    """The cached scoring plan is rebuilt whenever a weight or a normaliser statistic changes."""
    rng = np.random.default_rng(0)
    disc = AMPDiscriminator(210, DiscriminatorConfig(hidden=(64, 32), batch_size=32), scoring=scoring)
    x = rng.normal(size=(8, 210))

    def direct():
        with torch.no_grad():
            return disc(torch.as_tensor(x, dtype=torch.float32)).numpy()

    before = disc.logits(x)
    np.testing.assert_allclose(before, direct(), atol=1e-5)
    disc.update(rng.normal(size=(32, 210)), rng.normal(size=(32, 210)))
    after = disc.logits(x)
    assert np.abs(after - before).max() > 1e-4
    np.testing.assert_allclose(after, direct(), atol=1e-5)
    with torch.no_grad():
        disc.trunk[0].weight.mul_(1.5)
        disc.norm.mean.add_(0.1)
    np.testing.assert_allclose(disc.logits(x), direct(), atol=1e-5)
    other = AMPDiscriminator(210, DiscriminatorConfig(hidden=(64, 32), batch_size=32), scoring=scoring)
    other.logits(x)  # builds its plan with its own weights
    other.load_state_dict(disc.state_dict())
    np.testing.assert_array_equal(other.logits(x), disc.logits(x))
    assert disc.logits(np.zeros((0, 210))).shape == (0,)
    with pytest.raises(ValueError, match="features"):
        disc.logits(np.zeros((2, 211)))


@pytest.mark.parametrize("count", [1, 3, 8, 13, 40])  # blocks of 8 windows, of 4, and single ones
def test_numba_and_torch_scoring_agree(reference, count):
    torch.manual_seed(0)
    disc = AMPDiscriminator(reference.dim, scoring="numba")
    rng = np.random.default_rng(0)
    disc.update(reference.sample(256, rng), random_action_windows(256, seed=3))
    windows = random_action_windows(count, seed=6)
    numba = disc.logits(windows)
    disc.scoring = "torch"
    disc._plan = None
    np.testing.assert_allclose(numba, disc.logits(windows), atol=1e-5)
    with pytest.raises(ValueError, match="scoring"):
        AMPDiscriminator(reference.dim, scoring="numpy")


def test_parallel_and_bf16_scoring_match_float32(reference):
    torch.manual_seed(0)
    disc = AMPDiscriminator(reference.dim)
    rng = np.random.default_rng(0)
    for _ in range(5):
        disc.update(reference.sample(256, rng), random_action_windows(256, seed=3))
    windows = np.concatenate((random_action_windows(40, seed=6), reference.sample(40, rng)))
    exact = disc.logits(windows)
    assert exact.std() > 0.1  # trained: the logits spread, so agreement below means something
    disc.scoring = "numba-parallel"
    np.testing.assert_allclose(disc.logits(windows), exact, atol=1e-5)
    disc.scoring_threads = 1
    np.testing.assert_allclose(disc.logits(windows), exact, atol=1e-5)
    disc.scoring = "bf16"
    half = disc.logits(windows)
    assert half.dtype == np.float32
    assert np.abs(half - exact).max() < 0.03 * max(1.0, np.abs(exact).max())
    rewards = style_reward(half, "lsgan") - style_reward(exact, "lsgan")
    assert np.abs(rewards).max() < 0.02


def _constant_feed(style: AMPStyleReward, windows: np.ndarray, calls: int) -> list[np.ndarray]:
    return [style(windows, np.zeros(len(windows)))[1] for _ in range(calls)]


def test_background_training_lags_the_synchronous_schedule_by_one_round(reference):
    """Same minibatches, same weights in the end; the rewards are the synchronous ones one round later."""
    windows = random_action_windows(8, seed=4)
    config = DiscriminatorConfig(hidden=(64, 32), batch_size=32, input_noise=0.5)
    runs = {}
    for background in (False, True):
        torch.manual_seed(1)
        disc = AMPDiscriminator(reference.dim, config)
        style = AMPStyleReward(reference, config=config, update_interval=16, seed=2, discriminator=disc,
                               background_training=background)
        runs[background] = (style, _constant_feed(style, windows, 12))
    (sync, r_sync), (bg, r_bg) = runs[False], runs[True]
    assert not np.allclose(r_sync[0], r_sync[-1])  # the discriminator did learn between rounds
    calls_per_round = 2  # 16 transitions / 8 envs
    np.testing.assert_array_equal(r_bg[:calls_per_round], r_sync[:calls_per_round])
    for i in range(calls_per_round, 12):
        np.testing.assert_allclose(r_bg[i], r_sync[i - calls_per_round], atol=1e-6)
    bg.wait()
    assert bg.rounds == sync.rounds == 6
    for a, b in zip(sync.disc.parameters(), bg.disc.parameters()):
        torch.testing.assert_close(a, b, atol=1e-6, rtol=1e-5)
    assert set(bg.last_stats) == set(sync.last_stats)
    bg.close()
    assert bg._worker is None


def test_background_training_errors_surface_at_the_next_round(reference, tmp_path):
    style = AMPStyleReward(reference, update_interval=8, background_training=True,
                           config=DiscriminatorConfig(hidden=(16,), batch_size=8))
    windows = random_action_windows(8, seed=5)

    def broken(*args):
        raise RuntimeError("disc exploded")

    style.disc.update = broken
    style(windows, np.zeros(8))  # starts the round, which fails in the worker
    with pytest.raises(RuntimeError, match="disc exploded"):
        style(windows, np.zeros(8))
    del style.disc.update  # the method again: saving joins the round in flight first
    style(windows, np.zeros(8))
    loaded = AMPStyleReward.load(style.save(tmp_path / "amp.pt"), reference)
    assert loaded.background_training and loaded.rounds == style.rounds == 1
    style.close()


def test_batched_scoring_equals_per_step_scoring(reference):
    """Scoring a whole rollout at once gives the rewards scoring it step by step (8 envs) does."""
    disc = AMPDiscriminator(reference.dim)
    rng = np.random.default_rng(0)
    disc.update(reference.sample(256, rng), random_action_windows(256, seed=3))
    windows = random_action_windows(64 * 8, seed=4)
    per_step = np.concatenate([disc.reward(w) for w in windows.reshape(64, 8, -1)])
    np.testing.assert_allclose(disc.reward(windows), per_step, atol=1e-5)
    np.testing.assert_allclose(disc.logits(windows[:1]), disc.logits(windows[:8])[:1], atol=1e-5)


def test_grad_penalty_on_a_subsample(reference):
    rng = np.random.default_rng(1)
    ref, agent = reference.sample(64, rng), random_action_windows(64, seed=5)
    for n in (None, 16):
        torch.manual_seed(0)
        disc = AMPDiscriminator(reference.dim, DiscriminatorConfig(batch_size=64, grad_penalty_batch=n),
                                backend="aten")
        probe = AMPDiscriminator.from_state(disc.state(), backend="aten")  # the penalty by hand, before the step
        probe.norm.update(torch.as_tensor(np.concatenate((ref, agent)), dtype=torch.float32))
        x = probe.norm(torch.as_tensor(ref[: n or 64], dtype=torch.float32)).requires_grad_(True)
        (grad,) = torch.autograd.grad(probe._mlp(x).sum(), x)
        stats = disc.update(ref, agent)
        assert stats["disc_grad_penalty"] == pytest.approx(grad.square().sum(-1).mean().item(), rel=1e-5)
    with pytest.raises(ValueError, match="grad_penalty_batch"):
        DiscriminatorConfig(grad_penalty_batch=0)
    stats = AMPDiscriminator(reference.dim, DiscriminatorConfig(batch_size=64, grad_penalty=0.0)).update(ref, agent)
    assert stats["disc_grad_penalty"] == 0.0


def test_instance_noise_is_training_only(reference):
    rng = np.random.default_rng(2)
    ref, agent = reference.sample(64, rng), random_action_windows(64, seed=7)
    states = []
    for noise in (0.0, 0.5):
        torch.manual_seed(0)
        disc = AMPDiscriminator(reference.dim, DiscriminatorConfig(batch_size=64, input_noise=noise))
        before = disc.logits(agent)
        disc.update(ref, agent)
        states.append((before, disc.logits(agent)))
    np.testing.assert_array_equal(states[0][0], states[1][0])  # same init, clean scoring
    assert np.abs(states[0][1] - states[1][1]).max() > 1e-6  # the noise changed the step
    with pytest.raises(ValueError, match="input_noise"):
        DiscriminatorConfig(input_noise=-0.1)


def test_train_ppo_discriminator_flags(baseline_script):
    paper = cli.discriminator_config(cli.parse_args(["--preset", "paper"]))
    assert paper == DiscriminatorConfig()  # the paper's discriminator with --preset paper
    default = cli.discriminator_config(cli.parse_args([]))
    assert default == DiscriminatorConfig(grad_penalty=10.0, input_noise=1.0, replay_size=200_000)
    args = cli.parse_args(["--disc-hidden", "512,256", "--disc-grad-penalty", "10", "--disc-lr", "1e-5",
                                 "--disc-replay-size", "200000", "--disc-grad-penalty-batch", "64",
                                 "--disc-updates", "1", "--disc-update-interval", "4096",
                                 "--disc-weight-decay", "1e-3", "--disc-logit-reg", "0.05",
                                 "--disc-input-noise", "0.5", "--disc-background", "--disc-scoring", "bf16"])
    config = cli.discriminator_config(args)
    assert config.hidden == (512, 256) and config.grad_penalty == 10.0 and config.learning_rate == 1e-5
    assert config.weight_decay == 1e-3 and config.logit_reg == 0.05 and config.input_noise == 0.5
    assert config.replay_size == 200_000 and config.grad_penalty_batch == 64
    assert args.disc_updates == 1 and args.disc_update_interval == 4096
    assert args.disc_background and args.disc_scoring == "bf16"
    defaults = cli.parse_args([])
    assert defaults.disc_background and defaults.vec_env == "batched"
    assert not cli.parse_args(["--no-disc-background"]).disc_background
    with pytest.raises(SystemExit):
        cli.parse_args(["--disc-hidden", "512,x"])
    preset = cli.parse_args(["--preset", "style-short", "--w-style", "0.7"])
    assert preset.disc_input_noise == 1.0 and preset.learning_rate == 1e-5 and preset.log_std_init == -2.0
    assert preset.w_style == 0.7  # explicit flags win over the preset
    no_noise = cli.parse_args(["--preset", "style-short", "--disc-input-noise", "0"])
    assert no_noise.disc_input_noise == 0.0  # even when the flag repeats the default
    assert cli.parse_args(["--preset", "paper"]).disc_input_noise == 0.0  # the paper's settings


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


@pytest.mark.parametrize("env_id", ["InterLevel-v0", "SIMS-Sit-v0"])
def test_isaac_lab_amp_convention(env_id):
    """``amp_observation_space`` holds every ``info["amp_obs"]``; ``collect_reference_motions`` gives
    windows of the env's reference clips shaped as it, and drawing them changes no episode."""
    env = gym.make(env_id, amp_history=3).unwrapped
    _, info = env.reset(seed=0)
    space = env.amp_observation_space
    assert space.shape == info["amp_obs"].shape == (3 * AMP_FEATURE_SIZE,)
    windows = env.collect_reference_motions(64)
    assert windows.shape == (64, *space.shape) and windows.dtype == np.float64 and space.contains(windows[0])
    library = load_reference_library(env.DEFAULT_REFERENCE_MOTION)
    every = ReferenceWindows(library, num_frames=3, fps=1.0 / env.dt).windows
    assert all(np.isclose(every, row, atol=1e-6).all(axis=1).any() for row in windows[:8].astype(np.float32))
    with pytest.raises(ValueError, match="num_samples"):
        env.collect_reference_motions(0)
    # the episode does not depend on whether reference windows were drawn
    action = np.full(28, 0.1)
    first = [env.step(action)[0] for _ in range(3)]
    env.reset(seed=0)
    env.collect_reference_motions(10)
    np.testing.assert_array_equal(first, [env.step(action)[0] for _ in range(3)])
    venv = gym.make_vec("InterLevel-v0", num_envs=2, vectorization_mode="vector_entry_point")
    assert venv.amp_observation_space.shape == (2 * AMP_FEATURE_SIZE,)
    assert venv.collect_reference_motions(5).shape == (5, 2 * AMP_FEATURE_SIZE)
    venv.close()
