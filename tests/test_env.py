"""InterLevel env: API conformance, determinism, observation layout, episode logic, bad input."""

from __future__ import annotations

import math

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from scipy.spatial.transform import Rotation

import stairenv
from stairenv.environments.interlevel import InterLevelEnv
from stairenv.humanoid import DOF_NAMES, STANDING_ROOT_HEIGHT
from stairenv.tasks import interlevel as task
from stairenv.humanoid.state import read_state
from stairenv.world.stairs import Staircase

ENV_IDS = ["InterLevel-v0", "InterLevel2D-v0", "InterSceneStairs-v0"]


def test_registered_ids():
    assert set(ENV_IDS) <= set(stairenv.ENV_IDS)
    env = gym.make("InterLevel-v0")
    assert env.spec.max_episode_steps == 600
    assert env.observation_space.shape == (118,)
    assert env.action_space.shape == (28,)
    assert env.unwrapped.dt == pytest.approx(1 / 30)
    assert env.unwrapped.model.opt.timestep == pytest.approx(1 / 240)  # 8 substeps per action


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_check_env(env_id):
    env = gym.make(env_id)
    check_env(env.unwrapped, skip_render_check=True)


def test_presets_are_kwargs_of_one_class():
    envs = {i: gym.make(i).unwrapped for i in ENV_IDS}
    assert all(type(e) is InterLevelEnv for e in envs.values())
    assert envs["InterLevel-v0"].reward_config.progress_scaling is True
    assert envs["InterLevel2D-v0"].reward_config.progress_scaling is False
    assert envs["InterSceneStairs-v0"].reward_name == "interscene"


def rollout(env_id: str, seed: int, steps: int = 120, **kwargs):
    env = gym.make(env_id, **kwargs)
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(123)
    trace = [obs]
    rewards = []
    for _ in range(steps):
        obs, reward, terminated, truncated, _ = env.step(rng.uniform(-1, 1, 28))
        trace.append(obs)
        rewards.append(reward)
        if terminated or truncated:
            obs, _ = env.reset()
            trace.append(obs)
    return np.array(trace), np.array(rewards)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_same_seed_same_trajectory(env_id):
    obs_a, rew_a = rollout(env_id, seed=7)
    obs_b, rew_b = rollout(env_id, seed=7)
    np.testing.assert_array_equal(obs_a, obs_b)
    np.testing.assert_array_equal(rew_a, rew_b)
    obs_c, _ = rollout(env_id, seed=8, steps=1)
    assert not np.array_equal(obs_a[0], obs_c[0])


def test_new_stairs_every_reset_from_seed():
    env = gym.make("InterLevel-v0")
    env.reset(seed=0)
    first = [env.unwrapped.stairs]
    for _ in range(4):
        env.reset()
        first.append(env.unwrapped.stairs)
    assert len({s.yaw for s in first}) == 5
    env.reset(seed=0)
    again = [env.unwrapped.stairs] + [env.reset()[1] and env.unwrapped.stairs for _ in range(4)]
    assert again == first


def test_observation_structure_covers_118():
    env = gym.make("InterLevel-v0").unwrapped
    slices = list(env.observation_structure.values())
    assert slices[0].start == 0 and slices[-1].stop == 118
    for a, b in zip(slices, slices[1:]):
        assert a.stop == b.start
    sizes = {k: s.stop - s.start for k, s in env.observation_structure.items()}
    assert sizes == {
        "root_height": 1, "root_rotation": 6, "root_linear_velocity": 3, "root_angular_velocity": 3,
        "joint_rotations": 72, "joint_velocities": 28, "target_offset": 3, "marker_distance": 1,
        "stairs_angle": 1,
    }


def _obs_part(env, obs, name):
    return obs[env.observation_structure[name]]


