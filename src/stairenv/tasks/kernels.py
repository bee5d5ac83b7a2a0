"""Compiled building blocks shared by the observation and style-feature kernels.

All work on one world's rows (``out`` a 1-D row, matrices 3x3); the batched
kernels loop over worlds and call these. The heading frame is the world frame
turned by the root's yaw (the yaw of its forward x axis), so that it is
invariant to where the character faces.
"""

from __future__ import annotations

import math

from numba import njit

jit = njit(cache=True, nogil=True)


@jit
def heading_cos_sin(R):
    """Yaw of the root's x axis on the ground, and its cosine and sine."""
    yaw = math.atan2(R[1, 0], R[0, 0])
    return yaw, math.cos(yaw), math.sin(yaw)


@jit
def write_heading_vector(out, at, x, y, z, c, s):
    """World vector (x, y, z) in the heading frame, written to out[at:at+3]."""
    out[at] = c * x + s * y
    out[at + 1] = -s * x + c * y
    out[at + 2] = z


@jit
def write_root_rotation_6d(out, at, R, c, s):
    """Root rotation in the heading frame as 6-D (columns 0 then 1), written to out[at:at+6]."""
    for col in range(2):
        write_heading_vector(out, at + 3 * col, R[0, col], R[1, col], R[2, col], c, s)


@jit
def write_local_angular_velocity(out, at, R, w, c, s):
    """Angular velocity ``w`` given in the root frame (MuJoCo's free joint), in the heading frame."""
    wx = R[0, 0] * w[0] + R[0, 1] * w[1] + R[0, 2] * w[2]
    wy = R[1, 0] * w[0] + R[1, 1] * w[1] + R[1, 2] * w[2]
    wz = R[2, 0] * w[0] + R[2, 1] * w[1] + R[2, 2] * w[2]
    write_heading_vector(out, at, wx, wy, wz, c, s)


@jit
def write_relative_rotation_6d(out, at, P, C):
    """Rotation of child C relative to parent P (P^T C) as 6-D, written to out[at:at+6]."""
    for col in range(2):
        for i in range(3):
            out[at + 3 * col + i] = P[0, i] * C[0, col] + P[1, i] * C[1, col] + P[2, i] * C[2, col]
