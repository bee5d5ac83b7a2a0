"""Furnished rooms and houses (SIMS): walls, doors, furniture placed without overlap.

SIMS retrieves room layouts (3D-FRONT bedrooms, living rooms, dining rooms, studies) as
graphs: furniture nodes, edges between items that are close and not obstructed, matched
by graph edit distance; if nothing fits, a room that fits is built. Here rooms are
generated: ``generate_room(config, rng, categories=None)`` furnishes one room (a random
template of its room type, or exactly the requested categories),
``generate_house(config, rng, num_rooms)`` joins rooms through doors, and
``add_room_to_spec(spec, room_or_house)`` writes walls and furniture into an ``MjSpec``.

Frames and units
----------------
World frame: z up, metres, radians. A room's ``bounds`` (x0, y0, x1, y1) is its interior
(the walkable floor between the inner faces of the walls). Walls are ``scenes.Box``\\ es of
``wall_thickness`` centred on the rectangle grown by half a thickness, ``wall_height``
tall, with gaps for doors. Furniture poses are (x, y, yaw) of the furniture frame (front
+x; see ``stairenv.world.furniture``).

Placement rules
---------------
- Footprints (oriented rectangles) stay inside the interior and apart by ``clearance``
  (a chair or stool pulled up to its table only needs to not overlap it); none may cover
  the area inside a door (``door_clearance`` deep).
- Beds, wardrobes, bookshelves, sofas and cabinets stand with their back to a wall
  (front into the room); lamps in corners or along walls; chairs and stools at a table
  facing it when the room has one; armchairs face the room's centre or stand at a wall.
- Free floor stays connected: on a grid of ``cell_size`` a character of ``body_radius``
  can walk from the (first) door to every other door and to within ``reach_distance`` of
  every piece (of its front for sofas, armchairs and cases); a candidate pose that breaks
  this is rejected.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import mujoco
import networkx as nx
import numpy as np
from scipy import ndimage

from stairenv.validation import check_choice, check_number, check_range
from stairenv.world.furniture import (
    FAMILIES,
    FurnitureHandle,
    PlacedFurniture,
    add_furniture_to_spec,
    make_furniture,
)
from stairenv.world.scenes import Box


@dataclass(frozen=True)
class RoomTemplate:
    """What a room type holds: one choice from each ``required`` tuple, then a few ``optional``."""

    required: tuple[tuple[str, ...], ...]
    optional: tuple[str, ...]


ROOM_TYPES: Mapping[str, RoomTemplate] = MappingProxyType({
    "bedroom": RoomTemplate((("bed", "double_bed"),),
                            ("wardrobe", "cabinet", "cabinet", "chair", "table", "lamp", "armchair", "bookshelf")),
    "living_room": RoomTemplate((("sofa",),),
                                ("table", "armchair", "armchair", "lamp", "bookshelf", "cabinet", "stool", "chair")),
    "dining_room": RoomTemplate((("table",), ("chair",), ("chair",)),
                                ("chair", "chair", "cabinet", "lamp", "stool", "bookshelf")),
    "study": RoomTemplate((("table",), ("chair",), ("bookshelf",)),
                          ("bookshelf", "armchair", "lamp", "cabinet", "sofa", "stool")),
})

# Families placed with their back to a wall, and those whose front must be reachable.
WALL_FAMILIES: frozenset[str] = frozenset({"bed", "double_bed", "wardrobe", "bookshelf", "sofa", "cabinet"})
FRONT_ACCESS_FAMILIES: frozenset[str] = frozenset({"armchair", "sofa", "cabinet", "wardrobe", "bookshelf"})
# Families with minimal interaction (SIMS marks them as less important graph nodes).
MINOR_FAMILIES: frozenset[str] = frozenset({"lamp"})
_ORDER = {"bed": 0, "double_bed": 0, "wardrobe": 1, "sofa": 1, "bookshelf": 2, "cabinet": 3, "table": 4,
          "armchair": 5, "chair": 6, "stool": 7, "lamp": 8}
_TABLE_SEATS = frozenset({"chair", "stool"})

WALL_RGBA = (0.85, 0.83, 0.78, 1.0)
FLOOR_RGBA: Mapping[str, tuple[float, float, float, float]] = MappingProxyType({
    "bedroom": (0.72, 0.62, 0.50, 1.0), "living_room": (0.62, 0.55, 0.47, 1.0),
    "dining_room": (0.68, 0.66, 0.60, 1.0), "study": (0.58, 0.50, 0.42, 1.0),
})
DEFAULT_FLOOR_RGBA = (0.65, 0.62, 0.58, 1.0)


# --- config --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class RoomConfig:
    """Ranges from which rooms (and the rooms of houses) are drawn. Metres.

    | field | default | valid |
    |---|---|---|
    | size_x | (3.5, 6.0) | within [1.5, 30]: interior extent along x |
    | size_y | (3.5, 6.0) | within [1.5, 30]: interior extent along y |
    | wall_height | 2.5 | [0.3, 10] |
    | wall_thickness | 0.12 | [0.02, 1.0] |
    | door_width | (0.8, 1.0) | within [0.4, 3.0] |
    | door_clearance | 0.9 | [0, 3]: depth of the furniture-free area inside a door |
    | clearance | 0.1 | [0, 2]: minimal gap between two footprints |
    | table_gap | (0.03, 0.15) | within [0, 1]: gap between a chair / stool and its table |
    | wall_gap | 0.02 | [0, 0.5]: between a wall-backed piece and its wall |
    | body_radius | 0.25 | [0.05, 1.0]: the walking character's radius (connectivity) |
    | reach_distance | 0.6 | (body_radius, 3]: a piece is reachable from a standing point this close |
    | cell_size | 0.05 | [0.01, 0.25]: the connectivity grid |
    | room_types | all of ``ROOM_TYPES`` | non-empty subset: templates to draw from |
    | num_optional | (1, 4) | integers within [0, 20]: optional pieces from the template |
    | max_attempts | 40 | [1, 10000]: rooms (or houses) tried before giving up |
    | placement_tries | 60 | [1, 100000]: candidate poses per piece |
    """

    size_x: tuple[float, float] = (3.5, 6.0)
    size_y: tuple[float, float] = (3.5, 6.0)
    wall_height: float = 2.5
    wall_thickness: float = 0.12
    door_width: tuple[float, float] = (0.8, 1.0)
    door_clearance: float = 0.9
    clearance: float = 0.1
    table_gap: tuple[float, float] = (0.03, 0.15)
    wall_gap: float = 0.02
    body_radius: float = 0.25
    reach_distance: float = 0.6
    cell_size: float = 0.05
    room_types: tuple[str, ...] = tuple(ROOM_TYPES)
    num_optional: tuple[int, int] = (1, 4)
    max_attempts: int = 40
    placement_tries: int = 60

    def __post_init__(self) -> None:
        for name in ("size_x", "size_y", "door_width", "table_gap", "num_optional", "room_types"):
            object.__setattr__(self, name, tuple(getattr(self, name)))
        check_range("size_x", self.size_x, 1.5, 30.0)
        check_range("size_y", self.size_y, 1.5, 30.0)
        check_number("wall_height", self.wall_height, 0.3, 10.0)
        check_number("wall_thickness", self.wall_thickness, 0.02, 1.0)
        check_range("door_width", self.door_width, 0.4, 3.0)
        check_number("door_clearance", self.door_clearance, 0.0, 3.0)
        check_number("clearance", self.clearance, 0.0, 2.0)
        check_range("table_gap", self.table_gap, 0.0, 1.0)
        check_number("wall_gap", self.wall_gap, 0.0, 0.5)
        check_number("body_radius", self.body_radius, 0.05, 1.0)
        check_number("reach_distance", self.reach_distance, self.body_radius, 3.0, low_open=True)
        check_number("cell_size", self.cell_size, 0.01, 0.25)
        if not self.room_types:
            raise ValueError(f"room_types must be a non-empty subset of {list(ROOM_TYPES)}, got ()")
        for t in self.room_types:
            check_choice("room_types", t, tuple(ROOM_TYPES))
        lo, hi = check_range("num_optional", self.num_optional, 0, 20)
        if int(lo) != lo or int(hi) != hi:
            raise ValueError(f"num_optional must be a (min, max) pair of integers within [0, 20], got {self.num_optional!r}")
        object.__setattr__(self, "num_optional", (int(lo), int(hi)))
        for name, high in (("max_attempts", 10000), ("placement_tries", 100000)):
            value = getattr(self, name)
            if not isinstance(value, (int, np.integer)) or not 1 <= value <= high:
                raise ValueError(f"{name} must be an integer in [1, {high}], got {value!r}")


# --- doors, free space ---------------------------------------------------------------------------
@dataclass(frozen=True)
class Door:
    """An opening in a wall: ``center`` (x, y) on the wall's centre line, ``width`` (m).

    ``axis`` is the direction one walks through it: 0 along x (a wall running along y),
    1 along y. ``rooms`` names the rooms it joins ("outside" for an entrance).
    """

    center: tuple[float, float]
    width: float
    axis: int
    rooms: tuple[str, ...]

    def normal(self) -> np.ndarray:
        return np.array([1.0, 0.0]) if self.axis == 0 else np.array([0.0, 1.0])

    def inward(self, bounds: Sequence[float]) -> np.ndarray:
        """Unit (x, y) direction from the door into the room with interior ``bounds``."""
        x0, y0, x1, y1 = bounds
        n = self.normal()
        mid = np.array([0.5 * (x0 + x1), 0.5 * (y0 + y1)])
        return n if (mid - np.asarray(self.center)) @ n > 0 else -n

    def approach_point(self, bounds: Sequence[float], depth: float) -> np.ndarray:
        """The point ``depth`` (m) inside the room with ``bounds`` in front of the door's centre."""
        return np.asarray(self.center) + depth * self.inward(bounds)

    def gap_box(self, wall_thickness: float, height: float = 2.0) -> Box:
        """The opening in the wall as a box (for rasterising passable cells)."""
        half = (0.5 * wall_thickness, 0.5 * self.width) if self.axis == 0 else (0.5 * self.width, 0.5 * wall_thickness)
        return Box(self.center, half, 0.0, 0.0, height)


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


