"""PlaMo's reference motion (``builtin:plamo``): shipped, labelled, every locomotion type, PlaMo's default."""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pytest

from stairenv.motion import plamo_set
from stairenv.motion.clip import MotionClip
from stairenv.motion.plamo_set import (CONVERTED, DATA_DIR, LOCOMOTION_TYPES, SYNTHESISED, head_heights,
                                       load_plamo_clips, measure)
from stairenv.planning.locomotion import LOCOMOTIONS

REPO = Path(__file__).resolve().parents[1]
# the raw files beside the checkout (../shared/motions); STAIRENV_MOTIONS names another place (a worktree's)
MOTIONS = Path(os.environ.get("STAIRENV_MOTIONS", REPO.parent / "shared" / "motions"))
HEAD_TOLERANCE = 0.01  # m: a label against the head height measured again


@pytest.fixture(scope="module")
def clips() -> list[MotionClip]:
    return load_plamo_clips()


def test_the_set_ships_inside_the_package_and_is_small(clips):
    assert DATA_DIR.is_dir() and DATA_DIR.is_relative_to(Path(plamo_set.__file__).resolve().parent)
    files = sorted(DATA_DIR.glob("*.npz"))
    assert [f.stem for f in files] == sorted(c.name for c in clips)
    assert {c.name for c in clips} == {r.name for r in CONVERTED} | {entry[0] for entry in SYNTHESISED}
    assert sum(f.stat().st_size for f in files) < 2_000_000
    for clip in clips:  # loaded from the package: no path of this machine (../shared) recorded
        assert not Path(clip.source).is_absolute() and "shared" not in clip.source
        assert all(not (isinstance(v, str) and v.startswith("/")) for v in clip.meta.values())


def test_the_builtin_set_loads_with_every_locomotion_type_weighted_equally(clips):
    from stairenv.motion.rsi import BUILTIN_REFERENCE_SETS, load_reference_library

    assert "builtin:plamo" in BUILTIN_REFERENCE_SETS
    library = load_reference_library("builtin:plamo")
    kinds = [clip.meta["locomotion"] for clip in library.clips]
    assert set(kinds) == set(LOCOMOTION_TYPES)
    for kind in LOCOMOTION_TYPES:
        share = sum(p for p, k in zip(library.probabilities, kinds) if k == kind)
        assert share == pytest.approx(0.25)
    qpos, qvel = library.states(*library.sample(16, np.random.default_rng(0)))
    assert qpos.shape == (16, 35) and qvel.shape == (16, 34) and np.isfinite(qvel).all()


@pytest.mark.parametrize("name", [r.name for r in CONVERTED] + [entry[0] for entry in SYNTHESISED])
def test_labels_match_the_measured_motion(clips, name):
    clip = next(c for c in clips if c.name == name)
    meta = clip.meta
    kind = LOCOMOTIONS[meta["locomotion"]]
    heads = head_heights(clip.qpos)
    assert meta["head_height"] == pytest.approx(heads.mean(), abs=HEAD_TOLERANCE)
    assert meta["head_height_range"] == pytest.approx([heads.min(), heads.max()], abs=HEAD_TOLERANCE)
    # the label's type is the planner's whose nominal head height is nearest (walk and run share it:
    # the speed tells them apart)
    nearest = min(abs(loc.head_height - meta["head_height"]) for loc in LOCOMOTIONS.values())
    assert abs(kind.head_height - meta["head_height"]) == pytest.approx(nearest)
    speed = np.linalg.norm(clip.qpos[-1, :2] - clip.qpos[0, :2]) / clip.duration
    assert meta["speed"] == pytest.approx(speed, abs=0.01)
    assert 0.1 < meta["speed"] <= kind.speed_max  # moving (the stealthy walk's 0.40 m/s is below walk's 0.5)
    if kind.name == "run":
        assert meta["speed"] >= kind.speed_min
    assert meta["terrain"] == "flat"
    again = measure(clip)
    for key in ("flight_fraction", "penetration", "median_lowest_point"):
        assert meta[key] == pytest.approx(again[key], abs=1e-3)


def test_clips_touch_the_floor_and_runs_fly(clips):
    for clip in clips:
        meta = clip.meta
        assert abs(meta["median_lowest_point"]) < 0.03, clip.name   # on its support, not floating
        if meta["locomotion"] == "run":
            assert meta["flight_fraction"] > 0.25, clip.name         # a flight phase
        else:
            assert meta["flight_fraction"] < 0.05, clip.name
        if meta["locomotion"] == "crouch-walk":
            assert meta["penetration"] < 0.005

