"""Bad lean-trainer checkpoints, replay buffers and ``--resume`` flags (``docs/bad-input.md``): every value of a
checkpoint is checked when it is read (``check_checkpoint``, one check for ``train_ppo.py --resume``,
``--init-from`` and ``export_policy.py``), each fault named with the file and the entry; a resume refuses a
flag that would change its run, naming it; a valid checkpoint reads and resumes as before."""

from __future__ import annotations

import math
import re
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch

import stairenv  # noqa: F401
from stairenv.training import CheckpointError, TrainConfig, Trainer, build_style, cli, make_env, read_checkpoint

#: PPO + AMP on serial physics, a checkpoint at 16 steps with its replay buffer; the env keywords train_ppo.py adds
SMALL = TrainConfig(num_envs=2, physics="serial", rollout_steps=8, minibatch_size=8, epochs=1, total_steps=16,
                    checkpoint_every=16, hidden=(16, 16), disc_hidden=(16,), disc_replay_size=40,
                    disc_update_interval=16, disc_updates=1, disc_batch_size=8,
                    env_kwargs={"init": "hybrid", "amp_history": 2})


def amp_trainer(config: TrainConfig = SMALL) -> Trainer:
    from stairenv.style.wrappers import default_reference

    venv = make_env(config)
    return Trainer(config, build_style(config, default_reference(venv)), venv)


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    """A PPO + AMP run's checkpoint after 16 steps (an update, a discriminator round), replay buffer beside it."""
    folder = tmp_path_factory.mktemp("run")
    trainer = amp_trainer()
    trainer.learn(checkpoint_dir=folder)
    trainer.close()
    return folder / "checkpoint_16.pt"


def saved(state: dict, folder: Path, name: str = "checkpoint_16.pt") -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    torch.save(state, folder / name)
    return folder / name


def set_item(*keys, value):
    """A fault: ``state[k0][k1]... = value`` (a tensor's item where the last key is an index)."""
    def fault(state):
        for key in keys[:-1]:
            state = state[key]
        state[keys[-1]] = value
    return fault


def remove(*keys):
    def fault(state):
        for key in keys[:-1]:
            state = state[key]
        del state[keys[-1]]
    return fault


def fill(*keys, value):
    def fault(state):
        for key in keys:
            state = state[key]
        state.fill_(value)
    return fault


