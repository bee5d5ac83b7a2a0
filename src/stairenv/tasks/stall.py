"""Stall termination (a training aid): end an episode that has stopped approaching its goal.

Standing still can pay well under a style reward (it looks like the reference's idle frames), so a
policy may settle there long before it learns to reach the goal; ending such episodes takes that
return away. The watch keeps the distance of the episode's last real approach (the first: its
start) and the step it was reached; a distance at least ``distance`` below it is a new approach.
More than ``seconds`` without one is a stall.
"""

from __future__ import annotations

import math


class StallWatch:
    """Per-episode stall clock: ``restart()`` at an episode's start, then ``stalled(distance, step)``
    once a step (``step`` counts the episode's steps, ``dt`` seconds each)."""

    def __init__(self, seconds: float | None, distance: float, dt: float) -> None:
        self.seconds, self.distance, self.dt = seconds, distance, dt
        self.restart()

    def restart(self) -> None:
        self.approach_distance, self.approach_step = math.inf, 0

    def stalled(self, distance: float, step: int) -> bool:
        """Whether no approach of ``self.distance`` happened for more than ``seconds`` (False without
        ``seconds``); ``distance`` is the step's distance to the goal."""
        if distance < self.approach_distance - self.distance or self.approach_distance == math.inf:
            self.approach_distance, self.approach_step = distance, step
        return self.seconds is not None and (step - self.approach_step) * self.dt > self.seconds
