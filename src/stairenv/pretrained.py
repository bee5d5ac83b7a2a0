"""Trained policies as plain numpy: ``load(env_id)`` or ``load_file(path)`` -> ``obs -> action``.

A policy file is an ``.npz`` of plain arrays (read with ``allow_pickle=False``: opening
one runs no code), needing neither torch nor Stable-Baselines3:

| array | meaning |
|---|---|
| ``obs_mean``, ``obs_var`` | the observation normaliser's running statistics (VecNormalize) |
| ``obs_clip``, ``obs_epsilon`` | ``clip((obs - mean) / sqrt(var + epsilon), -clip, clip)`` |
| ``weight_0``, ``bias_0``, ... | the actor's layers, ``x @ W.T + b``, ReLU between them; the last gives the action mean |
| ``config`` | a JSON string: env id, training settings, evaluation results (optional) |

The policy is deterministic: the Gaussian's mean, clipped to the action space [-1, 1],
exactly what ``PPO.predict(obs, deterministic=True)`` returns for the same network.
Policies shipped with the package live in ``stairenv/policies/<env id>.npz``.
"""

from __future__ import annotations

import json
import os
import zipfile
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

MAX_LAYERS = 16
MAX_WIDTH = 8192
#: what a policy file may unpack to (the zip directory's declared sizes, checked before reading)
MAX_UNPACKED_BYTES = 512 * 2**20


class PolicyFileError(ValueError):
    """A policy file that cannot be read as one (names the file and the fault)."""


class NumpyPolicy:
    """A deterministic MLP policy with observation normalisation, in numpy."""

    def __init__(self, weights: list[np.ndarray], biases: list[np.ndarray], obs_mean: np.ndarray,
                 obs_var: np.ndarray, obs_clip: float = 10.0, obs_epsilon: float = 1e-8,
                 config: dict[str, Any] | None = None) -> None:
        self.weights = [np.asarray(w, dtype=np.float64) for w in weights]
        self.biases = [np.asarray(b, dtype=np.float64) for b in biases]
        self.obs_mean = np.asarray(obs_mean, dtype=np.float64)
        self.obs_scale = 1.0 / np.sqrt(np.asarray(obs_var, dtype=np.float64) + obs_epsilon)
        self.obs_var, self.obs_clip, self.obs_epsilon = np.asarray(obs_var, dtype=np.float64), obs_clip, obs_epsilon
        self.config = dict(config or {})

    @property
    def obs_size(self) -> int:
        return self.weights[0].shape[1]

    @property
    def action_size(self) -> int:
        return self.weights[-1].shape[0]

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """One observation (obs_size,) or a batch (B, obs_size) -> actions in [-1, 1]."""
        x = np.clip((np.asarray(obs, dtype=np.float64) - self.obs_mean) * self.obs_scale, -self.obs_clip,
                    self.obs_clip)
        for weight, bias in zip(self.weights[:-1], self.biases[:-1]):
            x = np.maximum(x @ weight.T + bias, 0.0)
        return np.clip(x @ self.weights[-1].T + self.biases[-1], -1.0, 1.0).astype(np.float32)

    def save(self, path: str | os.PathLike) -> None:
        arrays = {f"weight_{i}": w for i, w in enumerate(self.weights)}
        arrays.update({f"bias_{i}": b for i, b in enumerate(self.biases)})
        np.savez_compressed(path, obs_mean=self.obs_mean, obs_var=self.obs_var, obs_clip=np.float64(self.obs_clip),
                            obs_epsilon=np.float64(self.obs_epsilon), config=np.array(json.dumps(self.config)),
                            **arrays)

    def __repr__(self) -> str:
        sizes = [self.obs_size] + [w.shape[0] for w in self.weights]
        return f"NumpyPolicy({' -> '.join(map(str, sizes))}, env={self.config.get('env_id')!r})"


def load_file(path: str | os.PathLike) -> NumpyPolicy:
    """A policy from an ``.npz`` written by ``NumpyPolicy.save``; ``PolicyFileError`` naming the file
    for anything else."""
    path = Path(path)
    try:
        with zipfile.ZipFile(path) as archive:
            unpacked = sum(member.file_size for member in archive.infolist())
        if unpacked > MAX_UNPACKED_BYTES:
            raise PolicyFileError(f"{path}: unpacks to {unpacked} bytes, more than {MAX_UNPACKED_BYTES}")
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile) as err:
        if isinstance(err, PolicyFileError):
            raise
        raise PolicyFileError(f"{path}: cannot read as a policy .npz ({type(err).__name__}: {err})") from err
    return _policy_from_arrays(path, arrays)


