"""Keyword checks that name the parameter, its value and its valid range or type in the error.

The env constructors check every keyword with these: a wrong type raises ``TypeError``
(``bool("False")`` is True and ``int(2.5)`` is 2, so nothing is converted silently), a value
out of range ``ValueError``. ``check_number`` and ``check_range`` take anything ``float()``
takes (config objects built from parsed files); ``check_bool``, ``check_int``, ``check_float``,
``check_numbers``, ``check_pair``, ``check_str`` and ``check_mapping`` also check the type, and
``check_grid`` bounds the memory a grid of samples may ask for.

A config field declares its check once, beside it: ``checked(default, Check(kind, low, high, ...))``;
``check_fields`` runs the checks of a frozen dataclass's fields (``stairenv.environments.config``).
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import reprlib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

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


# --- checks declared beside config fields ----------------------------------------------------------
CHECK_KEY = "stairenv.validation.check"


@dataclass(frozen=True)
class Check:
    """How a config field's value is checked, declared once beside the field (``checked``).

    ``kind`` picks the typed check of this module, with the range or choices given here:

    | kind | check |
    |---|---|
    | "float" | ``check_float`` in [low, high] (``low_open``: (low, high]) |
    | "number" | the type as ``check_float``, then the range as ``check_number`` (a config whose own
      ``__post_init__`` takes anything ``float()`` takes: its message for a value out of range) |
    | "int" | ``check_int`` in [low, high] |
    | "bool" | ``check_bool`` |
    | "choice" | ``check_choice`` among ``options`` |
    | "pair" | ``check_pair`` within [low, high] (``integer``: whole numbers) |
    | "numbers" | ``check_numbers`` within [low, high] |
    | "call" | ``call(value)``, which raises (naming the field) or returns the checked value |

    ``optional``: None is valid too. ``low_from``: the low bound is the checked value of that
    other field (checked before this one). ``keyword``: the name the value is given under, where it
    is not the field's own (errors name it).
    """

    kind: str
    low: float = -math.inf
    high: float = math.inf
    low_open: bool = False
    integer: bool = False
    options: tuple = ()
    optional: bool = False
    call: Callable[[Any], Any] | None = None
    low_from: str | None = None
    keyword: str | None = None

    def __call__(self, name: str, value, low: float | None = None):
        """``value`` checked under ``name`` (converted: a tuple for a pair, an int for 4.0, ...)."""
        if value is None and self.optional:
            return None
        low = self.low if low is None else low
        kind = self.kind
        if kind == "float":
            return check_float(name, value, low, self.high, self.low_open)
        if kind == "number":
            return check_number(name, check_float(name, value), low, self.high, self.low_open)
        if kind == "int":
            return check_int(name, value, low, self.high)
        if kind == "bool":
            return check_bool(name, value)
        if kind == "choice":
            return check_choice(name, value, self.options)
        if kind == "pair":
            return check_pair(name, value, low, self.high, integer=self.integer)
        if kind == "numbers":
            return check_numbers(name, value, low, self.high)
        if kind == "call":
            return self.call(value)
        raise ValueError(f"unknown check kind {kind!r}")

    def valid(self) -> str:
        """The valid values in words (a docstring table's column)."""
        kind, bracket = self.kind, "(" if self.low_open else "["
        low = self.low_from if self.low_from else f"{self.low:g}"
        text = {"float": f"{bracket}{low}, {self.high:g}]", "number": f"{bracket}{low}, {self.high:g}]",
                "int": f"integer in [{low}, {self.high:g}]", "bool": "True or False",
                "choice": " or ".join(f'"{o}"' for o in self.options),
                "pair": f"(min, max) {'integers ' if self.integer else ''}within [{low}, {self.high:g}]",
                "numbers": f"numbers within [{low}, {self.high:g}]", "call": "see the meaning"}[kind]
        return f"{text}, or None" if self.optional else text


def checked(default, check: Check, doc: str = "") -> Any:
    """A dataclass field with ``default`` whose values ``check`` checks (``field_check``)."""
    return dataclasses.field(default=default, metadata={CHECK_KEY: check, "doc": doc})


def field_check(field: dataclasses.Field) -> Check | None:
    """The ``Check`` a field was declared with (``checked``), or None."""
    return field.metadata.get(CHECK_KEY)


def check_fields(config) -> None:
    """Check every ``checked`` field of the frozen dataclass instance ``config`` in field order, under its
    keyword, and store the checked value (a frozen dataclass's ``__post_init__`` calls it)."""
    values = {}
    for field in dataclasses.fields(config):
        check = field_check(field)
        if check is None:
            continue
        low = None if check.low_from is None else values[check.low_from]
        value = check(check.keyword or field.name, getattr(config, field.name), low)
        object.__setattr__(config, field.name, value)
        values[field.name] = value


def checked_config(cls: type) -> type:
    """``dataclass(frozen=True)`` whose ``__post_init__`` runs ``check_fields`` (unless it has its own,
    which then calls it)."""
    if "__post_init__" not in vars(cls):
        cls.__post_init__ = check_fields
    return dataclass(frozen=True)(cls)