def _label_free(blocked: np.ndarray, c: float, body_radius: float) -> np.ndarray:
    """4-connected component labels of the cells whose centre is more than ``body_radius`` from blocked cells."""
    padded = np.pad(blocked, 1, constant_values=True)
    dist = ndimage.distance_transform_edt(~padded)[1:-1, 1:-1] * c
    free = dist - 0.5 * c >= body_radius
    labels, _ = ndimage.label(free)
    return labels


def _reach_points(placed: PlacedFurniture, body_radius: float, reach: float, c: float) -> np.ndarray:
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


# --- room and house ------------------------------------------------------------------------------
def _segment_hits_box(p: np.ndarray, q: np.ndarray, box: Box) -> bool:
    """Whether the segment p-q (world xy) crosses the footprint of ``box`` (Liang-Barsky)."""
    u, v = box.axes
    a = np.array([(p - box.center) @ u, (p - box.center) @ v])
    d = np.array([(q - p) @ u, (q - p) @ v])
    t0, t1 = 0.0, 1.0
    for k in range(2):
        h = box.half_size[k]
        if abs(d[k]) < 1e-12:
            if abs(a[k]) > h:
                return False
            continue
        ta, tb = (-h - a[k]) / d[k], (h - a[k]) / d[k]
        if ta > tb:
            ta, tb = tb, ta
        t0, t1 = max(t0, ta), min(t1, tb)
        if t0 > t1:
            return False
    return True


