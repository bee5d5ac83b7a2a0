"""Model facts: the 15-body, 28-DoF humanoid, its PD gains and its action mapping.

Names and order of bodies and degrees of freedom, the two public PD-gain
presets, the map from a policy action in [-1, 1]^28 to PD targets, loading the
MJCF (``xml/humanoid.xml``) into an ``mujoco.MjSpec`` that world builders add
to, the bare compiled model (``humanoid_model``) and the ids of the humanoid in
a compiled model (``HumanoidIndices``).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import mujoco
import numpy as np

from stairenv.assets import xml_path

BODY_NAMES: tuple[str, ...] = (
    "pelvis", "torso", "head",
    "right_upper_arm", "right_lower_arm", "right_hand",
    "left_upper_arm", "left_lower_arm", "left_hand",
    "right_thigh", "right_shin", "right_foot",
    "left_thigh", "left_shin", "left_foot",
)
PARENT_INDICES: tuple[int, ...] = (-1, 0, 1, 1, 3, 4, 1, 6, 7, 0, 9, 10, 0, 12, 13)

# The 12 internal joints in qpos order: (joint, body it moves, hinge axes).
JOINTS: tuple[tuple[str, str, str], ...] = (
    ("abdomen", "torso", "xyz"),
    ("neck", "head", "xyz"),
    ("right_shoulder", "right_upper_arm", "xyz"),
    ("right_elbow", "right_lower_arm", "y"),
    ("left_shoulder", "left_upper_arm", "xyz"),
    ("left_elbow", "left_lower_arm", "y"),
    ("right_hip", "right_thigh", "xyz"),
    ("right_knee", "right_shin", "y"),
    ("right_ankle", "right_foot", "xyz"),
    ("left_hip", "left_thigh", "xyz"),
    ("left_knee", "left_shin", "y"),
    ("left_ankle", "left_foot", "xyz"),
)
DOF_NAMES: tuple[str, ...] = tuple(
    f"{joint}_{axis}" if len(axes) == 3 else joint for joint, _, axes in JOINTS for axis in axes
)
DOF_JOINTS: tuple[str, ...] = tuple(joint for joint, _, axes in JOINTS for _ in axes)
NUM_DOFS = len(DOF_NAMES)  # 28
JOINT_BODIES: tuple[str, ...] = tuple(body for _, body, _ in JOINTS)
KEY_BODIES: tuple[str, ...] = ("right_hand", "left_hand", "right_foot", "left_foot")
FOOT_BODIES: tuple[str, ...] = ("right_foot", "left_foot")

# Height of the pelvis when standing on flat ground in the default pose (m).
STANDING_ROOT_HEIGHT = 0.885
#: the tracked head point (PlaMo's head paths): the centre of the head sphere, 0.175 m along the head body's z axis
HEAD_CENTRE_OFFSET = np.array([0.0, 0.0, 0.175])
HEAD_CENTRE_OFFSET.flags.writeable = False

# PD gains (stiffness kp [N m/rad], damping kv [N m s/rad]) per joint, from the two
# public AMP-humanoid configurations: "soft" (config A) and "stiff" (config B).
PD_GAINS: dict[str, dict[str, tuple[float, float]]] = {
    "soft": {
        "abdomen": (600.0, 60.0), "neck": (50.0, 5.0), "shoulder": (200.0, 20.0),
        "elbow": (150.0, 15.0), "hip": (300.0, 30.0), "knee": (300.0, 30.0),
        "ankle": (200.0, 20.0),
    },
    "stiff": {
        "abdomen": (1000.0, 100.0), "neck": (100.0, 10.0), "shoulder": (400.0, 40.0),
        "elbow": (300.0, 30.0), "hip": (500.0, 50.0), "knee": (500.0, 50.0),
        "ankle": (400.0, 40.0),
    },
}


def _joint_kind(joint: str) -> str:
    return joint.removeprefix("right_").removeprefix("left_")


def load_humanoid_spec(pd_gains: str = "soft") -> mujoco.MjSpec:
    """Load ``xml/humanoid.xml`` as an editable spec with the chosen PD-gain preset."""
    if pd_gains not in PD_GAINS:
        raise ValueError(f"pd_gains must be one of {sorted(PD_GAINS)}, got {pd_gains!r}")
    spec = mujoco.MjSpec.from_file(str(xml_path("humanoid.xml")))
    gains = PD_GAINS[pd_gains]
    to_rad = np.pi / 180.0 if spec.compiler.degree else 1.0
    ranges = np.array([spec.joint(n).range for n in DOF_NAMES]) * to_rad
    offset, scale = pd_action_offset_scale(ranges)
    for dof, name in enumerate(DOF_NAMES):
        actuator = spec.actuator(name)
        kp, kv = gains[_joint_kind(DOF_JOINTS[dof])]
        # A position servo: force = kp * ctrl - kp * q - kv * qdot.
        actuator.gainprm[0] = kp
        actuator.biasprm[1] = -kp
        actuator.biasprm[2] = -kv
        # The PD target range that actions in [-1, 1] span; MuJoCo clamps ctrl to it.
        actuator.ctrllimited = True
        actuator.ctrlrange = [offset[dof] - scale[dof], offset[dof] + scale[dof]]
    return spec


@lru_cache(maxsize=1)
def humanoid_model() -> mujoco.MjModel:
    """The bare humanoid (no scene), for kinematics of clips."""
    return load_humanoid_spec().compile()


def pd_action_offset_scale(dof_ranges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The affine map ``target = offset + scale * action`` for the 28 actuated DoFs.

    ``dof_ranges`` is (28, 2), joint limits in radians, in DOF_NAMES order.
    Three-axis joints get a symmetric range: scale = min(1.2 * max|limit|, pi) over the
    joint's three axes, offset 0. Hinges (elbows, knees) get their range widened 1.4x
    about its midpoint. Targets beyond the joint limits are allowed: the limit stops
    the joint and the servo saturates, as with the public configurations.
    """
    dof_ranges = np.asarray(dof_ranges, dtype=float)
    offset = np.zeros(NUM_DOFS)
    scale = np.zeros(NUM_DOFS)
    dof = 0
    for _, _, axes in JOINTS:
        ranges = dof_ranges[dof:dof + len(axes)]
        if len(axes) == 3:
            scale[dof:dof + 3] = min(1.2 * np.abs(ranges).max(), np.pi)
        else:
            low, high = ranges[0]
            offset[dof] = 0.5 * (low + high)
            scale[dof] = 0.7 * (high - low)
        dof += len(axes)
    return offset, scale


