"""Train Stable-Baselines3 PPO (+ AMP) on a stairenv env: the same envs and flags as ``train_ppo.py``.

    python baselines/train_sb3.py --env InterLevel-v0 --timesteps 2e6
    python baselines/train_sb3.py --config baselines/recipes/interlevel_climb.toml --vec-env dummy
    python baselines/train_sb3.py --resume runs/InterLevel-v0/seed0/checkpoints/ppo_1000000_steps.zip

SB3's ``PPO`` with ``VecNormalize`` and the AMP wrapper (``stairenv.style.wrappers.AMPVecEnvWrapper``) over
the natively batched env (``--vec-env batched``, ``stairenv.vec_sb3``) or Gymnasium envs stepped one after
another (``dummy``) or in processes (``subproc``). The flags, presets and ``--config`` recipes are
``train_ppo.py``'s (``stairenv.training.cli``; ``--help`` lists them); the lean trainer's own (``--auto-resume``,
``--reset-std``, torchrun) are not taken here.

Writes to ``--logdir/<env>/seed<k>/``: TensorBoard logs (PPO and ``amp/*``), checkpoints every
``--checkpoint-every`` steps (default 100,000: the model with its optimiser ``ppo_<n>_steps.zip``, the
VecNormalize statistics ``ppo_vecnormalize_<n>_steps.pkl``, the AMP state ``amp_<n>_steps.pt`` and, with a
curriculum, ``curriculum_<n>_steps.json``), ``final_model.zip`` + ``vecnormalize.pkl`` + ``amp.pt`` and the
evaluation (``evaluation.csv`` / ``.json``). ``baselines/export_policy.py`` turns the model into the numpy
policy ``stairenv.pretrained`` loads.

``--resume`` needs the checkpoint's VecNormalize statistics and, with AMP, its AMP state (without it the run
stops unless ``--fresh-discriminator`` asks for a new one); a PPO, network or style flag given that would
change the checkpoint's settings stops it, naming each. The model .zip and statistics .pkl are pickles (SB3's
formats): resume only from files you trust. The AMP state is read without running code from it.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import os
import sys
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback, CallbackList, CheckpointCallback
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecMonitor, VecNormalize

from stairenv.evaluation import evaluator_for
from stairenv.evaluation.policies import load_policy, read_normalizer
from stairenv.evaluation.report import write_reports
from stairenv.style.wrappers import AMPStyleReward, AMPVecEnvWrapper
from stairenv.tasks import curriculum
from stairenv.training.cli import (PPO_FLAGS, cpu_line, discriminator_config, evaluation_kwargs, flag_text,
                                   parse_args, reference_windows, run_env_kwargs, same_value, shown)
from stairenv.training.sb3 import (AdaptiveLearningRate, AMPCallback, CurriculumCallback, EpisodeStatsCallback,
                                   check_same_spaces, checkpoint_file, curriculum_state_beside, load_checkpoint,
                                   required_amp_state, restore_curriculum, resumed_style, run_env,
                                   statistics_beside)
from stairenv.vec_sb3 import make_sb3_vec_env

_SB3_STYLE = {"w_task": "w_task", "w_style": "w_style", "disc_update_interval": "update_interval",
              "disc_updates": "updates_per_round", "disc_hidden": "config.hidden", "disc_loss": "config.loss",
              "disc_lr": "config.learning_rate", "disc_grad_penalty": "config.grad_penalty",
              "disc_grad_penalty_batch": "config.grad_penalty_batch", "disc_weight_decay": "config.weight_decay",
              "disc_logit_reg": "config.logit_reg", "disc_input_noise": "config.input_noise",
              "disc_batch_size": "config.batch_size", "disc_replay_size": "config.replay_size"}


def refuse_sb3_changes(args: argparse.Namespace, checkpoint: Path, model, style) -> None:
    """``--resume``: ``SystemExit`` naming each PPO or network flag given (and, with the AMP state
    resumed, each style flag) whose value differs from the one the checkpoint goes on with (SB3 keeps its own).
    The env's flags (``--env``, ``--n-envs``, ``--seed``, ``--env-kwarg``) build this run's envs: taken; with
    ``--target-kl`` the rate adapts from the checkpoint's."""
    arch = model.policy_kwargs.get("net_arch")
    saved = {flag: getattr(model, keyword) for flag, keyword in PPO_FLAGS.items()}
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
    changes = [f"{flag_text(name, getattr(args, name))} (the checkpoint's: {shown(value)})"
               for name, value in saved.items() if name in getattr(args, "given", ())
               and not same_value(getattr(args, name), value)]
    if changes:
        raise SystemExit(f"--resume {checkpoint}: SB3 goes on with the checkpoint's own settings, and these given "
                         f"would change them: {'; '.join(changes)}. Leave them out to go on exactly, or start a new "
                         "run from the checkpoint with these settings with --init-from (its step count from 0)")


def main(argv: list[str] | None = None) -> Path:
    args = parse_args(argv, trainer="sb3", description=__doc__)
    if "WORLD_SIZE" in os.environ and int(os.environ["WORLD_SIZE"]) > 1:
        raise SystemExit("train_sb3.py trains in one process; data-parallel training (torchrun) is train_ppo.py's")
    if args.state_on_device and (args.vec_env != "batched" or args.physics != "warp"):
        raise SystemExit("--state-on-device needs --physics warp and --vec-env batched")
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
    ppo_kwargs = {keyword: getattr(args, flag) for flag, keyword in PPO_FLAGS.items()}
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
        refuse_sb3_changes(args, checkpoint, model, style if amp_state is not None else None)
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
            taken = ", discriminator" if amp_state else ""
            print(f"initialised from {checkpoint} (weights, optimiser, statistics{taken})")

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
    trained = model.num_timesteps - (0 if args.resume is None else start_steps)
    seconds = time.perf_counter() - start_time
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
