"""PlaMoScene-v0: instructions planned in a generated scene, the path followed, replanning, success."""

from __future__ import annotations

import dataclasses
import re

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import stairenv  # noqa: F401
from stairenv.environments.plamo_scene import PlaMoSceneEnv, random_instructions
from stairenv.planning.errors import InstructionError
from stairenv.planning.instructions import parse_instructions


def test_check_env_and_determinism():
    env = gym.make("PlaMoScene-v0")
    check_env(env.unwrapped, skip_render_check=True)
    a, info_a = env.reset(seed=3)
    b, info_b = env.reset(seed=3)
    np.testing.assert_array_equal(a, b)
    assert info_a["instructions"] == info_b["instructions"]


def test_scene_is_kept_between_unseeded_resets_and_rebuilt_on_a_seed():
    env = PlaMoSceneEnv(scene_resample_every=3)
    obs, _ = env.reset(seed=5)
    first_scene, first_model = env.scene, env.model
    env.step(np.zeros(28))
    env.reset()
    assert env.scene is first_scene and env.model is first_model  # same world, new instructions and start
    assert env._replans == 0 and env._steps == 0 and env.data.time == 0.0
    env.reset()
    assert env.scene is first_scene
    env.reset()  # the third reset since the build
    assert env.scene is not first_scene and env.model is not first_model
    # A seed rebuilds, so a seeded episode does not depend on the ones before it.
    again, _ = env.reset(seed=5)
    np.testing.assert_array_equal(again, obs)
    np.testing.assert_array_equal(env.scene.heights, first_scene.heights)
    with pytest.raises(ValueError, match="scene_resample_every"):
        PlaMoSceneEnv(scene_resample_every=0)


def test_replanning_keeps_the_route_continuous_and_its_segments_chained():
    # Seed 47's ball crosses the first of two segments; the detour used to end on another cell of the
    # landmark (and the whole route was appended again), so the followed path jumped.
    env = PlaMoSceneEnv()
    env.reset(seed=47)
    assert len(env._plans) == 2
    t = 0.0
    while t < env._trajectory.end_time:
        env._maybe_replan(t)
        t += 0.5
    assert env._replans >= 1
    route = env._trajectory
    assert np.linalg.norm(np.diff(route.xyz[:, :2], axis=0), axis=1).max() < 0.2
    assert np.all(np.diff(route.t) >= 0) and np.all(np.diff(route.s) >= -1e-9)
    first, second = (p.trajectory for p in env._plans)
    assert first.end_time == second.start_time
    np.testing.assert_allclose(first.xyz[-1, :2], second.xyz[0, :2], atol=0.05)
    np.testing.assert_allclose(route.xyz[-1], second.xyz[-1])
    assert route.end_time == second.end_time


def test_random_instructions_parse():
    rng = np.random.default_rng(0)
    names = ["tree", "swing", "car", "bench"]
    start, text = random_instructions(names, rng)
    segments = parse_instructions(text, {n: np.zeros((1, 2), int) for n in names})
    assert start in names and len(segments) == 2
    assert segments[1].source == segments[0].target


def test_path_follows_the_plan_and_user_instructions():
    env = gym.make("PlaMoScene-v0").unwrapped
    env.reset(seed=1)
    names = env.scene.landmark_names
    env2 = PlaMoSceneEnv(instructions=f"Walk to the {names[1]}")
    _, info = env2.reset(seed=1)
    assert info["instructions"] == f"Walk to the {names[1]}"
    # The sampled path is the planned trajectory.
    t = np.arange(0, env2._trajectory.end_time, 0.5)
    np.testing.assert_allclose(env2.path.at(t), env2._trajectory.position(t), atol=0.05)
    # It ends at the target landmark.
    end = env2._trajectory.position(env2._trajectory.end_time)[:2]
    assert np.hypot(*(end - env2._goal_xy)) < env2.scene.landmark(names[1]).radius + 0.6
    with pytest.raises(InstructionError, match="known landmarks"):
        PlaMoSceneEnv(instructions="Walk to the moon").reset(seed=1)


