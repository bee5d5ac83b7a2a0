"""The host's share of a batched step, against the same task kernels called once over arrays.

    python benchmarks/bench_host_share.py [--worlds 256] [--steps 100] [--rounds 3] [--array-worlds 4096]

Issue #27's GPU target (300k env steps/s for physics and task at 4,096 worlds) leaves the host ~3.3 us
per world-step. This script measures how far today's step is from that, and how far a step made only of
array operations would be. Per round:

- ``host``: ``InterLevel-v0``'s batched env, ``--worlds`` worlds, the shipped policy acting (the policy
  itself is not timed; its episodes rarely end, so resets are mostly outside both figures). The figure
  is the step's time minus its physics, in us per world-step. The physics is timed inside
  the step: ``physics=`` gets a ``SerialPhysics`` that times its step less the env's callbacks, so
  nothing else of the step is changed;
- ``arrays``: the kernels the env calls, once each over ``--array-worlds`` worlds' state arrays (the
  env's worlds' states and carry tiled). These are the task's compiled step (observation, reward terms,
  fall, success, progress), the reward and the episode's end with the stall clocks, then the style
  features with their history shifted (``FeatureHistory.push_rows``). That is the host's cost if the
  step handled its worlds only as arrays, with the same formulas. Not in it: the state's copy from the
  device and the device's own step.

- ``resets``: ``--resets`` worlds of the same env reset through the batched env's own paths, in us per
  reset: one at a time (``reset_world``) and in groups (``reset_worlds``, the autoreset's: the worlds
  whose episodes ended at one step, ``--worlds / --episode-steps`` of them by default), and what the
  grouped resets add per world-step at one episode end every ``--episode-steps`` world-steps (default
  17: the random actions of ``bench_warp.py``, measured on 2026-11-29; early in training ~28). The
  grouped resets are timed twice: as with the C back-end (``mj_forward`` at the end of each) and as a
  device back-end's batched env makes them (``mj_kinematics``, ``HumanoidEnv._reset_forward``), the
  figure per world-step being the device's.

- ``device host`` (with ``--device-worlds W``, and the ``gpu`` extra): the host's share of a step with the
  state on the device (``physics="warp", state_on_device=True``: the ctrl up as one array, the state down
  and converted, the task over arrays, the info), W worlds on Warp's CPU device with its kernels replaced
  by nothing, so that only the host's work is timed (the state stays as the reset left it: no episode ends,
  no reset is in it), us per world-step.

Printed per round: the figures, host / arrays and the 3.3 us budget; at the end the medians. Results on
our machine are in ``docs/gpu.md`` ("Where the targets stand", "Measured on one NVIDIA H200").
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import mujoco
import numpy as np

import stairenv  # noqa: F401  (registers the ids)
from stairenv import pretrained
from stairenv.environments.batch_physics import SerialPhysics
from stairenv.humanoid.state import HumanoidState
from stairenv.style.features import FeatureHistory, amp_features
from stairenv.tasks import interlevel as task

#: host time per world-step that 300k env steps/s allows when the host works serially with the device
BUDGET_US = 1e6 / 300_000


class TimedSerialPhysics(SerialPhysics):
    """``SerialPhysics`` that adds up the time of its physics: its step less the env's callbacks."""

    def __init__(self) -> None:
        self.seconds = 0.0

    def step(self, worlds, nstep, then=None, meanwhile=None, collect=None) -> None:
        in_callbacks = 0.0

        def timed(callback):
            if callback is None:
                return None

            def call(*args) -> None:
                nonlocal in_callbacks
                start = time.perf_counter()
                callback(*args)
                in_callbacks += time.perf_counter() - start
            return call

        start = time.perf_counter()
        super().step(worlds, nstep, timed(then), timed(meanwhile), timed(collect))
        self.seconds += time.perf_counter() - start - in_callbacks


