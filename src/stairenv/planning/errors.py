"""Errors raised by the planner and the instruction parser, and keyword checks."""

from __future__ import annotations

import math

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
