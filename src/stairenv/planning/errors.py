"""Errors raised by the planner and the instruction parser, and keyword checks."""

from __future__ import annotations

import math
import reprlib

import numpy as np

#: Why a goal could not be reached (``PlanningError.reason``).
REASONS = ("blocked", "ceiling", "slope", "ceiling+slope", "budget", "speed")

#: The most characters of a user's text an error message quotes (``quote``).
QUOTE_CHARS = 80

#: The most samples one sampler builds (a followed path, waypoints, a collision prediction's times, a
#: resampled polyline): 8 MB an array of floats. A path sampled every 0.1 s reaches it after 27.8 hours.
MAX_SAMPLES = 1_000_000


def quote(value: object, limit: int = QUOTE_CHARS) -> str:
    """``repr(value)`` for an error message, at most about ``limit`` characters: a longer text is cut
    after ``limit`` characters, with an ellipsis and its whole length (``'walk to the ...'... (1,048,576
    characters)``), so a message never echoes a megabyte of input."""
    if isinstance(value, str):
        if len(value) <= limit:
            return repr(value)
        return f"{value[:limit]!r}... ({len(value):,} characters)"
    shortener = reprlib.Repr()   # never builds the whole repr of a huge list
    shortener.maxstring = shortener.maxother = limit
    shortener.maxlist = shortener.maxtuple = shortener.maxset = shortener.maxdict = shortener.maxarray = 20
    text = shortener.repr(value)
    return text if len(text) <= limit else f"{text[:limit]}..."


def check_samples(name: str, span: float, step: float, unit: str = "s", limit: int = MAX_SAMPLES) -> int:
    """The number of samples every ``step`` over ``span`` (``ceil(span / step) + 1``), else ValueError
    naming ``name`` when ``span`` is not a finite number >= 0 or the count is over ``limit``: checked
    before anything is allocated (a duration of 7e10 s, or a step of 1e-12, would ask for terabytes)."""
    span, step = float(span), float(step)
    if not (math.isfinite(span) and span >= 0.0):
        raise ValueError(f"{name} must be a finite number >= 0 ({unit}), got {span!r}")
    count = span / step if step > 0.0 else math.inf
    if not count + 1.0 <= limit:
        raise ValueError(f"{name}: {span:g} {unit} sampled every {step:g} {unit} would need {count + 1.0:.3g} "
                         f"samples; at most {limit:,} are built")
    return int(math.ceil(count)) + 1


class PlanningError(RuntimeError):
    """No feasible plan.

    ``reason`` is one of :data:`REASONS`:

    - ``"blocked"``: walls (or the body's clearance from them, or a dynamic obstacle) cut every route;
    - ``"ceiling"``: every route passes under a ceiling too low for the locomotion
      (reachable once ceilings are ignored);
    - ``"slope"``: every route needs a slope or step steeper than allowed
      (reachable once slopes are ignored);
    - ``"ceiling+slope"``: reachable only if both are ignored;
    - ``"budget"``: the search stopped at ``max_expansions`` before it could decide;
    - ``"speed"``: the speed QP has no solution (e.g. a start speed too high to brake from).
    """

    def __init__(self, reason: str, message: str) -> None:
        if reason not in REASONS:
            raise ValueError(f"reason must be one of {REASONS}, got {reason!r}")
        super().__init__(message)
        self.reason = reason


class InstructionError(ValueError):
    """An instruction the parser cannot read: unknown landmark or locomotion verb, or bad grammar."""


def check_range(name: str, value: float, low: float = -math.inf, high: float = math.inf, *,
                low_open: bool = False, high_open: bool = False) -> float:
    """``float(value)`` if it lies in the interval, else ValueError naming ``name`` and the interval."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        x = math.nan
    ok = not math.isnan(x)
    ok = ok and (x > low if low_open else x >= low) and (x < high if high_open else x <= high)
    if not ok:
        interval = f"{'(' if low_open else '['}{low}, {high}{')' if high_open else ']'}"
        raise ValueError(f"{name} must be a number in {interval}, got {quote(value)}")
    return x


def check_cells(name: str, cells: object, shape: tuple[int, int]) -> np.ndarray:
    """``cells`` as a non-empty (K, 2) int64 array of (i, j) cells of a grid of ``shape``
    (one cell may be given as a pair), else ValueError naming ``name`` and the valid rows and columns."""
    array = np.asarray(cells)
    if array.size == 0:
        raise ValueError(f"{name} must hold at least one (i, j) cell, got none")
    if array.ndim == 1 and array.size == 2:
        array = array.reshape(1, 2)
    if array.ndim != 2 or array.shape[1] != 2:
        raise ValueError(f"{name} must be (i, j) grid cells, an array of shape (K, 2), got shape {array.shape}")
    integral = array.dtype.kind in "iu" or (
        array.dtype.kind == "f" and bool(np.all(np.isfinite(array))) and bool(np.all(array == np.round(array))))
    if not integral:
        raise ValueError(f"{name} must be integer (i, j) cell indices, got {array.dtype} values")
    rows, cols = shape
    # checked before the cast: -1 would wrap to the far corner, a huge float would overflow
    outside = (array[:, 0] < 0) | (array[:, 0] >= rows) | (array[:, 1] < 0) | (array[:, 1] >= cols)
    if outside.any():
        first = tuple(array[np.argmax(outside)].tolist())
        raise ValueError(f"{name} cells must lie in rows 0..{rows - 1} and columns 0..{cols - 1} of the grid; "
                         f"{int(outside.sum())} of {len(array)} do not, e.g. {first}")
    return array.astype(np.int64)
