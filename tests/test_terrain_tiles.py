"""PlaMo's terrain as tiles (``stairenv.world.tiles``): the collision model holds the heights the task reads."""

from __future__ import annotations

import copy

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import stairenv  # noqa: F401  (registers the envs)
from stairenv.world.scenes import SceneConfig, generate_scene
from stairenv.world.scenes.patches import StairsPatchConfig, generate_patch, stairs_patch_shape
from stairenv.world.terrain import terrain_heights, terrain_tiles
from stairenv.world.tiles import FLAT, FOCUS_RADIUS, PARK_DEPTH, STAIRS, TILE_KINDS

KINDS = ("flat", "slope", "rough", "stairs", "mixed")


def ray_heights(model, data, points, skip=()):
    """The top of the collision geometry under each (x, y) (a ray from 5 m above; geoms named with any of
    ``skip`` are looked through). Cast a hair off the point: MuJoCo's ray misses a height field exactly on
    a grid line."""
    out = []
    geomid = np.zeros(1, dtype=np.int32)
    for x, y in points:
        start = np.array([x + 1e-7, y + 1.3e-7, 5.0])
        while True:
            dist = mujoco.mj_ray(model, data, start, np.array([0.0, 0.0, -1.0]), None, 1, -1, geomid)
            name = model.geom(geomid[0]).name if dist >= 0 else ""
            if not any(word in name for word in skip):
                break
            start[2] -= dist + 1e-6
        out.append(start[2] - dist)
    return np.array(out)


def held_points(slots, tiles, every=3):
    """For each tile with a slot: focus on its centre (it comes into one), and the sample points of it."""
    for p in range(tiles.shape[0]):
        for q in range(tiles.shape[1]):
            x0, x1, y0, y1 = tiles.tile_bounds(p, q)
            yield (p, q), ((x0 + x1) / 2, (y0 + y1) / 2), [
                (i, j) for i in range(tiles.row_edges[p], tiles.row_edges[p + 1], every)
                for j in range(tiles.col_edges[q], tiles.col_edges[q + 1], every)]


@pytest.mark.parametrize("kind", KINDS)
def test_same_seed_same_terrain_and_the_heights_of_terrain_heights(kind):
    a = terrain_tiles(kind, np.random.default_rng(3))
    b = terrain_tiles(kind, np.random.default_rng(3))
    np.testing.assert_array_equal(a.heights, terrain_heights(kind, np.random.default_rng(3)))
    np.testing.assert_array_equal(a.heights, b.heights)
    np.testing.assert_array_equal(a.kinds, b.kinds)
    assert a.boxes.keys() == b.boxes.keys()
    for key in a.boxes:
        for x, y in zip(a.boxes[key], b.boxes[key]):
            np.testing.assert_array_equal(x, y)
    if kind != "flat":
        assert not np.array_equal(a.heights, terrain_tiles(kind, np.random.default_rng(4)).heights)
    expected = {"mixed": set(TILE_KINDS)}.get(kind, {kind})
    assert {TILE_KINDS[k] for k in np.unique(a.kinds)} <= expected


def test_stairs_shape_draws_what_stairs_patch_draws_and_its_boxes_hold_the_samples():
    config = StairsPatchConfig()
    for seed in range(20):
        heights, shape = stairs_patch_shape(config, np.random.default_rng(seed), shape=(40, 40), cell_size=0.1)
        np.testing.assert_array_equal(heights, generate_patch(config, np.random.default_rng(seed), shape=(40, 40),
                                                              cell_size=0.1))
        # the highest level box over each cell centre is the cell's height
        x = (np.arange(40) + 0.5 - 20) * 0.1
        xx, yy = np.meshgrid(x, x)
        yaw = shape.footprint.yaw
        u = xx * np.cos(yaw) + yy * np.sin(yaw)
        v = -xx * np.sin(yaw) + yy * np.cos(yaw)
        top = np.zeros((40, 40))
        for half_long, half_short, level_top in shape.levels():
            inside = (np.abs(u) <= half_long + 1e-12) & (np.abs(v) <= half_short + 1e-12)
            top = np.where(inside, np.maximum(top, level_top), top)
        np.testing.assert_allclose(top, heights, atol=1e-12)


