#!/usr/bin/env python
"""Filmstrips of a path-following policy on ``PlaMo-v0``: one strip per locomotion (crawl,
crouch-walk, walk, run), so that one can see whether it crawls on all fours, crouch-walks with a
low head, walks, and runs with a flight phase.

For each locomotion one episode runs from the same seed on a path restricted to it (env keyword
``locomotion``) at one head height and speed (``constant_paths``, the Table 2 protocol) on one terrain (``--terrain``, flat by default). Frames are rendered during the
episode by the env's follow camera (every ``--every`` steps, the path ahead drawn in green) and
``--frames`` of them, spread evenly, make the strip. Each strip is captioned with the locomotion, how
the episode ended (fell, lost the path, time limit) and its mean XY / Z head error.

The policy is given as to ``baselines/evaluate.py``: ``zero``, ``random``, an exported ``.npz``
(the lean trainer's ``final_policy.npz``), a Stable-Baselines3 ``.zip``, or ``pretrained``.

Examples::

    python baselines/filmstrip_tracking.py --policy runs/PlaMo-v0/seed0/final_policy.npz
    python baselines/filmstrip_tracking.py --policy zero --terrain stairs --combined docs/plamo_zero.png
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")  # before mujoco is imported

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402

import stairenv  # noqa: E402,F401  (registers the envs)

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the strip layout is filmstrip_climb's, beside us
from filmstrip_climb import (add_follow_camera_options, film_follow_camera, follow_camera_strip,  # noqa: E402
                             write_combined)
from stairenv.evaluation.plamo import LOCOMOTIONS, TERRAINS, TRACKING_TERRAIN_SIZE  # noqa: E402
from stairenv.policy_loading import load_policy  # noqa: E402


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--policy", required=True, help="zero, random, pretrained, a .npz or an SB3 .zip")
    parser.add_argument("--env", default="PlaMo-v0", help="env id (default: %(default)s)")
    parser.add_argument("--terrain", default="flat", choices=TERRAINS, help="(default: %(default)s)")
    parser.add_argument("--locomotions", nargs="+", default=list(LOCOMOTIONS), choices=LOCOMOTIONS)
    parser.add_argument("--seed", type=int, default=0, help="the episodes' reset seed (default: %(default)s)")
    add_follow_camera_options(parser, every=3, distance=3.0, elevation=-12.0, combined="filmstrips/plamo_tracking.png")
    return parser


def caption_tail(infos: list[dict], dt: float) -> str:
    """How the episode ended, when, and its mean XY / Z head error."""
    last = infos[-1]
    stable = [info for info in infos if not info["physics_unstable"]]
    ending = ("physics unstable" if last["physics_unstable"] else "fell" if last.get("fell")
              else "lost the path" if last.get("off_path") else "time limit")
    return (f"{ending} at {len(infos) * dt:.1f} s, XY {np.mean([i['xy_error'] for i in stable]):.2f} m, "
            f"Z {np.mean([i['z_error'] for i in stable]):.2f} m")


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.frames < 1 or args.every < 1:
        print("need --frames >= 1 and --every >= 1", file=sys.stderr)
        return 2
    strips = []
    for locomotion in args.locomotions:
        env = gym.make(args.env, terrain=args.terrain, locomotion=locomotion, constant_paths=True,
                       terrain_size=TRACKING_TERRAIN_SIZE,
                       render_mode="rgb_array", width=args.width, height=args.height)
        env.unwrapped.set_camera(args.elevation, args.distance)
        policy = load_policy(args.policy, env, seed=args.seed)
        images, times, infos = film_follow_camera(env, policy, args.seed, args.every)
        tail = caption_tail(infos, env.unwrapped.dt)
        env.close()
        strips.append(follow_camera_strip(images, times, args.frames, f"{locomotion} on {args.terrain}: {tail}"))
        print(f"{locomotion}: {tail}")
    write_combined(strips, args.combined, args.combined_width, args.combined_max_kb)
    return 0


if __name__ == "__main__":
    sys.exit(main())
