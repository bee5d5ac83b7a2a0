"""PlaMo scenes (``stairenv.world.scenes``): the generators' properties, the planner's grid,
the MuJoCo model (height field orientation, walls, moving obstacles) and scene files."""

from __future__ import annotations

import io
import json
import math
import re
import tracemalloc
import zipfile

import mujoco
import numpy as np
import pytest
from scipy import ndimage

from stairenv.humanoid import load_humanoid_spec
from stairenv.world.scenes import (
    DEFAULT_LANDMARK_NAMES,
    MAX_SCENE_CELLS,
    MAX_SCENE_HEIGHT,
    MAX_SCENE_JSON_BYTES,
    TERRAIN_KINDS,
    Box,
    ConstantVelocity,
    DynamicObstacle,
    FlatPatchConfig,
    Landmark,
    Loop,
    RoughPatchConfig,
    Scene,
    SceneConfig,
    SceneFileError,
    SlopePatchConfig,
    StairsPatchConfig,
    WaypointLoop,
    add_scene_to_spec,
    connected_free_space,
    flat_patch,
    generate_patch,
    generate_scene,
    rough_patch,
    scene_patch_edges,
    slalom_scene,
    slope_patch,
    stairs_patch,
)

SEEDS = (0, 1, 2, 3, 4, 5)
FLAT, SLOPE, ROUGH, STAIRS = (TERRAIN_KINDS.index(k) for k in ("flat", "slope", "rough", "stairs"))


@pytest.fixture(scope="module")
def scenes() -> dict[int, Scene]:
    return {seed: generate_scene(SceneConfig(), np.random.default_rng(seed)) for seed in SEEDS}


def _rng(seed: int) -> np.random.Generator:
    return np.random.default_rng(seed)


def _drop_spheres(scene: Scene, points: np.ndarray, radius: float = 0.05, seconds: float = 1.5,
                  drop_height: float = 0.25) -> np.ndarray:
    """Build ``scene`` into the humanoid's spec, drop a free sphere above each (x, y) and
    return where the spheres' lowest points come to rest (z)."""
    spec = load_humanoid_spec()
    handles = add_scene_to_spec(spec, scene)
    for k, (x, y) in enumerate(points):
        z = float(scene.surface_height_at(np.array([x, y]))) + radius + drop_height
        body = spec.worldbody.add_body(name=f"probe{k}", pos=[x, y, z])
        body.add_freejoint()
        body.add_geom(name=f"probe{k}", type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[radius, 0, 0], mass=0.5)
    model = spec.compile()
    handles.bind(model)
    data = mujoco.MjData(model)
    data.qpos[0] = scene.bounds[1] + 5.0  # the humanoid stands outside the scene, out of the way
    for _ in range(int(seconds / model.opt.timestep)):
        handles.update(model, data, data.time)
        mujoco.mj_step(model, data)
    return np.array([data.body(f"probe{k}").xpos[2] - radius for k in range(len(points))])


# --- terrain patches ----------------------------------------------------------------------------
PATCH_CASES = [
    (flat_patch, FlatPatchConfig()),
    (slope_patch, SlopePatchConfig()),
    (rough_patch, RoughPatchConfig()),
    (stairs_patch, StairsPatchConfig()),
]


@pytest.mark.parametrize("generator,config", PATCH_CASES, ids=TERRAIN_KINDS)
def test_patches_are_pure_and_zero_on_their_rim(generator, config):
    for seed in range(5):
        a = generator(config, _rng(seed), shape=(70, 90), cell_size=0.05)
        b = generate_patch(config, _rng(seed), shape=(70, 90), cell_size=0.05)
        assert a.shape == (70, 90)
        np.testing.assert_array_equal(a, b)
        rim = np.concatenate((a[0], a[-1], a[:, 0], a[:, -1]))
        assert np.all(rim == 0.0)
        assert a.min() >= 0.0


def test_slope_patch_heights_and_angles():
    config = SlopePatchConfig(angle_deg=(10.0, 25.0), height=(0.2, 1.5))
    c = 0.05
    steepest = []
    for seed in range(20):
        h = slope_patch(config, _rng(seed), shape=(80, 80), cell_size=c)
        assert 0.0 <= h.min() and h.max() <= 1.5 + 1e-12
        grad = max(np.abs(np.diff(h, axis=0)).max(), np.abs(np.diff(h, axis=1)).max()) / c
        assert grad <= math.tan(math.radians(25.0)) + 1e-9
        steepest.append(grad)
    # Along the inclines the slope reaches the sampled angle (>= 10 degrees), times cos of the yaw offset.
    assert min(steepest) >= math.tan(math.radians(10.0)) * math.cos(math.radians(45.0)) - 1e-9