def test_success_when_the_head_arrives_after_the_planned_time():
    env = gym.make("PlaMoScene-v0", max_xy_error=100.0).unwrapped
    env.reset(seed=2)
    env._steps = int(np.ceil(env._trajectory.end_time / env.dt))  # the planned arrival has passed
    data = env.data
    head, _ = env._head()
    data.qpos[:2] += env._goal_xy - head[:2]  # put the head over the goal's centre
    mujoco.mj_forward(env.model, data)
    _, _, terminated, _, info = env.step(np.zeros(28))
    assert info["success"] and terminated


def test_slalom_speed_profiles_and_scene_evaluation(tmp_path):
    from stairenv.evaluation.plamo import format_scene_rows, plot_planned_path, scene_episodes
    from stairenv.evaluation.policies import ZeroPolicy

    planned = gym.make("PlaMoScene-v0", scene_kind="slalom").unwrapped
    planned.reset(seed=0)
    constant = gym.make("PlaMoScene-v0", scene_kind="slalom", speed_profile="constant", constant_speed=2.0).unwrapped
    constant.reset(seed=0)
    assert planned.instructions_text == "Run to the goal"
    np.testing.assert_allclose(constant.path.speed[:-20], 2.0)  # the same path at one speed
    length = constant._plans[0].path.length
    assert constant._trajectory.end_time == pytest.approx(length / 2.0, rel=1e-6)
    assert planned._trajectory.end_time > constant._trajectory.end_time  # the QP slows down for the turns

    env = gym.make("PlaMoScene-v0")
    row = scene_episodes(ZeroPolicy(env.action_space), episodes=2, max_episode_steps=10, label="zero")
    assert row["episodes"] == 2 and 0.0 <= row["success_pct"] <= 100.0
    assert row["waits_per_episode"] >= 0.0 and row["replan_failures_per_episode"] >= 0.0
    assert "zero" in format_scene_rows([row])
    out = plot_planned_path({}, seed=1, path=tmp_path / "plan.png")
    assert out.stat().st_size > 10_000


def test_keywords_that_would_fail_at_reset_fail_at_construction():
    with pytest.raises(InstructionError, match=r"instructions 'fly to the moon': unknown locomotion verb 'fly'"):
        gym.make("PlaMoScene-v0", instructions="fly to the moon")
    with pytest.raises(InstructionError, match=r"instructions 'Walk to the moon': unknown landmark 'moon'"):
        gym.make("PlaMoScene-v0", instructions="Walk to the moon")
    with pytest.raises(InstructionError, match="instructions 'Walk to the tree'"):  # slalom: start and goal only
        gym.make("PlaMoScene-v0", scene_kind="slalom", instructions="Walk to the tree")
    with pytest.raises(ValueError, match=r"scene: 4 landmarks .* cannot fit in a scene of size \(2\.0, 2\.0\)"):
        gym.make("PlaMoScene-v0", scene={"size": (2.0, 2.0)})
    gym.make("PlaMoScene-v0", scene_kind="slalom", instructions="Run to the goal").reset(seed=0)


def test_a_scene_too_small_for_its_landmarks_names_the_least_size():
    """The error gives the least square size that passes the check; just above it, construction passes."""
    from stairenv.environments.plamo_scene import check_landmark_room
    from stairenv.world.scenes import SceneConfig
    for landmarks, separation in ((4, 4.0), (5, 3.0), (8, 2.5)):
        small = SceneConfig(size=(2.0, 2.0), num_landmarks=landmarks, landmark_separation=separation)
        with pytest.raises(ValueError, match=r"scene's size must exceed \(([\d.]+), \1\) m") as info:
            check_landmark_room(small)
        least = float(re.search(r"must exceed \(([\d.]+),", str(info.value))[1])
        assert "scene['size']" in str(info.value) and "scene['num_landmarks']" in str(info.value)
        check_landmark_room(dataclasses.replace(small, size=(least * 1.01, least * 1.01)))
        with pytest.raises(ValueError, match="must exceed"):
            check_landmark_room(dataclasses.replace(small, size=(least * 0.99, least * 0.99)))


