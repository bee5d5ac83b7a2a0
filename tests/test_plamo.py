"""PlaMo-v0: terrain height field, random path generator, observation layout, reward r^tau, episode logic."""

from __future__ import annotations

import math

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import stairenv  # noqa: F401
from stairenv.environments.plamo import PlaMoEnv
from stairenv.humanoid import HumanoidIndices
from stairenv.tasks import plamo as task
from stairenv.world.terrain import MAX_STAIRS_LEVELS, bilinear_height, terrain_heights, terrain_tiles
from stairenv.world.tiles import TerrainSlots


@pytest.mark.parametrize("env_id", ["PlaMo-v0", "PlaMoNaivePaths-v0"])
def test_check_env_and_determinism(env_id):
    env = gym.make(env_id)
    check_env(env.unwrapped, skip_render_check=True)
    runs = []
    for _ in range(2):
        obs, _ = env.reset(seed=5)
        trace = [obs]
        rng = np.random.default_rng(0)
        for _ in range(40):
            obs, reward, terminated, truncated, _ = env.step(rng.uniform(-1, 1, 28))
            trace.append(np.r_[obs, reward])
            if terminated or truncated:
                trace.append(env.reset()[0])
        runs.append(np.concatenate(trace))
    np.testing.assert_array_equal(runs[0], runs[1])


def test_observation_layout_on_flat_ground():
    env = gym.make("PlaMo-v0", terrain="flat").unwrapped
    obs, _ = env.reset(seed=1)
    s = env.observation_structure
    assert [v.stop - v.start for v in s.values()] == [113, 256, 30]
    pelvis = HumanoidIndices.from_model(env.model).pelvis_id
    root = env.data.xpos[pelvis]
    np.testing.assert_allclose(obs[s["heightmap"]], -root[2])  # flat: every sample is the floor
    assert obs[0] == pytest.approx(root[2])  # root height above the (zero) terrain
    head, _ = env._head()
    first = env.path.at(0.5) - head
    yaw = math.atan2(env.data.xmat[pelvis][3], env.data.xmat[pelvis][0])
    c, sn = math.cos(yaw), math.sin(yaw)
    np.testing.assert_allclose(obs[s["path"]][:3], [c * first[0] + sn * first[1], -sn * first[0] + c * first[1],
                                                    first[2]], atol=1e-9)


def _path(config, seed=0, duration=30.0):
    return task.random_head_path(config, np.random.default_rng(seed), duration, np.zeros(2), 0.3,
                                 lambda xy: np.zeros(len(xy)), arena_half=7.0)


def test_coupled_paths_respect_the_height_speed_envelope():
    for seed in range(5):
        path = _path(task.PathConfig(coupled=True), seed)
        assert np.all(path.speed <= task.coupled_max_speed(path.head) + 1e-9)
        assert path.head.min() >= 0.4 - 1e-9 and path.head.max() <= 1.47 + 1e-9
        assert np.all(np.abs(path.points[:, :2]) <= 7.0 + 5.0 * path.dt)
        # Smooth: head height changes by bounded amounts per sample.
        assert np.abs(np.diff(path.head)).max() < 0.2
        # Consecutive points are as far apart as the requested speed says.
        step = np.linalg.norm(np.diff(path.points[:, :2], axis=0), axis=1)
        np.testing.assert_allclose(step, path.speed[:-1] * path.dt, atol=1e-9)


def test_naive_paths_break_the_envelope():
    over = [np.any(p.speed > task.coupled_max_speed(p.head) + 0.5)
            for p in (_path(task.PathConfig(coupled=False), s) for s in range(5))]
    assert any(over)


def test_coupled_max_speed_formula():
    np.testing.assert_allclose(task.coupled_max_speed([0.4, 0.8, 1.2, 1.47]), [1.0, 3.0, 5.0, 5.0])


def test_the_locomotion_table_obeys_the_height_speed_coupling():
    from stairenv.planning.locomotion import LOCOMOTIONS

    for loc in LOCOMOTIONS.values():
        heads = np.linspace(loc.head_min, loc.head_height, 50)
        assert np.all(loc.speed_max <= task.coupled_max_speed(heads) + 1e-9), loc.name


