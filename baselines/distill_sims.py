#!/usr/bin/env python
"""Distil a SIMS skill's interaction clip, played back open-loop through the PD servos, into a SIMS actor
(DAgger), as the start of the skill's imitation-first run.

Played back from a frame of the clip made for the episode's piece (``interaction_start_fraction=1``: each
episode starts in such a frame, ``track_reward``: the env keeps the clip's frames in the world), each step's
PD targets the clip's joint angles one step ahead, the sit clip sits on the seat without a fall in most
starts (``docs/sims_training.md``, 2026-12-08). So the playback is the teacher: every visited state is
labelled with the playback's action for its own clip and time, and the student, an actor of the
``--template`` run's shape and observation normaliser, is fitted to the labels of the states it visits
(Ross et al. 2011; the loop is ``stairenv.training.dagger``'s). A world whose start found no frame that fits
its piece starts standing; its label is the template's own action, so that the student keeps the template's
behaviour where it has no clip. PPO (``train_ppo.py --init-from OUT``) then has to reach the piece
from a standing start and hold the contact goal.

    python baselines/distill_sims.py --template checkpoints/SIMS-Sit-v0/s13_checkpoint_6500352.pt \\
        --skill sit --out runs/sit_distilled.pt
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import torch

from stairenv.training.dagger import Student, add_arguments, distil, read_template
from stairenv.training.ppo import make_env

#: the env of each skill that has interaction clips
SKILL_ENVS = {"sit": "SIMS-Sit-v0", "lie": "SIMS-Lie-v0", "reach": "SIMS-Reach-v0"}
#: every episode starts in a frame of its clip, which the env keeps in the world (the tracking aid)
PLAYBACK_KWARGS = {"interaction_start_fraction": 1.0, "track_reward": 2.0, "max_track_error": 0.5}


def playback_action(env) -> np.ndarray | None:
    """The action whose PD targets are the world's start clip one step ahead (its last frame held once it
    ends; ``_apply_action`` inverted), or None for a world without a clip."""
    clip = env._start_clip
    if clip is None:
        return None
    target = clip[min(env._steps + 1, len(clip) - 1), 7:]
    return np.clip((target - env._ctrl_offset) / env._ctrl_scale, -1.0, 1.0)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--template", type=Path, required=True,
                        help="a lean checkpoint of a SIMS run: the student's shape, normaliser and the rest")
    parser.add_argument("--skill", choices=sorted(SKILL_ENVS), default="sit",
                        help="the skill whose interaction clips are played back (default: %(default)s)")
    add_arguments(parser)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    template, config = read_template(args.template)
    if not config.env_id.startswith("SIMS-"):
        print(f"--template: a SIMS run's checkpoint is needed, this one is {config.env_id}'s", file=sys.stderr)
        return 2
    # the template's aids that belong to its own skill (a walk's near zone and pushes) stay out
    kept = {key: value for key, value in config.env_kwargs.items() if key in ("init", "amp_history")}
    config = config.replace(env_id=SKILL_ENVS[args.skill], env_kwargs={**kept, **PLAYBACK_KWARGS},
                            num_envs=args.n_envs, physics_threads=args.physics_threads, seed=args.seed)
    venv = make_env(config)
    worlds = [env.unwrapped for env in venv.envs]
    torch.manual_seed(args.seed)
    obs_size, action_size = venv.single_observation_space.shape[0], venv.single_action_space.shape[0]
    student = Student(template, config, obs_size, action_size, args.n_envs, args.learning_rate)
    walker = Student(template, config, obs_size, action_size, args.n_envs, args.learning_rate)
    obs, _ = venv.reset(seed=args.seed)
    ended = {"episodes": 0, "fell": 0, "success": 0, "lost": 0, "no clip": 0}
    clipped = []

    def teacher(obs: np.ndarray) -> np.ndarray:
        actions = [playback_action(env) for env in worlds]
        missing = [k for k, a in enumerate(actions) if a is None]
        if missing:
            own = walker(obs[missing])
            for j, k in enumerate(missing):
                actions[k] = own[j]
        clipped.append(np.mean(np.abs(student.observations(obs)) >= student.normalizer.clip_obs))
        return np.stack(actions)

    def after_step(obs: np.ndarray, done: np.ndarray, infos: list) -> None:
        for i in np.flatnonzero(done):
            info = infos[i]
            ended["episodes"] += 1
            ended["fell"] += bool(info.get("fell"))
            ended["success"] += bool(info.get("success"))
            ended["lost"] += bool(info.get("track_lost"))
        ended["no clip"] += sum(env._start_clip is None for env in worlds)

    def after_iteration(iteration: int, beta: float, samples: int, loss: float, seconds: float) -> None:
        print(f"iteration {iteration}: teacher share {beta:.2f}, {samples:,} samples, episodes ended "
              f"{ended['episodes']} (success {ended['success']}, fell {ended['fell']}, clip lost {ended['lost']}), "
              f"world-steps without a clip {ended['no clip']}, observations at the clip bound "
              f"{100 * np.mean(clipped):.2f}%, fit loss {loss:.4f}, {seconds:.0f} s", flush=True)
        ended.update(dict.fromkeys(ended, 0))
        clipped.clear()

    distil(venv, obs, student, teacher, args, after_step, after_iteration)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
