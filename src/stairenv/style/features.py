"""AMP features: one function for env states and reference frames alike.

Per frame (``AMP_FEATURE_SIZE`` = 105), in this order:

| slice | size | feature |
|---|---|---|
| 0 | 1 | root height above the lower foot (terrain-independent: flat and stair references compare) |
| 1:7 | 6 | root rotation, heading frame, 6-D |
| 7:10 | 3 | root linear velocity, heading frame |
| 10:13 | 3 | root angular velocity, heading frame |
| 13:61 | 48 | the eight 3-axis joints' rotations relative to their parent, 6-D each |
| 61:65 | 4 | the four hinge angles (elbows, knees) |
| 65:93 | 28 | joint velocities |
| 93:105 | 12 | hands and feet relative to the root, heading frame |

The discriminator sees K consecutive frames, oldest first (K * 105 numbers).
Env states come from ``read_state`` on the env's ``MjData``; reference frames
from the same ``read_state`` on a scratch ``MjData`` after forward kinematics
of the clip's qpos (``reference_features``), so the two cannot drift apart.
"""

from __future__ import annotations

import numpy as np

from stairenv.humanoid import JOINTS, HumanoidIndices, humanoid_model
from stairenv.humanoid.kinematics import forward_kinematics
from stairenv.humanoid.state import (
    JOINT_ROWS,
    LEFT_FOOT,
    LEFT_HAND,
    PARENT_ROWS,
    PELVIS,
    RIGHT_FOOT,
    RIGHT_HAND,
    HumanoidState,
    read_state,
)
from stairenv.motion.clip import MotionClip
from stairenv.tasks.kernels import (
    heading_cos_sin,
    jit,
    write_heading_vector,
    write_local_angular_velocity,
    write_relative_rotation_6d,
    write_root_rotation_6d,
)

AMP_FEATURE_SIZE = 105
KEY_ROWS = np.array([RIGHT_HAND, LEFT_HAND, RIGHT_FOOT, LEFT_FOOT])
# Which of the 12 joints are 3-axis (6-D features) and where the hinges sit among the 28 DoFs.
BALL_JOINTS = np.array([j for j, (_, _, axes) in enumerate(JOINTS) if len(axes) == 3])
HINGE_DOFS = np.array(
    [sum(len(a) for _, _, a in JOINTS[:j]) for j, (_, _, axes) in enumerate(JOINTS) if len(axes) == 1]
)
AMP_FEATURE_STRUCTURE: dict[str, slice] = {
    "root_height": slice(0, 1),
    "root_rotation": slice(1, 7),
    "root_linear_velocity": slice(7, 10),
    "root_angular_velocity": slice(10, 13),
    "ball_joint_rotations": slice(13, 61),
    "hinge_angles": slice(61, 65),
    "joint_velocities": slice(65, 93),
    "key_body_positions": slice(93, 105),
}


@jit
def write_amp_features(row, body_pos, body_mat, root_lin_vel, root_ang_vel, dof_pos, dof_vel):
    """One world's features into ``row`` (105,): its ``body_pos`` (15, 3), ``body_mat`` (15, 3, 3), root
    velocities (3,) and joint positions and velocities (28,)."""
    R = body_mat[PELVIS]
    p = body_pos[PELVIS]
    _, c, s = heading_cos_sin(R)
    row[0] = p[2] - min(body_pos[RIGHT_FOOT, 2], body_pos[LEFT_FOOT, 2])
    write_root_rotation_6d(row, 1, R, c, s)
    write_heading_vector(row, 7, root_lin_vel[0], root_lin_vel[1], root_lin_vel[2], c, s)
    write_local_angular_velocity(row, 10, R, root_ang_vel, c, s)
    for k in range(BALL_JOINTS.shape[0]):
        j = BALL_JOINTS[k]
        write_relative_rotation_6d(row, 13 + 6 * k, body_mat[PARENT_ROWS[j]], body_mat[JOINT_ROWS[j]])
    for k in range(HINGE_DOFS.shape[0]):
        row[61 + k] = dof_pos[HINGE_DOFS[k]]
    row[65:93] = dof_vel
    for k in range(KEY_ROWS.shape[0]):
        q = body_pos[KEY_ROWS[k]]
        write_heading_vector(row, 93 + 3 * k, q[0] - p[0], q[1] - p[1], q[2] - p[2], c, s)


