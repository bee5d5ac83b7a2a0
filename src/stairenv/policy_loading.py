"""Policy loading, one home for the package: a policy spec -> a callable ``obs -> action``
(:func:`load_policy`), and a policy's name in reports and printouts (:func:`policy_label`).

Specs: the built-in "zero" and "random", Stable-Baselines3 models (``path.zip``, ``ALGO:path``)
with the observation normalisation saved beside them, and exported numpy policies (``.npz``).
:data:`KINEMATIC` names the stories' stand-in, which the story runner binds to its env.

This module sits below ``stories``, ``evaluation`` and ``training`` (it imports only
``stairenv.pretrained`` and, when a model is loaded, Stable-Baselines3), so each of them
loads and names policies the same way without importing the others.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from stairenv.pretrained import NumpyPolicy, check_text_encoder, load_file, shipped_policy_path

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
    with the observation normalisation of a ``VecNormalize`` saved beside it, if any."""

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


def _sb3_algorithm(name: str) -> type:
    import stable_baselines3

    modules = [stable_baselines3]
    try:
        import sb3_contrib  # optional: RecurrentPPO, TQC, ...

        modules.append(sb3_contrib)
    except ImportError:
        pass
    for module in modules:
        for attr in dir(module):
            cls = getattr(module, attr)
            if attr.lower() == name.lower() and isinstance(cls, type) and hasattr(cls, "load"):
                return cls
    known = sorted(a for a in dir(stable_baselines3) if a.isupper() and hasattr(getattr(stable_baselines3, a), "load"))
    raise ValueError(f"policy algorithm must be a Stable-Baselines3 algorithm {known}, got {name!r}")


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
    """VecNormalize statistics from ``path``, not yet attached to an env (``VecNormalize.load`` is
    this plus ``set_venv``). The file is a pickle: only open files you trust. ``ValueError`` names the
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


def load_policy(spec: str, env: gym.Env, seed: int | None = 0, device: str = "cpu") -> Policy:
    """Turn a policy spec into a callable ``obs -> action``.

    | spec | policy |
    |---|---|
    | ``"random"`` | uniform actions in ``env.action_space`` from ``np.random.default_rng(seed)`` |
    | ``"zero"`` | all-zero actions |
    | ``"path/model.zip"`` | ``stable_baselines3.PPO.load(path)``, deterministic ``predict`` |
    | ``"SAC:path/model.zip"`` | the same with another algorithm (SB3, or sb3_contrib if installed) |
    | ``"path/policy.npz"`` | an exported numpy policy (``stairenv.pretrained``; no pickle, no torch) |
    | ``"pretrained"`` | the numpy policy the package ships for ``env``'s id (``stairenv.pretrained.load``) |

    For a model, its VecNormalize statistics (``normalizer_beside``) normalise the
    observations before ``predict`` (statistics frozen).
    ``env`` provides the spaces; it is not stepped. ``device`` is passed to the SB3 loader.
    A model .zip and its statistics .pkl are pickles (SB3's formats): load only files you trust.
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
    algorithm = _sb3_algorithm(algo_name)
    try:
        model = algorithm.load(str(model_path), device=device)
    except Exception as err:  # a truncated .zip, another algorithm's model, ...
        raise ValueError(f"cannot read the policy model {str(model_path)!r} as {algorithm.__name__} "
                         f"({type(err).__name__}: {err})") from err
    expected = getattr(env.observation_space, "shape", None)
    if model.observation_space.shape != expected:
        raise ValueError(
            f"policy model {str(model_path)!r} expects observations of shape {model.observation_space.shape}, "
            f"the env gives {expected}"
        )
    if model.action_space.shape != env.action_space.shape:
        raise ValueError(
            f"policy model {str(model_path)!r} outputs actions of shape {model.action_space.shape}, "
            f"the env expects {env.action_space.shape}"
        )

    normalizer = None
    stats = normalizer_beside(model_path)
    if stats is not None:
        # Left unattached to an env (``venv`` None): ``SB3Policy`` calls only ``normalize_obs``,
        # which reads the statistics alone; the shape check below is the one ``set_venv`` makes.
        normalizer = read_normalizer(stats)
        if normalizer.observation_space.shape != expected:
            raise ValueError(f"VecNormalize statistics {str(stats)!r} are for observations of shape "
                             f"{normalizer.observation_space.shape}, the env gives {expected}")
        normalizer.training = False
        normalizer.norm_reward = False
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
    "BUILTIN_POLICIES", "KINEMATIC", "PRETRAINED", "STAND_IN_LABEL", "Policy", "RandomPolicy", "SB3Policy",
    "ZeroPolicy", "load_policy", "normalizer_beside", "policy_label", "read_normalizer", "shipped_policy",
]
