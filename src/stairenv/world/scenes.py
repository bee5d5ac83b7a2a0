"""PlaMo scenes: terrain, walls, low ceilings, moving obstacles and named landmarks.

A scene (PlaMo, Sec. 3) is

1. a terrain height map ``h(x, y)``,
2. static obstacles (walls) the character must go around,
3. dynamic obstacles whose motion the planner can predict,
4. top obstacles (low ceilings) the character must crouch or crawl under,
5. named landmarks ("tree", "swing", ...), each a set of grid cells.

Frames and units
----------------
World frame: z up, lengths in metres, angles in radians (unless a name ends in
``_deg``), time in seconds. The height map is sampled at the centres of the cells of
the grid that ``stairenv.planning.grid.PlanningGrid`` uses: cell (i, j) covers
x in [x0 + j c, x0 + (j + 1) c) and y in [y0 + i c, y0 + (i + 1) c), with
c = ``cell_size`` and (x0, y0) = ``origin``; **rows are y, columns are x**, and
``heights[i, j]`` is the ground height (world z) at the cell's centre. Between
centres the ground is interpolated (``Scene.height_at``: bilinear; MuJoCo's height
field: two planar triangles per square, equal at the centres and on planar ground).

Boxes (walls, ceilings) have vertical sides: a footprint rectangle centred at
``center`` with half extents ``half_size`` along its own axes u, v, where u is the
world x axis turned by ``yaw`` counter-clockwise about +z, and a z span
[``bottom``, ``top``]. A ceiling's ``bottom`` is the underside, in world z: the
planner compares it with the ground height and the head height of a locomotion.

What lives here
---------------
- ``Scene`` and its parts (``Box``, ``DynamicObstacle`` with a ``MotionModel``,
  ``Landmark``); ``Scene.planning_grid`` rasterises it for the planner;
  ``Scene.save`` / ``Scene.load`` store it as one ``.npz`` file.
- Terrain patch generators, pure functions of (config, rng): ``flat_patch``,
  ``slope_patch``, ``rough_patch``, ``stairs_patch`` (``generate_patch`` dispatches).
- ``generate_scene(config, rng)``: PlaMo's random 4-landmark scenes (Sec. 5.4).
- ``slalom_scene(...)``: the slalom test of Sec. 5.3 / Fig. 8.
- ``add_scene_to_spec(spec, scene)``: the MuJoCo model of a scene (a height field,
  one box geom per static body, mocap spheres for the dynamic obstacles, visual-only
  landmark markers); ``SceneHandles.update`` moves the obstacles over time.
"""

from __future__ import annotations

import abc
import json
import math
import zipfile
import zlib
from collections.abc import Sequence
from dataclasses import dataclass, field, fields
from os import PathLike
from typing import Any, ClassVar

import mujoco
import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from stairenv.planning.grid import PlanningGrid
from stairenv.validation import check_number, check_range

# Terrain kinds, in the order of ``Scene.terrain_labels`` codes and ``SceneConfig.terrain_weights``.
TERRAIN_KINDS: tuple[str, ...] = ("flat", "slope", "rough", "stairs")

# Landmark names of the paper's scenes (Fig. 1, 9) and a few more of the same kind.
DEFAULT_LANDMARK_NAMES: tuple[str, ...] = (
    "tree", "swing", "car", "bench", "fountain", "slide", "statue", "lamp",
)

SCENE_FILE_FORMAT = "stairenv.scene"
SCENE_FILE_VERSION = 1

# Height of a landmark's display position (its marker's top) above the ground (m).
LANDMARK_MARKER_HEIGHT = 1.0

# What ``Scene.load`` reads at most. A compressed file can declare arrays far larger than
# itself (3 MB of zeros inflate to 3 GB), so the declared sizes are checked first.
#: Cells of the height map (and of ``terrain_labels``): 4096 x 4096, 128 MiB of float64
#: (e.g. 200 m x 200 m at 5 cm).
MAX_SCENE_CELLS = 4096 * 4096
#: Bytes of the scene description (``scene_json``).
MAX_SCENE_JSON_BYTES = 16 * 2**20
#: Largest |height| (m) of a loaded height map; taller terrain means a corrupt file.
MAX_SCENE_HEIGHT = 1000.0


class SceneFileError(ValueError):
    """A scene file that cannot be read: not an ``.npz``, corrupt, incomplete or of another version."""


# --- small helpers -------------------------------------------------------------------------------
def _floats(name: str, value: Any, count: int) -> tuple[float, ...]:
    """``value`` as a tuple of ``count`` finite floats (lists from JSON become tuples)."""
    try:
        numbers = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be {count} finite numbers, got {value!r}") from None
    if len(numbers) != count or not all(math.isfinite(v) for v in numbers):
        raise ValueError(f"{name} must be {count} finite numbers, got {value!r}")
    return numbers


def _int_range(name: str, value: Sequence[float], low: int, high: int) -> tuple[int, int]:
    lo, hi = check_range(name, value, low, high)
    if int(lo) != lo or int(hi) != hi:
        raise ValueError(f"{name} must be a (min, max) pair of integers within [{low}, {high}], got {value!r}")
    return int(lo), int(hi)


def _from_mapping(cls: type, data: Any, what: str) -> dict[str, Any]:
    """Keyword arguments for dataclass ``cls`` from a JSON object, with clear errors."""
    if not isinstance(data, dict):
        raise TypeError(f"{what} must be a JSON object, got {type(data).__name__}")
    names = {f.name for f in fields(cls) if f.init}
    unknown = set(data) - names - {"kind"}
    if unknown:
        raise ValueError(f"{what} has unknown keys {sorted(unknown)}; expected {sorted(names)}")
    return {k: v for k, v in data.items() if k in names}


def _yaw_axes(yaw: float) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors u (the x axis turned by ``yaw``) and v (u turned by another 90 degrees)."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([c, s]), np.array([-s, c])


# --- boxes ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Box:
    """A box with vertical sides in the world frame (a wall, a ceiling slab, a pillar).

    Footprint: a rectangle centred at ``center`` (x, y), half extents ``half_size``
    (along u, v) where u is the x axis turned by ``yaw`` (rad, counter-clockwise about
    +z). Vertical span: z in [``bottom``, ``top``]. Metres.
    """

    center: tuple[float, float]
    half_size: tuple[float, float]
    yaw: float = 0.0
    bottom: float = 0.0
    top: float = 1.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", _floats("center", self.center, 2))
        half = _floats("half_size", self.half_size, 2)
        if min(half) <= 0.0:
            raise ValueError(f"half_size must be > 0, got {half!r}")
        object.__setattr__(self, "half_size", half)
        object.__setattr__(self, "yaw", check_number("yaw", self.yaw))
        bottom, top = check_number("bottom", self.bottom), check_number("top", self.top)
        if not top > bottom:
            raise ValueError(f"a box's top ({top}) must lie above its bottom ({bottom})")
        object.__setattr__(self, "bottom", bottom)
        object.__setattr__(self, "top", top)

    @property
    def axes(self) -> tuple[np.ndarray, np.ndarray]:
        """Unit vectors (u, v) of the footprint in the world's xy plane."""
        return _yaw_axes(self.yaw)

    @property
    def center_xyz(self) -> np.ndarray:
        return np.array([self.center[0], self.center[1], 0.5 * (self.bottom + self.top)])

    @property
    def half_extents_xyz(self) -> np.ndarray:
        return np.array([self.half_size[0], self.half_size[1], 0.5 * (self.top - self.bottom)])

    def corners_xy(self) -> np.ndarray:
        """The footprint's 4 corners (4, 2), counter-clockwise."""
        u, v = self.axes
        hu, hv = self.half_size
        signs = np.array([[1, 1], [-1, 1], [-1, -1], [1, -1]], dtype=float)
        return np.asarray(self.center) + (signs[:, :1] * hu) * u + (signs[:, 1:] * hv) * v

    def contains_xy(self, points: np.ndarray) -> np.ndarray:
        """Whether world points (..., 2) lie in the footprint (boundary included)."""
        d = np.asarray(points, dtype=float)[..., :2] - np.asarray(self.center)
        u, v = self.axes
        return (np.abs(d @ u) <= self.half_size[0] + 1e-12) & (np.abs(d @ v) <= self.half_size[1] + 1e-12)

    def overlapping_cells(self, shape: tuple[int, int], cell_size: float, origin: tuple[float, float]) -> np.ndarray:
        """(H, W) bool: the grid cells whose square shares interior area with the footprint.

        Exact (separating axes of the cell square and the rotated rectangle); a cell that
        only touches the footprint along an edge or at a corner is not counted, so an
        axis-aligned box whose sides lie on cell borders covers exactly the cells inside it.
        """
        mask = np.zeros(shape, dtype=bool)
        corners = self.corners_xy()
        lo = np.floor((corners.min(axis=0) - np.asarray(origin)) / cell_size).astype(int) - 1
        hi = np.ceil((corners.max(axis=0) - np.asarray(origin)) / cell_size).astype(int) + 1
        j0, j1 = max(lo[0], 0), min(hi[0], shape[1])
        i0, i1 = max(lo[1], 0), min(hi[1], shape[0])
        if j0 >= j1 or i0 >= i1:
            return mask
        half_cell = 0.5 * cell_size
        cx = origin[0] + (np.arange(j0, j1) + 0.5) * cell_size - self.center[0]
        cy = origin[1] + (np.arange(i0, i1) + 0.5) * cell_size - self.center[1]
        dx, dy = np.meshgrid(cx, cy)  # (rows = y, columns = x)
        c, s = abs(math.cos(self.yaw)), abs(math.sin(self.yaw))
        hu, hv = self.half_size
        u, v = self.axes
        eps = 1e-9 * cell_size
        inside = np.abs(dx) < half_cell + hu * c + hv * s - eps
        inside &= np.abs(dy) < half_cell + hu * s + hv * c - eps
        inside &= np.abs(dx * u[0] + dy * u[1]) < hu + half_cell * (c + s) - eps
        inside &= np.abs(dx * v[0] + dy * v[1]) < hv + half_cell * (c + s) - eps
        mask[i0:i1, j0:j1] = inside
        return mask

    def footprint_overlaps(self, other: Box, margin: float = 0.0) -> bool:
        """Whether the two footprints, each grown by ``margin`` (m) on every side, overlap."""
        d = np.asarray(other.center) - np.asarray(self.center)
        axes_a, axes_b = self.axes, other.axes
        ha = np.asarray(self.half_size) + margin
        hb = np.asarray(other.half_size) + margin
        for axis in (*axes_a, *axes_b):
            ra = ha[0] * abs(axes_a[0] @ axis) + ha[1] * abs(axes_a[1] @ axis)
            rb = hb[0] * abs(axes_b[0] @ axis) + hb[1] * abs(axes_b[1] @ axis)
            if abs(d @ axis) >= ra + rb:
                return False
        return True

    def to_dict(self) -> dict[str, Any]:
        return {"center": list(self.center), "half_size": list(self.half_size), "yaw": self.yaw,
                "bottom": self.bottom, "top": self.top}

    @classmethod
    def from_dict(cls, data: Any) -> Box:
        return cls(**_from_mapping(cls, data, "box"))


