"""Dynamic obstacles, collision prediction and replanning.

PlaMo (Sec. 3.1): "we detect potential collisions by estimating the movement pattern of
the obstacle and comparing it with the last designated path. If a collision is likely to
occur within a 1.5 s time frame, we replan the path, with the dynamic obstacle set at
its future location as an added constraint."

- Motion models: ``ConstantVelocityObstacle`` (p(t) = p0 + u (t - t0)) and
  ``ClosedLoopObstacle`` (constant speed around a closed polyline); anything with
  ``position(t) -> (..., 2)`` and ``radius`` works.
- ``predict_collision``: the first time in [t_now, t_now + horizon] (steps of ``dt``)
  at which |body(t) - obstacle(t)| < radius + body_radius.
- ``replan``: block the cells within radius + body_radius of the obstacle's positions from
  the predicted collision time to ``sweep`` s later, A* from the current position to a point of the old path
  ``rejoin`` metres past the collision (or to the old path's end if that is closer, to any
  target cell if the obstacle covers that end), string-pull,
  smooth the new part together with the rest of the old path, and plan the speed from
  the current speed (if the paper's gentle a_min cannot brake in time, ``emergency_a_min``
  is allowed; if even that cannot slow down for a sharp swerve, the braking curve may
  exceed the curvature bound until it meets it). If the new trajectory is again
  predicted to collide, the obstacle's position at that time is blocked too (up to
  ``max_rounds``). Obstacle positions over the character's current cell are not blocked
  (a ball coming at it is sidestepped). The new trajectory is spliced onto the old one
  at t_now.
- ``wait_for_obstacles``: the fallback when no detour exists (a ball sweeping across a
  corridor): brake to a stop on the same path, wait the shortest multiple of
  ``wait_step`` after which no contact is predicted, and go on.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np

from .astar import astar, disc_cells
from .errors import PlanningError, check_range, check_samples
from .planner import Plan, timed_plan
from .refine import profile_along, smooth_path, string_pull
from .waypoints import Trajectory
from .waypoints import bridge_stops as _bridge_stops


class DynamicObstacle(Protocol):
    radius: float

    def position(self, t: np.ndarray | float) -> np.ndarray: ...


class ConstantVelocityObstacle:
    """A disc moving at constant velocity: p(t) = position + velocity (t - t0)."""

    def __init__(self, position: Sequence[float], velocity: Sequence[float], radius: float = 0.3,
                 t0: float = 0.0) -> None:
        self.p0 = np.asarray(position, dtype=np.float64).reshape(2)
        self.velocity = np.asarray(velocity, dtype=np.float64).reshape(2)
        self.radius = check_range("radius", radius, 0.0, math.inf, high_open=True)
        self.t0 = float(t0)

    def position(self, t: np.ndarray | float) -> np.ndarray:
        t = np.asarray(t, dtype=np.float64)
        return self.p0 + (t - self.t0)[..., None] * self.velocity


class ClosedLoopObstacle:
    """A disc going round a closed polyline at constant speed, ``phase`` metres along it at t = 0."""

    def __init__(self, points: Sequence[Sequence[float]], speed: float, radius: float = 0.3,
                 phase: float = 0.0) -> None:
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        if len(pts) < 2:
            raise ValueError(f"points must hold at least 2 points of the loop, got {len(pts)}")
        self.points = np.vstack((pts, pts[:1]))
        self.s = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(self.points, axis=0), axis=1))]
        if self.s[-1] <= 0:
            raise ValueError("points must not all coincide")
        self.speed = check_range("speed", speed, -math.inf, math.inf, low_open=True, high_open=True)
        self.radius = check_range("radius", radius, 0.0, math.inf, high_open=True)
        self.phase = float(phase)

    def position(self, t: np.ndarray | float) -> np.ndarray:
        s = np.mod(self.phase + self.speed * np.asarray(t, dtype=np.float64), self.s[-1])
        return np.stack((np.interp(s, self.s, self.points[:, 0]), np.interp(s, self.s, self.points[:, 1])), axis=-1)


@dataclass(frozen=True)
class Collision:
    obstacle: int               # index into the obstacle list
    time: float                 # predicted time of contact (s)
    obstacle_xy: np.ndarray     # obstacle centre then (m)
    body_xy: np.ndarray         # the character's planned position then (m)
    distance: float             # centre distance then (m)


@dataclass(frozen=True)
class Replan:
    plan: Plan                  # the new plan from t_now to the target
    trajectory: Trajectory      # old trajectory up to t_now, then the new one
    collision: Collision        # the collision that triggered the replan
    rounds: int                 # A* runs needed until no collision was predicted (0: waited instead)
    blocked_discs: list         # [(xy, radius)] blocked for the final search
    waited: float = 0.0         # seconds standing still on the old path (``wait_for_obstacles``)


def predict_collision(trajectory: Trajectory, obstacles: Sequence[DynamicObstacle], *, t_now: float,
                      horizon: float = 1.5, body_radius: float = 0.25, dt: float = 0.05) -> Collision | None:
    """The earliest predicted contact within ``horizon`` seconds of ``t_now`` (None if there is none)."""
    t_now = check_range("t_now", t_now, -math.inf, math.inf, low_open=True, high_open=True)
    horizon = check_range("horizon", horizon, 0.0, math.inf, high_open=True)
    body_radius = check_range("body_radius", body_radius, 0.0, math.inf, high_open=True)
    dt = check_range("dt", dt, 0.0, math.inf, low_open=True, high_open=True)
    check_samples("horizon (every dt)", horizon, dt)
    times = t_now + np.arange(0.0, horizon + 0.5 * dt, dt)
    body = trajectory.position(times)[:, :2]
    best = None
    for k, obstacle in enumerate(obstacles):
        obs = np.asarray(obstacle.position(times), dtype=np.float64).reshape(-1, 2)
        dist = np.linalg.norm(body - obs, axis=1)
        hit = np.nonzero(dist < obstacle.radius + body_radius)[0]
        if len(hit) and (best is None or times[hit[0]] < best.time):
            i = hit[0]
            best = Collision(k, float(times[i]), obs[i].copy(), body[i].copy(), float(dist[i]))
    return best


def splice(old: Trajectory, new: Trajectory, t_now: float) -> Trajectory:
    """``old`` before ``t_now`` followed by ``new`` (which starts at ``t_now``); arc length runs on."""
    keep = old.t < t_now - 1e-9
    _, _, s_now = old.sample(t_now)
    return Trajectory(np.r_[old.t[keep], new.t], np.r_[old.s[keep], float(s_now) + new.s - new.s[0]],
                      np.vstack((old.xyz[keep], new.xyz)), np.r_[old.v[keep], new.v])


def _blocked_mask(shape, grid, discs) -> np.ndarray:
    mask = np.zeros(shape, bool)
    for xy, radius in discs:
        centre = ((xy[1] - grid.origin[1]) / grid.cell_size, (xy[0] - grid.origin[0]) / grid.cell_size)
        ii, jj = disc_cells(shape, centre, radius / grid.cell_size)
        mask[ii, jj] = True
    return mask


def replan(
    plan: Plan,
    obstacles: Sequence[DynamicObstacle],
    *,
    t_now: float,
    trajectory: Trajectory | None = None,
    horizon: float = 1.5,
    rejoin: float = 4.0,
    max_rounds: int = 4,
    sweep: float = 2.0,
    emergency_a_min: float = -1.0,
    dt: float = 0.05,
) -> Replan | None:
    """Replan ``plan`` around ``obstacles`` if a collision is predicted within ``horizon`` s of ``t_now``.

    trajectory: the trajectory being followed (default ``plan.trajectory``).
    rejoin (m, >= 0): how far past the collision point the detour rejoins the old path.
    max_rounds (>= 1): A* runs, each blocking one more predicted obstacle position.
    sweep (s, >= 0): block the obstacle's positions from the predicted contact time to
        ``sweep`` seconds later (0: only at the contact time, as in the paper); the detour
        then passes behind a moving obstacle instead of racing it.
    emergency_a_min (m/s^2, < 0): deceleration allowed if the plan's a_min cannot brake in time.
    Returns None when no collision is predicted; raises ``PlanningError`` if no detour exists.
    """
    rejoin = check_range("rejoin", rejoin, 0.0, math.inf, high_open=True)
    sweep = check_range("sweep", sweep, 0.0, math.inf, high_open=True)
    emergency_a_min = check_range("emergency_a_min", emergency_a_min, -math.inf, 0.0, low_open=True, high_open=True)
    if int(max_rounds) < 1:
        raise ValueError(f"max_rounds must be an integer >= 1, got {max_rounds!r}")
    dt = check_range("dt", dt, 0.0, math.inf, low_open=True, high_open=True)
    check_samples("sweep (every dt)", sweep, dt)
    traj = original = plan.trajectory if trajectory is None else trajectory
    cm = plan.costmap
    body_radius = cm.body_radius
    first = predict_collision(traj, obstacles, t_now=t_now, horizon=horizon, body_radius=body_radius, dt=dt)
    if first is None:
        return None
    grid = cm.grid
    xyz_now, v_now, _ = traj.sample(float(t_now))
    start_xy = xyz_now[:2]
    start = tuple(int(x) for x in grid.cell_of(start_xy))
    # the old path from the current position on (as world points with arc length)
    old_xy = traj.xyz[:, :2]
    old_s = traj.s
    discs: list[tuple[np.ndarray, float]] = []
    collision = first
    for rounds in range(1, int(max_rounds) + 1):
        obstacle = obstacles[collision.obstacle]
        times = collision.time + np.linspace(0.0, sweep, math.ceil(sweep / dt) + 1)
        for xy in np.asarray(obstacle.position(times), dtype=np.float64).reshape(-1, 2):
            # A position over the character's current cell is skipped: the character leaves before
            # the obstacle arrives (a ball coming at it must be sidestepped, not walled in).
            if np.linalg.norm(xy - start_xy) > obstacle.radius + body_radius + grid.cell_size:
                discs.append((xy, obstacle.radius + body_radius))
        extra = _blocked_mask(grid.shape, grid, discs)
        _, _, s_hit = traj.sample(collision.time)
        after = np.nonzero(old_s >= float(s_hit) + rejoin)[0]
        rejoin_idx = None
        for idx in after:
            i, j = grid.cell_of(old_xy[idx])
            if _free(cm, extra, i, j):
                rejoin_idx = int(idx)
                break
        if rejoin_idx is None:
            # end where the old path ended (the next segment starts there) unless the obstacle is in the way
            end = tuple(int(x) for x in grid.cell_of(old_xy[-1]))
            target = np.array([end], dtype=np.int64) if _free(cm, extra, *end) else plan.target
        else:
            target = np.array([grid.cell_of(old_xy[rejoin_idx])], dtype=np.int64)
        search = astar(cm, start, target, reach=plan.settings.reach, extra_blocked=extra,
                       max_expansions=plan.settings.max_expansions)
        vertices_cells = string_pull(cm, search.cells, search.passable)
        vertices = grid.cell_center(vertices_cells[:, 0], vertices_cells[:, 1]).astype(np.float64)
        poly = [start_xy[None, :], vertices]
        if rejoin_idx is not None:
            poly.append(old_xy[rejoin_idx + 1:])
        st = plan.settings
        xy = smooth_path(cm, np.vstack(poly), passable=search.passable, ds=st.ds, smoothing=st.smoothing,
                         comfort=st.comfort)
        path = profile_along(cm, xy, head_slope=st.head_slope, head_smoothing=st.head_smoothing,
                             curvature_scale=st.curvature_scale)
        path = replace(path, vertices=vertices)
        v_start = float(v_now)
        v_end = float(plan.trajectory.v[-1])
        new = _timed_replan(cm, search, path, plan, v_start, v_end, float(t_now), extra, emergency_a_min)
        again = predict_collision(new.trajectory, obstacles, t_now=t_now, horizon=horizon, body_radius=body_radius,
                                  dt=dt)
        if again is None or rounds == int(max_rounds):
            if again is not None:
                raise PlanningError("blocked", f"no collision-free detour found in {max_rounds} rounds: contact "
                                    f"predicted at t={again.time:.2f} s with obstacle {again.obstacle}")
            return Replan(new, splice(original, new.trajectory, float(t_now)), first, rounds, discs)
        collision = again
        traj = new.trajectory
        old_xy = traj.xyz[:, :2]
        old_s = traj.s
    raise AssertionError("unreachable")


def _timed_replan(cm, search, path, plan: Plan, v_start: float, v_end: float, t_now: float, extra,
                  emergency_a_min: float) -> Plan:
    """The speed QP for a detour, from the current speed: with the plan's bounds; if they cannot
    brake in time, with ``emergency_a_min``; if even that cannot slow down for a sharp swerve,
    with the braking curve allowed above the curvature bound until it meets it."""
    emergency = replace(plan.settings, a_min=min(emergency_a_min, plan.settings.a_min))
    attempts = ((plan.settings, None), (emergency, None), (emergency, emergency.a_min))
    for k, (settings, brake) in enumerate(attempts):
        try:
            return timed_plan(cm, search, path, plan.target, settings, v_start, v_end, t_now, extra, plan.segment,
                               emergency_brake=brake)
        except PlanningError as err:
            if err.reason != "speed" or k == len(attempts) - 1:
                raise
    raise AssertionError("unreachable")


def wait_for_obstacles(
    plan: Plan,
    obstacles: Sequence[DynamicObstacle],
    *,
    t_now: float,
    trajectory: Trajectory | None = None,
    horizon: float = 1.5,
    max_wait: float = 8.0,
    wait_step: float = 0.25,
    emergency_a_min: float = -1.0,
    dt: float = 0.05,
) -> Replan | None:
    """Stop on the path and let ``obstacles`` pass, if a collision is predicted within ``horizon`` s.

    The character brakes at ``emergency_a_min`` (m/s^2, < 0) to a stop, stands there for
    the shortest wait in 0, ``wait_step``, ..., ``max_wait`` s after which no contact is
    predicted until ``horizon`` s after it has passed the first predicted contact point,
    then follows the same path from rest (accelerating at the plan's ``a_max``, never
    faster than the old profile, so the curvature and slope limits still hold). The path
    is unchanged, only its timing (the returned ``plan`` keeps the old path and speed
    profile; its ``trajectory`` is the new timing). Returns None when no collision is
    predicted; raises ``PlanningError("blocked")``
    when even the longest wait does not clear the way (e.g. the obstacle comes at the
    stopping point).
    """
    horizon = check_range("horizon", horizon, 0.0, math.inf, high_open=True)
    max_wait = check_range("max_wait", max_wait, 0.0, math.inf, high_open=True)
    wait_step = check_range("wait_step", wait_step, 0.0, math.inf, low_open=True, high_open=True)
    emergency_a_min = check_range("emergency_a_min", emergency_a_min, -math.inf, 0.0, low_open=True, high_open=True)
    check_samples("max_wait (every wait_step)", max_wait, wait_step)
    traj = plan.trajectory if trajectory is None else trajectory
    body_radius = plan.costmap.body_radius
    first = predict_collision(traj, obstacles, t_now=t_now, horizon=horizon, body_radius=body_radius, dt=dt)
    if first is None:
        return None
    xyz_now, v_now, s_now = (np.asarray(x, dtype=np.float64) for x in traj.sample(float(t_now)))
    v_now, s_now = float(v_now), float(s_now)
    ahead = traj.s > s_now + 1e-9
    s_rest = np.r_[s_now, traj.s[ahead]]
    xyz_rest = np.vstack((xyz_now, traj.xyz[ahead]))
    v_rest = np.r_[v_now, traj.v[ahead]]
    # Stop where braking from the current speed ends (or at the path's end).
    s_stop = min(s_now + v_now * v_now / (2.0 * -emergency_a_min), float(s_rest[-1]))
    xyz_stop = np.array([np.interp(s_stop, s_rest, xyz_rest[:, k]) for k in range(3)])
    before = s_rest < s_stop - 1e-9
    after = s_rest > s_stop + 1e-9
    s_a, xyz_a = np.r_[s_rest[before], s_stop], np.vstack((xyz_rest[before], xyz_stop))
    v_a = np.minimum(np.r_[v_rest[before], 0.0],
                     np.sqrt(np.maximum(v_now * v_now + 2.0 * emergency_a_min * (s_a - s_now), 0.0)))
    v_a[-1] = 0.0
    gentle = min(plan.settings.a_max, -plan.settings.a_min)
    # The old profile may itself stop on the way (at a landmark between segments).
    s_a, xyz_a, v_a = _bridge_stops(s_a, xyz_a, v_a, gentle)
    braking = Trajectory.from_profile(s_a, xyz_a, v_a, t0=float(t_now))
    s_b, xyz_b = np.r_[s_stop, s_rest[after]], np.vstack((xyz_stop, xyz_rest[after]))
    v_b = np.minimum(np.r_[0.0, v_rest[after]], np.sqrt(2.0 * plan.settings.a_max * (s_b - s_stop)))
    s_b, xyz_b, v_b = _bridge_stops(s_b, xyz_b, v_b, gentle)
    _, _, s_hit = traj.sample(first.time)
    s_clear = float(s_hit) + obstacles[first.obstacle].radius + body_radius
    for wait in np.arange(0.0, max_wait + 0.5 * wait_step, wait_step):
        going = Trajectory.from_profile(s_b, xyz_b, v_b, t0=braking.end_time + float(wait))
        new = Trajectory(np.r_[braking.t, going.t], np.r_[braking.s, going.s],
                         np.vstack((braking.xyz, going.xyz)), np.r_[braking.v, going.v])
        # look until `horizon` after the character has passed the point of the first predicted contact
        t_pass = float(np.interp(s_clear, going.s, going.t)) if s_clear < going.s[-1] else going.end_time
        look = max(t_pass, going.start_time) + horizon - float(t_now)
        if predict_collision(new, obstacles, t_now=t_now, horizon=look, body_radius=body_radius, dt=dt) is None:
            return Replan(replace(plan, trajectory=new), splice(traj, new, float(t_now)), first, 0, [],
                          waited=float(wait))
    raise PlanningError("blocked", f"waiting up to {max_wait:g} s on the path does not clear the way: "
                        f"obstacle {first.obstacle} still meets the character (e.g. it comes to the stopping point)")


def _free(costmap, extra: np.ndarray, i: int, j: int) -> bool:
    H, W = extra.shape
    return 0 <= i < H and 0 <= j < W and bool(costmap.passable[i, j]) and not bool(extra[i, j])
