"""Clip tracking (``stairenv.motion.tracking``, PlaMo's ``track_reward`` / ``max_track_error`` /
``clip_paths`` training aids): the reference played on and placed, the terms by hand, the path from the clip."""

from __future__ import annotations

import math
from importlib.resources import files
from pathlib import Path

import numpy as np
import pytest

from stairenv.environments.plamo import PlaMoEnv
from stairenv.humanoid.kinematics import body_positions
from stairenv.humanoid.state import PELVIS
from stairenv.motion.clip import MotionClip
from stairenv.motion.tracking import turn_frames, clip_frames, reference_track, yaw_between
from stairenv.tasks.terms import TRACKING_TERMS, tracking_terms

CRAWL = str(files("stairenv.motion.data.plamo") / "dm_crawl.npz")
CMU_CRAWL = str(files("stairenv.motion.data.cmu") / "cmu_crawl_133_01.npz")


def test_a_looping_clip_carries_on_cycle_after_cycle_and_others_hold_their_last_frame():
    crawl = MotionClip.load(CRAWL)
    assert crawl.loop
    dt = 1 / 30
    steps = int(3 * crawl.duration / dt)
    frames = clip_frames(crawl, 0.0, steps, dt)
    # no jump at the seams: each step moves the root about as far as the clip's own steps do
    hops = np.linalg.norm(np.diff(frames[:, :2], axis=0), axis=1)
    own = np.linalg.norm(np.diff(crawl.sample(np.arange(0, crawl.duration, dt))[:, :2], axis=0), axis=1)
    assert hops.max() < 2 * own.max() + 1e-9
    # three cycles travel about three times one cycle's distance, forwards
    one = np.linalg.norm(crawl.qpos[-1, :2] - crawl.qpos[0, :2])
    three = np.linalg.norm(frames[-1, :2] - frames[0, :2])
    assert 2.5 * one < three < 3.1 * one
    # joints repeat each cycle
    k = round(crawl.duration / dt)
    np.testing.assert_allclose(frames[k, 7:], crawl.sample(k * dt - crawl.duration)[0, 7:], atol=1e-9)
    cmu = MotionClip.load(CMU_CRAWL)
    assert not cmu.loop
    held = clip_frames(cmu, cmu.duration - 0.1, 30, dt)
    np.testing.assert_allclose(held[-1], cmu.qpos[-1], atol=1e-9)
    np.testing.assert_allclose(held[-1], held[-5], atol=1e-9)


def test_yaw_between_is_the_turn_about_z_even_for_a_pelvis_facing_the_floor():
    crawl = MotionClip.load(CRAWL)
    for frame in crawl.qpos[::20]:
        for angle in (-2.5, -0.3, 0.0, 0.9, 3.0):
            turned = turn_frames(frame[None], angle, frame[:2], frame[:2])[0]
            assert yaw_between(frame[3:7], turned[3:7]) == pytest.approx(angle, abs=1e-9)


def test_a_looping_clips_next_cycle_starts_where_the_last_ended_moved_not_turned():
    crawl = MotionClip.load(CRAWL)
    k = crawl.num_frames - 1   # one cycle at the clip's own rate
    frames = clip_frames(crawl, 0.0, 2 * k, 1 / crawl.fps)
    first, last = crawl.qpos[0], crawl.qpos[-1]
    travel = last[:2] - first[:2]
    # the seam: the first frame moved by one cycle's travel (DeepMimic's cycle offset), not turned
    np.testing.assert_allclose(frames[k, :2], last[:2], atol=1e-9)
    np.testing.assert_allclose(frames[k, 2:], first[2:], atol=1e-9)
    np.testing.assert_allclose(frames[2 * k, :2], first[:2] + 2 * travel, atol=1e-9)
    # so the course is straight: every cycle's frames are the first cycle's, moved along the travel
    np.testing.assert_allclose(frames[k:2 * k, :2] - frames[:k, :2], np.broadcast_to(travel, (k, 2)), atol=1e-9)