NAN = math.nan
#: (fault, the entry the error names); the probe's findings first
FAULTS = {
    "nan_weight": (set_item("model", "policy_net.0.weight", (0, 3), value=NAN), "model['policy_net.0.weight']"),
    "nan_obs_var": (set_item("obs_rms", "var", 2, value=NAN), "obs_rms['var']"),
    "negative_obs_var": (set_item("obs_rms", "var", 2, value=-1.0), "obs_rms['var']"),
    "nan_obs_mean": (set_item("obs_rms", "mean", 0, value=NAN), "obs_rms['mean']"),
    "negative_obs_count": (set_item("obs_rms", "count", value=-3.0), "obs_rms['count']"),
    "nan_ret_var": (set_item("ret_rms", "var", value=torch.tensor(NAN, dtype=torch.float64)), "ret_rms['var']"),
    "negative_ret_count": (set_item("ret_rms", "count", value=-1.0), "ret_rms['count']"),
    "zero_obs_var": (fill("obs_rms", "var", value=0.0), "obs_rms['var']"),
    "log_std_50": (fill("model", "log_std", value=50.0), "model['log_std']"),
    "nan_learning_rate": (set_item("learning_rate", value=NAN), "learning_rate"),
    "negative_learning_rate": (set_item("learning_rate", value=-1e-4), "learning_rate"),
    "world_size_0": (set_item("world_size", value=0), "world_size"),
    "no_config": (remove("config"), "config"),
    "config_not_a_dict": (set_item("config", value=[1, 2]), "config"),
    "nan_config_learning_rate": (set_item("config", "learning_rate", value=NAN), "config"),
    "unknown_env": (set_item("config", "env_id", value="NoSuchEnv-v0"), "config['env_id']"),
    "no_env_id": (remove("config", "env_id"), "config['env_id']"),
    "no_num_envs": (remove("config", "num_envs"), "config['num_envs']"),
    "junk_discriminator_setting": (set_item("config", "disc_lr", value="fast"), "config"),
    "env_kwargs_not_a_dict": (set_item("config", "env_kwargs", value=[["init", "hybrid"]]), "config"),
    "no_model": (remove("model"), "model"),
    "missing_layer": (remove("model", "value.bias"), "model"),
    "other_hidden_layers": (set_item("config", "hidden", value=[8, 8]), "model['policy_net.0.weight']"),
    "short_bias": (set_item("model", "action_mean.bias", value=torch.zeros(3)), "model['action_mean.bias']"),
    "integer_weights": (set_item("model", "value.weight", value=torch.zeros(1, 16, dtype=torch.int64)),
                        "model['value.weight']"),
    "statistics_of_another_size": (set_item("obs_rms", "mean", value=torch.zeros(5, dtype=torch.float64)),
                                   "obs_rms['mean']"),
    "statistics_not_tensors": (set_item("obs_rms", "var", value=[1.0, 2.0]), "obs_rms['var']"),
    "no_ret_rms": (remove("ret_rms"), "ret_rms"),
    "steps_as_text": (set_item("steps", value="16"), "steps"),
    "negative_steps": (set_item("steps", value=-16), "steps"),
    "no_iterations": (remove("iterations"), "iterations"),
    "inf_adam_moment": (fill("optimizer", "state", 1, "exp_avg", value=math.inf), "optimizer['state'][1]['exp_avg']"),
    "negative_adam_moment": (fill("optimizer", "state", 1, "exp_avg_sq", value=-1.0),
                             "optimizer['state'][1]['exp_avg_sq']"),
    "adam_of_fewer_parameters": (remove("optimizer", "state", 3), "optimizer['state']"),
    "nan_adam_rate": (set_item("optimizer", "param_groups", 0, "lr", value=NAN), "optimizer['param_groups'][0]['lr']"),
    "adam_state_not_adam": (set_item("optimizer", value={"x": 1}), "optimizer"),
    "junk_torch_rng": (set_item("torch_rng", value=torch.zeros(3, dtype=torch.uint8)), "torch_rng"),
    "junk_curriculum": (set_item("curriculum_level", value=["high"]), "curriculum_level"),
    "nan_discriminator_weight": (fill("style", "discriminator", "model", "trunk.0.weight", value=NAN),
                                 "style['discriminator']['model']['trunk.0.weight']"),
    "zero_discriminator_variance": (fill("style", "discriminator", "model", "norm.var", value=0.0),
                                    "style['discriminator']['model']['norm.var']"),
    "nan_discriminator_count": (fill("style", "discriminator", "model", "norm.count", value=NAN),
                                "style['discriminator']['model']['norm.count']"),
    "discriminator_of_another_input": (set_item("style", "discriminator", "input_dim", value=3),
                                       "style['discriminator']['model']['norm.mean']"),
    "bad_discriminator_settings": (set_item("style", "discriminator", "config", "hidden", value=[0]),
                                   "style['discriminator']['config']"),
    "nan_discriminator_adam": (fill("style", "discriminator", "optimizer", "state", 0, "exp_avg", value=NAN),
                               "style['discriminator']['optimizer']['state'][0]['exp_avg']"),
    "negative_rounds": (set_item("style", "rounds", value=-1), "style['rounds']"),
    "replay_past_its_end": (set_item("style", "replay_next", value=99), "style['replay_next']"),
    "junk_style_rng": (set_item("style", "rng", value={"bit_generator": "MT19937"}), "style['rng']"),
    "junk_noise_rng": (set_item("style", "noise_rng", value=torch.zeros(3)), "style['noise_rng']"),
}


@pytest.mark.parametrize("fault", sorted(FAULTS))
def test_a_bad_checkpoint_is_refused_naming_the_file_and_the_entry(run, tmp_path, fault):
    change, entry = FAULTS[fault]
    state = torch.load(run, weights_only=True)
    change(state)
    path = saved(state, tmp_path)
    with pytest.raises(CheckpointError) as caught:
        read_checkpoint(path)
    assert str(caught.value).startswith(f"{path}: entry {entry} "), str(caught.value)


def test_a_valid_checkpoint_reads_and_leaves_torchs_generator_where_it_was(run):
    """Reading builds networks to compare with, under a forked generator: a resume or a new run seeded
    before it draws what it drew before."""
    torch.manual_seed(3)
    before = torch.get_rng_state()
    state = read_checkpoint(run)
    assert torch.equal(torch.get_rng_state(), before)
    assert state["steps"] == 16 and state["style"] is not None


@pytest.mark.parametrize("fault", ["nan_weight", "no_config", "world_size_0", "nan_obs_var", "log_std_50",
                                   "missing_layer", "unknown_env", "nan_discriminator_weight"])
