"""A piece placed in the world: ``PlacedFurniture`` (pose x, y, yaw)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from stairenv.rotations import yaw_matrix
from stairenv.world.furniture.model import Furniture
from stairenv.world.furniture.parts import ContactSurface
from stairenv.world.scenes import Box


# --- placement and MuJoCo ------------------------------------------------------------------------
def check_pose(pose: Sequence[float]) -> tuple[float, float, float]:
    try:
        x, y, yaw = (float(v) for v in pose)
    except (TypeError, ValueError):
        raise ValueError(f"pose must be (x, y, yaw), got {pose!r}") from None
    if not all(math.isfinite(v) for v in (x, y, yaw)):
        raise ValueError(f"pose must be finite, got {pose!r}")
    return x, y, yaw


@dataclass(frozen=True, eq=False)
class PlacedFurniture:
    """A furniture instance in the world: ``name``, the piece and its pose (x, y, yaw).

    World = ``rotation @ p + (x, y, 0)`` for a point p of the furniture frame.
    """

    name: str
    furniture: Furniture
    pose: tuple[float, float, float]

    def __post_init__(self) -> None:
        object.__setattr__(self, "pose", check_pose(self.pose))

    @property
    def category(self) -> str:
        return self.furniture.category

    @property
    def family(self) -> str:
        return self.furniture.family

    @property
    def position(self) -> np.ndarray:
        """World (x, y) of the footprint centre."""
        return np.array(self.pose[:2])

    @property
    def yaw(self) -> float:
        return self.pose[2]

    @property
    def rotation(self) -> np.ndarray:
        return yaw_matrix(self.pose[2])

    @property
    def translation(self) -> np.ndarray:
        return np.array([self.pose[0], self.pose[1], 0.0])

    def to_world(self, points: np.ndarray) -> np.ndarray:
        """Furniture-frame points (..., 3) -> world."""
        return np.asarray(points, dtype=float) @ self.rotation.T + self.translation

    def to_local(self, points: np.ndarray) -> np.ndarray:
        """World points (..., 3) -> furniture frame."""
        return (np.asarray(points, dtype=float) - self.translation) @ self.rotation

    def footprint_box(self, margin: float = 0.0) -> Box:
        """The footprint as a world ``stairenv.world.scenes.Box`` (z from 0 to the height), grown by ``margin``."""
        hx, hy = self.furniture.footprint
        return Box(self.pose[:2], (hx + margin, hy + margin), self.pose[2], 0.0, max(self.furniture.height, 1e-3))

    def contact_surface(self, label: str, index: int | None = None, side: str = "auto") -> ContactSurface:
        """``Furniture.contact_surface`` in the world frame."""
        return self.furniture.contact_surface(label, index, side).transformed(self.rotation, self.translation)

    def nearest_point(self, label: str, points: np.ndarray, index: int | None = None) -> np.ndarray:
        """Nearest world point on the ``label`` part(s) to world points (..., 3)."""
        return self.to_world(self.furniture.nearest_point(label, self.to_local(points), index))

    def contains(self, points: np.ndarray, label: str | None = None) -> np.ndarray:
        return self.furniture.contains(self.to_local(points), label)
