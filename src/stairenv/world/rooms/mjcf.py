"""The MuJoCo model of a room or house: ``add_room_to_spec`` and ``RoomHandles``."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import mujoco
import numpy as np

from stairenv.rotations import yaw_to_quat_wxyz
from stairenv.world.furniture import (
    FurnitureHandle,
    add_furniture_to_spec,
)
from stairenv.world.rooms.model import Room

WALL_RGBA = (0.85, 0.83, 0.78, 1.0)
FLOOR_RGBA: Mapping[str, tuple[float, float, float, float]] = MappingProxyType({
    "bedroom": (0.72, 0.62, 0.50, 1.0), "living_room": (0.62, 0.55, 0.47, 1.0),
    "dining_room": (0.68, 0.66, 0.60, 1.0), "study": (0.58, 0.50, 0.42, 1.0),
})
DEFAULT_FLOOR_RGBA = (0.65, 0.62, 0.58, 1.0)

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
                                       quat=yaw_to_quat_wxyz(wall.yaw).tolist())
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
