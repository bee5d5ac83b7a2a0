"""SIMS skill envs: rewards against the supplement's equations by hand, contact goals,
success thresholds, scene heights, the five presets (check_env, determinism), set_task."""

from __future__ import annotations

import dataclasses
import math

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import stairenv  # noqa: F401
from stairenv.environments.sims import SIMSEnv
from stairenv.humanoid import STANDING_ROOT_HEIGHT, HumanoidIndices
from stairenv.tasks import sims as task
from stairenv.world.furniture import PlacedFurniture, make_furniture
from stairenv.world.rooms import RoomConfig, generate_room

SKILL_IDS = ["SIMS-Walk-v0", "SIMS-Sit-v0", "SIMS-Lie-v0", "SIMS-Reach-v0", "SIMS-GetUp-v0"]
FAST = {"text_encoder": "hashing"}


def indices(env) -> HumanoidIndices:
    """The humanoid's ids in the env's model (public: the env keeps the same in a private field)."""
    return HumanoidIndices.from_model(env.model)


# --- rewards by hand -------------------------------------------------------------------------
def test_walk_reward_far_branch_by_hand():
    # target 2 m ahead on x, moving 1 m/s along x, facing 60 deg off the target direction
    target, root = np.array([2.0, 0.0]), np.array([0.0, 0.0])
    vel, facing = np.array([1.0, 0.5]), np.array([math.cos(math.pi / 3), math.sin(math.pi / 3)])
    terms = task.walk_reward_terms(target, root, vel, np.zeros(2), facing, target_speed=1.5)
    dist2 = 4.0
    far = 0.6 * math.exp(-0.5 * dist2) + 0.2 * math.exp(-2.0 * (1.5 - 1.0) ** 2) + 0.2 * 0.5 ** 2
    near = math.exp(-10 * dist2)
    np.testing.assert_allclose(terms, [0.4 * near, 0.5 * far, 0.0], rtol=1e-12)


def test_walk_reward_near_branch_by_hand():
    # |x* - x|^2 = 0.3^2 + 0.4^2 = 0.25 <= 0.5: far replaced by its maximum, still counts
    terms = task.walk_reward_terms(np.array([1.3, 2.4]), np.array([1.0, 2.0]), np.array([0.2, 0.1]),
                                   np.array([0.5, -0.3]), np.array([1.0, 0.0]), 1.0)
    still = math.exp(-2.0 * (0.3 ** 2 + 0.4 ** 2))
    np.testing.assert_allclose(terms, [0.4 * math.exp(-10 * 0.25), 0.5, 0.1 * still], rtol=1e-12)
    assert terms.sum() <= 1.0


def test_walk_facing_term_is_clamped_backwards():
    away = task.walk_reward_terms(np.array([3.0, 0.0]), np.zeros(2), np.zeros(2), np.zeros(2), np.array([-1.0, 0.0]), 1.0)
    towards = task.walk_reward_terms(np.array([3.0, 0.0]), np.zeros(2), np.zeros(2), np.zeros(2), np.array([1.0, 0.0]), 1.0)
    assert towards[1] - away[1] == pytest.approx(0.5 * 0.2)