def test_export_policy_refuses_a_bad_checkpoint_and_writes_nothing(run, tmp_path, fault, baseline_script, capsys):
    """``export_policy.py`` used to write a NaN policy (then fail reading it back, leaving it on disk) and to
    stop with tracebacks (``KeyError: 'config'``, ``ZeroDivisionError``) on malformed files."""
    change, entry = FAULTS[fault]
    state = torch.load(run, weights_only=True)
    change(state)
    path = saved(state, tmp_path)
    out = tmp_path / "policy.npz"
    with pytest.raises(SystemExit) as stopped:
        baseline_script("export_policy").main([str(path), "--out", str(out)])
    assert stopped.value.code == 2
    assert f"{path}: entry {entry} " in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["checkpoint_16.pt"]    # no policy, no temporary file


def test_export_policy_writes_a_policy_only_once_it_reads_back(tmp_path, baseline_script):
    """A policy that does not read back (NaN weights of an SB3 model, say) leaves no file, and an older file
    of that name as it was; the error names the file it was to write."""
    from stairenv.pretrained import NumpyPolicy, PolicyFileError

    export = baseline_script("export_policy")
    policy = NumpyPolicy([np.ones((2, 3))], [np.zeros(2)], np.zeros(3), np.ones(3), config={"env_id": "x"})
    out = tmp_path / "policy.npz"
    export.save_checked(policy, out)
    first = out.read_bytes()
    policy.weights[0][0, 0] = np.nan
    with pytest.raises(PolicyFileError, match="^" + re.escape(f"{out}: ") + ".*weight_0"):
        export.save_checked(policy, out)
    assert out.read_bytes() == first and sorted(p.name for p in tmp_path.iterdir()) == ["policy.npz"]


@pytest.mark.parametrize("flag", ["--resume", "--init-from"])
@pytest.mark.parametrize("fault", ["nan_weight", "negative_obs_var", "log_std_50", "nan_learning_rate",
                                   "no_config"])
def test_resume_and_init_from_refuse_a_bad_checkpoint_naming_it(run, tmp_path, flag, fault, baseline_script):
    """The values the probe found starting a run that died in torch's distribution check with a tensor dump."""
    change, entry = FAULTS[fault]
    state = torch.load(run, weights_only=True)
    change(state)
    path = saved(state, tmp_path)
    args = cli.parse_args([flag, str(path), "--logdir", str(tmp_path)])
    with pytest.raises(SystemExit, match="^" + re.escape(f"{flag}: {path}: entry {entry} ")):
        cli.lean_start(args)


@pytest.mark.parametrize("flag", ["--resume", "--init-from"])
@pytest.mark.parametrize("how", ["missing", "None"])
def test_a_checkpoint_without_its_discriminator_needs_fresh_discriminator(run, tmp_path, flag, how,
                                                                          baseline_script):
    """A run with AMP used to go on from a checkpoint without its ``style`` entry with a new discriminator, without
    a word (SB3's resume refuses that without ``--fresh-discriminator``)."""
    state = torch.load(run, weights_only=True)
    if how == "missing":
        del state["style"]
    else:
        state["style"] = None
    path = saved(state, tmp_path)
    args = cli.parse_args([flag, str(path), "--logdir", str(tmp_path)])
    with pytest.raises(SystemExit) as stopped:
        cli.lean_start(args)
    message = str(stopped.value)
    assert message.startswith(f"{flag} {path}: entry 'style' (the discriminator's state) is {how}: its run trained "
                              "with AMP") and "--fresh-discriminator" in message
    args = cli.parse_args([flag, str(path), "--logdir", str(tmp_path), "--fresh-discriminator"])
    resume, init = cli.lean_start(args)
    assert (resume or init)["style"] is None


def test_a_resume_whose_env_keywords_no_longer_build_its_env_names_them(run, tmp_path, baseline_script):
    state = torch.load(run, weights_only=True)
    state["config"]["env_kwargs"]["no_such_keyword"] = 1
    path = saved(state, tmp_path)
    args = cli.parse_args(["--resume", str(path), "--logdir", str(tmp_path)])
    with pytest.raises(SystemExit, match="^" + re.escape(f"--resume {path}: its run's env cannot be built here from "
                                                         "entries config['env_id'], config['env_kwargs']")):
        cli.lean_setup(args, print)