def test_the_track_starts_where_the_character_was_placed_and_moves_rigidly_with_it():
    crawl = MotionClip.load(CRAWL)
    start = crawl.sample(0.7)[0]
    placed = turn_frames(start[None], 1.2, start[:2], np.array([1.0, -2.0]))[0, :7]   # turned 1.2 rad, moved
    placed[2] = 0.5
    track = reference_track(crawl, 0.7, 60, 1 / 30, placed)
    np.testing.assert_allclose(track.qpos[0, :3], placed[:3], atol=1e-12)
    np.testing.assert_allclose(track.qpos[0, 3:7], placed[3:7], atol=1e-9)      # the start frame is the placed root
    own = clip_frames(crawl, 0.7, 60, 1 / 30)
    np.testing.assert_allclose(track.qpos[:, 7:], own[:, 7:], atol=1e-12)   # joints untouched
    # distances between frames are those of the clip (a rigid move), heights shifted by one offset
    np.testing.assert_allclose(np.linalg.norm(track.qpos[:, :2] - track.qpos[0, :2], axis=1),
                               np.linalg.norm(own[:, :2] - own[0, :2], axis=1), atol=1e-9)
    np.testing.assert_allclose(track.qpos[:, 2] - own[:, 2], placed[2] - own[0, 2], atol=1e-12)
    np.testing.assert_allclose(track.body_pos, body_positions(track.qpos), atol=1e-12)
    np.testing.assert_allclose(track.root_vel[5], (track.qpos[6, :3] - track.qpos[4, :3]) * 15, atol=1e-9)


def test_the_tracking_terms_are_the_documented_equations():
    rng = np.random.default_rng(1)
    ref = rng.normal(0.0, 0.5, (15, 3))
    body = ref + rng.normal(0.0, 0.1, (15, 3))
    v, v_ref = np.array([0.3, -0.1, 0.0]), np.array([0.5, 0.2, 0.1])
    root, velocity, bodies, error = tracking_terms(body, ref, v, v_ref, 2.0, root=PELVIS)
    d = body[PELVIS] - ref[PELVIS]
    assert root == pytest.approx(2.0 * 0.4 * math.exp(-5.0 * sum(x * x for x in d)), rel=1e-12)
    assert velocity == pytest.approx(2.0 * 0.3 * math.exp(-2.0 * (0.2 ** 2 + 0.3 ** 2 + 0.1 ** 2)), rel=1e-12)
    relative = [sum(((body[b][i] - body[PELVIS][i]) - (ref[b][i] - ref[PELVIS][i])) ** 2 for i in range(3))
                for b in range(15)]
    assert bodies == pytest.approx(2.0 * 0.3 * math.exp(-10.0 * sum(relative) / 15), rel=1e-12)
    distances = [math.dist(body[b], ref[b]) for b in range(15)]
    assert error == pytest.approx(sum(distances) / 15, rel=1e-12)
    assert tracking_terms(ref, ref, v, v, 1.0, root=PELVIS) == pytest.approx((0.4, 0.3, 0.3, 0.0))


def _crawl_env(**keywords):
    return PlaMoEnv(reference_motion=CRAWL, matched_starts=False, terrain="flat", locomotion="crawl",
                    max_xy_error=100.0, **keywords)


