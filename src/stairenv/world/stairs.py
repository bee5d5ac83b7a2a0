"""Procedural staircases (InterLevel).

A staircase is described in its own frame: ``u`` along the ascent, ``w`` across it
(to the left), ``z`` up. The origin is the foot of the first riser, on the
centre line. Tread ``k`` (1..n) is a solid box from the ground to height ``k*h``:
treads 1..n-1 are ``depth`` deep, tread n is the top floor (landing),
``landing_depth`` deep. Solid blocks leave no gap to fall through and cost one
box-box or box-capsule test each.

Markers (paper Fig. 4) sit at the height of a standing character's root, so
that the height progress (p_z - M_B_z) / (M_T_z - M_B_z) runs from 0 at the
bottom to 1 when standing on the landing:
- ``M_B`` at the foot of the stairs (u = 0, w = 0),
- ``M_T`` on the landing centre (the target).

The world frame is the arena: its centre is the origin. The staircase is rotated
by ``yaw`` (the ascent direction) and pushed ``distance`` along it, so that
its front faces the arena centre.

``generate_stairs(config, rng)`` is pure; ``StairsSlots`` adds reusable step
bodies to an ``MjSpec`` once and ``StairsSlots.place`` writes a new staircase
into the compiled model at every reset (no recompilation).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass, fields
from typing import NamedTuple

import mujoco
import numpy as np

from stairenv.humanoid import STANDING_ROOT_HEIGHT
from stairenv.validation import Check, check_number, check_range, checked, field_check

# The four fixed-height evaluation sets of the paper (Tables 1-3, Fig. 9).
PAPER_TEST_HEIGHTS: tuple[float, ...] = (0.05, 0.10, 0.15, 0.20)


@dataclass(frozen=True)
class StairsConfig:
    """Ranges from which staircases are sampled (uniformly). Lengths in metres, angles in radians.

    | field | default | valid |
    |---|---|---|
    | step_height | (0.05, 0.20) | within [0.01, 0.40] (the paper: 0.05-0.20) |
    | step_height_set | None | a non-empty set of heights in [0.01, 0.40]: sample from it instead (test sets) |
    | step_depth | (0.25, 0.40) | within [0.15, 1.0] |
    | step_width | (1.0, 2.0) | within [0.5, 5.0] |
    | num_steps | (3, 10) | integers within [1, 30]; risers, the landing's included |
    | landing_depth | 2.0 | [1.0, 10.0] |
    | distance | (2.0, 3.0) | within [0.5, 20]; arena centre to the foot of the stairs |
    | yaw | (0, 2 pi) | within [-2 pi, 2 pi]; ascent direction |
    """

    # each field's valid range, declared once: checked here, and under the env's keywords by
    # stairenv.environments.config (typed there)
    step_height: tuple[float, float] = checked((0.05, 0.20), Check("pair", 0.01, 0.40), "step height range (m)")
    step_height_set: tuple[float, ...] | None = checked(
        None, Check("numbers", 0.01, 0.40, optional=True),
        "sample step heights from this set instead, e.g. (0.05, 0.1, 0.15, 0.2) (the test sets)")
    step_depth: tuple[float, float] = checked((0.25, 0.40), Check("pair", 0.15, 1.0), "tread depth range (m)")
    step_width: tuple[float, float] = checked((1.0, 2.0), Check("pair", 0.5, 5.0), "step width range (m)")
    num_steps: tuple[int, int] = checked((3, 10), Check("pair", 1, 30, integer=True),
                                       "risers, the landing's included")
    landing_depth: float = checked(2.0, Check("float", 1.0, 10.0), "top floor depth (m)")
    distance: tuple[float, float] = checked((2.0, 3.0), Check("pair", 0.5, 20.0),
                                             "arena centre to the foot of the stairs (m)")
    yaw: tuple[float, float] = checked((0.0, 2.0 * math.pi), Check("pair", -2.0 * math.pi, 2.0 * math.pi),
                                        "ascent direction range (rad)")

    def __post_init__(self) -> None:
        # Keyword values may arrive as lists (e.g. from TOML presets): store tuples.
        bounds = STAIRS_CONFIG_RANGES
        for name in ("step_height", "step_depth", "step_width", "num_steps", "distance", "yaw"):
            object.__setattr__(self, name, tuple(getattr(self, name)))
        if self.step_height_set is not None:
            object.__setattr__(self, "step_height_set", tuple(float(h) for h in self.step_height_set))
        check_range("step_height", self.step_height, *bounds["step_height"])
        if self.step_height_set is not None:
            low, high = bounds["step_height_set"]
            if len(self.step_height_set) == 0 or any(not (low <= h <= high) for h in self.step_height_set):
                raise ValueError(
                    f"step_height_set must be a non-empty set of heights in [{low:.2f}, {high:.2f}], "
                    f"got {self.step_height_set!r}"
                )
        check_range("step_depth", self.step_depth, *bounds["step_depth"])
        check_range("step_width", self.step_width, *bounds["step_width"])
        check_range("num_steps", self.num_steps, *bounds["num_steps"])
        if any(int(n) != n for n in self.num_steps):
            raise ValueError(f"num_steps must be integers within [1, 30], got {self.num_steps!r}")
        check_number("landing_depth", self.landing_depth, *bounds["landing_depth"])
        check_range("distance", self.distance, *bounds["distance"])
        check_range("yaw", self.yaw, *bounds["yaw"])

    @property
    def max_steps(self) -> int:
        return int(self.num_steps[1])

    @property
    def height_range(self) -> tuple[float, float]:
        """The lowest and highest step height drawn: ``step_height``, or ``step_height_set``'s extremes."""
        if self.step_height_set is None:
            return self.step_height
        return min(self.step_height_set), max(self.step_height_set)