# --- replay buffers --------------------------------------------------------------------------------------
@pytest.mark.parametrize("value", [math.nan, math.inf, 1e30])
def test_a_replay_buffer_of_non_finite_or_absurd_windows_is_refused(run, tmp_path, value, baseline_script):
    """A replay buffer with a NaN, inf or 1e30 feature used to be taken into the discriminator's training."""
    state = read_checkpoint(run)
    path = saved(state, tmp_path)
    windows = np.load(run.with_name("replay_16.npy"))
    windows[5, 7] = value
    np.save(tmp_path / "replay_16.npy", windows)
    trainer = amp_trainer()
    try:
        with pytest.raises(CheckpointError, match="^" + re.escape(f"{tmp_path / 'replay_16.npy'}: replay window 5 ")):
            trainer.load_replay(path, state)
        args = cli.parse_args(["--resume", str(path), "--logdir", str(tmp_path)])
        with pytest.raises(SystemExit) as stopped:
            cli.take_resume(trainer, args, state)
        message = str(stopped.value)
        assert message.startswith(f"--resume: {tmp_path / 'replay_16.npy'}: replay window 5 holds ")
        assert "amp-text-condition" not in message
        np.save(tmp_path / "replay_16.npy", np.load(run.with_name("replay_16.npy")))    # a sound one is taken
        assert trainer.load_replay(path, state)
    finally:
        trainer.close()


def test_a_resume_into_other_networks_names_both_without_unrelated_advice(run, tmp_path, baseline_script):
    """Every resume failure used to end with advice about --amp-text-condition; now each says what fits it."""
    state = read_checkpoint(run)
    other = Trainer(TrainConfig(num_envs=2, physics="serial", rollout_steps=8, minibatch_size=8, epochs=1,
                                style="none", total_steps=16, hidden=(8, 8)))
    try:
        args = cli.parse_args(["--resume", str(run), "--logdir", str(tmp_path)])
        with pytest.raises(SystemExit) as stopped:
            cli.take_resume(other, args, state)
        message = str(stopped.value)
        assert "the checkpoint's policy maps 118 observations through hidden layers [16, 16] to 28 actions" in message
        assert "amp-text-condition" not in message
        args = cli.parse_args(["--init-from", str(run), "--logdir", str(tmp_path)])
        with pytest.raises(SystemExit, match=r"pass --policy-hidden 16,16, the layers it was trained with"):
            cli.take_init(other, args, {**state, "style": None})
    finally:
        other.close()


# --- resume flags ---------------------------------------------------------------------------------------
CHANGES = {    # flags given with a resume -> what the refusal says
    "--n-envs 8": "--n-envs 8 (the run's: 2)",
    "--learning-rate 1e-3": "--learning-rate 0.001 (the run's: 0.0001)",
    "--env InterLevel2D-v0": "--env InterLevel2D-v0 (the run's: InterLevel-v0)",
    "--seed 3": "--seed 3 (the run's: 0)",
    "--policy-hidden 64,64": "--policy-hidden 64,64 (the run's: 16,16)",
    "--env-kwarg target_speed=0.8": "--env-kwarg target_speed=0.8 (the run's: not set)",
    "--env-kwarg init=default": "--env-kwarg init='default' (the run's: 'hybrid')",
    "--init reference": "--init reference (the run's: hybrid)",
    "--n-steps 4": "--n-steps 4 (the run's: 8)",
    "--batch-size 16": "--minibatch-size 16 (the run's: 8)",    # the flag's earlier name: its name now
    "--n-epochs 3": "--n-epochs 3 (the run's: 1)",
    "--gamma 0.9": "--gamma 0.9 (the run's: 0.99)",
    "--target-kl 0.01": "--target-kl 0.01 (the run's: not set)",
    "--log-std-init -1": "--log-std-init -1 (the run's: -2)",
    "--style none": "--style none (the run's: amp)",
    "--w-style 0.8": "--w-style 0.8 (the run's: 0.5)",
    "--amp-history 3": "--amp-history 3 (the run's: 2)",
    "--disc-hidden 8": "--disc-hidden 8 (the run's: 16)",
    "--no-disc-background": "--no-disc-background (the run's: True)",
    "--update-bf16": "--update-bf16 (the run's: False)",
    "--checkpoint-every 64": "--checkpoint-every 64 (the run's: 16)",
    "--amp-text-condition": "--amp-text-condition (the run's discriminator was not conditioned on text)",
    "--preset paper": "--n-envs 4 (from --preset paper; the run's: 2)",
}


@pytest.mark.parametrize("given", sorted(CHANGES))
def test_resume_refuses_a_flag_that_would_change_the_run_naming_it(run, tmp_path, given, baseline_script):
    """``--resume`` used to drop these silently (the checkpoint's settings went on)."""
    args = cli.parse_args(["--resume", str(run), "--logdir", str(tmp_path), *given.split()])
    with pytest.raises(SystemExit) as stopped:
        cli.lean_setup(args, print)
    message = str(stopped.value)
    assert message.startswith(f"--resume {run}: a resume goes on with its run's own settings, and these given would "
                              "change the run: ")
    assert CHANGES[given] in message and "--init-from" in message


