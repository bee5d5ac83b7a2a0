"""stairenv.evaluation.gait: the gait metrics on synthetic contact sequences, on the synthesised
reference climb replayed kinematically, and as opt-in columns of the InterLevel evaluation."""

from __future__ import annotations

import json
import math

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import stairenv  # noqa: F401  (registers the envs)
from stairenv.evaluation.gait import (
    AIR,
    CRAWL_PARTS,
    GAIT_FIELDS,
    GaitRecorder,
    GaitSummary,
    GaitTrace,
    fill_flicker,
    footholds,
    gait_columns,
    slip_speeds,
    summarize,
)
from stairenv.evaluation.interlevel import ROW_FIELDS, evaluate
from stairenv.motion.synthesis import climb_stairs
from stairenv.world.stairs import Staircase

R, L = 0, 1


def _steps(placements, swing=4, double=3, start=(0, 0)):
    """A (T, 2) support sequence: from both feet on ``start``, each (foot, level) placement lifts
    that foot for ``swing`` frames, then both feet stand for ``double`` frames."""
    levels = list(start)
    frames = [tuple(levels)] * double
    for foot, level in placements:
        air = list(levels)
        air[foot] = AIR
        frames += [tuple(air)] * swing
        levels[foot] = level
        frames += [tuple(levels)] * double
    return np.array(frames)


def _summary(support, num_steps=3, **kwargs) -> GaitSummary:
    return summarize(GaitTrace(support, num_steps=num_steps, **kwargs))


# --- (a) and (b): alternation and touchdowns per tread ------------------------------
def test_step_over_step():
    s = _summary(_steps([(R, 1), (L, 2), (R, 3), (L, 3)]))
    assert s.pattern == "step-over-step" and s.alternating
    assert s.arrival_feet == (R, L, R) and s.arrivals == 3 and s.top_level == 3
    assert s.touchdowns_per_tread == 1.0  # treads 1 and 2 once each; the landing does not count
    assert s.hops == 0 and not s.crawled


def test_step_to_step():
    s = _summary(_steps([(R, 1), (L, 1), (R, 2), (L, 2), (R, 3), (L, 3)]))
    assert s.pattern == "step-to-step" and not s.alternating
    assert s.arrival_feet == (R, R, R)
    assert s.touchdowns_per_tread == 2.0


def test_irregular_and_no_climb():
    # the right foot goes up twice in a row while the left never stands on tread 1
    s = _summary(_steps([(R, 1), (R, 2), (L, 3), (R, 3)]))
    assert s.pattern == "irregular" and not s.alternating and s.arrival_feet == (R, R, L)
    # walking on the floor is no climb
    s = _summary(_steps([(R, 0), (L, 0), (R, 0)]))
    assert s.pattern == "none" and s.arrivals == 0 and s.touchdowns_per_tread is None
    # one step onto tread 1, then nothing: one arrival is not a pattern
    assert _summary(_steps([(R, 1)])).pattern == "none"


def test_shuffles_raise_touchdowns_per_tread():
    # step over step, but the right foot re-places itself on tread 1 once
    s = _summary(_steps([(R, 1), (R, 1), (L, 2), (R, 3), (L, 3)]))
    assert s.pattern == "step-over-step"
    assert s.touchdowns_per_tread == 1.5  # (2 on tread 1 + 1 on tread 2) / 2 treads
    # a partial climb counts the treads reached: top level 2 of 5 risers -> treads 1 and 2
    s = _summary(_steps([(R, 1), (L, 2), (R, 2)]), num_steps=5)
    assert s.top_level == 2 and s.touchdowns_per_tread == 1.5


def test_flicker_is_merged_but_a_step_is_not():
    support = np.array([[0, 0], [0, AIR], [0, 0], [0, AIR], [0, AIR], [0, AIR], [0, 0]])
    filled = fill_flicker(support, merge_gap=2)
    assert filled[:, L].tolist() == [0, 0, 0, AIR, AIR, AIR, 0]  # 1 frame merged, 3 frames kept
    holds = [(h.foot, h.level, h.start, h.end) for h in footholds(GaitTrace(support))]
    assert holds == [(R, 0, 0, 6), (L, 0, 0, 2), (L, 0, 6, 6)]
    # a flicker onto another level is a foothold there
    assert [h.level for h in footholds(GaitTrace([[0, 0], [0, AIR], [0, 1]]))] == [0, 0, 1]