def test_locomotion_restricts_paths():
    env = gym.make("PlaMo-v0", locomotion="crawl").unwrapped
    env.reset(seed=0)
    assert env.path.head.min() >= 0.3 - 1e-9 and env.path.head.max() <= 0.5 + 1e-9
    assert env.path.speed.max() <= 1.0 + 1e-9
    with pytest.raises(ValueError, match="locomotion"):
        PlaMoEnv(locomotion="moonwalk")


def test_path_reward_terms_by_hand():
    target = np.array([1.0, 2.0, 1.0])
    head = np.array([1.3, 1.6, 0.8])
    terms = task.path_reward_terms(target, head, target_yaw=0.5, target_pitch=0.1, head_yaw=0.2,
                                   head_pitch=-0.1, max_body_z=1.0)
    expected = [math.exp(-2 * (0.09 + 0.16)), math.exp(-10 * 0.04), math.exp(-20 * (0.09 + 0.04)), 0.1 * (0.8 - 1.0)]
    np.testing.assert_allclose(terms, expected)
    # Yaw differences wrap around.
    wrapped = task.path_reward_terms(target, head, math.pi - 0.05, 0.0, -math.pi + 0.05, 0.0, 0.8)
    assert wrapped[2] == pytest.approx(math.exp(-20 * 0.01))


def test_reward_terms_in_info_sum_to_the_reward():
    env = gym.make("PlaMo-v0")
    env.reset(seed=2)
    for _ in range(10):
        _, reward, terminated, truncated, info = env.step(np.zeros(28))
        assert reward == pytest.approx(sum(info[k] for k in task.REWARD_TERMS))
        assert info["reward_body"] <= 0.0
        if terminated or truncated:
            break


def test_losing_the_path_terminates():
    env = gym.make("PlaMo-v0", terrain="flat", max_xy_error=0.5)
    env.reset(seed=0)
    u = env.unwrapped
    u.data.qpos[:2] += 3.0  # teleport away from the path
    mujoco.mj_forward(u.model, u.data)
    _, _, terminated, _, info = env.step(np.zeros(28))
    assert terminated and info["xy_error"] > 0.5
    assert info["off_path"] and not info["fell"]  # the reason is in info


def test_a_fall_terminates_with_its_reason():
    env = gym.make("PlaMo-v0", terrain="flat", max_xy_error=50.0)  # the path cannot be lost here
    env.reset(seed=0)
    for _ in range(300):  # the zero policy collapses within a few seconds
        _, _, terminated, truncated, info = env.step(np.zeros(28))
        if terminated or truncated:
            break
    assert terminated and info["fell"] and not info["off_path"]


def test_unstable_physics_truncates():
    env = gym.make("PlaMo-v0")
    env.reset(seed=0)
    env.unwrapped.data.qvel[:] = 1e12
    with pytest.warns(UserWarning, match="unstable"):
        obs, reward, terminated, truncated, info = env.step(np.zeros(28))
    assert truncated and not terminated and info["physics_unstable"] and np.isfinite(obs).all()


@pytest.mark.parametrize("kind", ["stairs", "slope", "mixed"])
def test_terrain_tiles_hold_the_height_array(kind):
    """A sphere dropped on the terrain's tiles (the plane at 0, stairs boxes, slope and rough height fields,
    brought in under it by ``focus``) rests at the array's height there."""
    spec = mujoco.MjSpec()
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.1])
    tiles = terrain_tiles(kind, np.random.default_rng(4))
    slots = TerrainSlots(spec, tiles.tile_samples, tiles.cell_size, MAX_STAIRS_LEVELS, 4)
    body = spec.worldbody.add_body(name="ball", pos=[0, 0, 3])
    body.add_freejoint()
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.05, 0, 0])
    model = spec.compile()
    data = mujoco.MjData(model)
    slots.bind(model)
    slots.set_terrain(model, tiles)
    heights = tiles.heights
    rng = np.random.default_rng(4)
    # Probe flat spots (treads, plateaus, floor): where the 3x3 neighbourhood is level.
    n = heights.shape[0]
    checked = 0
    for i, j in rng.integers(2, n - 2, (400, 2)):
        if np.ptp(heights[i - 1:i + 2, j - 1:j + 2]) > 1e-9 or checked >= 6:
            continue
        xy = np.array([-8.0 + 0.1 * j, -8.0 + 0.1 * i])
        mujoco.mj_resetData(model, data)
        data.qpos[:3] = [*xy, heights[i, j] + 0.3]
        for _ in range(300):
            slots.focus(model, data.qpos[:2])
            mujoco.mj_step(model, data)
        assert data.qpos[2] - 0.05 == pytest.approx(bilinear_height(heights, 16.0, xy), abs=0.01)
        checked += 1
    assert checked >= 3


