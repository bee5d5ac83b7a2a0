"""AMP at batch: the style wrapper's cost relative to the bare vectorised env, on a
``DummyVecEnv`` and on the natively batched env, each step's N windows scored in one call.

    python benchmarks/bench_amp_batch.py [--dummy-n 4,8,16] [--batched-n 64] [--transitions 4096]
                                         [--rounds 7] [--train off,background] [--batched-scoring auto]

Groups, each timed against its own bare vec env:

- ``dummy-N``: SB3 ``DummyVecEnv`` of N InterLevel-v0 envs, the wrapper (``scoring``);
- ``batched-N``: ``stairenv.vec_sb3.make_sb3_vec_env("InterLevel-v0", n_envs=N)``, the wrapper
  (``scoring-<back-end>``: ``scoring="auto"`` and the back-ends of ``--batched-scoring``).

``--train``: ``off`` (the discriminator scores but never trains: the scoring's price alone),
``background`` (training rounds in a worker thread, the paper's schedule: 2 minibatches of 256 +
256 every 2048 transitions), ``sync`` (rounds in the calling thread).

Every run steps ``--transitions`` env transitions (N x steps) with the same random actions after a
seeded reset. Within a round every variant of every group runs once, in an order that rotates from
round to round (A, B, A, B ...); a variant's ratio is the median over rounds of wrapped / bare of
the same round, so a machine whose load changes between rounds skews it little. ``us/tr`` is the
median wall time per env transition, comparable across groups (absolute, so it moves with the
machine's load; the ratios much less). Target: wrapper <= 1.15x the bare batched env.

Figures (2-core AMD EPYC VM, loaded: two training runs and other tests on both cores, this at
``nice 10``; single rounds spread 0.5-2.8x, so medians move by ~+-0.1 between runs). Two runs
before pipelined per-env scoring was removed (``pipeline`` = a worker thread scoring each env's
window while the next env of the ``DummyVecEnv`` stepped; 7 and 11 rounds, 4096 transitions):

| group (train off)  | bare us/tr | pipelined      | one call (plain) |
| ------------------ | ---------- | -------------- | ---------------- |
| dummy-4            | 442        | 1.59x          | 1.11x            |
| dummy-8            | 420, 392   | 1.23x, 1.17x   | 1.13x, 1.08x     |
| dummy-16           | 378, 399   | 1.45x, 1.60x   | 1.15x, 1.15x     |
| batched-64         | 419, 387   | (not possible) | 1.06x, 1.12x     |

With background training (pipelined / plain; run 1, run 2): dummy-4 1.91 / 1.45 (run 1 only),
dummy-8 1.33 / 1.40 and 1.34 / 1.29, dummy-16 1.36 / 1.22 and 1.31 / 1.24; batched-64 plain 1.21
and 1.28. On the loaded machine the pipeline's worker has no spare core: it lost to plain scoring
of the same ``DummyVecEnv`` in 9 of 10 comparisons. Per transition the bare envs cost about the
same on the loaded machine (table); in a short run on the then idle machine the batched env's bare
step cost 213 us per transition (8 worlds) against the ``DummyVecEnv``'s 343 us (4 envs), a gap
no pipeline can close (it can at best bring the wrapper to 1.0x of that slower bare env). So the
pipeline was removed. Scoring alone meets the 1.15x target on the batched env; training rounds
(~106 ms per 2048 transitions, on cores the physics pool already uses) do not.

After the removal, same machine and load (7 rounds, single rounds 1.03-1.38x but for one 2.11):
dummy-8 1.11x scoring alone, 1.29x with background training, 1.23x with synchronous training;
batched-64 1.11x scoring alone (``scoring="torch"``: 1.10x), 1.23x background, 1.24x synchronous;
with one torch thread 1.26x background, 1.27x synchronous. With no spare core, background
training takes nothing off the step loop.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
import torch
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import DummyVecEnv

import stairenv  # noqa: F401  (registers the ids)
from stairenv.motion.rsi import load_reference_library
from stairenv.style.reference import ReferenceWindows
from stairenv.style.wrappers import AMPStyleReward, AMPVecEnvWrapper
from stairenv.vec_sb3 import make_sb3_vec_env

ENV_ID = "InterLevel-v0"
TRAIN_MODES = {"off": {"train": False}, "background": {"background_training": True}, "sync": {}}


def run(venv, actions: np.ndarray) -> float:
    """Seconds for ``len(actions)`` vectorised steps after a seeded reset."""
    venv.seed(0)
    venv.reset()
    start = time.perf_counter()
    for action in actions:
        venv.step(action)
    return time.perf_counter() - start


def wrapped(venv, reference: ReferenceWindows, style_kw: dict) -> AMPVecEnvWrapper:
    torch.manual_seed(0)
    style = AMPStyleReward(reference, **style_kw)
    # A long run's steady state: the replay buffer's pages already touched.
    style.replay.data.fill(0.0)
    return AMPVecEnvWrapper(venv, style)


def groups(args, reference: ReferenceWindows) -> dict[str, dict[str, object]]:
    """group -> {variant: vec env}; every group has its ``bare`` variant."""
    out: dict[str, dict[str, object]] = {}
    for train in args.train:
        style_kw = TRAIN_MODES[train]
        for n in args.dummy_n:
            def dummy(n=n):
                return make_vec_env(ENV_ID, n_envs=n, seed=0, vec_env_cls=DummyVecEnv)
            out[f"dummy-{n}/{train}"] = {
                "bare": dummy(),
                "scoring": wrapped(dummy(), reference, style_kw),
            }
        for n in args.batched_n:
            variants = {"bare": make_sb3_vec_env(ENV_ID, n_envs=n, seed=0)}
            for scoring in args.batched_scoring:
                variants[f"scoring-{scoring}"] = wrapped(make_sb3_vec_env(ENV_ID, n_envs=n, seed=0), reference,
                                                         {**style_kw, "scoring": scoring})
            out[f"batched-{n}/{train}"] = variants
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--dummy-n", default="4,8,16", help="DummyVecEnv sizes (comma-separated; '' for none)")
    parser.add_argument("--batched-n", default="64", help="batched env sizes (comma-separated; '' for none)")
    parser.add_argument("--batched-scoring", default="auto", help="scoring back-ends on the batched env")
    parser.add_argument("--transitions", type=int, default=4096, help="env transitions per run")
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--train", default="off,background", help=f"of {', '.join(TRAIN_MODES)}")
    parser.add_argument("--torch-threads", type=int, default=None, help="default: torch's")
    args = parser.parse_args()

    def ints(text: str) -> list[int]:
        return [int(v) for v in text.split(",") if v.strip()]
    args.dummy_n, args.batched_n = ints(args.dummy_n), ints(args.batched_n)
    args.batched_scoring = [v.strip() for v in args.batched_scoring.split(",") if v.strip()]
    args.train = [v.strip() for v in args.train.split(",") if v.strip()]
    unknown = [v for v in args.train if v not in TRAIN_MODES]
    if unknown:
        raise SystemExit(f"unknown --train {unknown}; known: {list(TRAIN_MODES)}")
    if args.torch_threads is not None:
        torch.set_num_threads(args.torch_threads)

    reference = ReferenceWindows(load_reference_library(None), num_frames=2, fps=30.0)
    table = groups(args, reference)
    rng = np.random.default_rng(0)
    actions = {}
    for name, variants in table.items():
        n = variants["bare"].num_envs
        steps = max(args.transitions // n, 1)
        actions[name] = rng.uniform(-1, 1, (steps, n, 28)).astype(np.float32)
        for venv in variants.values():  # warm-up: compile, caches, a training round
            run(venv, actions[name][: max(steps // 4, 2)])

    runs = [(name, variant) for name, variants in table.items() for variant in variants]
    times: dict[tuple[str, str], list[float]] = {key: [] for key in runs}
    for r in range(args.rounds):
        for name, variant in runs[r % len(runs):] + runs[: r % len(runs)]:
            times[name, variant].append(run(table[name][variant], actions[name]))

    print(f"{ENV_ID}, {args.transitions} transitions per run, {args.rounds} rounds (interleaved), "
          f"torch threads {torch.get_num_threads()}")
    print(f"{'group':<20} {'variant':<22} {'ms/step':>8} {'us/tr':>7} {'ratio':>6} {'(min-max)':>11}")
    for name, variants in table.items():
        steps, n = actions[name].shape[:2]
        bare = times[name, "bare"]
        for variant in variants:
            mine = times[name, variant]
            ratios = [w / b for w, b in zip(mine, bare)]
            per_step = statistics.median(mine) / steps
            print(f"{name:<20} {variant:<22} {per_step * 1e3:8.3f} {per_step / n * 1e6:7.1f} "
                  f"{statistics.median(ratios):6.3f} ({min(ratios):.2f}-{max(ratios):.2f})")
    print("ratio: median over rounds of wrapped / bare in the same round (target <= 1.15); us/tr: wall time "
          "per env transition (median), comparable across groups")
    for variants in table.values():
        for venv in variants.values():
            venv.close()


if __name__ == "__main__":
    main()