def test_observation_values_against_mujoco():
    env = gym.make("InterLevel-v0").unwrapped
    obs, _ = env.reset(seed=3)
    for _ in range(5):
        obs, *_ = env.step(np.full(28, 0.2))
    data, stairs = env.data, env.stairs
    pelvis = env.model.body("pelvis").id
    assert _obs_part(env, obs, "root_height")[0] == pytest.approx(data.xpos[pelvis, 2])
    offset = _obs_part(env, obs, "target_offset")
    assert np.linalg.norm(offset) == pytest.approx(np.linalg.norm(stairs.marker_top - data.xpos[pelvis]))
    assert offset[2] == pytest.approx(stairs.marker_top[2] - data.xpos[pelvis, 2])
    assert _obs_part(env, obs, "marker_distance")[0] == pytest.approx(
        np.linalg.norm(stairs.marker_top - stairs.marker_bottom))
    np.testing.assert_allclose(_obs_part(env, obs, "joint_velocities"), data.qvel[6:34])
    # Heading frame: horizontal speed is preserved, vertical velocity unchanged.
    lin = _obs_part(env, obs, "root_linear_velocity")
    assert np.linalg.norm(lin[:2]) == pytest.approx(np.linalg.norm(data.qvel[:2]))
    assert lin[2] == pytest.approx(data.qvel[2])
    # Stairs angle: root heading minus ascent direction, wrapped.
    root_mat = data.xmat[pelvis].reshape(3, 3)
    heading = math.atan2(root_mat[1, 0], root_mat[0, 0])
    expected = (heading - stairs.yaw + math.pi) % (2 * math.pi) - math.pi
    assert _obs_part(env, obs, "stairs_angle")[0] == pytest.approx(expected)


def test_joint_rotations_are_local_xyz_euler():
    env = gym.make("InterLevel-v0").unwrapped
    env.reset(seed=1)
    angles = np.array([0.3, -0.5, 0.2])  # right hip x, y, z
    hip_x = DOF_NAMES.index("right_hip_x")
    env.data.qpos[7 + hip_x: 7 + hip_x + 3] = angles
    env.data.qpos[7 + DOF_NAMES.index("right_knee")] = 0.7
    mujoco.mj_forward(env.model, env.data)
    obs = task.interlevel_observation(read_state(env.data, env._idx), env._goal)[0]
    rot6 = _obs_part(env, obs, "joint_rotations").reshape(12, 6)
    hip = Rotation.from_euler("XYZ", angles).as_matrix()
    np.testing.assert_allclose(rot6[6], np.concatenate((hip[:, 0], hip[:, 1])), atol=1e-9)
    knee = Rotation.from_euler("Y", 0.7).as_matrix()
    np.testing.assert_allclose(rot6[7], np.concatenate((knee[:, 0], knee[:, 1])), atol=1e-9)


def test_observation_invariant_to_rotating_the_whole_scene():
    """Character and stairs turned together about the arena centre: the same observation."""
    env = gym.make("InterLevel-v0").unwrapped
    env.reset(seed=5)
    for _ in range(8):
        env.step(np.full(28, 0.1))
    stairs, data = env.stairs, env.data
    qpos, qvel = data.qpos.copy(), data.qvel.copy()
    obs_a = task.interlevel_observation(read_state(data, env._idx), env._goal)[0]

    turn = 1.1
    rotated = Staircase(**{**stairs.as_dict(), "yaw": stairs.yaw + turn})
    env.reset(seed=5, options={"stairs": rotated})
    rot = Rotation.from_euler("z", turn)
    data.qpos[:] = qpos
    data.qpos[:3] = rot.apply(qpos[:3])
    w, x, y, z = qpos[3:7]
    xr, yr, zr, wr = (rot * Rotation.from_quat([x, y, z, w])).as_quat()
    data.qpos[3:7] = [wr, xr, yr, zr]
    data.qvel[:] = qvel
    data.qvel[:3] = rot.apply(qvel[:3])  # world linear velocity; angular velocity is in the body frame
    mujoco.mj_forward(env.model, data)
    obs_b = task.interlevel_observation(read_state(data, env._idx), env._goal)[0]
    np.testing.assert_allclose(obs_a, obs_b, atol=1e-9)


