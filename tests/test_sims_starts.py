"""SIMS training aids: starts in a frame of the skill's clip made for the episode's piece
(``interaction_start_fraction``) and the success-driven start-distance curriculum
(``start_distance_levels``)."""

import math

import gymnasium as gym
import numpy as np
import pytest

import stairenv  # noqa: F401  (registers the envs)
from stairenv.environments.sims import START_PENETRATION, SIMSEnv
from stairenv.motion import interaction_starts
from stairenv.rotations import heading_angle, wrap_angle
from stairenv.tasks import curriculum
from stairenv.training import cli

FAST = {"text_encoder": "hashing", "scene_resample_every": 1}


def _pelvis(env):
    return env.data.xpos[env._idx.pelvis_id].copy()


# --- interaction starts ---------------------------------------------------------------------------
@pytest.mark.parametrize("skill", ["sit", "lie"])
def test_seat_starts_are_at_the_piece_and_do_not_press_into_it(skill):
    env = SIMSEnv(skill=skill, interaction_start_fraction=1.0, **FAST)
    started = successes = 0
    for seed in range(12):
        _, info = env.reset(seed=seed)
        assert info["reference_start"] == info["interaction_start"]
        if not info["interaction_start"]:
            continue
        started += 1
        assert env.start_penetration() <= START_PENETRATION
        # standing right in front of the seat at the farthest: the pelvis within a metre of its target
        assert info["contact_error"] < 1.0
        surface = env._target.footprint_box(margin=1.0)
        assert surface.contains_xy(_pelvis(env)[None, :2])[0]
        successes += info["success"]
        # the character's velocities are the clip's (a start mid-motion moves)
        assert np.all(np.isfinite(env.data.qvel))
    assert started >= 10          # a frame that fits is found on nearly every piece
    assert successes >= 3         # seated (lying) frames start within the success distance


def test_starts_step_with_a_zero_action_without_ending():
    for skill in ("sit", "lie"):
        env = SIMSEnv(skill=skill, interaction_start_fraction=1.0, **FAST)
        for seed in range(4):
            env.reset(seed=seed)
            for _ in range(5):
                _, _, terminated, truncated, info = env.step(np.zeros(28))
                assert not terminated and not truncated
                assert not info["physics_unstable"]


def test_reach_start_holds_the_hand_towards_the_goal_drawn_for_it():
    env = SIMSEnv(skill="reach", interaction_start_fraction=1.0, **FAST)
    started = 0
    for seed in range(12):
        _, info = env.reset(seed=seed)
        if not info["interaction_start"]:
            # no frame fitted (a target deep inside a double bed): a start as the others, at rest,
            # none of the tried frames' joint angles or velocities left over
            assert not info["reference_start"]
            assert not np.any(env.data.qvel) and not np.any(env.data.qpos[env._idx.qpos_joints])
            continue
        started += 1
        assert env.start_penetration() <= START_PENETRATION
        # standing 0.45-0.75 m from the target (hand 0.2 m to the side): the hand within an arm's length
        assert info["contact_error"] < 1.0
        feet = min(env.data.xpos[env.model.body(n).id][2] for n in ("right_foot", "left_foot"))
        assert feet < 0.15
    assert started >= 6


def test_the_default_starts_no_episode_at_the_furniture_and_reports_nothing_new():
    env = SIMSEnv(skill="sit", **FAST)
    _, info = env.reset(seed=3)
    assert "interaction_start" not in info and env.curriculum_level is None
    aided = SIMSEnv(skill="sit", interaction_start_fraction=0.0, start_distance_levels=0, **FAST)
    obs, _ = aided.reset(seed=3)
    np.testing.assert_array_equal(obs, env.reset(seed=3)[0])


def test_clip_frames_are_cached_on_their_grid():
    a = interaction_starts.sit_frames(0.452)
    assert a[0] is interaction_starts.sit_frames(0.448)[0]    # both 0.45 m
    qpos, qvel, head = interaction_starts.lie_frames(0.5, 0.45, 0.1)
    assert qpos.shape[1] == 35 and qvel.shape == (len(qpos), 34)
    assert head[1] > 0.4        # lying with the head towards +y (the seated character's left)
    assert interaction_starts.reach_frames(0.6, 1.0, "left")[2] == pytest.approx(1.0)