def _point_segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    ab = b - a
    t = np.clip((p - a) @ ab / max(ab @ ab, 1e-18), 0.0, 1.0)
    return float(np.linalg.norm(p - (a + t * ab)))


def footprint_distance(a: Box, b: Box) -> float:
    """Gap (m) between two footprints (0 if they overlap)."""
    if a.footprint_overlaps(b):
        return 0.0
    ca, cb = a.corners_xy(), b.corners_xy()
    best = math.inf
    for corners, other in ((ca, cb), (cb, ca)):
        for p in corners:
            for k in range(4):
                best = min(best, _point_segment_distance(p, other[k], other[(k + 1) % 4]))
    return best


def _layout_graph(items: Sequence[PlacedFurniture], walls: Sequence[Box], room_of: Mapping[str, str],
                  threshold: float, obstruction_height: float | None) -> nx.Graph:
    graph = nx.Graph()
    boxes = {f.name: f.footprint_box() for f in items}
    for f in items:
        graph.add_node(f.name, category=f.category, family=f.family, position=(float(f.pose[0]), float(f.pose[1])),
                       yaw=float(f.pose[2]), footprint=tuple(f.furniture.footprint), height=float(f.furniture.height),
                       room=room_of.get(f.name, ""), important=f.family not in MINOR_FAMILIES)
    for i, a in enumerate(items):
        for b in items[i + 1:]:
            gap = footprint_distance(boxes[a.name], boxes[b.name])
            if gap > threshold:
                continue
            p, q = a.position, b.position
            if any(_segment_hits_box(p, q, w) for w in walls):
                continue
            if obstruction_height is not None and any(
                    _segment_hits_box(p, q, boxes[o.name]) for o in items
                    if o.name not in (a.name, b.name) and o.furniture.height > obstruction_height):
                continue
            graph.add_edge(a.name, b.name, distance=gap)
    return graph


