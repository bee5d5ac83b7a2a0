"""The planner's view of a scene: regular grids over the ground plane.

A scene (``stairenv.world.scenes``) hands the planner a ``PlanningGrid``; the
planner never sees MuJoCo. Cell (i, j) covers x in [x0 + j c, x0 + (j + 1) c),
y in [y0 + i c, y0 + (i + 1) c) with c = ``cell_size`` and (x0, y0) = ``origin``:
rows are y, columns are x, and a cell's centre is ``cell_center(i, j)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .errors import check_cells, check_range, quote


@dataclass
class PlanningGrid:
    heights: np.ndarray                 # (H, W) ground height (m)
    blocked: np.ndarray                 # (H, W) bool: walls and other static obstacles
    ceiling: np.ndarray                 # (H, W) height of the lowest overhead obstacle (m); inf where open sky
    cell_size: float                    # (m)
    origin: tuple[float, float] = (0.0, 0.0)
    landmarks: dict[str, np.ndarray] = field(default_factory=dict)  # name -> (K, 2) int cells (i, j)

    def __post_init__(self) -> None:
        self.heights = np.asarray(self.heights, dtype=np.float64)
        self.blocked = np.asarray(self.blocked, dtype=bool)
        self.ceiling = np.asarray(self.ceiling, dtype=np.float64)
        self.cell_size = check_range("cell_size", self.cell_size, 0.0, math.inf, low_open=True, high_open=True)
        self.origin = _finite_pair("origin", self.origin)
        self.check_maps()
        for name, cells in self.landmarks.items():
            self.landmarks[name] = check_cells(f"landmark {quote(name)}", cells, self.heights.shape)

    def check_maps(self) -> None:
        """Raise ValueError unless the maps are planner-readable: 2-D arrays of one shape, finite
        heights, ceilings that are heights or +inf (a NaN ceiling would read as "too low"), a
        finite cell size > 0. Run again by ``build_costmap``: the arrays may be edited in place."""
        shape = self.heights.shape
        if len(shape) != 2 or self.blocked.shape != shape or self.ceiling.shape != shape:
            raise ValueError(
                f"heights, blocked and ceiling must be 2-D arrays of one shape, got "
                f"{self.heights.shape}, {self.blocked.shape}, {self.ceiling.shape}"
            )
        check_range("cell_size", self.cell_size, 0.0, math.inf, low_open=True, high_open=True)
        _check_map("heights", self.heights, "finite heights (m)", np.isfinite(self.heights))
        _check_map("ceiling", self.ceiling, "heights (m) or inf (open sky)",
                   np.isfinite(self.ceiling) | (self.ceiling == np.inf))

    @property
    def shape(self) -> tuple[int, int]:
        return self.heights.shape

    def cell_center(self, i: np.ndarray | int, j: np.ndarray | int) -> np.ndarray:
        """World (x, y) of cell centres; broadcasts over arrays of indices."""
        i, j = np.asarray(i), np.asarray(j)
        return np.stack((self.origin[0] + (j + 0.5) * self.cell_size,
                         self.origin[1] + (i + 0.5) * self.cell_size), axis=-1)

    def cell_of(self, xy: np.ndarray) -> np.ndarray:
        """Cell (i, j) containing world points (..., 2)."""
        xy = np.asarray(xy, dtype=np.float64)
        j = np.floor((xy[..., 0] - self.origin[0]) / self.cell_size).astype(np.int64)
        i = np.floor((xy[..., 1] - self.origin[1]) / self.cell_size).astype(np.int64)
        return np.stack((i, j), axis=-1)


def _finite_pair(name: str, value: object) -> tuple[float, float]:
    try:
        pair = np.asarray(value, dtype=np.float64).ravel()
    except (TypeError, ValueError):
        pair = np.empty(0)
    if pair.shape != (2,) or not np.isfinite(pair).all():
        raise ValueError(f"{name} must be two finite numbers (x, y) in metres, got {quote(value)}")
    return float(pair[0]), float(pair[1])


def _check_map(name: str, values: np.ndarray, expected: str, ok: np.ndarray) -> None:
    if not ok.all():
        bad = np.argwhere(~ok)
        i, j = bad[0]
        raise ValueError(f"{name} must hold {expected}; {len(bad)} cells do not, e.g. cell ({i}, {j}) "
                         f"holds {float(values[i, j])}")
