"""The lean trainer's settings: one frozen dataclass, saved whole beside every checkpoint.

``TrainConfig`` holds everything a run depends on (env, PPO, AMP, run bookkeeping); ``as_dict`` /
``from_dict`` turn it into plain values and back (the checkpoint stores it, ``--resume`` reads it).
Values are checked once, in ``__post_init__``, each error naming the field and its range.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

from stairenv.environments.batch_physics import check_state_on_device
from stairenv.style.discriminator import LOSSES
from stairenv.style.scoring import SCORERS
from stairenv.validation import check_bool, check_choice, check_float, check_int

#: the Gaussian policy's log std a run may start at, and a checkpoint may hold (std 2e-9 .. 148)
LOG_STD_RANGE = (-20.0, 5.0)


@dataclass(frozen=True)
class TrainConfig:
    """One PPO + AMP run on a natively batched stairenv env.

    | field | default | meaning |
    |---|---|---|
    | env_id | "InterLevel-v0" | registered stairenv id |
    | env_kwargs | {} | keyword arguments of the env (training aids included: the evaluation drops them) |
    | num_envs | 128 | worlds stepped together (per rank in a data-parallel run) |
    | physics | "mujoco" | the batched env's physics ("mujoco": C library, thread pool; "serial"; "warp": GPU) |
    | physics_threads | None | threads of the "mujoco" pool (None: the cores) |
    | state_on_device | False | with "warp": the state stays on the device between resets (``WarpPhysics``) |
    | seed | 0 | seeds torch, the trainer's generators, the worlds (world i: seed + i; rank r's j: r x num_envs + j) |
    | total_steps | 2,000,000 | env steps (all worlds together, every rank's) |
    | rollout_steps | 16 | steps per world between updates |
    | epochs | 5 | passes over a rollout |
    | minibatch_size | 1024 | samples per gradient step (per rank) |
    | learning_rate | 1e-4 | Adam (eps 1e-5) |
    | target_kl | None | adapt the rate to keep approx-KL near this (x1.5 / /1.5, bounds 1e-6..1e-3) |
    | gamma | 0.99 | discount |
    | gae_lambda | 0.95 | GAE's lambda |
    | clip_range | 0.2 | PPO ratio clip |
    | ent_coef | 0.0 | entropy bonus weight |
    | vf_coef | 0.5 | value-loss weight |
    | max_grad_norm | 1.0 | gradient-norm clip |
    | hidden | (256, 256) | policy and value MLPs (ReLU, separate) |
    | log_std_init | -2.0 | initial log std of the Gaussian (std 0.135) |
    | clip_obs | 10.0 | observation normaliser clip |
    | clip_reward | 10.0 | reward normaliser clip |
    | style | "amp" | "amp": reward ``w_task r_task + w_style r_style``; "none": task only |
    | w_task | 0.5 | the task reward's weight |
    | w_style | 0.5 | the style reward's weight |
    | reference | None | folder or .npz of reference clips, or builtin:stairs / builtin:sims (None: the env's) |
    | amp_history | 2 | frames per discriminator sample |
    | amp_text_condition | False | SIMS: the discriminator also judges the caption's text embedding |
    | disc_hidden | (1024, 512) | discriminator hidden layers (the paper's) |
    | disc_loss | "lsgan" | discriminator loss |
    | disc_lr | 1e-4 | discriminator learning rate |
    | disc_grad_penalty | 10.0 | gradient penalty weight (the paper: 5) |
    | disc_grad_penalty_batch | None | reference windows the gradient penalty is estimated on (None: the whole batch) |
    | disc_weight_decay | 1e-4 | L2 penalty on every discriminator weight |
    | disc_logit_reg | 0.01 | L2 penalty on the output layer's weights |
    | disc_input_noise | 1.0 | std of instance noise on the discriminator's normalised training inputs (0: none, the paper) |
    | disc_batch_size | 256 | reference and agent windows per minibatch |
    | disc_replay_size | 200,000 | agent windows kept for training (the paper: 100,000) |
    | disc_update_interval | 2048 | transitions between the discriminator's training rounds |
    | disc_updates | 2 | discriminator minibatches per training round |
    | disc_background | True | train the discriminator in a worker thread while the envs step (rewards lag one round) |
    | disc_scoring | "auto" | how the discriminator scores each step (numba-parallel: over all cores; bf16: bfloat16) |
    | torch_threads | 1 | torch intra-op threads during the rollout (the physics pool uses the cores) |
    | update_threads | None | torch threads during the update, when the physics pool is idle (None: torch_threads) |
    | update_bf16 | False | the update's matrix products in bfloat16 (autocast; weights and optimiser stay float32) |
    | device | "cpu" | torch device of the networks, optimisers, rollout, PPO and AMP updates (envs: on the host) |
    | checkpoint_every | 1,000,000 | env steps between checkpoints (each starts every episode anew: resumes are exact) |

    Data-parallel runs (torchrun; ``stairenv.training.distributed``): ``disc_batch_size``,
    ``disc_update_interval`` and ``disc_replay_size`` are per rank too; ``total_steps`` and
    ``checkpoint_every`` count every rank's steps.
    """

    env_id: str = "InterLevel-v0"
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    num_envs: int = 128
    physics: str = "mujoco"
    physics_threads: int | None = None
    state_on_device: bool = False
    seed: int = 0
    total_steps: int = 2_000_000
    rollout_steps: int = 16
    epochs: int = 5
    minibatch_size: int = 1024
    learning_rate: float = 1e-4
    target_kl: float | None = None
    gamma: float = 0.99
    gae_lambda: float = 0.95
    clip_range: float = 0.2
    ent_coef: float = 0.0
    vf_coef: float = 0.5
    max_grad_norm: float = 1.0
    hidden: tuple[int, ...] = (256, 256)
    log_std_init: float = -2.0
    clip_obs: float = 10.0
    clip_reward: float = 10.0
    style: str = "amp"
    reference: str | None = None
    amp_history: int = 2
    amp_text_condition: bool = False    # SIMS: the discriminator also sees the caption's embedding
    w_task: float = 0.5
    w_style: float = 0.5
    disc_hidden: tuple[int, ...] = (1024, 512)
    disc_loss: str = "lsgan"
    disc_lr: float = 1e-4
    disc_grad_penalty: float = 10.0
    disc_grad_penalty_batch: int | None = None
    disc_weight_decay: float = 1e-4
    disc_logit_reg: float = 0.01
    disc_input_noise: float = 1.0
    disc_batch_size: int = 256
    disc_replay_size: int = 200_000
    disc_update_interval: int = 2048
    disc_updates: int = 2
    disc_background: bool = True
    disc_scoring: str = "auto"
    torch_threads: int | None = 1
    update_threads: int | None = None
    update_bf16: bool = False
    device: str = "cpu"
    checkpoint_every: int = 1_000_000

    def __post_init__(self) -> None:
        if not isinstance(self.env_id, str):
            raise TypeError(f"env_id must be a registered env id (a str), got {self.env_id!r:.60}")
        self._set("num_envs", check_int("num_envs", self.num_envs, 1, 1_000_000))
        self._set("physics", check_choice("physics", self.physics, ("mujoco", "threads", "serial", "warp")))
        if self.physics_threads is not None:
            self._set("physics_threads", check_int("physics_threads", self.physics_threads, 1, 1024))
        check_state_on_device(self.physics, self.state_on_device)
        self._set("seed", check_int("seed", self.seed, 0, 2**31 - 1))
        self._set("total_steps", check_int("total_steps", self.total_steps, 0, 10**12))
        self._set("rollout_steps", check_int("rollout_steps", self.rollout_steps, 1, 100_000))
        self._set("epochs", check_int("epochs", self.epochs, 1, 1000))
        # larger than a rollout: one minibatch of the whole rollout (as SB3)
        self._set("minibatch_size", check_int("minibatch_size", self.minibatch_size, 1, 10**9))
        self._set("learning_rate", check_float("learning_rate", self.learning_rate, 0.0, 1.0))
        if self.target_kl is not None:
            self._set("target_kl", check_float("target_kl", self.target_kl, 1e-6, 10.0))
        self._set("gamma", check_float("gamma", self.gamma, 0.0, 1.0))
        self._set("gae_lambda", check_float("gae_lambda", self.gae_lambda, 0.0, 1.0))
        self._set("clip_range", check_float("clip_range", self.clip_range, 1e-6, 10.0))
        self._set("ent_coef", check_float("ent_coef", self.ent_coef, 0.0, 10.0))
        self._set("vf_coef", check_float("vf_coef", self.vf_coef, 0.0, 100.0))
        self._set("max_grad_norm", check_float("max_grad_norm", self.max_grad_norm, 1e-6, 1e6))
        self._set("log_std_init", check_float("log_std_init", self.log_std_init, *LOG_STD_RANGE))
        self._set("clip_obs", check_float("clip_obs", self.clip_obs, 1e-3, 1e9))
        self._set("clip_reward", check_float("clip_reward", self.clip_reward, 1e-3, 1e9))
        self._set("style", check_choice("style", self.style, ("amp", "none")))
        self._set("amp_history", check_int("amp_history", self.amp_history, 1, 100))
        self._set("amp_text_condition", check_bool("amp_text_condition", self.amp_text_condition))
        self._set("w_task", check_float("w_task", self.w_task, 0.0, 1e6))
        self._set("w_style", check_float("w_style", self.w_style, 0.0, 1e6))
        self._set("checkpoint_every", check_int("checkpoint_every", self.checkpoint_every, 1, 10**12))
        if self.reference is not None and not isinstance(self.reference, str):
            raise TypeError(f"reference must be a path (a str) or None, got {self.reference!r:.60}")
        # the discriminator's, in DiscriminatorConfig's and AMPStyleReward's ranges (a checkpoint's too)
        self._set("disc_loss", check_choice("disc_loss", self.disc_loss, LOSSES))
        self._set("disc_lr", check_float("disc_lr", self.disc_lr, 0.0, 1.0, low_open=True))
        for name in ("disc_grad_penalty", "disc_weight_decay", "disc_logit_reg"):
            self._set(name, check_float(name, getattr(self, name), 0.0))
        self._set("disc_input_noise", check_float("disc_input_noise", self.disc_input_noise, 0.0, 10.0))
        if self.disc_grad_penalty_batch is not None:
            self._set("disc_grad_penalty_batch", check_int("disc_grad_penalty_batch", self.disc_grad_penalty_batch,
                                                           1, 1 << 20))
        self._set("disc_batch_size", check_int("disc_batch_size", self.disc_batch_size, 1, 1 << 20))
        self._set("disc_replay_size", check_int("disc_replay_size", self.disc_replay_size, 1, 1 << 30))
        self._set("disc_update_interval", check_int("disc_update_interval", self.disc_update_interval, 1, 10**12))
        self._set("disc_updates", check_int("disc_updates", self.disc_updates, 0, 10**6))
        self._set("disc_background", check_bool("disc_background", self.disc_background))
        self._set("disc_scoring", check_choice("disc_scoring", self.disc_scoring, SCORERS))
        if self.torch_threads is not None:
            self._set("torch_threads", check_int("torch_threads", self.torch_threads, 1, 1024))
        if self.update_threads is not None:
            self._set("update_threads", check_int("update_threads", self.update_threads, 1, 1024))
        if not isinstance(self.update_bf16, bool):
            raise TypeError(f"update_bf16 must be True or False, got {self.update_bf16!r}")
        if not isinstance(self.device, str) or not self.device:
            raise TypeError(f"device must be a torch device name like 'cpu' or 'cuda:0', got {self.device!r}")
        for name in ("hidden", "disc_hidden"):
            sizes = getattr(self, name)
            if not sizes or any(isinstance(s, bool) or not isinstance(s, int) or s < 1 for s in sizes):
                raise ValueError(f"{name} must be positive layer sizes like (256, 256), got {sizes!r}")
            object.__setattr__(self, name, tuple(sizes))
        if not isinstance(self.env_kwargs, dict) or not all(isinstance(key, str) for key in self.env_kwargs):
            raise TypeError(f"env_kwargs must be a dict of keywords, got {self.env_kwargs!r:.60}")
        object.__setattr__(self, "env_kwargs", dict(self.env_kwargs))

    def _set(self, name: str, value: Any) -> None:
        object.__setattr__(self, name, value)

    @property
    def batch_size(self) -> int:
        """Samples per rollout (all of this rank's worlds)."""
        return self.num_envs * self.rollout_steps

    def as_dict(self) -> dict[str, Any]:
        """Plain values (lists for tuples), as a checkpoint stores them."""
        return {f.name: _plain(getattr(self, f.name)) for f in dataclasses.fields(self)}

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> "TrainConfig":
        """The config ``as_dict`` wrote; unknown keys raise ``ValueError`` naming them."""
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(values) - names)
        if unknown:
            raise ValueError(f"unknown TrainConfig fields {unknown}; valid: {sorted(names)}")
        values = dict(values)
        for name in ("hidden", "disc_hidden"):
            if name in values:
                values[name] = tuple(values[name])
        return cls(**values)

    def replace(self, **changes: Any) -> "TrainConfig":
        return dataclasses.replace(self, **changes)


def _plain(value: Any) -> Any:
    if isinstance(value, tuple):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_plain(v) for v in value]
    return value


def field_docs() -> dict[str, str]:
    """Each ``TrainConfig`` field's meaning, as its docstring's table says it (the command line's help)."""
    docs = {}
    for line in (TrainConfig.__doc__ or "").splitlines():
        cells = [cell.strip() for cell in line.strip().strip("|").split("|")]
        if line.strip().startswith("|") and len(cells) == 3 and cells[0] != "field" and not set(cells[0]) <= {"-"}:
            docs[cells[0]] = cells[2]
    return docs


def field_default(name: str) -> Any:
    """``TrainConfig``'s default of field ``name`` (the one source of every run setting's default)."""
    field_ = TrainConfig.__dataclass_fields__[name]
    return field_.default_factory() if field_.default_factory is not dataclasses.MISSING else field_.default
