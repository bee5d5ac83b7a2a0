"""The body: ``stairenv.humanoid`` and ``xml/humanoid.xml`` against the body specification written out below."""

from __future__ import annotations

import math

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import stairenv  # noqa: F401  (registers the envs)
from stairenv.humanoid import (
    BODY_NAMES,
    DOF_NAMES,
    NUM_DOFS,
    PARENT_INDICES,
    PD_GAINS,
    STANDING_ROOT_HEIGHT,
    dof_ranges,
    load_humanoid_spec,
    pd_action_offset_scale,
)

# --- the specification, written out --------------------------------------------------------------
SPEC_BODIES = [
    "pelvis", "torso", "head", "right_upper_arm", "right_lower_arm", "right_hand",
    "left_upper_arm", "left_lower_arm", "left_hand", "right_thigh", "right_shin", "right_foot",
    "left_thigh", "left_shin", "left_foot",
]
SPEC_PARENTS = [-1, 0, 1, 1, 3, 4, 1, 6, 7, 0, 9, 10, 0, 12, 13]

# joint -> per-axis range in degrees (x, y, z) or (y,) for the one-axis joints
SPEC_RANGES_DEG = {
    "abdomen": [(-60, 60), (-60, 90), (-50, 50)],
    "neck": [(-50, 50), (-40, 60), (-45, 45)],
    "right_shoulder": [(-180, 45), (-180, 60), (-90, 90)],
    "right_elbow": [(-160, 0)],
    "left_shoulder": [(-45, 180), (-180, 60), (-90, 90)],
    "left_elbow": [(-160, 0)],
    "right_hip": [(-60, 15), (-140, 60), (-60, 35)],
    "right_knee": [(0, 160)],
    "right_ankle": [(-30, 30), (-55, 55), (-40, 40)],
    "left_hip": [(-15, 60), (-140, 60), (-35, 60)],
    "left_knee": [(0, 160)],
    "left_ankle": [(-30, 30), (-55, 55), (-40, 40)],
}
JOINT_ORDER = list(SPEC_RANGES_DEG)  # qpos order (the MJCF comment and the specification agree)
JOINT_BODY = {
    "abdomen": "torso", "neck": "head", "right_shoulder": "right_upper_arm", "right_elbow": "right_lower_arm",
    "left_shoulder": "left_upper_arm", "left_elbow": "left_lower_arm", "right_hip": "right_thigh",
    "right_knee": "right_shin", "right_ankle": "right_foot", "left_hip": "left_thigh", "left_knee": "left_shin",
    "left_ankle": "left_foot",
}
SPEC_MASSES = {
    "pelvis": 10.0, "torso": 12.0, "head": 3.88, "right_thigh": 4.5, "left_thigh": 4.5, "right_shin": 3.0,
    "left_shin": 3.0, "right_upper_arm": 1.5, "left_upper_arm": 1.5, "right_lower_arm": 1.0,
    "left_lower_arm": 1.0, "right_hand": 0.5, "left_hand": 0.5, "right_foot": 1.0, "left_foot": 1.0,
}
# stiffness / damping: config A ("soft") and config B ("stiff")
SPEC_GAINS = {
    "soft": {"abdomen": (600, 60), "neck": (50, 5), "shoulder": (200, 20), "elbow": (150, 15),
             "hip": (300, 30), "knee": (300, 30), "ankle": (200, 20)},
    "stiff": {"abdomen": (1000, 100), "neck": (100, 10), "shoulder": (400, 40), "elbow": (300, 30),
              "hip": (500, 50), "knee": (500, 50), "ankle": (400, 40)},
}


def _spec_dofs():
    """(dof name, joint, axis, (lo, hi) degrees) in qpos order."""
    out = []
    for joint in JOINT_ORDER:
        ranges = SPEC_RANGES_DEG[joint]
        if len(ranges) == 3:
            out += [(f"{joint}_{a}", joint, a, r) for a, r in zip("xyz", ranges)]
        else:
            out.append((joint, joint, "y", ranges[0]))
    return out


SPEC_DOFS = _spec_dofs()


def _kind(joint: str) -> str:
    return joint.split("_", 1)[1] if joint.startswith(("right_", "left_")) else joint


@pytest.fixture(scope="module")
def model():
    return load_humanoid_spec("soft").compile()


# --- structure -------------------------------------------------------------------------------------
def test_constants_match_spec():
    assert list(BODY_NAMES) == SPEC_BODIES
    assert list(PARENT_INDICES) == SPEC_PARENTS
    assert NUM_DOFS == 28
    assert list(DOF_NAMES) == [d[0] for d in SPEC_DOFS]


