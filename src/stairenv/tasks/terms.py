"""Reward terms as named, pure functions with their weights held in one place.

A task's reward is a sum of terms, each reported in ``info`` under its name (``reward_*``). A
``RewardTerm`` names a term, the pure function that computes its unweighted value from the task's
inputs and weights (``function(inputs, weights) -> float``) and the field of the task's frozen
weights dataclass that weighs it; ``weighted_terms`` evaluates a tuple of them, whose entries sum to
the reward. SIMS (``stairenv.tasks.sims``) and PlaMo (``stairenv.tasks.plamo``) are written this
way; InterLevel's terms are compiled (``stairenv.tasks.interlevel``) and take their weights from
``InterLevelReward``, its one place for them.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np


class RewardTerm(NamedTuple):
    """A reward term: its ``info`` key, its unweighted value and the weights' field weighing it."""

    name: str
    function: Callable[[Any, Any], float]
    weight: str


def term_names(terms: Sequence[RewardTerm]) -> tuple[str, ...]:
    return tuple(term.name for term in terms)


def weighted_terms(inputs: Any, weights: Any, terms: Sequence[RewardTerm]) -> np.ndarray:
    """Each term's weight times its value, in ``terms`` order: (len(terms),), summing to the reward."""
    return np.array(weighted_values(inputs, weights, terms))


def weighted_values(inputs: Any, weights: Any, terms: Sequence[RewardTerm]) -> tuple[float, ...]:
    """``weighted_terms`` as a tuple (no array: a per-world step that goes on in Python floats)."""
    return tuple(getattr(weights, term.weight) * term.function(inputs, weights) for term in terms)


@dataclass(frozen=True)
class TrackingReward:
    """The tracking aid's terms (DeepMimic's root, velocity and body-position terms): each term's share of
    the aid's weight and its scale (``tracking_terms``)."""

    root_share: float = 0.4
    velocity_share: float = 0.3
    bodies_share: float = 0.3
    c_root: float = 5.0       # m^-2
    c_velocity: float = 2.0   # (m/s)^-2
    c_bodies: float = 10.0    # m^-2


TRACKING_REWARD = TrackingReward()
TRACKING_TERMS = ("reward_track_root", "reward_track_velocity", "reward_track_bodies")


def tracking_terms(body_pos: np.ndarray, reference_body_pos: np.ndarray, root_vel: np.ndarray,
                   reference_root_vel: np.ndarray, weight: float, root: int = 0,
                   c: TrackingReward = TRACKING_REWARD) -> tuple[float, float, float, float]:
    """A training aid's clip tracking (PlaMo's and SIMS' ``track_reward``), against the reference played on from the start frame and placed
    where the character started (``stairenv.motion.tracking.reference_track``); w = ``weight``:

        root     = w 0.4 exp(-5 |p_root - p^_root|^2)             the pelvis in the world: the clip's travel
        velocity = w 0.3 exp(-2 |v_root - v^_root|^2)             the pelvis' linear velocity (world, m/s)
        bodies   = w 0.3 exp(-10 mean_b |(p_b - p_root) - (p^_b - p^_root)|^2)   the 15 bodies about the pelvis

    and the tracking error mean_b |p_b - p^_b| (m, world), which ``max_track_error`` bounds.
    ``body_pos`` and ``reference_body_pos`` are (15, 3) (``root`` the pelvis' row)."""
    body_pos = np.asarray(body_pos, dtype=np.float64)
    reference_body_pos = np.asarray(reference_body_pos, dtype=np.float64)
    d_root = body_pos[root] - reference_body_pos[root]
    d_vel = np.asarray(root_vel, dtype=np.float64) - np.asarray(reference_root_vel, dtype=np.float64)
    d_bodies = (body_pos - body_pos[root]) - (reference_body_pos - reference_body_pos[root])
    root_term = weight * c.root_share * math.exp(-c.c_root * float(d_root @ d_root))
    velocity_term = weight * c.velocity_share * math.exp(-c.c_velocity * float(d_vel @ d_vel))
    bodies_term = weight * c.bodies_share * math.exp(-c.c_bodies * float(np.mean(np.sum(d_bodies ** 2, axis=1))))
    error = float(np.mean(np.linalg.norm(body_pos - reference_body_pos, axis=1)))
    return root_term, velocity_term, bodies_term, error
