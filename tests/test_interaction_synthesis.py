"""Interaction reference motion (``stairenv.motion.interactions``), checked with MuJoCo.

Every clip is played back kinematically in a model holding our humanoid and the box it was
made for (``clip.meta["furniture"]``): joint angles inside the compiled model's ranges, no
geom below the floor, planted feet flat, still and 2 mm above it, less than 1 cm of
penetration into the furniture at any frame, the pelvis (and, lying, the back, head, legs
and hands) resting on it where the clip says so, no joint velocity spikes, the body's mass
over the feet whenever the pelvis is off the seat, reach targets hit exactly; plus
determinism, parameter validation and the default set's metadata.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import mujoco
import numpy as np
import pytest

from stairenv.humanoid import DOF_NAMES, FOOT_BODIES, load_humanoid_spec
from stairenv.motion.clip import MotionClip, humanoid_model
from stairenv.motion.interactions import (
    SKILLS,
    get_up_from_lying,
    idle,
    interaction_reference_set,
    lie_down,
    reach,
    sit_down,
    stand_up,
)
from stairenv.humanoid.kinematics import humanoid_lowest_z

CONTACT_MARGIN = 0.01   # geoms closer than this to the furniture count as near it
REST_GAP = 0.002        # resting bodies and planted soles float this far above their support
PELVIS_RADIUS = 0.09

CLIPS = {
    "sit_low": lambda: sit_down(0.35),
    "sit_high_seat_hands": lambda: sit_down(0.65, hands="seat"),
    "stand_mid": lambda: stand_up(0.45),
    "stand_high_seat_hands": lambda: stand_up(0.6, hands="seat"),
    "lie_low": lambda: lie_down(0.4),
    "lie_high_pillow": lambda: lie_down(0.6, lie_offset=0.5, pillow_height=0.1),
    "getup_lying": lambda: get_up_from_lying(0.5),
    "reach_high": lambda: reach((0.40, 0.25, 1.45), hand="left"),
    "reach_low": lambda: reach((0.50, -0.15, 0.45), hand="right"),
    "idle": lambda: idle(3.0),
}


@dataclass
class Scan:
    """One clip played back in MuJoCo (world frame, per frame)."""

    clip: MotionClip
    lowest: np.ndarray          # (T,) lowest point of any humanoid geom
    sole: np.ndarray            # (T, 2) lowest point of each foot box
    foot_pos: np.ndarray        # (T, 2, 3) foot body origins
    foot_up: np.ndarray         # (T, 2) z component of each foot's up axis
    penetration: np.ndarray     # (T,) deepest humanoid geom inside the furniture (m, 0 if none)
    distance: list[dict]        # per frame: humanoid geom name -> distance to the furniture (< margin)
    com: np.ndarray             # (T, 3) centre of mass


def world(clip: MotionClip) -> mujoco.MjModel:
    """The humanoid plus the clip's furniture as one static box."""
    spec = load_humanoid_spec()
    box = clip.meta.get("furniture")
    if box is not None:
        spec.worldbody.add_geom(name="furniture", type=mujoco.mjtGeom.mjGEOM_BOX,
                                pos=box["center"], size=box["half_size"])
    return spec.compile()


def scan(clip: MotionClip) -> Scan:
    model = world(clip)
    data = mujoco.MjData(model)
    human = np.flatnonzero(model.geom_bodyid > 0)
    feet_geoms = [model.geom(name).id for name in FOOT_BODIES]
    feet_bodies = [model.body(name).id for name in FOOT_BODIES]
    box = model.geom("furniture").id if clip.meta.get("furniture") else -1
    count = clip.num_frames
    out = Scan(clip, np.zeros(count), np.zeros((count, 2)), np.zeros((count, 2, 3)), np.zeros((count, 2)),
               np.zeros(count), [], np.zeros((count, 3)))
    root = model.joint("root").qposadr[0]
    fromto = np.zeros(6)
    for t in range(count):
        data.qpos[root:root + 35] = clip.qpos[t]
        mujoco.mj_forward(model, data)
        out.lowest[t] = humanoid_lowest_z(model, data, human)
        out.sole[t] = [humanoid_lowest_z(model, data, np.array([g])) for g in feet_geoms]
        out.foot_pos[t] = data.xpos[feet_bodies]
        out.foot_up[t] = data.xmat[feet_bodies].reshape(2, 3, 3)[:, 2, 2]
        out.com[t] = data.subtree_com[model.body("pelvis").id]
        near: dict[str, float] = {}
        if box >= 0:
            # Signed distances (negative: penetration) from MuJoCo's colliders. Contacts would do
            # too, but the capsule-box collider drops a capsule lying exactly parallel to a face
            # within the contact margin.
            for g in human:
                dist = mujoco.mj_geomDistance(model, data, int(g), box, CONTACT_MARGIN, fromto)
                if dist < CONTACT_MARGIN:
                    near[model.geom(g).name] = float(dist)
                    out.penetration[t] = max(out.penetration[t], -float(dist))
        out.distance.append(near)
    return out


