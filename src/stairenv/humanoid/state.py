"""The humanoid's state as plain arrays read off ``mujoco.MjData``, batch-first.

``read_state`` is the only place that touches MjData for the task functions: a
natively batched backend fills the same fields from many worlds at once. The
arrays may be views into MjData: use them before the next physics step, copy
what must outlive it.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import mujoco
import numpy as np

from stairenv.humanoid.model import BODY_NAMES, JOINT_BODIES, PARENT_INDICES, HumanoidIndices


class HumanoidState(NamedTuple):
    body_pos: np.ndarray      # (B, 15, 3) world positions of the bodies, BODY_NAMES order
    body_mat: np.ndarray      # (B, 15, 3, 3) world orientations (columns: body axes)
    root_lin_vel: np.ndarray  # (B, 3) root linear velocity, world frame
    root_ang_vel: np.ndarray  # (B, 3) root angular velocity, root (pelvis) frame, as MuJoCo's free joint
    dof_pos: np.ndarray       # (B, 28)
    dof_vel: np.ndarray       # (B, 28)


# Rows of HumanoidState.body_* (BODY_NAMES order).
PELVIS, HEAD = BODY_NAMES.index("pelvis"), BODY_NAMES.index("head")
RIGHT_HAND, LEFT_HAND = BODY_NAMES.index("right_hand"), BODY_NAMES.index("left_hand")
RIGHT_FOOT, LEFT_FOOT = BODY_NAMES.index("right_foot"), BODY_NAMES.index("left_foot")
# Joint bodies and their parents as rows of body_* (12 joints, qpos order).
JOINT_ROWS = np.array([BODY_NAMES.index(body) for body in JOINT_BODIES])
PARENT_ROWS = np.array([PARENT_INDICES[row] for row in JOINT_ROWS])


def read_state(data: mujoco.MjData, idx: HumanoidIndices) -> HumanoidState:
    """The humanoid's state in ``data`` as a batch of one."""
    root_vel = data.qvel[idx.qvel_root]
    bodies = idx.body_ids if idx.body_slice is None else idx.body_slice
    return HumanoidState(
        body_pos=data.xpos[bodies][None],
        body_mat=data.xmat[bodies].reshape(1, len(BODY_NAMES), 3, 3),
        root_lin_vel=root_vel[None, :3],
        root_ang_vel=root_vel[None, 3:],
        dof_pos=data.qpos[idx.qpos_joints][None],
        dof_vel=data.qvel[idx.qvel_joints][None],
    )


def read_states(datas, idx: HumanoidIndices) -> HumanoidState:
    """The humanoid's state in each of ``datas`` (worlds of one model structure, ``idx`` of any of
    them) as one batch: the rows equal ``read_state`` of each world. Copies, not views."""
    return states_from_arrays(np.stack([data.xpos for data in datas]), np.stack([data.xmat for data in datas]),
                              np.stack([data.qpos for data in datas]), np.stack([data.qvel for data in datas]), idx)


def states_from_arrays(xpos: np.ndarray, xmat: np.ndarray, qpos: np.ndarray, qvel: np.ndarray,
                       idx: HumanoidIndices) -> HumanoidState:
    """The humanoid's state from many worlds' ``MjData`` fields stacked (``xpos`` (B, nbody, 3), ``xmat``
    (B, nbody, 9), ``qpos``, ``qvel``): what ``read_states`` reads, from arrays a device back-end brings
    down in one copy per field. Copies, not views."""
    bodies = idx.body_ids if idx.body_slice is None else idx.body_slice
    root_vel = qvel[:, idx.qvel_root]
    return HumanoidState(
        body_pos=np.ascontiguousarray(xpos[:, bodies]),
        body_mat=np.ascontiguousarray(xmat[:, bodies]).reshape(len(xpos), len(BODY_NAMES), 3, 3),
        root_lin_vel=np.ascontiguousarray(root_vel[:, :3]),
        root_ang_vel=np.ascontiguousarray(root_vel[:, 3:]),
        dof_pos=np.ascontiguousarray(qpos[:, idx.qpos_joints]),
        dof_vel=np.ascontiguousarray(qvel[:, idx.qvel_joints]),
    )


def stack_states(states) -> HumanoidState:
    """One batch of ``states`` (batches, e.g. each world's ``read_state`` where the worlds' models differ in
    structure, which ``read_states`` cannot read at once), in their order. Copies, not views."""
    return HumanoidState(*(np.concatenate(field) for field in zip(*states)))


def push_root(model: mujoco.MjModel, data: mujoco.MjData, speed: float, angle: float) -> None:
    """A horizontal kick: ``speed`` (m/s) added to the root's world-frame linear velocity in direction
    ``angle`` (rad in the world's xy plane; the root's free joint: its first three DoFs are that velocity).
    The evaluations' pushes (``stairenv.evaluation.pushes``) and the training pushes of every env
    (``push_speed``) are this kick."""
    body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, BODY_NAMES[0])
    dof = model.jnt_dofadr[model.body_jntadr[body]]
    data.qvel[dof] += speed * math.cos(angle)
    data.qvel[dof + 1] += speed * math.sin(angle)