def test_rough_patch_amplitude():
    config = RoughPatchConfig(amplitude=(0.02, 0.06))
    for seed in range(10):
        h = rough_patch(config, _rng(seed), shape=(80, 80), cell_size=0.05)
        assert h.min() >= 0.0 and 0.02 * 0.5 <= h.max() <= 0.06 + 1e-12
        assert np.std(h[20:60, 20:60]) > 0.002  # not flat inside


def test_stairs_patch_steps():
    config = StairsPatchConfig(step_height=(0.05, 0.20), num_steps=(2, 6))
    for seed in range(20):
        h = stairs_patch(config, _rng(seed), shape=(80, 80), cell_size=0.05)
        step = h[h > 0].min()
        assert 0.05 - 1e-12 <= step <= 0.20 + 1e-12
        levels = h / step
        np.testing.assert_allclose(levels, np.round(levels), atol=1e-9)
        assert 2 <= levels.max() <= 6 + 1e-9
        # Risers: neighbouring cells differ by at most one step.
        assert max(np.abs(np.diff(h, axis=0)).max(), np.abs(np.diff(h, axis=1)).max()) <= step + 1e-9


# --- generate_scene -----------------------------------------------------------------------------
def test_generate_scene_is_deterministic(scenes):
    again = generate_scene(SceneConfig(), _rng(SEEDS[0]))
    assert again == scenes[SEEDS[0]]
    assert scenes[SEEDS[0]] != scenes[SEEDS[1]]
    other = SceneConfig(size=(12.0, 10.0), cell_size=0.1)
    assert generate_scene(other, _rng(7)) == generate_scene(other, _rng(7))


def test_scene_heights_follow_patch_kinds(scenes):
    config = SceneConfig()
    for scene in scenes.values():
        labels, h = scene.terrain_labels, scene.heights
        assert h.shape == (320, 320) and scene.cell_size == config.cell_size
        np.testing.assert_allclose(scene.bounds, (-8.0, 8.0, -8.0, 8.0))
        assert h.min() >= 0.0
        assert np.all(h[labels == FLAT] == 0.0)
        assert h[labels == SLOPE].max(initial=0.0) <= config.slope.height[1] + 1e-12
        assert h[labels == ROUGH].max(initial=0.0) <= config.rough.amplitude[1] + 1e-12
        assert h[labels == STAIRS].max(initial=0.0) <= config.stairs.num_steps[1] * config.stairs.step_height[1] + 1e-9
        assert (labels == FLAT).sum() >= config.min_flat_patches * 80 * 80


@pytest.mark.parametrize("config", [
    SceneConfig(),
    # Features up to the patch rims and steep inclines: still no cliff but stairs risers.
    SceneConfig(slope=SlopePatchConfig(angle_deg=(25.0, 35.0), border=0.0), stairs=StairsPatchConfig(border=0.0),
                terrain_weights=(0.1, 0.4, 0.2, 0.3), min_flat_patches=2),
], ids=["default", "no-border"])
def test_no_cliffs_at_patch_borders(config):
    row_edges, col_edges = scene_patch_edges(config)
    c = config.cell_size
    slope_limit = math.tan(math.radians(config.slope.angle_deg[1])) * c + 1e-9
    riser_limit = config.stairs.step_height[1] + 1e-9
    for seed in range(4):
        scene = generate_scene(config, _rng(seed))
        h, labels = scene.heights, scene.terrain_labels
        pairs = [(h[:, e - 1], h[:, e], labels[:, e - 1], labels[:, e]) for e in col_edges[1:-1]]
        pairs += [(h[e - 1, :], h[e, :], labels[e - 1, :], labels[e, :]) for e in row_edges[1:-1]]
        for a, b, la, lb in pairs:
            jump = np.abs(a - b)
            stairs = (la == STAIRS) | (lb == STAIRS)
            assert jump[~stairs].max(initial=0.0) <= slope_limit
            assert jump[stairs].max(initial=0.0) <= riser_limit


def test_landmarks_on_reachable_free_flat_ground(scenes):
    config = SceneConfig()
    for scene in scenes.values():
        names = scene.landmark_names
        assert len(names) == 4 and len(set(names)) == 4 and set(names) <= set(DEFAULT_LANDMARK_NAMES)
        grid = scene.planning_grid()
        region = connected_free_space(grid)
        to_wall = ndimage.distance_transform_edt(~grid.blocked) * grid.cell_size
        for lm in scene.landmarks:
            cells = grid.landmarks[lm.name]
            i, j = cells[:, 0], cells[:, 1]
            assert len(cells) >= 300  # a 0.5 m disc on 5 cm cells
            assert not grid.blocked[i, j].any()
            assert np.isinf(grid.ceiling[i, j]).all()
            assert np.ptp(grid.heights[i, j]) <= config.landmark_flatness
            assert to_wall[i, j].min() >= config.landmark_wall_clearance
            assert not any(w.contains_xy(np.array(lm.center)) for w in scene.walls)
            assert (region[i, j] == 0).all()  # all landmarks in the one largest reachable region
            np.testing.assert_allclose(lm.display_position[:2], lm.center)
            assert lm.display_position[2] > scene.height_at(np.array(lm.center))
        centres = np.array([lm.center for lm in scene.landmarks])
        gaps = np.linalg.norm(centres[:, None] - centres[None], axis=-1)[np.triu_indices(4, 1)]
        assert gaps.min() >= config.landmark_separation


