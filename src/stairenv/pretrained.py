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
Policies shipped with the package live in ``stairenv/policies/<env id>.npz``; an id whose preset
(``envs/<id>.toml``) names ``policy = "<other id>"`` runs that id's policy (the same controller in
another task, as ``PlaMoScene-v0`` runs ``PlaMo-v0``'s).
"""

from __future__ import annotations

import json
import os
import re
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


def load_file(path: str | os.PathLike, env: Any | None = None) -> NumpyPolicy:
    """A policy from an ``.npz`` written by ``NumpyPolicy.save``; ``PolicyFileError`` naming the file
    and the field for anything else.

    Every member's ``.npy`` header is read first: its dtype, and the bytes its shape declares must
    match the member's real size, so nothing is allocated for a shape the file does not hold. With
    ``env`` (an env or anything with ``observation_space`` and ``action_space``), the policy's
    observation and action sizes must be the env's.
    """
    path = Path(path)
    arrays = _read_arrays(path)
    policy = _policy_from_arrays(path, arrays)
    if env is not None:
        check_sizes(policy, env, path)
    return policy


def check_sizes(policy: NumpyPolicy, env: Any, path: str | os.PathLike = "policy") -> None:
    """``PolicyFileError`` unless ``policy`` maps the env's observations to its actions."""
    expected = (tuple(env.observation_space.shape), tuple(env.action_space.shape))
    if ((policy.obs_size,), (policy.action_size,)) != expected:
        raise PolicyFileError(f"{path}: the policy maps ({policy.obs_size},) observations (obs_mean, weight_0) to "
                              f"({policy.action_size},) actions (weight_{len(policy.weights) - 1}); the env has "
                              f"{expected[0]} and {expected[1]}")


#: how far (largest absolute difference) an env's embedding of a caption may lie from the one a policy
#: recorded: MiniLM's vectors differ by ~1e-7 from CPU to CPU, another encoder's or projection's by ~0.1
TEXT_EMBEDDING_TOLERANCE = 1e-3


def check_text_encoder(policy: NumpyPolicy, env: Any, path: str | os.PathLike = "policy") -> None:
    """``PolicyFileError`` if ``policy`` was trained on another text encoder's embeddings than the
    ones ``env`` observes: its config's ``text_encoder_id`` (the encoder by what it is: the model and
    the projection file's digest) must be the env's, and the env's embedding of every caption it
    recorded in ``text_embeddings`` must match the recorded one within ``TEXT_EMBEDDING_TOLERANCE``
    (never compared bit for bit: another machine computes other low bits). Policies without a
    ``text_encoder_id`` pass."""
    trained_with = policy.config.get("text_encoder_id")
    if trained_with is None:
        return
    unwrapped = getattr(env, "unwrapped", env)
    here = getattr(unwrapped, "text_encoder_id", None)
    if trained_with != here:
        legacy = ""
        if re.fullmatch(r".+\+svd\d+-[0-9a-f]{12}", str(trained_with)):
            legacy = (". An id like this one from before 2026-12-07 named a projection fitted at run time (its "
                      "digest differs from machine to machine): export the policy again from its checkpoint "
                      "(baselines/export_policy.py) to record the shipped projection's id")
        raise PolicyFileError(f"{path}: trained on the text embeddings of {trained_with!r}; the env embeds with "
                              f"{here!r} (pip install 'stairenv[sims]' for the MiniLM encoder){legacy}")
    recorded = policy.config.get("text_embeddings")
    if recorded is None:
        return
    dim = getattr(unwrapped, "text_dim", None)
    if not (isinstance(recorded, dict) and all(
            isinstance(text, str) and isinstance(vector, list) and len(vector) == dim
            and all(isinstance(x, (int, float)) for x in vector) for text, vector in recorded.items())):
        raise PolicyFileError(f"{path}: config's text_embeddings must map captions to lists of {dim} numbers")
    from stairenv.screenplays.embeddings import embeddings_match

    for text, vector in recorded.items():
        mine = unwrapped.embed_text(text)
        if not embeddings_match(mine, vector, TEXT_EMBEDDING_TOLERANCE):
            gap = float(np.max(np.abs(np.asarray(mine) - np.asarray(vector, dtype=np.float64))))
            shown = text if len(text) <= 60 else text[:57] + "..."
            raise PolicyFileError(f"{path}: the env ({here}) embeds the caption {shown!r} up to {gap:.3g} away from "
                                  f"the embedding the policy was trained on (tolerance {TEXT_EMBEDDING_TOLERANCE:g})")


