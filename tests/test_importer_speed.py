"""The clip importer's vectorised pieces give what the per-frame code gave (#23, item 6): rotations as
scipy's to rounding, the Viterbi choices and the lowest points bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from stairenv.humanoid.kinematics import forward_kinematics, humanoid_geoms, humanoid_lowest_z
from stairenv.humanoid.model import HumanoidIndices, humanoid_model
from stairenv.motion.clip import MotionFileError
from stairenv.motion.importers import (
    ball_joint_angles,
    compose,
    euler_rotation,
    foot_sole_heights,
    lowest_body_point,
)
from stairenv.motion.importers.kernels import viterbi2


@pytest.mark.parametrize("seq", ["XYZ", "ZYX", "ZXY", "xyz", "zyx", "zxy", "X", "zx", "YXZ"])
def test_euler_rotation_is_scipys(seq):
    angles = np.random.default_rng(len(seq)).uniform(-4.0, 4.0, (2000, len(seq)))
    ours, theirs = euler_rotation(seq, angles), Rotation.from_euler(seq, angles)
    np.testing.assert_allclose(ours.as_quat(), theirs.as_quat(), atol=1e-15, rtol=0)  # the same sign too
    np.testing.assert_allclose(euler_rotation(seq, np.degrees(angles), degrees=True).as_matrix(),
                               theirs.as_matrix(), atol=1e-14, rtol=0)


def test_compose_is_scipys_product():
    a, b, c = Rotation.random(500, rng=1), Rotation.random(500, rng=2), Rotation.random(rng=3)
    np.testing.assert_allclose(compose(c, a, c.inv(), b).as_quat(), (c * a * c.inv() * b).as_quat(), atol=1e-15)
    np.testing.assert_allclose(compose(a, c).as_quat(), (a * c).as_quat(), atol=1e-15)
    assert compose(c, c.inv()).single


def _reference_viterbi(error: np.ndarray, step: np.ndarray) -> np.ndarray:
    """The per-frame numpy pass the importer ran before (ties and NaN as np.argmin takes them)."""
    n = len(error)
    cost, back = error[0].copy(), np.zeros((n, 2), dtype=int)
    for t in range(1, n):
        total = cost[:, None] + step[t - 1]
        back[t] = np.argmin(total, axis=0)
        cost = total[back[t], [0, 1]] + error[t]
    choice = np.empty(n, dtype=int)
    choice[-1] = int(np.argmin(cost))
    for t in range(n - 1, 0, -1):
        choice[t - 1] = back[t, choice[t]]
    return choice


def test_compiled_viterbi_chooses_as_the_per_frame_pass():
    rng = np.random.default_rng(0)
    for trial in range(300):  # coarse values: many ties; some NaN
        n = int(rng.integers(1, 80))
        error = rng.integers(0, 3, (n, 2)) * 0.5
        step = rng.integers(0, 3, (max(n - 1, 0), 2, 2)) * 0.25
        if trial % 3 == 0 and n > 2:
            error[rng.integers(n), rng.integers(2)] = np.nan
        if trial % 5 == 0 and n > 2:
            step[rng.integers(n - 1), rng.integers(2), rng.integers(2)] = np.nan
        np.testing.assert_array_equal(viterbi2(error, step), _reference_viterbi(error, step))


def test_ball_joint_angles_choose_as_before():
    """A shoulder swinging through the gimbal region and out of reach: the branch choice of the
    vectorised transition costs and the Python pass equals the per-frame pass's."""
    t = np.linspace(0.0, 12.0, 700)
    rot = Rotation.from_rotvec(np.column_stack((1.8 * np.sin(t), 1.7 * np.cos(0.7 * t), 0.9 * np.sin(1.3 * t))))
    low, high = np.radians([-90.0, -90.0, -60.0]), np.radians([90.0, 60.0, 120.0])
    angles, raw = ball_joint_angles(rot, low, high, np.array([0.0, 0.0, -1.0]), fit=False)
    # the candidates and errors as the importer builds them, then the old pass
    e1 = rot.as_euler("XYZ")
    e2 = e1 + np.array([np.pi, 0.0, np.pi])
    e2[:, 1] = np.pi - e1[:, 1]
    centre = 0.5 * (low + high)
    e1, e2 = (centre + np.mod(e - centre + np.pi, 2.0 * np.pi) - np.pi for e in (e1, e2))
    cands = np.stack((np.clip(e1, low, high), np.clip(e2, low, high)), axis=1)
    assert {tuple(row) for row in angles} <= {tuple(c) for c in cands.reshape(-1, 3)}
    mats = rot.as_matrix()
    diff = Rotation.from_euler("XYZ", cands.reshape(-1, 3)).as_matrix().reshape(-1, 2, 3, 3) - mats[:, None]
    error = np.sum(diff ** 2, axis=(2, 3)) + 9.0 * np.sum((diff @ np.array([0.0, 0.0, -1.0])) ** 2, axis=2)
    step = 0.05 * np.sum((cands[1:, None] - cands[:-1, :, None]) ** 2, axis=3)
    choice = _reference_viterbi(error, step)
    np.testing.assert_array_equal(angles, cands[np.arange(len(t)), choice])
    assert len(set(choice.tolist())) == 2  # both branches are used