def test_bad_keywords():
    for kwargs, name in [({"terrain": "lava"}, "terrain"), ({"path_generator": "smart"}, "path_generator"),
                         ({"heightmap_size": 0}, "heightmap_size"), ({"max_xy_error": 0}, "max_xy_error")]:
        with pytest.raises(ValueError, match=name):
            PlaMoEnv(**kwargs)


def test_rgb_render_shows_the_terrain():
    env = gym.make("PlaMo-v0", render_mode="rgb_array", width=160, height=120)
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (120, 160, 3) and frame.std() > 5
    env.close()


def test_tracking_error_table(tmp_path):
    from stairenv.evaluation.plamo import format_rows, tracking_errors, write_rows
    from stairenv.evaluation.policies import ZeroPolicy

    env = gym.make("PlaMo-v0")
    rows = tracking_errors(ZeroPolicy(env.action_space), terrains=("flat", "stairs"), locomotions=("walk",),
                           episodes=1, max_episode_steps=20)
    assert [(r["terrain"], r["locomotion"]) for r in rows] == [("flat", "walk"), ("stairs", "walk")]
    assert all(r["steps"] > 0 and r["xy_error_m"] >= 0 and r["z_error_m"] >= 0 for r in rows)
    assert rows[1]["paper_xy_error_m"] == 0.39
    assert "stairs" in format_rows(rows)
    write_rows(rows, tmp_path / "t.csv", tmp_path / "t.json")
    assert (tmp_path / "t.csv").read_text().startswith("terrain,locomotion")


def _elementwise(obs):
    """A batch-capable policy computed element by element, so batch and single calls round alike."""
    return np.tanh(0.05 * np.asarray(obs)[..., 40:68])


def test_table2_on_side_by_side_worlds_equals_one_after_another():
    from stairenv.evaluation.plamo import evaluate

    # 5 episodes a cell on 3 worlds: worlds take new episodes as theirs end, one idles at the end
    kwargs = dict(terrains=("flat", "stairs"), locomotions=("walk",), episodes=5, seed=21, max_episode_steps=60,
                  push_speed=2.5)
    one = evaluate(_elementwise, **kwargs)
    side = evaluate(_elementwise, num_envs=3, **kwargs)
    assert side.details == one.details and side.rows == one.rows
    assert [e.index for e in side.details] == [0, 1, 2, 3, 4] * 2
    assert len({e.steps for e in one.details}) > 2     # episodes end at different steps
    assert side.meta["settings"]["num_envs"] == 3 and one.meta["settings"]["num_envs"] == 1
    serial = evaluate(_elementwise, num_envs=2, physics="serial", **kwargs)
    assert serial.rows == one.rows
    with pytest.raises(ValueError, match="num_envs"):
        evaluate(_elementwise, num_envs=0, **kwargs)
    with pytest.raises(ValueError, match="physics"):
        evaluate(_elementwise, physics="warp", **kwargs)    # one world after another has no back-end to choose


def test_reference_init_on_terrain():
    env = gym.make("PlaMo-v0", terrain="stairs", init="reference")
    u = env.unwrapped
    from stairenv.humanoid.kinematics import humanoid_geoms

    for seed in range(3):
        _, info = env.reset(seed=seed)
        assert info["reference_start"]
        mujoco.mj_forward(u.model, u.data)
        # Nothing of the body starts inside the terrain.
        geoms = set(humanoid_geoms(u.model, u._idx).tolist())
        for contact in u.data.contact[: u.data.ncon]:
            if {int(contact.geom1), int(contact.geom2)} & geoms:
                assert contact.dist > -0.005


