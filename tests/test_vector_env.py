"""The natively batched env (``stairenv.environments.vector``) and its SB3 adapter (``stairenv.vec_sb3``).

Equivalence is tested exactly: a batched world's observations, rewards, flags and info are bit-identical
(``np.array_equal``, tolerance 0) to ``SyncVectorEnv`` over single envs with the same seeds.
"""

from __future__ import annotations

import math

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from stable_baselines3 import PPO

import stairenv  # noqa: F401
from stairenv.environments.batch_physics import SerialPhysics, ThreadPoolPhysics
from stairenv.environments.vector import HumanoidVectorEnv
from stairenv.humanoid import DOF_NAMES, STANDING_ROOT_HEIGHT
from stairenv.motion import MotionClip, MotionLibrary
from stairenv.registration import load_presets
from stairenv.style.discriminator import DiscriminatorConfig
from stairenv.style.reference import ReferenceWindows
from stairenv.style.wrappers import AMPStyleReward, AMPVecEnvWrapper
from stairenv.vec_sb3 import SB3BatchedVecEnv, make_sb3_vec_env

IDS = sorted(load_presets())
# the contract tests below also run on MuJoCo Warp (its CPU device here) where it is installed
_NO_WARP = pytest.mark.skipif(__import__("importlib").util.find_spec("mujoco_warp") is None,
                              reason="mujoco_warp not installed (.[gpu])")
WARP = pytest.param("warp", marks=_NO_WARP)
# Warp with the state kept on the device between resets (state_on_device=True)
WARP_DEVICE_STATE = pytest.param("warp-device-state", marks=_NO_WARP)


def physics_keywords(physics: str) -> dict:
    return {"physics": "warp", "state_on_device": True} if physics == "warp-device-state" else {"physics": physics}


