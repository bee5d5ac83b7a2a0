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

What lives where (one module per job)
-------------------------------------
- ``config``: ``RoomConfig``, the room types (``ROOM_TYPES``) and placement groups.
- ``doors``: ``Door``.
- ``model``: ``Room``, ``House``, ``room_summary``.
- ``free_space``: ``FreeSpace`` and the reachability check.
- ``graph``: SIMS' layout graph (``Room.layout_graph``) and ``footprint_distance``.
- ``placement``: candidate poses and the furnishing of one room.
- ``generation``: ``generate_room`` and ``generate_house``.
- ``mjcf``: ``add_room_to_spec`` and ``RoomHandles``.

Everything is importable from ``stairenv.world.rooms`` itself.
"""

from stairenv.world.rooms.config import (
    FRONT_ACCESS_FAMILIES,
    MINOR_FAMILIES,
    ROOM_TYPES,
    WALL_FAMILIES,
    RoomConfig,
    RoomTemplate,
)
from stairenv.world.rooms.doors import Door
from stairenv.world.rooms.free_space import FreeSpace
from stairenv.world.rooms.generation import generate_house, generate_room
from stairenv.world.rooms.graph import footprint_distance
from stairenv.world.rooms.mjcf import DEFAULT_FLOOR_RGBA, FLOOR_RGBA, WALL_RGBA, RoomHandles, add_room_to_spec
from stairenv.world.rooms.model import House, Room, room_summary

__all__ = [
    "DEFAULT_FLOOR_RGBA", "FLOOR_RGBA", "FRONT_ACCESS_FAMILIES", "MINOR_FAMILIES", "ROOM_TYPES", "WALL_FAMILIES",
    "WALL_RGBA", "Door", "FreeSpace", "House", "Room", "RoomConfig", "RoomHandles", "RoomTemplate",
    "add_room_to_spec", "footprint_distance", "generate_house", "generate_room", "room_summary",
]
