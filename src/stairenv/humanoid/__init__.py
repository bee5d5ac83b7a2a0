"""The body: one home for the 15-body, 28-DoF humanoid; every other module calls it.

| module | holds |
|---|---|
| ``model`` | model facts: body and DoF names and order, PD gains, action map, spec loading, the bare compiled model, ``HumanoidIndices`` |
| ``state`` | ``read_state``: the state as batch-first arrays off ``MjData``; rows of its body arrays (derived from ``BODY_NAMES``) |
| ``kinematics`` | forward kinematics over frames; the lowest body point; body positions and foot-sole heights of clips |
| ``placement`` | putting a state on terrain with its lowest point just above the floor |

The model facts are importable from here (``from stairenv.humanoid import BODY_NAMES``).
"""

from stairenv.humanoid.model import (
    BODY_NAMES,
    DOF_JOINTS,
    DOF_NAMES,
    FOOT_BODIES,
    JOINT_BODIES,
    JOINTS,
    KEY_BODIES,
    NUM_DOFS,
    PARENT_INDICES,
    PD_GAINS,
    STANDING_ROOT_HEIGHT,
    HumanoidIndices,
    dof_ranges,
    humanoid_model,
    load_humanoid_spec,
    pd_action_offset_scale,
)

__all__ = [
    "BODY_NAMES",
    "DOF_JOINTS",
    "DOF_NAMES",
    "FOOT_BODIES",
    "JOINTS",
    "JOINT_BODIES",
    "KEY_BODIES",
    "NUM_DOFS",
    "PARENT_INDICES",
    "PD_GAINS",
    "STANDING_ROOT_HEIGHT",
    "HumanoidIndices",
    "dof_ranges",
    "humanoid_model",
    "load_humanoid_spec",
    "pd_action_offset_scale",
]
