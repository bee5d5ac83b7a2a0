"""Room types (templates of furniture families), placement groups and ``RoomConfig``."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np

from stairenv.validation import check_choice, check_number, check_range


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
PLACEMENT_ORDER = {"bed": 0, "double_bed": 0, "wardrobe": 1, "sofa": 1, "bookshelf": 2, "cabinet": 3, "table": 4,
          "armchair": 5, "chair": 6, "stool": 7, "lamp": 8}
TABLE_SEATS = frozenset({"chair", "stool"})

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