def test_contact_reward_by_hand():
    joints = np.zeros((15, 3))
    joints[0] = (0.0, 0.0, 0.9)
    joints[5] = (0.3, -0.2, 1.0)
    goals = joints.copy()
    goals[0] = (0.1, 0.0, 0.5)          # pelvis 0.41 m off
    goals[5] = (0.3, -0.2, 1.2)         # right hand 0.2 m off
    mask = np.zeros(15, dtype=bool)
    mask[[0, 5]] = True
    # far branch: x* 1.5 m away on y
    terms = task.contact_reward_terms(np.array([0.0, 1.5]), joints[0], np.array([0.0, 0.8]), np.array([0.0, 1.0]),
                                      1.0, goals, joints, mask)
    near = math.exp(-10.0 * ((0.1 ** 2 + 0.4 ** 2) + 0.2 ** 2))
    far = 0.5 * math.exp(-0.5 * 2.25) + 0.4 * math.exp(-2.0 * 0.2 ** 2) + 0.1 * 1.0
    np.testing.assert_allclose(terms, [0.6 * near, 0.4 * far], rtol=1e-12)
    # near branch (|x* - x|^2 = 0.49): far term at its maximum 0.4
    terms = task.contact_reward_terms(np.array([0.7, 0.0]), joints[0], np.zeros(2), np.array([1.0, 0.0]),
                                      1.0, goals, joints, mask)
    np.testing.assert_allclose(terms, [0.6 * near, 0.4], rtol=1e-12)
    # masked-out bodies do not count
    far_hand = goals.copy()
    far_hand[9] += 5.0
    same = task.contact_reward_terms(np.array([0.7, 0.0]), joints[0], np.zeros(2), np.array([1.0, 0.0]),
                                     1.0, far_hand, joints, mask)
    np.testing.assert_allclose(same, terms)


# --- contact goals ---------------------------------------------------------------------------
def chair(yaw: float = 0.4) -> PlacedFurniture:
    return PlacedFurniture("chair_0", make_furniture("armchair", np.random.default_rng(2)), (1.0, -0.5, yaw))


def test_goal_targets_are_nearest_points_of_the_part():
    placed = chair()
    goal = task.contact_goal("sit", placed, np.random.default_rng(0))
    assert goal.part == "seat" and goal.furniture == "chair_0"
    mask = goal.mask
    assert mask[task.JOINT["pelvis"]] and mask[task.JOINT["torso"]]
    assert mask[task.JOINT["left_hand"]] and mask[task.JOINT["right_hand"]]  # armrests
    joints = np.tile(np.array([5.0, 5.0, 1.0]), (15, 1))
    targets = goal.targets(joints)
    pelvis_pts = goal.points[0]
    d = np.linalg.norm(pelvis_pts - joints[0], axis=1)
    np.testing.assert_allclose(targets[0], pelvis_pts[np.argmin(d)])
    np.testing.assert_allclose(targets[~mask], joints[~mask])  # unmasked: themselves
    # pelvis targets lie above the seat's top surface by the pelvis clearance
    seat = placed.contact_surface("seat")
    np.testing.assert_allclose((pelvis_pts - seat.center) @ seat.normal, task.CONTACT_CLEARANCE["pelvis"], atol=1e-9)
    # left hand goes to the armrest on the character's left when seated facing the front
    left = goal.points[task.JOINT["left_hand"]].mean(axis=0)
    right = goal.points[task.JOINT["right_hand"]].mean(axis=0)
    front = placed.rotation[:, 0]
    assert np.cross(front, left - right)[2] > 0


def test_success_thresholds():
    assert task.SUCCESS_DISTANCE["sit"] == 0.2 and task.SUCCESS_DISTANCE["reach"] == 0.2
    assert task.SUCCESS_DISTANCE["lie"] == 0.3
    placed = chair()
    goal = task.contact_goal("sit", placed, np.random.default_rng(0))
    joints = np.zeros((15, 3))
    seat_point = goal.points[0][0]
    for offset, expected in ((0.19, True), (0.21, False)):
        joints[0] = seat_point + np.array([0.0, 0.0, offset])
        assert (goal.contact_error(joints) < task.SUCCESS_DISTANCE["sit"]) is expected


