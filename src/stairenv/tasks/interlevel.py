"""InterLevel stair climbing: observation, reward and termination (pure, batched).

Every public function takes arrays with a leading batch dimension B and returns
arrays with the same leading dimension: the single-world env calls them with
B = 1, a natively batched env with B = number of worlds. The kernels are
compiled with numba, which turns a step's ~80 small numpy calls (each costing
more than its arithmetic) into one native call; the formulas below are their
specification and the tests check them against hand-computed values.

Coordinates. The paper is y-up with x along the incline and z across it. Here
the world is z-up (MuJoCo) and every reward term is computed in the staircase's
own frame (see ``stairenv.world.stairs``):

| paper | here (stairs frame) | meaning |
|---|---|---|
| x | u | along the ascent, from M_B towards M_T |
| z | w | across the stairs (left of the ascent) |
| y | z | up |

Reward (paper Eq. 1-8), with p the root (pelvis) position in the stairs frame,
T = M_T and B = M_B:

    G(x; mu, s)   = exp(-(x - mu)^2 / (2 s^2)) / (s sqrt(2 pi))                    (2)
    TG(p_u)       = G(p_u; T_u, s1)            if T_u - p_u >= 0 (target ahead)
                    w_scale G(p_u; T_u, s2)    otherwise (past the target)         (3)
    R_location    = TG(p_u) G(p_w; T_w, s3) ReLU((p_z - B_z) / (T_z - B_z))        (4)
    R_facing      = ReLU(F_tar . F_cur)                                            (5, 6)
    R_velocity    = exp(-2 ReLU(S_tar - S_cur)^2)                                  (7, 8)
    R_p           = w_loc R_location + w_face R_facing + w_vel R_velocity          (1)

F_tar is the horizontal unit direction from the root to M_T, F_cur the root's
horizontal heading, S_cur the root's speed along the 3-D direction to M_T over
the last policy step (from p_{t-1} and p_t, as the paper computes it).
``progress_scaling=False`` replaces the ReLU height-progress factor by 1
(InterLevel-2D, Eq. 9). ``w_scale = s2 / s1`` makes the two peaks of TG equal.

Observation (118-D, ``OBSERVATION_STRUCTURE``): vectors are expressed in the
heading frame (the root's yaw removed), rotations as 6-D (first two columns of
the rotation matrix, Zhou et al.), joint rotations relative to the parent body.
The last entry is the angle between the root's heading and the ascent direction
M_B -> M_T, wrapped to [-pi, pi).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, fields
from typing import NamedTuple

import numpy as np

from stairenv.tasks.kernels import heading_cos_sin, jit, write_heading_vector, write_proprioception
from stairenv.tasks.stall import stall_step
from stairenv.humanoid.state import HEAD, LEFT_FOOT, PELVIS, RIGHT_FOOT, HumanoidState
from stairenv.validation import Check, check_number, checked, field_check
from stairenv.world.stairs import Staircase, StairsLayout

OBSERVATION_SIZE = 118
OBSERVATION_STRUCTURE: dict[str, slice] = {
    "root_height": slice(0, 1),              # world z of the pelvis
    "root_rotation": slice(1, 7),            # 6-D, heading frame
    "root_linear_velocity": slice(7, 10),    # heading frame
    "root_angular_velocity": slice(10, 13),  # heading frame
    "joint_rotations": slice(13, 85),        # 12 joints x 6-D, relative to the parent body
    "joint_velocities": slice(85, 113),      # 28 hinge velocities
    "target_offset": slice(113, 116),        # M_T - root, heading frame
    "marker_distance": slice(116, 117),      # |M_T - M_B|
    "stairs_angle": slice(117, 118),         # heading yaw - ascent yaw, in [-pi, pi)
}
REWARD_TERMS: tuple[str, ...] = ("reward_location", "reward_facing", "reward_velocity")
NUM_REWARD_TERMS = len(REWARD_TERMS)
# Where the observation kernel writes the task's entries (compile-time constants).
_OBS_TARGET_OFFSET = OBSERVATION_STRUCTURE["target_offset"].start
_OBS_MARKER_DISTANCE = OBSERVATION_STRUCTURE["marker_distance"].start
_OBS_STAIRS_ANGLE = OBSERVATION_STRUCTURE["stairs_angle"].start

# A root this far above the landing surface is standing on it (standing height 0.885 m).
STANDING_ON_TOP_MARGIN = 0.5

_SQRT_2PI = math.sqrt(2.0 * math.pi)
_EPS = 1e-9


class StairsGoal(NamedTuple):
    """Per-world constants of the task, batch-first, fixed for an episode; the step kernel takes it
    as it is and reads its fields by name. ``pack()`` lays the fields side by side in one
    (B, GOAL_SIZE) array (``GOAL_LAYOUT``, computed from ``GOAL_SHAPES``), ``unpack`` reads one back.
    """

    target: np.ndarray           # (B, 3) M_T, world
    bottom: np.ndarray           # (B, 3) M_B, world
    origin: np.ndarray           # (B, 3) stairs frame origin, world
    rotation: np.ndarray         # (B, 3, 3) world-from-stairs rotation (columns u, w, z)
    yaw: np.ndarray              # (B,) ascent direction
    marker_distance: np.ndarray  # (B,) |M_T - M_B|
    target_local: np.ndarray     # (B, 3) M_T, stairs frame
    bottom_local: np.ndarray     # (B, 3) M_B, stairs frame
    top_height: np.ndarray       # (B,) height of the landing surface
    step_depth: np.ndarray       # (B,) tread depth
    num_steps: np.ndarray        # (B,) risers, the landing's included
    landing_end: np.ndarray      # (B,) u of the landing's far edge
    half_width: np.ndarray       # (B,) half the stair width

    def pack(self) -> np.ndarray:
        b = self.target.shape[0]
        return np.ascontiguousarray(np.concatenate(
            [np.asarray(getattr(self, name)).reshape(b, -1) for name in GOAL_COLUMNS], axis=1))

    @classmethod
    def unpack(cls, packed: np.ndarray) -> StairsGoal:
        """The goal ``pack()`` laid out in ``packed`` (B, GOAL_SIZE); every field a contiguous copy."""
        b = packed.shape[0]
        return cls(**{name: np.ascontiguousarray(packed[:, GOAL_LAYOUT[name]].reshape((b, *shape)))
                      for name, shape in GOAL_SHAPES.items()})

    @classmethod
    def from_stairs(cls, stairs: Sequence[Staircase]) -> "StairsGoal":
        return cls.of_layout(StairsLayout.of(stairs, 0))

    @classmethod
    def of_layout(cls, layout: StairsLayout) -> "StairsGoal":
        """The goals of a ``StairsLayout``'s staircases (row i: staircase i)."""
        up = np.zeros_like(layout.axis)
        up[:, 2] = 1.0
        target, bottom = layout.marker_top, layout.marker_bottom
        return cls(
            target=target,
            bottom=bottom,
            origin=layout.origin,
            rotation=np.stack((layout.axis, layout.across, up), axis=-1),
            yaw=layout.yaw,
            marker_distance=np.linalg.norm(target - bottom, axis=-1),
            target_local=layout.marker_top_local,
            bottom_local=layout.marker_bottom_local,
            top_height=layout.num_steps * layout.step_height,
            step_depth=layout.step_depth,
            num_steps=layout.num_steps.astype(np.float64),
            landing_end=(layout.num_steps - 1) * layout.step_depth + layout.landing_depth,
            half_width=layout.width / 2,
        )


