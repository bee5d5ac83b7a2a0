r"""SIMS interaction skills as pure functions: contact goals, rewards, scene heights.

The five skills (walk, sit, lie, reach, get up) share one goal format (SIMS Sec. 3.3,
after UniHSI): a target point set for each of the humanoid's 15 bodies (joints) and a
mask of the bodies that have one. The target of body j is the point of its set nearest
to it, g_j = argmin_{p in P_j} |p - x_j| (supplement Eq. 13), so "the pelvis on the seat"
is any point of the seat's top surface (lifted by the body's radius).

Rewards (supplement Eq. 7-13), with x the root (pelvis) position, x* the root target,
d* the unit direction from x to x* on the ground, v* the target speed, f the facing
direction on the ground, all distances on the ground (x, y) unless stated:

* walk: far = 0.6 exp(-0.5 |x* - x|^2) + 0.2 exp(-2 (v* - d*.xdot)^2) + 0.2 max(0, d*.f)^2,
  near = exp(-10 |x* - x|^2), still = exp(-2 |xdot_t - xdot_{t-1}|^2);
  r = 0.4 near + 0.5 far if |x* - x|^2 > 0.5, else 0.4 near + 0.5 + 0.1 still.
* contact (sit, lie, reach, get up): far = 0.5 exp(-0.5 |x* - x|^2) + 0.4 exp(-2 (v* - d*.xdot)^2)
  + 0.1 max(0, d*.f)^2, near = exp(-10 sum_j m_j |g_j - x_j|^2) (3-D);
  r = 0.6 near + 0.4 far if |x* - x|^2 > 0.5, else 0.6 near + 0.4.

The paper writes the facing term as |d*.f|^2; the public implementations clamp the dot
product at 0 so that walking backwards earns nothing, and so do we (the two agree when
the character faces the target's half-plane). The get-up reward is the contact reward
with the pelvis target at standing height in front of the furniture.

Each term is a small pure function of ``SkillRewardInputs`` (``near_term``, ``far_term``,
``still_term``), named and weighed in ``WALK_TERMS`` / ``CONTACT_TERMS``; the weights are held in
one place, ``WALK_WEIGHTS`` and ``CONTACT_WEIGHTS``. ``root_frames``, ``goal_targets``,
``skill_observations``, ``skill_reward_values`` and ``skill_errors`` compute a step on a batch of worlds (one
world: a batch of one) with the same bits for a world alone or in any batch; they are the specification of
``skill_step``, which ``SIMSEnv`` calls each step (one world's step in one compiled call, the same bits:
``tests/test_sims_skills.py``). ``walk_reward_terms`` and ``contact_reward_terms`` are one world's rewards.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from stairenv.humanoid import BODY_NAMES, STANDING_ROOT_HEIGHT
from stairenv.humanoid.state import PELVIS, HumanoidState
from stairenv.rotations import yaw_matrix
from stairenv.tasks.kernels import (
    PROPRIOCEPTION_SIZE,
    fma,
    heading_cos_sin,
    jit,
    proprioception,
    write_proprioception,
)
from stairenv.tasks.terms import RewardTerm, term_names, weighted_values
from stairenv.world.furniture import PlacedFurniture

SKILLS: tuple[str, ...] = ("walk", "sit", "lie", "reach", "getup")
#: The registered env of each skill (its Table 1 env, and the id its shipped policy is kept under).
SKILL_ENV_IDS: dict[str, str] = {
    "sit": "SIMS-Sit-v0", "lie": "SIMS-Lie-v0", "reach": "SIMS-Reach-v0",
    "walk": "SIMS-Walk-v0", "getup": "SIMS-GetUp-v0",
}
CONTACT_JOINTS: tuple[str, ...] = BODY_NAMES
NUM_CONTACT_JOINTS = len(CONTACT_JOINTS)
JOINT = {name: k for k, name in enumerate(CONTACT_JOINTS)}

# Success: the primary contact within this distance (m). SIMS: 20 cm sit and reach, 30 cm lie;
# walk and get up (not in the paper's Table 1) use 20 cm on the pelvis target too.
SUCCESS_DISTANCE: dict[str, float] = {"walk": 0.2, "sit": 0.2, "lie": 0.3, "reach": 0.2, "getup": 0.2}
# |x* - x|^2 (m^2) below which the far term is replaced by its maximum (supplement Eq. 7, 11): the default
# of ``SkillRewardWeights.near_squared_distance``.
NEAR_SQUARED_DISTANCE = 0.5
# How far above a surface each body's origin rests when it touches it (its collision radius, m):
# pelvis capsule 0.09, chest 0.11 (the torso origin sits behind it), head sphere 0.095, hands 0.04.
CONTACT_CLEARANCE: dict[str, float] = {"pelvis": 0.10, "torso": 0.12, "head": 0.10,
                                       "right_hand": 0.04, "left_hand": 0.04}

# Which part each skill targets by default, per family (schema parts map here too).
SIT_PART = {"chair": "seat", "armchair": "seat", "stool": "seat", "sofa": "seat",
            "bed": "bed_surface", "double_bed": "bed_surface"}
LIE_PART = {"sofa": "seat", "bed": "bed_surface", "double_bed": "bed_surface"}
REACH_PARTS = {"chair": ("backrest", "seat"), "armchair": ("armrest", "backrest"), "stool": ("seat",),
               "sofa": ("armrest", "backrest"), "bed": ("bed_surface", "pillow"), "double_bed": ("bed_surface", "pillow"),
               "table": ("table_top",), "cabinet": ("top", "handle"), "wardrobe": ("handle", "door"),
               "bookshelf": ("shelf",), "lamp": ("lamp_shade", "pole")}
# Script part names (stairenv.screenplays.schema.PARTS) that are spelt differently on a family.
PART_ALIASES = {("cabinet", "table_top"): "top", ("cabinet", "shelf"): "door", ("lamp", "switch"): "pole",
                ("wardrobe", "shelf"): "door"}
REACH_HEIGHT = (0.3, 1.7)  # a standing character's hand reaches targets at these heights (m)


# --- rewards -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class SkillRewardWeights:
    """The weights of a skill's reward (supplement Eq. 7-13), the one place that holds them: those of
    its terms (``near``, ``far``, ``still``) and those inside the far term (``far_*``)."""

    near: float
    far: float
    still: float          # walk only: the contact skills have no still term
    far_position: float
    far_velocity: float
    far_facing: float
    #: |x* - x|^2 (m^2) below which the far term is at its maximum and the walk's still term acts (the
    #: paper's 0.5; the ``near_distance`` training aid narrows it)
    near_squared_distance: float = NEAR_SQUARED_DISTANCE


WALK_WEIGHTS = SkillRewardWeights(near=0.4, far=0.5, still=0.1, far_position=0.6, far_velocity=0.2, far_facing=0.2)
CONTACT_WEIGHTS = SkillRewardWeights(near=0.6, far=0.4, still=0.0, far_position=0.5, far_velocity=0.4, far_facing=0.1)


class SkillRewardInputs(NamedTuple):
    """What the reward terms are computed from, for one world (distances squared, m^2)."""

    dist2: float             # |x* - x|^2 on the ground
    velocity: float          # exp(-2 (v* - d*.xdot)^2)
    facing: float            # max(0, d*.f)^2
    near_error2: float       # walk: |x* - x|^2; contact: sum_j m_j |g_j - x_j|^2 (3-D)
    velocity_change2: float  # |xdot_t - xdot_{t-1}|^2 on the ground (walk's still term)


def near_term(x: SkillRewardInputs, w: SkillRewardWeights) -> float:
    """exp(-10 e^2), e the walk's root distance or the contact error (supplement Eq. 8, 13)."""
    return math.exp(-10.0 * x.near_error2)


