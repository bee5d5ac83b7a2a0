#!/usr/bin/env bash
# Issue #27's measurements for one short GPU session, in order of value, each under its own time limit
# (at most 9.3 minutes in all, within the device tool's 10-minute call), so that a session with little
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
# Warp's CUDA kernels, compiled once into its cache (~/.cache/warp) by a small run, so that no measurement
# below pays it: on an H200 a cold compile took over 3 minutes (2026-11-29), which ran a measurement out of time
step compile 220 "$PY" benchmarks/bench_warp.py --sizes 64 --c-size 0 --train-size 0 --train-c-size 0 --budget 1 \
    --deadline 210 --state-on-device --out "$OUT/compile.json"
# the env and the lean trainer at 4,096 worlds with the state on the device, after the grouped resets and the
# bookkeeping as rows of 2026-11-30 (on an H200 on 2026-11-29: env 16-20k env steps/s, trainer 8.8k; those two
# project 35-75k for the env)
step env_warp 100 "$PY" benchmarks/bench_warp.py --sizes 4096 --c-size 0 --train-size 4096 --train-c-size 0 \
    --train-iterations 3 --budget 5 --deadline 80 --state-on-device --out "$OUT/env_warp.json"
# PlaMo-v0 at 4,096 worlds (its terrain tiles per world on the device, each world's height fields routed to
# its own: issue #58), the host's state the truth (PlaMo's task finishes world by world on the host)
# (its first step compiles the height-field collision kernels the staircases never needed)
step plamo_warp 140 "$PY" benchmarks/bench_warp.py --env PlaMo-v0 --sizes 4096 --c-size 0 --train-size 4096 \
    --train-c-size 0 --train-iterations 2 --budget 5 --deadline 125 --out "$OUT/plamo_warp.json"
# 8 ranks sharing the GPU over 4,096 worlds, the state on the device: the host's per-world task on 8 cores
# (the H200 on 2026-11-29 measured 8 ranks with the host's MjData the truth, 16k env steps/s end to end). One rank under
# torchrun failed there, its cause not kept (bench_ranks now keeps each rank's stderr): `--ranks 1`
# is the next call's, with what time is left
step ranks_warp 70 "$PY" benchmarks/bench_ranks.py --ranks 8 --state-on-device --timeout 60 \
    --out "$OUT/ranks_warp.json"
# the lean trainer on CUDA against the CPU (skipped where torch sees no GPU)
step tests_cuda 30 "$PY" -m pytest -q -p no:cacheprovider tests/test_training.py -k cuda
echo "results in $OUT"