def test_walls_ceilings_and_ball(scenes):
    config = SceneConfig()
    for scene in scenes.values():
        assert config.num_ceilings[0] <= len(scene.ceilings) <= config.num_ceilings[1]
        assert len(scene.walls) >= config.num_walls[0] + 2 * len(scene.ceilings)  # tunnel sides / bridge pillars
        grid = scene.planning_grid()
        for slab in scene.ceilings:
            under = slab.overlapping_cells(grid.shape, grid.cell_size, scene.origin)
            clearance = slab.bottom - grid.heights[under].max()
            assert config.ceiling_clearance[0] - 1e-9 <= clearance <= config.ceiling_clearance[1] + 1e-9
            assert np.all(grid.ceiling[under] <= slab.bottom)
        for wall in scene.walls:
            cells = wall.overlapping_cells(grid.shape, grid.cell_size, scene.origin)
            assert wall.bottom < grid.heights[cells].min() and wall.top > grid.heights[cells].max()
        (ball,) = scene.dynamic_obstacles
        assert config.ball_radius[0] <= ball.radius <= config.ball_radius[1]
        path = ball.position(np.linspace(0.0, 30.0, 400))
        cells = grid.cell_of(path[:, :2])
        assert not grid.blocked[cells[:, 0], cells[:, 1]].any()
        above_ground = path[:, 2] - ball.radius - scene.height_at(path)
        assert above_ground.min() >= -0.01  # rolls over the terrain, never through it
        assert above_ground.max() <= config.stairs.step_height[1] + 0.1  # and rests on it (a step ahead at most)
        travelled = np.ptp(path[:, :2], axis=0)
        assert np.hypot(*travelled) >= config.ball_path_length[0] - 0.01


def test_generate_scene_gives_up_clearly():
    crowded = SceneConfig(size=(4.0, 4.0), patch_size=2.0, landmark_separation=50.0, max_attempts=2)
    with pytest.raises(RuntimeError, match="landmarks"):
        generate_scene(crowded, _rng(0))


# --- slalom -------------------------------------------------------------------------------------
def test_slalom_scene_layout():
    scene = slalom_scene(num_walls=5, wall_spacing=3.0, corridor_width=4.0, gap_width=1.2)
    gates = scene.walls[:5]
    assert [np.sign(w.center[1]) for w in gates] == [1, -1, 1, -1, 1]
    for w in gates:  # each gate leaves a 1.2 m gap on the other side of the corridor
        assert math.isclose(2 * w.half_size[1], 4.0 - 1.2)
    assert np.allclose(np.diff([w.center[0] for w in gates]), 3.0)
    assert scene.landmark_names == ("start", "goal")
    start, goal = scene.landmark("start"), scene.landmark("goal")
    assert start.center[0] < gates[0].center[0] < gates[-1].center[0] < goal.center[0]
    grid = scene.planning_grid()
    region = connected_free_space(grid)
    for name in ("start", "goal"):
        cells = grid.landmarks[name]
        assert not grid.blocked[cells[:, 0], cells[:, 1]].any()
        assert (region[cells[:, 0], cells[:, 1]] == 0).all()
    # The straight line is walled off: the path must weave.
    line = np.linspace(start.center, goal.center, 500)
    cells = grid.cell_of(line)
    assert grid.blocked[cells[:, 0], cells[:, 1]].any()
    assert np.all(scene.heights == 0.0)


# --- the planner's grid -------------------------------------------------------------------------
def test_wall_blocks_exactly_its_cells():
    c, origin = 0.25, (-1.0, 2.0)
    scene = Scene(np.zeros((20, 30)), c, origin)
    # x in [0.0, 1.5) -> columns 4..9, y in [3.0, 3.5) -> rows 4..5
    wall = Box(center=(0.75, 3.25), half_size=(0.75, 0.25), yaw=0.0, bottom=0.0, top=2.0)
    turned = Box(center=(0.75, 3.25), half_size=(0.25, 0.75), yaw=0.5 * math.pi, bottom=0.0, top=2.0)
    expected = np.zeros((20, 30), dtype=bool)
    expected[4:6, 4:10] = True
    for w in (wall, turned):
        scene.walls = [w]
        grid = scene.planning_grid()
        np.testing.assert_array_equal(grid.blocked, expected)
        assert np.isinf(grid.ceiling).all()


