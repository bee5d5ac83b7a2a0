"""The helpers every importer shares (see the package docstring, :mod:`stairenv.motion.importers`):
the limits and checks on what a file may ask for, rotations to joint angles, resampling into a
clip, grounding. The package re-exports them; the importers import them from here, so that the
package's ``import_motion`` (which names the importers by string) and the importers form no cycle."""

from __future__ import annotations

import math
import sys
from collections.abc import Mapping
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from stairenv.humanoid import BODY_NAMES, DOF_NAMES, JOINTS, NUM_DOFS, dof_ranges, humanoid_model
from stairenv.humanoid.kinematics import body_positions, foot_sole_heights, lowest_body_point
from stairenv.motion.clip import QPOS_SIZE, MotionClip, MotionFileError

__all__ = [
    "MAX_ABS_VALUE",
    "MAX_DURATION_S",
    "MAX_FILE_BYTES",
    "MAX_FPS",
    "MAX_FRAMES",
    "MAX_JOINTS",
    "MAX_ROOT_DISTANCE_M",
    "MIN_FPS",
    "MotionFileError",
    "ball_joint_angles",
    "body_positions",
    "check_timing",
    "check_values",
    "compose",
    "euler_rotation",
    "fk_position_error",
    "foot_sole_heights",
    "ground_offset",
    "joints_to_qpos",
    "lowest_body_point",
    "make_clip",
    "read_limited",
    "slerp",
    "snap_fps",
]

# Limits on what a motion file may ask for (see the package docstring).
MAX_FILE_BYTES = 32 * 2**20
MAX_FRAMES = 100_000
MAX_DURATION_S = 3600.0
MIN_FPS, MAX_FPS = 1.0, 1000.0
MAX_JOINTS = 256
MAX_ABS_VALUE = 1e6
MAX_ROOT_DISTANCE_M = 1000.0

# --------------------------------------------------------------------------------------
# Limits shared by all importers
# --------------------------------------------------------------------------------------
def read_limited(path: Path) -> bytes:
    """The bytes of ``path``; ``MotionFileError`` if unreadable or larger than ``MAX_FILE_BYTES``."""
    try:
        with path.open("rb") as f:
            data = f.read(MAX_FILE_BYTES + 1)  # never more, whatever the file claims to be
    except OSError as err:
        raise MotionFileError(f"{path}: cannot read ({err})") from err
    if len(data) > MAX_FILE_BYTES:
        raise MotionFileError(f"{path}: larger than the limit of {MAX_FILE_BYTES} bytes")
    return data


def check_timing(path: str | Path, frames: int, fps: float, duration: float) -> None:
    """``MotionFileError`` unless ``frames`` frames over ``duration`` s at ``fps`` are within the limits.

    Importers check their source with it before any work that grows with its length, and
    ``make_clip`` the clip it is about to make (``duration * fps + 1`` frames), so no file
    asks for more frames, time or memory than ``MAX_FRAMES`` and ``MAX_DURATION_S`` allow.
    """
    if not MIN_FPS <= fps <= MAX_FPS:  # NaN fails too
        raise MotionFileError(f"{path}: frame rate {fps:g} fps outside [{MIN_FPS:g}, {MAX_FPS:g}]")
    if not 0.0 <= duration <= MAX_DURATION_S:
        raise MotionFileError(f"{path}: duration {duration:g} s outside [0, {MAX_DURATION_S:g}] s")
    needed = max(frames, math.floor(duration * fps + 1e-6) + 1)
    if needed > MAX_FRAMES:
        raise MotionFileError(f"{path}: {needed} frames at {fps:g} fps, more than the limit of {MAX_FRAMES}")


def check_values(path: str | Path, what: str, values: np.ndarray, limit: float = MAX_ABS_VALUE) -> None:
    """``MotionFileError`` unless every number of ``values`` is finite and at most ``limit`` in size."""
    bad = ~(np.abs(values) <= limit)  # NaN fails too
    if bad.any():
        index = tuple(int(i) for i in np.argwhere(bad)[0])
        raise MotionFileError(
            f"{path}: {what}{list(index)} is {values[index]:g}, not a finite number within +-{limit:g}")


# --------------------------------------------------------------------------------------
# Local joint rotations -> hinge angles
# --------------------------------------------------------------------------------------
_HINGE_DOFS = [i for i, name in enumerate(DOF_NAMES) if name in {j for j, _, a in JOINTS if len(a) == 1}]


