"""Export a trained policy to a numpy ``.npz`` (``stairenv.pretrained``).

The exported file needs neither torch nor Stable-Baselines3 and runs no code when
opened; it holds the actor's layers, the observation statistics and a JSON config (the env
id, the run's settings and, if given, notes on the run and an evaluation file's contents).

The model is either
- a lean trainer's checkpoint ``.pt`` (``train_ppo.py``'s default trainer; read without running
  code from it): its actor, its observation statistics and its run's settings, or
- an SB3 PPO checkpoint ``.zip`` (``train_sb3.py``), with the VecNormalize ``.pkl`` saved beside it.

A lean checkpoint is checked entry by entry before anything is written (``check_checkpoint``); the policy
goes to a temporary file beside ``--out``, renamed only once it reads back: on a failure (a usage error
naming the file and the entry) nothing is written.

    python baselines/export_policy.py checkpoints/PlaMo-v0/p18_checkpoint_16001024.pt --out PlaMo-v0.npz \\
        --config notes.json --evaluation table2.json
    python baselines/export_policy.py runs/InterLevel-v0/seed0/final_model.zip --out InterLevel-v0.npz
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import gymnasium as gym

import stairenv  # noqa: F401  (registers the env ids)
from stairenv.evaluation.policies import load_policy
from stairenv.pretrained import (NumpyPolicy, PolicyFileError, check_sizes, from_sb3, load_file, record_text_encoder,
                                 with_trained_captions)

SB3_DEFAULT_ENV = "InterLevel-v0"


def from_lean_checkpoint(path: str, env_id: str | None) -> NumpyPolicy:
    """The policy of a lean checkpoint; ``ValueError`` if ``env_id`` is given and is not the run's. A
    text-conditioned env's encoder is recorded (``text_encoder_id``, and ``text_embeddings`` of the captions it
    trained on), as the run's keywords make it here."""
    from stairenv.training.ppo import policy_from_checkpoint, read_checkpoint

    policy = policy_from_checkpoint(read_checkpoint(path))
    trained_on = policy.config["env_id"]
    if env_id is not None and env_id != trained_on:
        raise ValueError(f"{path} was trained on {trained_on!r}, not --env {env_id!r}")
    text_encoder = policy.config["training"].get("env_kwargs", {}).get("text_encoder")
    env = gym.make(trained_on, **with_trained_captions({} if text_encoder is None else {"text_encoder": text_encoder},
                                                        policy))
    try:
        check_sizes(policy, env.unwrapped, path)
        if getattr(env.unwrapped, "text_conditioned", False):
            record_text_encoder(policy, env)
    finally:
        env.close()
    return policy


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("model", help="a lean checkpoint .pt, or an SB3 PPO checkpoint .zip (its VecNormalize "
                                      ".pkl beside it is used)")
    parser.add_argument("--env", default=None,
                        help=f"the env id the policy was trained on (default: the checkpoint's; {SB3_DEFAULT_ENV} "
                             "for an SB3 .zip)")
    parser.add_argument("--out", required=True, help="the .npz to write")
    parser.add_argument("--config", help="a JSON object stored with the policy's training settings (its lineage, "
                                          "wall-clock time, recipe)")
    parser.add_argument("--evaluation", help="a JSON evaluation report to store with the policy")
    args = parser.parse_args(argv)
    if not args.out.endswith(".npz"):
        parser.error(f"--out must end in .npz, got {args.out!r}")
    notes = {}
    for key, flag, path in (("training", "--config", args.config), ("evaluation", "--evaluation", args.evaluation)):
        if path:
            try:
                notes[key] = json.loads(Path(path).read_text())
            except (OSError, ValueError) as err:  # missing, not text, not JSON
                parser.error(f"{flag} {path}: not a readable JSON file ({err})")
    if args.model.endswith(".pt"):
        try:    # read_checkpoint checks every entry first (check_checkpoint): nothing is written from a bad file
            policy = from_lean_checkpoint(args.model, args.env)
        except ValueError as err:  # CheckpointError included: the file and the fault named
            parser.error(str(err))
        except (TypeError, gym.error.Error) as err:  # the run's env keywords no longer build its env
            parser.error(f"{args.model}: its run's env cannot be built here (config['env_kwargs']): {err}")
        config = dict(policy.config, source=Path(args.model).name)
        if "training" in notes:
            if not isinstance(notes["training"], dict):
                parser.error(f"--config {args.config}: a JSON object is needed, got {type(notes['training']).__name__}")
            config["training"] = dict(config["training"], **notes.pop("training"))
        policy.config = dict(config, **notes)
    else:
        env_id = args.env or SB3_DEFAULT_ENV
        sb3 = load_policy(args.model, gym.make(env_id))  # checks the spaces; the normaliser beside the model
        policy = from_sb3(sb3.model, sb3.obs_normalizer, dict({"env_id": env_id, "source": Path(args.model).name},
                                                              **notes))
    try:
        written = save_checked(policy, Path(args.out))
    except (PolicyFileError, OSError) as err:
        parser.error(f"{err}; nothing was written")
    print(f"wrote {args.out}: {written!r}")
    return 0


def save_checked(policy: NumpyPolicy, out: Path) -> NumpyPolicy:
    """``policy`` written to ``out`` and read back (``load_file``'s checks: finite weights, sound statistics)
    through a temporary file beside it, renamed to ``out`` only once it reads back: a policy that does not
    leaves no file (and an older ``out`` as it was). Returns the policy read back."""
    tmp = out.with_name(f".{out.stem}.{os.getpid()}.tmp.npz")
    try:
        policy.save(tmp)
        written = load_file(tmp)
    except BaseException as err:
        tmp.unlink(missing_ok=True)
        if isinstance(err, PolicyFileError):    # named as the file it was to be
            raise PolicyFileError(str(err).replace(str(tmp), str(out))) from None
        raise
    os.replace(tmp, out)
    return written


if __name__ == "__main__":
    sys.exit(main())