def test_reach_and_getup_goals():
    rng = np.random.default_rng(4)
    table = PlacedFurniture("table_0", make_furniture("table", rng), (0.0, 0.0, 0.0))
    goal = task.contact_goal("reach", table, rng, hand="left")
    assert goal.primary == task.JOINT["left_hand"] and goal.mask.sum() == 1
    top = table.contact_surface("table_top")
    assert (goal.points[goal.primary][0] - top.center) @ top.normal == pytest.approx(task.CONTACT_CLEARANCE["left_hand"])
    getup = task.contact_goal("getup", chair(0.0), rng)
    assert getup.root_target[2] == pytest.approx(STANDING_ROOT_HEIGHT)
    assert getup.root_target[0] > chair(0.0).furniture.bounds[1][0] + 1.0 - 1e-9  # in front of the chair
    with pytest.raises(ValueError, match="cannot lie on a table"):
        task.contact_goal("lie", table, rng)
    with pytest.raises(ValueError, match="hand must be"):
        task.contact_goal("reach", table, rng, hand="middle")
    with pytest.raises(ValueError, match="table has no part 'shelf'"):
        task.contact_goal("reach", table, rng, part="shelf")
    assert task.resolve_part("cabinet", "table_top", "reach") == "top"
    assert task.resolve_part("cabinet", "shelf", "reach") == "door"  # scripts reach for a cabinet's shelf
    # reach targets stay within a standing character's reach even on tall parts
    lamp = PlacedFurniture("lamp_0", make_furniture("lamp", rng), (0.0, 0.0, 0.0))
    heights = [task.contact_goal("reach", lamp, rng, part="switch").root_target[2] for _ in range(50)]
    assert task.REACH_HEIGHT[0] <= min(heights) and max(heights) <= task.REACH_HEIGHT[1] + 0.05
    # standing points work for pieces with several parts of the label (two armrests, four shelves)
    for family in ("sofa", "bookshelf", "wardrobe", "armchair"):
        piece = PlacedFurniture("p", make_furniture(family, rng), (0.0, 0.0, 0.0))
        point = task.standing_point(piece, task.resolve_part(family, None, "reach"))
        assert point[0] > piece.furniture.bounds[1][0]


# --- scene heights ---------------------------------------------------------------------------
def test_convex_top_heights_of_a_box():
    # unit cube [0,1]^3 as planes n.p <= d
    planes = np.array([[1, 0, 0, 1], [-1, 0, 0, 0], [0, 1, 0, 1], [0, -1, 0, 0], [0, 0, 1, 1], [0, 0, -1, 0]], float)
    z = task.convex_top_heights(planes, np.array([[0.5, 0.5], [1.5, 0.5], [0.0, 1.0]]))
    assert z[0] == pytest.approx(1.0) and z[1] == -np.inf and z[2] == pytest.approx(1.0)


def test_scene_heights_match_furniture_tops():
    placed = chair(0.0)
    heights = task.SceneHeights.build([placed], cell_size=0.02)
    seat = placed.contact_surface("seat")
    assert heights.sample(seat.center[None, :2])[0] == pytest.approx(seat.center[2], abs=1e-6)
    assert heights.sample(np.array([[10.0, 10.0]]))[0] == 0.0
    assert heights.heights.max() == pytest.approx(placed.furniture.height, abs=1e-6)


# --- the env ---------------------------------------------------------------------------------
@pytest.mark.parametrize("env_id", SKILL_IDS)
def test_check_env_and_determinism(env_id):
    env = gym.make(env_id, **FAST)
    check_env(env.unwrapped, skip_render_check=True)
    runs = []
    for _ in range(2):
        obs, _ = env.reset(seed=5)
        trace = [obs]
        rng = np.random.default_rng(0)
        for _ in range(25):
            obs, reward, terminated, truncated, info = env.step(rng.uniform(-1, 1, 28))
            assert reward == pytest.approx(sum(v for k, v in info.items() if k.startswith("reward_")))
            trace.append(np.r_[obs, reward])
            if terminated or truncated:
                trace.append(env.reset()[0])
        runs.append(np.concatenate(trace))
    np.testing.assert_array_equal(runs[0], runs[1])



