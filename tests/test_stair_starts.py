"""Training aids of InterLevel: staircase starts (a frame of a climb synthesised for the episode's staircase) and stall termination."""

from __future__ import annotations

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import stairenv  # noqa: F401
from stairenv.humanoid.model import FOOT_BODIES
from stairenv.motion import stair_starts
from stairenv.motion.synthesis import climb_stairs


@pytest.fixture(autouse=True)
def _own_climb_cache(tmp_path_factory, monkeypatch):
    """Each test's climbs kept in a disk cache of its own: what it synthesises or reads does not depend on the
    climbs this machine kept before (``stair_starts.load_climb``)."""
    monkeypatch.setenv("STAIRENV_CACHE", str(tmp_path_factory.mktemp("stairenv_cache")))


def test_snap_rounds_to_the_grid_inside_the_range():
    assert stair_starts.snap(0.1349, 0.05, 0.20) == 0.13
    assert stair_starts.snap(0.1351, 0.05, 0.20) == 0.14
    assert stair_starts.snap(0.2049, 0.05, 0.20) == 0.20  # never past the range
    assert stair_starts.snap(0.251, 0.255, 0.40) == 0.26  # the first grid point inside it
    assert stair_starts.snap(0.253, 0.245, 0.255) == 0.25


def test_climb_frames_are_the_synthesised_climb_on_the_stairs():
    qpos, qvel = stair_starts.climb_frames(0.15, 0.30, 6)
    clip = climb_stairs(0.15, 0.30, 6)
    keep = (clip.qpos[:, 0] >= -0.6) & (clip.qpos[:, 0] <= 5 * 0.30 + 0.3)
    np.testing.assert_array_equal(qpos, clip.qpos[keep].astype(np.float32))
    np.testing.assert_array_equal(qvel, clip.qvel()[keep].astype(np.float32))
    assert qpos[0, 2] < qpos[-1, 2] - 0.6  # it climbs
    with pytest.raises(ValueError, match="grid"):
        stair_starts.climb_frames(0.155, 0.30, 6)


def test_a_synthesised_climb_is_kept_on_the_disk_and_read_back_instead_of_synthesised(tmp_path, monkeypatch):
    monkeypatch.setenv("STAIRENV_CACHE", str(tmp_path))
    monkeypatch.setattr(stair_starts, "_CLIMBS", type(stair_starts._CLIMBS)())
    key = (12, 30, 4, "left")
    qpos, qvel = stair_starts.climb_frames(0.12, 0.30, 4, "left")
    path = stair_starts.climb_path(key)
    assert path.is_file() and path.is_relative_to(tmp_path / "climbs")
    # another process (an empty in-process cache) reads the file and synthesises nothing
    monkeypatch.setattr(stair_starts, "_CLIMBS", type(stair_starts._CLIMBS)())

    def no_synthesis(*key):
        raise AssertionError("synthesised although the disk holds the climb")

    monkeypatch.setattr(stair_starts, "_synthesise", no_synthesis)
    again = stair_starts.climb_frames(0.12, 0.30, 4, "left")
    np.testing.assert_array_equal(again[0], qpos)
    np.testing.assert_array_equal(again[1], qvel)
    assert stair_starts.fill_cache([(12, 30, 4, "left")], workers=1) == 0


@pytest.mark.parametrize("content", ["garbage", "pickle", "shape", "nan"])
def test_a_cached_climb_file_that_is_not_a_climb_is_synthesised_again_and_replaced(tmp_path, monkeypatch, content):
    monkeypatch.setenv("STAIRENV_CACHE", str(tmp_path))
    monkeypatch.setattr(stair_starts, "_CLIMBS", type(stair_starts._CLIMBS)())
    key = (10, 28, 3, "right")
    path = stair_starts.climb_path(key)
    path.parent.mkdir(parents=True)
    good = np.zeros((5, 35), np.float32), np.zeros((5, 34), np.float32)
    if content == "garbage":
        path.write_bytes(b"PK\x03\x04 not a zip")
    elif content == "pickle":    # an object array would need pickle to load: refused, never run
        np.savez(path, qpos=np.array([{"a": 1}], dtype=object), qvel=good[1])
    elif content == "shape":
        np.savez(path, qpos=np.zeros((5, 7), np.float32), qvel=good[1])
    else:
        np.savez(path, qpos=np.full((5, 35), np.nan, np.float32), qvel=good[1])
    assert stair_starts.load_climb(key) is None
    qpos, _ = stair_starts.climb_frames(0.10, 0.28, 3, "right")
    assert qpos.shape[1] == 35 and np.isfinite(qpos).all()
    np.testing.assert_array_equal(stair_starts.load_climb(key)[0], qpos)    # the file replaced


