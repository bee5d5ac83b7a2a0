#!/usr/bin/env python
"""Filmstrips of a policy on InterLevel's stairs: one PNG per step height and one small combined PNG.

Does the policy look like a person climbing? For each step height (the paper's 0.05 / 0.10 /
0.15 / 0.20 m unless ``--heights``) one episode runs from the same seed (env keyword
``step_height_set=(h,)``, so the staircases differ only in their height). The episode's ``qpos``
are kept step by step and ``--frames`` frames spread evenly over it are rendered afterwards from
the side of the staircase (the camera looks across the ascent, which runs left to right, and
follows the pelvis). Each strip is captioned with how the episode ended and its gait metrics
(``stairenv.evaluation.gait``: pattern, touchdowns per tread, hops, crawling, sliding), and each
frame with its time. The combined image stacks the strips and is scaled down (and reduced to 256
colours where needed) until it is at most ``--combined-max-kb`` (300 KB), small enough for the README.

The policy is given as to ``baselines/evaluate.py``: ``zero``, ``random``, a Stable-Baselines3
model ``.zip`` (``ALGO:path`` for another algorithm), an exported ``.npz``, or ``pretrained``
(the policy shipped with the package).

Examples::

    python baselines/filmstrip_climb.py --policy runs/ppo/final_model.zip
    python baselines/filmstrip_climb.py --policy policy.npz --frames 10 --combined docs/climb_filmstrip.png
    python baselines/filmstrip_climb.py --policy zero --heights 0.10 --width 96 --height 128
"""

from __future__ import annotations

import argparse
import io
import math
import os
import sys
from pathlib import Path
from typing import NamedTuple

os.environ.setdefault("MUJOCO_GL", "egl")  # before mujoco is imported

import gymnasium as gym
import mujoco
import numpy as np
from PIL import Image, ImageDraw, ImageFont

import stairenv  # noqa: F401  (registers the envs)
from stairenv.__main__ import resolve_policy
from stairenv.evaluation.cli import env_kwarg_argument
from stairenv.evaluation.gait import GaitRecorder, GaitSummary, summarize
from stairenv.evaluation.interlevel import PAPER_STEP_HEIGHTS
from stairenv.evaluation.policies import load_policy
from stairenv.world.stairs import Staircase

CAPTION_HEIGHT = 16  # px of caption above a strip
GAP = 4              # px between frames and between strips


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description="Filmstrips (PNG) of a policy climbing InterLevel's stairs, "
                                                 "one per step height, seen from the side, and a combined one.")
    parser.add_argument("--policy", required=True,
                        help="'zero', 'random', 'pretrained', an exported policy .npz, a Stable-Baselines3 model "
                             ".zip, or ALGO:path")
    parser.add_argument("--env", default="InterLevel-v0", help="env id (default: %(default)s)")
    parser.add_argument("--heights", type=float, nargs="+", default=list(PAPER_STEP_HEIGHTS), metavar="H",
                        help="step heights (m), one episode each (default: the paper's %(default)s)")
    parser.add_argument("--seed", type=int, default=0, help="the episodes' reset seed (default: %(default)s)")
    parser.add_argument("--frames", type=int, default=8, help="frames per strip (default: %(default)s)")
    parser.add_argument("--width", type=int, default=320, help="pixels per frame (default: %(default)s)")
    parser.add_argument("--height", type=int, default=240, help="pixels per frame (default: %(default)s)")
    parser.add_argument("--distance", type=float, default=4.0, help="camera distance, m (default: %(default)s)")
    parser.add_argument("--max-episode-steps", type=int, default=None,
                        help="time limit in policy steps (default: the preset's, 600 = 20 s)")
    parser.add_argument("--out-dir", type=Path, default=Path("filmstrips"),
                        help="folder of the per-height PNGs (default: %(default)s)")
    parser.add_argument("--combined", type=Path, default=Path("docs/climb_filmstrip.png"),
                        help="the combined PNG (default: %(default)s)")
    parser.add_argument("--combined-width", type=int, default=960,
                        help="largest width of the combined PNG in pixels (default: %(default)s)")
    parser.add_argument("--combined-max-kb", type=float, default=300.0,
                        help="largest size of the combined PNG in KB (default: %(default)s)")
    parser.add_argument("--env-kwarg", action="append", default=[], type=env_kwarg_argument, metavar="KEY=VALUE",
                        help="extra env keyword, repeatable; values parsed as Python literals, else strings")
    return parser


