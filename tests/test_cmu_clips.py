"""The captured CMU clips (``stairenv.motion.cmu_set``): shipped converted, labelled truly, each named in the
NOTICE with its trial, origin and licence; what each shows checked on the clip itself."""

from __future__ import annotations

import numpy as np
import pytest

from stairenv.humanoid.kinematics import geom_lowest_points
from stairenv.motion.cmu_set import CLIPS, DATA_DIR, load_cmu_clips
from stairenv.motion.plamo_set import LOCOMOTION_TYPES, measure


@pytest.fixture(scope="module")
def clips():
    return {clip.name: clip for clip in load_cmu_clips()}


def test_every_listed_clip_ships_and_loads(clips):
    assert set(clips) == {captured.name for captured in CLIPS}
    for captured in CLIPS:
        clip = clips[captured.name]
        assert clip.fps == 30 and clip.num_frames >= 30 and np.isfinite(clip.qpos).all()
        assert clip.meta["locomotion"] == captured.locomotion and captured.locomotion in LOCOMOTION_TYPES
        assert clip.meta["origin"] == captured.origin and captured.trial in clip.meta["source_file"]


def test_labels_are_what_the_clip_measures(clips):
    """The head heights, speeds and flight in ``meta`` are the clip's own (forward kinematics again)."""
    for clip in clips.values():
        again = measure(clip)
        assert again["head_height"] == pytest.approx(clip.meta["head_height"], abs=1e-3)
        assert again["speed"] == pytest.approx(clip.meta["speed"], abs=1e-3)
        assert again["flight_fraction"] == pytest.approx(clip.meta["flight_fraction"], abs=1e-3)
        assert clip.meta["penetration"] < 0.05    # on its floor, not in it


def test_each_clip_shows_its_locomotion(clips):
    """A run leaves the ground and is fast; a crawl holds the head low with knees and hands down; a crouched
    walk keeps the head between a crawl's and a walk's; a transition goes from standing height to a crawl's."""
    for clip in clips.values():
        kind, meta = clip.meta["locomotion"], clip.meta
        if meta.get("transition"):
            low, high = meta["head_height_range"]
            assert low < 0.8 and high > 1.25, clip.name
        elif kind == "run":
            assert meta["flight_fraction"] > 0.2 and meta["mean_speed"] > 2.0, clip.name
        elif kind == "crawl":
            lowest, _ = geom_lowest_points(clip.qpos)
            assert meta["head_height"] < 0.75 and np.median(lowest.min(axis=1)) < 0.05, clip.name
        elif kind == "crouch-walk":
            assert 0.8 < meta["head_height"] < 1.45 and meta["flight_fraction"] < 0.2, clip.name


def test_notice_names_every_clip_with_trial_origin_and_licence(clips):
    notice = (DATA_DIR / "NOTICE.txt").read_text()
    assert "mocap.cs.cmu.edu" in notice and "NSF EIA-0196217" in notice
    for captured in CLIPS:
        line = next(line for line in notice.splitlines() if line.startswith(captured.name + " "))
        assert captured.trial in line, captured.name
        assert captured.origin.split(" @ ")[1].split(" : ")[0][:7] in notice, captured.name


def test_the_stair_ascent_is_step_over_step(clips):
    """CMU 83_32: each new tread is reached by the other foot than the last (left, right, left: ~0.19 m steps),
    the character starting on its floor (z = 0 under the first frames) and ending ~0.56 m up."""
    from stairenv.humanoid.kinematics import body_positions
    from stairenv.humanoid.model import BODY_NAMES

    clip = clips["cmu_stairs_up_83_32"]
    assert clip.meta["terrain"] == "stairs"
    positions = body_positions(clip.qpos)
    plants = []    # (time, foot, height) of each still stretch of a foot
    for foot in ("right_foot", "left_foot"):
        track = positions[:, BODY_NAMES.index(foot)]
        still = np.linalg.norm(np.gradient(track[:, :2], axis=0), axis=1) * clip.fps < 0.15
        edges = np.flatnonzero(np.diff(np.concatenate(([0], still.astype(int), [0]))))
        for start, end in zip(edges[::2], edges[1::2]):
            if end - start >= 4:
                plants.append((start, foot, float(np.median(track[start:end, 2]))))
    plants.sort()
    ground = min(height for _, _, height in plants)
    rising, level = [], ground + 0.1
    for _, foot, height in plants:
        if height > level:            # a new, higher tread
            rising.append(foot)
            level = height + 0.1
    assert len(rising) == 3 and rising[0] != rising[1] != rising[2]
    top = max(height for _, _, height in plants) - ground
    assert 0.5 < top < 0.62
