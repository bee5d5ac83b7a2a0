"""PlaMo path following: random training paths, observation pieces and the reward r^tau.

A path is the head's requested position sampled every ``dt`` seconds:
``PathSamples.points`` (T, 3) with the head's yaw and pitch along it. Training
paths come from ``random_head_path``: head heights are sampled first (smooth
transitions between levels in ``head_range``), then speeds; with
``coupled=True`` (PlaMo) the speed is uniform in [0, v_max(z)] with

    v_max(z) = min(1 + 4 (z - z_min) / (1.2 - z_min), V_max),  z_min = 0.4 m, V_max = 5 m/s,

so crawling is slow and running is upright; ``coupled=False`` (the paper's naive
ablation) samples speed uniform in [0, V_max] regardless of height.

Reward (paper Sec. 3.2), with s the head, tau_t the path point due now:

    r^tau = exp(-c_pos |tau^xy - s^xy|^2) + exp(-c_height (tau^z - s^z)^2)
            + exp(-c_dir |tau^(yaw,pitch) - s^(yaw,pitch)|^2) + c_body (z_head - max_body z)

with c_pos = 2, c_height = 10, c_dir = 20, c_body = 0.1 (yaw difference wrapped). Those numbers
are held in one place, ``PathReward`` (``PATH_REWARD``); each term is a small pure function
(``position_term``, ...) named and weighed in ``TERMS``. ``heightmap_points``, ``path_observation`` and
``path_reward_terms`` are the numpy forms of the observation and reward; ``PlaMoEnv._step_outcomes``
computes the same bits for a batch of worlds with their compiled pieces (``write_terrain_heightmap``,
``write_path_observation``) and ``path_reward_values`` (Python floats).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from stairenv.numba_jit import jit
from stairenv.tasks.terms import RewardTerm, term_names, weighted_terms, weighted_values
from stairenv.validation import check_number, check_range
from stairenv.world.terrain import bilinear_at, clamped_bilinear_at

Z_MIN, Z_KNEE, V_MAX = 0.4, 1.2, 5.0
C_POS, C_HEIGHT, C_DIR, C_BODY = 2.0, 10.0, 20.0, 0.1


@dataclass(frozen=True)
class PathReward:
    """The weights (``w_*``) and sharpnesses (``c_*``) of r^tau, the one place that holds them."""

    w_position: float = 1.0
    w_height: float = 1.0
    w_direction: float = 1.0
    w_body: float = C_BODY
    c_position: float = C_POS
    c_height: float = C_HEIGHT
    c_direction: float = C_DIR


PATH_REWARD = PathReward()


class PathRewardInputs(NamedTuple):
    """What the terms of r^tau are computed from, for one world (squared errors in m^2 and rad^2)."""

    position_error2: float   # |tau^xy - s^xy|^2
    height_error2: float     # (tau^z - s^z)^2
    direction_error2: float  # |tau^(yaw,pitch) - s^(yaw,pitch)|^2, the yaw difference wrapped
    head_above_body: float   # z_head - max body z (<= 0)


def position_term(x: PathRewardInputs, w: PathReward) -> float:
    return math.exp(-w.c_position * x.position_error2)


def height_term(x: PathRewardInputs, w: PathReward) -> float:
    return math.exp(-w.c_height * x.height_error2)


def direction_term(x: PathRewardInputs, w: PathReward) -> float:
    return math.exp(-w.c_direction * x.direction_error2)


def body_term(x: PathRewardInputs, w: PathReward) -> float:
    """Keeping the head the highest body: z_head - max body z."""
    return x.head_above_body


TERMS = (RewardTerm("reward_position", position_term, "w_position"),
         RewardTerm("reward_height", height_term, "w_height"),
         RewardTerm("reward_direction", direction_term, "w_direction"),
         RewardTerm("reward_body", body_term, "w_body"))
REWARD_TERMS = term_names(TERMS)


def pose_imitation_term(reference_joints: np.ndarray, joints: np.ndarray, c_pose: float) -> float:
    """A training aid's imitation term, DeepMimic's pose reward on our hinge joints:
    exp(-c_pose * sum_j (q_ref_j - q_j)^2), the joint angles in rad (a 3-axis joint as its three hinges);
    c_pose is the env's ``pose_sharpness`` (DeepMimic's 2 by default)."""
    d = np.asarray(reference_joints, dtype=np.float64) - np.asarray(joints, dtype=np.float64)
    return math.exp(-c_pose * float(d @ d))


def coupled_max_speed(head_height: np.ndarray, z_min: float = Z_MIN, v_max: float = V_MAX) -> np.ndarray:
    """PlaMo's v_max(z) = min(1 + 4 (z - z_min) / (1.2 - z_min), V_max), at least 1 m/s."""
    z = np.asarray(head_height, dtype=np.float64)
    return np.clip(1.0 + 4.0 * (z - z_min) / (Z_KNEE - z_min), 1.0, v_max)


