"""Cost of the AMP wrapper per vectorised step, relative to the bare vectorised env.

    python benchmarks/bench_amp.py [--n-envs 8] [--steps 256] [--rounds 21] [--vec dummy|subproc]
                                   [--variants paper,paper-bg,...]
    python benchmarks/bench_amp.py --rounds 31   # more rounds on a busy machine
    python benchmarks/bench_amp.py --env PlaMo-v0 --variants paper-bg,paper   # another env

Every run steps the same vec env (``--env``, default ``InterLevel-v0``, our fastest
env and so the hardest case for the ratio) with the same random actions.
A wrapped run includes the discriminator's forward pass on every step and its
training rounds (paper schedule: 2 minibatches of 256 reference + 256 agent
windows every 2048 transitions), so the ratio is the whole price of AMP. Target: below 1.25x.

The bare env and every variant are timed in turn within each round (the order
rotates from round to round), and each variant's ratio is the median over
rounds of wrapped / bare of the same round, so a machine whose load changes
between rounds skews the ratios little. The wrapped time per step is split
into the inner vec env's step (``env``), the discriminator's forward pass
(``scoring``), its training rounds
(``training``, amortised; with background training, the calling thread's share)
and the rest (``other``: the wrapper's bookkeeping).

Figures on a 2-core AMD EPYC VM (a shared host: single rounds spread by +-0.2,
medians by +-0.05 from run to run), 8 envs, ``DummyVecEnv``, bare ~1.7-1.9 ms per
vectorised step, measured while pipelined per-env scoring (a worker thread scoring each env's
window while the next env stepped) existed; it was removed since (``bench_amp_batch.py``: on a
loaded machine it lost to scoring the step's windows in one call, and the batched env does not
need it). Scoring after the step, as now:

- ``paper-bg`` (background training): 1.22-1.43x over the day's runs (pipelined: 1.11-1.25x);
- ``paper`` (synchronous training: the round's ~0.37 ms per step stays on the calling
  thread): 1.44x (pipelined: 1.31-1.41x);
- scoring alone (no training): ``paper-notrain`` 1.21-1.30x (pipelined: 1.08-1.10x).

Before pipelining, the paper's discriminator cost ~0.3 ms per step to score in
situ (12 MFLOP, near one core's float32 peak: no faster kernel on this core
fits the budget; bf16 through oneDNN was ~1.8x faster but inexact) and the best
setting (background training, scoring split over both cores) read 1.20-1.35x.

Variants (``--variants``, comma-separated; see ``VARIANTS``):

- ``paper``: the defaults: MLP [1024, 512], 2 updates per 2048 transitions,
  gradient penalty on the whole reference batch, the step's windows scored in one call.
- ``paper-bg``: the same, training rounds in a background thread (rewards lag one round).
- ``paper-notrain``: scoring only (the discriminator never trains).
- ``paper-torch``: scoring with torch (oneDNN) instead of the numba kernel.
- ``paper-aten``: the same, scoring and training with plain torch kernels (MKL, no oneDNN).
- ``paper-gp64``: gradient penalty estimated on 64 of the 256 reference windows.
- ``paper-1update``: one minibatch per 2048 transitions.
- ``paper-bf16``, ``paper-bf16-bg``: scoring in bfloat16 (without, with background training).
- ``paper-par``, ``paper-par-bg``: the numba kernel split over numba's threads.
- ``fast``: MLP [512, 256], otherwise the paper's schedule.
- ``fast-1update``: MLP [512, 256], one minibatch per 2048 transitions.
- ``small``: MLP [256, 128], otherwise the paper's schedule.
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
from stairenv.style.discriminator import AMPDiscriminator, DiscriminatorConfig
from stairenv.style.reference import ReferenceWindows
from stairenv.style.wrappers import AMPStyleReward, AMPVecEnvWrapper

# name -> (DiscriminatorConfig keywords, AMPStyleReward keywords, AMPDiscriminator keywords)
VARIANTS: dict[str, tuple[dict, dict, dict]] = {
    "paper": ({}, {}, {}),
    "paper-bg": ({}, {"background_training": True}, {}),
    "paper-notrain": ({}, {"train": False}, {}),
    "paper-torch": ({}, {}, {"scoring": "torch"}),
    "paper-aten": ({}, {}, {"scoring": "torch", "backend": "aten"}),
    "paper-gp64": ({"grad_penalty_batch": 64}, {}, {}),
    "paper-1update": ({}, {"updates_per_round": 1}, {}),
    "paper-bf16": ({}, {}, {"scoring": "bf16"}),
    "paper-bf16-bg": ({}, {"background_training": True}, {"scoring": "bf16"}),
    "paper-par": ({}, {}, {"scoring": "numba-parallel"}),
    "paper-par-bg": ({}, {"background_training": True}, {"scoring": "numba-parallel"}),
    "fast": ({"hidden": (512, 256)}, {}, {}),
    "fast-1update": ({"hidden": (512, 256)}, {"updates_per_round": 1}, {}),
    "small": ({"hidden": (256, 128)}, {}, {}),
}


def reference_windows() -> ReferenceWindows:
    try:
        from stairenv.motion.synthesis import reference_set

        clips = reference_set()
    except ImportError:  # synthesis not available: a stand-in standing clip
        q = np.zeros((60, 35))
        q[:, 2], q[:, 3] = 0.88, 1.0
        clips = [MotionClip(q, 30.0, "stand")]
    return ReferenceWindows(MotionLibrary(clips), num_frames=2, fps=30.0)


class Timed:
    """Accumulates the wall time of the wrapped vec env's own step and of the style's scoring and training.

    """

    def __init__(self, wrapper: AMPVecEnvWrapper) -> None:
        self.env = self.scoring = self.training = 0.0
        style = wrapper.style

        def timed(function, field: str):
            def call(*args, **kwargs):
                start = time.perf_counter()
                out = function(*args, **kwargs)
                setattr(self, field, getattr(self, field) + time.perf_counter() - start)
                return out
            return call

        wrapper.venv.step_wait = timed(wrapper.venv.step_wait, "env")
        style.disc.reward = timed(style.disc.reward, "scoring")
        style.train_round = timed(style.train_round, "training")
        # background: the calling thread's share
        style._start_background_round = timed(style._start_background_round, "training")


def run(venv, actions: np.ndarray, timed: Timed | None = None) -> tuple[float, float, float, float]:
    """Seconds per vectorised step: total, the inner vec env's step, scoring, training."""
    venv.seed(0)
    venv.reset()
    if timed is not None:
        timed.env = timed.scoring = timed.training = 0.0
    start = time.perf_counter()
    for action in actions:
        venv.step(action)
    total = (time.perf_counter() - start) / len(actions)
    if timed is None:
        return total, total, 0.0, 0.0
    return total, timed.env / len(actions), timed.scoring / len(actions), timed.training / len(actions)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env", default="InterLevel-v0", help="registered env id (default: %(default)s)")
    parser.add_argument("--n-envs", type=int, default=8)
    parser.add_argument("--steps", type=int, default=256)
    parser.add_argument("--rounds", type=int, default=21)
    parser.add_argument("--vec", choices=("dummy", "subproc"), default="dummy")
    parser.add_argument("--torch-threads", type=int, default=1)
    parser.add_argument("--variants", default="paper-bg,paper",
                        help=f"comma-separated, of {', '.join(VARIANTS)}")
    args = parser.parse_args()
    names = [v.strip() for v in args.variants.split(",") if v.strip()]
    unknown = [v for v in names if v not in VARIANTS]
    if unknown:
        raise SystemExit(f"unknown variants {unknown}; known: {list(VARIANTS)}")
    torch.set_num_threads(args.torch_threads)

    vec_cls = DummyVecEnv if args.vec == "dummy" else SubprocVecEnv
    reference = reference_windows()

    def vec_env():
        return make_vec_env(args.env, n_envs=args.n_envs, seed=0, vec_env_cls=vec_cls)

    envs: dict[str, tuple] = {"bare": (vec_env(), None, None)}
    for name in names:
        config_kw, style_kw, disc_kw = VARIANTS[name]
        torch.manual_seed(0)
        disc = AMPDiscriminator(reference.dim, DiscriminatorConfig(**config_kw), **disc_kw)
        style = AMPStyleReward(reference, discriminator=disc, **style_kw)
        wrapper = AMPVecEnvWrapper(vec_env(), style)
        # A long run's steady state: the replay buffer's pages are already there (its first pass
        # through 100k windows otherwise takes a page fault every few steps, ~17 us per step).
        style.replay.data.fill(0.0)
        envs[name] = (wrapper, style, Timed(wrapper))
    actions = np.random.default_rng(0).uniform(-1, 1, (args.steps, args.n_envs, 28)).astype(np.float32)

    for venv, _, timed in envs.values():  # warm-up
        run(venv, actions[:50], timed)
    order = list(envs)
    times: dict[str, list[tuple[float, float, float, float]]] = {name: [] for name in order}
    for r in range(args.rounds):
        for name in order[r % len(order):] + order[: r % len(order)]:
            venv, _, timed = envs[name]
            times[name].append(run(venv, actions, timed))

    def ms(values) -> float:
        return statistics.median(values) * 1e3

    bare = [t[0] for t in times["bare"]]
    onednn = any(style.disc.onednn for _, style, _ in envs.values() if style is not None)
    print(f"{args.vec} vec env, {args.n_envs} x {args.env}, {args.steps} steps x {args.rounds} rounds, "
          f"torch threads {args.torch_threads}, oneDNN {'available' if onednn else 'off'}")
    print(f"{'variant':<14} {'hidden':<9} {'upd':>3} {'ms/step':>8} {'env':>6} {'scoring':>7} {'training':>8} "
          f"{'other':>6} {'ratio':>6} {'(min-max)':>11}  target < 1.25")
    print(f"{'bare':<14} {'':<9} {'':>3} {ms(bare):8.3f} {ms(bare):6.3f}")
    for name in names:
        _, style, _ = envs[name]
        total, env, scoring, training = ([t[i] for t in times[name]] for i in range(4))
        ratios = [w / b for w, b in zip(total, bare)]
        ratio = statistics.median(ratios)
        hidden = "x".join(str(h) for h in style.config.hidden)
        other = ms(total) - ms(env) - ms(scoring) - ms(training)
        print(f"{name:<14} {hidden:<9} {style.updates_per_round:>3} {ms(total):8.3f} {ms(env):6.3f} "
              f"{ms(scoring):7.3f} {ms(training):8.3f} {other:6.3f} "
              f"{ratio:6.3f} ({min(ratios):.2f}-{max(ratios):.2f})  {'met' if ratio < 1.25 else 'NOT met'}")
    print("ms per vectorised step (medians over rounds): env = the wrapped vec env's own step (compare with bare: "
          "the rest of the wrapper's price is the cache it takes from the env), scoring = the discriminator's "
          "forward pass, training = its training rounds (amortised), other = the wrapper's own bookkeeping; "
          "ratio = median over rounds of wrapped / bare in the same round")


if __name__ == "__main__":
    main()
