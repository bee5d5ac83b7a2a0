"""Importers of IsaacGymEnvs .npy, DeepMimic .txt and CMU BVH motions, on the real files.

The motion files live outside the repository, in ``../shared/motions`` (each folder with
its NOTICE); they are read from there and never copied. Tests that need them skip when
the folder is absent. Measured on the shipped files (for the bounds below):

* IsaacGymEnvs walk/run/hop: FK of our humanoid vs. the file's own skeleton (its offsets,
  its quaternions): mean 2.8-2.9 mm, max 6.4 mm (the skeletons' offsets differ by up to
  4.5 mm); with our offsets the conversion is exact (< 1e-5 m). Clips that leave the
  joint ranges: dance max 5.8 cm, backflip 11 cm, cartwheel 47 cm (hips 80 deg beyond).
* DeepMimic walk/zombie walk/stealthy walk: FK in DeepMimic's y-up frame with the AMP
  skeleton's offsets vs. ours: mean 2.8-2.9 mm, max 6.3 mm; jog/jump/run (a few degrees
  of clamping): mean 3.0-3.4 mm, max 1.5-3.0 cm.
* CMU 83_32.bvh: limb directions (arms, thighs, shins) equal the source's to < 0.01 deg;
  the root rises 0.551 m; sole plateaus at 0.01-0.02 (floor), 0.21 (left), 0.38 (right)
  and 0.56-0.57 m (both): three steps of 0.186 m (CMU's ~0.17 m steps scaled by our leg
  length over the subject's, 0.831 / 0.755 m).
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from stairenv.humanoid import BODY_NAMES, DOF_NAMES, JOINTS, PARENT_INDICES
from stairenv.motion.clip import MotionClip, MotionFileError, humanoid_model
from stairenv.motion.importers import body_positions, foot_sole_heights, import_motion, lowest_body_point
from stairenv.motion.library import MotionLibrary

MOTIONS = Path(__file__).resolve().parents[2] / "shared" / "motions"
ISAAC = MOTIONS / "IsaacGymEnvs"
DEEPMIMIC = MOTIONS / "DeepMimic"
CMU_STAIRS = MOTIONS / "CMU" / "83_32.bvh"

needs_isaac = pytest.mark.skipif(not ISAAC.is_dir(), reason=f"IsaacGymEnvs motions not found at {ISAAC}")
needs_deepmimic = pytest.mark.skipif(not DEEPMIMIC.is_dir(), reason=f"DeepMimic motions not found at {DEEPMIMIC}")
needs_cmu = pytest.mark.skipif(not CMU_STAIRS.is_file(), reason=f"CMU stair clip not found at {CMU_STAIRS}")

ISAAC_CLIPS = ["amp_humanoid_walk", "amp_humanoid_run", "amp_humanoid_hop", "amp_humanoid_dance",
               "amp_humanoid_backflip", "amp_humanoid_cartwheel", "amp_humanoid_tpose"]
DEEPMIMIC_LOCOMOTION = ["humanoid3d_walk", "humanoid3d_run", "humanoid3d_jog", "humanoid3d_zombie_walk",
                        "humanoid3d_stealthy_walk"]
DEEPMIMIC_FLOOR_CONTACT = ["humanoid3d_crawl", "humanoid3d_roll", "humanoid3d_getup_faceup",
                           "humanoid3d_getup_facedown"]
Y_UP_TO_Z_UP = Rotation.from_euler("x", 90.0, degrees=True)


# ------------------------------------------------------------------------------------------
# helpers
# ------------------------------------------------------------------------------------------
def assert_valid_clip(clip: MotionClip, frames: int | None = None, fps: float | None = None) -> None:
    assert clip.qpos.ndim == 2 and clip.qpos.shape[1] == 35
    if frames is not None:
        assert clip.num_frames == frames
    if fps is not None:
        assert clip.fps == pytest.approx(fps)
    assert np.isfinite(clip.qpos).all()
    np.testing.assert_allclose(np.linalg.norm(clip.qpos[:, 3:7], axis=1), 1.0, atol=1e-9)
    model = humanoid_model()
    ranges = np.array([model.jnt_range[model.joint(n).id] for n in DOF_NAMES])
    angles = clip.qpos[:, 7:]
    assert np.all(angles >= ranges[:, 0] - 1e-9) and np.all(angles <= ranges[:, 1] + 1e-9), "angle out of range"


def skeleton_fk(root_pos, root_rot, local_rots, parents, offsets) -> np.ndarray:
    """(T, J, 3) positions: world rotation = parent world x local, position = parent + parent world (offset)."""
    n = len(root_pos)
    world, pos = [], np.zeros((n, len(parents), 3))
    for j, parent in enumerate(parents):
        if parent < 0:
            world.append(root_rot)
            pos[:, j] = root_pos
        else:
            world.append(world[parent] * local_rots[j])
            pos[:, j] = pos[:, parent] + world[parent].apply(offsets[j])
    return pos


def our_offsets() -> np.ndarray:
    model = humanoid_model()
    return np.array([model.body_pos[model.body(b).id] for b in BODY_NAMES])


def plateaus(height: np.ndarray, step_tol: float = 0.006, min_len: int = 6) -> list[tuple[int, int, float]]:
    """Runs of >= min_len frames whose frame-to-frame change stays below step_tol: (start, end, median)."""
    still = np.abs(np.diff(height)) < step_tol
    out, t = [], 0
    while t < len(still):
        if not still[t]:
            t += 1
            continue
        u = t
        while u < len(still) and still[u]:
            u += 1
        if u - t + 1 >= min_len:
            out.append((t, u, float(np.median(height[t:u + 1]))))
        t = u
    return out


# ------------------------------------------------------------------------------------------
# dispatch and corrupt files
# ------------------------------------------------------------------------------------------
def test_unknown_suffix_is_a_motion_file_error(tmp_path):
    path = tmp_path / "walk.fbx"
    path.write_bytes(b"Kaydara FBX Binary")
    with pytest.raises(MotionFileError, match=r"walk\.fbx.*unknown motion file type '\.fbx'"):
        import_motion(path)
    with pytest.raises(MotionFileError, match="no such file"):
        import_motion(tmp_path / "missing.bvh")


@needs_isaac
def test_corrupt_npy_files(tmp_path):
    data = (ISAAC / "amp_humanoid_walk.npy").read_bytes()
    truncated = tmp_path / "truncated.npy"
    truncated.write_bytes(data[: len(data) // 2])
    with pytest.raises(MotionFileError, match=r"truncated\.npy: cannot read"):
        import_motion(truncated)
    garbage = tmp_path / "garbage.npy"
    garbage.write_bytes(bytes(range(256)) * 8)
    with pytest.raises(MotionFileError, match=r"garbage\.npy"):
        import_motion(garbage)
    plain = tmp_path / "plain.npy"
    np.save(plain, np.zeros((10, 15, 4)))
    with pytest.raises(MotionFileError, match=r"plain\.npy: expected a pickled dict"):
        import_motion(plain)
    motion = np.load(ISAAC / "amp_humanoid_walk.npy", allow_pickle=True).item()
    motion["rotation"]["arr"] = motion["rotation"]["arr"][:, :14]
    wrong = tmp_path / "wrong_shape.npy"
    np.save(wrong, motion, allow_pickle=True)
    with pytest.raises(MotionFileError, match=r"wrong_shape\.npy: rotation must be \(T, 15, 4\)"):
        import_motion(wrong)


@needs_deepmimic
def test_corrupt_deepmimic_files(tmp_path):
    text = (DEEPMIMIC / "humanoid3d_walk.txt").read_text()
    truncated = tmp_path / "truncated.txt"
    truncated.write_text(text[: len(text) // 2])
    with pytest.raises(MotionFileError, match=r"truncated\.txt: not valid JSON"):
        import_motion(truncated)
    data = json.loads(text)
    data["Frames"][3] = data["Frames"][3][:43]
    short = tmp_path / "short_frame.txt"
    short.write_text(json.dumps(data))
    with pytest.raises(MotionFileError, match=r"short_frame\.txt: frame 3 has 43 values, expected 44"):
        import_motion(short)
    data = json.loads(text)
    data["Frames"][5][8:12] = [0.0, 0.0, 0.0, 0.0]  # chest quaternion of zero length
    zero = tmp_path / "zero_quat.txt"
    zero.write_text(json.dumps(data))
    with pytest.raises(MotionFileError, match=r"zero_quat\.txt: chest quaternion .* frame 5"):
        import_motion(zero)
    with pytest.raises(MotionFileError, match=r"NOTICE\.txt: not valid JSON"):
        import_motion(DEEPMIMIC / "NOTICE.txt")


@needs_cmu
def test_corrupt_bvh_files(tmp_path):
    lines = CMU_STAIRS.read_text().splitlines()
    motion_at = lines.index("MOTION")

    def write(name: str, new_lines: list[str]) -> Path:
        path = tmp_path / name
        path.write_text("\n".join(new_lines) + "\n")
        return path

    truncated = write("truncated.bvh", lines[:-100])
    with pytest.raises(MotionFileError,
                       match=r"truncated\.bvh: truncated motion: 'Frames: 1042' declared but only 942"):
        import_motion(truncated)
    cut_line = lines[:-1] + [" ".join(lines[-1].split()[:50])]
    with pytest.raises(MotionFileError,
                       match=r"cut_line\.bvh, line \d+: frame 1041 has 50 values, the hierarchy declares 96"):
        import_motion(write("cut_line.bvh", cut_line))
    # One joint announces 4 channels but lists 3: the parser meets 'JOINT' where a channel name belongs.
    channels = list(lines)
    k = next(i for i, line in enumerate(channels) if "CHANNELS 3" in line)
    channels[k] = channels[k].replace("CHANNELS 3", "CHANNELS 4")
    with pytest.raises(MotionFileError,
                       match=r"wrong_channels\.bvh, line \d+: joint LHipJoint: unknown channel 'JOINT'"):
        import_motion(write("wrong_channels.bvh", channels))
    # A joint with one channel fewer: every frame line is one value too long.
    fewer = list(lines)
    fewer[k] = fewer[k].replace("CHANNELS 3 Zrotation Yrotation Xrotation", "CHANNELS 2 Zrotation Yrotation")
    with pytest.raises(MotionFileError, match=r"frame 0 has 96 values, the hierarchy declares 95"):
        import_motion(write("fewer_channels.bvh", fewer))
    bad_number = list(lines)
    bad_number[motion_at + 10] = bad_number[motion_at + 10].replace("0.0000", "zero", 1)
    with pytest.raises(MotionFileError, match=r"bad_number\.bvh, line \d+: frame 7: 'zero' is not a number"):
        import_motion(write("bad_number.bvh", bad_number))
    no_motion = write("no_motion.bvh", lines[:motion_at])
    with pytest.raises(MotionFileError, match=r"no_motion\.bvh: no MOTION section"):
        import_motion(no_motion)
    hierarchy = [line for line in lines[:motion_at] if line.strip() != "}"]
    unbalanced = write("unbalanced.bvh", hierarchy + lines[motion_at:])
    with pytest.raises(MotionFileError, match=r"unbalanced\.bvh.*(expected|unexpected end)"):
        import_motion(unbalanced)
    garbage = tmp_path / "garbage.bvh"
    garbage.write_bytes(np.random.default_rng(0).bytes(4096))
    with pytest.raises(MotionFileError, match=r"garbage\.bvh: not"):
        import_motion(garbage)
    text = tmp_path / "text.bvh"
    text.write_text("this is not a motion file\n")
    with pytest.raises(MotionFileError, match=r"text\.bvh: not a BVH file"):
        import_motion(text)


# ------------------------------------------------------------------------------------------
# IsaacGymEnvs .npy
# ------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def isaac_clips():
    return {name: import_motion(ISAAC / f"{name}.npy") for name in ISAAC_CLIPS}


@needs_isaac
@pytest.mark.parametrize("name", ISAAC_CLIPS)
def test_isaac_npy_shapes_ranges_and_floor(isaac_clips, name):
    raw = np.load(ISAAC / f"{name}.npy", allow_pickle=True).item()
    frames = raw["rotation"]["arr"].shape[0] if raw["rotation"]["arr"].ndim == 3 else 1
    fps = float(np.asarray(raw["fps"])) if "fps" in raw else 30.0
    clip = isaac_clips[name]
    assert_valid_clip(clip, frames=frames, fps=fps)
    soles = foot_sole_heights(clip.qpos)
    # All these are on flat ground: the lowest sole touches the floor without sinking into it.
    assert -1e-6 <= soles.min() <= 0.02
    assert lowest_body_point(clip.qpos).min() >= -1e-6
    assert 0.0 <= clip.meta["clamped_fraction"] < 0.1


@needs_isaac
@pytest.mark.parametrize("name, mean_bound, max_bound", [
    ("amp_humanoid_walk", 0.004, 0.008),
    ("amp_humanoid_run", 0.004, 0.008),
    ("amp_humanoid_hop", 0.004, 0.008),
    ("amp_humanoid_dance", 0.004, 0.07),       # left hip clamped by up to 4 degrees
    ("amp_humanoid_backflip", 0.007, 0.13),    # hips beyond their ranges (up to 44 deg)
])
def test_isaac_npy_fk_matches_source_skeleton(isaac_clips, name, mean_bound, max_bound):
    raw = np.load(ISAAC / f"{name}.npy", allow_pickle=True).item()
    tree = raw["skeleton_tree"]
    assert list(tree["node_names"]) == list(BODY_NAMES)
    quat = raw["rotation"]["arr"].astype(np.float64)
    rots = [Rotation.from_quat(quat[:, j]) for j in range(15)]
    source = skeleton_fk(raw["root_translation"]["arr"], rots[0], rots,
                         tree["parent_indices"]["arr"], tree["local_translation"]["arr"])
    clip = isaac_clips[name]
    ours = body_positions(clip.qpos)
    ours[..., 2] -= clip.meta["root_height_offset"]
    err = np.linalg.norm(ours - source, axis=-1)
    assert err.mean() < mean_bound and err.max() < max_bound, (err.mean(), err.max())
    assert clip.meta["fk_error"]["max_m"] == pytest.approx(err.max(), abs=1e-5)


@needs_isaac
def test_isaac_npy_conversion_is_exact_with_our_offsets(isaac_clips):
    raw = np.load(ISAAC / "amp_humanoid_walk.npy", allow_pickle=True).item()
    quat = raw["rotation"]["arr"].astype(np.float64)
    rots = [Rotation.from_quat(quat[:, j]) for j in range(15)]
    source = skeleton_fk(raw["root_translation"]["arr"], rots[0], rots, PARENT_INDICES, our_offsets())
    clip = isaac_clips["amp_humanoid_walk"]
    assert clip.meta["clamped_fraction"] == 0.0
    ours = body_positions(clip.qpos)
    ours[..., 2] -= clip.meta["root_height_offset"]
    assert np.abs(ours - source).max() < 1e-5


@needs_isaac
def test_isaac_npy_root_offset_is_measured(isaac_clips):
    # The file's root heights leave the walk's soles about 8 cm under the floor; the
    # importer measures the shift instead of assuming one.
    walk = isaac_clips["amp_humanoid_walk"]
    assert 0.05 < walk.meta["root_height_offset"] < 0.12
    assert walk.meta["lowest_sole_height"] == pytest.approx(0.0, abs=1e-6)


@needs_isaac
def test_isaac_npy_resample_and_roundtrip(tmp_path):
    clip = import_motion(ISAAC / "amp_humanoid_run.npy", fps=30)
    assert_valid_clip(clip, fps=30.0)
    assert clip.duration == pytest.approx(81 / 60, abs=1 / 30)
    loaded = MotionClip.load(clip.save(tmp_path / "run.npz"))
    assert np.array_equal(loaded.qpos, clip.qpos) and loaded.fps == clip.fps
    assert loaded.meta["importer"] == "isaac_npy"


# ------------------------------------------------------------------------------------------
# DeepMimic .txt
# ------------------------------------------------------------------------------------------
def deepmimic_fk(frames: np.ndarray, offsets_z_up: np.ndarray) -> np.ndarray:
    """Independent DeepMimic FK: y-up, quaternions w x y z, knees/elbows about z; result mapped to z up."""
    layout = [("duration", 1), ("root_pos", 3), ("root_rot", 4), ("torso", 4), ("head", 4),
              ("right_thigh", 4), ("right_shin", 1), ("right_foot", 4), ("right_upper_arm", 4),
              ("right_lower_arm", 1), ("left_thigh", 4), ("left_shin", 1), ("left_foot", 4),
              ("left_upper_arm", 4), ("left_lower_arm", 1)]
    cols, col = {}, 0
    for name, size in layout:
        cols[name] = frames[:, col:col + size]
        col += size
    n = len(frames)

    def quat(q):
        return Rotation.from_quat(q / np.linalg.norm(q, axis=1, keepdims=True), scalar_first=True)

    rots = []
    for body in BODY_NAMES:
        if body == "pelvis":
            rots.append(quat(cols["root_rot"]))
        elif body not in cols:
            rots.append(Rotation.identity(n))
        elif cols[body].shape[1] == 4:
            rots.append(quat(cols[body]))
        else:
            rots.append(Rotation.from_euler("z", cols[body]))
    offsets_y_up = Y_UP_TO_Z_UP.inv().apply(offsets_z_up)
    pos = skeleton_fk(cols["root_pos"], rots[0], rots, PARENT_INDICES, offsets_y_up)
    return Y_UP_TO_Z_UP.apply(pos.reshape(-1, 3)).reshape(pos.shape)


def amp_offsets() -> np.ndarray:
    """DeepMimic's humanoid3d offsets: the AMP skeleton's (from the IsaacGymEnvs file), else ours."""
    path = ISAAC / "amp_humanoid_walk.npy"
    if path.is_file():
        return np.load(path, allow_pickle=True).item()["skeleton_tree"]["local_translation"]["arr"]
    return our_offsets()


@needs_deepmimic
@pytest.mark.parametrize("name", DEEPMIMIC_LOCOMOTION + ["humanoid3d_jump"])
def test_deepmimic_shapes_ranges_fk_and_floor(name):
    data = json.loads((DEEPMIMIC / f"{name}.txt").read_text())
    frames = np.asarray(data["Frames"], dtype=np.float64)
    clip = import_motion(DEEPMIMIC / f"{name}.txt")
    assert_valid_clip(clip, frames=len(frames), fps=round(1.0 / frames[0, 0]))
    assert clip.loop == (data["Loop"] == "wrap")
    soles = foot_sole_heights(clip.qpos)
    assert -1e-6 <= soles.min() <= 0.02
    # FK: the file's own kinematics with DeepMimic's (= AMP) bone offsets vs. our humanoid.
    source = deepmimic_fk(frames, amp_offsets())
    source[..., 2] += clip.meta["root_height_offset"]
    err = np.linalg.norm(body_positions(clip.qpos) - source, axis=-1)
    assert err.mean() < 0.005, err.mean()
    assert err.max() < (0.01 if clip.meta["clamped_fraction"] == 0 else 0.05), err.max()


@needs_deepmimic
def test_deepmimic_joint_angles_round_trip():
    """Our Euler angles, mapped back to DeepMimic's y-up frame, give the file's quaternions."""
    data = json.loads((DEEPMIMIC / "humanoid3d_walk.txt").read_text())
    frames = np.asarray(data["Frames"], dtype=np.float64)
    clip = import_motion(DEEPMIMIC / "humanoid3d_walk.txt")
    assert clip.meta["clamped_fraction"] == 0.0
    fields = {"abdomen": 8, "neck": 12, "right_hip": 16, "right_ankle": 21, "right_shoulder": 25,
              "left_hip": 30, "left_ankle": 35, "left_shoulder": 39}
    hinges = {"right_knee": 20, "right_elbow": 29, "left_knee": 34, "left_elbow": 43}
    col = 7
    for joint, _, axes in JOINTS:
        angles = clip.qpos[:, col:col + len(axes)]
        col += len(axes)
        if joint in hinges:
            np.testing.assert_allclose(angles[:, 0], -frames[:, hinges[joint]], atol=1e-9)
            continue
        ours = Rotation.from_euler("XYZ", angles)
        back = Y_UP_TO_Z_UP.inv() * ours * Y_UP_TO_Z_UP
        theirs = Rotation.from_quat(frames[:, fields[joint]:fields[joint] + 4], scalar_first=True)
        assert (back.inv() * theirs).magnitude().max() < 1e-6, joint
    root = Rotation.from_quat(clip.qpos[:, 3:7], scalar_first=True)
    theirs = Y_UP_TO_Z_UP * Rotation.from_quat(frames[:, 4:8], scalar_first=True) * Y_UP_TO_Z_UP.inv()
    assert (root.inv() * theirs).magnitude().max() < 1e-6
    np.testing.assert_allclose(clip.qpos[:, :2], np.stack((frames[:, 1], -frames[:, 3]), axis=1), atol=1e-9)


@needs_deepmimic
@pytest.mark.parametrize("name", DEEPMIMIC_FLOOR_CONTACT)
def test_deepmimic_floor_contact_clips_stay_above_the_floor(name):
    clip = import_motion(DEEPMIMIC / f"{name}.txt")
    assert_valid_clip(clip, fps=60.0)
    low = lowest_body_point(clip.qpos)
    assert low.min() == pytest.approx(0.0, abs=1e-6)  # something touches, nothing sinks
    assert foot_sole_heights(clip.qpos).min() >= -1e-6


@needs_deepmimic
def test_deepmimic_irregular_durations_are_resampled():
    # humanoid3d_roll.txt has one frame of double duration and non-unit quaternions.
    clip = import_motion(DEEPMIMIC / "humanoid3d_roll.txt")
    assert clip.meta["irregular_durations"] is True and clip.meta["resampled"] is True
    assert clip.meta["max_quaternion_norm_error"] > 0.1
    assert_valid_clip(clip, fps=60.0)
    assert clip.duration == pytest.approx(2.0, abs=1 / 60)


# ------------------------------------------------------------------------------------------
# BVH: the CMU stair ascent
# ------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def stairs():
    return import_motion(CMU_STAIRS)


@needs_cmu
def test_bvh_parser_reads_the_hierarchy():
    from stairenv.motion.importers.bvh import forward_kinematics, read_bvh

    motion = read_bvh(CMU_STAIRS)
    assert len(motion.joints) == 31 and motion.num_channels == 96
    assert motion.frames.shape == (1042, 96)
    assert motion.fps == pytest.approx(120.0, rel=1e-4)
    root = motion.joints[0]
    assert root.name == "Hips" and root.parent == -1 and len(root.channels) == 6
    assert root.rotation_order == "ZYX"
    assert all(j.rotation_order == "ZYX" for j in motion.joints)
    rest = motion.rest_positions()
    assert np.linalg.norm(rest["LeftLeg"] - rest["LeftUpLeg"]) == pytest.approx(np.hypot(2.29640, 6.30932), abs=1e-4)
    # Frame 1 stands with the hips 16.26 units (0.92 m) up; FK puts the root where the channels say.
    _, pos = forward_kinematics(motion, motion.frames[1:2])
    assert pos[0, 0] == pytest.approx(motion.frames[1, :3])
    assert pos[0, 0, 1] * 0.0564 == pytest.approx(0.92, abs=0.01)


def test_bvh_rotation_order_comes_from_the_channels():
    from stairenv.motion.importers.bvh import forward_kinematics, parse_bvh

    text = """HIERARCHY
