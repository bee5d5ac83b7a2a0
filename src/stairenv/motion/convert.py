"""Convert motion-capture files into stairenv clips (``.npz``).

Usage::

    python -m stairenv.motion.convert INPUT [INPUT ...] --out DIR [--fps 30]
                                      [--skeleton cmu] [--skip-frames N] [--ground body]

Each INPUT is a file (``.npy`` IsaacGymEnvs/ASE, ``.txt`` DeepMimic, ``.bvh``) or a folder,
whose files with those suffixes are converted (not recursively; ``NOTICE``, ``README``
and ``LICENSE`` text files are skipped). Clips are written to ``DIR/<name>.npz`` and one
line per clip reports frames, fps, duration, the forward-kinematics check (position error
against the source for .npy/.txt, limb-direction error for .bvh) and the share of joint
angles clamped into range. A file or folder that fails, for whatever reason, is reported
on stderr and the others are still converted; the last line counts the failures. The exit
status is 0 if every input converted, 1 if some failed, 2 on bad arguments.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterable, Sequence
from pathlib import Path

from stairenv.motion.clip import MotionClip, MotionFileError

_DOC_STEMS = ("NOTICE", "README", "LICENSE", "LICENCE", "COPYING")


def _suffixes() -> dict[str, tuple[str, str]]:
    from stairenv.motion.importers import SUFFIXES

    return SUFFIXES


def collect_inputs(inputs: Iterable[str | Path]) -> list[Path]:
    """Expand folders into their motion files (sorted); files are kept as given.

    Raises ``FileNotFoundError`` for a missing path and ``ValueError`` for a folder without
    motion files.
    """
    files: list[Path] = []
    for item in inputs:
        path = Path(item)
        if path.is_dir():
            found = sorted(
                p for p in path.iterdir()
                if p.is_file() and p.suffix.lower() in _suffixes()
                and not p.stem.upper().startswith(_DOC_STEMS)
            )
            if not found:
                raise ValueError(f"{path}: no motion files ({', '.join(sorted(_suffixes()))}) in this folder")
            files.extend(found)
        elif path.is_file():
            files.append(path)
        else:
            raise FileNotFoundError(f"{path}: no such file or folder")
    return files


def summary_line(clip: MotionClip, out: Path) -> str:
    """One line: name, frames, fps, duration, FK check, clamped share, output path."""
    meta = clip.meta
    parts = [f"{clip.name}: {clip.num_frames} frames", f"{clip.fps:g} fps", f"{clip.duration:.2f} s"]
    if "fk_error" in meta:
        fk = meta["fk_error"]
        parts.append(f"FK error mean {100 * fk['mean_m']:.2f} cm max {100 * fk['max_m']:.2f} cm")
    if "limb_direction_error_deg" in meta:
        fk = meta["limb_direction_error_deg"]
        parts.append(f"limb direction error mean {fk['mean']:.2f} deg max {fk['max']:.2f} deg")
    if "clamped_fraction" in meta:
        parts.append(f"clamped {100 * meta['clamped_fraction']:.2f}% (max {meta['max_clamp_deg']:.1f} deg)")
    return ", ".join(parts) + f" -> {out}"


def _output_name(path: Path, taken: set[str]) -> str:
    name = path.stem
    if name in taken:
        name = f"{path.stem}_{path.suffix.lstrip('.').lower()}"
    k = 2
    base = name
    while name in taken:
        name, k = f"{base}_{k}", k + 1
    taken.add(name)
    return name


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m stairenv.motion.convert",
        description="Convert IsaacGymEnvs .npy, DeepMimic .txt and BVH motions into stairenv .npz clips.",
    )
    parser.add_argument("inputs", nargs="+", metavar="INPUT", help="motion files or folders of them")
    parser.add_argument("--out", required=True, metavar="DIR", help="folder for the .npz clips (created)")
    parser.add_argument("--fps", type=float, default=30.0,
                        help="frame rate of the clips, by slerp resampling; 0 keeps each file's own "
                             "(default: %(default)s)")
    parser.add_argument("--skeleton", default="cmu", help="source skeleton of BVH files (default: %(default)s)")
    parser.add_argument("--skip-frames", type=int, default=None, metavar="N",
                        help="leading BVH frames to drop (default: the skeleton's, 1 for cmu)")
    parser.add_argument("--ground", choices=("body", "feet", "none"), default="body",
                        help="what touches z = 0: the lowest body point, the lowest foot sole, "
                             "or keep the file's heights (default: %(default)s)")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.fps < 0 or args.fps != args.fps:
        parser.error(f"--fps must be >= 0, got {args.fps}")
    if args.skip_frames is not None and args.skip_frames < 0:
        parser.error(f"--skip-frames must be >= 0, got {args.skip_frames}")
    from stairenv.motion.importers import import_motion
    from stairenv.motion.importers.bvh import SKELETONS

    if args.skeleton not in SKELETONS:
        parser.error(f"unknown --skeleton {args.skeleton!r}; known: {', '.join(sorted(SKELETONS))}")
    failed: list[str] = []  # inputs that are no file or folder of motion files, then files that failed
    files: list[Path] = []
    for item in args.inputs:
        try:
            files.extend(collect_inputs([item]))
        except (FileNotFoundError, ValueError) as err:
            failed.append(str(item))
            print(f"error: {err}", file=sys.stderr)
    total = len(failed) + len(files)
    out_dir = Path(args.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    taken: set[str] = set()
    for path in files:
        try:
            clip = import_motion(path, fps=args.fps or None, skeleton=args.skeleton,
                                 skip_frames=args.skip_frames, ground=args.ground)
            saved = clip.save(out_dir / f"{_output_name(path, taken)}.npz")
        except Exception as err:  # one bad file, or an importer bug it reveals, must not stop the batch
            failed.append(str(path))
            print(f"error: {_describe(err, path)}", file=sys.stderr)
            continue
        print(summary_line(clip, saved))
    if failed:
        print(f"{len(failed)} of {total} input(s) failed: {', '.join(failed)}", file=sys.stderr)
        return 1
    return 0


def _describe(err: Exception, path: Path) -> str:
    """The error's message, led by the file (``MotionFileError`` names it already)."""
    if isinstance(err, MotionFileError):
        return str(err)
    return f"{path}: {type(err).__name__}: {err}"


if __name__ == "__main__":
    sys.exit(main())
