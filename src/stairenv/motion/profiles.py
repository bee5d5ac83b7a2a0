"""Smooth 0 -> 1 profiles of the synthesised clips' keyframed paths."""

from __future__ import annotations

import numpy as np

__all__ = ["bump", "smoothstep"]


def smoothstep(u: np.ndarray) -> np.ndarray:
    """Quintic 0 -> 1 on [0, 1] with zero slope and curvature at both ends (clamped outside)."""
    u = np.clip(u, 0.0, 1.0)
    return u * u * u * (10.0 - 15.0 * u + 6.0 * u * u)


def bump(phase: np.ndarray, share: float) -> np.ndarray:
    """Rises over the first ``share`` of ``phase`` in [0, 1], falls over the last."""
    return smoothstep(phase / share) * smoothstep((1.0 - phase) / share)
