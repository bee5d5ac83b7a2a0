"""The benchmark scripts run (tiny sizes: a smoke test, no timing is asserted)."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"
#: the benchmark scripts run in subprocesses, minutes in all: out of the default run, CI runs them (-m slow)
pytestmark = pytest.mark.slow

CASES = {
    "bench_amp": ["--steps", "20", "--rounds", "1", "--n-envs", "2", "--variants", "small,paper-bg,paper-par-bg"],
    "bench_amp_batch": ["--dummy-n", "2", "--batched-n", "2", "--transitions", "8", "--rounds", "1", "--train", "off"],
    "bench_step": ["--steps", "40", "--rounds", "1", "--resets", "4"],
    "bench_plamo_physics": ["--seeds", "1", "--ground-steps", "10", "--walk-steps", "10", "--rounds", "1",
                            "--env-seeds", "1", "--env-steps", "10", "--resets", "2"],
    "bench_sims": ["--steps", "40", "--rounds", "1", "--resets", "3"],
    "bench_planning": ["--rounds", "1", "--no-nx-full", "--crop", "60"],
    "bench_retrieval": ["--rooms", "20", "--stories", "1"],
    "bench_saturated": ["--steps", "30", "--ids", "InterLevel-v0,SIMS-Lie-v0"],
    "bench_evaluate": ["--episodes", "1", "--num-envs", "2", "--rounds", "1"],
    "bench_vector": ["--ids", "InterLevel-v0", "--n-envs", "2", "--steps", "5", "--rounds", "1"],
    "bench_train": ["--steps", "256", "--rounds", "1", "--settings", "lean", "sb3",
                    "--extra", "--n-envs 2 --n-steps 64 --batch-size 64"],
    "bench_host_share": ["--worlds", "4", "--steps", "3", "--rounds", "1", "--array-worlds", "16", "--resets", "6",
                         "--device-worlds", "4"],
    # two torchrun ranks on the C back-end: exits 1 unless the run completes and logs a timed iteration
    "bench_ranks": ["--physics", "mujoco", "--ranks", "2", "--worlds", "4", "--iterations", "3", "--device", "cpu"],
}


@pytest.mark.slow
@pytest.mark.parametrize("name", list(CASES))
def test_benchmark_runs(name, tmp_path):
    env = {**os.environ, "MUJOCO_GL": "egl"}
    done = subprocess.run([sys.executable, str(BENCHMARKS / f"{name}.py"), *CASES[name]], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.strip(), "prints its measurements"


@pytest.mark.slow
def test_bench_libraries_runs(tmp_path):
    """The lean trainer always runs; skrl and rsl-rl run where importable, else are skipped with a note."""
    env = {**os.environ, "MUJOCO_GL": "egl"}
    done = subprocess.run([sys.executable, str(BENCHMARKS / "bench_libraries.py"), "--iterations", "1", "--rounds", "1",
                           "--num-envs", "8"], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    lines = done.stdout.splitlines()
    assert any(line.startswith("round 0: lean ") for line in lines), done.stdout
    assert any(line.startswith("round 0: lean-amp ") for line in lines), done.stdout
    for name, library in (("skrl", "skrl"), ("skrl-amp", "skrl"), ("rsl-rl", "rsl_rl")):
        ran = any(line.startswith(f"round 0: {name} ") for line in lines)
        skipped = any(line.startswith(f"note: {name} skipped") for line in lines)
        assert ran != skipped, f"{name}: neither a rate nor a skip note ({library})\n{done.stdout}"


@pytest.mark.slow
def test_bench_importers_runs(tmp_path):
    """Tiny clips, every tree the checkout's HEAD (no history needed); needs the shipped motion files."""
    if not (BENCHMARKS.parents[1] / "shared" / "motions" / "CMU" / "83_32.bvh").is_file():
        pytest.skip("motion files (../shared/motions) absent")
    env = {**os.environ, "MUJOCO_GL": "egl"}
    done = subprocess.run([sys.executable, str(BENCHMARKS / "bench_importers.py"), "--frames", "600",
                           "--fit-frames", "60", "--before", "HEAD", "--main", "HEAD"], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.count("faster than before") == 8, done.stdout  # 2 clips x 2 modes x wall, CPU


@pytest.mark.slow
@pytest.mark.skipif(__import__("torch").cuda.is_available(), reason="needs a machine where torch sees no GPU")
def test_bench_ranks_reports_what_a_failed_rank_died_of(tmp_path):
    """A run whose ranks fail (networks on CUDA where torch sees none) is reported with each rank's own
    stderr (torchrun's --tee files), not only torchrun's report, which leaves the cause out."""
    spec = importlib.util.spec_from_file_location("bench_ranks", BENCHMARKS / "bench_ranks.py")
    bench_ranks = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench_ranks)
    result = bench_ranks.run_ranks(2, 4, 3, "mujoco", "cuda", timeout=300, logdir=tmp_path)
    assert result["returncode"] not in (0, "timeout") and not result["ok"]
    assert sorted(result["rank_errors"]) == ["0", "1"], result
    assert all("torch sees no GPU" in error for error in result["rank_errors"].values()), result["rank_errors"]