# --- dynamic obstacles ---------------------------------------------------------------------------
class MotionModel(abc.ABC):
    """A trajectory the planner can predict: the obstacle centre p(t) in the world frame (m), t in s.

    ``position`` and ``velocity_at`` take a scalar time (-> shape (3,)) or an array of
    times (-> shape (..., 3)).
    """

    kind: ClassVar[str]

    @abc.abstractmethod
    def position(self, t: float | np.ndarray) -> np.ndarray:
        """Centre (x, y, z) at time ``t`` (m)."""

    @abc.abstractmethod
    def velocity_at(self, t: float | np.ndarray) -> np.ndarray:
        """Velocity of the centre at time ``t`` (m/s)."""

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready parameters, with ``kind`` naming the model."""
        out: dict[str, Any] = {"kind": self.kind}
        for f in fields(self):  # type: ignore[arg-type]
            if f.init:
                value = getattr(self, f.name)
                if isinstance(value, tuple):
                    value = [list(v) if isinstance(v, tuple) else v for v in value]
                out[f.name] = value
        return out

    @staticmethod
    def from_dict(data: Any) -> MotionModel:
        kind = data.get("kind") if isinstance(data, dict) else None
        if kind not in MOTION_MODELS:
            raise ValueError(f"motion kind must be one of {sorted(MOTION_MODELS)}, got {kind!r}")
        cls = MOTION_MODELS[kind]
        return cls(**_from_mapping(cls, data, f"{kind} motion"))


@dataclass(frozen=True)
class ConstantVelocity(MotionModel):
    """Straight-line motion: p(t) = start + velocity * t (m, m/s)."""

    start: tuple[float, float, float]
    velocity: tuple[float, float, float]
    kind: ClassVar[str] = "constant_velocity"

    def __post_init__(self) -> None:
        object.__setattr__(self, "start", _floats("start", self.start, 3))
        object.__setattr__(self, "velocity", _floats("velocity", self.velocity, 3))

    def position(self, t: float | np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=float)[..., None]
        return np.asarray(self.start) + t * np.asarray(self.velocity)

    def velocity_at(self, t: float | np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        return np.broadcast_to(np.asarray(self.velocity), t.shape + (3,)).copy()


@dataclass(frozen=True)
class Loop(MotionModel):
    """A horizontal circle, counter-clockwise seen from above.

    p(t) = center + radius (cos a, sin a, 0) with a = phase + 2 pi t / period
    (m, s, rad).
    """

    center: tuple[float, float, float]
    radius: float
    period: float
    phase: float = 0.0
    kind: ClassVar[str] = "loop"

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", _floats("center", self.center, 3))
        object.__setattr__(self, "radius", check_number("radius", self.radius, 0.0))
        object.__setattr__(self, "period", check_number("period", self.period, 0.0, low_open=True))
        object.__setattr__(self, "phase", check_number("phase", self.phase))

    def _angle(self, t: float | np.ndarray) -> np.ndarray:
        return self.phase + 2.0 * math.pi * np.asarray(t, dtype=float) / self.period

    def position(self, t: float | np.ndarray) -> np.ndarray:
        a = self._angle(t)
        offset = np.stack((np.cos(a), np.sin(a), np.zeros_like(a)), axis=-1)
        return np.asarray(self.center) + self.radius * offset

    def velocity_at(self, t: float | np.ndarray) -> np.ndarray:
        a = self._angle(t)
        speed = 2.0 * math.pi * self.radius / self.period
        return speed * np.stack((-np.sin(a), np.cos(a), np.zeros_like(a)), axis=-1)


@dataclass(frozen=True)
class WaypointLoop(MotionModel):
    """Constant-speed motion around a closed polyline (the last waypoint joins the first).

    ``waypoints`` (N >= 2) are world points (m); ``speed`` in m/s; ``phase`` in [0, 1) is
    the fraction of the loop already travelled at t = 0. ``back_and_forth`` builds a loop
    that runs along an open path and back.
    """

    waypoints: tuple[tuple[float, float, float], ...]
    speed: float
    phase: float = 0.0
    kind: ClassVar[str] = "waypoint_loop"
    _points: np.ndarray = field(init=False, repr=False, compare=False)
    _cumulative: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        try:
            points = tuple(_floats(f"waypoints[{k}]", p, 3) for k, p in enumerate(self.waypoints))
        except TypeError:
            raise ValueError(f"waypoints must be a sequence of (x, y, z) points, got {self.waypoints!r}") from None
        if len(points) < 2:
            raise ValueError(f"waypoints must hold at least 2 points, got {len(points)}")
        object.__setattr__(self, "waypoints", points)
        object.__setattr__(self, "speed", check_number("speed", self.speed, 0.0))
        phase = check_number("phase", self.phase, 0.0, 1.0)
        if phase == 1.0:
            phase = 0.0
        object.__setattr__(self, "phase", phase)
        closed = np.asarray(points + points[:1])
        lengths = np.linalg.norm(np.diff(closed, axis=0), axis=1)
        if lengths.sum() <= 0.0:
            raise ValueError("waypoints must not all coincide (the loop has zero length)")
        object.__setattr__(self, "_points", closed)
        object.__setattr__(self, "_cumulative", np.concatenate(([0.0], np.cumsum(lengths))))

    @classmethod
    def back_and_forth(cls, path: Sequence[Sequence[float]], speed: float, phase: float = 0.0) -> WaypointLoop:
        """Run along ``path`` (N >= 2 points) and back along it, forever."""
        points = [tuple(float(c) for c in p) for p in path]
        return cls(waypoints=tuple(points + points[-2:0:-1]), speed=speed, phase=phase)

    @property
    def length(self) -> float:
        """Length of one loop (m)."""
        return float(self._cumulative[-1])

    def _segment(self, t: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        s = np.mod(self.phase * self.length + self.speed * np.asarray(t, dtype=float), self.length)
        k = np.clip(np.searchsorted(self._cumulative, s, side="right") - 1, 0, len(self._points) - 2)
        return k, s

    def position(self, t: float | np.ndarray) -> np.ndarray:
        k, s = self._segment(t)
        start, end = self._points[k], self._points[k + 1]
        seg = np.maximum(self._cumulative[k + 1] - self._cumulative[k], 1e-12)
        frac = ((s - self._cumulative[k]) / seg)[..., None]
        return start + frac * (end - start)

    def velocity_at(self, t: float | np.ndarray) -> np.ndarray:
        k, _ = self._segment(t)
        delta = self._points[k + 1] - self._points[k]
        seg = np.maximum(np.linalg.norm(delta, axis=-1, keepdims=True), 1e-12)
        return self.speed * delta / seg


MOTION_MODELS: dict[str, type[MotionModel]] = {
    cls.kind: cls for cls in (ConstantVelocity, Loop, WaypointLoop)
}


@dataclass(frozen=True)
class DynamicObstacle:
    """A moving ball: a sphere of ``radius`` (m) whose centre follows ``motion``."""

    name: str
    radius: float
    motion: MotionModel

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"a dynamic obstacle needs a non-empty name, got {self.name!r}")
        object.__setattr__(self, "radius", check_number("radius", self.radius, 0.0, low_open=True))
        if not isinstance(self.motion, MotionModel):
            raise TypeError(f"motion must be a MotionModel, got {type(self.motion).__name__}")

    def position(self, t: float | np.ndarray) -> np.ndarray:
        return self.motion.position(t)

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "radius": self.radius, "motion": self.motion.to_dict()}

    @classmethod
    def from_dict(cls, data: Any) -> DynamicObstacle:
        kwargs = _from_mapping(cls, data, "dynamic obstacle")
        kwargs["motion"] = MotionModel.from_dict(kwargs.get("motion"))
        return cls(**kwargs)


# --- landmarks -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Landmark:
    """A named goal region: the disc of ``radius`` (m) around ``center`` (x, y).

    On a grid, the landmark is the set of cells whose centre lies in the disc, plus the
    cell that contains ``center`` (so a small disc still has a cell). ``display_position``
    (x, y, z) is where a marker or label is drawn (the top of the marker post).
    """

    name: str
    center: tuple[float, float]
    radius: float
    display_position: tuple[float, float, float]

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"a landmark needs a non-empty name, got {self.name!r}")
        object.__setattr__(self, "center", _floats("center", self.center, 2))
        object.__setattr__(self, "radius", check_number("radius", self.radius, 0.0))
        object.__setattr__(self, "display_position", _floats("display_position", self.display_position, 3))

    def cells(self, shape: tuple[int, int], cell_size: float, origin: tuple[float, float]) -> np.ndarray:
        """(K, 2) int cells (i, j) of the landmark on a grid; may be empty if it lies off the grid."""
        x0, y0 = origin
        cx, cy = self.center
        j_lo = max(math.floor((cx - self.radius - x0) / cell_size), 0)
        j_hi = min(math.ceil((cx + self.radius - x0) / cell_size) + 1, shape[1])
        i_lo = max(math.floor((cy - self.radius - y0) / cell_size), 0)
        i_hi = min(math.ceil((cy + self.radius - y0) / cell_size) + 1, shape[0])
        ii, jj = np.mgrid[i_lo:max(i_hi, i_lo), j_lo:max(j_hi, j_lo)]
        dx = x0 + (jj + 0.5) * cell_size - cx
        dy = y0 + (ii + 0.5) * cell_size - cy
        inside = dx * dx + dy * dy <= self.radius * self.radius + 1e-12
        cells = np.stack((ii[inside], jj[inside]), axis=-1).reshape(-1, 2)
        own = (math.floor((cy - y0) / cell_size), math.floor((cx - x0) / cell_size))
        if 0 <= own[0] < shape[0] and 0 <= own[1] < shape[1] and not (
            (cells[:, 0] == own[0]) & (cells[:, 1] == own[1])
        ).any():
            cells = np.concatenate((cells, np.array([own])), axis=0)
        return cells.astype(np.int64)

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "center": list(self.center), "radius": self.radius,
                "display_position": list(self.display_position)}

    @classmethod
    def from_dict(cls, data: Any) -> Landmark:
        return cls(**_from_mapping(cls, data, "landmark"))


# --- the scene -----------------------------------------------------------------------------------
@dataclass(eq=False)
class Scene:
    """A PlaMo scene in the world frame (z up, metres).

    | field | meaning |
    |---|---|
    | heights | (H, W) ground height (world z) at cell centres; rows are y, columns are x |
    | cell_size | grid spacing c (m) |
    | origin | (x0, y0): the corner of cell (0, 0) at minimal x and y (m) |
    | walls | static obstacles (``Box``): impassable, from ``bottom`` to ``top`` |
    | ceilings | top obstacles (``Box``): ``bottom`` is the underside (world z) the head must stay below |
    | dynamic_obstacles | moving balls (``DynamicObstacle``) with predictable motion |
    | landmarks | named goal regions (``Landmark``), names unique |
    | terrain_labels | optional (H, W) uint8: index into ``TERRAIN_KINDS`` of the patch each cell belongs to |

    ``Scene`` compares by value (``==``), arrays included.
    """

    heights: np.ndarray
    cell_size: float
    origin: tuple[float, float] = (0.0, 0.0)
    walls: list[Box] = field(default_factory=list)
    ceilings: list[Box] = field(default_factory=list)
    dynamic_obstacles: list[DynamicObstacle] = field(default_factory=list)
    landmarks: list[Landmark] = field(default_factory=list)
    terrain_labels: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.heights = np.array(self.heights, dtype=np.float64)
        if self.heights.ndim != 2 or min(self.heights.shape) < 2:
            raise ValueError(f"heights must be a 2-D array of at least 2 x 2 cells, got shape {self.heights.shape}")
        if not np.isfinite(self.heights).all():
            raise ValueError("heights must be finite")
        self.cell_size = check_number("cell_size", self.cell_size, 0.0, low_open=True)
        self.origin = _floats("origin", self.origin, 2)
        self.walls = list(self.walls)
        self.ceilings = list(self.ceilings)
        self.dynamic_obstacles = list(self.dynamic_obstacles)
        self.landmarks = list(self.landmarks)
        for name, items, cls in (("walls", self.walls, Box), ("ceilings", self.ceilings, Box),
                                 ("dynamic_obstacles", self.dynamic_obstacles, DynamicObstacle),
                                 ("landmarks", self.landmarks, Landmark)):
            for item in items:
                if not isinstance(item, cls):
                    raise TypeError(f"{name} must hold {cls.__name__} objects, got {type(item).__name__}")
        for what, names in (("landmark", [lm.name for lm in self.landmarks]),
                            ("dynamic obstacle", [ob.name for ob in self.dynamic_obstacles])):
            if len(set(names)) != len(names):
                raise ValueError(f"{what} names must be unique, got {names}")
        if self.terrain_labels is not None:
            labels = np.array(self.terrain_labels)
            if labels.shape != self.heights.shape or (labels.size and (labels.min() < 0 or labels.max() >= len(TERRAIN_KINDS))):
                raise ValueError(
                    f"terrain_labels must be an array of the heights' shape {self.heights.shape} with values in "
                    f"[0, {len(TERRAIN_KINDS) - 1}] (indices into TERRAIN_KINDS)"
                )
            self.terrain_labels = labels.astype(np.uint8)

    # --- geometry ----------------------------------------------------------------------------
    @property
    def shape(self) -> tuple[int, int]:
        return self.heights.shape

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(x_min, x_max, y_min, y_max) of the grid (m)."""
        x0, y0 = self.origin
        return x0, x0 + self.shape[1] * self.cell_size, y0, y0 + self.shape[0] * self.cell_size

    @property
    def landmark_names(self) -> tuple[str, ...]:
        return tuple(lm.name for lm in self.landmarks)

    def landmark(self, name: str) -> Landmark:
        for lm in self.landmarks:
            if lm.name == name:
                return lm
        raise KeyError(f"no landmark {name!r}; this scene has {list(self.landmark_names)}")

    def cell_center(self, i: np.ndarray | int, j: np.ndarray | int) -> np.ndarray:
        """World (x, y) of cell centres; broadcasts over arrays of indices."""
        i, j = np.asarray(i), np.asarray(j)
        return np.stack((self.origin[0] + (j + 0.5) * self.cell_size,
                         self.origin[1] + (i + 0.5) * self.cell_size), axis=-1)

    def height_at(self, points: np.ndarray) -> np.ndarray:
        """Ground height (world z) under world points (..., 2 or 3): bilinear between cell centres.

        Outside the grid the border values continue (as in the MuJoCo height field's
        half-cell rim).
        """
        xy = np.asarray(points, dtype=float)[..., :2]
        col = (xy[..., 0] - self.origin[0]) / self.cell_size - 0.5
        row = (xy[..., 1] - self.origin[1]) / self.cell_size - 0.5
        coords = np.stack((row.ravel(), col.ravel()))
        values = ndimage.map_coordinates(self.heights, coords, order=1, mode="nearest")
        return values.reshape(xy.shape[:-1])

    def surface_height_at(self, points: np.ndarray) -> np.ndarray:
        """Top of whatever is under world points (..., 2 or 3): ground or the top of a wall."""
        xy = np.asarray(points, dtype=float)[..., :2]
        top = self.height_at(xy)
        for wall in self.walls:
            top = np.where(wall.contains_xy(xy), np.maximum(top, wall.top), top)
        return top

    def dynamic_positions(self, t: float) -> np.ndarray:
        """(K, 3) centres of the dynamic obstacles at time ``t``."""
        if not self.dynamic_obstacles:
            return np.zeros((0, 3))
        return np.stack([ob.position(t) for ob in self.dynamic_obstacles])

    # --- the planner's view ------------------------------------------------------------------
    def planning_grid(self, cell_size: float | None = None) -> PlanningGrid:
        """Rasterise the scene for the planner (``PlanningGrid``, same origin).

        ``cell_size`` None keeps the scene's grid (heights copied). Another size covers the
        same area (the last row/column may reach past it) and samples ``height_at`` at the
        new cell centres. A cell is ``blocked`` if its square shares area with a wall's
        footprint; its ``ceiling`` is the lowest underside (world z) of the ceilings whose
        footprint shares area with it (inf under open sky). Landmarks become their cells.
        Dynamic obstacles are left to the planner's prediction.
        """
        if cell_size is None or float(cell_size) == self.cell_size:
            c = self.cell_size
            shape = self.shape
            heights = self.heights.copy()
        else:
            c = check_number("cell_size", cell_size, 0.0, low_open=True)
            width, depth = self.shape[1] * self.cell_size, self.shape[0] * self.cell_size
            shape = (max(math.ceil(depth / c - 1e-9), 1), max(math.ceil(width / c - 1e-9), 1))
            ii, jj = np.mgrid[0:shape[0], 0:shape[1]]
            heights = self.height_at(np.stack((self.origin[0] + (jj + 0.5) * c,
                                               self.origin[1] + (ii + 0.5) * c), axis=-1))
        blocked = np.zeros(shape, dtype=bool)
        for wall in self.walls:
            blocked |= wall.overlapping_cells(shape, c, self.origin)
        ceiling = np.full(shape, np.inf)
        for slab in self.ceilings:
            mask = slab.overlapping_cells(shape, c, self.origin)
            ceiling[mask] = np.minimum(ceiling[mask], slab.bottom)
        landmarks = {lm.name: lm.cells(shape, c, self.origin) for lm in self.landmarks}
        return PlanningGrid(heights=heights, blocked=blocked, ceiling=ceiling, cell_size=c,
                            origin=self.origin, landmarks=landmarks)

    # --- comparison --------------------------------------------------------------------------
    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Scene):
            return NotImplemented
        labels_equal = (self.terrain_labels is None and other.terrain_labels is None) or (
            self.terrain_labels is not None and other.terrain_labels is not None
            and np.array_equal(self.terrain_labels, other.terrain_labels)
        )
        return (
            np.array_equal(self.heights, other.heights) and self.cell_size == other.cell_size
            and self.origin == other.origin and self.walls == other.walls and self.ceilings == other.ceilings
            and self.dynamic_obstacles == other.dynamic_obstacles and self.landmarks == other.landmarks
            and labels_equal
        )

    __hash__ = None  # type: ignore[assignment]

    # --- files -------------------------------------------------------------------------------
    def to_json_dict(self) -> dict[str, Any]:
        """The structured parts (everything but the arrays), JSON-ready."""
        return {
            "format": SCENE_FILE_FORMAT,
            "version": SCENE_FILE_VERSION,
            "cell_size": self.cell_size,
            "origin": list(self.origin),
            "walls": [w.to_dict() for w in self.walls],
            "ceilings": [c.to_dict() for c in self.ceilings],
            "dynamic_obstacles": [ob.to_dict() for ob in self.dynamic_obstacles],
            "landmarks": [lm.to_dict() for lm in self.landmarks],
        }

    def save(self, path: str | PathLike[str]) -> None:
        """Write the scene to ``path`` (an ``.npz``: arrays ``heights``, optional
        ``terrain_labels``, and ``scene_json``, the UTF-8 JSON of ``to_json_dict``)."""
        arrays: dict[str, np.ndarray] = {
            "heights": self.heights,
            "scene_json": np.frombuffer(json.dumps(self.to_json_dict()).encode("utf-8"), dtype=np.uint8),
        }
        if self.terrain_labels is not None:
            arrays["terrain_labels"] = self.terrain_labels
        with open(path, "wb") as f:
            np.savez_compressed(f, **arrays)

    @classmethod
    def load(cls, path: str | PathLike[str]) -> Scene:
        """Read a file written by ``save``. Raises ``FileNotFoundError`` for a missing file and
        ``SceneFileError`` (a ``ValueError``) naming the file for anything else that is not a
        valid scene file.

        Sizes are bounded before anything is decompressed, from the shapes the arrays' ``.npy``
        headers declare: ``heights`` and ``terrain_labels`` at most ``MAX_SCENE_CELLS``
        (4096 x 4096) cells, ``scene_json`` at most ``MAX_SCENE_JSON_BYTES`` (16 MiB). Heights
        must be finite with |h| <= ``MAX_SCENE_HEIGHT`` (1000 m).
        """
        try:
            loaded = np.load(path, allow_pickle=False)
            if not isinstance(loaded, np.lib.npyio.NpzFile):
                raise SceneFileError(f"{path}: not a scene file (a single .npy array, not an .npz archive)")
            with loaded as npz:
                missing = {"heights", "scene_json"} - set(npz.files)
                if missing:
                    raise SceneFileError(f"{path}: not a scene file (missing {sorted(missing)})")
                has_labels = "terrain_labels" in npz.files
                _check_declared(path, npz, "heights", 2, "iuf", MAX_SCENE_CELLS, "MAX_SCENE_CELLS")
                _check_declared(path, npz, "scene_json", 1, "iu", MAX_SCENE_JSON_BYTES, "MAX_SCENE_JSON_BYTES")
                if has_labels:
                    _check_declared(path, npz, "terrain_labels", 2, "iu", MAX_SCENE_CELLS, "MAX_SCENE_CELLS")
                heights = npz["heights"]
                raw_json = npz["scene_json"]
                labels = npz["terrain_labels"] if has_labels else None
        except (FileNotFoundError, SceneFileError):
            raise
        except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, zlib.error) as e:
            raise SceneFileError(f"{path}: not a readable scene file (.npz): {e}") from e
        _check_loaded_heights(path, heights)
        try:
            meta = json.loads(raw_json.astype(np.uint8).tobytes().decode("utf-8"))
        except (UnicodeDecodeError, json.JSONDecodeError, ValueError) as e:
            raise SceneFileError(f"{path}: corrupt scene description (scene_json): {e}") from e
        if not isinstance(meta, dict) or meta.get("format") != SCENE_FILE_FORMAT:
            found = meta.get("format") if isinstance(meta, dict) else None
            raise SceneFileError(f"{path}: not a scene file (format {found!r}, expected {SCENE_FILE_FORMAT!r})")
        if meta.get("version") != SCENE_FILE_VERSION:
            raise SceneFileError(
                f"{path}: scene file version {meta.get('version')!r}; this stairenv reads version {SCENE_FILE_VERSION}"
            )
        try:
            return cls(
                heights=heights,
                cell_size=meta["cell_size"],
                origin=meta["origin"],
                walls=[Box.from_dict(d) for d in meta["walls"]],
                ceilings=[Box.from_dict(d) for d in meta["ceilings"]],
                dynamic_obstacles=[DynamicObstacle.from_dict(d) for d in meta["dynamic_obstacles"]],
                landmarks=[Landmark.from_dict(d) for d in meta["landmarks"]],
                terrain_labels=labels,
            )
        except (KeyError, TypeError, ValueError) as e:
            raise SceneFileError(f"{path}: invalid scene data: {e!r}") from e


