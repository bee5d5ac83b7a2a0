"""PPO + AMP on the batched env's arrays: the lean trainer, readable in one sitting.

One loop (``Trainer.learn``), in the shape of CleanRL's and rsl_rl's PPO::

    for each iteration:
        rollout:  rollout_steps x num_envs transitions, the policy called on the whole batch,
                  the batched env stepping every world (``HumanoidVectorEnv.step_worlds``, ended worlds
                  reset inside the step), AMP scoring the step's style windows in one call
        returns:  GAE over the rollout (truncations bootstrapped with the value of the final observation)
        update:   epochs x minibatches of the clipped PPO loss (policy, value, entropy), one optimiser

Everything is an array: observations, rewards, flags, style windows and the episode statistics the
log shows; the per-world ``info`` dicts are read only for the worlds whose episode ended. The
algorithm is Stable-Baselines3's PPO with VecNormalize as ``baselines/train_sb3.py`` runs it
(same initialisation, normalisers, bootstrapping, losses and defaults), so recipes carry over;
``docs/training.md`` gives the measurements against it and against skrl and rsl-rl-lib.

``TrainConfig.device`` (``train_ppo.py --device``) places the policy, value, their optimiser, the
rollout, GAE, the PPO update and the AMP discriminator (its scoring, training and optimiser) on a torch
device; the envs, the normalisers (numpy, float64), the discriminator's replay buffer and the torch
generators stay on the host. Per step the normalised observations, the action noise (drawn on the CPU,
so every device draws the same), the rewards and episode starts go to the device, the actions come back.

A checkpoint (``checkpoint_<steps>.pt``) is one file of tensors and plain values: the whole resolved
``TrainConfig``, policy, optimiser, observation and return normalisers, the AMP discriminator with its
optimiser and schedule, the curriculum levels, the step counter and the trainer's generators. It is
read with ``torch.load(weights_only=True)``: opening one runs no code from it. Its tensors are saved
on the CPU and loaded onto the run's device, so a checkpoint goes on on any device.
"""

from __future__ import annotations

import json
import math
import os
import re
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from torch import nn

from stairenv.environments.infos import column, floats_of
from stairenv.environments.vector import HumanoidVectorEnv
from stairenv.pretrained import NumpyPolicy
from stairenv.style.discriminator import AMPDiscriminator, DiscriminatorConfig, cpu_tensors, plain_config
from stairenv.style.wrappers import AMPStyleReward, load_weights_only, refused_object
from stairenv.tasks import curriculum
from stairenv.training.config import LOG_STD_RANGE, TrainConfig
from stairenv.training.distributed import LOCAL, RANK_DRIFT_TOLERANCE, Local

#: the task's results logged at each episode's end (InterLevel's; other families log what they report)
EPISODE_KEYS = ("progress", "success", "fell", "stalled", "off_path", "grounded", "z_off_path", "z_above_path",
                "contact_error", "xy_error", "z_error")
CHECKPOINT_FORMAT = "stairenv-ppo-amp/1"


class CheckpointError(ValueError):
    """A checkpoint that cannot be read as the lean trainer's (names the file and the fault)."""


class RunMismatch(ValueError):
    """A sound checkpoint whose networks (``part`` "networks") or discriminator ("discriminator") have other
    sizes than the run taking it: ``saved`` and ``run`` are the two."""

    def __init__(self, part: str, message: str, saved: Any, run: Any) -> None:
        super().__init__(message)
        self.part, self.saved, self.run = part, saved, run


def network_sizes(weights: dict[str, Any]) -> tuple[int, tuple[int, ...], int]:
    """``(observations, hidden layers, actions)`` of an ``ActorCritic``'s state dict."""
    hidden = [int(weights[f"policy_net.{i}.weight"].shape[0]) for i in range(0, 2 * len(weights), 2)
              if f"policy_net.{i}.weight" in weights]
    return (int(weights["policy_net.0.weight"].shape[1]), tuple(hidden), int(weights["action_mean.weight"].shape[0]))


# --- normalisers (VecNormalize's statistics, on arrays) ------------------------------------------------
class RunningMeanStd:
    """Running mean and variance over batches (Chan et al.'s parallel update; count starts at 1e-4).
    In a data-parallel run (``parallel``) a batch is every rank's batch together."""

    def __init__(self, shape: tuple[int, ...] = (), parallel: Local = LOCAL) -> None:
        self.mean = np.zeros(shape, dtype=np.float64)
        self.var = np.ones(shape, dtype=np.float64)
        self.count = 1e-4
        self.parallel = parallel

    def update(self, batch: np.ndarray) -> None:
        batch_mean, batch_var, n = self.parallel.moments(batch.mean(axis=0), batch.var(axis=0), batch.shape[0])
        delta = batch_mean - self.mean
        total = self.count + n
        self.mean = self.mean + delta * n / total
        self.var = (self.var * self.count + batch_var * n + delta**2 * self.count * n / total) / total
        self.count = total

    def state(self) -> dict[str, Any]:
        return {"mean": torch.from_numpy(np.array(self.mean, dtype=np.float64)),
                "var": torch.from_numpy(np.array(self.var, dtype=np.float64)), "count": float(self.count)}

    def load(self, state: dict[str, Any]) -> None:
        mean, var = state["mean"].numpy().astype(np.float64), state["var"].numpy().astype(np.float64)
        if mean.shape != np.shape(self.mean) or var.shape != np.shape(self.var):
            raise ValueError(f"statistics of shape {tuple(mean.shape)}, this run needs {np.shape(self.mean)}")
        self.mean, self.var, self.count = mean, var, float(state["count"])


class Normalizer:
    """Observation and reward normalisation as SB3's ``VecNormalize`` (epsilon 1e-8): observations
    standardised by their running statistics and clipped; rewards divided by the running std of the
    discounted return (reset where an episode ends) and clipped."""

    EPSILON = 1e-8

    def __init__(self, obs_size: int, num_envs: int, gamma: float, clip_obs: float, clip_reward: float,
                 parallel: Local = LOCAL) -> None:
        self.obs_rms = RunningMeanStd((obs_size,), parallel)
        self.ret_rms = RunningMeanStd((), parallel)
        self.returns = np.zeros(num_envs, dtype=np.float64)
        self.gamma, self.clip_obs, self.clip_reward = gamma, clip_obs, clip_reward

    def observations(self, obs: np.ndarray, update: bool = True) -> np.ndarray:
        if update:
            self.obs_rms.update(obs)
        scaled = (obs - self.obs_rms.mean) / np.sqrt(self.obs_rms.var + self.EPSILON)
        return np.clip(scaled, -self.clip_obs, self.clip_obs).astype(np.float32)

    def rewards(self, reward: np.ndarray, dones: np.ndarray) -> np.ndarray:
        self.returns = self.returns * self.gamma + reward
        self.ret_rms.update(self.returns)
        scaled = np.clip(reward / np.sqrt(self.ret_rms.var + self.EPSILON), -self.clip_reward, self.clip_reward)
        self.returns[dones] = 0.0
        return scaled.astype(np.float32)


# --- the networks ------------------------------------------------------------------------------------
def _mlp(sizes: list[int]) -> nn.Sequential:
    layers: list[nn.Module] = []
    for a, b in zip(sizes[:-1], sizes[1:]):
        layers += [nn.Linear(a, b), nn.ReLU()]
    return nn.Sequential(*layers)


