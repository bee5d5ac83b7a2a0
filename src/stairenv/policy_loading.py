"""Policy loading, one home for the package: a policy spec -> a callable ``obs -> action``
(:func:`load_policy`), and a policy's name in reports and printouts (:func:`policy_label`).

Specs: the built-in "zero" and "random", Stable-Baselines3 models (``path.zip``, ``ALGO:path``)
with the observation normalisation saved beside them, and exported numpy policies (``.npz``).
No policy file runs code when loaded: SB3's files are pickles by SB3's design, so they are not
given to SB3's loader but read here (:func:`read_sb3_model`, :func:`read_statistics`): plain JSON
fields, weights with ``torch.load(weights_only=True)``, statistics by an unpickler that builds
only inert stand-ins.
:data:`KINEMATIC` names the stories' stand-in, which the story runner binds to its env.

This module sits below ``stories``, ``evaluation`` and ``training`` (it imports only
``stairenv.pretrained`` and, when a model is loaded, torch), so each of them
loads and names policies the same way without importing the others.
"""

from __future__ import annotations

import os
import re
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from stairenv.pretrained import (MAX_LAYERS, MAX_WIDTH, NumpyPolicy, PolicyFileError, check_text_encoder, load_file,
                                 shipped_policy_path)
from stairenv.safe_pickle import numpy_globals, pickled_array

Policy = Callable[[np.ndarray], Any]

#: Policy specs understood by :func:`load_policy` besides a model path.
BUILTIN_POLICIES: tuple[str, ...] = ("random", "zero")
#: the spec of the policy shipped with the package for the env's id (``stairenv.pretrained``)
PRETRAINED = "pretrained"
#: Policy spec of the stories' kinematic stand-in (``stairenv.stories.KinematicStandIn``): not
#: loaded here; :class:`~stairenv.stories.machine.StoryRunner` builds one for its env.
KINEMATIC = "kinematic"
#: What :func:`policy_label` (detailed) calls the stand-in, so that no result hides it.
STAND_IN_LABEL = "kinematic stand-in (NOT physics-based: writes qpos)"


class ZeroPolicy:
    """All-zero actions: the PD targets stay at the middle of their ranges."""

    def __init__(self, action_space: gym.spaces.Box) -> None:
        self.action = np.zeros(action_space.shape, dtype=action_space.dtype)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return self.action.copy()

    def __repr__(self) -> str:
        return "ZeroPolicy()"


class RandomPolicy:
    """Uniform actions in the Box action space from a seeded generator.

    ``reset(seed)`` reseeds it; the evaluators call it with each episode's seed,
    so an episode's actions do not depend on the episodes run before it.
    """

    def __init__(self, action_space: gym.spaces.Box, seed: int | None = 0) -> None:
        if not isinstance(action_space, gym.spaces.Box) or not (
            np.isfinite(action_space.low).all() and np.isfinite(action_space.high).all()
        ):
            raise ValueError(f"policy 'random' needs a bounded Box action space, got {action_space!r}")
        self.low, self.high, self.dtype = action_space.low, action_space.high, action_space.dtype
        self.reset(seed)

    def reset(self, seed: int | None = None) -> None:
        self.rng = np.random.default_rng(seed)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return self.rng.uniform(self.low, self.high).astype(self.dtype)

    def __repr__(self) -> str:
        return "RandomPolicy()"


class SB3Policy:
    """A Stable-Baselines3 model used as ``obs -> action`` (deterministic ``predict``),
    with the observation normalisation of a ``VecNormalize`` saved beside it, if any
    (``load_policy`` gives an :class:`SB3ZipModel` and :class:`VecNormalizeStatistics`)."""

    def __init__(self, model: Any, obs_normalizer: Any | None = None, path: str = "") -> None:
        self.model = model
        self.obs_normalizer = obs_normalizer
        self.path = path

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        if self.obs_normalizer is not None:
            obs = self.obs_normalizer.normalize_obs(np.asarray(obs, dtype=np.float32))
        action, _ = self.model.predict(obs, deterministic=True)
        return action

    def __repr__(self) -> str:
        norm = ", normalised obs" if self.obs_normalizer is not None else ""
        return f"SB3Policy({type(self.model).__name__}: {self.path}{norm})"


def _policy_spec_error(spec: Any, reason: str) -> ValueError:
    return ValueError(
        f"policy must be one of {[*BUILTIN_POLICIES, PRETRAINED]}, a path to a Stable-Baselines3 model .zip, "
        f"or 'ALGO:path' (e.g. 'SAC:runs/model.zip'); got {spec!r}: {reason}"
    )


