"""Timed trajectories: a path with speeds -> head positions at fixed time steps.

PlaMo (App. C): the planner's (x, y, z, v) path is turned into (x, y, z) waypoints at
fixed time intervals, "a larger waypoint spacing corresponds to a higher speed".
Between samples k and k + 1 the speed profile has constant acceleration
a_k = (v_{k+1}^2 - v_k^2) / (2 Δs_k), so

    t_{k+1} = t_k + 2 Δs_k / (v_k + v_{k+1}),
    s(t) = s_k + v_k τ + a_k τ^2 / 2,   v(t) = v_k + a_k τ,   τ = t - t_k,

and positions are interpolated linearly in s between samples.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import check_range, check_samples


@dataclass(frozen=True)
class Waypoints:
    t: np.ndarray      # (M,) times (s): t0, t0 + dt, ..., and the arrival time last
    xyz: np.ndarray    # (M, 3) head positions (m)
    v: np.ndarray      # (M,) speed (m/s)


@dataclass(frozen=True)
class Trajectory:
    """A path with a speed profile, timed from ``t[0]`` (absolute time, s)."""

    t: np.ndarray      # (N,) time at each sample
    s: np.ndarray      # (N,) arc length (m)
    xyz: np.ndarray    # (N, 3) head position: x, y, z_head (m)
    v: np.ndarray      # (N,) speed (m/s)

    @classmethod
    def from_profile(cls, s: np.ndarray, xyz: np.ndarray, v: np.ndarray, t0: float = 0.0) -> Trajectory:
        """Timed by constant acceleration between samples. Raises ValueError where two samples apart are
        both at rest (no such motion joins them; timed at a floor speed, 3.5 cm took 2,240 years):
        ``bridge_stops`` inserts a sample between them."""
        s = np.asarray(s, dtype=np.float64)
        v = np.asarray(v, dtype=np.float64)
        still = np.flatnonzero((v[1:] + v[:-1] <= 0.0) & (np.diff(s) > 0.0))
        if len(still):
            k = int(still[0])
            raise ValueError(f"speeds v[{k}] and v[{k + 1}] are both 0 over {s[k + 1] - s[k]:g} m of path: no motion "
                             f"at a constant acceleration joins them (insert a sample between: bridge_stops)")
        dt = 2.0 * np.diff(s) / np.maximum(v[1:] + v[:-1], 1e-12)
        t = float(t0) + np.r_[0.0, np.cumsum(dt)]
        return cls(t, s, np.asarray(xyz, dtype=np.float64), v)

    @property
    def start_time(self) -> float:
        return float(self.t[0])

    @property
    def end_time(self) -> float:
        return float(self.t[-1])

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])

    def sample(self, t: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(xyz (..., 3), v (...), s (...)) at times ``t`` (held at the ends outside [t0, t_end])."""
        t = np.asarray(t, dtype=np.float64)
        n = len(self.s)
        if n == 1:
            shape = t.shape
            return (np.broadcast_to(self.xyz[0], shape + (3,)).copy(), np.full(shape, self.v[0]),
                    np.full(shape, self.s[0]))
        k = np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, n - 2)
        tau = np.clip(t - self.t[k], 0.0, self.t[k + 1] - self.t[k])
        ds = self.s[k + 1] - self.s[k]
        v0 = self.v[k]
        v1 = self.v[k + 1]
        a = (v1 * v1 - v0 * v0) / (2.0 * np.maximum(ds, 1e-15))
        d = np.clip(v0 * tau + 0.5 * a * tau * tau, 0.0, ds)
        v = np.clip(v0 + a * tau, np.minimum(v0, v1), np.maximum(v0, v1))
        v = np.where(t >= self.t[-1], self.v[-1], np.where(t <= self.t[0], self.v[0], v))
        w = (d / np.maximum(ds, 1e-15))[..., None]
        xyz = self.xyz[k] * (1.0 - w) + self.xyz[k + 1] * w
        return xyz, v, self.s[k] + d

    def position(self, t: np.ndarray | float) -> np.ndarray:
        """Head position (..., 3) at times ``t``."""
        return self.sample(t)[0]

    def waypoints(self, dt: float = 0.1, t_start: float | None = None) -> Waypoints:
        return timed_waypoints(self, dt=dt, t_start=t_start)


def timed_waypoints(trajectory: Trajectory, *, dt: float = 0.1, t_start: float | None = None) -> Waypoints:
    """Waypoints at t_start, t_start + dt, ... up to the arrival, plus the arrival itself.

    dt (s, > 0): time step (PlaMo's controller reads ten samples 0.5 s apart).
    t_start: first time (default the trajectory's start).
    """
    dt = check_range("dt", dt, 0.0, math.inf, low_open=True, high_open=True)
    t0 = trajectory.start_time if t_start is None else check_range("t_start", t_start, -math.inf, math.inf,
                                                                    low_open=True, high_open=True)
    t_end = trajectory.end_time
    if t0 > t_end:
        t = np.array([t0])
    else:
        check_samples("the waypoints' time span (every dt)", t_end - t0, dt)
        steps = math.floor((t_end - t0) / dt + 1e-9)
        t = t0 + dt * np.arange(steps + 1)
        if t_end - t[-1] > 1e-9:
            t = np.r_[t, t_end]
    xyz, v, _ = trajectory.sample(t)
    return Waypoints(t, xyz, v)


def bridge_stops(s: np.ndarray, xyz: np.ndarray, v: np.ndarray, accel: float):
    """Insert a midpoint between consecutive samples that are both at rest (no constant-acceleration
    motion joins them): speed up at ``accel`` over the first half and slow down over the second."""
    both = np.flatnonzero((v[:-1] == 0.0) & (v[1:] == 0.0) & (np.diff(s) > 0.0))
    if len(both) == 0:
        return s, xyz, v
    mid_s = 0.5 * (s[both] + s[both + 1])
    mid_v = np.sqrt(accel * (s[both + 1] - s[both]))
    mid_xyz = 0.5 * (xyz[both] + xyz[both + 1])
    return (np.insert(s, both + 1, mid_s), np.insert(xyz, both + 1, mid_xyz, axis=0), np.insert(v, both + 1, mid_v))
