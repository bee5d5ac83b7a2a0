"""The training command line: flags, presets and recipes into a ``TrainConfig``; resumes checked.

``baselines/train_ppo.py`` (the lean trainer) and ``baselines/train_sb3.py`` (Stable-Baselines3 PPO over the
same envs) read the same flags through :func:`parse_args`: a flag given wins over a ``--config`` TOML key,
which wins over a ``--preset`` value, which wins over the default. Every default of a run setting is
``TrainConfig``'s (:func:`build_parser` reads them from its fields, and its docstring's table is each
flag's help), so the flags, the recipes and a checkpoint's config agree. A ``--resume`` goes on with the
checkpoint's own settings and refuses a setting given that would change them, naming it
(:func:`refuse_changes`); this machine's settings (``MACHINE_FLAGS``) are taken and said.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import tomllib
from pathlib import Path
from typing import Any

import gymnasium as gym
import torch

import stairenv
from stairenv.environments.config import InterLevelConfig, PlaMoConfig, group_keywords
from stairenv.environments.sims import SIMSEnv, reference_captions
from stairenv.environments.sims_config import SIMSConfig
from stairenv.evaluation.cli import env_kwarg_argument
from stairenv.motion import stair_starts
from stairenv.motion.rsi import load_reference_library
from stairenv.style.discriminator import LOSSES, SCORERS, DiscriminatorConfig
from stairenv.style.reference import ReferenceWindows, text_conditions
from stairenv.training.config import TrainConfig, field_default, field_docs
from stairenv.training.distributed import LOCAL
from stairenv.training.from_sb3 import state_from_sb3
from stairenv.training.ppo import (CheckpointError, RunMismatch, Trainer, check_checkpoint, checkpoints_in,
                                   read_checkpoint)
from stairenv.training.sb3 import checkpoint_file, curriculum_state_beside, required_amp_state, statistics_beside


#: flags that set a field of the run's ``TrainConfig`` (flag -> field), besides the ``--disc-*`` flags (each the
#: field of its own name): their defaults and help are the field's. ``--resume`` goes on with the checkpoint's
#: and refuses such a flag given with another value (``--fresh-discriminator`` takes the ``--disc-*`` flags given
#: for the new discriminator).
_CONFIG_FLAGS = {"env": "env_id", "n_envs": "num_envs", "seed": "seed", "n_steps": "rollout_steps",
                 "n_epochs": "epochs", "minibatch_size": "minibatch_size", "learning_rate": "learning_rate",
                 "adaptive_kl": "target_kl", "gamma": "gamma", "gae_lambda": "gae_lambda", "clip_range": "clip_range",
                 "ent_coef": "ent_coef", "max_grad_norm": "max_grad_norm", "policy_hidden": "hidden",
                 "log_std_init": "log_std_init", "style": "style", "reference": "reference",
                 "amp_history": "amp_history", "w_task": "w_task", "w_style": "w_style",
                 "update_bf16": "update_bf16", "checkpoint_every": "checkpoint_every"}
#: the discriminator's flags (``--disc-*``), each the ``TrainConfig`` field of its name
DISC_FLAGS = tuple(f"disc_{name}" for name in (
    "hidden", "loss", "lr", "grad_penalty", "grad_penalty_batch", "weight_decay", "logit_reg", "input_noise",
    "batch_size", "replay_size", "update_interval", "updates", "background", "scoring"))
RUN_FLAGS = {**_CONFIG_FLAGS, **{name: name for name in DISC_FLAGS}}

FIELD_DOCS = field_docs()

#: the PPO flags Stable-Baselines3's ``PPO`` takes by the same name (flag -> SB3 keyword)
PPO_FLAGS = {"learning_rate": "learning_rate", "n_steps": "n_steps", "minibatch_size": "batch_size",
             "n_epochs": "n_epochs", "gamma": "gamma", "gae_lambda": "gae_lambda", "clip_range": "clip_range",
             "ent_coef": "ent_coef", "max_grad_norm": "max_grad_norm"}

_PAPER_DISCRIMINATOR = DiscriminatorConfig()    # the paper's discriminator (its defaults)

# The InterLevel paper's settings (learning rate 2e-5, minibatch 64, [1024, 512] networks, std 1 at the
# start, the paper's discriminator) on the sequential vec env.
PAPER = {
    "learning_rate": 2e-5, "n_steps": 256, "minibatch_size": 64, "n_epochs": 5,
    "policy_hidden": (1024, 512), "log_std_init": 0.0, "n_envs": 4, "vec_env": "dummy", "torch_threads": None,
    "disc_input_noise": _PAPER_DISCRIMINATOR.input_noise, "disc_grad_penalty": _PAPER_DISCRIMINATOR.grad_penalty,
    "disc_replay_size": _PAPER_DISCRIMINATOR.replay_size,
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
        **{key: PAPER[key] for key in ("n_steps", "minibatch_size", "policy_hidden", "n_envs", "vec_env",
                                       "torch_threads")},
    },
}

#: ``--config`` keys of earlier recipes, read as the flag they became
RENAMED_KEYS = {"batch_size": "minibatch_size"}


def _layer_sizes(text: str) -> tuple[int, ...]:
    try:
        sizes = tuple(int(v) for v in str(text).replace(" ", "").strip("[]()").split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected layer sizes like 1024,512, got {text!r}") from None
    if not sizes or min(sizes) < 1:
        raise argparse.ArgumentTypeError(f"expected positive layer sizes like 1024,512, got {text!r}")
    return sizes


class _HelpFormatter(argparse.RawDescriptionHelpFormatter, argparse.ArgumentDefaultsHelpFormatter):
    """The description as written; each flag's default after its help."""