@dataclass(frozen=True, eq=False)
class Room:
    """A furnished room in the world frame (metres).

    | field | meaning |
    |---|---|
    | name | the room's name (houses: ``{room_type}{k}``) |
    | room_type | a key of ``ROOM_TYPES`` or "custom" |
    | bounds | (x0, y0, x1, y1): the interior, between the walls' inner faces |
    | walls | ``Box``\\ es around it, with gaps at the doors |
    | doors | ``Door``\\ s in its walls |
    | furniture | ``PlacedFurniture`` instances (unique names such as ``chair_0``) |
    | wall_height, wall_thickness | of its walls |
    | body_radius, reach_distance, cell_size | the connectivity rule it was built with |
    """

    name: str
    room_type: str
    bounds: tuple[float, float, float, float]
    walls: tuple[Box, ...]
    doors: tuple[Door, ...]
    furniture: tuple[PlacedFurniture, ...]
    wall_height: float = 2.5
    wall_thickness: float = 0.12
    body_radius: float = 0.25
    reach_distance: float = 0.6
    cell_size: float = 0.05

    @property
    def size(self) -> tuple[float, float]:
        x0, y0, x1, y1 = self.bounds
        return (x1 - x0, y1 - y0)

    @property
    def center(self) -> np.ndarray:
        x0, y0, x1, y1 = self.bounds
        return np.array([0.5 * (x0 + x1), 0.5 * (y0 + y1)])

    @property
    def rooms(self) -> tuple[Room, ...]:
        return (self,)

    @property
    def categories(self) -> list[str]:
        return [f.category for f in self.furniture]

    def instance(self, name: str) -> PlacedFurniture:
        for f in self.furniture:
            if f.name == name:
                return f
        raise KeyError(f"{self.name} has no furniture named {name!r}; names: {[f.name for f in self.furniture]}")

    def of_category(self, category: str) -> list[PlacedFurniture]:
        return [f for f in self.furniture if f.category == category]

    def contains_xy(self, points: np.ndarray) -> np.ndarray:
        """Whether world points (..., 2|3) lie in the interior."""
        p = np.asarray(points, dtype=float)
        x0, y0, x1, y1 = self.bounds
        return (p[..., 0] >= x0) & (p[..., 0] <= x1) & (p[..., 1] >= y0) & (p[..., 1] <= y1)

    def obstacle_boxes(self) -> list[Box]:
        """Walls and furniture footprints (z from 0 to their tops): what a walking character avoids."""
        return list(self.walls) + [f.footprint_box() for f in self.furniture]

    def free_space(self, *, cell_size: float | None = None, body_radius: float | None = None) -> FreeSpace:
        """Free floor of the room(s) (door gaps passable, outside blocked) with its components."""
        return _free_space(self.rooms, self.walls, self.doors, self.furniture,
                           cell_size or self.cell_size, self.body_radius if body_radius is None else body_radius)

    def is_connected(self) -> bool:
        """Whether every door and every piece is reachable from the first door (see the module doc)."""
        return _check_reachable(self.free_space(), self.rooms, self.doors, self.furniture,
                                self.body_radius, self.reach_distance, self.cell_size)

    def layout_graph(self, *, threshold: float = 1.0, obstruction_height: float | None = None) -> nx.Graph:
        """SIMS' layout graph: a node per furniture instance, an edge between items whose
        footprints are within ``threshold`` (m) and whose centres see each other (no wall
        crossed; with ``obstruction_height``, no piece taller than that (m) either).

        Node attributes: ``category`` (family name), ``family``, ``position`` (x, y),
        ``yaw``, ``footprint`` (half extents), ``height``, ``room``, ``important`` (False for
        lamps). Edge attribute: ``distance`` (the footprint gap, m).
        """
        room_of = {f.name: r.name for r in self.rooms for f in r.furniture}
        return _layout_graph(list(self.furniture), list(self.walls), room_of, threshold, obstruction_height)


