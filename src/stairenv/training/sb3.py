"""Stable-Baselines3 PPO with the AMP wrapper (``baselines/train_sb3.py``): its callbacks (AMP
statistics and state, episode results, a KL-adaptive learning rate, the step-height curriculum) and the
files a run saves beside each ``ppo_<n>_steps.zip`` (VecNormalize statistics, AMP state, curriculum
levels), found and checked before a resume. The model .zip and statistics .pkl are SB3's pickles:
resume only from files you trust.
"""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.utils import ConstantSchedule
from stable_baselines3.common.vec_env import VecNormalize

from stairenv.policy_loading import normalizer_beside
from stairenv.style.reference import ReferenceWindows
from stairenv.style.wrappers import AMPStateError, AMPStyleReward


class AMPCallback(BaseCallback):
    """Logs the discriminator's statistics and saves the AMP state next to each checkpoint."""

    def __init__(self, style: AMPStyleReward, save_freq: int, folder: Path) -> None:
        super().__init__()
        self.style, self.save_freq, self.folder = style, save_freq, folder

    def _on_step(self) -> bool:
        infos = self.locals.get("infos", [])
        if infos:
            self.logger.record_mean("amp/style_reward", float(sum(i["style_reward"] for i in infos) / len(infos)))
            self.logger.record_mean("amp/task_reward", float(sum(i["task_reward"] for i in infos) / len(infos)))
        for key, value in self.style.last_stats.items():
            self.logger.record(f"amp/{key}", value)
        if self.n_calls % self.save_freq == 0:
            self.style.save(self.folder / f"amp_{self.num_timesteps}_steps.pt")
        return True


class EpisodeStatsCallback(BaseCallback):
    """Logs the task's results at each episode's end (``episode/*``): InterLevel's progress, success and
    falls, for all episodes and for those that started on the floor (``info["stairs_start"]`` false),
    the ones comparable with the evaluation's."""

    KEYS = ("progress", "success", "fell", "stalled")

    def _on_step(self) -> bool:
        for done, info in zip(self.locals["dones"], self.locals["infos"]):
            if not done or "progress" not in info:
                continue
            groups = ("episode", "episode_floor_start") if not info.get("stairs_start") else ("episode",)
            for group in groups:
                for key in self.KEYS:
                    if key in info:
                        self.logger.record_mean(f"{group}/{key}", float(info[key]))
        return True


class AdaptiveLearningRate(BaseCallback):
    """Keeps PPO's approx-KL near ``target``: after each update the learning rate is multiplied by 1.5
    when the update's approx-KL was below target / 2 and divided by 1.5 when above 2 target (the rule of
    legged-robot PPO trainers). The rate lives in the model's schedule, so checkpoints resume with it."""

    def __init__(self, target: float, low: float = 1e-6, high: float = 1e-3) -> None:
        super().__init__()
        self.target, self.low, self.high = target, low, high

    def _on_rollout_end(self) -> None:
        kl = self.model.logger.name_to_value.get("train/approx_kl")
        rate = float(self.model.lr_schedule(1.0))
        if kl is not None and kl > 2.0 * self.target:
            rate = max(self.low, rate / 1.5)
        elif kl is not None and 0.0 < kl < 0.5 * self.target:
            rate = min(self.high, rate * 1.5)
        self.model.learning_rate = rate
        self.model.lr_schedule = ConstantSchedule(rate)
        self.logger.record("train/adaptive_learning_rate", rate)

    def _on_step(self) -> bool:
        return True


class CurriculumCallback(BaseCallback):
    """The step-height curriculum's state (``step_height_levels``): its worlds' levels logged as
    ``curriculum/level`` (mean) after each rollout and saved as ``curriculum_<n>_steps.json`` beside
    each checkpoint, which ``--resume`` and ``--init-from`` read back."""

    def __init__(self, save_freq: int, folder: Path) -> None:
        super().__init__()
        self.save_freq, self.folder = save_freq, folder

    def _levels(self) -> list[int | None]:
        return list(self.training_env.get_attr("curriculum_level"))

    def _on_rollout_end(self) -> None:
        levels = [level for level in self._levels() if level is not None]
        if levels:
            self.logger.record("curriculum/level", float(np.mean(levels)))

    def _on_step(self) -> bool:
        if self.n_calls % self.save_freq == 0:
            path = self.folder / f"curriculum_{self.num_timesteps}_steps.json"
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(json.dumps({"curriculum_level": self._levels()}))
        return True


def saved_beside(checkpoint: Path, kind: str, suffix: str) -> Path:
    """What a run saves beside ``ppo_<n>_steps.zip`` under another name: ``<kind>_<n>_steps<suffix>``."""
    return checkpoint.with_name(f"{kind}_{checkpoint.stem.removeprefix('ppo_')}{suffix}")


def curriculum_state_beside(checkpoint: Path) -> Path | None:
    """The curriculum levels saved with a checkpoint (ppo_<n>_steps.zip -> curriculum_<n>_steps.json)."""
    path = saved_beside(checkpoint, "curriculum", ".json")
    return path if checkpoint.stem.startswith("ppo_") and path.is_file() else None