def _config_flag(p: argparse.ArgumentParser, dest: str, *names: str, **kwargs) -> None:
    """A flag that sets ``TrainConfig``'s field of ``dest``: the field's default and its doc as the help."""
    field = RUN_FLAGS.get(dest, dest)
    default = field_default(field)
    kwargs.setdefault("default", default)
    if "type" not in kwargs and "action" not in kwargs and default is not None and not isinstance(default, tuple):
        kwargs["type"] = type(default)
    help_text = FIELD_DOCS[field].replace("%", "%%")
    extra = kwargs.pop("help_extra", "")
    p.add_argument(*(names or ("--" + dest.replace("_", "-"),)), dest=dest,
                   help=f"{help_text}{'; ' + extra if extra else ''} (TrainConfig.{field})", **kwargs)


def build_parser(description: str | None = None) -> argparse.ArgumentParser:
    """The flags of ``train_ppo.py`` and ``train_sb3.py``; a run setting's default and help are its
    ``TrainConfig`` field's."""
    p = argparse.ArgumentParser(description=description, formatter_class=_HelpFormatter)
    p.add_argument("--config", type=Path, help="TOML file whose keys set any flag below (flags win)")
    p.add_argument("--preset", choices=sorted(PRESETS), default="cpu",
                   help="named flag values (flags and --config win): cpu (the defaults), paper, style-short; "
                        "see above")
    _config_flag(p, "env", "--env")
    p.add_argument("--env-kwarg", action="append", type=env_kwarg_argument, default=[], metavar="KEY=VALUE",
                   help="an env keyword (TrainConfig.env_kwargs); training aids too, which the evaluation drops")
    p.add_argument("--timesteps", type=float, default=float(field_default("total_steps")),
                   help=f"{FIELD_DOCS['total_steps']} (TrainConfig.total_steps; with --resume: the steps to go on for)")
    _config_flag(p, "n_envs")
    p.add_argument("--vec-env", choices=("dummy", "subproc", "batched"), default="batched",
                   help="train_sb3.py: dummy: the envs step one after another in this process; subproc: a process "
                        "per env; batched: the natively batched env (stairenv.vec_sb3), one step call advancing "
                        "every world's physics on every core (train_ppo.py always steps the batched env)")
    p.add_argument("--physics", choices=("mujoco", "serial", "warp"), default=None,
                   help=f"{FIELD_DOCS['physics']} (TrainConfig.physics; default mujoco; with --resume: the "
                        "checkpoint's unless given)")
    p.add_argument("--physics-threads", type=int, default=None,
                   help=f"{FIELD_DOCS['physics_threads']} (TrainConfig.physics_threads; with --resume: the "
                        "checkpoint's unless given)")
    p.add_argument("--state-on-device", action="store_true",
                   help=f"{FIELD_DOCS['state_on_device']} (TrainConfig.state_on_device; 2-2.5x the env's rate on "
                        "an H200, docs/gpu.md); like --device, this machine's choice, not taken from a checkpoint")
    p.add_argument("--climb-cache-workers", type=int, default=0,
                   help="InterLevel stair starts: synthesise every climb the env can draw on this many processes "
                        "before training (~80-165 ms of one core each, ~4,000 on the default ranges); 0 (default): "
                        "as episodes draw them. The same climbs either way; worth it on a machine with many cores")
    _config_flag(p, "seed")
    p.add_argument("--logdir", type=Path, default=Path("runs"))
    _config_flag(p, "checkpoint_every", default=None, type=int,
                 help_extra="None: 1,000,000 with train_ppo.py, 100,000 with train_sb3.py")
    p.add_argument("--resume", type=Path, help="checkpoint to continue from (its settings, its step count)")
    p.add_argument("--auto-resume", action="store_true",
                   help="train_ppo.py: go on from the newest checkpoint_<steps>.pt of this run (--logdir, --env, "
                        "--seed) to the run's own end, or start the run if it has none; the same command then "
                        "restarts a stopped run (a session's end, a lost rank or machine)")
    p.add_argument("--init-from", type=Path,
                   help="checkpoint to start a new run from: its policy and value weights, optimiser, "
                        "observation statistics and (with AMP) discriminator, with this run's settings "
                        "(a recipe change on a trained policy); step count from 0")
    p.add_argument("--fresh-discriminator", action="store_true",
                   help="with --resume or --init-from: train a new discriminator (--disc-* flags) instead of "
                        "the AMP state saved beside the checkpoint")
    p.add_argument("--reset-std", action="store_true",
                   help="with --init-from (train_ppo.py): start the policy's action noise at --log-std-init, not "
                        "at the checkpoint's (a trained policy's noise has shrunk: on a new task it explores "
                        "little and, with --target-kl, holds the rate down)")
    p.add_argument("--eval-episodes", type=int, default=50, help="0 skips the final evaluation")
    p.add_argument("--eval-max-episode-steps", type=int, default=None, help="shorter evaluation episodes")
    _config_flag(p, "style", choices=("amp", "none"))
    _config_flag(p, "reference", type=str)
    _config_flag(p, "amp_text_condition", action=argparse.BooleanOptionalAction)
    p.add_argument("--amp-text-captions", choices=("reference", "all"), default="reference",
                   help="with --amp-text-condition: the policy sees the reference clips' texts only (reference), "
                        "or every caption of the env, the discriminator its style's reference text (all)")
    p.add_argument("--init", choices=("default", "reference", "hybrid"), default="hybrid",
                   help="episode start (env keyword init): standing, reference frames, or half/half")
    _config_flag(p, "w_task")
    _config_flag(p, "w_style")
    _config_flag(p, "amp_history")
    _config_flag(p, "policy_hidden", "--policy-hidden", type=_layer_sizes, metavar="N,N")
    for name in DISC_FLAGS:
        if name == "disc_hidden":
            _config_flag(p, name, type=_layer_sizes, metavar="N,N")
        elif name == "disc_loss":
            _config_flag(p, name, choices=LOSSES)
        elif name == "disc_scoring":
            _config_flag(p, name, choices=SCORERS)
        elif name == "disc_background":
            _config_flag(p, name, action=argparse.BooleanOptionalAction)
        elif name == "disc_grad_penalty_batch":
            _config_flag(p, name, type=int)
        else:
            _config_flag(p, name)
    _config_flag(p, "log_std_init")
    _config_flag(p, "adaptive_kl", "--target-kl", type=float)
    p.add_argument("--torch-threads", type=int, default=field_default("torch_threads"),
                   help=f"{FIELD_DOCS['torch_threads']} (TrainConfig.torch_threads; 1: the batched env's physics "
                        "uses the other cores; paper preset: torch's default)")
    p.add_argument("--device", default=field_default("device"),
                   help=f"{FIELD_DOCS['device']} (TrainConfig.device; with --resume: this flag's, not the "
                        "checkpoint's), or SB3's policy")
    p.add_argument("--update-threads", type=int, default=field_default("update_threads"),
                   help=f"{FIELD_DOCS['update_threads']} (TrainConfig.update_threads)")
    _config_flag(p, "update_bf16", action=argparse.BooleanOptionalAction)
    p.add_argument("--no-progress-bar", action="store_true")
    _config_flag(p, "learning_rate")
    _config_flag(p, "n_steps")
    _config_flag(p, "minibatch_size", "--minibatch-size", "--batch-size",
                 help_extra="--batch-size: its earlier name")
    _config_flag(p, "n_epochs")
    for name in ("gamma", "gae_lambda", "clip_range", "ent_coef", "max_grad_norm"):
        _config_flag(p, name)
    return p


