"""DAgger (Ross et al. 2011) into a lean run's actor: what ``baselines/distill_walk.py`` (the climber teaching
the SIMS walk) and ``baselines/distill_crawl.py`` (the crawl playback teaching PlaMo's actor) share.

The student is the ``template`` checkpoint's actor, read through its fixed observation normaliser. Iteration
i executes the teacher's action with probability ``0.5 ** i`` (else the student's), plus Gaussian noise so
that the data covers small recoveries; every visited state is labelled with the teacher's action and the
student is fitted on all the data so far (mean squared error of its mean action). The output is the template
with the student's actor in place of its own, for ``train_ppo.py --init-from``.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch

from stairenv.training.config import TrainConfig
from stairenv.training.ppo import ActorCritic, Normalizer, read_checkpoint


def read_template(path: Path) -> tuple[dict, TrainConfig]:
    """The ``--template`` lean checkpoint (read without running code) and its run's ``TrainConfig``."""
    template = read_checkpoint(path)
    return template, TrainConfig.from_dict(template["config"])


class Student:
    """The template's actor (its weights, ``config``'s shape) behind the template's fixed normaliser."""

    def __init__(self, template: dict, config: TrainConfig, obs_size: int, action_size: int, num_envs: int,
                 learning_rate: float) -> None:
        self.template = template
        self.model = ActorCritic(obs_size, action_size, tuple(config.hidden), config.log_std_init)
        self.model.load_state_dict(template["model"])
        self.normalizer = Normalizer(self.model.policy_net[0].in_features, num_envs, config.gamma, config.clip_obs,
                                     config.clip_reward)
        self.normalizer.obs_rms.load(template["obs_rms"])   # fixed: the run goes on with the template's statistics
        self.optimizer = torch.optim.Adam(
            list(self.model.policy_net.parameters()) + list(self.model.action_mean.parameters()), lr=learning_rate)

    def observations(self, obs: np.ndarray) -> np.ndarray:
        return self.normalizer.observations(obs, update=False)

    def mean_action(self, x: torch.Tensor) -> torch.Tensor:
        return self.model.action_mean(self.model.policy_net(x))

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            return self.mean_action(torch.as_tensor(self.observations(obs))).numpy().astype(np.float64)

    def fit(self, inputs: list[np.ndarray], labels: list[np.ndarray], epochs: int) -> float:
        """``epochs`` passes over all the data in minibatches of 1024; the mean of the last 20 losses."""
        x, y = torch.as_tensor(np.concatenate(inputs)), torch.as_tensor(np.concatenate(labels))
        losses = []
        for _ in range(epochs):
            for batch in torch.randperm(len(x)).split(1024):
                loss = torch.mean((self.mean_action(x[batch]) - y[batch]) ** 2)
                self.optimizer.zero_grad()
                loss.backward()
                self.optimizer.step()
                losses.append(loss.item())
        return float(np.mean(losses[-20:]))

    def save(self, out: Path) -> None:
        """The template's checkpoint with this actor (and the rest of the template's model) to ``out``."""
        state = dict(self.template)
        state["model"] = {k: v.detach().clone() for k, v in self.model.state_dict().items()}
        out.parent.mkdir(parents=True, exist_ok=True)
        torch.save(state, out)


def dagger(venv, obs: np.ndarray, student: Student, teacher: Callable[[np.ndarray], np.ndarray], *,
           iterations: int, steps: int, epochs: int, action_noise: float, rng: np.random.Generator,
           after_step: Callable[[np.ndarray, np.ndarray, list], None],
           after_iteration: Callable[[int, float, int, float, float], None]) -> None:
    """DAgger on the batched env ``venv`` (SAME_STEP autoreset) from its observations ``obs``. ``teacher(obs)``
    labels a batch; ``after_step(obs, done, infos)`` sees each step's outcome (the next observations, which
    worlds' episodes ended, their ``info``); ``after_iteration(i, teacher share, samples, fit loss, seconds)``."""
    inputs, labels = [], []
    for iteration in range(iterations):
        begun = time.perf_counter()
        beta = 0.5 ** iteration
        for _ in range(steps):
            label = teacher(obs)
            inputs.append(student.observations(obs))
            labels.append(label.astype(np.float32))
            act = label if beta == 1.0 else np.where(rng.uniform(size=(len(obs), 1)) < beta, label, student(obs))
            act = np.clip(act + action_noise * rng.standard_normal(act.shape), -1.0, 1.0)
            # SAME_STEP autoreset: an ended world's row is already its next episode's first observation
            obs, _, terminated, truncated, infos, _ = venv.step_worlds(act, reset_ended=True)
            after_step(obs, terminated | truncated, infos)
        loss = student.fit(inputs, labels, epochs)
        after_iteration(iteration, beta, sum(len(x) for x in inputs), loss, time.perf_counter() - begun)


def add_arguments(parser: argparse.ArgumentParser, *, steps: int = 150, epochs: int = 6,
                  physics_threads: int = 2) -> None:
    """The flags every distillation script takes (``--out`` and the DAgger loop's), its defaults where given."""
    parser.add_argument("--out", type=Path, required=True, help="the checkpoint to write (for --init-from)")
    parser.add_argument("--iterations", type=int, default=6, help="DAgger iterations (default: %(default)s)")
    parser.add_argument("--steps", type=int, default=steps,
                        help="env steps per iteration (default: %(default)s; 30 a second)")
    parser.add_argument("--n-envs", type=int, default=64)
    parser.add_argument("--epochs", type=int, default=epochs, help="passes over all the data per iteration")
    parser.add_argument("--action-noise", type=float, default=0.05, help="std of the executed actions' noise")
    parser.add_argument("--learning-rate", type=float, default=3e-4)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--physics-threads", type=int, default=physics_threads)


def distil(venv, obs: np.ndarray, student: Student, teacher: Callable[[np.ndarray], np.ndarray],
           args: argparse.Namespace, after_step: Callable[[np.ndarray, np.ndarray, list], None],
           after_iteration: Callable[[int, float, int, float, float], None]) -> None:
    """``dagger`` with ``add_arguments``' settings (its rng seeded by ``--seed``), then the env closed and the
    template with the student's actor written to ``--out``."""
    dagger(venv, obs, student, teacher, iterations=args.iterations, steps=args.steps, epochs=args.epochs,
           action_noise=args.action_noise, rng=np.random.default_rng(args.seed), after_step=after_step,
           after_iteration=after_iteration)
    venv.close()
    student.save(args.out)
    print(f"wrote {args.out}: the template's checkpoint with the distilled actor")
