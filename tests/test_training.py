"""The lean PPO + AMP trainer (``stairenv.training``): its pieces against Stable-Baselines3's, which it
mirrors (normalisers, GAE, networks), its checkpoints, and ``train_ppo.py`` running it end to end."""

from __future__ import annotations

import json
import os
import pickle
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch
from stable_baselines3.common.vec_env import VecEnv

import stairenv  # noqa: F401
from stairenv.environments.sims import reference_captions
from stairenv.motion.rsi import load_reference_library
from stairenv.training import CheckpointError, TrainConfig, Trainer, cli, read_checkpoint
from stairenv.training.ppo import ActorCritic, Normalizer, Rollout

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "baselines" / "train_ppo.py"
SHIPPED_CHECKPOINT = ROOT / "checkpoints" / "InterLevel-v0" / "ppo_3200000_steps.zip"


class ScriptedVecEnv(VecEnv):
    """An SB3 VecEnv that replays given (obs, rewards, dones): what VecNormalize sees from an env."""

    def __init__(self, first: np.ndarray, steps: list) -> None:
        space = gym.spaces.Box(-np.inf, np.inf, shape=first.shape[1:], dtype=np.float64)
        self.first, self.steps = first, iter(steps)
        super().__init__(first.shape[0], space, gym.spaces.Box(-1, 1, (1,)))

    def reset(self):
        return self.first.copy()

    def step_async(self, actions):
        pass

    def step_wait(self):
        obs, rewards, dones = next(self.steps)
        return obs.copy(), rewards.copy(), dones.copy(), [{} for _ in dones]

    def close(self):
        pass

    def get_attr(self, name, indices=None):
        return [None] * self.num_envs

    def set_attr(self, name, value, indices=None):
        pass

    def env_method(self, *args, **kwargs):
        return []

    def env_is_wrapped(self, wrapper_class, indices=None):
        return [False] * self.num_envs