@pytest.fixture(scope="module")
def scans() -> dict[str, Scan]:
    return {key: scan(make()) for key, make in CLIPS.items()}


def planted_mask(clip: MotionClip) -> np.ndarray:
    mask = np.zeros((clip.num_frames, 2), dtype=bool)
    for side, body in enumerate(FOOT_BODIES):
        for first, last in clip.meta["stance_frames"][body]:
            mask[first:last + 1, side] = True
    return mask


# --- geometry ----------------------------------------------------------------------------------
@pytest.mark.parametrize("key", list(CLIPS))
def test_joint_angles_inside_the_model_ranges(scans, key):
    model = humanoid_model()
    ranges = np.array([model.jnt_range[model.joint(name).id] for name in DOF_NAMES])
    angles = scans[key].clip.qpos[:, 7:]
    assert np.all(angles >= ranges[:, 0] - 1e-9)
    assert np.all(angles <= ranges[:, 1] + 1e-9)


@pytest.mark.parametrize("key", list(CLIPS))
def test_nothing_below_the_floor_and_planted_feet_flat_and_still(scans, key):
    s = scans[key]
    assert s.lowest.min() > -0.001
    planted = planted_mask(s.clip)
    assert planted.any(axis=0).all(), "both feet start (or stay) planted"
    for side in range(2):
        frames = np.flatnonzero(planted[:, side])
        np.testing.assert_allclose(s.sole[frames, side], REST_GAP, atol=5e-4)
        assert np.all(s.foot_up[frames, side] > 0.9999), "planted feet lie flat"
        slip = np.linalg.norm(s.foot_pos[frames, side] - s.foot_pos[frames[0], side], axis=1)
        assert slip.max() < 0.001, f"foot slides {slip.max() * 1000:.2f} mm"


@pytest.mark.parametrize("key", [k for k in CLIPS if k.split("_")[0] in ("sit", "stand", "lie", "getup")])
def test_furniture_penetration_below_one_centimetre_and_pelvis_resting(scans, key):
    s = scans[key]
    assert s.penetration.max() < 0.01, f"{s.penetration.max() * 1000:.1f} mm into the furniture"
    top = s.clip.meta["furniture"]["top"]
    for first, last in s.clip.meta["rest_frames"]:
        for t in range(first, last + 1):
            assert s.distance[t].get("pelvis", np.inf) < 0.003, f"pelvis off the surface at frame {t}"
            assert abs(s.clip.qpos[t, 2] - (top + PELVIS_RADIUS + REST_GAP)) < 1e-6
    # Frames outside the rest ranges: the pelvis is clear of the furniture.
    resting = np.zeros(s.clip.num_frames, dtype=bool)
    for first, last in s.clip.meta["rest_frames"]:
        resting[first:last + 1] = True
    for t in np.flatnonzero(~resting):
        assert s.distance[t].get("pelvis", np.inf) > 0.0


