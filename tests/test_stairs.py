"""Procedural staircases (``stairenv.world.stairs``): properties for any valid config, and the
MuJoCo slots that hold them (collisions must follow every new staircase)."""

from __future__ import annotations

import atexit
import math
import shutil
import tempfile

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.configuration import set_hypothesis_home_dir

import stairenv  # noqa: F401  (registers the envs)
from stairenv.world.stairs import Staircase, StairsConfig, StairsLayout, StairsSlots, generate_stairs

# Hypothesis writes its storage (example database, a constants cache filled while pytest
# collects) under ./.hypothesis by default: keep it in a temporary directory instead.
_HYPOTHESIS_HOME = tempfile.mkdtemp(prefix="stairenv-test-hypothesis-")
set_hypothesis_home_dir(_HYPOTHESIS_HOME)
atexit.register(shutil.rmtree, _HYPOTHESIS_HOME, ignore_errors=True)

STANDING = 0.885  # the standing root height the markers sit at
TOL = 1e-9


# --- strategies -------------------------------------------------------------------------------
def _range(lo: float, hi: float):
    finite = st.floats(lo, hi, allow_nan=False, allow_infinity=False)
    return st.tuples(finite, finite).map(lambda p: (min(p), max(p)))


@st.composite
def configs(draw):
    use_set = draw(st.booleans())
    n_lo = draw(st.integers(1, 30))
    n_hi = draw(st.integers(n_lo, 30))
    return StairsConfig(
        step_height=draw(_range(0.01, 0.40)),
        step_height_set=(
            tuple(draw(st.lists(st.floats(0.01, 0.40), min_size=1, max_size=5))) if use_set else None
        ),
        step_depth=draw(_range(0.15, 1.0)),
        step_width=draw(_range(0.5, 5.0)),
        num_steps=(n_lo, n_hi),
        landing_depth=draw(st.floats(1.0, 10.0)),
        distance=draw(_range(0.5, 20.0)),
        yaw=draw(_range(-2.0 * math.pi, 2.0 * math.pi)),
    )


@st.composite
def staircases(draw):
    return generate_stairs(draw(configs()), np.random.default_rng(draw(st.integers(0, 2**32 - 1))))


# database=None: no example database written into the working tree
SETTINGS = settings(max_examples=150, deadline=None, database=None)


def _within(value, bounds) -> bool:
    return bounds[0] <= value <= bounds[1]


# --- sampling -----------------------------------------------------------------------------------
@SETTINGS
@given(configs(), st.integers(0, 2**32 - 1))
def test_generate_stairs_within_ranges(config, seed):
    s = generate_stairs(config, np.random.default_rng(seed))
    if config.step_height_set is not None:
        assert s.step_height in config.step_height_set
    else:
        assert _within(s.step_height, config.step_height)
    assert _within(s.step_depth, config.step_depth)
    assert _within(s.width, config.step_width)
    assert isinstance(s.num_steps, int)
    assert config.num_steps[0] <= s.num_steps <= config.num_steps[1]
    assert s.landing_depth == config.landing_depth
    assert _within(s.distance, config.distance)
    assert _within(s.yaw, config.yaw)


@SETTINGS
@given(configs(), st.integers(0, 2**32 - 1))
def test_generate_stairs_same_seed_same_staircase(config, seed):
    a = generate_stairs(config, np.random.default_rng(seed))
    b = generate_stairs(config, np.random.default_rng(seed))
    assert a == b
    assert a.as_dict() == b.as_dict()


def test_generate_stairs_varies_with_seed_and_covers_num_steps():
    config = StairsConfig(num_steps=(3, 5))
    stairs = [generate_stairs(config, np.random.default_rng(seed)) for seed in range(60)]
    assert len({s.step_height for s in stairs}) == 60
    assert {s.num_steps for s in stairs} == {3, 4, 5}  # both ends of the integer range included
    test_set = StairsConfig(step_height_set=(0.05, 0.10, 0.15, 0.20))
    heights = {generate_stairs(test_set, np.random.default_rng(seed)).step_height for seed in range(60)}
    assert heights == {0.05, 0.10, 0.15, 0.20}