def test_lowest_points_are_the_per_frame_values_bit_for_bit():
    model = humanoid_model()
    rng = np.random.default_rng(3)
    qpos = np.zeros((400, model.nq))
    qpos[:, 2] = 1.0
    quat = rng.normal(size=(400, 4))
    qpos[:, 3:7] = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    qpos[:, 7:] = rng.normal(0.0, 1.0, (400, model.nq - 7))
    geoms = humanoid_geoms(model, HumanoidIndices.from_model(model))
    expected = np.array([humanoid_lowest_z(model, data, geoms) for data in forward_kinematics(qpos)])
    np.testing.assert_array_equal(lowest_body_point(qpos), expected)
    from stairenv.humanoid.kinematics import foot_box_geoms

    feet = foot_box_geoms()
    soles = np.array([[humanoid_lowest_z(model, data, feet[k:k + 1]) for k in range(2)]
                      for data in forward_kinematics(qpos)])
    np.testing.assert_array_equal(foot_sole_heights(qpos), soles)


@pytest.mark.parametrize("with_bone", [True, False])
def test_compiled_fit_is_scipys_fit(with_bone):
    """The compiled bounded fit (``kernels.fit_in_range``, what the importers take) ends where scipy's
    ``least_squares`` (``_fit_in_range``) ends, bit for bit: the same steps, the same BLAS products."""
    from stairenv.motion.importers.common import _fit_in_range
    from stairenv.motion.importers.kernels import fit_in_range

    low, high = np.radians([-60.0, -80.0, -45.0]), np.radians([70.0, 40.0, 90.0])
    bone = np.array([0.0, 0.0, -1.0]) if with_bone else None
    targets = Rotation.random(120, rng=7 + with_bone).as_matrix()
    e1 = Rotation.from_matrix(targets).as_euler("XYZ")
    e2 = e1 + np.array([np.pi, 0.0, np.pi])
    e2[:, 1] = np.pi - e1[:, 1]
    starts = np.concatenate([np.clip(e1, low, high), np.clip(e2, low, high)])
    targets = np.concatenate([targets, targets])
    expected = np.array([_fit_in_range(t, s, low, high, bone, 3.0) for t, s in zip(targets, starts)])
    got = fit_in_range(targets, starts, low, high, np.zeros(3) if bone is None else bone, 3.0,
                       9 if bone is None else 12)
    assert np.all((got >= low) & (got <= high))
    np.testing.assert_array_equal(got, expected)
    assert np.mean(np.any(got != starts, axis=1)) > 0.5  # most of them moved


def _number_texts(rng: np.random.Generator, count: int) -> list[str]:
    """Decimal numbers as files write them (fixed, exponent, short and long, signs, '5.', '.5')."""
    texts = []
    for k in rng.integers(0, 7, count):
        x = rng.normal() * 10.0 ** rng.integers(-8, 8)
        texts.append([repr(x), f"{x:.{rng.integers(0, 17)}f}", f"{x:.{rng.integers(0, 19)}e}",
                      str(rng.integers(-10**6, 10**6)), f"{rng.uniform(-1, 1):.6f}".replace("0.", "."),
                      f"{rng.integers(0, 1000)}.", f"+{abs(x):.9f}"][k])
    return texts


