"""The InterScene 2-D navigation reward, the baseline InterLevel compares against.

With p the root position, d the unit horizontal direction to the target and v the
root velocity (from the last policy step), heights ignored:

    far  = 0.5 exp(-0.5 |p_tgt - p|^2) + 0.4 exp(-2 max(0, 1.5 - v.d)^2) + 0.1 max(0, facing.d)
           (far = 1 once |p_tgt - p|^2 < 0.5)
    near = exp(-10 |p_tgt - p|^2)
    r    = 0.7 near + 0.3 far
"""

from __future__ import annotations

import numpy as np

from stairenv.humanoid.state import PELVIS, HumanoidState

TARGET_SPEED = 1.5
NEAR_WEIGHT, FAR_WEIGHT = 0.7, 0.3
FAR_DISTANCE_SQ = 0.5


def interscene_reward(
    prev_root: np.ndarray, root: np.ndarray, heading: np.ndarray, target: np.ndarray, dt: float
) -> tuple[np.ndarray, np.ndarray]:
    """Return (near term, far term), already weighted (0.7, 0.3); the reward is their sum.

    prev_root, root, target: (B, 3) (only x, y used); heading: (B, 2) root forward direction.
    """
    delta = target[:, :2] - root[:, :2]
    dist_sq = np.sum(np.square(delta), axis=-1)
    direction = delta / np.maximum(np.sqrt(dist_sq), 1e-9)[:, None]
    speed = np.sum((root[:, :2] - prev_root[:, :2]) / dt * direction, axis=-1)
    heading = heading / np.maximum(np.linalg.norm(heading, axis=-1, keepdims=True), 1e-9)
    far = (
        0.5 * np.exp(-0.5 * dist_sq)
        + 0.4 * np.exp(-2.0 * np.square(np.maximum(TARGET_SPEED - speed, 0.0)))
        + 0.1 * np.maximum(np.sum(heading * direction, axis=-1), 0.0)
    )
    far = np.where(dist_sq < FAR_DISTANCE_SQ, 1.0, far)
    near = np.exp(-10.0 * dist_sq)
    return NEAR_WEIGHT * near, FAR_WEIGHT * far


REWARD_TERMS: tuple[str, ...] = ("reward_near", "reward_far")


def interscene_reward_terms(
    state: HumanoidState, prev_root: np.ndarray, target: np.ndarray, dt: float
) -> np.ndarray:
    """The InterScene reward of a ``HumanoidState`` as (B, 2) terms in ``REWARD_TERMS`` order."""
    near, far = interscene_reward(
        prev_root, state.body_pos[:, PELVIS], state.body_mat[:, PELVIS, :2, 0], target, dt
    )
    return np.stack((near, far), axis=-1)