# --- (c) hops -----------------------------------------------------------------------
def _hop(right_land: int, left_land: int, right_level=1, left_level=1, takeoff_gap=0):
    """Both feet on the floor for 5 frames, left foot leaves ``takeoff_gap`` frames after the right,
    each lands at its frame on its level, and stays there until frame 30."""
    support = np.zeros((30, 2), dtype=int)
    support[5:right_land, R] = AIR
    support[right_land:, R] = right_level
    support[5 + takeoff_gap:left_land, L] = AIR
    support[left_land:, L] = left_level
    return _summary(support)


def test_hops():
    assert _hop(12, 12).hops == 1                                   # both feet up onto tread 1 together
    assert _hop(12, 14, right_level=1, left_level=2).hops == 1      # landing 2 frames apart, different treads
    assert _hop(12, 12, right_level=0, left_level=0).hops == 0      # a jump in place
    assert _hop(12, 22).hops == 0                                   # landings 0.33 s apart: a running step
    assert _hop(12, 12, takeoff_gap=4).hops == 1                    # take-offs 0.13 s apart
    assert _hop(15, 15, takeoff_gap=9).hops == 0                    # take-offs 0.3 s apart
    # a step-over-step climb has no flight at all
    assert _summary(_steps([(R, 1), (L, 2), (R, 3), (L, 3)])).hops == 0


# --- (d) crawling -------------------------------------------------------------------
def test_crawling():
    support = _steps([(R, 1), (L, 2), (R, 3), (L, 3)])
    contact = np.zeros((len(support), len(CRAWL_PARTS)), bool)
    contact[10:12, 0] = True  # a hand on a tread for 2 frames (67 ms): a touch, not a crawl
    s = _summary(support, body_contact=contact)
    assert math.isclose(s.crawl_time, 2 / 30) and not s.crawled and s.crawl_parts == ("arms",)
    contact[20:24, 1] = True  # a knee for 4 frames more
    s = _summary(support, body_contact=contact)
    assert math.isclose(s.crawl_time, 6 / 30) and s.crawled and s.crawl_parts == ("arms", "legs")


# --- (e) sliding --------------------------------------------------------------------
def test_sliding_foot():
    frames = 10
    support = np.zeros((frames, 2), dtype=int)
    foot_pos = np.zeros((frames, 2, 3))
    foot_pos[:, :, 2] = 0.05
    foot_pos[:, R, 0] = 0.01 * np.arange(frames)  # the right foot slides 1 cm a frame: 0.3 m/s
    contact = foot_pos - np.array([0.0, 0.0, 0.05])
    trace = GaitTrace(support, foot_pos=foot_pos, contact_point=contact)
    speeds = slip_speeds(trace)
    assert np.isnan(speeds[0]).all()
    np.testing.assert_allclose(speeds[1:, R], 0.3)
    np.testing.assert_allclose(speeds[1:, L], 0.0)
    s = summarize(trace)
    assert s.stance_frames == 18 and s.sliding_frames == 9 and s.slide_fraction == 0.5
    assert math.isclose(s.max_slip_speed, 0.3)
    # in the air there is no slip: the lifted frames and the frame after them are not stance
    support[4:6, R] = AIR
    speeds = slip_speeds(GaitTrace(support, foot_pos=foot_pos, contact_point=contact))
    assert np.isnan(speeds[4:7, R]).all() and np.isfinite(speeds[7:, R]).all()


def test_rolling_over_the_toe_is_not_sliding():
    """A foot pitching about its toe contact: the ankle moves forward and up, the toe stays."""
    frames = 8
    toe = np.array([0.3, 0.0, 0.0])
    ankle_from_toe = np.array([-0.13, 0.0, 0.05])
    foot_pos, foot_rot = np.zeros((frames, 2, 3)), np.zeros((frames, 2, 3, 3))
    for t in range(frames):
        angle = 0.1 * t  # heel rising
        c, s = math.cos(angle), math.sin(angle)
        rot = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
        foot_rot[t] = rot
        foot_pos[t] = toe + rot @ ankle_from_toe
    contact = np.broadcast_to(toe, (frames, 2, 3))
    trace = GaitTrace(np.zeros((frames, 2), dtype=int), foot_pos=foot_pos, foot_rot=foot_rot, contact_point=contact)
    assert np.ptp(foot_pos[:, R, 0]) > 0.02  # the foot body itself moves
    np.testing.assert_allclose(slip_speeds(trace)[1:], 0.0, atol=1e-12)
    # without the rotation the same positions read as sliding
    moved = GaitTrace(trace.support, foot_pos=foot_pos, contact_point=contact)
    assert np.nanmax(slip_speeds(moved)) > 0.1