@pytest.mark.parametrize("key", ["lie_low", "lie_high_pillow", "getup_lying"])
def test_lying_pose_rests_on_the_surface(scans, key):
    s = scans[key]
    lying = -1 if s.clip.meta["generator"] == "lie_down" else 0
    near = s.distance[lying]
    resting = ["pelvis", "chest", "right_hand", "left_hand"]
    if s.clip.meta["parameters"]["pillow_height"] == 0.0:
        resting.append("head")
    for geom in resting:
        assert near.get(geom, np.inf) < 0.003, f"{geom} not resting on the surface: {near}"
    assert min(near.get(f"{side}_{part}", np.inf) for side in ("right", "left")
               for part in ("thigh", "shin", "foot")) < 0.003, "the legs rest on the surface"
    # Lying on the back along +y, head towards +y, face up.
    qpos = s.clip.qpos[lying]
    model, data = humanoid_model(), mujoco.MjData(humanoid_model())
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    pelvis = data.xmat[model.body("pelvis").id].reshape(3, 3)
    np.testing.assert_allclose(pelvis[:, 0], [0, 0, 1], atol=0.1)    # facing up (the back a little raised)
    assert data.xpos[model.body("head").id][1] > qpos[1] + 0.4
    assert data.xpos[model.body("left_foot").id][1] < qpos[1] - 0.7


def test_seated_poses_chain():
    """sit_down ends where stand_up starts; lie_down starts there too; get up is lie down reversed."""
    for height in (0.4, 0.55):
        sit, stand = sit_down(height), stand_up(height)
        np.testing.assert_allclose(sit.qpos[-1], stand.qpos[0], atol=1e-9)
        np.testing.assert_allclose(lie_down(height).qpos[0], sit.qpos[-1], atol=1e-9)
        np.testing.assert_allclose(sit.qpos[0], stand.qpos[-1], atol=1e-9)
    lie, up = lie_down(0.5), get_up_from_lying(0.5)
    np.testing.assert_array_equal(up.qpos, lie.qpos[::-1])


# --- motion quality ----------------------------------------------------------------------------
@pytest.mark.parametrize("key", list(CLIPS))
def test_smooth_and_at_rest_at_both_ends(scans, key):
    clip = scans[key].clip
    joints = clip.qpos[:, 7:]
    assert np.degrees(np.abs(np.diff(joints, axis=0))).max() < 12.0, "joint velocity below 6.3 rad/s"
    assert np.degrees(np.abs(np.diff(joints, 2, axis=0))).max() < 5.0, "no velocity spikes"
    root = np.linalg.norm(np.diff(clip.qpos[:, :3], axis=0), axis=1) * clip.fps
    assert root.max() < 1.0
    qvel = clip.qvel()
    assert np.isfinite(qvel).all() and np.abs(qvel[:, 3:6]).max() < 3.0
    if not clip.loop:
        assert np.abs(qvel[[0, -1]]).max() < 1e-6, "clips start and end at rest"


@pytest.mark.parametrize("key", ["sit_low", "sit_high_seat_hands", "stand_mid", "stand_high_seat_hands"])
def test_mass_over_the_feet_while_off_the_seat(scans, key):
    s = scans[key]
    heel = s.clip.meta["feet_x"] - 0.0435
    toe = s.clip.meta["feet_x"] + 0.1335
    off = np.ones(s.clip.num_frames, dtype=bool)
    for first, last in s.clip.meta["rest_frames"]:
        off[first:last + 1] = False
    assert off.sum() > 20
    assert np.all(s.com[off, 0] > heel - 0.005)
    assert np.all(s.com[off, 0] < toe)
    assert s.clip.meta["balance_margin"] > 0.0


def test_reach_hits_the_target_and_returns():
    model, data = humanoid_model(), mujoco.MjData(humanoid_model())
    for target, hand in (((0.45, -0.2, 1.1), "right"), ((0.4, 0.25, 1.45), "left"),
                         ((0.5, -0.15, 0.45), "right"), ((0.35, 0.45, 0.9), "left")):
        clip = reach(target, hand=hand)
        first, last = clip.meta["hold_frames"][0]
        assert last - first >= 15
        for t in (first, last):
            data.qpos[:] = clip.qpos[t]
            mujoco.mj_kinematics(model, data)
            np.testing.assert_allclose(data.xpos[model.body(f"{hand}_hand").id], target, atol=0.002)
        np.testing.assert_allclose(clip.qpos[-1], clip.qpos[0], atol=1e-9)
        assert clip.meta["hand"] == f"{hand}_hand"


