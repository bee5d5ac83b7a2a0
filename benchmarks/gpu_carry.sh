#!/usr/bin/env bash
# Packs what benchmarks/gpu_session.sh needs for a GPU machine that has no network and takes at most 64 MiB
# per call (this project's device tool; docs/gpu.md, "Carrying it to a GPU machine"). warp-lang's wheel alone
# is 149 MB, so two calls carry it: .whl1 holds the cp312 wheels the machine lacks, Warp's Python files and
# the first part of warp.so (xz), .whl2 the rest; each folder holds the script its call runs.
#
#   bash benchmarks/gpu_carry.sh        # ~5 minutes here (xz of warp.so's 299 MB on 2 cores)
#   call 1: carry [".whl1"], command "bash .whl1/call1.sh"            installs into /tmp/gpuenv (~35 s)
#   call 2, at once (a machine stays warm 30 s): carry [".whl2"], "LIMIT=540 bash .whl2/call2.sh"
#           rebuilds warp.so (checked against its sha256), runs gpu_session.sh within LIMIT seconds, and
#           returns its JSON and results.tgz (the device tool returns at most 8 files)
#
# The working tree travels with every call and must stay under 64 MiB with the folder: checkpoints/ (~100 MiB)
# stays behind while the calls run (`git rm -r -q --cached checkpoints` with /checkpoints/ in
# .git/info/exclude; afterwards `git reset -q HEAD -- checkpoints` and that line removed). Needs pip, xz, unzip.
set -eu
cd "$(dirname "$0")/.."
grep -qx '/.whl1/' .git/info/exclude 2>/dev/null || printf '/.whl1/\n/.whl2/\n' >> .git/info/exclude
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
platforms=""
for p in manylinux_2_17_x86_64 manylinux2014_x86_64 manylinux_2_24_x86_64 manylinux_2_27_x86_64 \
         manylinux_2_28_x86_64 manylinux_2_31_x86_64 manylinux_2_34_x86_64 manylinux_2_35_x86_64; do
    platforms="$platforms --platform $p"
done
# what the machine's image lacks (its list: the device tool's KINDS.md); mujoco-studio (the viewer) not needed
python3 -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp $platforms \
    -d "$work/wheels" mujoco==4.0.0 mujoco-core==4.0.0 mujoco-warp==4.0.0 warp-lang==1.19.0 gymnasium==1.4.0 \
    farama-notifications==0.0.6 trimesh==5.2.0 osqp==1.1.3 stable-baselines3==2.9.2 glfw==2.11.0 pyopengl==3.1.10
rm -rf .whl1 .whl2
mkdir -p .whl1 .whl2 "$work/warp"
find "$work/wheels" -name '*.whl' ! -name 'warp_lang-*' -exec cp {} .whl1/ \;
unzip -q "$work"/wheels/warp_lang-*.whl -d "$work/warp"
(cd "$work/warp" && sha256sum warp/bin/warp.so) > .whl1/warp.so.sha256
xz -9e -T2 -c "$work/warp/warp/bin/warp.so" > "$work/warp.so.xz"
rm "$work/warp/warp/bin/warp.so" "$work/warp/warp/bin/warp-clang.so"    # warp-clang: Warp's CPU device only
tar -cJf .whl1/warp_py.tar.xz -C "$work/warp" .
# the tree as it will travel: without checkpoints/ (see above)
tree=$(git ls-files --cached --others --exclude-standard | grep -v '^checkpoints/' | tr '\n' '\0' |
       xargs -0 stat -c %s | awk '{s += $1} END {print s}')
small=$(du -cb .whl1/* | tail -1 | cut -f1)
first=$(( 62 * 1048576 - tree - small ))    # call 1's share of warp.so.xz: 62 MiB with the tree
head -c "$first" "$work/warp.so.xz" > .whl1/warp.so.xz.part1
tail -c +"$(( first + 1 ))" "$work/warp.so.xz" > .whl2/warp.so.xz.part2

cat > .whl1/call1.sh <<'EOF'
# device call 1 of 2: the carried wheels into /tmp/gpuenv (kept while the machine stays warm), warp.so's first part
set -u
t0=$(date +%s)
mkdir -p /tmp/gpuenv /tmp/carry
cp .whl1/warp.so.xz.part1 .whl1/warp.so.sha256 /tmp/carry/
for w in .whl1/*.whl; do python3 -m zipfile -e "$w" /tmp/gpuenv || echo "unpacking $w failed"; done
tar -xJf .whl1/warp_py.tar.xz -C /tmp/gpuenv || echo "Warp's Python files failed"
export PYTHONPATH=/tmp/gpuenv:$PWD/src MUJOCO_GL=disable PYTHONUNBUFFERED=1
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv | tee "$OUT/gpu.csv"
echo "cores $(nproc)"; python3 --version
python3 -c "import mujoco, gymnasium, torch, numba, numpy, stairenv; print('mujoco', mujoco.__version__, 'torch', torch.__version__, 'numba', numba.__version__, 'numpy', numpy.__version__, 'cuda', torch.cuda.is_available())"
echo "call 1: $(( $(date +%s) - t0 )) s"
EOF
cat > .whl2/call2.sh <<'EOF'
# device call 2 of 2: warp.so rebuilt and checked, then benchmarks/gpu_session.sh within LIMIT seconds
set -u
t0=$(date +%s)
LIMIT=${LIMIT:-540}
cat /tmp/carry/warp.so.xz.part1 .whl2/warp.so.xz.part2 | xz -d > /tmp/gpuenv/warp/bin/warp.so
(cd /tmp/gpuenv && sha256sum -c /tmp/carry/warp.so.sha256) || echo "warp.so: checksum FAILED"
export PYTHONPATH=/tmp/gpuenv:$PWD/src MUJOCO_GL=disable PYTHONUNBUFFERED=1
mkdir -p /tmp/res
timeout --kill-after=10 $(( LIMIT - ($(date +%s) - t0) )) env OUT=/tmp/res PYTHON=python3 bash benchmarks/gpu_session.sh
cp /tmp/res/*.json "$OUT/" 2>/dev/null
tar -czf "$OUT/results.tgz" -C /tmp res
for f in /tmp/res/*.log; do echo "=== $f"; tail -c 1500 "$f"; done
cat /tmp/res/status.txt
echo "call 2: $(( $(date +%s) - t0 )) s"
EOF
du -sb .whl1 .whl2 | awk -v t="$tree" '{printf "%s: %.1f MiB (+ the tree, %.1f MiB)\n", $2, $1 / 1048576, t / 1048576}'
