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
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import torch
from torch import nn

from stairenv.validation import check_choice, check_number

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


class RunningNorm(nn.Module):
    """Running mean and variance of the inputs (parallel-update formula), saved with the model."""

    def __init__(self, dim: int, clip: float = 5.0) -> None:
        super().__init__()
        self.clip = clip
        self.register_buffer("mean", torch.zeros(dim, dtype=torch.float64))
        self.register_buffer("var", torch.ones(dim, dtype=torch.float64))
        self.register_buffer("count", torch.tensor(1e-4, dtype=torch.float64))

    @torch.no_grad()
    def update(self, x: torch.Tensor) -> None:
        x = x.to(torch.float64)
        batch_mean, batch_var, n = x.mean(0), x.var(0, unbiased=False), x.shape[0]
        delta = batch_mean - self.mean
        total = self.count + n
        self.mean += delta * n / total
        self.var = (self.var * self.count + batch_var * n + delta.square() * self.count * n / total) / total
        self.count = total

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        std = torch.sqrt(self.var + 1e-8).to(x.dtype)
        return torch.clamp((x - self.mean.to(x.dtype)) / std, -self.clip, self.clip)


class AMPDiscriminator(nn.Module):
    def __init__(self, input_dim: int, config: DiscriminatorConfig = DiscriminatorConfig()) -> None:
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
        self.optimizer = torch.optim.Adam(self.parameters(), lr=config.learning_rate)

    def _mlp(self, x_normalised: torch.Tensor) -> torch.Tensor:
        return self.logit(self.trunk(x_normalised)).squeeze(-1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Logits d(x) of raw feature windows (normalised inside): (N,)."""
        return self._mlp(self.norm(x))

    @torch.inference_mode()
    def logits(self, features: np.ndarray) -> np.ndarray:
        """Logits of raw feature windows (N, input_dim), without autograd: (N,)."""
        return self(torch.as_tensor(features, dtype=torch.float32)).numpy()

    def reward(self, features: np.ndarray) -> np.ndarray:
        """Style reward of K-frame feature windows (N, input_dim): (N,)."""
        return style_reward(self.logits(features), self.config.loss)

    def update(self, reference: np.ndarray, agent: np.ndarray) -> dict[str, float]:
        """One gradient step on a batch of reference and agent windows; returns training statistics."""
        ref = torch.as_tensor(reference, dtype=torch.float32)
        fake = torch.as_tensor(agent, dtype=torch.float32)
        self.norm.update(torch.cat((ref, fake)))
        # The gradient penalty is taken with respect to the normalised inputs, which the MLP sees.
        ref_n = self.norm(ref).requires_grad_(True)
        d_ref = self._mlp(ref_n)
        d_fake = self._mlp(self.norm(fake))
        if self.config.loss == "lsgan":
            loss_ref = 0.5 * torch.mean((d_ref - 1.0) ** 2)
            loss_fake = 0.5 * torch.mean((d_fake + 1.0) ** 2)
        else:
            bce = nn.functional.binary_cross_entropy_with_logits
            loss_ref = bce(d_ref, torch.ones_like(d_ref))
            loss_fake = bce(d_fake, torch.zeros_like(d_fake))
        (grad,) = torch.autograd.grad(d_ref.sum(), ref_n, create_graph=True)
        penalty = grad.square().sum(-1).mean()
        weights = [m.weight for m in self.trunk if isinstance(m, nn.Linear)] + [self.logit.weight]
        decay = sum(w.square().sum() for w in weights)
        loss = (loss_ref + loss_fake + self.config.grad_penalty * penalty
                + self.config.logit_reg * self.logit.weight.square().sum()
                + self.config.weight_decay * decay)
        self.optimizer.zero_grad(set_to_none=True)
        loss.backward()
        self.optimizer.step()
        # Both losses separate the classes at logit 0.
        return {
            "disc_loss": loss.item(),
            "disc_grad_penalty": penalty.item(),
            "disc_ref_logit": d_ref.mean().item(),
            "disc_agent_logit": d_fake.mean().item(),
            "disc_accuracy": 0.5 * ((d_ref > 0).float().mean() + (d_fake < 0).float().mean()).item(),
        }

    def state(self) -> dict:
        return {"config": asdict(self.config), "input_dim": self.input_dim, "model": self.state_dict(),
                "optimizer": self.optimizer.state_dict()}

    @classmethod
    def from_state(cls, state: dict) -> "AMPDiscriminator":
        config = state["config"]
        config["hidden"] = tuple(config["hidden"])
        disc = cls(state["input_dim"], DiscriminatorConfig(**config))
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