def test_speed_scale_scales_every_speed_and_nothing_else():
    ground = lambda xy: np.zeros(len(xy))  # noqa: E731
    full = task.random_head_path(task.PathConfig(), np.random.default_rng(3), 30.0, np.zeros(2), 0.0, ground)
    slow = task.random_head_path(task.PathConfig(speed_scale=0.25), np.random.default_rng(3), 30.0, np.zeros(2), 0.0,
                                 ground)
    np.testing.assert_array_equal(slow.head, full.head)
    np.testing.assert_allclose(slow.speed, 0.25 * full.speed)
    assert full.speed.max() > 0.5
    with pytest.raises(ValueError, match="speed_scale"):
        task.PathConfig(speed_scale=0.0)


def _run(env, steps):
    for _ in range(steps):
        env.step(np.zeros(28))


def test_speed_curriculum_moves_with_the_episode_outcome():
    # a 1 s episode that nothing ends early (no off-path or fall termination): lasting it is a success
    env = PlaMoEnv(speed_levels=4, episode_seconds=1.0, max_xy_error=100.0, min_head_height=0.0, terrain="flat")
    env.reset(seed=0)
    assert env.curriculum_level == 0
    assert env.episode_path_config().speed_scale == 0.25
    assert np.all(env.path.speed <= 0.25 * task.coupled_max_speed(env.path.head) + 1e-12)
    _run(env, round(1.0 / env.dt))
    env.reset()
    assert env.curriculum_level == 1                      # lasted the episode: up
    _run(env, 3)
    env.reset(options={"episode_cut": True})
    assert env.curriculum_level == 1                      # cut by a trainer: not judged
    env.reset()
    assert env.curriculum_level == 1                      # no step taken: not judged
    env.max_xy_error = 1e-6                               # now every step loses the path at once
    env.curriculum_level = 3
    env.reset()
    env.step(np.zeros(28))
    env.reset()
    assert env.curriculum_level == 2                      # ended early before half the episode: down
    assert env.episode_path_config().speed_scale == 0.75


def test_speed_levels_off_leaves_the_paper_paths():
    env = PlaMoEnv()
    env.reset(seed=0)
    assert env.curriculum_level is None and env.episode_path_config() is env.path_config
    with pytest.raises(ValueError, match="speed_levels"):
        PlaMoEnv(speed_levels=-1)
    with pytest.raises(ValueError, match="speed_levels"):
        PlaMoEnv(speed_levels=2.5)
    with pytest.raises(TypeError, match="speed_levels"):
        PlaMoEnv(speed_levels="4")


def test_speed_curriculum_per_locomotion_scales_each_sample_and_judges_the_locomotions_asked_for():
    from stairenv.planning.locomotion import locomotion_labels

    env = PlaMoEnv(speed_levels=4, speed_levels_by_locomotion=True, episode_seconds=3.0, max_xy_error=100.0,
                   min_head_height=0.0, terrain="flat")
    env.reset(seed=3)
    names = env.curriculum_level_names
    assert names == ("crawl", "crouch-walk", "walk", "run", "sprint") and env.curriculum_level == (0,) * 5
    assert env.episode_path_config() is env.path_config     # no per-world scale
    env.curriculum_level = (3, 0, 3, 1, 0)                  # crawl and walk at the paper's speeds
    env.reset(options={"episode_cut": True})
    assert env.curriculum_level == (3, 0, 3, 1, 0)
    scale = np.array([1.0, 0.25, 1.0, 0.5, 0.25])[env._speed_labels]
    drawn = env.path.speed / scale                          # the speeds before scaling
    assert np.all(drawn <= task.coupled_max_speed(env.path.head) + 1e-9)
    np.testing.assert_array_equal(env._speed_labels, locomotion_labels(env.path.head, drawn, names))
    assert len(set(env._speed_labels.tolist())) >= 2        # (this seed's path asks for several)
    # a success: up every locomotion the episode asked for, the others stay
    asked = set(env._speed_labels[:env.path.index(3.0) + 1].tolist())
    _run(env, round(3.0 / env.dt))
    env.reset()
    assert env.curriculum_level == tuple(min(k + 1, 3) if i in asked else k
                                         for i, k in enumerate((3, 0, 3, 1, 0)))
    # an early end before half the episode: down only the locomotion asked for when it ended
    before = env.curriculum_level = (2, 2, 2, 2, 2)
    env.reset(options={"episode_cut": True})
    env.max_xy_error = 1e-6
    env.step(np.zeros(28))
    ended_on = int(env._speed_labels[env.path.index(env.dt)])
    env.reset()
    assert env.curriculum_level == tuple(k - 1 if i == ended_on else k for i, k in enumerate(before))


