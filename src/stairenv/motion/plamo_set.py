"""PlaMo's reference motion (``builtin:plamo``): clips of the four locomotion types, labelled.

PlaMo's planner (``stairenv.planning.locomotion``) asks for crawling (head ~0.4 m),
crouch-walking (~0.8 m), walking and running (upright). The built-in set covers each:

* converted motion capture (``stairenv.motion.importers``) from ``../shared/motions``:
  DeepMimic (MIT) walk, jog, run, crawl and stealthy walk; IsaacGymEnvs (BSD-3) walk and run
  (:data:`CONVERTED`);
* synthesised crouch-walks (``stairenv.motion.synthesis.crouch_walk``), since no clip holds
  the head anywhere near 0.8 m (the stealthy walk's is ~1.2 m), and walks and crouch-walks that
  speed up and slow down (``synthesis.speed_change``: starts and stops from and to a slow walk)
  (:data:`SYNTHESISED`). No clip turns: neither the sources nor the synthesis have turns.

Every clip's ``meta`` carries ``locomotion`` (a planner name), ``head_height`` (mean height of
the head centre over the clip, m; ``head_height_range`` min and max), ``speed`` (net
horizontal speed of the root, m/s), ``flight_fraction``, ``penetration`` and ``terrain``
("flat": the clip moves on level ground, so starts on a floor may be drawn from it).

Converted clips are put on the floor by their *support*: the height of the lowest body point
over the frames where that point is (nearly) still, i.e. a planted sole, knee or hand (its
median for a looping clip, a straight line in time otherwise: :func:`support_offset`;
``meta["root_height_offset"]`` the shift at the first and last frame). The importers' default
(the lowest point over the whole clip at z = 0) lifts these clips by 2-15 cm, because a few
frames dip a toe or a shin into their own floor; measured per clip in ``meta["penetration"]``
(how deep the lowest frame dips).

The clips ship, converted, in ``stairenv/motion/data/plamo/`` (``NOTICE.txt`` names each
source, its licence and what was changed); ``python -m stairenv.motion.plamo_set --motions
../shared/motions`` rebuilds them (the raw files are never shipped).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from stairenv.humanoid.model import HEAD_CENTRE_OFFSET
from stairenv.motion.clip import MotionClip

__all__ = ["CONVERTED", "DATA_DIR", "LOCOMOTION_TYPES", "SYNTHESISED", "build_clips", "head_heights",
           "label_clip", "load_plamo_clips", "measure", "on_support", "plamo_weights", "support_offset"]

DATA_DIR = Path(__file__).resolve().parent / "data" / "plamo"
#: the locomotion types the set covers (the planner's names; "sprint" has no clip)
LOCOMOTION_TYPES = ("crawl", "crouch-walk", "walk", "run")
_STILL_SPEED = 0.25   # m/s: a lowest point moving slower than this is planted (support)
_FLIGHT_GAP = 0.02    # m: frames whose lowest point is higher than this are airborne


@dataclass(frozen=True)
class Converted:
    """A clip converted from ``source`` (a path under the motions folder)."""

    name: str
    source: str
    locomotion: str
    licence: str
    time_scale: float = 1.0   # > 1 plays the clip faster (the frame rate multiplied)
    note: str = ""


CONVERTED: tuple[Converted, ...] = (
    Converted("dm_walk", "DeepMimic/humanoid3d_walk.txt", "walk", "MIT"),
    Converted("dm_stealthy_walk", "DeepMimic/humanoid3d_stealthy_walk.txt", "walk", "MIT",
              note="a slow, careful walk on bent knees; its head (~1.29 m) is far above the crouch-walk's range"),
    Converted("ige_walk", "IsaacGymEnvs/amp_humanoid_walk.npy", "walk", "BSD-3-Clause"),
    Converted("dm_jog", "DeepMimic/humanoid3d_jog.txt", "run", "MIT"),
    Converted("dm_run", "DeepMimic/humanoid3d_run.txt", "run", "MIT"),
    Converted("ige_run", "IsaacGymEnvs/amp_humanoid_run.npy", "run", "BSD-3-Clause"),
    Converted("dm_crawl", "DeepMimic/humanoid3d_crawl.txt", "crawl", "MIT"),
    Converted("dm_crawl_fast", "DeepMimic/humanoid3d_crawl.txt", "crawl", "MIT", time_scale=1.5,
              note="played 1.5 times faster (frame rate 45 fps), a second crawling speed"),
)

#: synthesised clips: (name, locomotion, ``stairenv.motion.synthesis`` function, its keyword arguments)
SYNTHESISED: tuple[tuple[str, str, str, dict[str, Any]], ...] = (
    ("crouch_walk_0.5mps", "crouch-walk", "crouch_walk", dict(speed=0.5, lead_foot="right")),
    ("crouch_walk_1.0mps", "crouch-walk", "crouch_walk", dict(speed=1.0, lead_foot="left")),
    ("crouch_walk_1.5mps", "crouch-walk", "crouch_walk", dict(speed=1.5, lead_foot="right")),
    ("crouch_walk_high_1.0mps", "crouch-walk", "crouch_walk", dict(speed=1.0, lean=1.3, lead_foot="right")),
    ("crouch_walk_speed_up", "crouch-walk", "speed_change", dict(speed_from=0.4, speed_to=1.4, crouch=True)),
    ("crouch_walk_slow_down", "crouch-walk", "speed_change",
     dict(speed_from=1.4, speed_to=0.4, crouch=True, lead_foot="left")),
    ("walk_speed_up", "walk", "speed_change", dict(speed_from=0.3, speed_to=1.5)),
    ("walk_slow_down", "walk", "speed_change", dict(speed_from=1.5, speed_to=0.3, lead_foot="left")),
)


# --- measuring -------------------------------------------------------------------------------------
def head_heights(qpos: np.ndarray) -> np.ndarray:
    """(T,) height of the head centre (the point ``PlaMoEnv`` tracks) in each frame of ``qpos``."""
    from stairenv.humanoid import humanoid_model
    from stairenv.humanoid.kinematics import forward_kinematics

    head = humanoid_model().body("head").id
    out = np.empty(len(qpos))
    for t, data in enumerate(forward_kinematics(qpos)):
        out[t] = data.xpos[head, 2] + data.xmat[head, 6:9] @ HEAD_CENTRE_OFFSET
    return out


def _lowest_points(qpos: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(T,) height of the lowest body point per frame, (T, G) the lowest point of each geom, and
    (T, G, 2) the geoms' horizontal positions."""
    from stairenv.humanoid.kinematics import geom_lowest_points

    per_geom, xy = geom_lowest_points(qpos)
    return per_geom.min(axis=1), per_geom, xy


