"""Pushes: robustness to a kick, one home for every evaluator (InterLevel, PlaMo Table 2, SIMS skills).

With ``push_speed`` V > 0 each evaluation episode's character is kicked once: V m/s of horizontal
velocity added to its root (``apply_push``) before a policy step drawn from ``PUSH_STEPS`` (30-179,
1-6 s in at 30 steps a second), in a direction drawn uniformly. Both come from the episode's seed
alone (``push_plan``, on its own random stream ``PUSH_STREAM``, apart from the env's), so every
policy meets the same push in the same episode, whatever it does. The push comes only while the
episode runs: an episode that ends (a fall, a success that ends it, the time limit) before its push
step gets none (:class:`EpisodePush` records whether it came).

An evaluator keeps one :class:`EpisodePush` per episode and calls its ``before_step`` with the
unwrapped env and the steps taken so far before every ``env.step``::

    push = EpisodePush(seed, push_speed)
    obs, info = env.reset(seed=seed)
    steps = 0
    while True:
        push.before_step(env.unwrapped, steps)
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        steps += 1
        ...
    push.step, push.angle   # where and which way it came; None, None if it did not
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from stairenv.humanoid.state import push_root

#: the steps (policy steps, 30 per second) between which an episode's push comes: 1 to 6 s in
PUSH_STEPS: tuple[int, int] = (30, 180)
#: the stream of the episode's push draws (its step and direction), apart from the env's own rng:
#: every policy meets the same push in the same episode
PUSH_STREAM = 0x9055
#: the highest push speed an evaluator takes (m/s)
MAX_PUSH_SPEED = 10.0

#: the ``--push-speed`` help of the evaluation scripts (one wording for all of them)
PUSH_HELP = ("kick each episode's character once: V m/s of horizontal velocity added to its root in a random "
             "direction before a random policy step 30-179 (1-6 s in), both drawn from the episode's seed alone "
             "(the same push for every policy); an episode that ends before its push step gets none "
             "(default: %(default)s, no push)")


def check_push_speed(push_speed: Any) -> float:
    """``push_speed`` as a float, checked: a number of m/s in [0, ``MAX_PUSH_SPEED``] (``ValueError`` naming
    ``push_speed`` otherwise)."""
    if isinstance(push_speed, bool) or not isinstance(push_speed, (int, float, np.integer, np.floating)) or not (
            0.0 <= float(push_speed) <= MAX_PUSH_SPEED):
        raise ValueError(f"push_speed must be a speed in [0, {MAX_PUSH_SPEED:g}] m/s, got {push_speed!r}")
    return float(push_speed)


def push_plan(seed: int, speed: float) -> tuple[int, float] | None:
    """The push of the episode reset with ``seed``: (step, direction in rad), drawn from the episode's
    seed alone (``PUSH_STREAM``); None without a push (``speed`` 0)."""
    if speed <= 0.0:
        return None
    rng = np.random.default_rng([int(seed), PUSH_STREAM])
    return int(rng.integers(*PUSH_STEPS)), float(rng.uniform(-math.pi, math.pi))


#: a horizontal velocity kick of ``speed`` (m/s) in direction ``angle`` (rad) added to the root's velocity;
#: its home is :func:`stairenv.humanoid.state.push_root`, which the envs' training pushes use too
apply_push = push_root


class EpisodePush:
    """One episode's push (``push_plan(seed, speed)``), applied at most once, at its planned step."""

    def __init__(self, seed: int, speed: float) -> None:
        self.speed = float(speed)
        self.plan = push_plan(seed, self.speed)
        self.came = False

    def before_step(self, env: Any, steps: int) -> bool:
        """Apply the push if it is due before the step about to run (``steps``: the steps taken so far in
        this episode; ``env``: the unwrapped env, its ``model`` and ``data``). True when it came now."""
        if self.plan is None or self.came or steps != self.plan[0]:
            return False
        apply_push(env.model, env.data, self.speed, self.plan[1])
        self.came = True
        return True

    @property
    def step(self) -> int | None:
        """The step before which the push came, None if it did not (no push, or the episode ended first)."""
        return self.plan[0] if self.came else None

    @property
    def angle(self) -> float | None:
        """Its direction in the world's xy plane (rad), None if it did not come."""
        return self.plan[1] if self.came else None


def push_meta(speed: float, pushed: int) -> dict[str, Any]:
    """The settings an evaluation with pushes records (nothing without: ``speed`` 0): the speed, the
    window of steps and how many episodes the push reached."""
    if speed <= 0.0:
        return {}
    return {"push_speed": float(speed), "push_steps": list(PUSH_STEPS), "pushed": int(pushed)}


def push_summary(settings: Mapping[str, Any], episodes: int) -> str | None:
    """The line an evaluation script prints under its table with pushes (from :func:`push_meta`'s
    settings), None without."""
    if not settings.get("push_speed"):
        return None
    return (f"pushes: {settings['push_speed']:g} m/s, {settings['pushed']} of {episodes} episodes pushed "
            "(an episode that ended before its push step got none)")


__all__ = [
    "MAX_PUSH_SPEED", "PUSH_HELP", "PUSH_STEPS", "PUSH_STREAM", "EpisodePush", "apply_push", "check_push_speed",
    "push_meta", "push_plan", "push_summary",
]