def test_step_outcomes_of_mixed_skills_equal_each_world_alone():
    """A batch of worlds with walk and contact goals (as a screenplay sets them) against each world's
    ``_step_outcome`` on its own state: the same bits."""
    from stairenv.humanoid.state import stack_states

    envs = [gym.make(env_id, **FAST).unwrapped for env_id in ("SIMS-Sit-v0", "SIMS-Walk-v0", "SIMS-Reach-v0")]
    rng = np.random.default_rng(0)
    for seed, env in enumerate(envs):
        env.reset(seed=seed)
    for _ in range(8):
        for env in envs:
            env.step(rng.uniform(-0.5, 0.5, 28))
        carried = [(env._prev_root_vel, env._success_once) for env in envs]   # what an outcome updates
        alone = [env._step_outcome(env._read_state()) for env in envs]
        for env, (prev_root_vel, success_once) in zip(envs, carried):
            env._prev_root_vel, env._success_once = prev_root_vel, success_once
        batch = SIMSEnv._step_outcomes(envs, stack_states([env._read_state() for env in envs]))
        for one, row in zip(alone, batch):
            assert one.obs.tobytes() == row.obs.tobytes()
            assert (one.reward, one.terms, one.terminated, one.results) == (row.reward, row.terms, row.terminated,
                                                                           row.results)

def _reference_step(env, state):
    """One world's step outcome by ``stairenv.tasks.sims``' batch functions (numpy, its BLAS): the observation,
    the goal's targets, the weighted reward terms (near, far, still: 0 for a contact goal) and the error."""
    goal = env.goal
    frames = task.root_frames(state)
    targets = task.goal_targets([goal], state.body_pos)
    obs = task.skill_observations(state, frames, [goal], targets, [env._heights], env.heightmap_size,
                                  env.heightmap_extent, [env._z])
    terms = task.skill_reward_values(state, frames, [goal], targets, np.array([env._prev_root_vel]),
                                     [env._target_speed], env._near_squared_distance)[0]
    error = task.skill_errors([goal], targets, state.body_pos)[0]
    return obs[0], targets[0], (*terms, 0.0)[:3], error


def test_compiled_step_equals_the_batch_functions():
    """``task.skill_step`` (what ``SIMSEnv`` runs each step) against the batch functions it replaced on the
    states the envs visit, the character also put next to its goal's root target (the near branches, walk's
    still term) and on a masked-out goal body: the same numbers within 1e-12. (The kernel writes numpy's BLAS
    calls out as this machine's OpenBLAS kernels round them, ``task.skill_step``'s section, so here they agree
    bit for bit, which ``benchmarks/trajectory_hashes.py`` checks; another CPU's BLAS rounds in its own low
    bits, so the test allows them.)"""
    rng = np.random.default_rng(0)
    for env_id in SKILL_IDS:
        env = gym.make(env_id, fall_height=0.0, **FAST).unwrapped
        env.reset(seed=1)
        idx = indices(env)
        for step in range(40):
            env.step(rng.uniform(-1.0, 1.0, 28))
            if step % 10 == 9:    # next to the root target, moving
                env.data.qpos[idx.qpos_root.start:idx.qpos_root.start + 2] = (
                    env.goal.root_target[:2] + rng.uniform(-0.5, 0.5, 2))
                env.data.qvel[:3] = rng.uniform(-1.0, 1.0, 3)
                env.data.qpos[idx.qpos_root.start + 3:idx.qpos_root.start + 7] = (
                    rng.normal(size=4) / np.linalg.norm(rng.normal(size=4)))
                mujoco.mj_forward(env.model, env.data)
            state = env._read_state()
            obs, targets, terms, error = _reference_step(env, state)
            out = (np.empty((1, len(obs))), np.empty((1, task.NUM_CONTACT_JOINTS, 3)),
                   np.empty((1, task.STEP_VALUES_SIZE)))
            goal = env.goal
            task.skill_step(0, state.body_pos, state.body_mat, state.root_lin_vel, state.root_ang_vel, state.dof_vel,
                            env._step_parameters, goal._flat, goal._owner, env._heights.heights, env._z,
                            env._prev_root_vel, *out)
            np.testing.assert_allclose(out[0][0], obs, rtol=1e-12, atol=1e-12, err_msg=env_id)
            np.testing.assert_allclose(out[1][0], targets, rtol=1e-12, atol=1e-12, err_msg=env_id)
            np.testing.assert_allclose(out[2][0, :4], [*terms, error], rtol=1e-12, atol=1e-12, err_msg=env_id)
        # many more roots and velocities about the target (the near and still branches)
        _compare_about_target(env, rng, 1000, 2.0, env_id)