def test_a_cache_folder_that_cannot_be_written_is_left_alone(tmp_path, monkeypatch):
    blocked = tmp_path / "file"
    blocked.write_text("a file where the cache folder would be")
    monkeypatch.setenv("STAIRENV_CACHE", str(blocked))
    monkeypatch.setattr(stair_starts, "_CLIMBS", type(stair_starts._CLIMBS)())
    qpos, _ = stair_starts.climb_frames(0.10, 0.28, 3, "right")
    assert len(qpos) and not stair_starts.climb_path((10, 28, 3, "right")).exists()


def _foot_clearances(env) -> list[float]:
    """Height of each foot's lowest geom point over the tread (or floor) under its body."""
    model, data, stairs = env.model, env.data, env.stairs
    gaps = []
    for body in FOOT_BODIES:
        body_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
        geoms = np.flatnonzero(model.geom_bodyid == body_id)
        low = min(data.geom_xpos[g][2] - model.geom_size[g][0] if model.geom_type[g] != mujoco.mjtGeom.mjGEOM_BOX
                  else data.geom_xpos[g][2] - np.abs(data.geom_xmat[g].reshape(3, 3)[2]) @ model.geom_size[g]
                  for g in geoms)
        gaps.append(low - float(stairs.surface_height(data.xpos[body_id][:2])))
    return gaps


def test_stairs_starts_put_the_feet_on_the_treads():
    env = gym.make("InterLevel-v0", stairs_start_fraction=1.0).unwrapped
    heights = []
    for seed in range(8):
        _, info = env.reset(seed=seed)
        stairs = env.stairs
        assert info["stairs_start"] and info["reference_start"]
        for value in (stairs.step_height, stairs.step_depth):
            assert abs(value / 0.01 - round(value / 0.01)) < 1e-6  # snapped to the 1 cm grid
        assert min([c.dist for c in env.data.contact[:env.data.ncon]] or [0.0]) > -1e-3  # nothing sunk in
        gaps = _foot_clearances(env)
        assert min(gaps) > -0.01 and min(gaps) < 0.05, gaps  # at least one foot stands on its tread
        heights.append(info["height_progress"])
        for _ in range(5):  # holding the pose a moment neither blows up nor ends the episode at once
            _, _, terminated, truncated, info = env.step(np.zeros(28))
            assert not info["physics_unstable"]
    assert max(heights) - min(heights) > 0.2  # starts spread over the climb
    env.close()


def test_stairs_starts_leave_other_episodes_alone():
    plain = gym.make("InterLevel-v0").unwrapped
    off = gym.make("InterLevel-v0", stairs_start_fraction=0.0).unwrapped
    half = gym.make("InterLevel-v0", stairs_start_fraction=0.5).unwrapped
    obs, info = plain.reset(seed=3)
    obs_off, info_off = off.reset(seed=3)
    np.testing.assert_array_equal(obs, obs_off)
    assert not info["stairs_start"] and info["stairs"] == info_off["stairs"]
    starts = []
    for seed in range(40):
        _, info = half.reset(seed=seed)
        starts.append(info["stairs_start"])
    assert 8 < sum(starts) < 32
    for env in (plain, off, half):
        env.close()


def test_stairs_start_keywords_are_checked():
    with pytest.raises(ValueError, match="stairs_start_fraction"):
        gym.make("InterLevel-v0", stairs_start_fraction=1.5)
    with pytest.raises(ValueError, match="step_height"):
        gym.make("InterLevel-v0", stairs_start_fraction=0.5, step_height=(0.05, 0.30))
    with pytest.raises(ValueError, match="step_depth"):
        gym.make("InterLevel-v0", stairs_start_fraction=0.5, step_depth=(0.25, 0.60))


