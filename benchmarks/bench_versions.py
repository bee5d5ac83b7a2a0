"""One id's natively batched env on two versions of the code, interleaved round by round.

    git archive <rev> src envs xml | tar -x -C /tmp/before        # the code before (as trajectory_hashes.py)
    python benchmarks/bench_versions.py --before /tmp/before/src [--after src] [--id PlaMo-v0]
                                        [--n-envs 64] [--steps 40] [--rounds 7] [--physics-threads N] [--init I]

Each version runs in a worker process of its own (``PYTHONPATH`` its ``src``) that builds
``gym.make_vec(id, n, vectorization_mode="vector_entry_point", init=...)`` (``--init``, "hybrid") once; the
rounds alternate between the two workers (which goes first flips every round), so load that the machine
takes on or sheds shifts both alike. In a round each worker times, on the same seeded actions (uniform in [-0.3, 0.3]):

- ``steps``: batched steps, env steps per second (resets inside, as the episodes end);
- ``task``: the task part alone, per world-step: ``_step_outcomes`` of all worlds on one read of their
  states where the batched env finishes batch-first (what ``HumanoidEnv._finish_worlds`` calls), else
  ``_step_outcome`` world by world;
- ``reset``: ``reset(seed=...)`` of the batch, per world.

Where the change keeps every trajectory's bits (``trajectory_hashes.py --check``), both workers do the same
work. Printed: each round's numbers and after / before ratios, then the ratios' median, min and max.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np


def worker(args) -> None:
    """Build the env, then per line on stdin (a round number) time one round; one JSON line out."""
    import gymnasium as gym

    import stairenv  # noqa: F401  (registers the ids)
    from stairenv.humanoid.state import read_states

    kwargs = {} if args.physics_threads is None else {"physics_threads": args.physics_threads}
    if args.init:
        kwargs["init"] = args.init
    venv = gym.make_vec(args.id, num_envs=args.n_envs, vectorization_mode="vector_entry_point", **kwargs)
    venv.reset(seed=0)
    envs, n = venv.envs, args.n_envs
    for a in np.random.default_rng(0).uniform(-0.3, 0.3, (5, n, 28)):
        venv.step(a)
    print(json.dumps({"ready": os.path.dirname(stairenv.__file__)}), flush=True)
    for line in sys.stdin:
        r = int(line)
        actions = np.random.default_rng(100 + r).uniform(-0.3, 0.3, (args.steps, n, 28))
        start = time.perf_counter()
        for a in actions:
            venv.step(a)
        steps = args.steps * n / (time.perf_counter() - start)
        if venv.batch_outcomes:
            # what ``_finish_worlds`` reads (``_read_worlds``: SIMS' worlds' models differ); older code: read_states
            read = getattr(type(envs[0]), "_read_worlds", None)
            state = read(envs) if read is not None else read_states([env.data for env in envs], envs[0]._idx)
            outcomes = lambda: type(envs[0])._step_outcomes(envs, state)  # noqa: E731
        else:
            states = [env._read_state() for env in envs]
            outcomes = lambda: [env._step_outcome(s) for env, s in zip(envs, states)]  # noqa: E731
        start = time.perf_counter()
        for _ in range(5):
            outcomes()
        task = (time.perf_counter() - start) / (5 * n)
        start = time.perf_counter()
        venv.reset(seed=1000 + r)
        reset = (time.perf_counter() - start) / n
        print(json.dumps({"steps": steps, "task_us": task * 1e6, "reset_ms": reset * 1e3}), flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--before", required=True, help="the src folder of the code before")
    parser.add_argument("--after", default="src", help="the src folder of the code after (default: src)")
    parser.add_argument("--id", default="PlaMo-v0")
    parser.add_argument("--n-envs", type=int, default=64)
    parser.add_argument("--steps", type=int, default=40)
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--physics-threads", type=int, default=None)
    parser.add_argument("--init", default="hybrid", help='the env\'s init keyword ("": none, for ids without it)')
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        return worker(args)
    forwarded = [f"--id={args.id}", f"--n-envs={args.n_envs}", f"--steps={args.steps}", f"--init={args.init}"]
    if args.physics_threads is not None:
        forwarded.append(f"--physics-threads={args.physics_threads}")
    workers = {}
    for name, src in (("before", args.before), ("after", args.after)):
        env = {**os.environ, "PYTHONPATH": os.path.abspath(src)}
        workers[name] = subprocess.Popen([sys.executable, __file__, "--before=", "--worker", *forwarded], env=env,
                                         stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        print(name, json.loads(workers[name].stdout.readline())["ready"], flush=True)
    print(f"{args.id}: {args.n_envs} worlds, {args.steps} steps x {args.rounds} rounds, "
          f"physics_threads={args.physics_threads or 'default'}")
    keys = ("steps", "task_us", "reset_ms")
    ratios = []
    for r in range(args.rounds):
        results = {}
        for name in (("before", "after") if r % 2 == 0 else ("after", "before")):
            workers[name].stdin.write(f"{r}\n")
            workers[name].stdin.flush()
            results[name] = json.loads(workers[name].stdout.readline())
        b, a = results["before"], results["after"]
        # speed-ups: more steps per second, fewer microseconds per task, fewer milliseconds per reset
        ratios.append((a["steps"] / b["steps"], b["task_us"] / a["task_us"], b["reset_ms"] / a["reset_ms"]))
        print(f"  round {r}: env steps/s {b['steps']:.0f} -> {a['steps']:.0f} ({ratios[-1][0]:.2f}x), task per "
              f"world-step {b['task_us']:.1f} -> {a['task_us']:.1f} us ({ratios[-1][1]:.2f}x), reset per world "
              f"{b['reset_ms']:.2f} -> {a['reset_ms']:.2f} ms ({ratios[-1][2]:.2f}x)", flush=True)
    for process in workers.values():
        process.stdin.close()
        process.wait()
    columns = np.array(ratios).T
    print(f"{args.id} after / before: " + "; ".join(
        f"{name} median {np.median(c):.2f}x (min {c.min():.2f}, max {c.max():.2f})"
        for name, c in zip(("env steps/s", "task speed", "reset speed"), columns)))


if __name__ == "__main__":
    main()