def test_compiled_bvh_values_are_floats_of_the_text():
    """``kernels.parse_frames`` gives what ``float()`` gives, bit for bit, or declines (status 2: then
    the importer reads the line with ``float()``, which names a fault); a line of another length: 1."""
    from stairenv.motion.importers.kernels import parse_frames

    def parse(text: str, rows: int, columns: int):
        return parse_frames(np.frombuffer(text.encode("ascii"), dtype=np.uint8), rows, columns)

    texts = _number_texts(np.random.default_rng(5), 24_000)
    taken = [t for t in texts if parse(t, 1, 1)[1] == 0]
    assert len(taken) > 0.7 * len(texts)  # the rest: more than 2^53 as digits (repr of most doubles)
    taken = taken[:len(taken) // 8 * 8]
    block = "\n".join(" \t".join(taken[i:i + 8]) for i in range(0, len(taken), 8))
    values, status = parse(block, len(taken) // 8, 8)
    assert status == 0
    expected = np.array([float(t) for t in taken]).reshape(-1, 8)
    np.testing.assert_array_equal(values.view(np.int64), expected.view(np.int64))  # -0.0 too
    for text in ("1e", "e5", ".", "-", "1.2.3", "1_0", "inf", "nan", "--1", "1e5x", "0x10", "1" * 30, "1e400"):
        assert parse(text, 1, 1)[1] == 2, text
    assert parse("1 2", 1, 1)[1] == 1 and parse("1\n2 3", 2, 1)[1] == 1 and parse("1", 2, 1)[1] == 1


def test_bvh_frames_parse_the_same_either_way(monkeypatch):
    from stairenv.motion.importers import bvh

    lines = ["HIERARCHY", "ROOT Hips", "{", "OFFSET 0 0 0",
             "CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation",
             "End Site", "{", "OFFSET 0 1 0", "}", "}", "MOTION", "Frames: 600", "Frame Time: .0083333"]
    texts = [t for t in _number_texts(np.random.default_rng(6), 8000) if len(t) < 17 and abs(float(t)) < 1e5][:3600]
    rows = [" ".join(texts[i:i + 6]) for i in range(0, 3600, 6)]
    rows[10:10] = ["", " \t "]  # blank lines are skipped
    text = "\n".join(lines + rows) + "\n\n"
    monkeypatch.setattr(bvh, "COMPILED_VITERBI_FRAMES", 500)
    compiled = bvh._parse_frames_compiled(text.splitlines()[13:], 600, 6)
    assert compiled is not None
    monkeypatch.setattr(bvh, "COMPILED_VITERBI_FRAMES", 10**9)
    monkeypatch.delitem(__import__("sys").modules, "numba")
    plain = bvh.parse_bvh(text).frames
    np.testing.assert_array_equal(compiled.view(np.int64), plain.view(np.int64))
    monkeypatch.setattr(bvh, "COMPILED_VITERBI_FRAMES", 500)
    bad = text.replace(texts[700], "1.2.3", 1)  # the plain reader names the fault
    with pytest.raises(MotionFileError, match="'1.2.3' is not a number"):
        bvh.parse_bvh(bad)
    with pytest.raises(MotionFileError, match="frame 3 has 7 values"):
        bvh.parse_bvh(text.replace(rows[3], rows[3] + " 1", 1))
    with pytest.raises(MotionFileError, match="but 601 frame lines follow"):
        bvh.parse_bvh(text + rows[5] + "\n")
    with pytest.raises(MotionFileError, match="only 599 frame lines"):
        bvh.parse_bvh(text.replace(rows[20] + "\n", "", 1))


def test_slerp_is_scipys():
    from scipy.spatial.transform import Slerp

    from stairenv.motion.importers.common import slerp

    rng = np.random.default_rng(4)
    times = np.cumsum(rng.uniform(0.005, 0.04, 600))
    rot = Rotation.from_rotvec(np.cumsum(rng.normal(0.0, 0.3, (600, 3)), axis=0))
    rot = Rotation.from_quat(np.concatenate([rot.as_quat()[:300], Rotation.random(300, rng=4).as_quat()]))
    rot = Rotation.from_quat(np.concatenate([rot.as_quat(), rot.as_quat()[-1:]]) [1:])  # a repeated pose too
    at = np.concatenate([[times[0]], np.sort(rng.uniform(times[0], times[-1], 2000)), times[5:9], [times[-1]]])
    ours, theirs = slerp(times, rot, at), Slerp(times, rot)(at)
    np.testing.assert_allclose(ours.as_quat(), theirs.as_quat(), atol=2e-15, rtol=0)
    for bad in (at + 1.0, at - 1.0):
        with pytest.raises(ValueError):
            slerp(times, rot, bad)


def test_body_rotations_are_mujocos():
    """``body_rotations`` (all frames at once, for the limb-direction check) gives MuJoCo's ``xmat``."""
    from stairenv.humanoid.kinematics import body_rotations

    model = humanoid_model()
    rng = np.random.default_rng(8)
    qpos = np.zeros((300, model.nq))
    qpos[:, :3] = rng.normal(size=(300, 3))
    qpos[:, 3:7] = rng.normal(size=(300, 4)) * rng.uniform(0.5, 2.0, (300, 1))  # normalised as MuJoCo does
    qpos[:, 7:] = rng.normal(0.0, 2.0, (300, model.nq - 7))
    names = [model.body(b).name for b in range(1, model.nbody)]
    ours = body_rotations(qpos, ["left_hand", "right_foot"])
    assert set(ours) == {"pelvis", "torso", "left_upper_arm", "left_lower_arm", "left_hand",
                         "right_thigh", "right_shin", "right_foot"}
    ours = body_rotations(qpos, names)
    mujocos = np.array([data.xmat.copy() for data in forward_kinematics(qpos)]).reshape(300, -1, 3, 3)
    for name in names:
        np.testing.assert_allclose(ours[name], mujocos[:, model.body(name).id], atol=5e-15, rtol=0)


def test_sum3_adds_as_numpy():
    from stairenv.motion.importers.common import _sum3

    x = np.random.default_rng(9).normal(size=(4, 5000, 2, 3)) * 10.0 ** np.arange(-8, 8, 4)[:, None, None, None]
    np.testing.assert_array_equal(_sum3(x ** 2), np.sum(x ** 2, axis=-1))
    np.testing.assert_array_equal(_sum3(x[:, 0, 0]), x[:, 0, 0].sum(axis=-1))