def test_batched_stairs_starts_equal_single_envs():
    kwargs = dict(stairs_start_fraction=0.5, max_episode_steps=30)
    vec = gym.make_vec("InterLevel-v0", num_envs=2, vectorization_mode="vector_entry_point", **kwargs)
    ref = gym.make_vec("InterLevel-v0", num_envs=2, vectorization_mode="sync", **kwargs)
    a, b = vec.reset(seed=5), ref.reset(seed=5)
    np.testing.assert_array_equal(a[0], b[0])
    rng = np.random.default_rng(0)
    for _ in range(80):
        action = rng.uniform(-1, 1, (2, 28)).astype(np.float32)
        got, want = vec.step(action), ref.step(action)
        for x, y in zip(got[:4], want[:4]):
            np.testing.assert_array_equal(x, y)
        np.testing.assert_array_equal(got[4]["stairs_start"], want[4]["stairs_start"])
    vec.close()
    ref.close()


# --- stall termination (the other training aid) ----------------------------------------------------
def test_stall_clock_restarts_on_each_approach():
    from stairenv.tasks.stall import StallWatch

    dt = 1.0 / 30.0
    watch = StallWatch(1.0, 0.2, dt)
    steps_per_second = round(1.0 / dt)
    assert not watch.stalled(5.0, 0)  # the first evaluation sets the reference distance
    for step in range(1, steps_per_second + 1):  # 1 s closer by less than 0.2 m: not yet
        assert not watch.stalled(5.0 - 0.19 * step / steps_per_second, step)
    step = steps_per_second + 1
    assert watch.stalled(4.85, step)  # more than 1 s without a 0.2 m approach
    step += 1
    assert not watch.stalled(4.79, step)  # 0.21 m closer than the start: the clock restarts
    step += steps_per_second
    assert not watch.stalled(4.70, step)
    step += 1
    assert watch.stalled(4.70, step)
    watch.restart()  # a new episode
    assert not watch.stalled(9.0, 0)
    assert not StallWatch(None, 0.2, dt).stalled(5.0, 10_000)  # off without seconds
    env = gym.make("InterLevel-v0", stall_seconds=1.0, stall_distance=0.2).unwrapped
    env.reset(seed=0)
    assert (env._stall.seconds, env._stall.distance, env._stall.dt) == (1.0, 0.2, env.dt)  # the env's own
    env.close()


def test_stall_clocks_as_arrays_follow_each_watch():
    """The batched reward kernel's stall clocks (``interlevel_reward_and_end``) give, step by step, what each
    world's ``StallWatch`` gives; a stall ends the episode; without ``stall_seconds`` nothing stalls."""
    from stairenv.tasks import interlevel as task
    from stairenv.tasks.stall import StallWatch

    dt, rng, n = 1.0 / 30.0, np.random.default_rng(0), 5
    watches = [StallWatch(0.5, 0.2, dt) for _ in range(n)]
    approach, approach_at = np.full(n, np.inf), np.zeros(n, dtype=np.int64)
    results = np.zeros((n, len(task.STEP_RESULTS)))
    distance = results[:, task.STEP_RESULTS.index("distance_to_target")]
    distance[:] = 6.0
    stalls = 0
    for step in range(120):
        distance -= rng.uniform(-0.02, 0.05, n)
        _, _, flags = task.interlevel_reward_and_end(np.zeros((n, 3)), results, np.full(n, step), approach,
                                                     approach_at, task.end_parameters(0.2, 0.5, dt, 10.0, -1.0, True))
        stalled = [watch.stalled(d, step) for watch, d in zip(watches, distance.tolist())]
        assert flags[:, 2].tolist() == stalled and flags[:, 3].tolist() == stalled
        assert approach.tolist() == [watch.approach_distance for watch in watches]
        stalls += sum(stalled)
    assert stalls > 0
    _, _, flags = task.interlevel_reward_and_end(np.zeros((n, 3)), results, np.full(n, 10_000), approach, approach_at,
                                                 task.end_parameters(0.2, None, dt, 10.0, -1.0, True))
    assert not flags.any()