def normalizer_beside(model_path: str | os.PathLike) -> Path | None:
    """The VecNormalize statistics saved with a model: a checkpoint's own
    (SB3's ``CheckpointCallback``: ``ppo_1000_steps.zip`` -> ``ppo_vecnormalize_1000_steps.pkl``),
    else ``vecnormalize.pkl`` in its folder; None if neither exists."""
    model_path = Path(model_path)
    found = re.fullmatch(r"(.*)_(\d+)_steps", model_path.stem)
    candidates = [model_path.with_name(f"{found[1]}_vecnormalize_{found[2]}_steps.pkl")] if found else []
    candidates.append(model_path.parent / "vecnormalize.pkl")
    return next((path for path in candidates if path.is_file()), None)


def read_normalizer(path: str | os.PathLike):
    """VecNormalize statistics from ``path`` as SB3's own object, not yet attached to an env
    (``VecNormalize.load`` is this plus ``set_venv``), for resuming training (``train_ppo.py --resume``).
    The file is unpickled: it can run code stored in it, so open only files you made or trust
    (:func:`read_statistics` reads the same file without running anything). ``ValueError`` names the
    file when it cannot be read."""
    import pickle

    from stable_baselines3.common.vec_env import VecNormalize

    try:
        with open(path, "rb") as f:
            normalizer = pickle.load(f)
    except Exception as err:  # truncated pickles, wrong magic, ... surface as many types
        raise ValueError(f"cannot read the VecNormalize statistics {str(path)!r} ({type(err).__name__}: {err}): "
                         "the file is truncated or not a VecNormalize .pkl") from err
    if not isinstance(normalizer, VecNormalize):
        raise ValueError(  # noqa: TRY004  (a wrong file, not a wrong argument)
            f"{str(path)!r} holds a {type(normalizer).__name__}, not VecNormalize statistics")
    return normalizer


# --- Stable-Baselines3 files, read without running code from them --------------------------------
# SB3 saves a model as a .zip whose ``data`` member is JSON in which every value that is not plain
# JSON (the policy class, the spaces, policy_kwargs, schedules) is a base64 pickle under ":serialized:",
# beside plain copies of its fields; ``PPO.load`` unpickles them, so a crafted file runs code when
# loaded. Here only plain JSON fields are read (never a ":serialized:" value), the weights come from
# ``policy.pth`` with ``torch.load(weights_only=True)`` and the layer sizes from the tensors' shapes.
# The VecNormalize statistics (a pickle of the whole object) are read by an unpickler that resolves
# no name of the file's to anything that runs: the classes a VecNormalize pickle names become inert
# records and numpy's arrays are rebuilt from their bytes; any other name is refused before anything
# is built.

#: the largest ``data`` (JSON) member of an SB3 model .zip read
MAX_SB3_DATA_BYTES = 16 * 2**20
#: the largest ``policy.pth`` (weights) of an SB3 model .zip read, and what its storages may unpack to
MAX_SB3_WEIGHTS_BYTES = 512 * 2**20
#: the largest VecNormalize statistics .pkl read
MAX_STATISTICS_BYTES = 64 * 2**20

#: SB3 algorithms whose models are read: (the Sequential of the actor's hidden layers, its output
#: Linear (None: the Sequential's last Linear, followed by a Tanh), tanh-squashed and scaled to the
#: action bounds (else clipped to them), the algorithm's default activation)
SB3_ACTORS: dict[str, tuple[str, str | None, bool, str]] = {
    "PPO": ("mlp_extractor.policy_net", "action_net", False, "Tanh"),
    "A2C": ("mlp_extractor.policy_net", "action_net", False, "Tanh"),
    "TRPO": ("mlp_extractor.policy_net", "action_net", False, "Tanh"),
    "SAC": ("actor.latent_pi", "actor.mu", True, "ReLU"),
    "TQC": ("actor.latent_pi", "actor.mu", True, "ReLU"),
    "TD3": ("actor.mu", None, True, "ReLU"),
    "DDPG": ("actor.mu", None, True, "ReLU"),
}
#: activations (``policy_kwargs["activation_fn"]``, read from its plain JSON text) built with their defaults
SB3_ACTIVATIONS = ("CELU", "ELU", "GELU", "Hardtanh", "LeakyReLU", "Mish", "ReLU", "ReLU6", "SELU", "SiLU",
                   "Sigmoid", "Softplus", "Softsign", "Tanh")