def test_rotated_wall_blocks_the_cells_it_covers():
    c = 0.1
    scene = Scene(np.zeros((40, 40)), c, (0.0, 0.0),
                  walls=[Box(center=(2.0, 2.0), half_size=(1.2, 0.1), yaw=math.radians(30.0), bottom=0.0, top=1.0)])
    blocked = scene.planning_grid().blocked
    # Dense samples strictly inside each cell: a cell holding an inside sample must be blocked,
    # and a blocked cell must hold one (the footprint is wide enough to reach a sample).
    offsets = (np.arange(10) + 0.5) / 10.0
    covered = np.zeros_like(blocked)
    for oy in offsets:
        for ox in offsets:
            ii, jj = np.mgrid[0:40, 0:40]
            points = np.stack(((jj + ox) * c, (ii + oy) * c), axis=-1)
            covered |= scene.walls[0].contains_xy(points)
    assert np.all(blocked[covered])
    assert blocked.sum() <= covered.sum() + 0.1 * covered.sum()


def test_ceiling_values_and_resampled_grid():
    h = np.tile(np.linspace(0.0, 0.59, 60), (40, 1))  # rises 1 cm per 10 cm along x
    scene = Scene(h, 0.1, (0.0, 0.0),
                  ceilings=[Box((1.0, 1.0), (0.5, 0.5), 0.0, 1.2, 1.4), Box((1.5, 1.0), (0.5, 0.5), 0.0, 0.8, 1.0)],
                  landmarks=[Landmark("tree", (4.0, 3.0), 0.3, (4.0, 3.0, 1.0))])
    grid = scene.planning_grid()
    assert np.all(grid.ceiling[5:15, 5:10] == 1.2)
    assert np.all(grid.ceiling[5:15, 10:20] == 0.8)  # the lower one where both overlap
    finite = np.isfinite(grid.ceiling)
    assert finite.sum() == 10 * 15
    cells = grid.landmarks["tree"]
    centres = grid.cell_center(cells[:, 0], cells[:, 1])
    assert np.all(np.hypot(centres[:, 0] - 4.0, centres[:, 1] - 3.0) <= 0.3 + 1e-9)
    coarse = scene.planning_grid(cell_size=0.25)
    assert coarse.shape == (16, 24) and coarse.cell_size == 0.25 and coarse.origin == scene.origin
    centres = coarse.cell_center(*np.mgrid[0:16, 0:24])
    inside = (centres[..., 0] > 0.05) & (centres[..., 0] < 5.85)
    np.testing.assert_allclose(coarse.heights[inside], 0.1 * (centres[..., 0][inside] - 0.05), atol=1e-9)
    assert np.all(coarse.ceiling[np.isfinite(coarse.ceiling)] >= 0.8)
    assert len(coarse.landmarks["tree"]) > 0


# --- motion models ------------------------------------------------------------------------------
def test_motion_models():
    line = ConstantVelocity(start=(1.0, 2.0, 0.3), velocity=(0.5, -1.0, 0.0))
    np.testing.assert_allclose(line.position(2.0), [2.0, 0.0, 0.3])
    np.testing.assert_allclose(line.position(np.array([0.0, 1.0])), [[1.0, 2.0, 0.3], [1.5, 1.0, 0.3]])
    np.testing.assert_allclose(line.velocity_at(3.0), [0.5, -1.0, 0.0])

    loop = Loop(center=(0.0, 0.0, 0.3), radius=2.0, period=4.0, phase=0.0)
    np.testing.assert_allclose(loop.position(1.0), [0.0, 2.0, 0.3], atol=1e-12)
    np.testing.assert_allclose(loop.position(4.0), loop.position(0.0), atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(loop.velocity_at(0.7)), 2 * math.pi * 2.0 / 4.0)

    back = WaypointLoop.back_and_forth([(0, 0, 0.3), (3, 0, 0.3), (3, 4, 0.3)], speed=1.0)
    assert math.isclose(back.length, 14.0)
    np.testing.assert_allclose(back.position(5.0), [3.0, 2.0, 0.3])
    np.testing.assert_allclose(back.position(9.0), [3.0, 2.0, 0.3])  # on the way back
    np.testing.assert_allclose(back.position(12.0), [2.0, 0.0, 0.3])
    np.testing.assert_allclose(back.position(14.0), [0.0, 0.0, 0.3], atol=1e-12)
    np.testing.assert_allclose(back.velocity_at(8.0), [0.0, -1.0, 0.0])
    t = np.linspace(0.0, 28.0, 2801)
    steps = np.linalg.norm(np.diff(back.position(t), axis=0), axis=1)
    assert steps.max() <= 0.01 + 1e-9  # continuous, constant speed
    shifted = WaypointLoop(back.waypoints, speed=1.0, phase=0.25)
    np.testing.assert_allclose(shifted.position(0.0), back.position(3.5))
    with pytest.raises(ValueError, match="period"):
        Loop(center=(0, 0, 0), radius=1.0, period=0.0)