class ActorCritic(nn.Module):
    """Separate ReLU MLPs for the Gaussian policy's mean and the value; a state-independent log std.
    Orthogonal initialisation (hidden gain sqrt 2, mean 0.01, value 1), as SB3's ``MlpPolicy``."""

    def __init__(self, obs_size: int, action_size: int, hidden: tuple[int, ...], log_std_init: float) -> None:
        super().__init__()
        self.policy_net = _mlp([obs_size, *hidden])
        self.value_net = _mlp([obs_size, *hidden])
        self.action_mean = nn.Linear(hidden[-1], action_size)
        self.value = nn.Linear(hidden[-1], 1)
        self.log_std = nn.Parameter(torch.full((action_size,), float(log_std_init)))
        for layer in (*self.policy_net, *self.value_net):
            if isinstance(layer, nn.Linear):
                nn.init.orthogonal_(layer.weight, math.sqrt(2))
                nn.init.zeros_(layer.bias)
        nn.init.orthogonal_(self.action_mean.weight, 0.01)
        nn.init.zeros_(self.action_mean.bias)
        nn.init.orthogonal_(self.value.weight, 1.0)
        nn.init.zeros_(self.value.bias)

    def values(self, obs: torch.Tensor) -> torch.Tensor:
        return self.value(self.value_net(obs)).squeeze(-1)

    def distribution(self, obs: torch.Tensor) -> torch.distributions.Normal:
        return torch.distributions.Normal(self.action_mean(self.policy_net(obs)), self.log_std.exp())

    def act(self, obs: torch.Tensor, noise: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """The action ``mean + std * noise`` (unclipped; ``noise`` standard normal, as ``sample()``
        draws it), its log-probability and the value."""
        dist = self.distribution(obs)
        action = dist.loc + dist.scale * noise
        return action, dist.log_prob(action).sum(-1), self.values(obs)

    def as_numpy(self, normalizer: Normalizer, clip_obs: float, config: dict[str, Any]) -> NumpyPolicy:
        """The deterministic actor with its observation statistics (``stairenv.pretrained``'s format)."""
        linear = [m for m in self.policy_net if isinstance(m, nn.Linear)] + [self.action_mean]
        return NumpyPolicy([m.weight.detach().cpu().numpy().copy() for m in linear],
                           [m.bias.detach().cpu().numpy().copy() for m in linear],
                           normalizer.obs_rms.mean.copy(), normalizer.obs_rms.var.copy(), clip_obs,
                           Normalizer.EPSILON, config)


# --- the rollout --------------------------------------------------------------------------------------
@dataclass
class Rollout:
    """``rollout_steps x num_envs`` transitions (float32 tensors), then their advantages and returns."""

    obs: torch.Tensor
    actions: torch.Tensor
    log_probs: torch.Tensor
    values: torch.Tensor
    rewards: torch.Tensor
    starts: torch.Tensor          # 1 where the observation is an episode's first
    advantages: torch.Tensor
    returns: torch.Tensor

    @classmethod
    def empty(cls, steps: int, n: int, obs_size: int, action_size: int,
              device: torch.device | str = "cpu") -> "Rollout":
        def z(*shape: int) -> torch.Tensor:
            return torch.zeros(*shape, device=device)

        return cls(z(steps, n, obs_size), z(steps, n, action_size), z(steps, n), z(steps, n), z(steps, n),
                   z(steps, n), z(steps, n), z(steps, n))

    def compute_returns(self, last_values: torch.Tensor, last_starts: torch.Tensor, gamma: float,
                        lam: float) -> None:
        """GAE(gamma, lambda); ``starts[t + 1]`` cuts the sum where an episode ended after step t."""
        steps = self.rewards.shape[0]
        advantage = torch.zeros_like(last_values)
        for t in reversed(range(steps)):
            next_values = last_values if t == steps - 1 else self.values[t + 1]
            next_live = 1.0 - (last_starts if t == steps - 1 else self.starts[t + 1])
            delta = self.rewards[t] + gamma * next_values * next_live - self.values[t]
            advantage = delta + gamma * lam * next_live * advantage
            self.advantages[t] = advantage
        self.returns = self.advantages + self.values


class EpisodeLog:
    """Per-world episode returns and lengths, and the task's results of ended episodes, as arrays."""

    def __init__(self, n: int) -> None:
        self.task_return = np.zeros(n)
        self.length = np.zeros(n, dtype=np.int64)
        self.sums: dict[str, list[float]] = {}

    def step(self, task_reward: np.ndarray, dones: np.ndarray, infos: list[dict[str, Any]]) -> None:
        self.task_return += task_reward
        self.length += 1
        ended = np.flatnonzero(dones)
        if ended.size:    # the ended worlds' values read key by key, without making their dicts
            self._add("episode/task_return", self.task_return[ended])
            self._add("episode/length", self.length[ended])
            # starts on the stairs or at the furniture (training aids) are not the evaluation's
            aided = np.zeros(len(ended), dtype=bool)
            for key in ("stairs_start", "interaction_start"):
                values, present = floats_of(infos, ended, key)
                aided |= present & (values != 0.0)
            for key in EPISODE_KEYS:
                values, present = floats_of(infos, ended, key)
                self._add(f"episode/{key}", values[present])
                self._add(f"episode_floor_start/{key}", values[present & ~aided])
        self.task_return[dones] = 0.0
        self.length[dones] = 0

    def _add(self, key: str, values: np.ndarray) -> None:
        if len(values):
            self.sums.setdefault(key, []).extend(values.astype(np.float64).tolist())

    def means(self, parallel: Local = LOCAL) -> dict[str, float]:
        """The means since the last call (of every rank's episodes), then forgotten."""
        sums: dict[str, list[float]] = {}
        for part in parallel.gather(self.sums):
            for key, values in part.items():
                sums.setdefault(key, []).extend(values)
        out = {key: float(np.mean(values)) for key, values in sums.items() if values}
        self.sums = {}
        return out


# --- the trainer -------------------------------------------------------------------------------------
class Trainer:
    """PPO + AMP over a ``HumanoidVectorEnv`` (see the module docstring).

    ``Trainer(config, style=None)`` builds the env and networks; ``learn(log)`` trains to
    ``config.total_steps``; ``save(path)`` / ``Trainer.load(path)`` checkpoint and resume.
    ``style``: an ``AMPStyleReward`` (built by the caller from reference windows; None with
    ``config.style == "none"``).

    ``parallel``: this rank of a data-parallel run (``stairenv.training.distributed``; default: one
    process). Every rank steps its own ``config.num_envs`` worlds: world j of rank r is world
    ``r x num_envs + j`` of the run, seeded as that world of one process stepping them all would be,
    and drawing its action noise from the same place of the same stream (every rank draws the run's
    whole noise and keeps its rows, so the torch generator stays the same on every rank). Gradients
    are averaged over the ranks, the normalisers' and advantages' statistics are every rank's batch
    together, so the weights stay equal everywhere; ``steps`` and ``total_steps`` count every rank's
    env steps; rank 0 writes the checkpoints."""

    def __init__(self, config: TrainConfig, style: AMPStyleReward | None = None,
                 venv: HumanoidVectorEnv | None = None, parallel: Local = LOCAL) -> None:
        if config.style == "amp" and style is None:
            raise ValueError("style='amp' needs an AMPStyleReward (see stairenv.training.build_style)")
        self.device = torch.device(config.device)
        if style is not None and style.disc.device.type != self.device.type:
            raise ValueError(f"the discriminator is on {style.disc.device}, the trainer on {self.device}: build the "
                             "style with the config's device (build_style does)")
        self.config = config
        self.parallel = parallel
        if config.torch_threads is not None:
            torch.set_num_threads(config.torch_threads)
        torch.manual_seed(config.seed)
        # built on every rank before the first collective: a rank that cannot (no MuJoCo Warp on its machine,
        # its GPU busy) stops every rank with its reason instead of leaving them waiting
        self.venv = venv if venv is not None else parallel.agree(lambda: make_env(config, parallel),
                                                                 "Building the worlds")
        obs_size = self.venv.single_observation_space.shape[0]
        action_size = self.venv.single_action_space.shape[0]
        self.action_low = self.venv.single_action_space.low.astype(np.float32)
        self.action_high = self.venv.single_action_space.high.astype(np.float32)
        # initialised on the CPU (the same weights on every device), then moved before the optimiser sees them
        self.model = ActorCritic(obs_size, action_size, config.hidden, config.log_std_init).to(self.device)
        self.optimizer = torch.optim.Adam(self.model.parameters(), lr=config.learning_rate, eps=1e-5)
        self.learning_rate = config.learning_rate
        self.normalizer = Normalizer(obs_size, config.num_envs, config.gamma, config.clip_obs, config.clip_reward,
                                     parallel)
        self.style = style
        self._style_parallel = parallel.for_thread() if style is not None else None
        parallel.broadcast(self.model)    # the same start on every rank (the discriminator's differs)
        if style is not None:
            parallel.broadcast(style.disc)
            style.disc.parallel = self._style_parallel
        self.rollout = Rollout.empty(config.rollout_steps, config.num_envs, obs_size, action_size, self.device)
        self.steps = 0
        self.iterations = 0
        self.episodes = EpisodeLog(config.num_envs)
        self._obs: torch.Tensor | None = None
        self._starts = torch.ones(config.num_envs, device=self.device)
        self._resumed = False

    def _to_device(self, array: np.ndarray) -> torch.Tensor:
        return torch.from_numpy(array).to(self.device)

    # --- one iteration --------------------------------------------------------------------------
    def reset(self, update_statistics: bool = True) -> None:
        """Reset every world, world i seeded with ``seed + i + num_envs x iterations done`` (a run's first
        reset and each checkpoint's; ``update_statistics=False``: a resumed run repeating the reset its
        checkpoint already counted)."""
        n, p = self.config.num_envs, self.parallel
        cut = {"episode_cut": True} if self._obs is not None else None    # a checkpoint's: no task judged them
        seed = self.config.seed + n * p.rank + n * p.world_size * self.iterations    # world r x n + j of the run
        obs, _ = self.venv.reset(seed=seed, options=cut)
        self._obs = self._to_device(self.normalizer.observations(obs, update=update_statistics))
        self._starts = torch.ones(n, device=self.device)
        self.normalizer.returns[:] = 0.0
        self.episodes = EpisodeLog(n)

    def collect(self) -> dict[str, float]:
        """Fill the rollout; returns the mean task and style rewards."""
        if self._obs is None:
            self.reset(update_statistics=not self._resumed)
        cfg, r, p = self.config, self.rollout, self.parallel
        task_sum = style_sum = 0.0
        mine = slice(p.rank * cfg.num_envs, (p.rank + 1) * cfg.num_envs)
        for t in range(cfg.rollout_steps):
            noise = torch.randn(p.world_size * cfg.num_envs, len(self.action_low))[mine]    # the run's, my rows
            with torch.no_grad():
                action, log_prob, value = self.model.act(self._obs, noise.to(self.device))
            clipped = np.clip(action.cpu().numpy(), self.action_low, self.action_high)
            obs, task_reward, terminated, truncated, infos, finals = self.venv.step_worlds(clipped, reset_ended=True)
            dones = terminated | truncated
            if self.style is not None:
                amp = column(infos, "amp_obs")
                conditions = None
                if self.style.reference.condition_dim:
                    conditions = column(infos, "amp_condition")
                reward, style = self.style(self.style.agent_inputs(amp, conditions), task_reward)
                style_sum += float(style.mean())
            else:
                reward = np.asarray(task_reward, dtype=np.float64)
            if not np.isfinite(reward).all():    # the return normaliser would keep it, and the update spread it
                raise FloatingPointError(
                    f"a non-finite reward for world(s) {np.flatnonzero(~np.isfinite(reward)).tolist()} at step "
                    f"{self.steps} (task reward {np.asarray(task_reward)[~np.isfinite(reward)].tolist()}): training "
                    f"stops before it reaches the statistics or the weights, so the checkpoints written are sound")
            task_sum += float(np.mean(task_reward))
            self.episodes.step(task_reward, dones, infos)
            norm_obs = self.normalizer.observations(obs)
            norm_reward = self._to_device(self.normalizer.rewards(reward, dones))
            # a truncated episode did not end: its last reward also earns the value of where it stopped
            cut = [i for i in np.flatnonzero(truncated & ~terminated) if i in finals]
            if cut:
                final = self.normalizer.observations(np.stack([finals[i][0] for i in cut]), update=False)
                with torch.no_grad():
                    norm_reward[cut] += cfg.gamma * self.model.values(self._to_device(final))
            r.obs[t], r.actions[t], r.log_probs[t], r.values[t] = self._obs, action, log_prob, value
            r.rewards[t], r.starts[t] = norm_reward, self._starts
            self._obs = self._to_device(norm_obs)
            self._starts = self._to_device(dones.astype(np.float32))
            self.steps += cfg.num_envs * p.world_size
        with torch.no_grad():
            last_values = self.model.values(self._obs)
        r.compute_returns(last_values, self._starts, cfg.gamma, cfg.gae_lambda)
        return p.mean_of({"amp/task_reward": task_sum / cfg.rollout_steps,
                          "amp/style_reward": style_sum / cfg.rollout_steps})

    def update(self) -> dict[str, float]:
        """``epochs`` passes of shuffled minibatches of the clipped PPO loss."""
        cfg, r = self.config, self.rollout
        total = cfg.batch_size
        obs, actions = r.obs.reshape(total, -1), r.actions.reshape(total, -1)
        old_log_probs, advantages, returns = r.log_probs.reshape(-1), r.advantages.reshape(-1), r.returns.reshape(-1)
        for group in self.optimizer.param_groups:
            group["lr"] = self.learning_rate
        stats: dict[str, list[float]] = {"loss/policy": [], "loss/value": [], "loss/entropy": [], "train/approx_kl": [],
                                         "train/clip_fraction": []}
        rollout_threads = torch.get_num_threads()
        if cfg.update_threads is not None:    # the physics pool is idle now: its cores may serve the update
            torch.set_num_threads(cfg.update_threads)
        for _ in range(cfg.epochs):
            order = torch.randperm(total).to(self.device)    # the CPU generator's: the same order on every device
            for start in range(0, total, cfg.minibatch_size):
                mb = order[start:start + cfg.minibatch_size]
                with torch.autocast(self.device.type, dtype=torch.bfloat16, enabled=cfg.update_bf16):
                    mean, values = self.model.action_mean(self.model.policy_net(obs[mb])), self.model.values(obs[mb])
                dist = torch.distributions.Normal(mean.float(), self.model.log_std.exp())
                values = values.float()
                log_prob = dist.log_prob(actions[mb]).sum(-1)
                entropy = dist.entropy().sum(-1)
                adv = advantages[mb]
                if len(mb) * self.parallel.world_size > 1:
                    mean, std = self.parallel.mean_std(adv)    # over every rank's minibatch
                    adv = (adv - mean) / (std + 1e-8)
                log_ratio = log_prob - old_log_probs[mb]
                ratio = log_ratio.exp()
                policy_loss = -torch.min(adv * ratio, adv * ratio.clamp(1 - cfg.clip_range, 1 + cfg.clip_range)).mean()
                value_loss = (returns[mb] - values).pow(2).mean()
                entropy_loss = -entropy.mean()
                loss = policy_loss + cfg.ent_coef * entropy_loss + cfg.vf_coef * value_loss
                self.optimizer.zero_grad(set_to_none=True)
                loss.backward()
                self.parallel.average_gradients(self.model.parameters())    # equal weights on every rank
                nn.utils.clip_grad_norm_(self.model.parameters(), cfg.max_grad_norm)
                self.optimizer.step()
                with torch.no_grad():
                    stats["loss/policy"].append(policy_loss.item())
                    stats["loss/value"].append(value_loss.item())
                    stats["loss/entropy"].append(entropy_loss.item())
                    stats["train/approx_kl"].append(((ratio - 1) - log_ratio).mean().item())
                    stats["train/clip_fraction"].append(((ratio - 1).abs() > cfg.clip_range).float().mean().item())
        torch.set_num_threads(rollout_threads)
        out = self.parallel.mean_of({key: float(np.mean(values)) for key, values in stats.items()})
        if cfg.target_kl is not None:    # the legged-robot rule: keep approx-KL near the target
            kl = out["train/approx_kl"]
            if kl > 2.0 * cfg.target_kl:
                self.learning_rate = max(1e-6, self.learning_rate / 1.5)
            elif 0.0 < kl < 0.5 * cfg.target_kl:
                self.learning_rate = min(1e-3, self.learning_rate * 1.5)
        out["train/learning_rate"] = self.learning_rate
        out["train/std"] = float(self.model.log_std.detach().exp().mean())
        self.iterations += 1
        return out

    # --- the loop ---------------------------------------------------------------------------------
    def learn(self, log: "RunLog | None" = None, checkpoint_dir: Path | None = None) -> None:
        """Train until ``config.total_steps`` env steps; a checkpoint every ``checkpoint_every`` steps and
        at the last."""
        cfg = self.config
        next_checkpoint = (self.steps // cfg.checkpoint_every + 1) * cfg.checkpoint_every
        start_steps, start = self.steps, time.perf_counter()
        while self.steps < cfg.total_steps:
            clock, cpu = time.perf_counter(), time.process_time()
            stats = self.collect()
            clock_collect, cpu_collect = time.perf_counter(), time.process_time()
            stats.update(self.update())
            # where the time goes: wall and CPU (all threads) microseconds per env step, per phase
            per_step = 1e6 / cfg.batch_size
            stats.update({"time/collect_us": (clock_collect - clock) * per_step,
                          "time/collect_cpu_us": (cpu_collect - cpu) * per_step,
                          "time/update_us": (time.perf_counter() - clock_collect) * per_step,
                          "time/update_cpu_us": (time.process_time() - cpu_collect) * per_step})
            if self.style is not None:
                stats.update({f"amp/{k}": v for k, v in self.style.last_stats.items()})
            levels = [level for level in self.all_curriculum_levels() if level is not None]
            if levels:
                stats["curriculum/level"] = float(np.mean(levels))
                names = self.venv.get_attr("curriculum_level_names")[0] if np.ndim(levels[0]) else None
                if names:    # a level per locomotion (PlaMo's speed_levels_by_locomotion): each one's mean
                    means = np.mean(levels, axis=0)
                    stats.update({f"curriculum/level_{name}": float(m) for name, m in zip(names, means)})
            stats.update(self.episodes.means(self.parallel))
            stats["time/steps_per_second"] = (self.steps - start_steps) / (time.perf_counter() - start)
            if log is not None:
                log.write(self.steps, stats)
            # the run's last step is a checkpoint too, so that it resumes exactly, replay buffer and all
            last = self.steps >= cfg.total_steps
            if checkpoint_dir is not None and (self.steps >= next_checkpoint or last):
                self.checkpoint(checkpoint_dir / checkpoint_name(self.steps))
                next_checkpoint += cfg.checkpoint_every

    def checkpoint(self, path: Path) -> Path:
        """A checkpoint that resumes exactly: every world starts a new episode here (their episodes end
        as truncations, bootstrapped), so the state to save is the trainer's, not the worlds'; the
        style's background round is joined and its scoring follows the trained weights from here, as
        in a resumed run; the replay buffer goes beside it (``replay_<steps>.npy``, the latest only)."""
        self.reset()
        if self.style is not None:
            self.style.wait()
            self.style.disc.unfreeze_scoring()
        self._resumed = False
        networks = [*self.model.parameters(), *(self.style.disc.state_dict().values() if self.style else ())]
        gap = self.parallel.weights_gap(networks)
        if gap > RANK_DRIFT_TOLERANCE:
            raise RuntimeError(f"the ranks' weights differ by {gap:.3g} (relative; ranks on other CPUs drift by "
                               f"~1e-7): data-parallel training must keep them equal")
        if gap > 0.0:    # ranks on other kinds of CPU: every rank takes rank 0's weights, the checkpoint's
            self.parallel.broadcast(self.model)
            if self.style is not None:
                self.parallel.broadcast(self.style.disc)
        return self.save(path, replay=True)

    def close(self) -> None:
        if self.style is not None:
            self.style.close()
        self.venv.close()

    # --- the curriculum (InterLevel's step_height_levels, SIMS' start_distance_levels) -------------------
    def curriculum_levels(self) -> list[int | None]:
        """This rank's worlds' levels."""
        if not any(self.config.env_kwargs.get(keyword) for keyword in curriculum.LEVEL_KEYWORDS):
            return []
        return list(self.venv.get_attr("curriculum_level"))

    def all_curriculum_levels(self) -> list[int | None]:
        """Every rank's worlds' levels, in the run's world order."""
        return [level for part in self.parallel.gather(self.curriculum_levels()) for level in part]

    def set_curriculum_levels(self, levels: list[int | None]) -> None:
        if len(levels) != self.config.num_envs:
            raise ValueError(f"{len(levels)} saved curriculum levels, this run has {self.config.num_envs} worlds")
        self.venv.set_attr("curriculum_level", list(levels))

    # --- checkpoints ----------------------------------------------------------------------------------
    def policy(self) -> NumpyPolicy:
        """The deterministic policy as ``stairenv.pretrained`` stores it."""
        return self.model.as_numpy(self.normalizer, self.config.clip_obs, policy_config(self.config, self.steps))

    def state(self) -> dict[str, Any]:
        """The checkpoint's contents (in a data-parallel run every rank must call it: it gathers the
        ranks' curriculum levels and style generators; ``style["ranks"]`` holds those of ranks 1..)."""
        style = None
        if self.style is not None:
            self.style.wait()
            replay = self.style.replay
            generators = self.parallel.gather({"rng": self.style.rng.bit_generator.state,
                                               "noise_rng": self.style.disc.noise_generator.get_state()})
            style = {"discriminator": self.style.disc.state(), "config": plain_config(self.style.config),
                     "rounds": int(self.style.rounds), "pending": int(self.style.pending),
                     **generators[0], "replay_size": int(replay.size), "replay_next": int(replay.next)}
            if len(generators) > 1:
                style["ranks"] = generators[1:]
        return {
            "format": CHECKPOINT_FORMAT, "config": self.config.as_dict(), "steps": int(self.steps),
            "iterations": int(self.iterations), "learning_rate": float(self.learning_rate),
            "model": cpu_tensors(self.model.state_dict()), "optimizer": cpu_tensors(self.optimizer.state_dict()),
            "obs_rms": self.normalizer.obs_rms.state(), "ret_rms": self.normalizer.ret_rms.state(),
            "style": style, "curriculum_level": self.all_curriculum_levels(),
            "torch_rng": torch.get_rng_state(), "world_size": self.parallel.world_size,
        }

    def save(self, path: Path, replay: bool = False) -> Path:
        """Write ``state()`` to ``path`` (whole or not at all); with ``replay``, the style's replay buffer
        to ``replay_<steps>.npy`` beside it, removing older ones (a run keeps one: ~170 MB at 200k windows).
        Data-parallel: every rank calls it, rank 0 writes, rank r's replay buffer as
        ``replay_<steps>_rank<r>.npy``."""
        path = Path(path)
        state = self.state()
        buffers = None
        if replay and self.style is not None:
            buffer = self.style.replay
            buffers = self.parallel.gather_to_first(buffer.data[:buffer.size])
        if self.parallel.rank != 0:
            return path
        path.parent.mkdir(parents=True, exist_ok=True)
        targets = []
        if buffers is not None:
            targets = [replay_beside(path, self.steps, rank) for rank in range(len(buffers))]
            for target, windows in zip(targets, buffers):
                _atomic(target, lambda tmp, windows=windows: np.save(tmp, windows))
        _atomic(path, lambda tmp: torch.save(state, tmp))
        if buffers is not None:    # only now: until the new checkpoint is whole, the last one needs its buffers
            for older in path.parent.glob("replay_*.npy"):
                if older not in targets:
                    older.unlink()
        return path

    def load_state(self, state: dict[str, Any], weights_only: bool = False) -> None:
        """Take a checkpoint's state (``weights_only``: policy, value, optimiser, normalisers and
        discriminator, for a new run from a trained one; else also the counters and generators).

        Written by a run of another rank count (``state["world_size"]``), the shared state is taken
        whole (weights, optimisers, statistics, counters, the torch generator); of the per-rank state,
        rank r takes the style generators of saved rank r where there was one (else keeps its own,
        seeded ``seed + r``), and the worlds take the saved curriculum levels in order, repeated or cut
        to the new world count. The worlds' own generators need nothing: a checkpoint reset every world
        with the seeds of its place in the run. Exact only for the same rank count.

        ``RunMismatch`` for networks or a discriminator of other sizes than this run's (``state`` checked by
        ``check_checkpoint`` first: ``read_checkpoint`` does)."""
        saved, mine = network_sizes(state["model"]), network_sizes(self.model.state_dict())
        if saved != mine:
            raise RunMismatch("networks", f"the checkpoint's policy maps {saved[0]} observations through hidden "
                                          f"layers {list(saved[1])} to {saved[2]} actions; this run's maps {mine[0]} "
                                          f"through {list(mine[1])} to {mine[2]} ({self.config.env_id})",
                              saved, mine)
        self.model.load_state_dict(state["model"])
        self.optimizer.load_state_dict(state["optimizer"])
        self.normalizer.obs_rms.load(state["obs_rms"])
        self.normalizer.ret_rms.load(state["ret_rms"])
        if self.style is not None and state.get("style") is not None:
            own = self.style.disc    # this run's: how it scores (a machine's choice), its seeded noise
            disc = AMPDiscriminator.from_state(state["style"]["discriminator"], backend=own.backend,
                                               scoring=own.scoring, device=self.device)
            disc.scoring_threads, disc.noise_generator = own.scoring_threads, own.noise_generator
            if disc.input_dim != self.style.reference.dim:
                raise RunMismatch("discriminator", f"the checkpoint's discriminator judges {disc.input_dim} "
                                  f"numbers, this run's reference windows have {self.style.reference.dim}",
                                  disc.input_dim, self.style.reference.dim)
            keep = self.style.config
            if weights_only and tuple(keep.hidden) != tuple(disc.config.hidden):
                raise RunMismatch("discriminator", f"the checkpoint's discriminator has hidden layers "
                                  f"{list(disc.config.hidden)}, this run asks for {list(keep.hidden)} "
                                  "(--disc-hidden); its weights fix them", disc.config.hidden, keep.hidden)
            self.style.disc = disc
            if weights_only:    # this run's settings of the discriminator's training, its learning rate too
                disc.config = keep
                for group in disc.optimizer.param_groups:
                    group["lr"] = keep.learning_rate
            self.style.config = disc.config
            self.style.rounds = int(state["style"]["rounds"])
            disc.parallel = self._style_parallel
            generators = [state["style"], *state["style"].get("ranks", [])]
            if not weights_only:
                self.style.pending = int(state["style"]["pending"])
                if self.parallel.rank < len(generators):
                    self.style.rng.bit_generator.state = generators[self.parallel.rank]["rng"]
                    disc.noise_generator.set_state(generators[self.parallel.rank]["noise_rng"])
        saved_kwargs = (state.get("config") or {}).get("env_kwargs") or {}
        same_curriculum = [k for k in curriculum.LEVEL_KEYWORDS if self.config.env_kwargs.get(k)] == [
            k for k in curriculum.LEVEL_KEYWORDS if saved_kwargs.get(k)]
        # a world's saved level given to a per-locomotion world counts for every locomotion; saved
        # per-locomotion levels do not fit a run with one level per world: not taken
        if any(np.ndim(level) for level in state.get("curriculum_level") or []) and not any(
                self.config.env_kwargs.get(k) for k in curriculum.PER_KIND_KEYWORDS):
            same_curriculum = False
        if state.get("curriculum_level") and self.curriculum_levels() and same_curriculum:
            levels = list(state["curriculum_level"])    # every world's, when both runs have a curriculum
            n, p = self.config.num_envs, self.parallel
            if len(levels) != n * p.world_size:    # another count of worlds or ranks: repeated or cut
                levels = [levels[i % len(levels)] for i in range(n * p.world_size)]
            if p.world_size > 1:
                levels = levels[p.rank * n:(p.rank + 1) * n]
            self.set_curriculum_levels(levels)
        if not weights_only:
            self._resumed = True
            self.steps, self.iterations = int(state["steps"]), int(state["iterations"])
            self.learning_rate = float(state["learning_rate"])
            torch.set_rng_state(state["torch_rng"])


    def load_replay(self, path: Path, state: dict[str, Any]) -> bool:
        """Refill the style's replay buffer from ``replay_<steps>.npy`` beside checkpoint ``path``, or in
        ``checkpoints/`` beside it (a run's ``final_checkpoint.pt``), read without pickles; False when there
        is none (the buffer then refills within a round)."""
        if self.style is None or state.get("style") is None:
            return False
        saved_ranks = int(state.get("world_size", 1))    # rank r takes saved rank r's (r mod their count)
        path, steps, rank = Path(path), int(state["steps"]), self.parallel.rank % saved_ranks
        # beside the checkpoint, or (a run's final_checkpoint.pt) beside its last checkpoint, same steps
        candidates = [replay_beside(p, steps, rank) for p in (path, path.parent / "checkpoints" / path.name)]
        file = next((f for f in candidates if f.is_file()), None)
        if file is None:
            return False
        try:
            windows = np.load(file, allow_pickle=False, mmap_mode="r")
        except (OSError, ValueError) as err:
            raise CheckpointError(f"{file}: not a readable replay buffer ({err})") from None
        buffer = self.style.replay
        size, position = int(state["style"]["replay_size"]), int(state["style"]["replay_next"])
        if windows.shape != (size, buffer.data.shape[1]) or size > len(buffer.data) or windows.dtype != np.float32:
            raise CheckpointError(f"{file}: holds {windows.shape} {windows.dtype} windows, the checkpoint says "
                                  f"({size}, {buffer.data.shape[1]}) float32 in a buffer of {len(buffer.data)}")
        if position >= len(buffer.data):
            raise CheckpointError(f"{path}: entry style['replay_next'] is {position}, past the end of this run's "
                                  f"replay buffer of {len(buffer.data)} windows")
        check_replay(windows, file)
        buffer.data[:size] = windows
        buffer.size, buffer.next = size, position
        return True


def policy_config(config: TrainConfig, steps: int) -> dict[str, Any]:
    """What an exported policy records of its run (``NumpyPolicy.config``)."""
    return {"env_id": config.env_id, "steps": int(steps), "training": config.as_dict()}


def policy_from_checkpoint(state: dict[str, Any]) -> NumpyPolicy:
    """The deterministic policy of a checkpoint's state (``read_checkpoint``), as ``Trainer.policy``
    gave it, without building the env."""
    config, weights = TrainConfig.from_dict(state["config"]), state["model"]
    obs_size, action_size = weights["policy_net.0.weight"].shape[1], weights["action_mean.weight"].shape[0]
    model = ActorCritic(obs_size, action_size, config.hidden, config.log_std_init)
    model.load_state_dict(weights)
    normalizer = Normalizer(obs_size, 1, config.gamma, config.clip_obs, config.clip_reward)
    normalizer.obs_rms.load(state["obs_rms"])
    return model.as_numpy(normalizer, config.clip_obs, policy_config(config, state["steps"]))


def replay_beside(checkpoint: Path, steps: int, rank: int = 0) -> Path:
    """The replay buffer of rank ``rank`` beside a checkpoint (rank 0's, and a single process's, without
    a rank in its name)."""
    return Path(checkpoint).with_name(f"replay_{steps}.npy" if rank == 0 else f"replay_{steps}_rank{rank}.npy")


def _atomic(path: Path, write) -> None:
    """``write(tmp)`` then rename to ``path``: a file is whole or absent, never half-written (its bytes are on
    the disk before the rename, so a crash of the machine cannot leave a newest file that is empty)."""
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as f:
        write(f)
        f.flush()
        os.fsync(f.fileno())
    tmp.replace(path)


def checkpoint_name(steps: int) -> str:
    """The file name of a run's checkpoint at ``steps`` (``Trainer.learn`` writes them into ``checkpoints/``)."""
    return f"checkpoint_{steps}.pt"


def checkpoints_in(folder: str | Path) -> list[tuple[int, Path]]:
    """``(steps, path)`` of every ``checkpoint_<steps>.pt`` in ``folder``, fewest steps first (each written whole
    or not at all, so the last is the newest complete one)."""
    found = [(int(match[1]), path) for path in Path(folder).glob("checkpoint_*.pt")
             if (match := re.fullmatch(r"checkpoint_(\d+)", path.stem))]
    return sorted(found)


def read_checkpoint(path: str | Path, style: bool = True) -> dict[str, Any]:
    """A checkpoint's state, read without running code from the file, every entry checked
    (``check_checkpoint``; ``style=False``: not the discriminator's, which the caller replaces);
    ``CheckpointError`` naming the file and the entry otherwise."""
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"no checkpoint file {str(path)!r}")
    try:
        state = load_weights_only(path)
    except Exception as err:  # noqa: BLE001  (truncated or foreign files surface as many types)
        refused = refused_object(err, path)
        if refused is not None:
            raise CheckpointError(f"{path}: refused: it asks to build the Python object {refused}, and a "
                                  "lean-trainer checkpoint holds only tensors and plain values; nothing in it "
                                  "was run") from None
        raise CheckpointError(f"{path}: not a readable lean-trainer checkpoint ({type(err).__name__}); "
                              "nothing in it was run") from None
    if not isinstance(state, dict) or state.get("format") != CHECKPOINT_FORMAT:
        raise CheckpointError(f"{path}: not a lean-trainer checkpoint (format {CHECKPOINT_FORMAT!r} expected)")
    check_checkpoint(state, path, style=style)
    return state


# --- checking a checkpoint's values ----------------------------------------------------------------
#: the largest magnitude a saved replay window's feature may have (joint speeds stop at 250 rad/s, positions
#: at a few hundred metres): beyond it a window is corrupt, and would blow up the discriminator's statistics
MAX_FEATURE = 1e6


def _bounds(low: float, high: float, low_open: bool) -> str:
    """`` in [low, high]``, `` > 0``, ...: the range of a check, as its message says it."""
    if high == math.inf:
        return "" if low == -math.inf else f" {'>' if low_open else '>='} {low:g}"
    return f" <= {high:g}" if low == -math.inf else f" in {'(' if low_open else '['}{low:g}, {high:g}]"


#: the ``TrainConfig`` fields every lean checkpoint records (those of the first lean trainer); a field added
#: since (``physics_threads``, ``amp_text_condition``, ``device``...) takes its default in an older checkpoint
RECORDED_SETTINGS = (
    "env_id", "env_kwargs", "num_envs", "physics", "seed", "total_steps", "rollout_steps", "epochs", "minibatch_size",
    "learning_rate", "target_kl", "gamma", "gae_lambda", "clip_range", "ent_coef", "vf_coef", "max_grad_norm",
    "hidden", "log_std_init", "clip_obs", "clip_reward", "style", "reference", "amp_history", "w_task", "w_style",
    "disc_hidden", "disc_loss", "disc_lr", "disc_grad_penalty", "disc_grad_penalty_batch", "disc_weight_decay",
    "disc_logit_reg", "disc_input_noise", "disc_batch_size", "disc_replay_size", "disc_update_interval",
    "disc_updates", "disc_background", "disc_scoring", "torch_threads", "checkpoint_every")


class _Check:
    """Checks of a checkpoint's entries, each failure a ``CheckpointError`` naming the file and the entry
    (``obs_rms['var']``)."""

    def __init__(self, path: str | Path) -> None:
        self.path = path

    def fail(self, where: tuple, text: str) -> CheckpointError:
        named = where[0] + "".join(f"[{key!r}]" for key in where[1:])
        return CheckpointError(f"{self.path}: entry {named} {text}")

    def entry(self, parent: dict, where: tuple, kind: type | None = dict) -> Any:
        """``parent[where[-1]]`` (``parent`` is the entry ``where[:-1]``), which must be a ``kind``."""
        if where[-1] not in parent:
            raise self.fail(where, "is missing (not a whole lean-trainer checkpoint: altered, or written by "
                                   "another program?)")
        value = parent[where[-1]]
        if kind is not None and (not isinstance(value, kind) or (kind is int and isinstance(value, bool))):
            wanted = {dict: "a dict", int: "an integer", list: "a list", torch.Tensor: "a tensor", str: "a str"}[kind]
            raise self.fail(where, f"is {type(value).__name__} {value!r:.60}; it must be {wanted}")
        return value

    def integer(self, parent: dict, where: tuple, least: int, most: int = 2**62) -> int:
        value = self.entry(parent, where, int)
        if not least <= value <= most:
            raise self.fail(where, f"is {value}; it must lie in [{least}, {most}]")
        return value

    def number(self, value: Any, where: tuple, low: float = -math.inf, high: float = math.inf,
               low_open: bool = False) -> float:
        """A finite real number in [low, high] (or (low, high])."""
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(where, f"is {type(value).__name__} {value!r:.60}; it must be a number")
        if not math.isfinite(value) or (value <= low if low_open else value < low) or value > high:
            raise self.fail(where, f"is {value!r}; it must be a finite number{_bounds(low, high, low_open)}")
        return float(value)

    def values(self, tensor: torch.Tensor, where: tuple, low: float = -math.inf, high: float = math.inf,
               low_open: bool = False) -> None:
        """Every value of a floating-point ``tensor`` finite and in [low, high] (or (low, high])."""
        if not tensor.is_floating_point():
            raise self.fail(where, f"holds {tensor.dtype} values; it must hold floating-point numbers")
        values = tensor.detach().to(torch.float64)
        bad = ~torch.isfinite(values) | (values > high) | ((values <= low) if low_open else (values < low))
        if bool(bad.any()):
            first = tuple(int(i) for i in bad.nonzero()[0])
            raise self.fail(where, f"holds {int(bad.sum())} value(s) that are not finite numbers"
                                   f"{_bounds(low, high, low_open)} (the "
                                   f"first{' at ' + str(first) if first else ''}: {float(values[first]):g})")

    def tensors(self, saved: dict, where: tuple, expected: dict[str, torch.Tensor],
                ranges: dict[str, tuple] | None = None) -> None:
        """``saved`` holds exactly ``expected``'s names, each a tensor of its shape, its values finite (and
        within ``ranges[name]``: low, high, low_open)."""
        missing = [name for name in expected if name not in saved]
        unknown = [str(name) for name in saved if name not in expected]
        if missing or unknown:
            raise self.fail(where, f"is not the network its settings describe (missing {missing}, unknown "
                                   f"{unknown[:8]})")
        for name, want in expected.items():
            tensor = self.entry(saved, (*where, name), torch.Tensor)
            if tuple(tensor.shape) != tuple(want.shape):
                raise self.fail((*where, name), f"has shape {tuple(tensor.shape)}; the network needs "
                                                f"{tuple(want.shape)}")
            self.values(tensor, (*where, name), *(ranges or {}).get(name, ()))

    def adam(self, saved: dict, where: tuple, optimizer: torch.optim.Optimizer) -> None:
        """``saved`` an Adam state of ``optimizer``'s parameters: moments of their shapes, finite (the second
        and the step count >= 0), finite positive rates."""
        params = [p for group in optimizer.param_groups for p in group["params"]]
        try:
            optimizer.load_state_dict(saved)
        except Exception as err:  # noqa: BLE001  (torch's checks raise several types)
            raise self.fail(where, f"is not an Adam state of the network's {len(params)} parameters "
                                   f"({type(err).__name__}: {err})") from None
        for i, group in enumerate(saved["param_groups"]):
            for key in ("lr", "eps"):
                self.number(group.get(key), (*where, "param_groups", i, key), 0.0, 1e3, low_open=True)
            self.number(group.get("weight_decay", 0.0), (*where, "param_groups", i, "weight_decay"), 0.0, 1e3)
            betas = group.get("betas")
            if not isinstance(betas, (tuple, list)) or len(betas) != 2:
                raise self.fail((*where, "param_groups", i, "betas"), f"is {betas!r:.60}; it must be 2 numbers")
            for beta in betas:
                self.number(beta, (*where, "param_groups", i, "betas"), 0.0, 1.0)
        held = sum(param in optimizer.state for param in params)
        if 0 < held < len(params):    # none: saved before the first update; else every parameter's
            raise self.fail((*where, "state"), f"holds the moments of {held} of the network's {len(params)} "
                                               "parameters")
        for index, param in enumerate(params):
            for key, value in optimizer.state.get(param, {}).items():
                at = (*where, "state", index, key)
                if not isinstance(value, torch.Tensor):
                    raise self.fail(at, f"is {type(value).__name__}; it must be a tensor")
                if key != "step" and tuple(value.shape) != tuple(param.shape):
                    raise self.fail(at, f"has shape {tuple(value.shape)}; its parameter has {tuple(param.shape)}")
                self.values(value, at, -math.inf if key == "exp_avg" else 0.0)

    def statistics(self, state: dict, name: str, shape: tuple[int, ...]) -> None:
        """A normaliser's running statistics: finite means of ``shape``, positive finite variances and count."""
        saved = self.entry(state, (name,))
        for key in ("mean", "var"):
            tensor = self.entry(saved, (name, key), torch.Tensor)
            if tuple(tensor.shape) != shape:
                raise self.fail((name, key), f"has shape {tuple(tensor.shape)}; it must be {shape}")
            self.values(tensor, (name, key), *((0.0, math.inf, True) if key == "var" else ()))
        self.number(self.entry(saved, (name, "count"), None), (name, "count"), 0.0, math.inf, low_open=True)

    def generator(self, parent: dict, where: tuple, kind: str) -> None:
        """A generator's state: numpy's bit generator (``kind`` "numpy") or torch's, as it would load."""
        saved = self.entry(parent, where, dict if kind == "numpy" else torch.Tensor)
        try:
            if kind == "numpy":
                np.random.default_rng().bit_generator.state = saved
            else:
                torch.Generator().set_state(saved)
        except Exception as err:  # noqa: BLE001  (numpy and torch refuse a state with several types)
            raise self.fail(where, f"is not a {kind} generator's state ({type(err).__name__}: {err})") from None


def check_checkpoint(state: dict[str, Any], path: str | Path, style: bool = True,
                     weights_only: bool = False) -> None:
    """``CheckpointError`` naming ``path`` and the entry for anything in ``state`` a run cannot go on from:
    a missing or mistyped entry, settings ``TrainConfig`` refuses or an unknown env, networks other than the
    settings describe, weights, optimiser moments or statistics that are not finite, a log std outside
    ``LOG_STD_RANGE``, variances or counts <= 0, a learning rate outside (0, 1], negative counters, or
    generator states that do not load. ``style=False``: the discriminator's state is not looked at (the
    caller starts a new one). ``weights_only``: ``state_from_sb3``'s state (networks, optimiser, statistics,
    discriminator; the hidden layers in ``state["hidden"]``), which has no counters or generators.

    One check for every reader: ``read_checkpoint`` runs it (``train_ppo.py --resume``, ``--init-from``,
    ``export_policy.py``), ``train_ppo.py --init-from`` on an SB3 run's converted state. Building the
    networks to compare with leaves torch's generator where it was."""
    check = _Check(path)
    if weights_only:
        hidden, where = check.entry(state, ("hidden",), list), ("hidden",)
    else:
        saved = check.entry(state, ("config",))
        for name in RECORDED_SETTINGS:    # a field added later takes its default (an older checkpoint lacks it)
            check.entry(saved, ("config", name), None)
        try:
            config = TrainConfig.from_dict(saved)
        except (TypeError, ValueError) as err:
            raise check.fail(("config",), f"is not a run's settings: {err}") from None
        if config.env_id not in gym.registry:
            raise check.fail(("config", "env_id"), f"is {config.env_id!r:.60}, not a registered env id")
        hidden, where = config.hidden, ("config", "hidden")
        check.integer(state, ("steps",), 0)
        check.integer(state, ("iterations",), 0)
        check.integer(state, ("world_size",), 1, 1_000_000)
        check.number(check.entry(state, ("learning_rate",), None), ("learning_rate",), 0.0, 1.0, low_open=True)
        check.generator(state, ("torch_rng",), "torch")
        levels = check.entry(state, ("curriculum_level",), list)

        def level(value: Any) -> bool:
            return value is None or (isinstance(value, int) and not isinstance(value, bool) and value >= 0)

        if not all(level(v) or (isinstance(v, (list, tuple)) and all(level(x) and x is not None for x in v))
                   for v in levels):
            raise check.fail(("curriculum_level",), f"is {levels!r:.80}; it must be a list of levels (integers "
                                                    ">= 0, None, or lists of integers: one per locomotion)")
    if not hidden or not all(isinstance(h, int) and not isinstance(h, bool) and 1 <= h <= 1 << 16 for h in hidden):
        raise check.fail(where, f"is {hidden!r:.60}; it must be positive layer sizes")
    model = check.entry(state, ("model",))
    sizes = []
    for name, axis in (("policy_net.0.weight", 1), ("action_mean.weight", 0)):
        tensor = check.entry(model, ("model", name), torch.Tensor)
        if tensor.ndim != 2 or not 1 <= tensor.shape[axis] <= 1 << 20:
            raise check.fail(("model", name), f"has shape {tuple(tensor.shape)}; it must be a layer's weights "
                                              "(outputs, inputs)")
        sizes.append(int(tensor.shape[axis]))
    with torch.random.fork_rng(devices=[]):    # a resume restores torch's generator, a new run seeds it
        networks = ActorCritic(sizes[0], sizes[1], tuple(hidden), 0.0)
    check.tensors(model, ("model",), networks.state_dict(), {"log_std": LOG_STD_RANGE})
    check.adam(check.entry(state, ("optimizer",)), ("optimizer",),
               torch.optim.Adam(networks.parameters(), lr=1e-4, eps=1e-5))
    check.statistics(state, "obs_rms", (sizes[0],))
    check.statistics(state, "ret_rms", ())
    if style and state.get("style") is not None:
        _check_style(check, check.entry(state, ("style",)), weights_only)


def _check_style(check: _Check, style: dict, weights_only: bool) -> None:
    """A checkpoint's discriminator: its settings, weights, input statistics, optimiser and schedule, and of a
    run (not ``weights_only``) its generators and the replay buffer's fill."""
    disc = check.entry(style, ("style", "discriminator"))
    where = ("style", "discriminator")
    dim = check.integer(disc, (*where, "input_dim"), 1, 1 << 20)
    settings = dict(check.entry(disc, (*where, "config")))
    try:
        config = DiscriminatorConfig(**{**settings, "hidden": tuple(settings.get("hidden") or ())})
    except (TypeError, ValueError) as err:
        raise check.fail((*where, "config"), f"is not a discriminator's settings: {err}") from None
    with torch.random.fork_rng(devices=[]):
        network = AMPDiscriminator(dim, config, backend="aten")
    positive = (0.0, math.inf, True)
    check.tensors(check.entry(disc, (*where, "model")), (*where, "model"), network.state_dict(),
                  {"norm.var": positive, "norm.count": positive})
    check.adam(check.entry(disc, (*where, "optimizer")), (*where, "optimizer"), network.optimizer)
    check.integer(style, ("style", "rounds"), 0)
    if weights_only:
        return
    check.integer(style, ("style", "pending"), 0)
    size = check.integer(style, ("style", "replay_size"), 0, config.replay_size)
    position = check.integer(style, ("style", "replay_next"), 0, max(config.replay_size - 1, 0))
    if size < config.replay_size and position != size:
        raise check.fail(("style", "replay_next"), f"is {position}; a buffer holding {size} of its "
                                                   f"{config.replay_size} windows is filled next at {size}")
    ranks = check.entry(style, ("style", "ranks"), list) if "ranks" in style else []
    for i, generators in enumerate([style, *ranks]):
        at = ("style",) if i == 0 else ("style", "ranks", i - 1)
        if not isinstance(generators, dict):
            raise check.fail(at, f"is {type(generators).__name__}; it must be a dict of generator states")
        check.generator(generators, (*at, "rng"), "numpy")
        check.generator(generators, (*at, "noise_rng"), "torch")


def check_replay(windows: np.ndarray, path: str | Path) -> None:
    """``CheckpointError`` naming ``path`` unless every saved replay window is finite and within
    ``MAX_FEATURE``; read in blocks (a 200k-window buffer is ~170 MB)."""
    for start in range(0, len(windows), 16384):
        block = np.asarray(windows[start:start + 16384], dtype=np.float64)
        bad = ~np.isfinite(block) | (np.abs(block) > MAX_FEATURE)
        if bad.any():
            row, column = (int(i) for i in np.argwhere(bad)[0])
            raise CheckpointError(
                f"{path}: replay window {start + row} holds {block[row, column]:g} (feature {column}); a saved "
                f"window holds finite features within {MAX_FEATURE:g}, so the file is corrupt: delete it to "
                "resume with an empty buffer (it refills within a round), or resume from another checkpoint")


# --- building a run --------------------------------------------------------------------------------
def make_env(config: TrainConfig, parallel: Local = LOCAL) -> HumanoidVectorEnv:
    """The batched env of ``config`` (SAME_STEP autoreset; the registration's episode limit) for this rank
    of ``parallel``: with ``physics="warp"`` on the rank's GPU (``parallel.physics_device``; one process:
    Warp's first GPU), with the C back-end's thread pool sized to the node's cores shared by its ranks
    unless ``config.physics_threads`` says (one process: every core)."""
    kwargs = dict(config.env_kwargs)
    if config.style == "amp":
        kwargs.setdefault("amp_history", config.amp_history)
    threads = config.physics_threads
    if config.state_on_device:
        kwargs["state_on_device"] = True
    if config.physics == "warp" and parallel.physics_device is not None:
        kwargs["physics_device"] = parallel.physics_device
    elif config.physics != "warp" and threads is None and parallel.ranks_on_node > 1:
        threads = max(1, (os.cpu_count() or 1) // parallel.ranks_on_node)    # the pool's default: cpu_count
    venv = gym.make_vec(config.env_id, num_envs=config.num_envs, vectorization_mode="vector_entry_point",
                        physics=config.physics, physics_threads=threads, **kwargs)
    if not isinstance(venv, HumanoidVectorEnv):
        raise TypeError(f"{config.env_id} has no natively batched env; the lean trainer needs one")
    return venv


def discriminator_config(config: TrainConfig) -> DiscriminatorConfig:
    return DiscriminatorConfig(
        hidden=config.disc_hidden, loss=config.disc_loss, learning_rate=config.disc_lr,
        grad_penalty=config.disc_grad_penalty, grad_penalty_batch=config.disc_grad_penalty_batch,
        weight_decay=config.disc_weight_decay, logit_reg=config.disc_logit_reg,
        input_noise=config.disc_input_noise, batch_size=config.disc_batch_size, replay_size=config.disc_replay_size)


def build_style(config: TrainConfig, reference, rank: int = 0) -> AMPStyleReward | None:
    """The AMP reward of ``config`` on ``reference`` windows (None with ``style == "none"``); rank r of a
    data-parallel run draws its discriminator minibatches and instance noise with seed ``seed + r``."""
    if config.style != "amp":
        return None
    return AMPStyleReward(reference, w_task=config.w_task, w_style=config.w_style, seed=config.seed + rank,
                          update_interval=config.disc_update_interval, updates_per_round=config.disc_updates,
                          config=discriminator_config(config), background_training=config.disc_background,
                          scoring=config.disc_scoring, device=config.device)


class RunLog:
    """Scalars to TensorBoard (when installed) and a JSON line per iteration (``log.jsonl``)."""

    def __init__(self, folder: Path, print_every: int = 20) -> None:
        folder.mkdir(parents=True, exist_ok=True)
        self.lines = (folder / "log.jsonl").open("a")
        self.print_every, self.count = print_every, 0
        try:
            from torch.utils.tensorboard import SummaryWriter
            self.writer = SummaryWriter(str(folder / "tb"))
        except ImportError:
            self.writer = None

    def write(self, steps: int, stats: dict[str, float]) -> None:
        self.lines.write(json.dumps({"steps": steps, **stats}) + "\n")
        self.lines.flush()
        if self.writer is not None:
            for key, value in stats.items():
                self.writer.add_scalar(key, value, steps)
        self.count += 1
        if self.count % self.print_every == 0:
            shown = {k: stats[k] for k in ("time/steps_per_second", "episode/length", "amp/task_reward",
                                           "amp/style_reward", "episode_floor_start/progress") if k in stats}
            print(f"{steps:>11,d} steps  " + "  ".join(f"{k.split('/')[-1]} {v:.3g}" for k, v in shown.items()),
                  flush=True)

    def close(self) -> None:
        self.lines.close()
        if self.writer is not None:
            self.writer.close()