# Each field's per-world shape; pack()'s layout (offsets in this order) is computed from them.
GOAL_SHAPES: dict[str, tuple[int, ...]] = {
    "target": (3,), "bottom": (3,), "origin": (3,), "rotation": (3, 3), "yaw": (), "marker_distance": (),
    "target_local": (3,), "bottom_local": (3,), "top_height": (), "step_depth": (), "num_steps": (),
    "landing_end": (), "half_width": (),
}
assert tuple(GOAL_SHAPES) == StairsGoal._fields
GOAL_COLUMNS: tuple[str, ...] = StairsGoal._fields


def _layout(shapes: dict[str, tuple[int, ...]]) -> dict[str, slice]:
    layout, at = {}, 0
    for name, shape in shapes.items():
        size = math.prod(shape)
        layout[name] = slice(at, at + size)
        at += size
    return layout


GOAL_LAYOUT: dict[str, slice] = _layout(GOAL_SHAPES)
GOAL_SIZE = GOAL_LAYOUT[GOAL_COLUMNS[-1]].stop


class StepResults(NamedTuple):
    """Per-world results of the step kernel, each (B,): the three weighted reward terms of Eq. (1),
    the episode's end (``fell``, ``success``), the progress up the stairs (``surface_progress``), the
    root's height progress (``progress``) and the distance from the root to M_T (m)."""

    reward_location: np.ndarray
    reward_facing: np.ndarray
    reward_velocity: np.ndarray
    fell: np.ndarray              # 1.0 where the character fell, else 0.0
    success: np.ndarray           # 1.0 where it arrived, else 0.0
    progress: np.ndarray
    height_progress: np.ndarray
    distance_to_target: np.ndarray

    @classmethod
    def from_columns(cls, results: np.ndarray) -> StepResults:
        """Views of the kernel's (B, 8) array, whose columns are in field order."""
        return cls(*results.T)


