"""The MuJoCo Warp back-end (``physics="warp"``) on Warp's CPU device, against the MuJoCo C back-end.

MuJoCo Warp computes in float32 and generates some contacts differently (box-box: the feet, which are
boxes, against each other or a tread), so it follows the C back-end within a tolerance, not bit for bit.
Measured on this model (``docs/gpu.md``), one env step (8 substeps) from the same state and actions: in
96% of 295 world-steps the two differ by float32 rounding (<= 3.1e-6 m or rad in qpos, <= 6.9e-5 in qvel);
in the rest, steps with contacts the two back-ends resolve differently (a hand resting on the pelvis, a
foot on the other foot or a tread: box-box), by up to ~2e-2 m and ~5 rad/s.
The tolerances below are ~10-20x the float32 figures for the tight checks, and bound the contact-set
differences for the rest. Skipped where ``mujoco_warp`` is not installed (the ``gpu`` extra); the first run
compiles Warp's CPU kernels (~35 s of one core, then cached in ``WARP_CACHE_PATH`` / ~/.cache/warp).
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import stairenv  # noqa: F401
from stairenv.environments.batch_physics import ThreadPoolPhysics
from stairenv.environments.vector import HumanoidVectorEnv

# tight: float32 rounding of one 8-substep step (measured over 295 world-steps: <= 3.1e-6 m or rad in qpos,
# 6.9e-5 in qvel and obs); the reward differentiates root positions over dt = 1/30 s, so a few 1e-6 m give
# up to 1.3e-3 (measured) in its velocity term
QPOS_TOL, QVEL_TOL, OBS_TOL, REWARD_TOL = 1e-5, 1e-3, 1e-3, 5e-3
# loose: a step whose contacts the back-ends resolve differently (measured up to 2.3e-2 m, 4.8 rad/s)
QPOS_LOOSE, QVEL_LOOSE = 0.05, 10.0


def batched(n, env_id="InterLevel-v0", **kwargs):
    return gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)


# --- without MuJoCo Warp: the keywords and the refusals -------------------------------------------
@pytest.mark.parametrize("env_id, reason", [("PlaMoScene-v0", "landmarks"), ("SIMS-Sit-v0", "furniture")])
def test_ids_without_a_shared_world_structure_are_refused(env_id, reason):
    with pytest.raises(ValueError, match=f"physics='warp'.*{reason}"):
        batched(2, env_id, physics="warp")


def test_physics_threads_sizes_the_pool():
    vec = batched(2, physics_threads=3)
    assert isinstance(vec.physics, ThreadPoolPhysics) and vec.physics.nthread == 3
    vec.close()
    assert batched(1, nthread=2).physics.nthread == 2    # the older name
    with pytest.raises(ValueError, match="physics_threads"):
        batched(1, physics_threads=0)
    with pytest.raises(ValueError, match="physics_threads"):
        batched(1, physics_threads=2, nthread=3)
    with pytest.raises(ValueError, match="physics must be one of"):
        batched(1, physics="gpu")


def test_physics_device_is_for_warp_only():
    """``physics_device`` places the Warp back-end; the C back-ends run on the host, so it is refused there
    (before any world is built), as is a device that is not a name."""
    with pytest.raises(ValueError, match="physics_device='cuda:0' is for physics='warp' only"):
        batched(1, physics_device="cuda:0")
    with pytest.raises(ValueError, match="physics_device"):
        batched(1, physics=ThreadPoolPhysics(1), physics_device="cpu")
    with pytest.raises(TypeError, match="physics_device must be None or a device name"):
        batched(1, physics="warp", physics_device=0)


def test_state_on_device_is_for_warp_only():
    """``state_on_device`` keeps Warp's state on the device; the C back-ends step each world's ``MjData``, and
    a back-end object takes its own setting, so both are refused (before any world is built), as is a value
    that is not a bool."""
    with pytest.raises(ValueError, match="state_on_device=True is for physics='warp' only"):
        batched(1, state_on_device=True)
    with pytest.raises(ValueError, match="state_on_device"):
        batched(1, physics=ThreadPoolPhysics(1), state_on_device=True)
    with pytest.raises(TypeError, match="state_on_device must be True or False"):
        batched(1, physics="warp", state_on_device="yes")


def test_a_replicated_env_equals_a_freshly_built_one():
    """``replicate`` (how a device back-end's batched env makes its worlds): its own model and data, and
    the same episodes as an env built anew."""
    from stairenv.environments.interlevel import InterLevelEnv
    first = InterLevelEnv()
    clone, fresh = first.replicate(), InterLevelEnv()
    assert clone.model is not first.model and clone.data is not first.data
    rng = np.random.default_rng(0)
    for env in (clone, fresh):
        env.reset(seed=5)
    first.reset(seed=99)    # the original going on does not touch its copy
    for _ in range(20):
        action = rng.uniform(-1, 1, 28)
        got, want = clone.step(action), fresh.step(action)
        first.step(action)
        np.testing.assert_array_equal(got[0], want[0])
        assert got[1:4] == want[1:4]


# --- with MuJoCo Warp (on its CPU device here) ------------------------------------------------------
warp_only = pytest.mark.skipif(not __import__("importlib").util.find_spec("mujoco_warp"),
                               reason="mujoco_warp is not installed (pip install 'stairenv[gpu]')")


def copy_state(src, dst):
    """World by world, the C back-end's state into the Warp env's host data (then stepped from it)."""
    for a, b in zip(src.envs, dst.envs):
        for field in ("qpos", "qvel", "qacc_warmstart", "ctrl"):
            getattr(b.data, field)[:] = getattr(a.data, field)
        b.data.time = a.data.time


@warp_only
def test_the_device_runs_the_c_models_options():
    """Integrator, solver, iterations, timestep...: the C model's. The solver tolerance only is raised to
    1e-6 (MuJoCo Warp does so for float32: ``put_model``)."""
    vec = batched(2, physics="warp")
    for name, (host, device) in vec.physics.settings().items():
        want = max(host, 1e-6) if name == "tolerance" else host
        assert want == pytest.approx(device, rel=1e-6), name
    vec.close()


@warp_only
@pytest.mark.parametrize("kwargs", [{}, {"init": "hybrid", "stairs_start_fraction": 0.5}])
def test_a_reset_on_the_device_computes_the_poses_only(kwargs):
    """On the Warp back-end a reset runs ``mj_kinematics``, not ``mj_forward``: the same staircases, state,
    poses and first observations as the C back-end's reset (so the same episodes), but no derived quantity
    the host never reads (no contact, no acceleration)."""
    c_backend, device = batched(4, **kwargs), batched(4, physics="warp", **kwargs)
    got, want = device.reset(seed=2)[0], c_backend.reset(seed=2)[0]
    np.testing.assert_array_equal(got, want)
    for a, b in zip(c_backend.envs, device.envs):
        for name in ("qpos", "qvel", "ctrl", "xpos", "xmat", "geom_xpos"):
            np.testing.assert_array_equal(getattr(b.data, name), getattr(a.data, name), name)
        assert np.abs(a.data.qacc).max() > 0 and not b.data.qacc.any() and b.data.ncon == 0
    assert any(a.data.ncon for a in c_backend.envs)
    c_backend.close()
    device.close()


@warp_only
def test_one_step_from_the_same_state_matches_the_c_backend():
    """The same reset states (the host's code) and actions, one env step, 8 worlds x 3 seeds: most worlds
    agree to float32 rounding; the rest (measured: 1-2 worlds in 6 on some seeds, where a hand rests on
    the pelvis or a thigh, or a foot touches the other foot: contacts the two back-ends resolve
    differently) within the loose bound."""
    n = 8
    warp, c = batched(n, physics="warp"), batched(n, physics="serial")
    tight = 0
    for seed in (0, 5, 11):
        obs_w, _ = warp.reset(seed=seed)
        obs_c, _ = c.reset(seed=seed)
        np.testing.assert_array_equal(obs_w, obs_c)    # the reset is the host's, the same code
        action = np.random.default_rng(seed).uniform(-1, 1, (n, 28))
        ow, rw, tw, uw, iw = warp.step(action)
        oc, rc, tc, uc, ic = c.step(action)
        qpos = np.abs(np.stack([e.data.qpos for e in warp.envs]) - np.stack([e.data.qpos for e in c.envs])).max(1)
        qvel = np.abs(np.stack([e.data.qvel for e in warp.envs]) - np.stack([e.data.qvel for e in c.envs])).max(1)
        assert (qpos < QPOS_LOOSE).all() and (qvel < QVEL_LOOSE).all(), (qpos, qvel)
        close = (qpos < QPOS_TOL) & (qvel < QVEL_TOL)
        tight += close.sum()
        assert np.abs(ow - oc)[close].max() < OBS_TOL and np.abs(rw - rc)[close].max() < REWARD_TOL
        assert (tw == tc).all() and (uw == uc).all() and not iw["physics_unstable"].any()
        for key in ("reward_location", "progress"):
            np.testing.assert_allclose(iw[key][close], ic[key][close], atol=1e-3)
    assert tight >= 0.75 * 3 * n, tight
    warp.close()
    c.close()


@warp_only
def test_steps_from_the_same_states_stay_within_tolerance():
    """30 steps x 4 worlds, each step from the C back-end's state: most world-steps agree to float32
    rounding (measured: 96%); the others (contacts resolved differently) stay within the loose bound."""
    n = 4
    warp, c = batched(n, physics="warp"), batched(n, physics="serial")
    warp.reset(seed=3)
    c.reset(seed=3)
    rng = np.random.default_rng(1)
    tight = total = 0
    for _ in range(30):
        copy_state(c, warp)
        action = rng.uniform(-1, 1, (n, 28))
        _, _, tw, uw, _ = warp.step(action)
        _, _, tc, uc, _ = c.step(action)
        for a, b, ended in zip(warp.envs, c.envs, tc | uc):
            if ended:
                continue
            dq, dv = np.abs(a.data.qpos - b.data.qpos).max(), np.abs(a.data.qvel - b.data.qvel).max()
            assert dq < QPOS_LOOSE and dv < QVEL_LOOSE, (dq, dv)
            tight += dq < QPOS_TOL and dv < QVEL_TOL
            total += 1
        if (tc | uc).any() or (tw | uw).any():    # both reset the ended worlds at the next step
            copy_state(c, warp)
    assert total >= 60 and tight >= 0.6 * total, (tight, total)
    warp.close()
    c.close()


@warp_only
def test_each_world_keeps_its_own_staircase_on_the_device():
    """Resets write new staircases (per-world sizes and poses) that reach the device, and the characters
    started on the treads (reference starts on a climb of each world's staircase) stand on them as with
    the C back-end. (A tread is a static body, whose geom pose MuJoCo Warp never computes: without the
    host's poses uploaded at reset, these characters sank through the treads, ~0.1 m in 5 steps.)"""
    n = 3
    kwargs = dict(stairs_start_fraction=1.0, init="reference")    # every episode starts on its climb
    warp, c = batched(n, physics="warp", **kwargs), batched(n, physics="serial", **kwargs)
    for seed in (0, 100):
        warp.reset(seed=seed)
        c.reset(seed=seed)
        assert max(e.data.qpos[2] for e in c.envs) > 1.0    # someone starts high up the stairs
        hold = np.zeros((n, 28))
        for _ in range(5):
            warp.step(hold)
            c.step(hold)
        device = warp.physics.model
        for name in ("geom_size", "body_pos", "body_quat", "geom_rbound"):
            got = getattr(device, name).numpy().reshape(n, -1)
            want = np.stack([getattr(env.model, name).reshape(-1) for env in warp.envs])
            np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-6, err_msg=name)
        treads = warp.envs[0]._slots.geom_ids
        for name in ("geom_xpos", "geom_xmat"):    # where the collision detection puts the treads
            got = getattr(warp.physics.data, name).numpy().reshape(n, warp.envs[0].model.ngeom, -1)[:, treads]
            want = np.stack([getattr(env.data, name)[treads].reshape(len(treads), -1) for env in warp.envs])
            np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-6, err_msg=name)
        sizes = np.stack([env.model.geom_size for env in warp.envs])
        assert not np.allclose(sizes[0], sizes[1])    # worlds differ
        zw = np.array([e.data.qpos[2] for e in warp.envs])
        zc = np.array([e.data.qpos[2] for e in c.envs])
        assert np.abs(zw - zc).max() < 0.02, (zw, zc)    # on the treads, not fallen through them
        assert (zw > 0.5).all()
    warp.close()
    c.close()


@warp_only
def test_a_captured_graph_steps_as_kernel_launches_do():
    """The substeps captured once and replayed (a CUDA graph on a GPU; Warp replays graphs on its CPU
    device too) give exactly what launching them one by one gives, resets in between included."""
    from stairenv.environments.warp_physics import WarpPhysics
    runs = []
    for graph in (False, True):
        physics = WarpPhysics(device="cpu", graph=graph)
        vec = batched(3, physics=physics, max_episode_steps=3)
        vec.reset(seed=0)
        rng = np.random.default_rng(0)
        runs.append([vec.step(rng.uniform(-1, 1, (3, 28)))[:4] for _ in range(7)])
        assert physics.graph is graph and physics.graph_error is None
        vec.close()
    for (a, b) in zip(*runs):
        for x, y in zip(a, b):
            np.testing.assert_array_equal(x, y)


def test_a_world_is_diverged_where_c_would_reset_it():
    """``_diverged``: a non-finite value or one beyond MuJoCo's bound (1e10) in the position, the velocity or
    the acceleration (the warm start: C's ``mj_checkAcc`` reads the acceleration), row by row."""
    from stairenv.environments.warp_physics import MAX_VALUE, _diverged

    qpos, qvel, warm = np.zeros((7, 3)), np.zeros((7, 2)), np.zeros((7, 2))
    qpos[1, 0], qvel[2, 1], warm[3, 0] = np.nan, 2 * MAX_VALUE, -2 * MAX_VALUE
    qpos[4, 2], warm[5, 1], qvel[6, 0] = -2 * MAX_VALUE, np.inf, MAX_VALUE    # row 6: at the bound, not beyond
    assert _diverged(qpos, qvel, warm).tolist() == [False, True, True, True, True, True, False]


@warp_only
def test_a_divergence_truncates_that_world_only():
    vec = batched(3, physics="warp")
    vec.reset(seed=0)
    vec.step(np.zeros((3, 28)))
    before = [env.data.time for env in vec.envs]
    vec.envs[1].data.qvel[:] = 1e12    # as the C test does: a state MuJoCo calls diverged
    with pytest.warns(UserWarning, match="physics became unstable"):
        obs, reward, terminated, truncated, info = vec.step(np.zeros((3, 28)))
    assert truncated.tolist() == [False, True, False] and not terminated.any()
    assert info["physics_unstable"].tolist() == [False, True, False]
    assert reward[1] == 0 and np.isfinite(obs).all()
    assert vec.envs[0].data.time > before[0] and vec.envs[2].data.time > before[2]
    # the next step resets that world alone and it steps on
    obs, reward, terminated, truncated, info = vec.step(np.zeros((3, 28)))
    assert not truncated.any() and info["time"][1] == 0 and np.isfinite(obs).all()
    obs, *_ = vec.step(np.zeros((3, 28)))
    assert np.isfinite(obs).all() and vec.physics.overflows == 0
    vec.close()


@warp_only
def test_state_on_the_device_follows_the_host_truth_path():
    """``WarpPhysics(state_on_device=True)``: the same trajectories as with the host's ``MjData`` as the truth
    (the same physics on the device; only the kinematics the task reads run in float32 there), resets and
    ends included; the worlds' ``MjData`` lag until ``sync_worlds``; a write into a world's ``MjData``
    announced with ``world_changed`` reaches the device (a diverged state: that world alone truncated), and one
    announced for a world whose ``MjData`` lags is refused."""
    from stairenv.environments.warp_physics import WarpPhysics

    n, runs = 4, {}
    for on_device in (False, True):
        vec = batched(n, physics=WarpPhysics(device="cpu", state_on_device=on_device), max_episode_steps=12)
        vec.reset(seed=3)
        rng = np.random.default_rng(0)
        runs[on_device] = [vec.step(rng.uniform(-1, 1, (n, 28))) for _ in range(30)]
        if on_device:
            physics = vec.physics
            stale = np.flatnonzero(physics._stale)
            host_qpos = physics._state_host["qpos"]
            assert stale.size and not np.array_equal(vec.envs[stale[0]].data.qpos, host_qpos[stale[0]].astype(np.float64))
            physics.sync_worlds()
            for k in stale:
                assert np.array_equal(vec.envs[k].data.qpos, host_qpos[k].astype(np.float64))
            vec.envs[1].data.qvel[:] = 1e12
            physics.world_changed(1)
            with pytest.warns(UserWarning, match="physics became unstable"):
                *_, truncated, info = vec.step(np.zeros((n, 28)))
            assert info["physics_unstable"].tolist() == [False, True, False, False] and truncated[1]
            # the worlds stepped, so their MjData lag again: a write into one would go into an old state and
            # rewind the world when sent up, so announcing it is refused until the world is synced
            assert physics._stale.all()
            physics.sync_worlds([1])
            with pytest.raises(RuntimeError, match=r"world\(s\) \[0, 2\]: the MjData lags.*sync_worlds\(\[0, 2\]\)"):
                physics.world_changed([0, 1, 2])
            physics.world_changed(1)
        vec.close()
    ends = 0
    for t, (host, device) in enumerate(zip(runs[False], runs[True])):
        assert np.abs(host[0] - device[0]).max() < OBS_TOL and np.abs(host[1] - device[1]).max() < REWARD_TOL, t
        assert np.array_equal(host[2], device[2]) and np.array_equal(host[3], device[3]), t
        ends += int(np.sum(host[2] | host[3]))
    assert ends >= n


@warp_only
@pytest.mark.parametrize("env_id", ["InterLevel2D-v0", "InterSceneStairs-v0"])
def test_the_ablation_ids_run_on_warp(env_id):
    warp, c = batched(2, env_id, physics="warp"), batched(2, env_id, physics="serial")
    warp.reset(seed=0)
    c.reset(seed=0)
    action = np.full((2, 28), 0.1)
    ow, rw, *_ = warp.step(action)
    oc, rc, *_ = c.step(action)
    assert np.abs(ow - oc).max() < QVEL_LOOSE and np.abs(rw - rc).max() < 0.1
    warp.close()
    c.close()


@warp_only
@pytest.mark.parametrize("state_on_device", [False, True])
def test_the_lean_trainer_runs_on_warp_physics(state_on_device):
    from stairenv.training import Trainer, TrainConfig
    config = TrainConfig(num_envs=2, physics="warp", rollout_steps=4, minibatch_size=8, epochs=1, style="none",
                         total_steps=8, state_on_device=state_on_device)
    trainer = Trainer(config)
    assert isinstance(trainer.venv, HumanoidVectorEnv) and type(trainer.venv.physics).__name__ == "WarpPhysics"
    assert trainer.venv.physics.state_on_device is state_on_device
    trainer.collect()
    stats = trainer.update()
    assert all(np.isfinite(v) for v in stats.values())
    trainer.venv.close()


@warp_only
def test_a_ranks_physics_runs_on_its_own_device(monkeypatch):
    """A data-parallel rank hands the trainer its GPU (``physics_device``, ``cuda:r`` under torchrun), and
    the Warp back-end is built there (here the CPU device, named: the devices asked for are recorded, since
    on a machine without a GPU Warp's own default is the CPU too); a plain process leaves Warp its default."""
    from stairenv.environments import warp_physics
    from stairenv.training import Trainer, TrainConfig
    from stairenv.training.distributed import LOCAL, Local

    asked = []
    build = warp_physics.WarpPhysics.__init__

    def recording(self, device=None, **kwargs):
        asked.append(device)
        build(self, device=device, **kwargs)

    monkeypatch.setattr(warp_physics.WarpPhysics, "__init__", recording)

    class Rank(Local):
        physics_device = "cpu"

    config = TrainConfig(num_envs=2, physics="warp", rollout_steps=4, minibatch_size=8, epochs=1, style="none",
                         total_steps=8)
    trainer = Trainer(config, parallel=Rank())
    assert asked == ["cpu"] and trainer.venv.physics.device.alias == "cpu"
    trainer.collect()
    trainer.venv.close()
    Trainer(config, parallel=LOCAL).venv.close()
    assert asked == ["cpu", None]
    batched(1, physics="warp", physics_device="cpu").close()
    assert asked == ["cpu", None, "cpu"]


@warp_only
def test_train_ppo_keeps_the_state_on_the_device_by_flag_and_resumes_as_this_machine_says(tmp_path, train_ppo):
    """``--state-on-device`` is the machine's choice, as ``--device``: the checkpoint records it, a resume
    takes the flag (absent: the host's ``MjData`` the truth), and a resume on the C physics with it stops
    with the reason."""
    from stairenv.training import read_checkpoint
    tiny = ["--physics", "warp", "--n-envs", "2", "--n-steps", "4", "--batch-size", "8", "--n-epochs", "1",
            "--style", "none", "--eval-episodes", "0", "--no-progress-bar", "--logdir", str(tmp_path)]
    train_ppo.run(["--timesteps", "8", "--state-on-device", *tiny], tmp_path)
    final = tmp_path / "InterLevel-v0" / "seed0" / "final_checkpoint.pt"
    assert read_checkpoint(final)["config"]["state_on_device"] is True
    train_ppo.run(["--timesteps", "8", "--resume", str(final), *tiny], tmp_path)
    assert read_checkpoint(final)["config"]["state_on_device"] is False and read_checkpoint(final)["steps"] == 16
    train_ppo.run(["--timesteps", "8", "--state-on-device", "--resume", str(final), *tiny], tmp_path)
    train_ppo.run(["--timesteps", "8", "--resume", str(final), "--physics", "mujoco", *tiny[2:]], tmp_path)
    config = read_checkpoint(final)["config"]    # a state-on-device run goes on on the C physics
    assert (config["physics"], config["state_on_device"], read_checkpoint(final)["steps"]) == ("mujoco", False, 32)
    said = train_ppo.fails(["--timesteps", "8", "--resume", str(final), "--state-on-device", "--physics", "mujoco",
                            *tiny[2:]], tmp_path)
    assert "state_on_device=True is for physics='warp' only" in said


# --- PlaMo: terrain tiles, each world's height fields its own on the device ------------------------------
def _roots(vec):
    return np.stack([env.data.qpos[:3] for env in vec.envs])


@warp_only
@pytest.mark.slow
@pytest.mark.parametrize("terrain", ["mixed", "rough"])
def test_plamo_worlds_keep_their_own_terrain_on_the_device(terrain):
    from stairenv import pretrained
    """PlaMo-v0 on Warp (CPU device) against the C back-end: the same seeds give the same terrain (the host
    draws it for both) and the device holds each world's height fields as its own (routed by its
    ``geom_dataid``); after 2 s of the same actions the roots agree (median gap over the worlds <= 5 cm);
    a character moved onto other tiles makes the focus write its world's slots, which reach the device
    (its slots' fields and poses on the device are the host's).

    On rough ground (every tile a height field) the two back-ends part: from the same state, one step
    differs by 1e-3-1e-2 m in most world-steps and by up to 0.35 m in a few (measured 2026-12-07, 4 worlds x
    40 steps of the shipped walker), where MuJoCo C makes one contact per height-field prism under a geom
    and MuJoCo Warp's convex height-field collision another contact set; so the 2 s agreement is asserted
    on the preset's mixed terrain (plane, stairs as boxes, slope and rough patches), and only the routing
    on rough ground."""
    n = 4
    kwargs = {"terrain": terrain, "max_xy_error": 100.0}
    warp, c = batched(n, "PlaMo-v0", physics="warp", **kwargs), batched(n, "PlaMo-v0", physics="serial", **kwargs)
    warp.reset(seed=21)
    c.reset(seed=21)
    for a, b in zip(warp.envs, c.envs):
        np.testing.assert_array_equal(a._heights, b._heights)
    heights = [env._heights for env in warp.envs]
    assert not np.array_equal(heights[0], heights[1])    # worlds differ
    walker = pretrained.load("PlaMo-v0")
    apart = np.zeros(n, dtype=bool)
    obs = c.reset(seed=21)[0]
    warp.reset(seed=21)
    for _ in range(60):    # 2 s of the same actions: the shipped walker's on the C back-end's observations
        action = walker(obs)
        _, _, tw, uw, _ = warp.step(action)
        obs, _, tc, uc, _ = c.step(action)
        apart |= (tw | uw) != (tc | uc)    # (a world whose episode ends on both at once is reset alike on both)
    if terrain == "mixed":
        assert apart.sum() <= n // 2, apart
        gaps = np.linalg.norm(_roots(warp) - _roots(c), axis=1)[~apart]
        assert np.median(gaps) <= 0.05, gaps
    for env in warp.envs:    # every character carried 3 m along x: the next step's focus brings new tiles in
        env.data.qpos[0] += 3.0
    held = [env._terrain_slots.held() for env in warp.envs]
    warp.step(np.zeros((n, 28)))
    assert [env._terrain_slots.held() for env in warp.envs] != held
    device, model0 = warp.physics.model, warp.envs[0].model
    fields = model0.hfield_size.shape[0]
    if fields:
        data = device.hfield_data.numpy().reshape(n, -1)
        sizes = device.hfield_size.numpy().reshape(n, fields, 4)
        for k, env in enumerate(warp.envs):
            np.testing.assert_allclose(data[k], env.model.hfield_data, atol=1e-6)
            np.testing.assert_allclose(sizes[k], env.model.hfield_size, rtol=1e-6, atol=1e-6)
        routed = device.geom_dataid.numpy()
        field_geoms = np.flatnonzero(model0.geom_type == int(__import__("mujoco").mjtGeom.mjGEOM_HFIELD))
        np.testing.assert_array_equal(routed[:, field_geoms], np.arange(n)[:, None] * fields
                                      + model0.geom_dataid[field_geoms])
    for name in ("body_pos", "geom_pos", "geom_size"):
        got = getattr(device, name).numpy().reshape(n, -1)
        want = np.stack([getattr(env.model, name).reshape(-1) for env in warp.envs])
        np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-6, err_msg=name)
    slots = warp.envs[0]._terrain_slots.geom_ids()    # the slot geoms' poses, which the device never computes
    got = warp.physics.data.geom_xpos.numpy().reshape(n, model0.ngeom, 3)[:, slots]
    np.testing.assert_allclose(got, np.stack([env.data.geom_xpos[slots] for env in warp.envs]), atol=1e-5)
    assert warp.physics.overflows == 0
    warp.close()
    c.close()


@warp_only
@pytest.mark.slow
def test_plamo_table2_runs_on_the_device_as_on_the_host():
    """``evaluate_plamo.py --num-envs N --physics warp``: PlaMo's Table 2 on MuJoCo Warp (CPU device) runs the
    same episodes as on MuJoCo C side by side (the same seeds, the same flat walk paths, the shipped walker) and
    measures alike: the back-ends' contacts differ in the low bits, so each row's mean errors agree within
    5 cm and its early terminations within one episode of the four."""
    from stairenv import pretrained
    from stairenv.evaluation.plamo import evaluate

    walker = pretrained.load("PlaMo-v0")
    kwargs = dict(terrains=("flat",), locomotions=("walk",), episodes=4, seed=31, max_episode_steps=60, num_envs=2)
    host = evaluate(walker, **kwargs).rows[0]
    device = evaluate(walker, physics="warp", physics_device="cpu", **kwargs).rows[0]
    assert abs(device["xy_error_m"] - host["xy_error_m"]) <= 0.05, (device, host)
    assert abs(device["z_error_m"] - host["z_error_m"]) <= 0.05, (device, host)
    assert abs(device["early_termination_pct"] - host["early_termination_pct"]) <= 25.0