def restore_curriculum(venv, path: Path) -> list[int | None]:
    """Give each world its saved level; ``SystemExit`` naming the file when it does not fit this run."""
    try:
        levels = json.loads(path.read_text())["curriculum_level"]
        if not isinstance(levels, list) or not all(
                level is None or type(level) is int
                or (isinstance(level, list) and all(type(k) is int for k in level)) for level in levels):
            raise ValueError("curriculum_level must be a list of integers (or of lists of integers: a level "
                             "per locomotion)")
    except (OSError, ValueError, KeyError, TypeError) as err:
        raise SystemExit(f"--resume: cannot read the curriculum state {path} ({err})") from None
    if len(levels) != venv.num_envs:
        raise SystemExit(f"--resume: {path} holds {len(levels)} worlds' levels, this run has {venv.num_envs} "
                         "(--n-envs)")
    for i, level in enumerate(levels):
        venv.set_attr("curriculum_level", level, indices=[i])
    return levels


def amp_state_candidates(checkpoint: Path) -> list[Path]:
    """Where the AMP state saved with a checkpoint lies (ppo_<n>_steps.zip -> amp_<n>_steps.pt, or amp.pt)."""
    own = [saved_beside(checkpoint, "amp", ".pt")]
    return (own if checkpoint.stem.startswith("ppo_") else []) + [checkpoint.parent / "amp.pt"]


def amp_state_beside(checkpoint: Path) -> Path | None:
    return next((path for path in amp_state_candidates(checkpoint) if path.is_file()), None)


def checkpoint_file(resume: Path) -> Path:
    """The --resume checkpoint as an existing file (SB3 also takes it without its .zip)."""
    for candidate in (resume, resume.with_name(resume.name + ".zip")):
        if candidate.is_file():
            return candidate
    raise SystemExit(f"--resume {resume}: no such checkpoint file; give a run's checkpoints/ppo_<n>_steps.zip "
                     "or its final_model.zip")


def statistics_beside(checkpoint: Path) -> Path:
    stats = normalizer_beside(checkpoint)
    if stats is None:
        raise SystemExit(f"--resume {checkpoint}: no VecNormalize statistics beside it "
                         "(ppo_vecnormalize_<n>_steps.pkl or vecnormalize.pkl); the policy cannot go on without "
                         "the observation normalisation it learnt with: copy the file back or resume from "
                         "another checkpoint")
    return stats


def required_amp_state(checkpoint: Path) -> Path:
    """The AMP state beside the checkpoint; missing, resuming would silently restart the discriminator."""
    found = amp_state_beside(checkpoint)
    if found is None:
        expected = " or ".join(str(path) for path in amp_state_candidates(checkpoint))
        raise SystemExit(f"--resume {checkpoint}: no AMP state beside it ({expected}), so the discriminator "
                         "trained with it is lost: copy it back, or pass --fresh-discriminator to go on "
                         "with a new discriminator (its style rewards start over), or --style none")
    return found


def run_env(checkpoint: Path) -> str | None:
    """The env id of the run folder a checkpoint lies in (<logdir>/<env>/seed<k>/[checkpoints/])."""
    return next((folder.name for folder in list(checkpoint.parents)[:3] if folder.name in gym.registry), None)


def check_same_spaces(checkpoint: Path, stats: Path, normalizer: VecNormalize, venv, env_id: str) -> None:
    """Stop when the checkpoint's env (its statistics' spaces) is not --env's."""
    saved = (normalizer.observation_space.shape, normalizer.action_space.shape)
    now = (venv.observation_space.shape, venv.action_space.shape)
    if saved != now:
        origin = run_env(checkpoint)
        hint = f" (its run folder is {origin}'s)" if origin and origin != env_id else ""
        raise SystemExit(f"--resume {checkpoint}: trained on observations of shape {saved[0]} and actions of shape "
                         f"{saved[1]} (statistics {stats}){hint}, but --env {env_id} gives {now[0]} and {now[1]}: "
                         "pass the --env and --env-kwarg it was trained with")


def resumed_style(amp_state: Path, reference: ReferenceWindows, seed: int) -> AMPStyleReward:
    try:
        return AMPStyleReward.load(amp_state, reference, seed=seed)
    except (AMPStateError, ValueError) as err:
        raise SystemExit(f"--resume: {err}. To go on with a new discriminator instead, pass --fresh-discriminator"
                         ) from None


def load_checkpoint(checkpoint: Path, venv, device: str, tensorboard: str | None) -> PPO:
    try:
        return PPO.load(checkpoint, env=venv, device=device, tensorboard_log=tensorboard)
    except Exception as err:  # noqa: BLE001  (a truncated .zip, another algorithm's, other spaces: many types)
        raise SystemExit(f"--resume {checkpoint}: cannot load it as a PPO checkpoint for this env "
                         f"({type(err).__name__}: {err})") from None
