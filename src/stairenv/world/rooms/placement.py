"""Placing furniture in a room: candidate poses (at a wall, at a table, free) kept only
while footprints stay apart and the free floor stays connected."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from stairenv.world.furniture import (
    PlacedFurniture,
    make_furniture,
)
from stairenv.world.rooms.config import PLACEMENT_ORDER, TABLE_SEATS, WALL_FAMILIES, RoomConfig
from stairenv.world.rooms.doors import Door
from stairenv.world.rooms.free_space import label_free, reach_points
from stairenv.world.scenes import Box


# --- placement -----------------------------------------------------------------------------------
@dataclass
class _Layout:
    """Mutable state while furnishing one room (interior grid, placed pieces)."""

    cfg: RoomConfig
    bounds: tuple[float, float, float, float]
    doors: list[Door]
    shape: tuple[int, int] = (0, 0)
    origin: tuple[float, float] = (0.0, 0.0)
    occupied: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), dtype=bool))
    placed: list[PlacedFurniture] = field(default_factory=list)
    reach_cells: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)
    door_cells: list[tuple[int, int]] = field(default_factory=list)
    door_zones: list[Box] = field(default_factory=list)
    radius: float = 0.0
    reach: float = 0.0

    def __post_init__(self) -> None:
        c = self.cfg.cell_size
        # Placement checks with one cell of margin (a wider body, a shorter reach), so the
        # room stays connected on any grid alignment (``Room.is_connected``, other tools).
        self.radius = self.cfg.body_radius + c
        self.reach = max(self.cfg.reach_distance - c, self.radius + c)
        x0, y0, x1, y1 = self.bounds
        self.shape = (max(1, math.floor((y1 - y0) / c + 1e-9)), max(1, math.floor((x1 - x0) / c + 1e-9)))
        self.origin = (x0, y0)
        self.occupied = np.zeros(self.shape, dtype=bool)
        depth = 0.5 * self.cfg.wall_thickness + self.radius + 2 * c
        for d in self.doors:
            p = d.approach_point(self.bounds, depth)
            self.door_cells.append(self._cell(p))
            n = d.inward(self.bounds)
            zone_depth = max(self.cfg.door_clearance, depth + c)
            centre = np.asarray(d.center) + n * (0.5 * self.cfg.wall_thickness + 0.5 * zone_depth)
            half_along = 0.5 * d.width + 0.1
            half = (0.5 * zone_depth, half_along) if d.axis == 0 else (half_along, 0.5 * zone_depth)
            self.door_zones.append(Box(tuple(centre), half, 0.0, 0.0, 2.0))

    def _cell(self, p: np.ndarray) -> tuple[int, int]:
        c = self.cfg.cell_size
        j = int(np.clip(math.floor((p[0] - self.origin[0]) / c), 0, self.shape[1] - 1))
        i = int(np.clip(math.floor((p[1] - self.origin[1]) / c), 0, self.shape[0] - 1))
        return i, j

    def _reach(self, f: PlacedFurniture) -> tuple[np.ndarray, np.ndarray]:
        pts = reach_points(f, self.radius, self.reach, self.cfg.cell_size)
        c = self.cfg.cell_size
        j = np.floor((pts[:, 0] - self.origin[0]) / c).astype(int)
        i = np.floor((pts[:, 1] - self.origin[1]) / c).astype(int)
        ok = (i >= 0) & (i < self.shape[0]) & (j >= 0) & (j < self.shape[1])
        return i[ok], j[ok]

    def fits(self, cand: PlacedFurniture, table: PlacedFurniture | None) -> bool:
        """Inside the interior, apart from the others and the doors' areas (no grid yet)."""
        box = cand.footprint_box()
        x0, y0, x1, y1 = self.bounds
        corners = box.corners_xy()
        eps = 1e-6
        if corners[:, 0].min() < x0 - eps or corners[:, 0].max() > x1 + eps:
            return False
        if corners[:, 1].min() < y0 - eps or corners[:, 1].max() > y1 + eps:
            return False
        if any(box.footprint_overlaps(z) for z in self.door_zones):
            return False
        for other in self.placed:
            margin = 0.0 if other is table else 0.5 * self.cfg.clearance
            if box.footprint_overlaps(other.footprint_box(), margin):
                return False
        return True

    def connected_with(self, cand: PlacedFurniture) -> tuple[bool, np.ndarray]:
        """Whether the doors and all pieces (with ``cand``) stay reachable; and cand's mask."""
        mask = cand.footprint_box().overlapping_cells(self.shape, self.cfg.cell_size, self.origin)
        labels = label_free(self.occupied | mask, self.cfg.cell_size, self.radius)
        if self.door_cells:
            start = labels[self.door_cells[0]]
        else:  # no door: the largest free component
            counts = np.bincount(labels.ravel())
            counts[0] = 0
            start = int(np.argmax(counts)) if counts.size > 1 else 0
        if start == 0 or any(labels[cell] != start for cell in self.door_cells[1:]):
            return False, mask
        for i, j in self.reach_cells + [self._reach(cand)]:
            if not np.any(labels[i, j] == start):
                return False, mask
        return True, mask

    def add(self, cand: PlacedFurniture, mask: np.ndarray) -> None:
        self.placed.append(cand)
        self.occupied |= mask
        self.reach_cells.append(self._reach(cand))


