#!/usr/bin/env python
"""Distil the crawl clips, played back open-loop through the PD servos, into a PlaMo-v0 actor (DAgger).

Session 23 of ``docs/plamo_training.md``: played back (each step's PD targets = the clip's joint angles
one step ahead), the DeepMimic crawl crawls on flat ground for 10 s in most starts, yet the PlaMo
policies started in a crawl frame leave that pose within 0.15 s and never find it again under PPO's
noise. So the playback is the teacher: each world starts in a crawl frame (``init="reference"``,
``locomotion="crawl"``), its label is the playback's action for its own clip and time (``_reference_clip``
and the episode's time), and the student, an actor of the ``--template`` run's shape and observation
normaliser, is fitted to the labels of the states it visits (Ross et al. 2011). The teacher ignores the
path; PPO (``train_ppo.py --init-from OUT``) then has to steer the crawl along it.

    python baselines/distill_crawl.py --template /work/runs/p18_16m_std2.pt --out runs/crawl_distilled.pt

Iteration i executes the teacher's action with probability ``0.5 ** i`` (else the student's), plus
Gaussian noise (``--action-noise``); the student is fitted on all the data so far (mean squared error).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import torch

from stairenv.training.config import TrainConfig
from stairenv.training.ppo import ActorCritic, Normalizer, make_env, read_checkpoint

#: the crawl-only env: every path a crawl, every start a crawl frame, the paths at the paper's speeds
CRAWL_KWARGS = {"locomotion": "crawl", "init": "reference", "matched_starts": True, "speed_levels": 0}


def playback_action(env) -> np.ndarray:
    """The action whose PD targets are the world's start clip one step ahead (``_apply_action`` inverted)."""
    clip, start_time = env._reference_clip
    target = clip.sample(start_time + (env._steps + 1) * env.dt)[0, 7:]
    return np.clip((target - env._ctrl_offset) / env._ctrl_scale, -1.0, 1.0)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--template", type=Path, required=True,
                        help="a lean checkpoint of a PlaMo-v0 run: the student's shape, normaliser and the rest")
    parser.add_argument("--out", type=Path, required=True, help="the checkpoint to write (for --init-from)")
    parser.add_argument("--iterations", type=int, default=6)
    parser.add_argument("--steps", type=int, default=150, help="env steps per iteration (default: 150 = 5 s)")
    parser.add_argument("--n-envs", type=int, default=64)
    parser.add_argument("--epochs", type=int, default=6, help="passes over all the data per iteration")
    parser.add_argument("--action-noise", type=float, default=0.05)
    parser.add_argument("--learning-rate", type=float, default=3e-4)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--physics-threads", type=int, default=2)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    template = read_checkpoint(args.template)
    config = TrainConfig.from_dict(template["config"])
    if config.env_id != "PlaMo-v0":
        print(f"--template: a PlaMo-v0 run's checkpoint is needed, this one is {config.env_id}'s", file=sys.stderr)
        return 2
    config = config.replace(env_kwargs={**config.env_kwargs, **CRAWL_KWARGS}, num_envs=args.n_envs,
                            physics_threads=args.physics_threads, seed=args.seed)
    venv = make_env(config)
    worlds = [env.unwrapped for env in venv.envs]
    torch.manual_seed(args.seed)
    rng = np.random.default_rng(args.seed)
    model = ActorCritic(venv.single_observation_space.shape[0], venv.single_action_space.shape[0],
                        tuple(config.hidden), config.log_std_init)
    model.load_state_dict(template["model"])
    normalizer = Normalizer(model.policy_net[0].in_features, args.n_envs, config.gamma, config.clip_obs,
                            config.clip_reward)
    normalizer.obs_rms.load(template["obs_rms"])       # fixed: the run goes on with the template's statistics
    optimizer = torch.optim.Adam(list(model.policy_net.parameters()) + list(model.action_mean.parameters()),
                                 lr=args.learning_rate)

    def student(obs: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            x = torch.as_tensor(normalizer.observations(obs, update=False))
            return model.action_mean(model.policy_net(x)).numpy().astype(np.float64)

    inputs, labels = [], []
    obs, _ = venv.reset(seed=args.seed)
    for iteration in range(args.iterations):
        begun = time.perf_counter()
        beta = 0.5 ** iteration
        episodes = falls = 0
        pelvis = []
        for _ in range(args.steps):
            label = np.stack([playback_action(env) for env in worlds])
            inputs.append(normalizer.observations(obs, update=False))
            labels.append(label.astype(np.float32))
            act = label if beta == 1.0 else np.where(rng.uniform(size=(len(obs), 1)) < beta, label, student(obs))
            act = np.clip(act + args.action_noise * rng.standard_normal(act.shape), -1.0, 1.0)
            obs, _, terminated, truncated, infos, _ = venv.step_worlds(act, reset_ended=True)
            pelvis.append(np.mean(obs[:, 0]))
            done = terminated | truncated
            episodes += int(done.sum())
            falls += sum(bool(infos[i].get("fell")) for i in np.flatnonzero(done))
        x, y = torch.as_tensor(np.concatenate(inputs)), torch.as_tensor(np.concatenate(labels))
        losses = []
        for _ in range(args.epochs):
            for batch in torch.randperm(len(x)).split(1024):
                loss = torch.mean((model.action_mean(model.policy_net(x[batch])) - y[batch]) ** 2)
                optimizer.zero_grad()
                loss.backward()
                optimizer.step()
                losses.append(loss.item())
        print(f"iteration {iteration}: teacher share {beta:.2f}, {len(x):,} samples, episodes ended {episodes} "
              f"(fell {falls}), mean root height {np.mean(pelvis):.2f} m, fit loss {np.mean(losses[-20:]):.4f}, "
              f"{time.perf_counter() - begun:.0f} s", flush=True)
    venv.close()
    state = dict(template)
    state["model"] = {k: v.detach().clone() for k, v in model.state_dict().items()}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    torch.save(state, args.out)
    print(f"wrote {args.out}: the template's checkpoint with the distilled actor")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
