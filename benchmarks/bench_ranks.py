"""Training with several data-parallel ranks on one machine: the same worlds split over K processes, so the
task's per-world Python (the host's ceiling, ``docs/gpu.md``) runs on K cores instead of one.

    python benchmarks/bench_ranks.py [--physics warp|mujoco] [--ranks 1,4,8] [--worlds 4096] [--iterations 8]
                                     [--device cuda] [--timeout 240] [--out ranks.json] [--quick]
                                     [--state-on-device]

For each K of ``--ranks``: ``torchrun --standalone --nproc-per-node K baselines/train_ppo.py --physics P
--device DEVICE --n-envs WORLDS/K`` (the lean trainer, PPO + AMP with the default recipe, InterLevel-v0),
for ``--iterations`` iterations, gradients averaged through gloo. With ``--physics warp`` every rank's
physics runs on the node's GPU ``LOCAL_RANK mod GPUs`` (``stairenv.training.distributed.rank_gpu``), so
the ranks share it; with ``--physics mujoco`` (MuJoCo's C library) every rank has ``cores / K`` physics
threads (the trainer's default under torchrun), so the ranks share the cores. The same total of worlds
for every K, so the rates compare the same batch split over K processes.

Measured from rank 0's ``log.jsonl`` (the ranks wait for each other at every gradient all-reduce, so rank
0's iteration is the run's), after the first two iterations (CUDA graph capture, the first update):
end to end, env steps/s of all ranks = K x 1e6 / (collect_us + update_us) per iteration; the collect
alone = K x 1e6 / collect_us. Printed: a table with each K's median and its ratio to the first K in
this run.

Without MPS (``nvidia-cuda-mps-control -d``) the GPU time-slices the ranks' kernels, so the device's share
does not shrink with K; the host's does. ``--quick``: 4 worlds, ranks 1 and 2, networks on the CPU, Warp
on its CPU device, 4 iterations: checks that the plumbing runs (the rates are not speed figures there).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ROLLOUT_STEPS = 16    # train_ppo.py's default --n-steps


def run_ranks(ranks: int, worlds: int, iterations: int, physics: str, device: str, timeout: float,
              logdir: Path, state_on_device: bool = False) -> dict:
    per_rank = worlds // ranks
    # torchrun's --tee: each rank's streams also into files of its own, so a failed rank's error is kept
    command = [sys.executable, "-m", "torch.distributed.run", "--standalone", f"--nproc-per-node={ranks}",
               "--log-dir", str(logdir / "ranks"), "--tee", "3",
               str(ROOT / "baselines" / "train_ppo.py"), "--env", "InterLevel-v0", "--physics", physics,
               "--device", device, "--n-envs", str(per_rank), "--n-steps", str(ROLLOUT_STEPS),
               "--timesteps", str(iterations * ranks * per_rank * ROLLOUT_STEPS), "--eval-episodes", "0",
               "--no-progress-bar", "--checkpoint-every", str(10**12), "--logdir", str(logdir),
               *(["--state-on-device"] if state_on_device else [])]
    # src first, the caller's path kept (packages carried to a machine with --target live there)
    path = os.pathsep.join(filter(None, [str(ROOT / "src"), os.environ.get("PYTHONPATH")]))
    env = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONPATH": path}
    start = time.perf_counter()
    launch = subprocess.Popen(command, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        output, _ = launch.communicate(timeout=timeout)
        returncode = launch.returncode
    except subprocess.TimeoutExpired:
        # SIGTERM: torchrun stops its ranks (each in a session of its own, out of reach of a group kill; a rank
        # whose torchrun was killed outright waits for its rendezvous forever, holding the GPU)
        launch.terminate()
        try:
            output, _ = launch.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            launch.kill()
            output = ""
        returncode = "timeout"
    tail = output[-1500:]
    result = {"physics": physics, "state_on_device": state_on_device, "ranks": ranks, "worlds_per_rank": per_rank,
              "returncode": returncode, "wall_s": round(time.perf_counter() - start, 1)}
    log = logdir / "InterLevel-v0" / "seed0" / "log.jsonl"
    lines = [json.loads(line) for line in log.read_text().splitlines()] if log.exists() else []
    timed = lines[2:] if len(lines) > 2 else lines[-1:]
    if timed:
        result["iterations_timed"] = len(timed)
        result["env_steps_per_s"] = statistics.median(
            ranks * 1e6 / (line["time/collect_us"] + line["time/update_us"]) for line in timed)
        result["collect_steps_per_s"] = statistics.median(ranks * 1e6 / line["time/collect_us"] for line in timed)
    result["ok"] = returncode == 0 and bool(timed)    # completed, with a timed iteration
    if returncode != 0:
        result["output_tail"] = tail
        result["rank_errors"] = rank_errors(logdir / "ranks")
    return result


def rank_errors(folder: Path, chars: int = 2000) -> dict[str, str]:
    """The end of each rank's stderr where it wrote any (torchrun's ``--tee`` files,
    ``<run>/attempt_<n>/<local rank>/stderr.log``), keyed by local rank: what a rank died of, which
    torchrun's own report leaves out."""
    errors = {}
    for path in sorted(folder.glob("**/stderr.log")):
        text = path.read_text(errors="replace").strip()
        if text:
            errors[path.parent.name] = text[-chars:]
    return errors