def _stand_at(env, position, yaw=0.0):
    """Put the character upright at ``position`` (root), servos holding the default pose."""
    data = env.data
    data.qpos[:3] = position
    data.qpos[3:7] = [math.cos(yaw / 2), 0, 0, math.sin(yaw / 2)]
    data.qpos[7:] = 0.0
    data.qvel[:] = 0.0
    data.ctrl[:] = np.clip(0.0, *env.model.actuator_ctrlrange.T)
    mujoco.mj_forward(env.model, data)
    env._prev_root = data.xpos[env.model.body("pelvis").id][None].copy()


def _hold_action(env):
    """The action whose PD targets are the zero pose (clipped into range)."""
    return np.clip(-env._ctrl_offset / env._ctrl_scale, -1, 1)


def test_termination_on_fallen_pose():
    env = gym.make("InterLevel-v0", failure_reward=-2.5)
    env.reset(seed=0)
    u = env.unwrapped
    data = u.data
    # Lying on the floor: body horizontal, root 0.15 m up.
    data.qpos[:3] = [0.0, 0.0, 0.15]
    data.qpos[3:7] = Rotation.from_euler("y", 90, degrees=True).as_quat(scalar_first=True)
    data.qvel[:] = 0
    mujoco.mj_forward(u.model, data)
    _, reward, terminated, truncated, info = env.step(_hold_action(u))
    assert terminated and not truncated
    assert info["fell"] and not info["success"]
    assert reward == pytest.approx(-2.5)
    assert info["reward_failure"] == -2.5
    assert info["reward_location"] == info["reward_facing"] == info["reward_velocity"] == 0.0


def test_standing_does_not_terminate():
    env = gym.make("InterLevel-v0")
    env.reset(seed=0)
    u = env.unwrapped
    _stand_at(u, [0.0, 0.0, STANDING_ROOT_HEIGHT + 0.005])
    _, _, terminated, _, info = env.step(_hold_action(u))
    assert not terminated and not info["fell"]


def test_success_on_the_top_floor_at_mt():
    env = gym.make("InterLevel-v0", success_reward=7.0)
    env.reset(seed=2)
    u = env.unwrapped
    stairs = u.stairs
    target = stairs.marker_top
    _stand_at(u, [target[0], target[1], stairs.top_height + STANDING_ROOT_HEIGHT + 0.005], yaw=stairs.yaw)
    _, reward, terminated, _, info = env.step(_hold_action(u))
    assert info["success"] and terminated and not info["fell"]
    assert info["progress"] == pytest.approx(1.0, abs=0.02)
    assert info["reward_success"] == 7.0
    parts = sum(v for k, v in info.items() if k.startswith("reward_"))
    assert reward == pytest.approx(parts)
    # Location term at its peak region: TG and across-Gaussian near their maxima, progress ~1.
    peak = 3.0 / (2 * math.pi * 2.0 * 0.5)
    assert info["reward_location"] == pytest.approx(peak, rel=0.05)


def test_success_needs_the_top_floor():
    """Right under M_T but on the ground (e.g. a floating target above a short landing): no success."""
    env = gym.make("InterLevel-v0")
    env.reset(seed=2)
    u = env.unwrapped
    target = u.stairs.marker_top
    _stand_at(u, [target[0], target[1], 0.3])  # inside the landing block: not standing on top
    assert not task.reached_top(u.data.xpos[[1]], u._goal.target, u._goal.top_height, 0.5)[0]


def test_no_termination_on_success_when_disabled():
    env = gym.make("InterLevel-v0", terminate_on_success=False)
    env.reset(seed=2)
    u = env.unwrapped
    stairs = u.stairs
    target = stairs.marker_top
    _stand_at(u, [target[0], target[1], stairs.top_height + STANDING_ROOT_HEIGHT + 0.005], yaw=stairs.yaw)
    _, _, terminated, _, info = env.step(_hold_action(u))
    assert info["success"] and not terminated