def _compare_about_target(env, rng, roots: int, spread: float, env_id: str) -> None:
    """The compiled step's reward terms and error against the batch functions' on ``roots`` roots within
    ``spread`` (m) of the goal's root target on the ground, with random root velocities (1e-12)."""
    goal, base = env.goal, env._read_state()
    for _ in range(roots):
        state = type(base)(*(np.array(field) for field in base))
        state.body_pos[0, :, :2] += goal.root_target[:2] - state.body_pos[0, 0, :2] + rng.uniform(-spread, spread, 2)
        state.root_lin_vel[0] = rng.normal(0.0, 1.5, 3)
        env._prev_root_vel = rng.normal(0.0, 1.5, 2)
        obs, targets, terms, error = _reference_step(env, state)
        values = np.empty((1, task.STEP_VALUES_SIZE))
        task.skill_step(0, state.body_pos, state.body_mat, state.root_lin_vel, state.root_ang_vel, state.dof_vel,
                        env._step_parameters, goal._flat, goal._owner, env._heights.heights, env._z,
                        env._prev_root_vel, np.empty((1, len(obs))), np.empty((1, task.NUM_CONTACT_JOINTS, 3)),
                        values)
        np.testing.assert_allclose(values[0, :4], [*terms, error], rtol=1e-12, atol=1e-12, err_msg=env_id)


def test_near_distance_moves_the_near_zone_of_the_kernel_and_of_its_specification():
    """``near_distance`` (a training aid): the far term is at its maximum (and the walk's still term acts) only
    within d of x* on the ground. The compiled step and the batch functions agree on roots about the target,
    and 0.4 m from it the walk's far term is the paper's Eq. 7 written out by hand with d = 0.2 m, 1 with the
    paper's 0.71 m."""
    rng = np.random.default_rng(5)
    for env_id in ("SIMS-Walk-v0", "SIMS-Sit-v0"):
        env = gym.make(env_id, fall_height=0.0, near_distance=0.2, **FAST).unwrapped
        env.reset(seed=4)
        assert env._near_squared_distance == pytest.approx(0.04)
        _compare_about_target(env, rng, 300, 0.8, env_id)
    # by hand: the walk reward 0.4 m due east of x*, facing it, moving towards it at 0.5 m/s, v* = 1
    target, root, vel, facing = np.array([0.4, 0.0]), np.zeros(2), np.array([0.5, 0.0]), np.array([1.0, 0.0])
    d2 = 0.16
    far = 0.6 * math.exp(-0.5 * d2) + 0.2 * math.exp(-2.0 * (1.0 - 0.5) ** 2) + 0.2 * 1.0 ** 2
    narrow = dataclasses.replace(task.WALK_WEIGHTS, near_squared_distance=0.04)
    near, far_w, still = task.walk_reward_terms(target, root, vel, vel, facing, 1.0, narrow)
    assert far_w == pytest.approx(0.5 * far) and still == 0.0 and near == pytest.approx(0.4 * math.exp(-10 * d2))
    near, far_w, still = task.walk_reward_terms(target, root, vel, vel, facing, 1.0)
    assert far_w == pytest.approx(0.5) and still == pytest.approx(0.1)
    with pytest.raises(ValueError, match="near_distance"):
        gym.make("SIMS-Walk-v0", near_distance=0.0)


