"""Train PPO + AMP on a stairenv env: CPU-tuned defaults, the InterLevel paper's settings as a preset.

    python baselines/train_ppo.py                         # InterLevel-v0, PPO + AMP, the CPU settings below
    python baselines/train_ppo.py --preset paper          # the paper's settings
    python baselines/train_ppo.py --env InterLevel2D-v0   # the 2-D ablation
    python baselines/train_ppo.py --env InterSceneStairs-v0 --style none   # task reward only
    python baselines/train_ppo.py --env-kwarg target_speed=0.8 --timesteps 5e6
    python baselines/train_ppo.py --config baselines/recipes/interlevel_climb.toml   # any flags below as keys
    python baselines/train_ppo.py --resume runs/InterLevel-v0/seed0/checkpoints/checkpoint_1000448.pt
    python baselines/train_ppo.py --init-from .../checkpoint_1000448.pt --learning-rate 3e-5  # new run, trained weights
    python baselines/train_ppo.py --init-from checkpoints/InterLevel-v0/ppo_3200000_steps.zip   # from an SB3 run
    python baselines/train_ppo.py --env SIMS-Sit-v0 --amp-text-condition   # SIMS: discriminator sees the caption
    python baselines/train_ppo.py --trainer sb3 ...       # Stable-Baselines3 PPO instead (ppo_<n>_steps.zip)
    torchrun --nproc-per-node 2 baselines/train_ppo.py --n-envs 64 ...   # data-parallel: 2 ranks x 64 worlds

Two trainers run the same algorithm with the same flags. ``--trainer lean`` (the default):
``stairenv.training``, PPO + AMP written for the batched env's arrays (the loop is
``stairenv.training.ppo.Trainer.learn``; the run's whole resolved ``TrainConfig`` is saved in every
checkpoint, one ``checkpoint_<n>.pt`` holding policy, optimiser, normalisers, discriminator, curriculum
levels, step counter and generators, read without running code, ``replay_<n>.npy`` beside the latest;
the last step is always a checkpoint; ``--resume`` continues exactly, from it or ``final_checkpoint.pt``;
``final_policy.npz`` is the numpy policy ``stairenv.pretrained`` loads).
``--trainer sb3``: Stable-Baselines3 PPO with VecNormalize and the AMP wrapper (the files below).
Under ``torchrun`` (``--nproc-per-node P``, ``--nnodes N --rdzv-backend c10d --rdzv-endpoint HOST:PORT``
across machines) the lean trainer runs data-parallel (``stairenv.training.distributed``): each rank its
own ``--n-envs`` worlds (world j of rank r seeded as world ``r x n_envs + j`` of the run), gradients
averaged, statistics merged, ``--timesteps`` counting every rank's steps, rank 0 printing, logging,
checkpointing and evaluating; ``--resume`` takes a checkpoint of any rank count (exact with the same);
``--device cuda``: the lean trainer's networks, rollout, PPO and AMP updates on the GPU, the envs on the host;
under torchrun local rank r takes the node's GPU ``r mod GPUs`` for its networks (``--device cuda``) and its
physics (``--physics warp``), so several ranks may share one GPU (nccl beside gloo where each has its own);
``--state-on-device`` (with ``--physics warp``): the worlds' state stays on the GPU between resets;
a rank that cannot start (its machine lacks the checkpoint, the motions, MuJoCo Warp or a GPU) stops every
rank with its reason. ``docs/training.md`` compares them.

Defaults (``--preset cpu``): the fastest settings measured to still learn on a 2-core CPU
(``docs/reproducing.md``): the natively batched env (``--vec-env batched``, 128 worlds, physics on
every core), MLP [256, 256] ReLU for policy and value, rollouts of 16 steps per world (2,048
samples), minibatch 1024, 5 epochs, learning rate 1e-4 (``--target-kl`` adapts it to a KL target
instead), initial action std 0.135 (``--log-std-init -2``), one torch thread, gradient-norm clip
1.0, entropy 0, gamma 0.99, observation and return normalisation (VecNormalize). Style: the AMP
discriminator wrapper (``stairenv.style.wrappers``; the paper's [1024, 512] discriminator with
instance noise 1.0 on its training inputs, gradient penalty 10 and a 200k-window replay buffer)
trained on reference clips (``--reference``; default: the env's built-in synthesised set, walks
and stair ascents, or for SIMS envs walks plus sit / lie / reach / get-up clips), reward
0.5 task + 0.5 style, episodes started half from reference states (``--init hybrid``).

``--preset paper``: the InterLevel paper's settings: learning rate 2e-5 constant, MLP [1024, 512],
minibatch 64, rollouts of 256 steps, 4 envs stepping in this process (``--vec-env dummy``), action
std 1, the discriminator without instance noise (gradient penalty 5, 100k replay).
``--preset style-short``: the settings of the earlier short CPU runs (policy learning rate 1e-5,
style weighted 0.8), on the paper's sizes. ``PRESETS`` holds them; flags and ``--config`` keys win
over a preset. The runs behind each setting are in ``docs/reproducing.md``.

``--init-from CHECKPOINT`` starts a new run (steps counted from 0, this run's flags) from a
checkpoint's (lean ``.pt`` or SB3 ``.zip``) policy and value weights, optimiser state, statistics and discriminator
(task and style weights, the discriminator's instance noise and gradient penalty from this run's
flags; a step-height curriculum's levels when both runs have one): a recipe change on a trained
policy. ``--reset-std`` (lean trainer) also starts the policy's action noise at ``--log-std-init`` again:
a trained policy's noise has shrunk, which on a new task explores little and, under ``--target-kl``, holds
the rate down. ``--resume`` continues a run exactly (the checkpoint's own settings and step count): a flag,
``--config`` key or ``--preset`` value given that would change them stops it, naming each (the same values
again go on; other settings on trained weights are ``--init-from``'s); this machine's ``--physics``,
``--physics-threads``, ``--device``, ``--state-on-device``, ``--torch-threads`` and ``--update-threads`` are
taken, and said. Every checkpoint is checked as it is read (``stairenv.training.check_checkpoint``: finite
weights and statistics, positive variances, a sane log std and learning rate, each fault naming the file
and the entry), and one of a run with AMP without its discriminator needs ``--fresh-discriminator``.

Logged beside SB3's: ``amp/*`` (style and task reward, discriminator statistics) and, for
InterLevel envs, ``episode/{progress,success,fell,stalled}`` at each episode's end, also for the episodes
that started on the floor alone (``episode_floor_start/*``, the ones comparable with the evaluation
when ``stairs_start_fraction`` starts others on the staircase; the lean trainer also leaves SIMS' episodes
started at the furniture by ``interaction_start_fraction`` out of them). With a step-height curriculum
(``--env-kwarg step_height_levels=N``) or SIMS' start-distance curriculum (``start_distance_levels=N``)
the worlds' mean level as ``curriculum/level``, the levels
saved beside each checkpoint (``curriculum_<n>_steps.json``) and restored by ``--resume`` and
``--init-from``. The final evaluation leaves the training aids (``TRAINING_AIDS``) out.

``--amp-text-condition`` (SIMS envs with ``text_conditioned``): the discriminator
judges [motion window, text embedding]; each reference clip is embedded from its
``meta["text"]`` with the env's encoder, and the env's captions become the
reference texts of its skill, so agent and reference conditions come from one set. With
``--amp-text-captions all`` the env keeps its own captions (the evaluation's: many per style) for the
policy's observation, and the discriminator is conditioned on the reference text of the caption's
style (env keyword ``condition_captions``).

Writes to ``--logdir/<env>/seed<k>/``: TensorBoard logs (PPO and ``amp/*``; the lean trainer also
``log.jsonl``, one line of scalars per iteration, with the wall and CPU time of each phase per env step),
checkpoints; with ``--trainer sb3`` (model, VecNormalize statistics, AMP state) ``final_model.zip`` +
``vecnormalize.pkl`` + ``amp.pt`` and the evaluation table
(``evaluation.csv`` / ``.json``) of the trained policy, by the evaluator of the env's family
(``stairenv.evaluation.evaluator_for``: InterLevel Tables 1-3, PlaMo Table 2 or SIMS Table 1);
the JSON is a list of reports.

With ``--trainer sb3``, ``--resume`` needs the checkpoint's VecNormalize statistics and, with AMP, its
AMP state (``amp_<n>_steps.pt``, or ``amp.pt`` beside ``final_model.zip``); without
the AMP state it stops unless ``--fresh-discriminator`` asks for a new one. The
model .zip and statistics .pkl are pickles (SB3's formats): resume only from files
you trust. The AMP state is read without running code from it.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import json
import os
import sys
import time
import tomllib
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback, CallbackList, CheckpointCallback
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecMonitor, VecNormalize

import stairenv  # noqa: F401  (registers the envs)
from stairenv.environments.config import InterLevelConfig, PlaMoConfig, group_keywords
from stairenv.environments.sims import SIMSEnv, reference_captions
from stairenv.environments.sims_config import SIMSConfig
from stairenv.evaluation import evaluator_for
from stairenv.evaluation.cli import env_kwarg_argument
from stairenv.evaluation.policies import load_policy, read_normalizer
from stairenv.evaluation.report import write_reports
from stairenv.motion import stair_starts
from stairenv.motion.rsi import load_reference_library
from stairenv.style.discriminator import LOSSES, SCORERS, DiscriminatorConfig
from stairenv.style.reference import ReferenceWindows, text_conditions
from stairenv.style.wrappers import AMPStyleReward, AMPVecEnvWrapper
from stairenv.tasks import curriculum
from stairenv.training import (CheckpointError, RunLog, Trainer, TrainConfig, build_style, check_checkpoint,
                               checkpoints_in, read_checkpoint)
from stairenv.training.ppo import RunMismatch
from stairenv.training.distributed import LOCAL, DataParallel
from stairenv.training.from_sb3 import state_from_sb3
from stairenv.training.sb3 import (  # noqa: F401  (AdaptiveLearningRate, restore_curriculum: tested here)
    AdaptiveLearningRate,
    AMPCallback,
    CurriculumCallback,
    EpisodeStatsCallback,
    check_same_spaces,
    checkpoint_file,
    curriculum_state_beside,
    load_checkpoint,
    required_amp_state,
    restore_curriculum,
    resumed_style,
    run_env,
    statistics_beside,
)
from stairenv.vec_sb3 import make_sb3_vec_env

# The defaults: the fastest settings measured to learn on a 2-core CPU (docs/reproducing.md).
PPO_DEFAULTS = {
    "learning_rate": 1e-4,
    "n_steps": 16,
    "batch_size": 1024,
    "n_epochs": 5,
    "gamma": 0.99,
    "gae_lambda": 0.95,
    "clip_range": 0.2,
    "ent_coef": 0.0,
    "max_grad_norm": 1.0,
}

# The InterLevel paper's settings (learning rate 2e-5, minibatch 64, [1024, 512] networks, std 1 at the
# start, the paper's discriminator) on the sequential vec env.
PAPER = {
    "learning_rate": 2e-5, "n_steps": 256, "batch_size": 64, "n_epochs": 5,
    "policy_hidden": (1024, 512), "log_std_init": 0.0, "n_envs": 4, "vec_env": "dummy", "torch_threads": None,
    "disc_input_noise": 0.0, "disc_grad_penalty": 5.0, "disc_replay_size": 100_000,
}

# Named groups of flag values (see the module docstring); explicit flags and --config keys win.
PRESETS: dict[str, dict] = {
    "cpu": {},
    "paper": PAPER,
    "style-short": {
        "learning_rate": 1e-5,
        "log_std_init": -2.0,
        "w_task": 0.2,
        "w_style": 0.8,
        "disc_grad_penalty": 10.0,
        "disc_replay_size": 200_000,
        "disc_input_noise": 1.0,
        **{key: PAPER[key] for key in ("n_steps", "batch_size", "policy_hidden", "n_envs", "vec_env",
                                       "torch_threads")},
    },
}


def _layer_sizes(text: str) -> tuple[int, ...]:
    try:
        sizes = tuple(int(v) for v in str(text).replace(" ", "").strip("[]()").split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected layer sizes like 1024,512, got {text!r}") from None
    if not sizes or min(sizes) < 1:
        raise argparse.ArgumentTypeError(f"expected positive layer sizes like 1024,512, got {text!r}")
    return sizes


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--config", type=Path, help="TOML file whose keys set any flag below (flags win)")
    p.add_argument("--preset", choices=sorted(PRESETS), default="cpu",
                   help="named flag values (flags and --config win): cpu (the defaults), paper, style-short; "
                        "see above")
    p.add_argument("--env", default="InterLevel-v0", help="registered env id")
    p.add_argument("--env-kwarg", action="append", type=env_kwarg_argument, default=[], metavar="KEY=VALUE")
    p.add_argument("--timesteps", type=float, default=2e6)
    p.add_argument("--n-envs", type=int, default=128, help="worlds (envs) stepped together")
    p.add_argument("--vec-env", choices=("dummy", "subproc", "batched"), default="batched",
                   help="dummy: the envs step one after another in this process; subproc: a process per env; "
                        "batched: the natively batched env (stairenv.vec_sb3), one step call advancing every "
                        "world's physics on every core")
    p.add_argument("--physics", choices=("mujoco", "serial", "warp"), default=None,
                   help="the batched env's physics: mujoco (default; MuJoCo's C library on a pool of threads), "
                        "serial (one core), warp (MuJoCo Warp on a GPU; InterLevel ids; pip install '.[gpu]'); "
                        "with --resume: the checkpoint's unless given")
    p.add_argument("--physics-threads", type=int, default=None,
                   help="threads of the mujoco physics pool (default: the cores; with --resume: the checkpoint's "
                        "unless given)")
    p.add_argument("--state-on-device", action="store_true",
                   help="with --physics warp: the state stays on the device between resets, the step reads it as "
                        "arrays (2-2.5x the env's rate on an H200; docs/gpu.md); like --device, this machine's "
                        "choice, not taken from a checkpoint")
    p.add_argument("--climb-cache-workers", type=int, default=0,
                   help="InterLevel stair starts: synthesise every climb the env can draw on this many processes "
                        "before training (~80-165 ms of one core each, ~4,000 on the default ranges); 0 (default): "
                        "as episodes draw them. The same climbs either way; worth it on a machine with many cores")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--logdir", type=Path, default=Path("runs"))
    p.add_argument("--checkpoint-every", type=int, default=None,
                   help="env steps between checkpoints (default: 1,000,000 with the lean trainer, whose checkpoints "
                        "start every world's episode anew so that a resume is exact; 100,000 with sb3)")
    p.add_argument("--resume", type=Path, help="checkpoint .zip to continue from (its settings, its step count)")
    p.add_argument("--auto-resume", action="store_true",
                   help="lean trainer: go on from the newest checkpoint_<steps>.pt of this run (--logdir, --env, "
                        "--seed) to the run's own end, or start the run if it has none; the same command then "
                        "restarts a stopped run (a session's end, a lost rank or machine)")
    p.add_argument("--init-from", type=Path,
                   help="checkpoint .zip to start a new run from: its policy and value weights, optimiser, "
                        "observation statistics and (with AMP) discriminator, with this run's settings "
                        "(a recipe change on a trained policy); step count from 0")
    p.add_argument("--fresh-discriminator", action="store_true",
                   help="with --resume or --init-from: train a new discriminator (--disc-* flags) instead of "
                        "the AMP state saved beside the checkpoint")
    p.add_argument("--reset-std", action="store_true",
                   help="with --init-from (lean trainer): start the policy's action noise at --log-std-init, not "
                        "at the checkpoint's (a trained policy's noise has shrunk: on a new task it explores "
                        "little and, with --target-kl, holds the rate down)")
    p.add_argument("--eval-episodes", type=int, default=50, help="0 skips the final evaluation")
    p.add_argument("--eval-max-episode-steps", type=int, default=None, help="shorter evaluation episodes")
    p.add_argument("--style", choices=("amp", "none"), default="amp", help="add the AMP style reward")
    p.add_argument("--reference", default=None,
                   help="folder or .npz of reference clips, or builtin:stairs / builtin:sims (default: the env's)")
    p.add_argument("--amp-text-condition", action="store_true",
                   help="SIMS: condition the discriminator on the caption's text embedding (see above)")
    p.add_argument("--amp-text-captions", choices=("reference", "all"), default="reference",
                   help="with --amp-text-condition: the policy sees the reference clips' texts only (reference), "
                        "or every caption of the env, the discriminator its style's reference text (all)")
    p.add_argument("--init", choices=("default", "reference", "hybrid"), default="hybrid",
                   help="episode start: standing, reference frames, or half/half")
    p.add_argument("--w-task", type=float, default=0.5)
    p.add_argument("--w-style", type=float, default=0.5)
    p.add_argument("--amp-history", type=int, default=2, help="frames per discriminator sample")
    p.add_argument("--disc-loss", choices=LOSSES, default="lsgan")
    p.add_argument("--disc-lr", type=float, default=1e-4)
    p.add_argument("--policy-hidden", type=_layer_sizes, default=(256, 256), metavar="N,N",
                   help="policy and value network hidden layers (paper: 1024,512)")
    p.add_argument("--disc-hidden", type=_layer_sizes, default=(1024, 512), metavar="N,N",
                   help="discriminator hidden layers (paper: 1024,512)")
    p.add_argument("--disc-grad-penalty", type=float, default=10.0, help="gradient penalty weight (paper: 5)")
    p.add_argument("--disc-grad-penalty-batch", type=int, default=None,
                   help="reference windows the gradient penalty is estimated on (default: the whole batch)")
    p.add_argument("--disc-weight-decay", type=float, default=1e-4, help="L2 penalty on every discriminator weight")
    p.add_argument("--disc-logit-reg", type=float, default=0.01, help="L2 penalty on the output layer's weights")
    p.add_argument("--disc-input-noise", type=float, default=1.0,
                   help="std of instance noise on the discriminator's normalised training inputs (0: none, "
                        "the paper)")
    p.add_argument("--disc-batch-size", type=int, default=256, help="reference and agent windows per minibatch")
    p.add_argument("--disc-replay-size", type=int, default=200_000,
                   help="agent windows kept for training (paper preset: 100000)")
    p.add_argument("--disc-update-interval", type=int, default=2048, help="transitions between training rounds")
    p.add_argument("--disc-updates", type=int, default=2, help="discriminator minibatches per training round")
    p.add_argument("--disc-background", action=argparse.BooleanOptionalAction, default=True,
                   help="train the discriminator in a worker thread while the envs step (rewards lag one round; "
                        "--no-disc-background: in the step that completes a round)")
    p.add_argument("--disc-scoring", choices=SCORERS, default="auto",
                   help="how the discriminator scores each step (numba-parallel: over all cores; bf16: bfloat16)")
    p.add_argument("--log-std-init", type=float, default=-2.0,
                   help="initial log std of the Gaussian policy (-2: std 0.135; the paper preset: 0, std 1)")
    p.add_argument("--target-kl", type=float, default=None, dest="adaptive_kl",
                   help="adapt the learning rate after each update to keep PPO's approx-KL near this value "
                        "(x1.5 when below half of it, /1.5 when above twice it; bounds 1e-6..1e-3); "
                        "default: a constant learning rate")
    p.add_argument("--torch-threads", type=int, default=1,
                   help="torch intra-op threads (1: the batched env's physics uses the other cores; "
                        "paper preset: torch's default)")
    p.add_argument("--device", default="cpu",
                   help="torch device: the lean trainer's networks, rollout and updates (the envs stay on the host; "
                        "with --resume: this flag's, not the checkpoint's), or SB3's policy")
    p.add_argument("--update-threads", type=int, default=None,
                   help="lean trainer: torch threads during the PPO update, when the physics is idle "
                        "(default: --torch-threads)")
    p.add_argument("--update-bf16", action="store_true",
                   help="lean trainer: the PPO update's matrix products in bfloat16 (weights stay float32)")
    p.add_argument("--trainer", choices=("lean", "sb3"), default="lean",
                   help="lean: stairenv.training, PPO + AMP on the batched env's arrays (checkpoints "
                        "checkpoint_<n>.pt, final_policy.npz); sb3: Stable-Baselines3 PPO (ppo_<n>_steps.zip)")
    p.add_argument("--no-progress-bar", action="store_true")
    for key, value in PPO_DEFAULTS.items():
        p.add_argument(f"--{key.replace('_', '-')}", type=type(value), default=value)
    return p


def _explicit(argv: list[str] | None) -> set[str]:
    """The flags given on the command line (even when equal to their defaults)."""
    probe = build_parser()
    for action in probe._actions:
        action.default = argparse.SUPPRESS
    return set(vars(probe.parse_args(argv)))


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """Flags, then ``--config`` keys, then ``--preset`` values: the first that sets a key wins."""
    parser = build_parser()
    args = parser.parse_args(argv)
    fixed, from_config = _explicit(argv), set()
    if args.config is not None:
        with args.config.open("rb") as f:
            config = tomllib.load(f)
        actions = {a.dest: a for a in parser._actions}
        unknown = set(config) - set(actions) - {"env_kwargs"}
        if unknown:
            raise SystemExit(f"--config {args.config}: unknown keys {sorted(unknown)}; valid: {sorted(actions)}")
        for key, value in config.items():
            if key == "env_kwargs":
                args.env_kwarg = list(value.items()) + args.env_kwarg
            elif key not in fixed:
                convert = actions[key].type    # as the flag would take it (TOML has no paths)
                if isinstance(value, str) and callable(convert):
                    value = convert(value)
                setattr(args, key, value)
                fixed.add(key)
                from_config.add(key)
    for key, value in PRESETS[args.preset].items():
        if key not in fixed:
            setattr(args, key, value)
    args.given = frozenset(fixed)    # set by a flag or a --config key, not a default or a preset
    args.from_config = frozenset(from_config)    # of those, set by a --config key
    if args.env not in gym.registry:
        raise SystemExit(f"--env {args.env!r} is not registered; known stairenv ids: {list(stairenv.ENV_IDS)}")
    if args.n_envs < 1:
        raise SystemExit("--n-envs must be >= 1")
    if args.fresh_discriminator and ((args.resume is None and args.init_from is None) or args.style != "amp"):
        raise SystemExit("--fresh-discriminator only applies to --resume or --init-from with --style amp")
    if args.resume is not None and args.init_from is not None:
        raise SystemExit("--resume continues a run, --init-from starts a new one from a checkpoint: give one")
    if args.auto_resume and (args.resume is not None or args.init_from is not None or args.trainer != "lean"):
        raise SystemExit("--auto-resume finds the run's own checkpoint (lean trainer): not with --resume, "
                         "--init-from or --trainer sb3")
    if args.reset_std and (args.init_from is None or args.trainer != "lean"):
        raise SystemExit("--reset-std only applies to --init-from with the lean trainer (a resume stays exact)")
    return args


#: Env keywords that only shape training; the final evaluation leaves them out (the paper's protocol): the
#: fields of the configs' ``training_aids`` (InterLevel's, PlaMo's, SIMS').
TRAINING_AIDS = tuple(dict.fromkeys(group_keywords(InterLevelConfig, "training_aids")
                                    + group_keywords(PlaMoConfig, "training_aids")
                                    + group_keywords(SIMSConfig, "training_aids")))


def evaluation_kwargs(env_kwargs: dict) -> dict:
    """``env_kwargs`` without the training aids; with a step-height curriculum also without its
    ``step_height`` range (the evaluation draws the env's own)."""
    aids = TRAINING_AIDS + (("step_height",) if env_kwargs.get("step_height_levels") else ())
    return {key: value for key, value in env_kwargs.items() if key not in aids}


def discriminator_config(args: argparse.Namespace) -> DiscriminatorConfig:
    return DiscriminatorConfig(
        hidden=tuple(args.disc_hidden), loss=args.disc_loss, learning_rate=args.disc_lr,
        grad_penalty=args.disc_grad_penalty, grad_penalty_batch=args.disc_grad_penalty_batch,
        weight_decay=args.disc_weight_decay, logit_reg=args.disc_logit_reg, input_noise=args.disc_input_noise,
        batch_size=args.disc_batch_size, replay_size=args.disc_replay_size,
    )


def cpu_line(steps: int, seconds: float, cpu_seconds: float) -> str:
    """The CPU a run spent per env step (all threads) and how many cores it kept busy on average."""
    return (f"cpu {1e6 * cpu_seconds / max(steps, 1):.0f} us per env step, "
            f"{cpu_seconds / max(seconds, 1e-9):.2f} cores busy")


def run_env_kwargs(args: argparse.Namespace) -> dict:
    """The env keywords of the run: ``--env-kwarg`` and ``--config``'s, plus the start, reference and
    style-history flags."""
    env_kwargs = dict(args.env_kwarg)
    env_kwargs.setdefault("init", args.init)
    if args.reference is not None:
        env_kwargs.setdefault("reference_motion", str(args.reference))
    if args.style == "amp":
        env_kwargs.setdefault("amp_history", args.amp_history)
    if args.amp_text_condition and args.style != "amp":
        raise SystemExit("--amp-text-condition needs --style amp")
    return env_kwargs


def style_conditions(reference: tuple[tuple[str, str], ...],
                     captions: tuple[tuple[str, str], ...]) -> tuple[tuple[str, str], ...]:
    """``condition_captions`` for ``--amp-text-captions all``: each reference style's text, and for a style of
    the env's ``captions`` that no clip has (sit's clips are unstyled), the neutral clip's text."""
    texts = dict(reference)
    for style, _ in captions:
        if style not in texts and "neutral" in texts:
            texts[style] = texts["neutral"]
    return tuple(sorted(texts.items()))


def reference_windows(args: argparse.Namespace, env_kwargs: dict) -> ReferenceWindows | None:
    """The discriminator's reference windows (None without AMP): the ``--reference`` clips or the env's
    own, ``--amp-history`` frames at the env's control rate; with ``--amp-text-condition`` each clip's
    text embedding, and the env's captions set to the reference texts (in ``env_kwargs``)."""
    if args.style != "amp":
        return None
    probe = gym.make(args.env, **env_kwargs).unwrapped
    library = load_reference_library(args.reference if args.reference is not None
                                     else probe.DEFAULT_REFERENCE_MOTION)
    conditions = None
    if args.amp_text_condition:
        if not isinstance(probe, SIMSEnv) or not probe.text_conditioned:
            raise SystemExit(f"--amp-text-condition needs a SIMS env with text_conditioned=True, not {args.env}")
        conditions = text_conditions(library, probe.embed_text)
        pairs = reference_captions(library, probe.skill)
        if args.amp_text_captions == "all" or "condition_captions" in env_kwargs:  # a resumed "all" run too
            env_kwargs.setdefault("condition_captions", style_conditions(pairs, probe.captions))
        else:
            env_kwargs.setdefault("captions", pairs)
    reference = ReferenceWindows(library, num_frames=args.amp_history, fps=1.0 / probe.dt, conditions=conditions)
    probe.close()
    return reference


#: the discriminator's flags (``--disc-*``), each the ``TrainConfig`` field of its name
DISC_FLAGS = tuple(f"disc_{name}" for name in (
    "hidden", "loss", "lr", "grad_penalty", "grad_penalty_batch", "weight_decay", "logit_reg", "input_noise",
    "batch_size", "replay_size", "update_interval", "updates", "background", "scoring"))

#: flags that set a field of the run's ``TrainConfig`` (flag -> field): ``--resume`` goes on with the
#: checkpoint's and refuses such a flag given with another value (``--fresh-discriminator`` takes the
#: ``--disc-*`` flags given for the new discriminator)
RUN_FLAGS = {"env": "env_id", "n_envs": "num_envs", "seed": "seed", "n_steps": "rollout_steps",
             "n_epochs": "epochs", "batch_size": "minibatch_size", "learning_rate": "learning_rate",
             "adaptive_kl": "target_kl", "gamma": "gamma", "gae_lambda": "gae_lambda", "clip_range": "clip_range",
             "ent_coef": "ent_coef", "max_grad_norm": "max_grad_norm", "policy_hidden": "hidden",
             "log_std_init": "log_std_init", "style": "style", "reference": "reference",
             "amp_history": "amp_history", "w_task": "w_task", "w_style": "w_style", "update_bf16": "update_bf16",
             "checkpoint_every": "checkpoint_every", **{name: name for name in DISC_FLAGS}}
#: flags of the machine, which ``--resume`` takes over the checkpoint's (and says so)
MACHINE_FLAGS = ("physics", "physics_threads", "state_on_device", "device", "torch_threads", "update_threads")
#: flags ``--resume`` compares with the checkpoint's env keywords and text conditioning one by one
KEYWORD_FLAGS = ("env_kwarg", "init", "amp_text_condition", "amp_text_captions")
#: flags that choose what to do, not how the run trains (``--timesteps``: the steps to go on for)
OTHER_FLAGS = ("config", "preset", "timesteps", "logdir", "resume", "auto_resume", "init_from", "fresh_discriminator",
               "reset_std", "eval_episodes", "eval_max_episode_steps", "climb_cache_workers", "vec_env", "trainer",
               "no_progress_bar", "help")


def lean_config(args: argparse.Namespace, env_kwargs: dict) -> TrainConfig:
    """The flags as the lean trainer's ``TrainConfig``."""
    disc = {name: getattr(args, name) for name in DISC_FLAGS}
    try:
        return TrainConfig(
            env_id=args.env, env_kwargs=env_kwargs, num_envs=args.n_envs, seed=args.seed,
            physics=args.physics or TrainConfig.physics, physics_threads=args.physics_threads,
            state_on_device=args.state_on_device, total_steps=int(args.timesteps), rollout_steps=args.n_steps,
            epochs=args.n_epochs, minibatch_size=args.batch_size, learning_rate=args.learning_rate,
            target_kl=args.adaptive_kl,
            gamma=args.gamma, gae_lambda=args.gae_lambda, clip_range=args.clip_range, ent_coef=args.ent_coef,
            max_grad_norm=args.max_grad_norm, hidden=tuple(args.policy_hidden), log_std_init=args.log_std_init,
            style=args.style, reference=None if args.reference is None else str(args.reference),
            amp_history=args.amp_history, amp_text_condition=args.amp_text_condition,
            w_task=args.w_task, w_style=args.w_style,
            torch_threads=args.torch_threads, update_threads=args.update_threads, update_bf16=args.update_bf16,
            device=args.device, checkpoint_every=args.checkpoint_every or TrainConfig.checkpoint_every, **disc)
    except (TypeError, ValueError) as err:
        raise SystemExit(f"train_ppo: {err}") from None


def _read_lean(path: Path, flag: str, args: argparse.Namespace) -> dict:
    """A lean checkpoint, every entry checked (``check_checkpoint``); with ``--fresh-discriminator`` without
    its style state (a new discriminator). A run with AMP (``--resume``: the checkpoint's run; ``--init-from``:
    this one) refuses a checkpoint without a discriminator unless ``--fresh-discriminator`` asks for a new one."""
    try:
        state = read_checkpoint(path, style=not args.fresh_discriminator)
    except CheckpointError as err:
        raise SystemExit(f"{flag}: {err}") from None
    if args.fresh_discriminator:
        state["style"] = None
        return state
    saved_style = TrainConfig.from_dict(state["config"]).style
    if (saved_style if flag == "--resume" else args.style) == "amp" and state.get("style") is None:
        entry = "is missing" if "style" not in state else "is None"
        why = ("its run trained with AMP, so the file has lost it" if saved_style == "amp" else
               "its run trained without AMP (style 'none')")
        raise SystemExit(f"{flag} {path}: entry 'style' (the discriminator's state) {entry}: {why}. Pass "
                         "--fresh-discriminator to train a new discriminator with this run, or go on from a "
                         "checkpoint that holds one")
    return state


def _lean_start(args: argparse.Namespace) -> tuple[dict | None, dict | None]:
    """``(resume_state, init_state)`` read from ``--resume`` / ``--init-from`` (a lean ``.pt``; for
    ``--init-from`` also an SB3 ``.zip`` with its statistics and AMP state beside it); ``--auto-resume``
    sets ``--resume`` to the run's newest checkpoint, if it has one."""
    if args.auto_resume:    # the newest of the run's checkpoints, if it has one
        found = checkpoints_in(args.logdir / args.env / f"seed{args.seed}" / "checkpoints")
        args.resume = found[-1][1] if found else None
    if args.resume is not None:
        if args.resume.suffix == ".zip":
            raise SystemExit(f"--resume {args.resume}: an SB3 checkpoint continues with --trainer sb3; to go on "
                             "with the lean trainer start a new run from it with --init-from")
        return _read_lean(args.resume, "--resume", args), None
    if args.init_from is None:
        return None, None
    if args.init_from.suffix != ".zip":
        state = _read_lean(args.init_from, "--init-from", args)
    else:
        checkpoint = checkpoint_file(args.init_from)
        amp_state = required_amp_state(checkpoint) if args.style == "amp" and not args.fresh_discriminator else None
        state = state_from_sb3(checkpoint, statistics_beside(checkpoint), amp_state)
        try:    # the same checks as a lean checkpoint's (a NaN in the statistics .pkl, say)
            check_checkpoint(state, checkpoint, weights_only=True)
        except CheckpointError as err:
            raise SystemExit(f"--init-from: {err}") from None
        saved = curriculum_state_beside(checkpoint)
        state["curriculum_level"] = json.loads(saved.read_text())["curriculum_level"] if saved else []
    if args.reset_std:
        state["model"]["log_std"] = torch.full_like(state["model"]["log_std"], float(args.log_std_init))
    return None, state


def train_lean(args: argparse.Namespace) -> Path:
    """The lean trainer (``stairenv.training``): PPO + AMP on the batched env's arrays; under torchrun
    one data-parallel rank of it (``stairenv.training.distributed``)."""
    parallel = DataParallel.from_environment(args.device)
    try:
        return _train_lean(args, parallel or LOCAL)
    finally:
        if parallel is not None:
            parallel.close()


def fill_climb_cache(config: TrainConfig, workers: int, say, parallel=LOCAL) -> None:
    """Every climb the run's stair starts can draw, synthesised on ``workers`` processes into this process's
    cache (``stair_starts.fill_cache``), so the first minutes of training do not wait for them. Data-parallel
    ranks each synthesise a share and then take the others' (the same arrays: the synthesis is deterministic)."""
    env = gym.make(config.env_id, **config.env_kwargs).unwrapped
    keys = env.climb_keys() if hasattr(env, "climb_keys") else []
    env.close()
    if keys:
        start = time.perf_counter()
        mine = keys[parallel.rank::parallel.world_size]    # grid keys: each once
        count = stair_starts.fill_cache(mine, workers)
        if parallel.world_size == 1:
            say(f"climb cache: {count} staircases synthesised on {workers} processes in "
                f"{time.perf_counter() - start:.0f} s")
            return
        counts = []
        for rank_count, climbs in parallel.gather((count, stair_starts.cached(mine))):
            counts.append(rank_count)
            stair_starts.remember(climbs)
        say(f"climb cache: {sum(counts)} staircases synthesised by {parallel.world_size} ranks ({counts}) on "
            f"{workers} processes each in {time.perf_counter() - start:.0f} s, every rank holding them all")


def _flag_name(dest: str) -> str:
    """The command-line flag that sets ``dest`` (``adaptive_kl``: ``--target-kl``)."""
    names = {action.dest: action.option_strings[0] for action in build_parser()._actions if action.option_strings}
    return names.get(dest, "--" + dest.replace("_", "-"))


def _saved_form(value: Any) -> Any:
    """``value`` as a checkpoint's config holds it (lists for tuples, text keys, a path as text)."""
    if isinstance(value, (tuple, list)):
        return [_saved_form(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _saved_form(v) for k, v in value.items()}
    return str(value) if isinstance(value, Path) else value


def _same(new: Any, saved: Any) -> bool:
    """Whether a flag's value is the one a checkpoint's config holds (4 and 4.0 alike, True and 1 not)."""
    new = _saved_form(new)
    if isinstance(new, bool) or isinstance(saved, bool):
        return new is saved
    if isinstance(new, (int, float)) and isinstance(saved, (int, float)):
        return float(new) == float(saved)
    return new == saved


def _shown(value: Any) -> str:
    """A setting as a flag takes it (``256,256``, ``1e-05``; None: ``not set``)."""
    if value is None:
        return "not set"
    if isinstance(value, (tuple, list)) and all(isinstance(v, int) for v in value):
        return ",".join(map(str, value))    # as --policy-hidden takes it
    return f"{value:g}" if isinstance(value, float) else str(value)


def _flag_text(dest: str, value: Any) -> str:
    """The flag as given: ``--n-envs 8``, ``--update-bf16``, ``--no-disc-background``."""
    flag = _flag_name(dest)
    if isinstance(value, bool):
        return flag if value else "--no-" + flag[2:]
    return f"{flag} {_shown(value)}"


_NOT_SET = object()


def _refuse_changes(args: argparse.Namespace, resume: dict, saved: TrainConfig) -> None:
    """``SystemExit`` naming every setting given (a flag, a ``--config`` key, a ``--preset``'s value) that
    would change the run ``--resume`` goes on with: its checkpoint's settings (``RUN_FLAGS``, the env keywords,
    the text conditioning). A resume goes on exactly; other settings on trained weights are ``--init-from``'s.
    Taken instead of the checkpoint's: ``MACHINE_FLAGS`` (this machine's), ``--timesteps`` (the steps to go on
    for) and, with ``--fresh-discriminator``, the ``--disc-*`` flags."""
    given = set(getattr(args, "given", ()))
    origin = {name: f"from --config {args.config}; " for name in getattr(args, "from_config", ())}
    if "preset" in given:    # a preset asked for on the command line: its values are given too
        for name in PRESETS[args.preset]:
            if name not in given:
                given.add(name)
                origin[name] = f"from --preset {args.preset}; "
    fields, changes = saved.as_dict(), []
    for name, field in RUN_FLAGS.items():
        if name in given and not (args.fresh_discriminator and name in DISC_FLAGS) \
                and not _same(getattr(args, name), fields[field]):
            changes.append(f"{_flag_text(name, getattr(args, name))} ({origin.get(name, '')}the run's: "
                           f"{_shown(fields[field])})")
    wanted, keywords = run_env_kwargs(args), dict(args.env_kwarg)
    for key in [*keywords, *(["init"] if "init" in given and "init" not in keywords else [])]:
        old = saved.env_kwargs.get(key, _NOT_SET)
        if old is _NOT_SET or not _same(wanted[key], old):
            flag = f"--env-kwarg {key}={wanted[key]!r}" if key in keywords else _flag_text("init", wanted[key])
            changes.append(f"{flag} ({'' if key in keywords else origin.get('init', '')}the run's: "
                           f"{'not set' if old is _NOT_SET else repr(old) if key in keywords else old})")
    if args.amp_text_condition and "amp_text_condition" in resume["config"] and not saved.amp_text_condition:
        changes.append("--amp-text-condition (the run's discriminator was not conditioned on text)")
    if "amp_text_captions" in given and saved.amp_text_condition:
        old = "all" if "condition_captions" in saved.env_kwargs else "reference"
        if args.amp_text_captions != old:
            changes.append(f"--amp-text-captions {args.amp_text_captions} (the run's: {old})")
    if changes:
        what = f"--auto-resume (the run's checkpoint {args.resume})" if args.auto_resume else f"--resume {args.resume}"
        raise SystemExit(f"{what}: a resume goes on with its run's own settings, and these given would change the "
                         f"run: {'; '.join(changes)}. Leave them out to go on exactly, or start a new run from the "
                         "checkpoint with these settings with --init-from (its step count from 0)")


#: ``--disc-*`` flags -> the resumed AMP state's setting (``AMPStyleReward``: its own or its discriminator config's)
_SB3_STYLE = {"w_task": "w_task", "w_style": "w_style", "disc_update_interval": "update_interval",
              "disc_updates": "updates_per_round", "disc_hidden": "config.hidden", "disc_loss": "config.loss",
              "disc_lr": "config.learning_rate", "disc_grad_penalty": "config.grad_penalty",
              "disc_grad_penalty_batch": "config.grad_penalty_batch", "disc_weight_decay": "config.weight_decay",
              "disc_logit_reg": "config.logit_reg", "disc_input_noise": "config.input_noise",
              "disc_batch_size": "config.batch_size", "disc_replay_size": "config.replay_size"}


def _refuse_sb3_changes(args: argparse.Namespace, checkpoint: Path, model, style) -> None:
    """``--trainer sb3 --resume``: ``SystemExit`` naming each PPO or network flag given (and, with the AMP state
    resumed, each style flag) whose value differs from the one the checkpoint goes on with (SB3 keeps its own).
    The env's flags (``--env``, ``--n-envs``, ``--seed``, ``--env-kwarg``) build this run's envs: taken; with
    ``--target-kl`` the rate adapts from the checkpoint's."""
    arch = model.policy_kwargs.get("net_arch")
    saved = {key: getattr(model, key) for key in PPO_DEFAULTS}
    clip = model.clip_range
    saved.update(learning_rate=float(model.lr_schedule(1.0)), clip_range=float(clip(1.0)) if callable(clip) else clip,
                 policy_hidden=arch["pi"] if isinstance(arch, dict) else arch,
                 log_std_init=model.policy_kwargs.get("log_std_init", 0.0))
    if args.adaptive_kl is not None:
        saved.pop("learning_rate")
    if style is not None:
        for name, attribute in _SB3_STYLE.items():
            value = style
            for part in attribute.split("."):
                value = getattr(value, part)
            saved[name] = value
    changes = [f"{_flag_text(name, getattr(args, name))} (the checkpoint's: {_shown(value)})"
               for name, value in saved.items() if name in getattr(args, "given", ())
               and not _same(getattr(args, name), value)]
    if changes:
        raise SystemExit(f"--resume {checkpoint}: SB3 goes on with the checkpoint's own settings, and these given "
                         f"would change them: {'; '.join(changes)}. Leave them out to go on exactly, or start a new "
                         "run from the checkpoint with these settings with --init-from (its step count from 0)")


def _lean_setup(args: argparse.Namespace, say) -> tuple[dict | None, dict | None, TrainConfig, dict, Any]:
    """``(resume_state, init_state, config, env_kwargs, reference windows)``: what the run reads from this
    machine's files before its worlds are built (``--resume`` / ``--init-from``, the reference motions)."""
    resume, init = _lean_start(args)
    if resume is not None:    # the checkpoint's own settings; --timesteps more steps (as SB3's resume)
        config = TrainConfig.from_dict(resume["config"])
        _refuse_changes(args, resume, config)
        if not args.auto_resume:    # --auto-resume: on to the run's own end
            config = config.replace(total_steps=int(resume["steps"]) + int(args.timesteps))
        # where the physics runs is the machine's business, not the run's: a flag given overrides the checkpoint's
        # (as the torch threads: this machine's cores); the device and the state's place are this machine's flags
        # (default cpu, host truth) whatever trained it
        machine = {name: getattr(args, name) for name in ("physics", "physics_threads")
                   if getattr(args, name) is not None}
        machine.update({name: getattr(args, name) for name in ("torch_threads", "update_threads")
                        if name in args.given})
        # a fresh discriminator (--fresh-discriminator) is built with the --disc-* flags given, else the run's
        fresh = {name: getattr(args, name) for name in DISC_FLAGS if name in getattr(args, "given", ())} \
            if args.fresh_discriminator else {}
        saved = config
        try:
            config = config.replace(**machine, **fresh, device=args.device, state_on_device=args.state_on_device)
        except ValueError as err:
            raise SystemExit(f"--resume: {err}") from None
        taken = [f"{_flag_text(name, getattr(config, name))} (the run's: {_shown(getattr(saved, name))})"
                 for name in MACHINE_FLAGS if name in args.given and getattr(config, name) != getattr(saved, name)]
        if taken:
            say(f"--resume: this machine's settings, not the checkpoint's: {', '.join(taken)}")
        args.env, args.amp_history, args.style, args.reference = (config.env_id, config.amp_history, config.style,
                                                                   config.reference)
        # checkpoints written before the run recorded it need the flag again
        if args.amp_text_condition and "amp_text_condition" not in resume["config"]:
            say("--resume: --amp-text-condition taken (the checkpoint was written before runs recorded it)")
        args.amp_text_condition = args.amp_text_condition or config.amp_text_condition
        config = config.replace(amp_text_condition=args.amp_text_condition)
        env_kwargs = dict(config.env_kwargs)
    else:
        env_kwargs = run_env_kwargs(args)
        config = None
    if args.vec_env != "batched":
        say(f"note: the lean trainer steps the batched env ({args.vec_env!r} is --trainer sb3's)", file=sys.stderr)
    if resume is None:
        reference = reference_windows(args, env_kwargs)
    else:    # a checkpoint's keywords (and reference motions) that no longer build its env: named, no traceback
        try:
            reference = reference_windows(args, env_kwargs)
            if reference is None:    # (reference_windows builds the env only for AMP)
                gym.make(config.env_id, **env_kwargs).close()
        except (TypeError, ValueError, gym.error.Error) as err:
            raise SystemExit(f"--resume {args.resume}: its run's env cannot be built here from entries "
                             f"config['env_id'], config['env_kwargs'] and config['reference']: {err}") from None
    if config is None:
        config = lean_config(args, env_kwargs)
    elif reference is not None:
        config = config.replace(env_kwargs=env_kwargs)
    return resume, init, config, env_kwargs, reference


def _take_resume(trainer: Trainer, args: argparse.Namespace, resume: dict) -> bool:
    """The checkpoint's state into ``trainer``, its replay buffer beside it; whether there was one."""
    try:
        trainer.load_state(resume)
        return trainer.load_replay(args.resume, resume)
    except CheckpointError as err:    # the replay buffer beside it: the file and the fault named
        raise SystemExit(f"--resume: {err}") from None
    except RunMismatch as err:    # a sound checkpoint whose run is not the one its settings build here
        advice = "; it was written by another version of stairenv, or its env's keywords no longer build its env"
        if err.part == "discriminator" and "amp_text_condition" not in resume["config"] \
                and not args.amp_text_condition:
            advice = ("; a text-conditioned run written before checkpoints recorded amp_text_condition needs "
                      "--amp-text-condition again, any other run --fresh-discriminator")
        raise SystemExit(f"--resume {args.resume}: cannot go on from it: {err}{advice}") from None
    except (RuntimeError, ValueError, KeyError) as err:
        raise SystemExit(f"--resume {args.resume}: cannot go on from it ({type(err).__name__}: {err})") from None


def _take_init(trainer: Trainer, args: argparse.Namespace, init: dict) -> None:
    try:
        trainer.load_state(init, weights_only=True)
    except RunMismatch as err:
        if err.part == "discriminator":
            advice = ("pass --fresh-discriminator to train a new one (the style's inputs differ)"
                      if isinstance(err.saved, int) else "pass its --disc-hidden, or --fresh-discriminator to train "
                      "a new one")
        elif err.saved[1] != err.run[1] and (err.saved[0], err.saved[2]) == (err.run[0], err.run[2]):
            advice = f"pass --policy-hidden {_shown(err.saved[1])}, the layers it was trained with"
        else:
            advice = "pass the --env and --env-kwarg it was trained with" + (
                f" and --policy-hidden {_shown(err.saved[1])}" if err.saved[1] != err.run[1] else "")
        raise SystemExit(f"--init-from {args.init_from}: cannot take it into this run: {err}; {advice}") from None
    except (RuntimeError, ValueError, KeyError) as err:
        raise SystemExit(f"--init-from {args.init_from}: cannot take it into this run ({type(err).__name__}: "
                         f"{err})") from None


def _train_lean(args: argparse.Namespace, parallel) -> Path:
    first = parallel.rank == 0    # rank 0 prints, logs, writes and evaluates

    def say(*words, **kwargs) -> None:
        if first:
            print(*words, **kwargs)

    # each rank reads its machine's files; one that cannot stops them all with its reason (parallel.agree)
    resume, init, config, env_kwargs, reference = parallel.agree(
        lambda: _lean_setup(args, say), "Reading the run's files (--resume, --init-from, the reference motions)")
    if args.auto_resume:
        chosen = parallel.gather(None if args.resume is None else str(args.resume))
        if len(set(chosen)) > 1:    # a folder the machines see differently: they would go on from different states
            raise SystemExit(f"--auto-resume: the ranks found different newest checkpoints ({chosen}); give "
                             "--logdir a folder every machine sees alike")
    run_dir = args.logdir / config.env_id / f"seed{config.seed}"
    if args.auto_resume and resume is None:
        say(f"--auto-resume: no checkpoint of this run in {run_dir}: starting it")
    if args.climb_cache_workers > 0:
        fill_climb_cache(config, args.climb_cache_workers, say, parallel)
    trainer = Trainer(config, build_style(config, reference, parallel.rank), parallel=parallel)
    if parallel.world_size > 1:
        say(f"data-parallel: {parallel.world_size} ranks x {config.num_envs} worlds "
            f"({parallel.world_size * config.num_envs} in all); --timesteps counts them all")
    if resume is not None:
        replay = parallel.agree(lambda: _take_resume(trainer, args, resume), "Resuming")
        note = "" if replay or trainer.style is None else " (no replay buffer beside it: it refills within a round)"
        if args.fresh_discriminator:
            note += "; a fresh discriminator (--fresh-discriminator)"
        saved_ranks = int(resume.get("world_size", 1))
        if saved_ranks != parallel.world_size:
            note += f" (written by {saved_ranks} ranks, going on with {parallel.world_size}: not exact)"
        say(f"resumed from {args.resume} at {trainer.steps} steps{note}")
    elif init is not None:
        parallel.agree(lambda: _take_init(trainer, args, init), "Starting from --init-from")
        taken = ", discriminator" if init.get("style") else ""
        if args.fresh_discriminator:
            taken = "; a fresh discriminator (--fresh-discriminator)"
        if args.reset_std:
            taken += f"; action noise reset to log std {args.log_std_init:g} (--reset-std)"
        say(f"initialised from {args.init_from} (weights, optimiser, statistics{taken})")
    log = RunLog(run_dir) if first else None
    start_steps, start, start_cpu = trainer.steps, time.perf_counter(), time.process_time()
    try:
        trainer.learn(log, run_dir / "checkpoints")
    finally:
        if log is not None:
            log.close()
    seconds = time.perf_counter() - start
    say(f"trained {trainer.steps - start_steps} env steps in {seconds:.1f} s "
        f"({(trainer.steps - start_steps) / max(seconds, 1e-9):.0f} env steps/s)")
    say(cpu_line(trainer.steps - start_steps, seconds, time.process_time() - start_cpu)
        + (" (rank 0)" if parallel.world_size > 1 else ""))
    final = trainer.save(run_dir / "final_checkpoint.pt")
    policy_path = run_dir / "final_policy.npz"
    if first:
        trainer.policy().save(policy_path)
    trainer.close()
    say(f"saved {final} and {policy_path}")
    if args.eval_episodes > 0 and first:
        report = evaluator_for(config.env_id)(
            load_policy(str(policy_path), gym.make(config.env_id, **env_kwargs)), env_id=config.env_id,
            episodes=args.eval_episodes, seed=10_000 + config.seed, env_kwargs=evaluation_kwargs(env_kwargs),
            max_episode_steps=args.eval_max_episode_steps, progress_bar=not args.no_progress_bar,
            label=str(policy_path))
        print(report.format_table())
        write_reports([report], run_dir / "evaluation.csv", run_dir / "evaluation.json")
    return policy_path


def main(argv: list[str] | None = None) -> Path:
    args = parse_args(argv)
    if args.trainer == "lean":
        return train_lean(args)
    if "WORLD_SIZE" in os.environ and int(os.environ["WORLD_SIZE"]) > 1:
        raise SystemExit("--trainer sb3 trains in one process; data-parallel training (torchrun) is the lean "
                         "trainer's")
    if args.state_on_device and (args.vec_env != "batched" or args.physics != "warp"):
        raise SystemExit("--state-on-device needs --physics warp (with --trainer sb3: and --vec-env batched)")
    if args.torch_threads is not None:
        torch.set_num_threads(args.torch_threads)
    env_kwargs = run_env_kwargs(args)
    checkpoint = stats = amp_state = None
    source = args.resume if args.resume is not None else args.init_from
    if source is not None:  # every file first, before minutes of env setup
        checkpoint = checkpoint_file(source)
        stats = statistics_beside(checkpoint)
        if args.style == "amp" and not args.fresh_discriminator:
            amp_state = required_amp_state(checkpoint)
    run_dir = args.logdir / args.env / f"seed{args.seed}"
    run_dir.mkdir(parents=True, exist_ok=True)

    style = None
    reference = reference_windows(args, env_kwargs)
    if args.vec_env == "batched":
        # VecMonitor: episode returns and lengths for SB3's rollout/ep_*_mean (make_vec_env's Monitor does it
        # for the other vec envs)
        venv = VecMonitor(make_sb3_vec_env(args.env, n_envs=args.n_envs, seed=args.seed,
                                           physics=args.physics or "mujoco", physics_threads=args.physics_threads,
                                           **({"state_on_device": True} if args.state_on_device else {}),
                                           **env_kwargs))
    else:
        vec_cls = SubprocVecEnv if args.vec_env == "subproc" and args.n_envs > 1 else DummyVecEnv
        venv = make_vec_env(args.env, n_envs=args.n_envs, seed=args.seed, env_kwargs=env_kwargs, vec_env_cls=vec_cls)
    ppo_kwargs = {key: getattr(args, key) for key in PPO_DEFAULTS}
    tensorboard = str(run_dir / "tb") if importlib.util.find_spec("tensorboard") else None

    normalizer = None
    if checkpoint is not None:
        try:
            normalizer = read_normalizer(stats)
        except ValueError as err:
            raise SystemExit(f"--resume {checkpoint}: {err}; copy an intact file back or resume from another "
                             "checkpoint") from None
        check_same_spaces(checkpoint, stats, normalizer, venv, args.env)

    if reference is not None:
        if amp_state is not None:
            style = resumed_style(amp_state, reference, args.seed)
            if args.init_from is not None:  # a new run on the trained discriminator: this run's weights
                style.w_task, style.w_style = args.w_task, args.w_style
                # and this run's settings of the discriminator's training that can change on a trained one
                style.config = style.disc.config = dataclasses.replace(
                    style.disc.config, input_noise=args.disc_input_noise, grad_penalty=args.disc_grad_penalty)
        else:
            style = AMPStyleReward(reference, w_task=args.w_task, w_style=args.w_style, seed=args.seed,
                                   update_interval=args.disc_update_interval, updates_per_round=args.disc_updates,
                                   config=discriminator_config(args), background_training=args.disc_background,
                                   scoring=args.disc_scoring)
        venv = AMPVecEnvWrapper(venv, style)

    if normalizer is not None and args.resume is not None:
        normalizer.set_venv(venv)
        venv = normalizer
        model = load_checkpoint(checkpoint, venv, args.device, tensorboard)
        _refuse_sb3_changes(args, checkpoint, model, style if amp_state is not None else None)
        discriminator = f", discriminator {amp_state}" if amp_state else ""
        if args.fresh_discriminator:
            discriminator = ", a fresh discriminator (--fresh-discriminator)"
        print(f"resumed from {checkpoint} ({model.num_timesteps} steps) with statistics {stats}{discriminator}")
        origin = run_env(checkpoint)
        if origin is not None and origin != args.env:
            print(f"note: {checkpoint} comes from a {origin} run; training goes on with --env {args.env}",
                  file=sys.stderr)
    else:
        venv = VecNormalize(venv, norm_obs=True, norm_reward=True, gamma=args.gamma)
        model = PPO(
            "MlpPolicy",
            venv,
            policy_kwargs={"net_arch": {"pi": list(args.policy_hidden), "vf": list(args.policy_hidden)},
                           "activation_fn": torch.nn.ReLU,
                           "log_std_init": args.log_std_init},
            tensorboard_log=tensorboard,
            seed=args.seed,
            device=args.device,
            verbose=0,
            **ppo_kwargs,
        )
        if normalizer is not None:  # --init-from: the trained weights, optimiser and statistics
            venv.obs_rms, venv.ret_rms = normalizer.obs_rms, normalizer.ret_rms
            try:
                model.set_parameters(str(checkpoint), exact_match=True, device=args.device)
            except Exception as err:  # noqa: BLE001  (other network sizes, a truncated .zip: many types)
                raise SystemExit(f"--init-from {checkpoint}: cannot take its weights into this run's networks "
                                 f"({type(err).__name__}: {err}); pass the --policy-hidden it was trained "
                                 "with") from None
            print(f"initialised from {checkpoint} (weights, optimiser, statistics{', discriminator' if amp_state else ''})")

    save_freq = max((args.checkpoint_every or 100_000) // args.n_envs, 1)
    callbacks: list[BaseCallback] = [CheckpointCallback(
        save_freq=save_freq, save_path=str(run_dir / "checkpoints"), name_prefix="ppo", save_vecnormalize=True,
    )]
    if style is not None:
        callbacks.append(AMPCallback(style, save_freq, run_dir / "checkpoints"))
    callbacks.append(EpisodeStatsCallback())
    if args.adaptive_kl is not None:
        callbacks.append(AdaptiveLearningRate(args.adaptive_kl))
    if any(env_kwargs.get(keyword) for keyword in curriculum.LEVEL_KEYWORDS):
        callbacks.append(CurriculumCallback(save_freq, run_dir / "checkpoints"))
        saved = curriculum_state_beside(checkpoint) if checkpoint is not None else None
        if saved is not None:
            levels = restore_curriculum(venv, saved)
            known = [level for level in levels if level is not None] or [0]
            print(f"curriculum levels from {saved} (mean {np.mean(known):.2f})")
    start_steps, start_time, start_cpu = model.num_timesteps, time.perf_counter(), time.process_time()
    model.learn(
        total_timesteps=int(args.timesteps),
        callback=CallbackList(callbacks),
        progress_bar=not args.no_progress_bar,
        reset_num_timesteps=args.resume is None,
        tb_log_name="ppo",
    )
    trained, seconds = model.num_timesteps - (0 if args.resume is None else start_steps), time.perf_counter() - start_time
    print(f"trained {trained} env steps in {seconds:.1f} s ({trained / seconds:.0f} env steps/s)")
    print(cpu_line(trained, seconds, time.process_time() - start_cpu))
    model_path = run_dir / "final_model.zip"
    model.save(model_path)
    venv.save(str(run_dir / "vecnormalize.pkl"))
    if style is not None:
        style.save(run_dir / "amp.pt")
    venv.close()
    print(f"saved {model_path}")

    if args.eval_episodes > 0:
        eval_env = gym.make(args.env, **env_kwargs)
        policy = load_policy(str(model_path), eval_env)
        eval_env.close()
        # the evaluation starts as the paper's protocol does: standing on the floor
        eval_kwargs = evaluation_kwargs(env_kwargs)
        evaluate = evaluator_for(args.env)
        report = evaluate(policy, env_id=args.env, episodes=args.eval_episodes, seed=10_000 + args.seed,
                          env_kwargs=eval_kwargs, max_episode_steps=args.eval_max_episode_steps,
                          progress_bar=not args.no_progress_bar, label=str(model_path))
        print(report.format_table())
        write_reports([report], run_dir / "evaluation.csv", run_dir / "evaluation.json")
    return model_path


if __name__ == "__main__":
    main()
