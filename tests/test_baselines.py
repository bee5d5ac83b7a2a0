"""The SB3 training script (``train_sb3.py``) runs end to end, checkpoints, resumes and evaluates (in the test's
process, ``conftest.InProcessScript``; ``test_bad_flags_are_rejected`` runs both scripts as scripts); the flags
both scripts read (``stairenv.training.cli``)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from stairenv.training import cli

SCRIPT = Path(__file__).resolve().parents[1] / "baselines" / "train_ppo.py"
SB3_SCRIPT = SCRIPT.with_name("train_sb3.py")
# the SB3 trainer's runs; the lean trainer's are in test_training.py
TINY = ["--n-envs", "2", "--vec-env", "dummy", "--n-steps", "256", "--batch-size", "128",
        "--no-progress-bar", "--checkpoint-every", "512"]


@pytest.mark.slow
def test_train_checkpoint_resume_evaluate(tmp_path, train_sb3):
    out = train_sb3.run(["--timesteps", "1024", "--logdir", str(tmp_path), "--eval-episodes", "2",
                         "--eval-max-episode-steps", "20", *TINY], tmp_path)
    run_dir = tmp_path / "InterLevel-v0" / "seed0"
    for name in ("final_model.zip", "vecnormalize.pkl", "amp.pt", "evaluation.csv", "evaluation.json",
                 "checkpoints/ppo_512_steps.zip", "checkpoints/ppo_vecnormalize_512_steps.pkl",
                 "checkpoints/amp_512_steps.pt"):
        assert (run_dir / name).exists(), name
    assert "Progress (%)" in out
    assert any((run_dir / "tb").rglob("events.out.tfevents*"))

    out = train_sb3.run(["--timesteps", "512", "--logdir", str(tmp_path), "--eval-episodes", "0",
                         "--resume", str(run_dir / "checkpoints" / "ppo_512_steps.zip"), *TINY], tmp_path)
    assert "resumed from" in out and "(512 steps)" in out

    # Without its AMP state a checkpoint resumes only with an explicit fresh discriminator.
    checkpoint = run_dir / "checkpoints" / "ppo_512_steps.zip"
    (run_dir / "checkpoints" / "amp_512_steps.pt").unlink()
    resume = ["--timesteps", "256", "--logdir", str(tmp_path), "--eval-episodes", "0", "--resume", str(checkpoint),
              *TINY]
    said = train_sb3.fails(resume, tmp_path)
    assert "amp_512_steps.pt" in said and "--fresh-discriminator" in said
    assert "a fresh discriminator" in train_sb3.run([*resume, "--fresh-discriminator"], tmp_path)


def test_train_sims_with_a_text_conditioned_discriminator(tmp_path, train_sb3):
    """SIMS: the discriminator judges [window, caption embedding]; the final evaluation is Table 1's."""
    import json

    import torch

    train_sb3.run(["--env", "SIMS-Sit-v0", "--amp-text-condition", "--env-kwarg", "text_encoder=hashing",
                   "--env-kwarg", "text_dim=8", "--timesteps", "512", "--logdir", str(tmp_path), "--eval-episodes",
                   "2", "--eval-max-episode-steps", "20", *TINY], tmp_path)
    run_dir = tmp_path / "SIMS-Sit-v0" / "seed0"
    amp = torch.load(run_dir / "amp.pt", weights_only=True)
    assert amp["reference_condition_dim"] == 8
    report = json.loads((run_dir / "evaluation.json").read_text())[0]
    assert report["table"] == "skills" and report["rows"][0]["group"] == "sit" and report["rows"][0]["n"] == 2
    assert report["settings"]["env_kwargs"]["captions"] == [["neutral", "sit down"]]
    assert "needs a SIMS env" in train_sb3.fails(["--amp-text-condition", "--timesteps", "10"], tmp_path)


