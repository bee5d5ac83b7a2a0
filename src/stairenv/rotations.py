"""Rotation helpers: batched ones (leading batch dimension, numpy) and the one yaw rotation
(``yaw_matrix``, ``yaw_to_quat_wxyz``) that every rotation about +z by a single angle uses.

Rotation matrices are (..., 3, 3); the 6-D representation of Zhou et al. (2019) is
the first two columns of the matrix, concatenated: (R[:, 0], R[:, 1]).
Per-call conversions that are off the hot path use ``scipy.spatial.transform``.
"""

from __future__ import annotations

import math

import numpy as np


def matrix_to_6d(mats: np.ndarray) -> np.ndarray:
    """(..., 3, 3) -> (..., 6): first column then second column."""
    return np.concatenate((mats[..., :, 0], mats[..., :, 1]), axis=-1)


def sixd_to_matrix(sixd: np.ndarray) -> np.ndarray:
    """(..., 6) -> (..., 3, 3) by Gram-Schmidt (the inverse of ``matrix_to_6d``)."""
    a, b = sixd[..., :3], sixd[..., 3:]
    c0 = a / np.linalg.norm(a, axis=-1, keepdims=True)
    b = b - np.sum(c0 * b, axis=-1, keepdims=True) * c0
    c1 = b / np.linalg.norm(b, axis=-1, keepdims=True)
    c2 = np.cross(c0, c1)
    return np.stack((c0, c1, c2), axis=-1)


def heading_angle(mats: np.ndarray) -> np.ndarray:
    """Yaw of the body's forward (x) axis projected on the ground: (..., 3, 3) -> (...)."""
    return np.arctan2(mats[..., 1, 0], mats[..., 0, 0])


def yaw_matrix(yaw: float) -> np.ndarray:
    """The (3, 3) rotation by ``yaw`` (rad) about +z: the package's one yaw matrix (furniture poses
    and parts, the SIMS heading frame). ``math`` cos and sin, so equal bit for bit wherever it
    replaced the same matrix written out."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def wrap_angle(angle: np.ndarray) -> np.ndarray:
    """Wrap to [-pi, pi)."""
    return (angle + np.pi) % (2.0 * np.pi) - np.pi


def yaw_to_quat_wxyz(yaw: float) -> np.ndarray:
    """MuJoCo (w, x, y, z) quaternion of a rotation by ``yaw`` (rad) about +z: the package's one yaw
    quaternion (root poses, the bodies of scene boxes, room walls and furniture)."""
    # The closed form of Rotation.from_euler("z", yaw), bit for bit (tested); scipy costs ~60 us a call
    # on the reset path.
    half = 0.5 * float(yaw)
    return np.array([math.cos(half), 0.0, 0.0, math.sin(half)])
