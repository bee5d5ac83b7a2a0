"""Fingerprints of seeded trajectories of every registered id, to show that a speed-up changes no bit.

    python benchmarks/trajectory_hashes.py --record hashes.json   # on the code before the change
    python benchmarks/trajectory_hashes.py --check hashes.json    # after: exits 1 on any difference

For each id: the single env (``gym.make``, wrappers included, a short episode limit so that
truncations and resets happen) and the batched env (``gym.make_vec(..., "vector_entry_point")``, 4
worlds, in both autoreset modes) run ``--steps`` steps of seeded uniform actions in [-1, 1] from a
seeded reset; at two steps a world's state is broken before the step (a root speed far beyond the
body's, which the speed check catches, then a NaN joint angle that MuJoCo resets the data for, which
the divergence check catches), so that the unstable-physics branch is fingerprinted too. Hashed,
separately: observations, rewards, terminated, truncated and every info value (numbers and arrays by
dtype, shape and bytes; nested dicts and object arrays element by element).
The hashes are comparable only on one machine with the same library builds: they hash the exact
bits of floats that MuJoCo, NumPy (its SIMD kernels and BLAS), Numba and libm compute, and another
CPU or another build of any of them gives other low bits (every hash then differs, and that says
nothing about the code). Record and check on the same machine, with the same environment, minutes
apart; never commit a recording as expected values, and no test compares these hashes to stored
ones. A recording notes the machine and the library versions (``machine``); ``--check`` says so when
they are not this one's.
To record an earlier commit's: ``git archive <commit> src envs xml | tar -x -C /tmp/before``, then run
this script with ``PYTHONPATH=/tmp/before/src``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import platform
import sys
import warnings

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode

import stairenv

# Steps before which the state is broken (see break_physics), and the joint whose angle is.
IMPLAUSIBLE_SPEED_STEP, DIVERGENCE_STEP, BROKEN_JOINT = 50, 150, 3


def break_physics(env, step: int) -> None:
    """Before ``IMPLAUSIBLE_SPEED_STEP``: the root moving at 100 m/s (twice ``MAX_ROOT_SPEED``, below
    anything MuJoCo flags: the speed check's case); before ``DIVERGENCE_STEP``: a NaN joint angle
    (MuJoCo resets the data: the divergence check's case)."""
    idx = env._idx
    if step == IMPLAUSIBLE_SPEED_STEP:
        env.data.qvel[idx.qvel_root.start] = 100.0
    elif step == DIVERGENCE_STEP:
        env.data.qpos[idx.qpos_joints.start + BROKEN_JOINT] = np.nan


def _feed(digest, value) -> None:
    """Add ``value`` to ``digest``: its numbers by dtype, shape and bytes (so a Python float and a
    float64 with the same bits hash alike), dicts key by key, sequences element by element."""
    if isinstance(value, dict):
        for key in sorted(value):
            digest.update(f"<{key}>".encode())
            _feed(digest, value[key])
    elif isinstance(value, (list, tuple)) or (isinstance(value, np.ndarray) and value.dtype == object):
        digest.update(f"[{len(value)}".encode())
        for item in value:
            _feed(digest, item)
        digest.update(b"]")
    elif value is None or isinstance(value, str):
        digest.update(repr(value).encode())
    else:
        array = np.ascontiguousarray(np.asarray(value))
        digest.update(f"{array.dtype.str}{array.shape}".encode())
        digest.update(array.tobytes())


class Trajectory:
    """One sha256 per part of a step's result."""

    PARTS = ("obs", "reward", "terminated", "truncated", "info")

    def __init__(self) -> None:
        self.digests = {part: hashlib.sha256() for part in self.PARTS}

    def add(self, **parts) -> None:
        for part, value in parts.items():
            _feed(self.digests[part], value)

    def hexdigests(self) -> dict[str, str]:
        return {part: digest.hexdigest()[:16] for part, digest in self.digests.items()}


def single_env(env_id: str, steps: int, seed: int) -> dict[str, str]:
    env = gym.make(env_id, max_episode_steps=60)
    trajectory = Trajectory()
    rng = np.random.default_rng(seed)
    obs, info = env.reset(seed=seed)
    trajectory.add(obs=obs, info=info)
    for step in range(steps):
        action = rng.uniform(-1.0, 1.0, env.action_space.shape)
        break_physics(env.unwrapped, step)
        obs, reward, terminated, truncated, info = env.step(action)
        trajectory.add(obs=obs, reward=reward, terminated=terminated, truncated=truncated, info=info)
        if terminated or truncated:
            obs, info = env.reset()
            trajectory.add(obs=obs, info=info)
    env.close()
    return trajectory.hexdigests()


def batched_env(env_id: str, steps: int, seed: int, mode: AutoresetMode) -> dict[str, str]:
    env = gym.make_vec(env_id, num_envs=4, vectorization_mode="vector_entry_point",
                       autoreset_mode=mode, max_episode_steps=60)
    trajectory = Trajectory()
    rng = np.random.default_rng(seed)
    obs, info = env.reset(seed=seed)
    trajectory.add(obs=obs, info=info)
    for step in range(steps):
        action = rng.uniform(-1.0, 1.0, env.action_space.shape)
        break_physics(env.unwrapped.envs[1], step)
        obs, reward, terminated, truncated, info = env.step(action)
        trajectory.add(obs=obs, reward=reward, terminated=terminated, truncated=truncated, info=info)
    env.close()
    return trajectory.hexdigests()


def machine() -> dict[str, str]:
    """What the hashes depend on besides the code: the host, its CPU and the numeric libraries' versions
    (a recording is comparable only where all of these are the same)."""
    import mujoco
    import numba
    import scipy

    cpu = platform.processor()
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next((line.split(":", 1)[1].strip() for line in f if line.startswith("model name")), cpu)
    except OSError:
        pass
    return {"host": platform.node(), "cpu": cpu, "arch": platform.machine(), "python": platform.python_version(),
            "mujoco": mujoco.__version__, "numpy": np.__version__, "numba": numba.__version__,
            "scipy": scipy.__version__}


def all_hashes(ids, steps: int, seed: int) -> dict[str, dict[str, str]]:
    hashes = {}
    for env_id in ids:
        hashes[f"{env_id} single"] = single_env(env_id, steps, seed)
        for mode in (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP):
            hashes[f"{env_id} batched {mode.value}"] = batched_env(env_id, steps, seed, mode)
        print(env_id, "done", file=sys.stderr, flush=True)
    return hashes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--ids", default=",".join(stairenv.ENV_IDS))
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--seed", type=int, default=7)
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument("--record", metavar="JSON")
    group.add_argument("--check", metavar="JSON")
    args = parser.parse_args()
    warnings.filterwarnings("ignore", message=".*physics became unstable")
    hashes = all_hashes(args.ids.split(","), args.steps, args.seed)
    if args.record:
        with open(args.record, "w") as f:
            json.dump({"steps": args.steps, "seed": args.seed, "machine": machine(), "hashes": hashes}, f, indent=1)
        print(f"recorded {len(hashes)} trajectories in {args.record}")
        return
    with open(args.check) as f:
        stored = json.load(f)
    if (stored["steps"], stored["seed"]) != (args.steps, args.seed):
        sys.exit(f"{args.check} was recorded with --steps {stored['steps']} --seed {stored['seed']}")
    here, there = machine(), stored.get("machine")
    if there != here:
        changed = ("no machine recorded" if there is None else
                   ", ".join(f"{k} {there.get(k)!r} -> {v!r}" for k, v in here.items() if there.get(k) != v))
        print(f"NOTE: {args.check} was recorded on another machine or library build ({changed}): hashes are "
              "comparable only on one machine with the same builds, so differences here say nothing about the code",
              file=sys.stderr)
    differing = [f"{name}: {part}" for name, parts in hashes.items() for part, value in parts.items()
                 if stored["hashes"].get(name, {}).get(part) != value]
    for line in differing:
        print("DIFFERS", line)
    print(f"{len(hashes) - len({d.split(':')[0] for d in differing})} of {len(hashes)} trajectories identical")
    sys.exit(1 if differing else 0)


if __name__ == "__main__":
    main()
