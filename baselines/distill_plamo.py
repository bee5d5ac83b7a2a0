#!/usr/bin/env python
"""Distil PlaMo's per-locomotion specialists into one path follower (DAgger; issue #54, gate 2).

Each specialist (a crawl, a crouch-walk, a walk, a run policy, each an exported ``.npz`` or ``pretrained``)
follows paths of its own locomotion. The student, an actor of the ``--template`` run's shape and
observation normaliser (the shipped walker's run, say), drives PlaMo-v0 on the template run's paths (mixed
locomotions and terrains, its starts), and each state it visits is labelled by the specialist of the
locomotion the path asks for at that moment (the template's env keywords, its terrain and aids, with
paths of every locomotion) (``planning.locomotion.nearest_locomotion`` of the path's head
height and speed at the world's time; sprint goes to the run specialist). All share PlaMo-v0's observation,
so every teacher reads the student's observation as it is. The output is the template with the student's
actor in place of its own, for ``train_ppo.py --init-from OUT`` (PPO + AMP on mixed paths then).

    python baselines/distill_plamo.py --template checkpoints/PlaMo-v0/w1_checkpoint_5001216.pt \\
        --teacher crawl=crawl.npz --teacher crouch-walk=crouch.npz --teacher walk=pretrained \\
        --teacher run=run.npz --out runs/plamo_distilled.pt

The DAgger loop is ``stairenv.training.dagger``'s, shared with ``distill_walk.py`` and ``distill_crawl.py``.
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path

import numpy as np
import torch

from stairenv import pretrained
from stairenv.planning.locomotion import LOCOMOTIONS, get_locomotion, nearest_locomotion
from stairenv.policy_loading import load_policy
from stairenv.training.dagger import Student, add_arguments, distil, read_template
from stairenv.training.ppo import make_env

#: the specialist a locomotion without its own is taught by
FALLBACK = {"sprint": "run"}


def path_locomotion(env) -> str:
    """The locomotion the world's path asks for now: its head height and speed at the episode's time."""
    i = env.path.index(env._steps * env.dt)
    return nearest_locomotion(float(env.path.head[i]), float(env.path.speed[i]))


def routed_teacher(worlds: list, teachers: dict) -> callable:
    """``teacher(obs)`` for a batch: row k labelled by the specialist of world k's path locomotion now."""
    def teacher(obs: np.ndarray) -> np.ndarray:
        kinds = [path_locomotion(env) for env in worlds]
        kinds = [kind if kind in teachers else FALLBACK.get(kind, kind) for kind in kinds]
        labels = np.empty((len(obs), worlds[0].action_space.shape[0]))
        for kind in set(kinds):
            rows = [k for k, other in enumerate(kinds) if other == kind]
            labels[rows] = np.asarray(teachers[kind](obs[rows]), dtype=np.float64).reshape(len(rows), -1)
        teacher.counts.update(kinds)
        return labels
    teacher.counts = Counter()
    return teacher


def teacher_argument(text: str) -> tuple[str, str]:
    kind, sep, spec = text.partition("=")
    if not sep or not spec:
        raise argparse.ArgumentTypeError(f"--teacher wants LOCOMOTION=POLICY, got {text!r}")
    try:
        return get_locomotion(kind.strip()).name, spec.strip()
    except (KeyError, ValueError) as error:
        raise argparse.ArgumentTypeError(f"--teacher {text!r}: {error}") from error


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--template", type=Path, required=True,
                        help="a lean checkpoint of a PlaMo-v0 run: the student's shape, normaliser, paths and starts")
    parser.add_argument("--teacher", type=teacher_argument, action="append", required=True,
                        metavar="LOCOMOTION=POLICY", help="a specialist (.npz or pretrained), repeatable")
    add_arguments(parser)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    template, config = read_template(args.template)
    if config.env_id != "PlaMo-v0":
        print(f"--template: a PlaMo-v0 run's checkpoint is needed, this one is {config.env_id}'s", file=sys.stderr)
        return 2
    specs = dict(args.teacher)
    missing = [name for name in LOCOMOTIONS if name not in specs and FALLBACK.get(name) not in specs]
    if missing:
        parser.error(f"no --teacher for {missing} (sprint falls back to run)")
    # every locomotion's paths (a template run of one locomotion's, W1's walk, would teach only its own)
    env_kwargs = {**config.env_kwargs, "locomotion": None}
    config = config.replace(env_kwargs=env_kwargs, num_envs=args.n_envs, physics_threads=args.physics_threads,
                            seed=args.seed)
    venv = make_env(config)
    worlds = [env.unwrapped for env in venv.envs]
    teachers = {kind: pretrained.load(config.env_id) if spec == "pretrained" else load_policy(spec, worlds[0])
                for kind, spec in specs.items()}
    torch.manual_seed(args.seed)
    student = Student(template, config, venv.single_observation_space.shape[0], venv.single_action_space.shape[0],
                      args.n_envs, args.learning_rate)
    obs, _ = venv.reset(seed=args.seed)
    teacher = routed_teacher(worlds, teachers)
    ended = Counter()

    def after_step(obs: np.ndarray, done: np.ndarray, infos: list) -> None:
        for i in np.flatnonzero(done):
            ended["episodes"] += 1
            ended["fell"] += bool(infos[i].get("fell"))
            ended["off_path"] += bool(infos[i].get("off_path"))

    def after_iteration(iteration: int, beta: float, samples: int, loss: float, seconds: float) -> None:
        shares = ", ".join(f"{kind} {n / max(sum(teacher.counts.values()), 1):.0%}"
                           for kind, n in sorted(teacher.counts.items()))
        print(f"iteration {iteration}: teacher share {beta:.2f}, {samples:,} samples ({shares}), episodes ended "
              f"{ended['episodes']} (fell {ended['fell']}, off the path {ended['off_path']}), fit loss {loss:.4f}, "
              f"{seconds:.0f} s", flush=True)
        teacher.counts.clear()
        ended.clear()

    distil(venv, obs, student, teacher, args, after_step, after_iteration)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
