"""PlaMo Table 2: mean XY and Z head-tracking error per terrain x locomotion for a policy.

    python baselines/evaluate_plamo.py --policy random --episodes 5
    python baselines/evaluate_plamo.py --policy runs/PlaMo-v0/seed0/final_model.zip --csv plamo.csv
    python baselines/evaluate_plamo.py --policy pretrained --terrains flat --locomotions walk --push-speed 1.0

ET (%) is the share of episodes ended early: the head fell within ``min_head_height`` of the terrain
or left the path by more than ``max_xy_error``; ``--json`` records each episode's ending (fell, off path)
and, with ``--push-speed``, its push.
"""

from __future__ import annotations

import argparse

from stairenv.evaluation.plamo import LOCOMOTIONS, TERRAINS, evaluate
from stairenv.evaluation.pushes import PUSH_HELP, push_summary


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--policy", required=True,
                        help="'random', 'zero', 'pretrained' (the policy shipped for the env), an exported .npz or a "
                             "Stable-Baselines3 model .zip")
    parser.add_argument("--env", default="PlaMo-v0")
    parser.add_argument("--episodes", type=int, default=10, help="episodes per terrain x locomotion")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--terrains", nargs="+", default=list(TERRAINS), choices=TERRAINS)
    parser.add_argument("--locomotions", nargs="+", default=list(LOCOMOTIONS), choices=LOCOMOTIONS)
    parser.add_argument("--max-episode-steps", type=int, default=None)
    parser.add_argument("--varying-paths", action="store_true",
                        help="heights and speeds change along a path (as in training) instead of the paper's "
                             "one height and one speed per path")
    parser.add_argument("--push-speed", type=float, default=0.0, metavar="V", help=PUSH_HELP)
    parser.add_argument("--csv")
    parser.add_argument("--json")
    args = parser.parse_args(argv)
    if args.episodes < 1:
        parser.error("--episodes must be >= 1")
    try:
        report = evaluate(args.policy, args.env, args.episodes, args.seed, max_episode_steps=args.max_episode_steps,
                          terrains=args.terrains, locomotions=args.locomotions, constant_paths=not args.varying_paths,
                          push_speed=args.push_speed)
    except ValueError as error:
        parser.error(str(error))
    print(report.format_table())
    pushes = push_summary(report.meta["settings"], len(report.details))
    if pushes:
        print(pushes)
    if args.csv:
        report.to_csv(args.csv)
    if args.json:
        report.to_json(args.json)


if __name__ == "__main__":
    main()
