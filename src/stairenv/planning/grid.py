"""The planner's view of a scene: regular grids over the ground plane.

A scene (``stairenv.world.scenes``) hands the planner a ``PlanningGrid``; the
planner never sees MuJoCo. Cell (i, j) covers x in [x0 + j c, x0 + (j + 1) c),
y in [y0 + i c, y0 + (i + 1) c) with c = ``cell_size`` and (x0, y0) = ``origin``:
rows are y, columns are x, and a cell's centre is ``cell_center(i, j)``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


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
        if self.heights.ndim != 2 or self.blocked.shape != self.heights.shape or self.ceiling.shape != self.heights.shape:
            raise ValueError(
                f"heights, blocked and ceiling must be 2-D arrays of one shape, got "
                f"{self.heights.shape}, {self.blocked.shape}, {self.ceiling.shape}"
            )
        if not self.cell_size > 0:
            raise ValueError(f"cell_size must be > 0, got {self.cell_size!r}")
        if not np.isfinite(self.heights).all():
            raise ValueError("heights must be finite")
        for name, cells in self.landmarks.items():
            cells = np.asarray(cells, dtype=np.int64).reshape(-1, 2)
            if len(cells) == 0 or cells.min() < 0 or np.any(cells >= self.heights.shape):
                raise ValueError(f"landmark {name!r} has no cells or cells outside the grid {self.heights.shape}")
            self.landmarks[name] = cells

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