def _check_declared(path: Any, npz: Any, key: str, ndim: int, kinds: str, limit: int, limit_name: str) -> None:
    """SceneFileError unless member ``key`` of an open ``.npz`` declares an ``ndim``-D array of
    a numeric kind in ``kinds`` with at most ``limit`` elements. Reads the ``.npy`` header only."""
    member = f"{key}.npy" if f"{key}.npy" in npz.zip.namelist() else key
    npy = np.lib.format
    with npz.zip.open(member) as f:
        version = npy.read_magic(f)
        read_header = npy.read_array_header_1_0 if version == (1, 0) else npy.read_array_header_2_0
        shape, _, dtype = read_header(f)
    if len(shape) != ndim or min(shape, default=0) < 0 or dtype.kind not in kinds:
        raise SceneFileError(f"{path}: {key} must be a {ndim}-D numeric array, the file declares shape {shape} "
                             f"of {dtype}")
    size = math.prod(shape)
    if size > limit:
        raise SceneFileError(f"{path}: {key} declares shape {shape} ({size} elements), more than the {limit} "
                             f"Scene.load reads ({limit_name})")


def _check_loaded_heights(path: Any, heights: np.ndarray) -> None:
    bad = ~(np.abs(heights) <= MAX_SCENE_HEIGHT)  # NaN fails the comparison too
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise SceneFileError(f"{path}: heights must be finite with |h| <= {MAX_SCENE_HEIGHT} m "
                             f"(MAX_SCENE_HEIGHT); {int(bad.sum())} cells are not, e.g. cell ({i}, {j}) holds "
                             f"{float(heights[i, j])}")