def test_the_env_pays_the_tracking_terms_against_its_track_and_ends_a_lost_track():
    env = _crawl_env(init="reference", track_reward=1.5, max_track_error=0.3)
    env.reset(seed=3)
    track = env._track
    np.testing.assert_allclose(track.qpos[0, :3], env.data.qpos[:3], atol=1e-12)
    rng = np.random.default_rng(0)
    for _ in range(3):
        _, reward, terminated, _, info = env.step(rng.normal(0.0, 0.1, 28))
        body = np.array([env.data.xpos[i] for i in env._idx.body_ids])
        expected = tracking_terms(body, track.body_pos[env._steps], env.data.qvel[:3], track.root_vel[env._steps],
                                  1.5, PELVIS)
        assert [info[name] for name in TRACKING_TERMS] == pytest.approx(expected[:3], rel=1e-9)
        path = sum(info[name] for name in ("reward_position", "reward_height", "reward_direction", "reward_body"))
        assert reward == pytest.approx(path + sum(expected[:3]), rel=1e-12)
        assert info["track_lost"] == (expected[3] > 0.3) == terminated
    # held still, the character falls behind the crawl: the track is lost within the episode
    env.reset(seed=3)
    for step in range(300):
        _, _, terminated, truncated, info = env.step(np.zeros(28))
        if terminated or truncated:
            break
    assert terminated and info["track_lost"] and step < 299
    # a standing start has no clip: no track, zero terms, never lost; without the aids no entries
    standing = _crawl_env(init="default", track_reward=1.5, max_track_error=0.3)
    standing.reset(seed=3)
    info = standing.step(np.zeros(28))[4]
    assert standing._track is None and info["reward_track_root"] == 0.0 and not info["track_lost"]
    plain = _crawl_env(init="reference")
    plain.reset(seed=3)
    info = plain.step(np.zeros(28))[4]
    assert plain._track is None and "reward_track_root" not in info and "track_lost" not in info


def test_clip_paths_ask_for_the_clips_own_head():
    env = _crawl_env(init="reference", clip_paths=True)
    env.reset(seed=5)
    head = env._head()[0]
    np.testing.assert_allclose(env.path.points[0], head, atol=1e-9)   # the path starts at the head
    np.testing.assert_allclose(env.path.points, env._track.head, atol=0)
    assert env.path.dt == env.dt
    travelled = np.linalg.norm(env.path.points[int(4 / env.dt), :2] - env.path.points[0, :2])
    assert 0.5 < travelled < 3.0     # the crawl's 0.26-0.44 m/s over 4 s
    assert np.all(np.abs(env.path.head - env._track.head[:, 2]) < 1e-12)   # flat ground: heights are z
    drawn = _crawl_env(init="reference")
    drawn.reset(seed=5)
    assert drawn._track is None and not np.array_equal(drawn.path.points[:5], env.path.points[:5])


def test_tracking_keywords_are_checked():
    with pytest.raises(ValueError, match="track_reward"):
        PlaMoEnv(track_reward=-1.0)
    with pytest.raises(ValueError, match="max_track_error"):
        PlaMoEnv(max_track_error=0.0)
    with pytest.raises(TypeError, match="clip_paths"):
        PlaMoEnv(clip_paths="yes")


GET_DOWN = str(files("stairenv.motion.data.stitched") / "get_down_forearm_crawl.npz")
WALK_CRAWL = str(files("stairenv.motion.data.cmu") / "cmu_walk_crawl_walk_133_01.npz")


