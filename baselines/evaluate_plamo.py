"""PlaMo Table 2: mean XY and Z head-tracking error per terrain x locomotion for a policy.

    python baselines/evaluate_plamo.py --policy random --episodes 5
    python baselines/evaluate_plamo.py --policy runs/PlaMo-v0/seed0/final_model.zip --csv plamo.csv
    python baselines/evaluate_plamo.py --policy pretrained --terrains flat --locomotions walk --push-speed 1.0
    python baselines/evaluate_plamo.py --policy pretrained --episodes 50 --num-envs 10   # 10 worlds side by side

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
    parser.add_argument("--num-envs", type=int, default=1,
                        help="run a cell's episodes on this many worlds of the batched env side by side (the same "
                             "episodes; physics on every core); 1 = one after another (default: %(default)s)")
    parser.add_argument("--physics", choices=("mujoco", "serial", "warp"), default=None,
                        help="with --num-envs > 1: the physics back-end (default: the batched env's, MuJoCo C on a "
                             "pool of threads)")
    parser.add_argument("--physics-device", default=None, help="with --physics warp: Warp's device (cuda:0, cpu)")
    parser.add_argument("--csv")
    parser.add_argument("--json")
    args = parser.parse_args(argv)
    if args.episodes < 1:
        parser.error("--episodes must be >= 1")
    try:
        report = evaluate(args.policy, args.env, args.episodes, args.seed, max_episode_steps=args.max_episode_steps,
                          terrains=args.terrains, locomotions=args.locomotions, constant_paths=not args.varying_paths,
                          push_speed=args.push_speed, num_envs=args.num_envs, physics=args.physics,
                          physics_device=args.physics_device)
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
