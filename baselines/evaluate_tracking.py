"""A PlaMo tracking specialist in its own training conditions: how long it keeps to its clip, how far its
head is from the clip's, how far it travels against the clip.

The recipe's ``[env_kwargs]`` build the env (``--set key=value`` overrides one, as TOML); episodes run with
the policy's deterministic actions and are reported by how they started: a frame of the start clips
("reference") or standing ("standing", tracking ``standing_clip`` where the recipe names one). Per kind:
steps survived (of the episode's), the share ended by a lost track (``info["track_lost"]``) and by a fall,
the mean head error against the clip's head (XY, Z), the mean pelvis height, and the root's travel
against the clip's over the steps survived. The gate itself is ``evaluate_plamo.py`` (the planner's paths,
standing starts); this says what the specialist learned of its clip.

    python baselines/evaluate_tracking.py --policy t2.npz --config baselines/recipes/plamo_crawl_track_standing.toml
    python baselines/evaluate_tracking.py --policy t2.npz --config ... --set hybrid_fraction=0.0 --episodes 20
"""

from __future__ import annotations

import argparse
import json
import tomllib

import numpy as np
from gymnasium.wrappers import TimeLimit

from stairenv.environments.plamo import PlaMoEnv
from stairenv.pretrained import load_file


def _override(text: str) -> tuple[str, object]:
    key, sep, value = text.partition("=")
    if not sep:
        raise argparse.ArgumentTypeError(f"--set wants key=value, got {text!r}")
    return key.strip(), tomllib.loads(f"v = {value}")["v"]


def run(policy, env_kwargs: dict, episodes: int, seed: int, steps: int) -> dict[str, dict[str, float]]:
    env = TimeLimit(PlaMoEnv(**env_kwargs), steps)
    base = env.unwrapped
    rows: dict[str, list[dict[str, float]]] = {"reference": [], "standing": []}
    for episode in range(episodes):
        obs, info = env.reset(seed=seed + episode)
        kind = "reference" if info.get("reference_start") else "standing"
        track = base._track
        xy, z, pelvis, lost, fell, n = [], [], [], False, False, 0
        while True:
            obs, _, terminated, truncated, info = env.step(policy(obs))
            n += 1
            head = base._head()[0]
            if track is not None:
                target = track.head[track.frame(n)]
                xy.append(float(np.linalg.norm(head[:2] - target[:2])))
                z.append(abs(float(head[2] - target[2])))
            pelvis.append(float(base.data.qpos[2]))     # the root is the pelvis
            if terminated or truncated:
                lost, fell = bool(info.get("track_lost", False)), bool(info.get("fell", False))
                break
        row = {"steps": n, "lost": lost, "fell": fell, "pelvis": float(np.mean(pelvis))}
        if track is not None:
            row.update(xy=float(np.mean(xy)), z=float(np.mean(z)),
                       travel=float(np.linalg.norm(base.data.qpos[:2] - track.qpos[0, :2])),
                       clip_travel=float(np.linalg.norm(track.qpos[track.frame(n), :2] - track.qpos[0, :2])))
        rows[kind].append(row)
    summary = {}
    for kind, kind_rows in rows.items():
        if not kind_rows:
            continue
        summary[kind] = {"episodes": len(kind_rows),
                         **{key: float(np.mean([r[key] for r in kind_rows])) for key in kind_rows[0]}}
    return summary


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--policy", required=True, help="an exported .npz (baselines/export_policy.py)")
    parser.add_argument("--config", required=True, help="the training recipe (.toml) whose env_kwargs to use")
    parser.add_argument("--set", type=_override, action="append", default=[], metavar="KEY=VALUE")
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--seed", type=int, default=700000)
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--json")
    args = parser.parse_args(argv)
    with open(args.config, "rb") as file:
        recipe = tomllib.load(file)
    env_kwargs = dict(recipe.get("env_kwargs", {}))
    if "init" in recipe:
        env_kwargs.setdefault("init", recipe["init"])
    env_kwargs.update(dict(args.set))
    policy = load_file(args.policy, PlaMoEnv(**env_kwargs))
    summary = run(policy, env_kwargs, args.episodes, args.seed, args.steps)
    print(f"{'start':<10} {'n':>3} {'steps':>6} {'lost':>5} {'fell':>5} {'xy':>5} {'z':>5} {'pelvis':>6} "
          f"{'travel':>6} {'clip':>5}")
    for kind, s in summary.items():
        print(f"{kind:<10} {s['episodes']:>3} {s['steps']:>6.0f} {s['lost']:>5.0%} {s['fell']:>5.0%} "
              f"{s.get('xy', np.nan):>5.2f} {s.get('z', np.nan):>5.2f} {s['pelvis']:>6.2f} "
              f"{s.get('travel', np.nan):>6.2f} {s.get('clip_travel', np.nan):>5.2f}")
    if args.json:
        with open(args.json, "w") as file:
            json.dump({"settings": {**vars(args), "set": dict(args.set), "env_kwargs": env_kwargs},
                       "summary": summary}, file, indent=2, default=str)


if __name__ == "__main__":
    main()