def test_a_stalled_episode_terminates_without_a_reward_of_its_own():
    env = gym.make("InterLevel-v0", stall_seconds=0.2).unwrapped
    env.reset(seed=1)
    env._stall.approach_distance = -1.0  # no approach can count from here on
    for _ in range(20):
        _, reward, terminated, truncated, info = env.step(np.zeros(28))
        if terminated:
            break
    assert terminated and info["stalled"] and not info["fell"] and not info["success"]
    task_terms = ("reward_location", "reward_facing", "reward_velocity", "reward_success", "reward_failure")
    assert reward == pytest.approx(sum(info[key] for key in task_terms)) and info["reward_failure"] == 0.0
    with pytest.raises(ValueError, match="stall_seconds"):
        gym.make("InterLevel-v0", stall_seconds=0.0)
    env.close()


# --- step-height curriculum (training aid) ----------------------------------------------------------
def test_curriculum_bands_split_the_range_and_levels_move_on_outcomes():
    from stairenv.tasks import curriculum

    assert curriculum.level_band(0, 9, 0.02, 0.20) == pytest.approx((0.02, 0.04))
    assert curriculum.level_band(8, 9, 0.02, 0.20) == pytest.approx((0.18, 0.20))
    with pytest.raises(ValueError, match="level"):
        curriculum.level_band(9, 9, 0.02, 0.20)
    rng = np.random.default_rng(0)
    assert curriculum.next_level(3, 9, success=True, progress=1.0, rng=rng) == 4
    assert curriculum.next_level(3, 9, success=False, progress=0.49, rng=rng) == 2
    assert curriculum.next_level(3, 9, success=False, progress=0.5, rng=rng) == 3  # half-way: stays
    assert curriculum.next_level(0, 9, success=False, progress=0.0, rng=rng) == 0
    # a success at the top level sends the world anywhere, so the population spreads over the range
    tops = {curriculum.next_level(8, 9, success=True, progress=1.0, rng=rng) for _ in range(200)}
    assert tops == set(range(9))
    assert {curriculum.initial_level(9, rng) for _ in range(200)} == set(range(5))


def _finish_episode(env, progress: float, success: bool) -> None:
    """As if the episode had ended after a step with this outcome (its last evaluation's results)."""
    env._steps = max(env._steps, 1)
    env._outcome = env._outcome._replace(
        results={**env._outcome.results, "progress": progress, "success": success})


def test_curriculum_draws_the_level_band_and_moves_on_floor_start_episodes():
    env = gym.make("InterLevel-v0", step_height=(0.02, 0.20), step_height_levels=9).unwrapped
    env.reset(seed=0)
    level = env.curriculum_level
    assert 0 <= level <= 4
    low, high = 0.02 + 0.02 * level, 0.04 + 0.02 * level
    assert low - 1e-9 <= env.stairs.step_height <= high + 1e-9
    _finish_episode(env, 1.0, True)
    env.reset()
    assert env.curriculum_level == level + 1
    assert 0.04 + 0.02 * level - 1e-9 <= env.stairs.step_height <= 0.06 + 0.02 * level + 1e-9
    _finish_episode(env, 0.2, False)
    env.reset(seed=3)  # the level is training state: a seeded reset keeps it
    assert env.curriculum_level == level
    env.curriculum_level = 8  # as a resumed trainer sets it
    env.reset()
    assert 0.18 - 1e-9 <= env.stairs.step_height <= 0.20 + 1e-9
    env.close()


def test_curriculum_ignores_staircase_start_episodes_and_bad_keywords():
    env = gym.make("InterLevel-v0", step_height=(0.02, 0.20), step_height_levels=9,
                   stairs_start_fraction=1.0).unwrapped
    env.reset(seed=0)
    level = env.curriculum_level
    for _ in range(3):  # started on the stairs: a success there says little about the floor start
        _finish_episode(env, 1.0, True)
        env.reset()
        assert env.curriculum_level == level and env._stairs_start
        assert 0.02 + 0.02 * level - 1e-9 <= env.stairs.step_height <= 0.04 + 0.02 * level + 1e-9
    env.close()
    plain = gym.make("InterLevel-v0").unwrapped
    plain.reset(seed=0)
    assert plain.curriculum_level is None  # off by default
    plain.close()
    with pytest.raises(ValueError, match="step_height_levels"):
        gym.make("InterLevel-v0", step_height_levels=-1)
    with pytest.raises(TypeError, match="step_height_levels"):
        gym.make("InterLevel-v0", step_height_levels="9")
    with pytest.raises(ValueError, match="step_height_levels"):
        gym.make("InterLevel-v0", step_height_levels=4, step_height_set=(0.05, 0.1))