def record_text_encoder(policy: NumpyPolicy, env: Any) -> None:
    """Write into ``policy.config`` what a text-conditioned ``env`` (the one it was trained in, with its
    captions) embeds with: ``text_encoder_id`` and ``text_embeddings``, every caption's embedding, which
    :func:`check_text_encoder` compares within a tolerance wherever the policy is loaded."""
    unwrapped = getattr(env, "unwrapped", env)
    policy.config["text_encoder_id"] = unwrapped.text_encoder_id
    texts = sorted({caption for _, caption in unwrapped.captions})
    policy.config["text_embeddings"] = {text: [float(x) for x in unwrapped.embed_text(text)] for text in texts}


def trained_captions(policy: NumpyPolicy, path: str | os.PathLike = "policy") -> tuple[tuple[str, str], ...] | None:
    """The (style, caption) pairs a text-conditioned policy's env drew in training (its config's
    ``training.env_kwargs.captions``), or None where it recorded none (the env's own captions):
    ``PolicyFileError`` if the record is not a list of pairs of strings."""
    training = policy.config.get("training")
    env_kwargs = training.get("env_kwargs") if isinstance(training, dict) else None
    captions = env_kwargs.get("captions") if isinstance(env_kwargs, dict) else None
    if captions is None:
        return None
    if not (isinstance(captions, list) and captions and all(
            isinstance(pair, list) and len(pair) == 2 and all(isinstance(x, str) for x in pair) for pair in captions)):
        raise PolicyFileError(f"{path}: training.env_kwargs.captions must be a list of [style, caption] strings")
    return tuple((style, caption) for style, caption in captions)


def with_trained_captions(env_kwargs: dict[str, Any], policy: Any) -> dict[str, Any]:
    """``env_kwargs`` with ``captions`` set to those ``policy`` recorded from its training (a text-conditioned
    env then draws them), or ``env_kwargs`` itself where it names captions already or the policy recorded
    none (not a :class:`NumpyPolicy`, or trained on the env's own)."""
    captions = trained_captions(policy) if isinstance(policy, NumpyPolicy) and "captions" not in env_kwargs else None
    return env_kwargs if captions is None else {**env_kwargs, "captions": captions}


#: a member over this many bytes may unpack to at most MAX_COMPRESSION_RATIO times its packed size
#: (trained weights pack about 2:1, a config's text about 8:1; a zip bomb about 1000:1)
RATIO_CHECKED_BYTES = 4 * 2**20
MAX_COMPRESSION_RATIO = 50
#: the bytes a member is read in, straight into its array (no second copy of the whole member)
READ_CHUNK_BYTES = 2**20


def _read_arrays(path: Path) -> dict[str, np.ndarray]:
    from numpy.lib import format as npy

    arrays: dict[str, np.ndarray] = {}
    try:
        with zipfile.ZipFile(path) as archive:
            members = archive.infolist()
            unpacked = sum(member.file_size for member in members)
            if unpacked > MAX_UNPACKED_BYTES:
                raise PolicyFileError(f"{path}: unpacks to {unpacked} bytes, more than {MAX_UNPACKED_BYTES}")
            for member in members:  # a zip bomb under the limit: refused before anything is unpacked
                if (member.file_size > RATIO_CHECKED_BYTES
                        and member.file_size > MAX_COMPRESSION_RATIO * max(member.compress_size, 1)):
                    raise PolicyFileError(
                        f"{path}: member {member.filename!r} unpacks {member.compress_size} bytes to "
                        f"{member.file_size}, over {MAX_COMPRESSION_RATIO} times (no policy's arrays pack so tightly)")
            if len(members) > 4 * MAX_LAYERS + 8:
                raise PolicyFileError(f"{path}: {len(members)} members, more than a policy file has")
            for member in members:
                name = member.filename[:-4] if member.filename.endswith(".npy") else member.filename
                if not member.filename.endswith(".npy") or name in arrays:
                    raise PolicyFileError(f"{path}: member {member.filename!r} is not one .npy array")
                with archive.open(member) as fp:
                    version = npy.read_magic(fp)
                    if version not in ((1, 0), (2, 0)):
                        raise PolicyFileError(f"{path}: {name}: .npy format version {version} is not read")
                    reader = npy.read_array_header_1_0 if version == (1, 0) else npy.read_array_header_2_0
                    shape, fortran, dtype = reader(fp)
                    if dtype.hasobject or dtype.kind not in "fiuUS" or dtype.subdtype is not None or dtype.names:
                        raise PolicyFileError(f"{path}: {name} has dtype {dtype}, not numbers or text")
                    declared = int(np.prod(shape, dtype=object)) * dtype.itemsize  # python ints: no overflow
                    header = fp.tell()
                    if declared != member.file_size - header:
                        raise PolicyFileError(f"{path}: {name}: its header declares shape {shape} of {dtype} "
                                              f"({declared} bytes) but the file holds {member.file_size - header}")
                    flat = np.empty(int(np.prod(shape, dtype=object)), dtype=dtype)  # read into, a chunk at a time
                    into, filled = flat.view(np.uint8), 0
                    while filled < declared:
                        chunk = fp.read(min(READ_CHUNK_BYTES, declared - filled))
                        if not chunk:
                            break
                        into[filled:filled + len(chunk)] = np.frombuffer(chunk, dtype=np.uint8)
                        filled += len(chunk)
                if filled != declared:
                    raise PolicyFileError(f"{path}: {name} is truncated")
                arrays[name] = flat.reshape(shape, order="F" if fortran else "C")
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, RuntimeError) as err:
        if isinstance(err, PolicyFileError):
            raise
        raise PolicyFileError(f"{path}: cannot read as a policy .npz ({type(err).__name__}: {err})") from err
    return arrays