def test_stitch_plays_the_lead_then_blends_into_the_follow_clip_placed_on_the_leads_root():
    from stairenv.motion.stitch import stitch

    lead, crawl = MotionClip.load(WALK_CRAWL), MotionClip.load(CRAWL)
    clip = stitch(lead, (1.87, 3.4), crawl, 0.67, 0.8, 8.0, on_floor=False)
    assert clip.fps == 30.0 and clip.num_frames == 241 and not clip.loop
    assert clip.meta["stitched"]["window_s"] == [1.87, 3.4]
    # before the blend: the lead's frames (moved to start at the origin), joints untouched
    own = lead.sample(1.87 + np.arange(40) / 30)
    np.testing.assert_allclose(clip.qpos[:40, 7:], own[:, 7:], atol=1e-9)
    np.testing.assert_allclose(clip.qpos[:40, :2] - clip.qpos[0, :2], own[:, :2] - own[0, :2], atol=1e-9)
    # after it: the crawl's joints, cycle after cycle, its travel as long as the crawl's own
    after = clip_frames(crawl, 0.67, 240, 1 / 30)
    np.testing.assert_allclose(clip.qpos[72:, 7:], after[26:26 + 169, 7:], atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(clip.qpos[-1, :2] - clip.qpos[72, :2]),
                               np.linalg.norm(after[26 + 168, :2] - after[26, :2]), atol=1e-9)
    # no jump anywhere: each step moves the root no further than the faster part's steps do
    hops = np.linalg.norm(np.diff(clip.qpos[:, :3], axis=0), axis=1)
    own_hops = max(np.linalg.norm(np.diff(own[:, :3], axis=0), axis=1).max(),
                   np.linalg.norm(np.diff(after[:, :3], axis=0), axis=1).max())
    assert hops.max() < 1.5 * own_hops
    # heading: the crawl goes on the way the kneeling person was moving
    lead_way = lead.sample(3.4)[0, :2] - lead.sample(2.9)[0, :2]
    crawl_way = clip.qpos[-1, :2] - clip.qpos[72, :2]
    cosine = lead_way @ crawl_way / np.linalg.norm(lead_way) / np.linalg.norm(crawl_way)
    assert cosine > 0.8
    with pytest.raises(ValueError, match="window"):
        stitch(lead, (3.0, 2.0), crawl, 0.0, 0.5, 8.0)
    with pytest.raises(ValueError, match="duration"):
        stitch(lead, (1.0, 3.0), crawl, 0.0, 0.5, 2.0)
    with pytest.raises(ValueError, match="follow_start"):
        stitch(lead, (1.0, 3.0), crawl, 9.0, 0.5, 8.0)


def test_the_shipped_get_down_stands_then_crawls_low():
    from stairenv.motion.plamo_set import head_heights

    clip = MotionClip.load(GET_DOWN)
    heads = head_heights(clip.qpos)
    assert heads[0] > 1.3                                   # standing
    assert 0.28 < np.median(heads[int(3 * clip.fps):]) < 0.5   # the planner's crawl heads: 0.30-0.50 m
    assert clip.meta["locomotion"] == "crawl" and clip.duration >= 14.0


def test_a_standing_start_tracks_the_standing_clip_from_its_first_frame():
    env = _crawl_env(init="default", track_reward=1.0, max_track_error=0.6, clip_paths=True, pose_reward=1.0,
                     standing_clip=GET_DOWN)
    env.reset(seed=4)
    clip = MotionClip.load(GET_DOWN)
    assert env._reference_clip[1] == 0.0 and env._track is not None
    # the track is the clip from its first frame, placed on the standing character's root
    np.testing.assert_allclose(env._track.qpos[:, 7:], clip_frames(clip, 0.0, len(env._track.qpos) - 1,
                                                                   env.dt)[:, 7:], atol=1e-12)
    np.testing.assert_allclose(env._track.qpos[0, :2], env.data.qpos[:2], atol=1e-12)
    np.testing.assert_allclose(env.path.points, env._track.head, atol=0)      # its path: the clip's head
    info = env.step(np.zeros(28))[4]
    assert info["reward_track_root"] > 0.0 and info["reward_pose"] > 0.0 and not info["reference_start"]
    # held standing, the character is left behind as the clip gets down: the track is lost
    for _ in range(120):
        _, _, terminated, _, info = env.step(np.zeros(28))
        if terminated:
            break
    assert terminated and info["track_lost"]
    with pytest.raises(ValueError, match="standing_clip"):
        PlaMoEnv(standing_clip="/no/such/clip.npz")
    env = _crawl_env(init="default", clip_paths=True, standing_clip=str(Path(GET_DOWN).parent))
    drawn = set()
    for seed in range(8):
        env.reset(seed=seed)
        drawn.add(env._reference_clip[0].name)
    assert len(drawn) > 1    # a folder: one of its clips drawn per standing start
    with pytest.raises(TypeError, match="standing_clip"):
        PlaMoEnv(standing_clip=3)


