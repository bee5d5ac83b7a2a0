"""The slalom test scene (PlaMo Sec. 5.3, Fig. 8): ``slalom_scene(...)``."""

from __future__ import annotations

import math

import numpy as np

from stairenv.validation import check_number
from stairenv.world.scenes.model import LANDMARK_MARKER_HEIGHT, Landmark, Scene
from stairenv.world.scenes.shapes import Box, check_integer


def slalom_scene(*, num_walls: int = 5, wall_spacing: float = 3.0, corridor_width: float = 4.0,
                 gap_width: float = 1.2, wall_thickness: float = 0.2, wall_height: float = 1.5,
                 run_up: float = 3.0, landmark_radius: float = 0.5, cell_size: float = 0.05,
                 side_walls: bool = True) -> Scene:
    """The slalom test (PlaMo Sec. 5.3, Fig. 8, 11): sharp turns around wall corners on flat ground.

    A corridor along +x, ``corridor_width`` wide and centred on y = 0 and on x = 0. Walls
    across it every ``wall_spacing`` metres start alternately from the left (+y) and the
    right (-y) side and leave a ``gap_width`` opening at the other side, so the path
    weaves between their corners. Landmark ``"start"`` lies ``run_up`` / 2 before the
    first wall's line, ``"goal"`` the same after the last. ``side_walls`` closes the
    corridor's long sides (each ``wall_thickness`` thick, outside the corridor).
    """
    num_walls = check_integer("num_walls", num_walls, 1, 100)
    wall_spacing = check_number("wall_spacing", wall_spacing, 0.5, 50.0)
    corridor_width = check_number("corridor_width", corridor_width, 1.0, 50.0)
    gap_width = check_number("gap_width", gap_width, 0.1, corridor_width - 0.1)
    wall_thickness = check_number("wall_thickness", wall_thickness, 0.01, min(5.0, 0.5 * wall_spacing))
    wall_height = check_number("wall_height", wall_height, 0.05, 10.0)
    landmark_radius = check_number("landmark_radius", landmark_radius, 0.05, 5.0)
    # The start and goal discs fit between the corridor's end and the first / last wall.
    run_up = check_number("run_up", run_up, 2.0 * landmark_radius + wall_thickness, 100.0)
    if 2.0 * landmark_radius > corridor_width:
        raise ValueError(f"landmark_radius must be at most corridor_width / 2 ({corridor_width / 2}), "
                         f"got {landmark_radius}")
    cell_size = check_number("cell_size", cell_size, 0.01, 0.5)

    course = 2.0 * run_up + (num_walls - 1) * wall_spacing
    margin = wall_thickness + cell_size
    cols = math.ceil((course + 2.0 * margin) / cell_size)
    rows = math.ceil((corridor_width + 2.0 * margin) / cell_size)
    origin = (-0.5 * cols * cell_size, -0.5 * rows * cell_size)
    half_width = 0.5 * corridor_width

    walls: list[Box] = []
    blade = corridor_width - gap_width
    for k in range(num_walls):
        x = -0.5 * course + run_up + k * wall_spacing
        side = 1.0 if k % 2 == 0 else -1.0  # first wall from the left (+y)
        y = side * (half_width - 0.5 * blade)
        walls.append(Box((x, y), (0.5 * wall_thickness, 0.5 * blade), 0.0, -0.1, wall_height))
    if side_walls:
        for side in (-1.0, 1.0):
            walls.append(Box((0.0, side * (half_width + 0.5 * wall_thickness)),
                             (0.5 * course, 0.5 * wall_thickness), 0.0, -0.1, wall_height))
    landmarks = [
        Landmark(name, (x, 0.0), landmark_radius, (x, 0.0, LANDMARK_MARKER_HEIGHT))
        for name, x in (("start", -0.5 * course + 0.5 * run_up), ("goal", 0.5 * course - 0.5 * run_up))
    ]
    return Scene(np.zeros((rows, cols)), cell_size, origin, walls=walls, landmarks=landmarks,
                 terrain_labels=np.zeros((rows, cols), dtype=np.uint8))
