"""Train PPO + AMP on a stairenv env with the lean trainer (``stairenv.training``).

    python baselines/train_ppo.py                         # InterLevel-v0, PPO + AMP, the CPU settings
    python baselines/train_ppo.py --preset paper          # the InterLevel paper's settings
    python baselines/train_ppo.py --env InterLevel2D-v0   # the 2-D ablation
    python baselines/train_ppo.py --env InterSceneStairs-v0 --style none   # task reward only
    python baselines/train_ppo.py --env-kwarg target_speed=0.8 --timesteps 5e6
    python baselines/train_ppo.py --config baselines/recipes/interlevel_climb.toml   # any flags below as keys
    python baselines/train_ppo.py --resume runs/InterLevel-v0/seed0/checkpoints/checkpoint_1000448.pt
    python baselines/train_ppo.py --auto-resume --config ...   # go on from the run's newest checkpoint, or start it
    python baselines/train_ppo.py --init-from .../checkpoint_1000448.pt --learning-rate 3e-5  # new run, trained weights
    python baselines/train_ppo.py --init-from checkpoints/InterLevel-v0/ppo_3200000_steps.zip   # from an SB3 run
    python baselines/train_ppo.py --env SIMS-Sit-v0 --amp-text-condition   # SIMS: discriminator sees the caption
    torchrun --nproc-per-node 2 baselines/train_ppo.py --n-envs 64 ...   # data-parallel: 2 ranks x 64 worlds

Stable-Baselines3 PPO over the same envs and flags is ``baselines/train_sb3.py``.

The run is one ``TrainConfig`` (``stairenv.training.config``: every setting, its default and its meaning,
which ``--help`` shows), built from the flags, a ``--config`` TOML recipe and a ``--preset``, in that order of
precedence (``stairenv.training.cli``). The loop is ``stairenv.training.ppo.Trainer.learn``: PPO + AMP on the
natively batched env's arrays. Every checkpoint (``checkpoint_<n>.pt``, read without running code) holds the
whole config, policy, optimiser, normalisers, discriminator, curriculum levels, step counter and generators,
with ``replay_<n>.npy`` beside the latest; the last step is always a checkpoint.

``--resume`` continues exactly: the checkpoint's own settings and step count; a flag, ``--config`` key or
``--preset`` value given that would change them stops it, naming each (the same values go on); this
machine's ``--physics``, ``--physics-threads``, ``--device``, ``--state-on-device``, ``--torch-threads`` and
``--update-threads`` are taken, and said. ``--init-from`` starts a new run (steps from 0, this run's flags)
on a checkpoint's weights, optimiser, statistics and discriminator (``--reset-std``: the action noise at
``--log-std-init`` again; ``--fresh-discriminator``: a new discriminator). Every checkpoint is checked as it is
read, each fault naming the file and the entry.

Presets: ``cpu`` (the defaults: the fastest settings measured to still learn on a 2-core CPU, 128 worlds,
[256, 256] networks, 16-step rollouts, minibatch 1024, AMP with instance noise 1.0, reward 0.5 task + 0.5
style, half the episodes from reference states), ``paper`` (learning rate 2e-5, [1024, 512], minibatch 64,
256-step rollouts, std 1, the paper's discriminator), ``style-short`` (the earlier short CPU runs'). The
runs behind them are in ``docs/reproducing.md``.

Under ``torchrun`` the run is data-parallel (``stairenv.training.distributed``): each rank its own
``--n-envs`` worlds (world j of rank r seeded as world ``r x n_envs + j``), gradients averaged, statistics
merged, ``--timesteps`` counting every rank's steps, rank 0 printing, logging, checkpointing and
evaluating; a rank that cannot start stops every rank with its reason. ``--device cuda`` puts the
networks, rollout and updates on the GPU; ``--physics warp`` (``--state-on-device``) the physics.

Writes to ``--logdir/<env>/seed<k>/``: ``log.jsonl`` (one line of scalars per iteration, with the wall and
CPU time of each phase per env step; ``episode/*`` and, for the episodes that started as the evaluation
does, ``episode_floor_start/*``; ``curriculum/level`` with a curriculum), TensorBoard logs, ``checkpoints/``,
``final_checkpoint.pt``, ``final_policy.npz`` (what ``stairenv.pretrained`` loads) and the evaluation
(``evaluation.csv`` / ``.json``, by the env family's evaluator, the training aids left out).
"""

from __future__ import annotations

import time
from pathlib import Path

import gymnasium as gym

from stairenv.evaluation import evaluator_for
from stairenv.evaluation.policies import load_policy
from stairenv.evaluation.report import write_reports
from stairenv.training import RunLog, Trainer, build_style
from stairenv.training.cli import (cpu_line, evaluation_kwargs, fill_climb_cache, lean_setup, parse_args, take_init,
                                   take_resume)
from stairenv.training.distributed import LOCAL, DataParallel


def train(args) -> Path:
    """One run of the lean trainer; under torchrun one data-parallel rank of it."""
    parallel = DataParallel.from_environment(args.device)
    try:
        return _train(args, parallel or LOCAL)
    finally:
        if parallel is not None:
            parallel.close()


def _train(args, parallel) -> Path:
    first = parallel.rank == 0    # rank 0 prints, logs, writes and evaluates

    def say(*words, **kwargs) -> None:
        if first:
            print(*words, **kwargs)

    # each rank reads its machine's files; one that cannot stops them all with its reason (parallel.agree)
    resume, init, config, env_kwargs, reference = parallel.agree(
        lambda: lean_setup(args, say), "Reading the run's files (--resume, --init-from, the reference motions)")
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
        replay = parallel.agree(lambda: take_resume(trainer, args, resume), "Resuming")
        note = "" if replay or trainer.style is None else " (no replay buffer beside it: it refills within a round)"
        if args.fresh_discriminator:
            note += "; a fresh discriminator (--fresh-discriminator)"
        saved_ranks = int(resume.get("world_size", 1))
        if saved_ranks != parallel.world_size:
            note += f" (written by {saved_ranks} ranks, going on with {parallel.world_size}: not exact)"
        say(f"resumed from {args.resume} at {trainer.steps} steps{note}")
    elif init is not None:
        parallel.agree(lambda: take_init(trainer, args, init), "Starting from --init-from")
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

    if args.eval_episodes > 0 and first:    # as the paper's protocol: standing starts, no training aids
        report = evaluator_for(config.env_id)(
            load_policy(str(policy_path), gym.make(config.env_id, **env_kwargs)), env_id=config.env_id,
            episodes=args.eval_episodes, seed=10_000 + config.seed, env_kwargs=evaluation_kwargs(env_kwargs),
            max_episode_steps=args.eval_max_episode_steps, progress_bar=not args.no_progress_bar,
            label=str(policy_path))
        print(report.format_table())
        write_reports([report], run_dir / "evaluation.csv", run_dir / "evaluation.json")
    return policy_path


def main(argv: list[str] | None = None) -> Path:
    return train(parse_args(argv, trainer="lean", description=__doc__))


if __name__ == "__main__":
    main()
