"""The AMP style reward as a vectorised-env wrapper, so any PPO library trains unchanged.

Every env of the package puts its last K frames of style features in
``info["amp_obs"]``. The wrappers read them after each vectorised step, score
them with the discriminator, replace the reward by

    r = w_task * r_task + w_style * r_style

(keeping both parts in ``info["task_reward"]`` and ``info["style_reward"]``),
store the agent's windows in a replay buffer and, every ``update_interval``
transitions, train the discriminator for ``updates_per_round`` minibatches of
reference windows against replayed agent windows.

- ``AMPVecEnvWrapper``: Stable-Baselines3 ``VecEnv`` (``DummyVecEnv``, ``SubprocVecEnv``).
- ``AMPVectorWrapper``: ``gymnasium.vector.VectorEnv`` (next-step autoreset).

``save(path)`` / ``load(path)`` keep the discriminator, its optimiser and input
normaliser, the weights and the schedule; the replay buffer's contents are not
saved (its size is), it refills within one round.
"""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper

from stairenv.style.discriminator import AMPDiscriminator, DiscriminatorConfig, ReplayBuffer
from stairenv.style.reference import ReferenceWindows
from stairenv.validation import check_number


class AMPStyleReward:
    """Discriminator, replay buffer and training schedule shared by both wrappers."""

    def __init__(
        self,
        reference: ReferenceWindows,
        w_task: float = 0.5,
        w_style: float = 0.5,
        config: DiscriminatorConfig | None = None,
        update_interval: int = 2048,
        updates_per_round: int = 2,
        train: bool = True,
        seed: int = 0,
        discriminator: AMPDiscriminator | None = None,
    ) -> None:
        self.reference = reference
        self.w_task = check_number("w_task", w_task, 0.0)
        self.w_style = check_number("w_style", w_style, 0.0)
        self.update_interval = int(check_number("update_interval", update_interval, 1))
        self.updates_per_round = int(check_number("updates_per_round", updates_per_round, 0))
        self.train = bool(train)
        torch.manual_seed(seed)
        self.rng = np.random.default_rng(seed)
        self.disc = discriminator if discriminator is not None else AMPDiscriminator(reference.dim, config or DiscriminatorConfig())
        if self.disc.input_dim != reference.dim:
            raise ValueError(f"discriminator input {self.disc.input_dim} != reference window size {reference.dim}")
        self.config = self.disc.config
        self.replay = ReplayBuffer(self.config.replay_size, reference.dim)
        self.pending = 0
        self.rounds = 0
        self.last_stats: dict[str, float] = {}

    def __call__(self, amp_obs: np.ndarray, task_reward: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Combined reward and style reward of a batch of transitions; also learns from them."""
        if amp_obs.shape[1] != self.reference.dim:
            raise ValueError(
                f"info['amp_obs'] has {amp_obs.shape[1]} numbers per env but the reference windows have "
                f"{self.reference.dim}: make the env's amp_history equal the reference's num_frames"
            )
        style = self.disc.reward(amp_obs)
        if self.train:
            self.replay.add(amp_obs)
            self.pending += len(amp_obs)
            if self.pending >= self.update_interval:
                self.pending = 0
                self.train_round()
        return self.w_task * np.asarray(task_reward, dtype=np.float64) + self.w_style * style, style

    def train_round(self, updates: int | None = None) -> dict[str, float]:
        updates = self.updates_per_round if updates is None else updates
        batch = self.config.batch_size
        stats: list[dict[str, float]] = []
        for _ in range(updates):
            if len(self.replay) == 0:
                break
            stats.append(self.disc.update(self.reference.sample(batch, self.rng), self.replay.sample(batch, self.rng)))
        if stats:
            self.rounds += 1
            self.last_stats = {k: float(np.mean([s[k] for s in stats])) for k in stats[0]}
        return self.last_stats

    def save(self, path: str | Path) -> Path:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        torch.save({
            "discriminator": self.disc.state(),
            "w_task": self.w_task, "w_style": self.w_style,
            "update_interval": self.update_interval, "updates_per_round": self.updates_per_round,
            "replay_size": self.config.replay_size, "rounds": self.rounds,
            "reference_num_frames": self.reference.num_frames, "reference_fps": self.reference.fps,
            "config": asdict(self.config),
        }, path)
        return path

    @classmethod
    def load(cls, path: str | Path, reference: ReferenceWindows, train: bool = True, seed: int = 0) -> "AMPStyleReward":
        state = torch.load(Path(path), weights_only=False)
        disc = AMPDiscriminator.from_state(state["discriminator"])
        style = cls(reference, state["w_task"], state["w_style"], update_interval=state["update_interval"],
                    updates_per_round=state["updates_per_round"], train=train, seed=seed, discriminator=disc)
        style.rounds = state["rounds"]
        return style


class AMPVecEnvWrapper(VecEnvWrapper):
    """Stable-Baselines3 VecEnv wrapper adding the AMP style reward."""

    def __init__(self, venv: VecEnv, style: AMPStyleReward) -> None:
        super().__init__(venv)
        self.style = style
        self._amp = np.empty((self.num_envs, style.reference.dim), dtype=np.float32)

    def reset(self):
        return self.venv.reset()

    def step_wait(self):
        obs, task_reward, dones, infos = self.venv.step_wait()
        windows = [info["amp_obs"] for info in infos]
        if windows[0].shape[-1] == self._amp.shape[1]:  # straight into float32, as the discriminator reads them
            amp = np.stack(windows, out=self._amp)
        else:  # AMPStyleReward explains the mismatch
            amp = np.stack(windows)
        reward, style = self.style(amp, task_reward)
        for info, task, sty in zip(infos, task_reward.tolist(), style.tolist()):
            info["task_reward"] = task
            info["style_reward"] = sty
        return obs, reward.astype(np.float32), dones, infos


class AMPVectorWrapper(gym.vector.VectorWrapper):
    """``gymnasium.vector`` wrapper adding the AMP style reward (next-step autoreset envs).

    With next-step autoreset, the step after an episode ends only resets that env
    (reward 0): those entries get no style reward and are not learned from.
    """

    def __init__(self, env: gym.vector.VectorEnv, style: AMPStyleReward) -> None:
        super().__init__(env)
        self.style = style
        self._resetting = np.zeros(self.num_envs, dtype=bool)

    def reset(self, **kwargs):
        self._resetting[:] = False
        return self.env.reset(**kwargs)

    def step(self, actions):
        obs, task_reward, terminated, truncated, info = self.env.step(actions)
        if "amp_obs" not in info:
            raise KeyError("the wrapped envs put no 'amp_obs' in info; AMP needs stairenv envs (or compatible)")
        live = ~self._resetting
        task_reward = np.asarray(task_reward, dtype=np.float64)
        reward = task_reward.copy()
        style = np.zeros(self.num_envs)
        if live.any():
            reward[live], style[live] = self.style(np.asarray(info["amp_obs"])[live], task_reward[live])
        info = dict(info)
        info["task_reward"] = task_reward
        info["style_reward"] = style
        self._resetting = np.logical_or(terminated, truncated)
        return obs, reward, terminated, truncated, info