def test_normalizer_matches_vecnormalize():
    """Observations and rewards normalised as SB3's VecNormalize does, step by step, episode ends included."""
    from stable_baselines3.common.vec_env import VecNormalize

    rng = np.random.default_rng(0)
    n, size, gamma = 4, 5, 0.99
    first = rng.normal(3.0, 2.0, (n, size))
    steps = [(rng.normal(3.0, 2.0, (n, size)), rng.normal(0.5, 1.0, n), rng.uniform(size=n) < 0.2)
             for _ in range(30)]
    sb3 = VecNormalize(ScriptedVecEnv(first, steps), gamma=gamma)
    ours = Normalizer(size, n, gamma, clip_obs=10.0, clip_reward=10.0)
    np.testing.assert_allclose(ours.observations(first), sb3.reset(), rtol=1e-6, atol=1e-6)
    for obs, rewards, dones in steps:
        want_obs, want_rewards, _, _ = sb3.step(np.zeros((n, 1)))
        np.testing.assert_allclose(ours.observations(obs), want_obs, rtol=1e-5, atol=1e-6)
        np.testing.assert_allclose(ours.rewards(rewards, dones), want_rewards, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(ours.obs_rms.var, sb3.obs_rms.var)
    np.testing.assert_allclose(ours.ret_rms.var, sb3.ret_rms.var)


def test_gae_matches_sb3_rollout_buffer():
    from stable_baselines3.common.buffers import RolloutBuffer

    rng = np.random.default_rng(1)
    steps, n = 7, 3
    rewards, values = rng.normal(size=(steps, n)), rng.normal(size=(steps, n))
    starts = (rng.uniform(size=(steps, n)) < 0.3).astype(np.float32)
    last_values, last_dones = rng.normal(size=n), rng.uniform(size=n) < 0.5
    buffer = RolloutBuffer(steps, gym.spaces.Box(-1, 1, (2,)), gym.spaces.Box(-1, 1, (1,)), n_envs=n,
                           gamma=0.98, gae_lambda=0.9)
    for t in range(steps):
        buffer.add(np.zeros((n, 2)), np.zeros((n, 1)), rewards[t], starts[t], torch.as_tensor(values[t]),
                   torch.zeros(n))
    buffer.compute_returns_and_advantage(torch.as_tensor(last_values), last_dones)
    rollout = Rollout.empty(steps, n, 2, 1)
    rollout.rewards[:], rollout.values[:] = torch.as_tensor(rewards), torch.as_tensor(values)
    rollout.starts[:] = torch.as_tensor(starts)
    rollout.compute_returns(torch.as_tensor(last_values, dtype=torch.float32),
                            torch.as_tensor(last_dones, dtype=torch.float32), 0.98, 0.9)
    np.testing.assert_allclose(rollout.advantages.numpy(), buffer.advantages, rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(rollout.returns.numpy(), buffer.returns, rtol=1e-5, atol=1e-5)


def small_trainer(**changes) -> Trainer:
    config = TrainConfig(num_envs=2, physics="serial", rollout_steps=8, minibatch_size=8, epochs=2, style="none",
                         total_steps=32, **changes)
    return Trainer(config)


#: PPO + AMP on serial physics, small enough for a test: the discriminator trains every 16 steps
SMALL_AMP = TrainConfig(num_envs=2, physics="serial", rollout_steps=8, minibatch_size=8, epochs=2, total_steps=64,
                        checkpoint_every=32, disc_hidden=(16,), disc_replay_size=40, disc_update_interval=16,
                        disc_updates=1, disc_batch_size=8)


def amp_trainer(config: TrainConfig = SMALL_AMP) -> Trainer:
    from stairenv.style.wrappers import default_reference
    from stairenv.training import build_style, make_env

    venv = make_env(config)
    return Trainer(config, build_style(config, default_reference(venv)), venv)


@pytest.mark.skipif(not SHIPPED_CHECKPOINT.is_file(), reason="needs the committed SB3 checkpoint")
def test_an_sb3_checkpoint_carries_over(tmp_path):
    """``--init-from ppo_<n>_steps.zip``: the lean trainer's policy and value equal SB3's, so a run
    trained with SB3 goes on where it was."""
    from stable_baselines3 import PPO

    from stairenv.evaluation.policies import read_normalizer
    from stairenv.pretrained import from_sb3
    from stairenv.training.from_sb3 import state_from_sb3

    stats = SHIPPED_CHECKPOINT.with_name("ppo_vecnormalize_3200000_steps.pkl")
    trainer = small_trainer()
    trainer.load_state(state_from_sb3(SHIPPED_CHECKPOINT, stats, None), weights_only=True)
    model = PPO.load(str(SHIPPED_CHECKPOINT), device="cpu")
    reference = from_sb3(model, read_normalizer(stats))
    obs = np.random.default_rng(2).normal(size=(16, 118))
    np.testing.assert_allclose(trainer.policy()(obs), reference(obs), atol=1e-6)
    normalised = torch.as_tensor(trainer.normalizer.observations(obs, update=False))
    with torch.no_grad():
        want = model.policy.predict_values(normalised).squeeze(-1)
        np.testing.assert_allclose(trainer.model.values(normalised).numpy(), want.numpy(), rtol=1e-5, atol=1e-5)
    assert trainer.optimizer.state_dict()["state"].keys() == model.policy.optimizer.state_dict()["state"].keys()
    trainer.close()


def test_checkpoint_round_trip(tmp_path):
    trainer = small_trainer()
    trainer.collect()
    trainer.update()
    path = trainer.save(tmp_path / "checkpoint_16.pt")
    other = small_trainer(seed=5)
    other.load_state(read_checkpoint(path))
    assert (other.steps, other.iterations) == (16, 1)
    for a, b in zip(trainer.model.parameters(), other.model.parameters()):
        assert torch.equal(a, b)
    np.testing.assert_array_equal(other.normalizer.obs_rms.mean, trainer.normalizer.obs_rms.mean)
    assert other.config.seed == 5    # the caller chooses the config; train_ppo --resume takes the saved one
    assert TrainConfig.from_dict(read_checkpoint(path)["config"]) == trainer.config
    trainer.close()
    other.close()


def test_a_checkpoint_never_runs_code(tmp_path):
    marker = tmp_path / "ran"

    class Payload:
        def __reduce__(self):
            return (os.system, (f"touch {marker}",))

    crafted = tmp_path / "crafted.pt"
    torch.save({"format": "stairenv-ppo-amp/1", "model": Payload()}, crafted)
    with pytest.raises(CheckpointError, match="nothing in it was run"):
        read_checkpoint(crafted)
    assert not marker.exists()
    other = tmp_path / "other.pt"
    torch.save({"weights": torch.zeros(2)}, other)
    with pytest.raises(CheckpointError, match="not a lean-trainer checkpoint"):
        read_checkpoint(other)
    (tmp_path / "truncated.pt").write_bytes(pickle.dumps({"a": 1})[:5])
    with pytest.raises(CheckpointError):
        read_checkpoint(tmp_path / "truncated.pt")
    with pytest.raises(CheckpointError, match="no checkpoint file"):
        read_checkpoint(tmp_path / "missing.pt")


@pytest.mark.parametrize("field, value, message", [
    ("num_envs", 0, "num_envs"), ("epochs", 2.5, "epochs"), ("physics", "gpu", "physics"),
    ("hidden", (256, 0), "hidden"), ("style", "gail", "style"), ("learning_rate", -1.0, "learning_rate"),
    ("device", "", "device"), ("state_on_device", True, "for physics='warp' only"),
    ("state_on_device", "yes", "state_on_device must be True or False"),
])
def test_config_errors_name_the_field(field, value, message):
    with pytest.raises((TypeError, ValueError), match=message):
        TrainConfig(**{field: value})


def test_config_round_trip_and_unknown_fields():
    config = TrainConfig(env_kwargs={"step_height": (0.05, 0.1)}, hidden=(64, 32), target_kl=0.02, physics="warp",
                         state_on_device=True)
    again = TrainConfig.from_dict(config.as_dict())
    assert again.hidden == (64, 32) and again.target_kl == 0.02 and again.state_on_device is True
    older = config.as_dict()    # a checkpoint written before the field existed: the host's MjData the truth
    del older["state_on_device"]
    assert TrainConfig.from_dict(older).state_on_device is False
    with pytest.raises(ValueError, match="unknown TrainConfig fields"):
        TrainConfig.from_dict({"bogus": 1})


def test_actor_critic_mirrors_sb3_parameter_order():
    """Same parameter order as SB3's MlpPolicy, so an Adam state carries over slot by slot."""
    from stable_baselines3.common.policies import ActorCriticPolicy

    sb3 = ActorCriticPolicy(gym.spaces.Box(-1, 1, (5,)), gym.spaces.Box(-1, 1, (3,)), lambda _: 1e-4,
                            net_arch={"pi": [8, 8], "vf": [8, 8]}, activation_fn=torch.nn.ReLU)
    ours = ActorCritic(5, 3, (8, 8), 0.0)
    assert [tuple(p.shape) for p in ours.parameters()] == [tuple(p.shape) for p in sb3.parameters()]


def run_script(args: list[str], cwd: Path) -> str:
    # a cache of the run's own: what it synthesises does not depend on earlier tests' climbs
    env = {**os.environ, "MUJOCO_GL": "egl", "STAIRENV_CACHE": str(Path(cwd) / "stairenv-cache")}
    done = subprocess.run([sys.executable, str(SCRIPT), *args], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    return done.stdout


def test_train_ppo_lean_trains_checkpoints_resumes_and_evaluates(tmp_path, train_ppo):
    tiny = ["--n-envs", "4", "--n-steps", "32", "--batch-size", "64", "--checkpoint-every", "128",
            "--no-progress-bar", "--logdir", str(tmp_path)]
    out = train_ppo.run(["--timesteps", "256", "--eval-episodes", "2", "--eval-max-episode-steps", "20", *tiny],
                        tmp_path)
    run_dir = tmp_path / "InterLevel-v0" / "seed0"
    for name in ("checkpoints/checkpoint_128.pt", "checkpoints/checkpoint_256.pt", "final_checkpoint.pt",
                 "final_policy.npz", "evaluation.json", "log.jsonl"):
        assert (run_dir / name).exists(), name
    assert "Progress (%)" in out
    state = read_checkpoint(run_dir / "checkpoints" / "checkpoint_128.pt")
    assert state["steps"] == 128 and state["config"]["num_envs"] == 4 and state["style"] is not None
    state["config"]["device"] = "cuda"    # as a GPU run writes it: --resume takes this machine's --device (cpu)
    torch.save(state, run_dir / "checkpoints" / "checkpoint_128.pt")
    out = train_ppo.run(["--resume", str(run_dir / "checkpoints" / "checkpoint_128.pt"), "--timesteps", "128",
                         "--eval-episodes", "0", *tiny], tmp_path)
    assert "at 128 steps" in out and "trained 128 env steps" in out

    # --reset-std: a new run from the trained weights whose action noise starts at --log-std-init again
    # (a new task from a trained policy); a resume refuses the flag (it stays exact).
    start = read_checkpoint(run_dir / "checkpoints" / "checkpoint_256.pt")
    out = train_ppo.run(["--init-from", str(run_dir / "checkpoints" / "checkpoint_256.pt"), "--reset-std",
                         "--log-std-init", "-1.0", "--timesteps", "128", "--eval-episodes", "0", *tiny[:-2],
                         "--logdir", str(tmp_path / "reset")], tmp_path)
    assert "action noise reset to log std -1 (--reset-std)" in out
    after = read_checkpoint(tmp_path / "reset" / "InterLevel-v0" / "seed0" / "checkpoints" / "checkpoint_128.pt")
    assert torch.allclose(after["model"]["log_std"], torch.full_like(after["model"]["log_std"], -1.0), atol=0.02)
    assert not torch.allclose(start["model"]["log_std"], after["model"]["log_std"], atol=0.5)
    said = train_ppo.fails(["--resume", str(run_dir / "checkpoints" / "checkpoint_256.pt"), "--reset-std", *tiny],
                           tmp_path)
    assert "--reset-std only applies to --init-from" in said


@pytest.mark.slow
def test_climb_cache_workers_synthesise_the_runs_staircases_first(tmp_path):
    """--climb-cache-workers: the climbs of every staircase the run's stair starts can draw (here 2 heights x
    1 depth x 1 count x 2 lead feet) are synthesised before training; the run then trains as usual."""
    out = run_script(["--n-envs", "2", "--n-steps", "16", "--batch-size", "32", "--timesteps", "32",
                      "--no-progress-bar", "--logdir", str(tmp_path), "--eval-episodes", "0",
                      "--climb-cache-workers", "2", "--env-kwarg", "stairs_start_fraction=1.0",
                      "--env-kwarg", "step_height=(0.10,0.11)", "--env-kwarg", "step_depth=(0.30,0.30)",
                      "--env-kwarg", "num_steps=(3,3)"], tmp_path)
    assert "climb cache: 4 staircases synthesised on 2 processes" in out
    assert "trained 32 env steps" in out


def test_a_text_conditioned_run_resumes_without_the_flag(tmp_path, train_ppo):
    """The checkpoint records amp_text_condition: --resume needs no --amp-text-condition again."""
    tiny = ["--n-envs", "2", "--n-steps", "16", "--batch-size", "32", "--checkpoint-every", "32",
            "--no-progress-bar", "--logdir", str(tmp_path), "--eval-episodes", "0"]
    train_ppo.run(["--env", "SIMS-Sit-v0", "--amp-text-condition", "--env-kwarg", "text_encoder=hashing",
                   "--timesteps", "32", *tiny], tmp_path)
    checkpoint = tmp_path / "SIMS-Sit-v0" / "seed0" / "checkpoints" / "checkpoint_32.pt"
    assert read_checkpoint(checkpoint)["config"]["amp_text_condition"] is True
    out = train_ppo.run(["--resume", str(checkpoint), "--timesteps", "32", *tiny], tmp_path)
    assert "at 32 steps" in out and "trained 32 env steps" in out
    out = train_ppo.run(["--resume", str(checkpoint), "--timesteps", "32", "--fresh-discriminator", *tiny], tmp_path)
    assert "at 32 steps" in out and "a fresh discriminator" in out

    # A sit run's weights into reach, which SIMS does not condition on text: the discriminator's inputs
    # differ, so it is refused unless the run asks for a fresh discriminator.
    into_reach = ["--init-from", str(checkpoint), "--env", "SIMS-Reach-v0", "--timesteps", "32", *tiny]
    assert "--fresh-discriminator" in train_ppo.fails(into_reach, tmp_path)
    out = train_ppo.run([*into_reach, "--fresh-discriminator"], tmp_path)
    assert "a fresh discriminator" in out and "trained 32 env steps" in out
    reach = read_checkpoint(tmp_path / "SIMS-Reach-v0" / "seed0" / "checkpoints" / "checkpoint_32.pt")
    assert reach["config"]["amp_text_condition"] is False and reach["style"] is not None


def test_amp_text_captions_all_trains_on_every_caption_against_the_styles_texts(tmp_path, train_ppo):
    """--amp-text-captions all: the env keeps its own captions (the evaluation's) and conditions the
    discriminator on each style's reference text (condition_captions, recorded); --resume keeps it so."""
    tiny = ["--n-envs", "2", "--n-steps", "16", "--batch-size", "32", "--checkpoint-every", "32",
            "--no-progress-bar", "--logdir", str(tmp_path), "--eval-episodes", "0"]
    train_ppo.run(["--env", "SIMS-Walk-v0", "--amp-text-condition", "--amp-text-captions", "all", "--env-kwarg",
                   "text_encoder=hashing", "--timesteps", "32", *tiny], tmp_path)
    checkpoint = tmp_path / "SIMS-Walk-v0" / "seed0" / "checkpoints" / "checkpoint_32.pt"
    kwargs = read_checkpoint(checkpoint)["config"]["env_kwargs"]
    library = load_reference_library("builtin:sims")
    assert "captions" not in kwargs
    assert {tuple(pair) for pair in kwargs["condition_captions"]} >= set(reference_captions(library, "walk"))
    out = train_ppo.run(["--resume", str(checkpoint), "--timesteps", "32", *tiny], tmp_path)
    assert "at 32 steps" in out
    resumed = read_checkpoint(tmp_path / "SIMS-Walk-v0" / "seed0" / "checkpoints" / "checkpoint_64.pt")
    assert "captions" not in resumed["config"]["env_kwargs"]
    assert resumed["config"]["env_kwargs"]["condition_captions"] == kwargs["condition_captions"]


@pytest.mark.parametrize("scoring", ["auto", "bf16"])
def test_resume_equals_an_uninterrupted_run(tmp_path, scoring):
    """Serial physics, PPO + AMP (discriminator trained in the background): training on from a checkpoint
    (and the replay buffer beside it) gives the same weights, statistics and discriminator as the run
    that was never stopped, whichever way the discriminator scores (the resumed run's own way: bf16 used
    to fall back to "auto" at a resume)."""
    config = SMALL_AMP.replace(disc_scoring=scoring)

    def trainer():
        return amp_trainer(config)
    whole = trainer()
    whole.learn(checkpoint_dir=tmp_path / "whole")
    assert (tmp_path / "whole" / "checkpoint_32.pt").exists() and (tmp_path / "whole" / "replay_64.npy").exists()
    assert not (tmp_path / "whole" / "replay_32.npy").exists()    # only the latest replay buffer is kept
    # the same run stopped at 32 steps (its checkpoint's replay buffer then the latest), and resumed
    first = trainer()
    first.config = config.replace(total_steps=32)
    first.learn(checkpoint_dir=tmp_path / "first")
    first.close()
    resumed = trainer()
    state = read_checkpoint(tmp_path / "first" / "checkpoint_32.pt")
    resumed.load_state(state)
    assert resumed.load_replay(tmp_path / "first" / "checkpoint_32.pt", state)
    assert resumed.style.disc.scoring == scoring
    resumed.learn(checkpoint_dir=tmp_path / "resumed")
    assert resumed.steps == whole.steps == 64
    for a, b in zip(whole.model.parameters(), resumed.model.parameters()):
        assert torch.equal(a, b)
    for a, b in zip(whole.style.disc.state_dict().values(), resumed.style.disc.state_dict().values()):
        assert torch.equal(a, b)
    np.testing.assert_array_equal(whole.normalizer.obs_rms.var, resumed.normalizer.obs_rms.var)
    np.testing.assert_array_equal(whole.normalizer.ret_rms.var, resumed.normalizer.ret_rms.var)
    whole.close()
    resumed.close()


def test_the_last_step_is_a_checkpoint_and_a_final_checkpoint_finds_its_replay(tmp_path):
    """A run whose length is not a multiple of ``checkpoint_every`` still ends with a checkpoint (and its
    replay buffer), and ``final_checkpoint.pt`` beside ``checkpoints/`` resumes with that replay buffer."""
    trainer = amp_trainer(SMALL_AMP.replace(total_steps=48))    # rounds of 16: checkpoints at 32 and 48
    trainer.learn(checkpoint_dir=tmp_path / "checkpoints")
    assert (tmp_path / "checkpoints" / "checkpoint_32.pt").exists()
    assert (tmp_path / "checkpoints" / "checkpoint_48.pt").exists()
    assert (tmp_path / "checkpoints" / "replay_48.npy").exists()
    trainer.save(tmp_path / "final_checkpoint.pt")    # as train_ppo.py ends a run
    saved = trainer.style.replay
    last, final = (read_checkpoint(tmp_path / name) for name in ("checkpoints/checkpoint_48.pt", "final_checkpoint.pt"))
    assert final["steps"] == last["steps"] == 48
    for key in last["model"]:
        assert torch.equal(last["model"][key], final["model"][key])
    resumed = amp_trainer(SMALL_AMP.replace(total_steps=48))
    resumed.load_state(final)
    assert resumed.load_replay(tmp_path / "final_checkpoint.pt", final)
    assert resumed.style.replay.size == saved.size and resumed.style.replay.next == saved.next
    np.testing.assert_array_equal(resumed.style.replay.data[:saved.size], saved.data[:saved.size])
    (tmp_path / "checkpoints" / "replay_48.npy").unlink()    # none anywhere: the buffer refills
    fresh = amp_trainer(SMALL_AMP.replace(total_steps=48))
    assert not fresh.load_replay(tmp_path / "final_checkpoint.pt", final)
    for t in (trainer, resumed, fresh):
        t.close()


def test_a_kill_while_a_checkpoint_is_written_leaves_the_last_one_whole_with_its_replay(tmp_path, monkeypatch):
    """The older replay buffer is removed only once the new checkpoint is whole: a run stopped while writing
    ``checkpoint_64.pt`` leaves ``checkpoint_32.pt`` (the newest, which ``--auto-resume`` takes) with its
    replay buffer, so the resume is exact."""
    from stairenv.training import ppo

    write = ppo._atomic

    def killed_at_64(path, contents):
        if path.name == "checkpoint_64.pt":
            raise KeyboardInterrupt
        write(path, contents)

    monkeypatch.setattr(ppo, "_atomic", killed_at_64)
    trainer = amp_trainer()
    with pytest.raises(KeyboardInterrupt):
        trainer.learn(checkpoint_dir=tmp_path)
    trainer.close()
    monkeypatch.setattr(ppo, "_atomic", write)
    newest = ppo.checkpoints_in(tmp_path)[-1][1]
    assert newest.name == "checkpoint_32.pt" and (tmp_path / "replay_32.npy").is_file()
    resumed = amp_trainer()
    state = read_checkpoint(newest)
    resumed.load_state(state)
    assert resumed.load_replay(newest, state)
    resumed.close()


def test_init_from_takes_this_runs_discriminator_settings_or_says_why_not(tmp_path):
    """``load_state(weights_only=True)`` (``--init-from``): the discriminator's weights come from the checkpoint,
    its training settings (the learning rate its optimiser uses too) and instance noise (seeded with this
    rank's seed) from this run; other hidden layers than the weights' are refused, naming them (they used
    to be recorded, so the run's own checkpoints could not be resumed)."""
    first = amp_trainer(SMALL_AMP.replace(total_steps=16, checkpoint_every=16))
    first.learn(checkpoint_dir=tmp_path)
    first.close()
    state = read_checkpoint(tmp_path / "checkpoint_16.pt")
    config = SMALL_AMP.replace(seed=7, disc_lr=1e-3, disc_input_noise=0.5)
    run = amp_trainer(config)
    run.load_state(state, weights_only=True)
    disc = run.style.disc
    assert disc.config.learning_rate == 1e-3 and disc.config.input_noise == 0.5
    assert [group["lr"] for group in disc.optimizer.param_groups] == [1e-3]
    assert torch.equal(disc.noise_generator.get_state(), torch.Generator().manual_seed(7).get_state())
    for a, b in zip(disc.state_dict().values(), first.style.disc.state_dict().values()):
        assert torch.equal(a, b)
    run.close()
    other = amp_trainer(SMALL_AMP.replace(disc_hidden=(8,)))
    with pytest.raises(ValueError, match=r"hidden layers \[16\], this run asks for \[8\] \(--disc-hidden\)"):
        other.load_state(state, weights_only=True)
    other.close()


def test_saved_curriculum_levels_fit_another_count_of_worlds():
    """A checkpoint's curriculum levels, taken by a run of another world count (one rank or several), are
    repeated or cut in order to its worlds (a 2-world run's into a 4-world run used to stop)."""
    config = TrainConfig(num_envs=2, physics="serial", rollout_steps=8, minibatch_size=8, epochs=1, style="none",
                         total_steps=16, hidden=(32, 32), env_kwargs={"step_height_levels": 4})
    saved = Trainer(config)
    saved.venv.set_attr("curriculum_level", [3, 1])
    state = saved.state()
    saved.close()
    for n, levels in ((4, [3, 1, 3, 1]), (1, [3])):
        run = Trainer(config.replace(num_envs=n))
        run.load_state(state, weights_only=True)
        assert run.curriculum_levels() == levels
        run.close()


def test_a_non_finite_reward_stops_training_before_it_reaches_the_statistics(tmp_path):
    """A NaN reward (from a wrapper, say) stops the run with a ``FloatingPointError`` naming the world, before
    the return normaliser keeps it and the update spreads it into every weight: the checkpoints written
    before it stay sound (it used to train on and write an all-NaN checkpoint)."""
    config = TrainConfig(num_envs=2, physics="serial", rollout_steps=8, minibatch_size=16, epochs=1, style="none",
                         total_steps=32, checkpoint_every=16, hidden=(32, 32))
    trainer = Trainer(config)
    step_worlds, steps = trainer.venv.step_worlds, []

    def nan_at_the_12th_step(*args, **kwargs):
        out = list(step_worlds(*args, **kwargs))
        steps.append(1)
        if len(steps) == 12:    # after the checkpoint at 16 steps (8 steps of 2 worlds)
            out[1] = np.where([False, True], np.nan, out[1])
        return tuple(out)

    trainer.venv.step_worlds = nan_at_the_12th_step
    with pytest.raises(FloatingPointError, match=r"non-finite reward for world\(s\) \[1\] at step 22"):
        trainer.learn(checkpoint_dir=tmp_path)
    assert np.isfinite(trainer.normalizer.ret_rms.var).all()
    assert all(torch.isfinite(p).all() for p in trainer.model.parameters())
    state = read_checkpoint(tmp_path / "checkpoint_16.pt")
    assert all(torch.isfinite(v).all() for v in state["model"].values())
    trainer.close()


def test_config_paths_are_paths_and_a_fresh_discriminator_takes_the_disc_flags(tmp_path, baseline_script):
    """``--config`` keys are converted as their flags would be (``logdir = "runs"`` is a path, as
    ``--logdir runs``); ``--resume --fresh-discriminator`` builds the new discriminator with the ``--disc-*``
    flags given (they used to be ignored for the checkpoint's), the others staying the run's."""
    toml = tmp_path / "run.toml"
    toml.write_text(f'logdir = "{tmp_path / "runs"}"\ninit_from = "{tmp_path / "x.pt"}"\n')
    args = cli.parse_args(["--config", str(toml)])
    assert args.logdir == tmp_path / "runs" and isinstance(args.init_from, Path)
    saved = amp_trainer(SMALL_AMP.replace(total_steps=16, disc_loss="bce"))
    saved.save(tmp_path / "checkpoint_16.pt")
    saved.close()
    args = cli.parse_args(["--resume", str(tmp_path / "checkpoint_16.pt"), "--fresh-discriminator",
                                 "--disc-hidden", "8", "--disc-lr", "1e-3", "--logdir", str(tmp_path)])
    resume, _, config, _, _ = cli.lean_setup(args, print)
    assert resume["style"] is None
    assert (config.disc_hidden, config.disc_lr, config.disc_loss) == ((8,), 1e-3, "bce")


def test_a_checkpoint_cut_is_not_judged_by_the_curriculum():
    """The worlds' episodes cut at a checkpoint keep their curriculum levels (a task-ended one moves them)."""
    env = gym.make("InterLevel-v0", step_height_levels=4).unwrapped
    env.reset(seed=0)
    env.curriculum_level = 2
    for _ in range(3):
        env.step(np.zeros(28))
    env.reset(seed=1, options={"episode_cut": True})
    assert env.curriculum_level == 2
    for _ in range(3):
        env.step(np.zeros(28))
    env.reset(seed=1)    # a 3-step floor-start episode far below half the stairs: down a level
    assert env.curriculum_level == 1


def test_per_locomotion_speed_levels_are_logged_checkpointed_and_restored(tmp_path):
    """PlaMo's ``speed_levels_by_locomotion``: each locomotion's mean level is logged, a checkpoint keeps
    every world's tuple, a run with it takes them back; a per-world level is taken for every locomotion,
    and a run with one level per world does not take tuples."""
    from stairenv.training import make_env
    from stairenv.training.ppo import RunLog

    per_kind = {"speed_levels": 3, "speed_levels_by_locomotion": True}
    config = TrainConfig(env_id="PlaMo-v0", env_kwargs=per_kind, num_envs=2, physics="serial", style="none",
                         rollout_steps=8, minibatch_size=8, epochs=1, total_steps=16, checkpoint_every=16)
    trainer = Trainer(config, None, make_env(config))
    trainer.learn(log=RunLog(tmp_path), checkpoint_dir=tmp_path)
    logged = json.loads((tmp_path / "log.jsonl").read_text().splitlines()[-1])
    assert {"curriculum/level_crawl", "curriculum/level_walk", "curriculum/level_sprint"} <= set(logged)
    state = read_checkpoint(tmp_path / "checkpoint_16.pt")
    assert all(len(level) == 5 for level in state["curriculum_level"])
    trainer.close()
    state["curriculum_level"] = [(2, 1, 0, 1, 2), (0, 0, 2, 2, 1)]
    again = Trainer(config, None, make_env(config))
    again.load_state(state, weights_only=True)
    assert again.curriculum_levels() == [(2, 1, 0, 1, 2), (0, 0, 2, 2, 1)]
    again.load_state({**state, "curriculum_level": [1, 2], "config": {"env_kwargs": {"speed_levels": 3}}},
                     weights_only=True)
    assert again.curriculum_levels() == [(1,) * 5, (2,) * 5]
    again.close()
    per_world = config.replace(env_kwargs={"speed_levels": 3})
    plain = Trainer(per_world, None, make_env(per_world))
    plain.venv.reset(seed=0)
    plain.load_state(state, weights_only=True)                 # tuples do not fit one level per world
    assert plain.curriculum_levels() == [0, 0]
    plain.close()


# --- the device option ------------------------------------------------------------------------------
def assert_same_training(a: Trainer, b: Trainer) -> None:
    """The same weights, optimiser moments, statistics and discriminator, bit for bit."""
    for x, y in zip([*a.model.parameters(), *a.style.disc.state_dict().values()],
                    [*b.model.parameters(), *b.style.disc.state_dict().values()]):
        assert torch.equal(x.cpu(), y.cpu())
    for x, y in zip(a.optimizer.state_dict()["state"].values(), b.optimizer.state_dict()["state"].values()):
        assert all(torch.equal(x[k].cpu(), y[k].cpu()) for k in x)
    np.testing.assert_array_equal(a.normalizer.obs_rms.var, b.normalizer.obs_rms.var)
    np.testing.assert_array_equal(a.normalizer.ret_rms.var, b.normalizer.ret_rms.var)


def test_device_cpu_given_is_the_default():
    """``device="cpu"`` spelled out trains exactly as the default (PPO + AMP, background discriminator)."""
    trained = []
    for config in (SMALL_AMP, SMALL_AMP.replace(device="cpu")):    # one after the other: torch's generator is global
        trainer = amp_trainer(config)
        trainer.learn()
        trainer.style.wait()
        trained.append(trainer)
    default, given = trained
    assert given.device == torch.device("cpu") and given.style.disc.device == torch.device("cpu")
    assert_same_training(default, given)
    default.close()
    given.close()


def test_a_checkpoint_holds_cpu_tensors_and_loads_onto_the_runs_device(tmp_path):
    """Checkpoints are device-independent: every tensor saved on the CPU (a plain ``torch.load`` finds them
    there), taken onto the loading trainer's device by ``load_state``."""
    def tensors_in(value):
        if isinstance(value, dict):
            value = list(value.values())
        if isinstance(value, (list, tuple)):
            return [t for item in value for t in tensors_in(item)]
        return [value] if isinstance(value, torch.Tensor) else []

    trainer = amp_trainer()
    trainer.learn()
    path = trainer.save(tmp_path / "checkpoint_64.pt")
    state = read_checkpoint(path)
    saved = torch.load(path, weights_only=True)    # without map_location: where they were saved
    assert len(tensors_in(saved)) > 20 and all(t.device.type == "cpu" for t in tensors_in(saved))
    assert torch.equal(saved["model"]["action_mean.weight"], state["model"]["action_mean.weight"])
    other = amp_trainer(SMALL_AMP.replace(device="cpu", seed=3))
    other.load_state(state)
    assert_same_training(trainer, other)
    np.testing.assert_array_equal(trainer.policy().weights[0], other.policy().weights[0])
    trainer.close()
    other.close()


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA GPU")
def test_training_on_cuda_checkpoints_load_on_the_cpu(tmp_path):
    """``device="cuda"``: networks, rollout, optimisers and discriminator on the GPU; its checkpoint loads on
    the CPU (and back), the exported numpy policy acts as the CUDA policy's mean, the discriminator scores
    alike on both devices."""
    config = SMALL_AMP.replace(device="cuda")
    gpu = amp_trainer(config)
    assert gpu.rollout.obs.is_cuda and next(gpu.model.parameters()).is_cuda and gpu.style.disc.device.type == "cuda"
    gpu.learn()
    gpu.style.wait()
    assert all(s.is_cuda for s in gpu.optimizer.state_dict()["state"][0].values() if s.dim() > 0)
    path = gpu.save(tmp_path / "checkpoint_64.pt")
    state = read_checkpoint(path)
    cpu = amp_trainer(SMALL_AMP)
    cpu.load_state(state)
    assert_same_training(gpu, cpu)
    obs = np.random.default_rng(0).normal(size=(16, gpu.venv.single_observation_space.shape[0]))
    with torch.no_grad():
        normalised = torch.as_tensor(gpu.normalizer.observations(obs, update=False), device="cuda")
        mean = gpu.model.distribution(normalised).loc.cpu().numpy()
    np.testing.assert_allclose(gpu.policy()(obs), mean, rtol=1e-4, atol=1e-5)
    np.testing.assert_array_equal(gpu.policy()(obs), cpu.policy()(obs))
    gpu.style.disc.unfreeze_scoring()    # score with the trained weights, as the checkpoint holds them
    windows = gpu.style.reference.sample(32, np.random.default_rng(1))
    np.testing.assert_allclose(gpu.style.disc.logits(windows), cpu.style.disc.logits(windows), rtol=1e-4, atol=1e-4)
    # and back: a CPU checkpoint goes on on the GPU (its optimisers' moments moved there)
    again = amp_trainer(config.replace(total_steps=96))
    again.load_state(read_checkpoint(cpu.save(tmp_path / "cpu_64.pt")))
    again.learn()
    assert again.steps == 96
    for trainer in (gpu, cpu, again):
        trainer.close()


def test_auto_resume_goes_on_from_the_runs_newest_checkpoint_as_if_never_stopped(tmp_path, train_ppo):
    """--auto-resume: the same command starts the run, and after a stop goes on from its newest checkpoint
    to the run's own end, with the weights of the run never stopped (no style: no replay buffer, which is
    kept beside the latest checkpoint only)."""
    command = ["--style", "none", "--n-envs", "2", "--n-steps", "16", "--batch-size", "32", "--checkpoint-every",
               "32", "--timesteps", "96", "--no-progress-bar", "--logdir", str(tmp_path), "--eval-episodes", "0",
               "--policy-hidden", "32,32", "--auto-resume"]
    assert "no checkpoint of this run" in train_ppo.run(command, tmp_path)
    run = tmp_path / "InterLevel-v0" / "seed0"
    never_stopped = read_checkpoint(run / "final_checkpoint.pt")
    for later in ("checkpoints/checkpoint_64.pt", "checkpoints/checkpoint_96.pt", "final_checkpoint.pt"):
        (run / later).unlink()    # as if stopped after its checkpoint at 32 steps
    out = train_ppo.run(command, tmp_path)
    assert f"resumed from {run / 'checkpoints' / 'checkpoint_32.pt'} at 32 steps" in out
    assert "trained 64 env steps" in out    # on to the run's 96, not 96 more
    restarted = read_checkpoint(run / "final_checkpoint.pt")
    assert restarted["steps"] == never_stopped["steps"] == 96
    for name, weights in never_stopped["model"].items():
        assert torch.equal(restarted["model"][name], weights), name
    said = train_ppo.fails([*command, "--resume", str(run / "final_checkpoint.pt")], tmp_path)
    assert "--auto-resume finds the run's own checkpoint" in said


def test_episode_log_reads_ended_worlds_from_columns_and_dicts():
    """``EpisodeLog``: an ended world's return, length and results, read from the step's columns or from a
    world's whole dict (an unstable step's, lacking a key); an aided start (on the stairs) counts in
    ``episode/`` only, a floor start in ``episode_floor_start/`` too; worlds that did not end count nowhere."""
    from stairenv.environments.infos import WorldInfos
    from stairenv.training.ppo import EpisodeLog

    log = EpisodeLog(4)
    log.step(np.array([1.0, 2.0, 3.0, 4.0]), np.zeros(4, dtype=bool), WorldInfos(4))
    infos = WorldInfos(4)
    infos.put(np.array([0, 1, 3]), {"progress": np.array([0.5, 0.25, 0.75]), "success": np.array([True, False, False]),
                                    "stairs_start": np.array([False, True, False])})
    infos[2] = {"success": False, "stairs_start": False}    # no progress reported
    log.step(np.array([1.0, 1.0, 1.0, 1.0]), np.array([True, True, True, False]), infos)
    means = log.means()
    assert means["episode/task_return"] == pytest.approx((2 + 3 + 4) / 3) and means["episode/length"] == 2
    assert means["episode/progress"] == pytest.approx((0.5 + 0.25) / 2)
    assert means["episode_floor_start/progress"] == 0.5    # world 1 started on the stairs; world 2 lacks it
    assert means["episode/success"] == pytest.approx(1 / 3) and means["episode_floor_start/success"] == 0.5
    assert log.length.tolist() == [0, 0, 0, 2] and log.task_return[3] == 5.0 and log.means() == {}


def test_ranks_on_other_cpus_drift_within_a_tolerance_and_are_realigned(tmp_path, monkeypatch):
    """Ranks on machines with other CPUs round their optimiser steps in other low bits, so their weights
    drift apart by ~1e-7 (relative): a checkpoint used to stop such a run ("the ranks' weights differ",
    an exact comparison). Now a drift within ``RANK_DRIFT_TOLERANCE`` realigns every rank on rank 0's
    weights (the checkpoint's), and only a larger gap (a fault) stops the run, saying by how much."""
    from stairenv.training import distributed

    same = [torch.tensor([[3.0, 5.0], [-1.0, 2.0]], dtype=torch.float64)] * 3
    assert distributed.relative_gap(same) == 0.0
    drifted = [same[0], same[0] + torch.tensor([[5e-7, 5e-7], [0.0, 0.0]], dtype=torch.float64)]
    assert distributed.relative_gap(drifted) == pytest.approx(1e-7)
    apart = [same[0], same[0] * 1.01]
    assert distributed.relative_gap(apart) > distributed.RANK_DRIFT_TOLERANCE

    trainer = small_trainer()
    broadcasts = []
    monkeypatch.setattr(trainer.parallel, "broadcast", lambda module: broadcasts.append(module), raising=False)
    monkeypatch.setattr(trainer.parallel, "weights_gap", lambda tensors: 1e-7, raising=False)
    assert trainer.checkpoint(tmp_path / "drift.pt").is_file() and broadcasts == [trainer.model]
    monkeypatch.setattr(trainer.parallel, "weights_gap", lambda tensors: 1e-3, raising=False)
    with pytest.raises(RuntimeError, match="differ by 0.001"):
        trainer.checkpoint(tmp_path / "apart.pt")
    trainer.close()


def test_a_recipes_true_switch_is_turned_off_by_its_no_flag(tmp_path):
    """A boolean run setting a recipe turns on (``amp_text_condition = true``) is turned off on the command line by
    its ``--no-`` flag (flags win over ``--config`` keys), and the recipe's value holds without it."""
    toml = tmp_path / "run.toml"
    toml.write_text('style = "amp"\namp_text_condition = true\nupdate_bf16 = true\n')
    args = cli.parse_args(["--config", str(toml)])
    assert args.amp_text_condition is True and args.update_bf16 is True
    args = cli.parse_args(["--config", str(toml), "--no-amp-text-condition", "--no-update-bf16", "--style", "none"])
    assert args.amp_text_condition is False and args.update_bf16 is False and args.style == "none"
    assert {"amp_text_condition", "update_bf16"} <= args.given
