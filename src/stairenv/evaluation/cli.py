"""Command-line helpers shared by ``python -m stairenv`` and the baseline scripts."""

from __future__ import annotations

from typing import Any


#: the recipes' TOML spellings of True, False and None
TOML_WORDS = {"true": True, "false": False, "none": None}


def parse_env_kwarg(text: str) -> tuple[str, Any]:
    """A command-line ``key=value`` -> ``(key, value)``, the value parsed by
    ``ast.literal_eval`` (numbers, tuples, True/None...) or else kept as a string; ``true``, ``false``
    and ``none`` as the recipes' TOML writes them (any case) are True, False and None."""
    import ast

    key, sep, raw = text.partition("=")
    key = key.strip()
    if not sep or not key.isidentifier():
        raise ValueError(f"env kwarg must look like key=value (e.g. pd_gains=stiff), got {text!r}")
    if raw.strip().lower() in TOML_WORDS:
        return key, TOML_WORDS[raw.strip().lower()]
    try:
        value = ast.literal_eval(raw.strip())
    except (ValueError, SyntaxError, MemoryError, RecursionError):
        value = raw
    return key, value


def env_kwarg_argument(text: str) -> tuple[str, Any]:
    """argparse ``type=`` for ``--env-kwarg key=value`` (see :func:`parse_env_kwarg`)."""
    import argparse

    try:
        return parse_env_kwarg(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


__all__ = ["env_kwarg_argument", "parse_env_kwarg"]
