#!/usr/bin/env python
"""Distil the shipped InterLevel climber into a SIMS-Walk-v0 policy (DAgger), as the start of a walk run.

The climber (``stairenv.pretrained.load("InterLevel-v0")``) walks to a marker on its feet without falling;
a SIMS-Walk policy trained from scratch spends millions of samples learning to stay up. Both drive the
same humanoid with the same 28 actions at 30 Hz, and their observations share the 113-D proprioception, so
the climber can teach the walk by imitation (Ross et al. 2011, DAgger): it sees a SIMS walk goal as a
staircase of no height (``climber_view``) and labels the states the student visits; the student, a
network of the SIMS-Walk run's own shape and observation normaliser, is fitted to the labels.

The output is the ``--template`` lean checkpoint (a SIMS-Walk run's: normaliser, value network,
optimiser, discriminator) with the student's actor in place of its own, for
``train_ppo.py --config baselines/recipes/sims_walk.toml --init-from OUT``: PPO + AMP then teach what the
climber cannot (stopping at the goal, the styles, the furniture the blind climber walks into).

    python baselines/distill_walk.py --template checkpoints/SIMS-Walk-v0/w4_checkpoint_2500608.pt \\
        --out runs/walk_distilled.pt

DAgger here: iteration 0 is the climber's own rollout; from then on each step's action is the
climber's with probability ``0.5 ** i`` (else the student's), with Gaussian noise (``--action-noise``)
so that the data covers small recoveries. Every visited state is labelled with the climber's action;
the student is fitted on all the data so far (mean squared error of its mean action).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import torch

from stairenv import pretrained
from stairenv.tasks.kernels import PROPRIOCEPTION_SIZE
from stairenv.tasks.interlevel import OBSERVATION_SIZE as CLIMBER_OBS_SIZE
from stairenv.tasks.interlevel import OBSERVATION_STRUCTURE as CLIMBER
from stairenv.training.dagger import Student, add_arguments, distil, read_template
from stairenv.training.ppo import make_env

#: the training aid that shortens goals at the curriculum's first levels: the data should cover 1-5 m
LEFT_OUT_AIDS = ("start_distance_levels",)


def walk_targets(obs: np.ndarray, structure: dict[str, slice]) -> np.ndarray:
    """(B, 3) each world's one goal target (heading frame, relative to the root) from its observation."""
    goals = obs[:, structure["goal_positions"]].reshape(len(obs), -1, 3)
    masks = obs[:, structure["goal_mask"]] > 0.5
    if (masks.sum(axis=1) != 1).any():
        raise ValueError("climber_view needs one target per world (a walk goal's pelvis target)")
    return goals[masks]


def ground_distance(obs: np.ndarray, structure: dict[str, slice]) -> np.ndarray:
    target = walk_targets(obs, structure)
    return np.hypot(target[:, 0], target[:, 1])


def climber_view(obs: np.ndarray, structure: dict[str, slice], start_distance: np.ndarray) -> np.ndarray:
    """(B, 118) the climber's observation of SIMS walk observations ``obs`` (B, size): the proprioception
    as it is (same layout), the walk target (a point at standing pelvis height, heading frame) as the top
    marker, ``start_distance`` (the target's distance when the episode began) as the marker distance, and
    the heading's angle to the target as the angle to the ascent direction (a flight of no height whose
    ascent points at the target)."""
    target = walk_targets(obs, structure)
    out = np.empty((len(obs), CLIMBER_OBS_SIZE))
    out[:, :PROPRIOCEPTION_SIZE] = obs[:, :PROPRIOCEPTION_SIZE]
    out[:, CLIMBER["target_offset"]] = target
    out[:, CLIMBER["marker_distance"]] = start_distance[:, None]
    out[:, CLIMBER["stairs_angle"]] = -np.arctan2(target[:, 1], target[:, 0])[:, None]
    return out


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--template", type=Path, required=True,
                        help="a lean checkpoint of a SIMS-Walk-v0 run: the student's shape, normaliser and the rest")
    add_arguments(parser, steps=300, epochs=4, physics_threads=1)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    template, config = read_template(args.template)
    if config.env_id != "SIMS-Walk-v0":
        print(f"--template: a SIMS-Walk-v0 run's checkpoint is needed, this one is {config.env_id}'s", file=sys.stderr)
        return 2
    kwargs = {k: v for k, v in config.env_kwargs.items() if k not in LEFT_OUT_AIDS}
    config = config.replace(env_kwargs=kwargs, num_envs=args.n_envs, physics_threads=args.physics_threads,
                            seed=args.seed)
    teacher = pretrained.load("InterLevel-v0")
    venv = make_env(config)
    structure = venv.envs[0].unwrapped.observation_structure
    torch.manual_seed(args.seed)
    student = Student(template, config, venv.single_observation_space.shape[0], venv.single_action_space.shape[0],
                      args.n_envs, args.learning_rate)
    obs, _ = venv.reset(seed=args.seed)
    start = ground_distance(obs, structure)    # each world's goal distance when its episode began
    ended = {"episodes": 0, "success": 0, "fell": 0, "grounded": 0}

    def label(obs: np.ndarray) -> np.ndarray:
        return np.clip(teacher(climber_view(obs, structure, start)), -1.0, 1.0)

    def after_step(obs: np.ndarray, done: np.ndarray, infos: list) -> None:
        nonlocal start
        if done.any():
            infos = [infos[i] for i in np.flatnonzero(done)]
            ended["episodes"] += len(infos)
            for key in ("success", "fell", "grounded"):
                ended[key] += sum(bool(info.get(key)) for info in infos)
            start = np.where(done, ground_distance(obs, structure), start)

    def after_iteration(iteration: int, beta: float, samples: int, loss: float, seconds: float) -> None:
        print(f"iteration {iteration}: teacher share {beta:.2f}, {samples:,} samples, episodes ended "
              f"{ended['episodes']} (success {ended['success']}, fell {ended['fell']}, grounded {ended['grounded']}), "
              f"fit loss {loss:.4f}, {seconds:.0f} s", flush=True)
        ended.update(dict.fromkeys(ended, 0))

    distil(venv, obs, student, label, args, after_step, after_iteration)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
