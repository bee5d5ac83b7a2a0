"""Motion-aware speed profile: a QP (OSQP) for the fastest speed along a path.

PlaMo (Sec. 3.1, 4.5): "a quadratic program (QP) is solved to minimize travel time along
the refined path", constrained by each locomotion's speed range, longitudinal
acceleration a_max = 0.5 m/s^2 and deceleration a_min = -0.1 m/s^2, lateral acceleration
from the curvature, and the slope.

Variables b_k = v_k^2 at knots s_k spaced <= ``knot_spacing`` along the path, b linear in
s between knots (constant acceleration a = db/ds / 2 on each interval). Constraints:

    0 <= b_k <= ub_k,                   ub_k = min over samples within one knot of v_up(s)^2
    2 a_min Δ <= b_{k+1} - b_k <= 2 a_max Δ      (longitudinal acceleration, v dv/ds = a)
    b_0 = v_start^2,  b_M = v_end^2
    v_up(s) = min(v_max f(slope(s)), sqrt(a_lat / |kappa(s)|))      (``speed_limits``)
    f(slope) = clip(1 - uphill_gain max(slope, 0) - downhill_gain max(-slope, 0), min_speed_fraction, 1)

(ub_k takes the minimum over both neighbouring intervals, so the linear b between knots
stays below v_up^2 at every sample.) Travel time T = sum_k 2 Δ / (sqrt b_k + sqrt b_{k+1})
decreases in every b_k. The feasible set is a lattice (the pointwise max of two feasible
profiles is feasible: every constraint bounds one b_k from above or a difference), so it has
a greatest element b*, which minimises T, maximises sum b, and is the unique minimiser
of the QP solved here:

    minimise  sum_k (b_k - ub_k)^2     subject to the constraints above.

OSQP solves it (rho 1, polishing); the solution is then clipped into the bounds and passed
forward and backward through the acceleration limits (b_k <- min(b_k, b_{k-1} + 2 a_max Δ),
then b_k <- min(b_k, b_{k+1} - 2 a_min Δ)), which only removes solver-tolerance violations.
``time_optimal_reference`` computes b* directly by those two passes, for tests.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import osqp
import scipy.sparse as sp

from .errors import PlanningError, check_range

#: PlaMo's longitudinal acceleration bounds (Sec. 4.5), m/s^2.
A_MAX = 0.5
A_MIN = -0.1


@dataclass(frozen=True)
class SpeedProfile:
    s: np.ndarray          # (N,) arc length of the path samples (m)
    v: np.ndarray          # (N,) speed (m/s)
    v_upper: np.ndarray    # (N,) the upper bound it was planned under (m/s)
    knots: np.ndarray      # (M,) knot arc lengths (m)
    b: np.ndarray          # (M,) squared speed at the knots (m^2/s^2)
    iterations: int        # OSQP iterations
    status: str            # OSQP status

    @property
    def travel_time(self) -> float:
        return travel_time(self.s, self.v)


def travel_time(s: np.ndarray, v: np.ndarray) -> float:
    """sum 2 Δs / (v_k + v_{k+1}): exact for constant acceleration between samples."""
    ds = np.diff(np.asarray(s, dtype=np.float64))
    vs = np.asarray(v, dtype=np.float64)
    return float(np.sum(2.0 * ds / np.maximum(vs[1:] + vs[:-1], 1e-12)))


def speed_limits(
    s: np.ndarray,
    curvature: np.ndarray,
    ground: np.ndarray,
    v_max: float,
    *,
    a_lat: float = 1.0,
    uphill_gain: float = 1.0,
    downhill_gain: float = 0.5,
    min_speed_fraction: float = 0.3,
) -> np.ndarray:
    """Upper speed bound at every sample, v_up = min(v_max f(slope), sqrt(a_lat / |kappa|)).

    slope = d ground / ds along the path (positive uphill). a_lat (m/s^2, > 0): lateral
    acceleration bound v^2 |kappa| <= a_lat. uphill_gain, downhill_gain (>= 0) and
    min_speed_fraction (in (0, 1]): the slope factor f in the module docstring.
    """
    v_max = check_range("v_max", v_max, 0.0, math.inf, low_open=True, high_open=True)
    a_lat = check_range("a_lat", a_lat, 0.0, math.inf, low_open=True)
    uphill_gain = check_range("uphill_gain", uphill_gain, 0.0, math.inf, high_open=True)
    downhill_gain = check_range("downhill_gain", downhill_gain, 0.0, math.inf, high_open=True)
    min_speed_fraction = check_range("min_speed_fraction", min_speed_fraction, 0.0, 1.0, low_open=True)
    s = np.asarray(s, dtype=np.float64)
    ground = np.asarray(ground, dtype=np.float64)
    slope = np.gradient(ground, s) if len(s) > 1 else np.zeros_like(s)
    f = np.clip(1.0 - uphill_gain * np.maximum(slope, 0.0) - downhill_gain * np.maximum(-slope, 0.0),
                min_speed_fraction, 1.0)
    kappa = np.abs(np.asarray(curvature, dtype=np.float64))
    v_lat = np.sqrt(a_lat / np.maximum(kappa, 1e-12))
    return np.minimum(v_max * f, v_lat)


def _knots(s: np.ndarray, knot_spacing: float, max_knots: int) -> np.ndarray:
    length = float(s[-1])
    m = int(min(max(math.ceil(length / knot_spacing), 2) + 1, max(max_knots, 3)))
    return np.linspace(0.0, length, m)  # >= 3 knots: a short path can start and stop at rest


def _knot_bounds(s: np.ndarray, ub_samples: np.ndarray, knots: np.ndarray) -> np.ndarray:
    """ub_k = min of the sample bounds over [s_{k-1}, s_{k+1}]."""
    idx = np.clip(np.searchsorted(knots, s, side="right") - 1, 0, len(knots) - 2)  # interval of each sample
    interval_min = np.full(len(knots) - 1, np.inf)
    np.minimum.at(interval_min, idx, ub_samples)
    # samples exactly at a knot belong to both neighbouring intervals
    at_knot = np.isclose(s, knots[np.clip(idx, 0, len(knots) - 1)]) & (idx > 0)
    np.minimum.at(interval_min, idx[at_knot] - 1, ub_samples[at_knot])
    ub = np.minimum(np.r_[interval_min, np.inf], np.r_[np.inf, interval_min])
    finite = np.isfinite(ub)
    if not finite.all():  # intervals without samples: interpolate the sample bound
        ub[~finite] = np.interp(knots[~finite], s, ub_samples)
    return ub


def _forward_backward(b: np.ndarray, delta: np.ndarray, a_max: float, a_min: float) -> np.ndarray:
    b = b.copy()
    up = 2.0 * a_max * delta
    down = -2.0 * a_min * delta
    for k in range(1, len(b)):
        b[k] = min(b[k], b[k - 1] + up[k - 1])
    for k in range(len(b) - 2, -1, -1):
        b[k] = min(b[k], b[k + 1] + down[k])
    return b


def _check_accels(a_max: float, a_min: float, v_start: float, v_end: float) -> tuple[float, float, float, float]:
    a_max = check_range("a_max", a_max, 0.0, math.inf, low_open=True, high_open=True)
    a_min = check_range("a_min", a_min, -math.inf, 0.0, low_open=True, high_open=True)
    v_start = check_range("v_start", v_start, 0.0, math.inf, high_open=True)
    v_end = check_range("v_end", v_end, 0.0, math.inf, high_open=True)
    return a_max, a_min, v_start, v_end


def time_optimal_reference(s: np.ndarray, v_upper: np.ndarray, *, a_max: float = A_MAX, a_min: float = A_MIN,
                           v_start: float = 0.0, v_end: float = 0.0) -> np.ndarray:
    """The greatest feasible speed at the samples themselves (two passes, no QP); for tests."""
    a_max, a_min, v_start, v_end = _check_accels(a_max, a_min, v_start, v_end)
    b = np.asarray(v_upper, dtype=np.float64) ** 2
    b[0] = v_start ** 2
    b[-1] = min(b[-1], v_end ** 2)
    b = _forward_backward(b, np.diff(np.asarray(s, dtype=np.float64)), a_max, a_min)
    return np.sqrt(np.maximum(b, 0.0))


def speed_profile(
    s: np.ndarray,
    v_upper: np.ndarray,
    *,
    a_max: float = A_MAX,
    a_min: float = A_MIN,
    v_start: float = 0.0,
    v_end: float = 0.0,
    knot_spacing: float = 0.5,
    max_knots: int = 400,
    eps: float = 1e-4,
    max_iter: int = 20000,
) -> SpeedProfile:
    """Fastest speed along samples ``s`` under ``v_upper`` (from ``speed_limits``) by the QP above.

    a_max (> 0) and a_min (< 0): longitudinal acceleration bounds (m/s^2, PlaMo 0.5 and -0.1).
    v_start, v_end (>= 0): speeds at the ends. knot_spacing (m, > 0) and max_knots (>= 2):
    QP resolution (longer paths get wider knots). eps: OSQP's absolute/relative tolerance
    (its solution polishing usually makes the result exact; the two passes remove the rest).
    A start speed above the first bound is allowed (the profile brakes from it).
    Raises ``PlanningError("speed")`` if no profile satisfies the bounds.
    """
    a_max, a_min, v_start, v_end = _check_accels(a_max, a_min, v_start, v_end)
    knot_spacing = check_range("knot_spacing", knot_spacing, 0.0, math.inf, low_open=True, high_open=True)
    if int(max_knots) < 2:
        raise ValueError(f"max_knots must be an integer >= 2, got {max_knots!r}")
    eps = check_range("eps", eps, 0.0, 1.0, low_open=True)
    s = np.asarray(s, dtype=np.float64)
    v_upper = np.asarray(v_upper, dtype=np.float64)
    if s.ndim != 1 or v_upper.shape != s.shape or len(s) < 2 or np.any(np.diff(s) <= 0):
        raise ValueError(f"s must be increasing arc lengths (N >= 2) and v_upper of the same shape, got "
                         f"{s.shape} and {v_upper.shape}")
    if np.any(v_upper < 0):
        raise ValueError("v_upper must be >= 0")
    knots = _knots(s, knot_spacing, int(max_knots))
    m = len(knots)
    delta = np.diff(knots)
    ub = _knot_bounds(s, v_upper ** 2, knots)
    ub[0] = max(ub[0], v_start ** 2)
    lo = np.zeros(m)
    lo[0] = ub[0] = v_start ** 2
    if v_end ** 2 > ub[-1] + 1e-9:
        raise PlanningError("speed", f"v_end={v_end} m/s exceeds the speed bound {math.sqrt(ub[-1]):.3f} m/s "
                            f"at the end of the path")
    lo[-1] = ub[-1] = v_end ** 2
    diff = sp.diags([-np.ones(m - 1), np.ones(m - 1)], [0, 1], shape=(m - 1, m))
    A = sp.vstack([sp.identity(m), diff], format="csc")
    lower = np.r_[lo, 2.0 * a_min * delta]
    upper = np.r_[ub, 2.0 * a_max * delta]
    P = sp.identity(m, format="csc")
    solver = osqp.OSQP()
    solver.setup(P, -ub, A, lower, upper, verbose=False, eps_abs=eps, eps_rel=eps, polishing=True,
                 max_iter=int(max_iter), rho=1.0)
    result = solver.solve(raise_error=False)
    status = result.info.status
    if result.info.status_val in (osqp.SolverStatus.OSQP_PRIMAL_INFEASIBLE,
                                  osqp.SolverStatus.OSQP_PRIMAL_INFEASIBLE_INACCURATE):
        raise PlanningError("speed", f"no speed profile satisfies the bounds (start {v_start} m/s, end {v_end} m/s, "
                            f"a_min {a_min} m/s^2): OSQP says {status}")
    x = result.x
    if x is None or not np.all(np.isfinite(x)):
        raise PlanningError("speed", f"the speed QP failed: OSQP says {status}")
    # remove solver-tolerance violations (only lowers b)
    b = _forward_backward(np.clip(x, lo, ub), delta, a_max, a_min)
    tol = 10.0 * eps * max(1.0, float(ub.max()))
    if b[0] < v_start ** 2 - tol or b[-1] < v_end ** 2 - tol:
        raise PlanningError("speed", f"no speed profile satisfies the bounds (start {v_start} m/s, end {v_end} m/s, "
                            f"a_min {a_min} m/s^2): OSQP says {status}")
    b[0] = v_start ** 2
    b[-1] = v_end ** 2
    v = np.sqrt(np.maximum(np.interp(s, knots, b), 0.0))
    return SpeedProfile(s, v, v_upper, knots, b, int(result.info.iter), status)