# --- terrain patches -----------------------------------------------------------------------------
# A patch is an (h, w) array of heights (m) on the scene's grid. Every generator leaves the
# patch's rim at height 0 (features start ``border`` metres inside it, the rough noise fades
# out towards the rim), so that patches of any kinds tile without a cliff at their borders.


@dataclass(frozen=True)
class FlatPatchConfig:
    """Level ground at height 0 (no parameters)."""


@dataclass(frozen=True)
class SlopePatchConfig:
    """A hill of inclines: a truncated pyramid on a rotated rectangular footprint.

    Inside the footprint (random yaw, the largest rectangle of the sampled aspect ratio
    that fits ``border`` metres inside the patch) the ground rises at the sampled angle
    from the footprint's edge up to a plateau at the sampled height (a ridge if the
    footprint is too small to reach it). Every incline has the sampled angle.

    | field | default | valid |
    |---|---|---|
    | angle_deg | (5, 20) | within [0, 45]: incline angle (degrees) |
    | height | (0.3, 1.0) | within [0, 5]: plateau height (m) |
    | aspect | (0.4, 1.0) | within [0.05, 1]: footprint short side / long side |
    | border | 0.3 | [0, 10]: flat rim around the footprint (m) |
    """

    angle_deg: tuple[float, float] = (5.0, 20.0)
    height: tuple[float, float] = (0.3, 1.0)
    aspect: tuple[float, float] = (0.4, 1.0)
    border: float = 0.3

    def __post_init__(self) -> None:
        object.__setattr__(self, "angle_deg", check_range("angle_deg", self.angle_deg, 0.0, 45.0))
        object.__setattr__(self, "height", check_range("height", self.height, 0.0, 5.0))
        object.__setattr__(self, "aspect", check_range("aspect", self.aspect, 0.05, 1.0))
        object.__setattr__(self, "border", check_number("border", self.border, 0.0, 10.0))


@dataclass(frozen=True)
class RoughPatchConfig:
    """Gravel-like ground: Gaussian-smoothed white noise scaled to [0, amplitude].

    The noise fades (smoothstep) to 0 over the ``border`` metres next to the patch's rim;
    the outermost cells are 0.

    | field | default | valid |
    |---|---|---|
    | amplitude | (0.03, 0.08) | within [0, 0.5]: peak-to-valley height (m) |
    | smoothing | 0.1 | [0, 2]: standard deviation of the Gaussian filter (m); 0 = raw noise |
    | border | 0.3 | [0, 10]: fade-out band at the rim (m) |
    """

    amplitude: tuple[float, float] = (0.03, 0.08)
    smoothing: float = 0.1
    border: float = 0.3

    def __post_init__(self) -> None:
        object.__setattr__(self, "amplitude", check_range("amplitude", self.amplitude, 0.0, 0.5))
        object.__setattr__(self, "smoothing", check_number("smoothing", self.smoothing, 0.0, 2.0))
        object.__setattr__(self, "border", check_number("border", self.border, 0.0, 10.0))


@dataclass(frozen=True)
class StairsPatchConfig:
    """Stairs: steps rising from the edge of a rotated rectangular footprint to a top landing.

    The footprint is fitted as for ``SlopePatchConfig`` (random yaw = the direction the
    flights run in). Walking inwards from any side of it, the ground rises one
    ``step_height`` every ``tread_depth``, ``num_steps`` times at most (a stepped pyramid:
    no side of the stairs is a cliff).

    | field | default | valid |
    |---|---|---|
    | step_height | (0.05, 0.20) | within [0.01, 0.30] (m) |
    | tread_depth | (0.25, 0.40) | within [0.10, 1.0] (m) |
    | num_steps | (2, 5) | integers within [1, 30] |
    | aspect | (0.5, 1.0) | within [0.05, 1]: footprint short side / long side |
    | border | 0.3 | [0, 10]: flat rim around the footprint (m) |
    """

    step_height: tuple[float, float] = (0.05, 0.20)
    tread_depth: tuple[float, float] = (0.25, 0.40)
    num_steps: tuple[int, int] = (2, 5)
    aspect: tuple[float, float] = (0.5, 1.0)
    border: float = 0.3

    def __post_init__(self) -> None:
        object.__setattr__(self, "step_height", check_range("step_height", self.step_height, 0.01, 0.30))
        object.__setattr__(self, "tread_depth", check_range("tread_depth", self.tread_depth, 0.10, 1.0))
        object.__setattr__(self, "num_steps", _int_range("num_steps", self.num_steps, 1, 30))
        object.__setattr__(self, "aspect", check_range("aspect", self.aspect, 0.05, 1.0))
        object.__setattr__(self, "border", check_number("border", self.border, 0.0, 10.0))


PatchConfig = FlatPatchConfig | SlopePatchConfig | RoughPatchConfig | StairsPatchConfig


def _check_patch_shape(shape: tuple[int, int], cell_size: float) -> tuple[int, int]:
    rows, cols = (int(n) for n in shape)
    if rows < 1 or cols < 1:
        raise ValueError(f"shape must be (rows, columns) >= (1, 1), got {shape!r}")
    check_number("cell_size", cell_size, 0.0, low_open=True)
    return rows, cols


def _patch_xy(shape: tuple[int, int], cell_size: float) -> tuple[np.ndarray, np.ndarray]:
    """x, y (h, w) of the cell centres relative to the patch centre (m)."""
    rows, cols = shape
    x = (np.arange(cols) + 0.5 - 0.5 * cols) * cell_size
    y = (np.arange(rows) + 0.5 - 0.5 * rows) * cell_size
    return np.meshgrid(x, y)


def _fitted_footprint_depth(rng: np.random.Generator, shape: tuple[int, int], cell_size: float,
                            border: float, aspect: tuple[float, float]) -> np.ndarray:
    """How far each cell centre lies inside a random rotated rectangle (negative outside).

    The rectangle has a random yaw and aspect ratio and is the largest such that fits
    ``border`` inside the patch, centred on it. Depth = min(hu - |u|, hv - |v|), which grows
    by 1 m per metre walked inwards (the distance to the nearest side).
    """
    yaw = rng.uniform(0.0, math.pi)
    ratio = rng.uniform(*aspect)
    x, y = _patch_xy(shape, cell_size)
    room_x = 0.5 * shape[1] * cell_size - border
    room_y = 0.5 * shape[0] * cell_size - border
    if room_x <= 0.0 or room_y <= 0.0:
        return np.full(shape, -1.0)
    c, s = abs(math.cos(yaw)), abs(math.sin(yaw))
    half_long = min(room_x / (c + ratio * s), room_y / (s + ratio * c))
    half_short = ratio * half_long
    u = x * math.cos(yaw) + y * math.sin(yaw)
    v = -x * math.sin(yaw) + y * math.cos(yaw)
    return np.minimum(half_long - np.abs(u), half_short - np.abs(v))


def flat_patch(config: FlatPatchConfig, rng: np.random.Generator, *, shape: tuple[int, int],
               cell_size: float) -> np.ndarray:
    """Level ground: an (h, w) array of zeros (m). Draws nothing from ``rng``."""
    return np.zeros(_check_patch_shape(shape, cell_size))


def slope_patch(config: SlopePatchConfig, rng: np.random.Generator, *, shape: tuple[int, int],
                cell_size: float) -> np.ndarray:
    """Heights (m) of a hill with inclines of a random angle (see ``SlopePatchConfig``); in [0, height]."""
    shape = _check_patch_shape(shape, cell_size)
    angle = math.radians(rng.uniform(*config.angle_deg))
    height = rng.uniform(*config.height)
    depth = _fitted_footprint_depth(rng, shape, cell_size, config.border, config.aspect)
    return np.minimum(height, math.tan(angle) * np.maximum(depth, 0.0))


