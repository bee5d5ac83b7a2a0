"""The natively batched env against ``SyncVectorEnv`` and against the raw physics limit.

    python benchmarks/bench_vector.py [--ids InterLevel-v0,PlaMo-v0,SIMS-Sit-v0] [--n-envs 64]
                                      [--steps 60] [--rounds 7] [--physics threads]

For each id, every round times in turn (the order rotates from round to round):

- ``batched``: ``gym.make_vec(id, n, vectorization_mode="vector_entry_point")``, env steps per second;
- ``sync``: ``gym.make_vec(id, n, vectorization_mode="sync")`` (``SyncVectorEnv`` of the same env);
- ``limit``: the raw physics limit, serial ``mujoco.mj_step(model, data, frame_skip)`` over copies of the
  batched env's N worlds, in worlds per second, times the cores (``os.sched_getaffinity``);
- ``physics alone``: the batched env's ``BatchPhysics`` over copies of the worlds with nothing else, what
  parallel physics reaches on the machine as it is (on cores shared with other work, below the limit).

Both envs get the same actions (uniform in [-0.3, 0.3], seeded), so resets happen inside the timed steps
for both. Printed: each round's ratios batched / sync and batched / limit, and their median, min and
max over rounds (targets for InterLevel-v0 on 2 cores: >= 1.7x sync, >= 0.85x the limit). The ratios of
one round come from back-to-back timings, so a machine whose load changes between rounds skews them
little; the spread over rounds says how noisy the machine was.
"""

from __future__ import annotations

import argparse
import os
import time

import gymnasium as gym
import mujoco
import numpy as np

import stairenv  # noqa: F401  (registers the ids)


def time_env(env, actions) -> float:
    start = time.perf_counter()
    for a in actions:
        env.step(a)
    return len(actions) * env.num_envs / (time.perf_counter() - start)


def copied_worlds(venv) -> list:
    worlds = [(env.model, mujoco.MjData(env.model)) for env in venv.envs]
    for (model, data), env in zip(worlds, venv.envs):
        mujoco.mj_copyData(data, model, env.data)
    return worlds


def time_limit(venv, steps: int, cores: int) -> float:
    """Serial mj_step over copies of the worlds, worlds per second, times the cores."""
    worlds, frame_skip = copied_worlds(venv), venv.envs[0].frame_skip
    start = time.perf_counter()
    for _ in range(steps):
        for model, data in worlds:
            mujoco.mj_step(model, data, frame_skip)
    return steps * len(worlds) / (time.perf_counter() - start) * cores


def time_pool(venv, steps: int) -> float:
    """The batched env's own BatchPhysics over copies of the worlds, nothing else: what parallel physics
    reaches on this machine now (below the limit where the cores are shared with other work)."""
    worlds, frame_skip = copied_worlds(venv), venv.envs[0].frame_skip
    start = time.perf_counter()
    for _ in range(steps):
        venv.physics.step(worlds, frame_skip)
    return steps * len(worlds) / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--ids", default="InterLevel-v0,PlaMo-v0,SIMS-Sit-v0")
    parser.add_argument("--n-envs", type=int, default=64)
    parser.add_argument("--steps", type=int, default=60)
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--physics", default="threads")
    args = parser.parse_args()
    cores = len(os.sched_getaffinity(0))
    print(f"{cores} cores, {args.n_envs} worlds, {args.steps} steps x {args.rounds} rounds, physics={args.physics}")
    for env_id in args.ids.split(","):
        batched = gym.make_vec(env_id, num_envs=args.n_envs, vectorization_mode="vector_entry_point",
                               physics=args.physics)
        sync = gym.make_vec(env_id, num_envs=args.n_envs, vectorization_mode="sync")
        rng = np.random.default_rng(0)
        batched.reset(seed=0)
        sync.reset(seed=0)
        warm = rng.uniform(-0.3, 0.3, (5, args.n_envs, 28)).astype(np.float32)
        time_env(batched, warm)
        time_env(sync, warm)
        rows = []
        for r in range(args.rounds):
            actions = rng.uniform(-0.3, 0.3, (args.steps, args.n_envs, 28)).astype(np.float32)
            timers = [("batched", lambda: time_env(batched, actions)), ("sync", lambda: time_env(sync, actions)),
                      ("limit", lambda: time_limit(batched, args.steps, cores)),
                      ("pool", lambda: time_pool(batched, args.steps))]
            timers = timers[r % 4:] + timers[:r % 4]
            rates = {name: timer() for name, timer in timers}
            rows.append((rates["batched"] / rates["sync"], rates["batched"] / rates["limit"],
                         rates["batched"] / rates["pool"], rates["pool"] / rates["limit"]))
            print(f"  {env_id} round {r}: batched {rates['batched']:.0f}/s, sync {rates['sync']:.0f}/s, "
                  f"limit {rates['limit']:.0f}/s, physics alone {rates['pool']:.0f}/s -> {rows[-1][0]:.2f}x sync, "
                  f"{rows[-1][1]:.2f}x limit, {rows[-1][2]:.2f}x physics alone (which is {rows[-1][3]:.2f}x limit)")
        names = ("batched / sync", "batched / physics limit", "batched / parallel physics alone",
                 "parallel physics alone / limit")
        print(f"{env_id}: " + "; ".join(f"{name} median {np.median(col):.2f}x (min {col.min():.2f}, max "
                                        f"{col.max():.2f})" for name, col in zip(names, np.array(rows).T)))
        batched.close()
        sync.close()


if __name__ == "__main__":
    main()