def _explicit(argv: list[str] | None) -> set[str]:
    """The flags given on the command line (even when equal to their defaults)."""
    probe = build_parser()
    for action in probe._actions:
        action.default = argparse.SUPPRESS
    return set(vars(probe.parse_args(argv)))


def parse_args(argv: list[str] | None = None, trainer: str = "lean",
               description: str | None = None) -> argparse.Namespace:
    """Flags, then ``--config`` keys, then ``--preset`` values: the first that sets a key wins. ``trainer``:
    "lean" (``train_ppo.py``) or "sb3" (``train_sb3.py``), for the flags only one of them has."""
    parser = build_parser(description)
    args = parser.parse_args(argv)
    fixed, from_config = _explicit(argv), set()
    if args.config is not None:
        with args.config.open("rb") as f:
            config = tomllib.load(f)
        config = {RENAMED_KEYS.get(key, key): value for key, value in config.items()}
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
    args.trainer = trainer
    if args.env not in gym.registry:
        raise SystemExit(f"--env {args.env!r} is not registered; known stairenv ids: {list(stairenv.ENV_IDS)}")
    if args.n_envs < 1:
        raise SystemExit("--n-envs must be >= 1")
    if args.fresh_discriminator and ((args.resume is None and args.init_from is None) or args.style != "amp"):
        raise SystemExit("--fresh-discriminator only applies to --resume or --init-from with --style amp")
    if args.resume is not None and args.init_from is not None:
        raise SystemExit("--resume continues a run, --init-from starts a new one from a checkpoint: give one")
    if args.auto_resume and (args.resume is not None or args.init_from is not None or trainer != "lean"):
        raise SystemExit("--auto-resume finds the run's own checkpoint (train_ppo.py): not with --resume, "
                         "--init-from or train_sb3.py")
    if args.reset_std and (args.init_from is None or trainer != "lean"):
        raise SystemExit("--reset-std only applies to --init-from with train_ppo.py (a resume stays exact)")
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