def test_a_steps_outcome_and_info_are_world_outcome_and_full_info():
    """``SIMSEnv._finish_step`` writes ``_world_outcome`` and ``_full_info`` out where no training aid adds to
    them: a step's outcome and info against those two on the step's own kernel results, the info's keys in the
    same order; with an aid the step calls them."""
    rng = np.random.default_rng(3)
    for env_id, aids in (("SIMS-Walk-v0", {}), ("SIMS-Sit-v0", {}), ("SIMS-Sit-v0", {"min_root_height": 0.3})):
        env = gym.make(env_id, fall_height=0.0, **FAST, **aids).unwrapped
        assert env._plain_outcomes == (not aids)
        env.reset(seed=2)
        for _ in range(15):
            obs, reward, terminated, truncated, info = env.step(rng.uniform(-0.5, 0.5, 28))
            outcome = env._outcome
            buffers = env._step_buffers
            near, far, still, error, _, _, x, y, z, head_z = buffers[2].tolist()
            again = env._world_outcome(buffers[0], buffers[1], near, far, still, error, x, y, z, head_z)
            assert again.obs.tobytes() == outcome.obs.tobytes() == obs.tobytes()
            assert (again.reward, again.terms, again.terminated, again.results) == (
                reward, outcome.terms, terminated, outcome.results)
            full = env._full_info(again, unstable=False, terms=True, amp_obs=info["amp_obs"])
            assert list(full) == list(info), env_id
            for key, value in full.items():
                if isinstance(value, np.ndarray):
                    assert value.dtype == info[key].dtype and value.tobytes() == info[key].tobytes(), key
                else:
                    assert type(value) is type(info[key]) and value == info[key], key


def test_observation_layout_and_text():
    env = SIMSEnv(skill="sit", families=("chair",), **FAST)
    obs, info = env.reset(seed=3)
    s = env.observation_structure
    assert obs.shape == (113 + 256 + 60 + 64,)
    mask = obs[s["goal_mask"]]
    np.testing.assert_array_equal(mask, env.goal.mask.astype(float))
    goal = obs[s["goal_positions"]].reshape(15, 3)
    assert np.all(goal[mask == 0] == 0)
    # the pelvis goal offset has the length of target minus root
    root = env.data.xpos[indices(env).pelvis_id]
    targets = env.goal.targets(env.data.xpos[indices(env).body_ids])
    assert np.linalg.norm(goal[0]) == pytest.approx(np.linalg.norm(targets[0] - root))
    z = obs[s["text"]]
    assert np.linalg.norm(z) == pytest.approx(1.0, abs=1e-5)
    np.testing.assert_array_equal(info["amp_condition"], z.astype(np.float32))
    off = SIMSEnv(skill="reach", text_conditioned=False, **FAST)
    assert np.all(off.reset(seed=0)[0][off.observation_structure["text"]] == 0)


def test_target_speed_follows_the_captions_style():
    sad = SIMSEnv(skill="walk", captions=[("sad", "walks slowly with the head bowed")], **FAST)
    hurried = SIMSEnv(skill="walk", captions=[("hurried", "hurries over, leaning forward")], **FAST)
    neutral = SIMSEnv(skill="walk", captions=[("neutral", "walks over")], target_speed=(0.9, 1.0), **FAST)
    fixed = SIMSEnv(skill="walk", captions=[("sad", "walks slowly")], speed_from_style=False,
                    target_speed=(1.4, 1.5), **FAST)
    for seed in range(5):
        sad.reset(seed=seed), hurried.reset(seed=seed), neutral.reset(seed=seed), fixed.reset(seed=seed)
        assert 0.48 <= sad._target_speed <= 0.72          # 0.6 m/s +- 20%
        assert 1.2 <= hurried._target_speed <= 1.8        # 1.5 m/s +- 20%
        assert 0.9 <= neutral._target_speed <= 1.0
        assert 1.4 <= fixed._target_speed <= 1.5
    assert sad.speed_range("tired") == pytest.approx((0.44, 0.66))


def test_heightmap_sees_the_furniture():
    env = SIMSEnv(skill="sit", families=("bed",), start_distance=(1.4, 1.6), **FAST)
    obs, _ = env.reset(seed=0)
    hm = obs[env.observation_structure["heightmap"]]
    root_z = env.data.xpos[indices(env).pelvis_id][2]
    assert hm.min() == pytest.approx(-root_z)          # floor somewhere
    assert hm.max() > -root_z + 0.3                   # the bed within 1 m


