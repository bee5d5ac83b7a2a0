"""Gait metrics of stair climbs: does a policy climb like a person?

A :class:`GaitRecorder` reads MuJoCo's contacts once per frame (a policy step, or a frame of a
kinematic replay) into a :class:`GaitTrace`; everything after that is a pure function of the
trace. Feet are index 0 (right) and 1 (left), as ``stairenv.humanoid.FOOT_BODIES``.

**Surfaces and levels.** Level 0 is the floor, level k (1..n) the top of tread k of a staircase
of n risers (``Staircase.num_steps``; level n is the landing). A foot *stands on* level k in a
frame when one of its geoms touches the top face of tread k's block (a contact point no more than
``top_tolerance`` = 2 cm below the block's top; a toe against a riser is no support) or, for
k = 0, the floor. A foot touching several tops stands on the highest. ``support[t, f]`` is that
level, -1 (:data:`AIR`) when the foot stands on nothing.

**Footholds.** Per foot, air gaps of at most ``merge_gap`` frames (default 2, 67 ms at 30 Hz)
between two frames on the same level are filled (contact flicker is not a step); a *foothold*
is then a maximal run of frames of one foot on one level, and its first frame a *touchdown*.

The metrics, per episode (:func:`summarize` -> :class:`GaitSummary`):

- **arrival**: a foothold on a level higher than every level either foot stood on before it
  started (footholds ordered by start; of two starting together the right foot's comes first).
- **(a) alternating / pattern**: ``alternating`` when there are at least two arrivals on treads
  (levels >= 1) and no two consecutive arrivals are by the same foot. ``pattern``:
  ``"step-over-step"`` if alternating; else ``"step-to-step"`` if every level from 1 to the top
  level reached minus one was stood on by both feet; else ``"irregular"``; ``"none"`` with fewer
  than two arrivals on treads.
- **(b) touchdowns per tread**: footholds on the intermediate treads 1..min(top, n - 1) (the
  landing excluded: walking on it is not climbing) divided by the number of those treads; 1 for
  step-over-step, 2 for step-to-step, more for shuffling; None when no tread was reached.
- **(c) hop**: a flight (a maximal run of frames in which neither foot stands on anything) after
  which each foot's next foothold is on a level higher than both feet's last footholds before it,
  with the two take-offs and the two touchdowns each within ``hop_window`` (0.2 s) of one
  another. ``hops`` counts them.
- **(d) crawl**: ``crawl_time`` is the time (s) in which an arm (hand, fore- or upper arm), a leg
  above the foot (shin or thigh: the knees) or the trunk (pelvis, torso, head) touches the top of
  a tread or the landing (floor contacts are falls, not crawling); ``crawled`` when it reaches
  ``crawl_min_time`` (0.1 s), so that a knee grazing a nose for a frame is not a crawl.
- **(e) slide**: a foot's *slip speed* in frame t, when it stands on the same level in frames
  t - 1 and t (no gap filling here), is the horizontal speed of the foot's material point that
  was at its contact centroid in frame t - 1 (moved rigidly with the foot to frame t, so rolling
  over the toe is not sliding), divided by the frame time. A stance frame *slides* above
  ``slide_speed`` (0.1 m/s, 3 mm per 30 Hz frame); ``slide_fraction`` is the share of stance
  frames that slide.

:func:`gait_columns` pools episode summaries into the evaluation report's columns
(:data:`GAIT_FIELDS`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from itertools import pairwise
from typing import Any

import mujoco
import numpy as np

from stairenv.humanoid import FOOT_BODIES

#: ``support`` of a foot that stands on nothing.
AIR = -1
#: Body parts whose contact with a tread counts as crawling (``GaitTrace.body_contact`` columns).
CRAWL_PARTS: dict[str, tuple[str, ...]] = {
    "arms": ("right_upper_arm", "right_lower_arm", "right_hand", "left_upper_arm", "left_lower_arm", "left_hand"),
    "legs": ("right_thigh", "right_shin", "left_thigh", "left_shin"),
    "trunk": ("pelvis", "torso", "head"),
}
PATTERNS: tuple[str, ...] = ("step-over-step", "step-to-step", "irregular", "none")

TOP_TOLERANCE = 0.02   # m below a block's top that still counts as its top face
MERGE_GAP = 2          # frames of air on one level that are contact flicker, not a step
HOP_WINDOW = 0.2       # s between the two feet's take-offs (and touchdowns) of a hop
CRAWL_MIN_TIME = 0.1   # s of arm / knee / trunk contact with treads that make a crawl
SLIDE_SPEED = 0.1      # m/s of slip above which a stance frame slides


# --- the trace ------------------------------------------------------------------
@dataclass(frozen=True)
class GaitTrace:
    """One episode's contacts, frame by frame (T frames ``dt`` apart).

    Only ``support`` is needed; the other arrays default to "nothing known" (no crawl contacts,
    feet without poses: slip undefined) so that synthetic sequences stay short.
    """

    support: np.ndarray                      # (T, 2) int: level under each foot, AIR = -1
    dt: float = 1.0 / 30.0                   # s between frames
    num_steps: int | None = None             # risers n of the staircase (level n = landing); None: the top level seen
    body_contact: np.ndarray | None = None   # (T, 3) bool: arms, legs, trunk on a tread top
    contact_point: np.ndarray | None = None  # (T, 2, 3): each foot's contact centroid on its level (nan in the air)
    foot_pos: np.ndarray | None = None       # (T, 2, 3): foot body origins
    foot_rot: np.ndarray | None = None       # (T, 2, 3, 3): foot body rotations (world from body); None: identity

    def __post_init__(self) -> None:
        support = np.asarray(self.support, dtype=np.int64).reshape(-1, 2)
        frames = len(support)
        if support.size and support.min() < AIR:
            raise ValueError(f"support levels must be >= {AIR}, got {support.min()}")
        if not (math.isfinite(self.dt) and self.dt > 0):
            raise ValueError(f"dt must be a positive number of seconds, got {self.dt!r}")
        object.__setattr__(self, "support", support)
        top = int(support.max(initial=0))
        object.__setattr__(self, "num_steps", top if self.num_steps is None else int(self.num_steps))
        contact = np.zeros((frames, len(CRAWL_PARTS)), bool) if self.body_contact is None else self.body_contact
        object.__setattr__(self, "body_contact", np.asarray(contact, dtype=bool).reshape(frames, len(CRAWL_PARTS)))
        for name, shape in (("contact_point", (frames, 2, 3)), ("foot_pos", (frames, 2, 3)),
                            ("foot_rot", (frames, 2, 3, 3))):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, np.asarray(value, dtype=np.float64).reshape(shape))

    @property
    def frames(self) -> int:
        return len(self.support)


class GaitRecorder:
    """Reads each frame's foot supports, crawl contacts and foot poses off an ``MjData``.

    ``model`` holds the humanoid, a geom named ``floor`` and the staircase written by
    ``StairsSlots`` (geoms ``{stairs_prefix}_step{i}``: the block of tread i + 1). Contacts
    farther apart than ``max_distance`` (m) are ignored; the physics only makes contacts that
    touch (distance <= the geoms' margin, 0 in the envs).
    """

    def __init__(self, model: mujoco.MjModel, stairs_prefix: str = "stairs", top_tolerance: float = TOP_TOLERANCE,
                 max_distance: float = math.inf) -> None:
        self.model = model
        self.top_tolerance = float(top_tolerance)
        self.max_distance = float(max_distance)
        self.foot_body_ids = np.array([model.body(name).id for name in FOOT_BODIES])
        self.geom_foot = np.full(model.ngeom, -1)
        self.geom_part = np.full(model.ngeom, -1)
        for foot, body in enumerate(self.foot_body_ids):
            self.geom_foot[model.geom_bodyid == body] = foot
        for part, bodies in enumerate(CRAWL_PARTS.values()):
            for name in bodies:
                self.geom_part[model.geom_bodyid == model.body(name).id] = part
        self.geom_level = np.full(model.ngeom, -1)
        self.geom_level[model.geom("floor").id] = 0
        for slot in range(model.ngeom):
            name = model.geom(slot).name
            if name.startswith(f"{stairs_prefix}_step") and name[len(stairs_prefix) + 5:].isdigit():
                self.geom_level[model.geom(slot).id] = int(name[len(stairs_prefix) + 5:]) + 1
        self.reset()

    def reset(self) -> None:
        """Forget the recorded frames (a new episode)."""
        self._support: list[np.ndarray] = []
        self._points: list[np.ndarray] = []
        self._body: list[np.ndarray] = []
        self._pos: list[np.ndarray] = []
        self._rot: list[np.ndarray] = []

    def record(self, data: mujoco.MjData) -> None:
        """Append the frame in ``data`` (after ``mj_forward`` or ``mj_step``: contacts and poses current)."""
        support = np.full(2, AIR)
        points = np.full((2, 3), np.nan)
        body = np.zeros(len(CRAWL_PARTS), bool)
        n = data.ncon
        if n:
            geoms = data.contact.geom[:n]
            pos = data.contact.pos[:n]
            keep = data.contact.dist[:n] <= self.max_distance
            levels = self.geom_level[geoms]
            # the side that is a surface (floor or a tread block) and the side that is the body
            surface_side = np.where(levels[:, 0] >= 0, 0, 1)
            rows = np.arange(n)
            surface = geoms[rows, surface_side]
            other = geoms[rows, 1 - surface_side]
            level = self.geom_level[surface]
            top = data.geom_xpos[surface, 2] + np.where(level > 0, self.model.geom_size[surface, 2], 0.0)
            on_top = keep & (level >= 0) & (self.geom_level[other] < 0) & (pos[:, 2] >= top - self.top_tolerance)
            for foot in (0, 1):
                mine = on_top & (self.geom_foot[other] == foot)
                if mine.any():
                    highest = level[mine].max()
                    at = mine & (level == highest)
                    support[foot] = highest
                    points[foot] = pos[at].mean(axis=0)
            parts = self.geom_part[other[on_top & (level > 0)]]
            body[parts[parts >= 0]] = True
        self._support.append(support)
        self._points.append(points)
        self._body.append(body)
        self._pos.append(data.xpos[self.foot_body_ids].copy())
        self._rot.append(data.xmat[self.foot_body_ids].reshape(2, 3, 3).copy())

    def trace(self, dt: float, num_steps: int | None = None) -> GaitTrace:
        """The frames recorded since the last :meth:`reset`."""
        frames = len(self._support)
        return GaitTrace(
            support=np.array(self._support, dtype=np.int64).reshape(frames, 2), dt=dt, num_steps=num_steps,
            body_contact=np.array(self._body, dtype=bool).reshape(frames, len(CRAWL_PARTS)),
            contact_point=np.array(self._points).reshape(frames, 2, 3),
            foot_pos=np.array(self._pos).reshape(frames, 2, 3),
            foot_rot=np.array(self._rot).reshape(frames, 2, 3, 3),
        )


# --- footholds ------------------------------------------------------------------
@dataclass(frozen=True)
class Foothold:
    """A foot on one level from frame ``start`` to ``end`` (inclusive)."""

    foot: int   # 0 right, 1 left
    level: int  # 0 floor, k tread k
    start: int
    end: int


def fill_flicker(support: np.ndarray, merge_gap: int = MERGE_GAP) -> np.ndarray:
    """``support`` (T, 2) with air gaps of at most ``merge_gap`` frames between two frames of one
    foot on the same level filled with that level."""
    filled = np.array(support, dtype=np.int64, copy=True).reshape(-1, 2)
    for foot in (0, 1):
        column = filled[:, foot]
        last, last_level = None, AIR
        for t, level in enumerate(column.tolist()):
            if level == AIR:
                continue
            if last is not None and level == last_level and 1 < t - last <= merge_gap + 1:
                column[last + 1:t] = level
            last, last_level = t, level
    return filled


def footholds(trace: GaitTrace, merge_gap: int = MERGE_GAP) -> list[Foothold]:
    """The footholds of both feet (after :func:`fill_flicker`), ordered by start, right foot first."""
    support = fill_flicker(trace.support, merge_gap)
    holds = []
    for foot in (0, 1):
        column = support[:, foot]
        start = None
        for t in range(len(column) + 1):
            level = column[t] if t < len(column) else AIR - 1
            if start is not None and level != column[start]:
                holds.append(Foothold(foot, int(column[start]), start, t - 1))
                start = None
            if start is None and t < len(column) and level != AIR:
                start = t
    return sorted(holds, key=lambda h: (h.start, h.foot))


def arrivals(holds: Sequence[Foothold]) -> list[Foothold]:
    """The footholds on a level higher than every level stood on before (``holds`` ordered by start)."""
    found, highest = [], -math.inf
    for hold in holds:
        if hold.level > highest:
            found.append(hold)
        highest = max(highest, hold.level)
    return found


def tread_arrivals(holds: Sequence[Foothold]) -> list[Foothold]:
    """:func:`arrivals` on treads (levels >= 1)."""
    return [hold for hold in arrivals(holds) if hold.level >= 1]


def is_alternating(climb: Sequence[Foothold]) -> bool:
    """At least two arrivals and no two consecutive ones by the same foot."""
    return len(climb) >= 2 and all(a.foot != b.foot for a, b in pairwise(climb))


def gait_pattern(holds: Sequence[Foothold]) -> str:
    """One of :data:`PATTERNS` (module docstring, metric (a))."""
    climb = tread_arrivals(holds)
    if len(climb) < 2:
        return "none"
    if is_alternating(climb):
        return "step-over-step"
    top = max(hold.level for hold in holds)
    visited = [{hold.level for hold in holds if hold.foot == foot} for foot in (0, 1)]
    if all(level in visited[0] and level in visited[1] for level in range(1, top)):
        return "step-to-step"
    return "irregular"


def touchdowns_per_tread(holds: Sequence[Foothold], num_steps: int) -> float | None:
    """Footholds on treads 1..min(top level, num_steps - 1) per tread; None when none was reached."""
    top = max((hold.level for hold in holds), default=0)
    last = min(top, num_steps - 1)
    if last < 1:
        return None
    return sum(1 <= hold.level <= last for hold in holds) / last


def count_hops(trace: GaitTrace, holds: Sequence[Foothold] | None = None, merge_gap: int = MERGE_GAP,
               hop_window: float = HOP_WINDOW) -> int:
    """Flights after which both feet land higher than both left from, together (metric (c))."""
    holds = footholds(trace, merge_gap) if holds is None else holds
    support = fill_flicker(trace.support, merge_gap)
    flying = (support == AIR).all(axis=1)
    window = hop_window / trace.dt + 1e-9
    hops, t = 0, 0
    while t < len(flying):
        if not flying[t]:
            t += 1
            continue
        end = t
        while end + 1 < len(flying) and flying[end + 1]:
            end += 1
        before = [max((h for h in holds if h.foot == foot and h.end < t), key=lambda h: h.end, default=None)
                  for foot in (0, 1)]
        after = [min((h for h in holds if h.foot == foot and h.start > end), key=lambda h: h.start, default=None)
                 for foot in (0, 1)]
        if None not in before and None not in after:
            left_from = max(h.level for h in before)
            if (all(h.level > left_from for h in after) and abs(before[0].end - before[1].end) <= window
                    and abs(after[0].start - after[1].start) <= window):
                hops += 1
        t = end + 1
    return hops


def slip_speeds(trace: GaitTrace) -> np.ndarray:
    """(T, 2) slip speed (m/s) of each foot (metric (e)); nan where the foot is not on the same level
    in frames t - 1 and t, or where the trace has no foot poses or contact points."""
    speeds = np.full((trace.frames, 2), np.nan)
    if trace.frames < 2 or trace.foot_pos is None or trace.contact_point is None:
        return speeds
    rot = trace.foot_rot if trace.foot_rot is not None else np.broadcast_to(np.eye(3), (trace.frames, 2, 3, 3))
    support = trace.support
    stance = (support[1:] == support[:-1]) & (support[1:] != AIR)
    before = trace.contact_point[:-1]
    # the material point under the contact centroid at t - 1, in foot coordinates, then back in the world at t
    local = np.einsum("tfji,tfj->tfi", rot[:-1], before - trace.foot_pos[:-1])
    moved = np.einsum("tfij,tfj->tfi", rot[1:], local) + trace.foot_pos[1:]
    speed = np.linalg.norm((moved - before)[..., :2], axis=-1) / trace.dt
    speeds[1:] = np.where(stance & np.isfinite(speed), speed, np.nan)
    return speeds


# --- an episode's summary ---------------------------------------------------------
@dataclass(frozen=True)
class GaitSummary:
    """The gait metrics of one episode (module docstring)."""

    pattern: str                          # one of PATTERNS
    alternating: bool                     # (a) tread arrivals by alternating feet
    arrivals: int                         # arrivals on treads
    top_level: int                        # highest level a foot stood on (num_steps = the landing)
    touchdowns_per_tread: float | None    # (b)
    hops: int                             # (c)
    crawl_time: float                     # (d) s of arm / knee / trunk contact with tread tops
    crawled: bool                         # (d) crawl_time >= crawl_min_time
    crawl_parts: tuple[str, ...]          # (d) the parts that touched, of CRAWL_PARTS
    stance_frames: int                    # (e) foot-frames on the same level as the frame before
    sliding_frames: int                   # (e) of those, slipping faster than slide_speed
    max_slip_speed: float | None          # (e) m/s, None without stance frames
    arrival_feet: tuple[int, ...] = field(default=())  # the foot of each tread arrival, in order

    @property
    def slide_fraction(self) -> float | None:
        return self.sliding_frames / self.stance_frames if self.stance_frames else None


def summarize(trace: GaitTrace, merge_gap: int = MERGE_GAP, hop_window: float = HOP_WINDOW,
              crawl_min_time: float = CRAWL_MIN_TIME, slide_speed: float = SLIDE_SPEED) -> GaitSummary:
    """All metrics of one episode's trace."""
    holds = footholds(trace, merge_gap)
    climb = tread_arrivals(holds)
    crawl_frames = trace.body_contact.any(axis=1)
    crawl_time = float(crawl_frames.sum() * trace.dt)
    speeds = slip_speeds(trace)
    stance = np.isfinite(speeds)
    return GaitSummary(
        pattern=gait_pattern(holds),
        alternating=is_alternating(climb),
        arrivals=len(climb),
        top_level=max((h.level for h in holds), default=0),
        touchdowns_per_tread=touchdowns_per_tread(holds, trace.num_steps),
        hops=count_hops(trace, holds, merge_gap, hop_window),
        crawl_time=crawl_time,
        crawled=crawl_time >= crawl_min_time - 1e-9,
        crawl_parts=tuple(name for name, touched in zip(CRAWL_PARTS, trace.body_contact.any(axis=0)) if touched),
        stance_frames=int(stance.sum()),
        sliding_frames=int((speeds[stance] > slide_speed).sum()),
        max_slip_speed=float(speeds[stance].max()) if stance.any() else None,
        arrival_feet=tuple(h.foot for h in climb),
    )


# --- the report's columns -----------------------------------------------------------
#: Row keys that ``evaluate(..., gait=True)`` adds (see :func:`gait_columns`).
GAIT_FIELDS: tuple[str, ...] = ("alternating_pct", "touchdowns_per_tread", "hop_pct", "crawl_pct", "slide_pct")


def gait_columns(summaries: Sequence[GaitSummary], successes: Sequence[bool]) -> dict[str, Any]:
    """The gait columns of a group of episodes (None where undefined):

    - ``alternating_pct``: % of the successful climbs whose tread arrivals alternate feet;
    - ``touchdowns_per_tread``: mean over the episodes that reached a tread;
    - ``hop_pct``, ``crawl_pct``: % of the episodes with a hop, with a crawl;
    - ``slide_pct``: % of all stance frames of the group's episodes that slide.
    """
    if len(summaries) != len(successes):
        raise ValueError(f"{len(summaries)} summaries but {len(successes)} success flags")
    n = len(summaries)
    climbs = [s for s, ok in zip(summaries, successes) if ok]
    per_tread = [s.touchdowns_per_tread for s in summaries if s.touchdowns_per_tread is not None]
    stance = sum(s.stance_frames for s in summaries)

    def share(flags: Sequence[bool]) -> float | None:
        return 100.0 * sum(flags) / len(flags) if flags else None

    return {
        "alternating_pct": share([s.alternating for s in climbs]),
        "touchdowns_per_tread": float(np.mean(per_tread)) if per_tread else None,
        "hop_pct": share([s.hops > 0 for s in summaries]) if n else None,
        "crawl_pct": share([s.crawled for s in summaries]) if n else None,
        "slide_pct": 100.0 * sum(s.sliding_frames for s in summaries) / stance if stance else None,
    }


__all__ = [
    "AIR", "CRAWL_MIN_TIME", "CRAWL_PARTS", "GAIT_FIELDS", "HOP_WINDOW", "MERGE_GAP", "PATTERNS", "SLIDE_SPEED",
    "TOP_TOLERANCE", "Foothold", "GaitRecorder", "GaitSummary", "GaitTrace", "arrivals", "count_hops",
    "fill_flicker", "footholds", "gait_columns", "gait_pattern", "is_alternating", "slip_speeds", "summarize",
    "touchdowns_per_tread", "tread_arrivals",
]