def test_per_locomotion_levels_are_checked_and_a_world_level_counts_for_every_locomotion():
    env = PlaMoEnv(speed_levels=3, speed_levels_by_locomotion=True)
    env.curriculum_level = 2
    assert env.curriculum_level == (2,) * 5
    env.curriculum_level = [0, 1, 2, 2, 1]                   # as a saved JSON gives it back
    assert env.curriculum_level == (0, 1, 2, 2, 1)
    with pytest.raises(ValueError, match="5 ints"):
        env.curriculum_level = (1, 2)
    with pytest.raises(ValueError, match="one level per world"):
        PlaMoEnv(speed_levels=3).curriculum_level = (1, 1, 1, 1, 1)
    # without speed_levels the keyword does nothing: one level per world, none at all
    plain = PlaMoEnv(speed_levels_by_locomotion=True)
    plain.reset(seed=0)
    assert plain.curriculum_level is None and plain.curriculum_level_names is None
    with pytest.raises(TypeError, match="speed_levels_by_locomotion"):
        PlaMoEnv(speed_levels_by_locomotion="yes")


def test_speed_curriculum_levels_in_the_batched_env():
    venv = gym.make_vec("PlaMo-v0", num_envs=3, vectorization_mode="vector_entry_point", speed_levels=5)
    venv.reset(seed=0)
    assert list(venv.get_attr("curriculum_level")) == [0, 0, 0]
    venv.set_attr("curriculum_level", [4, 2, 1])
    assert list(venv.get_attr("curriculum_level")) == [4, 2, 1]
    venv.close()


def test_compiled_step_pieces_equal_the_numpy_forms():
    """The compiled pieces of a step (``bilinear_height``'s kernel, ``write_terrain_heightmap``,
    ``write_path_observation``) give the bits of the numpy forms, out-of-field points included."""
    rng = np.random.default_rng(4)
    heights = terrain_heights("mixed", rng, 16.0, 0.1)
    xy = rng.uniform(-9.0, 9.0, (5000, 2))
    n, cell = heights.shape[0], 16.0 / (heights.shape[0] - 1)
    u, v = (xy[:, 0] + 8.0) / cell, (xy[:, 1] + 8.0) / cell
    inside = (u >= 0) & (u <= n - 1) & (v >= 0) & (v <= n - 1)
    u, v = np.clip(u, 0, n - 1.000001), np.clip(v, 0, n - 1.000001)
    j, i = np.floor(u).astype(int), np.floor(v).astype(int)
    fu, fv = u - j, v - i
    expected = np.where(inside, (1 - fv) * ((1 - fu) * heights[i, j] + fu * heights[i, j + 1])
                        + fv * ((1 - fu) * heights[i + 1, j] + fu * heights[i + 1, j + 1]), 0.0)
    np.testing.assert_array_equal(bilinear_height(heights, 16.0, xy), expected)
    path = task.random_head_path(task.PathConfig(), rng, 16.0, np.zeros(2), 0.3,
                                 lambda p: bilinear_height(heights, 16.0, p), arena_half=6.5)
    for t in (0.0, 0.2667, 3.1, 15.9, 40.0):
        root, head = rng.uniform(-8.5, 8.5, 3), rng.uniform(-8.5, 8.5, 3)
        yaw = float(rng.uniform(-math.pi, math.pi))
        c, s = math.cos(yaw), math.sin(yaw)
        heightmap = np.empty(12 * 12)
        grounds = task.write_terrain_heightmap(heightmap, heights, 16.0, root, c, s, 12, 2.5, head)
        points = task.heightmap_points(root[:2], yaw, 12, 2.5)
        np.testing.assert_array_equal(heightmap, bilinear_height(heights, 16.0, points) - root[2])
        assert grounds == (bilinear_height(heights, 16.0, root[:2]), bilinear_height(heights, 16.0, head[:2]))
        targets = np.empty(30)
        target = task.write_path_observation(targets, path.points, path.dt, t, head, c, s, 0.5)
        np.testing.assert_array_equal(targets, task.path_observation(path, t, head, yaw, 10, 0.5))
        np.testing.assert_array_equal(np.array(target), path.at(t))