_WALL_YAW = {"west": 0.0, "east": math.pi, "south": 0.5 * math.pi, "north": -0.5 * math.pi}


def _wall_pose(rng: np.random.Generator, bounds: Sequence[float], fp: tuple[float, float], side: str,
               gap: float, corner: bool = False) -> tuple[float, float, float] | None:
    """A pose with the piece's back to wall ``side`` (front into the room)."""
    x0, y0, x1, y1 = bounds
    hx, hy = fp
    if side in ("west", "east"):
        lo, hi = y0 + hy, y1 - hy
    else:
        lo, hi = x0 + hy, x1 - hy
    if hi < lo:
        return None
    if corner:
        t = lo if rng.uniform() < 0.5 else hi
    else:
        t = float(rng.uniform(lo, hi))
    if side == "west":
        return (x0 + gap + hx, t, _WALL_YAW[side])
    if side == "east":
        return (x1 - gap - hx, t, _WALL_YAW[side])
    if side == "south":
        return (t, y0 + gap + hx, _WALL_YAW[side])
    return (t, y1 - gap - hx, _WALL_YAW[side])


def _free_pose(rng: np.random.Generator, bounds: Sequence[float], fp: tuple[float, float],
               yaw: float) -> tuple[float, float, float] | None:
    x0, y0, x1, y1 = bounds
    c, s = abs(math.cos(yaw)), abs(math.sin(yaw))
    ex, ey = fp[0] * c + fp[1] * s, fp[0] * s + fp[1] * c
    if x1 - x0 < 2 * ex or y1 - y0 < 2 * ey:
        return None
    return (float(rng.uniform(x0 + ex, x1 - ex)), float(rng.uniform(y0 + ey, y1 - ey)), yaw)


def _table_pose(rng: np.random.Generator, table: PlacedFurniture, fp: tuple[float, float],
                gap_range: tuple[float, float]) -> tuple[float, float, float]:
    """A chair / stool pose at ``table``, its front (+x) facing the table."""
    gap = float(rng.uniform(*gap_range))
    thx, thy = table.furniture.footprint
    if table.furniture.params.get("round", False):
        a = float(rng.uniform(0.0, 2.0 * math.pi))
        dist, lateral = thx + gap + fp[0], 0.0
    else:
        k = int(rng.integers(0, 4))
        a = 0.5 * math.pi * k
        half_normal, half_side = (thx, thy) if k % 2 == 0 else (thy, thx)
        dist = half_normal + gap + fp[0]
        room_along = max(0.0, half_side - 0.8 * fp[1])
        lateral = float(rng.uniform(-room_along, room_along))
    u = np.array([math.cos(a), math.sin(a)])
    v = np.array([-u[1], u[0]])
    local = dist * u + lateral * v
    world = table.rotation[:2, :2] @ local + table.position
    yaw = table.yaw + a + math.pi
    return (float(world[0]), float(world[1]), float(math.remainder(yaw, 2.0 * math.pi)))


