"""MuJoCo Warp physics (``physics="warp"``) against the MuJoCo C back-end: env steps/s of a batched env
(``--env``: InterLevel-v0 by default; PlaMo-v0 and PlaMoNaivePaths-v0 too), and of the lean trainer end to end.

    PYTHONPATH=src python benchmarks/bench_warp.py [--sizes 1024,4096,8192] [--c-size 256]
                                                   [--budget 25] [--out bench_warp.json] [--quick]
                                                   [--state-on-device] [--env PlaMo-v0]

Measured, each size in its own try (a failure is recorded and the next size runs):

- ``warp env``: ``gym.make_vec(ENV, num_envs=N, vectorization_mode="vector_entry_point",
  physics="warp")`` stepped with random actions (uniform in [-0.3, 0.3]): physics on the device, the
  task (observation, reward, termination, style features, info) on the host, resets included; env
  steps/s = worlds x steps / s, after warm-up steps (kernel compilation, CUDA graph capture);
- ``warp physics``: the same worlds' ``WarpPhysics.step`` alone (host-device copies included, no task);
- ``warp device``: ``nstep`` substeps of ``mujoco_warp.step`` on the device alone (CUDA graph replays, no
  copies): the physics limit of the card, in env steps/s (x 8 for physics steps/s);
- ``c env``: the same env with ``physics="mujoco"`` (MuJoCo's C library on a pool of one thread per
  core) at ``--c-size`` worlds, the CPU baseline of the same run;
- ``train warp`` / ``train c``: the lean trainer (``stairenv.training.Trainer``, PPO + AMP, the default
  recipe: 16-step rollouts, 5 epochs of 1,024-sample minibatches) for a few iterations after one
  warm-up iteration, env steps/s end to end (collect + update) and the collect alone. The policy,
  the update and the discriminator run on ``--train-device`` (auto: cuda where torch sees a GPU;
  ``policy_device`` in the JSON says which).

``--state-on-device``: every Warp measurement with the state kept on the device between resets
(``state_on_device=True``; physics ``warp-device-state`` in the table and JSON).

Each measurement stops at its time budget (``--budget`` seconds of timed steps) and none starts after
``--deadline`` seconds, so the whole run is bounded (about 5-6 minutes with the defaults, most of it
building 13,000 worlds on the host and compiling Warp's CUDA kernels once). Order: the C env, the Warp
sizes up to ``--train-size`` (the trainer runs on that size's env), the C trainer, the larger sizes.
Output: a table on stdout (flushed line by line) and, with ``--out``, every figure as JSON (the card,
versions, sizes, rates, failures), rewritten after each measurement.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
import traceback

import numpy as np

T0 = time.perf_counter()


def say(text: str) -> None:
    print(f"[{time.perf_counter() - T0:7.1f} s] {text}", flush=True)


def gpu_name() -> str:
    try:
        import warp as wp
        wp.config.quiet = True
        wp.init()
        device = wp.get_preferred_device()
        return f"{device.alias}: {device.name}"
    except Exception as error:    # noqa: BLE001  (reported, not fatal)
        return f"unknown ({error})"


#: ``--state-on-device``'s name for Warp with the state kept on the device between resets
WARP_DEVICE_STATE = "warp-device-state"


#: the env id measured (``--env``)
ENV_ID = ["InterLevel-v0"]


def train_config(n: int, physics: str, **kwargs):
    """The lean trainer's config for ``physics`` ("mujoco", "warp" or ``WARP_DEVICE_STATE``) on ``--env``."""
    from stairenv.training import TrainConfig
    if physics == WARP_DEVICE_STATE:
        return TrainConfig(env_id=ENV_ID[0], num_envs=n, physics="warp", state_on_device=True, **kwargs)
    return TrainConfig(env_id=ENV_ID[0], num_envs=n, physics=physics, **kwargs)


def make(n: int, physics: str):
    """The batched env the lean trainer builds (``make_env``: its amp_history, the registration's limit)."""
    from stairenv.training import make_env
    return make_env(train_config(n, physics))


def time_steps(step, warmup: int, max_steps: int, budget: float) -> tuple[int, float]:
    """(timed steps, seconds): ``warmup`` untimed calls, then calls until ``max_steps`` or ``budget`` s."""
    for _ in range(warmup):
        step()
    steps, start = 0, time.perf_counter()
    while steps < max_steps and time.perf_counter() - start < budget:
        step()
        steps += 1
    return steps, time.perf_counter() - start


