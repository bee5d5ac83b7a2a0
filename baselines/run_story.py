#!/usr/bin/env python
"""Run a SIMS story or short script through the state machine and film it.

Examples::

    python baselines/run_story.py --theme "a tired evening at home" --length 3 --out videos/story.mp4
    python baselines/run_story.py --script tired_bedtime --json story.json
    python baselines/run_story.py --script tired_bedtime --sit runs/sit/model.zip --lie runs/lie/model.zip
    python baselines/run_story.py --list-scripts

A theme is turned into a story with ``assemble_story`` (short scripts retrieved by text
embedding and chained); ``--script`` runs one short script of the database. A room with the
furniture the keyframes need is generated (``generate_room``), the keyframes are bound to its
pieces, and the state machine (``stairenv.stories.machine``) runs them one skill policy after
another. Each skill's policy is a Stable-Baselines3 .zip (``--sit PATH``, ``ALGO:path``),
"zero", "random" or, by default, the KINEMATIC STAND-IN: a placeholder that writes the
character's qpos (not physics-based; no trained skill policy exists yet). Writes an MP4 of the
whole run (caption on every frame) and, with ``--json``, the per-keyframe results.

Every setting accepted takes effect: an empty ``--theme``, a ``--length`` outside 1 to the
database's size (a story uses each short script once) or ``--length`` with ``--script`` is a usage
error; a story shorter than ``--length`` (no other script can follow) says so. ``--out`` and
``--json`` are checked before the run, and each is written under a hidden name beside it and moved
there once whole, so a run that stops leaves no half-written file.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys

SKILLS = ("walk", "sit", "lie", "reach", "getup")
#: short scripts in a --theme story unless --length says
DEFAULT_LENGTH = 3


def build_parser() -> argparse.ArgumentParser:
    from stairenv.evaluation.cli import env_kwarg_argument

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    what = parser.add_mutually_exclusive_group(required=True)
    what.add_argument("--theme", help="a story theme, e.g. 'a tired evening at home'")
    what.add_argument("--script", metavar="ID", help="a short script id of the database (see --list-scripts)")
    what.add_argument("--list-scripts", action="store_true", help="print the database's script ids and exit")
    parser.add_argument("--length", type=int, default=None,
                        help=f"short scripts in a --theme story, 1 to the database's size (default: {DEFAULT_LENGTH})")
    parser.add_argument("--encoder", default="auto", choices=("auto", "minilm", "hashing"),
                        help="text encoder of story retrieval (default: %(default)s)")
    parser.add_argument("--text-encoder", default="auto", choices=("auto", "minilm", "hashing"),
                        help="text encoder of the env's caption embedding z (default: %(default)s)")
    for skill in SKILLS:
        parser.add_argument(f"--{skill}", default="kinematic", metavar="SPEC",
                            help=f"{skill} policy: SB3 .zip, ALGO:path, zero, random or kinematic (default)")
    parser.add_argument("--seed", type=int, default=0, help="room, env reset and goal seed (default: %(default)s)")
    parser.add_argument("--dwell", type=float, default=1.0, help="seconds a goal must hold (default: %(default)s)")
    parser.add_argument("--max-seconds", type=float, default=20.0, help="per keyframe (default: %(default)s)")
    parser.add_argument("--continue-on-failure", action="store_true", help="go on after a failed keyframe")
    parser.add_argument("--out", default="videos/story.mp4", help="MP4 path (default: %(default)s)")
    parser.add_argument("--no-video", action="store_true", help="run without rendering")
    parser.add_argument("--video-every", type=int, default=1,
                        help="render every k-th step (offscreen rendering is slow; default: %(default)s)")
    parser.add_argument("--width", type=int, default=640)
    parser.add_argument("--height", type=int, default=480)
    parser.add_argument("--json", metavar="PATH", help="write the story and per-keyframe results as JSON")
    parser.add_argument("--env-kwarg", action="append", default=[], type=env_kwarg_argument, metavar="KEY=VALUE",
                        help="extra SIMSEnv keyword, repeatable")
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)

    from stairenv.__main__ import check_output, written_whole
    from stairenv.screenplays import assemble_story, get_encoder, load_database
    from stairenv.stories import BindingError, MachineSettings, describe_policy, run_script

    db = load_database()
    if args.list_scripts:
        for s in db:
            print(f"{s.id:32s} {s.difficulty:6s} {s.n_interactions} interactions  {s.title}")
        return 0
    if args.theme is not None and not args.theme.strip():
        parser.error("--theme: an empty theme; give a few words, e.g. 'a tired evening at home'")
    if args.length is not None and args.script is not None:
        parser.error("--length: a --theme story's length; --script runs one short script")
    length = DEFAULT_LENGTH if args.length is None else args.length
    if not 1 <= length <= len(db):
        parser.error(f"--length must be in [1, {len(db)}] (a story uses each of the database's {len(db)} short "
                     f"scripts at most once), got {length}")
    # the outputs, before any work (a run used to end in a traceback at its end)
    try:
        if not args.no_video and not args.out.lower().endswith(".mp4"):
            raise ValueError(f"--out must be an .mp4 path, got {args.out!r}")
        out = None if args.no_video else check_output("--out", args.out)
        json_path = None if args.json is None else check_output("--json", args.json)
    except ValueError as error:
        parser.error(str(error))
    if args.video_every < 1:
        parser.error(f"--video-every must be >= 1, got {args.video_every}")
    try:
        settings = MachineSettings(dwell_seconds=args.dwell, max_seconds=args.max_seconds,
                                   stop_on_failure=not args.continue_on_failure)
    except ValueError as error:
        parser.error(str(error))
    if args.script is not None:
        try:
            story = db.get(args.script)
        except KeyError as error:
            parser.error(str(error.args[0]))
        print(f"script {story.id!r} ({story.difficulty}): {story.summary}")
    else:
        story = assemble_story(args.theme, db, get_encoder(args.encoder), length=length)
        print(f"story for {args.theme!r}: {' -> '.join(story.script_ids)}\n  {story.narrative}")
        if len(story.script_ids) < length:
            print(f"note: the story has {len(story.script_ids)} of the {length} short scripts asked for (--length): "
                  "no other script can follow its last one")

    policies = {skill: getattr(args, skill) for skill in SKILLS}
    for skill, spec in policies.items():
        print(f"  {skill:6s} policy: {describe_policy(spec)}")
    env_kwargs = {"text_encoder": args.text_encoder, **dict(args.env_kwarg)}
    try:
        with contextlib.ExitStack() as film:  # the video is moved to --out once whole, else removed
            video = None if out is None else film.enter_context(written_whole(out))
            result = run_script(story, policies, seed=args.seed, settings=settings, env_kwargs=env_kwargs,
                                video=video, video_every=args.video_every, width=args.width, height=args.height)
    except (BindingError, ValueError) as error:
        parser.error(str(error))
    if result.video:
        result.video = str(out)

    print(f"room {result.room!r}: {[f['name'] for f in result.details['room_summary']['furniture']]}")
    for k in result.keyframes:
        error = "-" if k.contact_error is None else f"{k.contact_error:.3f}"
        print(f"  {k.index:2d} {k.skill:6s} {k.furniture!s:14s} {k.outcome:8s} err {error:>6s} m  "
              f"{k.seconds:5.1f} s  {k.caption}" + (f"  [{k.note}]" if k.note else ""))
    print(f"story {'succeeded' if result.success else 'failed'}: {sum(k.success for k in result.keyframes)}"
          f"/{len(result.keyframes)} keyframes, {result.seconds:.1f} s simulated")
    if result.video:
        print(f"wrote {result.video} ({result.frames} frames)")
    if json_path is not None:
        text = json.dumps({"theme": args.theme, "script": args.script, "story": story.to_dict(),
                           "result": result.to_dict()}, indent=2) + "\n"
        with written_whole(json_path) as partial:
            partial.write_text(text)
        print(f"wrote {json_path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
