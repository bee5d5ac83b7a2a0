"""Reference-state initialisation (RSI): start episodes from frames of reference motion.

``load_reference_library(source)`` gives the clips an env starts from and the
discriminator learns from: a folder or list of ``.npz`` clips, or a built-in set
synthesised in about a second and cached per process: ``None`` / ``"builtin:stairs"``
(``stairenv.motion.synthesis``: flat walks and stair ascents for step heights
0.05-0.20 m) or ``"builtin:sims"`` (the flat walks, a walk in each of the eight SIMS
styles (``synthesis.WALK_STYLES``) and ``stairenv.motion.interactions``' sit, stand-up,
lie, get-up, reach and idle clips).
``level_clips`` / ``standing_clips`` pick the clips a start may be drawn from (a stair
climb's frame on flat ground would start with a foot on no step).
``place_reference_state`` puts a sampled frame at a start position and
heading with its lowest point just above the floor, so nothing penetrates.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation

from stairenv.humanoid import HumanoidIndices
from stairenv.motion.library import MotionLibrary

# Gap left between the lowest body point and the floor when placing a reference state (m).
PLACEMENT_CLEARANCE = 0.002


BUILTIN_REFERENCE_SETS = ("builtin:stairs", "builtin:sims")

# Clips of these meta["skill"] values start standing up: the ones standing starts are drawn from.
STANDING_SKILLS = ("walk", "idle")


@lru_cache(maxsize=8)
def _load_cached(source: str | None, include_descents: bool) -> MotionLibrary:
    from stairenv.motion.synthesis import reference_set

    if source is None or source == "builtin:stairs":
        return MotionLibrary(reference_set(descents=include_descents))
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
    """The clips that stay on level ground (root height range below ``max_rise`` m), keeping their
    weights: the frames a start on a floor may be drawn from. A stair climb's frame placed on flat
    ground would start with a foot in the air on no step (and fall)."""
    keep = [i for i, clip in enumerate(library.clips) if float(np.ptp(clip.qpos[:, 2])) < max_rise]
    if not keep:
        raise ValueError(f"the reference motion has no clip on level ground (root height range < {max_rise} m) "
                         "to start episodes from; use init='default'")
    if len(keep) == len(library.clips):
        return library
    return MotionLibrary([library.clips[i] for i in keep], library.probabilities[keep])


def humanoid_lowest_z(model: mujoco.MjModel, data: mujoco.MjData, geom_ids: np.ndarray) -> float:
    """Exact lowest world z of the given sphere, capsule and box geoms (after kinematics)."""
    lowest = np.inf
    for g in geom_ids:
        z, size, R = data.geom_xpos[g, 2], model.geom_size[g], data.geom_xmat[g].reshape(3, 3)
        kind = model.geom_type[g]
        if kind == mujoco.mjtGeom.mjGEOM_SPHERE:
            bottom = z - size[0]
        elif kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
            bottom = z - abs(R[2, 2]) * size[1] - size[0]
        elif kind == mujoco.mjtGeom.mjGEOM_BOX:
            bottom = z - np.abs(R[2]) @ size
        else:
            bottom = z - model.geom_rbound[g]
        lowest = min(lowest, bottom)
    return float(lowest)


def humanoid_geoms(model: mujoco.MjModel, idx: HumanoidIndices) -> np.ndarray:
    return np.flatnonzero(np.isin(model.geom_bodyid, idx.body_ids))


def place_reference_state(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    idx: HumanoidIndices,
    qpos: np.ndarray,
    qvel: np.ndarray,
    xy: tuple[float, float],
    heading: float,
    floor_height: float = 0.0,
) -> None:
    """Write a reference state into ``data``: turned to face ``heading``, root over ``xy``,
    lowest point PLACEMENT_CLEARANCE above ``floor_height``. Runs kinematics."""
    root_rot = Rotation.from_quat(qpos[3:7], scalar_first=True)
    forward = root_rot.apply([1.0, 0.0, 0.0])
    turn = Rotation.from_euler("z", heading - np.arctan2(forward[1], forward[0]))
    data.qpos[idx.qpos_root] = (xy[0], xy[1], qpos[2], *(turn * root_rot).as_quat(scalar_first=True))
    data.qpos[idx.qpos_joints] = qpos[7:]
    data.qvel[idx.qvel_root] = (*turn.apply(qvel[:3]), *qvel[3:6])  # angular velocity is in the root frame
    data.qvel[idx.qvel_joints] = qvel[6:]
    mujoco.mj_kinematics(model, data)
    lift = floor_height + PLACEMENT_CLEARANCE - humanoid_lowest_z(model, data, humanoid_geoms(model, idx))
    data.qpos[idx.qpos_root.start + 2] += lift
    mujoco.mj_kinematics(model, data)