def test_defaults_are_the_cpu_settings_and_the_paper_preset_restores_the_paper():
    cpu = cli.parse_args([])
    assert (cpu.vec_env, cpu.n_envs, cpu.policy_hidden, cpu.minibatch_size, cpu.n_steps) == ("batched", 128, (256, 256),
                                                                                         1024, 16)
    assert cpu.learning_rate == 1e-4 and cpu.log_std_init == -2.0 and cpu.torch_threads == 1
    paper = cli.parse_args(["--preset", "paper"])
    assert (paper.vec_env, paper.n_envs, paper.policy_hidden, paper.minibatch_size, paper.n_steps) == (
        "dummy", 4, (1024, 512), 64, 256)
    assert paper.learning_rate == 2e-5 and paper.log_std_init == 0.0 and paper.torch_threads is None
    assert paper.w_task == paper.w_style == 0.5 and paper.disc_grad_penalty == 5.0
    mixed = cli.parse_args(["--preset", "paper", "--n-envs", "8", "--timesteps", "1e5"])
    assert mixed.n_envs == 8 and mixed.timesteps == 1e5 and mixed.minibatch_size == 64  # flags win
    with pytest.raises(SystemExit):
        cli.parse_args(["--resume", "a.zip", "--init-from", "b.zip"])


def test_every_default_is_the_train_configs_and_its_doc_says_it():
    """One source of defaults: each flag that sets a ``TrainConfig`` field defaults to the field's default, the
    run the defaults build is ``TrainConfig()`` but for its keywords, and the docstring table (the flags' help)
    names each field with its true default."""
    import ast
    import re

    from stairenv.training.config import TrainConfig, field_default, field_docs

    parser = cli.build_parser()
    defaults = {action.dest: action.default for action in parser._actions}
    for flag, field in cli.RUN_FLAGS.items():
        if flag != "checkpoint_every":    # None: each trainer's own interval
            value = defaults[flag]
            assert (tuple(value) if isinstance(value, list) else value) == field_default(field), flag
    args = cli.parse_args([])
    built = cli.lean_config(args, {})
    assert built == TrainConfig(), {name: (getattr(built, name), getattr(TrainConfig(), name))
                                    for name in TrainConfig.__dataclass_fields__
                                    if getattr(built, name) != getattr(TrainConfig(), name)}
    docs = field_docs()
    assert set(docs) == set(TrainConfig.__dataclass_fields__)
    for line in TrainConfig.__doc__.splitlines():
        cells = [cell.strip() for cell in line.strip().strip("|").split("|")]
        if line.strip().startswith("|") and len(cells) == 3 and cells[0] in docs:
            written = re.sub(r"(?<=\d),(?=\d{3})", "", cells[1])    # 2,000,000
            assert ast.literal_eval(written) == field_default(cells[0]), cells[0]
    help_text = parser.format_help()
    assert docs["minibatch_size"] in " ".join(help_text.split())


def test_earlier_recipe_keys_are_read_as_the_flags_they_became(tmp_path):
    recipe = tmp_path / "old.toml"
    recipe.write_text("batch_size = 64\n")
    args = cli.parse_args(["--config", str(recipe)])
    assert args.minibatch_size == 64 and "minibatch_size" in args.given
    assert cli.parse_args(["--batch-size", "32"]).minibatch_size == 32    # the flag's earlier name


def test_adaptive_learning_rate_follows_the_kl():
    from types import SimpleNamespace

    from stable_baselines3.common.utils import ConstantSchedule

    from stairenv.training.sb3 import AdaptiveLearningRate

    callback = AdaptiveLearningRate(target=0.01)
    logged = {}
    model = SimpleNamespace(lr_schedule=ConstantSchedule(1e-4), learning_rate=1e-4,
                            logger=SimpleNamespace(name_to_value=logged, record=lambda *a: None))
    callback.model = model
    rates = []
    for kl in (None, 0.001, 0.01, 0.05, 0.05, 0.019):
        logged.clear()
        if kl is not None:
            logged["train/approx_kl"] = kl
        callback.on_rollout_end()
        rates.append(model.lr_schedule(1.0))
    np.testing.assert_allclose(rates, [1e-4, 1.5e-4, 1.5e-4, 1e-4, 1e-4 / 1.5, 1e-4 / 1.5])
    for _ in range(40):
        logged["train/approx_kl"] = 1.0
        callback.on_rollout_end()
    assert model.lr_schedule(1.0) == 1e-6 and model.learning_rate == 1e-6  # bounded