# --- the start-distance curriculum -------------------------------------------------------------------
def _end_episode(env, success: bool, progress: float) -> None:
    """Take a step, then make the episode's outcome what the test needs (success, distance closed)."""
    env.step(np.zeros(28))
    env._success_once = success
    env._root_distance = (1.0 - progress) * env._start_root_distance


def test_curriculum_grows_the_start_distance_with_success_and_ignores_cut_episodes():
    env = SIMSEnv(skill="sit", start_distance_levels=3, start_distance=(1.0, 4.0), **FAST)
    env.reset(seed=0)
    assert env.curriculum_level == 0 and env.episode_start_distance() == (1.0, 2.0)
    _end_episode(env, success=True, progress=1.0)
    env.reset(options={"episode_cut": True})        # a trainer's checkpoint: not judged
    assert env.curriculum_level == 0
    _end_episode(env, success=True, progress=1.0)
    env.reset()
    assert env.curriculum_level == 1 and env.episode_start_distance() == (1.0, 3.0)
    _end_episode(env, success=True, progress=1.0)
    env.reset(seed=5)                               # seeded resets keep the level too
    assert env.curriculum_level == 2 and env.episode_start_distance() == (1.0, 4.0)
    _end_episode(env, success=True, progress=1.0)
    env.reset()
    assert env.curriculum_level == 2                # the top level already draws the whole range
    _end_episode(env, success=False, progress=0.7)  # most of the way: the level holds
    env.reset()
    assert env.curriculum_level == 2
    _end_episode(env, success=False, progress=0.1)  # hardly moved: down a level
    env.reset()
    assert env.curriculum_level == 1
    env.reset()                                     # no step taken: nothing to judge
    assert env.curriculum_level == 1


def test_curriculum_starts_within_the_level_range():
    env = SIMSEnv(skill="sit", start_distance_levels=4, start_distance=(1.0, 5.0), **FAST)
    for seed in range(10):
        env.reset(seed=seed)
        distance = float(np.hypot(*(_pelvis(env)[:2] - env._target.position)))
        low, high = env.episode_start_distance()
        assert high == 2.0
        # within the band, or (when the band is inside the piece's margin) just outside the piece
        radius = max(env._target.furniture.footprint) + 0.5
        assert distance <= max(high, radius) + 0.05


def test_walk_curriculum_grows_the_goal_distance_and_keeps_the_starts():
    """Walk: the level grows the goal's distance from the start within ``walk_distance``; the start itself
    is placed as without the aid (the same draws: with the top level's range the goal is the same too)."""
    walk_distance = (1.0, 5.0)
    env = SIMSEnv(skill="walk", start_distance_levels=4, walk_distance=walk_distance, **FAST)
    plain = SIMSEnv(skill="walk", walk_distance=walk_distance, **FAST)
    for seed in range(8):
        env.reset(seed=seed)
        plain.reset(seed=seed)
        assert env.curriculum_level == 0 and env.episode_walk_distance() == (1.0, 2.0)
        assert env.episode_start_distance() == plain.start_distance
        np.testing.assert_array_equal(_pelvis(env), _pelvis(plain))
        goal_distance = float(np.hypot(*(env._start - env.goal.root_target[:2])))
        assert 1.0 - 1e-9 <= goal_distance <= 2.0 + 1e-9
    _end_episode(env, success=True, progress=1.0)
    env.reset()
    assert env.curriculum_level == 1 and env.episode_walk_distance() == (1.0, 3.0)
    env.curriculum_level = 3                         # the top level: the plain env's goals, draw for draw
    env.reset(seed=11)
    plain.reset(seed=11)
    np.testing.assert_array_equal(env.goal.root_target, plain.goal.root_target)


def test_interaction_starts_are_not_judged_by_the_curriculum():
    env = SIMSEnv(skill="sit", start_distance_levels=3, interaction_start_fraction=1.0, **FAST)
    env.reset(seed=1)
    assert env._interaction_start
    _end_episode(env, success=True, progress=1.0)
    env.reset(seed=2)
    assert env.curriculum_level == 0