def support_offset(clip: MotionClip) -> np.ndarray:
    """(T,) vertical shift (add to the root height) that puts the clip's support on z = 0.

    The support is the lowest body point in the frames where the geom holding it moves slower
    than 0.25 m/s horizontally (a planted sole, knee or hand; all frames if none is that still).
    A looping clip is shifted by the median support height (one number: the loop must close); a
    clip that does not loop by a straight line in time fitted to it (least squares), since some
    sources drift (IsaacGymEnvs' walk sinks ~9 cm into its floor over 2.5 s)."""
    low, per_geom, xy = _lowest_points(clip.qpos)
    speed = np.linalg.norm(np.gradient(xy, axis=0), axis=2) * clip.fps  # (T, G)
    lowest = per_geom.argmin(axis=1)
    still = speed[np.arange(len(low)), lowest] < _STILL_SPEED
    if not still.any():
        still[:] = True
    times = np.arange(clip.num_frames) / clip.fps
    if clip.loop or np.count_nonzero(still) < 4:
        return np.full(clip.num_frames, -float(np.median(low[still])))
    slope, intercept = np.polyfit(times[still], low[still], 1)
    return -(intercept + slope * times)


def measure(clip: MotionClip) -> dict[str, Any]:
    """Head height (mean, min, max), net and mean horizontal root speed, share of airborne frames
    (lowest point above 2 cm), how deep the lowest frame dips into the floor, and the median height
    of the lowest point (the floating of a clip that should touch the ground)."""
    heads = head_heights(clip.qpos)
    low = _lowest_points(clip.qpos)[0]
    root = clip.qpos[:, :2]
    step = np.linalg.norm(np.diff(root, axis=0), axis=1) * clip.fps
    duration = max(clip.duration, 1e-9)
    return {
        "head_height": round(float(heads.mean()), 4),
        "head_height_range": [round(float(heads.min()), 4), round(float(heads.max()), 4)],
        "speed": round(float(np.linalg.norm(root[-1] - root[0]) / duration), 4),
        "mean_speed": round(float(step.mean()) if len(step) else 0.0, 4),
        "flight_fraction": round(float(np.mean(low > _FLIGHT_GAP)), 4),
        "penetration": round(float(max(0.0, -low.min())), 4),
        "median_lowest_point": round(float(np.median(low)), 4),
    }


def label_clip(clip: MotionClip, locomotion: str, **extra: Any) -> MotionClip:
    """The clip with ``meta`` gaining its locomotion type, :func:`measure`'s numbers, ``terrain``
    "flat" and ``extra``."""
    from stairenv.planning.locomotion import get_locomotion

    name = get_locomotion(locomotion).name
    meta = {**clip.meta, "locomotion": name, "terrain": "flat", **measure(clip), **extra}
    return MotionClip(clip.qpos, clip.fps, clip.name, clip.loop, clip.source, meta)