_ACTIVATION_TEXT = re.compile(r"<class 'torch\.nn\.modules\.activation\.(\w+)'>")
_BOX_TYPE = re.compile(r"<class 'gym(nasium)?\.spaces\.box\.Box'>")


def _sb3_layout(name: str) -> tuple[str, tuple[str, str | None, bool, str]]:
    for algorithm, layout in SB3_ACTORS.items():
        if algorithm.lower() == name.lower():
            return algorithm, layout
    raise ValueError(f"policy algorithm must be one of {sorted(SB3_ACTORS)} (Stable-Baselines3 models whose "
                     f"actor is read without running code from the file), got {name!r}")


class SB3ZipModel:
    """The deterministic actor of a Stable-Baselines3 model .zip (:func:`read_sb3_model`), with the
    part of SB3's model interface the loaders use: ``predict(obs, deterministic=True)`` (the same
    float32 layers and the same clipping or scaling to ``action_space`` as ``model.predict``),
    ``observation_space``, ``action_space`` and, for actor-critic models, ``policy.mlp_extractor.policy_net``
    and ``policy.action_net`` (what ``stairenv.pretrained.from_sb3`` exports)."""

    def __init__(self, algorithm: str, hidden: Any, output: Any, squash: bool, observation_shape: tuple[int, ...],
                 action_shape: tuple[int, ...], path: str = "") -> None:
        from types import SimpleNamespace

        self.algorithm, self.hidden, self.output, self.squash, self.path = algorithm, hidden, output, squash, path
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, observation_shape, np.float32)
        #: the bounds actions are clipped or scaled to (``load_policy`` sets the env's)
        self.action_space = gym.spaces.Box(-1.0, 1.0, action_shape, np.float32)
        self.policy = SimpleNamespace(mlp_extractor=SimpleNamespace(policy_net=hidden), action_net=output)

    def predict(self, observation: np.ndarray, state: Any = None, episode_start: Any = None,
                deterministic: bool = True) -> tuple[np.ndarray, None]:
        """The actor's mean action(s) (its only action: the model is read for acting, not training)."""
        import torch

        obs = np.asarray(observation)
        shape = self.observation_space.shape
        if obs.shape != shape and obs.shape[1:] != shape:
            raise ValueError(f"{self.path}: observations of shape {obs.shape}, the model takes {shape} or a batch")
        with torch.no_grad():
            x = torch.as_tensor(obs.reshape((-1, *shape))).float().flatten(1)
            x = self.output(self.hidden(x))
            if self.squash:
                x = torch.tanh(x)
        actions = x.cpu().numpy().reshape((-1, *self.action_space.shape))
        low, high = self.action_space.low, self.action_space.high
        actions = low + (0.5 * (actions + 1.0) * (high - low)) if self.squash else np.clip(actions, low, high)
        return (actions if obs.shape != shape else actions.squeeze(axis=0)), None

    def __repr__(self) -> str:
        return f"SB3ZipModel({self.algorithm}: {self.path})"


def _zip_member(path: Path, archive: zipfile.ZipFile, name: str, limit: int) -> bytes:
    try:
        info = archive.getinfo(name)
    except KeyError:
        raise PolicyFileError(f"{path}: not a Stable-Baselines3 model .zip: it has no {name!r} member "
                              f"(members: {archive.namelist()[:10]})") from None
    if info.file_size > limit:
        raise PolicyFileError(f"{path}: its {name!r} unpacks to {info.file_size} bytes, more than {limit}")
    with archive.open(info) as member:
        return member.read(limit + 1)


def _sb3_weights(path: Path, blob: bytes) -> dict[str, Any]:
    """``policy.pth``'s tensors, read with ``torch.load(weights_only=True)`` from a torch zip whose
    storages unpack to at most :data:`MAX_SB3_WEIGHTS_BYTES`."""
    import io
    import pickle
    import warnings

    import torch

    try:
        with zipfile.ZipFile(io.BytesIO(blob)) as inner:
            unpacked = sum(member.file_size for member in inner.infolist())
    except zipfile.BadZipFile:
        raise PolicyFileError(f"{path}: its policy.pth is not a torch zip file (what SB3 saves weights as)") from None
    if unpacked > MAX_SB3_WEIGHTS_BYTES:
        raise PolicyFileError(f"{path}: its policy.pth unpacks to {unpacked} bytes, more than {MAX_SB3_WEIGHTS_BYTES}")
    with warnings.catch_warnings():  # a crafted file's pickle protocol: torch asks to report it to them
        warnings.filterwarnings("ignore", category=UserWarning)
        try:
            state = torch.load(io.BytesIO(blob), map_location="cpu", weights_only=True)
        except pickle.UnpicklingError:  # torch's text advises weights_only=False: not passed on
            raise PolicyFileError(f"{path}: its policy.pth asks to build Python objects besides tensors, which a "
                                  "safe load refuses (nothing in it was run)") from None
        except Exception as err:  # noqa: BLE001  (truncated storages, bad records: many types)
            raise PolicyFileError(f"{path}: cannot read its policy.pth ({type(err).__name__}: {err})") from None
    if not (isinstance(state, dict) and all(isinstance(k, str) and isinstance(v, torch.Tensor)
                                            for k, v in state.items())):
        raise PolicyFileError(f"{path}: its policy.pth is not a dict of named tensors (a policy's state_dict)")
    return state