@pytest.mark.parametrize("locomotion", [None, "crawl", "run"])
def test_constant_paths_hold_one_height_speed_and_turn_rate(locomotion):
    # on a 100 m field no path of 16 s (run: 4 m/s at most) turns back at the edge
    env = PlaMoEnv(constant_paths=True, locomotion=locomotion, terrain="flat", terrain_size=100.0)
    varying = PlaMoEnv(locomotion=locomotion, terrain="flat")
    for seed in range(3):
        env.reset(seed=seed)
        path = env.path
        assert np.ptp(path.head) == 0.0 and np.ptp(path.speed) == 0.0
        if locomotion is not None:
            low, high = env.locomotion.head_range
            assert low <= path.head[0] <= high
        turn = np.diff(np.unwrap(path.yaw))
        assert np.ptp(turn) < 1e-9
        varying.reset(seed=seed)
    assert np.ptp(varying.path.head) > 0.0  # the training paths do change


def test_tracking_evaluation_uses_constant_paths_by_default(monkeypatch):
    from stairenv.evaluation import plamo as evaluation

    made = []
    real_make = gym.make
    monkeypatch.setattr(evaluation.gym, "make", lambda *a, **k: made.append(k) or real_make(*a, **k))
    zero = lambda obs: np.zeros(28)  # noqa: E731
    evaluation.tracking_errors(zero, terrains=("flat",), locomotions=("walk",), episodes=1, max_episode_steps=5)
    evaluation.tracking_errors(zero, terrains=("flat",), locomotions=("walk",), episodes=1, max_episode_steps=5,
                               constant_paths=False)
    assert [k["constant_paths"] for k in made] == [True, False]
    assert made[0]["terrain_size"] == evaluation.TRACKING_TERRAIN_SIZE


def test_grounded_termination_ends_a_low_pelvis_on_an_upright_path_only():
    """``min_root_height`` (training aid): a crawl's start (pelvis 0.17-0.31 m up) on a walk path ends at
    the first step as grounded; on a crawl path it goes on; without the aid ``info`` has no such key."""
    from importlib.resources import files

    crawl = str(files("stairenv.motion.data.plamo") / "dm_crawl.npz")

    def first_step(**keywords):
        env = PlaMoEnv(init="reference", reference_motion=crawl, matched_starts=False, terrain="flat",
                       max_xy_error=100.0, **keywords)
        env.reset(seed=2)
        root_clearance = env.data.qpos[2]
        _, _, terminated, _, info = env.step(np.zeros(28))
        return root_clearance, terminated, info

    clearance, terminated, info = first_step(locomotion="walk", min_root_height=0.4)
    assert clearance < 0.35 and not info["fell"]
    assert info["grounded"] and terminated
    _, terminated, info = first_step(locomotion="crawl", min_root_height=0.4)
    assert not info["grounded"] and not terminated          # a crawl path may keep the pelvis low
    _, terminated, info = first_step(locomotion="walk")
    assert "grounded" not in info and not terminated
    with pytest.raises(ValueError, match="min_root_height"):
        PlaMoEnv(min_root_height=0.0)


