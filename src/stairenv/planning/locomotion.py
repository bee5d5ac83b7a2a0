"""The locomotion table: every locomotion's words, head heights and speeds, in one place.

PlaMo (Sec. 3.2, Fig. 7) requests crawling with a head height of 0.4 m, crouch-walking
with 0.8 m, walking and running upright at 1.47 m (the SMPL character's head), at
speeds of about 1, 2 and 4 m/s; its path generator couples the highest speed to the
head height, v_max(z) = min(1 + 4 (z - 0.4) / (1.2 - 0.4), 5) m/s. This table reads
those numbers as ranges:

============  ===================  ===========  ==========  ===================================
name          head height (m)      nominal (m)  speed (m/s)  words
============  ===================  ===========  ==========  ===================================
crawl         0.30 .. 0.50         0.40         0.2 .. 1.0  crawl, crawling, crawls, creep
crouch-walk   0.65 .. 0.95         0.80         0.3 .. 2.0  crouch, crouching, crouch-walk, ...
walk          1.25 .. 1.47         1.47         0.5 .. 2.0  walk, walking, go, stroll, ...
run           1.35 .. 1.47         1.47         2.0 .. 4.0  run, running, jog, ...
sprint        1.40 .. 1.47         1.47         4.0 .. 5.0  sprint, sprinting, dash, rush
============  ===================  ===========  ==========  ===================================

- The head height range is what the locomotion can do: the planner keeps the head at
  most at the nominal height and ducks under ceilings, but not below the range's low end
  (a ceiling needs ``head_min + ceiling_margin`` of headroom to be passable).
- The speed range's high end is the speed QP's upper bound; the low end is the slowest
  speed the style is meant for (the QP starts and ends at rest, so it only reports it).
- sprint's 5 m/s is PlaMo's V_max.
- Over each locomotion's head range its top speed never exceeds PlaMo's coupled
  v_max(z) (``stairenv.tasks.plamo.coupled_max_speed``; tested), so a plan that ducks
  within the range obeys the coupling without a separate head-height bound in the QP.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import quote


@dataclass(frozen=True)
class Locomotion:
    name: str
    head_min: float          # lowest head height the locomotion can hold (m)
    head_height: float       # nominal head height (m), also the highest
    speed_min: float         # slowest cruising speed (m/s)
    speed_max: float         # fastest speed (m/s), the QP's bound
    words: tuple[str, ...]   # words of an instruction that request it

    @property
    def speed_range(self) -> tuple[float, float]:
        return (self.speed_min, self.speed_max)

    @property
    def head_range(self) -> tuple[float, float]:
        return (self.head_min, self.head_height)


LOCOMOTIONS: dict[str, Locomotion] = {
    loc.name: loc
    for loc in (
        Locomotion("crawl", 0.30, 0.40, 0.2, 1.0, ("crawl", "crawls", "crawling", "crawled", "creep", "creeping")),
        Locomotion("crouch-walk", 0.65, 0.80, 0.3, 2.0,
                   ("crouch-walk", "crouch-walking", "crouch", "crouches", "crouching", "crouched",
                    "duck", "ducking", "stoop", "stooping", "sneak", "sneaking")),
        Locomotion("walk", 1.25, 1.47, 0.5, 2.0,
                   ("walk", "walks", "walking", "walked", "go", "goes", "going", "stroll", "strolling", "amble")),
        Locomotion("run", 1.35, 1.47, 2.0, 4.0, ("run", "runs", "running", "ran", "jog", "jogs", "jogging")),
        Locomotion("sprint", 1.40, 1.47, 4.0, 5.0, ("sprint", "sprints", "sprinting", "dash", "dashing", "rush")),
    )
}

#: word -> locomotion name, derived from the table.
LOCOMOTION_WORDS: dict[str, str] = {word: loc.name for loc in LOCOMOTIONS.values() for word in loc.words}


def get_locomotion(locomotion: str | Locomotion) -> Locomotion:
    """The table entry for a name (or any of its words); a ``Locomotion`` passes through."""
    if isinstance(locomotion, Locomotion):
        return locomotion
    key = str(locomotion).strip().lower().replace("_", "-").replace(" ", "-")
    name = LOCOMOTION_WORDS.get(key, key)
    if name not in LOCOMOTIONS:
        raise ValueError(f"locomotion must be one of {sorted(LOCOMOTIONS)} (or a word for one: "
                         f"{sorted(LOCOMOTION_WORDS)}), got {quote(locomotion)}")
    return LOCOMOTIONS[name]


def nearest_locomotion(head_height: float, speed: float, names=None) -> str:
    """The locomotion (of ``names``, default all) a head height and speed ask for: the one whose
    nominal head height is nearest; among those sharing it (walk, run, sprint: upright) the one
    whose speed range holds ``speed``, or is nearest to it. E.g. 0.5 m -> crawl, 0.9 m -> crouch-walk,
    1.3 m at 1 m/s -> walk, at 3 m/s -> run."""
    names = list(LOCOMOTIONS) if names is None else [get_locomotion(n).name for n in names]
    return names[int(locomotion_labels(head_height, speed, names))]


def locomotion_labels(head_height: np.ndarray, speed: np.ndarray, names=None) -> np.ndarray:
    """``nearest_locomotion`` of every (head height, speed) pair at once: indices into ``names`` (default
    all, in the table's order). Ties go to the earlier name; head costs are rounded to 1e-9 so that
    locomotions sharing a nominal height tie exactly."""
    names = list(LOCOMOTIONS) if names is None else [get_locomotion(n).name for n in names]
    if not names:
        raise ValueError("nearest_locomotion needs at least one locomotion to choose from")
    head_height, speed = np.broadcast_arrays(np.asarray(head_height, dtype=np.float64),
                                             np.asarray(speed, dtype=np.float64))
    labels = np.zeros(head_height.shape, dtype=np.intp)
    best_head = best_speed = None
    for i, name in enumerate(names):
        loc = LOCOMOTIONS[name]
        head_cost = np.round(np.abs(loc.head_height - head_height), 9)
        speed_cost = np.maximum(np.maximum(loc.speed_min - speed, 0.0), speed - loc.speed_max)
        if best_head is None:
            best_head, best_speed = head_cost, speed_cost
            continue
        better = (head_cost < best_head) | ((head_cost == best_head) & (speed_cost < best_speed))
        labels[better] = i
        best_head, best_speed = np.where(better, head_cost, best_head), np.where(better, speed_cost, best_speed)
    return labels
