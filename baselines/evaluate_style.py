#!/usr/bin/env python
"""Rank the checkpoints of a PPO + AMP run by how their motion compares with the reference.

Examples::

    python baselines/evaluate_style.py runs/InterLevel-v0/seed0
    python baselines/evaluate_style.py runs/InterLevel-v0/seed0 --episodes 16 --discriminator runs/other/amp.pt \\
        --csv style.csv

The style reward logged during training comes from a discriminator that keeps
training against the policy, so it is a moving yardstick. This script holds the
yardstick still: every checkpoint (``checkpoints/ppo_<n>_steps.zip`` and
``final_model.zip``, each with its own VecNormalize statistics; or a lean run's
``checkpoints/checkpoint_<n>.pt`` and ``final_policy.npz``) runs the same
seeded episodes (deterministic actions), and every step's ``info["amp_obs"]`` is
measured by

- ``style``: the mean style reward of ONE discriminator (``--discriminator``;
  default: the run's ``amp.pt``, else its newest checkpoint's ``amp_<n>_steps.pt``; for a
  lean run the discriminator in ``final_checkpoint.pt``, else in its newest checkpoint);
- ``ref_dist``: the mean distance to the nearest reference window, in reference
  standard deviations per number (``stairenv.style.metrics``; no discriminator);

with the mean episode length. The "zero" and "random" policies are measured first
for scale (``--baselines``). The env is the run folder's parent name (train_ppo.py's
layout ``<logdir>/<env>/seed<k>``) unless ``--env`` is given; episodes start from
the default pose (``init="default"``) unless ``--env-kwarg init=...`` says otherwise.
"""

from __future__ import annotations

import argparse
import csv
import json
import re
from pathlib import Path


def build_parser() -> argparse.ArgumentParser:
    from stairenv.evaluation.cli import env_kwarg_argument

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run", type=Path, help="a train_ppo.py run folder (<logdir>/<env>/seed<k>)")
    parser.add_argument("--env", help="env id (default: the run folder's parent name)")
    parser.add_argument("--discriminator", type=Path, help="AMP state to score with (default: the run's newest)")
    parser.add_argument("--reference", help="reference motion (default: the env's built-in set)")
    parser.add_argument("--episodes", type=int, default=8, help="episodes per checkpoint (default: %(default)s)")
    parser.add_argument("--max-episode-steps", type=int, default=None, help="cut episodes here (default: the env's)")
    parser.add_argument("--seed", type=int, default=0, help="episode k uses seed + k (default: %(default)s)")
    parser.add_argument("--baselines", nargs="*", default=["zero", "random"], metavar="SPEC",
                        help="policies measured first for scale (default: zero random; none: give no value)")
    parser.add_argument("--every", type=int, default=1, help="use every k-th checkpoint (default: all)")
    parser.add_argument("--env-kwarg", action="append", default=[], type=env_kwarg_argument, metavar="KEY=VALUE",
                        help="extra env keyword, repeatable")
    parser.add_argument("--csv", type=Path, help="write the table as CSV")
    parser.add_argument("--json", type=Path, help="write the table and settings as JSON")
    return parser


def checkpoints(run: Path) -> list[tuple[int | None, Path]]:
    """(steps, model) of every checkpoint by steps, then the final policy (steps None): an SB3 run's
    ``ppo_<n>_steps.zip`` and ``final_model.zip``, a lean run's ``checkpoint_<n>.pt`` and ``final_policy.npz``."""
    from stairenv.training import checkpoints_in
    found = []
    for path in (run / "checkpoints").glob("*_steps.zip"):
        match = re.fullmatch(r".*_(\d+)_steps", path.stem)
        if match and "vecnormalize" not in path.stem:
            found.append((int(match[1]), path))
    found += checkpoints_in(run / "checkpoints")
    found.sort()
    for final in ("final_model.zip", "final_policy.npz"):
        if (run / final).is_file():
            found.append((None, run / final))
    return found


def newest_discriminator(run: Path) -> Path | None:
    """An SB3 run's ``amp.pt`` or newest ``amp_<n>_steps.pt``; a lean run's ``final_checkpoint.pt`` or
    newest ``checkpoint_<n>.pt`` (the discriminator is inside)."""
    from stairenv.training import checkpoints_in
    for final in ("amp.pt", "final_checkpoint.pt"):
        if (run / final).is_file():
            return run / final
    states = [(int(m[1]), p) for p in (run / "checkpoints").glob("amp_*_steps.pt")
              if (m := re.fullmatch(r"amp_(\d+)_steps", p.stem))] + checkpoints_in(run / "checkpoints")
    return max(states)[1] if states else None


def read_discriminator(path: Path) -> dict:
    """The discriminator's saved state as ``AMPStyleReward.save`` writes it, from an AMP state file or a
    lean checkpoint (both read without running code from them); ``ValueError`` naming the file."""
    from stairenv.style.features import AMP_FEATURE_SIZE
    from stairenv.style.wrappers import read_amp_state
    from stairenv.training import read_checkpoint

    if re.fullmatch(r"checkpoint_\d+|final_checkpoint", path.stem):
        state = read_checkpoint(path)
        if state.get("style") is None:
            raise ValueError(f"{path}: a run without AMP holds no discriminator")
        frames = int(state["config"]["amp_history"])
        disc = state["style"]["discriminator"]
        return {"discriminator": disc, "reference_num_frames": frames, "reference_condition_dim":
                int(disc["input_dim"]) - frames * AMP_FEATURE_SIZE}
    return read_amp_state(path)


