#!/usr/bin/env python
"""Filmstrips of a SIMS skill policy (``SIMS-Sit-v0``, ``-Lie-``, ``-Reach-``, ``-Walk-``, ``-GetUp-``):
one strip per seed, so that one can see whether the character walks to the piece and sits down onto the
seat, lies with the head on the pillow, reaches while standing balanced, gets up in a plausible order.

Each strip is one episode from its seed, rendered by the env's follow camera every ``--every`` steps;
``--frames`` of the frames, spread evenly, make the strip. Its caption names the skill, the piece of
furniture, how the episode ended (success, fell, time limit, or an aid's grounded or stalled) and the
contact error at the end.

The env is the registered id with the evaluation's settings (no training aids) unless ``--env-kwarg``
adds some, e.g. the front curriculum's starts at a level (``--env-kwarg start_from_front=True
--env-kwarg start_distance_levels=10 --level 0``).

Examples::

    python baselines/filmstrip_sims.py --policy runs/SIMS-Sit-v0/seed0/final_policy.npz
    python baselines/filmstrip_sims.py --env SIMS-Walk-v0 --policy runs/SIMS-Walk-v0/seed0/final_policy.npz --seeds 0 1
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")  # before mujoco is imported

import gymnasium as gym  # noqa: E402

import stairenv  # noqa: E402,F401  (registers the envs)

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the strip layout is filmstrip_climb's, beside us
from filmstrip_climb import (add_follow_camera_options, film_follow_camera, follow_camera_strip,  # noqa: E402
                             write_combined)
from stairenv.evaluation.cli import env_kwarg_argument  # noqa: E402
from stairenv.policy_loading import load_policy  # noqa: E402
from stairenv.pretrained import with_trained_captions  # noqa: E402


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--policy", required=True, help="zero, random, pretrained, a .npz or an SB3 .zip")
    parser.add_argument("--env", default="SIMS-Sit-v0", help="a SIMS skill id (default: %(default)s)")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3], help="one strip each (default: 0 1 2 3)")
    parser.add_argument("--env-kwarg", action="append", default=[], type=env_kwarg_argument, metavar="KEY=VALUE",
                        help="extra env keyword, repeatable (e.g. a training aid)")
    parser.add_argument("--policy-captions", action="store_true",
                        help="draw the captions the policy recorded from its training instead of the env's")
    parser.add_argument("--level", type=int, default=None,
                        help="with start_distance_levels: the curriculum level every episode starts at")
    add_follow_camera_options(parser, every=5, distance=3.5, elevation=-20.0, combined="filmstrips/sims.png")
    return parser


def ending_of(info: dict) -> str:
    """How an episode ended, from its last ``info``; the training aids' endings (grounded, stalled) are
    named too, since a filmstrip of an aid's run must not call them a time limit."""
    for key, name in (("physics_unstable", "physics unstable"), ("fell", "fell"), ("grounded", "grounded"),
                      ("stalled", "stalled"), ("success", "succeeded")):
        if info.get(key):
            return name
    return "time limit"


def caption_tail(env: gym.Env, infos: list[dict]) -> str:
    """The piece, how the episode ended and when, the contact error at the end, the first success."""
    target = getattr(env.unwrapped, "_target", None)
    dt, last = env.unwrapped.dt, infos[-1]
    ending = ending_of(last)
    first = next((k for k, info in enumerate(infos) if info.get("success")), None)
    reached = "" if first is None else f", first within reach at {(first + 1) * dt:.1f} s"
    return (f"{'floor' if target is None else target.family}: {ending} at {len(infos) * dt:.1f} s, contact error "
            f"{last.get('contact_error', float('nan')):.2f} m{reached}")


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.frames < 1 or args.every < 1:
        print("need --frames >= 1 and --every >= 1", file=sys.stderr)
        return 2
    kwargs = dict(args.env_kwarg)
    if args.level is not None and not kwargs.get("start_distance_levels"):
        print("--level needs --env-kwarg start_distance_levels=N", file=sys.stderr)
        return 2
    strips = []
    for seed in args.seeds:
        env = gym.make(args.env, render_mode="rgb_array", width=args.width, height=args.height, **kwargs)
        env.unwrapped.set_camera(args.elevation, args.distance)
        policy = load_policy(args.policy, env, seed=seed)
        filmed_kwargs = with_trained_captions(kwargs, policy) if args.policy_captions else kwargs
        if filmed_kwargs is not kwargs:
            env.close()   # again, drawing the captions the policy trained on
            env = gym.make(args.env, render_mode="rgb_array", width=args.width, height=args.height, **filmed_kwargs)
            env.unwrapped.set_camera(args.elevation, args.distance)
        if args.level is not None:
            env.unwrapped.curriculum_level = args.level   # before the first reset, which keeps a set level
        images, times, infos = film_follow_camera(env, policy, seed, args.every)
        tail = caption_tail(env, infos)
        env.close()
        strips.append(follow_camera_strip(images, times, args.frames, f"{args.env} seed {seed}, {tail}"))
        print(f"seed {seed}: {tail}")
    write_combined(strips, args.combined, args.combined_width, args.combined_max_kb)
    return 0


if __name__ == "__main__":
    sys.exit(main())
