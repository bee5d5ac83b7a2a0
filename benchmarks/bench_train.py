"""End-to-end training throughput of ``baselines/train_ppo.py``: its defaults against ``--preset paper``.

    python benchmarks/bench_train.py [--env InterLevel-v0] [--default-steps 131072] [--paper-steps 16384]
                                     [--rounds 2] [--extra "--style none"]

Each round runs the script once per setting, in turn (the order alternates between rounds), PPO + AMP,
no evaluation, no checkpoints in the timed part; the rate is the script's own ``trained N env steps
in T s`` line (``model.learn`` only: start-up and env construction excluded). Printed: each run's env
steps per second, the ratio defaults / paper per round, and the median over rounds. Target for
InterLevel-v0 on 2 cores: >= 6,000 env steps/s with the defaults. Run it on an idle machine: the
absolute rates move with the load, the ratio of back-to-back runs much less.
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
RATE = re.compile(r"trained (\d+) env steps in ([\d.]+) s \((\d+) env steps/s\)")


def run(env: str, steps: int, extra: list[str], logdir: str) -> float:
    cmd = [sys.executable, str(SCRIPT), "--env", env, "--timesteps", str(steps), "--eval-episodes", "0",
           "--no-progress-bar", "--checkpoint-every", str(10 * steps), "--logdir", logdir, *extra]
    done = subprocess.run(cmd, capture_output=True, text=True, check=False)
    found = RATE.search(done.stdout)
    if done.returncode != 0 or found is None:
        raise SystemExit(f"{shlex.join(cmd)} failed:\n{done.stderr[-2000:]}")
    return float(found.group(3))


def main(argv: list[str] | None = None) -> dict[str, list[float]]:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--env", default="InterLevel-v0")
    p.add_argument("--default-steps", type=int, default=131_072, help="env steps of each defaults run")
    p.add_argument("--paper-steps", type=int, default=16_384, help="env steps of each --preset paper run")
    p.add_argument("--rounds", type=int, default=2)
    p.add_argument("--extra", default="", help="flags added to both settings, e.g. \"--style none\"")
    args = p.parse_args(argv)
    extra = shlex.split(args.extra)
    settings = {"defaults": (args.default_steps, []), "paper": (args.paper_steps, ["--preset", "paper"])}
    rates: dict[str, list[float]] = {name: [] for name in settings}
    ratios = []
    with tempfile.TemporaryDirectory() as logdir:
        for r in range(args.rounds):
            order = list(settings) if r % 2 == 0 else list(settings)[::-1]
            for name in order:
                steps, flags = settings[name]
                rates[name].append(run(args.env, steps, [*flags, *extra], logdir))
                print(f"round {r}: {name:8s} {rates[name][-1]:8.0f} env steps/s", flush=True)
            ratios.append(rates["defaults"][-1] / rates["paper"][-1])
            print(f"round {r}: defaults / paper = {ratios[-1]:.2f}x", flush=True)
    print(f"{args.env}: defaults {statistics.median(rates['defaults']):.0f} env steps/s, paper preset "
          f"{statistics.median(rates['paper']):.0f}; defaults / paper median {statistics.median(ratios):.2f}x "
          f"(min {min(ratios):.2f}, max {max(ratios):.2f}) over {args.rounds} rounds; target >= 6000 env steps/s")
    return rates


if __name__ == "__main__":
    main()