def _policy_from_arrays(path: Path, arrays: dict[str, np.ndarray]) -> NumpyPolicy:
    layers = 0
    while f"weight_{layers}" in arrays and layers <= MAX_LAYERS:
        layers += 1
    missing = [k for k in ("obs_mean", "obs_var", "obs_clip", "obs_epsilon") if k not in arrays]
    if missing or layers == 0 or layers > MAX_LAYERS:
        raise PolicyFileError(f"{path}: not a policy file (missing {missing or 'weight_0'}, or over {MAX_LAYERS} layers)")
    weights = [arrays[f"weight_{i}"] for i in range(layers)]
    biases = [arrays.get(f"bias_{i}") for i in range(layers)]
    size = arrays["obs_mean"].shape
    for i, (w, b) in enumerate(zip(weights, biases)):
        expected_in = size[0] if i == 0 else weights[i - 1].shape[0]
        if (w.ndim != 2 or b is None or b.shape != (w.shape[0],) or w.shape[1] != expected_in
                or max(w.shape) > MAX_WIDTH or w.dtype.kind != "f"):
            raise PolicyFileError(f"{path}: layer {i} has shape {w.shape} (bias {None if b is None else b.shape}), "
                                  f"which does not follow {expected_in} inputs")
    if len(size) != 1 or arrays["obs_var"].shape != size:
        raise PolicyFileError(f"{path}: obs_mean {size} and obs_var {arrays['obs_var'].shape} must be equal 1-D")
    values = [*weights, *biases, arrays["obs_mean"], arrays["obs_var"]]
    if not all(np.isfinite(v).all() for v in values) or (arrays["obs_var"] < 0).any():
        raise PolicyFileError(f"{path}: non-finite weights or statistics, or a negative variance")
    try:
        config = json.loads(str(arrays["config"])) if "config" in arrays else {}
    except json.JSONDecodeError as err:
        raise PolicyFileError(f"{path}: config is not JSON ({err})") from err
    return NumpyPolicy(weights, biases, arrays["obs_mean"], arrays["obs_var"], float(arrays["obs_clip"]),
                       float(arrays["obs_epsilon"]), config if isinstance(config, dict) else {})


def shipped_policy_path(env_id: str) -> Path:
    return Path(str(resources.files("stairenv"))) / "policies" / f"{env_id}.npz"


def load(env_id: str) -> NumpyPolicy:
    """The policy shipped with the package for ``env_id``."""
    path = shipped_policy_path(env_id)
    if not path.is_file():
        shipped = sorted(p.stem for p in path.parent.glob("*.npz")) if path.parent.is_dir() else []
        raise FileNotFoundError(f"no trained policy for {env_id!r} is shipped with stairenv (shipped: {shipped}); "
                                "train one with baselines/train_ppo.py and export it with baselines/export_policy.py")
    return load_file(path)


def from_sb3(model: Any, obs_normalizer: Any | None = None, config: dict[str, Any] | None = None) -> NumpyPolicy:
    """The actor of an SB3 ``PPO`` MlpPolicy (ReLU; Linear layers of ``mlp_extractor.policy_net`` then
    ``action_net``) and a ``VecNormalize``'s observation statistics, as a ``NumpyPolicy``."""
    policy = model.policy
    activations = {type(m).__name__ for m in policy.mlp_extractor.policy_net if not hasattr(m, "weight")}
    if activations - {"ReLU"}:
        raise ValueError(f"only ReLU policies can be exported, this one uses {sorted(activations)}")
    linear = [m for m in policy.mlp_extractor.policy_net if hasattr(m, "weight")] + [policy.action_net]
    weights = [m.weight.detach().cpu().numpy() for m in linear]
    biases = [m.bias.detach().cpu().numpy() for m in linear]
    size = weights[0].shape[1]
    if obs_normalizer is not None and obs_normalizer.norm_obs:
        rms = obs_normalizer.obs_rms
        mean, var = rms.mean, rms.var
        clip, epsilon = obs_normalizer.clip_obs, obs_normalizer.epsilon
    else:  # no normaliser: an identity map (clip far outside any observation)
        mean, var, clip, epsilon = np.zeros(size), np.ones(size), np.inf, 0.0
    return NumpyPolicy(weights, biases, mean, var, clip, epsilon, config)
