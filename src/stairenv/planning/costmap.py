"""A ``PlanningGrid`` prepared for one locomotion: the maps every planner stage reads.

Built once per (grid, locomotion) and reused by A*, the refiner and replanning:

- ``terrain``: the ground the planner climbs, heights averaged over ``slope_window``
  (a uniform filter; stairs become the ramp they form, so their slope is rise / run
  and not riser / cell size). Slopes, edge costs and head heights use it.
- ``clearance``: distance (m) from each cell centre to the nearest blocked cell centre,
  ``scipy.ndimage.distance_transform_edt(~blocked) * cell_size`` (inf without walls).
- ``headroom``: ceiling - max(height, terrain), the smallest over a disc of radius
  ``head_radius`` around the cell (m; inf under open sky); ``ceiling_low``: the lowest
  ceiling over the same disc (the refiner keeps the head below it).
- ``passable`` = ``free & wide & tall``, with ``free = ~blocked``,
  ``wide = clearance >= body_radius`` (walls inflated by the body) and
  ``tall = headroom >= head_min + ceiling_margin`` (the locomotion's lowest head
  height plus a margin fits under the ceiling).

Edges (``stairenv.planning.astar``) additionally need
|terrain_b - terrain_a| <= max_slope * length and |height_b - height_a| <= max_step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy import ndimage

from .errors import check_range
from .grid import PlanningGrid
from .locomotion import Locomotion, get_locomotion


@dataclass(frozen=True, eq=False)
class Costmap:
    grid: PlanningGrid
    locomotion: Locomotion
    terrain: np.ndarray      # (H, W) smoothed ground height (m)
    clearance: np.ndarray    # (H, W) distance to the nearest blocked cell centre (m)
    headroom: np.ndarray     # (H, W) ceiling minus ground over the head's footprint (m)
    ceiling_low: np.ndarray  # (H, W) lowest ceiling over the head's footprint (m; inf under open sky)
    free: np.ndarray         # (H, W) bool, not blocked
    wide: np.ndarray         # (H, W) bool, clearance >= body_radius
    tall: np.ndarray         # (H, W) bool, headroom >= head_min + ceiling_margin
    passable: np.ndarray     # (H, W) bool, free & wide & tall
    body_radius: float
    ceiling_margin: float
    head_radius: float
    max_slope: float
    max_step: float
    slope_window: float
    height_cost: float
    slope_preference: float

    @property
    def cell_size(self) -> float:
        return self.grid.cell_size

    @property
    def heights(self) -> np.ndarray:
        return self.grid.heights

    @property
    def required_headroom(self) -> float:
        return self.locomotion.head_min + self.ceiling_margin

    def tall_for(self, locomotion: str | Locomotion) -> np.ndarray:
        """``tall`` for another locomotion (used to say which one would fit under a ceiling)."""
        return self.headroom >= get_locomotion(locomotion).head_min + self.ceiling_margin

    def with_locomotion(self, locomotion: str | Locomotion) -> Costmap:
        """The same maps for another locomotion (only ``tall``/``passable`` change)."""
        loc = get_locomotion(locomotion)
        tall = self.headroom >= loc.head_min + self.ceiling_margin
        return replace(self, locomotion=loc, tall=tall, passable=self.free & self.wide & tall)


def _disc(radius_cells: float) -> np.ndarray:
    r = math.floor(radius_cells)
    ii, jj = np.mgrid[-r:r + 1, -r:r + 1]
    return ii * ii + jj * jj <= radius_cells * radius_cells + 1e-9


def build_costmap(
    grid: PlanningGrid,
    locomotion: str | Locomotion = "walk",
    *,
    body_radius: float = 0.25,
    ceiling_margin: float = 0.1,
    head_radius: float = 0.15,
    max_slope: float = 1.0,
    max_step: float = 0.3,
    slope_window: float = 0.5,
    height_cost: float = 1.0,
    slope_preference: float = 0.0,
) -> Costmap:
    """Prepare ``grid`` for ``locomotion`` (see the module docstring for the maps).

    body_radius (m, >= 0): walls are inflated by it (cells closer to a blocked cell centre
        are impassable). ceiling_margin (m, >= 0): headroom kept above the head.
    head_radius (m, finite >= 0): footprint over which the lowest ceiling counts.
    max_slope (>= 0): steepest terrain slope rise/run of an edge; max_step (m, >= 0):
        highest raw height jump between neighbouring cells.
    slope_window (m, finite >= 0): width of the terrain's averaging window (0: raw heights).
    height_cost (>= 0) and slope_preference c (>= 0): edge cost
        w = d + height_cost |dh| + d (e^{c |dh| / d} - 1)  (d the edge length, dh the terrain rise).
    Raises ValueError for a grid whose maps ``PlanningGrid.check_maps`` rejects (they may have
    been edited since the grid was built).
    """
    if not isinstance(grid, PlanningGrid):
        raise TypeError(f"grid must be a PlanningGrid, got {type(grid).__name__}")
    grid.check_maps()
    loc = get_locomotion(locomotion)
    body_radius = check_range("body_radius", body_radius, 0.0)
    ceiling_margin = check_range("ceiling_margin", ceiling_margin, 0.0)
    # head_radius and slope_window become window sizes in cells: they must be finite
    head_radius = check_range("head_radius", head_radius, 0.0, math.inf, high_open=True)
    max_slope = check_range("max_slope", max_slope, 0.0)
    max_step = check_range("max_step", max_step, 0.0)
    slope_window = check_range("slope_window", slope_window, 0.0, math.inf, high_open=True)
    height_cost = check_range("height_cost", height_cost, 0.0, math.inf, high_open=True)
    slope_preference = check_range("slope_preference", slope_preference, 0.0, 50.0)
    c = grid.cell_size
    heights = grid.heights
    n = round(slope_window / c)
    n += 1 - n % 2  # odd window
    terrain = ndimage.uniform_filter(heights, size=n, mode="nearest") if n > 1 else heights.copy()
    free = ~grid.blocked
    if grid.blocked.any():
        clearance = ndimage.distance_transform_edt(free) * c
    else:
        clearance = np.full(heights.shape, np.inf)
    headroom = grid.ceiling - np.maximum(heights, terrain)
    ceiling_low = grid.ceiling
    if head_radius >= c and np.isfinite(grid.ceiling).any():
        footprint = _disc(head_radius / c)
        headroom = ndimage.minimum_filter(headroom, footprint=footprint, mode="nearest")
        ceiling_low = ndimage.minimum_filter(grid.ceiling, footprint=footprint, mode="nearest")
    wide = clearance >= body_radius - 1e-9
    tall = headroom >= loc.head_min + ceiling_margin
    return Costmap(grid, loc, terrain, clearance, headroom, ceiling_low, free, wide, tall, free & wide & tall,
                   body_radius, ceiling_margin, head_radius, max_slope, max_step, slope_window,
                   height_cost, slope_preference)