@dataclass(frozen=True)
class PathConfig:
    """How random training paths are drawn (lengths in m, times in s, speeds in m/s)."""

    head_range: tuple[float, float] = (0.4, 1.47)
    speed_range: tuple[float, float] | None = None  # None: [0, v_max(z)] coupled, or [0, V_max] naive
    coupled: bool = True
    segment_duration: tuple[float, float] = (2.0, 5.0)
    transition: float = 1.0          # smooth change of head height and speed between segments
    max_turn_rate: float = 0.8       # rad/s, a new turn rate per segment
    dt: float = 0.1
    speed_scale: float = 1.0         # every speed times this (a speed curriculum's level; 1 = the paper's)

    def __post_init__(self) -> None:
        object.__setattr__(self, "head_range", check_range("head_range", self.head_range, 0.2, 2.0))
        if self.speed_range is not None:
            object.__setattr__(self, "speed_range", check_range("speed_range", self.speed_range, 0.0, 10.0))
        object.__setattr__(self, "segment_duration", check_range("segment_duration", self.segment_duration, 0.2, 1e4))
        check_number("transition", self.transition, 0.0, 10.0)
        check_number("max_turn_rate", self.max_turn_rate, 0.0, 10.0)
        check_number("dt", self.dt, 0.0, 1.0, low_open=True)
        check_number("speed_scale", self.speed_scale, 0.0, 1.0, low_open=True)


class PathSamples(NamedTuple):
    points: np.ndarray  # (T, 3) head positions (z relative to the terrain under it is in ``head``)
    head: np.ndarray    # (T,) requested head height above the terrain
    speed: np.ndarray   # (T,) requested horizontal speed
    yaw: np.ndarray     # (T,) direction of travel
    pitch: np.ndarray   # (T,) slope of travel (rad)
    dt: float

    def at(self, t: float | np.ndarray) -> np.ndarray:
        """Head target at time(s) t (linear between samples, held after the end): (..., 3)."""
        f = np.clip(np.asarray(t, dtype=np.float64) / self.dt, 0.0, len(self.points) - 1.000001)
        i = np.floor(f).astype(int)
        a = (f - i)[..., None]
        return (1 - a) * self.points[i] + a * self.points[i + 1]

    def index(self, t: float) -> int:
        return int(min(max(round(t / self.dt), 0), len(self.points) - 1))


def _smooth_levels(rng: np.random.Generator, times: np.ndarray, config: PathConfig, draw) -> np.ndarray:
    """Piecewise-constant levels per random-length segment, blended over ``transition`` seconds."""
    values = np.empty_like(times)
    t, current = 0.0, draw(None)
    starts, levels = [], []
    while t <= times[-1] + 1e-9:
        starts.append(t)
        levels.append(current)
        t += rng.uniform(*config.segment_duration)
        current = draw(current)
    starts, levels = np.array(starts), np.array(levels)
    seg = np.searchsorted(starts, times, side="right") - 1
    values[:] = levels[seg]
    if config.transition > 0:
        # Cosine blend from the previous level during the first `transition` seconds of a segment.
        since = times - starts[seg]
        blend = np.clip(since / config.transition, 0.0, 1.0)
        previous = levels[np.maximum(seg - 1, 0)]
        w = 0.5 - 0.5 * np.cos(np.pi * blend)
        values = np.where(seg > 0, previous + w * (levels[seg] - previous), values)
    return values