def main(argv: list[str] | None = None) -> list[dict]:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--physics", choices=("warp", "mujoco"), default="warp",
                   help="warp: the ranks share the GPU; mujoco: the ranks share the cores")
    p.add_argument("--ranks", default="1,4,8", help="processes on this machine, comma-separated")
    p.add_argument("--state-on-device", action="store_true",
                   help="with --physics warp: the state kept on the device between resets (train_ppo.py's flag)")
    p.add_argument("--worlds", type=int, default=4096, help="worlds in all, split over the ranks")
    p.add_argument("--iterations", type=int, default=8, help="PPO iterations per run (the first two untimed)")
    p.add_argument("--device", default="cuda", help="torch device of the networks and updates (cuda or cpu)")
    p.add_argument("--timeout", type=float, default=240.0, help="seconds a run may take at most")
    p.add_argument("--quick", action="store_true", help="4 worlds, ranks 1,2, networks on the CPU: checks that it runs")
    p.add_argument("--out", help="write the figures as JSON here")
    args = p.parse_args(argv)
    if args.quick:
        args.ranks, args.worlds, args.iterations, args.device = "1,2", 4, 4, "cpu"
    results = []
    where = " (state on the device)" if args.state_on_device else ""
    print(f"physics {args.physics}{where}, {args.worlds} worlds in all, {args.iterations} iterations, networks on "
          f"{args.device}", flush=True)
    print(f"{'ranks':>5} {'worlds/rank':>11} {'env steps/s':>12} {'collect/s':>10} {'x 1 rank':>8} {'wall s':>7}",
          flush=True)
    for ranks in (int(k) for k in args.ranks.split(",")):
        with tempfile.TemporaryDirectory() as folder:
            result = run_ranks(ranks, args.worlds, args.iterations, args.physics, args.device, args.timeout,
                               Path(folder), args.state_on_device)
        results.append(result)
        base = results[0].get("env_steps_per_s")
        rate = result.get("env_steps_per_s")
        ratio = f"{rate / base:.2f}" if rate and base else "-"
        collect = result.get("collect_steps_per_s", 0)
        failed = "" if result["ok"] else f"  failed ({result['returncode']})"
        print(f"{ranks:>5} {result['worlds_per_rank']:>11} {rate or 0:>12,.0f} {collect:>10,.0f} {ratio:>8} "
              f"{result['wall_s']:>7}{failed}", flush=True)
        if result["returncode"] != 0:
            print(result.get("output_tail", ""), flush=True)
            for rank, error in result["rank_errors"].items():
                print(f"--- local rank {rank}'s stderr, its end:\n{error}", flush=True)
        if args.out:
            Path(args.out).write_text(json.dumps(results, indent=1))
    return results


if __name__ == "__main__":
    # a run that failed or logged no timed iteration fails the benchmark (after every K has been tried)
    sys.exit(0 if all(result["ok"] for result in main()) else 1)
