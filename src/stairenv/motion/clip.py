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
        alpha = (frame - i0)[:, None]
        a, b = self.qpos[i0], self.qpos[i0 + 1]
        out = (1.0 - alpha) * a + alpha * b
        out[:, 3:7] = _slerp_wxyz(a[:, 3:7], b[:, 3:7], alpha[:, 0])
        for cols in _BALL_COLUMNS:
            ra = Rotation.from_euler("XYZ", a[:, cols])
            rb = Rotation.from_euler("XYZ", b[:, cols])
            out[:, cols] = euler_near(_slerp_rot(ra, rb, alpha[:, 0]), out[:, cols])
        return out

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
    first = rot.as_euler("XYZ")
    second = first + np.array([np.pi, 0.0, np.pi])
    second[:, 1] = np.pi - first[:, 1]
    best = []
    for cand in (first, second):
        cand = cand + 2.0 * np.pi * np.round((reference - cand) / (2.0 * np.pi))
        best.append(cand)
    closer = np.sum((best[0] - reference) ** 2, axis=1) <= np.sum((best[1] - reference) ** 2, axis=1)
    return np.where(closer[:, None], best[0], best[1])


def _slerp_rot(ra: Rotation, rb: Rotation, alpha: np.ndarray) -> Rotation:
    """Element-wise slerp between two stacks of rotations."""
    delta = (ra.inv() * rb).as_rotvec()
    return ra * Rotation.from_rotvec(delta * alpha[:, None])


def _slerp_wxyz(qa: np.ndarray, qb: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    ra = Rotation.from_quat(qa, scalar_first=True)
    rb = Rotation.from_quat(qb, scalar_first=True)
    out = _slerp_rot(ra, rb, alpha).as_quat(scalar_first=True)
    # Keep the hemisphere of the first frame so sequences stay continuous.
    out *= np.where(np.sum(out * qa, axis=1) < 0, -1.0, 1.0)[:, None]
    return out


