"""A success-driven curriculum over one terrain parameter (training aid).

The range of the parameter (InterLevel: the step height) is split into ``levels`` equal bands; each
world holds a level and draws its episodes from that band. After an episode that counts, the world
moves up a level on success (or past ``promote_at`` of the way) and down one when the episode ended
below ``demote_below`` of the way, as the terrain curricula of legged-robot training do (Rudin et al.
2021, which promote past half of the terrain and demote below half of the commanded distance). A
success at the top level sends the world to a random level, so that a trained population spreads
over the whole range and training ends on the full distribution rather than on its hardest band.
"""

from __future__ import annotations

import numpy as np

#: An episode that ends below this progress (0 = floor, 1 = landing) without success moves down.
DEMOTE_BELOW = 0.5


def level_band(level: int, levels: int, low: float, high: float) -> tuple[float, float]:
    """The sub-range of [low, high] that ``level`` (0 = easiest) of ``levels`` draws from."""
    if not 0 <= level < levels:
        raise ValueError(f"level must be in [0, {levels - 1}], got {level}")
    width = (high - low) / levels
    return (low + level * width, low + (level + 1) * width)


def next_level(level: int, levels: int, success: bool, progress: float, rng: np.random.Generator,
               demote_below: float = DEMOTE_BELOW, promote_at: float | None = None) -> int:
    """The level after an episode with this outcome: up on success or, with ``promote_at``, at that
    progress (at the top: a random level); down when it ended below ``demote_below`` progress without
    either; else the same."""
    if success or (promote_at is not None and progress >= promote_at):
        return int(rng.integers(levels)) if level == levels - 1 else level + 1
    if progress < demote_below:
        return max(level - 1, 0)
    return level


def initial_level(levels: int, rng: np.random.Generator) -> int:
    """A world's first level: uniform over the easier half (the levels below ``levels // 2`` and that one)."""
    return int(rng.integers(levels // 2 + 1))


# --- a growing range (SIMS: the start distance from the furniture) ------------------------------------
#: Env keywords that turn on a level curriculum (their worlds hold ``curriculum_level``): what a trainer
#: logs as ``curriculum/level`` and saves with its checkpoints.
LEVEL_KEYWORDS = ("step_height_levels", "start_distance_levels", "speed_levels")
#: Env keywords that make a world's level a tuple (one per kind, e.g. per locomotion) instead of an int.
PER_KIND_KEYWORDS = ("speed_levels_by_locomotion",)


def growing_range(level: int, levels: int, low: float, high: float) -> tuple[float, float]:
    """The range ``level`` (0 = easiest) of ``levels`` draws from when the range grows with the level:
    [low, low + (level + 1) / levels of the way to high]; the top level draws from all of [low, high]."""
    if not 0 <= level < levels:
        raise ValueError(f"level must be in [0, {levels - 1}], got {level}")
    return (low, low + (level + 1) * (high - low) / levels)


def next_growing_level(level: int, levels: int, success: bool, progress: float,
                       demote_below: float = DEMOTE_BELOW) -> int:
    """The level of a growing range after an episode: up on success (the top level stays: it already
    draws from the whole range); down when it ended below ``demote_below`` progress without success;
    else the same. No random draw."""
    if success:
        return min(level + 1, levels - 1)
    if progress < demote_below:
        return max(level - 1, 0)
    return level