def rough_patch(config: RoughPatchConfig, rng: np.random.Generator, *, shape: tuple[int, int],
                cell_size: float) -> np.ndarray:
    """Heights (m) of gravel-like ground (see ``RoughPatchConfig``); in [0, amplitude]."""
    shape = _check_patch_shape(shape, cell_size)
    amplitude = rng.uniform(*config.amplitude)
    noise = rng.standard_normal(shape)
    if config.smoothing > 0.0:
        noise = ndimage.gaussian_filter(noise, sigma=config.smoothing / cell_size, mode="reflect")
    spread = noise.max() - noise.min()
    unit = (noise - noise.min()) / spread if spread > 0.0 else np.zeros(shape)
    if config.border > 0.0:
        x, y = _patch_xy(shape, cell_size)
        to_rim = np.minimum(0.5 * shape[1] * cell_size - np.abs(x), 0.5 * shape[0] * cell_size - np.abs(y))
        ramp = np.clip((to_rim - 0.5 * cell_size) / config.border, 0.0, 1.0)  # 0 on the outermost cells
        unit = unit * ramp * ramp * (3.0 - 2.0 * ramp)
    return amplitude * unit


def stairs_patch(config: StairsPatchConfig, rng: np.random.Generator, *, shape: tuple[int, int],
                 cell_size: float) -> np.ndarray:
    """Heights (m) of stairs (see ``StairsPatchConfig``): multiples of the sampled step height
    in [0, num_steps * step_height]."""
    shape = _check_patch_shape(shape, cell_size)
    step_height = rng.uniform(*config.step_height)
    tread = rng.uniform(*config.tread_depth)
    num_steps = int(rng.integers(config.num_steps[0], config.num_steps[1] + 1))
    depth = _fitted_footprint_depth(rng, shape, cell_size, config.border, config.aspect)
    level = np.where(depth > 0.0, np.minimum(num_steps, np.floor(depth / tread) + 1), 0.0)
    return step_height * level


def generate_patch(config: PatchConfig, rng: np.random.Generator, *, shape: tuple[int, int],
                   cell_size: float) -> np.ndarray:
    """Heights (m) of one patch of the kind ``config`` describes (dispatches on its type)."""
    generators = {FlatPatchConfig: flat_patch, SlopePatchConfig: slope_patch,
                  RoughPatchConfig: rough_patch, StairsPatchConfig: stairs_patch}
    generator = generators.get(type(config))
    if generator is None:
        raise ValueError(f"config must be one of {[c.__name__ for c in generators]}, got {type(config).__name__}")
    return generator(config, rng, shape=shape, cell_size=cell_size)


# --- reachability --------------------------------------------------------------------------------
def connected_free_space(grid: PlanningGrid, *, max_step_height: float = 0.25, min_clearance: float = 0.5,
                         body_radius: float = 0.25) -> np.ndarray:
    """Label the cells a character can move between (4-connected), largest region first.

    A cell is free if its centre lies more than ``body_radius`` (m) from the centre of
    every blocked cell and the ceiling above it leaves at least ``min_clearance`` (m, a
    crawl). Two neighbouring free cells connect if their heights differ by at most
    ``max_step_height`` (m). Returns (H, W) int labels: 0 for the largest connected
    region, 1 for the next, ...; -1 where not free.
    """
    rows, cols = grid.shape
    c = grid.cell_size
    if grid.blocked.any():
        to_blocked = ndimage.distance_transform_edt(~grid.blocked) * c
    else:
        to_blocked = np.full(grid.shape, np.inf)
    free = (to_blocked > body_radius) & (grid.ceiling - grid.heights >= min_clearance)
    index = np.arange(rows * cols).reshape(rows, cols)
    h = grid.heights
    join_x = free[:, 1:] & free[:, :-1] & (np.abs(h[:, 1:] - h[:, :-1]) <= max_step_height)
    join_y = free[1:, :] & free[:-1, :] & (np.abs(h[1:, :] - h[:-1, :]) <= max_step_height)
    src = np.concatenate((index[:, :-1][join_x], index[:-1, :][join_y]))
    dst = np.concatenate((index[:, 1:][join_x], index[1:, :][join_y]))
    graph = coo_matrix((np.ones(len(src), dtype=np.int8), (src, dst)), shape=(rows * cols, rows * cols))
    count, labels = connected_components(graph, directed=False)
    labels = labels.reshape(rows, cols)
    sizes = np.bincount(labels[free], minlength=count)
    rank = np.empty(count, dtype=np.int64)
    rank[np.argsort(-sizes, kind="stable")] = np.arange(count)
    return np.where(free, rank[labels], -1)


# --- random scenes -------------------------------------------------------------------------------
@dataclass(frozen=True)
class SceneConfig:
    """Ranges from which ``generate_scene`` draws a scene (uniformly). Metres, seconds.

    The scene is centred on the world origin and tiled with square-ish terrain patches;
    low ceilings (tunnels and bridges) stand on flat patches, walls anywhere else,
    landmarks on flat ground in the largest reachable region, and the balls roll back and
    forth along free straight paths.

    | field | default | valid |
    |---|---|---|
    | size | (16, 16) | each in [2, 200]: extent along x and y |
    | cell_size | 0.05 | [0.01, 0.5]: height-map spacing |
    | patch_size | 4.0 | [0.5, 100]: side of a terrain patch (the scene holds round(size / patch_size) per axis) |
    | terrain_weights | (0.35, 0.25, 0.2, 0.2) | >= 0, sum > 0: odds of flat, slope, rough, stairs patches |
    | min_flat_patches | 3 | [0, 10000]: more patches are turned flat if the draw has fewer |
    | flat, slope, rough, stairs | defaults | the patch configs (``FlatPatchConfig``, ...) |
    | num_walls | (2, 5) | integers within [0, 100] |
    | wall_length | (1.5, 4.0) | within [0.1, 100] |
    | wall_thickness | 0.2 | [0.01, 5]; also a tunnel's side walls |
    | wall_height | (1.0, 2.0) | within [0.05, 10]: above the highest ground under the wall |
    | num_ceilings | (1, 2) | integers within [0, 50]: low-ceiling structures (at most one per flat patch) |
    | tunnel_probability | 0.5 | [0, 1]: a structure is a tunnel (side walls) or else a bridge (4 pillars) |
    | ceiling_clearance | (0.6, 1.2) | within [0.2, 5]: underside above the highest ground under it |
    | ceiling_length | (1.5, 3.0) | within [0.3, 50]: along the passage (shrunk to fit its patch) |
    | ceiling_width | (1.2, 2.5) | within [0.3, 50]: across the passage (shrunk to fit its patch) |
    | ceiling_thickness | 0.2 | [0.01, 2] |
    | landmark_names | DEFAULT_LANDMARK_NAMES | distinct non-empty names, at least num_landmarks |
    | num_landmarks | 4 | [1, 100] |
    | landmark_radius | 0.5 | [0.05, 5] |
    | landmark_separation | 4.0 | [0, 100]: least distance between landmark centres |
    | landmark_wall_clearance | 0.5 | [0, 10]: least gap between a landmark's disc and a wall |
    | landmark_flatness | 0.01 | [0, 1]: largest height range over a landmark's square |
    | num_dynamic_obstacles | 1 | [0, 20]: balls |
    | ball_radius | (0.2, 0.35) | within [0.02, 2] |
    | ball_speed | (1.0, 2.5) | within [0, 20] (m/s) |
    | ball_path_length | (3.0, 8.0) | within [0.5, 100]: one way |
    | max_step_height | 0.25 | [0, 2]: reachability: largest height change between neighbouring cells |
    | min_clearance | 0.5 | [0.1, 3]: reachability: lowest gap a character crawls through |
    | body_radius | 0.25 | [0, 2]: reachability: how close to a wall a character's centre gets |
    | max_attempts | 50 | [1, 10000]: redraws of walls and ceilings before giving up |
    """

    size: tuple[float, float] = (16.0, 16.0)
    cell_size: float = 0.05
    patch_size: float = 4.0
    terrain_weights: tuple[float, float, float, float] = (0.35, 0.25, 0.2, 0.2)
    min_flat_patches: int = 3
    flat: FlatPatchConfig = FlatPatchConfig()
    slope: SlopePatchConfig = SlopePatchConfig()
    rough: RoughPatchConfig = RoughPatchConfig()
    stairs: StairsPatchConfig = StairsPatchConfig()
    num_walls: tuple[int, int] = (2, 5)
    wall_length: tuple[float, float] = (1.5, 4.0)
    wall_thickness: float = 0.2
    wall_height: tuple[float, float] = (1.0, 2.0)
    num_ceilings: tuple[int, int] = (1, 2)
    tunnel_probability: float = 0.5
    ceiling_clearance: tuple[float, float] = (0.6, 1.2)
    ceiling_length: tuple[float, float] = (1.5, 3.0)
    ceiling_width: tuple[float, float] = (1.2, 2.5)
    ceiling_thickness: float = 0.2
    landmark_names: tuple[str, ...] = DEFAULT_LANDMARK_NAMES
    num_landmarks: int = 4
    landmark_radius: float = 0.5
    landmark_separation: float = 4.0
    landmark_wall_clearance: float = 0.5
    landmark_flatness: float = 0.01
    num_dynamic_obstacles: int = 1
    ball_radius: tuple[float, float] = (0.2, 0.35)
    ball_speed: tuple[float, float] = (1.0, 2.5)
    ball_path_length: tuple[float, float] = (3.0, 8.0)
    max_step_height: float = 0.25
    min_clearance: float = 0.5
    body_radius: float = 0.25
    max_attempts: int = 50

    def __post_init__(self) -> None:
        def put(name: str, value: Any) -> None:
            object.__setattr__(self, name, value)

        size = _floats("size", self.size, 2)
        for axis, value in zip("xy", size):
            check_number(f"size ({axis})", value, 2.0, 200.0)
        put("size", size)
        put("cell_size", check_number("cell_size", self.cell_size, 0.01, 0.5))
        put("patch_size", check_number("patch_size", self.patch_size, 0.5, 100.0))
        weights = _floats("terrain_weights", self.terrain_weights, len(TERRAIN_KINDS))
        if min(weights) < 0.0 or sum(weights) <= 0.0:
            raise ValueError(
                f"terrain_weights must be {len(TERRAIN_KINDS)} numbers >= 0 with a positive sum "
                f"(odds of {', '.join(TERRAIN_KINDS)}), got {self.terrain_weights!r}"
            )
        put("terrain_weights", weights)
        put("min_flat_patches", self._integer("min_flat_patches", self.min_flat_patches, 0, 10000))
        for name, cls in (("flat", FlatPatchConfig), ("slope", SlopePatchConfig),
                          ("rough", RoughPatchConfig), ("stairs", StairsPatchConfig)):
            if not isinstance(getattr(self, name), cls):
                raise TypeError(f"{name} must be a {cls.__name__}, got {type(getattr(self, name)).__name__}")
        put("num_walls", _int_range("num_walls", self.num_walls, 0, 100))
        put("wall_length", check_range("wall_length", self.wall_length, 0.1, 100.0))
        put("wall_thickness", check_number("wall_thickness", self.wall_thickness, 0.01, 5.0))
        put("wall_height", check_range("wall_height", self.wall_height, 0.05, 10.0))
        put("num_ceilings", _int_range("num_ceilings", self.num_ceilings, 0, 50))
        put("tunnel_probability", check_number("tunnel_probability", self.tunnel_probability, 0.0, 1.0))
        put("ceiling_clearance", check_range("ceiling_clearance", self.ceiling_clearance, 0.2, 5.0))
        put("ceiling_length", check_range("ceiling_length", self.ceiling_length, 0.3, 50.0))
        put("ceiling_width", check_range("ceiling_width", self.ceiling_width, 0.3, 50.0))
        put("ceiling_thickness", check_number("ceiling_thickness", self.ceiling_thickness, 0.01, 2.0))
        put("num_landmarks", self._integer("num_landmarks", self.num_landmarks, 1, 100))
        names = tuple(self.landmark_names) if not isinstance(self.landmark_names, str) else (self.landmark_names,)
        if (len(names) < self.num_landmarks or len(set(names)) != len(names)
                or not all(isinstance(n, str) and n for n in names)):
            raise ValueError(
                f"landmark_names must hold at least num_landmarks ({self.num_landmarks}) distinct non-empty "
                f"names, got {self.landmark_names!r}"
            )
        put("landmark_names", names)
        put("landmark_radius", check_number("landmark_radius", self.landmark_radius, 0.05, 5.0))
        put("landmark_separation", check_number("landmark_separation", self.landmark_separation, 0.0, 100.0))
        put("landmark_wall_clearance",
            check_number("landmark_wall_clearance", self.landmark_wall_clearance, 0.0, 10.0))
        put("landmark_flatness", check_number("landmark_flatness", self.landmark_flatness, 0.0, 1.0))
        put("num_dynamic_obstacles", self._integer("num_dynamic_obstacles", self.num_dynamic_obstacles, 0, 20))
        put("ball_radius", check_range("ball_radius", self.ball_radius, 0.02, 2.0))
        put("ball_speed", check_range("ball_speed", self.ball_speed, 0.0, 20.0))
        put("ball_path_length", check_range("ball_path_length", self.ball_path_length, 0.5, 100.0))
        put("max_step_height", check_number("max_step_height", self.max_step_height, 0.0, 2.0))
        put("min_clearance", check_number("min_clearance", self.min_clearance, 0.1, 3.0))
        put("body_radius", check_number("body_radius", self.body_radius, 0.0, 2.0))
        put("max_attempts", self._integer("max_attempts", self.max_attempts, 1, 10000))

    @staticmethod
    def _integer(name: str, value: Any, low: int, high: int) -> int:
        number = check_number(name, value, low, high)
        if int(number) != number:
            raise ValueError(f"{name} must be an integer in [{low}, {high}], got {value!r}")
        return int(number)

    @property
    def patch_configs(self) -> tuple[PatchConfig, ...]:
        """The patch configs in the order of ``TERRAIN_KINDS``."""
        return (self.flat, self.slope, self.rough, self.stairs)


