"""Boxes with vertical sides (walls, ceiling slabs, pillars) and the small checks the scene parts share."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from stairenv.validation import check_number, check_range


# --- small helpers -------------------------------------------------------------------------------
def check_floats(name: str, value: Any, count: int) -> tuple[float, ...]:
    """``value`` as a tuple of ``count`` finite floats (lists from JSON become tuples)."""
    try:
        numbers = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be {count} finite numbers, got {value!r}") from None
    if len(numbers) != count or not all(math.isfinite(v) for v in numbers):
        raise ValueError(f"{name} must be {count} finite numbers, got {value!r}")
    return numbers


def check_integer(name: str, value: Any, low: int, high: int) -> int:
    """``value`` as an int in [low, high]; a float without a fraction (3.0) is accepted."""
    number = check_number(name, value, low, high)
    if int(number) != number:
        raise ValueError(f"{name} must be an integer in [{low}, {high}], got {value!r}")
    return int(number)


def check_int_range(name: str, value: Sequence[float], low: int, high: int) -> tuple[int, int]:
    lo, hi = check_range(name, value, low, high)
    if int(lo) != lo or int(hi) != hi:
        raise ValueError(f"{name} must be a (min, max) pair of integers within [{low}, {high}], got {value!r}")
    return int(lo), int(hi)


def kwargs_from_json(cls: type, data: Any, what: str) -> dict[str, Any]:
    """Keyword arguments for dataclass ``cls`` from a JSON object, with clear errors."""
    if not isinstance(data, dict):
        raise TypeError(f"{what} must be a JSON object, got {type(data).__name__}")
    names = {f.name for f in fields(cls) if f.init}
    unknown = set(data) - names - {"kind"}
    if unknown:
        raise ValueError(f"{what} has unknown keys {sorted(unknown)}; expected {sorted(names)}")
    return {k: v for k, v in data.items() if k in names}


def yaw_axes(yaw: float) -> tuple[np.ndarray, np.ndarray]:
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
        object.__setattr__(self, "center", check_floats("center", self.center, 2))
        half = check_floats("half_size", self.half_size, 2)
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
        return yaw_axes(self.yaw)

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
        return cls(**kwargs_from_json(cls, data, "box"))
