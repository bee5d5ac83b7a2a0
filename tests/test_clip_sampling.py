"""``MotionClip.sample`` (vectorised numpy) against the straightforward scipy implementation it replaced.

``scipy_sample`` is that implementation, kept verbatim as the reference (hence its likeness to
``MotionClip.sample``'s first lines).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from stairenv.humanoid import DOF_NAMES, JOINTS, STANDING_ROOT_HEIGHT
from stairenv.motion import MotionClip
from stairenv.motion.clip import euler_near
from stairenv.motion.rsi import load_reference_library
from stairenv.motion.synthesis import climb_stairs

BALL_COLUMNS = []
_col = 7
for _, _, _axes in JOINTS:
    if len(_axes) == 3:
        BALL_COLUMNS.append(slice(_col, _col + 3))
    _col += len(_axes)


def scipy_sample(clip: MotionClip, times) -> np.ndarray:
    """The previous ``MotionClip.sample``: scipy Rotation objects per joint (the reference)."""
    times = np.atleast_1d(np.asarray(times, dtype=np.float64))
    if clip.num_frames == 1:
        return np.repeat(clip.qpos, len(times), axis=0)
    times = np.mod(times, clip.duration) if clip.loop else np.clip(times, 0.0, clip.duration)
    frame = times * clip.fps
    i0 = np.minimum(np.floor(frame).astype(int), clip.num_frames - 2)
    alpha = (frame - i0)[:, None]
    a, b = clip.qpos[i0], clip.qpos[i0 + 1]
    out = (1.0 - alpha) * a + alpha * b
    out[:, 3:7] = _slerp_wxyz(a[:, 3:7], b[:, 3:7], alpha[:, 0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # scipy's gimbal-lock warning
        for cols in BALL_COLUMNS:
            ra = Rotation.from_euler("XYZ", a[:, cols])
            rb = Rotation.from_euler("XYZ", b[:, cols])
            out[:, cols] = _scipy_euler_near(_slerp_rot(ra, rb, alpha[:, 0]), out[:, cols])
    return out


def _scipy_euler_near(rot: Rotation, reference: np.ndarray) -> np.ndarray:
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
    delta = (ra.inv() * rb).as_rotvec()
    return ra * Rotation.from_rotvec(delta * alpha[:, None])


def _slerp_wxyz(qa: np.ndarray, qb: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    ra = Rotation.from_quat(qa, scalar_first=True)
    rb = Rotation.from_quat(qb, scalar_first=True)
    out = _slerp_rot(ra, rb, alpha).as_quat(scalar_first=True)
    out *= np.where(np.sum(out * qa, axis=1) < 0, -1.0, 1.0)[:, None]
    return out


def gimbal_clip() -> MotionClip:
    """Pitch (Y) at, near and through +-90 deg on joints whose range reaches it, root turning over.

    Even frames sit at gimbal lock (scipy then zeroes X) or 1e-9 .. 1e-3 rad from it, odd frames
    0.02 .. 0.3 rad from it on either side. Within ~1e-7 .. 1e-6 rad of the lock (but not in it)
    X and Z alone are ill-conditioned (rounding / distance: scipy's own error against extended
    precision reaches 2e-9 there), so no two frames both lie in that band: a random time lands in it
    with a probability of ~1e-5.
    """
    rng = np.random.default_rng(7)
    n = 40
    q = np.zeros((n, 35))
    q[:, 2] = STANDING_ROOT_HEIGHT
    q[:, 3:7] = Rotation.from_euler("xyz", rng.uniform(-3, 3, (n, 3))).as_quat(scalar_first=True)
    near = np.array([0.0, 0.0, 1e-9, -1e-6, 1e-5, -1e-4, 1e-3])
    far = np.array([-0.3, -0.05, -0.02, 0.02, 0.05, 0.3])
    for name, pitch in (("right_hip", -np.pi / 2), ("left_hip", -np.pi / 2), ("abdomen", np.pi / 2),
                        ("right_shoulder", -np.pi / 2), ("left_shoulder", -np.pi / 2)):
        col = 7 + DOF_NAMES.index(f"{name}_x")
        q[:, col] = rng.uniform(-0.7, 0.7, n)
        q[0::2, col + 1] = pitch + rng.choice(near, n // 2)
        q[1::2, col + 1] = pitch + rng.choice(far, n // 2)
        q[:, col + 2] = rng.uniform(-0.6, 0.6, n)
    return MotionClip(q, 30.0, "gimbal")


def all_clips() -> list[MotionClip]:
    return [*load_reference_library().clips, climb_stairs(0.15, 0.3, 5), gimbal_clip()]


@pytest.fixture(scope="module")
def clips() -> list[MotionClip]:
    return all_clips()


def test_sample_matches_scipy_reference(clips):
    rng = np.random.default_rng(0)
    worst = 0.0
    for clip in clips:
        frames = np.arange(clip.num_frames) / clip.fps
        batched = np.concatenate((
            [0.0, clip.duration, -0.3, clip.duration + 0.7],  # ends, clamped or wrapped
            frames,  # on the frames exactly
            rng.uniform(-0.1 * clip.duration, 1.1 * clip.duration, 500),
        ))
        expected = scipy_sample(clip, batched)
        got = clip.sample(batched)
        assert got.shape == expected.shape
        worst = max(worst, float(np.max(np.abs(got - expected))))
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-9, err_msg=clip.name)
        for t in batched[::25]:  # single times, scalar and (1,)
            np.testing.assert_allclose(clip.sample(t), scipy_sample(clip, t), rtol=0, atol=1e-9)
            np.testing.assert_allclose(clip.sample([t]), scipy_sample(clip, [t]), rtol=0, atol=1e-9)
    assert worst < 1e-9


def test_resample_matches_scipy_reference(clips):
    for clip in clips[:3] + clips[-2:]:
        for fps in (17.0, 120.0):
            resampled = clip.resample(fps)
            expected = MotionClip(scipy_sample(clip, np.arange(resampled.num_frames) / fps), fps).qpos
            np.testing.assert_allclose(resampled.qpos, expected, rtol=0, atol=1e-9)


def test_one_frame_clip_and_empty_times(clips):
    single = MotionClip(clips[0].qpos[:1], 30.0)
    np.testing.assert_array_equal(single.sample([0.0, 5.0]), np.repeat(single.qpos, 2, axis=0))
    assert clips[0].sample(np.zeros(0)).shape == (0, 35)


def test_euler_near_keeps_its_scipy_contract():
    rng = np.random.default_rng(3)
    angles = rng.uniform(-3, 3, (200, 3))
    reference = angles + rng.normal(0, 0.3, angles.shape)
    rot = Rotation.from_euler("XYZ", angles)
    np.testing.assert_allclose(euler_near(rot, reference), _scipy_euler_near(rot, reference), rtol=0, atol=1e-12)
