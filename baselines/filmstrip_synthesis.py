#!/usr/bin/env python
"""Render a filmstrip of a synthesised stair climb (or styled walk): evenly spaced frames side by side (PNG).

Kinematic playback: each frame's ``qpos`` is written into a model holding our humanoid
and the clip's staircase (``StairsSlots``), ``mj_forward`` places the bodies, and an
offscreen ``mujoco.Renderer`` (``MUJOCO_GL=egl`` unless set) draws it from the side, the
camera following the pelvis. Nothing is simulated: what you see is the reference motion.

Examples::

    python baselines/filmstrip_synthesis.py --out filmstrip.png
    python baselines/filmstrip_synthesis.py --step-height 0.20 --step-depth 0.28 --direction down
    python baselines/filmstrip_synthesis.py --frames 12 --columns 6 --out climb.png
    python baselines/filmstrip_synthesis.py --walk-style tired --out tired.png   # a SIMS style, on flat ground
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")  # before mujoco is imported

import imageio.v3 as iio  # noqa: E402
import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from stairenv.humanoid import load_humanoid_spec  # noqa: E402
from stairenv.motion.synthesis import WALK_STYLES, climb_stairs, styled_walk  # noqa: E402
from stairenv.world.stairs import Staircase, StairsSlots  # noqa: E402


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description="Filmstrip (PNG) of a synthesised stair climb, seen from the side.")
    parser.add_argument("--out", type=Path, default=Path("filmstrip.png"), help="PNG to write (default: %(default)s)")
    parser.add_argument("--step-height", type=float, default=0.15, help="m (default: %(default)s)")
    parser.add_argument("--step-depth", type=float, default=0.30, help="m (default: %(default)s)")
    parser.add_argument("--num-steps", type=int, default=5, help="risers, the landing's included (default: %(default)s)")
    parser.add_argument("--direction", choices=("up", "down"), default="up")
    parser.add_argument("--walk-style", choices=sorted(WALK_STYLES), default=None,
                        help="show a walk in this SIMS style on flat ground instead of a climb")
    parser.add_argument("--lead-foot", choices=("right", "left"), default="right")
    parser.add_argument("--frames", type=int, default=8, help="frames in the strip (default: %(default)s)")
    parser.add_argument("--columns", type=int, default=None, help="frames per row (default: all in one row)")
    parser.add_argument("--first", type=float, default=0.0,
                        help="start of the shown part, as a share of the clip (default: %(default)s)")
    parser.add_argument("--last", type=float, default=1.0,
                        help="end of the shown part, as a share of the clip (default: %(default)s)")
    parser.add_argument("--width", type=int, default=300, help="pixels per frame (default: %(default)s)")
    parser.add_argument("--height", type=int, default=420, help="pixels per frame (default: %(default)s)")
    parser.add_argument("--distance", type=float, default=3.2, help="camera distance, m (default: %(default)s)")
    return parser


def render_filmstrip(args: argparse.Namespace) -> np.ndarray:
    """The strip as an (H, W, 3) uint8 image."""
    if args.walk_style is not None:
        clip = styled_walk(args.walk_style, duration=2.0, lead_foot=args.lead_foot)
        # no stairs in a walk: park the staircase far behind the camera
        stairs = Staircase(step_height=args.step_height, step_depth=args.step_depth, width=2.0,
                           num_steps=args.num_steps, landing_depth=1.0, yaw=0.0, distance=-100.0)
    else:
        clip = climb_stairs(args.step_height, args.step_depth, args.num_steps, direction=args.direction,
                            lead_foot=args.lead_foot)
        stairs = Staircase(**clip.meta["stairs"])
    spec = load_humanoid_spec()
    slots = StairsSlots(spec, max_steps=stairs.num_steps)
    spec.visual.global_.offwidth = max(spec.visual.global_.offwidth, args.width)
    spec.visual.global_.offheight = max(spec.visual.global_.offheight, args.height)
    model = spec.compile()
    slots.bind(model)
    slots.place(model, stairs)
    data = mujoco.MjData(model)

    camera = mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_FREE
    camera.azimuth = 90.0     # looking along +y: the ascent (+x) runs left to right
    camera.elevation = -8.0
    camera.distance = args.distance

    options = mujoco.MjvOption()
    options.geomgroup[2] = 0  # hide the stairs markers

    first = int(round(args.first * (clip.num_frames - 1)))
    last = int(round(args.last * (clip.num_frames - 1)))
    frame_ids = np.linspace(first, last, args.frames).round().astype(int)
    columns = args.columns or args.frames
    rows = math.ceil(args.frames / columns)
    gap = 4
    strip = np.full((rows * (args.height + gap) - gap, columns * (args.width + gap) - gap, 3), 255, np.uint8)
    root = model.joint("root").qposadr[0]
    with mujoco.Renderer(model, height=args.height, width=args.width) as renderer:
        for i, frame in enumerate(frame_ids):
            data.qpos[root:root + clip.qpos.shape[1]] = clip.qpos[frame]
            mujoco.mj_forward(model, data)
            pelvis = clip.qpos[frame, :3]
            camera.lookat[:] = (pelvis[0], 0.0, pelvis[2] - 0.25)
            renderer.update_scene(data, camera=camera, scene_option=options)
            image = renderer.render()
            r, c = divmod(i, columns)
            top, left = r * (args.height + gap), c * (args.width + gap)
            strip[top:top + args.height, left:left + args.width] = image
    return strip


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.frames < 1 or not 0.0 <= args.first <= args.last <= 1.0:
        print("need --frames >= 1 and 0 <= --first <= --last <= 1", file=sys.stderr)
        return 2
    strip = render_filmstrip(args)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    iio.imwrite(args.out, strip)
    print(f"wrote {args.out} ({strip.shape[1]}x{strip.shape[0]})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