class Episode(NamedTuple):
    """One recorded episode: its states and how it went."""

    step_height: float
    seed: int
    qpos: np.ndarray        # (T, nq), the reset state first
    times: np.ndarray       # (T,) s
    progress: float         # highest info["progress"]
    ending: str             # "success", "fell", "time limit", "unstable"
    gait: GaitSummary

    def caption(self) -> str:
        g = self.gait
        per_tread = "-" if g.touchdowns_per_tread is None else f"{g.touchdowns_per_tread:.1f}"
        slide = "-" if g.slide_fraction is None else f"{100 * g.slide_fraction:.0f}%"
        return (f"{self.step_height:.2f} m, seed {self.seed}: {self.ending} at {self.times[-1]:.1f} s, "
                f"progress {100 * self.progress:.0f}% | {g.pattern}, {per_tread} touchdowns/tread, "
                f"{g.hops} hops, crawl {'yes' if g.crawled else 'no'}, slide {slide}")


def run_episode(env: gym.Env, policy, seed: int) -> Episode:
    """Play one episode, keeping every step's ``qpos`` and the feet's contacts."""
    base = env.unwrapped
    recorder = GaitRecorder(base.model)
    if callable(getattr(policy, "reset", None)):
        policy.reset(seed)
    obs, info = env.reset(seed=seed)
    stairs = info["stairs"]
    qpos, progress = [base.data.qpos.copy()], float(info["progress"])
    recorder.record(base.data)
    while True:
        obs, _, terminated, truncated, info = env.step(np.asarray(policy(obs)))
        if info.get("physics_unstable"):
            ending = "unstable"
            break
        qpos.append(base.data.qpos.copy())
        recorder.record(base.data)
        progress = max(progress, float(info["progress"]))
        if terminated or truncated:
            ending = "success" if info.get("success") else "fell" if info.get("fell") else "time limit"
            break
    trace = recorder.trace(base.dt, int(stairs["num_steps"]))
    return Episode(float(stairs["step_height"]), seed, np.array(qpos), base.dt * np.arange(len(qpos)), progress,
                   ending, summarize(trace))


def frame_indices(count: int, frames: int) -> np.ndarray:
    """``frames`` indices spread evenly over ``count`` states, first and last included."""
    return np.unique(np.linspace(0, count - 1, frames).round().astype(int))


def render_side_view(model: mujoco.MjModel, qpos: np.ndarray, stairs: Staircase, width: int, height: int,
                     distance: float) -> list[np.ndarray]:
    """Each ``qpos`` row drawn from the side of ``stairs``: the camera looks across the ascent (the
    stairs rise left to right) at the pelvis, or, while the pelvis is still before the first riser,
    halfway between it and the riser's line, so that the stairs come into view."""
    data = mujoco.MjData(model)
    camera = mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_FREE
    camera.azimuth = math.degrees(stairs.yaw) + 90.0
    camera.elevation = -10.0
    camera.distance = distance
    options = mujoco.MjvOption()
    options.geomgroup[2] = 0  # no stairs markers
    images = []
    with mujoco.Renderer(model, height=height, width=width) as renderer:
        for state in qpos:
            data.qpos[:] = state
            mujoco.mj_kinematics(model, data)
            pelvis = data.qpos[:3]
            before = max(0.0, -float(stairs.to_local(pelvis)[0]))  # m before the first riser
            camera.lookat[:] = pelvis + 0.5 * before * stairs.axis - np.array([0.0, 0.0, 0.2])
            renderer.update_scene(data, camera=camera, scene_option=options)
            images.append(renderer.render().copy())
    return images


def _font(size: int) -> ImageFont.ImageFont:
    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # Pillow < 10.1: the bitmap font only
        return ImageFont.load_default()


