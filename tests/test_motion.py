"""Our clip format, the motion library and reference-state initialisation."""

from __future__ import annotations

import math

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import stairenv  # noqa: F401
from stairenv.humanoid import DOF_NAMES, STANDING_ROOT_HEIGHT
from stairenv.motion import MotionClip, MotionFileError, MotionLibrary
from stairenv.humanoid.kinematics import humanoid_geoms, humanoid_lowest_z
from stairenv.humanoid.placement import PLACEMENT_CLEARANCE


def turning_clip(n: int = 31, fps: float = 30.0) -> MotionClip:
    """Root walks forward while turning 90 degrees; the right hip and knee move."""
    t = np.arange(n) / fps
    q = np.zeros((n, 35))
    q[:, 0] = 0.8 * t
    q[:, 2] = STANDING_ROOT_HEIGHT
    q[:, 3:7] = Rotation.from_euler("z", np.linspace(0, math.pi / 2, n)[:, None]).as_quat(scalar_first=True)
    q[:, 7 + DOF_NAMES.index("right_hip_y")] = -0.5 * np.sin(2 * t)
    q[:, 7 + DOF_NAMES.index("right_knee")] = 0.6 * t
    return MotionClip(q, fps, "turn")


def test_save_load_round_trip(tmp_path):
    clip = turning_clip()
    clip.meta["source_file"] = "made in a test"
    loaded = MotionClip.load(clip.save(tmp_path / "turn.npz"))
    np.testing.assert_array_equal(loaded.qpos, clip.qpos)
    assert (loaded.fps, loaded.name, loaded.loop, loaded.meta) == (30.0, "turn", False, {"source_file": "made in a test"})


@pytest.mark.parametrize(
    "content, message",
    [
        (b"not a zip at all", "cannot read"),
        (None, "missing"),
    ],
)
def test_corrupt_files_raise_motion_file_error(tmp_path, content, message):
    path = tmp_path / "bad.npz"
    if content is None:
        np.savez(path, something=np.zeros(3))
    else:
        path.write_bytes(content)
    with pytest.raises(MotionFileError, match=message):
        MotionClip.load(path)


def test_bad_arrays_are_rejected(tmp_path):
    q = turning_clip().qpos
    with pytest.raises(MotionFileError, match="shape"):
        MotionClip(q[:, :30], 30.0)
    bad = q.copy()
    bad[3, 10] = np.nan
    with pytest.raises(MotionFileError, match="NaN"):
        MotionClip(bad, 30.0)
    with pytest.raises(MotionFileError, match="fps"):
        MotionClip(q, 0.0)
    # A truncated file on disk.
    path = turning_clip().save(tmp_path / "ok.npz")
    path.write_bytes(path.read_bytes()[:200])
    with pytest.raises(MotionFileError):
        MotionClip.load(path)