def test_info_fields_and_time_limit():
    env = gym.make("InterLevel-v0", termination_height=0.0, max_episode_steps=20)
    _, info = env.reset(seed=0)
    for key in ("progress", "success", "fell", "time", "distance_to_target", "physics_unstable", "stairs"):
        assert key in info
    assert set(info["stairs"]) >= {"step_height", "step_depth", "width", "num_steps", "yaw"}
    for t in range(1, 21):
        _, _, terminated, truncated, info = env.step(np.zeros(28))
        assert info["time"] == pytest.approx(t / 30)
        assert 0.0 <= info["progress"] <= 1.0
    assert truncated and not terminated


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"step_height": (-0.1, 0.2)}, "step_height"),
        ({"step_height": (0.2, 0.1)}, "step_height"),
        ({"step_depth": (0.0, 0.3)}, "step_depth"),
        ({"num_steps": (0, 5)}, "num_steps"),
        ({"num_steps": (3.5, 5)}, "num_steps"),
        ({"step_height_set": ()}, "step_height_set"),
        ({"reward": "interplanet"}, "reward"),
        ({"pd_gains": "medium"}, "pd_gains"),
        ({"sigma_before": 0.0}, "sigma_before"),
        ({"w_location": -1.0}, "w_location"),
        ({"target_speed": float("nan")}, "target_speed"),
        ({"termination_height": 2.0}, "termination_height"),
        ({"frame_skip": 0}, "frame_skip"),
        ({"render_mode": "ascii"}, "render_mode"),
        ({"stairs_distance": (0.5, 3.0)}, "stairs_distance"),
        ({"success_radius": 0.0}, "success_radius"),
    ],
)
def test_bad_keywords_name_the_parameter(kwargs, name):
    with pytest.raises(ValueError, match=name):
        InterLevelEnv(**kwargs)


@pytest.mark.parametrize(
    "action, message",
    [
        (np.zeros(27), "shape"),
        (np.zeros((2, 28)), "shape"),
        (np.full(28, np.nan), "finite"),
        (np.r_[np.zeros(27), np.inf], "finite"),
        (np.r_[np.zeros(27), 0.5j], "real numbers, got dtype complex128"),      # not its real part
        (np.zeros(28, dtype=complex), "real numbers, got dtype complex128"),
        (np.zeros(28).astype(str), "real numbers, got dtype <U"),
        ([0.0] * 27 + ["0.1"], "real numbers, got dtype <U"),
        (np.zeros(28, dtype=object), "real numbers, got dtype object"),
        (np.zeros(28, dtype=np.float32)[::2], "shape"),                     # the fast path checks shape too
    ],
)
def test_bad_actions_raise(action, message):
    env = gym.make("InterLevel-v0").unwrapped
    env.reset(seed=0)
    with pytest.raises(ValueError, match=message):
        env.step(action)


def test_real_actions_of_any_dtype_step_alike():
    """float32, float64 (also a list) and integer actions give the same step as their float64 values."""
    results = []
    for action in (np.full(28, 0.5, dtype=np.float32), np.full(28, 0.5), [0.5] * 28):
        env = gym.make("InterLevel-v0").unwrapped
        env.reset(seed=0)
        results.append(env.step(action)[0])
    for other in results[1:]:
        np.testing.assert_array_equal(results[0], other)
    env = gym.make("InterLevel-v0").unwrapped
    env.reset(seed=0)
    integer_obs = env.step(np.ones(28, dtype=np.int64))[0]
    env.reset(seed=0)
    np.testing.assert_array_equal(integer_obs, env.step(np.ones(28))[0])


def test_a_deep_copy_steps_its_own_data_alike():
    """The views a step reads and writes (ctrl, qvel, the state) belong to the copy's own MjData."""
    import copy
    env = gym.make("InterLevel-v0").unwrapped
    env.reset(seed=0)
    env.step(np.zeros(28))
    twin = copy.deepcopy(env)
    for action in (np.full(28, 0.7), np.full(28, -0.4)):
        obs, reward, *_ = env.step(action)
        twin_obs, twin_reward, *_ = twin.step(action)
        np.testing.assert_array_equal(obs, twin_obs)
        assert reward == twin_reward
    np.testing.assert_array_equal(twin.data.ctrl, env.data.ctrl)
    assert twin.data.ctrl.ctypes.data != env.data.ctrl.ctypes.data


