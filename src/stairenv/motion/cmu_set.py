"""Captured clips from the CMU Graphics Lab Motion Capture Database, converted for stairenv.

PlaMo's crawl and crouch-walk references were one DeepMimic crawl and synthesised crouch-walks
(:mod:`stairenv.motion.plamo_set`); these are real captures of people crawling, walking crouched and
running, for the per-locomotion specialists (a specialist's ``--reference`` is the folder, or a clip of
it). CMU's terms: the data may be copied, modified and redistributed, for research or commercial use, but
not resold (``data/cmu/NOTICE.txt``; "The data used in this project was obtained from mocap.cs.cmu.edu. The
database was created with funding from NSF EIA-0196217.").

The raw files are the cgspeed / B. Hahne BVH release of the database (root ``Hips``, 31 joints, y up,
120 frames a second), as stored in the public GitHub repository ``una-dinosauria/cmu-mocap``
(:data:`CLIPS` names each file's commit and path); they are never shipped. Each clip is imported with
the ``cmu`` skeleton (``stairenv.motion.importers.bvh``: the T-pose frame 0 dropped, 30 frames a
second by slerp), cut to :attr:`Captured.seconds`, put on the floor by its support and labelled
(``plamo_set.label_clip``: locomotion, head height, speed, flight). The converted clips ship in
``stairenv/motion/data/cmu/`` with a ``NOTICE.txt``; rebuild them from a folder holding the raw
``<trial>.bvh`` files with ``python -m stairenv.motion.cmu_set --raw DIR``.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from stairenv.motion.clip import MotionClip
from stairenv.motion.plamo_set import label_clip, load_folder, on_support, save_and_describe

__all__ = ["CLIPS", "DATA_DIR", "Captured", "build_clip", "build_clips", "load_cmu_clips"]

DATA_DIR = Path(__file__).resolve().parent / "data" / "cmu"
LICENCE = "CMU Graphics Lab Motion Capture Database terms (mocap.cs.cmu.edu/faqs.php): free to use, not to resell"


@dataclass(frozen=True)
class Captured:
    """One CMU trial: its clip name, the trial id, CMU's description, the locomotion it shows, the part
    kept (seconds of the converted clip, ``None``: all), where the raw file was read, and whether the clip
    changes from one locomotion to another (``transition``: its ``locomotion`` is the one it changes to)."""

    name: str
    trial: str
    description: str
    locomotion: str
    origin: str
    seconds: tuple[float, float] | None = None
    note: str = ""
    transition: bool = False    # the clip changes locomotion (gets down, gets up): meta["transition"]
    terrain: str = "flat"       # "stairs": grounded by its first frames' floor, not a line through its support


_REPO = "github.com/una-dinosauria/cmu-mocap"
CLIPS: tuple[Captured, ...] = (
    Captured("cmu_run_09_01", "09_01", "run", "run",
             f"{_REPO} @ 62ac0fb0ec43cff2bf66426928f4fa6682d4bbdc : 009/09_01.bvh"),
    Captured("cmu_crouch_walk_136_10", "136_10", "Walk Crouched", "crouch-walk",
             f"{_REPO} @ 5d98bb6b62b4735d89ff5f53e96899de2b92d8b4 : data/136/136_10.bvh", seconds=(1.5, 9.8),
             note="a shallow crouch (head ~1.3 m, the planner's crouch-walk ~0.8 m), walking straight; the still "
                  "start and the final turn cut"),
    Captured("cmu_crawl_133_01", "133_01", "Walk Crawl", "crawl",
             f"{_REPO} @ f50fdd380214418ff240056a728a34adaf7bd1b0 : 133/133_01.bvh", seconds=(4.3, 7.7),
             note="the crawl on hands and knees alone (head ~0.75 m, ~0.5 m/s)"),
    Captured("cmu_walk_crawl_walk_133_01", "133_01", "Walk Crawl", "crawl",
             f"{_REPO} @ f50fdd380214418ff240056a728a34adaf7bd1b0 : 133/133_01.bvh", seconds=(1.0, 10.5),
             note="walks, gets down onto hands and knees, crawls ~1.6 m, gets up and walks on: the getting down "
                  "a crawl from a standing start needs", transition=True),
    Captured("cmu_stairs_up_83_32", "83_32", "walk forward stepping up stairs", "walk",
             f"{_REPO} @ 5d98bb6b62b4735d89ff5f53e96899de2b92d8b4 : data/083/83_32.bvh", seconds=(1.5, 8.6),
             note="stands, walks four steps and climbs three steps of ~0.19 m step over step (feet alternating), "
                  "then stands on the top: the real stair ascent beside the synthesised ones (InterLevel)",
             terrain="stairs"),
)


def build_clip(captured: Captured, raw_dir: str | Path) -> MotionClip:
    """One clip: imported from ``raw_dir/<trial>.bvh``, cut, put on its support, labelled."""
    from stairenv.motion.importers import import_motion

    clip = import_motion(Path(raw_dir) / f"{captured.trial}.bvh", ground="none", name=captured.name)
    qpos = clip.qpos
    if captured.seconds is not None:
        first, last = (int(round(s * clip.fps)) for s in captured.seconds)
        qpos = qpos[first:last]
    cut = MotionClip(qpos, clip.fps, captured.name, False, f"CMU {captured.trial}", dict(clip.meta))
    extra = {**({"note": captured.note} if captured.note else {}),
             **({"transition": True} if captured.transition else {})}
    about = dict(source_file=f"CMU {captured.trial}.bvh", origin=captured.origin, licence=LICENCE,
                 description=captured.description, seconds=None if captured.seconds is None else list(captured.seconds),
                 **extra)
    if captured.terrain == "stairs":    # the support rises with the steps: the importer's floor (its first frame's)
        grounded = MotionClip(cut.qpos, cut.fps, cut.name, False, cut.source, {**cut.meta, **about})
        return label_clip(grounded, captured.locomotion, terrain="stairs")
    return label_clip(on_support(cut, **about), captured.locomotion)


def build_clips(raw_dir: str | Path) -> list[MotionClip]:
    return [build_clip(captured, raw_dir) for captured in CLIPS]


def load_cmu_clips(folder: str | Path = DATA_DIR) -> list[MotionClip]:
    """The shipped clips (sorted by file name)."""
    return load_folder(folder, "CMU clips")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m stairenv.motion.cmu_set",
                                     description="Rebuild the shipped CMU clips from the raw CMU BVH files.")
    parser.add_argument("--raw", type=Path, required=True, help="folder holding <trial>.bvh (e.g. 133_01.bvh)")
    parser.add_argument("--out", type=Path, default=DATA_DIR, help="folder for the .npz clips (default: the package's)")
    parser.add_argument("--only", nargs="+", metavar="NAME", help="rebuild only these clips (e.g. those whose raw "
                        "files you have: ../shared/motions/CMU holds 83_32.bvh)")
    args = parser.parse_args(argv)
    chosen = [c for c in CLIPS if args.only is None or c.name in args.only]
    if args.only is not None and len(chosen) != len(set(args.only)):
        parser.error(f"--only: unknown clip names; the clips are {[c.name for c in CLIPS]}")
    save_and_describe([build_clip(captured, args.raw) for captured in chosen], args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