def main(argv: list[str] | None = None) -> list[dict]:
    parser = build_parser()
    args = parser.parse_args(argv)
    import gymnasium as gym
    import numpy as np

    import stairenv  # noqa: F401  (registers the envs)
    from stairenv.environments.sims import SIMSEnv, reference_captions
    from stairenv.evaluation.policies import load_policy
    from stairenv.motion.rsi import load_reference_library
    from stairenv.style.metrics import nearest_reference_distance, rollout_windows
    from stairenv.style.reference import ReferenceWindows, text_conditions
    from stairenv.pretrained import check_sizes
    from stairenv.style.discriminator import AMPDiscriminator
    from stairenv.style.wrappers import AMPStyleReward
    from stairenv.training import read_checkpoint
    from stairenv.training.ppo import policy_from_checkpoint

    if args.episodes < 1 or args.every < 1:
        parser.error("--episodes and --every must be >= 1")
    if not args.run.is_dir():
        parser.error(f"no run folder {str(args.run)!r}")
    models = checkpoints(args.run)[::-1][::args.every][::-1]  # keep the newest, thin out older ones
    if not models:
        parser.error(f"no checkpoints/ppo_<n>_steps.zip, checkpoints/checkpoint_<n>.pt, final_model.zip or "
                     f"final_policy.npz in {str(args.run)!r}")
    env_id = args.env or args.run.parent.name
    if env_id not in gym.registry:
        parser.error(f"env {env_id!r} (from the run folder) is not registered: give --env")
    if args.discriminator is not None and not args.discriminator.is_file():
        parser.error(f"--discriminator: no such file {str(args.discriminator)!r}")
    disc_path = args.discriminator or newest_discriminator(args.run)
    if disc_path is None:
        parser.error(f"no discriminator state in {str(args.run)!r} (amp.pt, checkpoints/amp_<n>_steps.pt or a "
                     "lean run's checkpoint): give --discriminator")
    try:
        saved = read_discriminator(disc_path)  # tensors and plain values only: opening it runs nothing
    except ValueError as err:  # AMPStateError and CheckpointError among them
        parser.error(str(err))

    env_kwargs = {"init": "default", "amp_history": int(saved["reference_num_frames"]), **dict(args.env_kwarg)}
    probe = gym.make(env_id, **env_kwargs).unwrapped
    library = load_reference_library(args.reference or probe.DEFAULT_REFERENCE_MOTION)
    conditions = None
    if int(saved.get("reference_condition_dim", 0)):
        if not isinstance(probe, SIMSEnv):
            parser.error(f"{disc_path} is text-conditioned but {env_id} is not a SIMS env")
        conditions = text_conditions(library, probe.embed_text)
        env_kwargs.setdefault("captions", reference_captions(library, probe.skill))
    reference = ReferenceWindows(library, num_frames=env_kwargs["amp_history"], fps=1.0 / probe.dt,
                                 conditions=conditions)
    probe.close()
    style = AMPStyleReward(reference, discriminator=AMPDiscriminator.from_state(saved["discriminator"]), train=False)

    env = gym.make(env_id, **env_kwargs)
    rows = []
    for steps, model in [(None, spec) for spec in args.baselines] + models:
        if isinstance(model, Path) and model.suffix == ".pt":    # a lean run's checkpoint
            policy = policy_from_checkpoint(read_checkpoint(model))
            check_sizes(policy, env, model)
        else:
            policy = load_policy(str(model), env, seed=args.seed)
        windows, conds, lengths = rollout_windows(policy, env, args.episodes, seed=args.seed,
                                                  max_steps=args.max_episode_steps)
        rewards = style.disc.reward(style.agent_inputs(list(windows), conds))
        distance = nearest_reference_distance(windows, reference)
        name = model.name if isinstance(model, Path) else model
        rows.append({"checkpoint": name, "steps": steps, "episodes": args.episodes,
                     "episode_length": float(lengths.mean()), "style": float(rewards.mean()),
                     "ref_dist": float(distance.mean()), "ref_dist_median": float(np.median(distance))})
        print(f"{name:>28}  length {rows[-1]['episode_length']:7.1f}  style {rows[-1]['style']:.3f}  "
              f"ref_dist {rows[-1]['ref_dist']:.3f} (median {rows[-1]['ref_dist_median']:.3f})", flush=True)
    env.close()
    style.close()

    if args.csv:
        args.csv.parent.mkdir(parents=True, exist_ok=True)
        with args.csv.open("w", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        settings = {"run": str(args.run), "env": env_id, "env_kwargs": {k: repr(v) for k, v in env_kwargs.items()},
                    "discriminator": str(disc_path), "episodes": args.episodes, "seed": args.seed,
                    "max_episode_steps": args.max_episode_steps}
        args.json.write_text(json.dumps({"settings": settings, "rows": rows}, indent=2))
    return rows


if __name__ == "__main__":
    main()