@pytest.mark.parametrize("kind", KINDS)
def test_the_collision_geometry_holds_the_heights_the_task_reads(kind):
    """At sample points of every tile, the top of the collision geometry (the plane, the slot's boxes or
    height field) is the task's ground height (``ground_height``, the heights' bilinear reading)."""
    env = gym.make("PlaMo-v0", terrain=kind)
    env.reset(seed=2)
    u = env.unwrapped
    u.data.qpos[:2] = 500.0    # the character out of the rays' way
    slots, tiles = u._terrain_slots, u._tiles
    worst, checked = 0.0, 0
    for tile, centre, samples in held_points(slots, tiles):
        if slots is not None:
            slots.focus(u.model, centre)
            assert tiles.kinds[tile] == FLAT or tile in slots.held()
        mujoco.mj_kinematics(u.model, u.data)
        points = np.array([(tiles.origin[0] + j * tiles.cell_size, tiles.origin[1] + i * tiles.cell_size)
                           for i, j in samples])
        got = ray_heights(u.model, u.data, points)
        expected = u.ground_height(points)
        np.testing.assert_allclose(expected, [tiles.heights[i, j] for i, j in samples], atol=1e-12)
        worst = max(worst, float(np.abs(got - expected).max()))
        checked += len(points)
    assert checked > 2000 and worst < 1e-6, worst
    env.close()


def test_a_scene_s_collision_geometry_holds_its_heights():
    """The same for PlaMoScene's generated scenes (stairs, slopes, rough patches), against ``Scene.height_at``."""
    env = gym.make("PlaMoScene-v0")
    for seed in (0, 1):
        env.reset(seed=seed)
        u = env.unwrapped
        slots, tiles = u._terrain_slots, u._terrain_slots.tiles
        assert tiles is u.scene.tiles and tiles.kinds.size == 16
        u.data.qpos[:2] = 500.0
        worst = 0.0
        for _, centre, samples in held_points(slots, tiles, every=5):
            slots.focus(u.model, centre)
            mujoco.mj_kinematics(u.model, u.data)
            points = np.array([(tiles.origin[0] + j * tiles.cell_size, tiles.origin[1] + i * tiles.cell_size)
                               for i, j in samples])
            got = ray_heights(u.model, u.data, points, skip=("wall", "ceiling", "obstacle", "landmark"))
            worst = max(worst, float(np.abs(got - u.scene.height_at(points)).max()))
        assert worst < 1e-6, worst
    env.close()


@pytest.mark.parametrize("kind", ["stairs", "slope", "rough"])
def test_contacts_are_found_on_every_held_tile(kind):
    """A small sphere pressed 1 cm into the ground at sample points of the held tiles touches the terrain:
    the slots' bounding volumes, refitted at every placement, let MuJoCo's collision reach every geom."""
    spec = mujoco.MjSpec()
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.1])
    from stairenv.world.terrain import MAX_STAIRS_LEVELS
    from stairenv.world.tiles import TerrainSlots
    tiles = terrain_tiles(kind, np.random.default_rng(7))
    slots = TerrainSlots(spec, tiles.tile_samples, tiles.cell_size, MAX_STAIRS_LEVELS, 4)
    ball = spec.worldbody.add_body(name="ball")
    ball.add_freejoint()
    ball.add_geom(name="ball", type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.02, 0, 0])
    model = spec.compile()
    data = mujoco.MjData(model)
    slots.bind(model)
    slots.set_terrain(model, tiles)
    terrain_geoms = set(slots.geom_ids().tolist()) | {0}
    rng = np.random.default_rng(0)
    for (p, q), centre, samples in held_points(slots, tiles, every=1):
        slots.focus(model, centre)
        for k in rng.choice(len(samples), 20, replace=False):
            i, j = samples[k]
            data.qpos[:3] = (tiles.origin[0] + j * tiles.cell_size, tiles.origin[1] + i * tiles.cell_size,
                             tiles.heights[i, j] + 0.01)
            mujoco.mj_forward(model, data)
            touched = {int(g) for con in data.contact[:data.ncon] for g in con.geom} - {model.geom("ball").id}
            assert data.ncon and touched <= terrain_geoms, (p, q, i, j)
            assert min(con.dist for con in data.contact[:data.ncon]) < -0.005


def test_focus_holds_the_tiles_within_reach_and_parks_the_rest_below_ground():
    env = gym.make("PlaMo-v0", terrain="mixed")
    env.reset(seed=5)
    u = env.unwrapped
    slots, tiles = u._terrain_slots, u._tiles
    rng = np.random.default_rng(0)
    for _ in range(200):
        xy = rng.uniform(-8.5, 8.5, 2)
        slots.focus(u.model, xy)
        held = set(slots.held())
        assert set(tiles.tiles_near(xy, FOCUS_RADIUS)) <= held
        mujoco.mj_kinematics(u.model, u.data)
        for s, tile in enumerate(slots.held()):
            box_geoms = slots._ids["boxes"][s]
            used = len(tiles.boxes[tile][0]) if tile is not None and tiles.kinds[tile] == STAIRS else 0
            assert (u.data.geom_xpos[box_geoms[used:], 2] <= -PARK_DEPTH + 1e-9).all()
    assert tiles.max_tiles_near(FOCUS_RADIUS) == slots.slots == 4
    # a copy of the env (a batched env's worlds) has slots of its own
    clone = copy.deepcopy(u)
    clone._terrain_slots.focus(clone.model, (-7.0, -7.0))
    assert clone._terrain_slots.held() != slots.held() or slots.held() == clone._terrain_slots.held()
    env.close()


