"""The InterLevel evaluation, one episode after another against N worlds of the batched env.

    python benchmarks/bench_evaluate.py [--policy pretrained] [--episodes 8] [--num-envs 32] [--rounds 3]

Each round times, back to back (the order alternating between rounds), ``evaluate(policy,
step_heights=PAPER_STEP_HEIGHTS, episodes=E)`` with ``num_envs=1`` (one env, episode after episode)
and with ``num_envs=N`` (the env's batched vector env, physics on every core, the policy called on the
batch), and prints episodes per second of each and their ratio, then the median, min and max of the
ratio over rounds. Both runs play the same episodes (seeds and staircases); with an MLP policy a
chaotic episode can end differently (the batch's matrix products round differently), so the
progress and early-termination rates of the two are printed beside the timings.

Idle 2-core machine, the shipped policy: ``--episodes 48 --num-envs 16 --rounds 1``: 5.35 against
6.05 episodes/s, 1.13x; ``--episodes 8 --num-envs 32 --rounds 2``: 0.94x and 1.04x (8 worlds per
height: the batch lasts as long as its longest episode, and worlds without an episode left still step).
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import stairenv  # noqa: F401  (registers the ids)
from stairenv.__main__ import resolve_policy
from stairenv.evaluation.interlevel import PAPER_STEP_HEIGHTS, evaluate
from stairenv.evaluation.policies import load_policy


def timed(policy, episodes: int, num_envs: int, seed: int) -> tuple[float, object]:
    start = time.perf_counter()
    report = evaluate(policy, episodes=episodes, seed=seed, step_heights=PAPER_STEP_HEIGHTS, progress_bar=False,
                      num_envs=num_envs)
    return report.overall.n / (time.perf_counter() - start), report


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--policy", default="pretrained",
                        help="'pretrained' (the policy the package ships) or a policy spec for evaluate.py "
                             "(default: %(default)s)")
    parser.add_argument("--episodes", type=int, default=8, help="episodes per paper height and run")
    parser.add_argument("--num-envs", type=int, default=32, help="worlds of the batched evaluation")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--seed", type=int, default=900000)
    args = parser.parse_args()

    env = gym.make("InterLevel-v0")
    policy = load_policy(resolve_policy(args.policy, "InterLevel-v0")[0], env)    # one object for both runs
    env.close()
    timed(policy, 1, min(2, args.num_envs), args.seed)    # compile the JIT kernels outside the timings
    ratios = []
    for r in range(args.rounds):
        order = (1, args.num_envs) if r % 2 == 0 else (args.num_envs, 1)
        rates, reports = {}, {}
        for n in order:
            rates[n], reports[n] = timed(policy, args.episodes, n, args.seed + 1000 * r)
        ratio = rates[args.num_envs] / rates[1]
        ratios.append(ratio)
        one, many = reports[1].overall, reports[args.num_envs].overall
        print(f"round {r}: one env {rates[1]:.2f} episodes/s, {args.num_envs} worlds {rates[args.num_envs]:.2f} "
              f"episodes/s: {ratio:.2f}x  (progress / ET: {one.progress_pct:.1f} / {one.et_pct:.1f}% and "
              f"{many.progress_pct:.1f} / {many.et_pct:.1f}%)")
    print(f"batched / one env over {args.rounds} rounds: median {np.median(ratios):.2f}x "
          f"(min {min(ratios):.2f}, max {max(ratios):.2f}), {4 * args.episodes} episodes each")


if __name__ == "__main__":
    main()