# --- geometry -------------------------------------------------------------------------------------
@SETTINGS
@given(staircases())
def test_local_boxes_are_contiguous_solid_blocks(s):
    centres, half = s.local_boxes()
    n, h, d = s.num_steps, s.step_height, s.step_depth
    assert centres.shape == half.shape == (n, 3)
    assert np.all(half > 0)
    bottom = centres[:, 2] - half[:, 2]
    top = centres[:, 2] + half[:, 2]
    front = centres[:, 0] - half[:, 0]
    back = centres[:, 0] + half[:, 0]
    np.testing.assert_allclose(bottom, 0.0, atol=TOL)                      # solid down to the ground
    np.testing.assert_allclose(top, h * np.arange(1, n + 1), rtol=TOL, atol=TOL)
    assert front[0] == pytest.approx(0.0, abs=TOL)                           # first riser at u = 0
    np.testing.assert_allclose(front[1:], back[:-1], atol=TOL)               # touching: no gap, no overlap
    np.testing.assert_allclose(2 * half[:-1, 0], d, rtol=TOL)               # treads are step_depth deep
    assert 2 * half[-1, 0] == pytest.approx(s.landing_depth, rel=TOL)        # the landing
    np.testing.assert_allclose(centres[:, 1], 0.0, atol=TOL)                 # centred across
    np.testing.assert_allclose(2 * half[:, 1], s.width, rtol=TOL)
    assert s.top_height == pytest.approx(n * h, rel=TOL)
    assert s.landing_start == pytest.approx((n - 1) * d, rel=TOL, abs=TOL)


@SETTINGS
@given(staircases())
def test_markers(s):
    centres, half = s.local_boxes()
    landing_front, landing_back = centres[-1, 0] - half[-1, 0], centres[-1, 0] + half[-1, 0]
    top = s.marker_top_local
    assert landing_front < top[0] < landing_back
    assert abs(top[1]) <= s.width / 2
    assert top[2] == pytest.approx(s.num_steps * s.step_height + STANDING, rel=TOL)
    np.testing.assert_allclose(s.marker_bottom_local, [0.0, 0.0, STANDING], atol=TOL)
    # world markers are the local ones through the staircase's pose
    c, sn = math.cos(s.yaw), math.sin(s.yaw)
    expected_top = [(s.distance + top[0]) * c - top[1] * sn, (s.distance + top[0]) * sn + top[1] * c, top[2]]
    np.testing.assert_allclose(s.marker_top, expected_top, atol=1e-9)
    np.testing.assert_allclose(s.marker_bottom, [s.distance * c, s.distance * sn, STANDING], atol=1e-9)