def test_walking_off_a_tile_brings_the_next_one_in():
    """The env's own step brings tiles in as the root moves (``_before_physics``): pushed across the terrain,
    the character never lacks the tiles within reach."""
    env = gym.make("PlaMo-v0", terrain="stairs", max_episode_steps=10**6, max_xy_error=100.0, min_head_height=0.0)
    env.reset(seed=0)
    u = env.unwrapped
    for step in range(120):
        u.data.qvel[:2] = (3.0, 1.0)    # pushed along
        env.step(np.zeros(28))
        assert set(u._tiles.tiles_near(u.data.qpos[:2], FOCUS_RADIUS - 0.2)) <= set(u._terrain_slots.held())
    env.close()


def test_flat_terrain_has_no_slots_and_the_ground_plane_at_zero():
    env = gym.make("PlaMo-v0", terrain="flat")
    env.reset(seed=0)
    u = env.unwrapped
    assert u._terrain_slots.slots == 0 and u.model.nhfield == 0
    floor = u.model.geom("floor")
    assert floor.pos[2] == 0.0
    env.close()


def test_rendering_draws_the_whole_terrain():
    env = gym.make("PlaMo-v0", terrain="slope", render_mode="rgb_array", width=96, height=72)
    env.reset(seed=0)
    u = env.unwrapped
    assert u._terrain_view is not None
    hfield = u.model.hfield(u._terrain_view.name)
    assert hfield.nrow[0] == u._tiles.heights.shape[0]
    frame = env.render()
    assert frame.shape == (72, 96, 3) and frame.std() > 5
    env.close()


def test_a_generated_scene_carries_its_tiles_and_the_same_seed_the_same_scene():
    a = generate_scene(SceneConfig(), np.random.default_rng(11))
    b = generate_scene(SceneConfig(), np.random.default_rng(11))
    assert a == b and a.tiles is not None
    np.testing.assert_array_equal(a.tiles.heights, a.heights)
    np.testing.assert_array_equal(a.tiles.kinds, b.tiles.kinds)
    assert a.tiles.boxes.keys() == b.tiles.boxes.keys()
    labels = a.terrain_labels
    for p in range(a.tiles.shape[0]):
        for q in range(a.tiles.shape[1]):
            r0, c0 = a.tiles.row_edges[p], a.tiles.col_edges[q]
            assert labels[r0, c0] == a.tiles.kinds[p, q]


def test_a_scene_s_compiled_ground_reading_is_scene_height_at():
    """PlaMoScene reads its heightmap compiled (``terrain.clamped_bilinear_at``): ``Scene.height_at``'s values
    (``map_coordinates`` of order 1, the border continued) to 1e-15 m, inside the grid and beyond it."""
    env = gym.make("PlaMoScene-v0")
    env.reset(seed=3)
    u = env.unwrapped
    xy = np.random.default_rng(0).uniform(-9.0, 9.0, (20000, 2))
    np.testing.assert_allclose(u.ground_height(xy), u.scene.height_at(xy), rtol=0, atol=1e-15)
    heightmap = np.empty(u.heightmap_size ** 2)
    state = u._read_state()
    root, head = state.body_pos[0, 0], state.body_pos[0, 2]
    under_root, under_head = u._terrain_samples(heightmap, root, 0.6, 0.8, head)
    from stairenv.tasks.plamo import heightmap_offsets
    gx, gy = heightmap_offsets(u.heightmap_size, u.heightmap_extent)
    points = np.column_stack((root[0] + 0.6 * gx - 0.8 * gy, root[1] + 0.8 * gx + 0.6 * gy))
    np.testing.assert_allclose(heightmap, u.scene.height_at(points) - root[2], rtol=0, atol=1e-15)
    assert under_root == pytest.approx(float(u.scene.height_at(root[:2])), abs=1e-15)
    assert under_head == pytest.approx(float(u.scene.height_at(head[:2])), abs=1e-15)
    env.close()


def test_a_ball_s_position_at_one_time_has_the_bits_of_the_array_form():
    """``WaypointLoop.position`` of one float time (every step of PlaMoScene) runs on Python floats: the same
    bits as the numpy form over an array of times."""
    for seed in range(4):
        scene = generate_scene(SceneConfig(), np.random.default_rng(seed))
        for obstacle in scene.dynamic_obstacles:
            times = np.random.default_rng(seed).uniform(0.0, 300.0, 2000)
            one_by_one = np.array([obstacle.position(float(t)) for t in times])
            np.testing.assert_array_equal(one_by_one, obstacle.position(times))