def test_bend_curves_a_straight_course_into_an_arc_keeping_its_pace():
    from stairenv.motion.tracking import bend

    n, dt, v, omega = 91, 1 / 30, 0.5, 0.6
    straight = np.zeros((n, 35))
    straight[:, 0] = v * dt * np.arange(n)                  # along x at 0.5 m/s, facing x
    straight[:, 2], straight[:, 3] = 0.9, 1.0
    straight[:, 7:] = np.linspace(0, 1, n)[:, None]
    bent = bend(straight, omega, dt)
    np.testing.assert_array_equal(bend(straight, 0.0, dt), straight)
    np.testing.assert_array_equal(bent[:, 7:], straight[:, 7:])            # joints and heights untouched
    np.testing.assert_array_equal(bent[:, 2], straight[:, 2])
    steps = np.linalg.norm(np.diff(bent[:, :2], axis=0), axis=1)
    np.testing.assert_allclose(steps, v * dt, atol=1e-12)                  # the same pace
    # the course is (to the step's discretisation) the arc of radius v / omega, turning left
    radius = v / omega
    centre = np.array([0.0, radius])
    np.testing.assert_allclose(np.linalg.norm(bent[:, :2] - centre, axis=1), radius, atol=0.01)
    # each frame faces turned by omega * t
    for k in (0, 30, 90):
        assert yaw_between(straight[k, 3:7], bent[k, 3:7]) == pytest.approx(omega * k * dt, abs=1e-9)


def test_a_track_played_faster_shows_the_clips_frames_sooner_and_travels_faster():
    crawl = MotionClip.load(CRAWL)
    placed = crawl.sample(0.2)[0, :7]
    slow = reference_track(crawl, 0.2, 90, 1 / 30, placed)
    fast = reference_track(crawl, 0.2, 90, 1 / 30, placed, rate=2.0)
    np.testing.assert_allclose(fast.qpos[:46, 7:], slow.qpos[::2, 7:], atol=1e-9)
    speed = lambda track: np.linalg.norm(track.head[-1, :2] - track.head[0, :2])  # noqa: E731
    assert speed(fast) > 1.7 * speed(reference_track(crawl, 0.2, 90, 1 / 30, placed))


def test_the_env_draws_each_episodes_cadence_and_bend_only_when_asked():
    env = _crawl_env(init="reference", clip_paths=True, track_reward=1.0, track_rate=(0.5, 3.0),
                     track_turn_rate=0.8)
    speeds, turns = [], []
    for seed in range(12):
        env.reset(seed=seed)
        head = env._track.head
        speeds.append(np.linalg.norm(head[150, :2] - head[0, :2]) / 5.0)
        heading = np.unwrap(np.arctan2(*np.diff(head[::30, :2], axis=0).T[::-1]))
        turns.append(heading[-1] - heading[0])
        np.testing.assert_allclose(env.path.points, head, atol=0)
    assert max(speeds) > 2.5 * min(speeds)           # cadences drawn from (0.5, 3.0)
    assert max(turns) > 0.5 and min(turns) < -0.5    # bends both ways
    plain = _crawl_env(init="reference", clip_paths=True, track_reward=1.0)
    plain.reset(seed=3)
    same = reference_track(plain._reference_clip[0], plain._reference_clip[1], len(plain._track.qpos) - 1,
                           plain.dt, plain._track.qpos[0, :7])
    np.testing.assert_allclose(plain._track.qpos, same.qpos, atol=1e-12)


