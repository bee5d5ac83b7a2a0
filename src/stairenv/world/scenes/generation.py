"""PlaMo's random scenes (Sec. 5.4): ``SceneConfig`` and ``generate_scene(config, rng)``."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import ndimage

from stairenv.planning.grid import PlanningGrid
from stairenv.validation import check_number, check_range
from stairenv.world.scenes.model import DEFAULT_LANDMARK_NAMES, LANDMARK_MARKER_HEIGHT, TERRAIN_KINDS, Landmark, Scene
from stairenv.world.scenes.obstacles import DynamicObstacle, WaypointLoop
from stairenv.world.scenes.patches import (
    FlatPatchConfig,
    PatchConfig,
    RoughPatchConfig,
    SlopePatchConfig,
    StairsPatchConfig,
    generate_patch_shape,
)
from stairenv.world.scenes.reachability import connected_free_space
from stairenv.world.scenes.shapes import Box, check_floats, check_int_range, check_integer, yaw_axes
from stairenv.world.tiles import TerrainTiles, stairs_boxes


# --- random scenes -------------------------------------------------------------------------------
@dataclass(frozen=True)
class SceneConfig:
    """Ranges from which ``generate_scene`` draws a scene (uniformly). Metres, seconds.

    The scene is centred on the world origin and tiled with square-ish terrain patches;
    low ceilings (tunnels and bridges) stand on flat patches, walls anywhere else,
    landmarks on flat ground in the largest reachable region, and the balls roll back and
    forth along free straight paths.

    | field | default | valid |
    |---|---|---|
    | size | (16, 16) | each in [2, 200]: extent along x and y |
    | cell_size | 0.05 | [0.01, 0.5]: height-map spacing |
    | patch_size | 4.0 | [0.5, 100]: side of a terrain patch (the scene holds round(size / patch_size) per axis) |
    | terrain_weights | (0.35, 0.25, 0.2, 0.2) | >= 0, sum > 0: odds of flat, slope, rough, stairs patches |
    | min_flat_patches | 3 | [0, 10000]: more patches are turned flat if the draw has fewer |
    | flat, slope, rough, stairs | defaults | the patch configs (``FlatPatchConfig``, ...) |
    | num_walls | (2, 5) | integers within [0, 100] |
    | wall_length | (1.5, 4.0) | within [0.1, 100] |
    | wall_thickness | 0.2 | [0.01, 5]; also a tunnel's side walls |
    | wall_height | (1.0, 2.0) | within [0.05, 10]: above the highest ground under the wall |
    | num_ceilings | (1, 2) | integers within [0, 50]: low-ceiling structures (at most one per flat patch) |
    | tunnel_probability | 0.5 | [0, 1]: a structure is a tunnel (side walls) or else a bridge (4 pillars) |
    | ceiling_clearance | (0.6, 1.2) | within [0.2, 5]: underside above the highest ground under it |
    | ceiling_length | (1.5, 3.0) | within [0.3, 50]: along the passage (shrunk to fit its patch) |
    | ceiling_width | (1.2, 2.5) | within [0.3, 50]: across the passage (shrunk to fit its patch) |
    | ceiling_thickness | 0.2 | [0.01, 2] |
    | landmark_names | DEFAULT_LANDMARK_NAMES | distinct non-empty names, at least num_landmarks |
    | num_landmarks | 4 | [1, 100] |
    | landmark_radius | 0.5 | [0.05, 5] |
    | landmark_separation | 4.0 | [0, 100]: least distance between landmark centres |
    | landmark_wall_clearance | 0.5 | [0, 10]: least gap between a landmark's disc and a wall |
    | landmark_flatness | 0.01 | [0, 1]: largest height range over a landmark's square |
    | num_dynamic_obstacles | 1 | [0, 20]: balls |
    | ball_radius | (0.2, 0.35) | within [0.02, 2] |
    | ball_speed | (1.0, 2.5) | within [0, 20] (m/s) |
    | ball_path_length | (3.0, 8.0) | within [0.5, 100]: one way |
    | max_step_height | 0.25 | [0, 2]: reachability: largest height change between neighbouring cells |
    | min_clearance | 0.5 | [0.1, 3]: reachability: lowest gap a character crawls through |
    | body_radius | 0.25 | [0, 2]: reachability: how close to a wall a character's centre gets |
    | max_attempts | 50 | [1, 10000]: redraws of walls and ceilings before giving up |
    """

    size: tuple[float, float] = (16.0, 16.0)
    cell_size: float = 0.05
    patch_size: float = 4.0
    terrain_weights: tuple[float, float, float, float] = (0.35, 0.25, 0.2, 0.2)
    min_flat_patches: int = 3
    flat: FlatPatchConfig = FlatPatchConfig()
    slope: SlopePatchConfig = SlopePatchConfig()
    rough: RoughPatchConfig = RoughPatchConfig()
    stairs: StairsPatchConfig = StairsPatchConfig()
    num_walls: tuple[int, int] = (2, 5)
    wall_length: tuple[float, float] = (1.5, 4.0)
    wall_thickness: float = 0.2
    wall_height: tuple[float, float] = (1.0, 2.0)
    num_ceilings: tuple[int, int] = (1, 2)
    tunnel_probability: float = 0.5
    ceiling_clearance: tuple[float, float] = (0.6, 1.2)
    ceiling_length: tuple[float, float] = (1.5, 3.0)
    ceiling_width: tuple[float, float] = (1.2, 2.5)
    ceiling_thickness: float = 0.2
    landmark_names: tuple[str, ...] = DEFAULT_LANDMARK_NAMES
    num_landmarks: int = 4
    landmark_radius: float = 0.5
    landmark_separation: float = 4.0
    landmark_wall_clearance: float = 0.5
    landmark_flatness: float = 0.01
    num_dynamic_obstacles: int = 1
    ball_radius: tuple[float, float] = (0.2, 0.35)
    ball_speed: tuple[float, float] = (1.0, 2.5)
    ball_path_length: tuple[float, float] = (3.0, 8.0)
    max_step_height: float = 0.25
    min_clearance: float = 0.5
    body_radius: float = 0.25
    max_attempts: int = 50

    def __post_init__(self) -> None:
        def put(name: str, value: Any) -> None:
            object.__setattr__(self, name, value)

        size = check_floats("size", self.size, 2)
        for axis, value in zip("xy", size):
            check_number(f"size ({axis})", value, 2.0, 200.0)
        put("size", size)
        put("cell_size", check_number("cell_size", self.cell_size, 0.01, 0.5))
        put("patch_size", check_number("patch_size", self.patch_size, 0.5, 100.0))
        weights = check_floats("terrain_weights", self.terrain_weights, len(TERRAIN_KINDS))
        if min(weights) < 0.0 or sum(weights) <= 0.0:
            raise ValueError(
                f"terrain_weights must be {len(TERRAIN_KINDS)} numbers >= 0 with a positive sum "
                f"(odds of {', '.join(TERRAIN_KINDS)}), got {self.terrain_weights!r}"
            )
        put("terrain_weights", weights)
        put("min_flat_patches", check_integer("min_flat_patches", self.min_flat_patches, 0, 10000))
        for name, cls in (("flat", FlatPatchConfig), ("slope", SlopePatchConfig),
                          ("rough", RoughPatchConfig), ("stairs", StairsPatchConfig)):
            if not isinstance(getattr(self, name), cls):
                raise TypeError(f"{name} must be a {cls.__name__}, got {type(getattr(self, name)).__name__}")
        put("num_walls", check_int_range("num_walls", self.num_walls, 0, 100))
        put("wall_length", check_range("wall_length", self.wall_length, 0.1, 100.0))
        put("wall_thickness", check_number("wall_thickness", self.wall_thickness, 0.01, 5.0))
        put("wall_height", check_range("wall_height", self.wall_height, 0.05, 10.0))
        put("num_ceilings", check_int_range("num_ceilings", self.num_ceilings, 0, 50))
        put("tunnel_probability", check_number("tunnel_probability", self.tunnel_probability, 0.0, 1.0))
        put("ceiling_clearance", check_range("ceiling_clearance", self.ceiling_clearance, 0.2, 5.0))
        put("ceiling_length", check_range("ceiling_length", self.ceiling_length, 0.3, 50.0))
        put("ceiling_width", check_range("ceiling_width", self.ceiling_width, 0.3, 50.0))
        put("ceiling_thickness", check_number("ceiling_thickness", self.ceiling_thickness, 0.01, 2.0))
        put("num_landmarks", check_integer("num_landmarks", self.num_landmarks, 1, 100))
        names = tuple(self.landmark_names) if not isinstance(self.landmark_names, str) else (self.landmark_names,)
        if (len(names) < self.num_landmarks or len(set(names)) != len(names)
                or not all(isinstance(n, str) and n for n in names)):
            raise ValueError(
                f"landmark_names must hold at least num_landmarks ({self.num_landmarks}) distinct non-empty "
                f"names, got {self.landmark_names!r}"
            )
        put("landmark_names", names)
        put("landmark_radius", check_number("landmark_radius", self.landmark_radius, 0.05, 5.0))
        put("landmark_separation", check_number("landmark_separation", self.landmark_separation, 0.0, 100.0))
        put("landmark_wall_clearance",
            check_number("landmark_wall_clearance", self.landmark_wall_clearance, 0.0, 10.0))
        put("landmark_flatness", check_number("landmark_flatness", self.landmark_flatness, 0.0, 1.0))
        put("num_dynamic_obstacles", check_integer("num_dynamic_obstacles", self.num_dynamic_obstacles, 0, 20))
        put("ball_radius", check_range("ball_radius", self.ball_radius, 0.02, 2.0))
        put("ball_speed", check_range("ball_speed", self.ball_speed, 0.0, 20.0))
        put("ball_path_length", check_range("ball_path_length", self.ball_path_length, 0.5, 100.0))
        put("max_step_height", check_number("max_step_height", self.max_step_height, 0.0, 2.0))
        put("min_clearance", check_number("min_clearance", self.min_clearance, 0.1, 3.0))
        put("body_radius", check_number("body_radius", self.body_radius, 0.0, 2.0))
        put("max_attempts", check_integer("max_attempts", self.max_attempts, 1, 10000))

    @property
    def patch_configs(self) -> tuple[PatchConfig, ...]:
        """The patch configs in the order of ``TERRAIN_KINDS``."""
        return (self.flat, self.slope, self.rough, self.stairs)

def _ground_under(box: Box, heights: np.ndarray, cell_size: float, origin: tuple[float, float]) -> tuple[float, float]:
    """(min, max) ground height over the cells a footprint covers (the cell of its centre if none)."""
    mask = box.overlapping_cells(heights.shape, cell_size, origin)
    if not mask.any():
        i = int(np.clip(math.floor((box.center[1] - origin[1]) / cell_size), 0, heights.shape[0] - 1))
        j = int(np.clip(math.floor((box.center[0] - origin[0]) / cell_size), 0, heights.shape[1] - 1))
        return float(heights[i, j]), float(heights[i, j])
    return float(heights[mask].min()), float(heights[mask].max())


def _low_ceiling_structures(config: SceneConfig, rng: np.random.Generator, heights: np.ndarray,
                            origin: tuple[float, float], flat_patch_rects: list[tuple[float, float, float, float]]
                            ) -> tuple[list[Box], list[Box]]:
    """Tunnels and bridges on flat patches: (ceiling slabs, their walls / pillars)."""
    c = config.cell_size
    count = int(rng.integers(config.num_ceilings[0], config.num_ceilings[1] + 1))
    count = min(count, len(flat_patch_rects))
    slabs: list[Box] = []
    supports: list[Box] = []
    if count == 0:
        return slabs, supports
    for index in rng.choice(len(flat_patch_rects), size=count, replace=False):
        x_min, x_max, y_min, y_max = flat_patch_rects[int(index)]
        center = (0.5 * (x_min + x_max), 0.5 * (y_min + y_max))
        yaw = rng.uniform(0.0, math.pi)
        length = rng.uniform(*config.ceiling_length)
        width = rng.uniform(*config.ceiling_width)
        clearance = rng.uniform(*config.ceiling_clearance)
        tunnel = bool(rng.random() < config.tunnel_probability)
        # Shrink the structure (side walls included) to fit in its patch.
        outer_half_width = 0.5 * width + (config.wall_thickness if tunnel else 0.0)
        cs, sn = abs(math.cos(yaw)), abs(math.sin(yaw))
        extent_x = 0.5 * length * cs + outer_half_width * sn
        extent_y = 0.5 * length * sn + outer_half_width * cs
        scale = min(1.0, (0.5 * (x_max - x_min) - c) / extent_x, (0.5 * (y_max - y_min) - c) / extent_y)
        length, width = scale * length, scale * width
        outer = Box(center, (0.5 * length, outer_half_width * scale), yaw, 0.0, 1.0)
        ground_low, ground_high = _ground_under(outer, heights, c, origin)
        underside = ground_high + clearance
        slabs.append(Box(center, (0.5 * length, 0.5 * width), yaw, underside, underside + config.ceiling_thickness))
        u, v = yaw_axes(yaw)
        base = ground_low - 0.1
        if tunnel:
            for side in (-1.0, 1.0):
                wall_center = np.asarray(center) + side * (0.5 * width + 0.5 * config.wall_thickness) * v
                supports.append(Box(tuple(wall_center), (0.5 * length, 0.5 * config.wall_thickness), yaw,
                                    base, underside))
        else:
            half = min(0.1, 0.25 * length, 0.25 * width)
            for su in (-1.0, 1.0):
                for sv in (-1.0, 1.0):
                    pillar_center = (np.asarray(center) + su * (0.5 * length - half) * u
                                     + sv * (0.5 * width - half) * v)
                    supports.append(Box(tuple(pillar_center), (half, half), yaw, base, underside))
    return slabs, supports


def _random_walls(config: SceneConfig, rng: np.random.Generator, heights: np.ndarray,
                  origin: tuple[float, float], keep_clear: list[Box]) -> list[Box]:
    """Free-standing walls, half of them axis-aligned, at least 1 m from ``keep_clear``."""
    c = config.cell_size
    x_min, y_min = origin
    x_max, y_max = x_min + heights.shape[1] * c, y_min + heights.shape[0] * c
    walls: list[Box] = []
    for _ in range(int(rng.integers(config.num_walls[0], config.num_walls[1] + 1))):
        for _try in range(20):
            length = rng.uniform(*config.wall_length)
            yaw = rng.choice((0.0, 0.5 * math.pi)) if rng.random() < 0.5 else rng.uniform(0.0, math.pi)
            center = (rng.uniform(x_min + 0.5, x_max - 0.5), rng.uniform(y_min + 0.5, y_max - 0.5))
            height = rng.uniform(*config.wall_height)
            footprint = Box(center, (0.5 * length, 0.5 * config.wall_thickness), float(yaw), 0.0, 1.0)
            if any(footprint.footprint_overlaps(other, margin=1.0) for other in keep_clear):
                continue
            ground_low, ground_high = _ground_under(footprint, heights, c, origin)
            walls.append(Box(center, footprint.half_size, float(yaw), ground_low - 0.1, ground_high + height))
            break
    return walls


def _square_size(radius: float, cell_size: float) -> int:
    """Side (cells) of the odd square that covers a disc of ``radius`` centred on a cell."""
    return 2 * math.ceil(radius / cell_size) + 1


def _place_landmarks(config: SceneConfig, rng: np.random.Generator, grid: PlanningGrid, region: np.ndarray,
                     to_wall: np.ndarray) -> list[Landmark] | None:
    """Landmarks on flat, open-sky ground in ``region``, away from walls and each other (None: no room)."""
    c = grid.cell_size
    names = [str(n) for n in rng.choice(np.asarray(config.landmark_names), size=config.num_landmarks, replace=False)]
    size = _square_size(config.landmark_radius, c)
    h = grid.heights
    flat = ndimage.maximum_filter(h, size=size, mode="nearest") - ndimage.minimum_filter(h, size=size, mode="nearest")
    flat = flat <= config.landmark_flatness
    under_ceiling = ndimage.maximum_filter(np.isfinite(grid.ceiling).astype(np.uint8), size=size, mode="constant")
    in_region = ndimage.minimum_filter(region.astype(np.uint8), size=size, mode="constant", cval=0)
    away = to_wall >= config.landmark_radius + config.landmark_wall_clearance + 0.5 * c
    candidates = np.flatnonzero(flat & (under_ceiling == 0) & (in_region == 1) & away)
    landmarks: list[Landmark] = []
    for name in names:
        if len(candidates) == 0:
            return None
        cell = int(candidates[rng.integers(len(candidates))])
        i, j = divmod(cell, h.shape[1])
        x, y = grid.cell_center(i, j)
        ground = float(h[i, j])
        landmarks.append(Landmark(name, (float(x), float(y)), config.landmark_radius,
                                  (float(x), float(y), ground + LANDMARK_MARKER_HEIGHT)))
        ci, cj = np.divmod(candidates, h.shape[1])
        centres = grid.cell_center(ci, cj)
        candidates = candidates[np.hypot(centres[:, 0] - x, centres[:, 1] - y) >= config.landmark_separation]
    return landmarks


def _resting_ball_height(grid: PlanningGrid, xy: np.ndarray, radius: float) -> np.ndarray:
    """Centre height (world z) of a ball of ``radius`` resting on the ground samples at points (N, 2).

    z = max over cell centres p within ``radius`` of (x, y) of h(p) + sqrt(radius^2 - |p - (x, y)|^2).
    """
    c = grid.cell_size
    reach = math.ceil(radius / c) + 1
    di, dj = np.mgrid[-reach:reach + 1, -reach:reach + 1]
    cells = grid.cell_of(xy)
    ii = np.clip(cells[:, :1] + di.ravel(), 0, grid.shape[0] - 1)
    jj = np.clip(cells[:, 1:] + dj.ravel(), 0, grid.shape[1] - 1)
    centres = grid.cell_center(ii, jj)
    squared = radius * radius - np.sum((centres - xy[:, None, :]) ** 2, axis=-1)
    lift = np.where(squared >= 0.0, np.sqrt(np.maximum(squared, 0.0)), -np.inf)
    return np.max(grid.heights[ii, jj] + lift, axis=1)


def _place_balls(config: SceneConfig, rng: np.random.Generator, scene: Scene, grid: PlanningGrid,
                 region: np.ndarray, to_wall: np.ndarray) -> list[DynamicObstacle] | None:
    """Balls rolling back and forth on straight open-sky paths in ``region`` (None: no room)."""
    c = grid.cell_size
    rows, cols = grid.shape
    balls: list[DynamicObstacle] = []
    for k in range(config.num_dynamic_obstacles):
        radius = rng.uniform(*config.ball_radius)
        speed = rng.uniform(*config.ball_speed)
        wanted = rng.uniform(*config.ball_path_length)
        phase = rng.uniform(0.0, 1.0)
        usable = region & ~np.isfinite(grid.ceiling) & (to_wall >= radius + c)
        starts = np.flatnonzero(usable)
        if len(starts) == 0:
            return None
        arc = np.arange(0.0, wanted + 1e-9, 0.5 * c)
        best_start, best_direction, best_length = None, None, -1.0
        for _try in range(64):
            i, j = divmod(int(starts[rng.integers(len(starts))]), cols)
            theta = rng.uniform(0.0, 2.0 * math.pi)
            start = grid.cell_center(i, j)
            direction = np.array([math.cos(theta), math.sin(theta)])
            cells = grid.cell_of(start + arc[:, None] * direction)
            inside = (cells[:, 0] >= 0) & (cells[:, 0] < rows) & (cells[:, 1] >= 0) & (cells[:, 1] < cols)
            ok = inside.copy()
            ok[inside] = usable[cells[inside, 0], cells[inside, 1]]
            reach = len(arc) if ok.all() else int(np.argmin(ok))
            length = float(arc[reach - 1]) if reach > 0 else 0.0
            if length > best_length:
                best_start, best_direction, best_length = start, direction, length
            if length >= wanted - 1e-9:
                break
        if best_length < config.ball_path_length[0] - 1e-9 and best_length < wanted - 1e-9:
            return None
        # Waypoints every 10 cm, each at the height where the ball rests on the ground there.
        samples = np.linspace(0.0, best_length, max(math.ceil(best_length / 0.1), 1) + 1)
        xy = best_start + samples[:, None] * best_direction
        path = np.column_stack((xy, _resting_ball_height(grid, xy, radius)))
        balls.append(DynamicObstacle(f"ball{k}", radius, WaypointLoop.back_and_forth(path, speed, phase)))
    return balls


def scene_patch_edges(config: SceneConfig) -> tuple[np.ndarray, np.ndarray]:
    """Where ``generate_scene`` puts the patch borders: (row_edges, col_edges), cell indices.

    Patch (p, q) covers rows ``row_edges[p]:row_edges[p + 1]`` and columns
    ``col_edges[q]:col_edges[q + 1]``; the last edges are the grid's shape (H, W).
    """
    c = config.cell_size
    cols = max(round(config.size[0] / c), 2)
    rows = max(round(config.size[1] / c), 2)
    patches_x = max(round(cols * c / config.patch_size), 1)
    patches_y = max(round(rows * c / config.patch_size), 1)
    return (np.round(np.linspace(0, rows, patches_y + 1)).astype(int),
            np.round(np.linspace(0, cols, patches_x + 1)).astype(int))


def generate_scene(config: SceneConfig, rng: np.random.Generator) -> Scene:
    """A random PlaMo scene (paper Sec. 5.4), centred on the world origin. Pure: same rng state, same scene.

    1. Terrain: the area is tiled with patches whose kinds are drawn with
       ``terrain_weights`` (at least ``min_flat_patches`` flat); each patch's heights come
       from its generator and meet the neighbours at height 0 on the patch rims.
    2. Low ceilings: tunnels / bridges on flat patches. 3. Walls elsewhere.
    4. Landmarks (``num_landmarks`` distinct names) on flat open-sky ground of the largest
       region a character can reach (``connected_free_space``), away from walls.
    5. Balls rolling back and forth (``WaypointLoop.back_and_forth``) on the terrain.

    Steps 2-5 are redrawn (up to ``max_attempts``) if the landmarks or balls find no room;
    then a ``RuntimeError`` says so.
    """
    c = config.cell_size
    row_edges, col_edges = scene_patch_edges(config)
    rows, cols = int(row_edges[-1]), int(col_edges[-1])
    patches_y, patches_x = len(row_edges) - 1, len(col_edges) - 1
    origin = (-0.5 * cols * c, -0.5 * rows * c)

    weights = np.asarray(config.terrain_weights) / sum(config.terrain_weights)
    kinds = rng.choice(len(TERRAIN_KINDS), size=(patches_y, patches_x), p=weights)
    missing_flat = config.min_flat_patches - int((kinds == 0).sum())
    if missing_flat > 0:
        others = np.flatnonzero(kinds != 0)
        kinds.flat[rng.permutation(others)[:missing_flat]] = 0

    heights = np.zeros((rows, cols))
    labels = np.zeros((rows, cols), dtype=np.uint8)
    flat_patch_rects: list[tuple[float, float, float, float]] = []
    stairs = {}
    for pi in range(patches_y):
        for pj in range(patches_x):
            r0, r1, c0, c1 = row_edges[pi], row_edges[pi + 1], col_edges[pj], col_edges[pj + 1]
            kind = int(kinds[pi, pj])
            heights[r0:r1, c0:c1], shape = generate_patch_shape(config.patch_configs[kind], rng,
                                                                shape=(r1 - r0, c1 - c0), cell_size=c)
            labels[r0:r1, c0:c1] = kind
            if TERRAIN_KINDS[kind] == "stairs":
                boxes = stairs_boxes(shape, (origin[0] + 0.5 * (c0 + c1) * c, origin[1] + 0.5 * (r0 + r1) * c))
                if boxes is not None:
                    stairs[pi, pj] = boxes
            if kind == 0:
                flat_patch_rects.append((origin[0] + c0 * c, origin[0] + c1 * c, origin[1] + r0 * c, origin[1] + r1 * c))

    for _attempt in range(config.max_attempts):
        slabs, supports = _low_ceiling_structures(config, rng, heights, origin, flat_patch_rects)
        walls = supports + _random_walls(config, rng, heights, origin, keep_clear=slabs + supports)
        scene = Scene(heights, c, origin, walls=walls, ceilings=slabs, terrain_labels=labels)
        grid = scene.planning_grid()
        region = connected_free_space(grid, max_step_height=config.max_step_height,
                                      min_clearance=config.min_clearance, body_radius=config.body_radius) == 0
        if grid.blocked.any():
            to_wall = ndimage.distance_transform_edt(~grid.blocked) * c
        else:
            to_wall = np.full(grid.shape, np.inf)
        landmarks = _place_landmarks(config, rng, grid, region, to_wall)
        if landmarks is None:
            continue
        balls = _place_balls(config, rng, scene, grid, region, to_wall)
        if balls is None:
            continue
        # the terrain as tiles (``stairenv.world.tiles``): sample (i, j) is cell (i, j)'s centre, a tile
        # spans its patch's cells and the next patch's first ones
        tiles = TerrainTiles(heights, (origin[0] + 0.5 * c, origin[1] + 0.5 * c), c, row_edges, col_edges,
                             kinds.astype(np.uint8), stairs, outside="edge")
        return Scene(heights, c, origin, walls=walls, ceilings=slabs, dynamic_obstacles=balls,
                     landmarks=landmarks, terrain_labels=labels, tiles=tiles)
    raise RuntimeError(
        f"generate_scene: no room for {config.num_landmarks} landmarks (or the balls) after "
        f"{config.max_attempts} attempts; use a larger size, more flat patches, fewer walls, "
        f"or a smaller landmark_separation / landmark_radius"
    )