def _numbers(path: Path, name: str, value: np.ndarray) -> np.ndarray:
    if value.dtype.kind not in "fiu":
        raise PolicyFileError(f"{path}: {name} has dtype {value.dtype}, not numbers")
    return value.astype(np.float64)


def _scalar(path: Path, name: str, value: np.ndarray) -> float:
    if value.size != 1 or value.ndim > 1:
        raise PolicyFileError(f"{path}: {name} must be one number, got shape {value.shape}")
    number = float(_numbers(path, name, value).reshape(()))
    if np.isnan(number):
        raise PolicyFileError(f"{path}: {name} is NaN")
    return number


#: the largest normalised input the output bound assumes when ``obs_clip`` is infinite (no normaliser)
UNCLIPPED_INPUT_BOUND = 1e6
#: the largest value any layer may reach for inputs within the clip (far below float64's overflow)
MAX_ACTIVATION_BOUND = 1e100


def _layer(path: Path, i: int, arrays: dict[str, np.ndarray], inputs: int) -> tuple[np.ndarray, np.ndarray]:
    """``weight_i`` (outputs, inputs) and ``bias_i`` (outputs,) as float64, ``inputs`` being the size of the
    previous layer's output (the observation's, from ``obs_mean``, for layer 0)."""
    w, b = arrays[f"weight_{i}"], arrays.get(f"bias_{i}")
    source = "the observation size (obs_mean)" if i == 0 else f"weight_{i - 1}'s outputs"
    if w.ndim != 2 or w.shape[1] != inputs:
        raise PolicyFileError(f"{path}: weight_{i} has shape {w.shape}; expected (outputs, {inputs}), {inputs} "
                              f"being {source}")
    if not 0 < w.shape[0] <= MAX_WIDTH:
        raise PolicyFileError(f"{path}: weight_{i} has {w.shape[0]} outputs; expected 1..{MAX_WIDTH}")
    if w.dtype.kind != "f":
        raise PolicyFileError(f"{path}: weight_{i} has dtype {w.dtype}, not floats")
    if b is None:
        raise PolicyFileError(f"{path}: bias_{i} missing (weight_{i} has no bias)")
    if b.shape != (w.shape[0],):
        raise PolicyFileError(f"{path}: bias_{i} has shape {b.shape}; expected ({w.shape[0]},), one per output "
                              f"of weight_{i}")
    return w.astype(np.float64), _numbers(path, f"bias_{i}", b)


