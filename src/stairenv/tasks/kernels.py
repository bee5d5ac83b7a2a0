"""Compiled building blocks shared by the observation and style-feature kernels.

All work on one world's rows (``out`` a 1-D row, matrices 3x3); the batched
kernels loop over worlds and call these. The heading frame is the world frame
turned by the root's yaw (the yaw of its forward x axis), so that it is
invariant to where the character faces.
"""

from __future__ import annotations

import math

from llvmlite import ir
from numba.core import types
from numba.extending import intrinsic

from stairenv.humanoid.state import JOINT_ROWS, PARENT_ROWS, PELVIS
from stairenv.numba_jit import jit


@intrinsic
def fma(typingctx, a, b, c):
    """a * b + c rounded once (LLVM's ``llvm.fma.f64``: the CPU's fused multiply-add, else libm's ``fma``),
    for compiled code that must round as a BLAS kernel built with FMA does. Float64 arguments only."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        double = ir.DoubleType()
        fn = builder.module.declare_intrinsic("llvm.fma", [double], ir.FunctionType(double, [double] * 3))
        return builder.call(fn, args)

    return sig, codegen


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


PROPRIOCEPTION_SIZE = 113


@jit
def write_proprioception(row, body_mat, root_lin_vel, root_ang_vel, dof_vel, root_height, c, s):
    """The character's own state, 113 numbers at row[0:113]: root height, root rotation (6-D),
    root linear and angular velocity (heading frame), 12 joint rotations relative to their
    parents (6-D), 28 joint velocities. ``body_mat`` is one world's (15, 3, 3)."""
    R = body_mat[PELVIS]
    row[0] = root_height
    write_root_rotation_6d(row, 1, R, c, s)
    write_heading_vector(row, 7, root_lin_vel[0], root_lin_vel[1], root_lin_vel[2], c, s)
    write_local_angular_velocity(row, 10, R, root_ang_vel, c, s)
    for j in range(JOINT_ROWS.shape[0]):
        write_relative_rotation_6d(row, 13 + 6 * j, body_mat[PARENT_ROWS[j]], body_mat[JOINT_ROWS[j]])
    row[85:113] = dof_vel


@jit
def proprioception(body_mat, root_lin_vel, root_ang_vel, dof_vel, root_height, out):
    """Batched ``write_proprioception``: (B, 113) with the root height given per world."""
    for b in range(body_mat.shape[0]):
        _, c, s = heading_cos_sin(body_mat[b, PELVIS])
        write_proprioception(out[b], body_mat[b], root_lin_vel[b], root_ang_vel[b], dof_vel[b], root_height[b], c, s)
    return out


# --- per-step checks of every env ---------------------------------------------------
@jit
def all_finite(values):
    """Whether every entry of the 1-D ``values`` is finite (no NaN, no inf): one native pass,
    where ``np.isfinite(values).all()`` costs two numpy calls and a temporary."""
    for i in range(values.shape[0]):
        if not math.isfinite(values[i]):
            return False
    return True


@jit
def within_limits(values, start, limits):
    """Whether ``|values[start + i]| <= limits[i]`` for every i (False on NaN, as ``np.abs(...).max()
    <= limit`` is): the speed check after each step, one native call instead of three numpy reductions."""
    for i in range(limits.shape[0]):
        if not abs(values[start + i]) <= limits[i]:
            return False
    return True


@jit
def no_warnings_within_limits(warnings, rows, values, limits):
    """Whether ``warnings[rows]`` are all 0 (MuJoCo's counts of the warnings named by ``rows``) and
    ``within_limits(values, 0, limits)``: the divergence and speed checks after a step in one native call."""
    for i in range(rows.shape[0]):
        if warnings[rows[i]] != 0:
            return False
    return within_limits(values, 0, limits)


@jit
def pd_targets(offset, scale, action, out):
    """``out[:] = offset + scale * action`` (the PD targets of an action), each entry rounded as numpy's
    multiply then add round it: one native call instead of two ufunc calls."""
    for i in range(out.shape[0]):
        out[i] = offset[i] + scale[i] * action[i]
    return out


@jit
def finite_pd_targets(offset, scale, action, out):
    """``pd_targets`` of ``action`` if every entry of it is finite (True), else nothing written (False): an
    action's check for NaN and inf and its PD targets in one native call."""
    for i in range(action.shape[0]):
        if not math.isfinite(action[i]):
            return False
    pd_targets(offset, scale, action, out)
    return True
