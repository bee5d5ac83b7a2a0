"""``Door``: an opening in a wall between two rooms (or a room and the outside)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from stairenv.world.scenes import Box


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