def _sb3_space_shape(path: Path, data: dict[str, Any], key: str) -> tuple[int, ...] | None:
    """A Box space's shape from the plain ``_shape`` field SB3 writes beside its pickle; None if absent."""
    space = data.get(key)
    if space is None:
        return None
    kind = space.get(":type:") if isinstance(space, dict) else None
    if not (isinstance(kind, str) and _BOX_TYPE.fullmatch(kind)):
        raise PolicyFileError(f"{path}: its {key} is {kind or type(space).__name__}, not a Box (only Box spaces "
                              "are read)")
    shape = space.get("_shape")
    if shape is None:
        return None
    if not (isinstance(shape, list) and len(shape) <= 8 and all(type(n) is int and 0 < n <= 2**20 for n in shape)):
        raise PolicyFileError(f"{path}: its {key}'s shape {shape!r} is not a list of positive sizes")
    return tuple(shape)


def _sb3_linears(path: Path, state: dict[str, Any], prefix: str) -> list[tuple[Any, Any]]:
    """The (weight, bias) of the Linear layers of the Sequential ``prefix`` (indices 0, 2, 4, ...:
    an activation between them)."""
    found: dict[int, dict[str, Any]] = {}
    pattern = re.compile(re.escape(prefix) + r"\.(\d+)\.(weight|bias)")
    for key, tensor in state.items():
        match = pattern.fullmatch(key)
        if match:
            found.setdefault(int(match[1]), {})[match[2]] = tensor
        elif key.startswith(prefix + "."):
            raise PolicyFileError(f"{path}: policy.pth's {key!r} is not a Linear layer's weight or bias (only MLP "
                                  "actors are read)")
    if sorted(found) != list(range(0, 2 * len(found), 2)):
        raise PolicyFileError(f"{path}: policy.pth's {prefix} has Linear layers {sorted(found)}; expected 0, 2, 4, "
                              "... (an activation between them)")
    return [(found[i].get("weight"), found[i].get("bias")) for i in sorted(found)]