def test_getup_starts_on_the_furniture_and_holding_still_keeps_it_there():
    env = SIMSEnv(skill="getup", families=("chair",), getup_from="sit", **FAST)
    _obs, info = env.reset(seed=2)
    seat = env.furniture["chair"].contact_surface("seat")
    pelvis = env.data.xpos[indices(env).pelvis_id].copy()
    assert 0.05 < pelvis[2] - seat.center[2] < 0.2
    hold = (env.data.qpos[indices(env).qpos_joints] - env._ctrl_offset) / env._ctrl_scale
    for _ in range(60):
        _obs, _reward, terminated, _truncated, info = env.step(hold)
    assert not terminated and not info["success"]
    assert np.linalg.norm(env.data.xpos[indices(env).pelvis_id] - pelvis) < 0.1


def test_success_flag_when_the_pelvis_is_on_the_seat():
    env = SIMSEnv(skill="sit", families=("stool",), **FAST)
    env.reset(seed=1)
    env.place_on(env.furniture["stool"], "sit")
    _obs, info = env.set_task("sit", "stool")
    assert info["success"] and info["contact_error"] < 0.2
    hold = (env.data.qpos[indices(env).qpos_joints] - env._ctrl_offset) / env._ctrl_scale
    _obs, _reward, _terminated, _truncated, info = env.step(hold)
    assert info["success"] and info["success_once"]
    assert info["reward_near"] > 0.6 * math.exp(-10 * 0.2 ** 2)


def test_room_goals_stand_on_free_floor_and_the_heightmap_sees_the_walls():
    """In a room: a get-up goal is on free floor (in front of a chair at a table it used to lie inside the
    table), the arrays the env hands out are the caller's own, and the heightmap holds the walls (which stand
    outside the interior: a character facing a wall used to see flat floor)."""
    from stairenv.environments.sims_config import host_families

    env = SIMSEnv(skill="sit", scene="room", scene_resample_every=1, **FAST)
    at_table = moved = 0
    for seed in range(8):
        env.reset(seed=seed)
        free = env.room.free_space()
        for name, placed in env.furniture.items():
            if placed.family not in host_families("getup"):
                continue
            env.set_task("getup", name)
            target = env.goal.root_target
            assert free.label_at(target[None, :2])[0] > 0, (seed, name)
            assert not np.shares_memory(target, env.goal.points[task.JOINT["pelvis"]])
            plain = task.standing_point(placed, task.resolve_part(placed.family, None, "getup"))
            at_table += free.label_at(plain[None, :2])[0] == 0
            moved += not np.allclose(plain[:2], target[:2])
        point = env.approach_point(placed)
        point += 100.0
        assert not np.array_equal(env.approach_point(placed), point)
    assert at_table > 0 and moved == at_table    # only the points off free floor move
    x0, y0, x1, y1 = env.room.bounds
    mid = (0.5 * (x0 + x1), 0.5 * (y0 + y1))
    walls = np.array([[x0 - 0.05, mid[1]], [x1 + 0.05, mid[1]], [mid[0], y0 - 0.05], [mid[0], y1 + 0.05]])
    assert (env._heights.sample(walls) >= 2.0).all()


def test_a_sofa_sit_asks_for_no_hands_on_armrests_out_of_reach():
    """Both hands go to the armrests of an armchair; a sofa's are 1.4-2.2 m apart, where seated in its middle
    each hand would be 0.6-0.8 m from its armrest and the near term ~0 whatever the character did: its sit goal
    is the pelvis on the seat and the torso at the backrest."""
    rng = np.random.default_rng(0)
    for family, hands in (("armchair", True), ("sofa", False)):
        placed = PlacedFurniture(family, make_furniture(family, rng), (0.0, 0.0, 0.3))
        goal = task.contact_goal("sit", placed, rng)
        names = {name for name, k in task.JOINT.items() if goal.mask[k]}
        assert ({"left_hand", "right_hand"} <= names) == hands and {"pelvis", "torso"} <= names, (family, names)


