#!/usr/bin/env python
"""Distil the crawl clips, played back open-loop through the PD servos, into a PlaMo-v0 actor (DAgger).

``docs/plamo_training.md`` (2026-11-29): played back (each step's PD targets = the clip's joint angles
one step ahead), the DeepMimic crawl crawls on flat ground for 10 s in most starts, yet the PlaMo
policies started in a crawl frame leave that pose within 0.15 s and never find it again under PPO's
noise. So the playback is the teacher: each world starts in a crawl frame (``init="reference"``,
``locomotion="crawl"``), its label is the playback's action for its own clip and time (``_reference_clip``
and the episode's time), and the student, an actor of the ``--template`` run's shape and observation
normaliser, is fitted to the labels of the states it visits (Ross et al. 2011). The teacher ignores the
path; PPO (``train_ppo.py --init-from OUT``) then has to steer the crawl along it.

    python baselines/distill_crawl.py --template /work/runs/p18_16m_std2.pt --out runs/crawl_distilled.pt

Any locomotion's clips are played back alike (``--locomotion``, ``--reference``: a folder of clips labelled
with it), e.g. the crouch-walks at three depths for the crouch-walk specialist:

    python baselines/distill_crawl.py --template checkpoints/PlaMo-v0/w1_checkpoint_5001216.pt \
        --locomotion crouch-walk --reference src/stairenv/motion/data/crouch --flat --out runs/crouch_distilled.pt

The DAgger loop is ``stairenv.training.dagger``'s, shared with ``distill_walk.py``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import torch

from stairenv.training.dagger import Student, add_arguments, distil, read_template
from stairenv.training.ppo import make_env

#: the crawl-only env: every path a crawl, every start a crawl frame, the paths at the paper's speeds
CRAWL_KWARGS = {"locomotion": "crawl", "init": "reference", "matched_starts": True, "speed_levels": 0}


def playback_action(env) -> np.ndarray:
    """The action whose PD targets are the world's start clip one step ahead (``_apply_action`` inverted)."""
    clip, start_time = env._reference_clip
    return env.action_of_targets(clip.sample(start_time + (env._steps + 1) * env.dt)[0, 7:])


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--template", type=Path, required=True,
                        help="a lean checkpoint of a PlaMo-v0 run: the student's shape, normaliser and the rest")
    parser.add_argument("--locomotion", default="crawl",
                        help="the locomotion whose paths and clips (of --reference) are played back (default: crawl)")
    parser.add_argument("--reference", default=None,
                        help="a folder or .npz of clips labelled with that locomotion (default: builtin:plamo's)")
    parser.add_argument("--flat", action="store_true",
                        help="flat ground and none of the template's height aids (min_root_height, max_z_error, "
                             "max_z_above): the specialists' training conditions")
    add_arguments(parser)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    template, config = read_template(args.template)
    if config.env_id != "PlaMo-v0":
        print(f"--template: a PlaMo-v0 run's checkpoint is needed, this one is {config.env_id}'s", file=sys.stderr)
        return 2
    playback = {**CRAWL_KWARGS, "locomotion": args.locomotion,
                **({} if args.reference is None else {"reference_motion": args.reference})}
    env_kwargs = {**config.env_kwargs, **playback}
    if args.flat:
        env_kwargs = {key: value for key, value in env_kwargs.items()
                      if key not in ("min_root_height", "max_z_error", "max_z_above")} | {"terrain": "flat"}
    config = config.replace(env_kwargs=env_kwargs, num_envs=args.n_envs,
                            physics_threads=args.physics_threads, seed=args.seed)
    venv = make_env(config)
    worlds = [env.unwrapped for env in venv.envs]
    torch.manual_seed(args.seed)
    student = Student(template, config, venv.single_observation_space.shape[0], venv.single_action_space.shape[0],
                      args.n_envs, args.learning_rate)
    obs, _ = venv.reset(seed=args.seed)
    root_heights, ended = [], {"episodes": 0, "fell": 0}

    def after_step(obs: np.ndarray, done: np.ndarray, infos: list) -> None:
        root_heights.append(np.mean(obs[:, 0]))
        ended["episodes"] += int(done.sum())
        ended["fell"] += sum(bool(infos[i].get("fell")) for i in np.flatnonzero(done))

    def after_iteration(iteration: int, beta: float, samples: int, loss: float, seconds: float) -> None:
        print(f"iteration {iteration}: teacher share {beta:.2f}, {samples:,} samples, episodes ended "
              f"{ended['episodes']} (fell {ended['fell']}), mean root height {np.mean(root_heights):.2f} m, "
              f"fit loss {loss:.4f}, {seconds:.0f} s", flush=True)
        root_heights.clear()
        ended.update(dict.fromkeys(ended, 0))

    distil(venv, obs, student, lambda obs: np.stack([playback_action(env) for env in worlds]), args, after_step,
           after_iteration)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