STEP_RESULTS: tuple[str, ...] = StepResults._fields
assert STEP_RESULTS[:NUM_REWARD_TERMS] == REWARD_TERMS  # the terms first, in order


@dataclass(frozen=True)
class InterLevelReward:
    """Weights and shape parameters of Eq. 1-8 (defaults justified in the env docstring), each with its
    valid range. Built directly it takes anything ``float()`` takes (``check_number``); the env's
    keywords are also checked for their type (``stairenv.environments.config``)."""

    w_location: float = checked(3.0, Check("number", 0.0), "weight of R_location (Eq. 1)")
    w_facing: float = checked(0.1, Check("number", 0.0), "weight of R_facing (Eq. 1)")
    w_velocity: float = checked(0.4, Check("number", 0.0), "weight of R_velocity (Eq. 1)")
    sigma_before: float = checked(2.0, Check("number", 0.0, low_open=True),
                                  "s1 of Eq. 3-4: spread before the target, along the ascent (m)")
    sigma_after: float = checked(0.5, Check("number", 0.0, low_open=True),
                                 "s2 of Eq. 3-4: spread past the target, along the ascent (m)")
    sigma_across: float = checked(0.5, Check("number", 0.0, low_open=True),
                                  "s3 of Eq. 3-4: spread across the ascent (m)")
    w_scale: float | None = checked(None, Check("number", 0.0, optional=True),
                                    "factor past the target; None = s2/s1 (equal peaks)")
    target_speed: float = checked(1.0, Check("number", 0.0, 10.0), "S_tar (m/s)")
    progress_scaling: bool = checked(True, Check("bool"),
                                     "ReLU height-progress factor of Eq. 4; False = InterLevel-2D")

    def __post_init__(self) -> None:
        for field in fields(self):
            check, value = field_check(field), getattr(self, field.name)
            if field.name == "w_scale" and value is None:  # (the sigmas, checked above, give it)
                value = equal_peak_scale(self.sigma_before, self.sigma_after)
            if check.kind == "number":
                value = check_number(field.name, value, check.low, check.high, check.low_open)
            else:
                value = bool(value)
            object.__setattr__(self, field.name, value)

    def as_array(self) -> np.ndarray:
        """What the compiled kernels take: the fields in ``REWARD_FIELDS`` order as one float64 array
        (``progress_scaling`` as 1.0 or 0.0), read there by the named indices ``_P_*``."""
        return np.array([getattr(self, name) for name in REWARD_FIELDS], dtype=np.float64)


# The kernels' reward array: InterLevelReward's fields in order, and where each one is (compile-time
# constants, so the kernel takes one array instead of nine scalars).
REWARD_FIELDS: tuple[str, ...] = tuple(field.name for field in fields(InterLevelReward))
(_P_W_LOCATION, _P_W_FACING, _P_W_VELOCITY, _P_SIGMA_BEFORE, _P_SIGMA_AFTER, _P_SIGMA_ACROSS, _P_W_SCALE,
 _P_TARGET_SPEED, _P_PROGRESS_SCALING) = range(len(REWARD_FIELDS))
