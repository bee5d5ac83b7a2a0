"""``Room`` and ``House`` (rooms joined by doors), and ``room_summary``."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import networkx as nx
import numpy as np

from stairenv.world.furniture import PlacedFurniture
from stairenv.world.rooms.doors import Door
from stairenv.world.rooms.free_space import FreeSpace, all_reachable, build_free_space
from stairenv.world.rooms.graph import build_layout_graph
from stairenv.world.scenes import Box


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
        return build_free_space(self.rooms, self.walls, self.doors, self.furniture,
                           cell_size or self.cell_size, self.body_radius if body_radius is None else body_radius)

    def is_connected(self) -> bool:
        """Whether every door and every piece is reachable from the first door (see the module doc)."""
        return all_reachable(self.free_space(), self.rooms, self.doors, self.furniture,
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
        return build_layout_graph(list(self.furniture), list(self.walls), room_of, threshold, obstruction_height)


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

def room_summary(room: Room) -> dict[str, Any]:
    """A JSON-ready description: type, bounds, doors and the pieces with their poses."""
    return {
        "name": room.name, "room_type": room.room_type, "bounds": list(room.bounds),
        "doors": [{"center": list(d.center), "width": d.width, "axis": d.axis, "rooms": list(d.rooms)} for d in room.doors],
        "furniture": [{"name": f.name, "category": f.category, "pose": list(f.pose)} for f in room.furniture],
        "rooms": [r.name for r in room.rooms],
    }
