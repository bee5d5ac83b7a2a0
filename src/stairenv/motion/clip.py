"""One clip format of our own: frames of the humanoid's ``qpos`` at a known fps.

A clip is ``qpos`` (T, 35): root position (3, world, z up), root quaternion
(4, MuJoCo's w x y z), then the 28 hinge angles in ``DOF_NAMES`` order, sampled
at ``fps``. A looping clip (``loop=True``) ends on the pose it starts with (the
root may have moved on): its period is ``duration = (T - 1) / fps``. Velocities are derived, never stored, with MuJoCo's own
``mj_differentiatePos`` (central differences; the root's angular velocity in
the root frame, as the free joint's qvel), so a clip's states are exactly what
the env would read from ``MjData``.

Files are ``.npz`` with the arrays ``qpos``, ``fps`` and a JSON ``meta`` string
(name, loop, source, format version, anything an importer adds). ``load``
checks everything and raises ``MotionFileError`` naming the file and the fault.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation

from stairenv.humanoid import JOINTS, NUM_DOFS, humanoid_model  # humanoid_model: re-exported here

FORMAT_VERSION = 1
QPOS_SIZE = 7 + NUM_DOFS  # 35
QVEL_SIZE = 6 + NUM_DOFS  # 34

# Column ranges of the 3-axis joints (intrinsic XYZ Euler angles) and of the hinges in qpos.
_BALL_COLUMNS: list[slice] = []
_HINGE_COLUMNS: list[int] = []
_col = 7
for _, _, _axes in JOINTS:
    if len(_axes) == 3:
        _BALL_COLUMNS.append(slice(_col, _col + 3))
    else:
        _HINGE_COLUMNS.append(_col)
    _col += len(_axes)
# (J, 3) qpos columns of the 3-axis joints, for gathering all of them in one index.
_BALL_INDEX = np.array([[cols.start, cols.start + 1, cols.start + 2] for cols in _BALL_COLUMNS])


class MotionFileError(ValueError):
    """A motion file that cannot be read as a clip (corrupt, wrong shape, NaN, ...)."""


@dataclass
class MotionClip:
    qpos: np.ndarray
    fps: float
    name: str = ""
    loop: bool = False
    source: str = ""
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.qpos = np.asarray(self.qpos, dtype=np.float64)
        self.fps = float(self.fps)
        problem = _check_qpos(self.qpos, self.fps)
        if problem:
            raise MotionFileError(f"clip {self.name or '<unnamed>'}: {problem}")
        # One sign per quaternion hemisphere, continuous in time (q and -q are the same rotation).
        quat = self.qpos[:, 3:7]
        norms = np.linalg.norm(quat, axis=1)
        off = np.abs(norms - 1.0) > 1e-12  # unit already: left alone, so that save + load is exact
        quat[off] /= norms[off, None]
        flips = np.cumprod(np.where(np.sum(quat[1:] * quat[:-1], axis=1) < 0, -1.0, 1.0))
        quat[1:] *= flips[:, None]

    # --- basic properties ----------------------------------------------------------
    @property
    def num_frames(self) -> int:
        return self.qpos.shape[0]

    @property
    def dt(self) -> float:
        return 1.0 / self.fps

    @property
    def duration(self) -> float:
        """Time of the last frame (a one-frame clip lasts 0 s)."""
        return (self.num_frames - 1) / self.fps

    def qvel(self) -> np.ndarray:
        """(T, 34) velocities from central differences of qpos (one-sided at the ends).

        A looping clip's last frame repeats its first pose (the root may have moved on), so
        at the seam the velocity is the mean of the differences just before and after it.
        """
        model = humanoid_model()
        n = self.num_frames
        qvel = np.zeros((n, QVEL_SIZE))
        if n < 2:
            return qvel
        for t in range(n):
            before, after = max(t - 1, 0), min(t + 1, n - 1)
            mujoco.mj_differentiatePos(model, qvel[t], (after - before) * self.dt, self.qpos[before], self.qpos[after])
        if self.loop and n > 2:
            into_seam = np.zeros(QVEL_SIZE)
            mujoco.mj_differentiatePos(model, into_seam, self.dt, self.qpos[n - 2], self.qpos[n - 1])
            out_of_seam = np.zeros(QVEL_SIZE)
            mujoco.mj_differentiatePos(model, out_of_seam, self.dt, self.qpos[0], self.qpos[1])
            qvel[0] = qvel[n - 1] = 0.5 * (into_seam + out_of_seam)
        return qvel

    # --- interpolation -------------------------------------------------------------
    def sample(self, times: np.ndarray) -> np.ndarray:
        """qpos (N, 35) at ``times`` (s): slerp for the root and 3-axis joint rotations, linear otherwise.

        Times are clamped to [0, duration], or wrapped for looping clips.
        """
        times = np.atleast_1d(np.asarray(times, dtype=np.float64))
        if self.num_frames == 1:
            return np.repeat(self.qpos, len(times), axis=0)
        times = np.mod(times, self.duration) if self.loop else np.clip(times, 0.0, self.duration)
        frame = times * self.fps
        i0 = np.minimum(np.floor(frame).astype(int), self.num_frames - 2)
        return blend_poses(self.qpos[i0], self.qpos[i0 + 1], frame - i0)

    def resample(self, fps: float) -> "MotionClip":
        """The same motion at another frame rate."""
        if not (fps > 0 and math.isfinite(fps)):
            raise ValueError(f"fps must be a positive number, got {fps!r}")
        n = max(int(round(self.duration * fps)) + 1, 1)
        times = np.arange(n) / fps
        return MotionClip(self.sample(times), fps, self.name, self.loop, self.source, dict(self.meta))

    # --- files -----------------------------------------------------------------------
    def save(self, path: str | Path) -> Path:
        path = Path(path)
        if path.suffix != ".npz":
            path = path.with_suffix(".npz")
        path.parent.mkdir(parents=True, exist_ok=True)
        meta = {"name": self.name, "loop": self.loop, "source": self.source,
                "format_version": FORMAT_VERSION, **self.meta}
        np.savez_compressed(path, qpos=self.qpos, fps=np.float64(self.fps), meta=np.array(json.dumps(meta)))
        return path

    @classmethod
    def load(cls, path: str | Path) -> "MotionClip":
        path = Path(path)
        try:
            with np.load(path, allow_pickle=False) as f:
                missing = {"qpos", "fps", "meta"} - set(f.files)
                if missing:
                    raise MotionFileError(f"{path}: not a stairenv clip (missing {sorted(missing)})")
                qpos, fps, meta_text = f["qpos"], float(f["fps"]), str(f["meta"])
        except MotionFileError:
            raise
        except Exception as err:  # zip/npy corruption surfaces as many types
            raise MotionFileError(f"{path}: cannot read ({type(err).__name__}: {err})") from err
        try:
            meta = json.loads(meta_text)
        except json.JSONDecodeError as err:
            raise MotionFileError(f"{path}: metadata is not JSON ({err})") from err
        if meta.get("format_version", 0) > FORMAT_VERSION:
            raise MotionFileError(f"{path}: format version {meta['format_version']} is newer than {FORMAT_VERSION}")
        problem = _check_qpos(np.asarray(qpos), fps)
        if problem:
            raise MotionFileError(f"{path}: {problem}")
        name = meta.pop("name", path.stem)
        loop = bool(meta.pop("loop", False))
        source = meta.pop("source", "")
        meta.pop("format_version", None)
        return cls(qpos, fps, name, loop, source, meta)



def blend_poses(a: np.ndarray, b: np.ndarray, alpha: np.ndarray | float) -> np.ndarray:
    """Poses (N, 35) between ``a`` and ``b`` (N, 35) at ``alpha`` (0: ``a``, 1: ``b``; (N,) or a scalar):
    slerp for the root and every 3-axis joint rotation (its Euler angles kept near the linear blend's),
    linear for positions and hinges."""
    a, b = np.atleast_2d(a), np.atleast_2d(b)
    alpha = np.broadcast_to(np.asarray(alpha, dtype=np.float64), (len(a),))[:, None]
    ends = np.stack((a, b))  # (2, N, 35): the poses before and after
    out = (1.0 - alpha) * ends[0] + alpha * ends[1]
    # The root and every 3-axis joint at once, as (2, N, 1 + J) quaternion components.
    x, y, z, w = _root_and_ball_quats(ends)
    rx, ry, rz, rw = _slerp_xyzw(x, y, z, w, alpha)
    root = np.stack((rw[:, 0], rx[:, 0], ry[:, 0], rz[:, 0]), axis=1)
    # Keep the hemisphere of the first pose so sequences stay continuous.
    root *= np.where(np.sum(root * ends[0, :, 3:7], axis=1) < 0, -1.0, 1.0)[:, None]
    out[:, 3:7] = root
    first = _quat_to_euler_xyz(rx[:, 1:], ry[:, 1:], rz[:, 1:], rw[:, 1:])
    out[:, _BALL_INDEX] = _euler_near_angles(first, out[:, _BALL_INDEX])
    return out

def _check_qpos(qpos: np.ndarray, fps: float) -> str | None:
    if qpos.ndim != 2 or qpos.shape[1] != QPOS_SIZE or qpos.shape[0] < 1:
        return f"qpos must have shape (T >= 1, {QPOS_SIZE}), got {qpos.shape}"
    if not np.isfinite(qpos).all():
        return "qpos contains NaN or inf"
    if not (math.isfinite(fps) and fps > 0):
        return f"fps must be a positive number, got {fps!r}"
    norms = np.linalg.norm(qpos[:, 3:7], axis=1)
    if np.any(norms < 1e-6):
        return "root quaternion of zero length"
    return None


def euler_near(rot: Rotation, reference: np.ndarray) -> np.ndarray:
    """Intrinsic XYZ angles of ``rot`` (N,) nearest to ``reference`` (N, 3).

    Every rotation has two XYZ solutions, (x, y, z) and (x + pi, pi - y, z + pi), each
    defined up to 2 pi per angle; hip and shoulder flexion beyond 90 degrees needs the
    second. Both are wrapped towards ``reference`` and the closer one is kept.
    """
    return _euler_near_angles(rot.as_euler("XYZ"), np.asarray(reference, dtype=np.float64))


def _euler_near_angles(first: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """``euler_near`` for angles (..., 3) already in scipy's XYZ solution ``first``."""
    second = first + np.array([np.pi, 0.0, np.pi])
    second[..., 1] = np.pi - first[..., 1]
    cands = np.stack((first, second))
    cands += 2.0 * np.pi * np.round((reference - cands) / (2.0 * np.pi))
    dist = np.sum((cands - reference) ** 2, axis=-1)
    return np.where((dist[0] <= dist[1])[..., None], cands[0], cands[1])


# Quaternions below are scipy's (x, y, z, w), one array per component, so that a handful of
# numpy calls covers the root and all 3-axis joints of every sample; the formulas are scipy's
# (from_euler, slerp through as_rotvec/from_rotvec, as_euler), equal to it within rounding.
def _root_and_ball_quats(ends: np.ndarray) -> tuple[np.ndarray, ...]:
    """(x, y, z, w), each (..., 1 + J): the root quaternion then the XYZ Euler joints of qpos rows."""
    half = 0.5 * ends[..., _BALL_INDEX]
    s, c = np.sin(half), np.cos(half)
    sx, sy, sz = s[..., 0], s[..., 1], s[..., 2]
    cx, cy, cz = c[..., 0], c[..., 1], c[..., 2]
    root = ends[..., 3:7] / np.linalg.norm(ends[..., 3:7], axis=-1, keepdims=True)  # wxyz
    cycz, sysz, cysz, sycz = cy * cz, sy * sz, cy * sz, sy * cz
    return (np.concatenate((root[..., 1:2], sx * cycz + cx * sysz), axis=-1),
            np.concatenate((root[..., 2:3], cx * sycz - sx * cysz), axis=-1),
            np.concatenate((root[..., 3:4], cx * cysz + sx * sycz), axis=-1),
            np.concatenate((root[..., 0:1], cx * cycz - sx * sysz), axis=-1))


def _slerp_xyzw(x: np.ndarray, y: np.ndarray, z: np.ndarray, w: np.ndarray,
                alpha: np.ndarray) -> tuple[np.ndarray, ...]:
    """a * (a^-1 * b)^alpha for the pairs (x[0], ...) -> (x[1], ...); ``alpha`` (N, 1)."""
    ax, ay, az, aw = x[0], y[0], z[0], w[0]
    bx, by, bz, bw = x[1], y[1], z[1], w[1]
    dx = aw * bx - bw * ax - (ay * bz - az * by)
    dy = aw * by - bw * ay - (az * bx - ax * bz)
    dz = aw * bz - bw * az - (ax * by - ay * bx)
    dw = aw * bw + ax * bx + ay * by + az * bz
    sign = np.where(dw < 0, -1.0, 1.0)  # the shorter way round, as as_rotvec's canonical form
    norm = np.sqrt(dx * dx + dy * dy + dz * dz)
    half = alpha * np.arctan2(norm, sign * dw)
    scale = sign * np.sin(half) / np.where(norm > 0, norm, 1.0)
    ex, ey, ez, ew = dx * scale, dy * scale, dz * scale, np.cos(half)
    return (aw * ex + ew * ax + (ay * ez - az * ey),
            aw * ey + ew * ay + (az * ex - ax * ez),
            aw * ez + ew * az + (ax * ey - ay * ex),
            aw * ew - ax * ex - ay * ey - az * ez)


def _quat_to_euler_xyz(x: np.ndarray, y: np.ndarray, z: np.ndarray, w: np.ndarray) -> np.ndarray:
    """(..., 3) intrinsic XYZ angles as ``Rotation.as_euler("XYZ")`` (third angle 0 at gimbal lock)."""
    a, b, c, d = w - y, z - x, y + w, -x - z
    half_sum, half_diff = np.arctan2(b, a), np.arctan2(d, c)
    middle = 2.0 * np.arctan2(np.hypot(c, d), np.hypot(a, b))
    at_zero, at_pi = np.abs(middle) <= 1e-7, np.abs(middle - np.pi) <= 1e-7
    regular = ~(at_zero | at_pi)
    angles = np.stack((
        -np.where(regular, half_sum + half_diff, np.where(at_zero, 2.0 * half_sum, 2.0 * half_diff)),
        middle - 0.5 * np.pi,
        np.where(regular, half_sum - half_diff, 0.0),
    ), axis=-1)
    return (angles + np.pi) % (2.0 * np.pi) - np.pi
