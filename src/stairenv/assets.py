"""Where the package's data lives: the MJCF models (``xml/``) and env presets (``envs/``), and the user's cache
(``cache_dir``: what the package computes once on a machine and keeps).

In a built wheel both folders are installed inside the package
(``stairenv/xml``, ``stairenv/envs``); in an editable install they are read from
the repository's top level, where the user's design puts them.
"""

from __future__ import annotations

import os
from importlib import resources
from pathlib import Path

_PACKAGE_DIR = Path(str(resources.files("stairenv")))
_REPO_ROOT = _PACKAGE_DIR.parent.parent


def asset_dir(name: str) -> Path:
    """Return the folder ``name`` ("xml" or "envs"), installed or in the source tree."""
    for candidate in (_PACKAGE_DIR / name, _REPO_ROOT / name):
        if candidate.is_dir():
            return candidate
    raise FileNotFoundError(
        f"stairenv data folder {name!r} not found in {_PACKAGE_DIR} or {_REPO_ROOT}; "
        "reinstall the package (pip install stairenv) or run from a full checkout"
    )


def xml_path(filename: str) -> Path:
    path = asset_dir("xml") / filename
    if not path.is_file():
        raise FileNotFoundError(f"MJCF asset {filename!r} not found in {path.parent}")
    return path


def cache_dir() -> Path:
    """``$STAIRENV_CACHE`` or ``~/.cache/stairenv``: the text embeddings and the synthesised stair climbs
    computed on this machine."""
    env = os.environ.get("STAIRENV_CACHE")
    return Path(env).expanduser() if env else Path.home() / ".cache" / "stairenv"