@SETTINGS
@given(staircases(), st.lists(st.tuples(*[st.floats(-30, 30)] * 3), min_size=1, max_size=8))
def test_frames_are_inverse_and_follow_yaw(s, points):
    pts = np.array(points)
    np.testing.assert_allclose(s.to_local(s.to_world(pts)), pts, atol=1e-9)
    np.testing.assert_allclose(s.to_world(s.to_local(pts)), pts, atol=1e-9)
    # the ascent axis points along the yaw, w to its left, z up
    o = s.to_world(np.zeros(3))
    np.testing.assert_allclose(s.to_world(np.array([1.0, 0.0, 0.0])) - o, [math.cos(s.yaw), math.sin(s.yaw), 0], atol=1e-12)
    np.testing.assert_allclose(s.to_world(np.array([0.0, 1.0, 0.0])) - o, [-math.sin(s.yaw), math.cos(s.yaw), 0], atol=1e-12)
    np.testing.assert_allclose(s.to_world(np.array([0.0, 0.0, 1.0])) - o, [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(o, [s.distance * math.cos(s.yaw), s.distance * math.sin(s.yaw), 0], atol=1e-12)
    # distances are preserved (a rotation)
    np.testing.assert_allclose(np.linalg.norm(s.to_local(pts) - s.to_local(np.zeros(3)), axis=-1),
                               np.linalg.norm(pts, axis=-1), rtol=1e-9, atol=1e-9)


@SETTINGS
@given(staircases())
def test_stairs_face_arena_centre(s):
    centre = s.to_local(np.zeros(3))
    assert centre[0] == pytest.approx(-s.distance, rel=1e-9)  # in front of the first riser
    assert centre[0] < 0
    assert abs(centre[1]) < 1e-9
    assert s.surface_height(np.zeros(2)) == 0.0


@SETTINGS
@given(staircases(), st.floats(0.05, 0.95), st.floats(-0.95, 0.95))
def test_surface_height(s, frac, across):
    n, h, d = s.num_steps, s.step_height, s.step_depth
    w = across * s.width / 2
    # the middle part of every tread, and of the landing
    local = [[(k - 1 + frac) * d, w, 0.0] for k in range(1, n)]
    local.append([(n - 1) * d + frac * s.landing_depth, w, 0.0])
    world = s.to_world(np.array(local))
    expected = h * np.arange(1, n + 1)
    np.testing.assert_allclose(s.surface_height(world), expected, rtol=1e-9)
    np.testing.assert_allclose(s.surface_height(world[:, :2]), expected, rtol=1e-9)  # (..., 2) input
    # off the stairs: in front, beside, beyond the landing
    end = (n - 1) * d + s.landing_depth
    off = s.to_world(np.array([
        [-0.05, w, 0.0],
        [-3.0, 0.0, 0.0],
        [frac * end, s.width / 2 + 0.05, 0.0],
        [frac * end, -s.width / 2 - 0.3, 0.0],
        [end + 0.05, 0.0, 0.0],
    ]))
    np.testing.assert_allclose(s.surface_height(off), 0.0, atol=0)


def test_surface_height_batched_shape():
    s = Staircase(step_height=0.1, step_depth=0.3, width=1.0, num_steps=4, landing_depth=2.0, yaw=0.0, distance=2.0)
    grid = np.zeros((3, 5, 2))
    grid[..., 0] = np.linspace(2.1, 2.1 + 4 * 0.3, 5)[None, :]
    out = s.surface_height(grid)
    assert out.shape == (3, 5)
    np.testing.assert_allclose(out[0], [0.1, 0.2, 0.3, 0.4, 0.4], rtol=1e-12)


# --- validation ----------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "kwargs, name",
    [
        (dict(step_height=(-0.1, 0.1)), "step_height"),
        (dict(step_height=(0.2, 0.1)), "step_height"),
        (dict(step_height=(0.05, 0.5)), "step_height"),
        (dict(step_height=(0.05,)), "step_height"),
        (dict(step_height_set=()), "step_height_set"),
        (dict(step_height_set=(0.1, -0.05)), "step_height_set"),
        (dict(step_height_set=(0.1, 0.9)), "step_height_set"),
        (dict(step_depth=(0.1, 0.3)), "step_depth"),
        (dict(step_depth=(0.4, 0.3)), "step_depth"),
        (dict(step_width=(1.0, 6.0)), "step_width"),
        (dict(step_width=(float("nan"), 2.0)), "step_width"),
        (dict(num_steps=(3, 5.5)), "num_steps"),
        (dict(num_steps=(0, 5)), "num_steps"),
        (dict(num_steps=(6, 5)), "num_steps"),
        (dict(num_steps=(3, 31)), "num_steps"),
        (dict(landing_depth=0.5), "landing_depth"),
        (dict(landing_depth=-2.0), "landing_depth"),
        (dict(distance=(0.1, 2.0)), "distance"),
        (dict(distance=(3.0, 2.0)), "distance"),
        (dict(yaw=(0.0, 7.0)), "yaw"),
        (dict(yaw="north"), "yaw"),
    ],
)
def test_invalid_config_names_parameter(kwargs, name):
    with pytest.raises(ValueError, match=rf"^{name}\b"):
        StairsConfig(**kwargs)


def test_config_accepts_lists_and_stores_tuples():
    c = StairsConfig(step_height=[0.1, 0.2], num_steps=[2, 4], step_height_set=[0.1, 0.2])
    assert c.step_height == (0.1, 0.2)
    assert c.num_steps == (2, 4)
    assert c.step_height_set == (0.1, 0.2)
    assert c.max_steps == 4


def test_layout_is_the_frame_transform_to_the_last_bit():
    """A batch's layout (what resets write into the models) holds, bit for bit, each staircase's treads and
    markers taken through ``to_world`` (the full rotation), its unused slots parked."""
    rng = np.random.default_rng(3)
    config = StairsConfig()
    stairs = [generate_stairs(config, rng) for _ in range(40)]
    layout = StairsLayout.of(stairs, config.max_steps)
    assert layout.centres.shape == layout.half.shape == (40, config.max_steps, 3)
    for k, s in enumerate(stairs):
        n = s.num_steps
        local, half = s.local_boxes()
        assert np.array_equal(layout.centres[k, :n], s.to_world(local))
        assert np.array_equal(layout.half[k, :n], half)
        assert np.array_equal(layout.marker_bottom[k], s.to_world(s.marker_bottom_local))
        assert np.array_equal(layout.marker_top[k], s.to_world(s.marker_top_local))
        assert np.array_equal(layout.origin[k], s.origin)
        assert (layout.centres[k, n:, 2] < 0).all() and (layout.half[k, n:] <= 0.01).all()
        assert np.array_equal(layout.quat[k], [math.cos(s.yaw / 2), 0.0, 0.0, math.sin(s.yaw / 2)])


    assert np.array_equal(layout.rbound, np.linalg.norm(layout.half, axis=-1))


# --- MuJoCo slots ---------------------------------------------------------------------------------
def _expected_world_boxes(s: Staircase):
    """Centres and half sizes of the treads in the world, by hand."""
    c, sn = math.cos(s.yaw), math.sin(s.yaw)
    centres, halves = [], []
    for k in range(1, s.num_steps + 1):
        depth = s.landing_depth if k == s.num_steps else s.step_depth
        u = (k - 1) * s.step_depth + depth / 2
        centres.append([(s.distance + u) * c, (s.distance + u) * sn, k * s.step_height / 2])
        halves.append([depth / 2, s.width / 2, k * s.step_height / 2])
    return np.array(centres), np.array(halves)


@pytest.fixture(scope="module")
def interlevel_env():
    env = gym.make("InterLevel-v0").unwrapped
    yield env
    env.close()


@pytest.mark.parametrize("seed", [0, 1, 2, 7])
def test_env_reset_writes_staircase_into_model(interlevel_env, seed):
    env = interlevel_env
    env.reset(seed=seed)
    s = env.stairs
    model, data = env.model, env.data
    max_steps = env.stairs_config.max_steps
    gids = [model.geom(f"stairs_step{i}").id for i in range(max_steps)]
    centres, halves = _expected_world_boxes(s)
    n = s.num_steps
    np.testing.assert_allclose(model.geom_size[gids[:n]], halves, rtol=1e-12)
    np.testing.assert_allclose(data.geom_xpos[gids[:n]], centres, atol=1e-9)
    # boxes are yawed with the staircase: their x axis is the ascent direction
    for g in gids[:n]:
        R = data.geom_xmat[g].reshape(3, 3)
        np.testing.assert_allclose(R[:, 0], [math.cos(s.yaw), math.sin(s.yaw), 0.0], atol=1e-9)
        np.testing.assert_allclose(R[:, 2], [0.0, 0.0, 1.0], atol=1e-9)
    # unused slots: entirely below the floor
    for g in gids[n:]:
        assert data.geom_xpos[g][2] + np.abs(model.geom_size[g]).max() < 0.0
    # markers
    np.testing.assert_allclose(data.xpos[model.body("stairs_marker_top").id], s.marker_top, atol=1e-9)
    np.testing.assert_allclose(data.xpos[model.body("stairs_marker_bottom").id], s.marker_bottom, atol=1e-9)


def test_env_reset_with_fewer_steps_parks_the_rest(interlevel_env):
    env = interlevel_env
    env.reset(seed=0)
    big = Staircase(step_height=0.15, step_depth=0.3, width=1.5, num_steps=10, landing_depth=2.0, yaw=1.0, distance=2.5)
    env.reset(seed=0, options={"stairs": big})
    small = Staircase(step_height=0.1, step_depth=0.3, width=1.5, num_steps=3, landing_depth=2.0, yaw=1.0, distance=2.5)
    env.reset(seed=0, options={"stairs": small})
    model, data = env.model, env.data
    for i in range(10):
        g = model.geom(f"stairs_step{i}").id
        top = data.geom_xpos[g][2] + model.geom_size[g][2]
        if i < 3:
            assert top == pytest.approx((i + 1) * 0.1, abs=1e-9)
        else:
            assert top < 0.0


def _tiny_world(max_steps: int, two_geoms: bool):
    spec = mujoco.MjSpec()
    spec.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.1])
    slots = StairsSlots(spec, max_steps=max_steps)
    body = spec.worldbody.add_body(name="probe", pos=[0, 0, 3])
    body.add_freejoint()
    if two_geoms:
        # a body with two geoms (like the humanoid's torso: belly and chest)
        body.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.05, 0, 0], pos=[0.05, 0, 0], mass=0.5)
        body.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.05, 0, 0], pos=[-0.05, 0, 0], mass=0.5)
    else:
        body.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.05, 0, 0], mass=1.0)
    model = spec.compile()
    data = mujoco.MjData(model)
    slots.bind(model)
    return model, data, slots