def test_bodies_and_parents(model):
    # world, then the 15 bodies in the specification's order
    assert model.nbody == 16
    names = [model.body(i).name for i in range(1, 16)]
    assert names == SPEC_BODIES
    parents = []
    for i in range(1, 16):
        p = int(model.body_parentid[i])
        parents.append(-1 if p == 0 else SPEC_BODIES.index(model.body(p).name))
    assert parents == SPEC_PARENTS


def test_free_root_and_28_hinges(model):
    assert model.njnt == 29
    assert model.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE
    assert model.joint(0).name == "root"
    assert model.jnt_bodyid[0] == model.body("pelvis").id
    assert model.nq == 7 + 28 and model.nv == 6 + 28 and model.nu == 28
    for j in range(1, 29):
        assert model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE
    # joints in qpos order, on the right bodies, about the right axes
    axes = {"x": [1, 0, 0], "y": [0, 1, 0], "z": [0, 0, 1]}
    for k, (name, joint, axis, _) in enumerate(SPEC_DOFS):
        j = model.joint(name).id
        assert j == k + 1
        assert model.jnt_qposadr[j] == 7 + k
        assert model.body(model.jnt_bodyid[j]).name == JOINT_BODY[joint]
        np.testing.assert_allclose(model.jnt_axis[j], axes[axis])
    # hands have no joint
    for hand in ("right_hand", "left_hand"):
        assert model.body_jntnum[model.body(hand).id] == 0
    # actuators drive the DoFs in the same order
    for k, (name, _, _, _) in enumerate(SPEC_DOFS):
        assert model.actuator(k).name == name
        assert model.actuator_trnid[k, 0] == model.joint(name).id


def test_joint_ranges_match_spec(model):
    for name, _, _, (lo, hi) in SPEC_DOFS:
        j = model.joint(name).id
        assert model.jnt_limited[j]
        np.testing.assert_allclose(np.degrees(model.jnt_range[j]), [lo, hi], atol=1e-9, err_msg=name)
    expected = np.radians([r for *_, r in SPEC_DOFS])
    np.testing.assert_allclose(dof_ranges(model), expected, atol=1e-12)


def test_masses(model):
    for name, mass in SPEC_MASSES.items():
        assert model.body_mass[model.body(name).id] == pytest.approx(mass, rel=1e-9), name
    assert model.body_mass.sum() == pytest.approx(48.88, abs=1e-6)
    assert sum(SPEC_MASSES.values()) == pytest.approx(48.88)


def test_segment_offsets(model):
    np.testing.assert_allclose(model.body_pos[model.body("torso").id], [0, 0, 0.236], atol=1e-12)
    for side in ("right", "left"):
        knee_offset = model.body_pos[model.body(f"{side}_shin").id]
        assert np.linalg.norm(knee_offset) == pytest.approx(0.422, abs=1e-9)
        shin = np.linalg.norm(model.body_pos[model.body(f"{side}_foot").id])
        assert shin == pytest.approx(0.422, abs=0.02)  # "about the same"


def test_standing_height_and_sole(model):
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    pelvis = model.body("pelvis").id
    assert data.xpos[pelvis][2] == pytest.approx(STANDING_ROOT_HEIGHT, abs=1e-9)
    # head top ~ 1.6 m
    head = model.geom("head").id
    assert model.geom_type[head] == mujoco.mjtGeom.mjGEOM_SPHERE
    head_top = data.geom_xpos[head][2] + model.geom_size[head][0]
    assert head_top == pytest.approx(1.6, abs=0.03)
    # the highest point of the whole body is the head top
    tops = []
    for g in range(model.ngeom):
        if model.geom_bodyid[g] == 0:
            continue
        tops.append(data.geom_xpos[g][2] + model.geom_rbound[g])
    assert max(tops) == pytest.approx(head_top, abs=0.02)
    for side in ("right", "left"):
        foot_body = model.body(f"{side}_foot").id
        foot = model.geom(f"{side}_foot").id
        assert model.geom_type[foot] == mujoco.mjtGeom.mjGEOM_BOX
        sole = data.geom_xpos[foot][2] - model.geom_size[foot][2]
        assert sole - data.xpos[foot_body][2] == pytest.approx(-0.05, abs=0.005)
        # standing at the standing root height, the soles are on (just above) the floor
        assert 0.0 <= sole < 0.01


