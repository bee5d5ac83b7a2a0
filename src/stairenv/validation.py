"""Keyword checks that name the parameter, its value and its valid range or type in the error.

The env constructors check every keyword with these: a wrong type raises ``TypeError``
(``bool("False")`` is True and ``int(2.5)`` is 2, so nothing is converted silently), a value
out of range ``ValueError``. ``check_number`` and ``check_range`` take anything ``float()``
takes (config objects built from parsed files); ``check_bool``, ``check_int``, ``check_float``,
``check_numbers``, ``check_pair``, ``check_str`` and ``check_mapping`` also check the type, and
``check_grid`` bounds the memory a grid of samples may ask for.
"""

from __future__ import annotations

import math
import numbers
import reprlib
from collections.abc import Mapping, Sequence

import numpy as np


def check_number(name: str, value: float, low: float = -math.inf, high: float = math.inf,
                 low_open: bool = False) -> float:
    """``value`` must be a finite number in [low, high] (or (low, high] with ``low_open``)."""
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    below = value <= low if low_open else value < low
    if not math.isfinite(value) or below or value > high:
        bracket = "(" if low_open else "["
        raise ValueError(f"{name} must lie in {bracket}{low}, {high}], got {value!r}")
    return value


def check_range(name: str, value: Sequence[float], low: float, high: float) -> tuple[float, float]:
    """``value`` must be a (min, max) pair with low <= min <= max <= high."""
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a (min, max) pair within [{low}, {high}], got {value!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise ValueError(f"{name} must be finite, got {value!r}")
    if lo > hi:
        raise ValueError(f"{name}: min {lo} > max {hi}; expected min <= max within [{low}, {high}]")
    if lo < low or hi > high:
        raise ValueError(f"{name} must lie within [{low}, {high}], got {value!r}")
    return lo, hi


def check_choice(name: str, value: str, choices: Sequence[str]) -> str:
    if not isinstance(value, str):  # (an array would compare element-wise)
        raise TypeError(f"{name} must be one of {list(choices)} (a str), got {_shown(value)}")
    if value not in choices:
        raise ValueError(f"{name} must be one of {list(choices)}, got {value!r}")
    return value


# --- typed checks ------------------------------------------------------------------------------
def _shown(value) -> str:
    """``value``'s repr (shortened) and type, for error messages."""
    return f"{reprlib.repr(value)} ({type(value).__name__})"


def _is_bool(value) -> bool:
    return isinstance(value, (bool, np.bool_))


def _is_real(value) -> bool:
    # True is an int to Python, not a number of metres or steps.
    return isinstance(value, numbers.Real) and not _is_bool(value)


def _is_sequence(value) -> bool:
    """A list, tuple or 1-D array; not a str (a sequence of characters)."""
    if isinstance(value, np.ndarray):
        return value.ndim == 1
    return isinstance(value, Sequence) and not isinstance(value, (str, bytes))


def check_bool(name: str, value) -> bool:
    """``value`` must be True or False (a numpy bool too): ``bool("False")`` is True, so nothing else."""
    if not _is_bool(value):
        raise TypeError(f"{name} must be a bool (True or False), got {_shown(value)}")
    return bool(value)


def check_float(name: str, value, low: float = -math.inf, high: float = math.inf,
                low_open: bool = False) -> float:
    """``value`` must be a real number (not a bool or a str), finite, in [low, high] (or (low, high])."""
    if not _is_real(value):
        bounded = low > -math.inf or high < math.inf
        interval = f" in {'(' if low_open else '['}{low}, {high}]" if bounded else ""
        raise TypeError(f"{name} must be a finite number{interval}, got {_shown(value)}")
    return check_number(name, value, low, high, low_open)


def check_int(name: str, value, low: float = -math.inf, high: float = math.inf) -> int:
    """``value`` must be an integer in [low, high]; a float only with an integral value (4.0, not 2.5:
    no truncation)."""
    if not _is_real(value):
        raise TypeError(f"{name} must be an integer in [{low}, {high}], got {_shown(value)}")
    if not (isinstance(value, numbers.Integral) or float(value).is_integer()):
        raise ValueError(f"{name} must be an integer in [{low}, {high}], got {value!r}")
    if not low <= value <= high:
        raise ValueError(f"{name} must lie in [{low}, {high}], got {value!r}")
    return int(value)


def check_numbers(name: str, value, low: float = -math.inf, high: float = math.inf,
                  length: int | None = None) -> tuple[float, ...]:
    """``value`` must be a non-empty list, tuple or 1-D array of real numbers within [low, high]
    (``length`` of them if given)."""
    what = f"a sequence of {'' if length is None else f'{length} '}numbers within [{low}, {high}]"
    if not _is_sequence(value) or not all(_is_real(v) for v in value):
        raise TypeError(f"{name} must be {what}, got {_shown(value)}")
    if len(value) == 0 or (length is not None and len(value) != length):
        raise ValueError(f"{name} must be {what}, got {value!r}")
    numbers_ = tuple(float(v) for v in value)
    if not all(math.isfinite(v) and low <= v <= high for v in numbers_):
        raise ValueError(f"{name} must be {what}, got {value!r}")
    return numbers_


def check_pair(name: str, value, low: float = -math.inf, high: float = math.inf,
               integer: bool = False) -> tuple:
    """``value`` must be a (min, max) pair of numbers (integers with ``integer``), low <= min <= max <= high."""
    kind = "integers" if integer else "numbers"
    if not _is_sequence(value) or len(value) != 2 or not all(_is_real(v) for v in value):
        raise TypeError(f"{name} must be a (min, max) pair of {kind} within [{low}, {high}], got {_shown(value)}")
    if integer:
        return tuple(check_int(name, v, low, high) for v in check_range(name, value, low, high))
    return check_range(name, value, low, high)


def check_str(name: str, value) -> str:
    """``value`` must be a non-empty str."""
    if not isinstance(value, str):
        raise TypeError(f"{name} must be a str, got {_shown(value)}")
    if not value.strip():
        raise ValueError(f"{name} must not be empty, got {value!r}")
    return value


def check_mapping(name: str, value, allowed: Sequence[str]) -> dict:
    """``value`` must be a mapping whose keys are among ``allowed`` (the fields of a config)."""
    if not isinstance(value, Mapping):
        raise TypeError(f"{name} must be a dict of {list(allowed)}, got {_shown(value)}")
    unknown = [key for key in value if key not in allowed]
    if unknown:
        raise TypeError(f"{name} has unknown keys {unknown}; valid keys: {list(allowed)}")
    return dict(value)


def check_grid(names: tuple[str, str], sizes: Sequence[float], cell_size: float, max_cells: int,
               bytes_per_cell: float) -> int:
    """A grid of ``size / cell_size + 1`` samples along each of ``sizes``: its cell count must not pass
    ``max_cells`` (the error names both keywords and the memory the grid would need). Returns the count."""
    per_axis = [round(size / cell_size) + 1 for size in sizes]
    cells = math.prod(per_axis)
    if cells > max_cells:
        raise ValueError(
            f"{names[0]}={_plain(sizes)} with {names[1]}={cell_size!r} makes a "
            f"{' x '.join(map(str, per_axis))} grid ({cells:.3g} cells, ~{_bytes(cells * bytes_per_cell)}); "
            f"at most {max_cells:.3g} cells (~{_bytes(max_cells * bytes_per_cell)}) are allowed: "
            f"raise {names[1]} or lower {names[0]}")
    return cells


def _plain(sizes: Sequence[float]):
    return sizes[0] if len(set(sizes)) == 1 else tuple(sizes)


def _bytes(n: float) -> str:
    return f"{n / 2**30:.3g} GB" if n >= 2**30 else f"{n / 2**20:.3g} MB"