def test_bad_flags_are_rejected(tmp_path):
    env = {**os.environ, "MUJOCO_GL": "egl"}
    done = subprocess.run([sys.executable, str(SCRIPT), "--env", "NoSuchEnv-v0", "--timesteps", "10"],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode != 0 and "not registered" in done.stderr
    config = tmp_path / "run.toml"
    config.write_text('timesteps = 10\nbogus_key = 1\n')
    done = subprocess.run([sys.executable, str(SCRIPT), "--config", str(config)],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode != 0 and "bogus_key" in done.stderr
    # the state on the device is Warp's: refused with the C physics, by both trainers
    for script in (SCRIPT, SB3_SCRIPT):
        done = subprocess.run([sys.executable, str(script), "--state-on-device", "--timesteps", "10"],
                              cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
        assert done.returncode != 0 and "warp" in done.stderr and "Traceback" not in done.stderr, done.stderr


@pytest.mark.slow
def test_train_with_the_batched_env_checkpoints_and_resumes(tmp_path, train_sb3):
    batched = [arg if arg != "dummy" else "batched" for arg in TINY]
    train_sb3.run(["--timesteps", "512", "--logdir", str(tmp_path), "--eval-episodes", "1", "--eval-max-episode-steps",
                   "10", *batched], tmp_path)
    checkpoint = tmp_path / "InterLevel-v0" / "seed0" / "checkpoints" / "ppo_512_steps.zip"
    assert checkpoint.exists() and checkpoint.with_name("amp_512_steps.pt").exists()
    out = train_sb3.run(["--timesteps", "256", "--logdir", str(tmp_path), "--eval-episodes", "0", "--resume",
                         str(checkpoint), *batched], tmp_path)
    assert "resumed from" in out and "(512 steps)" in out

    # A new run from the checkpoint: its weights, statistics and discriminator, this run's settings.
    out = train_sb3.run(["--timesteps", "512", "--logdir", str(tmp_path / "warm"), "--eval-episodes", "0",
                         "--init-from", str(checkpoint), "--learning-rate", "3e-4", "--target-kl", "0.01",
                         "--env-kwarg", "stairs_start_fraction=0.5", "--disc-input-noise", "0.3", *batched], tmp_path)
    assert "initialised from" in out and "discriminator" in out
    warm = tmp_path / "warm" / "InterLevel-v0" / "seed0"
    assert (warm / "checkpoints" / "ppo_512_steps.zip").exists()  # counted from 0
    from stairenv.style.wrappers import read_amp_state

    config = read_amp_state(warm / "checkpoints" / "amp_512_steps.pt")["config"]
    assert config["input_noise"] == 0.3  # this run's flag on the trained discriminator (the default is 1.0)


def test_plot_training_averages_step_windows(baseline_script, tmp_path):
    from torch.utils.tensorboard import SummaryWriter

    writer = SummaryWriter(str(tmp_path / "run" / "tb" / "ppo_1"))
    for step in range(0, 1000, 10):
        writer.add_scalar("rollout/ep_len_mean", step / 10.0, step)
        writer.add_scalar("episode/progress", 0.5, step)
    writer.close()
    plot = baseline_script("plot_training")
    out = plot.main([f"a={tmp_path / 'run'}", "--out", str(tmp_path / "curves.png"), "--bins", "4"])
    assert out.stat().st_size > 1000
    rows = plot.read_scalars(tmp_path / "run")["rollout/ep_len_mean"]
    curve = plot.binned(rows, 4)
    assert len(curve) == 4 and curve[0, 1] == pytest.approx(np.mean(np.arange(0, 25)))  # steps 0-240
    with pytest.raises(SystemExit, match="LABEL=FOLDER"):
        plot.main([str(tmp_path / "run")])


@pytest.mark.slow
def test_train_sb3_curriculum_levels_resume_and_stay_out_of_the_evaluation(tmp_path, train_sb3):
    """The curriculum's levels are saved beside each checkpoint and given back world by world on
    --resume; a file that does not fit the run stops it, naming the file; the final evaluation draws
    the env's own step heights, without the curriculum."""
    train_sb3.run(["--timesteps", "512", "--logdir", str(tmp_path), "--eval-episodes", "0", "--env-kwarg",
                   "step_height_levels=9", "--env-kwarg", "step_height=(0.02, 0.2)", *TINY], tmp_path)
    folder = tmp_path / "InterLevel-v0" / "seed0" / "checkpoints"
    saved = folder / "curriculum_512_steps.json"
    import json

    levels = json.loads(saved.read_text())["curriculum_level"]
    assert len(levels) == 2 and all(0 <= level < 9 for level in levels)
    saved.write_text(json.dumps({"curriculum_level": [7, 1]}))
    out = train_sb3.run(["--timesteps", "256", "--logdir", str(tmp_path), "--eval-episodes", "0", "--resume",
                         str(folder / "ppo_512_steps.zip"), "--env-kwarg", "step_height_levels=9", "--env-kwarg",
                         "step_height=(0.02, 0.2)", *TINY], tmp_path)
    assert f"curriculum levels from {saved} (mean 4.00)" in out


def test_train_sb3_restores_levels_and_refuses_bad_files(tmp_path):
    import json

    from stairenv.training import sb3 as train

    class Worlds:
        num_envs = 2

        def __init__(self):
            self.levels = {}

        def set_attr(self, name, value, indices):
            self.levels[(name, indices[0])] = value

    worlds, path = Worlds(), tmp_path / "curriculum_512_steps.json"
    path.write_text(json.dumps({"curriculum_level": [3, None]}))
    assert train.restore_curriculum(worlds, path) == [3, None]
    assert worlds.levels == {("curriculum_level", 0): 3, ("curriculum_level", 1): None}
    for text, message in (('{"curriculum_level": [1, 2, 3]}', "3 worlds"), ("{", "cannot read"),
                          ('{"curriculum_level": ["1", 2]}', "cannot read"), ("{}", "cannot read")):
        path.write_text(text)
        with pytest.raises(SystemExit, match=message):
            train.restore_curriculum(worlds, path)
    assert train.curriculum_state_beside(tmp_path / "ppo_512_steps.zip") == path
    assert train.curriculum_state_beside(tmp_path / "final_model.zip") is None
    kwargs = {"init": "hybrid", "stairs_start_fraction": 0.5, "stall_seconds": 4.0, "step_height_levels": 9,
              "step_height": (0.02, 0.2), "target_speed": 0.8}
    assert cli.evaluation_kwargs(kwargs) == {"target_speed": 0.8}
    assert cli.evaluation_kwargs({"step_height": (0.1, 0.2)}) == {"step_height": (0.1, 0.2)}


@pytest.mark.parametrize("recipe", sorted((SCRIPT.parent / "recipes").glob("*.toml")), ids=lambda p: p.stem)
def test_recipes_parse_and_build_their_env(recipe):
    """Every shipped recipe is a valid --config: known keys, and env keywords the env accepts."""
    import gymnasium as gym

    args = cli.parse_args(["--config", str(recipe)])
    env_kwargs = dict(args.env_kwarg)
    assert args.env in gym.registry and env_kwargs
    env = gym.make(args.env, **env_kwargs)
    env.reset(seed=0)
    env.close()
    # what the final evaluation keeps: no training aid
    assert not set(cli.evaluation_kwargs(env_kwargs)) & set(cli.TRAINING_AIDS)