def test_height_termination_ends_a_head_far_below_its_target_only():
    """``max_z_error`` (training aid): a crawl's start (head ~0.3 m up) on a walk path ends at the first step
    as z_off_path; on a crawl path it goes on, and so does a standing start on a crawl path (the head
    above its target does not count); without the aid ``info`` has no such key."""
    from importlib.resources import files

    crawl = str(files("stairenv.motion.data.plamo") / "dm_crawl.npz")

    def first_step(init="reference", **keywords):
        env = PlaMoEnv(init=init, reference_motion=crawl, matched_starts=False, terrain="flat",
                       max_xy_error=100.0, **keywords)
        env.reset(seed=2)
        _, _, terminated, _, info = env.step(np.zeros(28))
        return terminated, info

    terminated, info = first_step(locomotion="walk", max_z_error=0.5)
    assert info["z_off_path"] and terminated and info["z_error"] > 0.5 and not info["fell"]
    terminated, info = first_step(locomotion="crawl", max_z_error=0.5)
    assert not info["z_off_path"] and not terminated
    terminated, info = first_step(init="default", locomotion="crawl", max_z_error=0.5)
    assert info["z_error"] > 0.5 and not info["z_off_path"] and not terminated
    terminated, info = first_step(locomotion="walk")
    assert "z_off_path" not in info
    with pytest.raises(ValueError, match="max_z_error"):
        PlaMoEnv(max_z_error=0.0)


def test_upright_termination_ends_a_standing_head_on_a_crawl_path_after_its_grace():
    """``max_z_above`` (training aid): a standing start (head ~1.5 m) on a crawl path (head ~0.3 m) goes on
    for ``z_above_grace`` seconds, then ends as z_above_path; a crawl start on the same path does not; a
    walk path never ends so; with no grace it ends at the first step; without the aid ``info`` has no key."""
    from importlib.resources import files

    crawl = str(files("stairenv.motion.data.plamo") / "dm_crawl.npz")

    def step_at(seconds, init="default", locomotion="crawl", **keywords):
        env = PlaMoEnv(init=init, reference_motion=crawl, matched_starts=False, terrain="flat",
                       locomotion=locomotion, max_xy_error=100.0, **keywords)
        env.reset(seed=2)
        env._steps = int(round(seconds / env.dt)) - 1          # the step below ends this far into the episode
        _, _, terminated, _, info = env.step(np.zeros(28))
        return terminated, info

    terminated, info = step_at(0.5, max_z_above=0.5)             # within the default 1 s grace
    assert not info["z_above_path"] and not terminated and info["z_error"] > 0.5
    terminated, info = step_at(1.5, max_z_above=0.5)
    assert info["z_above_path"] and terminated and not info["fell"]
    terminated, info = step_at(0.1, max_z_above=0.5, z_above_grace=0.0)
    assert info["z_above_path"] and terminated
    terminated, info = step_at(1.5, init="reference", max_z_above=0.5)
    assert not info["z_above_path"] and not terminated
    terminated, info = step_at(1.5, locomotion="walk", max_z_above=0.5)
    assert not info["z_above_path"]
    terminated, info = step_at(1.5)
    assert "z_above_path" not in info
    with pytest.raises(ValueError, match="max_z_above"):
        PlaMoEnv(max_z_above=0.0)
    with pytest.raises(ValueError, match="z_above_grace"):
        PlaMoEnv(z_above_grace=-1.0)


def test_aid_grace_lets_a_crawl_rise_with_its_path():
    """``aid_grace``: the height aids judge the lowest head the path asked for over the last ``aid_grace``
    seconds. A crawl (head ~0.3 m, pelvis < 0.4 m) whose path has just risen to a walk's head height is
    ended by both aids without grace; with a grace longer than the rise it goes on, and once the path has
    stood that high for longer than the grace it ends as before."""
    from importlib.resources import files

    crawl = str(files("stairenv.motion.data.plamo") / "dm_crawl.npz")

    def step_after_rise(grace, risen_for):
        env = PlaMoEnv(init="reference", reference_motion=crawl, matched_starts=False, terrain="flat",
                       locomotion="crawl", max_xy_error=100.0, min_root_height=0.4, max_z_error=0.4,
                       aid_grace=grace)
        env.reset(seed=2)
        path = env.path
        times = np.arange(len(path.head)) * path.dt
        head = np.where(times >= 1.0 - risen_for - 1e-9, 1.4, path.head)   # the path rose this long before 1 s
        points = path.points.copy()
        points[:, 2] += head - path.head
        env.path = path._replace(head=head, points=points)
        env._steps = int(round(1.0 / env.dt)) - 1          # the step below ends 1 s into the episode
        assert times[-1] > 2.0
        _, _, terminated, _, info = env.step(np.zeros(28))
        return terminated, info

    terminated, info = step_after_rise(0.0, risen_for=0.2)
    assert terminated and info["grounded"] and info["z_off_path"]
    terminated, info = step_after_rise(0.5, risen_for=0.2)
    assert not info["grounded"] and not info["z_off_path"] and not terminated
    terminated, info = step_after_rise(0.5, risen_for=0.8)
    assert terminated and info["grounded"] and info["z_off_path"]
    with pytest.raises(ValueError, match="aid_grace"):
        PlaMoEnv(aid_grace=-1.0)


