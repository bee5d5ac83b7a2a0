"""The MuJoCo model of a piece: ``add_furniture_to_spec`` and ``FurnitureHandle``."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import mujoco
import numpy as np

from stairenv.rotations import yaw_to_quat_wxyz
from stairenv.world.furniture.colors import part_rgba
from stairenv.world.furniture.model import Furniture
from stairenv.world.furniture.placement import PlacedFurniture, check_pose


@dataclass(eq=False)
class FurnitureHandle:
    """What ``add_furniture_to_spec`` added: the body and the geom names per label.

    ``geom_names[label][k]`` is ``{name}/{label}/{k}``. ``bind(model)`` looks up the ids.
    """

    name: str
    furniture: Furniture
    pose: tuple[float, float, float]
    body_name: str
    geom_names: dict[str, tuple[str, ...]]
    body_id: int = -1
    geom_ids: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def placed(self) -> PlacedFurniture:
        return PlacedFurniture(self.name, self.furniture, self.pose)

    @property
    def all_geom_names(self) -> tuple[str, ...]:
        return tuple(n for names in self.geom_names.values() for n in names)

    def bind(self, model: mujoco.MjModel) -> None:
        self.body_id = model.body(self.body_name).id
        self.geom_ids = {label: np.array([model.geom(n).id for n in names], dtype=np.int64)
                         for label, names in self.geom_names.items()}


def add_furniture_to_spec(spec: mujoco.MjSpec, furniture: Furniture, pose: Sequence[float] = (0.0, 0.0, 0.0),
                          name: str | None = None, *, friction: Sequence[float] = (1.0, 0.005, 0.0001),
                          rgba: Sequence[float] | None = None, group: int = 0) -> FurnitureHandle:
    """Add ``furniture`` at ``pose`` (x, y, yaw; world, m and rad) as one static body ``name``.

    One geom per part, named ``{name}/{label}/{k}``: boxes as box geoms, other parts as
    mesh geoms (a mesh asset of the same name made from the part's vertices; MuJoCo
    collides with its convex hull, which is the part itself). Colours from ``part_rgba``
    unless ``rgba`` is given. ``name`` defaults to the family.
    """
    x, y, yaw = check_pose(pose)
    name = furniture.family if name is None else str(name)
    body = spec.worldbody.add_body(name=name, pos=[x, y, 0.0], quat=yaw_to_quat_wxyz(yaw).tolist())
    names: dict[str, list[str]] = {}
    for part in furniture.part_list:
        k = len(names.setdefault(part.label, []))
        geom_name = f"{name}/{part.label}/{k}"
        color = list(rgba) if rgba is not None else list(part_rgba(furniture.family, part.label, k))
        common = {"name": geom_name, "rgba": color, "friction": list(friction), "condim": 3, "group": group}
        if part.is_box:
            quat = np.zeros(4)
            mujoco.mju_mat2Quat(quat, part.rotation.ravel())
            body.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, pos=part.center.tolist(), quat=quat.tolist(),
                          size=part.half_extents.tolist(), **common)
        else:
            spec.add_mesh(name=geom_name, uservert=part.vertices.ravel().tolist())
            body.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname=geom_name, **common)
        names[part.label].append(geom_name)
    return FurnitureHandle(name, furniture, (x, y, yaw), name, {k: tuple(v) for k, v in names.items()})
