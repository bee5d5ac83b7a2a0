"""Kinematic reference motion (``stairenv.motion.synthesis``), checked with MuJoCo's own kinematics.

Every geometric check reads the foot boxes off ``mj_kinematics`` (geom pose + half sizes) and
the ground off ``Staircase.surface_height``, so it tests the clips, not the generator's
internal model of the body: feet flat and still on their treads, no foot box below the
stairs, swinging feet clear of every tread edge, the pelvis rising (dropping) monotonically
by the flight's height, walks that loop, joint angles inside the model's limits, plausible
velocities, and no kinematic penetration with the staircase that ``StairsSlots`` builds.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from stairenv.humanoid import DOF_NAMES, FOOT_BODIES, load_humanoid_spec
from stairenv.motion.clip import MotionClip, humanoid_model
from stairenv.motion.library import MotionLibrary
from stairenv.motion.synthesis import (
    WALK_STYLES,
    WalkStyle,
    climb_stairs,
    reference_set,
    save_reference_set,
    styled_walk,
    walk,
)
from stairenv.world.stairs import Staircase, StairsSlots

# (direction, step height, step depth, lead foot): every paper test height, both directions,
# shallow to deep treads.
STAIR_CASES = [
    ("up", 0.05, 0.30, "right"),
    ("up", 0.10, 0.25, "left"),
    ("up", 0.15, 0.35, "right"),
    ("up", 0.20, 0.28, "left"),
    ("down", 0.05, 0.35, "left"),
    ("down", 0.10, 0.30, "right"),
    ("down", 0.15, 0.25, "left"),
    ("down", 0.20, 0.28, "right"),
]
NUM_STEPS = 5
CORNER_SIGNS = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)
BOTTOM = CORNER_SIGNS[:, 2] < 0
TOE_SOLE = BOTTOM & (CORNER_SIGNS[:, 0] > 0)


@dataclass
class FootPoses:
    """Both foot boxes over a clip, from MuJoCo forward kinematics (world frame)."""

    centre: np.ndarray        # (T, 2, 3) box centres
    rotation: np.ndarray      # (T, 2, 3, 3) box orientations
    half: np.ndarray          # (2, 3) half sizes
    corners: np.ndarray       # (T, 2, 8, 3)
    ankle: np.ndarray         # (T, 2, 3) foot body origins
    knee: np.ndarray          # (T, 2, 3) shin body origins
    hip: np.ndarray           # (T, 2, 3) thigh body origins


def foot_poses(clip: MotionClip) -> FootPoses:
    model = humanoid_model()
    data = mujoco.MjData(model)
    geoms = [model.geom(name).id for name in FOOT_BODIES]
    feet = [model.body(name).id for name in FOOT_BODIES]
    shins = [model.body(name.replace("foot", "shin")).id for name in FOOT_BODIES]
    thighs = [model.body(name.replace("foot", "thigh")).id for name in FOOT_BODIES]
    count = clip.num_frames
    centre, rotation = np.zeros((count, 2, 3)), np.zeros((count, 2, 3, 3))
    ankle, knee, hip = np.zeros((count, 2, 3)), np.zeros((count, 2, 3)), np.zeros((count, 2, 3))
    for t in range(count):
        data.qpos[:] = clip.qpos[t]
        mujoco.mj_kinematics(model, data)
        centre[t] = data.geom_xpos[geoms]
        rotation[t] = data.geom_xmat[geoms].reshape(2, 3, 3)
        ankle[t], knee[t], hip[t] = data.xpos[feet], data.xpos[shins], data.xpos[thighs]
    half = model.geom_size[geoms]
    corners = centre[:, :, None, :] + np.einsum("sck,tsjk->tscj", CORNER_SIGNS * half[:, None, :], rotation)
    return FootPoses(centre, rotation, half, corners, ankle, knee, hip)


def staircase(clip: MotionClip) -> Staircase:
    return Staircase(**clip.meta["stairs"])


def frame_sets(clip: MotionClip, key: str) -> list[tuple[int, np.ndarray]]:
    """(foot index, frame indices) of every phase listed under ``clip.meta[key]``."""
    return [(side, np.arange(first, last + 1))
            for side, body in enumerate(FOOT_BODIES) for first, last in clip.meta[key][body]]


def contact_mask(clip: MotionClip) -> np.ndarray:
    """(T, 2): the foot is planted flat or pushing off (not swinging)."""
    mask = np.zeros((clip.num_frames, 2), dtype=bool)
    for key in ("stance_frames", "push_off_frames"):
        for side, frames in frame_sets(clip, key):
            mask[frames, side] = True
    return mask


def edge_distance(poses: FootPoses, stairs: Staircase) -> np.ndarray:
    """(T, 2, n) distance from each tread's front edge (a line across the stairs) to each foot box
    (negative inside)."""
    k = np.arange(1, stairs.num_steps + 1)
    edges = np.stack(((k - 1) * stairs.step_depth, k * stairs.step_height), axis=1)  # (n, 2) x, z
    points = np.repeat(poses.centre[:, :, None, :], len(k), axis=2)  # the edge at the box's y
    points[..., 0], points[..., 2] = edges[:, 0], edges[:, 1]
    local = np.einsum("tsji,tsnj->tsni", poses.rotation, points - poses.centre[:, :, None, :])
    outside = np.abs(local) - poses.half[None, :, None, :]
    distance = np.linalg.norm(np.maximum(outside, 0.0), axis=-1)
    inside = np.minimum(outside.max(axis=-1), 0.0)
    return distance + inside


@pytest.fixture(scope="module")
def stair_clips() -> dict[tuple, tuple[MotionClip, FootPoses]]:
    out = {}
    for case in STAIR_CASES:
        direction, height, depth, lead = case
        clip = climb_stairs(height, depth, NUM_STEPS, direction=direction, lead_foot=lead)
        out[case] = (clip, foot_poses(clip))
    return out


@pytest.fixture(scope="module")
def default_set() -> list[MotionClip]:
    return reference_set()


# --- feet on the stairs ----------------------------------------------------------------------
@pytest.mark.parametrize("case", STAIR_CASES, ids=lambda c: f"{c[0]}-{c[1]:.2f}-{c[2]:.2f}")
def test_stance_feet_flat_still_and_on_one_tread(stair_clips, case):
    clip, poses = stair_clips[case]
    stairs = staircase(clip)
    phases = frame_sets(clip, "stance_frames")
    assert len(phases) >= 2 * NUM_STEPS, "every tread and the landing get a planted foot"
    treads_used = set()
    for side, frames in phases:
        bottom = poses.corners[frames, side][:, BOTTOM]               # (F, 4, 3)
        ground = stairs.surface_height(bottom)                         # (F, 4)
        assert np.ptp(ground) < 1e-9, "the whole sole stands on one tread"
        sole = bottom[..., 2].min(axis=1)
        assert np.abs(sole - ground[:, 0]).max() < 0.01, "sole on the tread top"
        up = poses.rotation[frames, side][:, :, 2]                     # box z axis in the world
        assert np.degrees(np.arccos(np.clip(up[:, 2], -1, 1))).max() < 1.0, "foot flat"
        drift = np.linalg.norm(poses.centre[frames, side, :2] - poses.centre[frames[0], side, :2], axis=1)
        assert drift.max() < 0.01, "no sliding while planted"
        treads_used.add(round(ground[0, 0] / stairs.step_height))
    assert treads_used == set(range(0, NUM_STEPS + 1)), "one foot on each tread, floor and landing"


@pytest.mark.parametrize("case", STAIR_CASES[:4:3] + STAIR_CASES[4::3], ids=lambda c: f"{c[0]}-{c[1]:.2f}")
def test_push_off_rolls_over_a_fixed_toe(stair_clips, case):
    clip, poses = stair_clips[case]
    stairs = staircase(clip)
    phases = frame_sets(clip, "push_off_frames")
    assert phases
    for side, frames in phases:
        toe_edge = poses.corners[frames, side][:, TOE_SOLE].mean(axis=1)  # middle of the toe's lower edge
        assert np.ptp(toe_edge[:, 0]) < 0.005, "the toe does not slide"
        assert np.abs(toe_edge[:, 2] - stairs.surface_height(toe_edge)).max() < 0.01


@pytest.mark.parametrize("case", STAIR_CASES, ids=lambda c: f"{c[0]}-{c[1]:.2f}-{c[2]:.2f}")
def test_no_foot_corner_below_the_stairs(stair_clips, case):
    clip, poses = stair_clips[case]
    stairs = staircase(clip)
    height_above = poses.corners[..., 2] - stairs.surface_height(poses.corners)
    assert height_above.min() > -0.005


@pytest.mark.parametrize("case", STAIR_CASES, ids=lambda c: f"{c[0]}-{c[1]:.2f}-{c[2]:.2f}")
def test_feet_clear_every_tread_edge(stair_clips, case):
    clip, poses = stair_clips[case]
    stairs = staircase(clip)
    distance = edge_distance(poses, stairs)            # (T, 2, n)
    swinging = ~contact_mask(clip)
    assert swinging.any()
    # A swinging foot keeps >= 1 cm from every edge (1.5 cm from a riser while it lifts beside
    # it, 2 cm once it moves, 4 cm above an edge it passes); planted feet stand clear too.
    assert distance[swinging].min() > 0.01
    assert distance.min() > 0.005
    # Passing over an edge, the sole is well above it.
    sole_low = poses.corners[..., 2][..., BOTTOM].min(axis=-1)
    xs = poses.corners[..., BOTTOM, 0]
    for k in range(1, stairs.num_steps + 1):
        edge_x, edge_z = (k - 1) * stairs.step_depth, k * stairs.step_height
        over = swinging & (xs.min(axis=-1) < edge_x) & (xs.max(axis=-1) > edge_x)
        if over.any():
            assert (sole_low[over] - edge_z).min() > 0.03


@pytest.mark.parametrize("case", STAIR_CASES, ids=lambda c: f"{c[0]}-{c[1]:.2f}-{c[2]:.2f}")
def test_knees_bend_forward_over_the_feet(stair_clips, case):
    clip, poses = stair_clips[case]
    heading = 1.0 if case[0] == "up" else -1.0
    # The knee lies ahead of the hip-ankle line (in the walking direction) whenever it is bent.
    hip, knee, ankle = poses.hip, poses.knee, poses.ankle
    line = ankle - hip
    along = np.sum((knee - hip) * line, axis=-1) / np.sum(line * line, axis=-1)
    offset = knee - (hip + along[..., None] * line)
    bent = np.linalg.norm(offset, axis=-1) > 0.02
    assert bent.any()
    assert np.all(heading * offset[..., 0][bent] > 0.0)


# --- pelvis ----------------------------------------------------------------------------------
@pytest.mark.parametrize("case", STAIR_CASES, ids=lambda c: f"{c[0]}-{c[1]:.2f}-{c[2]:.2f}")
def test_pelvis_height_monotone_by_the_flight(stair_clips, case):
    clip, _ = stair_clips[case]
    direction, height = case[0], case[1]
    z = clip.qpos[:, 2] if direction == "up" else -clip.qpos[:, 2]
    assert np.max(np.maximum.accumulate(z) - z) < 0.01, "never goes back by more than 1 cm"
    assert abs((z[-1] - z[0]) - NUM_STEPS * height) < 0.01
    # Starts and ends at a walking height over the ground.
    low, high = sorted((clip.qpos[0, 2], clip.qpos[-1, 2]))
    assert 0.78 < low < 0.88 and abs(high - low - NUM_STEPS * height) < 0.01


# --- walking ---------------------------------------------------------------------------------
@pytest.mark.parametrize("speed", [0.8, 1.2])
def test_walk_loops_and_keeps_its_speed(speed):
    clip = walk(speed, duration=3.0)
    q = clip.qpos
    assert clip.loop
    np.testing.assert_allclose(q[-1, 1:], q[0, 1:], atol=1e-6)         # joints, height, orientation
    distance = q[-1, 0] - q[0, 0]
    assert distance == pytest.approx(speed * clip.duration, rel=1e-6)
    # Velocity continuous across the seam: the second difference there is an ordinary one.
    seam = q[1, 7:] - 2.0 * q[0, 7:] + q[-2, 7:]
    interior = np.abs(q[2:, 7:] - 2.0 * q[1:-1, 7:] + q[:-2, 7:]).max(axis=0)
    assert np.all(np.abs(seam) <= interior + 1e-9)
    qvel = clip.qvel()
    assert np.isfinite(qvel).all()
    assert np.mean(qvel[:, 0]) == pytest.approx(speed, rel=0.02)
    assert np.abs(qvel[:, 1]).max() < 0.3 and np.abs(qvel[:, 2]).max() < 0.5
    poses = foot_poses(clip)
    assert (poses.corners[..., 2].min()) > -0.005, "feet above the floor"
    for side, frames in frame_sets(clip, "stance_frames"):
        drift = np.linalg.norm(poses.centre[frames, side, :2] - poses.centre[frames[0], side, :2], axis=1)
        assert drift.max() < 0.01
        assert np.abs(poses.corners[frames, side][..., 2].min(axis=1)).max() < 0.01


@pytest.fixture(scope="module")
def styled_walks() -> dict[str, MotionClip]:
    return {name: styled_walk(name, duration=3.0, lead_foot=("right", "left")[i % 2])
            for i, name in enumerate(WALK_STYLES)}


@pytest.mark.parametrize("name", list(WALK_STYLES))
def test_styled_walks_loop_keep_their_speed_and_plant_the_feet(styled_walks, name):
    clip, style = styled_walks[name], WALK_STYLES[name]
    q = clip.qpos
    assert clip.loop and clip.meta["style"] == name and clip.meta["text"] == style.text
    assert clip.meta["skill"] == "walk"
    np.testing.assert_allclose(q[-1, 1:], q[0, 1:], atol=1e-6)
    assert q[-1, 0] - q[0, 0] == pytest.approx(style.speed * clip.duration, rel=1e-6)
    model = humanoid_model()
    ranges = np.array([model.jnt_range[model.joint(n).id] for n in DOF_NAMES])
    assert np.all(q[:, 7:] >= ranges[:, 0] - 1e-9) and np.all(q[:, 7:] <= ranges[:, 1] + 1e-9)
    qvel = clip.qvel()
    assert np.isfinite(qvel).all() and np.abs(qvel[:, 6:]).max() < 15.0
    poses = foot_poses(clip)
    assert poses.corners[..., 2].min() > -0.005, "feet above the floor"
    for side, frames in frame_sets(clip, "stance_frames"):
        drift = np.linalg.norm(poses.centre[frames, side, :2] - poses.centre[frames[0], side, :2], axis=1)
        assert drift.max() < 0.01
        assert np.abs(poses.corners[frames, side][..., 2].min(axis=1)).max() < 0.01
    # the caption is one of the script database's walking captions of that style
    from stairenv.screenplays.database import load_database

    captions = {(kf.style, kf.caption) for script in load_database() for kf in script.keyframes
                if kf.skill == "walk"}
    if name != "neutral":
        assert (name, style.text) in captions


def test_styles_show_in_the_motion(styled_walks):
    def trunk_pitch(clip):  # pelvis pitch + abdomen pitch, mean over the clip
        pitch = np.array([Rotation.from_quat(q[3:7], scalar_first=True).as_euler("ZYX")[1] for q in clip.qpos])
        return float(np.mean(pitch + clip.qpos[:, 7 + DOF_NAMES.index("abdomen_y")]))

    def head_down(clip):  # head pitch below level: trunk pitch + neck
        return trunk_pitch(clip) + float(np.mean(clip.qpos[:, 7 + DOF_NAMES.index("neck_y")]))

    def arm_swing(clip):
        shoulder = clip.qpos[:, 7 + DOF_NAMES.index("right_shoulder_y")]
        return float(shoulder.max() - shoulder.min())

    def sway(clip):  # pelvis roll amplitude
        roll = np.array([Rotation.from_quat(q[3:7], scalar_first=True).as_euler("ZYX")[2] for q in clip.qpos])
        return float(roll.max() - roll.min())

    neutral = styled_walks["neutral"]
    assert trunk_pitch(styled_walks["tired"]) > trunk_pitch(neutral) + 0.1
    assert head_down(styled_walks["sad"]) > head_down(neutral) + 0.3
    assert head_down(styled_walks["happy"]) < head_down(neutral) - 0.1
    assert arm_swing(styled_walks["happy"]) > 1.3 * arm_swing(neutral)
    assert arm_swing(styled_walks["sad"]) < 0.5 * arm_swing(neutral)
    assert sway(styled_walks["drunk"]) > 1.8 * sway(neutral)
    elbow = 7 + DOF_NAMES.index("right_elbow")
    assert styled_walks["stressed"].qpos[:, elbow].mean() < neutral.qpos[:, elbow].mean() - 0.4  # arms held bent
    with pytest.raises(ValueError, match="style must be one of"):
        styled_walk("sleepy")
    with pytest.raises(ValueError, match="lean"):
        WalkStyle(lean=1.0)


# --- the default set -------------------------------------------------------------------------
def test_reference_set_is_fast_and_covers_the_paper_heights():
    reference_set(walk_speeds=(1.0,), step_heights=(0.1,), step_depths=(0.3,), descents=False)  # warm-up
    start = time.perf_counter()
    clips = reference_set()
    elapsed = time.perf_counter() - start
    assert elapsed < 10.0, f"reference_set took {elapsed:.1f} s"
    names = [clip.name for clip in clips]
    assert len(set(names)) == len(names)
    assert sum(clip.meta["generator"] == "walk" for clip in clips) >= 2
    for direction in ("up", "down"):
        heights = {round(clip.meta["parameters"]["step_height"], 3) for clip in clips
                   if clip.meta["generator"] == "climb_stairs"
                   and clip.meta["parameters"]["direction"] == direction}
        assert heights == {0.05, 0.10, 0.15, 0.20}


def test_joint_angles_inside_the_model_ranges(default_set):
    model = humanoid_model()
    ranges = np.array([model.jnt_range[model.joint(name).id] for name in DOF_NAMES])
    for clip in default_set:
        angles = clip.qpos[:, 7:]
        assert np.all(angles >= ranges[:, 0] - 1e-9), clip.name
        assert np.all(angles <= ranges[:, 1] + 1e-9), clip.name


def test_velocities_finite_and_plausible(default_set):
    for clip in default_set:
        qvel = clip.qvel()
        assert np.isfinite(qvel).all(), clip.name
        assert np.abs(qvel[:, 6:]).max() < 15.0, clip.name                 # rad/s
        assert np.linalg.norm(qvel[:, :2], axis=1).max() < 2.0, clip.name  # m/s
        assert np.abs(qvel[:, 2]).max() < 1.5, clip.name
        assert np.abs(qvel[:, 3:6]).max() < 3.0, clip.name                 # pelvis rad/s
        if clip.meta["generator"] == "climb_stairs":
            speed = np.linalg.norm(clip.qpos[-1, :2] - clip.qpos[0, :2]) / clip.duration
            assert 0.3 < speed < 1.0, clip.name


def test_save_and_load_round_trip(tmp_path):
    kwargs = dict(walk_speeds=(1.0,), step_heights=(0.1,), step_depths=(0.3,))
    paths = save_reference_set(tmp_path, **kwargs)
    assert len(paths) == 3 and all(path.exists() for path in paths)
    library = MotionLibrary.load(tmp_path)
    originals = {clip.name: clip for clip in reference_set(**kwargs)}
    assert sorted(library.names) == sorted(originals)
    for clip in library.clips:
        np.testing.assert_array_equal(clip.qpos, originals[clip.name].qpos)
        assert clip.loop == originals[clip.name].loop
        assert clip.meta["stance_frames"] == originals[clip.name].meta["stance_frames"]


def test_generators_are_pure():
    a = climb_stairs(0.15, 0.3, 4, direction="down", lead_foot="left")
    b = climb_stairs(0.15, 0.3, 4, direction="down", lead_foot="left")
    np.testing.assert_array_equal(a.qpos, b.qpos)
    assert a.meta == b.meta
    np.testing.assert_array_equal(walk(1.1).qpos, walk(1.1).qpos)


def test_lead_foot_and_step_counts():
    clip = climb_stairs(0.12, 0.3, 4, approach_steps=3, landing_steps=2, lead_foot="left")
    stairs = staircase(clip)
    poses = foot_poses(clip)
    first_on_tread = {}
    for side, frames in frame_sets(clip, "stance_frames"):
        ground = float(stairs.surface_height(poses.centre[frames[0], side][None])[0])
        tread = round(ground / stairs.step_height)
        first_on_tread.setdefault(tread, []).append((frames[0], side))
    assert FOOT_BODIES[min(first_on_tread[1])[1]] == "left_foot"
    # Floor: the foot that has just landed at the first frame (the other one is pushing off),
    # then approach_steps; landing: one step onto it, then landing_steps.
    assert len(first_on_tread[0]) == 1 + 3
    assert len(first_on_tread[4]) == 1 + 2
    assert all(len(first_on_tread[k]) == 1 for k in (1, 2, 3))


def test_invalid_parameters_are_rejected():
    with pytest.raises(ValueError, match="direction"):
        climb_stairs(0.1, 0.3, 4, direction="sideways")
    with pytest.raises(ValueError, match="step_depth"):
        climb_stairs(0.1, 0.18, 4)                      # shorter than a foot + 1 cm
    with pytest.raises(ValueError, match="num_steps"):
        climb_stairs(0.1, 0.3, 0)
    with pytest.raises(ValueError, match="lead_foot"):
        walk(1.0, lead_foot="middle")
    with pytest.raises(ValueError, match="speed"):
        walk(0.0)


# --- physics: kinematic penetration with the staircase StairsSlots builds ---------------------
CONTACT_MARGIN = 0.02  # report geom pairs closer than this, so planted feet show up as contacts


@pytest.fixture(scope="module")
def stairs_world():
    spec = load_humanoid_spec()
    slots = StairsSlots(spec, max_steps=8)
    model = spec.compile()
    slots.bind(model)
    model.geom_margin[:] = CONTACT_MARGIN
    return model, slots


@pytest.mark.parametrize("direction", ["up", "down"])
@pytest.mark.parametrize("height", [0.10, 0.15, 0.20])
def test_kinematic_penetration_below_one_centimetre(stairs_world, direction, height):
    model, slots = stairs_world
    clip = climb_stairs(height, 0.28, NUM_STEPS, direction=direction)
    slots.place(model, staircase(clip))
    data = mujoco.MjData(model)
    scenery = set(slots.geom_ids.tolist()) | {model.geom("floor").id}
    feet = {model.geom(name).id for name in FOOT_BODIES}
    root = model.joint("root").qposadr[0]
    deepest_foot = deepest_any = -np.inf
    foot_contacts = 0
    for t in range(clip.num_frames):
        data.qpos[root:root + 35] = clip.qpos[t]
        mujoco.mj_forward(model, data)
        for contact in data.contact[:data.ncon]:
            pair = {int(contact.geom1), int(contact.geom2)}
            if len(pair & scenery) != 1:
                continue  # humanoid self-contact or scenery-scenery
            depth = -float(contact.dist)
            deepest_any = max(deepest_any, depth)
            if pair & feet:
                deepest_foot = max(deepest_foot, depth)
                foot_contacts += 1
    assert foot_contacts > clip.num_frames, "the planted feet are seen touching the treads"
    assert deepest_foot < 0.01
    assert deepest_any < 0.01, "no other body part sinks into the stairs either"