def test_what_can_only_fail_at_reset_names_the_keyword():
    env = gym.make("PlaMoScene-v0", scene={"size": (6.0, 6.0)})  # 4 landmarks 4 m apart: fits on paper only
    with pytest.raises(RuntimeError, match=r"scene \(the keyword: size \(6\.0, 6\.0\), num_landmarks 4"):
        env.reset(seed=0)
    env = gym.make("PlaMoScene-v0", instructions="Walk to the tree")  # a known name this scene may not hold
    for seed in range(20):
        try:
            env.reset(seed=seed)
        except InstructionError as error:
            assert str(error).startswith("instructions 'Walk to the tree' cannot be planned in this episode's scene")
            break
    else:
        pytest.fail("no scene of 20 without a tree")


def test_a_route_that_starts_from_a_named_landmark_starts_the_character_there():
    """"Walk from the swing to the tree": the character stands at the swing, on its path (it used to stand at the
    scene's first landmark, metres away, and the episode ended off the path at its first step)."""
    env = PlaMoSceneEnv(scene={"landmark_names": ("tree", "swing", "car", "bench"), "num_landmarks": 4},
                        instructions="Walk from the swing to the tree")
    for seed in range(2):
        _, info = env.reset(seed=seed)
        assert np.array_equal(env._start_xy, env._plans[0].start_xy) and info["xy_error"] < 0.05
        _, _, terminated, _, info = env.step(np.zeros(env.action_space.shape))
        assert not terminated and not info["off_path"]
    env.close()


def test_legs_that_do_not_join_are_refused_naming_them():
    """A leg from another landmark than the one the leg before reaches would make the character jump between
    them: refused with an ``InstructionError`` saying how to write it."""
    from stairenv.planning.errors import InstructionError

    env = PlaMoSceneEnv(scene={"landmark_names": ("tree", "swing", "car", "bench"), "num_landmarks": 4},
                        instructions="Walk to the tree, then walk from the swing to the car")
    with pytest.raises(InstructionError, match="leg 2 starts from the swing, but leg 1 ends at the tree: say 'from "
                                               "the tree', or leave 'from' out"):
        env.reset(seed=0)
    env.close()


def test_a_stop_turns_the_shorter_way_round():
    """While the path stands still its direction turns from the last direction of travel to the next: across the
    +-pi seam the short way (0.08 rad), not through due east; elsewhere as ``np.interp``; held at the ends."""
    from stairenv.environments.plamo_scene import _direction_while_still

    yaw = np.array([np.nan, 3.1, 3.1, np.nan, np.nan, np.nan, -3.1, np.nan, 0.5, np.nan, np.nan, 1.5, np.nan])
    moving = ~np.isnan(yaw)
    out = _direction_while_still(yaw, moving)
    assert out[0] == 3.1 and out[-1] == 1.5 and np.array_equal(out[moving], yaw[moving])
    assert (np.abs(out[3:6]) > 3.1).all() and np.all(np.abs(np.diff(np.unwrap(out[2:7]))) < 0.03)
    np.testing.assert_array_equal(out[9:11], np.interp([9, 10], [8, 11], [0.5, 1.5]))


def test_an_instruction_to_the_start_landmark_plans_a_zero_length_route():
    """"Walk to the fountain" where the character starts at the fountain: the route is the start point, timed
    0 s, and the episode runs (a success at the first step). It used to stop the reset with a MemoryError
    (5.14 TiB): the leg was a few cm to its cell's centre, both ends at rest, timed 7e10 s. Every landmark of
    two seeds; a zero-length leg between two others ("crawl to the X, then walk to the X, then ...") used to
    end in an IndexError."""
    _, info = gym.make("PlaMoScene-v0", instructions="Walk to the fountain").reset(seed=0)   # as reported
    assert info["planned_time"] == 0.0
    names = ("tree", "swing", "car", "fountain")
    scene = {"landmark_names": names, "num_landmarks": 4}
    for name in names:
        env = PlaMoSceneEnv(scene=scene, instructions=f"Walk to the {name}")
        for seed in range(2):
            _, info = env.reset(seed=seed)
            at_start = name == env.scene.landmark_names[0]   # the character starts at the first landmark
            assert np.isfinite(info["planned_time"]) and info["planned_time"] < 60.0 and len(env.path.points) < 1000
            assert (info["planned_time"] == 0.0) == at_start
            _, _, terminated, _, info = env.step(np.zeros(env.action_space.shape))
            assert info["success"] == terminated == at_start
        env.close()
    a, b, c = names[:3]
    env = PlaMoSceneEnv(scene=scene, instructions=f"Crawl to the {a}, then walk to the {a}, then walk from the {a} "
                                                  f"to the {b}, then run to the {c}")
    for seed in range(2):
        _, info = env.reset(seed=seed)
        assert env._plans[1].trajectory.duration == 0.0 and info["planned_time"] == env._plans[-1].trajectory.end_time
        assert np.all(np.diff(env.trajectory.t) > 0) and np.all(np.diff(env.trajectory.s) >= 0)
        env.step(np.zeros(env.action_space.shape))
    env.close()


