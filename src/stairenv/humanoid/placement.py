"""Placing the humanoid on terrain: a state written into ``MjData`` with its lowest point just
above the floor, so nothing penetrates."""

from __future__ import annotations

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation

from stairenv.humanoid.kinematics import humanoid_geoms, humanoid_lowest_z
from stairenv.humanoid.model import HumanoidIndices

# Gap left between the lowest body point and the floor when placing a reference state (m).
PLACEMENT_CLEARANCE = 0.002


def rest_on_floor(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    idx: HumanoidIndices,
    floor_height: float = 0.0,
    geoms: np.ndarray | None = None,
) -> None:
    """Move the root vertically so the lowest point of ``geoms`` (default: all the humanoid's) is
    PLACEMENT_CLEARANCE above ``floor_height``. Needs current kinematics; runs kinematics after."""
    if geoms is None:
        geoms = humanoid_geoms(model, idx)
    lift = floor_height + PLACEMENT_CLEARANCE - humanoid_lowest_z(model, data, geoms)
    data.qpos[idx.qpos_root.start + 2] += lift
    mujoco.mj_kinematics(model, data)


def place_reference_state(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    idx: HumanoidIndices,
    qpos: np.ndarray,
    qvel: np.ndarray,
    xy: tuple[float, float],
    heading: float,
    floor_height: float = 0.0,
) -> None:
    """Write a reference state into ``data``: turned to face ``heading``, root over ``xy``,
    lowest point PLACEMENT_CLEARANCE above ``floor_height``. Runs kinematics."""
    root_rot = Rotation.from_quat(qpos[3:7], scalar_first=True)
    forward = root_rot.apply([1.0, 0.0, 0.0])
    turn = Rotation.from_euler("z", heading - np.arctan2(forward[1], forward[0]))
    data.qpos[idx.qpos_root] = (xy[0], xy[1], qpos[2], *(turn * root_rot).as_quat(scalar_first=True))
    data.qpos[idx.qpos_joints] = qpos[7:]
    data.qvel[idx.qvel_root] = (*turn.apply(qvel[:3]), *qvel[3:6])  # angular velocity is in the root frame
    data.qvel[idx.qvel_joints] = qvel[6:]
    mujoco.mj_kinematics(model, data)
    rest_on_floor(model, data, idx, floor_height)


def place_state_in_frame(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    idx: HumanoidIndices,
    qpos: np.ndarray,
    qvel: np.ndarray,
    yaw: float,
    origin: np.ndarray,
    lift: float = PLACEMENT_CLEARANCE,
) -> None:
    """Write a state given in a local frame (turned by ``yaw`` about z, its origin at world
    ``origin``) into ``data``, raised by ``lift``: a frame of motion planned on terrain that stands
    in the world at that pose (a staircase's climb on that staircase). Runs kinematics."""
    turn = Rotation.from_euler("z", yaw)
    root_rot = Rotation.from_quat(qpos[3:7], scalar_first=True)
    position = turn.apply(qpos[:3]) + np.asarray(origin, dtype=np.float64)
    position[2] += lift
    data.qpos[idx.qpos_root] = (*position, *(turn * root_rot).as_quat(scalar_first=True))
    data.qpos[idx.qpos_joints] = qpos[7:]
    data.qvel[idx.qvel_root] = (*turn.apply(qvel[:3]), *qvel[3:6])  # angular velocity is in the root frame
    data.qvel[idx.qvel_joints] = qvel[6:]
    mujoco.mj_kinematics(model, data)