assert REWARD_FIELDS == ("w_location", "w_facing", "w_velocity", "sigma_before", "sigma_after", "sigma_across",
                         "w_scale", "target_speed", "progress_scaling")


def equal_peak_scale(sigma_before: float, sigma_after: float) -> float:
    """w_scale that gives both halves of the threshold Gaussian the same peak."""
    return sigma_after / sigma_before


# --- scalar formulas (compiled; also callable with numpy arrays) ----------------
@jit
def gaussian(x, mu, sigma):
    """Eq. (2): the normal density N(x; mu, sigma^2)."""
    return np.exp((x - mu) * (x - mu) * (-0.5 / (sigma * sigma))) / (sigma * _SQRT_2PI)


@jit
def _threshold_gaussian(x, mu, sigma_before, sigma_after, w_scale):
    if mu - x >= 0.0:
        return gaussian(x, mu, sigma_before)
    return w_scale * gaussian(x, mu, sigma_after)


@jit
def _height_progress(z, bottom_z, top_z):
    return max((z - bottom_z) / (top_z - bottom_z), 0.0)


@jit
def _velocity_reward(speed, target_speed):
    error = max(target_speed - speed, 0.0)
    return math.exp(-2.0 * error * error)


@jit
def _facing(hx, hy, tx, ty):
    norm = math.sqrt(hx * hx + hy * hy) * math.sqrt(tx * tx + ty * ty)
    return max((hx * tx + hy * ty) / (norm + _EPS), 0.0)


# --- batched reward pieces ------------------------------------------------------
@jit
def threshold_gaussian(x, mu, sigma_before, sigma_after, w_scale):
    """Eq. (3) for (B,) arrays: G(sigma_before) while mu - x >= 0, else w_scale G(sigma_after)."""
    out = np.empty(x.shape[0])
    for b in range(x.shape[0]):
        out[b] = _threshold_gaussian(x[b], mu[b], sigma_before, sigma_after, w_scale)
    return out


@jit
def height_progress(z, bottom_z, top_z):
    """ReLU((z - B_z) / (T_z - B_z)), the factor of Eq. (4), for (B,) arrays."""
    out = np.empty(z.shape[0])
    for b in range(z.shape[0]):
        out[b] = _height_progress(z[b], bottom_z[b], top_z[b])
    return out


@jit
def location_reward(root_local, target_local, bottom_local, sigma_before, sigma_after, sigma_across,
                    w_scale, progress_scaling):
    """Eq. (4), or Eq. (9) with ``progress_scaling=False``; points (B, 3) in the stairs frame."""
    out = np.empty(root_local.shape[0])
    for b in range(root_local.shape[0]):
        r = _threshold_gaussian(root_local[b, 0], target_local[b, 0], sigma_before, sigma_after, w_scale)
        r *= gaussian(root_local[b, 1], target_local[b, 1], sigma_across)
        if progress_scaling:
            r *= _height_progress(root_local[b, 2], bottom_local[b, 2], target_local[b, 2])
        out[b] = r
    return out


@jit
def facing_reward(heading, root_pos, target):
    """Eq. (5)-(6): ReLU(F_tar . F_cur). heading (B, 2) any length; root_pos, target (B, 3)."""
    out = np.empty(heading.shape[0])
    for b in range(heading.shape[0]):
        out[b] = _facing(heading[b, 0], heading[b, 1], target[b, 0] - root_pos[b, 0], target[b, 1] - root_pos[b, 1])
    return out


@jit
def speed_towards(prev_root, root, target, dt):
    """S_cur: the root's speed along the 3-D direction from p_{t-1} to the target, (B,)."""
    out = np.empty(root.shape[0])
    for b in range(root.shape[0]):
        dot, dist2 = 0.0, 0.0
        for i in range(3):
            d = target[b, i] - prev_root[b, i]
            dot += (root[b, i] - prev_root[b, i]) * d
            dist2 += d * d
        out[b] = dot / (dt * math.sqrt(dist2) + _EPS)
    return out