def bench_env(n: int, physics: str, args, keep: dict | None = None) -> dict:
    """Env steps/s of the batched env (and, for warp, of its physics alone and of the device alone);
    the env is left in ``keep["venv"]`` (for the trainer) when ``keep`` is given, else closed."""
    built = time.perf_counter()
    vec = make(n, physics)
    vec.reset(seed=0)
    out = {"worlds": n, "physics": physics, "build_s": round(time.perf_counter() - built, 2)}
    rng = np.random.default_rng(0)
    actions = rng.uniform(-0.3, 0.3, (16, n, 28)).astype(np.float32)
    counter = iter(range(10**9))

    def env_step() -> None:
        vec.step(actions[next(counter) % len(actions)])

    first = time.perf_counter()
    env_step()    # the first step compiles (Warp: kernels, then the CUDA graph at the second)
    out["first_step_s"] = round(time.perf_counter() - first, 2)
    steps, seconds = time_steps(env_step, args.warmup, args.max_steps, args.budget)
    out.update(env_steps=steps, env_seconds=round(seconds, 3), env_steps_per_s=round(n * steps / seconds))
    say(f"{physics} env, {n} worlds: {out['env_steps_per_s']:,} env steps/s ({steps} steps in {seconds:.1f} s)")
    if physics.startswith("warp"):
        physics_impl = vec.physics
        worlds = [(env.model, env.data) for env in vec.envs]
        frame_skip = vec.envs[0].frame_skip
        physics_impl.sync_worlds()    # with the state on the device: its worlds' MjData brought up to date
        for k, env in enumerate(vec.envs):    # stand everyone up again: a fallen world's NaN-free state is all we need
            env.data.qvel[:] = 0.0
            physics_impl.world_changed(k)
        ctrl = {"ctrl": np.zeros((n, vec.envs[0].model.nu))} if physics_impl.state_on_device else {}
        steps, seconds = time_steps(lambda: physics_impl.step(worlds, frame_skip, **ctrl), 2, args.max_steps,
                                    args.budget / 3)
        out.update(physics_steps=steps, physics_steps_per_s=round(n * steps / seconds))
        say(f"warp physics alone (copies included), {n} worlds: {out['physics_steps_per_s']:,} env steps/s")
        launch = physics_impl._launch
        import warp as wp

        def device_step() -> None:
            with wp.ScopedDevice(physics_impl.device):
                launch(frame_skip)
                wp.synchronize_device(physics_impl.device)

        steps, seconds = time_steps(device_step, 2, args.max_steps * 4, args.budget / 3)
        out.update(device_steps=steps, device_steps_per_s=round(n * steps / seconds),
                   device_physics_steps_per_s=round(n * steps * frame_skip / seconds))
        say(f"warp device alone, {n} worlds: {out['device_steps_per_s']:,} env steps/s "
            f"({out['device_physics_steps_per_s']:,} physics steps/s); overflows {physics_impl.overflows}")
        out.update(overflows=physics_impl.overflows, device=str(physics_impl.device), cuda_graph=physics_impl.graph,
                   graph_error=physics_impl.graph_error)
    if keep is not None:
        keep["venv"] = vec
    else:
        vec.close()
    return out