def _policy_from_arrays(path: Path, arrays: dict[str, np.ndarray]) -> NumpyPolicy:
    layers = 0
    while f"weight_{layers}" in arrays and layers <= MAX_LAYERS:
        layers += 1
    missing = [k for k in ("obs_mean", "obs_var", "obs_clip", "obs_epsilon", "weight_0") if k not in arrays]
    if missing:
        raise PolicyFileError(f"{path}: not a policy file: {', '.join(missing)} missing (written by NumpyPolicy.save?)")
    if layers > MAX_LAYERS:
        raise PolicyFileError(f"{path}: weight_{MAX_LAYERS} present; a policy has at most {MAX_LAYERS} layers")
    known = {"obs_mean", "obs_var", "obs_clip", "obs_epsilon", "config"}
    known |= {f"{kind}_{i}" for kind in ("weight", "bias") for i in range(layers)}
    extra = sorted(set(arrays) - known)
    if extra:  # a layer after a gap (weight_1 missing, weight_2 there), or a stray bias: not a chain of layers
        raise PolicyFileError(f"{path}: {extra[0]} does not belong to the {layers} layer(s) weight_0.."
                              f"weight_{layers - 1} (unknown or after a missing layer: {extra})")
    mean = _numbers(path, "obs_mean", arrays["obs_mean"])
    var = _numbers(path, "obs_var", arrays["obs_var"])
    if mean.ndim != 1 or mean.size == 0 or var.shape != mean.shape:
        raise PolicyFileError(f"{path}: obs_mean {mean.shape} and obs_var {var.shape} must be equal 1-D")
    weights, biases = [], []
    for i in range(layers):
        w, b = _layer(path, i, arrays, inputs=mean.size if i == 0 else weights[-1].shape[0])
        weights.append(w)
        biases.append(b)
    for name, v in [*((f"weight_{i}", w) for i, w in enumerate(weights)),
                    *((f"bias_{i}", b) for i, b in enumerate(biases)), ("obs_mean", mean), ("obs_var", var)]:
        if not np.isfinite(v).all():
            raise PolicyFileError(f"{path}: {name} has {np.count_nonzero(~np.isfinite(v))} NaN or infinite "
                                  "value(s); all must be finite")
    if (var < 0).any():
        raise PolicyFileError(f"{path}: obs_var: a negative variance")
    clip = _scalar(path, "obs_clip", arrays["obs_clip"])
    epsilon = _scalar(path, "obs_epsilon", arrays["obs_epsilon"])
    if not clip > 0:
        raise PolicyFileError(f"{path}: obs_clip is {clip}; it must be positive (inf: no clipping)")
    if not (np.isfinite(epsilon) and epsilon >= 0):
        raise PolicyFileError(f"{path}: obs_epsilon is {epsilon}; it must be finite and >= 0")
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        scale = 1.0 / np.sqrt(var + epsilon)
    if not np.isfinite(scale).all():
        raise PolicyFileError(f"{path}: obs_var + obs_epsilon is 0 (or too small) for observation(s) "
                              f"{np.flatnonzero(~np.isfinite(scale))[:10].tolist()}: the normaliser divides by zero")
    # every layer's values for inputs within the clip stay far from overflow (weights x 1e300 would make
    # every action NaN): |x_{i+1}| <= max row sum |W_i| * |x_i| + max |b_i|
    bound = min(clip, UNCLIPPED_INPUT_BOUND)
    with np.errstate(over="ignore", invalid="ignore"):
        for i, (w, b) in enumerate(zip(weights, biases)):
            bound = float(np.abs(w).sum(axis=1).max()) * bound + float(np.abs(b).max())
            if not bound <= MAX_ACTIVATION_BOUND:
                raise PolicyFileError(f"{path}: weight_{i}, bias_{i}: layer {i}'s values may reach {bound:.3g} for "
                                      f"normalised inputs within +-{min(clip, UNCLIPPED_INPUT_BOUND):g}, beyond "
                                      f"{MAX_ACTIVATION_BOUND:g} (overflow would make actions NaN)")
    config: Any = {}
    if "config" in arrays:
        raw = arrays["config"]
        if raw.dtype.kind not in "US" or raw.ndim != 0:
            raise PolicyFileError(f"{path}: config must be one JSON string, got {raw.dtype} of shape {raw.shape}")
        try:
            text = raw.item().decode("utf-8") if raw.dtype.kind == "S" else str(raw.item())
            config = json.loads(text)
        except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as err:
            raise PolicyFileError(f"{path}: config is not JSON ({err})") from err
    return NumpyPolicy(weights, biases, mean, var, clip, epsilon, config if isinstance(config, dict) else {})


def policy_id(env_id: str) -> str:
    """The id whose shipped policy ``env_id`` runs: its preset's ``policy`` key (an id that shares
    another's controller, e.g. ``PlaMoScene-v0`` runs ``PlaMo-v0``'s), else ``env_id`` itself."""
    from stairenv.registration import load_presets

    preset = load_presets().get(env_id, {})
    return str(preset.get("policy", env_id))


def shipped_policy_path(env_id: str) -> Path:
    """Where the package keeps the policy ``env_id`` runs (``stairenv/policies/<policy id>.npz``)."""
    return Path(str(resources.files("stairenv"))) / "policies" / f"{policy_id(env_id)}.npz"


def load(env_id: str) -> NumpyPolicy:
    """The policy shipped with the package for ``env_id`` (its own, or the one its preset names with
    ``policy``), its sizes checked against the env's spaces."""
    path = shipped_policy_path(env_id)
    if not path.is_file():
        shipped = sorted(p.stem for p in path.parent.glob("*.npz")) if path.parent.is_dir() else []
        raise FileNotFoundError(f"no trained policy for {env_id!r} is shipped with stairenv (shipped: {shipped}); "
                                "train one with baselines/train_ppo.py and export it with baselines/export_policy.py")
    import gymnasium as gym

    import stairenv  # noqa: F401  (registers the ids)

    env = gym.make(env_id)
    try:
        policy = load_file(path, env)
        check_text_encoder(policy, env, path)
    finally:
        env.close()
    named, expected = policy.config.get("env_id"), policy_id(env_id)
    if named is not None and named != expected:
        raise PolicyFileError(f"{path}: config names env_id {named!r}, not {expected!r}")
    return policy


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
