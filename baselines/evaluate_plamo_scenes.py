"""PlaMo scene evaluations: random-scene success rate, the slalom test, and plan plots.

    python baselines/evaluate_plamo_scenes.py scenes --policy PATH --episodes 50     # paper: 81% solved
    python baselines/evaluate_plamo_scenes.py slalom --policy PATH --episodes 20     # planned vs constant speed
    python baselines/evaluate_plamo_scenes.py plot --seed 3 --out plan.png           # path coloured by speed
"""

from __future__ import annotations

import argparse

import gymnasium as gym

from stairenv.evaluation.plamo import plot_planned_path, scene_episodes, scene_report, slalom_comparison
from stairenv.evaluation.policies import load_policy


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("what", choices=("scenes", "slalom", "plot"))
    parser.add_argument("--policy", default="zero",
                        help="'random', 'zero', 'pretrained' (the policy shipped for the env), an exported .npz or a "
                             "Stable-Baselines3 model .zip")
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--max-episode-steps", type=int, default=None)
    parser.add_argument("--num-envs", type=int, default=1,
                        help="run the episodes on this many worlds of the batched env side by side (the same "
                             "episodes; physics on every core); 1 = one after another (default: %(default)s)")
    parser.add_argument("--slalom", action="store_true", help="plot the slalom scene")
    parser.add_argument("--json")
    parser.add_argument("--out", default="plamo_plan.png")
    args = parser.parse_args(argv)
    if args.what == "plot":
        kwargs = {"scene_kind": "slalom"} if args.slalom else {}
        print(f"wrote {plot_planned_path(kwargs, args.seed, args.out)}")
        return
    if args.episodes < 1:
        parser.error("--episodes must be >= 1")
    probe = gym.make("PlaMoScene-v0")
    policy = load_policy(args.policy, probe, seed=args.seed)
    probe.close()
    if args.what == "scenes":
        rows = [scene_episodes(policy, args.episodes, args.seed, None, args.max_episode_steps, args.policy,
                               args.num_envs)]
    else:
        rows = slalom_comparison(policy, args.episodes, args.seed, max_episode_steps=args.max_episode_steps,
                                 num_envs=args.num_envs)
    report = scene_report(rows, args.policy, {"what": args.what, "episodes": args.episodes, "seed": args.seed,
                                              "max_episode_steps": args.max_episode_steps})
    print(report.format_table())
    if args.json:
        report.to_json(args.json)


if __name__ == "__main__":
    main()