def _drop_on_tread(model, data, slots, s: Staircase, tread: int) -> float:
    """Drop the probe above the middle of tread ``tread`` (1-based), simulate 1 s; return its bottom z."""
    slots.place(model, s)
    mujoco.mj_resetData(model, data)
    u = (tread - 0.5) * s.step_depth
    c, sn = math.cos(s.yaw), math.sin(s.yaw)
    data.qpos[:3] = [(s.distance + u) * c - 0.1 * sn, (s.distance + u) * sn + 0.1 * c, tread * s.step_height + 0.3]
    mujoco.mj_forward(model, data)
    for _ in range(int(round(1.0 / model.opt.timestep))):
        mujoco.mj_step(model, data)
    return float(data.qpos[2] - 0.05)


TINY_STAIRS = [
    Staircase(step_height=0.10, step_depth=0.30, width=1.0, num_steps=4, landing_depth=1.5, yaw=0.7, distance=2.0),
    # then a different staircase with larger steps in the same compiled model
    Staircase(step_height=0.25, step_depth=0.50, width=1.8, num_steps=5, landing_depth=2.0, yaw=2.5, distance=3.0),
    Staircase(step_height=0.05, step_depth=0.20, width=0.8, num_steps=3, landing_depth=1.0, yaw=-1.2, distance=1.0),
]