def filmstrip(images: list[np.ndarray], times: list[float], caption: str) -> Image.Image:
    """The frames side by side under a caption line, each frame marked with its time."""
    height, width = images[0].shape[:2]
    strip = Image.new("RGB", (len(images) * (width + GAP) - GAP, CAPTION_HEIGHT + height), "white")
    draw = ImageDraw.Draw(strip)
    draw.text((2, 1), caption, fill="black", font=_font(12))
    small = _font(max(8, min(12, width // 10)))
    for k, (image, time) in enumerate(zip(images, times)):
        left = k * (width + GAP)
        strip.paste(Image.fromarray(image), (left, CAPTION_HEIGHT))
        draw.text((left + 3, CAPTION_HEIGHT + 2), f"{time:.1f} s", fill="white", font=small, stroke_width=1,
                  stroke_fill="black")
    return strip


def combine(strips: list[Image.Image], max_width: int, max_bytes: int) -> tuple[Image.Image, bytes]:
    """The strips stacked, scaled to at most ``max_width`` and shrunk until the PNG fits ``max_bytes``."""
    width = min(max_width, max(s.width for s in strips))
    while True:
        scaled = [s.resize((width, max(1, round(s.height * width / s.width))), Image.LANCZOS) for s in strips]
        sheet = Image.new("RGB", (width, sum(s.height for s in scaled) + GAP * (len(scaled) - 1)), "white")
        top = 0
        for s in scaled:
            sheet.paste(s, (0, top))
            top += s.height + GAP
        for image in (sheet, sheet.quantize(colors=256, method=Image.Quantize.MEDIANCUT)):
            buffer = io.BytesIO()
            image.save(buffer, "PNG", optimize=True)
            if buffer.tell() <= max_bytes:
                return image, buffer.getvalue()
        if width <= 64:
            raise ValueError(f"cannot fit the combined filmstrip into {max_bytes} bytes")
        width = int(width * 0.85)


def write_combined(strips: list[Image.Image], path: Path, max_width: int, max_kb: float) -> None:
    """``combine`` the strips and write the PNG to ``path`` (its folder made)."""
    _, png = combine(strips, max_width, int(max_kb * 1000))
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(png)
    print(f"wrote {path} ({len(png) / 1000:.0f} KB)")


def add_follow_camera_options(parser: argparse.ArgumentParser, *, every: int, distance: float, elevation: float,
                              combined: str) -> None:
    """The options of a filmstrip whose frames the env's follow camera renders during an episode
    (``filmstrip_tracking.py``, ``filmstrip_sims.py``)."""
    parser.add_argument("--frames", type=int, default=8, help="frames per strip (default: %(default)s)")
    parser.add_argument("--every", type=int, default=every,
                        help="render every this many steps (default: %(default)s)")
    parser.add_argument("--width", type=int, default=240, help="pixels per frame (default: %(default)s)")
    parser.add_argument("--height", type=int, default=240, help="pixels per frame (default: %(default)s)")
    parser.add_argument("--distance", type=float, default=distance, help="camera distance, m (default: %(default)s)")
    parser.add_argument("--elevation", type=float, default=elevation,
                        help="camera elevation, deg (default: %(default)s)")
    parser.add_argument("--combined", type=Path, default=Path(combined),
                        help="the combined PNG (default: %(default)s)")
    parser.add_argument("--combined-width", type=int, default=1200, help="(default: %(default)s)")
    parser.add_argument("--combined-max-kb", type=float, default=400.0, help="(default: %(default)s)")


def film_follow_camera(env: gym.Env, policy, seed: int,
                       every: int) -> tuple[list[np.ndarray], list[float], list[dict]]:
    """One episode from ``seed``: the follow camera's frames (the first, every ``every`` steps, the last),
    their times (s), and every step's ``info``."""
    if callable(getattr(policy, "reset", None)):
        policy.reset(seed)
    obs, _ = env.reset(seed=seed)
    images, times, infos = [env.render()], [0.0], []
    while True:
        obs, _, terminated, truncated, info = env.step(np.asarray(policy(obs)))
        infos.append(info)
        ended = terminated or truncated
        if len(infos) % every == 0 or ended:
            images.append(env.render())
            times.append(len(infos) * env.unwrapped.dt)
        if ended:
            return images, times, infos


def follow_camera_strip(images: list[np.ndarray], times: list[float], frames: int, caption: str) -> Image.Image:
    """``frames`` of an episode's rendered frames, spread evenly, as one captioned strip."""
    keep = frame_indices(len(images), frames)
    return filmstrip([images[k] for k in keep], [times[k] for k in keep], caption)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.frames < 1 or args.seed < 0 or not args.heights:
        parser.error("need --frames >= 1, --seed >= 0 and at least one height")
    for name in ("width", "height"):
        if not 16 <= getattr(args, name) <= 4096:
            parser.error(f"--{name} must be in [16, 4096] pixels")
    make_kwargs = {"max_episode_steps": args.max_episode_steps} if args.max_episode_steps else {}
    env_kwargs = dict(args.env_kwarg)
    policy = None
    strips = []
    args.out_dir.mkdir(parents=True, exist_ok=True)
    try:
        spec, note = resolve_policy(args.policy, args.env)
        if note:
            print(note)
        for h in args.heights:
            env = gym.make(args.env, step_height_set=(h,), width=args.width, height=args.height,
                           **make_kwargs, **env_kwargs)
            try:
                if policy is None:
                    policy = load_policy(spec, env, seed=args.seed)
                episode = run_episode(env, policy, args.seed)
                picked = frame_indices(len(episode.qpos), args.frames)
                images = render_side_view(env.unwrapped.model, episode.qpos[picked], env.unwrapped.stairs,
                                          args.width, args.height, args.distance)
            finally:
                env.close()
            strip = filmstrip(images, episode.times[picked].tolist(), episode.caption())
            path = args.out_dir / f"filmstrip_{h:.2f}m.png"
            strip.save(path, optimize=True)
            strips.append(strip)
            print(f"wrote {path} ({strip.width}x{strip.height}): {episode.caption()}")
    except ValueError as error:
        parser.error(str(error))
    write_combined(strips, args.combined, args.combined_width, args.combined_max_kb)
    return 0


if __name__ == "__main__":
    sys.exit(main())
