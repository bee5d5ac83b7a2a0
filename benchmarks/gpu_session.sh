#!/usr/bin/env bash
# Issue #27's measurements for one short GPU session, in order of value, each under its own time limit
# (at most 9.5 minutes in all, within the device tool's 10-minute call), so that a session with little
# device time gets the most from one call:
#
#   OUT=results bash benchmarks/gpu_session.sh        # PYTHON=... picks the interpreter (default python)
#
# Needs the package with its train and gpu extras installed (README, "Train on a GPU"). Writes into $OUT:
# gpu.csv (the card), one log per step, the benchmarks' JSON, and status.txt (each step's exit status:
# 124 when it ran out of its time). docs/gpu.md ("Next GPU session") says what each step is for.
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-gpu_results}
PY=${PYTHON:-python}
mkdir -p "$OUT"
export MUJOCO_GL=${MUJOCO_GL:-egl}

step() {    # step NAME SECONDS COMMAND...: run it, its output in $OUT/NAME.log, its status in status.txt
    local name=$1 limit=$2
    shift 2
    echo "== $name (at most $limit s): $*"
    timeout --signal=TERM --kill-after=20 "$limit" "$@" > "$OUT/$name.log" 2>&1
    echo "$name $?" | tee -a "$OUT/status.txt"
}

nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv > "$OUT/gpu.csv" 2>&1 || true
# the env and the trainer at 4,096 Warp worlds, the host's MjData the truth (the default), against C at 256
# (the first run compiles Warp's CUDA kernels, cached for the others)
step warp_env 170 "$PY" benchmarks/bench_warp.py --sizes 4096 --train-size 4096 --train-c-size 0 --budget 10 \
    --deadline 120 --out "$OUT/warp_env.json"
# the same with the state kept on the device between resets (state_on_device=True)
step warp_env_device_state 150 "$PY" benchmarks/bench_warp.py --sizes 4096 --train-size 4096 --c-size 0 \
    --train-c-size 0 --budget 10 --deadline 100 --state-on-device --out "$OUT/warp_env_device_state.json"
# K ranks sharing the GPU over 4,096 worlds of Warp physics: the host's per-world task on K cores
step ranks_warp 190 "$PY" benchmarks/bench_ranks.py --ranks 1,8 --timeout 85 --out "$OUT/ranks_warp.json"
# the lean trainer on CUDA against the CPU (skipped where torch sees no GPU)
step tests_cuda 60 "$PY" -m pytest -q -p no:cacheprovider tests/test_training.py -k cuda
echo "results in $OUT"