@dataclass(frozen=True, eq=False)
class House(Room):
    """Rooms joined by doors. ``walls``/``doors``/``furniture`` are the unions (shared walls
    once); ``bounds`` covers all interiors; ``rooms`` holds the rooms themselves."""

    room_list: tuple[Room, ...] = ()

    @property
    def rooms(self) -> tuple[Room, ...]:
        return self.room_list

    def room(self, name: str) -> Room:
        for r in self.room_list:
            if r.name == name:
                return r
        raise KeyError(f"no room {name!r}; rooms: {[r.name for r in self.room_list]}")


def _free_space(rooms: Sequence[Room], walls: Sequence[Box], doors: Sequence[Door],
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
    return FreeSpace(_label_free(blocked, c, body_radius), origin, c)


def _check_reachable(space: FreeSpace, rooms: Sequence[Room], doors: Sequence[Door],
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
    return all(np.any(space.label_at(_reach_points(f, body_radius, reach, c)) == start) for f in furniture)


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
        pts = _reach_points(f, self.radius, self.reach, self.cfg.cell_size)
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
        labels = _label_free(self.occupied | mask, self.cfg.cell_size, self.radius)
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
    if family in _TABLE_SEATS:
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


def _furnish(cfg: RoomConfig, rng: np.random.Generator, bounds: tuple[float, float, float, float],
             doors: list[Door], required: list[str], optional: list[str], prefix: str) -> list[PlacedFurniture] | None:
    """Place ``required`` (all, or None) and as many ``optional`` pieces as fit."""
    layout = _Layout(cfg, bounds, doors)
    items = sorted([(f, True) for f in required] + [(f, False) for f in optional], key=lambda it: _ORDER.get(it[0], 9))
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


def _walls_of_cell(cell: Sequence[float], doors: Sequence[Door], t: float, height: float) -> list[Box]:
    """Wall boxes on the 4 edges of ``cell`` (wall centre lines), with door gaps, corners closed."""
    cx0, cy0, cx1, cy1 = cell
    boxes = []
    edges = (((cx0, cy0), (cx1, cy0), 1), ((cx0, cy1), (cx1, cy1), 1), ((cx0, cy0), (cx0, cy1), 0), ((cx1, cy0), (cx1, cy1), 0))
    for (ax, ay), (bx, by), axis in edges:
        along = 0 if axis == 1 else 1  # coordinate that varies along the wall
        line = ay if axis == 1 else ax
        start, end = ((ax, bx) if along == 0 else (ay, by))
        cuts = sorted((d.center[along] - 0.5 * d.width, d.center[along] + 0.5 * d.width) for d in doors
                      if d.axis == (1 - along) and abs(d.center[1 - along] - line) < 1e-6
                      and start < d.center[along] < end)
        pieces, cursor = [], start - 0.5 * t
        for lo, hi in cuts:
            pieces.append((cursor, lo))
            cursor = hi
        pieces.append((cursor, end + 0.5 * t))
        for lo, hi in pieces:
            if hi - lo < 1e-6:
                continue
            mid = 0.5 * (lo + hi)
            if along == 0:
                boxes.append(Box((mid, line), (0.5 * (hi - lo), 0.5 * t), 0.0, 0.0, height))
            else:
                boxes.append(Box((line, mid), (0.5 * t, 0.5 * (hi - lo)), 0.0, 0.0, height))
    return boxes


def _template(cfg: RoomConfig, rng: np.random.Generator, room_type: str) -> tuple[list[str], list[str]]:
    template = ROOM_TYPES[room_type]
    required = [opts[int(rng.integers(0, len(opts)))] for opts in template.required]
    n = int(rng.integers(cfg.num_optional[0], cfg.num_optional[1] + 1))
    n = min(n, len(template.optional))
    picks = rng.choice(len(template.optional), size=n, replace=False) if n else []
    return required, [template.optional[int(k)] for k in picks]


def _check_categories(categories: Iterable[str]) -> list[str]:
    cats = list(categories)
    for c in cats:
        check_choice("categories", c, FAMILIES)
    return cats


def _room_door(cfg: RoomConfig, rng: np.random.Generator, cell: Sequence[float], width: float,
               side: str, rooms: tuple[str, ...]) -> Door | None:
    cx0, cy0, cx1, cy1 = cell
    t = cfg.wall_thickness
    along_lo, along_hi = ((cy0, cy1) if side in ("west", "east") else (cx0, cx1))
    lo, hi = along_lo + t + 0.5 * width + 0.1, along_hi - t - 0.5 * width - 0.1
    if hi < lo:
        return None
    s = float(rng.uniform(lo, hi))
    if side == "west":
        return Door((cx0, s), width, 0, rooms)
    if side == "east":
        return Door((cx1, s), width, 0, rooms)
    if side == "south":
        return Door((s, cy0), width, 1, rooms)
    return Door((s, cy1), width, 1, rooms)


def generate_room(config: RoomConfig, rng: np.random.Generator, categories: Sequence[str] | None = None, *,
                  room_type: str | None = None, name: str = "room",
                  center: Sequence[float] = (0.0, 0.0)) -> Room:
    """A furnished room with one door (to "outside"), interior centred at ``center`` (x, y).

    Without ``categories``: a ``room_type`` (default: drawn from ``config.room_types``)
    gives the required pieces and up to ``config.num_optional`` optional ones (dropped if
    they do not fit). With ``categories`` (family names, repeats allowed): exactly those,
    every one placed (``room_type`` defaults to "custom"); if they do not fit in rooms drawn
    from the config, the largest configured room is tried, then ``RuntimeError``.
    Pure: the same rng state gives the same room. Instance names: ``{family}_{k}``.
    """
    if categories is not None:
        cats = _check_categories(categories)
        room_type = "custom" if room_type is None else room_type
    if room_type is not None and room_type != "custom":
        check_choice("room_type", room_type, tuple(ROOM_TYPES))
    cx, cy = (float(v) for v in center)
    t = cfg_t = config.wall_thickness
    for attempt in range(config.max_attempts):
        big = categories is not None and attempt >= config.max_attempts // 2
        sx = config.size_x[1] if big else float(rng.uniform(*config.size_x))
        sy = config.size_y[1] if big else float(rng.uniform(*config.size_y))
        bounds = (cx - sx / 2, cy - sy / 2, cx + sx / 2, cy + sy / 2)
        cell = (bounds[0] - t / 2, bounds[1] - t / 2, bounds[2] + t / 2, bounds[3] + t / 2)
        rtype = room_type if room_type is not None else config.room_types[int(rng.integers(0, len(config.room_types)))]
        if categories is not None:
            required, optional = cats, []
        else:
            required, optional = _template(config, rng, rtype)
        side = ("west", "east", "south", "north")[int(rng.integers(0, 4))]
        door = _room_door(config, rng, cell, float(rng.uniform(*config.door_width)), side, (name, "outside"))
        if door is None:
            continue
        placed = _furnish(config, rng, bounds, [door], required, optional, "")
        if placed is None:
            continue
        walls = tuple(_walls_of_cell(cell, [door], cfg_t, config.wall_height))
        return Room(name, rtype, bounds, walls, (door,), tuple(placed), config.wall_height, cfg_t,
                    config.body_radius, config.reach_distance, config.cell_size)
    raise RuntimeError(f"generate_room: could not place {categories if categories is not None else 'the template'} "
                       f"in {config.max_attempts} rooms of size_x {config.size_x}, size_y {config.size_y}; "
                       f"allow larger rooms, fewer pieces or a smaller clearance / body_radius")


def generate_house(config: RoomConfig, rng: np.random.Generator, num_rooms: int = 3, *,
                   room_types: Sequence[str] | None = None, categories: Sequence[Sequence[str]] | None = None,
                   extra_door_probability: float = 0.25, entrance: bool = True) -> House:
    """``num_rooms`` furnished rooms on a grid, joined through doors in their shared walls.

    Rooms fill a grid of ceil(sqrt(n)) columns row by row; each column has a width drawn
    from ``config.size_x``, each row a depth from ``size_y``, so neighbours share whole
    walls (one wall, ``wall_thickness`` thick, on the shared line). A random spanning tree
    of the neighbours gets one door per edge, other neighbour pairs one with
    ``extra_door_probability``; ``entrance`` adds a door to "outside" on an outer wall.
    ``room_types`` (one per room) and ``categories`` (one list per room, as in
    ``generate_room``) fix the rooms' contents. Rooms are named ``{room_type}{k}``;
    instance names ``{room name}_{family}_{j}``. Pure given ``rng``.
    """
    if not isinstance(num_rooms, (int, np.integer)) or not 1 <= num_rooms <= 64:
        raise ValueError(f"num_rooms must be an integer in [1, 64], got {num_rooms!r}")
    check_number("extra_door_probability", extra_door_probability, 0.0, 1.0)
    if room_types is not None:
        if len(room_types) != num_rooms:
            raise ValueError(f"room_types must name {num_rooms} rooms, got {len(room_types)}")
        for r in room_types:
            if r != "custom":
                check_choice("room_types", r, tuple(ROOM_TYPES))
    if categories is not None:
        if len(categories) != num_rooms:
            raise ValueError(f"categories must hold {num_rooms} lists, got {len(categories)}")
        categories = [_check_categories(c) for c in categories]
    cols = math.ceil(math.sqrt(num_rooms))
    rows = math.ceil(num_rooms / cols)
    t = config.wall_thickness
    cells_ij = [(k // cols, k % cols) for k in range(num_rooms)]
    for attempt in range(config.max_attempts):
        big = categories is not None and attempt >= config.max_attempts // 2
        widths = [config.size_x[1] if big else float(rng.uniform(*config.size_x)) for _ in range(cols)]
        depths = [config.size_y[1] if big else float(rng.uniform(*config.size_y)) for _ in range(rows)]
        xs = np.concatenate(([0.0], np.cumsum(np.array(widths) + t)))
        ys = np.concatenate(([0.0], np.cumsum(np.array(depths) + t)))
        xs -= 0.5 * xs[-1]
        ys -= 0.5 * ys[-1]
        cells = [(xs[j], ys[i], xs[j + 1], ys[i + 1]) for i, j in cells_ij]
        if room_types is not None:
            types = list(room_types)
        elif categories is not None:
            types = ["custom"] * num_rooms
        else:
            pool = list(config.room_types)
            order = [pool[int(k)] for k in rng.permutation(len(pool))]
            types = [order[k % len(order)] for k in range(num_rooms)]
        names = []
        seen: dict[str, int] = {}
        for rt in types:
            names.append(f"{rt}{seen.get(rt, 0)}")
            seen[rt] = seen.get(rt, 0) + 1
        index = {ij: k for k, ij in enumerate(cells_ij)}
        pairs = []
        for k, (i, j) in enumerate(cells_ij):
            for di, dj in ((0, 1), (1, 0)):
                other = index.get((i + di, j + dj))
                if other is not None:
                    pairs.append((k, other, "east" if dj else "north"))
        # A random spanning tree (Kruskal on shuffled edges), then extra doors.
        parent = list(range(num_rooms))
        doors: list[Door] = []
        ok = True
        for e in rng.permutation(len(pairs)):
            a, b, side = pairs[int(e)]
            ra, rb = _find(parent, a), _find(parent, b)
            tree = ra != rb
            if tree:
                parent[ra] = rb
            if tree or rng.uniform() < extra_door_probability:
                width = float(rng.uniform(*config.door_width))
                door = _room_door(config, rng, cells[a], width, side, (names[a], names[b]))
                if door is None:
                    ok = False
                    break
                doors.append(door)
        if not ok:
            continue
        if entrance:
            outer = [(k, s) for k, (i, j) in enumerate(cells_ij) for s, nb in
                     (("west", (i, j - 1)), ("east", (i, j + 1)), ("south", (i - 1, j)), ("north", (i + 1, j)))
                     if nb not in index]
            k, s = outer[int(rng.integers(0, len(outer)))]
            door = _room_door(config, rng, cells[k], float(rng.uniform(*config.door_width)), s, (names[k], "outside"))
            if door is not None:
                doors.append(door)
        rooms = []
        for k in range(num_rooms):
            cell = cells[k]
            bounds = (cell[0] + t / 2, cell[1] + t / 2, cell[2] - t / 2, cell[3] - t / 2)
            room_doors = [d for d in doors if names[k] in d.rooms]
            placed = None
            for _ in range(5):
                if categories is not None:
                    required, optional = list(categories[k]), []
                elif types[k] == "custom":
                    required, optional = [], []
                else:
                    required, optional = _template(config, rng, types[k])
                placed = _furnish(config, rng, bounds, room_doors, required, optional, f"{names[k]}_")
                if placed is not None:
                    break
            if placed is None:
                break
            walls = tuple(_walls_of_cell(cell, room_doors, t, config.wall_height))
            rooms.append(Room(names[k], types[k], bounds, walls, tuple(room_doors), tuple(placed),
                              config.wall_height, t, config.body_radius, config.reach_distance, config.cell_size))
        if len(rooms) < num_rooms:
            continue
        all_walls = _unique_walls([w for r in rooms for w in r.walls])
        lo = np.min([r.bounds[:2] for r in rooms], axis=0)
        hi = np.max([r.bounds[2:] for r in rooms], axis=0)
        house = House("house", "house", (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])), tuple(all_walls),
                      tuple(doors), tuple(f for r in rooms for f in r.furniture), config.wall_height, t,
                      config.body_radius, config.reach_distance, config.cell_size, tuple(rooms))
        if house.is_connected():
            return house
    raise RuntimeError(f"generate_house: no house of {num_rooms} rooms after {config.max_attempts} attempts; "
                       f"allow larger rooms or fewer pieces")


def _find(parent: list[int], a: int) -> int:
    """Union-find root of ``a`` (with path halving)."""
    while parent[a] != a:
        parent[a] = parent[parent[a]]
        a = parent[a]
    return a


def _unique_walls(walls: Iterable[Box]) -> list[Box]:
    out: list[Box] = []
    keys = set()
    for w in walls:
        key = tuple(round(v, 6) for v in (*w.center, *w.half_size, w.yaw, w.bottom, w.top))
        if key not in keys:
            keys.add(key)
            out.append(w)
    return out


# --- MuJoCo --------------------------------------------------------------------------------------
@dataclass(eq=False)
class RoomHandles:
    """What ``add_room_to_spec`` added: wall and floor geom names, one ``FurnitureHandle`` per piece."""

    room: Room
    wall_geom_names: tuple[str, ...]
    floor_geom_names: tuple[str, ...]
    furniture: dict[str, FurnitureHandle]
    wall_geom_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    def bind(self, model: mujoco.MjModel) -> None:
        self.wall_geom_ids = np.array([model.geom(n).id for n in self.wall_geom_names], dtype=np.int64)
        for handle in self.furniture.values():
            handle.bind(model)

    def geom_label(self, model: mujoco.MjModel, geom_id: int) -> tuple[str, str] | None:
        """(instance name, part label) of a furniture geom id, or None."""
        name = model.geom(geom_id).name
        parts = name.rsplit("/", 2)
        if len(parts) == 3 and parts[0] in self.furniture:
            return parts[0], parts[1]
        return None


def add_room_to_spec(spec: mujoco.MjSpec, room: Room, *, prefix: str = "room", floors: bool = True) -> RoomHandles:
    """Add a ``Room`` or ``House`` to ``spec`` (e.g. ``load_humanoid_spec()``, which brings the ground plane).

    Walls: one static body with one box geom each (``{prefix}_wall{k}``). Floors: a
    visual-only (no collision) thin box per room, tinted by room type
    (``{prefix}_floor{k}``), 1 mm above z = 0. Furniture: ``add_furniture_to_spec`` per
    instance (body = instance name, geoms ``{instance}/{label}/{k}``).
    """
    wall_names = []
    for k, wall in enumerate(room.walls):
        name = f"{prefix}_wall{k}"
        body = spec.worldbody.add_body(name=name, pos=wall.center_xyz.tolist(),
                                       quat=[math.cos(0.5 * wall.yaw), 0.0, 0.0, math.sin(0.5 * wall.yaw)])
        body.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_BOX, size=wall.half_extents_xyz.tolist(),
                      rgba=list(WALL_RGBA), condim=3)
        wall_names.append(name)
    floor_names = []
    if floors:
        for k, r in enumerate(room.rooms):
            name = f"{prefix}_floor{k}"
            x0, y0, x1, y1 = r.bounds
            spec.worldbody.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_BOX,
                                    pos=[0.5 * (x0 + x1), 0.5 * (y0 + y1), 0.0005],
                                    size=[0.5 * (x1 - x0), 0.5 * (y1 - y0), 0.0005],
                                    rgba=list(FLOOR_RGBA.get(r.room_type, DEFAULT_FLOOR_RGBA)),
                                    contype=0, conaffinity=0)
            floor_names.append(name)
    handles = {f.name: add_furniture_to_spec(spec, f.furniture, f.pose, f.name) for f in room.furniture}
    return RoomHandles(room, tuple(wall_names), tuple(floor_names), handles)


def room_summary(room: Room) -> dict[str, Any]:
    """A JSON-ready description: type, bounds, doors and the pieces with their poses."""
    return {
        "name": room.name, "room_type": room.room_type, "bounds": list(room.bounds),
        "doors": [{"center": list(d.center), "width": d.width, "axis": d.axis, "rooms": list(d.rooms)} for d in room.doors],
        "furniture": [{"name": f.name, "category": f.category, "pose": list(f.pose)} for f in room.furniture],
        "rooms": [r.name for r in room.rooms],
    }