def test_sphere_rests_on_tread_after_replacing_staircase():
    model, data, slots = _tiny_world(5, two_geoms=False)
    for s in TINY_STAIRS:
        bottom = _drop_on_tread(model, data, slots, s, tread=2)
        assert bottom == pytest.approx(2 * s.step_height, abs=0.01), s


def test_two_geom_body_rests_on_tread_after_replacing_staircase():
    """Multi-geom bodies collide through the step bodies' bounding boxes, which place() must resize."""
    model, data, slots = _tiny_world(5, two_geoms=True)
    for s in TINY_STAIRS:
        bottom = _drop_on_tread(model, data, slots, s, tread=2)
        assert bottom == pytest.approx(2 * s.step_height, abs=0.01), s


def test_place_rejects_too_many_steps_and_unbound():
    spec = mujoco.MjSpec()
    slots = StairsSlots(spec, max_steps=3)
    model = spec.compile()
    with pytest.raises(RuntimeError, match="bind"):
        slots.place(model, TINY_STAIRS[0])
    slots.bind(model)
    with pytest.raises(ValueError, match="at most 3"):
        slots.place(model, TINY_STAIRS[0])  # 4 steps


def _torso_step_contacts(env, stairs: Staircase, u: float, w: float) -> set[str]:
    """Reset to ``stairs`` and stand the humanoid with its belly sunk 0.2 m into the tread under
    (u, w) (stairs frame); return the names of the step geoms touching the belly or chest."""
    env.reset(seed=0, options={"stairs": stairs})
    model, data = env.model, env.data
    surface = float(stairs.surface_height(stairs.to_world(np.array([u, w, 0.0]))))
    c, sn = math.cos(stairs.yaw), math.sin(stairs.yaw)
    root = env._idx.qpos_root
    # belly capsule: from 0.106 to 0.256 m above the pelvis, radius 0.085
    pelvis_z = surface - 0.2 - 0.106 + 0.085
    data.qpos[root] = [(stairs.distance + u) * c - w * sn, (stairs.distance + u) * sn + w * c, pelvis_z,
                       math.cos(stairs.yaw / 2), 0.0, 0.0, math.sin(stairs.yaw / 2)]
    mujoco.mj_forward(model, data)
    torso = {model.geom("belly").id, model.geom("chest").id}
    hits = set()
    for con in data.contact[: data.ncon]:
        pair = {int(con.geom1), int(con.geom2)}
        if pair & torso:
            other = (pair - torso).pop() if len(pair - torso) == 1 else None
            if other is not None and model.geom(other).name.startswith("stairs_step"):
                hits.add(model.geom(other).name)
    return hits


def test_humanoid_torso_collides_with_landing_off_centre(interlevel_env):
    s = Staircase(step_height=0.2, step_depth=0.4, width=2.0, num_steps=8, landing_depth=2.0, yaw=0.4, distance=2.0)
    landing_centre = (s.num_steps - 1) * s.step_depth + s.landing_depth / 2
    assert "stairs_step7" in _torso_step_contacts(interlevel_env, s, landing_centre + 0.5, 0.4)


def test_a_copy_of_an_env_writes_its_staircases_into_its_own_model():
    """``StairsSlots`` looks its model's fields up once; a copy of the env (``replicate``, as a device back-end's
    batched env makes its worlds) writes its staircases into its own model, and the original into its own."""
    env = gym.make("InterLevel-v0").unwrapped
    env.reset(seed=1)
    clone = env.replicate()
    clone.reset(seed=2)
    env.reset(seed=3)
    for world in (env, clone):
        ids = [world.model.geom(f"stairs_step{i}").id for i in range(world.stairs.num_steps)]
        _, halves = _expected_world_boxes(world.stairs)
        np.testing.assert_allclose(world.model.geom_size[ids], halves, rtol=1e-12)
        np.testing.assert_allclose(world.model.geom_rbound[ids], np.linalg.norm(halves, axis=1), rtol=1e-12)
    assert env.stairs != clone.stairs
    env.close()
