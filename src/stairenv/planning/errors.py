"""Errors raised by the planner and the instruction parser, and keyword checks."""

from __future__ import annotations

import math

import numpy as np

#: Why a goal could not be reached (``PlanningError.reason``).
REASONS = ("blocked", "ceiling", "slope", "ceiling+slope", "budget", "speed")


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
        raise ValueError(f"{name} must be a number in {interval}, got {value!r}")
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