def test_trace_checks_and_defaults():
    with pytest.raises(ValueError, match="support"):
        GaitTrace([[0, -2]])
    with pytest.raises(ValueError, match="dt"):
        GaitTrace([[0, 0]], dt=0.0)
    trace = GaitTrace(_steps([(R, 1), (L, 2)]))
    assert trace.num_steps == 2 and trace.body_contact.shape == (trace.frames, 3)
    s = summarize(trace)  # no poses: slip unknown
    assert s.stance_frames == 0 and s.slide_fraction is None and s.max_slip_speed is None
    assert summarize(GaitTrace(np.zeros((0, 2), dtype=int))).pattern == "none"


def test_gait_columns():
    climb = _summary(_steps([(R, 1), (L, 2), (R, 3), (L, 3)]))
    shuffle = _summary(_steps([(R, 1), (L, 1), (R, 2), (L, 2), (R, 3), (L, 3)]))
    hop = _summary(np.array([[0, 0]] * 5 + [[AIR, AIR]] * 5 + [[1, 1]] * 5))
    sliding = GaitSummary("none", False, 0, 0, None, 0, 0.0, False, (), stance_frames=10, sliding_frames=4,
                          max_slip_speed=0.5)
    columns = gait_columns([climb, shuffle, hop, sliding], [True, True, False, False])
    assert tuple(columns) == GAIT_FIELDS
    assert columns["alternating_pct"] == 50.0            # of the two successful climbs
    # over the episodes that reached a tread; the hop put both feet on tread 1
    assert columns["touchdowns_per_tread"] == pytest.approx((1.0 + 2.0 + 2.0) / 3)
    assert columns["hop_pct"] == 25.0 and columns["crawl_pct"] == 0.0
    assert columns["slide_pct"] == 40.0                  # pooled over stance frames (only the last has poses)
    empty = gait_columns([hop], [False])
    assert empty["alternating_pct"] is None and empty["slide_pct"] is None
    with pytest.raises(ValueError):
        gait_columns([hop], [])


# --- the reference climb, replayed kinematically --------------------------------------
# The synthesised clip keeps the soles 2 mm above the treads; the replay gives the foot geoms a
# 4 mm contact margin so that MuJoCo reports a standing foot's contacts (nothing is simulated).
REPLAY_FOOT_MARGIN = 0.004


def _replay(clip, stairs: Staircase):
    env = gym.make("InterLevel-v0")
    try:
        env.reset(seed=0, options={"stairs": stairs})
        model = env.unwrapped.model
        recorder = GaitRecorder(model)
        model.geom_margin[recorder.geom_foot >= 0] = REPLAY_FOOT_MARGIN
        data = mujoco.MjData(model)
        for qpos in clip.qpos:
            data.qpos[:] = qpos
            mujoco.mj_forward(model, data)  # kinematics and collision detection
            recorder.record(data)
        return recorder.trace(1.0 / clip.fps, stairs.num_steps)
    finally:
        env.close()


@pytest.mark.parametrize(("height", "depth", "lead"), [(0.05, 0.30, "right"), (0.15, 0.30, "left"),
                                                       (0.20, 0.32, "right")])
def test_reference_climb_reads_as_step_over_step(height, depth, lead):
    num_steps = 5
    clip = climb_stairs(height, depth, num_steps, lead_foot=lead)
    stairs = Staircase(**clip.meta["stairs"])
    trace = _replay(clip, stairs)
    s = summarize(trace)
    lead_index = R if lead == "right" else L
    assert s.pattern == "step-over-step" and s.alternating
    # one arrival per riser, the lead foot first, alternating up to the landing
    assert s.arrivals == num_steps and s.top_level == num_steps
    assert s.arrival_feet == tuple((lead_index + k) % 2 for k in range(num_steps))
    assert s.touchdowns_per_tread == 1.0
    assert s.hops == 0 and s.crawl_time == 0.0 and not s.crawled
    # planted feet: almost no stance frame slips faster than 0.1 m/s (touchdown transients at most)
    assert s.stance_frames > 150 and s.slide_fraction <= 0.02
    assert np.nanmedian(slip_speeds(trace)) < 0.01
    # every tread and the landing carries a foot at some time; the floor before
    assert set(np.unique(trace.support)) == {AIR, *range(num_steps + 1)}


