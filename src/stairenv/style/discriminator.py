"""The AMP discriminator (torch): an MLP on K-frame feature windows.

Two losses, as in the literature:

- ``"lsgan"`` (AMP paper): least squares with targets +1 (reference) and -1
  (agent); style reward ``max(0, 1 - 0.25 (d - 1)^2)``.
- ``"bce"`` (public implementations): binary cross-entropy on logits; style
  reward ``-log(max(1 - sigmoid(d), 1e-4))``.

Both add a gradient penalty on reference samples
(``grad_penalty * E ||grad_x d||^2``), a logit regularisation on the output
layer's weights (``logit_reg * ||W_out||^2``) and weight decay on every weight
(``weight_decay * sum ||W||^2``). Inputs are normalised by running statistics
of everything the discriminator has been trained on (clipped to +-5).

Scoring (``logits``, ``reward``) runs one of the back-ends of
:mod:`stairenv.style.scoring` (``scoring=``: "auto", "numba", "numba-parallel", "torch",
"bf16") on a cached plan (float32 normaliser constants, views of the weights), rebuilt only
when a parameter or statistic changed. ``freeze_scoring()`` snapshots the plan (copies), so
that training may change the parameters in another thread while scoring goes on
(``AMPStyleReward(background_training=True)``). On a device other than the CPU (``device=``)
scoring and training run torch's kernels there ("bf16" scoring stays bfloat16): the numba
kernels and oneDNN are CPU-only. Training's matrix products go through oneDNN
where it works (:mod:`stairenv.style.onednn`), weight decay and logit regularisation add their
gradients in place, and Adam is the fused kernel; all of it float32, equal to the plain torch
path up to rounding (tests compare them). ``AMPDiscriminator(..., backend="aten")`` trains with
plain torch kernels; ``STAIRENV_AMP_BACKEND=aten`` does so for every discriminator left at
"auto". Why and how fast: ``docs/amp-speed.md``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import torch
from torch import nn

from stairenv.style.onednn import BACKENDS, linear, onednn_available, use_onednn
from stairenv.style.scoring import SCORERS, plan_logits
from stairenv.validation import check_choice, check_number

__all__ = [
    "BACKENDS",
    "LOSSES",
    "SCORERS",
    "AMPDiscriminator",
    "DiscriminatorConfig",
    "ReplayBuffer",
    "RunningNorm",
    "cpu_tensors",
    "onednn_available",
    "plain_config",
    "plain_values",
    "style_reward",
]

LOSSES = ("lsgan", "bce")


@dataclass(frozen=True)
class DiscriminatorConfig:
    hidden: tuple[int, ...] = (1024, 512)
    loss: str = "lsgan"
    learning_rate: float = 1e-4
    grad_penalty: float = 5.0
    logit_reg: float = 0.01
    weight_decay: float = 1e-4
    batch_size: int = 256
    replay_size: int = 100_000
    # Reference windows the gradient penalty is estimated on: None = the whole
    # reference minibatch (the paper); n < batch_size = the first n of its
    # (randomly drawn) windows, an unbiased but noisier estimate that saves most
    # of the double backward's cost.
    grad_penalty_batch: int | None = None
    # Instance noise: Gaussian noise of this std added to every normalised training input,
    # reference and agent alike (0 = none, the paper); blurring both classes keeps the
    # discriminator from separating them on tiny feature differences (docs/amp-speed.md).
    # Scoring sees clean inputs.
    input_noise: float = 0.0

    def __post_init__(self) -> None:
        check_choice("loss", self.loss, LOSSES)
        if not self.hidden or any(int(h) < 1 for h in self.hidden):
            raise ValueError(f"hidden must be a non-empty list of positive layer sizes, got {self.hidden!r}")
        object.__setattr__(self, "hidden", tuple(int(h) for h in self.hidden))
        check_number("learning_rate", self.learning_rate, 0.0, 1.0, low_open=True)
        for name in ("grad_penalty", "logit_reg", "weight_decay"):
            check_number(name, getattr(self, name), 0.0)
        check_number("batch_size", self.batch_size, 1, 1 << 20)
        check_number("replay_size", self.replay_size, 1, 1 << 30)
        check_number("input_noise", self.input_noise, 0.0, 10.0)
        if self.grad_penalty_batch is not None:
            check_number("grad_penalty_batch", self.grad_penalty_batch, 1, 1 << 20)
            object.__setattr__(self, "grad_penalty_batch", int(self.grad_penalty_batch))


def plain_values(value):
    """``value`` with every numpy scalar in its dicts, lists and tuples turned into a Python number:
    saved, a numpy scalar is a pickled numpy object, which a weights-only load refuses."""
    if isinstance(value, dict):
        return {key: plain_values(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return type(value)(plain_values(item) for item in value)
    return value.item() if isinstance(value, np.generic) else value


def cpu_tensors(value):
    """``value`` with every tensor in its dicts, lists and tuples on the CPU (the same tensor where it is
    there already): what is saved then loads on any machine, whatever device trained it."""
    if isinstance(value, dict):
        return {key: cpu_tensors(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return type(value)(cpu_tensors(item) for item in value)
    return value.cpu() if isinstance(value, torch.Tensor) else value


def plain_config(config: DiscriminatorConfig) -> dict:
    """The config as a dict of Python numbers, strings and tuples."""
    return plain_values(asdict(config))


def _adam(params: list[torch.Tensor], lr: float) -> torch.optim.Adam:
    """Adam with the fused kernel where this torch has it for CPU tensors (>= 2.4): the same
    update in one pass over the parameters, ~10x faster than the default on a CPU."""
    try:
        return torch.optim.Adam(params, lr=lr, fused=True)
    except (RuntimeError, TypeError, ValueError):
        return torch.optim.Adam(params, lr=lr)


@dataclass(frozen=True)
class _FrozenLinear:
    """A snapshot of a linear layer's parameters (what scoring plans read of a layer)."""

    weight: torch.Tensor
    bias: torch.Tensor