def test_room_scene_and_set_task():
    room = generate_room(RoomConfig(), np.random.default_rng(0), categories=["chair", "table", "bed"])
    env = SIMSEnv(skill="walk", room=room, **FAST)
    _obs, info = env.reset(seed=0)
    assert set(env.furniture) == {f.name for f in room.furniture}
    _obs, info = env.set_task("sit", "chair_0", caption="sits down tiredly", style="tired")
    assert info["skill"] == "sit" and info["furniture"] == "chair_0" and info["caption"] == "sits down tiredly"
    _obs, info = env.set_task("walk", "bed_0")
    assert room.free_space().label_at(env.goal.root_target[None, :2])[0] > 0
    with pytest.raises(KeyError, match="no furniture named 'sofa_9'"):
        env.set_task("sit", "sofa_9")


@pytest.mark.parametrize("kwargs, match", [
    ({"skill": "fly"}, "skill must be one of"),
    ({"scene": "house"}, "scene must be one of"),
    ({"families": ("throne",)}, "families must be one of"),
    ({"start_distance": (3.0, 1.0)}, "start_distance"),
    ({"getup_from": "floor"}, "getup_from must be one of"),
    ({"scene_resample_every": 0}, "scene_resample_every"),
])
def test_bad_keywords_name_the_parameter(kwargs, match):
    with pytest.raises(ValueError, match=match):
        SIMSEnv(**FAST, **kwargs)


def test_nan_action_raises():
    env = SIMSEnv(skill="reach", **FAST)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="finite"):
        env.step(np.full(28, np.nan))


def test_compiled_heightmap_matches_the_reference_points():
    from stairenv.tasks.plamo import heightmap_points

    heights = task.SceneHeights.build([chair(0.3)], cell_size=0.05)
    root = np.array([1.3, -0.2, 0.9])
    expected = heights.sample(heightmap_points(root[:2], 0.7, 12, 2.5)) - root[2]
    np.testing.assert_allclose(heights.egocentric(root, 0.7, 12, 2.5), expected)


def test_captions_fit_the_furniture():
    from stairenv.environments.sims import captions_for, skill_captions

    sofa = captions_for(skill_captions("sit"), "sofa")
    assert sofa and all("stool" not in text and "chair" not in text for _, text in sofa)
    assert any("sofa" in text for _, text in sofa)
    walks = captions_for(skill_captions("walk"), None)
    assert walks and not any(" bed" in text for _, text in walks)
    beds = captions_for(skill_captions("lie"), "bed")
    assert all("sofa" not in text for _, text in beds)


def test_seated_start_rests_on_the_seat_even_at_a_table():
    for seed in (0, 3, 7):  # rooms whose two chairs stand at the table (their shins touch its legs)
        room = generate_room(RoomConfig(), np.random.default_rng(seed), categories=["table", "chair", "chair"])
        env = SIMSEnv(skill="getup", room=room, **FAST)
        env.reset(seed=0)
        for name in ("chair_0", "chair_1"):
            assert np.linalg.norm(env.furniture[name].position - env.furniture["table_0"].position) < 0.9
            env.place_on(env.furniture[name], "sit")
            _obs, info = env.set_task("sit", name)
            assert info["contact_error"] < task.SUCCESS_DISTANCE["sit"], (seed, name)
        assert env.skill == "getup"  # set_task leaves the episode skill alone


@pytest.mark.parametrize("env_id", [i for i in stairenv.ENV_IDS if i.startswith("SIMS-")])
def test_unknown_caption_styles_are_refused_at_construction(env_id):
    with pytest.raises(ValueError, match=r"captions: unknown style\(s\) \['bogus_style'\]"):
        gym.make(env_id, captions=(("bogus_style", "hello"),), **FAST)
    with pytest.raises(ValueError, match="Happy"):  # styles are exact names
        gym.make(env_id, captions=[("sad", "walks"), ("Happy", "hello")], **FAST)