def test_the_crawl_is_on_its_knees_with_the_arms_down(clips):
    """What the DeepMimic crawl is once converted (looked at in its filmstrip): low, on knees and
    shins most of the time, forearms and hands close to the floor; its hands touch it in few frames
    (the source's hands stay >= 2 cm above its own floor too)."""
    from stairenv.humanoid import humanoid_model
    from stairenv.humanoid.kinematics import geom_lowest_points, humanoid_geoms
    from stairenv.humanoid.model import HumanoidIndices

    model = humanoid_model()
    geoms = humanoid_geoms(model, HumanoidIndices.from_model(model))
    body = np.array([model.body(model.geom_bodyid[g]).name for g in geoms])
    crawl = next(c for c in clips if c.name == "dm_crawl")
    lowest, _ = geom_lowest_points(crawl.qpos)
    shins = lowest[:, np.isin(body, ["right_shin", "left_shin"])].min(axis=1)
    arms = lowest[:, np.isin(body, ["right_lower_arm", "left_lower_arm", "right_hand", "left_hand"])].min(axis=1)
    assert np.mean(shins < 0.03) > 0.8
    assert np.median(arms) < 0.08
    assert crawl.meta["head_height"] < 0.45 and np.median(crawl.qpos[:, 2]) < 0.45


def test_notice_names_every_shipped_clip_with_source_and_licence(clips):
    notice = (DATA_DIR / "NOTICE.txt").read_text()
    for clip in clips:
        assert re.search(rf"^{re.escape(clip.name)}\b", notice, re.M) or clip.name in notice, clip.name
    for recipe in CONVERTED:
        line = next(line for line in notice.splitlines() if line.startswith(recipe.name + " "))
        assert recipe.source in line and recipe.licence in line
    assert "MIT License" in notice and "BSD 3-Clause License" in notice
    assert "mocap.cs.cmu.edu" in notice  # the CMU acknowledgement the IsaacGymEnvs clips carry


def test_the_wheel_config_carries_the_clips():
    text = (REPO / "pyproject.toml").read_text()
    assert 'packages = ["src/stairenv"]' in text  # hatch ships every file under the package
    ignored = (REPO / ".gitignore").read_text().split()
    assert "*.npz" not in ignored and "*.txt" not in ignored


def test_plamo_envs_draw_starts_and_the_amp_reference_from_the_set():
    import gymnasium as gym

    import stairenv  # noqa: F401  (registers the ids)

    for env_id in ("PlaMo-v0", "PlaMoNaivePaths-v0"):
        env = gym.make(env_id, init="reference")
        try:
            base = env.unwrapped
            assert base.DEFAULT_REFERENCE_MOTION == "builtin:plamo"
            assert {c.meta["locomotion"] for c in base._library.clips} == set(LOCOMOTION_TYPES)
            env.reset(seed=3)
            _, _, _, _, info = env.step(env.action_space.sample())
            assert info["reference_start"]
            windows = base.collect_reference_motions(8)
            assert windows.shape == (8, *base.amp_observation_space.shape)
        finally:
            env.close()


def test_crouch_walk_synthesis_holds_the_head_low_in_range():
    from stairenv.humanoid import dof_ranges, humanoid_model
    from stairenv.motion.synthesis import crouch_walk

    ranges = dof_ranges(humanoid_model())
    for speed in (0.5, 1.5):
        clip = crouch_walk(speed, duration=1.0)
        heads = head_heights(clip.qpos)
        assert 0.75 < heads.mean() < 0.87
        joints = clip.qpos[:, 7:]
        assert np.all(joints >= ranges[:, 0] - 1e-9) and np.all(joints <= ranges[:, 1] + 1e-9)
        assert np.linalg.norm(clip.qpos[-1, :2] - clip.qpos[0, :2]) / clip.duration == pytest.approx(speed, rel=0.02)
        assert _deepest_self_contact(clip) > -1e-3      # the arms clear the knees
        assert _com_ahead_of_front_toe(clip).max() < 0.0  # the leaning trunk does not tip it over its toes


def _deepest_self_contact(clip: MotionClip) -> float:
    """Most negative distance of a contact between two of the character's geoms over the clip (m)."""
    import mujoco

    from stairenv.humanoid import humanoid_model

    model = humanoid_model()
    data = mujoco.MjData(model)
    deepest = 0.0
    for q in clip.qpos:
        data.qpos[:] = q
        mujoco.mj_forward(model, data)
        for contact in data.contact[:data.ncon]:
            if model.geom_bodyid[contact.geom1] and model.geom_bodyid[contact.geom2]:  # not the floor
                deepest = min(deepest, contact.dist)
    return deepest


def _com_ahead_of_front_toe(clip: MotionClip) -> np.ndarray:
    """(T,) how far (m) the centre of mass is ahead of the foremost toe, along the direction walked."""
    import mujoco

    from stairenv.humanoid import humanoid_model
    from stairenv.humanoid.kinematics import foot_box_geoms

    model = humanoid_model()
    data = mujoco.MjData(model)
    forward = clip.qpos[-1, :2] - clip.qpos[0, :2]
    forward /= np.linalg.norm(forward)
    out = []
    for q in clip.qpos:
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        toes = [data.geom_xpos[g, :2] @ forward + model.geom_size[g, 0] for g in foot_box_geoms()]
        out.append(data.subtree_com[1, :2] @ forward - max(toes))
    return np.array(out)


