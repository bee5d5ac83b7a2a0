#!/usr/bin/env python
"""Filmstrips of PlaMo's reference clips (``builtin:plamo``): one row per clip, frames over one period.

Kinematic playback, as ``filmstrip_synthesis.py``: each frame's ``qpos`` is written into the
bare humanoid model (with its floor), ``mj_forward`` places the bodies and an offscreen
``mujoco.Renderer`` (``MUJOCO_GL=egl`` unless set) draws it from the side, the camera
following the pelvis. Nothing is simulated. Each row is labelled with the clip's name,
locomotion type, mean head height and speed (``meta``).

Examples::

    python baselines/filmstrip_plamo.py --out-dir filmstrips/plamo            # one PNG per clip
    python baselines/filmstrip_plamo.py --combined docs/plamo_reference_clips.png --width 120 --height 150
    python baselines/filmstrip_plamo.py --clips dm_crawl crouch_walk_1.0mps --frames 10
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")  # before mujoco is imported

import imageio.v3 as iio  # noqa: E402
import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from stairenv.humanoid import load_humanoid_spec  # noqa: E402
from stairenv.motion.plamo_set import DATA_DIR, load_plamo_clips  # noqa: E402

LABEL_HEIGHT = 16


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description="Filmstrips (PNG) of the builtin:plamo reference clips.")
    parser.add_argument("--clips", nargs="*", default=None,
                        help="clip names, in the order shown (default: all, by locomotion type)")
    parser.add_argument("--folder", type=Path, default=DATA_DIR, help="folder of .npz clips (default: the package's)")
    parser.add_argument("--out-dir", type=Path, default=None, help="write one PNG per clip here")
    parser.add_argument("--combined", type=Path, default=None, help="write all rows into this one PNG")
    parser.add_argument("--frames", type=int, default=8, help="frames per clip (default: %(default)s)")
    parser.add_argument("--width", type=int, default=200, help="pixels per frame (default: %(default)s)")
    parser.add_argument("--height", type=int, default=240, help="pixels per frame (default: %(default)s)")
    parser.add_argument("--distance", type=float, default=3.0, help="camera distance, m (default: %(default)s)")
    parser.add_argument("--azimuth", type=float, default=90.0,
                        help="camera azimuth, degrees (90: from the character's left side; default: %(default)s)")
    return parser


def _label(text: str, width: int) -> np.ndarray:
    from PIL import Image, ImageDraw

    image = Image.new("RGB", (width, LABEL_HEIGHT), (255, 255, 255))
    ImageDraw.Draw(image).text((4, 2), text, fill=(0, 0, 0))
    return np.asarray(image)


def render_rows(args: argparse.Namespace) -> list[tuple[str, np.ndarray]]:
    """(clip name, labelled strip (H, W, 3) uint8) per clip."""
    order = {"crawl": 0, "crouch-walk": 1, "walk": 2, "run": 3}
    clips = sorted(load_plamo_clips(args.folder), key=lambda c: (order.get(c.meta.get("locomotion"), 4),
                                                                 c.meta.get("speed", 0.0)))
    if args.clips:
        unknown = set(args.clips) - {c.name for c in clips}
        if unknown:
            raise SystemExit(f"unknown clips {sorted(unknown)}; known: {[c.name for c in clips]}")
        by_name = {c.name: c for c in clips}
        clips = [by_name[name] for name in args.clips]  # in the order asked for
    spec = load_humanoid_spec()
    spec.visual.global_.offwidth = max(spec.visual.global_.offwidth, args.width)
    spec.visual.global_.offheight = max(spec.visual.global_.offheight, args.height)
    model = spec.compile()
    data = mujoco.MjData(model)
    camera = mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_FREE
    camera.elevation = -8.0
    camera.distance = args.distance
    gap = 4
    rows = []
    with mujoco.Renderer(model, height=args.height, width=args.width) as renderer:
        for clip in clips:
            strip = np.full((args.height, args.frames * (args.width + gap) - gap, 3), 255, np.uint8)
            times = np.linspace(0.0, clip.duration, args.frames, endpoint=not clip.loop)
            qpos = clip.sample(times)
            heading = np.arctan2(qpos[-1, 1] - qpos[0, 1], qpos[-1, 0] - qpos[0, 0]) if args.frames > 1 else 0.0
            for i, q in enumerate(qpos):
                data.qpos[:] = q
                mujoco.mj_forward(model, data)
                camera.azimuth = np.degrees(heading) + args.azimuth
                camera.lookat[:] = (q[0], q[1], 0.75)
                renderer.update_scene(data, camera=camera)
                renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False  # no shadow speckles
                strip[:, i * (args.width + gap):i * (args.width + gap) + args.width] = renderer.render()
            m = clip.meta
            text = (f"{clip.name}: {m.get('locomotion', '?')}, head {m.get('head_height', float('nan')):.2f} m, "
                    f"{m.get('speed', float('nan')):.2f} m/s, {clip.duration:.2f} s")
            rows.append((clip.name, np.concatenate((_label(text, strip.shape[1]), strip))))
    return rows


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.frames < 1 or (args.out_dir is None and args.combined is None):
        print("need --frames >= 1 and --out-dir or --combined", file=sys.stderr)
        return 2
    rows = render_rows(args)
    if args.out_dir is not None:
        args.out_dir.mkdir(parents=True, exist_ok=True)
        for name, image in rows:
            iio.imwrite(args.out_dir / f"{name}.png", image)
        print(f"wrote {len(rows)} filmstrips to {args.out_dir}")
    if args.combined is not None:
        width = max(image.shape[1] for _, image in rows)
        padded = [np.pad(image, ((0, 4), (0, width - image.shape[1]), (0, 0)), constant_values=255)
                  for _, image in rows]
        combined = np.concatenate(padded)[:-4]
        args.combined.parent.mkdir(parents=True, exist_ok=True)
        from PIL import Image

        # a 128-colour palette: a third of the bytes, no visible loss on these flat-shaded frames
        Image.fromarray(combined).quantize(128).save(args.combined, optimize=True)
        print(f"wrote {args.combined} ({combined.shape[1]}x{combined.shape[0]})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