def test_stands_on_floor_without_penetration(model):
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    floor = model.geom("floor").id
    for c in data.contact[: data.ncon]:
        assert floor not in (c.geom1, c.geom2) or c.dist > -1e-3


# --- gains and the action map ---------------------------------------------------------------------
@pytest.mark.parametrize("preset", ["soft", "stiff"])
def test_pd_gains(preset):
    m = load_humanoid_spec(preset).compile()
    for k, (name, joint, _, _) in enumerate(SPEC_DOFS):
        kp, kv = SPEC_GAINS[preset][_kind(joint)]
        assert PD_GAINS[preset][_kind(joint)] == (kp, kv)
        a = m.actuator(name).id
        assert m.actuator_gaintype[a] == mujoco.mjtGain.mjGAIN_FIXED
        assert m.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_AFFINE
        np.testing.assert_allclose(m.actuator_gainprm[a, :3], [kp, 0, 0], err_msg=name)
        np.testing.assert_allclose(m.actuator_biasprm[a, :3], [0, -kp, -kv], err_msg=name)


def test_pd_servo_force(model):
    """force = kp (target - q) - kv qdot for a joint away from its limits (hinge, no gear)."""
    m = load_humanoid_spec("stiff").compile()
    d = mujoco.MjData(m)
    a = m.actuator("right_knee").id
    j = m.joint("right_knee").id
    d.qpos[m.jnt_qposadr[j]] = 0.5
    d.qvel[m.jnt_dofadr[j]] = 0.2
    d.ctrl[a] = 0.6
    mujoco.mj_forward(m, d)
    assert d.actuator_force[a] == pytest.approx(500 * (0.6 - 0.5) - 50 * 0.2, rel=1e-9)


def test_unknown_preset():
    with pytest.raises(ValueError) as err:
        load_humanoid_spec("wobbly")
    msg = str(err.value)
    assert "pd_gains" in msg and "soft" in msg and "stiff" in msg and "wobbly" in msg


def _spec_offset_scale():
    offset, scale = [], []
    for joint in JOINT_ORDER:
        ranges = np.radians(SPEC_RANGES_DEG[joint])
        if len(ranges) == 3:
            s = min(1.2 * np.abs(ranges).max(), math.pi)
            offset += [0.0] * 3
            scale += [s] * 3
        else:
            lo, hi = ranges[0]
            mid, half = (lo + hi) / 2, (hi - lo) / 2
            offset.append(mid)
            scale.append(1.4 * half)
    return np.array(offset), np.array(scale)


def test_pd_action_offset_scale_matches_spec():
    offset, scale = pd_action_offset_scale(np.radians([r for *_, r in SPEC_DOFS]))
    e_offset, e_scale = _spec_offset_scale()
    np.testing.assert_allclose(offset, e_offset, atol=1e-12)
    np.testing.assert_allclose(scale, e_scale, rtol=1e-12)
    deg = {name: (math.degrees(o - s), math.degrees(o + s)) for (name, *_), o, s in zip(SPEC_DOFS, offset, scale)}
    # written-out examples
    for knee in ("right_knee", "left_knee"):
        assert deg[knee] == pytest.approx((-32.0, 192.0))
    for elbow in ("right_elbow", "left_elbow"):
        assert deg[elbow] == pytest.approx((-192.0, 32.0))
    assert deg["abdomen_y"] == pytest.approx((-108.0, 108.0))   # 1.2 * 90
    assert deg["neck_x"] == pytest.approx((-72.0, 72.0))        # 1.2 * 60
    assert deg["right_shoulder_z"] == pytest.approx((-180.0, 180.0))  # 1.2 * 180 capped at pi
    assert deg["left_hip_x"] == pytest.approx((-168.0, 168.0))  # 1.2 * 140
    assert deg["right_ankle_z"] == pytest.approx((-66.0, 66.0))  # 1.2 * 55


@pytest.mark.parametrize("preset", ["soft", "stiff"])
def test_compiled_ctrlrange_is_offset_pm_scale(preset):
    m = load_humanoid_spec(preset).compile()
    e_offset, e_scale = _spec_offset_scale()
    assert np.all(m.actuator_ctrllimited == 1)
    np.testing.assert_allclose(m.actuator_ctrlrange[:, 0], e_offset - e_scale, atol=1e-9)
    np.testing.assert_allclose(m.actuator_ctrlrange[:, 1], e_offset + e_scale, atol=1e-9)


