#!/usr/bin/env python
"""Render filmstrips of synthesised interaction clips (sit down, lie down, ...) with their furniture box (PNG).

Kinematic playback, as ``filmstrip_synthesis.py`` does for stairs: each frame's ``qpos`` is
written into a model holding our humanoid and the box the clip was made for
(``clip.meta["furniture"]``), ``mj_forward`` places the bodies, and an offscreen
``mujoco.Renderer`` (``MUJOCO_GL=egl`` unless set) draws it. Nothing is simulated: what you
see is the reference motion. One row per clip, evenly spaced frames side by side; the
camera stays still (centred on the clip's pelvis path), so the motion reads left to right.

Examples::

    python baselines/filmstrip_interactions.py --out interactions.png
    python baselines/filmstrip_interactions.py --clips sit_down stand_up --height 0.55
    python baselines/filmstrip_interactions.py --clips lie_down --frames 8 --azimuth 150
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")  # before mujoco is imported

import imageio.v3 as iio
import mujoco
import numpy as np

from stairenv.humanoid import load_humanoid_spec
from stairenv.motion import interactions
from stairenv.motion.clip import MotionClip

CLIPS = ("sit_down", "stand_up", "lie_down", "get_up_from_lying", "reach", "idle")
# Camera per clip kind: (azimuth, elevation) in degrees, distance in metres. Azimuth 90 looks
# along +y (x runs left to right).
VIEWS = {"sit_down": (90.0, -5.0, 2.6), "stand_up": (90.0, -5.0, 2.6), "lie_down": (150.0, -25.0, 3.2),
         "get_up_from_lying": (150.0, -25.0, 3.2), "reach": (60.0, -10.0, 2.6), "idle": (90.0, -5.0, 2.6)}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description="Filmstrip (PNG) of synthesised interaction clips with their furniture.")
    parser.add_argument("--out", type=Path, default=Path("filmstrip_interactions.png"),
                        help="PNG to write (default: %(default)s)")
    parser.add_argument("--clips", nargs="+", choices=CLIPS, default=["sit_down", "lie_down"],
                        help="one row per clip (default: %(default)s)")
    parser.add_argument("--height", type=float, default=None,
                        help="seat / surface height, m (default: the generator's)")
    parser.add_argument("--target", type=float, nargs=3, default=(0.45, -0.25, 1.1), metavar=("X", "Y", "Z"),
                        help="reach target, m (default: %(default)s)")
    parser.add_argument("--hand", choices=("right", "left"), default="right", help="reaching hand")
    parser.add_argument("--hands", choices=("thighs", "seat"), default="thighs",
                        help="where the hands rest when seated (default: %(default)s)")
    parser.add_argument("--frames", type=int, default=6, help="frames per row (default: %(default)s)")
    parser.add_argument("--width", type=int, default=300, help="pixels per frame (default: %(default)s)")
    parser.add_argument("--height-px", type=int, default=360, help="pixels per frame (default: %(default)s)")
    parser.add_argument("--distance", type=float, default=None, help="camera distance, m (default: per clip)")
    parser.add_argument("--azimuth", type=float, default=None, help="camera azimuth, deg (default: per clip)")
    parser.add_argument("--elevation", type=float, default=None, help="camera elevation, deg (default: per clip)")
    return parser


def make_clip(kind: str, args: argparse.Namespace) -> MotionClip:
    kwargs = {} if args.height is None else ({"surface_height": args.height} if "lying" in kind or kind == "lie_down"
                                             else {"seat_height": args.height})
    if kind == "reach":
        return interactions.reach(tuple(args.target), hand=args.hand)
    if kind == "idle":
        return interactions.idle()
    if kind in ("sit_down", "stand_up"):
        kwargs["hands"] = args.hands
    return getattr(interactions, kind)(**kwargs)


def scene_model(clip: MotionClip, width: int, height: int) -> mujoco.MjModel:
    """Our humanoid plus the clip's furniture box (if any)."""
    spec = load_humanoid_spec()
    spec.visual.global_.offwidth = max(spec.visual.global_.offwidth, width)
    spec.visual.global_.offheight = max(spec.visual.global_.offheight, height)
    box = clip.meta.get("furniture")
    if box is not None:
        spec.worldbody.add_geom(name="furniture", type=mujoco.mjtGeom.mjGEOM_BOX, pos=box["center"],
                                size=box["half_size"], rgba=[0.55, 0.42, 0.3, 1.0])
    return spec.compile()


def render_row(clip: MotionClip, kind: str, args: argparse.Namespace) -> np.ndarray:
    model = scene_model(clip, args.width, args.height_px)
    data = mujoco.MjData(model)
    camera = mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_FREE
    azimuth, elevation, distance = VIEWS[kind]
    camera.azimuth = azimuth if args.azimuth is None else args.azimuth
    camera.elevation = elevation if args.elevation is None else args.elevation
    camera.distance = distance if args.distance is None else args.distance
    path = clip.qpos[:, :3]
    centre = 0.5 * (path.min(axis=0) + path.max(axis=0))
    camera.lookat[:] = (centre[0], centre[1], 0.75)
    frame_ids = np.linspace(0, clip.num_frames - 1, args.frames).round().astype(int)
    gap = 4
    row = np.full((args.height_px, args.frames * (args.width + gap) - gap, 3), 255, np.uint8)
    root = model.joint("root").qposadr[0]
    with mujoco.Renderer(model, height=args.height_px, width=args.width) as renderer:
        for i, frame in enumerate(frame_ids):
            data.qpos[root:root + clip.qpos.shape[1]] = clip.qpos[frame]
            mujoco.mj_forward(model, data)
            renderer.update_scene(data, camera=camera)
            renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False  # no shadow acne on the box top
            left = i * (args.width + gap)
            row[:, left:left + args.width] = renderer.render()
    return row


def render_filmstrip(args: argparse.Namespace) -> np.ndarray:
    """The strip as an (H, W, 3) uint8 image: one row per clip."""
    rows = [render_row(make_clip(kind, args), kind, args) for kind in args.clips]
    gap = 4
    strip = np.full((len(rows) * (args.height_px + gap) - gap, rows[0].shape[1], 3), 255, np.uint8)
    for r, row in enumerate(rows):
        top = r * (args.height_px + gap)
        strip[top:top + args.height_px] = row
    return strip


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.frames < 1 or (args.distance is not None and not (math.isfinite(args.distance) and args.distance > 0)):
        print("need --frames >= 1 and --distance > 0", file=sys.stderr)
        return 2
    strip = render_filmstrip(args)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    iio.imwrite(args.out, strip)
    print(f"wrote {args.out} ({strip.shape[1]}x{strip.shape[0]})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