def test_every_landmark_of_a_drawn_scene_is_a_zero_length_leg_from_itself():
    """The planner alone, on the default scenes of five seeds: a leg to every landmark from its centre (where
    the env stands the character) and from its nearest passable point ("from the X") has zero length."""
    from stairenv.planning.planner import Planner
    from stairenv.world.scenes import SceneConfig, generate_scene

    for seed in range(5):
        scene = generate_scene(SceneConfig(), np.random.default_rng(seed))
        planner = Planner(scene.planning_grid(cell_size=0.1))
        for name in scene.landmark_names:
            for start in (np.asarray(scene.landmark(name).center, dtype=float), planner.landmark_point(name)):
                for locomotion in ("walk", "crawl"):
                    (plan,) = planner.route(f"{locomotion} to the {name}", start=start)
                    assert plan.trajectory.duration == 0.0 and np.array_equal(plan.trajectory.xyz[0, :2], start)


@pytest.mark.parametrize("duration", [7.07e10, 1e300, np.inf, np.nan, -1.0])
def test_the_path_sampler_refuses_an_absurd_duration(duration):
    """A duration that would need over a million samples (7e10 s asked for 5.14 TiB), or is not a finite number
    >= 0, raises ValueError before anything is allocated."""
    from stairenv.environments.plamo_scene import path_from_trajectory
    from stairenv.planning.waypoints import Trajectory

    trajectory = Trajectory.from_profile(np.array([0.0, 1.0]), np.zeros((2, 3)), np.array([1.0, 1.0]))
    with pytest.raises(ValueError, match="the path's duration"):
        path_from_trajectory(trajectory, lambda xy: np.zeros(len(xy)), duration)
    assert len(path_from_trajectory(trajectory, lambda xy: np.zeros(len(xy)), 0.0).points) == 1


def test_a_reset_error_quotes_at_most_80_characters_of_the_instructions():
    """Instructions of 256 KiB naming a landmark this scene lacks: the reset's error quotes 80 characters and
    the length (it quoted them whole)."""
    text = "Walk to the tree" + "." * 2 ** 18
    env = gym.make("PlaMoScene-v0", instructions=text)
    for seed in range(20):
        try:
            env.reset(seed=seed)
        except InstructionError as error:
            message = str(error)
            assert len(message) < 1000 and message.startswith(
                "instructions 'Walk to the tree.....") and "(262,160 characters) cannot be planned" in message
            break
    else:
        pytest.fail("no scene of 20 without a tree")


def test_scene_episodes_on_side_by_side_worlds_equal_one_after_another():
    from stairenv.evaluation.plamo import scene_episodes

    def elementwise(obs):   # a batch-capable policy computed element by element: batch and row calls agree
        return np.tanh(0.05 * np.asarray(obs)[..., 40:68])

    one = scene_episodes(elementwise, episodes=3, seed=5, max_episode_steps=40)
    side = scene_episodes(elementwise, episodes=3, seed=5, max_episode_steps=40, num_envs=2)
    assert side == one
    with pytest.raises(ValueError, match="num_envs"):
        scene_episodes(elementwise, episodes=1, num_envs=0)