def _yaw_quat(yaw: float) -> list[float]:
    """MuJoCo quaternion (w, x, y, z) of a rotation by ``yaw`` about +z."""
    return [math.cos(0.5 * yaw), 0.0, 0.0, math.sin(0.5 * yaw)]


def _ground_under(box: Box, heights: np.ndarray, cell_size: float, origin: tuple[float, float]) -> tuple[float, float]:
    """(min, max) ground height over the cells a footprint covers (the cell of its centre if none)."""
    mask = box.overlapping_cells(heights.shape, cell_size, origin)
    if not mask.any():
        i = int(np.clip(math.floor((box.center[1] - origin[1]) / cell_size), 0, heights.shape[0] - 1))
        j = int(np.clip(math.floor((box.center[0] - origin[0]) / cell_size), 0, heights.shape[1] - 1))
        return float(heights[i, j]), float(heights[i, j])
    return float(heights[mask].min()), float(heights[mask].max())


def _low_ceiling_structures(config: SceneConfig, rng: np.random.Generator, heights: np.ndarray,
                            origin: tuple[float, float], flat_patch_rects: list[tuple[float, float, float, float]]
                            ) -> tuple[list[Box], list[Box]]:
    """Tunnels and bridges on flat patches: (ceiling slabs, their walls / pillars)."""
    c = config.cell_size
    count = int(rng.integers(config.num_ceilings[0], config.num_ceilings[1] + 1))
    count = min(count, len(flat_patch_rects))
    slabs: list[Box] = []
    supports: list[Box] = []
    if count == 0:
        return slabs, supports
    for index in rng.choice(len(flat_patch_rects), size=count, replace=False):
        x_min, x_max, y_min, y_max = flat_patch_rects[int(index)]
        center = (0.5 * (x_min + x_max), 0.5 * (y_min + y_max))
        yaw = rng.uniform(0.0, math.pi)
        length = rng.uniform(*config.ceiling_length)
        width = rng.uniform(*config.ceiling_width)
        clearance = rng.uniform(*config.ceiling_clearance)
        tunnel = bool(rng.random() < config.tunnel_probability)
        # Shrink the structure (side walls included) to fit in its patch.
        outer_half_width = 0.5 * width + (config.wall_thickness if tunnel else 0.0)
        cs, sn = abs(math.cos(yaw)), abs(math.sin(yaw))
        extent_x = 0.5 * length * cs + outer_half_width * sn
        extent_y = 0.5 * length * sn + outer_half_width * cs
        scale = min(1.0, (0.5 * (x_max - x_min) - c) / extent_x, (0.5 * (y_max - y_min) - c) / extent_y)
        length, width = scale * length, scale * width
        outer = Box(center, (0.5 * length, outer_half_width * scale), yaw, 0.0, 1.0)
        ground_low, ground_high = _ground_under(outer, heights, c, origin)
        underside = ground_high + clearance
        slabs.append(Box(center, (0.5 * length, 0.5 * width), yaw, underside, underside + config.ceiling_thickness))
        u, v = _yaw_axes(yaw)
        base = ground_low - 0.1
        if tunnel:
            for side in (-1.0, 1.0):
                wall_center = np.asarray(center) + side * (0.5 * width + 0.5 * config.wall_thickness) * v
                supports.append(Box(tuple(wall_center), (0.5 * length, 0.5 * config.wall_thickness), yaw,
                                    base, underside))
        else:
            half = min(0.1, 0.25 * length, 0.25 * width)
            for su in (-1.0, 1.0):
                for sv in (-1.0, 1.0):
                    pillar_center = (np.asarray(center) + su * (0.5 * length - half) * u
                                     + sv * (0.5 * width - half) * v)
                    supports.append(Box(tuple(pillar_center), (half, half), yaw, base, underside))
    return slabs, supports


def _random_walls(config: SceneConfig, rng: np.random.Generator, heights: np.ndarray,
                  origin: tuple[float, float], keep_clear: list[Box]) -> list[Box]:
    """Free-standing walls, half of them axis-aligned, at least 1 m from ``keep_clear``."""
    c = config.cell_size
    x_min, y_min = origin
    x_max, y_max = x_min + heights.shape[1] * c, y_min + heights.shape[0] * c
    walls: list[Box] = []
    for _ in range(int(rng.integers(config.num_walls[0], config.num_walls[1] + 1))):
        for _try in range(20):
            length = rng.uniform(*config.wall_length)
            yaw = rng.choice((0.0, 0.5 * math.pi)) if rng.random() < 0.5 else rng.uniform(0.0, math.pi)
            center = (rng.uniform(x_min + 0.5, x_max - 0.5), rng.uniform(y_min + 0.5, y_max - 0.5))
            height = rng.uniform(*config.wall_height)
            footprint = Box(center, (0.5 * length, 0.5 * config.wall_thickness), float(yaw), 0.0, 1.0)
            if any(footprint.footprint_overlaps(other, margin=1.0) for other in keep_clear):
                continue
            ground_low, ground_high = _ground_under(footprint, heights, c, origin)
            walls.append(Box(center, footprint.half_size, float(yaw), ground_low - 0.1, ground_high + height))
            break
    return walls


def _square_size(radius: float, cell_size: float) -> int:
    """Side (cells) of the odd square that covers a disc of ``radius`` centred on a cell."""
    return 2 * math.ceil(radius / cell_size) + 1


def _place_landmarks(config: SceneConfig, rng: np.random.Generator, grid: PlanningGrid, region: np.ndarray,
                     to_wall: np.ndarray) -> list[Landmark] | None:
    """Landmarks on flat, open-sky ground in ``region``, away from walls and each other (None: no room)."""
    c = grid.cell_size
    names = [str(n) for n in rng.choice(np.asarray(config.landmark_names), size=config.num_landmarks, replace=False)]
    size = _square_size(config.landmark_radius, c)
    h = grid.heights
    flat = ndimage.maximum_filter(h, size=size, mode="nearest") - ndimage.minimum_filter(h, size=size, mode="nearest")
    flat = flat <= config.landmark_flatness
    under_ceiling = ndimage.maximum_filter(np.isfinite(grid.ceiling).astype(np.uint8), size=size, mode="constant")
    in_region = ndimage.minimum_filter(region.astype(np.uint8), size=size, mode="constant", cval=0)
    away = to_wall >= config.landmark_radius + config.landmark_wall_clearance + 0.5 * c
    candidates = np.flatnonzero(flat & (under_ceiling == 0) & (in_region == 1) & away)
    landmarks: list[Landmark] = []
    for name in names:
        if len(candidates) == 0:
            return None
        cell = int(candidates[rng.integers(len(candidates))])
        i, j = divmod(cell, h.shape[1])
        x, y = grid.cell_center(i, j)
        ground = float(h[i, j])
        landmarks.append(Landmark(name, (float(x), float(y)), config.landmark_radius,
                                  (float(x), float(y), ground + LANDMARK_MARKER_HEIGHT)))
        ci, cj = np.divmod(candidates, h.shape[1])
        centres = grid.cell_center(ci, cj)
        candidates = candidates[np.hypot(centres[:, 0] - x, centres[:, 1] - y) >= config.landmark_separation]
    return landmarks


def _resting_ball_height(grid: PlanningGrid, xy: np.ndarray, radius: float) -> np.ndarray:
    """Centre height (world z) of a ball of ``radius`` resting on the ground samples at points (N, 2).

    z = max over cell centres p within ``radius`` of (x, y) of h(p) + sqrt(radius^2 - |p - (x, y)|^2).
    """
    c = grid.cell_size
    reach = math.ceil(radius / c) + 1
    di, dj = np.mgrid[-reach:reach + 1, -reach:reach + 1]
    cells = grid.cell_of(xy)
    ii = np.clip(cells[:, :1] + di.ravel(), 0, grid.shape[0] - 1)
    jj = np.clip(cells[:, 1:] + dj.ravel(), 0, grid.shape[1] - 1)
    centres = grid.cell_center(ii, jj)
    squared = radius * radius - np.sum((centres - xy[:, None, :]) ** 2, axis=-1)
    lift = np.where(squared >= 0.0, np.sqrt(np.maximum(squared, 0.0)), -np.inf)
    return np.max(grid.heights[ii, jj] + lift, axis=1)