# --- the evaluation's opt-in columns ---------------------------------------------------
def test_evaluation_gait_columns(tmp_path):
    fast = {"max_episode_steps": 30, "progress_bar": False}
    plain = evaluate("zero", episodes=2, step_heights=(0.10,), **fast)
    report = evaluate("zero", episodes=2, step_heights=(0.10,), gait=True, **fast)
    # same episodes, and the plain report keeps its columns, table and JSON
    assert [e.progress for e in plain.episodes] == [e.progress for e in report.episodes]
    assert all(e.gait is None for e in plain.episodes)
    assert tuple(plain.to_rows()[0]) == ROW_FIELDS and "Alt. (%)" not in plain.format_table()
    assert "gait" not in plain.to_dict()["episodes"][0] and "gait" not in plain.meta
    rows = report.to_rows()
    assert tuple(rows[0]) == ROW_FIELDS + GAIT_FIELDS
    for column in ("Alt. (%)", "TD/tread", "Hop (%)", "Crawl (%)", "Slide (%)"):
        assert column in report.format_table(compare_paper=True)
    for e in report.episodes:
        assert isinstance(e.gait, GaitSummary) and e.gait.stance_frames > 0
    # standing still: no climb, no hop, no crawl
    assert rows[0]["alternating_pct"] is None and rows[0]["touchdowns_per_tread"] is None
    assert rows[0]["hop_pct"] == 0.0 and rows[0]["crawl_pct"] == 0.0
    assert 0.0 <= rows[0]["slide_pct"] <= 100.0
    data = json.loads(report.to_json(tmp_path / "r.json").read_text())
    assert data["episodes"][0]["gait"]["pattern"] == "none" and data["gait"] is True
    assert set(GAIT_FIELDS) <= set(data["groups"][0])


def test_evaluate_script_gait_flag(baseline_script, capsys):
    script = baseline_script("evaluate")
    assert script.main(["--policy", "zero", "--episodes", "1", "--max-episode-steps", "10", "--no-progress",
                        "--gait"]) == 0
    assert "TD/tread" in capsys.readouterr().out
    assert script.main(["--policy", "zero", "--episodes", "1", "--max-episode-steps", "10", "--no-progress"]) == 0
    assert "TD/tread" not in capsys.readouterr().out


# --- baselines/filmstrip_climb.py ---------------------------------------------------------
def test_filmstrip_climb_zero_policy(baseline_script, tmp_path, capsys):
    from PIL import Image

    script = baseline_script("filmstrip_climb")
    combined = tmp_path / "docs" / "climb.png"
    assert script.main(["--policy", "zero", "--heights", "0.05", "0.20", "--frames", "3", "--width", "48",
                        "--height", "40", "--max-episode-steps", "20", "--out-dir", str(tmp_path / "strips"),
                        "--combined", str(combined)]) == 0
    out = capsys.readouterr().out
    assert "0.05 m, seed 0" in out and "touchdowns/tread" in out
    for h in ("0.05", "0.20"):
        strip = np.asarray(Image.open(tmp_path / "strips" / f"filmstrip_{h}m.png"))
        assert strip.shape == (script.CAPTION_HEIGHT + 40, 3 * 48 + 2 * script.GAP, 3)
        assert strip[script.CAPTION_HEIGHT:].std() > 5  # rendered, not blank
    assert combined.stat().st_size <= 300_000
    assert Image.open(combined).height > 2 * 40
    # ending before the frames run out: every state at most once, first and last included
    assert script.frame_indices(3, 8).tolist() == [0, 1, 2]
    assert script.frame_indices(100, 3).tolist() == [0, 50, 99]


def test_filmstrip_combined_fits_its_size(baseline_script):
    from PIL import Image

    script = baseline_script("filmstrip_climb")
    rng = np.random.default_rng(0)
    noise = [Image.fromarray(rng.integers(0, 256, (200, 800, 3), dtype=np.uint8)) for _ in range(2)]
    image, png = script.combine(noise, max_width=600, max_bytes=60_000)
    assert len(png) <= 60_000 and image.width <= 600
