"""A* on the 8-connected grid of a ``Costmap``, compiled with numba.

Graph. Every cell is a node joined to its eight neighbours. The edge a -> b exists iff
(PlaMo Sec. 3.1: "remove connections based on walls, top obstacles too low to bypass,
and infeasible slopes")

- ``passable[b]`` (not a wall, not within ``body_radius`` of one, enough headroom) and,
  for a diagonal, both corner cells are passable (no cutting a wall's corner);
- |terrain_b - terrain_a| <= max_slope * d   (d = c or c sqrt 2, c the cell size);
- |height_b - height_a| <= max_step.

Its weight is the distance, the height difference, and the slope preference
(PlaMo Sec. 4.4: "the distance between each two points is increased by e^{c slope} - 1"):

    w(a, b) = d + height_cost |dh| + d (e^{c |dh| / d} - 1),   dh = terrain_b - terrain_a.

Every cell of the target landmark is a goal. The heuristic is the octile distance
c (max(|di|, |dj|) + (sqrt 2 - 1) min(|di|, |dj|)) to the nearest goal (up to 32 goals) or
to the goals' bounding box; it is consistent because w >= d, so the first goal popped
is optimal. The search is bounded by ``max_expansions`` (default: every cell once).

When no goal is reachable, ``PlanningError.reason`` says why, found by flood-filling
again with one constraint relaxed at a time (ceiling, then slope, then both).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from stairenv.numba_jit import jit

from .costmap import Costmap
from .errors import PlanningError, check_cells, check_range
from .locomotion import LOCOMOTIONS

SQRT2 = math.sqrt(2.0)
_DI = np.array([-1, -1, -1, 0, 0, 1, 1, 1], dtype=np.int64)
_DJ = np.array([-1, 0, 1, -1, 1, -1, 0, 1], dtype=np.int64)


@jit
def edge_ok(passable, terrain, raw, i, j, ni, nj, length, max_slope, max_step):
    """Whether the edge (i, j) -> (ni, nj) exists (the source is assumed passable)."""
    H, W = passable.shape
    if ni < 0 or nj < 0 or ni >= H or nj >= W:
        return False
    if not passable[ni, nj]:
        return False
    if ni != i and nj != j and (not passable[i, nj] or not passable[ni, j]):
        return False
    if abs(raw[ni, nj] - raw[i, j]) > max_step:
        return False
    return abs(terrain[ni, nj] - terrain[i, j]) <= max_slope * length


@jit
def edge_cost(length, dh, height_cost, slope_preference):
    """w = d + height_cost |dh| + d (e^{c |dh| / d} - 1)."""
    dh = abs(dh)
    return length + height_cost * dh + length * math.expm1(slope_preference * dh / length)


@jit
def _octile(di, dj, cell):
    if di > dj:
        return cell * (di + (SQRT2 - 1.0) * dj)
    return cell * (dj + (SQRT2 - 1.0) * di)


@jit
def _heuristic(i, j, goal_cells, use_list, bi0, bi1, bj0, bj1, cell):
    if use_list:
        best = np.inf
        for k in range(goal_cells.shape[0]):
            h = _octile(abs(i - goal_cells[k, 0]), abs(j - goal_cells[k, 1]), cell)
            best = min(best, h)
        return best
    di = max(bi0 - i, 0, i - bi1)
    dj = max(bj0 - j, 0, j - bj1)
    return _octile(di, dj, cell)


@jit
def _astar_kernel(passable, terrain, raw, si, sj, goal_mask, goal_cells, cell, max_slope, max_step,
                  height_cost, slope_preference, max_expansions):
    """Returns (path as flat indices start..goal, cost, expansions, status 0 found / 1 exhausted / 2 budget).

    Binary heap keyed by f = g + h with decrease-key (``pos`` holds each node's heap slot,
    -1 unseen, -2 closed), so every node is in the heap at most once.
    h = octile distance to the goals + (height_cost + c) * (distance of the terrain height
    to the goals' height range); consistent since w >= d + (height_cost + c) |dh|
    (e^x - 1 >= x).
    """
    H, W = passable.shape
    n = H * W
    g = np.full(n, np.inf)
    parent = np.full(n, -1, np.int32)
    pos = np.full(n, -1, np.int32)
    use_list = goal_cells.shape[0] <= 32
    bi0 = goal_cells[:, 0].min()
    bi1 = goal_cells[:, 0].max()
    bj0 = goal_cells[:, 1].min()
    bj1 = goal_cells[:, 1].max()
    zlo = np.inf
    zhi = -np.inf
    for k in range(goal_cells.shape[0]):
        z = terrain[goal_cells[k, 0], goal_cells[k, 1]]
        zlo = min(zlo, z)
        zhi = max(zhi, z)
    zw = height_cost + slope_preference
    offs = np.array([-W - 1, -W, -W + 1, -1, 1, W - 1, W, W + 1], np.int64)
    lens = np.array([cell * SQRT2, cell, cell * SQRT2, cell, cell, cell * SQRT2, cell, cell * SQRT2])
    cap = 4096
    hf = np.empty(cap)
    hv = np.empty(cap, np.int32)
    s = si * W + sj
    g[s] = 0.0
    z = terrain[si, sj]
    hf[0] = _heuristic(si, sj, goal_cells, use_list, bi0, bi1, bj0, bj1, cell) + zw * max(zlo - z, 0.0, z - zhi)
    hv[0] = s
    pos[s] = 0
    size = 1
    expansions = 0
    while size > 0:
        u = hv[0]
        pos[u] = -2
        size -= 1
        if size > 0:  # move the last entry to the root and sift it down
            lf = hf[size]
            lv = hv[size]
            k = 0
            while True:
                c1 = 2 * k + 1
                if c1 >= size:
                    break
                c2 = c1 + 1
                if c2 < size and hf[c2] < hf[c1]:
                    c1 = c2
                if hf[c1] < lf:
                    hf[k] = hf[c1]
                    hv[k] = hv[c1]
                    pos[hv[k]] = k
                    k = c1
                else:
                    break
            hf[k] = lf
            hv[k] = lv
            pos[lv] = k
        i = u // W
        j = u - i * W
        if goal_mask[i, j]:
            m = 1
            v = u
            while parent[v] >= 0:
                v = parent[v]
                m += 1
            path = np.empty(m, np.int64)
            v = u
            for q in range(m - 1, -1, -1):
                path[q] = v
                v = parent[v]
            return path, g[u], expansions, 0
        expansions += 1
        if expansions > max_expansions:
            return np.empty(0, np.int64), np.inf, expansions, 2
        g_u = g[u]
        for d in range(8):
            ni = i + _DI[d]
            nj = j + _DJ[d]
            if ni < 0 or nj < 0 or ni >= H or nj >= W:
                continue
            v = u + offs[d]
            if pos[v] == -2:
                continue
            length = lens[d]
            if not edge_ok(passable, terrain, raw, i, j, ni, nj, length, max_slope, max_step):
                continue
            ng = g_u + edge_cost(length, terrain[ni, nj] - terrain[i, j], height_cost, slope_preference)
            if ng < g[v]:
                g[v] = ng
                parent[v] = u
                z = terrain[ni, nj]
                f = ng + _heuristic(ni, nj, goal_cells, use_list, bi0, bi1, bj0, bj1, cell) \
                    + zw * max(zlo - z, 0.0, z - zhi)
                k = pos[v]
                if k < 0:  # new entry at the end
                    if size == cap:
                        cap *= 2
                        nf = np.empty(cap)
                        nv = np.empty(cap, np.int32)
                        nf[:size] = hf[:size]
                        nv[:size] = hv[:size]
                        hf = nf
                        hv = nv
                    k = size
                    size += 1
                while k > 0:  # sift up (the key only decreases)
                    p = (k - 1) >> 1
                    if f < hf[p]:
                        hf[k] = hf[p]
                        hv[k] = hv[p]
                        pos[hv[k]] = k
                        k = p
                    else:
                        break
                hf[k] = f
                hv[k] = v
                pos[v] = k
    return np.empty(0, np.int64), np.inf, expansions, 1


@jit
def _reach_kernel(passable, terrain, raw, si, sj, goal_mask, cell, max_slope, max_step):
    """Flood fill from (si, sj): whether any goal cell is reachable."""
    H, W = passable.shape
    seen = np.zeros((H, W), np.bool_)
    stack = np.empty(H * W, np.int64)
    stack[0] = si * W + sj
    seen[si, sj] = True
    top = 1
    while top > 0:
        top -= 1
        u = stack[top]
        i = u // W
        j = u - i * W
        if goal_mask[i, j]:
            return True
        for d in range(8):
            ni = i + _DI[d]
            nj = j + _DJ[d]
            length = cell * SQRT2 if (_DI[d] != 0 and _DJ[d] != 0) else cell
            if edge_ok(passable, terrain, raw, i, j, ni, nj, length, max_slope, max_step) and not seen[ni, nj]:
                seen[ni, nj] = True
                stack[top] = ni * W + nj
                top += 1
    return False


@jit
def _weights_kernel(passable, terrain, raw, cell, max_slope, max_step, height_cost, slope_preference):
    H, W = passable.shape
    out = np.full((H, W, 8), np.inf)
    for i in range(H):
        for j in range(W):
            if not passable[i, j]:
                continue
            for d in range(8):
                ni = i + _DI[d]
                nj = j + _DJ[d]
                length = cell * SQRT2 if (_DI[d] != 0 and _DJ[d] != 0) else cell
                if edge_ok(passable, terrain, raw, i, j, ni, nj, length, max_slope, max_step):
                    out[i, j, d] = edge_cost(length, terrain[ni, nj] - terrain[i, j], height_cost, slope_preference)
    return out


# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class AStarResult:
    cells: np.ndarray        # (n, 2) int cells (i, j), start first, a goal last
    cost: float              # sum of edge weights
    expansions: int          # nodes expanded
    passable: np.ndarray     # the mask searched (costmap.passable with escapes and dynamic obstacles)
    goals: np.ndarray        # (K, 2) goal cells used


def edge_weights(costmap: Costmap, passable: np.ndarray | None = None) -> np.ndarray:
    """(H, W, 8) weights of the edges out of every cell (inf: no edge); neighbour d is
    (i + DI[d], j + DJ[d]) with DI = [-1,-1,-1,0,0,1,1,1], DJ = [-1,0,1,-1,1,-1,0,1]."""
    passable = costmap.passable if passable is None else passable
    return _weights_kernel(passable, costmap.terrain, costmap.heights, costmap.cell_size, costmap.max_slope,
                           costmap.max_step, costmap.height_cost, costmap.slope_preference)


def edge_list(costmap: Costmap, passable: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The graph as undirected edges (u, v, w) with flat node ids u = i W + j, u < v."""
    w = edge_weights(costmap, passable)
    W = costmap.grid.shape[1]
    ii, jj, dd = np.nonzero(np.isfinite(w))
    u = ii * W + jj
    v = (ii + _DI[dd]) * W + (jj + _DJ[dd])
    keep = u < v
    return u[keep], v[keep], w[ii[keep], jj[keep], dd[keep]]


def disc_cells(shape: tuple[int, int], center: tuple[float, float], radius_cells: float) -> tuple[np.ndarray, np.ndarray]:
    """Indices (ii, jj) of the cells whose centres lie within ``radius_cells`` of the fractional cell ``center``."""
    ci, cj = center
    r = math.ceil(radius_cells) + 1
    i0, i1 = max(int(ci) - r, 0), min(int(ci) + r + 1, shape[0])
    j0, j1 = max(int(cj) - r, 0), min(int(cj) + r + 1, shape[1])
    ii, jj = np.mgrid[i0:i1, j0:j1]
    inside = (ii + 0.5 - ci) ** 2 + (jj + 0.5 - cj) ** 2 <= radius_cells * radius_cells
    return ii[inside], jj[inside]


def search_mask(costmap: Costmap, start: tuple[int, int], *, ceiling: bool = True,
                extra_blocked: np.ndarray | None = None, tall: np.ndarray | None = None) -> np.ndarray:
    """The mask A* searches: ``free & wide & tall`` minus ``extra_blocked``, plus an escape disc.

    The escape disc (radius body_radius + one cell around the start, free and tall cells
    only) lets a start closer to a wall than ``body_radius`` leave it. ``ceiling=False``
    drops ``tall`` (for diagnosis); ``tall`` overrides the locomotion's.
    """
    tall = costmap.tall if tall is None else tall
    ok = costmap.free & tall if ceiling else costmap.free.copy()
    mask = ok & costmap.wide
    if extra_blocked is not None:
        ok = ok & ~extra_blocked
        mask &= ~extra_blocked
    si, sj = start
    if not mask[si, sj] and ok[si, sj]:
        ii, jj = disc_cells(mask.shape, (si + 0.5, sj + 0.5), costmap.body_radius / costmap.cell_size + 1.0)
        mask[ii, jj] |= ok[ii, jj]
    return mask


def goal_cells(mask: np.ndarray, target: np.ndarray, reach_cells: float) -> np.ndarray:
    """Target cells that are in ``mask``; if none, mask cells within ``reach_cells`` of a target cell
    (a landmark that is itself an obstacle, e.g. a car, is reached next to it)."""
    target = np.asarray(target, dtype=np.int64).reshape(-1, 2)
    ok = mask[target[:, 0], target[:, 1]]
    if ok.any():
        return target[ok]
    r = math.ceil(reach_cells)
    H, W = mask.shape
    i0, i1 = max(target[:, 0].min() - r, 0), min(target[:, 0].max() + r + 1, H)
    j0, j1 = max(target[:, 1].min() - r, 0), min(target[:, 1].max() + r + 1, W)
    local = np.ones((i1 - i0, j1 - j0), bool)
    local[target[:, 0] - i0, target[:, 1] - j0] = False
    near = ndimage.distance_transform_edt(local) <= reach_cells
    ii, jj = np.nonzero(near & mask[i0:i1, j0:j1])
    return np.stack((ii + i0, jj + j0), axis=1).astype(np.int64)


def _goal_mask(shape, goals):
    m = np.zeros(shape, bool)
    m[goals[:, 0], goals[:, 1]] = True
    return m


def reachable(costmap: Costmap, start: tuple[int, int], goals: np.ndarray, passable: np.ndarray, *,
              slope: bool = True) -> bool:
    """Whether a goal is reachable from ``start`` in ``passable`` (``slope=False``: ignore slopes and steps)."""
    if len(goals) == 0 or not passable[start]:
        return False
    inf = np.inf
    return bool(_reach_kernel(passable, costmap.terrain, costmap.heights, int(start[0]), int(start[1]),
                              _goal_mask(passable.shape, goals), costmap.cell_size,
                              costmap.max_slope if slope else inf, costmap.max_step if slope else inf))


def diagnose(costmap: Costmap, start: tuple[int, int], target: np.ndarray, *, reach_cells: float = 0.0,
             extra_blocked: np.ndarray | None = None) -> PlanningError:
    """The ``PlanningError`` explaining why ``target`` cannot be reached from ``start``:
    re-check reachability with the ceiling, then the slope, then both constraints relaxed."""
    loc = costmap.locomotion
    start = (int(start[0]), int(start[1]))
    what = f"for {loc.name} from cell {start}"
    if not costmap.free[start]:
        return PlanningError("blocked", f"no path {what}: the start is inside an obstacle")
    if extra_blocked is not None and extra_blocked[start]:
        return PlanningError("blocked", f"no path {what}: the start is inside a dynamic obstacle")

    def can(ceiling: bool, slope: bool) -> bool:
        mask = search_mask(costmap, start, ceiling=ceiling, extra_blocked=extra_blocked)
        return reachable(costmap, start, goal_cells(mask, target, reach_cells), mask, slope=slope)

    if can(ceiling=False, slope=True):
        fits = []
        for other in LOCOMOTIONS.values():
            if other.head_min < loc.head_min:
                mask = search_mask(costmap, start, extra_blocked=extra_blocked, tall=costmap.tall_for(other))
                if reachable(costmap, start, goal_cells(mask, target, reach_cells), mask):
                    fits.append(other.name)
        hint = f"; {', '.join(fits)} would fit" if fits else ""
        return PlanningError("ceiling", f"no path {what}: the ceiling is too low for {loc.name} (it needs "
                             f"{costmap.required_headroom:.2f} m of headroom: head {loc.head_min:.2f} m + margin "
                             f"{costmap.ceiling_margin:.2f} m){hint}")
    if can(ceiling=True, slope=False):
        return PlanningError("slope", f"no path {what}: every route is too steep (max_slope {costmap.max_slope}, "
                             f"max_step {costmap.max_step} m)")
    if can(ceiling=False, slope=False):
        return PlanningError("ceiling+slope", f"no path {what}: every route is too steep or under a ceiling too low "
                             f"for {loc.name}")
    narrow = ""
    if costmap.body_radius > 0:
        mask = costmap.free.copy() if extra_blocked is None else costmap.free & ~extra_blocked
        if reachable(costmap, start, goal_cells(mask, target, reach_cells), mask, slope=False):
            narrow = f" (openings are narrower than the body: body_radius {costmap.body_radius} m)"
    return PlanningError("blocked", f"no path {what}: obstacles block every route{narrow}")


def astar(
    costmap: Costmap,
    start: tuple[int, int],
    target: np.ndarray,
    *,
    reach: float = 0.5,
    extra_blocked: np.ndarray | None = None,
    max_expansions: int | None = None,
) -> AStarResult:
    """Cheapest path from the ``start`` cell to any cell of ``target`` ((K, 2) cells).

    reach (m, finite >= 0): if no target cell is passable, passable cells within ``reach`` of one
        are goals. extra_blocked: (H, W) bool cells to avoid as well (dynamic obstacles).
    max_expansions: search budget (default H * W, which never binds).
    Raises ValueError for a start or target cell outside the grid, an empty target or a bad
    keyword, and ``PlanningError`` (reason blocked / ceiling / slope / ceiling+slope / budget)
    when no target cell can be reached.
    """
    reach = check_range("reach", reach, 0.0, math.inf, high_open=True)
    H, W = costmap.grid.shape
    start_cells = check_cells("start", start, (H, W))
    if len(start_cells) != 1:
        raise ValueError(f"start must be one (i, j) cell, got {len(start_cells)} cells")
    si, sj = (int(v) for v in start_cells[0])
    target = check_cells("target", target, (H, W))
    if extra_blocked is not None:
        extra_blocked = np.asarray(extra_blocked, dtype=bool)
        if extra_blocked.shape != (H, W):
            raise ValueError(f"extra_blocked must be a bool array of the grid's shape {(H, W)}, "
                             f"got shape {extra_blocked.shape}")
    if max_expansions is None:
        max_expansions = H * W
    elif int(max_expansions) < 1:
        raise ValueError(f"max_expansions must be an integer >= 1, got {max_expansions!r}")
    reach_cells = reach / costmap.cell_size
    mask = search_mask(costmap, (si, sj), extra_blocked=extra_blocked)
    goals = goal_cells(mask, target, reach_cells)
    if not mask[si, sj] or len(goals) == 0:
        raise diagnose(costmap, (si, sj), target, reach_cells=reach_cells, extra_blocked=extra_blocked)
    path, cost, expansions, status = _astar_kernel(
        mask, costmap.terrain, costmap.heights, si, sj, _goal_mask(mask.shape, goals), goals, costmap.cell_size,
        costmap.max_slope, costmap.max_step, costmap.height_cost, costmap.slope_preference, int(max_expansions))
    if status == 2:
        raise PlanningError("budget", f"A* stopped after max_expansions={max_expansions} expansions without "
                            f"reaching the goal")
    if status == 1:
        raise diagnose(costmap, (si, sj), target, reach_cells=reach_cells, extra_blocked=extra_blocked)
    cells = np.stack(np.divmod(path, W), axis=1)
    return AStarResult(cells, float(cost), int(expansions), mask, goals)