# --- MuJoCo -------------------------------------------------------------------------------------
def test_builds_with_the_humanoid(scenes):
    scene = scenes[SEEDS[0]]
    spec = load_humanoid_spec()
    handles = add_scene_to_spec(spec, scene)
    model = spec.compile()
    handles.bind(model)
    rows, cols = scene.shape
    assert model.nhfield == 1
    assert (model.hfield_nrow[0], model.hfield_ncol[0]) == (rows + 2, cols + 2)
    size = model.hfield_size[0]
    np.testing.assert_allclose(size[:2], [(cols + 1) * scene.cell_size / 2, (rows + 1) * scene.cell_size / 2])
    assert scene.heights.min() == 0.0
    assert math.isclose(size[2], scene.heights.max(), rel_tol=1e-9) and size[3] > 0.0
    data_range = model.hfield_data
    assert data_range.min() == 0.0 and math.isclose(float(data_range.max()), 1.0, rel_tol=1e-6)
    assert len(handles.wall_geom_ids) == len(scene.walls) and len(handles.ceiling_geom_ids) == len(scene.ceilings)
    for gid in (*handles.wall_geom_ids, *handles.ceiling_geom_ids, handles.terrain_geom_id):
        body = model.geom_bodyid[gid]
        assert model.body_geomnum[body] == 1 and model.body_dofnum[body] == 0
    assert model.nmocap == len(scene.dynamic_obstacles) == len(handles.obstacle_mocap_ids)
    for names in handles.landmark_geom_names.values():
        for name in names:
            assert model.geom(name).contype[0] == 0 and model.geom(name).conaffinity[0] == 0
    assert set(handles.landmark_geom_names) == set(scene.landmark_names)
    assert model.geom("floor").pos[2] < scene.heights.min()
    data = mujoco.MjData(model)
    for _ in range(30):
        handles.update(model, data, data.time)
        mujoco.mj_step(model, data)
    assert np.isfinite(data.qpos).all()


def test_height_field_surface_matches_height_map(scenes):
    """Rays straight down hit the height field at the height map's value at the sampled cell centres.

    (The rays pass a fraction of a millimetre off the exact sample: a ray through a vertex of
    MuJoCo's triangulation, or along a triangle's diagonal, can slip through.)"""
    for scene in (scenes[SEEDS[1]], scenes[SEEDS[2]]):
        spec = mujoco.MjSpec()
        handles = add_scene_to_spec(spec, scene)
        model = spec.compile()
        handles.bind(model)
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        rng = _rng(0)
        ii = rng.integers(0, scene.shape[0], 400)
        jj = rng.integers(0, scene.shape[1], 400)
        top = 5.0
        for i, j in zip(ii, jj):
            x, y = scene.cell_center(i, j)
            distance = mujoco.mj_rayHfield(model, data, handles.terrain_geom_id, np.array([x + 1e-4, y - 3e-4, top]),
                                           np.array([0.0, 0.0, -1.0]))
            assert abs((top - distance) - scene.heights[i, j]) < 2e-3, (i, j)


def test_spheres_rest_on_the_height_map():
    # Four plateaus of different heights, off-centre origin, a non-square grid: any flip of rows
    # or columns puts a sphere on the wrong plateau.
    h = np.zeros((24, 36))
    h[:12, :18], h[:12, 18:], h[12:, :18], h[12:, 18:] = 0.1, 0.3, 0.5, 0.0
    scene = Scene(h, 0.1, origin=(-1.0, 2.0))
    points = scene.cell_center(np.array([5, 5, 18, 18]), np.array([5, 30, 5, 30]))
    rest = _drop_spheres(scene, points)
    np.testing.assert_allclose(rest, [0.1, 0.3, 0.5, 0.0], atol=0.01)


def test_spheres_rest_on_generated_terrain(scenes):
    scene = scenes[SEEDS[3]]
    h = scene.heights
    # Cells whose 7 x 7 neighbourhood is level (plateaus, treads, flat ground), at several heights.
    level = (ndimage.maximum_filter(h, size=7) - ndimage.minimum_filter(h, size=7)) < 1e-9
    grid = scene.planning_grid()
    open_ground = level & ~ndimage.binary_dilation(grid.blocked, iterations=4) & np.isinf(grid.ceiling)
    rng = _rng(1)
    picks = []
    for value in np.unique(np.round(h[open_ground], 6))[-4:]:  # the highest levels present
        cells = np.argwhere(open_ground & (np.abs(h - value) < 1e-6))
        picks.append(cells[rng.integers(len(cells))])
    zero = np.argwhere(open_ground & (h == 0.0))
    picks.append(zero[rng.integers(len(zero))])
    picks = np.array(picks)
    points = scene.cell_center(picks[:, 0], picks[:, 1])
    rest = _drop_spheres(scene, points)
    np.testing.assert_allclose(rest, h[picks[:, 0], picks[:, 1]], atol=0.015)
    assert h[picks[:, 0], picks[:, 1]].max() > 0.1  # really tested off the ground level