def read_sb3_model(path: str | os.PathLike, algorithm: str = "PPO") -> SB3ZipModel:
    """The deterministic actor of a Stable-Baselines3 model .zip, read without running code from it:
    the weights from ``policy.pth`` (``torch.load(weights_only=True)``), the layer sizes from their
    shapes, the activation, gSDE flag and spaces' shapes from plain JSON fields of ``data`` (its
    ``:serialized:`` pickles are never decoded). MLP actors of :data:`SB3_ACTORS`' algorithms on Box
    spaces; anything else, or a fault, raises ``PolicyFileError`` naming the file."""
    import json

    import torch

    path = Path(path)
    algorithm, (hidden_name, output_name, squash, default_activation) = _sb3_layout(algorithm)
    try:
        with zipfile.ZipFile(path) as archive:
            text = _zip_member(path, archive, "data", MAX_SB3_DATA_BYTES)
            blob = _zip_member(path, archive, "policy.pth", MAX_SB3_WEIGHTS_BYTES)
    except PolicyFileError:
        raise
    except (OSError, EOFError, ValueError, RuntimeError, zipfile.BadZipFile, NotImplementedError) as err:
        raise PolicyFileError(f"{path}: cannot read as a Stable-Baselines3 model .zip "
                              f"({type(err).__name__}: {err})") from None
    try:
        data = json.loads(text.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as err:
        raise PolicyFileError(f"{path}: its 'data' member is not JSON ({type(err).__name__}: {err})") from None
    if not isinstance(data, dict):
        raise PolicyFileError(f"{path}: its 'data' member is not a JSON object")
    if data.get("use_sde", False) not in (False, None):
        raise PolicyFileError(f"{path}: trained with gSDE (use_sde): its actor is not read; export it with "
                              "baselines/export_policy.py from a trusted checkout")
    kwargs = data.get("policy_kwargs") or {}
    if not isinstance(kwargs, dict):
        raise PolicyFileError(f"{path}: its policy_kwargs is not a JSON object")
    if kwargs.get("squash_output", False) not in (False, None) and not squash:
        raise PolicyFileError(f"{path}: a squashed {algorithm} actor (squash_output) is not read")
    extractor = kwargs.get("features_extractor_class")
    if extractor is not None and "FlattenExtractor" not in str(extractor):
        raise PolicyFileError(f"{path}: features extractor {extractor!r} is not read (only MLP policies on flat "
                              "observations)")
    activation_text = kwargs.get("activation_fn", f"<class 'torch.nn.modules.activation.{default_activation}'>")
    named = _ACTIVATION_TEXT.fullmatch(activation_text) if isinstance(activation_text, str) else None
    if named is None or named[1] not in SB3_ACTIVATIONS:
        raise PolicyFileError(f"{path}: activation_fn {activation_text!r} is not read (one of {list(SB3_ACTIVATIONS)} "
                              "with its default settings is)")
    observation_shape = _sb3_space_shape(path, data, "observation_space")
    action_shape = _sb3_space_shape(path, data, "action_space")

    state = _sb3_weights(path, blob)
    if any("features_extractor." in key for key in state):
        raise PolicyFileError(f"{path}: its features extractor has weights; only MLP policies on flat observations "
                              "are read")
    layers = _sb3_linears(path, state, hidden_name)
    if output_name is None:
        if not layers:
            raise PolicyFileError(f"{path}: policy.pth has no {hidden_name} layers: not a {algorithm} model")
        *layers, output_layer = layers
    else:
        output_layer = (state.get(f"{output_name}.weight"), state.get(f"{output_name}.bias"))
        if output_layer[0] is None and not layers:
            raise PolicyFileError(f"{path}: policy.pth has no {output_name}.weight nor {hidden_name} layers: not a "
                                  f"{algorithm} model ({list(state)[:6]}...)")
    activation = getattr(torch.nn, named[1])
    modules: list[Any] = []
    inputs = int(np.prod(observation_shape)) if observation_shape else None
    names = [f"{hidden_name}.{2 * i}" for i in range(len(layers))] + [output_name or f"{hidden_name}.{2 * len(layers)}"]
    for i, ((weight, bias), name) in enumerate(zip([*layers, output_layer], names)):
        if weight is None or bias is None:
            raise PolicyFileError(f"{path}: policy.pth lacks {name}.{'weight' if weight is None else 'bias'}")
        if not (weight.dtype.is_floating_point and weight.ndim == 2 and bias.shape == (weight.shape[0],)
                and 0 < weight.shape[0] <= MAX_WIDTH and (inputs is None or weight.shape[1] == inputs)):
            raise PolicyFileError(f"{path}: policy.pth's {name} has weight {tuple(weight.shape)} and bias "
                                  f"{tuple(bias.shape)} of {weight.dtype}; expected floats (outputs, "
                                  f"{inputs if inputs is not None else 'inputs'}) and (outputs,)")
        if not (torch.isfinite(weight).all() and torch.isfinite(bias).all()):
            raise PolicyFileError(f"{path}: policy.pth's {name} has NaN or infinite values")
        linear = torch.nn.Linear(weight.shape[1], weight.shape[0])
        linear.load_state_dict({"weight": weight.float(), "bias": bias.float()})
        modules.append(linear)
        if i < len(layers):
            modules.append(activation())
        inputs = weight.shape[0]
    if len(modules) > 2 * MAX_LAYERS:
        raise PolicyFileError(f"{path}: {len(layers) + 1} layers; a policy has at most {MAX_LAYERS}")
    output = modules.pop()
    first_inputs = (modules[0] if modules else output).in_features
    if observation_shape is None:
        observation_shape = (first_inputs,)
    if action_shape is None:
        action_shape = (output.out_features,)
    if int(np.prod(action_shape)) != output.out_features:
        raise PolicyFileError(f"{path}: its action_space has shape {action_shape}, its actor outputs "
                              f"{output.out_features} values")
    hidden = torch.nn.Sequential(*modules).eval()
    return SB3ZipModel(algorithm, hidden, output.eval(), squash, observation_shape, action_shape, str(path))


class VecNormalizeStatistics:
    """The observation statistics of a VecNormalize ``.pkl`` (:func:`read_statistics`), frozen:
    ``normalize_obs`` is ``VecNormalize.normalize_obs``; ``obs_rms`` (``mean``, ``var``, ``count``),
    ``clip_obs``, ``epsilon``, ``norm_obs`` as VecNormalize names them (``training`` and
    ``norm_reward`` False)."""

    def __init__(self, mean: np.ndarray, var: np.ndarray, count: float, clip_obs: float, epsilon: float,
                 norm_obs: bool, path: str = "") -> None:
        from types import SimpleNamespace

        self.obs_rms = SimpleNamespace(mean=mean, var=var, count=count)
        self.clip_obs, self.epsilon, self.norm_obs, self.path = clip_obs, epsilon, norm_obs, path
        self.training = False
        self.norm_reward = False
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, mean.shape, np.float32)

    def normalize_obs(self, obs: np.ndarray) -> np.ndarray:
        if not self.norm_obs:
            return np.array(obs, copy=True)
        return np.clip((obs - self.obs_rms.mean) / np.sqrt(self.obs_rms.var + self.epsilon), -self.clip_obs,
                       self.clip_obs).astype(np.float32)

    def __repr__(self) -> str:
        return f"VecNormalizeStatistics({self.path}, {self.obs_rms.mean.shape})"