@jit
def velocity_reward(speed, target_speed):
    """Eq. (7)-(8): exp(-2 ReLU(S_tar - S_cur)^2) for (B,) speeds; only being too slow is penalised."""
    out = np.empty(speed.shape[0])
    for b in range(speed.shape[0]):
        out[b] = _velocity_reward(speed[b], target_speed)
    return out


@jit
def to_stairs_frame(points, origin, rotation):
    """World points (B, 3) -> stairs frame (u, w, z) given origins (B, 3) and rotations (B, 3, 3)."""
    out = np.empty(points.shape)
    for b in range(points.shape[0]):
        for i in range(3):
            acc = 0.0
            for m in range(3):
                acc += (points[b, m] - origin[b, m]) * rotation[b, m, i]
            out[b, i] = acc
    return out


# --- termination ----------------------------------------------------------------
@jit
def has_fallen(body_pos, min_height_gap):
    """Early termination, (B, 15, 3) -> (B,) bool: the head or a foot within
    ``min_height_gap`` (vertically) of the hips, i.e. the body is close to horizontal."""
    out = np.empty(body_pos.shape[0], dtype=np.bool_)
    for b in range(body_pos.shape[0]):
        pelvis_z = body_pos[b, PELVIS, 2]
        highest_foot = max(body_pos[b, RIGHT_FOOT, 2], body_pos[b, LEFT_FOOT, 2])
        out[b] = (body_pos[b, HEAD, 2] - pelvis_z < min_height_gap) or (pelvis_z - highest_foot < min_height_gap)
    return out


@jit
def reached_top(root_pos, target, top_height, radius):
    """Success, (B,) bool: root within ``radius`` of M_T on the ground plane and standing on the top floor."""
    out = np.empty(root_pos.shape[0], dtype=np.bool_)
    for b in range(root_pos.shape[0]):
        dx, dy = root_pos[b, 0] - target[b, 0], root_pos[b, 1] - target[b, 1]
        out[b] = dx * dx + dy * dy < radius * radius and root_pos[b, 2] > top_height[b] + STANDING_ON_TOP_MARGIN
    return out


@jit
def surface_progress(root_pos, origin, rotation, step_depth, num_steps, landing_end, half_width):
    """Progress up the stairs, (B,): the tread under the root's ground point as a fraction of the
    risers (k / n on tread k, 1 on the landing, 0 on the floor). Unlike the root's height it
    does not count a hop or a crouch on the floor, nor a fall onto the stairs from above."""
    out = np.empty(root_pos.shape[0])
    for b in range(root_pos.shape[0]):
        u = 0.0
        w = 0.0
        for m in range(2):
            u += (root_pos[b, m] - origin[b, m]) * rotation[b, m, 0]
            w += (root_pos[b, m] - origin[b, m]) * rotation[b, m, 1]
        if u < 0.0 or u > landing_end[b] or abs(w) > half_width[b]:
            out[b] = 0.0
        else:
            out[b] = min(math.floor(u / step_depth[b]) + 1.0, num_steps[b]) / num_steps[b]
    return out


@jit
def progress(root_pos, bottom, target):
    """Height progress of the root between M_B and M_T, clipped to [0, 1]: (B,)."""
    out = np.empty(root_pos.shape[0])
    for b in range(root_pos.shape[0]):
        out[b] = min(max((root_pos[b, 2] - bottom[b, 2]) / (target[b, 2] - bottom[b, 2]), 0.0), 1.0)
    return out


# --- observation ----------------------------------------------------------------
@jit
def _observation_kernel(body_pos, body_mat, root_lin_vel, root_ang_vel, dof_vel, target, marker_distance,
                        stairs_yaw, out):
    for b in range(body_pos.shape[0]):
        row = out[b]
        p = body_pos[b, PELVIS]
        yaw, c, s = heading_cos_sin(body_mat[b, PELVIS])
        write_proprioception(row, body_mat[b], root_lin_vel[b], root_ang_vel[b], dof_vel[b], p[2], c, s)
        write_heading_vector(row, _OBS_TARGET_OFFSET, target[b, 0] - p[0], target[b, 1] - p[1], target[b, 2] - p[2], c, s)
        row[_OBS_MARKER_DISTANCE] = marker_distance[b]
        row[_OBS_STAIRS_ANGLE] = (yaw - stairs_yaw[b] + math.pi) % (2.0 * math.pi) - math.pi
    return out