def far_term(x: SkillRewardInputs, w: SkillRewardWeights) -> float:
    """Approaching x*: position, speed towards it and facing it (Eq. 7, 11); its maximum 1 once near."""
    if x.dist2 > w.near_squared_distance:
        return w.far_position * math.exp(-0.5 * x.dist2) + w.far_velocity * x.velocity + w.far_facing * x.facing
    return 1.0


def still_term(x: SkillRewardInputs, w: SkillRewardWeights) -> float:
    """Once near, keeping the root's velocity (exp(-2 |xdot_t - xdot_{t-1}|^2), Eq. 10); 0 while far."""
    if x.dist2 > w.near_squared_distance:
        return 0.0
    return math.exp(-2.0 * x.velocity_change2)


WALK_TERMS = (RewardTerm("reward_near", near_term, "near"), RewardTerm("reward_far", far_term, "far"),
              RewardTerm("reward_still", still_term, "still"))
CONTACT_TERMS = WALK_TERMS[:2]
WALK_REWARD_TERMS = term_names(WALK_TERMS)
CONTACT_REWARD_TERMS = term_names(CONTACT_TERMS)


def row_dots(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(B,) a[k] . b[k] of the rows of ``a`` and ``b`` (B, d), each by the BLAS dot that ``a[k] @ b[k]``
    calls (a batched matmul of 1 x d by d x 1 calls it row by row; an einsum or a sum written out
    rounds differently), so a row has the same bits alone or in any batch."""
    a, b = np.ascontiguousarray(a, dtype=float), np.ascontiguousarray(b, dtype=float)
    return np.matmul(a[:, None, :], b[:, :, None])[:, 0, 0]


def direction_terms(target_xy: np.ndarray, root_xy: np.ndarray, root_vel_xy: np.ndarray, facing_xy: np.ndarray,
                    target_speeds: Sequence[float]) -> list[tuple[float, float, float]]:
    """Per world (rows of the (B, >= 2) arrays): (|x* - x|^2, velocity term, facing term) on the ground."""
    delta = np.asarray(target_xy, dtype=float)[:, :2] - np.asarray(root_xy, dtype=float)[:, :2]
    dist2 = row_dots(delta, delta).tolist()
    norms = [math.sqrt(d) for d in dist2]
    moving = np.array([norm > 1e-9 for norm in norms])[:, None]
    # the unit direction; none (zeros) on the target
    direction = np.divide(delta, np.array(norms)[:, None], out=np.zeros_like(delta), where=moving)
    speed_along = row_dots(direction, np.asarray(root_vel_xy, dtype=float)[:, :2]).tolist()
    facing = row_dots(direction, np.asarray(facing_xy, dtype=float)[:, :2]).tolist()
    return [(d, math.exp(-2.0 * (speed - along) ** 2), max(0.0, f) ** 2)
            for d, speed, along, f in zip(dist2, target_speeds, speed_along, facing)]


def walk_reward_values(target_xy: np.ndarray, root_xy: np.ndarray, root_vel_xy: np.ndarray,
                       prev_root_vel_xy: np.ndarray, facing_xy: np.ndarray, target_speeds: Sequence[float],
                       weights: SkillRewardWeights = WALK_WEIGHTS) -> list[tuple[float, ...]]:
    """``walk_reward_terms`` of each world (rows of the (B, >= 2) arrays; ``target_speeds`` (B,))."""
    directions = direction_terms(target_xy, root_xy, root_vel_xy, facing_xy, target_speeds)
    dv = np.asarray(root_vel_xy, dtype=float)[:, :2] - np.asarray(prev_root_vel_xy, dtype=float)[:, :2]
    changes = row_dots(dv, dv).tolist()
    return [weighted_values(SkillRewardInputs(dist2, velocity, facing, dist2, change), weights, WALK_TERMS)
            for (dist2, velocity, facing), change in zip(directions, changes)]


def contact_reward_values(target_xy: np.ndarray, root_xy: np.ndarray, root_vel_xy: np.ndarray,
                          facing_xy: np.ndarray, target_speeds: Sequence[float], goals: np.ndarray,
                          joints: np.ndarray, mask: np.ndarray,
                          weights: SkillRewardWeights = CONTACT_WEIGHTS) -> list[tuple[float, ...]]:
    """``contact_reward_terms`` of each world (rows of the (B, ...) arrays; ``target_speeds`` (B,))."""
    directions = direction_terms(target_xy, root_xy, root_vel_xy, facing_xy, target_speeds)
    err = np.sum(np.square(goals - joints), axis=-1)
    near_errors = np.sum(err * np.asarray(mask, dtype=float), axis=-1).tolist()
    return [weighted_values(SkillRewardInputs(dist2, velocity, facing, near_error2, 0.0), weights, CONTACT_TERMS)
            for (dist2, velocity, facing), near_error2 in zip(directions, near_errors)]


def walk_reward_terms(target_xy: np.ndarray, root_xy: np.ndarray, root_vel_xy: np.ndarray,
                      prev_root_vel_xy: np.ndarray, facing_xy: np.ndarray, target_speed: float,
                      weights: SkillRewardWeights = WALK_WEIGHTS) -> np.ndarray:
    """The walk reward's weighted terms (near, far, still), summing to r (supplement Eq. 7-10)."""
    rows = (np.asarray(v, dtype=float)[None] for v in (target_xy, root_xy, root_vel_xy, prev_root_vel_xy,
                                                         facing_xy))  # a batch of one
    return np.array(walk_reward_values(*rows, [target_speed], weights)[0])


def contact_reward_terms(target_xy: np.ndarray, root_xy: np.ndarray, root_vel_xy: np.ndarray,
                         facing_xy: np.ndarray, target_speed: float, goals: np.ndarray, joints: np.ndarray,
                         mask: np.ndarray, weights: SkillRewardWeights = CONTACT_WEIGHTS) -> np.ndarray:
    """The contact reward's weighted terms (near, far), summing to r (supplement Eq. 11-13).

    ``goals`` and ``joints`` (15, 3): targets g_j and body positions x_j; ``mask`` (15,).
    """
    target, root, vel, facing, goals, joints, mask = (np.asarray(v, dtype=float)[None] for v in (
        target_xy, root_xy, root_vel_xy, facing_xy, goals, joints, mask))  # a batch of one
    return np.array(contact_reward_values(target, root, vel, facing, [target_speed], goals, joints, mask, weights)[0])


# --- one step of a batch of worlds ---------------------------------------------------------------
# Row k of every argument is world k (of a ``HumanoidState`` batch); a world's results have the same
# bits alone (a batch of one) or in any batch: what is batched is elementwise or row by row.
class RootFrames(NamedTuple):
    """Each world's root and its heading frame: ``headings`` the yaw rotations (world-from-heading)."""

    positions: np.ndarray  # (B, 3)
    yaws: list[float]
    headings: np.ndarray   # (B, 3, 3)


def root_frames(state: HumanoidState) -> RootFrames:
    """The roots of the worlds of ``state`` and their heading frames."""
    axes = state.body_mat[:, PELVIS, :2, 0].tolist()  # (R00, R10): the root's yaw
    yaws = [math.atan2(r10, r00) for r00, r10 in axes]
    return RootFrames(state.body_pos[:, PELVIS], yaws, np.array([yaw_matrix(yaw) for yaw in yaws]))


def goal_targets(goals: Sequence[ContactGoal], joints: np.ndarray) -> np.ndarray:
    """(B, 15, 3): ``goal.targets`` of each world's goal and joints (B, 15, 3)."""
    out = np.empty((len(goals), NUM_CONTACT_JOINTS, 3))
    for goal, world_joints, world_out in zip(goals, joints, out):
        goal.targets(world_joints, world_out)
    return out


def skill_observations(state: HumanoidState, frames: RootFrames, goals: Sequence[ContactGoal], targets: np.ndarray,
                       heights: Sequence[SceneHeights], heightmap_size: int, heightmap_extent: float,
                       texts: Sequence[np.ndarray]) -> np.ndarray:
    """(B, size) the observations (``SIMSEnv``'s docstring): proprioception, the egocentric heightmap of
    each world's ``heights``, the goal's targets ``targets`` (``goal_targets``) relative to the root in
    the heading frame (zeros where masked out), the mask, and the text embedding of ``texts``."""
    n, hm = len(goals), heightmap_size * heightmap_size
    roots = frames.positions
    g0 = PROPRIOCEPTION_SIZE + hm
    g1 = g0 + 3 * NUM_CONTACT_JOINTS
    obs = np.empty((n, g1 + NUM_CONTACT_JOINTS + len(texts[0])))
    obs[:, :PROPRIOCEPTION_SIZE] = proprioception(state.body_mat, state.root_lin_vel, state.root_ang_vel,
                                                  state.dof_vel, roots[:, 2].copy(), np.empty((n, PROPRIOCEPTION_SIZE)))
    for k, (root, yaw) in enumerate(zip(roots.tolist(), frames.yaws)):
        heights[k].egocentric(root, yaw, heightmap_size, heightmap_extent, obs[k, PROPRIOCEPTION_SIZE:g0])
    masks = np.array([goal.mask for goal in goals])
    rel = (targets - roots[:, None, :]) * masks[:, :, None]
    obs[:, g0:g1] = np.matmul(rel, frames.headings).reshape(n, -1)  # into the heading frames
    obs[:, g1:g1 + NUM_CONTACT_JOINTS] = masks
    obs[:, g1 + NUM_CONTACT_JOINTS:] = texts
    return obs


def skill_reward_values(state: HumanoidState, frames: RootFrames, goals: Sequence[ContactGoal], targets: np.ndarray,
                        prev_root_vel: np.ndarray, target_speeds: Sequence[float],
                        near_squared_distance: float = NEAR_SQUARED_DISTANCE) -> list[tuple[float, ...]]:
    """Each world's weighted reward terms: ``WALK_REWARD_TERMS`` for a walk goal, else
    ``CONTACT_REWARD_TERMS``; ``prev_root_vel`` (B, 2) the roots' ground velocities a step before;
    ``near_squared_distance``: the weights' bound of the near zone (m^2)."""
    near = {"near_squared_distance": float(near_squared_distance)}
    walk_weights = dataclasses.replace(WALK_WEIGHTS, **near)
    contact_weights = dataclasses.replace(CONTACT_WEIGHTS, **near)
    target_xy = np.array([goal.root_target[:2] for goal in goals])
    vel, facing = state.root_lin_vel[:, :2], frames.headings[:, :2, 0]
    values: list = [None] * len(goals)
    for walk, worlds in _by_kind(goals).items():
        rows = slice(None) if len(worlds) == len(goals) else worlds  # one kind (as a batched env has): no copies
        speeds = [target_speeds[k] for k in worlds]
        if walk:
            group = walk_reward_values(target_xy[rows], frames.positions[rows], vel[rows], prev_root_vel[rows],
                                       facing[rows], speeds, walk_weights)
        else:
            masks = np.array([goals[k].mask for k in worlds])
            group = contact_reward_values(target_xy[rows], frames.positions[rows], vel[rows], facing[rows], speeds,
                                          targets[rows], state.body_pos[rows], masks, contact_weights)
        for k, terms in zip(worlds, group):
            values[k] = terms
    return values


def _by_kind(goals: Sequence[ContactGoal]) -> dict[bool, list[int]]:
    """The worlds of walk goals (True) and of contact goals (False), where there are any."""
    kinds: dict[bool, list[int]] = {}
    for k, goal in enumerate(goals):
        kinds.setdefault(goal.skill == "walk", []).append(k)
    return kinds


def skill_errors(goals: Sequence[ContactGoal], targets: np.ndarray, joints: np.ndarray) -> list[float]:
    """Each world's distance (m) that decides success: the root's to x* on the ground for walk, else
    the primary body's to its target."""
    worlds = np.arange(len(goals))
    primary = [goal.primary for goal in goals]
    offsets = targets[worlds, primary] - joints[worlds, primary]
    errors = np.sqrt(row_dots(offsets, offsets))
    walk = [goal.skill == "walk" for goal in goals]
    if any(walk):
        ground = np.array([goal.root_target[:2] for goal in goals]) - joints[:, PELVIS, :2]
        errors = np.where(walk, np.hypot(ground[:, 0], ground[:, 1]), errors)
    return errors.tolist()


# --- contact goals -----------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class ContactGoal:
    """Target point sets for some of the 15 bodies.

    ``points[j]`` (P_j, 3) world points for the bodies with ``mask[j]``; ``primary`` the body
    whose distance decides success and the contact error; ``root_target`` x* (3,) for the
    far / walk terms; ``furniture`` and ``part`` what is touched (None for walk).
    """

    skill: str
    points: tuple[np.ndarray | None, ...]
    primary: int
    root_target: np.ndarray
    furniture: str | None = None
    part: str | None = None

    def __post_init__(self) -> None:
        # All target points in one array with the body each belongs to, for the compiled lookup.
        sets = [(j, p) for j, p in enumerate(self.points) if p is not None]
        object.__setattr__(self, "_flat", np.ascontiguousarray(np.concatenate([p for _, p in sets]), dtype=np.float64))
        object.__setattr__(self, "_owner", np.concatenate([np.full(len(p), j, dtype=np.int64) for j, p in sets]))
        object.__setattr__(self, "mask", np.array([p is not None for p in self.points]))

    def targets(self, joints: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """g_j (15, 3): the nearest target point of each masked body; unmasked bodies: themselves
        (written to ``out``, (15, 3) C-contiguous, where given)."""
        return nearest_targets(self._flat, self._owner, np.ascontiguousarray(joints, dtype=np.float64),
                               np.empty((NUM_CONTACT_JOINTS, 3)) if out is None else out)

    def contact_error(self, joints: np.ndarray) -> float:
        """Distance (m) of the primary body to its target set."""
        pts = self.points[self.primary]
        return float(np.sqrt(np.min(np.sum(np.square(pts - joints[self.primary]), axis=-1))))


@jit
def nearest_targets(points, owner, joints, out):
    """out[j] = the point of ``points`` (P, 3) with ``owner`` j nearest to joints[j]; joints[j] if none."""
    best = np.full(joints.shape[0], np.inf)
    out[:] = joints
    for p in range(points.shape[0]):
        j = owner[p]
        d = 0.0
        for k in range(3):
            d += (points[p, k] - joints[j, k]) ** 2
        if d < best[j]:
            best[j] = d
            out[j, :] = points[p]
    return out


@jit
def egocentric_heights(heights, x0, y0, cell, root_x, root_y, root_z, yaw, size, extent, out):
    """SceneHeights.sample over a size x size grid of ``extent`` m turned with ``yaw``, minus root_z
    (the same points as ``stairenv.tasks.plamo.heightmap_points``), written to out (size * size)."""
    c, s = math.cos(yaw), math.sin(yaw)
    rows, cols = heights.shape
    k = 0
    for a in range(size):
        gy = (a + 0.5) / size * extent - extent / 2
        for b in range(size):
            gx = (b + 0.5) / size * extent - extent / 2
            x = root_x + c * gx - s * gy
            y = root_y + s * gx + c * gy
            j = math.floor((x - x0) / cell)
            i = math.floor((y - y0) / cell)
            h = 0.0
            if 0 <= i < rows and 0 <= j < cols:
                h = heights[i, j]
            out[k] = h - root_z
            k += 1
    return out


def _joint_points(**by_joint: np.ndarray) -> tuple[np.ndarray | None, ...]:
    points: list[np.ndarray | None] = [None] * NUM_CONTACT_JOINTS
    for name, pts in by_joint.items():
        points[JOINT[name]] = np.atleast_2d(np.asarray(pts, dtype=float))
    return tuple(points)


def _surface_points(placed: PlacedFurniture, label: str, clearance: float, count: int = 5,
                    index: int | None = None, side: str = "auto") -> np.ndarray:
    surface = placed.contact_surface(label, index=index, side=side)
    return surface.grid(count) + clearance * surface.normal


def resolve_part(family: str, part: str | None, skill: str) -> str:
    """The furniture label a skill touches: ``part`` (script spelling allowed) or the skill's default."""
    if part is not None:
        return PART_ALIASES.get((family, part), part)
    if skill in ("sit", "getup"):
        table = {**SIT_PART, **LIE_PART} if skill == "getup" else SIT_PART
    elif skill == "lie":
        table = LIE_PART
    else:
        return REACH_PARTS[family][0]
    if family not in table:
        raise ValueError(f"cannot {skill} on a {family}; possible: {sorted(table)}")
    return table[family]


#: the farthest apart (m, centre to centre) two armrests are for a sit goal to put a hand on each
ARMREST_SPAN = 1.0


def standing_point(placed: PlacedFurniture, label: str, distance: float = 0.35) -> np.ndarray:
    """Where a character stands after getting up from ``label``: in front of the surface's front edge."""
    # several parts of a label (two armrests, four shelves): their mean centre, furniture frame
    local_front = np.mean([s.center for s in placed.furniture.contact_surfaces(label)], axis=0)
    hi = placed.furniture.bounds[1]
    front_local = np.array([hi[0] + distance, local_front[1], 0.0])
    if placed.family in LIE_PART and placed.family != "sofa":
        # a bed is left from its long side (+y in the furniture frame is as good as -y)
        front_local = np.array([local_front[0], hi[1] + distance, 0.0])
    world = placed.to_world(front_local[None])[0]
    world[2] = STANDING_ROOT_HEIGHT
    return world


def contact_goal(skill: str, placed: PlacedFurniture | None, rng: np.random.Generator, *,
                 part: str | None = None, hand: str | None = None, walk_target: Sequence[float] | None = None,
                 details: bool = True, stand_at: Callable[[np.ndarray], np.ndarray] | None = None) -> ContactGoal:
    """The goal of ``skill`` on ``placed`` (walk: ``walk_target`` (x, y) instead; getup: ``stand_at`` maps the
    standing point's (x, y) to where the character can stand, e.g. free floor in a room).

    sit: pelvis on the seat (with ``details``: torso at the backrest and hands on the
    armrests when the piece has them); lie: pelvis on the bed surface / sofa seat and head on
    the pillow (if any); reach: one hand (``hand`` or random) to a point of ``part`` (default:
    a reachable part of the family); getup: pelvis at standing height in front of the piece.
    """
    if skill not in SKILLS:
        raise ValueError(f"skill must be one of {list(SKILLS)}, got {skill!r}")
    if skill == "walk":
        if walk_target is None:
            raise ValueError("a walk goal needs walk_target (x, y)")
        target = np.array([float(walk_target[0]), float(walk_target[1]), STANDING_ROOT_HEIGHT])
        return ContactGoal("walk", _joint_points(pelvis=target), JOINT["pelvis"], target.copy())
    if placed is None:
        raise ValueError(f"a {skill} goal needs a furniture")
    family = placed.family
    label = resolve_part(family, part, skill)
    if label not in placed.furniture.labels:
        raise ValueError(f"{family} has no part {label!r} ({skill}); its parts: {list(placed.furniture.labels)}")
    if skill == "getup":
        target = standing_point(placed, label)
        if stand_at is not None:
            target[:2] = stand_at(target[:2])
        return ContactGoal("getup", _joint_points(pelvis=target), JOINT["pelvis"], target.copy(), placed.name, label)
    if skill == "reach":
        hand = hand if hand is not None else ("right_hand", "left_hand")[int(rng.integers(0, 2))]
        hand = hand if hand.endswith("_hand") else f"{hand}_hand"
        if hand not in ("right_hand", "left_hand"):
            raise ValueError(f"hand must be 'left' or 'right', got {hand!r}")
        surfaces = placed.furniture.contact_surfaces(label)
        reachable = [k for k, s in enumerate(surfaces) if REACH_HEIGHT[0] <= s.center[2] <= REACH_HEIGHT[1]]
        k = int(rng.choice(reachable)) if reachable else int(np.argmin([abs(s.center[2] - 1.0) for s in surfaces]))
        surface = placed.contact_surface(label, index=k) if len(surfaces) > 1 else placed.contact_surface(label)
        # a tall part (a lamp pole, a door) has points out of reach: draw among the reachable ones
        candidates = surface.sample(rng, 32, margin=0.05)
        heights = candidates[:, 2]
        ok = (heights >= REACH_HEIGHT[0]) & (heights <= REACH_HEIGHT[1])
        point = candidates[int(np.flatnonzero(ok)[0])] if ok.any() else candidates[int(np.argmin(abs(heights - 1.0)))]
        point = point + CONTACT_CLEARANCE[hand] * surface.normal
        return ContactGoal("reach", _joint_points(**{hand: point}), JOINT[hand], point.copy(), placed.name, label)

    pelvis = _surface_points(placed, label, CONTACT_CLEARANCE["pelvis"])
    extra: dict[str, np.ndarray] = {}
    if details and skill == "sit":
        if "backrest" in placed.furniture.labels and len(placed.furniture.parts("backrest")) == 1:
            extra["torso"] = _surface_points(placed, "backrest", CONTACT_CLEARANCE["torso"], 3)
        armrests = placed.furniture.contact_surfaces("armrest") if "armrest" in placed.furniture.labels else []
        # both hands on the armrests where a seated person reaches both (an armchair's, not a sofa's: seated
        # in a sofa's middle each hand would be 0.6-0.8 m from its armrest, and the near term ~0 whatever it did)
        if len(armrests) == 2 and abs(armrests[0].center[1] - armrests[1].center[1]) <= ARMREST_SPAN:
            # facing the front (+x), the left hand is on the +y side
            left, right = sorted(armrests, key=lambda s: -s.center[1])
            for name, s in (("left_hand", left), ("right_hand", right)):
                s = s.transformed(placed.rotation, placed.translation)
                extra[name] = s.grid(3) + CONTACT_CLEARANCE[name] * s.normal
    if details and skill == "lie" and "pillow" in placed.furniture.labels:
        extra["head"] = _surface_points(placed, "pillow", CONTACT_CLEARANCE["head"], 3, index=0)
    centre = pelvis.mean(axis=0)
    return ContactGoal(skill, _joint_points(pelvis=pelvis, **extra), JOINT["pelvis"], centre, placed.name, label)


# --- scene heights ------------------------------------------------------------------------------
def convex_top_heights(planes: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Top z of a convex solid (planes (F, 4): n . p <= d inside) above points xy (N, 2); -inf off it."""
    n, d = planes[:, :3], planes[:, 3]
    rhs = d[None, :] - xy @ n[:, :2].T  # n_z z <= rhs
    up, down, side = n[:, 2] > 1e-9, n[:, 2] < -1e-9, np.abs(n[:, 2]) <= 1e-9
    top = np.min(rhs[:, up] / n[up, 2], axis=1) if up.any() else np.full(len(xy), np.inf)
    bottom = np.max(rhs[:, down] / n[down, 2], axis=1) if down.any() else np.full(len(xy), -np.inf)
    inside = bottom <= top + 1e-9
    if side.any():
        inside &= np.all(rhs[:, side] >= -1e-9, axis=1)
    return np.where(inside, top, -np.inf)


@dataclass(frozen=True, eq=False)
class SceneHeights:
    """The height of the highest surface on a grid over a scene (floor = 0): SIMS' pre-generated
    object heightmap. ``heights`` (rows y, columns x) of cells ``cell_size`` from ``origin``."""

    heights: np.ndarray
    origin: tuple[float, float]
    cell_size: float

    @classmethod
    def build(cls, furniture: Sequence[PlacedFurniture], walls: Sequence = (), *, bounds=None,
              cell_size: float = 0.05, margin: float = 1.0) -> SceneHeights:
        """Rasterise the top of every furniture part and wall ``Box`` over ``bounds`` (x0, y0, x1, y1)
        (default: the furniture's footprints grown by ``margin``)."""
        if bounds is None:
            corners = [f.footprint_box().corners_xy() for f in furniture] + [w.corners_xy() for w in walls]
            pts = np.concatenate(corners) if corners else np.zeros((1, 2))
            bounds = (*(pts.min(axis=0) - margin), *(pts.max(axis=0) + margin))
        x0, y0, x1, y1 = (float(v) for v in bounds)
        cols, rows = max(1, math.ceil((x1 - x0) / cell_size)), max(1, math.ceil((y1 - y0) / cell_size))
        xs = x0 + (np.arange(cols) + 0.5) * cell_size
        ys = y0 + (np.arange(rows) + 0.5) * cell_size
        grid = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
        heights = np.zeros(len(grid))
        for placed in furniture:
            box = placed.footprint_box(margin=cell_size)
            near = box.contains_xy(grid)
            if not near.any():
                continue
            local = placed.to_local(np.column_stack((grid[near], np.zeros(int(near.sum())))))[:, :2]
            for part in placed.furniture.part_list:
                heights[near] = np.maximum(heights[near], convex_top_heights(part.planes, local))
        for wall in walls:
            inside = wall.contains_xy(grid)
            heights[inside] = np.maximum(heights[inside], wall.top)
        return cls(heights.reshape(rows, cols), (x0, y0), float(cell_size))

    def sample(self, xy: np.ndarray) -> np.ndarray:
        """Height at world points (..., 2): the containing cell's (0 off the grid)."""
        p = np.asarray(xy, dtype=float)
        j = np.floor((p[..., 0] - self.origin[0]) / self.cell_size).astype(np.int64)
        i = np.floor((p[..., 1] - self.origin[1]) / self.cell_size).astype(np.int64)
        rows, cols = self.heights.shape
        ok = (i >= 0) & (i < rows) & (j >= 0) & (j < cols)
        out = np.zeros(p.shape[:-1])
        out[ok] = self.heights[i[ok], j[ok]]
        return out

    def egocentric(self, root: np.ndarray, yaw: float, size: int, extent: float,
                   out: np.ndarray | None = None) -> np.ndarray:
        """(size * size,) heights around ``root`` turned with ``yaw`` minus the root's height (written to
        ``out``, C-contiguous, where given)."""
        return egocentric_heights(self.heights, self.origin[0], self.origin[1], self.cell_size, float(root[0]),
                                  float(root[1]), float(root[2]), float(yaw), int(size), float(extent),
                                  np.empty(size * size) if out is None else out)


# --- the compiled step --------------------------------------------------------------------------
# ``skill_step`` computes one world's step outcome (what ``root_frames``, ``goal_targets``,
# ``skill_observations``, ``skill_reward_values`` and ``skill_errors`` compute for it) in one native call,
# with the same bits: every operation in the order and rounding those functions use. Three of them are
# numpy's BLAS (OpenBLAS) calls, written out as its kernels compute them for these sizes: a dot product of
# 2 or 3 numbers (``row_dots``: ``cblas_ddot``) as an unfused sum from +0, the 15 x 3 by 3 x 3 product into
# the heading frame (``np.matmul``: ``cblas_dgemm``) as a fused multiply-add chain from +0. Python's
# ``x ** 2`` is libm's ``pow(x, 2.0)``, which rounds some squares differently from x * x, so the kernel
# calls pow too, with the exponent read at run time (``STEP_SQUARE``) so that the compiler cannot turn it
# into x * x. ``tests/test_sims_skills.py`` compares the kernel with those functions bit for bit.

#: Where ``step_parameters`` puts a world's constants of ``skill_step`` (one float64 row, fixed while the
#: goal and the scene are).
STEP_ROOT_TARGET = 0                   # x* (3)
STEP_PRIMARY = 3                       # the primary body's row
STEP_WALK = 4                          # 1.0: the walk reward (WALK_TERMS); 0.0: the contact reward
STEP_TARGET_SPEED = 5                  # v* (m/s)
STEP_HEIGHTS = 6                       # the height grid's origin x, y and cell size (3)
STEP_HEIGHTMAP = 9                     # heightmap_size, heightmap_extent (2)
STEP_SQUARE = 11                       # 2.0: the exponent of the squares Python writes x ** 2
STEP_NEAR = 12                         # the near zone's bound |x* - x|^2 (m^2; the weights' near_squared_distance)
STEP_MASK = 13                         # the goal's mask, 1.0 / 0.0 (15)
STEP_PARAMETERS_SIZE = STEP_MASK + NUM_CONTACT_JOINTS
#: The columns of ``skill_step``'s ``values`` row: the weighted reward terms (near, far, still: 0 for a
#: contact goal, which has none), the error (``skill_errors``), the root's ground velocity (the next step's
#: previous one), the root's position and the head's height.
STEP_VALUES = ("reward_near", "reward_far", "reward_still", "error", "root_vel_x", "root_vel_y",
               "root_x", "root_y", "root_z", "head_z")
STEP_VALUES_SIZE = len(STEP_VALUES)
_HEAD = BODY_NAMES.index("head")
_WALK_W = (WALK_WEIGHTS.near, WALK_WEIGHTS.far, WALK_WEIGHTS.still, WALK_WEIGHTS.far_position,
           WALK_WEIGHTS.far_velocity, WALK_WEIGHTS.far_facing)
_CONTACT_W = (CONTACT_WEIGHTS.near, CONTACT_WEIGHTS.far, CONTACT_WEIGHTS.still, CONTACT_WEIGHTS.far_position,
              CONTACT_WEIGHTS.far_velocity, CONTACT_WEIGHTS.far_facing)


def step_parameters(goal: ContactGoal, heights: SceneHeights, target_speed: float, heightmap_size: int,
                    heightmap_extent: float, near_squared_distance: float = NEAR_SQUARED_DISTANCE) -> np.ndarray:
    """(STEP_PARAMETERS_SIZE,) a world's constants of ``skill_step`` (the layout ``STEP_*``)."""
    params = np.empty(STEP_PARAMETERS_SIZE)
    params[STEP_ROOT_TARGET:STEP_ROOT_TARGET + 3] = goal.root_target
    params[STEP_PRIMARY] = goal.primary
    params[STEP_WALK] = 1.0 if goal.skill == "walk" else 0.0
    params[STEP_TARGET_SPEED] = target_speed
    params[STEP_HEIGHTS:STEP_HEIGHTS + 3] = (heights.origin[0], heights.origin[1], heights.cell_size)
    params[STEP_HEIGHTMAP:STEP_HEIGHTMAP + 2] = (heightmap_size, heightmap_extent)
    params[STEP_SQUARE] = 2.0
    params[STEP_NEAR] = near_squared_distance
    params[STEP_MASK:STEP_MASK + NUM_CONTACT_JOINTS] = goal.mask
    return params


@jit
def _blas_dot2(a0, a1, b0, b1):
    """``row_dots`` of two 2-vectors: OpenBLAS' ddot (unfused, from +0), then numpy's 0. + it."""
    dot = 0.0
    dot += a0 * b0
    dot += a1 * b1
    return 0.0 + dot


@jit
def _blas_dot3(a0, a1, a2, b0, b1, b2):
    """``row_dots`` of two 3-vectors (as ``_blas_dot2``)."""
    dot = 0.0
    dot += a0 * b0
    dot += a1 * b1
    dot += a2 * b2
    return 0.0 + dot


@jit
def _heading_row(r0, r1, r2, h0, h1, h2):
    """One entry of (rel @ heading) as OpenBLAS' dgemm kernel rounds it: fused multiply-adds from +0 down the
    column (h0, h1, h2) of the heading matrix."""
    return fma(r2, h2, fma(r1, h1, fma(r0, h0, 0.0)))


@jit
def _pairwise_sum15(a):
    """numpy's sum of the 15 entries of ``a`` (``np.sum(..., axis=-1)``: its pairwise sum, 8 partial sums)."""
    res = ((a[0] + a[1]) + (a[2] + a[3])) + ((a[4] + a[5]) + (a[6] + a[7]))
    for i in range(8, 15):
        res += a[i]
    return 0.0 + res


@jit
def skill_step(k, body_pos, body_mat, root_lin_vel, root_ang_vel, dof_vel, params, points, owner, heights, text,
               prev_root_vel, obs, targets, values):
    """World k's step outcome (row k of the batch's state arrays, of ``obs``, ``targets`` (B, 15, 3) and
    ``values`` (B, STEP_VALUES_SIZE)): the observation, the goal's targets (``goal_targets``), the weighted
    reward terms, the error and what the env keeps (``STEP_VALUES``). ``params``: ``step_parameters``;
    ``points``, ``owner``: the goal's target points and their bodies; ``heights``: the scene's height grid;
    ``text``: the text embedding; ``prev_root_vel`` (2,): the root's ground velocity a step before."""
    joints = body_pos[k]
    yaw, c, s = heading_cos_sin(body_mat[k, PELVIS])
    rx, ry, rz = joints[PELVIS, 0], joints[PELVIS, 1], joints[PELVIS, 2]
    row = obs[k]
    # proprioception and the heightmap, as ``skill_observations``
    write_proprioception(row, body_mat[k], root_lin_vel[k], root_ang_vel[k], dof_vel[k], rz, c, s)
    size = int(params[STEP_HEIGHTMAP])
    g0 = PROPRIOCEPTION_SIZE + size * size
    egocentric_heights(heights, params[STEP_HEIGHTS], params[STEP_HEIGHTS + 1], params[STEP_HEIGHTS + 2], rx, ry,
                       rz, yaw, size, params[STEP_HEIGHTMAP + 1], row[PROPRIOCEPTION_SIZE:g0])
    # the goal: targets relative to the root, masked, into the heading frame; the mask; the text
    t = nearest_targets(points, owner, joints, targets[k])
    g1 = g0 + 3 * NUM_CONTACT_JOINTS
    near_terms = np.empty(NUM_CONTACT_JOINTS)
    for j in range(NUM_CONTACT_JOINTS):
        m = params[STEP_MASK + j]
        r0, r1, r2 = (t[j, 0] - rx) * m, (t[j, 1] - ry) * m, (t[j, 2] - rz) * m
        row[g0 + 3 * j] = _heading_row(r0, r1, r2, c, s, 0.0)
        row[g0 + 3 * j + 1] = _heading_row(r0, r1, r2, -s, c, 0.0)
        row[g0 + 3 * j + 2] = _heading_row(r0, r1, r2, 0.0, 0.0, 1.0)
        row[g1 + j] = m
        e0, e1, e2 = t[j, 0] - joints[j, 0], t[j, 1] - joints[j, 1], t[j, 2] - joints[j, 2]
        near_terms[j] = ((e0 * e0 + e1 * e1) + e2 * e2) * m
    row[g1 + NUM_CONTACT_JOINTS:] = text
    # the reward (``direction_terms``, ``walk_reward_values`` / ``contact_reward_values``)
    two = params[STEP_SQUARE]
    d0, d1 = params[STEP_ROOT_TARGET] - rx, params[STEP_ROOT_TARGET + 1] - ry
    dist2 = _blas_dot2(d0, d1, d0, d1)
    norm = math.sqrt(dist2)
    u0 = u1 = 0.0
    if norm > 1e-9:
        u0, u1 = d0 / norm, d1 / norm
    vx, vy = root_lin_vel[k, 0], root_lin_vel[k, 1]
    along = _blas_dot2(u0, u1, vx, vy)
    facing = _blas_dot2(u0, u1, c, s)
    velocity = math.exp(-2.0 * math.pow(abs(params[STEP_TARGET_SPEED] - along), two))
    facing = math.pow(facing if facing > 0.0 else 0.0, two)
    walk = params[STEP_WALK] != 0.0
    w = _WALK_W if walk else _CONTACT_W
    near2 = dist2 if walk else _pairwise_sum15(near_terms)
    out = values[k]
    out[0] = w[0] * math.exp(-10.0 * near2)
    far = 1.0
    still = 0.0
    if dist2 > params[STEP_NEAR]:
        far = w[3] * math.exp(-0.5 * dist2) + w[4] * velocity + w[5] * facing
    elif walk:
        c0, c1 = vx - prev_root_vel[0], vy - prev_root_vel[1]
        still = math.exp(-2.0 * _blas_dot2(c0, c1, c0, c1))
    out[1] = w[1] * far
    out[2] = w[2] * still if walk else 0.0
    # the error (``skill_errors``)
    if walk:
        out[3] = math.hypot(params[STEP_ROOT_TARGET] - rx, params[STEP_ROOT_TARGET + 1] - ry)
    else:
        p = int(params[STEP_PRIMARY])
        o0, o1, o2 = t[p, 0] - joints[p, 0], t[p, 1] - joints[p, 1], t[p, 2] - joints[p, 2]
        out[3] = math.sqrt(_blas_dot3(o0, o1, o2, o0, o1, o2))
    out[4], out[5] = vx, vy
    out[6], out[7], out[8] = rx, ry, rz
    out[9] = joints[_HEAD, 2]
