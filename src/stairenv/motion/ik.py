"""The humanoid's legs for synthesised clips: leg and foot dimensions, sides, and the analytic
two-link leg IK shared by :mod:`stairenv.motion.synthesis` (walks, stairs) and
:mod:`stairenv.motion.interactions` (sit, lie, reach, ...).

Joint conventions are synthesis' (its module docstring): 3-axis joints are intrinsic XYZ
Euler angles; hip y < 0 swings the thigh forward, knee > 0 bends the shin backwards, ankle
y > 0 points the toes down.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.spatial.transform import Rotation

from stairenv.humanoid import DOF_NAMES, humanoid_model

__all__ = ["LEFT", "LEG_EXTENSION", "RIGHT", "SIDE_SIGN", "SOLE_GAP", "LegGeometry", "dof_index", "leg_geometry",
           "leg_ik"]

# Sides, in FOOT_BODIES order.
RIGHT, LEFT = 0, 1
SIDE_SIGN = np.array([-1.0, 1.0])  # lateral (y) sign of each side
_SIDE_NAMES = ("right", "left")
_HIP_FIT_TOLERANCE = np.radians(0.5)  # hip angles beyond their range by more get the in-range fit

LEG_EXTENSION = 0.993  # hip-ankle distance never exceeds this share of thigh + shin
SOLE_GAP = 0.002  # planted soles float this far above the ground (no initial penetration)


@dataclass(frozen=True)
class LegGeometry:
    """The leg and foot dimensions the synthesis needs, read off the compiled humanoid (metres).

    ``hip_offset`` is the left hip joint in the pelvis frame (the right one mirrors it in y);
    the knee sits ``thigh`` below the hip, the ankle ``shin`` below the knee (zero pose), the
    sole ``ankle_to_sole`` below the ankle and the top of the foot box ``foot_box_top`` above
    it. Along the foot, the toe tip is ``toe`` ahead of the ankle, the heel ``heel`` behind it
    and the foot box centre ``foot_centre`` ahead of it. ``dof_low``/``dof_high`` are the 28
    joint limits (rad) in ``DOF_NAMES`` order.
    """

    hip_offset: np.ndarray
    thigh: float
    shin: float
    ankle_to_sole: float
    toe: float
    heel: float
    foot_box_top: float
    foot_centre: float
    dof_low: np.ndarray
    dof_high: np.ndarray

    @property
    def foot_length(self) -> float:
        return self.toe + self.heel

    @property
    def max_leg_length(self) -> float:
        """Longest hip-ankle distance the synthesis uses (knee never locked straight)."""
        return LEG_EXTENSION * (self.thigh + self.shin)


@lru_cache(maxsize=1)
def leg_geometry() -> LegGeometry:
    """The humanoid's leg geometry and joint limits (from ``xml/humanoid.xml``; cached)."""
    model = humanoid_model()
    hip = model.body("left_thigh").pos.copy()
    knee = model.body("left_shin").pos
    ankle = model.body("left_foot").pos
    foot = model.geom("left_foot")
    # The two-link IK assumes a straight vertical leg in the zero pose, the pelvis-height bound
    # hips level with the pelvis origin.
    if not (np.allclose(knee[:2], 0.0) and np.allclose(ankle[:2], 0.0) and np.allclose(hip[[0, 2]], 0.0)):
        raise RuntimeError("synthesis assumes hips level with the pelvis and straight vertical legs")
    ranges = np.array([model.jnt_range[model.joint(name).id] for name in DOF_NAMES])
    return LegGeometry(
        hip_offset=hip,
        thigh=float(-knee[2]),
        shin=float(-ankle[2]),
        ankle_to_sole=float(-(foot.pos[2] - foot.size[2])),
        toe=float(foot.pos[0] + foot.size[0]),
        heel=float(foot.size[0] - foot.pos[0]),
        foot_box_top=float(foot.pos[2] + foot.size[2]),
        foot_centre=float(foot.pos[0]),
        dof_low=ranges[:, 0].copy(),
        dof_high=ranges[:, 1].copy(),
    )


def dof_index(name: str) -> int:
    """Column of a DoF in the 28 joint angles."""
    return DOF_NAMES.index(name)


