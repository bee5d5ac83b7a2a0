"""Foot contact states of synthesised clips and the clip ``meta`` made from them
(``stance_frames``, ``push_off_frames``)."""

from __future__ import annotations

import numpy as np

from stairenv.humanoid import FOOT_BODIES

__all__ = ["FLAT", "PUSH_OFF", "SWINGING", "clip_meta", "contact_ranges"]

# Contact states of a foot.
SWINGING, FLAT, PUSH_OFF = 0, 1, 2


def contact_ranges(contact: np.ndarray, state: int) -> dict[str, list[list[int]]]:
    """Inclusive [first, last] frame ranges in which each foot is in contact ``state``."""
    out: dict[str, list[list[int]]] = {}
    for side, body in enumerate(FOOT_BODIES):
        flags = np.concatenate(([False], contact[:, side] == state, [False]))
        edges = np.flatnonzero(np.diff(flags.astype(int)))
        out[body] = [[int(a), int(b) - 1] for a, b in zip(edges[::2], edges[1::2])]
    return out


def clip_meta(generator: str, params: dict, contact: np.ndarray, **extra) -> dict:
    """A clip's ``meta``: generator, parameters, the frames each foot is planted flat and rolls over
    its toe (``contact``: (T, 2) contact states), and ``extra``."""
    return {
        "generator": generator,
        "parameters": params,
        "stance_frames": contact_ranges(contact, FLAT),
        "push_off_frames": contact_ranges(contact, PUSH_OFF),
        **extra,
    }