# Direction of the segment each three-axis joint moves, in the joint body's frame (zero pose):
# the spine and neck point up, limbs down, the foot forward.
_BONES: dict[str, np.ndarray] = {
    "abdomen": np.array([0.0, 0.0, 1.0]), "neck": np.array([0.0, 0.0, 1.0]),
    "right_shoulder": np.array([0.0, 0.0, -1.0]), "left_shoulder": np.array([0.0, 0.0, -1.0]),
    "right_hip": np.array([0.0, 0.0, -1.0]), "left_hip": np.array([0.0, 0.0, -1.0]),
    "right_ankle": np.array([1.0, 0.0, 0.0]), "left_ankle": np.array([1.0, 0.0, 0.0]),
}


def _quat_product(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton products of (..., 4) x, y, z, w quaternions (broadcast): the rotation ``p`` after ``q``."""
    px, py, pz, pw = (p[..., k] for k in range(4))
    qx, qy, qz, qw = (q[..., k] for k in range(4))
    out = np.empty(np.broadcast_shapes(p.shape, q.shape))
    out[..., 0] = pw * qx + px * qw + py * qz - pz * qy
    out[..., 1] = pw * qy - px * qz + py * qw + pz * qx
    out[..., 2] = pw * qz + px * qy - py * qx + pz * qw
    out[..., 3] = pw * qw - px * qx - py * qy - pz * qz
    return out


def _axis_product(p: np.ndarray, axis: int, sin: np.ndarray, cos: np.ndarray) -> np.ndarray:
    """``_quat_product(p, q)`` for q the axis quaternions (sin on ``axis``, cos as w, 0 elsewhere): the
    same sums without their products with 0 (x + 0 and 0 + x are x), so the same values."""
    px, py, pz, pw = (p[..., k] for k in range(4))
    out = np.empty(np.broadcast_shapes(p.shape, sin.shape + (4,)))
    if axis == 0:
        out[..., 0] = pw * sin + px * cos
        out[..., 1] = py * cos + pz * sin
        out[..., 2] = -(py * sin) + pz * cos
        out[..., 3] = pw * cos - px * sin
    elif axis == 1:
        out[..., 0] = px * cos - pz * sin
        out[..., 1] = pw * sin + py * cos
        out[..., 2] = px * sin + pz * cos
        out[..., 3] = pw * cos - py * sin
    else:
        out[..., 0] = px * cos + py * sin
        out[..., 1] = -(px * sin) + py * cos
        out[..., 2] = pw * sin + pz * cos
        out[..., 3] = pw * cos - pz * sin
    return out


def compose(*rotations: Rotation) -> Rotation:
    """``r1 * r2 * ...`` (scipy's composition: ``r2`` applied first), on quaternion arrays: scipy 1.17
    composes a few microseconds per rotation, which over long clips cost seconds per product."""
    quat = rotations[0].as_quat()
    for rotation in rotations[1:]:
        quat = _quat_product(quat, rotation.as_quat())
    return Rotation.from_quat(quat)


def slerp(times: np.ndarray, rotations: Rotation, at: np.ndarray) -> Rotation:
    """``Slerp(times, rotations)(at)`` on quaternion arrays, for the intervals ``at`` falls in only:
    scipy's steps (the relative rotation of each interval as a rotation vector, scaled by the
    fraction of the interval, after the interval's first rotation) without a ``Rotation`` product per
    interval of the source (seconds over long clips). Equal to scipy's rotations to rounding (1e-15).
    ``ValueError`` for times outside [times[0], times[-1]] or not increasing, as scipy's."""
    times, at = np.asarray(times, dtype=np.float64), np.asarray(at, dtype=np.float64)
    if len(rotations) < 2 or len(times) != len(rotations):
        raise ValueError("slerp needs a time per rotation and at least 2 rotations")
    delta = np.diff(times)
    if np.any(delta <= 0):
        raise ValueError("Times must be in strictly increasing order.")
    ind = np.searchsorted(times, at) - 1
    ind[at == times[0]] = 0
    if np.any((ind < 0) | (ind > len(times) - 2)):
        raise ValueError(f"Interpolation times must be within the range [{times[0]}, {times[-1]}], both inclusive.")
    quat = rotations.as_quat()
    start, end = quat[ind], quat[ind + 1]
    relative = _quat_product(start * np.array([-1.0, -1.0, -1.0, 1.0]), end)
    relative[relative[:, 3] < 0] *= -1.0  # as_rotvec's canonical half: w >= 0
    sin_half = np.linalg.norm(relative[:, :3], axis=1)
    angle = 2.0 * np.arctan2(sin_half, relative[:, 3])
    small = angle <= 1e-3
    angle2 = angle ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        scale = np.where(small, 2.0 + angle2 / 12.0 + 7.0 * angle2 ** 2 / 2880.0, angle / np.sin(angle / 2.0))
    rotvec = scale[:, None] * relative[:, :3] * ((at - times[ind]) / delta[ind])[:, None]
    angle = np.linalg.norm(rotvec, axis=1)
    small = angle <= 1e-3
    angle2 = angle ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        scale = np.where(small, 0.5 - angle2 / 48.0 + angle2 ** 2 / 3840.0, np.sin(angle / 2.0) / angle)
    step = np.concatenate((rotvec * scale[:, None], np.cos(angle / 2.0)[:, None]), axis=1)
    return Rotation.from_quat(_quat_product(start, step))


_AXES = {"x": 0, "y": 1, "z": 2}


def euler_rotation(seq: str, angles: np.ndarray, degrees: bool = False) -> Rotation:
    """``Rotation.from_euler(seq, angles, degrees)`` for (T, len(seq)) angles (upper case: intrinsic
    axes, lower case: extrinsic), built from the axis quaternions at once (scipy 1.17 takes ~5-10 us
    a rotation). Equal to scipy's rotation to rounding (1e-15)."""
    angles = np.asarray(angles, dtype=np.float64)
    if degrees:
        angles = np.deg2rad(angles)
    half = 0.5 * angles
    axes = [_AXES[axis] for axis in seq.lower()]
    order = list(range(len(axes)))
    if seq.islower():  # extrinsic: the first axis applies first
        order.reverse()
    first = order[0]
    quat = np.zeros((*angles.shape[:-1], 4))
    quat[..., axes[first]] = np.sin(half[..., first])
    quat[..., 3] = np.cos(half[..., first])
    for k in order[1:]:
        quat = _axis_product(quat, axes[k], np.sin(half[..., k]), np.cos(half[..., k]))
    return Rotation.from_quat(quat)


@lru_cache(maxsize=1)
def _dof_ranges() -> np.ndarray:
    return dof_ranges(humanoid_model())


def _wrap_towards(angles: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """Add multiples of 2 pi so each angle lies in [centre - pi, centre + pi) of its range."""
    centre = 0.5 * (low + high)
    return centre + np.mod(angles - centre + np.pi, 2.0 * np.pi) - np.pi


def _violation(angles: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    return _sum3(np.maximum(low - angles, 0.0) + np.maximum(angles - high, 0.0))


def _sum3(x: np.ndarray) -> np.ndarray:
    """``np.sum(x, axis=-1)`` for a last axis of 3, as numpy adds them (first to last: numpy's sum of
    fewer than 8 values; the speed test holds it to that), without the reduction's overhead."""
    return (x[..., 0] + x[..., 1]) + x[..., 2]


def ball_joint_angles(
    rot: Rotation,
    low: np.ndarray,
    high: np.ndarray,
    bone: np.ndarray | None = None,
    bone_weight: float = 3.0,
    smoothness: float = 0.05,
    fit: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """(T,) rotations -> in-range intrinsic XYZ Euler angles (T, 3), and the raw angles (T, 3).

    Every rotation has two XYZ solutions, (x, y, z) and (x + pi, pi - y, z + pi) (hip and
    shoulder flexion beyond 90 degrees needs the second); each angle is wrapped by 2 pi
    towards its range. Each frame gets one in-range candidate per solution: the solution
    itself when it lies in [low, high] (exact), else its per-axis clamp, refined when
    neither solution is in range (``fit``) by a bounded least-squares fit that minimises
    the chordal distance of the rotation matrices plus ``bone_weight`` times the distance
    between the images of ``bone`` (the child segment's direction, whose end position
    matters most); clamping each angle on its own is not the nearest reachable rotation.

    The candidates are then chosen along the clip by dynamic programming (Viterbi over
    the two per frame), minimising the summed pose error (the same distance) plus
    ``smoothness`` times the squared change of the angles between frames. Exact
    candidates win unless taking one would mean a jump of the angles between branches
    (the gimbal region y = +-90 degrees, or a rotation that leaves the joint's reach);
    there the sequence follows one branch instead of hopping.

    The raw angles are the solution nearest the range, unclamped: raw - angles is how far
    the source is out of range.
    """
    e1 = rot.as_euler("XYZ")
    e2 = e1 + np.array([np.pi, 0.0, np.pi])
    e2[:, 1] = np.pi - e1[:, 1]
    e1 = _wrap_towards(e1, low, high)
    e2 = _wrap_towards(e2, low, high)
    v1, v2 = _violation(e1, low, high), _violation(e2, low, high)
    raw = np.where((v1 <= v2)[:, None], e1, e2)
    n = len(e1)
    cands = np.stack((np.clip(e1, low, high), np.clip(e2, low, high)), axis=1)  # (T, 2, 3)
    mats = rot.as_matrix()
    if fit:
        rows = np.flatnonzero((v1 > 1e-12) & (v2 > 1e-12))
        if rows.size:
            cands[rows] = _fit_all_in_range(mats[rows], cands[rows], low, high, bone, bone_weight)
    diff = euler_rotation("XYZ", cands.reshape(-1, 3)).as_matrix().reshape(n, 2, 3, 3) - mats[:, None]
    error = np.sum(diff ** 2, axis=(2, 3))
    if bone is not None:
        error += bone_weight ** 2 * _sum3((diff @ bone) ** 2)
    # Viterbi over the two candidates per frame: the transition costs of all frames at once
    # (previous choice, current choice), then the compiled pass along the clip.
    step = smoothness * _sum3((cands[1:, None, :, :] - cands[:-1, :, None, :]) ** 2)
    choice = _viterbi2(np.ascontiguousarray(error), np.ascontiguousarray(step))
    return cands[np.arange(n), choice], raw


#: clips this long repay numba's first load (~1 s) with a compiled Viterbi pass (a process that has
#: loaded numba already, an env's, takes it from 500 frames)
COMPILED_VITERBI_FRAMES = 20_000


def _first_min(a: float, b: float) -> int:
    """``np.argmin([a, b])``: the first minimum, NaN counting as the minimum."""
    if a != a:
        return 0
    if b != b or b < a:
        return 1
    return 0


def _viterbi2(error: np.ndarray, step: np.ndarray) -> np.ndarray:
    """The cheapest choice per frame of two candidates: ``error`` (T, 2) per frame, ``step`` (T - 1, 2, 2)
    from the previous frame's choice to this one's; ties and NaN go as ``np.argmin`` takes them. On
    Python floats (the same double additions as arrays, without an array call per frame); clips of
    ``COMPILED_VITERBI_FRAMES`` frames or more take the compiled ``kernels.viterbi2`` (the same operations,
    the same choices)."""
    n = error.shape[0]
    if n >= COMPILED_VITERBI_FRAMES or (n >= 500 and "numba" in sys.modules):
        from stairenv.motion.importers.kernels import viterbi2

        return viterbi2(error, step)
    errors, steps = error.tolist(), step.reshape(-1, 4).tolist()
    back = [(0, 0)] * n
    cost0, cost1 = errors[0]
    for t in range(1, n):  # _first_min written out: a call per comparison cost more than the rest
        s00, s01, s10, s11 = steps[t - 1]
        e0, e1 = errors[t]
        a, b = cost0 + s00, cost1 + s10
        k0 = 0 if a != a else (1 if b != b or b < a else 0)
        c, d = cost0 + s01, cost1 + s11
        k1 = 0 if c != c else (1 if d != d or d < c else 0)
        back[t] = (k0, k1)
        cost0, cost1 = (a if k0 == 0 else b) + e0, (c if k1 == 0 else d) + e1
    choice = np.empty(n, dtype=np.int64)
    k = _first_min(cost0, cost1)
    choice[n - 1] = k
    for t in range(n - 1, 0, -1):
        k = back[t][k]
        choice[t - 1] = k
    return choice


def _fit_all_in_range(
    targets: np.ndarray,
    starts: np.ndarray,
    low: np.ndarray,
    high: np.ndarray,
    bone: np.ndarray | None,
    bone_weight: float,
) -> np.ndarray:
    """``_fit_in_range`` of both candidates ``starts`` (R, 2, 3) of each rotation matrix ``targets``
    (R, 3, 3) at once: the compiled port of the same scipy fit (``kernels.fit_in_range``; ~7 ms a fit
    in scipy, well under 0.1 ms compiled), the same steps and the same results (bit for bit in the tests)."""
    from stairenv.motion.importers.kernels import fit_in_range

    pairs = np.ascontiguousarray(np.repeat(targets, 2, axis=0), dtype=np.float64)
    flat = np.ascontiguousarray(starts.reshape(-1, 3), dtype=np.float64)
    weighted = np.zeros(3) if bone is None else np.ascontiguousarray(bone, dtype=np.float64)
    fitted = fit_in_range(pairs, flat, np.ascontiguousarray(low, dtype=np.float64),
                          np.ascontiguousarray(high, dtype=np.float64),
                          weighted, float(bone_weight), 9 if bone is None else 12)
    return fitted.reshape(starts.shape)


def _fit_in_range(
    target: np.ndarray,
    start: np.ndarray,
    low: np.ndarray,
    high: np.ndarray,
    bone: np.ndarray | None,
    bone_weight: float,
) -> np.ndarray:
    """In-range angles near the rotation matrix ``target``, from ``start`` (see ``ball_joint_angles``):
    scipy's bounded least squares, the reference ``kernels.fit_in_range`` ports (the importers take the
    compiled one, ``_fit_all_in_range``)."""
    from scipy.optimize import least_squares

    lo, hi = low + 1e-9, high - 1e-9

    def residual(e: np.ndarray) -> np.ndarray:
        diff = _xyz_matrix(e) - target
        if bone is None:
            return diff.ravel()
        return np.concatenate((diff.ravel(), bone_weight * (diff @ bone)))

    fit = least_squares(residual, np.clip(start, lo, hi), bounds=(lo, hi), xtol=1e-10, ftol=1e-10)
    if np.sum(fit.fun ** 2) < np.sum(residual(start) ** 2):
        return np.clip(fit.x, low, high)
    return start


def _xyz_matrix(e: np.ndarray) -> np.ndarray:
    """The matrix of intrinsic XYZ Euler angles ``e`` (3,): Rx(e0) Ry(e1) Rz(e2), written out (a scipy
    ``Rotation`` per call cost ~100x more inside the fit's hundreds of evaluations)."""
    ca, sa = math.cos(e[0]), math.sin(e[0])
    cb, sb = math.cos(e[1]), math.sin(e[1])
    cc, sc = math.cos(e[2]), math.sin(e[2])
    return np.array([[cb * cc, -cb * sc, sb],
                     [ca * sc + sa * sb * cc, ca * cc - sa * sb * sc, -sa * cb],
                     [sa * sc - ca * sb * cc, sa * cc + ca * sb * sc, ca * cb]])


def hinge_twist_y(rot: Rotation) -> np.ndarray:
    """(T,) rotations -> (T,) angle of their twist about the y axis (swing-twist), in (-pi, pi].

    With q = (x, y, z, w) the twist about y is the normalised (0, y, 0, w); its angle
    is 2 atan2(y, w). For a pure rotation about y this is exactly that rotation's angle.
    """
    q = rot.as_quat()
    angle = 2.0 * np.arctan2(q[:, 1], q[:, 3])
    return np.arctan2(np.sin(angle), np.cos(angle))


def joints_to_qpos(
    root_pos: np.ndarray,
    root_rot: Rotation,
    local: Mapping[str, Rotation],
    clamp_tolerance: float = 1e-6,
    project: bool = True,
) -> tuple[np.ndarray, dict[str, Any]]:
    """Build qpos (T, 35) from a root pose and each joint's local rotation.

    ``root_pos`` (T, 3) in metres, z up; ``root_rot`` (T,) the pelvis orientation in the
    world; ``local`` maps every joint name of ``stairenv.humanoid.JOINTS`` ("abdomen",
    "right_knee", ...) to a (T,) ``Rotation``: the joint's body relative to its parent
    body, where the identity is our zero pose. Returns qpos and a report of the clamping:
    ``clamped_fraction`` (share of the T x 28 angles outside their range by more than
    ``clamp_tolerance`` rad), ``max_clamp_deg`` and ``clamp_deg_by_dof`` (worst excess per
    DoF, in the Euler branch nearest the range). Out-of-range three-axis rotations are
    replaced by a nearby reachable rotation (``ball_joint_angles``) when ``project`` is
    true, else by the per-axis clamped Euler angles; hinge angles are clamped.
    """
    root_pos = np.asarray(root_pos, dtype=np.float64)
    n = root_pos.shape[0]
    ranges = _dof_ranges()
    raw = np.zeros((n, NUM_DOFS))
    projected = np.zeros((n, NUM_DOFS))
    dof = 0
    for joint, _, axes in JOINTS:
        if joint not in local:
            raise KeyError(f"no rotation given for joint {joint!r}")
        rot = local[joint]
        if len(rot) != n:
            raise ValueError(f"joint {joint!r}: {len(rot)} frames, root has {n}")
        low, high = ranges[dof:dof + len(axes), 0], ranges[dof:dof + len(axes), 1]
        if len(axes) == 3:
            projected[:, dof:dof + 3], raw[:, dof:dof + 3] = ball_joint_angles(
                rot, low, high, _BONES[joint], fit=project)
        else:
            raw[:, dof] = _wrap_towards(hinge_twist_y(rot)[:, None], low, high)[:, 0]
        dof += len(axes)
    clipped = np.clip(raw, ranges[:, 0], ranges[:, 1])
    moved = np.abs(clipped - raw)
    clamped = moved > clamp_tolerance
    angles = projected
    angles[:, _HINGE_DOFS] = clipped[:, _HINGE_DOFS]
    report = {
        "clamped_fraction": float(clamped.mean()) if n else 0.0,
        "max_clamp_deg": float(np.degrees(moved.max())) if n else 0.0,
        "clamp_deg_by_dof": {
            DOF_NAMES[i]: round(float(np.degrees(moved[:, i].max())), 3)
            for i in range(NUM_DOFS) if clamped[:, i].any()
        },
    }
    qpos = np.zeros((n, QPOS_SIZE))
    qpos[:, :3] = root_pos
    qpos[:, 3:7] = root_rot.as_quat(scalar_first=True)
    qpos[:, 7:] = angles
    return qpos, report


def fk_position_error(qpos: np.ndarray, reference: np.ndarray) -> dict[str, float]:
    """Distances between our bodies' FK positions and ``reference`` (T, 15, 3), same frames.

    Returns ``mean_m``, ``max_m`` and ``worst_body``: a check that the imported joint angles
    reproduce the source pose (up to differences of bone lengths and clamping).
    """
    err = np.linalg.norm(body_positions(qpos) - reference, axis=-1)
    return {
        "mean_m": round(float(err.mean()), 6),
        "max_m": round(float(err.max()), 6),
        "worst_body": BODY_NAMES[int(np.argmax(err.max(axis=0)))],
    }


def ground_offset(qpos: np.ndarray, ground: str = "body") -> float:
    """Vertical shift that puts the clip on the floor: add it to ``qpos[:, 2]``.

    ``ground="feet"``: the lowest foot-sole point over the whole clip ends at z = 0.
    ``"body"`` (the importers' default): the lowest point of any geom over the clip ends at
    z = 0; for motion on the feet (walking, running, climbing stairs from the floor) this is
    the lowest sole, the same as "feet", and for crawling, rolling or getting up it keeps
    hands, knees and back out of the floor. ``"none"``: 0 (keep the source's heights).
    """
    if ground == "none":
        return 0.0
    if ground == "feet":
        return float(-foot_sole_heights(qpos).min())
    if ground == "body":
        return float(-lowest_body_point(qpos).min())
    raise ValueError(f"ground must be 'feet', 'body' or 'none', got {ground!r}")


def snap_fps(fps: float, rel_tol: float = 5e-4) -> float:
    """Round a frame rate to the nearest integer when within ``rel_tol``.

    Files store frame times with few digits (DeepMimic 0.033332 s, BVH ``.0083333`` s),
    which would otherwise give 30.001 or 120.0005 fps.
    """
    nearest = float(round(fps))
    return nearest if nearest > 0 and abs(fps - nearest) <= rel_tol * fps else fps


def make_clip(
    times: np.ndarray,
    root_pos: np.ndarray,
    root_rot: Rotation,
    local: Mapping[str, Rotation],
    fps: float,
    *,
    name: str,
    loop: bool,
    source: str,
    meta: dict[str, Any],
    ground: str = "body",
    projected: tuple[np.ndarray, dict[str, Any]] | None = None,
) -> MotionClip:
    """A clip at ``fps`` from a pose sequence given at ``times`` (s, increasing, maybe irregular).

    If ``times`` are not already the grid k / fps, the pose is resampled *as rotations*:
    linear interpolation of the root position, slerp of the root and of every joint's
    local rotation (``slerp``: scipy ``Slerp``'s steps), and only then the projection onto our joint angles
    and ranges (``joints_to_qpos``), so Euler angles are never interpolated and resampled
    frames are in range too. Then the clip is put on the floor (``finish_clip``; measured
    on the output frames) and ``meta`` gains the clamping report of the output frames.
    A clip beyond the limits (``check_timing`` at ``fps``; root positions within
    ``MAX_ROOT_DISTANCE_M``) raises ``MotionFileError`` naming ``source`` before any work.
    ``projected``: ``joints_to_qpos`` of the given frames, if already computed (used when
    no resampling is needed).
    """
    times = np.asarray(times, dtype=np.float64)
    if times.ndim != 1 or len(times) != len(root_pos) or np.any(np.diff(times) <= 0):
        raise ValueError("times must be increasing, one per frame")
    check_timing(source, len(times), fps, float(times[-1] - times[0]))
    check_values(source, "root position (m)", root_pos, MAX_ROOT_DISTANCE_M)
    n_out = int(math.floor((times[-1] - times[0]) * fps + 1e-6)) + 1
    grid = times[0] + np.arange(n_out) / fps
    resample = len(times) != n_out or not np.allclose(times, grid, atol=1e-6 / fps)
    if resample:
        if len(times) < 2:
            raise ValueError("cannot resample a single frame")
        root_pos = np.stack([np.interp(grid, times, root_pos[:, k]) for k in range(3)], axis=1)
        root_rot = slerp(times, root_rot, grid)
        local = {joint: slerp(times, rot, grid) for joint, rot in local.items()}
        meta = {**meta, "resampled": True}
    if projected is not None and not resample:
        qpos, report = projected[0], dict(projected[1])
    else:
        qpos, report = joints_to_qpos(root_pos, root_rot, local)
    if len(qpos) > 1:
        # Largest change of one joint angle between frames: large values flag branch
        # changes where the source leaves a joint's reach (cartwheels, crawling).
        report["max_joint_step_deg"] = round(float(np.degrees(np.abs(np.diff(qpos[:, 7:], axis=0)).max())), 3)
    return finish_clip(qpos, fps, name, loop, source, {**meta, **report}, ground=ground)


def finish_clip(
    qpos: np.ndarray,
    fps: float,
    name: str,
    loop: bool,
    source: str,
    meta: dict[str, Any],
    ground: str = "body",
) -> MotionClip:
    """Shift qpos onto the floor (``ground_offset``), record the shift, and build the clip.

    ``meta`` gains ``ground``, ``root_height_offset`` (m, added to the root height) and
    ``lowest_sole_height`` (m, the lowest foot-sole point over the clip after the shift).
    """
    if ground not in ("feet", "body", "none"):
        raise ValueError(f"ground must be 'feet', 'body' or 'none', got {ground!r}")
    offset = ground_offset(qpos, ground)
    qpos = qpos.copy()
    qpos[:, 2] += offset
    # Normalise the root quaternions to a floating-point fixed point of q / |q|, so that
    # MotionClip's own normalisation (on creation and on load) leaves them bit-identical
    # and a saved clip loads back exactly.
    quat = qpos[:, 3:7]
    for _ in range(8):
        normed = quat / np.linalg.norm(quat, axis=1, keepdims=True)
        if np.array_equal(normed, quat):
            break
        quat = normed
    qpos[:, 3:7] = quat
    meta = {
        **meta,
        "ground": ground,
        "root_height_offset": round(offset, 6),
        "lowest_sole_height": round(float(foot_sole_heights(qpos).min()), 6),
    }
    return MotionClip(qpos, fps, name=name, loop=loop, source=source, meta=meta)
