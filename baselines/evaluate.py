#!/usr/bin/env python
"""Evaluate a policy on a stairenv env with the InterLevel paper's metrics (Tables 1-3).

Examples::

    python baselines/evaluate.py --policy random --episodes 100
    python baselines/evaluate.py --policy zero --paper-heights --compare-paper
    python baselines/evaluate.py --policy runs/ppo/model.zip --env InterLevel-v0 --csv out.csv
    python baselines/evaluate.py --policy SAC:runs/sac/model.zip --env-kwarg pd_gains=stiff
    python baselines/evaluate.py --policy policy.npz --paper-heights --gait   # + gait columns
    python baselines/evaluate.py --policy policy.npz --paper-heights --num-envs 32   # 32 worlds side by side
    python baselines/evaluate.py --policy policy.npz --push-speed 1.0   # robustness: a 1 m/s kick per episode

A model path is loaded with ``stable_baselines3.PPO.load`` (``ALGO:path`` for another
algorithm); a ``vecnormalize.pkl`` beside it normalises the observations.
Prints the results table; ``--csv`` / ``--json`` save them. ``--gait`` adds the gait columns
(``stairenv.evaluation.gait``): Alt. (% of successful climbs with alternating feet), TD/tread
(foot touchdowns per tread), Hop, Crawl (% of episodes) and Slide (% of stance frames).
"""

from __future__ import annotations

import argparse
import sys

from stairenv.evaluation.cli import env_kwarg_argument
from stairenv.evaluation.interlevel import PAPER_STEP_HEIGHTS, evaluate
from stairenv.evaluation.pushes import PUSH_HELP, push_summary


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        description="Evaluate a policy with the InterLevel paper's metrics: progress (%), "
        "early termination (%) and completion time (s) of successful climbs.",
    )
    parser.add_argument("--policy", required=True,
                        help="'random', 'zero', a Stable-Baselines3 model .zip, or ALGO:path (e.g. SAC:model.zip)")
    parser.add_argument("--env", default="InterLevel-v0", help="env id (default: %(default)s)")
    parser.add_argument("--episodes", type=int, default=100,
                        help="episodes in all, or per step height with --heights (default: %(default)s)")
    parser.add_argument("--seed", type=int, default=0, help="episode i is reset with seed + i (default: %(default)s)")
    heights = parser.add_mutually_exclusive_group()
    heights.add_argument("--heights", type=float, nargs="+", metavar="H",
                         help="fixed step heights (m), --episodes each, e.g. 0.05 0.10 0.15 0.20")
    heights.add_argument("--paper-heights", action="store_true",
                         help=f"the paper's test heights {' '.join(f'{h:.2f}' for h in PAPER_STEP_HEIGHTS)} m")
    parser.add_argument("--max-episode-steps", type=int, default=None,
                        help="time limit in policy steps (default: the preset's, 600 = 20 s)")
    parser.add_argument("--csv", metavar="PATH", help="write the per-group results as CSV")
    parser.add_argument("--json", metavar="PATH", help="write settings, per-group and per-episode results as JSON")
    parser.add_argument("--label", help="Method name in the table (default: the --policy value)")
    parser.add_argument("--env-kwarg", action="append", default=[], type=env_kwarg_argument, metavar="KEY=VALUE",
                        help="extra env keyword, repeatable; values parsed as Python literals, else strings")
    parser.add_argument("--gait", action="store_true",
                        help="also record foot contacts and report alternating feet, touchdowns per tread, "
                             "hops, crawling and sliding")
    parser.add_argument("--num-envs", type=int, default=1,
                        help="run the episodes on this many worlds of the batched env side by side (physics on "
                             "every core); 1 = one episode after another (default: %(default)s)")
    parser.add_argument("--push-speed", type=float, default=0.0, metavar="V", help=PUSH_HELP)
    parser.add_argument("--compare-paper", action="store_true", help="also print the published numbers")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.episodes < 1:
        parser.error(f"--episodes must be >= 1, got {args.episodes}")
    step_heights = PAPER_STEP_HEIGHTS if args.paper_heights else args.heights
    try:
        report = evaluate(
            args.policy,
            env_id=args.env,
            episodes=args.episodes,
            seed=args.seed,
            env_kwargs=dict(args.env_kwarg),
            step_heights=step_heights,
            progress_bar=not args.no_progress,
            max_episode_steps=args.max_episode_steps,
            label=args.label,
            gait=args.gait,
            num_envs=args.num_envs,
            push_speed=args.push_speed,
        )
    except ValueError as error:
        parser.error(str(error))
    print(report.format_table(compare_paper=args.compare_paper))
    pushes = push_summary(report.meta, len(report.details))
    if pushes:
        print(pushes)
    if args.compare_paper:
        print("(paper): Shilton et al., AAAI 2025, Tables 1-3, 4096 trials per row; '-' = no successful climb.")
    if args.csv:
        print(f"wrote {report.to_csv(args.csv)}")
    if args.json:
        print(f"wrote {report.to_json(args.json)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