class _Record:
    """Stands in for a class a VecNormalize pickle names: keeps what the pickle gives it, runs nothing."""

    pickled_name = ""

    def __new__(cls, *args: Any, **kwargs: Any) -> _Record:
        record = object.__new__(cls)
        record.args, record.state = args, None
        return record

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        pass

    def __setstate__(self, state: Any) -> None:
        self.state = state


def _records(*names: str) -> dict[tuple[str, str], type]:
    out = {}
    for name in names:
        module, _, attribute = name.rpartition(".")
        out[(module, attribute)] = type(attribute, (_Record,), {"pickled_name": name})
    return out


_VECNORMALIZE = "stable_baselines3.common.vec_env.vec_normalize.VecNormalize"
_RUNNING_MEAN_STD = "stable_baselines3.common.running_mean_std.RunningMeanStd"
_STATISTICS_GLOBALS: dict[tuple[str, str], Any] = {
    **_records(_VECNORMALIZE, _RUNNING_MEAN_STD, "gymnasium.spaces.box.Box", "gym.spaces.box.Box"),
    **numpy_globals(frombuffer=True),
}


def _statistics_unpickler(stream: Any) -> Any:
    import pickle

    class Unpickler(pickle.Unpickler):
        def find_class(self, module: str, name: str) -> Any:
            if module == "numpy.random" or module.startswith("numpy.random."):  # a space's generator, unused
                return _records(f"{module}.{name}")[(module, name)]
            if (module, name) not in _STATISTICS_GLOBALS:
                raise pickle.UnpicklingError(f"it names {module}.{name}, not one of the names VecNormalize "
                                             "statistics of Box observations are read with")
            return _STATISTICS_GLOBALS[(module, name)]

    return Unpickler(stream)