def interlevel_observation(state: HumanoidState, goal: StairsGoal) -> np.ndarray:
    """The 118-D observation, layout ``OBSERVATION_STRUCTURE``: (B, 118)."""
    out = np.empty((state.body_pos.shape[0], OBSERVATION_SIZE))
    return _observation_kernel(state.body_pos, state.body_mat, state.root_lin_vel, state.root_ang_vel,
                               state.dof_vel, goal.target, goal.marker_distance, goal.yaw, out)


# --- the whole step -------------------------------------------------------------
@jit
def _reward_kernel(body_pos, body_mat, prev_root, origin, rotation, target, target_local, bottom_local, dt,
                   reward, out):
    """The weighted terms into ``out`` (B, NUM_REWARD_TERMS) in ``REWARD_TERMS`` order; ``reward`` is
    ``InterLevelReward.as_array()``."""
    root = body_pos[:, PELVIS]
    location = location_reward(to_stairs_frame(root, origin, rotation), target_local, bottom_local,
                               reward[_P_SIGMA_BEFORE], reward[_P_SIGMA_AFTER], reward[_P_SIGMA_ACROSS],
                               reward[_P_W_SCALE], reward[_P_PROGRESS_SCALING] > 0.5)
    facing = facing_reward(body_mat[:, PELVIS, :2, 0], root, target)
    velocity = velocity_reward(speed_towards(prev_root, root, target, dt), reward[_P_TARGET_SPEED])
    w_location, w_facing, w_velocity = reward[_P_W_LOCATION], reward[_P_W_FACING], reward[_P_W_VELOCITY]
    for b in range(root.shape[0]):
        out[b, 0] = w_location * location[b]
        out[b, 1] = w_facing * facing[b]
        out[b, 2] = w_velocity * velocity[b]
    return out


def interlevel_reward_terms(
    state: HumanoidState, prev_root: np.ndarray, goal: StairsGoal, cfg: InterLevelReward, dt: float
) -> np.ndarray:
    """The weighted terms of Eq. (1), (B, NUM_REWARD_TERMS) in ``REWARD_TERMS`` order (location, facing,
    velocity)."""
    out = np.empty((state.body_pos.shape[0], NUM_REWARD_TERMS))
    return _reward_kernel(state.body_pos, state.body_mat, prev_root, goal.origin, goal.rotation, goal.target,
                          goal.target_local, goal.bottom_local, dt, cfg.as_array(), out)


# Where the step kernel finds each goal field in ``StairsGoal.pack()`` (from ``GOAL_LAYOUT``) and puts
# each result (``STEP_RESULTS``): compile-time constants, so the kernel takes one goal array and
# fills one result array (a tuple argument would cost ~15 us a call in numba's dispatcher).
(_G_TARGET, _G_BOTTOM, _G_ORIGIN, _, _G_YAW, _G_MARKER_DISTANCE, _G_TARGET_LOCAL, _G_BOTTOM_LOCAL, _G_TOP_HEIGHT, _G_STEP_DEPTH,
 _G_NUM_STEPS, _G_LANDING_END, _G_HALF_WIDTH) = (GOAL_LAYOUT[name].start for name in GOAL_COLUMNS)
_R_FELL, _R_SUCCESS, _R_PROGRESS, _R_HEIGHT_PROGRESS, _R_DISTANCE_TO_TARGET = range(NUM_REWARD_TERMS, len(STEP_RESULTS))


@jit
def _vec3(goal, at):
    return goal[:, at:at + 3]


