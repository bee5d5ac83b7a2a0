"""Register every preset in ``envs/`` with Gymnasium.

A preset is a TOML file: ``id``, ``entry_point``, ``max_episode_steps``, an
optional ``description``, an optional ``policy`` (the id whose shipped policy this
one runs, ``stairenv.pretrained``) and a ``[kwargs]`` table of the keyword arguments
that define the env. Ablations are presets of the same class with different kwargs.
Every id also gets a ``vector_entry_point``: ``stairenv.environments.vector``'s batched env of its class.
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

import gymnasium as gym

from stairenv.assets import asset_dir

# the natively batched env of each env class (``gym.make_vec(id, n, vectorization_mode="vector_entry_point")``);
# named here as strings so that registering imports no env module
VECTOR_ENTRY_POINTS = {
    f"stairenv.environments.{module}:{name}Env": f"stairenv.environments.vector:{name}VectorEnv"
    for module, name in (("interlevel", "InterLevel"), ("plamo", "PlaMo"), ("plamo_scene", "PlaMoScene"),
                         ("sims", "SIMS"))
}


def load_presets() -> dict[str, dict[str, Any]]:
    """All presets, by env id."""
    presets = {}
    for path in sorted(asset_dir("envs").glob("*.toml")):
        preset = _load(path)
        presets[preset["id"]] = preset
    return presets


def _load(path: Path) -> dict[str, Any]:
    with path.open("rb") as f:
        preset = tomllib.load(f)
    missing = {"id", "entry_point", "max_episode_steps"} - preset.keys()
    if missing:
        raise ValueError(f"env preset {path} lacks {sorted(missing)}")
    if not isinstance(preset.get("policy", ""), str):
        raise ValueError(f"env preset {path}: policy must be an env id (a string), got {preset['policy']!r}")
    preset.setdefault("kwargs", {})
    return preset


def register_all() -> list[str]:
    ids = []
    for env_id, preset in load_presets().items():
        if env_id not in gym.registry:
            gym.register(
                id=env_id,
                entry_point=preset["entry_point"],
                max_episode_steps=int(preset["max_episode_steps"]),
                kwargs=dict(preset["kwargs"]),
                vector_entry_point=VECTOR_ENTRY_POINTS.get(preset["entry_point"]),
            )
        ids.append(env_id)
    return ids
