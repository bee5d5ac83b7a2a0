"""Config fields declared once: default, valid range and meaning side by side.

A furniture config is a frozen dataclass whose fields are made by ``ranged`` (a (min, max)
range a builder draws from, every value within hard bounds), ``number`` (one number within
bounds) or ``choice`` (one of a few strings)::

    @config_class
    class ChairConfig(FurnitureConfig):
        seat_height: tuple[float, float] = ranged((0.42, 0.48), 0.25, 0.9, "top of the seat above the floor")

The field's metadata (a ``FieldSpec``) drives both the validation in
``FurnitureConfig.__post_init__`` and the table that ``config_class`` appends to the class
docstring. A subclass may give a field a new plain default; its range and meaning stay those
of the class that declared it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, TypeVar

from stairenv.validation import check_choice, check_number, check_range

SPEC_KEY = "stairenv.world.furniture.spec"


@dataclass(frozen=True)
class FieldSpec:
    """What a config field holds: ``kind`` "range" ((min, max) within [low, high], whole numbers
    if ``integer``), "number" (within [low, high]) or "choice" (one of ``options``), and ``doc``."""

    kind: str
    low: float = 0.0
    high: float = 0.0
    integer: bool = False
    options: tuple[str, ...] = ()
    doc: str = ""

    def valid(self) -> str:
        """The "valid" column of the docstring table."""
        if self.kind == "choice":
            quoted = [f'"{o}"' for o in self.options]
            text = " or ".join((", ".join(quoted[:-1]), quoted[-1])) if len(quoted) > 1 else quoted[0]
        elif self.kind == "range":
            text = f"{'integers ' if self.integer else ''}within [{self.low:g}, {self.high:g}]"
        else:
            text = f"[{self.low:g}, {self.high:g}]"
        return f"{text}: {self.doc}" if self.doc else text


def ranged(default: Sequence[float], low: float, high: float, doc: str = "", *, integer: bool = False) -> Any:
    """A (min, max) range field with ``default``; both ends within [``low``, ``high``] (whole
    numbers if ``integer``). A scalar value x given for it means (x, x)."""
    return dataclasses.field(default=tuple(default),
                             metadata={SPEC_KEY: FieldSpec("range", low, high, integer, (), doc)})


def number(default: float, low: float, high: float, doc: str = "") -> Any:
    """A scalar field with ``default``, within [``low``, ``high``]."""
    return dataclasses.field(default=default, metadata={SPEC_KEY: FieldSpec("number", low, high, False, (), doc)})


def choice(default: str, options: Sequence[str], doc: str = "") -> Any:
    """A field holding one of ``options`` (``default`` first)."""
    return dataclasses.field(default=default, metadata={SPEC_KEY: FieldSpec("choice", options=tuple(options), doc=doc)})


def field_spec(cls: type, name: str) -> FieldSpec | None:
    """The ``FieldSpec`` of field ``name``: from the nearest class in ``cls``'s MRO that declared it."""
    for klass in cls.__mro__:
        declared = vars(klass).get("__dataclass_fields__", {})
        if name in declared and SPEC_KEY in declared[name].metadata:
            return declared[name].metadata[SPEC_KEY]
    return None


def field_specs(cls: type) -> list[tuple[str, FieldSpec]]:
    """(name, spec) of the declared fields of dataclass ``cls``, in field order."""
    specs = ((f.name, field_spec(cls, f.name)) for f in dataclasses.fields(cls))
    return [(name, spec) for name, spec in specs if spec is not None]


class FurnitureConfig:
    """Base of the furniture configs: validates every field by its ``FieldSpec``.

    Ranges are checked first (in field order; a scalar x becomes (x, x)), then numbers, then
    choices; invalid values raise ``ValueError`` naming the field and its valid range.
    """

    def __post_init__(self) -> None:
        specs = field_specs(type(self))
        for name, spec in specs:
            if spec.kind != "range":
                continue
            low, high = spec.low, spec.high
            value = getattr(self, name)
            if isinstance(value, (int, float)):
                value = (value, value)
            lo, hi = check_range(name, value, low, high)
            if spec.integer:
                if int(lo) != lo or int(hi) != hi:
                    raise ValueError(f"{name} must be a (min, max) pair of integers within [{low}, {high}], "
                                     f"got {value!r}")
                lo, hi = int(lo), int(hi)
            object.__setattr__(self, name, (lo, hi))
        for name, spec in specs:
            if spec.kind == "number":
                object.__setattr__(self, name, check_number(name, getattr(self, name), spec.low, spec.high))
        for name, spec in specs:
            if spec.kind == "choice":
                check_choice(name, getattr(self, name), spec.options)


def _show(value: Any) -> str:
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, tuple):
        return "(" + ", ".join(_show(v) for v in value) + ")"
    return f"{value:g}" if isinstance(value, float) else str(value)


def spec_table(cls: type) -> str:
    """The markdown table (field, default, valid) of dataclass ``cls``'s declared fields."""
    rows = ["| field | default | valid |", "|---|---|---|"]
    defaults = {f.name: f.default for f in dataclasses.fields(cls)}
    rows += [f"| {name} | {_show(defaults[name])} | {spec.valid()} |" for name, spec in field_specs(cls)]
    return "\n".join(rows)


_C = TypeVar("_C", bound=type)


def config_class(cls: _C) -> _C:
    """``dataclass(frozen=True)`` that also appends the field table (``spec_table``) to the docstring."""
    cls = dataclass(frozen=True)(cls)
    doc = (cls.__doc__ or "").rstrip()
    table = "\n".join("    " + row for row in spec_table(cls).splitlines())
    cls.__doc__ = f"{doc}\n\n{table}\n    "
    return cls
