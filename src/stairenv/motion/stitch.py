"""Two clips made one: a lead-in played, then blended into a second clip that carries on.

A crawl specialist is evaluated from a standing start, yet no single captured clip both gets down from
standing and crawls as low as PlaMo's crawl paths ask (CMU 133_01 gets down onto hands and knees with
its head ~0.7 m up; DeepMimic's crawl is on the forearms, ~0.37 m). ``stitch`` joins such clips the way
motion graphs do (Kovar et al. 2002): the lead clip is played over a window, the follow clip is turned
about z and moved so that its root, at the blend's start, lies on the lead's, heading the way the lead
was travelling, or facing if it stood still (the follow clip's heading: its travel over a cycle),
and for ``blend`` seconds the two are blended with a smooth weight (``clip.blend_poses``: slerp for the
root and the 3-axis joints, linear otherwise); then the follow clip plays on (a looping one cycle after
cycle, ``motion.tracking.clip_frames``) until the stitched clip's ``duration``. The root's height is
blended like every other coordinate; the result is put back on the floor by its support
(``plamo_set.on_support``) when ``on_floor``.

    python -m stairenv.motion.stitch --lead cmu/cmu_walk_crawl_walk_133_01.npz --window 1.87 3.4 \
        --follow plamo/dm_crawl.npz --follow-start 0.67 --blend 0.8 --duration 16 --out get_down_crawl.npz
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from stairenv.motion.clip import MotionClip, blend_poses
from stairenv.motion.tracking import turn_frames, clip_frames

#: how far back (s) the lead clip's travel before the blend is measured, for its heading
TRAVEL_WINDOW = 0.5
#: a lead whose root moves less than this (m) over ``TRAVEL_WINDOW`` stands still: its heading is the way its
#: pelvis faces (upright, its x axis is level), not its travel
STILL_TRAVEL = 0.05


def _smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def stitch(lead: MotionClip, window: tuple[float, float], follow: MotionClip, follow_start: float,
           blend: float, duration: float, fps: float = 30.0, name: str = "", on_floor: bool = True,
           **meta) -> MotionClip:
    """``lead`` from ``window[0]`` to ``window[1]`` (s), blended over ``blend`` s into ``follow`` played
    from ``follow_start`` (placed on the lead's root at ``window[1]``), ``duration`` s in all at ``fps``.
    The lead plays on through the blend (its frames beyond its end held). Not a looping clip."""
    start, end = float(window[0]), float(window[1])
    if not (0.0 <= start < end <= lead.duration + 1e-9):
        raise ValueError(f"window must satisfy 0 <= start < end <= the lead's duration ({lead.duration:.3f} s), "
                         f"got {window!r}")
    if not (blend >= 0.0 and math.isfinite(blend)):
        raise ValueError(f"blend must be a finite number of seconds >= 0, got {blend!r}")
    if not (duration > end - start + blend and math.isfinite(duration)):
        raise ValueError(f"duration must exceed the lead window plus the blend ({end - start + blend:.3f} s), "
                         f"got {duration!r}")
    if not (fps > 0 and math.isfinite(fps)):
        raise ValueError(f"fps must be a positive number, got {fps!r}")
    if not (0.0 <= follow_start <= follow.duration):
        raise ValueError(f"follow_start must lie in [0, {follow.duration:.3f}] s, got {follow_start!r}")
    times = np.arange(round(duration * fps) + 1) / fps          # the stitched clip's own clock
    lead_part = lead.sample(start + times)                            # (held at its last frame beyond its end)
    steps = len(times) - 1
    follow_frames = clip_frames(follow, follow_start, steps, 1.0 / fps)    # follow_frames[0] at follow_start
    joint = end - start                                               # when the blend begins (stitched clock)
    shift = np.clip(np.round((times - joint) * fps).astype(int), 0, steps)
    follow_part = follow_frames[shift]                                # the follow clip from ``joint`` on
    anchor = lead.sample(end)[0]
    # headings by travel: the lead's over its window's last ``TRAVEL_WINDOW`` s, the follow clip's over
    # one cycle (or the same span); a crawling pelvis's own x axis points at the floor, so its yaw is not one
    lead_travel = anchor[:2] - lead.sample(max(start, end - TRAVEL_WINDOW))[0, :2]
    span = min(round((follow.duration if follow.loop else TRAVEL_WINDOW) * fps), steps)
    follow_travel = follow_frames[span, :2] - follow_frames[0, :2]
    if np.linalg.norm(follow_travel) < 1e-3:
        raise ValueError("stitch aligns the clips by their travel: the follow clip must move (more than 1 mm)")
    if np.linalg.norm(lead_travel) < STILL_TRAVEL:    # a lead standing still: the way its pelvis faces
        forward = Rotation.from_quat(anchor[3:7], scalar_first=True).apply([1.0, 0.0, 0.0])
        lead_heading = float(np.arctan2(forward[1], forward[0]))
    else:
        lead_heading = float(np.arctan2(lead_travel[1], lead_travel[0]))
    angle = lead_heading - float(np.arctan2(follow_travel[1], follow_travel[0]))
    follow_part = turn_frames(follow_part, angle, follow_frames[0, :2], anchor[:2])
    weight = _smoothstep((times - joint) / blend) if blend > 0 else (times >= joint).astype(float)
    qpos = blend_poses(lead_part, follow_part, weight)
    qpos[:, :2] -= qpos[0, :2]                                         # the clip starts at the origin
    info = {"stitched": {"lead": lead.name, "window_s": [start, end], "follow": follow.name,
                         "follow_start_s": float(follow_start), "blend_s": float(blend)},
            "sources": [lead.meta.get("origin", lead.source), follow.meta.get("origin", follow.source)]}
    clip = MotionClip(qpos, fps, name or f"{lead.name}+{follow.name}", False,
                      f"stitched: {lead.source or lead.name} + {follow.source or follow.name}", {**info, **meta})
    if on_floor:
        from stairenv.motion.plamo_set import on_support
        clip = on_support(clip)
    return clip


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m stairenv.motion.stitch", description=__doc__.split("\n\n")[0])
    parser.add_argument("--lead", required=True, help="the lead-in clip (.npz)")
    parser.add_argument("--window", type=float, nargs=2, required=True, metavar=("START", "END"))
    parser.add_argument("--follow", required=True, help="the clip blended into (.npz)")
    parser.add_argument("--follow-start", type=float, default=0.0)
    parser.add_argument("--blend", type=float, default=0.5)
    parser.add_argument("--duration", type=float, required=True)
    parser.add_argument("--fps", type=float, default=30.0)
    parser.add_argument("--name", default="")
    parser.add_argument("--locomotion", default=None, help="label the clip with this locomotion (plamo_set.label_clip: its measures too)")
    parser.add_argument("--out", required=True)
    args = parser.parse_args(argv)
    clip = stitch(MotionClip.load(args.lead), tuple(args.window), MotionClip.load(args.follow), args.follow_start,
                  args.blend, args.duration, args.fps, args.name or Path(args.out).stem)
    if args.locomotion is not None:
        from stairenv.motion.plamo_set import label_clip
        clip = label_clip(clip, args.locomotion)
    print(f"{clip.save(args.out)}: {clip.num_frames} frames, {clip.duration:.2f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())


__all__ = ["stitch"]
