"""Reference states at a piece of furniture: frames of an interaction clip synthesised for it.

The SIMS analogue of :mod:`stairenv.motion.stair_starts`. A standing start far from the
furniture meets the seat only once the policy has learnt to walk there and turn round; a start
drawn from a clip of the skill made for the episode's own piece (its seat or surface height, how
deep the body lies on it, the pillow's height; the reach target's height) puts the character
anywhere from standing right in front of the seat, back to it, through the descent to seated
(sit), from there on through lying down (lie), or from standing at the target through the reach
to holding the hand on it (reach). The env places the clip's frame so that its seat edge is the
piece's front edge (``SIMSEnv._seat_start_frames``, ``_place_reach_start``).

Frames are drawn uniformly in time over the approach and the interaction, as RSI (DeepMimic)
draws from a reference clip: every phase is met in proportion to its duration and there is no
weight to tune. With the default clips that is, for sit, 12% standing in front of the seat, 48%
sitting down and 40% on the seat; for lie (sitting down on the edge, then lying down), 5%
standing, 21% sitting down, 73% on the piece (the last 8% lying still); for reach, 16% standing,
52% reaching and 33% holding the target. The transition, where a policy fails and which a start
far away reaches last, gets the largest share; the settled contact (the goal state, whose value the
critic must learn) is met often enough. The reach clip's return of the hand is left out: a start
there moves away from the goal.

Clips are cached per parameter set on grids (heights 1 cm, depths 5 cm, reach heights 2 cm;
each synthesis takes ~0.1-0.2 s), in single precision, frames and velocities (``clip.qvel``).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from stairenv.humanoid import humanoid_model
from stairenv.humanoid.kinematics import forward_kinematics
from stairenv.motion import interactions

#: Grid (m) of seat / surface heights and pillow heights; of lying depths; of reach target heights.
HEIGHT_GRID = 0.01
DEPTH_GRID = 0.05
REACH_GRID = 0.02
#: Seat and surface heights the clips are made for (``interactions``' ranges).
SEAT_HEIGHTS = (0.35, 0.65)
LIE_OFFSETS = (0.3, 0.6)
PILLOW_HEIGHTS = (0.0, 0.15)
REACH_HEIGHTS = (0.4, 1.6)
#: Horizontal distances (m) ahead of the pelvis a reach start puts the target at, and to the hand's side.
REACH_AHEAD = (0.45, 0.6, 0.75)
REACH_SIDE = 0.2
CACHE_SIZE = 512


def _grid(value: float, grid: float, low: float, high: float) -> int:
    """``value`` clipped to [low, high] in grid units (an int: the cache key)."""
    return int(round(min(max(value, low), high) / grid))


def _frames(*clips) -> tuple[np.ndarray, np.ndarray]:
    qpos = np.concatenate([c.qpos for c in clips]).astype(np.float32)
    qvel = np.concatenate([c.qvel() for c in clips]).astype(np.float32)
    qpos.setflags(write=False)
    qvel.setflags(write=False)
    return qpos, qvel


@lru_cache(maxsize=CACHE_SIZE)
def _sit(height_cm: int) -> tuple[np.ndarray, np.ndarray]:
    return _frames(interactions.sit_down(round(height_cm * HEIGHT_GRID, 6)))


def sit_frames(seat_height: float) -> tuple[np.ndarray, np.ndarray]:
    """qpos (T, 35) and qvel (T, 34) (float32) of ``interactions.sit_down`` for a seat of
    ``seat_height`` (rounded to :data:`HEIGHT_GRID`, clipped to :data:`SEAT_HEIGHTS`), in its seat
    frame: front edge on x = 0, the seat over x < 0, the character facing +x, pelvis on y = 0."""
    return _sit(_grid(seat_height, HEIGHT_GRID, *SEAT_HEIGHTS))


@lru_cache(maxsize=CACHE_SIZE)
def _lie(height_cm: int, offset: int, pillow_cm: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    height = round(height_cm * HEIGHT_GRID, 6)
    lie = interactions.lie_down(height, round(offset * DEPTH_GRID, 6), round(pillow_cm * HEIGHT_GRID, 6))
    qpos, qvel = _frames(interactions.sit_down(height), lie)
    model = humanoid_model()
    head = model.body("head").id
    final = next(iter(forward_kinematics(lie.qpos[-1:]))).xpos[head].copy()
    return qpos, qvel, final


def lie_frames(surface_height: float, lie_offset: float, pillow_height: float
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sitting down on the edge of a bed or sofa and lying down on it (``interactions.sit_down``
    then ``lie_down``; heights on :data:`HEIGHT_GRID`, ``lie_offset`` on :data:`DEPTH_GRID`) in the
    clips' frame (front edge on x = 0, lying with the head towards +y): qpos (T, 35), qvel (T, 34)
    (float32) and the head's final position (3,)."""
    return _lie(_grid(surface_height, HEIGHT_GRID, *SEAT_HEIGHTS), _grid(lie_offset, DEPTH_GRID, *LIE_OFFSETS),
                _grid(pillow_height, HEIGHT_GRID, *PILLOW_HEIGHTS))


@lru_cache(maxsize=CACHE_SIZE)
def _reach(ahead_cm: int, height: int, hand: str) -> tuple[np.ndarray, np.ndarray] | None:
    side = -REACH_SIDE if hand == "right" else REACH_SIDE
    try:
        clip = interactions.reach((ahead_cm / 100.0, side, round(height * REACH_GRID, 6)), hand=hand)
    except ValueError:  # out of reach from a standing pose
        return None
    last_hold = clip.meta["hold_frames"][-1][1]
    qpos, qvel = _frames(clip)
    return qpos[:last_hold + 1], qvel[:last_hold + 1]


def reach_frames(ahead: float, target_height: float, hand: str) -> tuple[np.ndarray, np.ndarray, float] | None:
    """Standing, reaching with ``hand`` ("right" or "left") to a target ``ahead`` m in front of the
    pelvis and :data:`REACH_SIDE` to the hand's side, at ``target_height`` (on :data:`REACH_GRID`,
    clipped to :data:`REACH_HEIGHTS`), up to the end of the hold: qpos, qvel (float32, the standing
    frame: pelvis over the origin facing +x) and the target height the clip was made for; None if out
    of reach."""
    height = _grid(target_height, REACH_GRID, *REACH_HEIGHTS)
    frames = _reach(int(round(ahead * 100)), height, hand)
    return None if frames is None else (*frames, round(height * REACH_GRID, 6))