def bench_train(n: int, physics: str, args, venv=None) -> dict:
    """The lean trainer end to end (PPO + AMP), env steps/s over a few iterations after one warm-up
    (on ``venv`` if given: an env of ``make`` with ``n`` worlds, saving its build)."""
    import torch

    from stairenv.style.wrappers import default_reference
    from stairenv.training import Trainer, build_style, make_env

    threads = max(1, (os.cpu_count() or 2) // 2)
    device = args.train_device if args.train_device != "auto" else ("cuda" if torch.cuda.is_available() else "cpu")
    config = train_config(n, physics, total_steps=10**12, torch_threads=threads, checkpoint_every=10**12,
                          device=device)
    venv = venv if venv is not None and venv.num_envs == n else make_env(config)
    trainer = Trainer(config, build_style(config, default_reference(venv)), venv)
    out = {"worlds": n, "physics": physics, "policy_device": device, "torch_threads": threads,
           "cuda_visible_to_torch": bool(torch.cuda.is_available()), "rollout_steps": config.rollout_steps}
    start = time.perf_counter()
    trainer.collect()
    trainer.update()
    out["warmup_iteration_s"] = round(time.perf_counter() - start, 2)
    collect_s = update_s = 0.0
    iterations = 0
    while iterations < args.train_iterations and collect_s + update_s < args.budget * 2:
        t = time.perf_counter()
        trainer.collect()
        t1 = time.perf_counter()
        trainer.update()
        t2 = time.perf_counter()
        collect_s, update_s, iterations = collect_s + t1 - t, update_s + t2 - t1, iterations + 1
    samples = iterations * config.batch_size
    out.update(iterations=iterations, collect_s=round(collect_s, 3), update_s=round(update_s, 3),
               collect_steps_per_s=round(samples / collect_s),
               train_steps_per_s=round(samples / (collect_s + update_s)))
    say(f"train {physics}, {n} worlds: {out['train_steps_per_s']:,} env steps/s end to end "
        f"(collect alone {out['collect_steps_per_s']:,}/s; {iterations} iterations)")
    trainer.close()
    return out


def versions() -> dict:
    found = {"python": platform.python_version()}
    for name in ("numpy", "torch", "mujoco", "mujoco_warp", "warp", "gymnasium", "numba"):
        try:
            found[name] = __import__(name).__version__
        except Exception as error:    # noqa: BLE001
            found[name] = f"missing ({type(error).__name__})"
    return found


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--sizes", default="1024,4096,8192", help="worlds of the Warp env, comma-separated")
    p.add_argument("--c-size", type=int, default=256, help="worlds of the C back-end baseline (0: none)")
    p.add_argument("--train-size", type=int, default=4096, help="worlds of the trainer with Warp (0: none)")
    p.add_argument("--train-c-size", type=int, default=256, help="worlds of the trainer with C (0: none)")
    p.add_argument("--train-iterations", type=int, default=3)
    p.add_argument("--train-device", default="auto", help="torch device of the trainer: auto (cuda if torch sees "
                   "a GPU, else cpu), cpu, cuda")
    p.add_argument("--budget", type=float, default=15.0, help="seconds of timed steps per measurement")
    p.add_argument("--deadline", type=float, default=330.0,
                   help="seconds after which no further measurement starts (the JSON keeps what was done)")
    p.add_argument("--max-steps", type=int, default=300, help="timed env steps per measurement at most")
    p.add_argument("--warmup", type=int, default=5, help="untimed env steps after the first")
    p.add_argument("--quick", action="store_true", help="tiny sizes and budgets: checks that it runs")
    p.add_argument("--state-on-device", action="store_true",
                   help="Warp with the state kept on the device between resets (state_on_device=True)")
    p.add_argument("--env", default="InterLevel-v0",
                   help="the id measured: InterLevel-v0 (default), its ablations, PlaMo-v0 or PlaMoNaivePaths-v0 "
                   "(PlaMo keeps the state on the host: no --state-on-device)")
    p.add_argument("--out", help="write the figures as JSON here")
    args = p.parse_args(argv)
    ENV_ID[0] = args.env
    if args.quick:
        args.c_size, args.train_size, args.train_c_size = 8, 8, 8
        args.sizes = "8,16"
        args.budget, args.max_steps, args.warmup, args.train_iterations = 3.0, 10, 1, 1
    sizes = [int(s) for s in args.sizes.split(",") if s]
    sizes = sorted(n for n in sizes if n <= args.train_size) + sorted(n for n in sizes if n > args.train_size)
    result = {"card": gpu_name(), "cpu_count": os.cpu_count(), "versions": versions(), "env_id": args.env,
              "args": vars(args),
              "env": [], "train": [], "failures": []}
    say(f"device {result['card']}; {result['cpu_count']} CPU cores; {result['versions']}")

    def attempt(kind: str, fn, *fn_args, **fn_kwargs) -> None:
        if time.perf_counter() - T0 > args.deadline:
            say(f"skipped {kind} {fn_args[:2]}: past the deadline ({args.deadline:.0f} s)")
            result["failures"].append({"what": kind, "args": list(fn_args[:2]), "error": "skipped: deadline"})
            return
        try:
            result[kind].append(fn(*fn_args, **fn_kwargs))
        except Exception as error:    # noqa: BLE001  (recorded; the next measurement runs)
            text = f"{kind} {fn_args[:2]}: {type(error).__name__}: {error}"
            say(f"FAILED {text}")
            result["failures"].append({"what": kind, "args": list(fn_args[:2]), "error": text,
                                       "traceback": traceback.format_exc()[-3000:]})
        if args.out:    # what is measured so far survives a later crash or timeout
            with open(args.out, "w") as f:
                json.dump(result, f, indent=1)

    # cheapest first, the trainer on the env of its size (saving a build), the largest size last
    if args.c_size:
        attempt("env", bench_env, args.c_size, "mujoco", args)
    warp = WARP_DEVICE_STATE if args.state_on_device else "warp"
    for n in sizes:
        keep: dict = {}
        attempt("env", bench_env, n, warp, args, keep if n == args.train_size else None)
        if n == args.train_size:
            attempt("train", bench_train, n, warp, args, keep.get("venv"))
    if args.train_size and args.train_size not in sizes:
        attempt("train", bench_train, args.train_size, warp, args)
    if args.train_c_size:
        attempt("train", bench_train, args.train_c_size, "mujoco", args)

    print("\n| measurement | worlds | env steps/s | notes |\n|---|---:|---:|---|", flush=True)
    for row in result["env"]:
        name = f"{row['physics']} env (physics + task)"
        print(f"| {name} | {row['worlds']} | {row['env_steps_per_s']:,} | first step {row['first_step_s']} s |")
        if "physics_steps_per_s" in row:
            print(f"| warp physics alone (copies incl.) | {row['worlds']} | {row['physics_steps_per_s']:,} | |")
            print(f"| warp device alone | {row['worlds']} | {row['device_steps_per_s']:,} | "
                  f"{row['device_physics_steps_per_s']:,} physics steps/s |")
    for row in result["train"]:
        print(f"| train {row['physics']} (PPO + AMP, policy {row['policy_device']}) | {row['worlds']} | "
              f"{row['train_steps_per_s']:,} | collect alone {row['collect_steps_per_s']:,}/s |")
    for failure in result["failures"]:
        print(f"| FAILED {failure['what']} | {failure['args']} | - | {failure['error'][:120]} |")
    say(f"done; card {result['card']}")
    sys.stdout.flush()
    return result


if __name__ == "__main__":
    main()
