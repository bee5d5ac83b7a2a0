"""Cost of the AMP wrapper per vectorised step, relative to the bare vectorised env.

    python benchmarks/bench_amp.py [--n-envs 8] [--steps 1024] [--vec dummy|subproc]

Both runs step the same ``InterLevel-v0`` vec env with the same random actions.
The wrapped run includes the discriminator's forward pass on every step and its
training rounds (default schedule: 2 minibatches of 256 reference + 256 agent
windows every 2048 transitions), so the ratio is the whole price of AMP. Target: below 1.25x.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
import torch
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

import stairenv  # noqa: F401
from stairenv.motion import MotionClip, MotionLibrary
from stairenv.style.reference import ReferenceWindows
from stairenv.style.wrappers import AMPStyleReward, AMPVecEnvWrapper


def reference_windows() -> ReferenceWindows:
    try:
        from stairenv.motion.synthesis import reference_set

        clips = reference_set()
    except ImportError:  # synthesis not available: a stand-in standing clip
        q = np.zeros((60, 35))
        q[:, 2], q[:, 3] = 0.88, 1.0
        clips = [MotionClip(q, 30.0, "stand")]
    return ReferenceWindows(MotionLibrary(clips), num_frames=2, fps=30.0)


def run(venv, actions: np.ndarray) -> float:
    venv.seed(0)
    venv.reset()
    start = time.perf_counter()
    for action in actions:
        venv.step(action)
    return (time.perf_counter() - start) / len(actions)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--n-envs", type=int, default=8)
    parser.add_argument("--steps", type=int, default=1024)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--vec", choices=("dummy", "subproc"), default="dummy")
    parser.add_argument("--torch-threads", type=int, default=1)
    args = parser.parse_args()
    torch.set_num_threads(args.torch_threads)

    vec_cls = DummyVecEnv if args.vec == "dummy" else SubprocVecEnv
    bare = make_vec_env("InterLevel-v0", n_envs=args.n_envs, seed=0, vec_env_cls=vec_cls)
    style = AMPStyleReward(reference_windows())
    wrapped = AMPVecEnvWrapper(make_vec_env("InterLevel-v0", n_envs=args.n_envs, seed=0, vec_env_cls=vec_cls), style)
    actions = np.random.default_rng(0).uniform(-1, 1, (args.steps, args.n_envs, 28)).astype(np.float32)

    run(bare, actions[:50])
    run(wrapped, actions[:50])
    bare_t, wrapped_t = [], []
    for _ in range(args.rounds):
        bare_t.append(run(bare, actions))
        wrapped_t.append(run(wrapped, actions))
    ratio = statistics.median(w / b for w, b in zip(wrapped_t, bare_t))
    print(f"bare {args.vec} vec env ({args.n_envs} envs)   {statistics.median(bare_t) * 1e3:7.3f} ms/step")
    print(f"with AMP wrapper                 {statistics.median(wrapped_t) * 1e3:7.3f} ms/step "
          f"({style.rounds} training rounds)")
    print(f"ratio wrapped / bare             {ratio:7.3f}   (target < 1.25)")


if __name__ == "__main__":
    main()
