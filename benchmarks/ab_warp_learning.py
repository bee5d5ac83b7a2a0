"""Does a policy learn as well per sample on MuJoCo Warp as on MuJoCo's C library? (issue #27)

Runs several arms of the same training recipe at once (default: the climbing recipe's first stage,
``baselines/recipes/interlevel_climb.toml``), each an ordinary ``baselines/train_ppo.py`` process that
differs only in ``--physics`` and ``--seed``, then reads their ``log.jsonl`` and compares them at the same
numbers of env samples (not wall time): task and style reward, episode progress, falls and length,
averaged over buckets of ``--bucket`` samples. Two C arms with different seeds give the yardstick: a
Warp arm is "as good per sample" where it differs from the C arms no more than they differ from each
other. Meant for a GPU machine (the Warp arm on the GPU, the C arms on its cores, all concurrently);
on a CPU-only machine ``--quick`` checks that the script works (Warp's CPU device: slow).

    python benchmarks/ab_warp_learning.py --timesteps 1.2e6 --deadline 420 --climb-cache-workers 5 --out ab.json
    python benchmarks/ab_warp_learning.py --quick       # a few thousand steps, to check the plumbing
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
METRICS = ("amp/task_reward", "amp/style_reward", "episode/progress", "episode/fell", "episode/length",
           "episode/success")


def parse_arms(text: str) -> list[tuple[str, int]]:
    """"warp:0,mujoco:0,mujoco:1" -> [("warp", 0), ("mujoco", 0), ("mujoco", 1)]."""
    arms = []
    for item in text.split(","):
        physics, _, seed = item.partition(":")
        if physics not in ("warp", "mujoco", "serial"):
            raise SystemExit(f"--arms: physics must be warp, mujoco or serial, got {physics!r}")
        arms.append((physics, int(seed or 0)))
    return arms


def launch(physics: str, seed: int, args, logdir: Path) -> subprocess.Popen:
    command = [sys.executable, str(ROOT / "baselines/train_ppo.py"), "--config", args.config,
               "--physics", physics, "--seed", str(seed), "--timesteps", str(int(args.timesteps)),
               "--checkpoint-every", str(10 ** 12), "--logdir", str(logdir)]
    if physics == "mujoco":
        command += ["--physics-threads", str(args.physics_threads)]
    if args.n_envs:
        command += ["--n-envs", str(args.n_envs)]
    if args.climb_cache_workers:
        command += ["--climb-cache-workers", str(args.climb_cache_workers)]
    log = (logdir.parent / f"{logdir.name}.out").open("w")
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "OMP_NUM_THREADS": "1"}
    return subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT, env=env, start_new_session=True)


def read_log(logdir: Path) -> list[dict]:
    found = list(logdir.glob("*/seed*/log.jsonl"))
    if not found:
        return []
    return [json.loads(line) for line in found[0].read_text().splitlines() if line.strip()]


def buckets(records: list[dict], size: int, until: int) -> list[dict]:
    """Per bucket of ``size`` samples up to ``until``: the mean of each metric over the iterations in it."""
    rows = []
    for start in range(0, until, size):
        inside = [r for r in records if start < r["steps"] <= start + size]
        row = {"samples": start + size}
        for key in METRICS:
            values = [r[key] for r in inside if key in r]
            row[key] = sum(values) / len(values) if values else None
        rows.append(row)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--config", default=str(ROOT / "baselines/recipes/interlevel_climb.toml"))
    parser.add_argument("--arms", default="warp:0,mujoco:0,mujoco:1")
    parser.add_argument("--timesteps", type=float, default=1.2e6)
    parser.add_argument("--n-envs", type=int, default=None, help="worlds per arm (default: the recipe's)")
    parser.add_argument("--physics-threads", type=int, default=max(1, (os.cpu_count() or 2) // 3))
    parser.add_argument("--climb-cache-workers", type=int, default=0,
                        help="each arm synthesises its stair starts' climbs on this many processes first (a fresh "
                             "process otherwise spends its first minutes on them: docs/gpu.md)")
    parser.add_argument("--deadline", type=float, default=420.0, help="seconds before the arms are stopped")
    parser.add_argument("--bucket", type=int, default=131072, help="samples per row of the comparison")
    parser.add_argument("--logroot", default="/tmp/ab_warp_learning")
    parser.add_argument("--out", default=None, help="JSON with the rows and every arm's log")
    parser.add_argument("--quick", action="store_true", help="a few thousand steps, 8 worlds (plumbing check)")
    args = parser.parse_args()
    if args.quick:
        args.timesteps, args.n_envs, args.bucket, args.deadline = 4096, 8, 1024, min(args.deadline, 600.0)

    arms = parse_arms(args.arms)
    root = Path(args.logroot)
    root.mkdir(parents=True, exist_ok=True)
    names = [f"{physics}_seed{seed}" for physics, seed in arms]
    start = time.perf_counter()
    processes = {name: launch(physics, seed, args, root / name) for name, (physics, seed) in zip(names, arms)}
    while time.perf_counter() - start < args.deadline and any(p.poll() is None for p in processes.values()):
        time.sleep(2.0)
    stopped = [name for name, p in processes.items() if p.poll() is None]
    for name in stopped:    # past the deadline: stop the arm (its log holds every finished iteration)
        os.killpg(processes[name].pid, signal.SIGTERM)
    for p in processes.values():
        p.wait()
    wall = time.perf_counter() - start

    logs = {name: read_log(root / name) for name in names}
    reached = {name: (records[-1]["steps"] if records else 0) for name, records in logs.items()}
    common = min(reached.values())
    size = args.bucket
    until = common - common % size
    table = {name: buckets(records, size, until) for name, records in logs.items()}
    rates = {name: (records[-1].get("time/steps_per_second") if records else None) for name, records in logs.items()}
    print(f"arms {names}; wall {wall:.0f} s; samples reached {reached}; stopped at the deadline: {stopped}")
    print(f"last logged env steps/s (arms ran concurrently, so only indicative): {rates}")
    for name, p in processes.items():
        if p.returncode not in (0, -signal.SIGTERM) and name not in stopped:
            print(f"{name} exited with {p.returncode}; its output: {root / (name + '.out')}")
    for key in METRICS:
        print(f"\n{key} per {size:,} samples")
        print("samples    " + "  ".join(f"{name:>16}" for name in names))
        for i in range(len(next(iter(table.values()))) if table else 0):
            cells = [table[name][i][key] for name in names]
            print(f"{table[names[0]][i]['samples']:>9,}  " + "  ".join(
                f"{c:16.4f}" if c is not None else f"{'-':>16}" for c in cells))
    if args.out:
        keep = ("steps", *METRICS, "time/steps_per_second", "amp/disc_accuracy")
        Path(args.out).write_text(json.dumps({
            "arms": names, "config": args.config, "timesteps": args.timesteps, "wall_s": wall,
            "samples_reached": reached, "stopped_at_deadline": stopped, "bucket": size, "rows": table,
            "logs": {name: [{k: r[k] for k in keep if k in r} for r in records] for name, records in logs.items()},
        }, indent=1))


if __name__ == "__main__":
    main()