@pytest.mark.parametrize("name, window, follow, blend", [
    ("get_down_forearm_crawl", (1.87, 3.4), "dm_crawl", 0.8),
    ("crouch/stand_crouch_walk_0.71m", (1.7, 1.87), "crouch/crouch_walk_0.71m_1.0mps", 1.2),
    ("stand_jog", (1.7, 1.87), "dm_jog", 1.0),
])
def test_the_shipped_stitched_clips_are_what_their_notice_says(name, window, follow, blend):
    from stairenv.motion.plamo_set import label_clip
    from stairenv.motion.stitch import stitch

    data = Path(WALK_CRAWL).parents[1]
    shipped = MotionClip.load(data / "stitched" / f"{name}.npz")
    follow_clip = MotionClip.load(data / ("" if "/" in follow else "plamo") / f"{follow}.npz")
    start = 0.67 if follow == "dm_crawl" else 0.0
    made = label_clip(stitch(MotionClip.load(WALK_CRAWL), window, follow_clip, start, blend, 16.0,
                             name=name.split("/")[-1]),
                      shipped.meta["locomotion"])
    assert made.num_frames == shipped.num_frames
    np.testing.assert_allclose(made.qpos, shipped.qpos, atol=1e-6)   # tolerances: another CPU's low bits
    assert name.split("/")[-1].rsplit("_", 1)[0] in (data / "stitched" / "NOTICE.txt").read_text()


def _first_step_pays_the_terms(env, track, weight: float):
    """One zero-action step of ``env`` (its track just built on the placed state): the info's tracking terms
    are ``tracking_terms`` of the state against the track's next frame, by hand. Returns (reward, the terms)."""
    from stairenv.humanoid.kinematics import body_positions as fk_bodies

    np.testing.assert_allclose(track.body_pos, fk_bodies(track.qpos), atol=1e-9)
    _, reward, _, _, info = env.step(np.zeros(28))
    state = env._read_state()
    expected = tracking_terms(state.body_pos[0], track.body_pos[1], state.root_lin_vel[0], track.root_vel[1], weight,
                              root=PELVIS)
    assert [info[name] for name in TRACKING_TERMS] == pytest.approx(expected[:3], rel=1e-9)
    return reward, info, sum(expected[:3])


def test_a_sims_interaction_start_tracks_its_clip_and_pays_the_terms_by_hand():
    from stairenv.environments.sims import SIMSEnv

    env = SIMSEnv(skill="sit", text_encoder="hashing", interaction_start_fraction=1.0, track_reward=2.0,
                  max_track_error=0.4)
    for seed in range(6):
        env.reset(seed=seed)
        if env._interaction_start:
            break
    assert env._interaction_start and env._track is not None
    track = env._track
    # the track starts on the placed state: the start frame, where the character stands
    np.testing.assert_allclose(track.qpos[0, :3], env.data.qpos[:3], atol=1e-6)
    reward, info, tracked = _first_step_pays_the_terms(env, track, 2.0)
    assert reward == pytest.approx(info["reward_near"] + info["reward_far"] + tracked, rel=1e-12)
    # held still while the clip sits down, the character is left behind: the track is lost
    for _ in range(120):
        _, _, terminated, truncated, info = env.step(np.zeros(28))
        if terminated or truncated:
            break
    assert (terminated and info["track_lost"]) or info["success"]
    # a standing start has no clip: zero terms, never lost; without the aids no entries
    standing = SIMSEnv(skill="sit", text_encoder="hashing", interaction_start_fraction=1e-9, track_reward=2.0)
    standing.reset(seed=0)
    info = standing.step(np.zeros(28))[4]
    assert standing._track is None and info["reward_track_root"] == 0.0
    plain = SIMSEnv(skill="sit", text_encoder="hashing", interaction_start_fraction=1.0)
    plain.reset(seed=0)
    assert "reward_track_root" not in plain.step(np.zeros(28))[4]
    with pytest.raises(ValueError, match="interaction_start_fraction"):
        SIMSEnv(skill="sit", track_reward=1.0)


