"""Importing long motion clips: this tree's importers against earlier ones (issue #23, item 6).

    python benchmarks/bench_importers.py [--motions ../shared/motions] [--frames 20000]
        [--fit-frames 4000] [--repeats 1] [--before 09d3380~1] [--main main] [--json out.json]

Long clips are made from the shipped motion files (never written into the repository; a
temporary folder): ``cmu``, CMU 83_32.bvh (120 fps, few joints out of reach) tiled to
``--frames`` frames, imported at 30 fps; ``fits``, the 60 fps DeepMimic clips whose joints
leave their ranges (crawl, getting up, jump, roll, zombie walk: every frame fits a joint into
range) concatenated and tiled to ``--fit-frames`` frames. Each tree (``--before``, the code
before the first speed-up, 09d3380~1; ``--main``; this tree) is exported with ``git archive``
and each import runs in a fresh process (``import_motion`` timed alone; its compile cache is
filled beforehand; trees naming the same commit are exported and timed once), ``fresh``: the first
import in that process (numba's load, ~0.5-1 s, included), ``warm``: after a short clip of the same
kind (83_32.bvh, humanoid3d_roll.txt), as in a process that imports several clips or has loaded numba
already (the envs do); the trees interleaved per repeat, so that the ratios come from one run on one
machine. Reported: the median wall and CPU (``time.process_time``: steadier than wall time on a busy
machine) seconds per tree, the ratios before/this and main/this, and the largest difference of the
imported qpos (this tree against each other tree).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]

FIT_CLIPS = ("crawl", "getup_facedown", "getup_faceup", "jump", "roll", "zombie_walk")

_KERNELS = """
try:
    from stairenv.motion.importers import kernels
except ImportError:  # before 09d3380: nothing compiled
    kernels = None
for name, args in (("viterbi2", (np.zeros((3, 2)), np.zeros((2, 2, 2)))),
                   ("fit_in_range", (np.eye(3)[None], np.zeros((1, 3)), -np.ones(3), np.ones(3), np.zeros(3), 3.0, 12)),
                   ("parse_frames", (np.frombuffer(b"1 2", dtype=np.uint8), 1, 2))):
    if hasattr(kernels, name):
        getattr(kernels, name)(*args)
"""

#: numba's compile caches filled (compiling is not importing)
_WARM = "import numpy as np\n" + _KERNELS

#: argv: the clip, where its qpos go, and for the warm mode a short clip to import first
_RUN = """
import sys, time
import numpy as np
from stairenv.motion.importers import import_motion
if len(sys.argv) > 3:  # warm: a short clip of the same kind first (scipy.optimize... loaded), the kernels
    import_motion(sys.argv[3])