def test_step_before_reset_raises():
    env = InterLevelEnv()
    with pytest.raises(gym.error.ResetNeeded):
        env.step(np.zeros(28))
    with pytest.raises(ValueError, match="finite"):    # a bad action is named first, before a reset too
        env.step(np.full(28, np.nan))


def test_a_refused_action_writes_no_ctrl():
    """A step's one-call path for float actions (checked and applied together) writes nothing for a NaN."""
    env = gym.make("InterLevel-v0").unwrapped
    env.reset(seed=0)
    ctrl = env.data.ctrl.copy()
    for dtype in (np.float64, np.float32):
        with pytest.raises(ValueError, match="finite"):
            env.step(np.r_[np.full(27, 0.5), np.nan].astype(dtype))
        np.testing.assert_array_equal(env.data.ctrl, ctrl)


def test_out_of_range_actions_act_as_the_range_limits():
    """Actions beyond [-1, 1] give the same PD targets as the limits (MuJoCo clamps ctrl)."""
    results = []
    for value in (5.0, 1.0):
        env = gym.make("InterLevel-v0").unwrapped
        env.reset(seed=0)
        obs, *_ = env.step(np.r_[np.full(14, value), np.full(14, -value)])
        results.append(obs)
    np.testing.assert_array_equal(results[0], results[1])


def test_physics_blow_up_truncates_with_flag():
    env = gym.make("InterLevel-v0")
    obs0, _ = env.reset(seed=0)
    u = env.unwrapped
    obs1, *_ = env.step(np.zeros(28))
    u.data.qvel[:] = 1e12  # diverged state: MuJoCo's checks reset the data
    with pytest.warns(UserWarning, match="unstable"):
        obs, reward, terminated, truncated, info = env.step(np.zeros(28))
    assert truncated and not terminated
    assert info["physics_unstable"] is True
    assert np.isfinite(obs).all()
    np.testing.assert_array_equal(obs, obs1)
    assert reward == 0.0
    with pytest.raises(gym.error.ResetNeeded):
        u.step(np.zeros(28))
    obs, _ = env.reset()
    assert np.isfinite(obs).all()


@pytest.mark.slow
def test_random_action_soak_20k_steps():
    env = gym.make("InterLevel-v0")
    obs, _ = env.reset(seed=11)
    rng = np.random.default_rng(11)
    unstable = 0
    for _ in range(20_000):
        obs, reward, terminated, truncated, info = env.step(rng.uniform(-1, 1, 28))
        assert np.isfinite(obs).all() and math.isfinite(reward)
        unstable += info["physics_unstable"]
        if terminated or truncated:
            obs, _ = env.reset()
    assert unstable == 0
    warnings = env.unwrapped.data.warning
    assert warnings[mujoco.mjtWarning.mjWARN_BADQACC].number == 0


def test_rgb_array_render():
    env = gym.make("InterLevel-v0", render_mode="rgb_array", width=160, height=120)
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (120, 160, 3) and frame.dtype == np.uint8
    assert frame.std() > 5  # not a blank image
    env.close()


def test_fused_step_kernel_matches_the_separate_functions():
    """The env's one-call kernel gives what the separately tested functions give."""
    env = gym.make("InterLevel-v0").unwrapped
    env.reset(seed=9)
    prev = None
    for _ in range(6):
        prev = env.data.xpos[env.model.body("pelvis").id][None].copy()
        env.step(np.full(28, 0.15))
    state = read_state(env.data, env._idx)
    goal = env._goal
    packed = goal.pack()
    assert packed.shape == (1, task.GOAL_SIZE)
    obs, res = task.interlevel_outcome_columns(state, prev, packed, goal.rotation, env.reward_config.as_array(),
                                               env.dt, 0.2, 0.5)
    np.testing.assert_allclose(obs, task.interlevel_observation(state, goal), atol=0)
    np.testing.assert_allclose(res[:, :3], task.interlevel_reward_terms(state, prev, goal, env.reward_config, env.dt))
    root = state.body_pos[:, 0]
    assert res[0, 3] == task.has_fallen(state.body_pos, 0.2)[0]
    assert res[0, 4] == task.reached_top(root, goal.target, goal.top_height, 0.5)[0]
    assert res[0, 5] == task.surface_progress(root, goal.origin, goal.rotation, goal.step_depth, goal.num_steps,
                                              goal.landing_end, goal.half_width)[0]
    assert res[0, 6] == task.progress(root, goal.bottom, goal.target)[0]
    assert res[0, 7] == pytest.approx(np.linalg.norm(goal.target[0] - root[0]))