#: flags of the machine, which ``--resume`` takes over the checkpoint's (and says so)
MACHINE_FLAGS = ("physics", "physics_threads", "state_on_device", "device", "torch_threads", "update_threads")
#: flags ``--resume`` compares with the checkpoint's env keywords and text conditioning one by one
KEYWORD_FLAGS = ("env_kwarg", "init", "amp_text_condition", "amp_text_captions")
#: flags that choose what to do, not how the run trains (``--timesteps``: the steps to go on for)
OTHER_FLAGS = ("config", "preset", "timesteps", "logdir", "resume", "auto_resume", "init_from", "fresh_discriminator",
               "reset_std", "eval_episodes", "eval_max_episode_steps", "climb_cache_workers", "vec_env",
               "no_progress_bar", "help")


def lean_config(args: argparse.Namespace, env_kwargs: dict) -> TrainConfig:
    """The flags as the lean trainer's ``TrainConfig``: every ``RUN_FLAGS`` flag into its field, and the
    machine's, the steps and the keywords."""
    fields = {field: getattr(args, flag) for flag, field in RUN_FLAGS.items()}
    fields.update(hidden=tuple(args.policy_hidden), reference=None if args.reference is None else str(args.reference),
                  checkpoint_every=args.checkpoint_every or TrainConfig.checkpoint_every)
    try:
        return TrainConfig(**fields, env_kwargs=env_kwargs, physics=args.physics or TrainConfig.physics,
                           physics_threads=args.physics_threads, state_on_device=args.state_on_device,
                           total_steps=int(args.timesteps), amp_text_condition=args.amp_text_condition,
                           torch_threads=args.torch_threads, update_threads=args.update_threads, device=args.device)
    except (TypeError, ValueError) as err:
        raise SystemExit(f"train_ppo: {err}") from None


def read_lean(path: Path, flag: str, args: argparse.Namespace) -> dict:
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


def lean_start(args: argparse.Namespace) -> tuple[dict | None, dict | None]:
    """``(resume_state, init_state)`` read from ``--resume`` / ``--init-from`` (a lean ``.pt``; for
    ``--init-from`` also an SB3 ``.zip`` with its statistics and AMP state beside it); ``--auto-resume``
    sets ``--resume`` to the run's newest checkpoint, if it has one."""
    if args.auto_resume:    # the newest of the run's checkpoints, if it has one
        found = checkpoints_in(args.logdir / args.env / f"seed{args.seed}" / "checkpoints")
        args.resume = found[-1][1] if found else None
    if args.resume is not None:
        if args.resume.suffix == ".zip":
            raise SystemExit(f"--resume {args.resume}: an SB3 checkpoint continues with train_sb3.py; to go on "
                             "with train_ppo.py start a new run from it with --init-from")
        return read_lean(args.resume, "--resume", args), None
    if args.init_from is None:
        return None, None
    if args.init_from.suffix != ".zip":
        state = read_lean(args.init_from, "--init-from", args)
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