def _numba_layers(linears: list, relu: list[bool]) -> list | None:
    """numpy views of the layers' float32 parameters for the numba kernels; None off the CPU."""
    if linears[0].weight.device.type != "cpu":
        return None
    return [(layer.weight.detach().numpy(), layer.bias.detach().numpy(), r) for layer, r in zip(linears, relu)]


class RunningNorm(nn.Module):
    """Running mean and variance of the inputs (parallel-update formula), saved with the model."""

    def __init__(self, dim: int, clip: float = 5.0) -> None:
        super().__init__()
        self.clip = clip
        self.register_buffer("mean", torch.zeros(dim, dtype=torch.float64))
        self.register_buffer("var", torch.ones(dim, dtype=torch.float64))
        self.register_buffer("count", torch.tensor(1e-4, dtype=torch.float64))

    @torch.no_grad()
    def update(self, x: torch.Tensor, parallel=None) -> None:
        """Take a batch into the statistics (with ``parallel``, a data-parallel run's collectives: every
        rank's batch together)."""
        x = x.to(torch.float64)
        batch_mean, batch_var, n = x.mean(0), x.var(0, unbiased=False), x.shape[0]
        if parallel is not None:
            batch_mean, batch_var, n = parallel.moments(batch_mean, batch_var, n)
        delta = batch_mean - self.mean
        total = self.count + n
        self.var.copy_((self.var * self.count + batch_var * n + delta.square() * self.count * n / total) / total)
        self.mean += delta * n / total
        self.count.copy_(total)  # in place: the buffers keep their identity (scoring caches key on them)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        std = torch.sqrt(self.var + 1e-8).to(x.dtype)
        return torch.clamp((x - self.mean.to(x.dtype)) / std, -self.clip, self.clip)


