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
from filmstrip_climb import filmstrip, frame_indices, write_combined  # noqa: E402
from stairenv.evaluation.plamo import LOCOMOTIONS, TERRAINS, TRACKING_TERRAIN_SIZE  # noqa: E402
from stairenv.policy_loading import load_policy  # noqa: E402


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--policy", required=True, help="zero, random, pretrained, a .npz or an SB3 .zip")
    parser.add_argument("--env", default="PlaMo-v0", help="env id (default: %(default)s)")
    parser.add_argument("--terrain", default="flat", choices=TERRAINS, help="(default: %(default)s)")
    parser.add_argument("--locomotions", nargs="+", default=list(LOCOMOTIONS), choices=LOCOMOTIONS)
    parser.add_argument("--seed", type=int, default=0, help="the episodes' reset seed (default: %(default)s)")
    parser.add_argument("--frames", type=int, default=8, help="frames per strip (default: %(default)s)")
    parser.add_argument("--every", type=int, default=3, help="render every this many steps (default: %(default)s)")
    parser.add_argument("--width", type=int, default=240, help="pixels per frame (default: %(default)s)")
    parser.add_argument("--height", type=int, default=240, help="pixels per frame (default: %(default)s)")
    parser.add_argument("--distance", type=float, default=3.0, help="camera distance, m (default: %(default)s)")
    parser.add_argument("--elevation", type=float, default=-12.0, help="camera elevation, deg (default: %(default)s)")
    parser.add_argument("--combined", type=Path, default=Path("filmstrips/plamo_tracking.png"),
                        help="the combined PNG (default: %(default)s)")
    parser.add_argument("--combined-width", type=int, default=1200, help="(default: %(default)s)")
    parser.add_argument("--combined-max-kb", type=float, default=400.0, help="(default: %(default)s)")
    return parser


def film_episode(env: gym.Env, policy, seed: int, every: int) -> tuple[list[np.ndarray], list[float], str]:
    """One episode: frames every ``every`` steps (and the last), their times, and a caption tail."""
    base = env.unwrapped
    if callable(getattr(policy, "reset", None)):
        policy.reset(seed)
    obs, _ = env.reset(seed=seed)
    images, times, xy, z = [env.render()], [0.0], [], []
    steps = 0
    while True:
        obs, _, terminated, truncated, info = env.step(np.asarray(policy(obs)))
        steps += 1
        if not info["physics_unstable"]:
            xy.append(info["xy_error"])
            z.append(info["z_error"])
        ended = terminated or truncated
        if steps % every == 0 or ended:
            images.append(env.render())
            times.append(steps * base.dt)
        if ended:
            break
    ending = ("physics unstable" if info["physics_unstable"] else "fell" if info.get("fell")
              else "lost the path" if info.get("off_path") else "time limit")
    return images, times, f"{ending} at {steps * base.dt:.1f} s, XY {np.mean(xy):.2f} m, Z {np.mean(z):.2f} m"


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
        images, times, tail = film_episode(env, policy, args.seed, args.every)
        env.close()
        keep = frame_indices(len(images), args.frames)
        strips.append(filmstrip([images[k] for k in keep], [times[k] for k in keep],
                                f"{locomotion} on {args.terrain}: {tail}"))
        print(f"{locomotion}: {tail}")
    write_combined(strips, args.combined, args.combined_width, args.combined_max_kb)
    return 0


if __name__ == "__main__":
    sys.exit(main())
