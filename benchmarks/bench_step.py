"""Step and reset cost of InterLevel-v0, as ratios measured in one run.

    python benchmarks/bench_step.py [--steps 3000] [--rounds 3] [--json out.json]

Compares, on the same model, from the same initial state (a seeded reset):
- ``env``: ``gym.make("InterLevel-v0")`` step (wrappers included), seeded random actions;
- ``raw``: ``mujoco.mj_step(model, data, frame_skip)`` with the env's own PD targets for those
  actions (``offset + scale * a`` as the env computes them), so that both step the same trajectory:
  each round checks that they end in the same state, bit for bit;
- Gymnasium's ``Humanoid-v5`` step (its own model, frame_skip 5 at 333 Hz);
- reset with a new staircase, in milliseconds and in env steps.
Falls are not terminated during the timed run (termination_height=0), so every timed call is a
step. Rounds interleave the timings (env and raw in alternating order); the ratios are the medians
of each round's ratios, all from this one run.
Targets (issue #22): env/raw <= 1.15; reset < 10 env steps.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import gymnasium as gym
import mujoco
import numpy as np

import stairenv  # noqa: F401  (registers the envs)


def end_state(env) -> bytes:
    data = env.unwrapped.data
    return data.qpos.tobytes() + data.qvel.tobytes() + np.float64(data.time).tobytes()


def time_env_steps(env, actions: np.ndarray, seed: int) -> tuple[float, bytes]:
    """Seconds per env step, and the state the steps end in."""
    env.reset(seed=seed)
    start = time.perf_counter()
    for action in actions:
        env.step(action)
    return (time.perf_counter() - start) / len(actions), end_state(env)


def time_raw_steps(env, ctrls: np.ndarray, seed: int) -> tuple[float, bytes]:
    """Seconds per ``mj_step(frame_skip)`` from the env's seeded reset state, and the state they end in."""
    env.reset(seed=seed)
    model, data, frame_skip = env.unwrapped.model, env.unwrapped.data, env.unwrapped.frame_skip
    start = time.perf_counter()
    for ctrl in ctrls:
        data.ctrl[:] = ctrl
        mujoco.mj_step(model, data, frame_skip)
    return (time.perf_counter() - start) / len(ctrls), end_state(env)


def time_humanoid_v5(steps: int, seed: int) -> float:
    env = gym.make("Humanoid-v5")
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    actions = rng.uniform(env.action_space.low, env.action_space.high, (steps,) + env.action_space.shape)
    start = time.perf_counter()
    for action in actions:
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()
    elapsed = (time.perf_counter() - start) / steps
    env.close()
    return elapsed


def time_resets(env, n: int, seed: int) -> float:
    env.reset(seed=seed)
    start = time.perf_counter()
    for _ in range(n):
        env.reset()
    return (time.perf_counter() - start) / n


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=3000)
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--resets", type=int, default=300)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", type=str, default=None)
    args = parser.parse_args()

    env = gym.make("InterLevel-v0", termination_height=0.0, max_episode_steps=10**9)
    rng = np.random.default_rng(args.seed)
    actions = rng.uniform(-1.0, 1.0, (args.steps, 28))
    unwrapped = env.unwrapped
    # The env's own PD targets (its action map, _apply_action: offset + scale * a, unclipped; MuJoCo
    # clamps them to the ctrlrange in both loops).
    ctrls = unwrapped._ctrl_offset + unwrapped._ctrl_scale * actions
    reset_env = gym.make("InterLevel-v0")

    # Warm up (numba kernels load from cache or compile, caches fill).
    time_env_steps(env, actions[:200], args.seed)
    time_raw_steps(env, ctrls[:200], args.seed)

    env_t, raw_t, v5_t, reset_t = [], [], [], []
    for r in range(args.rounds):
        timers = {"env": lambda: time_env_steps(env, actions, args.seed + r),
                  "raw": lambda: time_raw_steps(env, ctrls, args.seed + r)}
        order = ("env", "raw") if r % 2 == 0 else ("raw", "env")
        timed = {name: timers[name]() for name in order}
        (env_s, env_end), (raw_s, raw_end) = timed["env"], timed["raw"]
        if env_end != raw_end:
            raise RuntimeError(f"round {r}: the env and the raw loop ended in different states")
        env_t.append(env_s)
        raw_t.append(raw_s)
        v5_t.append(time_humanoid_v5(args.steps, args.seed + r))
        reset_t.append(time_resets(reset_env, args.resets, args.seed + r))

    step_ratio = statistics.median(e / r for e, r in zip(env_t, raw_t))
    v5_ratio = statistics.median(e / v for e, v in zip(env_t, v5_t))
    reset_steps = statistics.median(rs / e for rs, e in zip(reset_t, env_t))
    results = {
        "env_step_us": statistics.median(env_t) * 1e6,
        "raw_step_us": statistics.median(raw_t) * 1e6,
        "humanoid_v5_step_us": statistics.median(v5_t) * 1e6,
        "reset_ms": statistics.median(reset_t) * 1e3,
        "env_over_raw": step_ratio,
        "env_over_humanoid_v5": v5_ratio,
        "reset_in_env_steps": reset_steps,
        "env_steps_per_second": 1.0 / statistics.median(env_t),
    }
    print(f"InterLevel-v0 step (gym.make)   {results['env_step_us']:8.1f} us  ({results['env_steps_per_second']:.0f} steps/s)")
    print(f"raw mj_step x{unwrapped.frame_skip} (same model)  {results['raw_step_us']:8.1f} us")
    print(f"Humanoid-v5 step                {results['humanoid_v5_step_us']:8.1f} us")
    print(f"reset (new staircase)           {results['reset_ms']:8.3f} ms")
    print(f"ratio env / raw physics         {step_ratio:8.3f}   (target <= 1.15; same trajectory, checked)")
    print(f"ratio env / Humanoid-v5         {v5_ratio:8.3f}")
    print(f"reset cost in env steps         {reset_steps:8.2f}   (target < 10)")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=2)


if __name__ == "__main__":
    main()
