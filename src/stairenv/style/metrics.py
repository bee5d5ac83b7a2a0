"""Discriminator-free measures of how close agent motion is to the reference motion.

An AMP discriminator keeps training against the policy, so the style reward it
gives during training is a moving yardstick: it can stay flat while the motion
improves. These measures are fixed: they compare agent windows with the
reference windows themselves, so checkpoints of one run can be ranked.
"""

from __future__ import annotations

import numpy as np
import torch

from stairenv.style.reference import ReferenceWindows

#: Floor of the per-number reference spread used for standardising (numbers that never
#: vary in the reference would otherwise turn a tiny difference into a huge distance).
MIN_SPREAD = 0.01


def reference_spread(reference: ReferenceWindows | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard deviation of every number of the reference windows (std floored at MIN_SPREAD)."""
    windows = _windows(reference)
    return windows.mean(axis=0), np.maximum(windows.std(axis=0), MIN_SPREAD)


def nearest_reference_distance(windows: np.ndarray, reference: ReferenceWindows | np.ndarray,
                               chunk: int = 4096) -> np.ndarray:
    """For each agent window, the distance to the nearest reference window.

    Both are standardised by the reference's mean and spread (``reference_spread``),
    and the distance is the root mean square over the window's numbers, so 1.0 means
    "one reference standard deviation per number, on average". A window taken from
    the reference has distance 0. ``windows``: (N, D) motion windows as in
    ``info["amp_obs"]`` (without a text condition); returns (N,) float64.
    """
    ref = _windows(reference)
    windows = np.asarray(windows, dtype=np.float64)
    if windows.ndim != 2 or windows.shape[1] != ref.shape[1]:
        raise ValueError(f"windows must have shape (N, {ref.shape[1]}) like the reference windows, "
                         f"got {windows.shape}")
    if not np.all(np.isfinite(windows)):
        raise ValueError("windows must be finite")
    mean, spread = reference_spread(ref)
    ref_t = torch.from_numpy((ref - mean) / spread)
    out = np.empty(len(windows))
    for start in range(0, len(windows), chunk):
        part = torch.from_numpy((windows[start:start + chunk] - mean) / spread)
        out[start:start + chunk] = torch.cdist(part, ref_t).min(dim=1).values.numpy()
    return out / np.sqrt(ref.shape[1])


def _windows(reference: ReferenceWindows | np.ndarray) -> np.ndarray:
    windows = reference.windows if isinstance(reference, ReferenceWindows) else reference
    windows = np.asarray(windows, dtype=np.float64)
    if windows.ndim != 2 or len(windows) == 0:
        raise ValueError(f"reference windows must be a non-empty (N, D) array, got shape {windows.shape}")
    return windows


def rollout_windows(policy, env, episodes: int, seed: int = 0, max_steps: int | None = None
                    ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """Run ``policy`` (obs -> action) for ``episodes`` episodes (seeds seed, seed + 1, ...).

    Returns every step's ``info["amp_obs"]`` (what the AMP wrappers score), the matching
    ``info["amp_condition"]`` rows (None if the env gives none) and the episode lengths.
    ``max_steps`` ends an episode early (None: the env's own limit).
    """
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    windows, conditions, lengths = [], [], []
    for episode in range(episodes):
        if hasattr(policy, "reset"):
            policy.reset(seed + episode)
        obs, _ = env.reset(seed=seed + episode)
        steps, done = 0, False
        while not done:
            obs, _, terminated, truncated, info = env.step(policy(obs))
            steps += 1
            windows.append(np.asarray(info["amp_obs"], dtype=np.float32).ravel())
            if "amp_condition" in info:
                conditions.append(np.asarray(info["amp_condition"], dtype=np.float32).ravel())
            done = terminated or truncated or (max_steps is not None and steps >= max_steps)
        lengths.append(steps)
    return np.stack(windows), (np.stack(conditions) if conditions else None), np.asarray(lengths)
