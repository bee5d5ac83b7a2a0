"""Step and reset cost of InterLevel-v0, as ratios measured in one run.

    python benchmarks/bench_step.py [--steps 3000] [--rounds 3] [--json out.json]

Compares, on the same model, the same initial state and the same actions:
- ``env``: ``gym.make("InterLevel-v0")`` step (wrappers included), random actions;
- ``raw``: ``mujoco.mj_step(model, data, frame_skip)`` with the same PD targets;
- Gymnasium's ``Humanoid-v5`` step (its own model, frame_skip 5 at 333 Hz);
- reset with a new staircase, in milliseconds and in env steps.
Falls are not terminated during the timed run (termination_height=0), so
every timed call is a step; rounds are interleaved and the median is reported.
Targets (issue: InterLevel-v0): env/raw <= 1.3; reset < 10 env steps.
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


def time_env_steps(env, actions: np.ndarray, seed: int) -> float:
    env.reset(seed=seed)
    start = time.perf_counter()
    for action in actions:
        env.step(action)
    return (time.perf_counter() - start) / len(actions)


def time_raw_steps(env, ctrls: np.ndarray, seed: int) -> float:
    env.reset(seed=seed)
    model, data, frame_skip = env.unwrapped.model, env.unwrapped.data, env.unwrapped.frame_skip
    start = time.perf_counter()
    for ctrl in ctrls:
        data.ctrl[:] = ctrl
        mujoco.mj_step(model, data, frame_skip)
    return (time.perf_counter() - start) / len(ctrls)


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
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--resets", type=int, default=300)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", type=str, default=None)
    args = parser.parse_args()

    env = gym.make("InterLevel-v0", termination_height=0.0, max_episode_steps=10**9)
    rng = np.random.default_rng(args.seed)
    actions = rng.uniform(-1.0, 1.0, (args.steps, 28))
    unwrapped = env.unwrapped
    ctrls = np.clip(unwrapped._ctrl_offset + unwrapped._ctrl_scale * actions, *unwrapped.model.actuator_ctrlrange.T)
    reset_env = gym.make("InterLevel-v0")

    # Warm up (numba kernels load from cache or compile, caches fill).
    time_env_steps(env, actions[:200], args.seed)
    time_raw_steps(env, ctrls[:200], args.seed)

    env_t, raw_t, v5_t, reset_t = [], [], [], []
    for r in range(args.rounds):
        env_t.append(time_env_steps(env, actions, args.seed + r))
        raw_t.append(time_raw_steps(env, ctrls, args.seed + r))
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
    print(f"ratio env / raw physics         {step_ratio:8.3f}   (target <= 1.3)")
    print(f"ratio env / Humanoid-v5         {v5_ratio:8.3f}")
    print(f"reset cost in env steps         {reset_steps:8.2f}   (target < 10)")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=2)


if __name__ == "__main__":
    main()