def _place_balls(config: SceneConfig, rng: np.random.Generator, scene: Scene, grid: PlanningGrid,
                 region: np.ndarray, to_wall: np.ndarray) -> list[DynamicObstacle] | None:
    """Balls rolling back and forth on straight open-sky paths in ``region`` (None: no room)."""
    c = grid.cell_size
    rows, cols = grid.shape
    balls: list[DynamicObstacle] = []
    for k in range(config.num_dynamic_obstacles):
        radius = rng.uniform(*config.ball_radius)
        speed = rng.uniform(*config.ball_speed)
        wanted = rng.uniform(*config.ball_path_length)
        phase = rng.uniform(0.0, 1.0)
        usable = region & ~np.isfinite(grid.ceiling) & (to_wall >= radius + c)
        starts = np.flatnonzero(usable)
        if len(starts) == 0:
            return None
        arc = np.arange(0.0, wanted + 1e-9, 0.5 * c)
        best_start, best_direction, best_length = None, None, -1.0
        for _try in range(64):
            i, j = divmod(int(starts[rng.integers(len(starts))]), cols)
            theta = rng.uniform(0.0, 2.0 * math.pi)
            start = grid.cell_center(i, j)
            direction = np.array([math.cos(theta), math.sin(theta)])
            cells = grid.cell_of(start + arc[:, None] * direction)
            inside = (cells[:, 0] >= 0) & (cells[:, 0] < rows) & (cells[:, 1] >= 0) & (cells[:, 1] < cols)
            ok = inside.copy()
            ok[inside] = usable[cells[inside, 0], cells[inside, 1]]
            reach = len(arc) if ok.all() else int(np.argmin(ok))
            length = float(arc[reach - 1]) if reach > 0 else 0.0
            if length > best_length:
                best_start, best_direction, best_length = start, direction, length
            if length >= wanted - 1e-9:
                break
        if best_length < config.ball_path_length[0] - 1e-9 and best_length < wanted - 1e-9:
            return None
        # Waypoints every 10 cm, each at the height where the ball rests on the ground there.
        samples = np.linspace(0.0, best_length, max(math.ceil(best_length / 0.1), 1) + 1)
        xy = best_start + samples[:, None] * best_direction
        path = np.column_stack((xy, _resting_ball_height(grid, xy, radius)))
        balls.append(DynamicObstacle(f"ball{k}", radius, WaypointLoop.back_and_forth(path, speed, phase)))
    return balls


def scene_patch_edges(config: SceneConfig) -> tuple[np.ndarray, np.ndarray]:
    """Where ``generate_scene`` puts the patch borders: (row_edges, col_edges), cell indices.

    Patch (p, q) covers rows ``row_edges[p]:row_edges[p + 1]`` and columns
    ``col_edges[q]:col_edges[q + 1]``; the last edges are the grid's shape (H, W).
    """
    c = config.cell_size
    cols = max(round(config.size[0] / c), 2)
    rows = max(round(config.size[1] / c), 2)
    patches_x = max(round(cols * c / config.patch_size), 1)
    patches_y = max(round(rows * c / config.patch_size), 1)
    return (np.round(np.linspace(0, rows, patches_y + 1)).astype(int),
            np.round(np.linspace(0, cols, patches_x + 1)).astype(int))


def generate_scene(config: SceneConfig, rng: np.random.Generator) -> Scene:
    """A random PlaMo scene (paper Sec. 5.4), centred on the world origin. Pure: same rng state, same scene.

    1. Terrain: the area is tiled with patches whose kinds are drawn with
       ``terrain_weights`` (at least ``min_flat_patches`` flat); each patch's heights come
       from its generator and meet the neighbours at height 0 on the patch rims.
    2. Low ceilings: tunnels / bridges on flat patches. 3. Walls elsewhere.
    4. Landmarks (``num_landmarks`` distinct names) on flat open-sky ground of the largest
       region a character can reach (``connected_free_space``), away from walls.
    5. Balls rolling back and forth (``WaypointLoop.back_and_forth``) on the terrain.

    Steps 2-5 are redrawn (up to ``max_attempts``) if the landmarks or balls find no room;
    then a ``RuntimeError`` says so.
    """
    c = config.cell_size
    row_edges, col_edges = scene_patch_edges(config)
    rows, cols = int(row_edges[-1]), int(col_edges[-1])
    patches_y, patches_x = len(row_edges) - 1, len(col_edges) - 1
    origin = (-0.5 * cols * c, -0.5 * rows * c)

    weights = np.asarray(config.terrain_weights) / sum(config.terrain_weights)
    kinds = rng.choice(len(TERRAIN_KINDS), size=(patches_y, patches_x), p=weights)
    missing_flat = config.min_flat_patches - int((kinds == 0).sum())
    if missing_flat > 0:
        others = np.flatnonzero(kinds != 0)
        kinds.flat[rng.permutation(others)[:missing_flat]] = 0

    heights = np.zeros((rows, cols))
    labels = np.zeros((rows, cols), dtype=np.uint8)
    flat_patch_rects: list[tuple[float, float, float, float]] = []
    for pi in range(patches_y):
        for pj in range(patches_x):
            r0, r1, c0, c1 = row_edges[pi], row_edges[pi + 1], col_edges[pj], col_edges[pj + 1]
            kind = int(kinds[pi, pj])
            heights[r0:r1, c0:c1] = generate_patch(config.patch_configs[kind], rng, shape=(r1 - r0, c1 - c0),
                                                   cell_size=c)
            labels[r0:r1, c0:c1] = kind
            if kind == 0:
                flat_patch_rects.append((origin[0] + c0 * c, origin[0] + c1 * c, origin[1] + r0 * c, origin[1] + r1 * c))

    for _attempt in range(config.max_attempts):
        slabs, supports = _low_ceiling_structures(config, rng, heights, origin, flat_patch_rects)
        walls = supports + _random_walls(config, rng, heights, origin, keep_clear=slabs + supports)
        scene = Scene(heights, c, origin, walls=walls, ceilings=slabs, terrain_labels=labels)
        grid = scene.planning_grid()
        region = connected_free_space(grid, max_step_height=config.max_step_height,
                                      min_clearance=config.min_clearance, body_radius=config.body_radius) == 0
        if grid.blocked.any():
            to_wall = ndimage.distance_transform_edt(~grid.blocked) * c
        else:
            to_wall = np.full(grid.shape, np.inf)
        landmarks = _place_landmarks(config, rng, grid, region, to_wall)
        if landmarks is None:
            continue
        balls = _place_balls(config, rng, scene, grid, region, to_wall)
        if balls is None:
            continue
        return Scene(heights, c, origin, walls=walls, ceilings=slabs, dynamic_obstacles=balls,
                     landmarks=landmarks, terrain_labels=labels)
    raise RuntimeError(
        f"generate_scene: no room for {config.num_landmarks} landmarks (or the balls) after "
        f"{config.max_attempts} attempts; use a larger size, more flat patches, fewer walls, "
        f"or a smaller landmark_separation / landmark_radius"
    )


def slalom_scene(*, num_walls: int = 5, wall_spacing: float = 3.0, corridor_width: float = 4.0,
                 gap_width: float = 1.2, wall_thickness: float = 0.2, wall_height: float = 1.5,
                 run_up: float = 3.0, landmark_radius: float = 0.5, cell_size: float = 0.05,
                 side_walls: bool = True) -> Scene:
    """The slalom test (PlaMo Sec. 5.3, Fig. 8, 11): sharp turns around wall corners on flat ground.

    A corridor along +x, ``corridor_width`` wide and centred on y = 0 and on x = 0. Walls
    across it every ``wall_spacing`` metres start alternately from the left (+y) and the
    right (-y) side and leave a ``gap_width`` opening at the other side, so the path
    weaves between their corners. Landmark ``"start"`` lies ``run_up`` / 2 before the
    first wall's line, ``"goal"`` the same after the last. ``side_walls`` closes the
    corridor's long sides (each ``wall_thickness`` thick, outside the corridor).
    """
    num_walls = SceneConfig._integer("num_walls", num_walls, 1, 100)
    wall_spacing = check_number("wall_spacing", wall_spacing, 0.5, 50.0)
    corridor_width = check_number("corridor_width", corridor_width, 1.0, 50.0)
    gap_width = check_number("gap_width", gap_width, 0.1, corridor_width - 0.1)
    wall_thickness = check_number("wall_thickness", wall_thickness, 0.01, min(5.0, 0.5 * wall_spacing))
    wall_height = check_number("wall_height", wall_height, 0.05, 10.0)
    landmark_radius = check_number("landmark_radius", landmark_radius, 0.05, 5.0)
    # The start and goal discs fit between the corridor's end and the first / last wall.
    run_up = check_number("run_up", run_up, 2.0 * landmark_radius + wall_thickness, 100.0)
    if 2.0 * landmark_radius > corridor_width:
        raise ValueError(f"landmark_radius must be at most corridor_width / 2 ({corridor_width / 2}), "
                         f"got {landmark_radius}")
    cell_size = check_number("cell_size", cell_size, 0.01, 0.5)

    course = 2.0 * run_up + (num_walls - 1) * wall_spacing
    margin = wall_thickness + cell_size
    cols = math.ceil((course + 2.0 * margin) / cell_size)
    rows = math.ceil((corridor_width + 2.0 * margin) / cell_size)
    origin = (-0.5 * cols * cell_size, -0.5 * rows * cell_size)
    half_width = 0.5 * corridor_width

    walls: list[Box] = []
    blade = corridor_width - gap_width
    for k in range(num_walls):
        x = -0.5 * course + run_up + k * wall_spacing
        side = 1.0 if k % 2 == 0 else -1.0  # first wall from the left (+y)
        y = side * (half_width - 0.5 * blade)
        walls.append(Box((x, y), (0.5 * wall_thickness, 0.5 * blade), 0.0, -0.1, wall_height))
    if side_walls:
        for side in (-1.0, 1.0):
            walls.append(Box((0.0, side * (half_width + 0.5 * wall_thickness)),
                             (0.5 * course, 0.5 * wall_thickness), 0.0, -0.1, wall_height))
    landmarks = [
        Landmark(name, (x, 0.0), landmark_radius, (x, 0.0, LANDMARK_MARKER_HEIGHT))
        for name, x in (("start", -0.5 * course + 0.5 * run_up), ("goal", 0.5 * course - 0.5 * run_up))
    ]
    return Scene(np.zeros((rows, cols)), cell_size, origin, walls=walls, landmarks=landmarks,
                 terrain_labels=np.zeros((rows, cols), dtype=np.uint8))


# --- MuJoCo --------------------------------------------------------------------------------------
# Depth of the height field's solid base below the scene's lowest point (MuJoCo size[3], m).
HFIELD_BASE_DEPTH = 0.5
# Ground planes already in the spec are lowered this far below the scene's lowest point, so
# that they neither poke through the height field nor render in the same place.
GROUND_PLANE_DROP = 0.01