def assert_same(a, b, where=""):
    """Exactly equal, recursively (dicts of arrays, object arrays of dicts / arrays / scalars)."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and a.keys() == b.keys(), (where, set(a) ^ set(b))
        for key in a:
            assert_same(a[key], b[key], f"{where}.{key}")
    elif isinstance(a, np.ndarray) and a.dtype == object:
        assert isinstance(b, np.ndarray) and a.shape == b.shape, where
        for x, y in zip(a, b):
            assert_same(x, y, where)
    elif isinstance(a, (list, tuple)):
        assert isinstance(b, (list, tuple)) and len(a) == len(b), where
        for k, (x, y) in enumerate(zip(a, b)):
            assert_same(x, y, f"{where}[{k}]")
    elif isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray) and a.dtype == b.dtype and np.array_equal(a, b), where
    else:
        assert a == b or (a != a and b != b), (where, a, b)


def batched(env_id, n, **kwargs):
    return gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)


@pytest.mark.parametrize("env_id", IDS)
def test_batched_equals_single_envs(env_id):
    """Every id: 2 worlds x 150 steps of saturating random actions, episodes of at most 40 steps (so
    several resets, autoresets and falls inside), against SyncVectorEnv of single envs; exact."""
    n, steps = 2, 150
    vec = batched(env_id, n, max_episode_steps=40)
    assert isinstance(vec, HumanoidVectorEnv) and vec.spec.id == env_id
    ref = gym.make_vec(env_id, num_envs=n, vectorization_mode="sync", max_episode_steps=40)
    assert_same(vec.reset(seed=7), ref.reset(seed=7), "reset")
    rng = np.random.default_rng(1)
    ends = 0
    for t in range(steps):
        action = rng.uniform(-1, 1, (n, 28)).astype(np.float32)
        got, want = vec.step(action), ref.step(action)
        assert_same(got, want, f"step {t}")
        ends += int(np.sum(got[2] | got[3]))
    assert ends >= n * 2
    vec.close()
    ref.close()


def test_every_id_registers_a_vector_entry_point():
    for env_id in IDS:
        assert gym.spec(env_id).vector_entry_point.startswith("stairenv.environments.vector:")


@pytest.mark.parametrize("physics", ["serial", ThreadPoolPhysics(3)])
def test_physics_backends_give_the_same_worlds(physics):
    """Each world keeps its own MjData (warm start included): the back-end changes nothing."""
    runs = []
    for backend in (SerialPhysics(), physics):
        vec = batched("InterLevel-v0", 5, physics=backend)
        vec.reset(seed=3)
        rng = np.random.default_rng(0)
        runs.append([vec.step(rng.uniform(-1, 1, (5, 28)))[:4] for _ in range(20)])
    assert_same(runs[0], runs[1])


@pytest.mark.parametrize("physics", ["mujoco", WARP, WARP_DEVICE_STATE])
def test_next_step_autoreset_semantics(physics):
    vec = batched("InterLevel-v0", 3, max_episode_steps=4, **physics_keywords(physics))
    assert vec.metadata["autoreset_mode"] == gym.vector.AutoresetMode.NEXT_STEP
    single = gym.make("InterLevel-v0")
    obs, info = vec.reset(seed=[10, 11, 12])
    np.testing.assert_array_equal(obs[1], single.reset(seed=11)[0])
    assert set(info["_time"]) == {True}
    zeros = np.zeros((3, 28))
    for _ in range(3):
        _, _, terminated, truncated, _ = vec.step(zeros)
        assert not (terminated | truncated).any()
    last_obs, _, terminated, truncated, info = vec.step(zeros)
    assert truncated.all() and not terminated.any()                 # the episode limit, all worlds
    # the next step resets every world: reset obs, reward 0, flags False, the reset's info
    obs, reward, terminated, truncated, info = vec.step(np.full((3, 28), np.float32(0.5)))
    assert not (terminated | truncated).any() and (reward == 0).all()
    assert (info["time"] == 0).all() and not np.array_equal(obs, last_obs)
    assert "reward_location" not in info                             # reset infos carry no reward terms
    # a world that ends alone resets alone
    on_device = getattr(vec.physics, "state_on_device", False)
    if on_device:
        vec.physics.sync_worlds([2])                                 # its MjData brought up to the device's
    vec.envs[2].data.qvel[:] = 1e3                                   # speeds no body reaches: unstable
    if on_device:
        vec.physics.world_changed(2)                                 # a write into a world's MjData, announced
    _, _, _, truncated, info = vec.step(zeros)
    assert truncated.tolist() == [False, False, True]
    _, reward, _, truncated, info = vec.step(zeros)
    assert reward[2] == 0 and info["time"].tolist() == pytest.approx([2 / 30, 2 / 30, 0.0])


def test_physics_blow_up_truncates_that_world_only():
    vec = batched("SIMS-Sit-v0", 3)
    vec.reset(seed=0)
    vec.step(np.zeros((3, 28)))
    before = [env.data.time for env in vec.envs]
    vec.envs[1].data.qvel[:] = 1e12                                   # MuJoCo's own divergence check fires
    with pytest.warns(UserWarning, match="physics became unstable"):
        obs, reward, terminated, truncated, info = vec.step(np.zeros((3, 28)))
    assert truncated.tolist() == [False, True, False] and not terminated.any()
    assert info["physics_unstable"].tolist() == [False, True, False] and info["_physics_unstable"].all()
    assert reward[1] == 0 and np.isfinite(obs).all()
    assert vec.envs[0].data.time > before[0] and vec.envs[2].data.time > before[2]


def test_bad_actions_are_refused_naming_the_world():
    vec = batched("InterLevel-v0", 4)
    with pytest.raises(gym.error.ResetNeeded):
        vec.step(np.zeros((4, 28)))
    vec.reset(seed=0)
    times = [env.data.time for env in vec.envs]
    with pytest.raises(ValueError, match=r"shape \(4, 28\).*\(3, 28\)"):
        vec.step(np.zeros((3, 28)))
    with pytest.raises(ValueError, match=r"shape"):
        vec.step(np.zeros(28))
    action = np.zeros((4, 28))
    action[2, 5] = np.nan
    action[3, 0] = np.inf
    with pytest.raises(ValueError, match=r"world\(s\) \[2, 3\].*2: \[5\], 3: \[0\]"):
        vec.step(action)
    assert [env.data.time for env in vec.envs] == times                # nothing was stepped
    vec.step(np.zeros((4, 28)))                                         # and the env goes on
    with pytest.raises(ValueError, match="num_envs"):
        batched("InterLevel-v0", 0)


def test_non_real_actions_are_refused_naming_the_world():
    """Complex, string and object actions are refused, not converted (float64 would drop an imaginary part)."""
    vec = batched("InterLevel-v0", 3)
    vec.reset(seed=0)
    times = [env.data.time for env in vec.envs]
    complex_actions = np.zeros((3, 28), dtype=complex)
    complex_actions[1, 4] = 0.5j
    with pytest.raises(ValueError, match=r"real numbers, got dtype complex128 in world\(s\) \[1\]"):
        vec.step(complex_actions)
    with pytest.raises(ValueError, match=r"complex128 in every world"):
        vec.step(np.zeros((3, 28), dtype=complex))
    strings = np.zeros((3, 28)).astype(str)
    with pytest.raises(ValueError, match=r"real numbers, got dtype <U"):
        vec.step(strings)
    objects = np.zeros((3, 28), dtype=object)
    objects[2, 0] = "0.1"
    with pytest.raises(ValueError, match=r"real numbers, got dtype object in world\(s\) \[2\]"):
        vec.step(objects)
    assert [env.data.time for env in vec.envs] == times                # nothing was stepped
    vec.step(np.zeros((3, 28), dtype=np.float32))                       # real dtypes are converted
    vec.step(np.zeros((3, 28), dtype=np.int64))


@pytest.mark.parametrize("physics", ["mujoco", WARP, WARP_DEVICE_STATE])
def test_reset_mask_resets_only_those_worlds(physics):
    vec = batched("InterLevel-v0", 3, **physics_keywords(physics))
    vec.reset(seed=0)
    obs, *_ = vec.step(np.zeros((3, 28)))
    new, info = vec.reset(options={"reset_mask": np.array([False, True, False])})
    np.testing.assert_array_equal(new[[0, 2]], obs[[0, 2]])
    assert info["_time"].tolist() == [False, True, False]


@pytest.mark.parametrize("kwargs", [{}, {"init": "hybrid", "step_height_levels": 4, "stairs_start_fraction": 0.5}])
def test_worlds_reset_together_equal_worlds_reset_one_by_one(kwargs):
    """``reset_worlds`` (an autoreset's resets, the draws per world and the rest over the group) gives what
    the same worlds reset in turn give: the staircases in the models, the state, observations and infos,
    and the episodes that follow."""
    n, group = 5, [0, 2, 3]
    together, one_by_one = batched("InterLevel-v0", n, **kwargs), batched("InterLevel-v0", n, **kwargs)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (12, n, 28))
    for vec in (together, one_by_one):
        vec.reset(seed=3)
        vec.step(actions[0])
    got = together.reset_worlds(group)
    want = [one_by_one.reset_world(i) for i in group]
    assert_same(got[0], np.array([obs for obs, _ in want]), "obs")
    assert_same(got[1], [info for _, info in want], "infos")
    for a, b in zip(together.envs, one_by_one.envs):
        for name in ("body_pos", "body_quat", "geom_size", "geom_rbound", "geom_aabb", "bvh_aabb"):
            assert np.array_equal(getattr(a.model, name), getattr(b.model, name)), name
        for name in ("qpos", "qvel", "ctrl", "xpos", "xmat"):
            assert np.array_equal(getattr(a.data, name), getattr(b.data, name)), name
    for t, action in enumerate(actions[1:]):
        assert_same(together.step(action), one_by_one.step(action), f"step {t}")
    obs, infos = together.reset_worlds([])
    assert obs.shape == (0, *together.single_observation_space.shape) and infos == []
    for worlds in ([1, 1], [5], [-1]):    # a world twice, out of range (a negative index would wrap)
        with pytest.raises(ValueError, match="distinct world indices in \\[0, 4\\]"):
            together.reset_worlds(worlds)
    with pytest.raises(ValueError, match="one seed and one options per world"):
        together.reset_worlds([0, 1], seeds=[3])
    together.close()
    one_by_one.close()


def test_sb3_vecenv_contract():
    venv = make_sb3_vec_env("InterLevel-v0", 3, seed=4, max_episode_steps=5)
    obs = venv.reset()
    assert obs.shape == (3, venv.observation_space.shape[0])
    np.testing.assert_array_equal(obs[2], gym.make("InterLevel-v0").reset(seed=6)[0])
    assert venv.get_attr("frame_skip") == [8, 8, 8] and len(venv.env_method("_reference_pose", None, indices=[0]))
    assert venv.env_is_wrapped(gym.Wrapper) == [False] * 3
    for t in range(5):
        obs, reward, dones, infos = venv.step(np.zeros((3, 28)))
        assert reward.dtype == np.float32 and len(infos) == 3 and "amp_obs" in infos[0]
    assert dones.all() and all(info["TimeLimit.truncated"] for info in infos)
    for info, o in zip(infos, obs):                                   # reset in the same step
        assert info["terminal_observation"].shape == o.shape and not np.array_equal(info["terminal_observation"], o)
    obs, reward, dones, infos = venv.step(np.zeros((3, 28)))
    assert not dones.any() and "terminal_observation" not in infos[0]
    with pytest.raises(TypeError):
        SB3BatchedVecEnv(gym.make_vec("InterLevel-v0", num_envs=2, vectorization_mode="sync"))
    venv.close()


def gait_reference() -> ReferenceWindows:
    t = np.arange(90) / 30.0
    phase = 2 * math.pi * t
    q = np.zeros((len(t), 35))
    q[:, 0], q[:, 2], q[:, 3] = t, STANDING_ROOT_HEIGHT - 0.03, 1.0
    dof = {name: 7 + i for i, name in enumerate(DOF_NAMES)}
    q[:, dof["right_hip_y"]], q[:, dof["left_hip_y"]] = -0.4 * np.sin(phase), 0.4 * np.sin(phase)
    return ReferenceWindows(MotionLibrary([MotionClip(q, 30.0, "gait")]), num_frames=2, fps=30.0)


@pytest.mark.slow
def test_sb3_ppo_learns_through_the_adapter_and_amp():
    style = AMPStyleReward(gait_reference(), w_task=0.5, w_style=0.5, update_interval=512, updates_per_round=2,
                           config=DiscriminatorConfig(batch_size=128))
    venv = AMPVecEnvWrapper(make_sb3_vec_env("InterLevel-v0", 4, seed=0), style)
    model = PPO("MlpPolicy", venv, n_steps=256, batch_size=256, n_epochs=1, verbose=0, seed=0)
    model.learn(2048)
    assert model.num_timesteps >= 2048 and style.rounds >= 3 and "disc_loss" in style.last_stats
    venv.close()


def test_threads_release_the_gil_and_keep_worlds_apart():
    """The pool steps worlds of different models at once; each ends where mj_step alone takes it."""
    vec = batched("InterLevel-v0", 4)
    vec.reset(seed=1)
    copies = []
    for env in vec.envs:
        data = mujoco.MjData(env.model)
        mujoco.mj_copyData(data, env.model, env.data)
        copies.append(data)
    ThreadPoolPhysics(2).step([(env.model, env.data) for env in vec.envs], 8)
    for env, data in zip(vec.envs, copies):
        mujoco.mj_step(env.model, data, 8)
        np.testing.assert_array_equal(env.data.qpos, data.qpos)


@pytest.mark.parametrize("physics", ["mujoco", WARP, WARP_DEVICE_STATE])
def test_gymnasium_amp_wrapper_runs_on_the_batched_env(physics):
    from stairenv.style.wrappers import AMPVectorWrapper
    wrapped = AMPVectorWrapper(batched("InterLevel-v0", 2, max_episode_steps=6, **physics_keywords(physics)),
                               AMPStyleReward(gait_reference(), w_task=1.0, w_style=1.0))
    wrapped.reset(seed=0)
    for _ in range(8):
        _, reward, _, _, info = wrapped.step(np.zeros((2, 28)))
        assert reward.shape == (2,) and "style_reward" in info


@pytest.mark.parametrize("env_id, kwargs", [
    ("InterSceneStairs-v0", {}), ("PlaMo-v0", {}), ("SIMS-Sit-v0", {}),
    # rooms: the worlds' models differ in their bodies; the training aids add results
    ("SIMS-Walk-v0", {"scene": "room", "stall_seconds": 0.3, "min_root_height": 0.5}),
])
def test_batch_outcomes_equal_per_world_finish(env_id, kwargs):
    """The batch-first finish (InterLevel: one compiled call for all worlds; PlaMo and SIMS: the batch's
    arrays, then each world's own scene and goal) against each world's own ``_finish_step``, with resets
    and falls inside; exact."""
    runs = []
    for flag in (True, False):
        vec = batched(env_id, 4, batch_outcomes=flag, max_episode_steps=15, **kwargs)
        assert vec.batch_outcomes is flag
        vec.reset(seed=2)
        rng = np.random.default_rng(3)
        runs.append([vec.step(rng.uniform(-1, 1, (4, 28))) for _ in range(40)])
    assert_same(runs[0], runs[1])
    assert batched(env_id, 1).batch_outcomes is True
    assert batched("PlaMoScene-v0", 1).batch_outcomes is False  # its worlds' models differ: world by world


def test_batch_evaluation_is_a_deprecated_name_of_batch_outcomes():
    with pytest.warns(DeprecationWarning, match="batch_outcomes"):
        assert batched("PlaMo-v0", 1, batch_evaluation=False).batch_outcomes is False
    with pytest.raises(ValueError, match="batch_evaluation"), pytest.warns(DeprecationWarning):
        batched("PlaMo-v0", 1, batch_outcomes=True, batch_evaluation=False)


@pytest.mark.parametrize("env_id", ["InterLevel-v0", "SIMS-Sit-v0"])
def test_same_step_autoreset_equals_sync_vector_env(env_id):
    """``autoreset_mode=SAME_STEP``: the reset inside the step that ends an episode (for InterLevel in the
    batch-first finish, for SIMS after the per-world finish) against SyncVectorEnv's SAME_STEP; exact,
    final_obs and final_info included."""
    same_step = gym.vector.AutoresetMode.SAME_STEP
    n = 3
    vec = batched(env_id, n, max_episode_steps=12, autoreset_mode=same_step)
    assert vec.metadata["autoreset_mode"] == same_step
    ref = gym.make_vec(env_id, num_envs=n, vectorization_mode="sync", max_episode_steps=12,
                       vector_kwargs={"autoreset_mode": same_step})
    assert_same(vec.reset(seed=5), ref.reset(seed=5), "reset")
    rng = np.random.default_rng(2)
    ends = 0
    for t in range(40):
        action = rng.uniform(-1, 1, (n, 28))
        got, want = vec.step(action), ref.step(action)
        assert_same(got, want, f"step {t}")
        ends += int(np.sum(got[2] | got[3]))
        if (got[2] | got[3]).any():
            assert got[4]["_final_obs"].tolist() == (got[2] | got[3]).tolist()
    assert ends >= n
    with pytest.raises(ValueError, match="autoreset_mode"):
        batched(env_id, 1, autoreset_mode="partial")


def test_sb3_adapter_equals_dummy_vec_env():
    """The adapter (ended worlds reset inside the step) against SB3's DummyVecEnv over single envs."""
    from stable_baselines3.common.vec_env import DummyVecEnv
    from gymnasium.wrappers import TimeLimit
    n = 3
    venv = make_sb3_vec_env("InterLevel-v0", n, seed=9, max_episode_steps=10)
    ref = DummyVecEnv([lambda: TimeLimit(gym.make("InterLevel-v0").unwrapped, 10) for _ in range(n)])
    ref.seed(9)
    assert_same(venv.reset(), ref.reset())
    rng = np.random.default_rng(0)
    for t in range(25):
        action = rng.uniform(-1, 1, (n, 28)).astype(np.float32)
        obs, reward, dones, infos = venv.step(action)
        obs_r, reward_r, dones_r, infos_r = ref.step(action)
        assert_same((obs, reward, dones), (obs_r, reward_r, dones_r), f"step {t}")
        for info, info_r in zip(infos, infos_r):
            assert info.keys() == info_r.keys(), f"step {t}"
            for key in ("terminal_observation", "TimeLimit.truncated", "progress", "amp_obs"):
                if key in info:
                    assert_same(info[key], info_r[key], f"step {t} {key}")
    assert venv.reset_infos[0].keys() == ref.reset_infos[0].keys()



@pytest.mark.parametrize("backend", [SerialPhysics(), ThreadPoolPhysics(2), ThreadPoolPhysics(3, group=2)])
def test_batch_physics_callbacks(backend):
    """``then`` once per world after its physics, ``meanwhile`` once, ``collect`` after ``meanwhile`` with
    every world exactly once, in groups of at least ``group`` (the last may be smaller)."""
    vec = batched("InterLevel-v0", 7)
    vec.reset(seed=0)
    worlds = [(env.model, env.data) for env in vec.envs]
    times = [data.time for _, data in worlds]
    thens, groups, order = [], [], []
    backend.step(worlds, 8, then=lambda k: thens.append((k, worlds[k][1].time > times[k])),
                 meanwhile=lambda: order.append("meanwhile"),
                 collect=lambda ks: (groups.append(list(ks)), order.append("collect")))
    assert sorted(k for k, _ in thens) == list(range(7)) and all(stepped for _, stepped in thens)
    assert sorted(k for group in groups for k in group) == list(range(7))
    assert order[0] == "meanwhile" and order.count("meanwhile") == 1
    if isinstance(backend, ThreadPoolPhysics):
        least = backend.group or max(1, 7 // 8)
        assert all(len(group) >= least for group in groups[:-1])


def test_thread_pool_raises_a_failure_without_hanging():
    """A failing ``then`` (in a physics thread) or ``collect`` (in the caller) is raised by ``step``
    once every thread is done; the pool then steps the next batch."""
    vec = batched("InterLevel-v0", 6)
    vec.reset(seed=0)
    worlds = [(env.model, env.data) for env in vec.envs]
    pool = ThreadPoolPhysics(2, group=1)

    def bad_then(k):
        if k == 3:
            raise RuntimeError("then failed")

    with pytest.raises(RuntimeError, match="then failed"):
        pool.step(worlds, 1, then=bad_then, collect=lambda ks: None)

    def bad_collect(ks):
        raise RuntimeError("collect failed")

    with pytest.raises(RuntimeError, match="collect failed"):
        pool.step(worlds, 1, collect=bad_collect)
    seen = []
    pool.step(worlds, 1, collect=seen.extend)
    assert sorted(seen) == list(range(6))
    with pytest.raises(ValueError, match="group"):
        ThreadPoolPhysics(2, group=0)


def test_stacked_infos_equal_gymnasium_add_info_world_by_world():
    """``_stack_infos`` (key by key, worlds grouped by their keys) gives ``VectorEnv._add_info``'s arrays,
    dtypes, masks and key order where worlds report different keys (a NEXT_STEP reset's fewer keys)."""
    from stairenv.environments.infos import stack_infos as _stack_infos

    infos = [{"a": 1.5, "b": np.arange(3.0), "c": "x", "d": {"e": True}},
             {"c": "y", "a": 2, "f": np.float32(4.0)},
             {},
             {"a": 3.5, "b": np.ones(3), "d": {"e": False, "g": 7}, "c": ("t", 1)}]
    world_by_world = gym.vector.VectorEnv.__new__(gym.vector.VectorEnv)    # only _add_info and num_envs
    world_by_world.num_envs = len(infos)
    expected: dict = {}
    for i, info in enumerate(infos):
        expected = world_by_world._add_info(expected, info, i)
    stacked = _stack_infos(infos)
    assert list(stacked) == list(expected)
    assert_same(stacked, expected)
    for key, array in expected.items():
        if isinstance(array, np.ndarray):
            assert stacked[key].dtype == array.dtype, key


def test_world_infos_read_as_the_per_world_dicts():
    """``WorldInfos``: columns for some worlds, whole dicts for others (fewer keys, an extra key, a nested
    dict); ``stacked()`` equals ``stack_infos`` of its per-world dicts (arrays, dtypes, masks, cleared rows),
    ``infos[i]`` gives Python numbers as a single env's dict does, ``column`` equals ``np.stack``,
    ``floats_of`` the worlds' values without making their dicts."""
    from stairenv.environments.infos import WorldInfos, column, floats_of, stack_infos

    infos = WorldInfos(4)
    infos.put(np.array([0, 2]), {"x": np.array([1.5, 2.5]), "ok": np.array([True, False]),
                                 "n": np.array([3, 4]), "v": np.arange(6.0).reshape(2, 3),
                                 "nest": {"h": np.array([0.1, 0.2])}})
    infos.put(np.array([3]), {"x": np.array([9.0]), "ok": np.array([True]), "n": np.array([5]),
                              "v": np.ones((1, 3)), "nest": {"h": np.array([0.3])}})
    infos[1] = {"x": 7.0, "extra": "reset", "nest": {"h": 0.5, "k": 1}}
    # floats_of(worlds, key): the worlds' values as numbers, read from the rows without making their dicts
    worlds, keys = np.array([2, 1, 3]), ("x", "ok", "n", "absent")
    got = {key: floats_of(infos, worlds, key) for key in keys}
    assert infos._dicts[2] is None and infos._dicts[3] is None    # no dict made
    for key, (values, present) in got.items():
        want = [infos[i].get(key) for i in worlds.tolist()]
        assert present.tolist() == [value is not None for value in want], key
        assert values.tolist() == [0.0 if value is None else float(value) for value in want], key
    world = infos[0]
    assert world == {"x": 1.5, "ok": True, "n": 3, "v": world["v"], "nest": {"h": 0.1}}
    assert [type(world[key]) for key in ("x", "ok", "n")] == [float, bool, int]
    assert np.array_equal(world["v"], [0.0, 1.0, 2.0]) and infos[0] is world    # made once
    assert_same(infos.stacked(), stack_infos(list(infos)))
    assert np.array_equal(column(infos, "x"), [1.5, 7.0, 2.5, 9.0])
    infos[0] = {"x": 2}    # the first world's int decides the dtype: the per-world route
    assert infos.stacked()["x"].dtype == np.int64
    assert_same(infos.stacked(), stack_infos(list(infos)))
    everyone = WorldInfos(2)
    everyone.put(np.arange(2), {"x": np.array([1.0, 2.0])})
    assert_same(everyone.stacked(), stack_infos(list(everyone)))
    assert list(everyone) == [{"x": 1.0}, {"x": 2.0}] and everyone[:1] == [{"x": 1.0}]
    with pytest.raises(ValueError, match="differ from the first group"):
        everyone.put(np.array([1]), {"y": np.array([1.0])})


@pytest.mark.parametrize("env_id", ["InterLevel-v0", "SIMS-Sit-v0"])
def test_step_worlds_infos_are_the_single_envs(env_id):
    """``step_worlds``' per-world infos (InterLevel: made from the step's columns) equal each single env's
    info key by key with the same Python types, ended and unstable steps included; ``column`` of a key
    equals the stack of the worlds' values."""
    from stairenv.environments.infos import column

    n = 3
    vec = batched(env_id, n, max_episode_steps=12)
    singles = [gym.make(env_id, max_episode_steps=12) for _ in range(n)]
    vec.reset(seed=5)
    for i, env in enumerate(singles):
        env.reset(seed=5 + i)
    rng = np.random.default_rng(0)
    for t in range(30):
        if t == 7:    # world 1 moves faster than a body can: an unstable step, truncated alone
            for env in (vec.envs[1], singles[1].unwrapped):
                env.data.qvel[0] = 100.0
        actions = rng.uniform(-1, 1, (n, 28))
        _, _, terminated, truncated, infos, finals = vec.step_worlds(actions, reset_ended=True)
        for i, env in enumerate(singles):
            _, _, term, trunc, info = env.step(actions[i])
            assert infos[i].keys() == info.keys(), (t, i)
            for key, value in info.items():
                assert type(infos[i][key]) is type(value), (t, i, key)
                assert_same(infos[i][key], value, f"step {t} world {i} {key}")
            if term or trunc:
                env.reset()
        assert np.array_equal(column(infos, "amp_obs"), np.stack([info["amp_obs"] for info in infos]))
    vec.close()


def test_shared_rows_are_the_worlds_own_carry():
    """A batched InterLevel env holds its worlds' carry (last root, goal, stall clock, style history), action
    map and bookkeeping (step count, reference start, last outcome) as rows of one array each: a world's
    own reset writes its rows; a copy of a world holds its own."""
    import copy

    vec = batched("InterLevel-v0", 3)
    vec.reset(seed=0)
    rows = vec.envs[0]._rows
    for i, env in enumerate(vec.envs):
        assert env._rows is rows and np.shares_memory(env._prev_root, rows["_prev_root"][i])
        assert np.shares_memory(env._amp.frames, rows["amp"][i])
        assert np.shares_memory(env._ctrl_scale, rows["_ctrl_scale"][i])
        assert np.array_equal(rows["_packed_goal"][i:i + 1], env._goal.pack())
    action = np.random.default_rng(0).uniform(-1, 1, (3, 28))
    vec.step(action)
    for env, world_action in zip(vec.envs, action):    # the PD targets read from the shared map
        assert np.array_equal(env.data.ctrl, env._ctrl_offset + env._ctrl_scale * world_action)
    obs, reward, *_ = vec.step(np.zeros((3, 28)))
    assert np.array_equal(rows["_prev_root"][1], vec.envs[1].data.xpos[vec.envs[1]._idx.pelvis_id])
    assert rows["_step_count"].tolist() == [2, 2, 2] and [env._steps for env in vec.envs] == [2, 2, 2]
    assert rows["_reference_flag"].tolist() == [env._reference_start for env in vec.envs]
    # the last outcome: the batch's, left in the rows; a world's own made when read, as a single env's
    assert all(batch is not None for batch in rows["_outcome_batch"])
    last = vec.envs[1]._outcome
    assert rows["_outcome_batch"][1] is None and rows["_outcome_batch"][0] is not None
    assert np.array_equal(last.obs, obs[1]) and type(last.reward) is float and last.reward == reward[1]
    vec.reset_world(2, seed=11)
    assert np.array_equal(rows["_packed_goal"][2:3], vec.envs[2]._goal.pack())
    assert rows["_step_count"][2] == 0 and rows["_outcome_batch"][2] is None    # its reset's outcome, its own
    clone = copy.deepcopy(vec.envs[0])    # its last outcome still in the rows: the copy takes it
    assert clone._rows is None and not np.shares_memory(clone._prev_root, rows["_prev_root"])
    assert np.array_equal(clone._outcome.obs, obs[0]) and clone._outcome.reward == reward[0]
    clone.step(np.zeros(28))
    assert clone._steps == 3 and vec.envs[0]._steps == 2
    assert not np.shares_memory(clone._step_count, rows["_step_count"])
    assert np.array_equal(rows["_prev_root"][0], vec.envs[0].data.xpos[vec.envs[0]._idx.pelvis_id])
    vec.close()


def test_episode_infos_are_columns_over_the_worlds():
    """A batched InterLevel env keeps its worlds' episode infos (the staircase, the stair start) as columns
    written at their resets, and a step's infos read them; an episode info with other keys in one world
    is refused, naming it (a step's infos are columns)."""
    from stairenv.environments.infos import column
    from stairenv.environments.interlevel import InterLevelEnv

    class Tagged(InterLevelEnv):
        tag = False

        def _episode_info(self):
            return {**super()._episode_info(), **({"tag": 1} if self.tag else {})}

    vec = HumanoidVectorEnv(3, env_class=Tagged)
    vec.reset(seed=0)
    rows = vec.envs[0]._rows
    vec.reset_world(1, seed=9)
    _, _, _, _, infos, _ = vec.step_worlds(np.zeros((3, 28)))
    assert np.array_equal(rows["_episode"]["stairs"]["num_steps"], [env.stairs.num_steps for env in vec.envs])
    assert [infos[i]["stairs"] for i in range(3)] == [env.stairs.as_dict() for env in vec.envs]
    assert np.array_equal(column(infos, "stairs_start"), [env._stairs_start for env in vec.envs])
    vec.envs[1].tag = True
    with pytest.raises(ValueError, match=r"same keys .*world\(s\) \[1\] gave other keys"):
        vec.reset_world(1, seed=9)
    vec.close()


def test_episode_columns_widen_rather_than_cut():
    """``write_rows``: a later group's values that the column's dtype cannot hold (floats into an int column)
    widen the column instead of being cut; ``take_rows`` reads nested columns by rows."""
    from stairenv.environments.infos import take_rows, write_rows

    columns = {}
    write_rows(columns, {"n": np.array([3, 4]), "nest": {"h": np.array([True, False])}}, np.array([0, 2]), 3)
    write_rows(columns, {"n": np.array([2.5]), "nest": {"h": np.array([True])}}, np.array([1]), 3)
    assert columns["n"].dtype == np.float64 and columns["n"].tolist() == [3.0, 2.5, 4.0]
    assert columns["nest"]["h"].dtype == bool
    taken = take_rows(columns, np.array([2, 1]))
    assert taken["n"].tolist() == [4.0, 2.5] and taken["nest"]["h"].tolist() == [False, True]


def test_episode_columns_hold_every_world_of_a_reset_group():
    """Worlds reset together whose episode infos differ in type (a staircase given with integer sizes, another
    with floats) share a column that holds both: each world's step info reports its own staircase, as the
    single env does, not the first world's integers cutting the others' floats."""
    from stairenv.environments.infos import columns_of_rows
    from stairenv.environments.interlevel import InterLevelEnv
    from stairenv.world.stairs import Staircase

    columns = columns_of_rows((("n",), ("a",), ("same",)), [(3, np.array([1, 2]), 1.5), (2.5, np.array([0.5, 1.0]), 2.5)])
    assert columns["n"].tolist() == [3.0, 2.5] and columns["a"].tolist() == [[1.0, 2.0], [0.5, 1.0]]
    assert columns["same"].dtype == np.float64
    assert columns_of_rows((("b",),), [(True,), (False,)])["b"].dtype == bool    # one type: stack_infos' dtype
    ints = Staircase(step_height=0.15, step_depth=0.3, width=1, num_steps=4, landing_depth=2, yaw=0, distance=3)
    floats = Staircase(step_height=0.15, step_depth=0.3, width=1.4, num_steps=4, landing_depth=2.5, yaw=0.7,
                       distance=3.3)
    vec = HumanoidVectorEnv(2, env_class=InterLevelEnv, physics="serial")
    vec.reset_each([0, 1], [{"stairs": ints}, {"stairs": floats}])
    _, _, _, _, infos, _ = vec.step_worlds(np.zeros((2, 28)))
    single = InterLevelEnv()
    single.reset(seed=1, options={"stairs": floats})
    *_, info = single.step(np.zeros(28))
    assert infos[1]["stairs"] == info["stairs"] == floats.as_dict()
    assert infos[0]["stairs"] == ints.as_dict()
    vec.close()


def test_set_attr_keeps_one_configuration_over_the_worlds():
    """A keyword of the env class set per world with different values (``set_attr``, SB3's ``indices``) is
    refused, naming it: the task runs over the worlds as one batch with one configuration, so world 1's
    own ``termination_height`` would be silently ignored. One value for every world, and values per world
    of what is not a keyword (``curriculum_level``), are set."""
    vec = batched("InterLevel-v0", 3, physics="serial")
    with pytest.raises(ValueError, match=r"'termination_height' is a keyword of InterLevelEnv.*world 1 5\.0"):
        vec.set_attr("termination_height", [0.3, 5.0, 0.3])
    assert vec.get_attr("termination_height") == (vec.envs[0].termination_height,) * 3
    vec.set_attr("termination_height", 0.5)
    vec.set_attr("curriculum_level", [4, 2, 1])
    assert vec.get_attr("termination_height") == (0.5,) * 3 and vec.get_attr("curriculum_level") == (4, 2, 1)
    sb3 = SB3BatchedVecEnv(vec)
    with pytest.raises(ValueError, match="one configuration"):
        sb3.set_attr("stall_seconds", 9.0, indices=[1])
    sb3.set_attr("curriculum_level", 0, indices=[1])
    sb3.set_attr("stall_seconds", 9.0)
    assert sb3.get_attr("curriculum_level") == [4, 0, 1] and sb3.get_attr("stall_seconds") == [9.0] * 3
    sb3.close()


@pytest.mark.parametrize("physics", ["serial", "mujoco"])
def test_a_batched_env_refuses_to_be_copied_and_says_how(physics):
    """A copy of a batched env would share its worlds' rows and physics back-end or lose them (a serial one's
    copy used to fail at every step, a threaded one's inside pickle): refused with the way out; a world
    alone still copies."""
    import copy
    import pickle

    vec = batched("InterLevel-v0", 2, physics=physics)
    vec.reset(seed=0)
    for make_copy in (copy.deepcopy, copy.copy, pickle.dumps):
        with pytest.raises(TypeError, match=r"cannot be copied or pickled.*gym\.make_vec"):
            make_copy(vec)
    clone = copy.deepcopy(vec.envs[1])
    clone.step(np.zeros(28))
    vec.step(np.zeros((2, 28)))
    vec.close()


def test_an_override_of_start_tracking_is_called_at_every_reset():
    """InterLevel starts its worlds' tracking over the batch; a subclass that overrides ``_start_tracking`` has
    it called for each world it resets (single or batched, with that world's row of the state), and the
    trajectories stay those of InterLevel's own."""
    from stairenv.environments.interlevel import InterLevelEnv
    from stairenv.humanoid.state import PELVIS

    class Tracked(InterLevelEnv):
        roots: list = []

        def _start_tracking(self, state):
            type(self).roots.append(state.body_pos[0, PELVIS].copy())
            super()._start_tracking(state)

    single = Tracked()
    single.reset(seed=0)
    assert len(Tracked.roots) == 1
    vec, plain = (HumanoidVectorEnv(3, env_class=cls, physics="serial") for cls in (Tracked, InterLevelEnv))
    outs = [v.reset(seed=4)[0] for v in (vec, plain)]
    assert len(Tracked.roots) == 4
    assert [root.tolist() for root in Tracked.roots[1:]] == [env.data.xpos[env._idx.pelvis_id].tolist()
                                                             for env in vec.envs]
    for _ in range(3):
        outs += [v.step(np.full((3, 28), 0.2))[0] for v in (vec, plain)]
    for a, b in zip(outs[::2], outs[1::2]):
        np.testing.assert_array_equal(a, b)
    vec.close()
    plain.close()
