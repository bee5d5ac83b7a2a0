"""Reference-state initialisation (RSI): start episodes from frames of reference motion.

``load_reference_library(source)`` gives the clips an env starts from and the
discriminator learns from: a folder or list of ``.npz`` clips, or a built-in set
synthesised in about a second and cached per process: ``None`` / ``"builtin:stairs"``
(``stairenv.motion.synthesis``: flat walks and stair ascents for step heights
0.05-0.20 m) or ``"builtin:sims"`` (the flat walks, a walk in each of the eight SIMS
styles (``synthesis.WALK_STYLES``) and ``stairenv.motion.interactions``' sit, stand-up,
lie, get-up, reach and idle clips); or ``"builtin:plamo"`` (``stairenv.motion.plamo_set``:
converted and synthesised crawls, crouch-walks, walks and runs that ship inside the package,
each labelled with its locomotion type and head height, every type weighted equally).
``level_clips`` / ``standing_clips`` pick the clips a start may be drawn from (a stair
climb's frame on flat ground would start with a foot on no step).
A sampled frame is put at a start position and heading, its lowest point just
above the floor, by ``stairenv.humanoid.placement.place_reference_state``.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

from stairenv.motion.library import MotionLibrary

BUILTIN_REFERENCE_SETS = ("builtin:stairs", "builtin:sims", "builtin:plamo")

# Clips of these meta["skill"] values start standing up: the ones standing starts are drawn from.
STANDING_SKILLS = ("walk", "idle")


@lru_cache(maxsize=8)
def _load_cached(source: str | None, include_descents: bool) -> MotionLibrary:
    from stairenv.motion.synthesis import reference_set

    if source is None or source == "builtin:stairs":
        return MotionLibrary(reference_set(descents=include_descents))
    if source == "builtin:plamo":
        from stairenv.motion.plamo_set import load_plamo_clips, plamo_weights

        clips = load_plamo_clips()
        return MotionLibrary(clips, plamo_weights(clips))
    if source == "builtin:sims":
        from stairenv.motion.interactions import interaction_reference_set
        from stairenv.motion.synthesis import WALK_STYLES, styled_walk

        styled = [styled_walk(name, lead_foot=("right", "left")[i % 2])
                  for i, name in enumerate(WALK_STYLES) if name != "neutral"]
        return MotionLibrary(reference_set(step_heights=(), descents=False) + styled + interaction_reference_set())
    if source.startswith("builtin:"):
        raise ValueError(f"reference_motion {source!r} is not a built-in set; known: {list(BUILTIN_REFERENCE_SETS)}")
    return MotionLibrary.load(source)


def load_reference_library(source: str | Path | None = None, include_descents: bool = False) -> MotionLibrary:
    """Clips from a folder or ``.npz`` file, or a built-in synthesised set (``None``: the stairs set;
    one of :data:`BUILTIN_REFERENCE_SETS`)."""
    return _load_cached(None if source is None else str(source), include_descents)


def standing_clips(library: MotionLibrary) -> MotionLibrary:
    """The clips that stand on the floor throughout (``meta["skill"]`` in :data:`STANDING_SKILLS`, or no
    skill given), keeping their weights: where a standing start may be drawn from."""
    keep = [i for i, clip in enumerate(library.clips) if clip.meta.get("skill", "walk") in STANDING_SKILLS]
    if not keep:
        raise ValueError("the reference motion has no standing clip (meta['skill'] walk or idle) to start from")
    if len(keep) == len(library.clips):
        return library
    return MotionLibrary([library.clips[i] for i in keep], library.probabilities[keep])


#: Root height range (m) below which a clip counts as moving on level ground.
LEVEL_MAX_RISE = 0.1


def level_clips(library: MotionLibrary, max_rise: float = LEVEL_MAX_RISE) -> MotionLibrary:
    """The clips that stay on level ground (``meta["terrain"] == "flat"``, or else a root height
    range below ``max_rise`` m), keeping their weights: the frames a start on a floor may be drawn
    from. A stair climb's frame placed on flat ground would start with a foot in the air on no step
    (and fall); a run's or a crawl's root rises and falls more than a walk's on flat ground."""
    keep = [i for i, clip in enumerate(library.clips)
            if clip.meta.get("terrain") == "flat" or float(np.ptp(clip.qpos[:, 2])) < max_rise]
    if not keep:
        raise ValueError(f"the reference motion has no clip on level ground (root height range < {max_rise} m) "
                         "to start episodes from; use init='default'")
    if len(keep) == len(library.clips):
        return library
    return MotionLibrary([library.clips[i] for i in keep], library.probabilities[keep])