def test_progress_counts_treads_not_hops():
    env = gym.make("InterLevel-v0").unwrapped
    env.reset(seed=2)
    stairs = env.stairs
    goal = env._goal

    def progress_at(u, height):
        p = stairs.to_world(np.array([u, 0.0, 0.0]))
        p[2] = height
        return task.surface_progress(p[None], goal.origin, goal.rotation, goal.step_depth, goal.num_steps,
                                     goal.landing_end, goal.half_width)[0]

    assert progress_at(-0.5, 1.5) == 0.0  # a hop in front of the stairs counts nothing
    assert progress_at(0.5 * stairs.step_depth, 1.0) == pytest.approx(1 / stairs.num_steps)
    assert progress_at(1.5 * stairs.step_depth, 1.0) == pytest.approx(2 / stairs.num_steps)
    assert progress_at(stairs.landing_start + 0.5, 2.0) == 1.0
    assert progress_at(stairs.landing_start + stairs.landing_depth + 0.1, 2.0) == 0.0


def test_physics_blow_up_on_the_first_step_is_caught():
    """At t = 0 MuJoCo's reset leaves the clock where a normal step would: the warnings tell."""
    env = gym.make("InterLevel-v0")
    env.reset(seed=0)
    env.unwrapped.data.qvel[:] = 1e12
    with pytest.warns(UserWarning, match="unstable"):
        obs, _, terminated, truncated, info = env.step(np.zeros(28))
    assert truncated and not terminated and info["physics_unstable"] and np.isfinite(obs).all()
    env.reset(seed=1)  # a new episode starts clean
    _, _, _, truncated, info = env.step(np.zeros(28))
    assert not info["physics_unstable"]


def test_yaw_quaternion_is_scipys_bit_for_bit():
    from stairenv.rotations import yaw_to_quat_wxyz
    for yaw in np.concatenate([np.random.default_rng(0).uniform(-7, 7, 500), [0.0, -0.0, math.pi, -math.pi]]):
        x, y, z, w = Rotation.from_euler("z", yaw).as_quat()
        assert np.array_equal(yaw_to_quat_wxyz(yaw), [w, x, y, z])


def test_one_yaw_rotation_equals_the_forms_it_replaced_bit_for_bit():
    """``yaw_matrix`` and ``yaw_to_quat_wxyz`` replaced the yaw rotations written out in the furniture
    parts and poses, the scene, room and furniture bodies, and the SIMS heading frame: same floats."""
    from stairenv.rotations import yaw_matrix, yaw_to_quat_wxyz
    angles = np.concatenate([np.random.default_rng(1).uniform(-7, 7, 2000), [0.0, -0.0, math.pi, -math.pi, 1e-300]])
    rel = np.random.default_rng(2).normal(size=(15, 3))
    for yaw in [*angles, *angles.tolist()]:  # numpy and Python floats
        c, s = math.cos(yaw), math.sin(yaw)
        written = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        assert yaw_matrix(yaw).tobytes() == written.tobytes()
        assert (rel @ yaw_matrix(yaw)).tobytes() == (rel @ written).tobytes()
        quat = np.array([math.cos(0.5 * yaw), 0.0, 0.0, math.sin(0.5 * yaw)])
        assert yaw_to_quat_wxyz(yaw).tobytes() == quat.tobytes()