def read_statistics(path: str | os.PathLike) -> VecNormalizeStatistics:
    """VecNormalize observation statistics from a ``.pkl`` (``VecNormalize.save``), read without running
    code from it: the names it may use are VecNormalize's, RunningMeanStd's, gymnasium's Box's, numpy's
    arrays and dtypes, and numpy's random generators (a seeded space's), each an inert stand-in (arrays
    from their own bytes once shape, type and length agree); any other name is refused before anything
    is built. ``PolicyFileError`` naming the file and the fault."""
    import io
    import pickle

    path = Path(path)
    try:
        size = path.stat().st_size
        if size > MAX_STATISTICS_BYTES:
            raise PolicyFileError(f"{path}: {size} bytes, more than VecNormalize statistics ({MAX_STATISTICS_BYTES})")
        top = _statistics_unpickler(io.BytesIO(path.read_bytes())).load()
    except PolicyFileError:
        raise
    except pickle.UnpicklingError as err:
        raise PolicyFileError(f"{path}: not read as VecNormalize statistics: {err} (nothing in it was run)") from None
    except Exception as err:  # noqa: BLE001  (truncation, malformed opcodes or arrays: many types)
        raise PolicyFileError(f"{path}: cannot read as VecNormalize statistics ({type(err).__name__}: {err})") from None
    state = top.state if getattr(top, "pickled_name", None) == _VECNORMALIZE else None
    if not isinstance(state, dict):
        held = getattr(top, "pickled_name", None) or type(top).__name__
        raise PolicyFileError(f"{path}: holds a {held}, not VecNormalize statistics")
    rms = state.get("obs_rms")
    if getattr(rms, "pickled_name", None) != _RUNNING_MEAN_STD or not isinstance(rms.state, dict):
        raise PolicyFileError(f"{path}: its obs_rms is not one RunningMeanStd (statistics of Dict observations are "
                              "not read)")
    try:
        mean = pickled_array(rms.state.get("mean"), "obs_rms.mean")
        var = pickled_array(rms.state.get("var"), "obs_rms.var")
    except ValueError as err:
        raise PolicyFileError(f"{path}: {err}") from None
    if mean.ndim != 1 or mean.size == 0 or var.shape != mean.shape or mean.dtype.kind != "f" or var.dtype.kind != "f":
        raise PolicyFileError(f"{path}: obs_rms.mean {mean.shape} and obs_rms.var {var.shape} must be equal 1-D floats")
    if not (np.isfinite(mean).all() and np.isfinite(var).all() and (var >= 0).all()):
        raise PolicyFileError(f"{path}: obs_rms has NaN, infinite or negative-variance values")
    numbers = {}
    for name in ("clip_obs", "epsilon"):
        value = state.get(name)
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
            raise PolicyFileError(f"{path}: {name} is {value!r}, not a number")
        numbers[name] = float(value)
    if not numbers["clip_obs"] > 0 or not (np.isfinite(numbers["epsilon"]) and numbers["epsilon"] >= 0):
        raise PolicyFileError(f"{path}: clip_obs {numbers['clip_obs']} must be > 0 and epsilon "
                              f"{numbers['epsilon']} finite and >= 0")
    if not (np.isfinite(var + numbers["epsilon"]).all() and (var + numbers["epsilon"] > 0).all()):
        raise PolicyFileError(f"{path}: obs_rms.var + epsilon is 0 for some observation: the normaliser divides by 0")
    norm_obs = state.get("norm_obs", True)
    if not isinstance(norm_obs, (bool, np.bool_)):
        raise PolicyFileError(f"{path}: norm_obs is {norm_obs!r}, not a bool")
    count = rms.state.get("count", 0.0)
    count = float(count) if isinstance(count, (int, float, np.integer, np.floating)) else float("nan")
    return VecNormalizeStatistics(mean, var, count, numbers["clip_obs"], numbers["epsilon"], bool(norm_obs), str(path))


def load_policy(spec: str, env: gym.Env, seed: int | None = 0, device: str = "cpu") -> Policy:
    """Turn a policy spec into a callable ``obs -> action``.

    | spec | policy |
    |---|---|
    | ``"random"`` | uniform actions in ``env.action_space`` from ``np.random.default_rng(seed)`` |
    | ``"zero"`` | all-zero actions |
    | ``"path/model.zip"`` | a Stable-Baselines3 PPO model's actor (:func:`read_sb3_model`), deterministic |
    | ``"SAC:path/model.zip"`` | the same with another algorithm of :data:`SB3_ACTORS` |
    | ``"path/policy.npz"`` | an exported numpy policy (``stairenv.pretrained``; no pickle, no torch) |
    | ``"pretrained"`` | the numpy policy the package ships for ``env``'s id (``stairenv.pretrained.load``) |

    For a model, its VecNormalize statistics (``normalizer_beside``, read by :func:`read_statistics`)
    normalise the observations before ``predict`` (statistics frozen). Its actions are SB3's
    ``predict(obs, deterministic=True)``: the same float32 layers, clipped (or, for SAC and TD3,
    scaled) to ``env.action_space``. Nothing in a model or its statistics is run: a file that would
    need it (a pickled custom policy, a features extractor with weights) raises ``PolicyFileError``
    naming it; export such a model with ``baselines/export_policy.py`` from a trusted checkout.
    ``env`` provides the spaces; it is not stepped. ``device`` is kept for callers: actors run on the CPU.
    """
    if not isinstance(spec, (str, os.PathLike)):
        raise _policy_spec_error(spec, "expected a string")
    spec = os.fspath(spec)
    if spec in BUILTIN_POLICIES:
        if spec == "zero":
            return ZeroPolicy(env.action_space)
        return RandomPolicy(env.action_space, seed)
    if not spec.strip():
        raise _policy_spec_error(spec, "empty string")
    if spec == PRETRAINED:
        return _shipped_policy(env)

    if spec.endswith(".npz"):
        return _numpy_policy(spec, env)
    algo_name, path = "PPO", spec
    head, sep, tail = spec.partition(":")
    # "ALGO:path"; a one-letter head is a Windows drive ("C:\\...").
    if sep and len(head) > 1 and head.replace("_", "").isalnum() and not os.path.exists(spec):
        algo_name, path = head, tail
    model_path = Path(path).expanduser()
    if not model_path.is_file():
        if model_path.suffix != ".zip" and model_path.with_name(model_path.name + ".zip").is_file():
            model_path = model_path.with_name(model_path.name + ".zip")
        else:
            raise _policy_spec_error(spec, f"no such file {str(model_path)!r}")
    model = read_sb3_model(model_path, algo_name)  # PolicyFileError naming the file; nothing in it is run
    expected = getattr(env.observation_space, "shape", None)
    if model.observation_space.shape != expected:
        raise PolicyFileError(
            f"policy model {str(model_path)!r} expects observations of shape {model.observation_space.shape}, "
            f"the env gives {expected}"
        )
    if model.action_space.shape != env.action_space.shape:
        raise PolicyFileError(
            f"policy model {str(model_path)!r} outputs actions of shape {model.action_space.shape}, "
            f"the env expects {env.action_space.shape}"
        )
    model.action_space = env.action_space  # the bounds its actions are clipped or scaled to

    normalizer = None
    stats = normalizer_beside(model_path)
    if stats is not None:
        normalizer = read_statistics(stats)  # PolicyFileError naming the file; nothing in it is run
        if normalizer.observation_space.shape != expected:
            raise PolicyFileError(f"VecNormalize statistics {str(stats)!r} are for observations of shape "
                                  f"{normalizer.observation_space.shape}, the env gives {expected}")
    return SB3Policy(model, normalizer, str(model_path))