def _candidate(rng: np.random.Generator, layout: _Layout, family: str,
               fp: tuple[float, float]) -> tuple[tuple[float, float, float] | None, PlacedFurniture | None]:
    """A random pose for a piece of ``family`` (and the table it belongs to, if any)."""
    cfg, bounds = layout.cfg, layout.bounds
    sides = ("west", "east", "south", "north")
    if family in WALL_FAMILIES:
        return _wall_pose(rng, bounds, fp, sides[int(rng.integers(0, 4))], cfg.wall_gap), None
    if family in TABLE_SEATS:
        tables = [f for f in layout.placed if f.family == "table"]
        if tables and rng.uniform() < 0.9:
            table = tables[int(rng.integers(0, len(tables)))]
            return _table_pose(rng, table, fp, cfg.table_gap), table
    if family == "lamp":
        return _wall_pose(rng, bounds, fp, sides[int(rng.integers(0, 4))], cfg.wall_gap,
                          corner=bool(rng.uniform() < 0.6)), None
    if family == "table":
        if rng.uniform() < 0.3:
            return _wall_pose(rng, bounds, fp, sides[int(rng.integers(0, 4))], cfg.wall_gap), None
        return _free_pose(rng, bounds, fp, 0.5 * math.pi * int(rng.integers(0, 2))), None
    if family == "armchair" and rng.uniform() < 0.5:
        return _wall_pose(rng, bounds, fp, sides[int(rng.integers(0, 4))], cfg.wall_gap), None
    # Armchairs, chairs and stools without a table: facing the room's centre (any yaw fits in the
    # circumscribed circle).
    x0, y0, x1, y1 = bounds
    r = math.hypot(*fp)
    if x1 - x0 < 2 * r or y1 - y0 < 2 * r:
        return None, None
    x, y = float(rng.uniform(x0 + r, x1 - r)), float(rng.uniform(y0 + r, y1 - r))
    yaw = math.atan2(0.5 * (y0 + y1) - y, 0.5 * (x0 + x1) - x) + float(rng.normal(0.0, 0.2))
    return (x, y, yaw), None


def furnish(cfg: RoomConfig, rng: np.random.Generator, bounds: tuple[float, float, float, float],
             doors: list[Door], required: list[str], optional: list[str], prefix: str) -> list[PlacedFurniture] | None:
    """Place ``required`` (all, or None) and as many ``optional`` pieces as fit."""
    layout = _Layout(cfg, bounds, doors)
    items = sorted([(f, True) for f in required] + [(f, False) for f in optional], key=lambda it: PLACEMENT_ORDER.get(it[0], 9))
    counts: dict[str, int] = {}
    for family, is_required in items:
        furniture = make_furniture(family, rng)
        name = f"{prefix}{furniture.family}_{counts.get(furniture.family, 0)}"
        done = False
        for _ in range(cfg.placement_tries):
            pose, table = _candidate(rng, layout, furniture.family, furniture.footprint)
            if pose is None:
                continue
            cand = PlacedFurniture(name, furniture, pose)
            if not layout.fits(cand, table):
                continue
            ok, mask = layout.connected_with(cand)
            if ok:
                layout.add(cand, mask)
                counts[furniture.family] = counts.get(furniture.family, 0) + 1
                done = True
                break
        if not done and is_required:
            return None
    return layout.placed
