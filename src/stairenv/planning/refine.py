"""Path refiner: string pulling, clearance-keeping smoothing and the head-height profile.

PlaMo (Sec. 3.1) refines the coarse A* path "to achieve smoother paths that avoid all
obstacles" and "sets the desired head height (z-axis) values that guide the character
beneath top obstacles". Three stages, each a function:

1. ``string_pull``: line-of-sight shortcutting of the A* cells. A shortcut a -> b is the
   straight line between cell centres, walked cell by cell (every cell it touches;
   through a corner diagonally); it is kept if every step is an edge of the A* graph
   (passable cells on the clearance-inflated map, headroom, slope and step limits) and
   its cost, sum_k w(L / n, dh_k) over its n steps (L its length), is at most the cost of
   the A* sub-path it replaces: with the slope preference the path still goes around hills.
   Galloping then binary search for the farthest such b keeps it O(n log n) line walks.
2. ``smooth_path``: the polyline p is resampled every ``ds`` (<= half a cell), then
   ``rounds`` times smoothed and pushed away from walls:
       q <- q + alpha (g_s * q - q)            (Gaussian, s = smoothing / sqrt(rounds))
       q <- q + (d* - d(q)) grad d(q)  where d(q) < d* = body_radius + comfort
   (d the clearance, a distance transform, so |grad d| = 1 and this projects onto
   d >= d*); alpha ramps 0 -> 1 over 2 sigma at both ends (the endpoints stay put).
   Finally q_k = p_k + beta_k (q_k - p_k), beta lowered (smoothly) around every sample
   whose cell is not passable or whose step from the previous sample is not a graph move,
   until none is. Passable cells are at least ``body_radius`` from a wall centre
   (``scipy.ndimage.distance_transform_edt``), so the path keeps that clearance.
3. ``head_profile``: head height above the ground h(s) under the envelope
       u(s) = min(h_nominal, ceiling_low(s) - margin - ground(s)),
   h = the largest function below u with |dh/ds| <= head_slope, i.e. the lower
   Lipschitz envelope h(s) = min_s' u(s') + k |s - s'| (a forward and a backward pass),
   its corners rounded by a min filter then a box filter of width ``head_smoothing``
   (box(min(h)) <= h pointwise), and the Lipschitz pass again (it only lowers h).
   So z_head = ground + h never rises above ceiling - margin, never above the nominal
   height, and ducks and rises on ramps of slope <= head_slope.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from stairenv.numba_jit import jit

from .astar import SQRT2, edge_cost, edge_ok
from .costmap import Costmap
from .errors import check_range, check_samples


# ----------------------------------------------------------------------------------------------
# 1. string pulling
@jit
def _line_cost(passable, terrain, raw, i0, j0, i1, j1, cell, max_slope, max_step, height_cost, slope_preference):
    """Cost of the straight line between cell centres (inf if a step is not a graph edge).

    The line crosses row boundaries at t = (k + 1/2) / |di| and column boundaries at
    t = (l + 1/2) / |dj|; comparing (2k + 1) |dj| with (2l + 1) |di| in integers orders
    them exactly, and a tie (a corner) is a diagonal step.
    """
    ni_ = abs(i1 - i0)
    nj_ = abs(j1 - j0)
    si = 1 if i1 > i0 else -1
    sj = 1 if j1 > j0 else -1
    dhs = np.empty(ni_ + nj_ + 1)
    i = i0
    j = j0
    ki = 0
    kj = 0
    steps = 0
    while i != i1 or j != j1:
        if ni_ == 0:
            cmp = 1
        elif nj_ == 0:
            cmp = -1
        else:
            a = (2 * ki + 1) * nj_
            b = (2 * kj + 1) * ni_
            cmp = -1 if a < b else (1 if a > b else 0)
        ni = i
        nj = j
        if cmp <= 0:
            ni = i + si
            ki += 1
        if cmp >= 0:
            nj = j + sj
            kj += 1
        length = cell * SQRT2 if (ni != i and nj != j) else cell
        if not edge_ok(passable, terrain, raw, i, j, ni, nj, length, max_slope, max_step):
            return np.inf
        dhs[steps] = terrain[ni, nj] - terrain[i, j]
        steps += 1
        i = ni
        j = nj
    if steps == 0:
        return 0.0
    d = cell * math.sqrt(float(ni_ * ni_ + nj_ * nj_)) / steps
    total = 0.0
    for k in range(steps):
        total += edge_cost(d, dhs[k], height_cost, slope_preference)
    return total


@jit
def _shortcut_ok(passable, terrain, raw, ci, cj, cum, a, b, cell, max_slope, max_step, height_cost, slope_preference):
    cost = _line_cost(passable, terrain, raw, ci[a], cj[a], ci[b], cj[b], cell, max_slope, max_step,
                      height_cost, slope_preference)
    budget = cum[b] - cum[a]
    return cost <= budget + 1e-9 * (1.0 + budget)


@jit
def _string_pull_kernel(passable, terrain, raw, ci, cj, cum, cell, max_slope, max_step, height_cost,
                        slope_preference):
    n = ci.shape[0]
    keep = np.empty(n, np.int64)
    keep[0] = 0
    m = 1
    a = 0
    while a < n - 1:
        best = a + 1
        bad = -1
        step = 1
        while True:
            b = min(a + 1 + step, n - 1)
            if b <= best:
                break
            if _shortcut_ok(passable, terrain, raw, ci, cj, cum, a, b, cell, max_slope, max_step, height_cost,
                            slope_preference):
                best = b
                if b == n - 1:
                    break
                step *= 2
            else:
                bad = b
                break
        if bad > 0:
            while bad - best > 1:
                mid = (best + bad) // 2
                if _shortcut_ok(passable, terrain, raw, ci, cj, cum, a, mid, cell, max_slope, max_step,
                                height_cost, slope_preference):
                    best = mid
                else:
                    bad = mid
        keep[m] = best
        m += 1
        a = best
    return keep[:m]


@jit
def _path_costs(terrain, ci, cj, cell, height_cost, slope_preference):
    n = ci.shape[0]
    cum = np.zeros(n)
    for k in range(1, n):
        diag = ci[k] != ci[k - 1] and cj[k] != cj[k - 1]
        length = cell * SQRT2 if diag else cell
        cum[k] = cum[k - 1] + edge_cost(length, terrain[ci[k], cj[k]] - terrain[ci[k - 1], cj[k - 1]],
                                        height_cost, slope_preference)
    return cum


def string_pull(costmap: Costmap, cells: np.ndarray, passable: np.ndarray | None = None) -> np.ndarray:
    """The A* cells kept as polyline vertices ((m, 2) cells, first and last included)."""
    cells = np.asarray(cells, dtype=np.int64).reshape(-1, 2)
    if len(cells) <= 2:
        return cells.copy()
    passable = costmap.passable if passable is None else passable
    ci = np.ascontiguousarray(cells[:, 0])
    cj = np.ascontiguousarray(cells[:, 1])
    cum = _path_costs(costmap.terrain, ci, cj, costmap.cell_size, costmap.height_cost, costmap.slope_preference)
    keep = _string_pull_kernel(passable, costmap.terrain, costmap.heights, ci, cj, cum, costmap.cell_size,
                               costmap.max_slope, costmap.max_step, costmap.height_cost, costmap.slope_preference)
    return cells[keep]


# ----------------------------------------------------------------------------------------------
# 2. smoothing
def resample_polyline(points: np.ndarray, ds: float) -> np.ndarray:
    """Points every <= ``ds`` along a polyline (uniform spacing, both ends kept)."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    keep = np.r_[True, seg > 1e-12]
    points = points[keep]
    if len(points) < 2:
        return points.copy()
    s = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))]
    check_samples("the path's length (resampled every ds)", float(s[-1]), ds, unit="m")
    n = max(math.ceil(s[-1] / ds), 1) + 1
    t = np.linspace(0.0, s[-1], n)
    return np.stack((np.interp(t, s, points[:, 0]), np.interp(t, s, points[:, 1])), axis=1)


