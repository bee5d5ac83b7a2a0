"""Stall termination (a training aid): end an episode that has stopped approaching its goal.

Standing still can pay well under a style reward (it looks like the reference's idle frames), so a
policy may settle there long before it learns to reach the goal; ending such episodes takes that
return away. The watch keeps the distance of the episode's last real approach (the first: its
start) and the step it was reached; a distance at least ``distance`` below it is a new approach.
More than ``seconds`` without one is a stall.

``stall_step`` is the rule for one world (compiled): ``StallWatch`` holds one episode's clock and calls
it, and compiled batch kernels (InterLevel's ``interlevel_reward_and_end``) call it for each world's clock.
"""

from __future__ import annotations

import math

import numpy as np

from stairenv.numba_jit import jit


@jit
def stall_step(distance, step, approach_distance, approach_step, min_approach, seconds, dt):
    """One step of the rule: ``(stalled, approach_distance, approach_step)`` after a step at ``distance``
    from the goal, the episode's ``step``-th; ``seconds`` is ``inf`` without the aid."""
    if distance < approach_distance - min_approach or approach_distance == math.inf:
        approach_distance, approach_step = distance, step
    return (step - approach_step) * dt > seconds, approach_distance, approach_step


class StallWatch:
    """Per-episode stall clock: ``restart()`` at an episode's start, then ``stalled(distance, step)``
    once a step (``step`` counts the episode's steps, ``dt`` seconds each). The clock is held in two
    arrays of one entry, ``approach`` (the distance of the last approach) and ``approach_at`` (its step),
    so that a batched env can hold many worlds' clocks as rows of one array each."""

    def __init__(self, seconds: float | None, distance: float, dt: float) -> None:
        self.seconds, self.distance, self.dt = seconds, distance, dt
        self.approach = np.full(1, math.inf)
        self.approach_at = np.zeros(1, dtype=np.int64)

    def restart(self) -> None:
        self.approach[0], self.approach_at[0] = math.inf, 0

    @property
    def approach_distance(self) -> float:
        return float(self.approach[0])

    @approach_distance.setter
    def approach_distance(self, value: float) -> None:
        self.approach[0] = value

    def stalled(self, distance: float, step: int) -> bool:
        """Whether no approach of ``self.distance`` happened for more than ``seconds`` (False without
        ``seconds``); ``distance`` is the step's distance to the goal."""
        stalled, self.approach[0], self.approach_at[0] = stall_step(
            float(distance), int(step), self.approach[0], self.approach_at[0], self.distance,
            math.inf if self.seconds is None else self.seconds, self.dt)
        return stalled