#: each ``StairsConfig`` field's valid (low, high), from its declared check: what a drawn staircase keeps to
STAIRS_CONFIG_RANGES = {field.name: (field_check(field).low, field_check(field).high) for field in fields(StairsConfig)}


@dataclass(frozen=True)
class Staircase:
    """One staircase, fully determined by these numbers."""

    step_height: float
    step_depth: float
    width: float
    num_steps: int
    landing_depth: float
    yaw: float
    distance: float

    # --- frames --------------------------------------------------------------
    @functools.cached_property
    def _frame(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(axis, across, origin, rotation), computed once (a reset reads them a dozen times), read-only."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        axis, across = np.array([c, s, 0.0]), np.array([-s, c, 0.0])
        origin = self.distance * axis
        rotation = np.stack((axis, across, np.array([0.0, 0.0, 1.0])), axis=1)
        for array in (axis, across, origin, rotation):
            array.flags.writeable = False
        return axis, across, origin, rotation

    @property
    def axis(self) -> np.ndarray:
        """Unit ascent direction in the world (horizontal)."""
        return self._frame[0]

    @property
    def across(self) -> np.ndarray:
        """Unit direction across the stairs, to the left of the ascent."""
        return self._frame[1]

    @property
    def origin(self) -> np.ndarray:
        """World position of the foot of the first riser on the centre line."""
        return self._frame[2]

    @property
    def rotation(self) -> np.ndarray:
        """World-from-stairs rotation matrix: columns (u, w, z)."""
        return self._frame[3]

    def to_local(self, points: np.ndarray) -> np.ndarray:
        """World points (..., 3) -> stairs frame (u, w, z)."""
        return (np.asarray(points) - self.origin) @ self.rotation

    def to_world(self, points: np.ndarray) -> np.ndarray:
        return np.asarray(points) @ self.rotation.T + self.origin

    # --- geometry ------------------------------------------------------------
    @property
    def top_height(self) -> float:
        return self.num_steps * self.step_height

    @property
    def landing_start(self) -> float:
        """u of the landing's front edge (the top riser)."""
        return (self.num_steps - 1) * self.step_depth

    def local_boxes(self) -> tuple[np.ndarray, np.ndarray]:
        """Centres and half sizes (n, 3) of the n tread blocks, in the stairs frame."""
        step_height, step_depth, width, num_steps, landing_depth, _, _ = _numbers([self])
        centres, half = _tread_boxes(step_height, step_depth, width, num_steps, landing_depth, self.num_steps)
        return centres[0], half[0]

    def world_boxes(self) -> tuple[np.ndarray, np.ndarray]:
        """Centres and half sizes (n, 3) of the n tread blocks, in the world."""
        layout = StairsLayout.of([self], self.num_steps)
        return layout.centres[0], layout.half[0]

    def surface_height(self, points: np.ndarray) -> np.ndarray:
        """Height of the walkable surface (tread top or floor) under world points (..., 2|3)."""
        pts = np.asarray(points, dtype=float)
        xyz = np.concatenate((pts[..., :2], np.zeros(pts.shape[:-1] + (1,))), axis=-1)
        local = self.to_local(xyz)
        u, w = local[..., 0], local[..., 1]
        on = (u >= 0) & (u <= self.landing_start + self.landing_depth) & (np.abs(w) <= self.width / 2)
        k = np.minimum(np.floor(u / self.step_depth) + 1, self.num_steps)
        return np.where(on, k * self.step_height, 0.0)

    # --- markers -------------------------------------------------------------
    @property
    def marker_bottom_local(self) -> np.ndarray:
        return np.array([0.0, 0.0, STANDING_ROOT_HEIGHT])

    @property
    def marker_top_local(self) -> np.ndarray:
        return np.array(
            [self.landing_start + self.landing_depth / 2, 0.0, self.top_height + STANDING_ROOT_HEIGHT]
        )

    @functools.cached_property
    def _markers(self) -> tuple[np.ndarray, np.ndarray]:
        """(M_B, M_T) in the world, computed once (a reset reads each twice), read-only."""
        layout = StairsLayout.of([self], 0)
        markers = layout.marker_bottom[0], layout.marker_top[0]
        for array in markers:
            array.flags.writeable = False
        return markers

    @property
    def marker_bottom(self) -> np.ndarray:
        """M_B in the world."""
        return self._markers[0]

    @property
    def marker_top(self) -> np.ndarray:
        """M_T in the world: the target."""
        return self._markers[1]

    def as_dict(self) -> dict[str, float | int]:
        return {name: getattr(self, name) for name in _FIELDS}


_FIELDS = tuple(field.name for field in fields(Staircase))


def _numbers(stairs: Sequence[Staircase]) -> tuple[np.ndarray, ...]:
    """The staircases' defining numbers as arrays over them (row i: ``stairs[i]``)."""
    return tuple(np.array([getattr(s, name) for s in stairs]) for name in _FIELDS)


def _tread_boxes(step_height, step_depth, width, num_steps, landing_depth,
                 slots: int) -> tuple[np.ndarray, np.ndarray]:
    """Centres and half sizes (B, slots, 3) in the stairs frame of treads 1..slots of B staircases (the
    arrays of ``_numbers``): tread k is a solid block from the ground to ``k * step_height``, the last one
    (k = num_steps) the landing, ``landing_depth`` deep. Rows past a staircase's ``num_steps`` are what the
    formula gives (``StairsLayout`` parks them)."""
    k = np.arange(1, slots + 1)
    depth = np.where(k == num_steps[:, None], landing_depth[:, None], step_depth[:, None])
    front = (k - 1) * step_depth[:, None]
    height = k * step_height[:, None]
    centres = np.stack((front + depth / 2, np.zeros_like(depth), height / 2), axis=-1)
    half = np.stack((depth / 2, np.broadcast_to(width[:, None] / 2, depth.shape), height / 2), axis=-1)
    return centres, half


class StairsLayout(NamedTuple):
    """B staircases in the world as arrays (row i: staircase i): what a reset writes into the model
    (``StairsSlots.place_layout``) and what the task's goal reads (``StairsGoal.of_layout``), made in a few
    array operations however many staircases a batch of resets draws.

    Every point lies on the centre line (w = 0), so the stairs-to-world transform of ``Staircase.to_world``
    reduces to ``origin + u * axis + z * up``: the terms it drops are exact zeros, so the numbers are the
    same to the last bit."""

    step_height: np.ndarray     # (B,)
    step_depth: np.ndarray      # (B,)
    width: np.ndarray           # (B,)
    num_steps: np.ndarray       # (B,) int
    landing_depth: np.ndarray   # (B,)
    yaw: np.ndarray             # (B,)
    distance: np.ndarray        # (B,)
    axis: np.ndarray            # (B, 3) unit ascent direction
    across: np.ndarray          # (B, 3) unit direction across, to the left
    origin: np.ndarray          # (B, 3) foot of the first riser on the centre line
    marker_bottom_local: np.ndarray    # (B, 3) M_B, stairs frame
    marker_top_local: np.ndarray       # (B, 3) M_T, stairs frame
    marker_bottom: np.ndarray   # (B, 3) M_B, world
    marker_top: np.ndarray      # (B, 3) M_T, world
    centres: np.ndarray         # (B, slots, 3) treads' centres, world; unused slots parked
    half: np.ndarray            # (B, slots, 3) treads' half sizes; unused slots parked
    rbound: np.ndarray          # (B, slots) treads' bounding radii (the half sizes' norms)
    quat: np.ndarray            # (B, 4) the treads' orientation (a yaw), wxyz

    @classmethod
    def of(cls, stairs: Sequence[Staircase], slots: int) -> StairsLayout:
        """The layout of ``stairs`` over ``slots`` tread slots: at least each staircase's ``num_steps`` for its
        treads (fewer keep the first ``slots``; 0: the markers and frames alone)."""
        step_height, step_depth, width, num_steps, landing_depth, yaw, distance = _numbers(stairs)
        # math's cos and sin, as Staircase's frame and the quaternion have always used (numpy's may differ in
        # the last bit)
        cos = np.array([math.cos(s.yaw) for s in stairs])
        sin = np.array([math.sin(s.yaw) for s in stairs])
        zero = np.zeros_like(cos)
        axis, across = np.stack((cos, sin, zero), axis=-1), np.stack((-sin, cos, zero), axis=-1)
        origin = distance[:, None] * axis
        top_height = num_steps * step_height
        landing_start = (num_steps - 1) * step_depth
        standing = np.full_like(cos, STANDING_ROOT_HEIGHT)
        bottom_local = np.stack((zero, zero, standing), axis=-1)
        top_local = np.stack((landing_start + landing_depth / 2, zero, top_height + STANDING_ROOT_HEIGHT), axis=-1)
        centres, half = _tread_boxes(step_height, step_depth, width, num_steps, landing_depth, slots)
        parked = np.arange(slots) >= num_steps[:, None]
        world_centres = _on_centre_line(centres, axis, origin)
        world_centres[parked], half[parked] = _PARKED_POS, _PARKED_HALF
        quat = np.stack((np.array([math.cos(s.yaw / 2) for s in stairs]), zero, zero,
                         np.array([math.sin(s.yaw / 2) for s in stairs])), axis=-1)
        return cls(step_height, step_depth, width, num_steps, landing_depth, yaw, distance, axis, across, origin,
                   bottom_local, top_local, _on_centre_line(bottom_local, axis, origin),
                   _on_centre_line(top_local, axis, origin), world_centres, half,
                   np.sqrt(np.add.reduce(half * half, axis=-1)), quat)    # np.linalg.norm's operations


def _on_centre_line(local: np.ndarray, axis: np.ndarray, origin: np.ndarray) -> np.ndarray:
    """Stairs-frame points (B, ..., 3) with w = 0 in the world (row i in staircase i's frame)."""
    extra = (slice(None),) + (None,) * (local.ndim - 2)
    u, z = local[..., 0:1], local[..., 2]
    world = u * axis[extra] + origin[extra]
    world[..., 2] = z
    return world


def generate_stairs(config: StairsConfig, rng: np.random.Generator) -> Staircase:
    """Sample one staircase from ``config`` with ``rng`` (pure: same rng state, same stairs)."""
    if config.step_height_set is not None:
        height = float(rng.choice(np.asarray(config.step_height_set)))
    else:
        height = float(rng.uniform(*config.step_height))
    return Staircase(
        step_height=height,
        step_depth=float(rng.uniform(*config.step_depth)),
        width=float(rng.uniform(*config.step_width)),
        num_steps=int(rng.integers(config.num_steps[0], config.num_steps[1] + 1)),
        landing_depth=float(config.landing_depth),
        yaw=float(rng.uniform(*config.yaw)),
        distance=float(rng.uniform(*config.distance)),
    )


# Where unused step slots wait: a sliver below the floor, out of reach and out of view.
_PARKED_POS = np.array([0.0, 0.0, -5.0])
_PARKED_HALF = np.array([0.01, 0.01, 0.01])

STAIRS_RGBA = (0.72, 0.68, 0.6, 1.0)
MARKER_RGBA = (0.9, 0.1, 0.1, 1.0)
MARKER_RADIUS = 0.08


def _rows(ids: np.ndarray) -> slice | np.ndarray:
    """``ids`` as a slice when they are consecutive and ascending, else as they are."""
    ids = np.asarray(ids)
    if len(ids) and np.array_equal(ids, np.arange(ids[0], ids[0] + len(ids))):
        return slice(int(ids[0]), int(ids[0]) + len(ids))
    return ids


class StairsSlots:
    """``max_steps`` step bodies and the two markers, built once with MjSpec.

    Each tread is its own static body with a single box geom at the body origin,
    so a new staircase is written by changing body poses, box sizes and the
    bodies' bounding boxes in the compiled model. (MuJoCo computes a body's
    bounding-volume hierarchy at compile time; with one geom per body it is a
    single box that ``place`` resizes. Moving several geoms of one body would
    need the whole hierarchy rebuilt.)
    """

    def __init__(self, spec: mujoco.MjSpec, max_steps: int, prefix: str = "stairs") -> None:
        self.max_steps = int(max_steps)
        self.prefix = prefix
        for i in range(self.max_steps):
            body = spec.worldbody.add_body(name=f"{prefix}_step{i}", pos=_PARKED_POS)
            body.add_geom(
                name=f"{prefix}_step{i}",
                type=mujoco.mjtGeom.mjGEOM_BOX,
                size=_PARKED_HALF,
                rgba=STAIRS_RGBA,
                condim=3,
            )
        for marker in ("marker_bottom", "marker_top"):
            body = spec.worldbody.add_body(name=f"{prefix}_{marker}", pos=_PARKED_POS)
            body.add_geom(
                name=f"{prefix}_{marker}",
                type=mujoco.mjtGeom.mjGEOM_SPHERE,
                size=[MARKER_RADIUS, 0, 0],
                rgba=MARKER_RGBA,
                contype=0,
                conaffinity=0,
                group=2,
            )
        self._body_ids: np.ndarray | None = None
        self._field_views: tuple | None = None

    def bind(self, model: mujoco.MjModel) -> None:
        """Look up ids in the compiled model (call once after compile)."""
        self._body_ids = np.array([model.body(f"{self.prefix}_step{i}").id for i in range(self.max_steps)])
        self._geom_ids = np.array([model.geom(f"{self.prefix}_step{i}").id for i in range(self.max_steps)])
        self._marker_ids = np.array(
            [model.body(f"{self.prefix}_{m}").id for m in ("marker_bottom", "marker_top")]
        )
        # The rows ``place`` writes, as slices where consecutive (as built): a slice assignment costs
        # a fraction of a fancy-indexed one, and a reset makes ten of them.
        self._body_rows, self._geom_rows = _rows(self._body_ids), _rows(self._geom_ids)
        self._bvh_rows = _rows(model.body_bvhadr[self._body_ids])

    @property
    def geom_ids(self) -> np.ndarray:
        return self._geom_ids

    def place(self, model: mujoco.MjModel, stairs: Staircase) -> None:
        """Write ``stairs`` into ``model`` (call mj_forward afterwards)."""
        self.place_layout(model, self.layout([stairs]), 0)

    def layout(self, stairs: Sequence[Staircase]) -> StairsLayout:
        """``StairsLayout`` of ``stairs`` over this model's slots (a ``ValueError`` if one has too many steps)."""
        self._check_bound()
        for s in stairs:
            if s.num_steps > self.max_steps:
                raise ValueError(f"staircase has {s.num_steps} steps; this model holds at most {self.max_steps}")
        return StairsLayout.of(stairs, self.max_steps)

    def place_layout(self, model: mujoco.MjModel, layout: StairsLayout, i: int) -> None:
        """Write staircase ``i`` of ``layout`` (made by ``layout``) into ``model`` (call mj_forward afterwards)."""
        self._check_bound()
        body_pos, body_quat, geom_size, geom_rbound, geom_aabb, bvh_aabb = self._fields(model)
        half = layout.half[i]
        bodies, geoms = self._body_rows, self._geom_rows
        body_pos[bodies] = layout.centres[i]
        body_quat[bodies] = layout.quat[i]
        geom_size[geoms] = half
        geom_rbound[geoms] = layout.rbound[i]
        geom_aabb[geoms, :3] = 0.0
        geom_aabb[geoms, 3:] = half
        # The body's bounding volume (used when the other body has several geoms, e.g. the
        # torso) is computed at compile time: resize it with the box (geom at the body origin).
        bvh = self._bvh_rows
        bvh_aabb[bvh, :3] = 0.0
        bvh_aabb[bvh, 3:] = half
        body_pos[self._marker_ids] = (layout.marker_bottom[i], layout.marker_top[i])

    def _fields(self, model: mujoco.MjModel) -> tuple[np.ndarray, ...]:
        """The model fields ``place_layout`` writes, looked up once per model (a model's buffers never move;
        each lookup makes a new view)."""
        bound = self._field_views
        if bound is None or bound[0] is not model:
            bound = self._field_views = (model, (model.body_pos, model.body_quat, model.geom_size, model.geom_rbound,
                                                 model.geom_aabb, model.bvh_aabb))
        return bound[1]

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["_field_views"] = None    # a copy's views would be arrays of their own, not its model's
        return state

    def _check_bound(self) -> None:
        if self._body_ids is None:
            raise RuntimeError("StairsSlots.bind(model) must be called before place()")