@jit
def _move_ok(passable, terrain, raw, pi, pj, i, j, cell, max_slope, max_step):
    di = abs(i - pi)
    dj = abs(j - pj)
    if di == 0 and dj == 0:
        return True
    if di > 1 or dj > 1:
        return False
    if di == 1 and dj == 1:
        if edge_ok(passable, terrain, raw, pi, pj, i, j, cell * SQRT2, max_slope, max_step):
            return True
        # through either corner cell
        if edge_ok(passable, terrain, raw, pi, pj, pi, j, cell, max_slope, max_step) and \
                edge_ok(passable, terrain, raw, pi, j, i, j, cell, max_slope, max_step):
            return True
        return edge_ok(passable, terrain, raw, pi, pj, i, pj, cell, max_slope, max_step) and \
            edge_ok(passable, terrain, raw, i, pj, i, j, cell, max_slope, max_step)
    return edge_ok(passable, terrain, raw, pi, pj, i, j, cell, max_slope, max_step)


@jit
def _bad_samples(passable, terrain, raw, xy, x0, y0, cell, max_slope, max_step):
    """Samples whose cell is not passable or whose move from the previous sample is not a graph move."""
    H, W = passable.shape
    n = xy.shape[0]
    bad = np.zeros(n, np.bool_)
    pi = -1
    pj = -1
    for k in range(n):
        j = int(math.floor((xy[k, 0] - x0) / cell))
        i = int(math.floor((xy[k, 1] - y0) / cell))
        if i < 0 or j < 0 or i >= H or j >= W or not passable[i, j]:
            bad[k] = True
        elif pi >= 0 and not _move_ok(passable, terrain, raw, pi, pj, i, j, cell, max_slope, max_step):
            bad[k] = True
            bad[k - 1] = True
        pi = i
        pj = j
    return bad