def leg_ik(pelvis_pos: np.ndarray, pelvis_rot: Rotation, ankle: np.ndarray, foot_rot: Rotation,
            side: int, deep_flexion: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Hip XYZ angles (T, 3), knee angle (T,), ankle XYZ angles (T, 3) placing the ankle at
    ``ankle`` with the foot at orientation ``foot_rot`` (world), for a pelvis pose.

    The knee hinge axis (the thigh's y axis) is set parallel to the foot's lateral axis,
    projected perpendicular to the hip-ankle line, so the knee bends forward over the foot.
    ``deep_flexion`` (the crouch-walk's): hips flexed to and beyond 90 degrees get in-range angles
    (see ``_hip_angles`` and below); off, scipy's XYZ angles as they come (walks, climbs and the
    interaction clips, unchanged).
    """
    geo = leg_geometry()
    l1, l2 = geo.thigh, geo.shin
    hip_offset = geo.hip_offset * np.array([1.0, SIDE_SIGN[side], 1.0])
    pelvis_mat = pelvis_rot.as_matrix()
    hip = pelvis_pos + pelvis_mat @ hip_offset
    to_ankle = np.einsum("tji,tj->ti", pelvis_mat, ankle - hip)  # pelvis frame
    length = np.clip(np.linalg.norm(to_ankle, axis=1), abs(l1 - l2) + 1e-6, l1 + l2 - 1e-9)
    cos_knee = (length**2 - l1**2 - l2**2) / (2.0 * l1 * l2)
    knee = np.arccos(np.clip(cos_knee, -1.0, 1.0))
    # Ankle seen from the hip in the thigh frame.
    in_thigh = np.stack((-l2 * np.sin(knee), np.zeros_like(knee), -l1 - l2 * np.cos(knee)), axis=1)
    direction = to_ankle / np.linalg.norm(to_ankle, axis=1, keepdims=True)
    foot_in_pelvis = pelvis_rot.inv() * foot_rot
    lateral = foot_in_pelvis.apply(np.array([0.0, 1.0, 0.0]))
    lateral -= np.sum(lateral * direction, axis=1, keepdims=True) * direction
    lateral /= np.linalg.norm(lateral, axis=1, keepdims=True)
    target = np.stack((direction, lateral, np.cross(direction, lateral)), axis=2)
    v = in_thigh / np.linalg.norm(in_thigh, axis=1, keepdims=True)
    e_y = np.broadcast_to(np.array([0.0, 1.0, 0.0]), v.shape)
    source = np.stack((v, e_y, np.cross(v, e_y)), axis=2)
    hip_rot = Rotation.from_matrix(target @ np.transpose(source, (0, 2, 1)))
    shin_rot = hip_rot * Rotation.from_euler("y", knee[:, None])
    ankle_rot = shin_rot.inv() * foot_in_pelvis
    if not deep_flexion:
        return hip_rot.as_euler("XYZ"), knee, ankle_rot.as_euler("XYZ")
    hip_angles, ankle_angles = _hip_angles(hip_rot), ankle_rot.as_euler("XYZ")
    # Near 90 degrees of flexion the hip's x and z hinges line up (gimbal): the exact angles of a
    # rotation there can lie far outside the hip's range while an in-range set turns the thigh
    # almost the same way. Those frames get the nearest in-range angles, and the ankle is solved
    # again under the thigh they give, so the foot keeps its orientation.
    dofs = slice(dof_index(f"{_SIDE_NAMES[side]}_hip_x"), dof_index(f"{_SIDE_NAMES[side]}_hip_z") + 1)
    low, high = geo.dof_low[dofs], geo.dof_high[dofs]
    out = np.flatnonzero(np.any((hip_angles < low - _HIP_FIT_TOLERANCE) | (hip_angles > high + _HIP_FIT_TOLERANCE),
                                axis=1))
    if len(out):
        from stairenv.motion.importers import ball_joint_angles, euler_rotation

        fitted, _ = ball_joint_angles(hip_rot[out], low, high, bone=np.array([0.0, 0.0, -1.0]))
        hip_angles[out] = fitted
        shin = euler_rotation("XYZ", fitted) * Rotation.from_euler("y", knee[out, None])
        ankle_angles[out] = (shin.inv() * foot_in_pelvis[out]).as_euler("XYZ")
    return hip_angles, knee, ankle_angles


def _hip_angles(hip_rot: Rotation) -> np.ndarray:
    """Hip XYZ angles (T, 3): scipy's solution keeps y in [-90, 90] degrees, so a hip flexed beyond
    90 degrees (a deep crouch) comes out with x and z turned by 180 degrees, far outside the hip's
    range; there the other solution (x + pi, pi - y, z + pi), wrapped to (-pi, pi], is taken."""
    angles = hip_rot.as_euler("XYZ")
    flip = np.abs(angles[:, 0]) > 0.5 * np.pi
    if flip.any():
        other = angles[flip] + np.array([np.pi, 0.0, np.pi])
        other[:, 1] = np.pi - angles[flip, 1]
        angles[flip] = np.mod(other + np.pi, 2.0 * np.pi) - np.pi
    return angles