def test_an_interlevel_stair_start_tracks_its_climb_and_pays_the_terms_by_hand():
    from stairenv.environments.interlevel import InterLevelEnv

    kwargs = dict(stairs_start_fraction=1.0, step_height=(0.10, 0.10), step_depth=(0.30, 0.30))
    env = InterLevelEnv(**kwargs, track_reward=2.0, max_track_error=0.4)
    env.reset(seed=2)
    start = env.data.qpos.copy()
    track = env._track
    assert env._stairs_start and track is not None
    np.testing.assert_allclose(track.qpos[0], env.data.qpos, atol=1e-6)          # starts on the placed state
    reward, info, tracked = _first_step_pays_the_terms(env, track, 2.0)
    paper = sum(info[name] for name in env._outcome_terms if name not in TRACKING_TERMS)
    assert reward == pytest.approx(paper + tracked, rel=1e-9)
    for _ in range(150):    # held still while the climb goes on: lost (or fallen)
        _, _, terminated, truncated, info = env.step(np.zeros(28))
        if terminated or truncated:
            break
    assert terminated and (info["track_lost"] or info["fell"])
    # the same draws as without the aid: the same staircase and start
    plain = InterLevelEnv(**kwargs)
    plain.reset(seed=2)
    np.testing.assert_array_equal(plain.data.qpos, start)
    with pytest.raises(ValueError, match="stairs_start_fraction"):
        InterLevelEnv(track_reward=1.0)


def _playback(env) -> np.ndarray:
    """The action whose PD targets are the start clip's next frame (``baselines/distill_sims.py``'s teacher)."""
    track = env._track
    return env.action_of_targets(track.qpos[track.frame(env._steps + 1), 7:])


def test_a_sims_hold_cuts_the_episode_after_the_goal_is_held_for_its_seconds():
    import gymnasium as gym

    from stairenv.environments.sims import SIMSEnv

    hold = 0.5
    needed = math.ceil(hold * 30 - 1e-6)    # steps of success in a row (30 Hz)
    cut = 0
    for seed in range(6):
        env = SIMSEnv(skill="sit", text_encoder="hashing", interaction_start_fraction=1.0, track_reward=2.0,
                      hold_seconds=hold)
        env.reset(seed=seed)
        run = 0
        for _ in range(300):
            _, _, terminated, truncated, info = env.step(_playback(env))
            run = run + 1 if info["success"] else 0
            assert info["held"] == (run >= needed and not terminated)
            assert truncated == info["held"]    # cut, not terminated: the trainer bootstraps its value
            if terminated or truncated:
                break
        cut += bool(truncated)
        assert not truncated or run == needed
    assert cut >= 3    # the played-back sit holds the seat in most starts
    # batched: the same seeds cut at the same steps; without the aid no "held" and no cut
    vec = gym.make_vec("SIMS-Sit-v0", num_envs=2, vectorization_mode="vector_entry_point", text_encoder="hashing",
                       interaction_start_fraction=1.0, track_reward=2.0, hold_seconds=hold)
    single = [SIMSEnv(skill="sit", text_encoder="hashing", interaction_start_fraction=1.0, track_reward=2.0,
                      hold_seconds=hold) for _ in range(2)]
    vec.reset(seed=[3, 4])
    for k, env in enumerate(single):
        env.reset(seed=3 + k)
    worlds = [env.unwrapped for env in vec.unwrapped.envs]
    live = [True, True]
    for _ in range(120):
        actions = np.stack([_playback(w) for w in worlds])
        _, _, terminated, truncated, _ = vec.step(actions)
        for k, env in enumerate(single):
            if live[k]:
                _, _, term, trunc, _ = env.step(actions[k])
                assert (term, trunc) == (terminated[k], truncated[k])
                live[k] = not (term or trunc)
        if not any(live):
            break
    plain = SIMSEnv(skill="sit", text_encoder="hashing", interaction_start_fraction=1.0, track_reward=2.0)
    plain.reset(seed=0)
    _, _, _, truncated, info = plain.step(_playback(plain))
    assert "held" not in info and not truncated
    with pytest.raises(ValueError, match="hold_seconds"):
        SIMSEnv(skill="sit", hold_seconds=-1.0)