def test_growing_range_and_levels():
    assert curriculum.growing_range(0, 4, 1.0, 5.0) == (1.0, 2.0)
    assert curriculum.growing_range(3, 4, 1.0, 5.0) == (1.0, 5.0)
    with pytest.raises(ValueError, match="level"):
        curriculum.growing_range(4, 4, 1.0, 5.0)
    assert curriculum.next_growing_level(1, 4, True, 0.0) == 2
    assert curriculum.next_growing_level(3, 4, True, 1.0) == 3
    assert curriculum.next_growing_level(1, 4, False, 0.2) == 0
    assert curriculum.next_growing_level(1, 4, False, 0.6) == 1


# --- keywords ------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("kwargs", "error", "match"), [
    ({"interaction_start_fraction": -0.1}, ValueError, "interaction_start_fraction"),
    ({"interaction_start_fraction": 1.5}, ValueError, r"interaction_start_fraction.*\[0\.0, 1\.0\]"),
    ({"interaction_start_fraction": "0.5"}, TypeError, "interaction_start_fraction"),
    ({"interaction_start_fraction": 0.5, "skill": "walk"}, ValueError, "interaction_start_fraction"),
    ({"interaction_start_fraction": 0.5, "skill": "getup"}, ValueError, "interaction_start_fraction"),
    ({"start_distance_levels": -1}, ValueError, r"start_distance_levels.*\[0, 100\]"),
    ({"start_distance_levels": 101}, ValueError, "start_distance_levels"),
    ({"start_distance_levels": 2.5}, ValueError, "start_distance_levels"),
    ({"start_distance_levels": "3"}, TypeError, "start_distance_levels"),
    ({"start_distance_levels": 3, "scene": "room"}, ValueError, "start_distance_levels"),
    ({"start_distance_levels": 3, "skill": "getup"}, ValueError, "start_distance_levels"),
])
def test_bad_values_are_refused_naming_the_keyword(kwargs, error, match):
    with pytest.raises(error, match=match):
        SIMSEnv(**{"skill": "sit", **FAST, **kwargs})


def test_both_keywords_work_in_the_batched_env():
    env = gym.make_vec("SIMS-Sit-v0", num_envs=4, vectorization_mode="vector_entry_point",
                       interaction_start_fraction=0.5, start_distance_levels=3, text_encoder="hashing",
                       max_episode_steps=4)
    _, info = env.reset(seed=0)
    assert info["interaction_start"].dtype == bool
    for _ in range(10):
        env.step(np.zeros((4, 28)))
    levels = env.get_attr("curriculum_level")
    assert all(level in (0, 1, 2) for level in levels)
    env.close()


def test_the_evaluation_drops_both_aids(baseline_script):
    kwargs = {"interaction_start_fraction": 0.5, "start_distance_levels": 3, "start_distance": (1.0, 4.0)}
    assert cli.evaluation_kwargs(kwargs) == {"start_distance": (1.0, 4.0)}
    assert "start_distance_levels" in curriculum.LEVEL_KEYWORDS
    assert math.isclose(START_PENETRATION, 0.01)


# --- stall termination (training aid) ---------------------------------------------------------------
def test_a_stalled_sims_episode_ends_with_its_reason():
    env = SIMSEnv(skill="sit", stall_seconds=0.2, **FAST)
    env.reset(seed=1)
    env._stall.approach_distance = -1.0  # no approach can count from here on
    for steps in range(1, 30):
        _, reward, terminated, _, info = env.step(np.zeros(28))
        if terminated:
            break
    assert terminated and info["stalled"] and not info["fell"] and not info["success"]
    assert steps * env.dt > 0.2 and steps * env.dt < 0.2 + 2 * env.dt  # at the first step past 0.2 s
    assert reward == pytest.approx(sum(v for k, v in info.items() if k.startswith("reward_")))


def test_stall_termination_is_off_by_default_and_leaves_info_unchanged():
    plain = SIMSEnv(skill="sit", **FAST)
    plain.reset(seed=1)
    _, _, _, _, info = plain.step(np.zeros(28))
    assert "stalled" not in info and plain.stall_seconds is None
    with pytest.raises(ValueError, match="stall_seconds"):
        SIMSEnv(skill="sit", stall_seconds=0.0, **FAST)
    with pytest.raises(ValueError, match="stall_distance"):
        SIMSEnv(skill="sit", stall_distance=-1.0, **FAST)