def test_gpu_session_script_runs_each_step_and_records_its_status(tmp_path):
    """benchmarks/gpu_session.sh, with an interpreter that only echoes its arguments: every step runs under
    its own limit, its output in its log, its exit status in status.txt (the GPU machine is not needed to
    check the script's wiring; what it measures is bench_ranks', smoke-tested above)."""
    out = tmp_path / "out"
    env = {**os.environ, "OUT": str(out), "PYTHON": "echo"}
    done = subprocess.run(["bash", str(BENCHMARKS / "gpu_session.sh")], env=env, capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 0, done.stderr
    assert (out / "status.txt").read_text().split() == ["compile", "0", "env_warp", "0", "plamo_warp", "0",
                                                        "ranks_warp", "0", "tests_cuda", "0"]
    assert "--state-on-device" in (out / "compile.log").read_text()
    assert "--sizes 4096" in (out / "env_warp.log").read_text()
    assert "--env PlaMo-v0 --sizes 4096" in (out / "plamo_warp.log").read_text()
    # every step's limit (and its 20 s kill grace) within the device tool's 10-minute call
    limits = [int(line.split()[2]) for line in (BENCHMARKS / "gpu_session.sh").read_text().splitlines()
              if line.startswith("step ")]
    assert sum(limits) + 20 <= 600, limits
    assert "--ranks 8 --state-on-device" in (out / "ranks_warp.log").read_text()
    assert (out / "gpu.csv").exists()


def test_trajectory_hashes_note_a_recording_from_another_machine(tmp_path, monkeypatch, capsys):
    """The hashes are the exact bits of floats MuJoCo, NumPy and Numba compute, which another CPU or build
    gives with other low bits: comparable only on one machine with the same builds. A recording names its
    machine and libraries, and ``--check`` against one made elsewhere says that its differences mean
    nothing (no test compares these hashes to stored ones: they are recorded and checked minutes apart)."""
    import json

    spec = importlib.util.spec_from_file_location("trajectory_hashes", BENCHMARKS / "trajectory_hashes.py")
    hashes = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(hashes)
    assert "comparable only on one machine with the same library builds" in " ".join(hashes.__doc__.split())
    monkeypatch.setattr(hashes, "all_hashes", lambda ids, steps, seed: {"X single": {"obs": "0123"}})
    recording = tmp_path / "h.json"

    def run(*argv):
        monkeypatch.setattr(sys, "argv", ["trajectory_hashes.py", "--ids", "X", *argv])
        with pytest.raises(SystemExit) as done:
            hashes.main()
            raise SystemExit(0)
        return done.value.code, capsys.readouterr().err

    assert run("--record", str(recording)) == (0, "")
    assert json.loads(recording.read_text())["machine"] == hashes.machine()
    assert run("--check", str(recording)) == (0, "")        # this machine: no note
    stored = json.loads(recording.read_text())
    stored["machine"]["cpu"] = "another CPU"
    recording.write_text(json.dumps(stored))
    code, err = run("--check", str(recording))
    assert code == 0 and "recorded on another machine or library build" in err and "another CPU" in err
    del stored["machine"]                                      # a recording from before: no machine named
    recording.write_text(json.dumps(stored))
    assert "no machine recorded" in run("--check", str(recording))[1]