@jit
def _step_kernel(body_pos, body_mat, root_lin_vel, root_ang_vel, dof_vel, prev_root, goal, rotation, dt,
                 termination_height, success_radius, reward, obs, results):
    """``goal`` packed, ``rotation`` its (B, 3, 3) field, ``reward`` ``InterLevelReward.as_array()``."""
    target, bottom, origin = _vec3(goal, _G_TARGET), _vec3(goal, _G_BOTTOM), _vec3(goal, _G_ORIGIN)
    _observation_kernel(body_pos, body_mat, root_lin_vel, root_ang_vel, dof_vel, target, goal[:, _G_MARKER_DISTANCE],
                        goal[:, _G_YAW], obs)
    terms = _reward_kernel(body_pos, body_mat, prev_root, origin, rotation, target, _vec3(goal, _G_TARGET_LOCAL),
                           _vec3(goal, _G_BOTTOM_LOCAL), dt, reward,
                           np.empty((body_pos.shape[0], NUM_REWARD_TERMS)))
    root = body_pos[:, PELVIS]
    fell = has_fallen(body_pos, termination_height)
    success = reached_top(root, target, goal[:, _G_TOP_HEIGHT], success_radius)
    stairs_progress = surface_progress(root, origin, rotation, goal[:, _G_STEP_DEPTH], goal[:, _G_NUM_STEPS],
                                       goal[:, _G_LANDING_END], goal[:, _G_HALF_WIDTH])
    root_progress = progress(root, bottom, target)
    for b in range(root.shape[0]):
        for i in range(NUM_REWARD_TERMS):
            results[b, i] = terms[b, i]
        results[b, _R_FELL] = fell[b]
        results[b, _R_SUCCESS] = success[b]
        results[b, _R_PROGRESS] = stairs_progress[b]
        results[b, _R_HEIGHT_PROGRESS] = root_progress[b]
        d2 = 0.0
        for i in range(3):
            d2 += (target[b, i] - root[b, i]) ** 2
        results[b, _R_DISTANCE_TO_TARGET] = math.sqrt(d2)


def interlevel_outcome(
    state: HumanoidState,
    prev_root: np.ndarray,
    goal: StairsGoal,
    cfg: InterLevelReward,
    dt: float,
    termination_height: float,
    success_radius: float,
    packed_goal: np.ndarray | None = None,
) -> tuple[np.ndarray, StepResults]:
    """Everything a step needs in one compiled call: the observation (B, 118) and the named
    per-world ``StepResults``. ``packed_goal``: ``goal.pack()`` if the caller keeps it (an env does,
    for the episode).

    It calls the same kernels as ``interlevel_observation``, ``interlevel_reward_terms``,
    ``has_fallen``, ``reached_top``, ``surface_progress`` and ``progress``.
    """
    obs, results = interlevel_outcome_columns(state, prev_root, goal.pack() if packed_goal is None else packed_goal,
                                               goal.rotation, cfg.as_array(), dt, termination_height, success_radius)
    return obs, StepResults.from_columns(results)


def interlevel_outcome_columns(state, prev_root, packed_goal, rotation, reward, dt, termination_height, success_radius):
    """The step kernel's call (what an env calls each step): the observation (B, 118) and the results
    (B, 8) in ``STEP_RESULTS`` order; ``packed_goal`` is ``goal.pack()``, ``rotation`` ``goal.rotation``,
    ``reward`` ``InterLevelReward.as_array()`` (an env keeps both for the episode)."""
    batch = state.body_pos.shape[0]
    obs = np.empty((batch, OBSERVATION_SIZE))
    results = np.empty((batch, len(STEP_RESULTS)))
    _step_kernel(state.body_pos, state.body_mat, state.root_lin_vel, state.root_ang_vel, state.dof_vel, prev_root,
                 packed_goal, rotation, dt, termination_height, success_radius, reward, obs, results)
    return obs, results