def test_old_names_of_the_step_outcome_still_work_with_a_deprecation_warning():
    from stairenv.environments import base
    with pytest.warns(DeprecationWarning, match="StepOutcome"):
        assert base.Evaluation is base.StepOutcome
    with pytest.warns(DeprecationWarning, match="StepOutcome"):
        from stairenv.environments.base import Evaluation  # noqa: F401
    with pytest.warns(DeprecationWarning, match="interlevel_outcome"):
        assert task.interlevel_evaluate is task.interlevel_outcome
    with pytest.warns(DeprecationWarning, match="interlevel_outcome_columns"):
        assert task.interlevel_evaluate_columns is task.interlevel_outcome_columns
    with pytest.raises(AttributeError):
        base.NoSuchName  # noqa: B018


def test_staircase_frame_is_cached_read_only_and_fresh_after_replace():
    import dataclasses
    stairs = Staircase(step_height=0.1, step_depth=0.3, width=1.5, num_steps=5, landing_depth=2.0, yaw=0.7,
                       distance=3.0)
    np.testing.assert_array_equal(stairs.axis, [math.cos(0.7), math.sin(0.7), 0.0])
    np.testing.assert_array_equal(stairs.origin, 3.0 * stairs.axis)
    assert stairs.rotation is stairs.rotation                       # computed once
    with pytest.raises(ValueError):
        stairs.origin[0] = 1.0                                      # a shared cache cannot be changed
    turned = dataclasses.replace(stairs, yaw=-0.2)
    np.testing.assert_array_equal(turned.axis, [math.cos(-0.2), math.sin(-0.2), 0.0])
    assert turned == dataclasses.replace(stairs, yaw=-0.2) and turned.as_dict()["yaw"] == -0.2
    assert stairs.as_dict() == dataclasses.asdict(stairs)


def test_a_step_that_is_both_success_and_fall_is_a_success():
    """At M_T bent over (head at the hips): the step kernel finds both; the end is a success with its bonus
    and the task terms, not also a fall's failure reward (it used to pay both, +9, and the evaluation counted
    the episode as a success and an early termination)."""
    params = task.end_parameters(0.2, None, 1 / 30, 10.0, -1.0, True)
    columns = {name: k for k, name in enumerate(task.STEP_RESULTS)}
    results = np.zeros((3, len(task.STEP_RESULTS)))
    results[0, columns["fell"]] = results[0, columns["success"]] = 1.0    # both
    results[1, columns["fell"]] = 1.0                                      # a fall alone
    results[2, columns["success"]] = 1.0                                   # a success alone
    terms = np.full((3, task.NUM_REWARD_TERMS), 0.25)
    reward, out_terms, flags = task.interlevel_reward_and_end(terms, results, np.ones(3, dtype=np.int64),
                                                               np.zeros(3), np.zeros(3), params)
    ended = {name: k for k, name in enumerate(task.END_FLAGS)}
    assert flags[:, ended["fell"]].tolist() == [False, True, False]
    assert flags[:, ended["success"]].tolist() == [True, False, True] and flags[:, ended["ended"]].all()
    expected_success = 0.25 * task.NUM_REWARD_TERMS + 10.0
    assert reward.tolist() == pytest.approx([expected_success, -1.0, expected_success])


@pytest.mark.parametrize("field, value", [("step_height", 0.0), ("step_depth", 0.0), ("width", -1.0),
                                          ("num_steps", 3.7), ("num_steps", 0), ("landing_depth", 0.0),
                                          ("distance", -1.0), ("yaw", math.nan), ("step_height", math.inf)])
def test_a_given_staircase_outside_a_drawn_ones_ranges_is_refused_naming_the_field(field, value):
    """``options={"stairs": ...}`` is checked as a drawn staircase is (a zero height used to stop the reset with
    a ZeroDivisionError in the progress, a negative width build inverted boxes); a staircase at the origin
    (distance 0, a clip's) is taken."""
    good = dict(step_height=0.15, step_depth=0.3, width=1.5, num_steps=4, landing_depth=2.0, yaw=0.0, distance=2.5)
    env = InterLevelEnv()
    with pytest.raises(ValueError, match=rf"options\['stairs'\]\.{field} must be"):
        env.reset(seed=0, options={"stairs": Staircase(**{**good, field: value})})
    env.reset(seed=0, options={"stairs": Staircase(**{**good, "distance": 0.0})})
    env.close()