def test_env_maps_action_to_pd_targets():
    env = gym.make("InterLevel-v0")
    env.reset(seed=0)
    e_offset, e_scale = _spec_offset_scale()
    action = np.random.default_rng(1).uniform(-1, 1, 28)
    action[0], action[1] = -1.0, 1.0
    env.step(action)
    np.testing.assert_allclose(env.unwrapped.data.ctrl, e_offset + e_scale * action, atol=1e-9)
    env.close()


# --- joint conventions ---------------------------------------------------------------------------
@pytest.mark.parametrize(
    "joint, parent, child",
    [("abdomen", "pelvis", "torso"), ("neck", "torso", "head"), ("right_hip", "pelvis", "right_thigh"),
     ("left_ankle", "left_shin", "left_foot"), ("left_shoulder", "torso", "left_upper_arm")],
)
def test_three_axis_joints_are_intrinsic_xyz(model, joint, parent, child):
    data = mujoco.MjData(model)
    rng = np.random.default_rng(4)
    for _ in range(5):
        angles = rng.uniform(-0.5, 0.5, 3)
        data.qpos[:] = model.qpos0
        root_rot = Rotation.random(random_state=rng)
        x, y, z, w = root_rot.as_quat()
        data.qpos[3:7] = [w, x, y, z]
        for a, v in zip("xyz", angles):
            data.qpos[model.jnt_qposadr[model.joint(f"{joint}_{a}").id]] = v
        mujoco.mj_kinematics(model, data)
        P = data.xmat[model.body(parent).id].reshape(3, 3)
        C = data.xmat[model.body(child).id].reshape(3, 3)
        expected = Rotation.from_euler("XYZ", angles).as_matrix()
        np.testing.assert_allclose(P.T @ C, expected, atol=1e-12)
        # and not extrinsic (the two differ for these angles)
        assert not np.allclose(Rotation.from_euler("xyz", angles).as_matrix(), expected, atol=1e-3)


def test_knee_bends_backwards_and_elbow_forwards(model):
    """Positive knee angle swings the foot backwards (-x); negative elbow swings the hand forwards (+x)."""
    data = mujoco.MjData(model)
    data.qpos[:] = model.qpos0
    data.qpos[model.jnt_qposadr[model.joint("right_knee").id]] = math.radians(90)
    data.qpos[model.jnt_qposadr[model.joint("right_elbow").id]] = math.radians(-90)
    mujoco.mj_kinematics(model, data)
    shin = data.xpos[model.body("right_shin").id]
    foot = data.xpos[model.body("right_foot").id]
    lower_arm = data.xpos[model.body("right_lower_arm").id]
    hand = data.xpos[model.body("right_hand").id]
    assert foot[0] - shin[0] == pytest.approx(-0.409, abs=1e-6)
    assert hand[0] - lower_arm[0] == pytest.approx(0.258, abs=1e-6)


# --- stability soak --------------------------------------------------------------------------------
BAD_WARNINGS = (mujoco.mjtWarning.mjWARN_BADQACC, mujoco.mjtWarning.mjWARN_BADQVEL, mujoco.mjtWarning.mjWARN_BADQPOS)


@pytest.mark.slow
@pytest.mark.parametrize("preset", ["soft", "stiff"])
def test_random_action_soak(preset):
    m = load_humanoid_spec(preset).compile()
    d = mujoco.MjData(m)
    offset, scale = _spec_offset_scale()
    rng = np.random.default_rng(12345)
    counts = dict.fromkeys(BAD_WARNINGS, 0)
    steps, reset_every, frame_skip = 20_000, 500, 4

    def harvest():
        # mj_resetData clears the warning counters: collect them before every reset
        for w in BAD_WARNINGS:
            counts[w] += int(d.warning[w].number)

    mujoco.mj_resetData(m, d)
    actions = rng.uniform(-1.0, 1.0, (steps, NUM_DOFS))
    max_speed = 0.0
    for i in range(steps):
        if i and i % reset_every == 0:
            harvest()
            mujoco.mj_resetData(m, d)
        d.ctrl[:] = offset + scale * actions[i]
        mujoco.mj_step(m, d, frame_skip)
        if i % 50 == 0:
            assert np.isfinite(d.qpos).all() and np.isfinite(d.qvel).all(), f"step {i}"
            max_speed = max(max_speed, float(np.abs(d.qvel).max()))
    harvest()
    assert np.isfinite(d.qpos).all() and np.isfinite(d.qvel).all()
    assert counts == dict.fromkeys(BAD_WARNINGS, 0), counts
    # the simulation really moved (a frozen sim would pass the checks above)
    assert max_speed > 1.0
    assert d.time > 0.0