def host_us(venv, physics: TimedSerialPhysics, policy, obs: np.ndarray, steps: int) -> tuple[float, float, np.ndarray]:
    """The step's time minus its physics and the physics, us per world-step, over ``steps`` steps; the last
    observation."""
    physics.seconds, total = 0.0, 0.0
    for _ in range(steps):
        actions = policy(obs)
        start = time.perf_counter()
        obs, *_ = venv.step(actions)
        total += time.perf_counter() - start
    scale = 1e6 / (steps * venv.num_envs)
    return (total - physics.seconds) * scale, physics.seconds * scale, obs


def array_step(envs, worlds: int):
    """A function running the env's kernels once over ``worlds`` worlds' arrays (``envs``' states tiled)."""
    first = envs[0]
    state = type(first)._read_worlds(envs)
    reps = -(-worlds // len(envs))

    def tiled(array: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(np.tile(array, (reps,) + (1,) * (array.ndim - 1))[:worlds])

    state = HumanoidState(*(tiled(field) for field in state))
    carry = {path: tiled(values) for path, values in type(first)._take_carry(envs, None).items()}
    rotation = task.StairsGoal.unpack(carry["_packed_goal"]).rotation
    steps = np.full(worlds, 10, dtype=np.int64)
    history = np.zeros((worlds, *first._amp.frames.shape))
    rows = np.arange(worlds)

    def step() -> None:
        obs, results = task.interlevel_outcome_columns(state, carry["_prev_root"], carry["_packed_goal"], rotation,
                                                       first._reward_array, first.dt, first.termination_height,
                                                       first.success_radius)
        task.interlevel_reward_and_end(results[:, :task.NUM_REWARD_TERMS], results, steps, carry["_stall.approach"],
                                       carry["_stall.approach_at"], first._end_parameters)
        FeatureHistory.push_rows(history, rows, amp_features(state))
    return step


def arrays_us(step, worlds: int, calls: int) -> float:
    start = time.perf_counter()
    for _ in range(calls):
        step()
    return (time.perf_counter() - start) / (calls * worlds) * 1e6


def reset_us(venv, obs: np.ndarray, count: int, group: int, device: bool = False) -> float:
    """us per world reset, ``group`` worlds at a time (``reset_worlds``; one: ``reset_world``), the worlds
    in turn; each reset world's first observation written into ``obs``. ``device``: ending as on a device
    back-end (``mj_kinematics``; the C back-end's ``mj_forward`` again afterwards)."""
    worlds = np.arange(count) % venv.num_envs
    for env in venv.envs:
        env._reset_forward = mujoco.mj_kinematics if device else mujoco.mj_forward
    start = time.perf_counter()
    if group == 1:
        for i in worlds.tolist():
            obs[i] = venv.reset_world(i)[0]
    else:
        for at in range(0, count, group):
            rows = np.unique(worlds[at:at + group])
            obs[rows] = venv.reset_worlds(rows)[0]
    seconds = time.perf_counter() - start
    for env in venv.envs:
        env._reset_forward = mujoco.mj_forward
    return seconds / count * 1e6


def device_host_env(worlds: int, seed: int):
    """A state-on-device batched env on Warp's CPU device whose device work is stubbed out (see the module
    docstring), or None without MuJoCo Warp."""
    import importlib.util
    if importlib.util.find_spec("mujoco_warp") is None:
        return None
    venv = gym.make_vec("InterLevel-v0", num_envs=worlds, vectorization_mode="vector_entry_point", physics="warp",
                        state_on_device=True, physics_device="cpu")
    venv.reset(seed=seed)
    venv.step(np.zeros((worlds, 28)))    # kernels loaded, the device's buffers filled once
    physics = venv.physics
    # the substeps and the kinematics do nothing: what is left of the step is the host's
    physics._launch = lambda nstep: None
    physics._mjw = type("NoKernels", (), {"kinematics": staticmethod(lambda model, data: None),
                                          "OverflowType": physics._mjw.OverflowType})
    return venv


def device_host_us(venv, steps: int) -> float:
    actions = np.zeros((venv.num_envs, 28))
    start = time.perf_counter()
    for _ in range(steps):
        venv.step(actions)
    return (time.perf_counter() - start) / (steps * venv.num_envs) * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--worlds", type=int, default=256, help="worlds of the batched env")
    parser.add_argument("--steps", type=int, default=100, help="timed steps per round")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--array-worlds", type=int, default=4096, help="worlds of the array-only step")
    parser.add_argument("--resets", type=int, default=200, help="world resets timed per round")
    parser.add_argument("--episode-steps", type=float, default=17.0,
                        help="world-steps per episode end, to put the resets per world-step")
    parser.add_argument("--reset-group", type=int, default=None,
                        help="worlds reset together (default: --worlds / --episode-steps, the ended worlds of a step)")
    parser.add_argument("--device-worlds", type=int, default=0,
                        help="worlds of the state-on-device step whose host share is timed (0: not timed)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    group = args.reset_group or max(1, round(args.worlds / args.episode_steps))

    policy = pretrained.load("InterLevel-v0")
    physics = TimedSerialPhysics()
    venv = gym.make_vec("InterLevel-v0", num_envs=args.worlds, vectorization_mode="vector_entry_point",
                        physics=physics)
    obs, _ = venv.reset(seed=args.seed)
    *_, obs = host_us(venv, physics, policy, obs, 5)    # warm-up: compiled kernels loaded
    step = array_step(venv.envs, args.array_worlds)
    step()
    device_env = device_host_env(args.device_worlds, args.seed) if args.device_worlds else None
    if args.device_worlds and device_env is None:
        print("device host: not timed (MuJoCo Warp is not installed: pip install 'stairenv[gpu]')")
    hosts, arrays, alone, grouped, on_device, device_hosts = [], [], [], [], [], []
    for r in range(args.rounds):
        host, physics_us, obs = host_us(venv, physics, policy, obs, args.steps)
        array = arrays_us(step, args.array_worlds, max(1, args.steps // 10))
        one = reset_us(venv, obs, args.resets, 1)
        grouped.append(reset_us(venv, obs, args.resets, group))
        reset = reset_us(venv, obs, args.resets, group, device=True)
        hosts.append(host)
        arrays.append(array)
        alone.append(one)
        on_device.append(reset)
        if device_env is not None:
            device_hosts.append(device_host_us(device_env, max(1, args.steps // 5)))
            print(f"round {r}: device host {device_hosts[-1]:.2f} us per world-step ({args.device_worlds} worlds)")
        print(f"round {r}: host {host:.1f} us per world-step ({args.worlds} worlds; physics {physics_us:.0f} "
              f"on one thread), arrays {array:.2f} "
              f"({args.array_worlds} worlds), host / arrays {host / array:.0f}x; budget at 300k env steps/s "
              f"{BUDGET_US:.1f}; a reset {one:.0f} us alone, {grouped[-1]:.0f} in groups of {group}, {reset:.0f} "
              f"as on a device ({reset / args.episode_steps:.1f} per world-step at one end per "
              f"{args.episode_steps:g})")
    host, array, one, together, reset = (float(np.median(values))
                                         for values in (hosts, arrays, alone, grouped, on_device))
    print(f"median: host {host:.1f} us per world-step, arrays {array:.2f}, host / arrays {host / array:.0f}x, "
          f"arrays / budget {array / BUDGET_US:.2f}; a reset {one:.0f} us alone, {together:.0f} in groups of "
          f"{group} ({one / together:.1f}x), {reset:.0f} as on a device ({one / reset:.1f}x), "
          f"{reset / args.episode_steps:.1f} per world-step at one end per {args.episode_steps:g}")
    if device_env is not None:
        print(f"median: device host {float(np.median(device_hosts)):.2f} us per world-step "
              f"({args.device_worlds} worlds, the state on the device, no resets)")
        device_env.close()
    venv.close()


if __name__ == "__main__":
    main()
