"""Free floor on a grid: ``FreeSpace`` and the reachability check of a furnished room."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from scipy import ndimage

from stairenv.world.furniture import PlacedFurniture
from stairenv.world.rooms.config import FRONT_ACCESS_FAMILIES
from stairenv.world.rooms.doors import Door
from stairenv.world.scenes import Box


class RoomShape(Protocol):
    """What the free-space check reads of a room (``rooms.model.Room`` is one; this module sits below it)."""

    name: str
    bounds: tuple[float, float, float, float]
    wall_thickness: float

    @property
    def center(self) -> np.ndarray: ...

    def contains_xy(self, xy: np.ndarray) -> np.ndarray: ...


@dataclass(frozen=True, eq=False)
class FreeSpace:
    """Where a character of ``body_radius`` can stand, on a grid (rows y, columns x).

    Cell (i, j) covers x in [x0 + j c, x0 + (j + 1) c), y in [y0 + i c, ...) with
    (x0, y0) = ``origin``, c = ``cell_size``. ``labels`` (H, W): 0 where not free,
    1, 2, ... the 4-connected component of each free cell.
    """

    labels: np.ndarray
    origin: tuple[float, float]
    cell_size: float

    @property
    def free(self) -> np.ndarray:
        return self.labels > 0

    def cell_of(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        p = np.asarray(points, dtype=float)[..., :2]
        j = np.floor((p[..., 0] - self.origin[0]) / self.cell_size).astype(int)
        i = np.floor((p[..., 1] - self.origin[1]) / self.cell_size).astype(int)
        return i, j

    def label_at(self, points: np.ndarray) -> np.ndarray:
        """Component label (0: blocked or off the grid) at world points (..., 2|3)."""
        i, j = self.cell_of(points)
        rows, cols = self.labels.shape
        ok = (i >= 0) & (i < rows) & (j >= 0) & (j < cols)
        out = np.zeros(np.shape(i), dtype=self.labels.dtype)
        out[ok] = self.labels[i[ok], j[ok]]
        return out


def _cell_centres(shape: tuple[int, int], origin: tuple[float, float], c: float) -> np.ndarray:
    rows, cols = shape
    xs = origin[0] + (np.arange(cols) + 0.5) * c
    ys = origin[1] + (np.arange(rows) + 0.5) * c
    gx, gy = np.meshgrid(xs, ys)
    return np.stack((gx, gy), axis=-1)


def label_free(blocked: np.ndarray, c: float, body_radius: float) -> np.ndarray:
    """4-connected component labels of the cells whose centre is more than ``body_radius`` from blocked cells."""
    padded = np.pad(blocked, 1, constant_values=True)
    dist = ndimage.distance_transform_edt(~padded)[1:-1, 1:-1] * c
    free = dist - 0.5 * c >= body_radius
    labels, _ = ndimage.label(free)
    return labels


def reach_points(placed: PlacedFurniture, body_radius: float, reach: float, c: float) -> np.ndarray:
    """World (N, 2) standing points from which the piece is within ``reach`` (m): its front
    edge for ``FRONT_ACCESS_FAMILIES``, otherwise any side."""
    hx, hy = placed.furniture.footprint
    offsets = np.arange(body_radius + 0.5 * c, reach + 1e-9, 0.5 * c)
    if len(offsets) == 0:
        offsets = np.array([reach])
    pts = []
    for o in offsets:
        ny = max(2, math.ceil(2 * (hy + o) / (0.5 * c)) + 1)
        ys = np.linspace(-hy, hy, ny)
        pts.append(np.column_stack((np.full(ny, hx + o), ys)))  # front
        if placed.family not in FRONT_ACCESS_FAMILIES:
            pts.append(np.column_stack((np.full(ny, -hx - o), ys)))
            nx_ = max(2, math.ceil(2 * (hx + o) / (0.5 * c)) + 1)
            xs = np.linspace(-hx - o, hx + o, nx_)
            pts.append(np.column_stack((xs, np.full(nx_, hy + o))))
            pts.append(np.column_stack((xs, np.full(nx_, -hy - o))))
    local = np.concatenate(pts)
    local3 = np.column_stack((local, np.zeros(len(local))))
    return placed.to_world(local3)[:, :2]


def build_free_space(rooms: Sequence[RoomShape], walls: Sequence[Box], doors: Sequence[Door],
                     furniture: Sequence[PlacedFurniture], c: float, body_radius: float) -> FreeSpace:
    t = max(r.wall_thickness for r in rooms)
    lo = np.min([r.bounds[:2] for r in rooms], axis=0) - t - 2 * c
    hi = np.max([r.bounds[2:] for r in rooms], axis=0) + t + 2 * c
    shape = (math.ceil((hi[1] - lo[1]) / c), math.ceil((hi[0] - lo[0]) / c))
    origin = (float(lo[0]), float(lo[1]))
    centres = _cell_centres(shape, origin, c)
    inside = np.zeros(shape, dtype=bool)
    for r in rooms:
        inside |= r.contains_xy(centres)
    for d in doors:
        inside |= d.gap_box(t + 2 * c).contains_xy(centres)
    blocked = ~inside
    for w in walls:
        blocked |= w.overlapping_cells(shape, c, origin)
    for f in furniture:
        blocked |= f.footprint_box().overlapping_cells(shape, c, origin)
    return FreeSpace(label_free(blocked, c, body_radius), origin, c)


def all_reachable(space: FreeSpace, rooms: Sequence[RoomShape], doors: Sequence[Door],
                  furniture: Sequence[PlacedFurniture], body_radius: float, reach: float, c: float) -> bool:
    targets = []
    for d in doors:
        for r in rooms:
            if r.name in d.rooms:
                targets.append(d.approach_point(r.bounds, 0.5 * r.wall_thickness + body_radius + 2 * c)[None])
    if not targets:
        targets.append(rooms[0].center[None])
    start = space.label_at(targets[0])[0]
    if start == 0:
        return False
    if any(space.label_at(p)[0] != start for p in targets[1:]):
        return False
    return all(np.any(space.label_at(reach_points(f, body_radius, reach, c)) == start) for f in furniture)