def test_sphere_rests_on_a_wall_top():
    wall = Box(center=(1.0, -0.5), half_size=(1.0, 0.2), yaw=0.3, bottom=-0.1, top=1.3)
    scene = Scene(np.zeros((40, 40)), 0.1, (-2.0, -2.0), walls=[wall])
    rest = _drop_spheres(scene, np.array([[1.0, -0.5], [1.4, -0.4], [-1.0, 1.0]]))
    np.testing.assert_allclose(rest, [1.3, 1.3, 0.0], atol=0.01)


def test_mocap_obstacles_follow_their_motion():
    obstacles = [
        DynamicObstacle("line", 0.2, ConstantVelocity(start=(-1.0, 0.0, 0.3), velocity=(0.5, 0.2, 0.0))),
        DynamicObstacle("circle", 0.3, Loop(center=(1.0, 1.0, 0.4), radius=1.5, period=3.0, phase=0.5)),
        DynamicObstacle("patrol", 0.25, WaypointLoop.back_and_forth([(-2, -2, 0.3), (2, -2, 0.3)], speed=2.0)),
    ]
    scene = Scene(np.zeros((60, 60)), 0.1, (-3.0, -3.0), dynamic_obstacles=obstacles)
    spec = load_humanoid_spec()
    handles = add_scene_to_spec(spec, scene)
    model = spec.compile()
    data = mujoco.MjData(model)
    body_ids = [model.body(name).id for name in handles.obstacle_body_names]
    for step in range(240):
        handles.update(model, data, data.time)
        mujoco.mj_step(model, data)
        if step % 40 == 0:
            t = data.time - model.opt.timestep  # the time the obstacles were set for
            np.testing.assert_allclose(data.xpos[body_ids], scene.dynamic_positions(t), atol=1e-12)
    handles.update(model, data, 7.3)
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(data.xpos[body_ids], np.stack([ob.position(7.3) for ob in obstacles]), atol=1e-12)
    assert model.geom_size[handles.obstacle_geom_ids, 0].tolist() == [0.2, 0.3, 0.25]


# --- files --------------------------------------------------------------------------------------
def test_save_load_round_trip(scenes, tmp_path):
    hand_made = Scene(
        np.random.default_rng(3).random((7, 9)), 0.3, (1.5, -2.0),
        walls=[Box((0.0, 0.1), (0.5, 0.1), 0.2, -0.1, 1.0)],
        ceilings=[Box((1.0, 1.0), (0.4, 0.6), 1.0, 0.9, 1.1)],
        dynamic_obstacles=[DynamicObstacle("a", 0.2, ConstantVelocity((0, 0, 0.2), (1, 0, 0))),
                           DynamicObstacle("b", 0.3, Loop((0, 0, 0.3), 1.0, 2.0, 0.1))],
        landmarks=[Landmark("x", (2.0, -1.0), 0.4, (2.0, -1.0, 1.5))],
    )
    for k, scene in enumerate((scenes[SEEDS[0]], slalom_scene(), hand_made)):
        path = tmp_path / f"scene{k}.npz"
        scene.save(path)
        loaded = Scene.load(path)
        assert loaded == scene
        assert loaded.planning_grid().blocked.sum() == scene.planning_grid().blocked.sum()
        np.testing.assert_array_equal(loaded.dynamic_positions(3.3), scene.dynamic_positions(3.3))
    assert Scene.load(tmp_path / "scene2.npz").terrain_labels is None


def _rewrite(source, target, change):
    """Copy a scene file, passing its JSON description through ``change``."""
    with np.load(source) as npz:
        arrays = {k: npz[k] for k in npz.files}
    meta = json.loads(arrays["scene_json"].tobytes().decode())
    text = change(meta)
    arrays["scene_json"] = np.frombuffer(text.encode() if isinstance(text, str) else json.dumps(text).encode(),
                                         dtype=np.uint8)
    with open(target, "wb") as f:
        np.savez(f, **arrays)


