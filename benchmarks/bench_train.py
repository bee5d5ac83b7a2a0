"""End-to-end training throughput of ``baselines/train_ppo.py`` (the lean trainer) against ``train_sb3.py`` (SB3),
same settings.

    python benchmarks/bench_train.py [--env InterLevel-v0] [--steps 131072] [--rounds 3]
                                     [--settings lean sb3 paper] [--extra "--style none"]

Settings (each script with its defaults, PPO + AMP, 128 worlds x 16-step rollouts):
``lean`` (``train_ppo.py``), ``sb3`` (``train_sb3.py``: Stable-Baselines3 PPO on the
same batched env, the defaults before the lean trainer), ``paper`` (``train_sb3.py --preset paper``,
run for an eighth of the steps); ``lean-bf16`` and ``lean-2threads``, the lean trainer with its update
options ``--update-bf16`` and ``--update-threads 2``. Each round runs every setting once, the order rotating between
rounds; no evaluation, no checkpoint in the timed part. The rate is the script's own ``trained N env
steps in T s`` line (the training loop only: start-up and env construction excluded), and its ``cpu``
line the CPU (all threads) per env step. Printed: each run's env steps/s and CPU per step, each
setting's ratio to the first per round, and the medians. Target (issue #22) for InterLevel-v0 on 2
cores: >= 5,000 env steps/s with the defaults. Run it on an idle machine: absolute rates move with
the load, ratios of back-to-back runs much less; the CPU per step moves least.
"""

from __future__ import annotations

import argparse
import re
import shlex
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[1] / "baselines" / "train_ppo.py"
SB3_SCRIPT = SCRIPT.with_name("train_sb3.py")
RATE = re.compile(r"trained (\d+) env steps in ([\d.]+) s \((\d+) env steps/s\)")
CPU = re.compile(r"cpu (\d+) us per env step, ([\d.]+) cores busy")
#: setting -> (fraction of the steps, script, flags)
SETTINGS = {"lean": (1, SCRIPT, []), "sb3": (1, SB3_SCRIPT, []), "paper": (8, SB3_SCRIPT, ["--preset", "paper"]),
            # the lean trainer's update options (off by default): bfloat16 products, both cores in the update
            "lean-bf16": (1, SCRIPT, ["--update-bf16"]), "lean-2threads": (1, SCRIPT, ["--update-threads", "2"])}


def run(script: Path, env: str, steps: int, extra: list[str], logdir: str) -> tuple[float, float, float]:
    """(env steps/s, CPU us per env step, cores busy) of one training run."""
    cmd = [sys.executable, str(script), "--env", env, "--timesteps", str(steps), "--eval-episodes", "0",
           "--no-progress-bar", "--checkpoint-every", str(10 * steps), "--logdir", logdir, *extra]
    done = subprocess.run(cmd, capture_output=True, text=True, check=False)
    rate, cpu = RATE.search(done.stdout), CPU.search(done.stdout)
    if done.returncode != 0 or rate is None or cpu is None:
        raise SystemExit(f"{shlex.join(cmd)} failed:\n{done.stderr[-2000:]}")
    return float(rate.group(3)), float(cpu.group(1)), float(cpu.group(2))


def main(argv: list[str] | None = None) -> dict[str, list[float]]:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--env", default="InterLevel-v0")
    p.add_argument("--steps", type=int, default=131_072, help="env steps of each run (paper: an eighth)")
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--settings", nargs="+", choices=sorted(SETTINGS), default=["lean", "sb3"])
    p.add_argument("--extra", default="", help="flags added to every setting, e.g. \"--style none\"")
    args = p.parse_args(argv)
    extra = shlex.split(args.extra)
    names = list(dict.fromkeys(args.settings))
    rates: dict[str, list[float]] = {name: [] for name in names}
    cpus: dict[str, list[float]] = {name: [] for name in names}
    ratios: dict[str, list[float]] = {name: [] for name in names[1:]}
    with tempfile.TemporaryDirectory() as logdir:
        for r in range(args.rounds):
            order = names[r % len(names):] + names[:r % len(names)]
            for name in order:
                divisor, script, flags = SETTINGS[name]
                rate, cpu, cores = run(script, args.env, max(args.steps // divisor, 2048), [*flags, *extra], logdir)
                rates[name].append(rate)
                cpus[name].append(cpu)
                print(f"round {r}: {name:6s} {rate:7.0f} env steps/s, {cpu:5.0f} us CPU per step, "
                      f"{cores:.2f} cores busy", flush=True)
            for name in names[1:]:
                ratios[name].append(rates[names[0]][-1] / rates[name][-1])
                print(f"round {r}: {names[0]} / {name} = {ratios[name][-1]:.2f}x", flush=True)
    for name in names:
        print(f"{args.env} {name}: {statistics.median(rates[name]):.0f} env steps/s "
              f"({min(rates[name]):.0f}-{max(rates[name]):.0f}), {statistics.median(cpus[name]):.0f} us CPU per step")
    for name in names[1:]:
        print(f"{names[0]} / {name}: median {statistics.median(ratios[name]):.2f}x "
              f"(min {min(ratios[name]):.2f}, max {max(ratios[name]):.2f}) over {args.rounds} rounds")
    print("target (issue #22): >= 5,000 env steps/s with the defaults on 2 cores")
    return rates


if __name__ == "__main__":
    main()
