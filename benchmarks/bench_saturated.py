"""Saturated-action soak: physics divergences per million steps, for every env id.

A trained policy at its bounds sends actions of +-1, and PPO's clipped Gaussian
does so often. This soak drives each registered id with such actions and counts
the steps that end with ``info["physics_unstable"]`` (MuJoCo's own divergence
check or the env's speed bound, ``stairenv.environments.base``):

- ``bang``: a fresh random +-1 on every DoF at every step (the harshest);
- ``bang-held``: random +-1, each DoF's sign redrawn with probability 0.2 per step;
- ``gauss3``: ``clip(3 * N(0, 1), -1, 1)``, PPO's Gaussian with std 3.

Termination is ignored: after a fall the character keeps acting until the time
limit truncates the episode, so most of the budget is spent in the fallen,
flailing states where divergences used to happen. Also printed: the largest
absolute observation and joint speed seen, to show that nothing huge reaches a
normaliser.

    python benchmarks/bench_saturated.py                       # 1M steps per id and mode
    python benchmarks/bench_saturated.py --steps 20000 --ids InterLevel-v0 --modes bang
"""

from __future__ import annotations

import argparse
import time
import warnings

import gymnasium as gym
import numpy as np

from stairenv import ENV_IDS  # importing stairenv registers the ids

MODES = ("bang", "bang-held", "gauss3")


def saturated_actions(mode: str, rng: np.random.Generator, previous: np.ndarray) -> np.ndarray:
    if mode == "bang":
        return np.sign(rng.standard_normal(previous.shape))
    if mode == "bang-held":
        redraw = rng.random(previous.shape) < 0.2
        return np.where(redraw, np.sign(rng.standard_normal(previous.shape)), previous)
    if mode == "gauss3":
        return np.clip(3.0 * rng.standard_normal(previous.shape), -1.0, 1.0)
    raise ValueError(f"mode must be one of {MODES}, got {mode!r}")


def soak(env_id: str, mode: str, steps: int, seed: int = 0) -> dict:
    """Step ``env_id`` ``steps`` times with saturated actions; divergences and magnitudes."""
    env = gym.make(env_id)
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    action = np.sign(rng.standard_normal(env.action_space.shape))
    unwrapped = env.unwrapped
    joints = unwrapped._idx.qvel_joints
    unstable = episodes = 0
    max_obs = max_joint_speed = 0.0
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for _ in range(steps):
            action = saturated_actions(mode, rng, action)
            obs, _, _, truncated, info = env.step(action)
            max_obs = max(max_obs, float(np.abs(obs).max()))
            max_joint_speed = max(max_joint_speed, float(np.abs(unwrapped.data.qvel[joints]).max()))
            if info["physics_unstable"]:
                unstable += 1
            if truncated:  # time limit or unstable physics; falls are stepped through
                episodes += 1
                env.reset()
    env.close()
    return {"id": env_id, "mode": mode, "steps": steps, "episodes": episodes, "unstable": unstable,
            "per_million": unstable * 1e6 / steps, "max_obs": max_obs,
            "max_joint_speed": max_joint_speed, "seconds": time.perf_counter() - start}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=1_000_000, help="steps per id and mode")
    parser.add_argument("--ids", default=",".join(ENV_IDS), help="comma-separated env ids")
    parser.add_argument("--modes", default=",".join(MODES), help=f"comma-separated, from {MODES}")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    print(f"{'id':22s} {'mode':10s} {'steps':>9s} {'episodes':>8s} {'unstable':>8s} {'per 1M':>7s} "
          f"{'max|obs|':>9s} {'max joint speed':>15s} {'s':>6s}")
    for env_id in args.ids.split(","):
        for mode in args.modes.split(","):
            r = soak(env_id, mode, args.steps, args.seed)
            print(f"{r['id']:22s} {r['mode']:10s} {r['steps']:9d} {r['episodes']:8d} {r['unstable']:8d} "
                  f"{r['per_million']:7.1f} {r['max_obs']:9.1f} {r['max_joint_speed']:15.1f} {r['seconds']:6.0f}",
                  flush=True)


if __name__ == "__main__":
    main()