def random_head_path(config: PathConfig, rng: np.random.Generator, duration: float, start_xy: np.ndarray,
                     start_yaw: float, ground_height, arena_half: float | None = None,
                     scale_speeds=None) -> PathSamples:
    """A random head path of ``duration`` seconds from ``start_xy`` (pure given rng).

    ``ground_height(xy (T, 2)) -> (T,)`` gives the terrain under the path; paths turn back
    before leaving ``arena_half`` (a square of that half size around the origin).
    ``scale_speeds(head (T,), speed (T,)) -> (T,)``, if given, is each sample's speed factor from the
    drawn head heights and speeds (a per-locomotion speed curriculum), applied with ``speed_scale``.
    """
    times = np.arange(int(math.ceil(duration / config.dt)) + 1) * config.dt
    head = _smooth_levels(rng, times, config, lambda prev: rng.uniform(*config.head_range))
    if config.speed_range is not None:
        fraction = _smooth_levels(rng, times, config, lambda prev: rng.uniform())
        speed = config.speed_range[0] + fraction * (config.speed_range[1] - config.speed_range[0])
    else:
        fraction = _smooth_levels(rng, times, config, lambda prev: rng.uniform())
        cap = coupled_max_speed(head) if config.coupled else np.full_like(head, V_MAX)
        speed = fraction * cap
    if scale_speeds is not None:
        speed = speed * scale_speeds(head, speed)
    speed = speed * config.speed_scale  # (x * 1.0 is x: the default paths are unchanged to the bit)
    turn = _smooth_levels(rng, times, config, lambda prev: rng.uniform(-1, 1) * config.max_turn_rate)
    xy = np.empty((len(times), 2))
    yaw = np.empty(len(times))
    start_x, start_y = np.asarray(start_xy, dtype=np.float64)
    walk_path(speed, turn, config.dt, start_x, start_y, start_yaw, math.inf if arena_half is None else arena_half,
              xy, yaw)
    ground = ground_height(xy)
    points = np.column_stack((xy, ground + head))
    rise = np.gradient(points[:, 2], config.dt)
    pitch = np.arctan2(rise, np.maximum(speed, 1e-6))
    return PathSamples(points, head, speed, yaw, pitch, config.dt)


@jit
def walk_path(speed, turn, dt, x, y, heading, arena_half, xy, yaw):
    """``random_head_path``'s walk from (x, y) facing ``heading``: point k + 1 is ``speed[k] * dt`` on from
    point k, turned by ``turn[k] * dt``, or towards the centre where it would leave the arena (``arena_half``,
    inf: none); written to ``xy`` (T, 2) and ``yaw`` (T,). (The libm functions CPython's ``math`` calls.)"""
    xy[0, 0], xy[0, 1], yaw[0] = x, y, heading
    for k in range(1, yaw.shape[0]):
        heading = heading + turn[k - 1] * dt
        step = speed[k - 1] * dt
        # Steer back towards the centre when the next point would leave the arena.
        if abs(x + step * math.cos(heading)) > arena_half or abs(y + step * math.sin(heading)) > arena_half:
            heading = math.atan2(-y, -x)
        x, y = x + step * math.cos(heading), y + step * math.sin(heading)
        xy[k, 0], xy[k, 1], yaw[k] = x, y, heading


def path_observation(path: PathSamples, t: float, head_pos: np.ndarray, root_yaw: float,
                     num: int = 10, spacing: float = 0.5) -> np.ndarray:
    """The next ``num`` head targets every ``spacing`` s from t, relative to the head, heading frame: (num * 3,)."""
    targets = path.at(t + spacing * np.arange(1, num + 1)) - head_pos
    c, s = math.cos(root_yaw), math.sin(root_yaw)
    local = np.column_stack((c * targets[:, 0] + s * targets[:, 1], -s * targets[:, 0] + c * targets[:, 1],
                             targets[:, 2]))
    return local.ravel()


def heightmap_offsets(size: int, extent: float) -> tuple[np.ndarray, np.ndarray]:
    """The heightmap grid before it is turned and moved to the root: x and y offsets (size * size,), in
    ``heightmap_points``'s order (row by row)."""
    offsets = (np.arange(size) + 0.5) / size * extent - extent / 2
    gx, gy = np.meshgrid(offsets, offsets)
    return gx.ravel(), gy.ravel()


def heightmap_points(root_xy: np.ndarray, root_yaw: float, size: int, extent: float) -> np.ndarray:
    """World (x, y) of a size x size grid of ``extent`` metres, centred on the root, turned with its yaw."""
    gx, gy = heightmap_offsets(size, extent)
    c, s = math.cos(root_yaw), math.sin(root_yaw)
    return np.stack((root_xy[0] + c * gx - s * gy, root_xy[1] + s * gx + c * gy), axis=-1)


def path_reward_terms(target: np.ndarray, head: np.ndarray, target_yaw: float, target_pitch: float,
                      head_yaw: float, head_pitch: float, max_body_z: float,
                      reward: PathReward = PATH_REWARD) -> np.ndarray:
    """The four weighted terms of r^tau (position, height, direction, body) for one world: (4,)."""
    return weighted_terms(path_reward_inputs(target, head, target_yaw, target_pitch, head_yaw, head_pitch,
                                             max_body_z), reward, TERMS)


