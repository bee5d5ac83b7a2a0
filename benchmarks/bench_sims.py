"""Step and reset cost of SIMS-Sit-v0 relative to InterLevel-v0, measured interleaved in one run.

    python benchmarks/bench_sims.py [--steps 2000] [--rounds 5] [--resets 30] [--json out.json]

Times, with the same random actions for all three:
- ``InterLevel-v0``: ``gym.make("InterLevel-v0")`` (the reference);
- ``SIMS-Sit-v0`` on a single generated piece (the preset, ``scene="object"``);
- ``SIMS-Sit-v0`` in a generated furnished room (``scene="room"``);
- reset cost of each (SIMS: a new scene every ``scene_resample_every`` = 10 resets, so the
  mean over ``--resets`` consecutive resets includes that share of scene rebuilds).
Falls are not terminated during the timed steps (fall / termination height 0, no time limit),
so every timed call is a step. Rounds are interleaved and medians are reported; ratios are
SIMS / InterLevel. The SIMS envs use the hashing text encoder (the caption embedding is
computed once per reset, not per step).
(Room retrieval over 1,000 rooms: benchmarks/bench_retrieval.py.)
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import gymnasium as gym
import numpy as np

import stairenv  # noqa: F401  (registers the envs)

SIMS_COMMON = {"text_encoder": "hashing", "fall_height": 0.0, "max_episode_steps": 10**9}
VARIANTS: dict[str, tuple[str, dict]] = {
    "interlevel": ("InterLevel-v0", {"termination_height": 0.0, "max_episode_steps": 10**9}),
    "sims_object": ("SIMS-Sit-v0", dict(SIMS_COMMON, scene="object")),
    "sims_room": ("SIMS-Sit-v0", dict(SIMS_COMMON, scene="room")),
}


def time_steps(env: gym.Env, actions: np.ndarray, seed: int) -> float:
    env.reset(seed=seed)
    start = time.perf_counter()
    for action in actions:
        _, _, _, truncated, info = env.step(action)
        if truncated and info.get("physics_unstable"):
            env.reset()
    return (time.perf_counter() - start) / len(actions)


def time_resets(env: gym.Env, n: int, seed: int) -> float:
    env.reset(seed=seed)
    start = time.perf_counter()
    for _ in range(n):
        env.reset()
    return (time.perf_counter() - start) / n


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--resets", type=int, default=30)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", type=str, default=None)
    args = parser.parse_args(argv)

    envs = {name: gym.make(env_id, **kwargs) for name, (env_id, kwargs) in VARIANTS.items()}
    rng = np.random.default_rng(args.seed)
    actions = rng.uniform(-1.0, 1.0, (args.steps, 28)).astype(np.float32)
    for env in envs.values():  # warm up: numba kernels load, caches fill, first scene built
        time_steps(env, actions[:100], args.seed)

    step_t: dict[str, list[float]] = {name: [] for name in envs}
    reset_t: dict[str, list[float]] = {name: [] for name in envs}
    for r in range(args.rounds):
        for name, env in envs.items():
            step_t[name].append(time_steps(env, actions, args.seed + r))
        for name, env in envs.items():
            reset_t[name].append(time_resets(env, args.resets, args.seed + r))

    results: dict = {"steps": args.steps, "rounds": args.rounds, "resets": args.resets}
    for name in envs:
        results[f"{name}_step_us"] = statistics.median(step_t[name]) * 1e6
        results[f"{name}_reset_ms"] = statistics.median(reset_t[name]) * 1e3
    for name in ("sims_object", "sims_room"):
        results[f"{name}_step_over_interlevel"] = statistics.median(
            s / i for s, i in zip(step_t[name], step_t["interlevel"]))
        results[f"{name}_reset_over_interlevel"] = statistics.median(
            s / i for s, i in zip(reset_t[name], reset_t["interlevel"]))
        results[f"{name}_reset_in_steps"] = statistics.median(
            rs / st for rs, st in zip(reset_t[name], step_t[name]))
    for env in envs.values():
        env.close()

    print(f"{'env':28s} {'step (us)':>10s} {'x InterLevel':>13s} {'reset (ms)':>11s} {'x InterLevel':>13s}")
    labels = {"interlevel": "InterLevel-v0", "sims_object": "SIMS-Sit-v0 (one object)",
              "sims_room": "SIMS-Sit-v0 (furnished room)"}
    for name, label in labels.items():
        step_ratio = results.get(f"{name}_step_over_interlevel", 1.0)
        reset_ratio = results.get(f"{name}_reset_over_interlevel", 1.0)
        print(f"{label:28s} {results[f'{name}_step_us']:10.1f} {step_ratio:13.2f} "
              f"{results[f'{name}_reset_ms']:11.2f} {reset_ratio:13.2f}")
    print(f"reset in env steps: object {results['sims_object_reset_in_steps']:.1f}, "
          f"room {results['sims_room_reset_in_steps']:.1f}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=2)
    return results


if __name__ == "__main__":
    main()