GROUND_RGB = ((0.42, 0.47, 0.40), (0.36, 0.41, 0.35))
WALL_RGBA = (0.66, 0.62, 0.56, 1.0)
CEILING_RGBA = (0.55, 0.42, 0.30, 1.0)
BALL_RGBA = (0.15, 0.75, 0.25, 1.0)
LANDMARK_RGBA: tuple[tuple[float, float, float, float], ...] = (
    (0.90, 0.20, 0.20, 1.0), (0.20, 0.45, 0.90, 1.0), (0.95, 0.75, 0.10, 1.0), (0.65, 0.25, 0.80, 1.0),
    (0.10, 0.75, 0.75, 1.0), (0.95, 0.50, 0.15, 1.0), (0.55, 0.55, 0.55, 1.0), (0.90, 0.40, 0.70, 1.0),
)
LANDMARK_POST_RADIUS = 0.04
LANDMARK_DISC_HALF_HEIGHT = 0.005


@dataclass(eq=False)
class SceneHandles:
    """What ``add_scene_to_spec`` added (names), and their ids once bound to a compiled model.

    Call ``bind(model)`` after compiling (``update`` binds on first use): it writes the
    height field's elevation into ``model.hfield_data`` (the spec carries it too, so a
    fresh compile already has it; a renderer created before ``bind`` needs
    ``mujoco.mjr_uploadHField``) and looks up the ids. Call
    ``update(model, data, t)`` with t = ``data.time`` before each step to move the
    dynamic obstacles' mocap bodies to ``motion.position(t)``.
    """

    scene: Scene
    prefix: str
    hfield_name: str
    terrain_geom_name: str
    wall_geom_names: tuple[str, ...]
    ceiling_geom_names: tuple[str, ...]
    obstacle_body_names: tuple[str, ...]
    obstacle_geom_names: tuple[str, ...]
    landmark_geom_names: dict[str, tuple[str, ...]]
    elevation: np.ndarray  # (nrow * ncol,) float32 in [0, 1], MuJoCo's row-major order
    terrain_geom_id: int = -1
    wall_geom_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    ceiling_geom_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    obstacle_geom_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    obstacle_mocap_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    _bound_to: Any = field(default=None, repr=False)

    def bind(self, model: mujoco.MjModel) -> None:
        """Write the elevation data into ``model`` and look up the ids of the scene's parts."""
        hfield = model.hfield(self.hfield_name)
        count = int(hfield.nrow[0]) * int(hfield.ncol[0])
        if count != self.elevation.size:
            raise ValueError(f"height field {self.hfield_name!r} holds {count} samples, the scene "
                             f"{self.elevation.size}: was the model compiled from another scene?")
        start = int(model.hfield_adr[hfield.id])
        model.hfield_data[start:start + count] = self.elevation
        self.terrain_geom_id = model.geom(self.terrain_geom_name).id
        self.wall_geom_ids = np.array([model.geom(n).id for n in self.wall_geom_names], dtype=np.int64)
        self.ceiling_geom_ids = np.array([model.geom(n).id for n in self.ceiling_geom_names], dtype=np.int64)
        self.obstacle_geom_ids = np.array([model.geom(n).id for n in self.obstacle_geom_names], dtype=np.int64)
        bodies = [model.body(n).id for n in self.obstacle_body_names]
        self.obstacle_mocap_ids = np.array([model.body_mocapid[b] for b in bodies], dtype=np.int64)
        self._bound_to = model

    def obstacle_positions(self, t: float) -> np.ndarray:
        """(K, 3) world centres of the dynamic obstacles at time ``t`` (s)."""
        return self.scene.dynamic_positions(t)

    def update(self, model: mujoco.MjModel, data: mujoco.MjData, t: float) -> None:
        """Move the dynamic obstacles' mocap bodies to their positions at time ``t`` (s)."""
        if self._bound_to is not model:
            self.bind(model)
        if len(self.obstacle_mocap_ids):
            data.mocap_pos[self.obstacle_mocap_ids] = self.obstacle_positions(t)


def _material(spec: mujoco.MjSpec, name: str, rgba: Sequence[float]) -> str:
    spec.add_material(name=name, rgba=list(rgba))
    return name


def add_scene_to_spec(spec: mujoco.MjSpec, scene: Scene, *, prefix: str = "scene",
                      lower_ground_planes: bool = True) -> SceneHandles:
    """Add ``scene`` to ``spec`` (e.g. ``load_humanoid_spec()``); compile, then ``handles.bind(model)``.

    - Ground: a height field on its own static body. Its samples are the scene's cell
      centres plus a one-cell rim that repeats the border values, so it covers the grid
      exactly and half a cell beyond: ``nrow = H + 2`` (along y, data row 0 at the lowest
      y), ``ncol = W + 2`` (along x), ``size = ((W + 1) c / 2, (H + 1) c / 2, h_max - h_min,
      HFIELD_BASE_DEPTH)``, body at the grid's centre at z = h_min, elevation normalised to
      [0, 1]. (With h_min = 0, as in generated scenes, size[2] is the highest point.)
    - Walls and ceilings: one box geom per static body (``{prefix}_wall{k}``,
      ``{prefix}_ceiling{k}``).
    - Dynamic obstacles: a mocap body with a sphere geom each (``{prefix}_obstacle{k}``),
      placed at ``position(0)``; they collide with the character.
    - Landmarks: visual-only markers (contype = conaffinity = 0, group 2): a disc over the
      landmark's area, a post up to ``display_position`` and a ball on top.
    - ``lower_ground_planes``: plane geoms of the world body (the humanoid's floor) are
      moved to ``GROUND_PLANE_DROP`` below the scene's lowest point: they keep catching
      whatever leaves the scene without touching or hiding the height field.
    """
    rows, cols = scene.shape
    c = scene.cell_size
    padded = np.pad(scene.heights, 1, mode="edge")
    low, high = float(padded.min()), float(padded.max())
    span = high - low
    elevation = ((padded - low) / span if span > 0.0 else np.zeros_like(padded)).astype(np.float32).ravel()
    x_min, x_max, y_min, y_max = scene.bounds

    ground_texture = f"{prefix}_ground"
    spec.add_texture(name=ground_texture, type=mujoco.mjtTexture.mjTEXTURE_2D,
                     builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER, rgb1=list(GROUND_RGB[0]),
                     rgb2=list(GROUND_RGB[1]), width=256, height=256)
    ground_material = spec.add_material(name=f"{prefix}_ground", texrepeat=[1.0, 1.0], texuniform=True)
    ground_material.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = ground_texture
    wall_material = _material(spec, f"{prefix}_wall", WALL_RGBA)
    ceiling_material = _material(spec, f"{prefix}_ceiling", CEILING_RGBA)
    ball_material = _material(spec, f"{prefix}_ball", BALL_RGBA)

    hfield_name = f"{prefix}_terrain"
    hfield = spec.add_hfield(name=hfield_name, nrow=rows + 2, ncol=cols + 2,
                             size=[0.5 * (cols + 1) * c, 0.5 * (rows + 1) * c, span if span > 0.0 else 1e-3,
                                   HFIELD_BASE_DEPTH])
    # MuJoCo needs the data at compile time too (it normalises it again: a no-op here).
    hfield.userdata = elevation.astype(np.float64).tolist()
    terrain = spec.worldbody.add_body(name=f"{prefix}_terrain", pos=[0.5 * (x_min + x_max), 0.5 * (y_min + y_max), low])
    terrain.add_geom(name=f"{prefix}_terrain", type=mujoco.mjtGeom.mjGEOM_HFIELD, hfieldname=hfield_name,
                     material=f"{prefix}_ground", condim=3)

    if lower_ground_planes:
        for geom in spec.worldbody.geoms:
            if geom.type == mujoco.mjtGeom.mjGEOM_PLANE:
                geom.pos = [geom.pos[0], geom.pos[1], min(float(geom.pos[2]), low - GROUND_PLANE_DROP)]

    def add_boxes(boxes: list[Box], kind: str, material: str) -> tuple[str, ...]:
        names = []
        for k, box in enumerate(boxes):
            name = f"{prefix}_{kind}{k}"
            body = spec.worldbody.add_body(name=name, pos=box.center_xyz.tolist(), quat=_yaw_quat(box.yaw))
            body.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_BOX, size=box.half_extents_xyz.tolist(),
                          material=material, condim=3)
            names.append(name)
        return tuple(names)

    wall_names = add_boxes(scene.walls, "wall", wall_material)
    ceiling_names = add_boxes(scene.ceilings, "ceiling", ceiling_material)

    obstacle_names = []
    for k, obstacle in enumerate(scene.dynamic_obstacles):
        name = f"{prefix}_obstacle{k}"
        body = spec.worldbody.add_body(name=name, mocap=True, pos=obstacle.position(0.0).tolist())
        body.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[obstacle.radius, 0.0, 0.0],
                      material=ball_material, condim=3)
        obstacle_names.append(name)

    landmark_geoms: dict[str, tuple[str, ...]] = {}
    for k, landmark in enumerate(scene.landmarks):
        rgba = LANDMARK_RGBA[k % len(LANDMARK_RGBA)]
        material = _material(spec, f"{prefix}_landmark{k}", rgba)
        x, y = landmark.center
        ground = float(scene.height_at(np.array(landmark.center)))
        top = max(landmark.display_position[2], ground + 0.05)
        disc_rgba = [rgba[0], rgba[1], rgba[2], 0.35]
        parts = (
            (f"{prefix}_landmark{k}_area", [x, y, ground + LANDMARK_DISC_HALF_HEIGHT + 0.001],
             {"type": mujoco.mjtGeom.mjGEOM_CYLINDER,
              "size": [max(landmark.radius, 0.05), LANDMARK_DISC_HALF_HEIGHT, 0.0], "rgba": disc_rgba}),
            (f"{prefix}_landmark{k}_post", [x, y, 0.5 * (ground + top)],
             {"type": mujoco.mjtGeom.mjGEOM_CYLINDER, "size": [LANDMARK_POST_RADIUS, 0.5 * (top - ground), 0.0],
              "material": material}),
            (f"{prefix}_landmark{k}_top", [x, y, top],
             {"type": mujoco.mjtGeom.mjGEOM_SPHERE, "size": [0.1, 0.0, 0.0], "material": material}),
        )
        for name, pos, geom in parts:
            body = spec.worldbody.add_body(name=name, pos=pos)
            body.add_geom(name=name, contype=0, conaffinity=0, group=2, **geom)
        landmark_geoms[landmark.name] = tuple(name for name, _, _ in parts)

    return SceneHandles(
        scene=scene, prefix=prefix, hfield_name=hfield_name, terrain_geom_name=f"{prefix}_terrain",
        wall_geom_names=wall_names, ceiling_geom_names=ceiling_names,
        obstacle_body_names=tuple(obstacle_names), obstacle_geom_names=tuple(obstacle_names),
        landmark_geom_names=landmark_geoms, elevation=elevation,
    )