def test_idle_loops_and_barely_moves():
    clip = idle(4.0)
    assert clip.loop
    np.testing.assert_array_equal(clip.qpos[-1], clip.qpos[0])
    assert np.ptp(clip.qpos[:, :3], axis=0).max() < 0.015
    assert np.ptp(clip.qpos[:, 7:], axis=0).max() < 0.06
    assert np.ptp(clip.qpos[:, 7:], axis=0).max() > 0.005, "it breathes"


# --- API ---------------------------------------------------------------------------------------
def test_generators_are_deterministic():
    for make in (lambda: sit_down(0.5, hands="seat"), lambda: lie_down(0.45, pillow_height=0.05),
                 lambda: reach((0.5, 0.1, 0.7), hand="left"), lambda: idle(2.5)):
        a, b = make(), make()
        np.testing.assert_array_equal(a.qpos, b.qpos)
        assert a.meta == b.meta and a.name == b.name


@pytest.mark.parametrize(("call", "match"), [
    (lambda: sit_down(0.30), r"seat_height must lie in \[0.35, 0.65\]"),
    (lambda: stand_up(0.7), r"seat_height must lie in \[0.35, 0.65\]"),
    (lambda: sit_down(0.45, hands="lap"), r"hands must be one of \['thighs', 'seat'\]"),
    (lambda: sit_down(0.45, sit_depth=0.5), r"sit_depth must lie in \[0.05, 0.3\]"),
    (lambda: sit_down(0.45, descent_time=0.1), r"descent_time must lie in"),
    (lambda: lie_down(0.9), r"surface_height must lie in \[0.35, 0.65\]"),
    (lambda: get_up_from_lying(0.5, pillow_height=0.3), r"pillow_height must lie in \[0.0, 0.15\]"),
    (lambda: lie_down(0.5, lie_offset=0.1), r"lie_offset must lie in \[0.3, 0.6\]"),
    (lambda: reach((0.4, 0.0, 1.8)), r"target z must lie in \[0.4, 1.6\]"),
    (lambda: reach((0.05, 0.0, 1.0)), r"target x must lie in \[0.15, 0.8\]"),
    (lambda: reach((0.4, 0.0)), r"target must be three numbers"),
    (lambda: reach((0.4, 0.0, 1.0), hand="middle"), r"hand must be one of \['right', 'left'\]"),
    (lambda: reach((0.8, -0.6, 0.4), hand="right"), r"out of the right hand's reach"),
    (lambda: idle(0.0), r"duration must lie in \[1.0, 60.0\]"),
    (lambda: sit_down(0.45, fps=0.0), r"fps must lie in"),
])
def test_bad_parameters_are_rejected(call, match):
    with pytest.raises(ValueError, match=match):
        call()


def test_reference_set_is_fast_and_labelled(tmp_path):
    interaction_reference_set(seat_heights=(0.45,), surface_heights=(0.5,),
                              reach_targets=(((0.45, -0.2, 1.1), "right"),))  # warm-up (caches)
    start = time.perf_counter()
    clips = interaction_reference_set()
    elapsed = time.perf_counter() - start
    assert elapsed < 8.0, f"interaction_reference_set took {elapsed:.1f} s"
    assert len({clip.name for clip in clips}) == len(clips)
    assert {clip.meta["skill"] for clip in clips} == set(SKILLS)
    texts = {clip.meta["skill"]: set() for clip in clips}
    for clip in clips:
        assert clip.meta["skill"] in SKILLS
        assert isinstance(clip.meta["text"], str) and clip.meta["text"]
        assert clip.meta["generator"] and isinstance(clip.meta["parameters"], dict)
        texts[clip.meta["skill"]].add(clip.meta["text"])
    assert texts["sit"] == {"sit down"} and texts["lie"] == {"lie down"} and texts["reach"] == {"reach"}
    assert texts["getup"] == {"stand up", "get up"} and texts["idle"] == {"stand still"}
    assert 30.0 < sum(clip.duration for clip in clips) < 90.0
    # The metadata survives the clip file format (JSON).
    path = clips[0].save(tmp_path / "clip.npz")
    loaded = MotionClip.load(path)
    assert loaded.meta == clips[0].meta
    np.testing.assert_array_equal(loaded.qpos, clips[0].qpos)