def test_velocities_match_mujoco_differences():
    clip = turning_clip()
    qvel = clip.qvel()
    # Central difference for the root: forward speed 0.8 m/s, yaw rate (pi/2)/1 s about the body z axis.
    np.testing.assert_allclose(qvel[10, 0:3], [0.8, 0.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(qvel[10, 3:6], [0.0, 0.0, math.pi / 2], rtol=1e-3)
    knee = 6 + DOF_NAMES.index("right_knee")
    np.testing.assert_allclose(qvel[1:-1, knee], 0.6, rtol=1e-9)


def test_sample_slerps_the_root_and_interpolates_joints():
    clip = turning_clip()
    mid = clip.sample([0.5 / 30])[0]  # halfway between frames 0 and 1
    yaw = Rotation.from_quat(mid[3:7], scalar_first=True).as_euler("xyz")[2]
    assert yaw == pytest.approx(0.5 * (math.pi / 2) / 30, rel=1e-9)
    np.testing.assert_allclose(mid[0], 0.5 * (clip.qpos[0, 0] + clip.qpos[1, 0]))
    # Clamped outside the clip (not looping).
    np.testing.assert_allclose(clip.sample([-1.0, 99.0]), clip.qpos[[0, -1]])
    # Resampling keeps the frames it lands on.
    double = clip.resample(60)
    np.testing.assert_allclose(double.qpos[::2], clip.qpos, atol=1e-9)


def test_library_sampling_follows_weights():
    a, b = turning_clip(), turning_clip()
    b.name = "b"
    lib = MotionLibrary([a, b], weights=[3, 1])
    ids, times = lib.sample(4000, np.random.default_rng(0))
    assert np.mean(ids == 0) == pytest.approx(0.75, abs=0.03)
    assert times.min() >= 0 and times.max() <= a.duration
    qpos, qvel = lib.states(ids[:5], times[:5])
    assert qpos.shape == (5, 35) and qvel.shape == (5, 34)
    with pytest.raises(ValueError, match="weights"):
        MotionLibrary([a, b], weights=[1, -1])
    with pytest.raises(ValueError, match="at least one"):
        MotionLibrary([])


def test_lowest_point_is_each_geoms_bottom_computed_by_hand():
    """``humanoid_lowest_z`` (shapes at once) against each geom's lowest point worked out alone: a
    sphere's centre minus its radius, a capsule's end cap, a box's lowest corner (the corners listed)."""
    env = gym.make("InterLevel-v0")
    u = env.unwrapped
    geoms = humanoid_geoms(u.model, u._idx)
    kinds = set(u.model.geom_type[geoms].tolist())
    assert {int(mujoco.mjtGeom.mjGEOM_SPHERE), int(mujoco.mjtGeom.mjGEOM_CAPSULE), int(mujoco.mjtGeom.mjGEOM_BOX)} <= kinds
    rng = np.random.default_rng(0)
    env.reset(seed=1)
    for _ in range(15):
        env.step(rng.uniform(-1, 1, 28))
    model, data = u.model, u.data
    lowest = []
    for g in geoms:
        z, size, rot = data.geom_xpos[g, 2], model.geom_size[g], data.geom_xmat[g].reshape(3, 3)
        if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE:
            lowest.append(z - size[0])
        elif model.geom_type[g] == mujoco.mjtGeom.mjGEOM_CAPSULE:
            ends = [data.geom_xpos[g] + sign * size[1] * rot[:, 2] for sign in (-1, 1)]
            lowest.append(min(end[2] for end in ends) - size[0])
        else:
            corners = [data.geom_xpos[g] + rot @ (np.array(signs) * size)
                       for signs in np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).T.reshape(-1, 3)]
            lowest.append(min(corner[2] for corner in corners))
    assert humanoid_lowest_z(model, data, geoms) == pytest.approx(min(lowest), abs=1e-12)
    for g, expected in zip(geoms, lowest):
        assert humanoid_lowest_z(model, data, np.array([g])) == pytest.approx(expected, abs=1e-12)


def test_reference_init_places_the_character_on_the_floor():
    env = gym.make("InterLevel-v0", init="reference")
    u = env.unwrapped
    geoms = humanoid_geoms(u.model, u._idx)
    for seed in range(6):
        obs, info = env.reset(seed=seed)
        assert info["reference_start"]
        mujoco.mj_forward(u.model, u.data)
        assert humanoid_lowest_z(u.model, u.data, geoms) == pytest.approx(PLACEMENT_CLEARANCE, abs=1e-9)
        assert u.data.ncon == 0  # nothing penetrates: not even touching
        assert np.isfinite(obs).all()
        # The reference velocities come along (a walking or climbing frame is moving).
        assert np.linalg.norm(u.data.qvel[:3]) > 0.05


def test_starts_are_drawn_from_level_ground_clips_only():
    """A stair climb's frame placed on flat ground would start with a foot on no step."""
    from stairenv.motion.rsi import level_clips, load_reference_library

    library = load_reference_library()
    level = level_clips(library)
    assert 0 < len(level.clips) < len(library.clips)
    assert all(np.ptp(c.qpos[:, 2]) < 0.1 for c in level.clips)
    assert {c.name for c in library.clips} - {c.name for c in level.clips} == {
        c.name for c in library.clips if c.meta.get("generator") == "climb_stairs"}
    np.testing.assert_allclose(level.probabilities.sum(), 1.0)
    env = gym.make("InterLevel-v0", init="reference").unwrapped
    assert [c.name for c in env._library.clips] == [c.name for c in level.clips]
    climbs = MotionLibrary([c for c in library.clips if c.meta.get("generator") == "climb_stairs"])
    with pytest.raises(ValueError, match="level ground"):
        level_clips(climbs)


def test_hybrid_init_fraction():
    env = gym.make("InterLevel-v0", init="hybrid", hybrid_fraction=0.25)
    starts = [env.reset(seed=i)[1]["reference_start"] for i in range(200)]
    assert np.mean(starts) == pytest.approx(0.25, abs=0.08)
    with pytest.raises(ValueError, match="init"):
        gym.make("InterLevel-v0", init="teleport")
    with pytest.raises(ValueError, match="hybrid_fraction"):
        gym.make("InterLevel-v0", init="hybrid", hybrid_fraction=1.5)


def test_reference_init_from_a_folder(tmp_path):
    turning_clip().save(tmp_path / "turn.npz")
    env = gym.make("InterLevel-v0", init="reference", reference_motion=str(tmp_path))
    env.reset(seed=0)
    assert env.unwrapped._library.names == ["turn"]


def test_sampling_keeps_hip_flexion_beyond_90_degrees():
    """Interpolating a hip flexed past 90 deg must stay on the right Euler branch (no jump)."""
    q = np.zeros((2, 35))
    q[:, 2], q[:, 3] = STANDING_ROOT_HEIGHT, 1.0
    hip = 7 + DOF_NAMES.index("right_hip_x")
    q[0, hip:hip + 3] = [0.1, -2.0, 0.2]   # 115 deg of flexion
    q[1, hip:hip + 3] = [0.2, -2.2, 0.1]
    mid = MotionClip(q, 30.0).sample([0.5 / 30])[0, hip:hip + 3]
    np.testing.assert_allclose(mid, [0.15, -2.1, 0.15], atol=0.02)