def flag_name(dest: str) -> str:
    """The command-line flag that sets ``dest`` (``adaptive_kl``: ``--target-kl``)."""
    names = {action.dest: action.option_strings[0] for action in build_parser()._actions if action.option_strings}
    return names.get(dest, "--" + dest.replace("_", "-"))


def saved_form(value: Any) -> Any:
    """``value`` as a checkpoint's config holds it (lists for tuples, text keys, a path as text)."""
    if isinstance(value, (tuple, list)):
        return [saved_form(v) for v in value]
    if isinstance(value, dict):
        return {str(k): saved_form(v) for k, v in value.items()}
    return str(value) if isinstance(value, Path) else value


def same_value(new: Any, saved: Any) -> bool:
    """Whether a flag's value is the one a checkpoint's config holds (4 and 4.0 alike, True and 1 not)."""
    new = saved_form(new)
    if isinstance(new, bool) or isinstance(saved, bool):
        return new is saved
    if isinstance(new, (int, float)) and isinstance(saved, (int, float)):
        return float(new) == float(saved)
    return new == saved


def shown(value: Any) -> str:
    """A setting as a flag takes it (``256,256``, ``1e-05``; None: ``not set``)."""
    if value is None:
        return "not set"
    if isinstance(value, (tuple, list)) and all(isinstance(v, int) for v in value):
        return ",".join(map(str, value))    # as --policy-hidden takes it
    return f"{value:g}" if isinstance(value, float) else str(value)


def flag_text(dest: str, value: Any) -> str:
    """The flag as given: ``--n-envs 8``, ``--update-bf16``, ``--no-disc-background``."""
    flag = flag_name(dest)
    if isinstance(value, bool):
        return flag if value else "--no-" + flag[2:]
    return f"{flag} {shown(value)}"


_NOT_SET = object()


def refuse_changes(args: argparse.Namespace, resume: dict, saved: TrainConfig) -> None:
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
                and not same_value(getattr(args, name), fields[field]):
            changes.append(f"{flag_text(name, getattr(args, name))} ({origin.get(name, '')}the run's: "
                           f"{shown(fields[field])})")
    wanted, keywords = run_env_kwargs(args), dict(args.env_kwarg)
    for key in [*keywords, *(["init"] if "init" in given and "init" not in keywords else [])]:
        old = saved.env_kwargs.get(key, _NOT_SET)
        if old is _NOT_SET or not same_value(wanted[key], old):
            flag = f"--env-kwarg {key}={wanted[key]!r}" if key in keywords else flag_text("init", wanted[key])
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


def lean_setup(args: argparse.Namespace, say) -> tuple[dict | None, dict | None, TrainConfig, dict, Any]:
    """``(resume_state, init_state, config, env_kwargs, reference windows)``: what the run reads from this
    machine's files before its worlds are built (``--resume`` / ``--init-from``, the reference motions)."""
    resume, init = lean_start(args)
    if resume is not None:    # the checkpoint's own settings; --timesteps more steps (as SB3's resume)
        config = TrainConfig.from_dict(resume["config"])
        refuse_changes(args, resume, config)
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
        taken = [f"{flag_text(name, getattr(config, name))} (the run's: {shown(getattr(saved, name))})"
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
        say(f"note: the lean trainer steps the batched env ({args.vec_env!r} is train_sb3.py's)", file=sys.stderr)
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


def take_resume(trainer: Trainer, args: argparse.Namespace, resume: dict) -> bool:
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


def take_init(trainer: Trainer, args: argparse.Namespace, init: dict) -> None:
    try:
        trainer.load_state(init, weights_only=True)
    except RunMismatch as err:
        if err.part == "discriminator":
            advice = ("pass --fresh-discriminator to train a new one (the style's inputs differ)"
                      if isinstance(err.saved, int) else "pass its --disc-hidden, or --fresh-discriminator to train "
                      "a new one")
        elif err.saved[1] != err.run[1] and (err.saved[0], err.saved[2]) == (err.run[0], err.run[2]):
            advice = f"pass --policy-hidden {shown(err.saved[1])}, the layers it was trained with"
        else:
            advice = "pass the --env and --env-kwarg it was trained with" + (
                f" and --policy-hidden {shown(err.saved[1])}" if err.saved[1] != err.run[1] else "")
        raise SystemExit(f"--init-from {args.init_from}: cannot take it into this run: {err}; {advice}") from None
    except (RuntimeError, ValueError, KeyError) as err:
        raise SystemExit(f"--init-from {args.init_from}: cannot take it into this run ({type(err).__name__}: "
                         f"{err})") from None