def path_reward_values(target, head, target_yaw: float, target_pitch: float, head_yaw: float, head_pitch: float,
                       max_body_z: float, reward: PathReward = PATH_REWARD) -> tuple[float, ...]:
    """``path_reward_terms`` as a tuple of floats (what the env's step uses, world by world)."""
    return weighted_values(path_reward_inputs(target, head, target_yaw, target_pitch, head_yaw, head_pitch,
                                              max_body_z), reward, TERMS)


def path_reward_inputs(target, head, target_yaw: float, target_pitch: float, head_yaw: float, head_pitch: float,
                       max_body_z: float) -> PathRewardInputs:
    """What r^tau's terms are computed from (``target``, ``head``: any 3 numbers, Python floats the fastest):
    the numpy form's operations in its order (a square as x * x, the squared distance dx^2 + dy^2, as
    ``np.sum(np.square(...))`` adds them), so the same bits whatever the numbers' types."""
    dx, dy = target[0] - head[0], target[1] - head[1]
    dyaw = (target_yaw - head_yaw + math.pi) % (2 * math.pi) - math.pi
    return PathRewardInputs(dx * dx + dy * dy, (target[2] - head[2]) ** 2,
                            dyaw * dyaw + (target_pitch - head_pitch) ** 2, head[2] - max_body_z)


# --- compiled pieces of a step (one world per call: each world has its own terrain and path) ----------
@jit
def path_point(points, dt, t):
    """``PathSamples.at(t)`` for one time t, as a tuple (x, y, z): the same operations, so the same bits."""
    f = min(max(t / dt, 0.0), points.shape[0] - 1.000001)
    i = int(math.floor(f))
    a = f - i
    return ((1 - a) * points[i, 0] + a * points[i + 1, 0], (1 - a) * points[i, 1] + a * points[i + 1, 1],
            (1 - a) * points[i, 2] + a * points[i + 1, 2])


@jit
def write_path_observation(out, points, dt, t, head, c, s, spacing):
    """``path_observation`` (``out.shape[0] // 3`` targets every ``spacing`` s after t; c, s the cosine
    and sine of the root's yaw) written to ``out``; returns the target due at t, ``path_point(t)``."""
    for k in range(out.shape[0] // 3):
        x, y, z = path_point(points, dt, t + spacing * (k + 1))
        x, y, z = x - head[0], y - head[1], z - head[2]
        out[3 * k] = c * x + s * y
        out[3 * k + 1] = -s * x + c * y
        out[3 * k + 2] = z
    return path_point(points, dt, t)


@jit
def heightmap_point(k, root, c, s, size, extent):
    """The world (x, y) of sample k (row-major, size x size) of the heightmap grid of ``extent`` m about the
    root, turned by its yaw (c, s: cosine and sine): ``heightmap_points``' k-th point."""
    a, b = k // size, k % size
    gy = (a + 0.5) / size * extent - extent / 2
    gx = (b + 0.5) / size * extent - extent / 2
    return root[0] + c * gx - s * gy, root[1] + s * gx + c * gy


@jit
def write_terrain_heightmap(out, heights, terrain_size, root, c, s, size, extent, head):
    """On a ``terrain.bilinear_height`` field: the heightmap (``heightmap_points`` of the root, c and s
    the cosine and sine of its yaw, terrain height minus root height) written to ``out`` (size * size),
    and the terrain height under the root and under ``head``, returned. The same bits as the numpy forms."""
    for k in range(size * size):
        x, y = heightmap_point(k, root, c, s, size, extent)
        out[k] = bilinear_at(heights, terrain_size, x, y) - root[2]
    return bilinear_at(heights, terrain_size, root[0], root[1]), bilinear_at(heights, terrain_size, head[0], head[1])


@jit
def write_grid_heightmap(out, heights, x0, y0, cell, root, c, s, size, extent, head):
    """``write_terrain_heightmap`` on a grid of cell-centre samples read by ``terrain.clamped_bilinear_at``
    (a scene's height map, ``Scene.height_at``'s reading): the heightmap written to ``out``, and the terrain
    height under the root and under ``head``, returned."""
    for k in range(size * size):
        x, y = heightmap_point(k, root, c, s, size, extent)
        out[k] = clamped_bilinear_at(heights, x0, y0, cell, x, y) - root[2]
    return (clamped_bilinear_at(heights, x0, y0, cell, root[0], root[1]),
            clamped_bilinear_at(heights, x0, y0, cell, head[0], head[1]))