# --- building -----------------------------------------------------------------------------------
def convert(recipe: Converted, motions_dir: str | Path) -> MotionClip:
    """One converted clip: imported at its own frame rate (no resampling), time-scaled, put on its
    support, labelled."""
    from stairenv.motion.importers import import_motion

    clip = import_motion(Path(motions_dir) / recipe.source, ground="none", name=recipe.name)
    grounded = on_support(clip, source_file=recipe.source, licence=recipe.licence, time_scale=recipe.time_scale)
    meta = dict(grounded.meta)
    if recipe.note:
        meta["note"] = recipe.note
    out = MotionClip(grounded.qpos, clip.fps * recipe.time_scale, recipe.name, clip.loop, recipe.source, meta)
    return label_clip(out, recipe.locomotion)


def on_support(clip: MotionClip, **meta: Any) -> MotionClip:
    """``clip`` shifted so that its support is on z = 0 (:func:`support_offset`), its importer's grounding
    in ``meta`` replaced by ``ground="support"`` and the shift at its first and last frame, then ``meta``."""
    offset = support_offset(clip)
    qpos = clip.qpos.copy()
    qpos[:, 2] += offset
    kept = {key: value for key, value in clip.meta.items()
            if key not in ("ground", "root_height_offset", "lowest_sole_height")}
    kept.update(ground="support", root_height_offset=[round(float(offset[0]), 6), round(float(offset[-1]), 6)],
                **meta)
    return MotionClip(qpos, clip.fps, clip.name, clip.loop, clip.source, kept)


def synthesise(name: str, locomotion: str, function: str, kwargs: dict[str, Any]) -> MotionClip:
    from stairenv.motion import synthesis

    clip = getattr(synthesis, function)(name=name, **kwargs)
    return label_clip(clip, locomotion, licence="stairenv (synthesised)")


def build_clips(motions_dir: str | Path) -> list[MotionClip]:
    """Every clip of the set, converted from ``motions_dir`` (the raw files) and synthesised."""
    return [convert(recipe, motions_dir) for recipe in CONVERTED] + [synthesise(*entry) for entry in SYNTHESISED]


def plamo_weights(clips: Sequence[MotionClip]) -> np.ndarray:
    """Sampling weights giving every locomotion type the same share, split evenly among its clips."""
    kinds = [clip.meta.get("locomotion", "") for clip in clips]
    counts = {kind: kinds.count(kind) for kind in set(kinds)}
    return np.array([1.0 / counts[kind] for kind in kinds])


def load_plamo_clips(folder: str | Path = DATA_DIR) -> list[MotionClip]:
    """The shipped clips (sorted by file name)."""
    return load_folder(folder, "PlaMo reference clips")


def load_folder(folder: str | Path, what: str) -> list[MotionClip]:
    """Every ``.npz`` clip of ``folder``, sorted by file name; ``FileNotFoundError`` naming ``what`` if none."""
    files = sorted(Path(folder).glob("*.npz"))
    if not files:
        raise FileNotFoundError(f"no {what} in {folder}")
    return [MotionClip.load(f) for f in files]


def save_and_describe(clips: Sequence[MotionClip], out: Path) -> None:
    """Write ``clips`` to ``out/<name>.npz`` and print a line of each one's labels."""
    out.mkdir(parents=True, exist_ok=True)
    for clip in clips:
        path = clip.save(out / f"{clip.name}.npz")
        m = clip.meta
        print(f"{clip.name}: {m['locomotion']}, {clip.num_frames} frames at {clip.fps:g} fps ({clip.duration:.2f} s), "
              f"head {m['head_height']:.2f} m [{m['head_height_range'][0]:.2f}, {m['head_height_range'][1]:.2f}], "
              f"speed {m['speed']:.2f} m/s, flight {m['flight_fraction']:.2f}, penetration {m['penetration']:.3f} m, "
              f"median lowest {m['median_lowest_point']:.3f} m -> {path}")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m stairenv.motion.plamo_set",
                                     description="Rebuild the builtin:plamo clips from the raw motion files.")
    parser.add_argument("--motions", type=Path, default=Path("../shared/motions"),
                        help="folder holding DeepMimic/ and IsaacGymEnvs/ (default: %(default)s)")
    parser.add_argument("--out", type=Path, default=DATA_DIR, help="folder for the .npz clips (default: the package's)")
    args = parser.parse_args(argv)
    save_and_describe(build_clips(args.motions), args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