def test_a_succeeding_episode_does_not_stall():
    env = SIMSEnv(skill="sit", stall_seconds=0.2, interaction_start_fraction=1.0, **FAST)
    env.reset(seed=4)  # starts seated (measured: succeeding for the first 20 steps under zero actions)
    env._stall.approach_distance = -1.0  # the clock runs from the start: past 0.2 s every step stalls...
    succeeded = 0
    for steps in range(1, 40):
        _, _, terminated, _, info = env.step(np.zeros(28))
        assert not (info["stalled"] and info["success"])  # ...unless it is succeeding
        succeeded += info["success"] and steps * env.dt > 0.2
        if terminated:
            break
    assert succeeded > 0


# --- grounded termination (training aid) ------------------------------------------------------------
def test_a_pelvis_below_min_root_height_ends_the_episode_and_a_seated_one_does_not():
    """Seated on the piece (an interaction start) the pelvis stays above 0.3 m and the episode goes on;
    standing (pelvis ~0.9 m) under a 1.5 m threshold counts as grounded at the first step."""
    seated = SIMSEnv(skill="sit", min_root_height=0.3, interaction_start_fraction=1.0, **FAST)
    seated.reset(seed=4)  # starts seated (the succeeding start of the stall test above)
    for _ in range(10):
        _, _, terminated, _, info = seated.step(np.zeros(28))
        assert not info["grounded"] and not terminated and _pelvis(seated)[2] > 0.3
    standing = SIMSEnv(skill="sit", min_root_height=1.5, **FAST)
    standing.reset(seed=1)
    _, _, terminated, _, info = standing.step(np.zeros(28))
    assert info["grounded"] and terminated and not info["fell"]
    plain = SIMSEnv(skill="sit", **FAST)
    plain.reset(seed=1)
    assert "grounded" not in plain.step(np.zeros(28))[4]
    with pytest.raises(ValueError, match="min_root_height"):
        SIMSEnv(skill="getup", min_root_height=0.3, **FAST)
    with pytest.raises(ValueError, match="min_root_height"):
        SIMSEnv(skill="sit", min_root_height=0.0, **FAST)


# --- start-from-front curriculum (training aid) -------------------------------------------------------
def _yaw_gap(a: float, b: float) -> float:
    return abs(float(wrap_angle(a - b)))


def test_front_starts_begin_in_front_of_the_seat_with_the_back_to_it_and_widen_with_the_level():
    """Level 0 of 10: the start lies within 18 deg of the direction out of the seat's front, 0.5-0.85 m from
    its front edge, heading within 36 deg of facing out (the back to the seat); the top level reaches
    bearings and headings far outside that."""
    env = SIMSEnv(skill="sit", start_distance_levels=10, start_distance=(0.5, 4.0), start_from_front=True, **FAST)
    bearings, headings = {0: [], 9: []}, {0: []}
    for level in (0, 9):
        for seed in range(12):
            env.reset(seed=seed)              # a seeded reset builds the scene, then the level is set
            env.curriculum_level = level
            env.reset()
            _, _, facing, origin = env._seat_start_frames(np.random.default_rng(0), env._target, "sit")
            offset = _pelvis(env)[:2] - origin[:2]
            bearings[level].append(_yaw_gap(math.atan2(offset[1], offset[0]), facing))
            if level == 0:
                assert 0.35 < np.hypot(*offset) < 1.1     # the sit's lateral spot is drawn anew: a little slack
                yaw = float(heading_angle(env.data.xmat[env._idx.pelvis_id].reshape(3, 3)))
                headings[0].append(_yaw_gap(yaw, facing))
    assert max(bearings[0]) < math.radians(45) and max(headings[0]) < math.radians(60)
    assert max(bearings[9]) > math.radians(90)
    with pytest.raises(ValueError, match="start_from_front"):
        SIMSEnv(skill="sit", start_from_front=True, **FAST)          # needs the distance curriculum
    with pytest.raises(ValueError, match="start_from_front"):
        SIMSEnv(skill="reach", start_distance_levels=10, start_from_front=True, **FAST)
