#!/usr/bin/env python
"""Evaluate SIMS skill policies with the SIMS paper's metrics (Tables 1 and 2).

Examples::

    python baselines/evaluate_sims.py --policy zero --tables skills --episodes 20 --compare-paper
    python baselines/evaluate_sims.py --sit runs/sit/model.zip --lie runs/lie/model.zip --reach runs/reach/model.zip \\
        --walk runs/walk/model.zip --getup runs/getup/model.zip --csv sims.csv --json sims.json
    python baselines/evaluate_sims.py --policy kinematic --tables scripts --scripts-per-difficulty 4
    python baselines/evaluate_sims.py --walk pretrained --tables skills --skills walk --push-speed 1.0

Table 1 ("skills"): success rate (success at any step; 20 cm sit / reach / walk / get up,
30 cm lie) and contact error (last step; also the mean smallest error) per skill, each on its
registered env (SIMS-Sit-v0, ...; one generated piece per scene). Table 2 ("scripts"): the
database's short scripts by difficulty (simple 2, mid 3-4, hard 5+ interactions) run through the
state machine in generated rooms; a script succeeds when every keyframe does.

``--policy`` applies to every skill; ``--sit PATH`` etc. override it per skill. A spec is
"zero", "random", a Stable-Baselines3 .zip (``ALGO:path`` for another algorithm) or
"kinematic": the state machine's stand-in, which writes qpos and is NOT physics-based (it checks
the pipeline; its numbers are not results).
"""

from __future__ import annotations

import argparse
import sys

SKILLS = ("walk", "sit", "lie", "reach", "getup")


def build_parser() -> argparse.ArgumentParser:
    from stairenv.evaluation.cli import env_kwarg_argument
    from stairenv.evaluation.pushes import PUSH_HELP
    from stairenv.evaluation.sims import TABLE1_SKILLS
    from stairenv.screenplays.database import DIFFICULTIES

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--policy", help="policy for every skill: zero, random, kinematic, pretrained (each skill's "
                                             "shipped policy), an exported .npz, an SB3 .zip or ALGO:path")
    for skill in SKILLS:
        parser.add_argument(f"--{skill}", metavar="SPEC", help=f"{skill} policy (overrides --policy)")
    parser.add_argument("--tables", nargs="+", choices=("skills", "scripts"), default=["skills", "scripts"],
                        help="which tables (default: both)")
    parser.add_argument("--skills", nargs="+", choices=TABLE1_SKILLS, default=list(TABLE1_SKILLS),
                        help="Table 1 skills (default: all five)")
    parser.add_argument("--episodes", type=int, default=100, help="Table 1 episodes per skill (default: %(default)s)")
    parser.add_argument("--max-episode-steps", type=int, default=None,
                        help="Table 1 time limit in steps (default: the preset's, 300 = 10 s; get up 150)")
    parser.add_argument("--push-speed", type=float, default=0.0, metavar="V",
                        help="Table 1 only (with --tables skills): " + PUSH_HELP)
    parser.add_argument("--difficulties", nargs="+", choices=DIFFICULTIES, default=list(DIFFICULTIES))
    parser.add_argument("--scripts-per-difficulty", type=int, default=None,
                        help="Table 2: the first k scripts of each difficulty (default: all)")
    parser.add_argument("--repeats", type=int, default=1, help="Table 2 runs per script (default: %(default)s)")
    parser.add_argument("--dwell", type=float, default=1.0, help="Table 2: seconds a goal must hold (default: 1)")
    parser.add_argument("--max-seconds", type=float, default=20.0, help="Table 2: seconds per keyframe (default: 20)")
    parser.add_argument("--continue-on-failure", action="store_true",
                        help="Table 2: run the remaining keyframes after a failure (the script still fails)")
    parser.add_argument("--seed", type=int, default=0, help="episode / run k uses seed + k (default: %(default)s)")
    parser.add_argument("--text-encoder", default=None, choices=("auto", "minilm", "hashing"),
                        help="env text encoder (default: the env's, auto)")
    parser.add_argument("--env-kwarg", action="append", default=[], type=env_kwarg_argument, metavar="KEY=VALUE",
                        help="extra env keyword, repeatable; values parsed as Python literals, else strings")
    parser.add_argument("--policy-captions", action="store_true",
                        help="Table 1: draw each skill's captions from those its exported policy trained on "
                             "(recorded in the .npz) instead of the env's own")
    parser.add_argument("--label", help="Method name in the table (default: from the policies)")
    parser.add_argument("--csv", metavar="PATH", help="write the rows of all tables as CSV")
    parser.add_argument("--json", metavar="PATH", help="write settings, rows and per-episode / per-script results")
    parser.add_argument("--compare-paper", action="store_true", help="print the published SIMS numbers beside ours")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bars")
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    from stairenv.evaluation.pushes import push_summary
    from stairenv.evaluation.sims import evaluate_scripts, evaluate_skills, write_reports
    from stairenv.stories import KINEMATIC, MachineSettings, describe_policy

    per_skill = {s: getattr(args, s) or args.policy for s in SKILLS}
    needed = set(args.skills) if args.tables == ["skills"] else set(SKILLS)
    missing = sorted(s for s in needed if per_skill[s] is None)
    if missing:
        parser.error(f"no policy for {missing}: give --policy or --{missing[0]} SPEC")
    for name in ("episodes", "repeats"):
        if getattr(args, name) < 1:
            parser.error(f"--{name} must be >= 1, got {getattr(args, name)}")
    if args.push_speed != 0.0 and "scripts" in args.tables:
        parser.error("--push-speed pushes Table 1's episodes only: add --tables skills")
    env_kwargs = dict(args.env_kwarg)
    if args.text_encoder is not None:
        env_kwargs["text_encoder"] = args.text_encoder
    for skill, spec in per_skill.items():
        if spec is not None:
            print(f"{skill:6s} policy: {describe_policy(spec)}")
    if any(spec == KINEMATIC for spec in per_skill.values()):
        print("NOTE: the kinematic stand-in is not a controller; its rows test the evaluation pipeline only.")

    reports = []
    try:
        if "skills" in args.tables:
            reports.append(evaluate_skills({s: per_skill[s] for s in args.skills}, skills=args.skills,
                                           episodes=args.episodes, seed=args.seed, env_kwargs=env_kwargs,
                                           max_episode_steps=args.max_episode_steps,
                                           progress_bar=not args.no_progress, label=args.label,
                                           policy_captions=args.policy_captions, push_speed=args.push_speed))
        if "scripts" in args.tables:
            settings = MachineSettings(dwell_seconds=args.dwell, max_seconds=args.max_seconds,
                                       stop_on_failure=not args.continue_on_failure)
            reports.append(evaluate_scripts(per_skill, difficulties=args.difficulties,
                                            scripts_per_difficulty=args.scripts_per_difficulty,
                                            repeats=args.repeats, seed=args.seed, settings=settings,
                                            env_kwargs=env_kwargs, progress_bar=not args.no_progress,
                                            label=args.label))
    except ValueError as error:
        parser.error(str(error))
    for report in reports:
        print(report.format_table(compare_paper=args.compare_paper))
        pushes = push_summary(report.meta["settings"], len(report.details))
        if pushes:
            print(pushes)
    if args.compare_paper:
        print("(paper): SIMS Table 1 (SIMS row, 4096 trials) and Table 2 (3D-FRONT scenes); walk and get up are "
              "not in the paper.")
    for path in write_reports(reports, args.csv, args.json):
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