@jit
def _reward_and_end_kernel(terms, results, steps, approach, approach_at, params, out_terms, out_reward, flags):
    min_approach, stall_seconds, dt = params[_E_STALL_DISTANCE], params[_E_STALL_SECONDS], params[_E_DT]
    success_reward, failure_reward = params[_E_SUCCESS_REWARD], params[_E_FAILURE_REWARD]
    terminate_on_success = params[_E_TERMINATE_ON_SUCCESS] > 0.5
    for b in range(terms.shape[0]):
        started = steps[b] > 0    # nothing has happened yet at an episode's start
        success = started and results[b, _R_SUCCESS] != 0.0
        # a step at M_T bent over counts as the success it is, not also as a fall (one reward, one ending)
        fell = started and results[b, _R_FELL] != 0.0 and not success
        total = 0.0
        for i in range(terms.shape[1]):    # a fall replaces the task terms by the failure reward
            out_terms[b, i] = 0.0 if fell else terms[b, i]
            total += out_terms[b, i]
        bonus = success_reward if success else 0.0
        penalty = failure_reward if fell else 0.0
        out_terms[b, terms.shape[1]] = bonus
        out_terms[b, terms.shape[1] + 1] = penalty
        out_reward[b] = total + (bonus + penalty)
        stalled, approach[b], approach_at[b] = stall_step(results[b, _R_DISTANCE_TO_TARGET], steps[b], approach[b],
                                                          approach_at[b], min_approach, stall_seconds, dt)
        stalled = stalled and not (fell or success)
        flags[b, 0], flags[b, 1], flags[b, 2] = fell, success, stalled
        flags[b, 3] = fell or (success and terminate_on_success) or stalled


#: columns of ``interlevel_reward_and_end``'s flags
END_FLAGS = ("fell", "success", "stalled", "ended")
#: what ``end_parameters`` packs, in order
END_PARAMETERS = ("stall_distance", "stall_seconds", "dt", "success_reward", "failure_reward", "terminate_on_success")
(_E_STALL_DISTANCE, _E_STALL_SECONDS, _E_DT, _E_SUCCESS_REWARD, _E_FAILURE_REWARD,
 _E_TERMINATE_ON_SUCCESS) = range(len(END_PARAMETERS))


def end_parameters(stall_distance: float, stall_seconds: float | None, dt: float, success_reward: float,
                   failure_reward: float, terminate_on_success: bool) -> np.ndarray:
    """``interlevel_reward_and_end``'s settings as one array (``END_PARAMETERS``; no stall: ``stall_seconds``
    None, packed as inf), which an env keeps for the episode."""
    return np.array([stall_distance, math.inf if stall_seconds is None else stall_seconds, dt, success_reward,
                     failure_reward, 1.0 if terminate_on_success else 0.0], dtype=np.float64)


def interlevel_reward_and_end(terms: np.ndarray, results: np.ndarray, steps: np.ndarray, approach: np.ndarray,
                              approach_at: np.ndarray, params: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A step's reward and end from the step kernel's ``results`` (``STEP_RESULTS`` columns) and the weighted
    task ``terms`` (B, T) (Eq. 1's, or another reward's), the episodes' step counts ``steps`` and their stall
    clocks (``approach``, ``approach_at``: ``stairenv.tasks.stall``, updated in place); ``params`` is
    ``end_parameters(...)``. Returns ``(reward (B,), terms (B, T + 2), flags (B, 4))``: the terms' last two
    columns the success bonus and the failure reward, the flags ``END_FLAGS``. A fall replaces the task
    terms by the failure reward; success adds the success reward, and a step that is both (at M_T, bent
    over) is a success, not a fall; neither counts at an episode's first outcome (``steps`` 0). The reward
    is the terms summed in order, the bonus and failure reward last. A stall counts only without a fall or
    success; the episode ends on a fall, a stall, or success where success terminates."""
    batch = terms.shape[0]
    out_terms = np.empty((batch, terms.shape[1] + 2))
    reward = np.empty(batch)
    flags = np.empty((batch, len(END_FLAGS)), dtype=np.bool_)
    _reward_and_end_kernel(terms, results, steps, approach, approach_at, params, out_terms, reward, flags)
    return reward, out_terms, flags


# the old names of ``interlevel_outcome`` and ``interlevel_outcome_columns``; deprecated, for one release
_OLD_NAMES = {"interlevel_evaluate": "interlevel_outcome", "interlevel_evaluate_columns": "interlevel_outcome_columns"}


def __getattr__(name: str):
    if name in _OLD_NAMES:
        warnings.warn(f"stairenv.tasks.interlevel.{name} is deprecated: use {_OLD_NAMES[name]} (a step's outcome; "
                      "'evaluation' now means only the papers' protocol, stairenv.evaluation)",
                      DeprecationWarning, stacklevel=2)
        return globals()[_OLD_NAMES[name]]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