@pytest.mark.skipif(not (MOTIONS / "DeepMimic").is_dir(), reason="raw motion files (../shared/motions) absent")
def test_rebuilding_from_the_raw_files_gives_the_shipped_clips(clips):
    by_name = {c.name: c for c in clips}
    for recipe in (CONVERTED[0], CONVERTED[2]):  # a DeepMimic and an IsaacGymEnvs clip: fast to convert
        clip = plamo_set.convert(recipe, MOTIONS)
        np.testing.assert_allclose(clip.qpos, by_name[recipe.name].qpos, atol=1e-9)
        assert clip.meta["locomotion"] == by_name[recipe.name].meta["locomotion"]


def test_nearest_locomotion():
    from stairenv.planning.locomotion import nearest_locomotion

    assert nearest_locomotion(0.45, 0.3) == "crawl"
    assert nearest_locomotion(0.9, 1.0) == "crouch-walk"
    assert nearest_locomotion(1.3, 1.0) == "walk" and nearest_locomotion(1.3, 0.1) == "walk"
    assert nearest_locomotion(1.4, 3.0) == "run" and nearest_locomotion(1.4, 4.5) == "sprint"
    assert nearest_locomotion(1.4, 4.5, LOCOMOTION_TYPES) == "run"  # no sprint clip: the nearest there is
    with pytest.raises(ValueError):
        nearest_locomotion(1.0, 1.0, ())



def test_locomotion_labels_are_nearest_locomotion_for_every_sample():
    from stairenv.planning.locomotion import LOCOMOTIONS, locomotion_labels, nearest_locomotion

    rng = np.random.default_rng(0)
    head, speed = rng.uniform(0.2, 1.6, 3000), rng.uniform(0.0, 5.5, 3000)
    head[:20], speed[:20] = 0.6, 2.0           # ties: crawl and crouch-walk equally near; walk and run both hold 2
    head[20:40], speed[20:40] = 1.47, 4.0
    for names in (list(LOCOMOTIONS), ["walk", "crawl"]):
        labels = locomotion_labels(head, speed, names)
        assert [names[k] for k in labels] == [nearest_locomotion(h, v, names) for h, v in zip(head, speed)]
    with pytest.raises(ValueError, match="at least one"):
        locomotion_labels(head, speed, [])

def test_matched_starts_begin_in_the_paths_opening_locomotion():
    import gymnasium as gym

    import stairenv  # noqa: F401
    from stairenv.planning.locomotion import nearest_locomotion

    errors = {}
    for matched in (True, False):
        env = gym.make("PlaMo-v0", init="reference", matched_starts=matched).unwrapped
        try:
            errors[matched] = []
            for seed in range(12):
                env.reset(seed=seed)
                head, _ = env._head()
                errors[matched].append(abs(head[2] - env.path.points[0, 2]))
                if matched:
                    kind = nearest_locomotion(env.path.head[0], env.path.speed[0], LOCOMOTION_TYPES)
                    heights = [c.meta["head_height"] for c in env._starts_by_locomotion[kind].clips]
                    assert {c.meta["locomotion"] for c in env._starts_by_locomotion[kind].clips} == {kind}
                    # the start's head is within the range of that type's clips (placed on the terrain)
                    assert min(heights) - 0.25 < head[2] - env.ground_height(head[None, :2])[0] < max(heights) + 0.25
        finally:
            env.close()
    assert np.mean(errors[True]) < 0.6 * np.mean(errors[False])
    # nothing to match without reference starts, or with clips that carry no locomotion label
    assert gym.make("PlaMo-v0").unwrapped._starts_by_locomotion is None
    unlabelled = gym.make("PlaMo-v0", init="reference", reference_motion="builtin:stairs").unwrapped
    assert unlabelled._starts_by_locomotion is None
    unlabelled.reset(seed=0)


def test_speed_change_ramps_the_speed_and_keeps_the_posture():
    from stairenv.motion.synthesis import speed_change

    for crouch, (v0, v1) in ((False, (0.3, 1.5)), (True, (1.4, 0.4))):
        clip = speed_change(v0, v1, ramp_steps=4, steady_steps=1, crouch=crouch)
        speed = np.linalg.norm(np.diff(clip.qpos[:, :2], axis=0), axis=1) * clip.fps
        assert speed[:8].mean() == pytest.approx(v0, abs=0.05) and speed[-8:].mean() == pytest.approx(v1, abs=0.05)
        heads = head_heights(clip.qpos)
        assert (0.75 < heads.mean() < 0.87) if crouch else (1.4 < heads.mean() < 1.55)
        assert not clip.loop and clip.meta["skill"] == "walk"
        assert _deepest_self_contact(clip) > -1e-3 and _com_ahead_of_front_toe(clip).max() < 0.0
    with pytest.raises(ValueError, match="speed_from"):
        speed_change(0.0, 1.0)