def _shipped_policy(env: gym.Env) -> NumpyPolicy:
    spec = getattr(getattr(env, "unwrapped", env), "spec", None) or getattr(env, "spec", None)
    if spec is None:
        raise ValueError(f"policy {PRETRAINED!r}: the env has no registered id (make it with gym.make) to find "
                         "the policy shipped for it")
    return shipped_policy(spec.id, env)


def shipped_policy(env_id: str, env: gym.Env) -> NumpyPolicy:
    """The policy shipped for ``env_id``, checked against ``env``'s spaces and text encoder;
    ``ValueError`` naming the id where none ships."""
    path = shipped_policy_path(env_id)
    if not path.is_file():
        raise ValueError(f"policy {PRETRAINED!r}: no trained policy for {env_id!r} ships with stairenv yet")
    policy = load_file(path, env)
    check_text_encoder(policy, env, path)
    return policy


def _numpy_policy(path: str, env: gym.Env) -> NumpyPolicy:
    policy = load_file(path, env)  # PolicyFileError (a ValueError) naming the file unless the sizes are the env's
    check_text_encoder(policy, env, path)    # a file's as the shipped one's: trained on this env's embeddings
    return policy


def policy_label(policy: Any, *, detailed: bool = False) -> str:
    """A policy's name for reports and printouts.

    | policy | label | ``detailed`` label |
    |---|---|---|
    | a spec string or path | itself | itself; :data:`KINEMATIC` -> :data:`STAND_IN_LABEL` |
    | a stand-in with ``physics_based = False`` | its ``__name__`` or type name | :data:`STAND_IN_LABEL` |
    | another object | its ``__name__`` or type name | its ``repr`` if its class defines one, else its type name |

    Report labels use the short form; the story runner and the scripts' printouts the detailed one.
    """
    if isinstance(policy, (str, os.PathLike)):
        if detailed and isinstance(policy, str) and policy == KINEMATIC:
            return STAND_IN_LABEL
        return os.fspath(policy)
    if not detailed:
        return getattr(policy, "__name__", None) or type(policy).__name__
    if getattr(policy, "physics_based", True) is False:
        return STAND_IN_LABEL
    return repr(policy) if type(policy).__repr__ is not object.__repr__ else type(policy).__name__


__all__ = [
    "BUILTIN_POLICIES", "KINEMATIC", "PRETRAINED", "SB3_ACTORS", "STAND_IN_LABEL", "Policy", "RandomPolicy",
    "SB3Policy", "SB3ZipModel", "VecNormalizeStatistics", "ZeroPolicy", "load_policy", "normalizer_beside",
    "policy_label", "read_normalizer", "read_sb3_model", "read_statistics", "shipped_policy",
]