ROOT A
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Xrotation Zrotation Yrotation
  JOINT B
  {
    OFFSET 0 1 0
    CHANNELS 3 Yrotation Xrotation Zrotation
    End Site
    {
      OFFSET 0 1 0
    }
  }
}
MOTION
Frames: 1
Frame Time: 0.01
1 2 3 10 20 30 40 50 60
"""
    motion = parse_bvh(text, "inline.bvh")
    assert [j.rotation_order for j in motion.joints] == ["XZY", "YXZ"]
    rots, pos = forward_kinematics(motion)
    expected_a = Rotation.from_euler("XZY", [10, 20, 30], degrees=True)
    expected_b = expected_a * Rotation.from_euler("YXZ", [40, 50, 60], degrees=True)
    assert (rots[0][0].inv() * expected_a).magnitude() < 1e-12
    assert (rots[1][0].inv() * expected_b).magnitude() < 1e-12
    np.testing.assert_allclose(pos[0, 1], [1, 2, 3] + expected_a.apply([0, 1, 0]))


@needs_cmu
def test_bvh_stairs_clip_is_valid(stairs):
    assert_valid_clip(stairs, frames=261, fps=30.0)  # 1041 frames at 120 Hz (frame 0 skipped) -> 30 Hz
    assert stairs.meta["skipped_frames"] == 1 and stairs.meta["skeleton"] == "cmu"
    assert stairs.meta["clamped_fraction"] < 0.01
    # Retargeted limbs point where the subject's do (bone-length-independent FK check).
    assert stairs.meta["limb_direction_error_deg"]["max"] < 1.0


@needs_cmu
def test_bvh_stairs_climb(stairs):
    root = stairs.qpos[:, :3]
    rise = root[-15:, 2].mean() - root[:15, 2].mean()
    assert 0.4 < rise < 0.6, rise
    assert 0.8 < root[:15, 2].mean() < 0.95  # standing pelvis height (ours: 0.885 m)
    assert np.linalg.norm(root[-1, :2] - root[0, :2]) > 2.0  # it walks up, not in place
    soles = foot_sole_heights(stairs.qpos)
    assert soles.min() == pytest.approx(0.0, abs=1e-6)
    treads = []
    for foot in range(2):
        runs = plateaus(soles[:, foot])
        floor = runs[0][2]
        assert runs[0][0] == 0 and floor < 0.03, "feet start on the floor"
        levels = [level for _, _, level in runs if level > floor + 0.1]
        assert levels, "each foot lands on treads"
        assert 0.45 < levels[-1] < 0.62, "each foot ends on the top tread"
        assert runs[-1][1] == len(soles) - 1, "and stands there to the end"
        treads += levels
    # Cluster the tread heights of both feet: three treads at multiples of one step height.
    treads = sorted(treads)
    clusters = [[treads[0]]]
    for level in treads[1:]:
        if level - clusters[-1][-1] < 0.06:
            clusters[-1].append(level)
        else:
            clusters.append([level])
    heights = np.array([np.mean(c) for c in clusters])
    assert len(heights) == 3, heights
    k = np.arange(1, 4)
    step = float(heights @ k / (k @ k))
    assert 0.15 < step < 0.21, step
    assert np.abs(heights - k * step).max() < 0.03, (heights, step)


@needs_cmu
def test_bvh_stairs_roundtrip_and_reference_motion(stairs, tmp_path):
    path = stairs.save(tmp_path / "stairs.npz")
    loaded = MotionClip.load(path)
    assert np.array_equal(loaded.qpos, stairs.qpos)
    assert loaded.fps == stairs.fps and loaded.name == "83_32" and loaded.meta == json.loads(json.dumps(stairs.meta))
    library = MotionLibrary.load(tmp_path)
    qpos, qvel = library.states(np.zeros(50, dtype=int), np.linspace(0.0, stairs.duration, 50))
    assert np.isfinite(qpos).all() and np.isfinite(qvel).all()
    assert np.abs(qvel[:, :3]).max() < 5.0  # no jumps in the root path
    from stairenv.style.features import reference_features

    features = reference_features(loaded, 30.0)
    assert len(features) == loaded.num_frames and np.isfinite(features).all()


@needs_cmu
def test_bvh_options(stairs):
    native = import_motion(CMU_STAIRS, fps=None)
    assert native.fps == 120.0 and native.num_frames == 1041
    # Resampling (slerp) lands on the native frames at every fourth frame; the floor is
    # measured on the output frames, so heights may differ by a constant below 1 mm.
    np.testing.assert_allclose(native.qpos[::4, 3:], stairs.qpos[:, 3:], atol=1e-9)
    np.testing.assert_allclose(native.qpos[::4, :2], stairs.qpos[:, :2], atol=1e-12)
    dz = native.qpos[::4, 2] - stairs.qpos[:, 2]
    assert np.ptp(dz) < 1e-12 and abs(dz[0]) < 1e-3
    with pytest.raises(ValueError, match="unknown source skeleton"):
        import_motion(CMU_STAIRS, skeleton="mixamo")
    no_skip = import_motion(CMU_STAIRS, skip_frames=0, fps=None)
    assert no_skip.num_frames == 1042


# ------------------------------------------------------------------------------------------
# command line
# ------------------------------------------------------------------------------------------
@needs_isaac
def test_convert_cli_on_a_folder(tmp_path):
    out = tmp_path / "clips"
    result = subprocess.run(
        [sys.executable, "-m", "stairenv.motion.convert", str(ISAAC), "--out", str(out), "--fps", "30"],
        capture_output=True, text=True, timeout=120,
    )
    assert result.returncode == 0, result.stderr
    written = sorted(p.stem for p in out.glob("*.npz"))
    assert written == sorted(p.stem for p in ISAAC.glob("*.npy"))
    lines = result.stdout.strip().splitlines()
    assert len(lines) == len(written)
    assert all("frames" in line and "30 fps" in line and "FK error" in line and "clamped" in line for line in lines)
    clip = MotionClip.load(out / "amp_humanoid_walk.npz")
    assert clip.fps == 30.0 and clip.meta["importer"] == "isaac_npy"


def test_convert_cli_bad_input(tmp_path):
    bad = tmp_path / "bad.bvh"
    bad.write_text("HIERARCHY\nROOT Hips\n{\n")
    result = subprocess.run(
        [sys.executable, "-m", "stairenv.motion.convert", str(bad), str(tmp_path / "missing.txt"),
         "--out", str(tmp_path / "out")],
        capture_output=True, text=True, timeout=60,
    )
    assert result.returncode == 1
    assert "missing.txt: no such file" in result.stderr
    result = subprocess.run(
        [sys.executable, "-m", "stairenv.motion.convert", str(bad), "--out", str(tmp_path / "out")],
        capture_output=True, text=True, timeout=60,
    )
    assert result.returncode == 1 and "bad.bvh: no MOTION section" in result.stderr
    assert not list((tmp_path / "out").glob("*.npz"))