class AMPDiscriminator(nn.Module):
    def __init__(self, input_dim: int, config: DiscriminatorConfig = DiscriminatorConfig(),
                 backend: str = "auto", scoring: str = "auto", device: str | torch.device = "cpu") -> None:
        super().__init__()
        self.config = config
        self.input_dim = int(input_dim)
        self.norm = RunningNorm(self.input_dim)
        layers: list[nn.Module] = []
        size = self.input_dim
        for hidden in config.hidden:
            layers += [nn.Linear(size, hidden), nn.ReLU()]
            size = hidden
        self.trunk = nn.Sequential(*layers)
        self.logit = nn.Linear(size, 1)
        nn.init.uniform_(self.logit.weight, -1.0, 1.0)
        self.logit.weight.data *= 0.01  # small initial logits: rewards start near the middle
        nn.init.zeros_(self.logit.bias)
        self.backend = backend
        self.to(device)    # before the optimiser, which then holds the parameters where they live
        self.onednn = use_onednn(backend) and self.device.type == "cpu"
        self.scoring = check_choice("scoring", scoring, SCORERS)
        self.optimizer = _adam(list(self.parameters()), config.learning_rate)
        self._plan: dict | None = None  # scoring's cache, see _inference_plan
        self._frozen: dict | None = None  # a snapshot plan that scoring uses while set, see freeze_scoring
        # "numba-parallel": threads to split a layer over (None: numba's); 1 while training runs beside.
        self.scoring_threads: int | None = None
        self.noise_generator = torch.Generator().manual_seed(0)  # instance noise: its own stream
        # A data-parallel run's collectives (``stairenv.training.distributed``, set by the trainer):
        # ``update`` then merges the input statistics and averages the gradients over the ranks.
        self.parallel = None

    @property
    def device(self) -> torch.device:
        return self.logit.weight.device

    @property
    def linears(self) -> list[nn.Linear]:
        return [m for m in self.trunk if isinstance(m, nn.Linear)] + [self.logit]

    def _mlp(self, x_normalised: torch.Tensor) -> torch.Tensor:
        layers = self.linears
        for layer in layers[:-1]:
            x_normalised = torch.relu(linear(x_normalised, layer, self.onednn))
        return linear(x_normalised, layers[-1], self.onednn).squeeze(-1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Logits d(x) of raw feature windows (normalised inside): (N,)."""
        return self._mlp(self.norm(x))

    # --- scoring ------------------------------------------------------------------
    def load_state_dict(self, *args, **kwargs):
        self._plan = self._frozen = None
        return super().load_state_dict(*args, **kwargs)

    def _apply(self, *args, **kwargs):
        self._plan = self._frozen = None
        return super()._apply(*args, **kwargs)

    def _inference_plan(self) -> dict:
        """Normaliser constants and layers for scoring, rebuilt when a parameter or statistic
        changed: their version counters, which training, in-place edits and
        ``load_state_dict`` all bump, are compared on every call."""
        plan = self._plan
        if plan is not None and plan["versions"] == tuple(t._version for t in plan["tracked"]):
            return plan
        linears = self.linears
        tracked = (self.norm.mean, self.norm.var, *(t for layer in linears for t in (layer.weight, layer.bias)))
        with torch.inference_mode():
            mean = self.norm.mean.to(torch.float32)
            std = torch.sqrt(self.norm.var + 1e-8).to(torch.float32)
        relu = [True] * (len(linears) - 1) + [False]
        self._plan = {
            "tracked": tracked, "versions": tuple(t._version for t in tracked), "mean": mean, "std": std,
            "numba": _numba_layers(linears, relu),
            "torch": None,  # built on first use: hidden weights pre-packed for oneDNN
            "linears": linears, "relu": relu,
        }
        return self._plan

    def freeze_scoring(self) -> None:
        """Score with a copy of the current parameters and statistics until
        :meth:`unfreeze_scoring` (or the next ``freeze_scoring``): training may then change
        them, in this thread or another, without touching what scoring reads."""
        with torch.no_grad():
            self._frozen = None
            live = self._inference_plan()
            # Plain copies of the tensors (an nn.Linear would first initialise weights of its own).
            linears = [_FrozenLinear(layer.weight.detach().clone(), layer.bias.detach().clone())
                       for layer in live["linears"]]
            self._frozen = {
                "tracked": (), "versions": (), "mean": live["mean"].clone(), "std": live["std"].clone(),
                "numba": _numba_layers(linears, live["relu"]),
                "torch": None, "linears": linears, "relu": live["relu"],
            }

    def unfreeze_scoring(self) -> None:
        """Score with the live parameters again."""
        self._frozen = None

    def scoring_plan(self) -> dict:
        """The plan scoring uses now: the snapshot while frozen, else the live one. A new
        dict whenever what it holds changed (callers may compare plans by identity)."""
        return self._frozen if self._frozen is not None else self._inference_plan()

    def logits(self, features: np.ndarray) -> np.ndarray:
        """Logits of raw feature windows (N, input_dim), without autograd: (N,).

        Equal to ``self(x)`` up to float32 rounding. Small batches (a vectorised step) run a
        compiled single-threaded numba kernel: no torch dispatch and no BLAS threads, which on
        a CPU shared with env stepping costs less per call than torch's kernels, whose code and
        data the envs evict between calls. Large batches run torch's (oneDNN) kernels in
        ``torch.inference_mode``. ``scoring="numba"`` or ``"torch"`` fixes either; ``"bf16"``
        runs torch in bfloat16 (normalisation in float32). Off the CPU: torch's kernels on the device
        ("bf16" there too), the windows copied to it and the logits back."""
        x = np.ascontiguousarray(features, dtype=np.float32)
        if x.ndim != 2 or x.shape[1] != self.input_dim:
            raise ValueError(f"features must be (N, {self.input_dim}), got {tuple(x.shape)}")
        if len(x) == 0:
            return np.zeros(0, dtype=np.float32)
        scoring = self.scoring
        if self.device.type != "cpu" and scoring != "bf16":    # the numba kernels read host memory
            scoring = "torch"
        return plan_logits(x, self.scoring_plan(), self.norm.clip, scoring, self.onednn, self.scoring_threads)

    def reward(self, features: np.ndarray) -> np.ndarray:
        """Style reward of K-frame feature windows (N, input_dim): (N,)."""
        return style_reward(self.logits(features), self.config.loss)

    # --- training -----------------------------------------------------------------
    def update(self, reference: np.ndarray, agent: np.ndarray) -> dict[str, float]:
        """One gradient step on a batch of reference and agent windows; returns training statistics."""
        cfg = self.config
        ref = torch.as_tensor(reference, dtype=torch.float32, device=self.device)
        fake = torch.as_tensor(agent, dtype=torch.float32, device=self.device)
        self.norm.update(torch.cat((ref, fake)), self.parallel)
        # The gradient penalty is taken with respect to the normalised inputs, which the MLP sees,
        # on the whole reference batch (paper) or its first grad_penalty_batch windows.
        ref_n, fake_n = self.norm(ref), self.norm(fake)
        if cfg.input_noise > 0.0:
            g = self.noise_generator    # a CPU generator: the same noise on every device
            ref_n = ref_n + cfg.input_noise * torch.randn(ref_n.shape, generator=g).to(self.device)
            fake_n = fake_n + cfg.input_noise * torch.randn(fake_n.shape, generator=g).to(self.device)
        gp_n = len(ref_n) if cfg.grad_penalty_batch is None else min(cfg.grad_penalty_batch, len(ref_n))
        if cfg.grad_penalty <= 0.0:
            gp_n = 0
        gp_in = ref_n[:gp_n].requires_grad_(True)
        if gp_n == len(ref_n):  # one pass for the penalised reference windows, one for the agent's
            d_gp = self._mlp(gp_in)
            d_ref, d_fake = d_gp, self._mlp(fake_n)
        else:
            d_gp = self._mlp(gp_in)
            d_rest = self._mlp(torch.cat((ref_n[gp_n:], fake_n)))
            d_ref, d_fake = torch.cat((d_gp, d_rest[: len(ref_n) - gp_n])), d_rest[len(ref_n) - gp_n:]
        if cfg.loss == "lsgan":
            loss_ref = 0.5 * torch.mean((d_ref - 1.0) ** 2)
            loss_fake = 0.5 * torch.mean((d_fake + 1.0) ** 2)
        else:
            bce = nn.functional.binary_cross_entropy_with_logits
            loss_ref = bce(d_ref, torch.ones_like(d_ref))
            loss_fake = bce(d_fake, torch.zeros_like(d_fake))
        if gp_n > 0:
            (grad,) = torch.autograd.grad(d_gp.sum(), gp_in, create_graph=True)
            penalty = grad.square().sum(-1).mean()
        else:
            penalty = torch.zeros((), device=self.device)
        loss = loss_ref + loss_fake + cfg.grad_penalty * penalty
        self.optimizer.zero_grad(set_to_none=True)
        loss.backward()
        # Weight decay (every weight) and logit regularisation (the output layer's weights) are
        # quadratic: their gradients 2 c W are added in place rather than through autograd.
        weights = [layer.weight for layer in self.linears]
        with torch.no_grad():
            decay = sum(float(torch.dot(w.view(-1), w.view(-1))) for w in weights)
            logit_sq = float(torch.dot(self.logit.weight.view(-1), self.logit.weight.view(-1)))
            for w in weights:
                w.grad.add_(w, alpha=2.0 * cfg.weight_decay)
            self.logit.weight.grad.add_(self.logit.weight, alpha=2.0 * cfg.logit_reg)
        if self.parallel is not None:
            self.parallel.average_gradients(self.parameters())
        self.optimizer.step()
        # Both losses separate the classes at logit 0.
        with torch.no_grad():
            accuracy = 0.5 * ((d_ref > 0).float().mean() + (d_fake < 0).float().mean()).item()
        return {
            "disc_loss": loss.item() + cfg.logit_reg * logit_sq + cfg.weight_decay * decay,
            "disc_grad_penalty": penalty.item(),
            "disc_ref_logit": d_ref.mean().item(),
            "disc_agent_logit": d_fake.mean().item(),
            "disc_accuracy": accuracy,
        }

    def state(self) -> dict:
        """Tensors (on the CPU) and plain values only, so ``torch.load(weights_only=True)`` reads it back
        on any machine."""
        optimizer = plain_values(self.optimizer.state_dict())  # its lr is the config's, maybe numpy
        return {"config": plain_config(self.config), "input_dim": int(self.input_dim),
                "model": cpu_tensors(self.state_dict()), "optimizer": cpu_tensors(optimizer)}

    @classmethod
    def from_state(cls, state: dict, backend: str = "auto", device: str | torch.device = "cpu",
                   scoring: str = "auto") -> "AMPDiscriminator":
        """The discriminator ``state()`` wrote, on ``device`` (its optimiser's state moved there too), scoring
        with ``scoring``."""
        config = dict(state["config"])
        config["hidden"] = tuple(config["hidden"])
        disc = cls(state["input_dim"], DiscriminatorConfig(**config), backend=backend, scoring=scoring, device=device)
        disc.load_state_dict(state["model"])
        disc.optimizer.load_state_dict(state["optimizer"])
        return disc


def style_reward(logits: np.ndarray, loss: str) -> np.ndarray:
    """The style reward of discriminator logits for the given loss."""
    logits = np.asarray(logits, dtype=np.float64)
    if loss == "lsgan":
        return np.maximum(0.0, 1.0 - 0.25 * np.square(logits - 1.0))
    if loss == "bce":
        prob = 1.0 / (1.0 + np.exp(-logits))
        return -np.log(np.maximum(1.0 - prob, 1e-4))
    raise ValueError(f"loss must be one of {list(LOSSES)}, got {loss!r}")


class ReplayBuffer:
    """A fixed-size ring buffer of agent feature windows."""

    def __init__(self, capacity: int, dim: int) -> None:
        self.data = np.zeros((int(capacity), dim), dtype=np.float32)
        self.size = 0
        self.next = 0

    def __len__(self) -> int:
        return self.size

    def add(self, batch: np.ndarray) -> None:
        batch = np.asarray(batch, dtype=np.float32)[-len(self.data):]
        n = len(batch)
        end = self.next + n
        if end <= len(self.data):
            self.data[self.next:end] = batch
        else:
            split = len(self.data) - self.next
            self.data[self.next:] = batch[:split]
            self.data[: n - split] = batch[split:]
        self.next = end % len(self.data)
        self.size = min(self.size + n, len(self.data))

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        if self.size == 0:
            raise ValueError("the replay buffer is empty")
        return self.data[rng.integers(0, self.size, n)]
