"""Export a trained SB3 PPO policy to a numpy ``.npz`` (``stairenv.pretrained``).

The exported file needs neither torch nor Stable-Baselines3 and runs no code when
opened; it holds the actor's layers, the VecNormalize observation statistics saved
beside the checkpoint, and a JSON config (the env id, the run's settings and, if
given, an evaluation file's contents).

    python baselines/export_policy.py runs/InterLevel-v0/seed0/final_model.zip --out InterLevel-v0.npz
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import gymnasium as gym

import stairenv  # noqa: F401  (registers the env ids)
from stairenv.evaluation.policies import load_policy
from stairenv.pretrained import from_sb3, load_file


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("model", help="an SB3 PPO checkpoint .zip (its VecNormalize .pkl beside it is used)")
    parser.add_argument("--env", default="InterLevel-v0", help="the env id the policy was trained on")
    parser.add_argument("--out", required=True, help="the .npz to write")
    parser.add_argument("--config", help="a JSON file to store with the policy (training settings)")
    parser.add_argument("--evaluation", help="a JSON evaluation report to store with the policy")
    args = parser.parse_args(argv)
    if not args.out.endswith(".npz"):
        parser.error(f"--out must end in .npz, got {args.out!r}")
    env = gym.make(args.env)
    sb3 = load_policy(args.model, env)  # checks the spaces; the normaliser beside the model
    config = {"env_id": args.env, "source": Path(args.model).name}
    for key, path in (("training", args.config), ("evaluation", args.evaluation)):
        if path:
            config[key] = json.loads(Path(path).read_text())
    policy = from_sb3(sb3.model, sb3.obs_normalizer, config)
    policy.save(args.out)
    print(f"wrote {args.out}: {load_file(args.out)!r}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