def test_curriculum_moves_with_real_episode_ends():
    """An episode played out (a fall of the zero policy) moves a floor-start world down a level."""
    env = gym.make("InterLevel-v0", step_height=(0.02, 0.20), step_height_levels=9, max_episode_steps=120)
    inner = env.unwrapped
    env.reset(seed=1)
    inner.curriculum_level = 3
    for _ in range(120):
        _, _, terminated, truncated, info = env.step(np.zeros(28))
        if terminated or truncated:
            break
    assert not info["success"] and info["progress"] < 0.5
    env.reset()
    assert inner.curriculum_level == 2
    env.close()


def test_curriculum_thresholds_move_levels_on_progress():
    from stairenv.tasks import curriculum

    rng = np.random.default_rng(0)
    # legged-gym style: up past half of the stairs, down below a quarter
    assert curriculum.next_level(3, 9, False, 0.5, rng, demote_below=0.25, promote_at=0.5) == 4
    assert curriculum.next_level(3, 9, False, 0.3, rng, demote_below=0.25, promote_at=0.5) == 3
    assert curriculum.next_level(3, 9, False, 0.2, rng, demote_below=0.25, promote_at=0.5) == 2
    env = gym.make("InterLevel-v0", step_height=(0.02, 0.20), step_height_levels=9, curriculum_promote_at=0.5,
                   curriculum_demote_below=0.25).unwrapped
    env.reset(seed=0)
    level = env.curriculum_level
    _finish_episode(env, 0.6, False)
    env.reset()
    assert env.curriculum_level == level + 1
    env.close()
    with pytest.raises(ValueError, match="curriculum_promote_at"):
        gym.make("InterLevel-v0", step_height_levels=9, curriculum_promote_at=0.2)  # below the demotion bar
    with pytest.raises(ValueError, match="curriculum_demote_below"):
        gym.make("InterLevel-v0", step_height_levels=9, curriculum_demote_below=1.5)


def test_fill_cache_on_worker_processes_gives_the_climbs_a_miss_would(monkeypatch):
    keys = stair_starts.grid_keys((0.105, 0.12), (0.30, 0.30), (3, 3))
    assert keys == [(h, 30, 3, foot) for h in (11, 12) for foot in ("right", "left")]
    for key in keys:
        stair_starts._CLIMBS.pop(key, None)
    assert stair_starts.fill_cache(keys, workers=2) == 4
    assert stair_starts.fill_cache(keys, workers=2) == 0          # already there
    filled = {key: stair_starts._CLIMBS[key] for key in keys}
    expected = {key: stair_starts._synthesise(*key) for key in keys}    # computed here, in this process
    monkeypatch.setattr(stair_starts, "_synthesise", lambda *key: pytest.fail(f"synthesised again: {key}"))
    for (h, d, n, foot), (qpos, qvel) in filled.items():
        want_qpos, want_qvel = expected[(h, d, n, foot)]
        np.testing.assert_array_equal(qpos, want_qpos)    # the same bits as a miss in this process
        np.testing.assert_array_equal(qvel, want_qvel)
        got = stair_starts.climb_frames(h * 0.01, d * 0.01, n, foot)
        assert got[0] is qpos and got[1] is qvel          # served from the cache


def test_climb_keys_are_the_grid_staircases_the_env_can_draw():
    assert gym.make("InterLevel-v0").unwrapped.climb_keys() == []    # no stair starts, nothing to synthesise
    keys = gym.make("InterLevel-v0", stairs_start_fraction=0.5).unwrapped.climb_keys()
    # 0.05-0.20 m x 0.25-0.40 m on the 1 cm grid, 3-10 steps, either foot: the whole cache
    assert len(keys) == 16 * 16 * 8 * 2 == stair_starts.CACHE_SIZE
    env = gym.make("InterLevel-v0", stairs_start_fraction=1.0).unwrapped
    for seed in range(4):
        env.reset(seed=seed)
        s = env.stairs
        assert (round(s.step_height / 0.01), round(s.step_depth / 0.01), s.num_steps, "right") in keys