def test_pose_imitation_is_deepmimics_pose_reward_against_the_start_clip_played_on():
    """``pose_reward`` w (training aid): reward_pose = w exp(-2 sum_j (q_ref_j - q_j)^2), q_ref the start
    clip at its start time plus the episode's time, computed here by hand from the joint angles; it is part of
    the reward; 0 on a standing start; absent (and the reward unchanged) without the aid."""
    import math
    from importlib.resources import files

    crawl = str(files("stairenv.motion.data.plamo") / "dm_crawl.npz")

    def env_with(**keywords):
        return PlaMoEnv(reference_motion=crawl, matched_starts=False, terrain="flat", locomotion="crawl",
                        max_xy_error=100.0, **keywords)

    env = env_with(init="reference", pose_reward=1.5)
    env.reset(seed=4)
    clip, start_time = env._reference_clip
    assert clip.name == "dm_crawl"
    rng = np.random.default_rng(0)
    for _ in range(3):
        _, reward, _, _, info = env.step(rng.normal(0.0, 0.1, 28))
        reference = clip.sample(start_time + env._steps * env.dt)[0, 7:]
        joints = env.data.qpos[env._idx.qpos_joints]
        expected = 1.5 * math.exp(-2.0 * sum((a - b) ** 2 for a, b in zip(reference, joints)))
        assert info["reward_pose"] == pytest.approx(expected, rel=1e-12)
        path_terms = sum(info[name] for name in ("reward_position", "reward_height", "reward_direction", "reward_body"))
        assert reward == pytest.approx(path_terms + expected, rel=1e-12)
    env.reset(seed=4)  # the first step after a reference start: near the clip, the term well above 0
    assert 0.05 < env.step(np.zeros(28))[4]["reward_pose"] <= 1.5
    standing = env_with(init="default", pose_reward=1.5)
    standing.reset(seed=4)
    assert standing.step(np.zeros(28))[4]["reward_pose"] == 0.0
    plain, aided = env_with(init="reference"), env_with(init="reference", pose_reward=1.5)
    plain.reset(seed=4), aided.reset(seed=4)
    _, plain_reward, _, _, plain_info = plain.step(np.zeros(28))
    _, aided_reward, _, _, aided_info = aided.step(np.zeros(28))
    assert "reward_pose" not in plain_info
    assert aided_reward == pytest.approx(plain_reward + aided_info["reward_pose"], rel=1e-12)
    soft = env_with(init="reference", pose_reward=1.5, pose_sharpness=0.1)
    soft.reset(seed=4)
    soft.step(np.zeros(28))
    _, _, _, _, info = soft.step(np.zeros(28))
    clip, start_time = soft._reference_clip
    reference = clip.sample(start_time + soft._steps * soft.dt)[0, 7:]
    squared = float(np.sum((reference - soft.data.qpos[soft._idx.qpos_joints]) ** 2))
    assert info["reward_pose"] == pytest.approx(1.5 * math.exp(-0.1 * squared), rel=1e-12)
    with pytest.raises(ValueError, match="pose_reward"):
        PlaMoEnv(pose_reward=-1.0)
    with pytest.raises(ValueError, match="pose_sharpness"):
        PlaMoEnv(pose_sharpness=0.0)