def test_corrupt_and_foreign_files(tmp_path):
    good = tmp_path / "good.npz"
    slalom_scene(num_walls=2).save(good)
    raw = good.read_bytes()

    def bad(name: str, content: bytes | None = None, change=None):
        path = tmp_path / name
        if change is not None:
            _rewrite(good, path, change)
        else:
            path.write_bytes(content)
        return path

    def with_version(meta):
        meta["version"] = 99
        return meta

    def with_format(meta):
        meta["format"] = "something.else"
        return meta

    def with_bad_wall(meta):
        meta["walls"][0]["half_size"] = [-1.0, 0.2]
        return meta

    def without_landmarks(meta):
        del meta["landmarks"]
        return meta

    cases = {
        "garbage": (bad("garbage.npz", b"this is not a scene at all" * 10), "not a readable scene file"),
        "empty": (bad("empty.npz", b""), "not a readable scene file"),
        "truncated": (bad("truncated.npz", raw[: len(raw) // 2]), "not a readable scene file"),
        "version": (bad("version.npz", change=with_version), "version 99"),
        "format": (bad("format.npz", change=with_format), "format"),
        "json": (bad("json.npz", change=lambda meta: "{not json"), "corrupt scene description"),
        "wall": (bad("wall.npz", change=with_bad_wall), "half_size"),
        "missing": (bad("missing.npz", change=without_landmarks), "landmarks"),
    }
    npy = tmp_path / "array.npy"
    np.save(npy, np.zeros(3))
    cases["npy"] = (npy, "not an .npz")
    other_zip = tmp_path / "other.npz"
    with zipfile.ZipFile(other_zip, "w") as z:
        z.writestr("readme.txt", "hello")
    cases["other-zip"] = (other_zip, "missing")
    for path, message in cases.values():
        with pytest.raises(SceneFileError, match=message):
            Scene.load(path)
    assert issubclass(SceneFileError, ValueError)
    with pytest.raises(FileNotFoundError):
        Scene.load(tmp_path / "nowhere.npz")


def _npy_head(shape: tuple[int, ...], descr: str = "<f8", data: bytes = b"") -> bytes:
    """An .npy member's bytes: a header declaring ``shape`` followed by ``data`` (at most a few bytes)."""
    out = io.BytesIO()
    np.lib.format.write_array_header_1_0(out, {"descr": descr, "fortran_order": False, "shape": shape})
    return out.getvalue() + data


def _npy(array: np.ndarray) -> bytes:
    out = io.BytesIO()
    np.save(out, array)
    return out.getvalue()


def _zip(path, members: dict[str, bytes]):
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        for name, content in members.items():
            z.writestr(f"{name}.npy", content)
    return path


def test_declared_array_sizes_are_bounded_before_reading(tmp_path):
    good = tmp_path / "good.npz"
    slalom_scene(num_walls=2).save(good)
    with np.load(good) as npz:
        heights, scene_json = _npy(npz["heights"]), _npy(npz["scene_json"])
    side = math.isqrt(MAX_SCENE_CELLS) + 1
    # a few kB that declare gigabytes (3 MB of zeros used to inflate to two 3 GB arrays)
    cases = {
        "heights": ({"heights": _npy_head((20000, 20000), data=bytes(1 << 16)), "scene_json": scene_json},
                    (r"heights declares shape \(20000, 20000\) \(400000000 elements\), more than the 16777216 "
                     r"Scene.load reads \(MAX_SCENE_CELLS\)")),
        "just_over": ({"heights": _npy_head((side, side - 1)), "scene_json": scene_json}, "MAX_SCENE_CELLS"),
        "json": ({"heights": heights, "scene_json": _npy_head((MAX_SCENE_JSON_BYTES + 1,), "|u1")},
                 "scene_json declares .*MAX_SCENE_JSON_BYTES"),
        "labels": ({"heights": heights, "scene_json": scene_json,
                    "terrain_labels": _npy_head((5000, 5000), "|u1")}, "terrain_labels declares .*MAX_SCENE_CELLS"),
        "three_d": ({"heights": _npy_head((2, 2, 2)), "scene_json": scene_json},
                    r"heights must be a 2-D numeric array, the file declares shape \(2, 2, 2\)"),
        "text": ({"heights": _npy(np.array([["a", "b"], ["c", "d"]])), "scene_json": scene_json},
                 "heights must be a 2-D numeric array"),
        "not_npy": ({"heights": b"plain bytes, no .npy header", "scene_json": scene_json}, "not a readable scene"),
    }
    tracemalloc.start()
    try:
        for name, (members, message) in cases.items():
            path = _zip(tmp_path / f"{name}.npz", members)
            with pytest.raises(SceneFileError, match=message) as info:
                Scene.load(path)
            assert str(path) in str(info.value)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 20 * 2**20  # nothing of the declared size was allocated


@pytest.mark.parametrize(("value", "shown"), [(1e300, "1e+300"), (math.nan, "nan"), (-math.inf, "-inf"),
                                              (-(MAX_SCENE_HEIGHT + 1), "-1001.0")])
def test_loaded_heights_must_be_finite_and_plausible(tmp_path, value, shown):
    good = tmp_path / "good.npz"
    slalom_scene(num_walls=2).save(good)
    with np.load(good) as npz:
        arrays = {k: npz[k] for k in npz.files}
    arrays["heights"][3, 4] = value
    path = tmp_path / "tall.npz"
    np.savez_compressed(path, **arrays)
    with pytest.raises(SceneFileError, match=rf"heights must be finite with \|h\| <= 1000.0 m \(MAX_SCENE_HEIGHT\); "
                                             rf"1 cells are not, e.g. cell \(3, 4\) holds {re.escape(shown)}") as info:
        Scene.load(path)
    assert str(path) in str(info.value)


def test_heights_up_to_the_bound_load(tmp_path):
    heights = np.full((4, 5), MAX_SCENE_HEIGHT)
    heights[0, 0] = -MAX_SCENE_HEIGHT
    scene = Scene(heights, 0.5)
    scene.save(tmp_path / "high.npz")
    assert Scene.load(tmp_path / "high.npz") == scene


# --- validation ---------------------------------------------------------------------------------
@pytest.mark.parametrize("make,parameter", [
    (lambda: SlopePatchConfig(angle_deg=(10.0, 60.0)), "angle_deg"),
    (lambda: SlopePatchConfig(height=(1.0, 0.5)), "height"),
    (lambda: RoughPatchConfig(amplitude=(0.0, 0.9)), "amplitude"),
    (lambda: RoughPatchConfig(smoothing=-0.1), "smoothing"),
    (lambda: StairsPatchConfig(step_height=(0.05, 0.5)), "step_height"),
    (lambda: StairsPatchConfig(num_steps=(2.5, 4)), "num_steps"),
    (lambda: StairsPatchConfig(tread_depth=(0.01, 0.3)), "tread_depth"),
    (lambda: SceneConfig(size=(16.0, 1.0)), "size"),
    (lambda: SceneConfig(cell_size=0.0), "cell_size"),
    (lambda: SceneConfig(terrain_weights=(1.0, -1.0, 0.0, 0.0)), "terrain_weights"),
    (lambda: SceneConfig(num_landmarks=0), "num_landmarks"),
    (lambda: SceneConfig(landmark_names=("tree", "swing")), "landmark_names"),
    (lambda: SceneConfig(landmark_names=("tree", "tree", "car", "bench")), "landmark_names"),
    (lambda: SceneConfig(num_walls=(3, 1)), "num_walls"),
    (lambda: SceneConfig(ceiling_clearance=(0.1, 1.0)), "ceiling_clearance"),
    (lambda: SceneConfig(ball_speed=(1.0, 50.0)), "ball_speed"),
    (lambda: slalom_scene(gap_width=5.0), "gap_width"),
    (lambda: slalom_scene(num_walls=0), "num_walls"),
    (lambda: slalom_scene(run_up=0.5), "run_up"),
    (lambda: Box((0, 0), (0.0, 1.0)), "half_size"),
    (lambda: Box((0, 0), (1.0, 1.0), bottom=1.0, top=0.5), "top"),
    (lambda: Landmark("", (0, 0), 1.0, (0, 0, 1)), "name"),
    (lambda: WaypointLoop(((0, 0, 0),), speed=1.0), "waypoints"),
    (lambda: Scene(np.zeros((4, 4)), 0.1, landmarks=[Landmark("a", (0, 0), 1, (0, 0, 1))] * 2), "landmark names"),
    (lambda: Scene(np.full((4, 4), np.nan), 0.1), "heights"),
    (lambda: Scene(np.zeros((4, 4)), -0.1), "cell_size"),
    (lambda: slope_patch(SlopePatchConfig(), _rng(0), shape=(0, 5), cell_size=0.1), "shape"),
])
def test_invalid_parameters_are_named(make, parameter):
    with pytest.raises(ValueError, match=parameter):
        make()


def test_wrong_types_are_named():
    with pytest.raises(TypeError, match="slope"):
        SceneConfig(slope=StairsPatchConfig())
    with pytest.raises(TypeError, match="walls"):
        Scene(np.zeros((4, 4)), 0.1, walls=[Landmark("a", (0, 0), 1, (0, 0, 1))])
    with pytest.raises(TypeError, match="motion"):
        DynamicObstacle("ball", 0.2, motion=(0, 0, 0))


def test_a_landmark_off_the_grid_is_refused_on_load(tmp_path):
    good = tmp_path / "good.npz"
    slalom_scene(num_walls=2).save(good)

    def far_landmark(meta):
        meta["landmarks"][0]["center"] = [1e6, 0.0]
        return meta

    def far_marker(meta):
        meta["landmarks"][0]["display_position"] = [0.0, 0.0, 1e6]
        return meta

    for name, change, message in (("far.npz", far_landmark, "lies outside the scene's grid"),
                                  ("marker.npz", far_marker, "display_position")):
        _rewrite(good, tmp_path / name, change)
        with pytest.raises(SceneFileError, match=f"{name}: landmark .*{message}"):
            Scene.load(tmp_path / name)
    for seed in range(5):  # generated scenes keep their landmarks on the grid
        scene = generate_scene(SceneConfig(), np.random.default_rng(seed))
        scene.save(tmp_path / "random.npz")
        assert Scene.load(tmp_path / "random.npz") == scene