def dof_ranges(model: mujoco.MjModel) -> np.ndarray:
    """(28, 2) joint limits in radians, in DOF_NAMES order, read off a compiled model."""
    return np.array([model.jnt_range[model.joint(n).id] for n in DOF_NAMES])


@dataclass(frozen=True)
class HumanoidIndices:
    """Ids of the humanoid's bodies and DoFs in a compiled model (which may hold a scene too)."""

    body_ids: np.ndarray          # (15,) MuJoCo body ids in BODY_NAMES order
    body_slice: slice | None      # the same ids as a slice when they are consecutive (cheap views)
    parent_ids: np.ndarray        # (12,) body id of each joint body's parent
    joint_body_ids: np.ndarray    # (12,) body id moved by each joint
    key_body_ids: np.ndarray      # (4,) hands then feet
    qpos_root: slice              # free joint position + quaternion (7)
    qvel_root: slice              # free joint linear (world) + angular (local) velocity (6)
    qpos_joints: slice            # 28 hinge angles
    qvel_joints: slice            # 28 hinge velocities
    head_id: int
    pelvis_id: int
    foot_ids: np.ndarray          # (2,)

    @classmethod
    def from_model(cls, model: mujoco.MjModel) -> "HumanoidIndices":
        body_ids = np.array([model.body(n).id for n in BODY_NAMES])
        root = model.joint("root")
        qpos0, qvel0 = int(root.qposadr[0]), int(root.dofadr[0])
        joint_body_ids = np.array([model.body(b).id for b in JOINT_BODIES])
        consecutive = bool(np.all(np.diff(body_ids) == 1))
        return cls(
            body_ids=body_ids,
            body_slice=slice(int(body_ids[0]), int(body_ids[-1]) + 1) if consecutive else None,
            parent_ids=model.body_parentid[joint_body_ids].copy(),
            joint_body_ids=joint_body_ids,
            key_body_ids=np.array([model.body(n).id for n in KEY_BODIES]),
            qpos_root=slice(qpos0, qpos0 + 7),
            qvel_root=slice(qvel0, qvel0 + 6),
            qpos_joints=slice(qpos0 + 7, qpos0 + 7 + NUM_DOFS),
            qvel_joints=slice(qvel0 + 6, qvel0 + 6 + NUM_DOFS),
            head_id=model.body("head").id,
            pelvis_id=model.body("pelvis").id,
            foot_ids=np.array([model.body(n).id for n in FOOT_BODIES]),
        )