def bad_samples(costmap: Costmap, xy: np.ndarray, passable: np.ndarray | None = None) -> np.ndarray:
    """(N,) bool: samples of a path that leave the passable cells or jump between cells illegally."""
    passable = costmap.passable if passable is None else passable
    x0, y0 = costmap.grid.origin
    return _bad_samples(passable, costmap.terrain, costmap.heights, np.ascontiguousarray(xy, dtype=np.float64),
                        float(x0), float(y0), costmap.cell_size, costmap.max_slope, costmap.max_step)


def _clearance_and_gradient(costmap: Costmap, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bilinear clearance at points and its gradient (central differences one cell apart)."""
    x0, y0 = costmap.grid.origin
    c = costmap.cell_size
    fi = (xy[:, 1] - y0) / c - 0.5
    fj = (xy[:, 0] - x0) / c - 0.5
    coords = np.stack((np.r_[fi, fi, fi, fi + 1, fi - 1], np.r_[fj, fj + 1, fj - 1, fj, fj]))
    v = ndimage.map_coordinates(costmap.clearance, coords, order=1, mode="nearest").reshape(5, -1)
    grad = np.stack(((v[1] - v[2]) / (2 * c), (v[3] - v[4]) / (2 * c)), axis=1)
    return v[0], grad


def smooth_path(costmap: Costmap, points: np.ndarray, *, passable: np.ndarray | None = None, ds: float = 0.05,
                smoothing: float = 0.75, comfort: float = 0.25, rounds: int = 16,
                max_iterations: int = 12) -> np.ndarray:
    """Smoothed samples (N, 2) of the polyline ``points`` that stay on passable cells (module docstring, 2.).

    ds (m, > 0): sample spacing (at most half a cell). smoothing (m, >= 0): Gaussian sigma.
    comfort (m, >= 0): extra clearance sought beyond body_radius while smoothing: ``rounds``
    times, a Gaussian step q <- q + alpha (g_s * q - q), s = sigma / sqrt(rounds) (together
    one step of sigma), is followed by the projection q <- q + (d* - d(q)) grad d(q) of the
    samples with clearance d(q) < d* = body_radius + comfort (d is a distance field,
    |grad d| = 1, so this projects onto d >= d*). Small steps leave only small kinks.
    Samples still off the passable cells are then blended back towards the polyline.
    """
    ds = check_range("ds", ds, 0.0, math.inf, low_open=True, high_open=True)
    smoothing = check_range("smoothing", smoothing, 0.0, math.inf, high_open=True)
    comfort = check_range("comfort", comfort, 0.0, math.inf, high_open=True)
    ds = min(ds, 0.5 * costmap.cell_size)
    p = resample_polyline(points, ds)
    if len(p) < 3 or smoothing == 0.0:
        return p
    passable = costmap.passable if passable is None else passable
    sigma = smoothing / ds
    s = np.arange(len(p)) * ds
    ramp = np.clip(np.minimum(s, s[-1] - s) / (2.0 * smoothing), 0.0, 1.0)
    alpha = ramp * ramp * (3.0 - 2.0 * ramp)  # smoothstep: 0 at both ends
    target = costmap.body_radius + comfort
    walls = bool(np.isfinite(costmap.clearance).any())
    g = p.copy()
    rounds = max(int(rounds), 1)
    step_sigma = sigma / math.sqrt(rounds)  # rounds Gaussian steps compose to one of sigma
    for _ in range(rounds):
        g = g + alpha[:, None] * (ndimage.gaussian_filter1d(g, step_sigma, axis=0, mode="nearest") - g)
        if walls:
            d, grad = _clearance_and_gradient(costmap, g)
            norm = np.linalg.norm(grad, axis=1)
            push = (d < target) & (norm > 1e-6) & (alpha > 0)
            g[push] += ((target - d[push]) / norm[push])[:, None] * grad[push] * alpha[push, None]
    reach = math.ceil(3.0 * sigma)
    beta = np.ones(len(p))
    for it in range(max_iterations):
        q = p + beta[:, None] * (g - p)
        bad = bad_samples(costmap, q, passable)
        if not bad.any():
            return q
        near = ndimage.maximum_filter1d(bad, 2 * reach + 1)
        beta = np.minimum(beta, ndimage.gaussian_filter1d((~near).astype(np.float64), sigma, mode="nearest"))
        if it >= max_iterations // 2:
            beta[near] = 0.0
    q = p + beta[:, None] * (g - p)
    bad = bad_samples(costmap, q, passable)
    q[bad] = p[bad]
    return q


def curvature(xy: np.ndarray, scale: float = 0.0) -> np.ndarray:
    """Menger curvature 4 area / (a b c) of each sample with the samples ``scale`` metres
    (at least one sample) before and after it (1/m; the ends take the nearest interior value)."""
    xy = np.asarray(xy, dtype=np.float64)
    n = len(xy)
    k = np.zeros(n)
    if n < 3:
        return k
    seg = np.linalg.norm(np.diff(xy, axis=0), axis=1)
    m = int(max(1, min(round(scale / max(float(np.median(seg)), 1e-12)), (n - 1) // 2)))
    a = xy[m:n - m] - xy[:n - 2 * m]
    b = xy[2 * m:] - xy[m:n - m]
    cross = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    denom = np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1) * np.linalg.norm(xy[2 * m:] - xy[:n - 2 * m], axis=1)
    k[m:n - m] = np.where(denom > 1e-15, 2.0 * np.abs(cross) / np.maximum(denom, 1e-300), 0.0)
    k[:m] = k[m]
    k[n - m:] = k[n - m - 1]
    return k


# ----------------------------------------------------------------------------------------------
# 3. head height
@jit
def _lipschitz_below(u, s, slope):
    """Largest h <= u with |h_{k+1} - h_k| <= slope (s_{k+1} - s_k)."""
    h = u.copy()
    for k in range(1, len(h)):
        h[k] = min(h[k], h[k - 1] + slope * (s[k] - s[k - 1]))
    for k in range(len(h) - 2, -1, -1):
        h[k] = min(h[k], h[k + 1] + slope * (s[k + 1] - s[k]))
    return h


def head_profile(s: np.ndarray, ground: np.ndarray, ceiling: np.ndarray, nominal: float, *, margin: float = 0.1,
                 head_slope: float = 0.5, head_smoothing: float = 0.5) -> np.ndarray:
    """Head height above ``ground`` along arc length ``s`` (module docstring, 3.).

    ceiling: (N,) lowest ceiling over the head at each sample (inf: open sky).
    margin (m, >= 0): kept below the ceiling. head_slope (> 0): steepest rise or fall of
    the head per metre travelled. head_smoothing (m, finite >= 0): width of the corner rounding.
    """
    margin = check_range("margin", margin, 0.0)
    head_slope = check_range("head_slope", head_slope, 0.0, math.inf, low_open=True)
    head_smoothing = check_range("head_smoothing", head_smoothing, 0.0, math.inf, high_open=True)
    s = np.ascontiguousarray(s, dtype=np.float64)
    u = np.minimum(float(nominal), np.asarray(ceiling, dtype=np.float64) - margin - np.asarray(ground, dtype=np.float64))
    u = np.ascontiguousarray(np.broadcast_to(u, s.shape), dtype=np.float64)
    h = _lipschitz_below(u, s, head_slope)
    if len(s) > 2 and head_smoothing > 0:
        w = round(head_smoothing / max(s[-1] / (len(s) - 1), 1e-9))
        if w >= 2:
            w += 1 - w % 2
            m = ndimage.minimum_filter1d(h, w, mode="nearest")
            h = _lipschitz_below(np.minimum(h, ndimage.uniform_filter1d(m, w, mode="nearest")), s, head_slope)
    return h


# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class RefinedPath:
    xy: np.ndarray           # (N, 2) smoothed samples (m)
    s: np.ndarray            # (N,) arc length (m)
    ground: np.ndarray       # (N,) terrain height under each sample (m)
    head: np.ndarray         # (N,) head height above the ground (m)
    curvature: np.ndarray    # (N,) 1/m
    vertices: np.ndarray     # (m, 2) string-pulled polyline (m)

    @property
    def z_head(self) -> np.ndarray:
        return self.ground + self.head

    @property
    def length(self) -> float:
        return float(self.s[-1])


def sample_terrain(costmap: Costmap, xy: np.ndarray) -> np.ndarray:
    """Terrain height at world points (bilinear between cell centres)."""
    x0, y0 = costmap.grid.origin
    c = costmap.cell_size
    coords = np.stack(((xy[:, 1] - y0) / c - 0.5, (xy[:, 0] - x0) / c - 0.5))
    return ndimage.map_coordinates(costmap.terrain, coords, order=1, mode="nearest")


def profile_along(costmap: Costmap, xy: np.ndarray, *, margin: float | None = None, head_slope: float = 0.5,
                  head_smoothing: float = 0.5, curvature_scale: float = 0.25) -> RefinedPath:
    """Arc length, ground, head height and curvature (over +-``curvature_scale`` m) along given samples."""
    xy = np.asarray(xy, dtype=np.float64)
    seg = np.linalg.norm(np.diff(xy, axis=0), axis=1)
    keep = np.r_[True, seg > 1e-9]
    xy = xy[keep]
    s = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(xy, axis=0), axis=1))]
    ground = sample_terrain(costmap, xy)
    cells = costmap.grid.cell_of(xy)
    H, W = costmap.grid.shape
    cells[:, 0] = np.clip(cells[:, 0], 0, H - 1)
    cells[:, 1] = np.clip(cells[:, 1], 0, W - 1)
    ceiling = costmap.ceiling_low[cells[:, 0], cells[:, 1]]
    head = head_profile(s, ground, ceiling, costmap.locomotion.head_height,
                        margin=costmap.ceiling_margin if margin is None else margin,
                        head_slope=head_slope, head_smoothing=head_smoothing)
    return RefinedPath(xy, s, ground, head, curvature(xy, curvature_scale), xy)


def refine_path(
    costmap: Costmap,
    cells: np.ndarray,
    *,
    passable: np.ndarray | None = None,
    start_xy: np.ndarray | None = None,
    ds: float = 0.05,
    smoothing: float = 0.75,
    comfort: float = 0.25,
    head_slope: float = 0.5,
    head_smoothing: float = 0.5,
    curvature_scale: float = 0.25,
) -> RefinedPath:
    """A* cells -> smooth samples with ground and head heights (string pull, smooth, head profile).

    start_xy: the exact start position (inside the first cell); the first sample is put there. One cell
    (the start cell is already a goal) gives a path of zero length, the start point alone (not a step from
    it to the cell's centre: a few centimetres that a profile from rest to rest could not time).
    ds, smoothing, comfort: see ``smooth_path``; head_slope, head_smoothing: see ``head_profile``;
    curvature_scale (m): see ``curvature``.
    """
    passable = costmap.passable if passable is None else passable
    vertices_cells = string_pull(costmap, cells, passable)
    vertices = costmap.grid.cell_center(vertices_cells[:, 0], vertices_cells[:, 1]).astype(np.float64)
    if start_xy is not None:
        start_xy = np.asarray(start_xy, dtype=np.float64).reshape(2)
        vertices = start_xy[None, :] if len(vertices_cells) == 1 else np.vstack((start_xy, vertices))
    xy = smooth_path(costmap, vertices, passable=passable, ds=ds, smoothing=smoothing, comfort=comfort)
    path = profile_along(costmap, xy, head_slope=head_slope, head_smoothing=head_smoothing,
                         curvature_scale=curvature_scale)
    return RefinedPath(path.xy, path.s, path.ground, path.head, path.curvature, vertices)
