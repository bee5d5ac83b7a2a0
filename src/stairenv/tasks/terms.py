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

from collections.abc import Callable, Sequence
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