def test_resume_names_a_config_key_that_would_change_the_run(run, tmp_path, baseline_script):
    toml = tmp_path / "recipe.toml"
    toml.write_text('n_envs = 8\n[env_kwargs]\ntarget_speed = 0.8\n')
    args = cli.parse_args(["--resume", str(run), "--config", str(toml), "--logdir", str(tmp_path)])
    with pytest.raises(SystemExit) as stopped:
        cli.lean_setup(args, print)
    assert f"--n-envs 8 (from --config {toml}; the run's: 2); --env-kwarg target_speed=0.8 (the run's: not set)" \
        in str(stopped.value)


def test_resume_takes_the_runs_own_values_and_this_machines_settings_and_says_so(run, tmp_path, baseline_script,
                                                                                  capsys):
    """The run's own values given again go on (the same command restarting a run); this machine's settings
    are taken instead of the checkpoint's and said; with --fresh-discriminator the --disc-* flags are taken."""
    same = ["--n-envs", "2", "--seed", "0", "--learning-rate", "1e-4", "--policy-hidden", "16,16", "--init", "hybrid",
            "--n-steps", "8", "--checkpoint-every", "16", "--env", "InterLevel-v0", "--env-kwarg", "amp_history=2"]
    args = cli.parse_args(["--resume", str(run), "--logdir", str(tmp_path), "--timesteps", "32",
                                 "--torch-threads", "2", "--physics", "mujoco", "--fresh-discriminator",
                                 "--disc-hidden", "8", *same])
    resume, _, config, _, _ = cli.lean_setup(args, print)
    assert (config.torch_threads, config.physics, config.disc_hidden, config.total_steps) == (2, "mujoco", (8,), 48)
    assert config.replace(torch_threads=1, physics="serial", disc_hidden=(16,), total_steps=16) == \
        TrainConfig.from_dict(resume["config"])
    said = capsys.readouterr().out
    assert "--resume: this machine's settings, not the checkpoint's: --physics mujoco (the run's: serial), " \
           "--torch-threads 2 (the run's: 1)" in said


def test_every_flag_has_a_defined_outcome_with_resume(baseline_script):
    """A flag added later must be sorted: compared with the checkpoint's setting, taken as this machine's, or
    one that does not change how the run trains."""
    sorted_flags = (set(cli.RUN_FLAGS) | set(cli.MACHINE_FLAGS) | set(cli.KEYWORD_FLAGS)
                    | set(cli.OTHER_FLAGS))
    assert {action.dest for action in cli.build_parser()._actions} - sorted_flags == set()
    assert set(cli.RUN_FLAGS.values()) <= {f for f in TrainConfig.__dataclass_fields__}


def test_sb3_resume_refuses_a_flag_its_checkpoint_would_drop(tmp_path, baseline_script):
    """``train_sb3.py --resume``: SB3 keeps the checkpoint's PPO settings and networks; a flag given with another
    value is named (the env's flags build this run's envs, as before)."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    venv = VecNormalize(DummyVecEnv([lambda: gym.make("InterLevel-v0")]))
    PPO("MlpPolicy", venv, n_steps=64, batch_size=64, learning_rate=1e-4, device="cpu",
        policy_kwargs={"net_arch": {"pi": [16, 16], "vf": [16, 16]}, "activation_fn": torch.nn.ReLU}
        ).save(tmp_path / "final_model.zip")
    venv.save(tmp_path / "vecnormalize.pkl")
    venv.close()
    common = ["--resume", str(tmp_path / "final_model.zip"), "--style", "none", "--n-envs", "1",
              "--vec-env", "dummy", "--timesteps", "0", "--eval-episodes", "0", "--no-progress-bar",
              "--logdir", str(tmp_path / "out")]
    with pytest.raises(SystemExit) as stopped:
        baseline_script("train_sb3").main([*common, "--learning-rate", "1e-3", "--policy-hidden", "32,32",
                                           "--n-steps", "64"])
    message = str(stopped.value)
    assert message.startswith(f"--resume {tmp_path / 'final_model.zip'}: SB3 goes on with the checkpoint's own "
                              "settings")
    assert "--learning-rate 0.001 (the checkpoint's: 0.0001); --policy-hidden 32,32 (the checkpoint's: 16,16)" \
        in message and "--n-steps" not in message