@jit
def push_amp_features(k, frames, body_pos, body_mat, root_lin_vel, root_ang_vel, dof_pos, dof_vel, flat):
    """``FeatureHistory.push`` of world k's state (row k of the batch's state arrays) into its history's
    ``frames`` (K, 105), and their ``flat()`` into ``flat`` (K * 105,): one compiled call."""
    last = frames.shape[0] - 1
    for i in range(last):
        frames[i, :] = frames[i + 1, :]
    write_amp_features(frames[last], body_pos[k], body_mat[k], root_lin_vel[k], root_ang_vel[k], dof_pos[k],
                       dof_vel[k])
    for i in range(frames.shape[0]):
        flat[i * AMP_FEATURE_SIZE:(i + 1) * AMP_FEATURE_SIZE] = frames[i]
    return flat


@jit
def _feature_kernel(body_pos, body_mat, root_lin_vel, root_ang_vel, dof_pos, dof_vel, out):
    for b in range(body_pos.shape[0]):
        write_amp_features(out[b], body_pos[b], body_mat[b], root_lin_vel[b], root_ang_vel[b], dof_pos[b], dof_vel[b])
    return out


def amp_features(state: HumanoidState, out: np.ndarray | None = None) -> np.ndarray:
    """Per-frame AMP features of a batch of humanoid states: (B, 105), written to ``out`` if given."""
    if out is None:
        out = np.empty((state.body_pos.shape[0], AMP_FEATURE_SIZE))
    return _feature_kernel(state.body_pos, state.body_mat, state.root_lin_vel, state.root_ang_vel,
                           state.dof_pos, state.dof_vel, out)


def state_features(qpos: np.ndarray, qvel: np.ndarray) -> np.ndarray:
    """Features of humanoid states given as qpos (N, 35) and qvel (N, 34), by forward kinematics."""
    qpos, qvel = np.atleast_2d(qpos), np.atleast_2d(qvel)
    idx = HumanoidIndices.from_model(humanoid_model())
    out = np.empty((qpos.shape[0], AMP_FEATURE_SIZE))
    for t, data in enumerate(forward_kinematics(qpos, qvel)):
        out[t] = amp_features(read_state(data, idx))[0]
    return out


def reference_features(clip: MotionClip, fps: float | None = None) -> np.ndarray:
    """Features of every frame of ``clip`` (resampled to ``fps`` if given): (T, 105)."""
    if fps is not None and abs(fps - clip.fps) > 1e-9:
        clip = clip.resample(fps)
    return state_features(clip.qpos, clip.qvel())


class FeatureHistory:
    """The last K feature frames of one world, oldest first."""

    def __init__(self, num_frames: int) -> None:
        if num_frames < 1:
            raise ValueError(f"amp_history must be >= 1, got {num_frames}")
        self.frames = np.zeros((num_frames, AMP_FEATURE_SIZE))

    def fill_features(self, frame: np.ndarray) -> None:
        """Every frame ``frame`` (a row of ``amp_features``), as at an episode start."""
        self.frames[:] = frame

    def push(self, state: HumanoidState) -> None:
        """Drop the oldest frame and append the features of ``state`` (a batch of one)."""
        self.frames[:-1] = self.frames[1:]
        amp_features(state, self.frames[-1:])

    def push_features(self, frame: np.ndarray) -> None:
        """``push`` with the frame's features already computed (a row of ``amp_features`` of a batch)."""
        self.frames[:-1] = self.frames[1:]
        self.frames[-1] = frame

    def flat(self) -> np.ndarray:
        return self.frames.reshape(-1).copy()

    @staticmethod
    def push_rows(frames: np.ndarray, rows: np.ndarray, features: np.ndarray) -> np.ndarray:
        """``push_each`` of the histories that are rows ``rows`` of ``frames`` (N, K, F), one array for many
        worlds' histories (a batched env's; row k of ``features``: the new frame of history ``rows[k]``);
        returns their ``flat()``, one row each, of one new array."""
        if len(rows) == len(frames) and np.array_equal(rows, np.arange(len(frames))):    # every history, in place
            frames[:, :-1] = frames[:, 1:]
            frames[:, -1] = features
            return frames.reshape(len(rows), -1).copy()
        own = frames[rows]
        own[:, :-1] = own[:, 1:]
        own[:, -1] = features
        frames[rows] = own
        return own.reshape(len(rows), -1)

    @staticmethod
    def push_each(histories: list[FeatureHistory], features: np.ndarray) -> np.ndarray:
        """``push_features`` of each of ``histories`` (row k of ``features``: history k's new frame) as array
        operations over the batch; returns their ``flat()``, one row each, of one new array."""
        frames = np.array([history.frames for history in histories])
        frames[:, :-1] = frames[:, 1:]
        frames[:, -1] = features
        for history, own in zip(histories, frames):
            history.frames[...] = own
        return frames.reshape(len(histories), -1)