""" + "\n".join("    " + line for line in _KERNELS.strip().splitlines()) + """
t, cpu = time.perf_counter(), time.process_time()
clip = import_motion(sys.argv[1])
elapsed, cpu = time.perf_counter() - t, time.process_time() - cpu
np.save(sys.argv[2], clip.qpos)
print(elapsed, cpu)
"""


def long_bvh(motions: Path, frames: int, out: Path) -> Path:
    """CMU 83_32.bvh with its motion frames repeated up to ``frames`` frames."""
    lines = (motions / "CMU" / "83_32.bvh").read_text().splitlines()
    k = next(i for i, line in enumerate(lines) if line.startswith("Frames:"))
    body = [line for line in lines[k + 2:] if line.strip()]
    tiled = [body[i % len(body)] for i in range(frames)]
    path = out / "long_cmu.bvh"
    path.write_text("\n".join([*lines[:k], f"Frames: {frames}", lines[k + 1], *tiled]) + "\n")
    return path


def long_fits(motions: Path, frames: int, out: Path) -> Path:
    """The DeepMimic clips of ``FIT_CLIPS`` one after another, repeated up to ``frames`` frames at 60 fps."""
    pool = []
    for name in FIT_CLIPS:
        pool += json.loads((motions / "DeepMimic" / f"humanoid3d_{name}.txt").read_text())["Frames"]
    tiled = [[1.0 / 60.0, *pool[i % len(pool)][1:]] for i in range(frames)]
    tiled[-1][0] = 0.0
    path = out / "long_fits.txt"
    path.write_text(json.dumps({"Loop": "none", "Frames": tiled}))
    return path


def export(rev: str, out: Path) -> Path:
    """``git archive`` of the package (and the assets it loads) at ``rev`` into ``out``; its src folder."""
    out.mkdir(parents=True)
    archive = subprocess.run(["git", "-C", str(REPO), "archive", rev, "src", "envs", "xml"],
                             check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(out)], input=archive, check=True)
    return out / "src"


def python(src: Path, code: str, *argv: str) -> str:
    """Run ``code`` in a fresh interpreter that imports stairenv from ``src``; its standard output."""
    env = {**os.environ, "PYTHONPATH": str(src)}
    return subprocess.run([sys.executable, "-c", code, *argv], env=env, check=True, capture_output=True,
                          text=True).stdout


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--motions", type=Path, default=REPO.parent / "shared" / "motions")
    parser.add_argument("--frames", type=int, default=20_000, help="frames of the long CMU clip")
    parser.add_argument("--fit-frames", type=int, default=4_000, help="frames of the long DeepMimic clip")
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--before", default="09d3380~1", help="the code before the first speed-up")
    parser.add_argument("--main", default="main", help="the current main branch")
    parser.add_argument("--this", help="a commit to time instead of the working tree")
    parser.add_argument("--clips", default="cmu,fits")
    parser.add_argument("--modes", default="fresh,warm",
                        help="fresh: the import alone in a new process (numba's load included); warm: after "
                             "importing a short clip of the same kind in that process")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        # one export and one timing per commit: trees naming the same commit share them (the suite's run
        # names HEAD twice)
        exported: dict[str, Path] = {}

        def tree(rev: str, name: str) -> Path:
            commit = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--verify", f"{rev}^{{commit}}"],
                                    check=True, capture_output=True, text=True).stdout.strip()
            if commit not in exported:
                exported[commit] = export(rev, tmp / name)
            return exported[commit]

        trees = {"before": tree(args.before, "before"), "main": tree(args.main, "main"),
                 "this": tree(args.this, "this") if args.this else REPO / "src"}
        for src in dict.fromkeys(trees.values()):  # fill numba's compile caches: compiling is not importing
            python(src, _WARM)
        makers = {"cmu": lambda: long_bvh(args.motions, args.frames, tmp),
                  "fits": lambda: long_fits(args.motions, args.fit_frames, tmp)}
        shorts = {"cmu": args.motions / "CMU" / "83_32.bvh", "fits": args.motions / "DeepMimic" / "humanoid3d_roll.txt"}
        results = {}
        for name, mode in ((n, m) for n in args.clips.split(",") for m in args.modes.split(",")):
            clip = makers[name]()
            warm = [str(shorts[name])] if mode == "warm" else []
            wall: dict[str, list[float]] = {tree: [] for tree in trees}
            cpu: dict[str, list[float]] = {tree: [] for tree in trees}
            # one import per distinct tree; trees sharing a commit share its timing and its qpos
            qpos_files = {src: tmp / f"{name}_{k}.npy" for k, src in enumerate(dict.fromkeys(trees.values()))}
            for _ in range(args.repeats):
                timed = {src: tuple(map(float, python(src, _RUN, str(clip), str(file), *warm).strip()
                                                .splitlines()[-1].split()))
                         for src, file in qpos_files.items()}
                for tree, src in trees.items():
                    wall[tree].append(timed[src][0])
                    cpu[tree].append(timed[src][1])
            qpos = {tree: np.load(qpos_files[src]) for tree, src in trees.items()}
            frames = args.frames if name == "cmu" else args.fit_frames
            r = results[f"{name}_{mode}"] = {
                "source_frames": frames,
                "clip_frames": int(len(qpos["this"])),
                "max_abs_qpos_diff_vs_before": float(np.abs(qpos["this"] - qpos["before"]).max()),
                "max_abs_qpos_diff_vs_main": float(np.abs(qpos["this"] - qpos["main"]).max()),
            }
            line = f"{name} ({mode}): {frames} source frames -> {r['clip_frames']} clip frames"
            for kind, times in (("wall", wall), ("cpu", cpu)):
                median = {tree: statistics.median(t) for tree, t in times.items()}
                r[f"{kind}_seconds"] = median
                r[f"{kind}_ms_per_source_frame"] = {tree: round(1000 * s / frames, 4) for tree, s in median.items()}
                r[f"{kind}_speedup_vs_before"] = round(median["before"] / median["this"], 2)
                r[f"{kind}_speedup_vs_main"] = round(median["main"] / median["this"], 2)
                line += (f"\n  {kind:4s}: " + ", ".join(f"{tree} {s:.2f} s" for tree, s in median.items())
                         + f"; this tree {r[f'{kind}_speedup_vs_before']}x faster than before 09d3380, "
                         f"{r[f'{kind}_speedup_vs_main']}x than main")
            line += (f"\n  max |qpos diff| vs before {r['max_abs_qpos_diff_vs_before']:.2e}, "
                     f"vs main {r['max_abs_qpos_diff_vs_main']:.2e}")
            print(line, flush=True)
    if args.json:
        args.json.write_text(json.dumps(results, indent=2))


if __name__ == "__main__":
    main()
