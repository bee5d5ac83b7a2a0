"""Planning time of the PlaMo planner on a 100 m x 100 m scene at 0.1 m cells (1000 x 1000).

    python benchmarks/bench_planning.py [--rounds 5] [--seed 0] [--crop 300] [--no-nx-full] [--json out.json]

A seeded synthetic scene: hills (Gaussian bumps up to +-3 m), 60 walls, six roofs (three at
1.0 m over the ground: too low to walk, fine to crouch-walk; three at 0.6 m: crawl only);
landmarks "home" (near (3, 3) m) and "tower" (near (97, 97) m). Reported (median of rounds):

- full plan: a fresh ``Planner`` (costmap for the locomotion + A* + refiner + speed QP),
  broken down by stage; also with the costmap already built (a second segment);
- replan: a ball crossing the path 1.2 s ahead of the character (``replan.replan``);
- A* against networkx's ``astar_path`` on the same graph (same edges, same weights, same
  octile heuristic), on a ``--crop`` x ``--crop`` window in the middle of the map and on
  the whole map (about 3.6e6 edges: networkx needs ~10 s and a few GB to build that graph
  and ~8 s to search it; ``--no-nx-full`` skips it). Graph building is timed separately.
Targets (issue: PlaMo planner): full plan < 1 s, replan < 100 ms.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import resource
import statistics
import time

import networkx as nx
import numpy as np
from scipy import ndimage

from stairenv.planning.astar import astar, edge_list, reachable
from stairenv.planning.costmap import build_costmap
from stairenv.planning.grid import PlanningGrid
from stairenv.planning.planner import Planner, PlannerSettings, plan_path
from stairenv.planning.refine import refine_path
from stairenv.planning.replan import ConstantVelocityObstacle, replan
from stairenv.planning.speed import speed_limits, speed_profile


def synthetic_scene(size_m: float = 100.0, cell: float = 0.1, seed: int = 0, n_hills: int = 25, n_walls: int = 60,
                    n_roofs: int = 6) -> PlanningGrid:
    rng = np.random.default_rng(seed)
    n = round(size_m / cell)
    y, x = (np.mgrid[0:n, 0:n] + 0.5) * cell
    h = np.zeros((n, n))
    for _ in range(n_hills):
        cx, cy = rng.uniform(0, size_m, 2)
        s = rng.uniform(3, 8)
        a = rng.uniform(0.5, 3.0) * rng.choice([-1, 1])
        h += a * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * s * s))
    blocked = np.zeros((n, n), bool)
    for _ in range(n_walls):
        length, thick = rng.uniform(5, 25), rng.uniform(0.2, 0.4)
        cx, cy = rng.uniform(0, size_m, 2)
        if rng.random() < 0.5:
            blocked |= (np.abs(y - cy) < thick / 2) & (np.abs(x - cx) < length / 2)
        else:
            blocked |= (np.abs(x - cx) < thick / 2) & (np.abs(y - cy) < length / 2)
    ceiling = np.full((n, n), np.inf)
    for k in range(n_roofs):
        cx, cy = rng.uniform(10, size_m - 10, 2)
        w, d = rng.uniform(4, 12, 2)
        roof = (np.abs(x - cx) < w / 2) & (np.abs(y - cy) < d / 2)
        ceiling[roof] = h[roof] + (1.0 if k % 2 == 0 else 0.6)
    for cx, cy in [(3, 3), (size_m - 3, size_m - 3)]:  # keep the landmarks clear
        clear = (x - cx) ** 2 + (y - cy) ** 2 < 3.0 ** 2
        blocked[clear] = False
        ceiling[clear] = np.inf
    a0, a1 = int(2 / cell), int(4 / cell)
    b0, b1 = n - int(4 / cell), n - int(2 / cell)
    landmarks = {"home": np.argwhere(np.ones((a1 - a0, a1 - a0))) + a0,
                 "tower": np.argwhere(np.ones((b1 - b0, b1 - b0))) + b0}
    return PlanningGrid(h, blocked, ceiling, cell, (0.0, 0.0), landmarks)


def crop(grid: PlanningGrid, i0: int, j0: int, size: int) -> PlanningGrid:
    sl = (slice(i0, i0 + size), slice(j0, j0 + size))
    return PlanningGrid(grid.heights[sl], grid.blocked[sl], grid.ceiling[sl], grid.cell_size)


def time_full_plan(grid, settings, locomotion, start):
    t0 = time.perf_counter()
    cm = build_costmap(grid, locomotion, **settings.costmap_kwargs())
    t1 = time.perf_counter()
    search = astar(cm, tuple(grid.cell_of(np.asarray(start))), grid.landmarks["tower"], reach=settings.reach)
    t2 = time.perf_counter()
    path = refine_path(cm, search.cells, passable=search.passable, start_xy=start, ds=settings.ds,
                       smoothing=settings.smoothing, comfort=settings.comfort, head_slope=settings.head_slope,
                       head_smoothing=settings.head_smoothing, curvature_scale=settings.curvature_scale)
    t3 = time.perf_counter()
    v_up = speed_limits(path.s, path.curvature, path.ground, cm.locomotion.speed_max, a_lat=settings.a_lat,
                        uphill_gain=settings.uphill_gain, downhill_gain=settings.downhill_gain,
                        min_speed_fraction=settings.min_speed_fraction)
    prof = speed_profile(path.s, v_up, a_max=settings.a_max, a_min=settings.a_min,
                         knot_spacing=settings.knot_spacing, max_knots=settings.max_knots)
    t4 = time.perf_counter()
    return {"costmap": t1 - t0, "astar": t2 - t1, "refine": t3 - t2, "qp": t4 - t3, "total": t4 - t0,
            "expansions": search.expansions, "length_m": path.length, "travel_time_s": prof.travel_time,
            "qp_iterations": prof.iterations}


def median_dict(rows):
    return {k: statistics.median(r[k] for r in rows) for k in rows[0]}


def nx_compare(grid, i0, j0, size, settings, locomotion, rounds):
    sub = crop(grid, i0, j0, size)
    cm = build_costmap(sub, locomotion, **settings.costmap_kwargs())
    # start and goal: cells of the largest passable region nearest opposite corners of the window
    labels, _ = ndimage.label(cm.passable, structure=np.ones((3, 3)))
    largest = np.argmax(np.bincount(labels.ravel())[1:]) + 1
    free = np.argwhere(labels == largest)
    order_s, order_g = np.argsort(free.sum(axis=1)), np.argsort(-free.sum(axis=1))
    for k in range(50):  # slopes may still separate them: take the first reachable pair
        start, goal = tuple(free[order_s[k]]), free[order_g[k]][None, :]
        if reachable(cm, start, goal, cm.passable):
            break
    t0 = time.perf_counter()
    u, v, w = edge_list(cm)
    graph = nx.Graph()
    graph.add_weighted_edges_from(zip(u.tolist(), v.tolist(), w.tolist()))
    build = time.perf_counter() - t0
    W = sub.shape[1]
    c = sub.cell_size

    def octile(a, b):
        di, dj = abs(a // W - b // W), abs(a % W - b % W)
        return c * (max(di, dj) + (math.sqrt(2) - 1) * min(di, dj))

    src, dst = int(start[0] * W + start[1]), int(goal[0, 0] * W + goal[0, 1])
    ours, theirs = [], []
    for _ in range(rounds):
        t = time.perf_counter()
        res = astar(cm, start, goal, reach=0.0)
        ours.append(time.perf_counter() - t)
    for _ in range(max(1, min(rounds, 3))):
        t = time.perf_counter()
        nodes = nx.astar_path(graph, src, dst, heuristic=octile, weight="weight")
        theirs.append(time.perf_counter() - t)
    nx_cost = sum(graph[a][b]["weight"] for a, b in itertools.pairwise(nodes))
    return {"cells": size * size, "edges": len(u), "nx_build_s": build, "ours_s": statistics.median(ours),
            "nx_s": statistics.median(theirs), "ratio": statistics.median(theirs) / statistics.median(ours),
            "cost_ours": res.cost, "cost_nx": nx_cost, "expansions": res.expansions}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--crop", type=int, default=300, help="side (cells) of the networkx comparison window")
    parser.add_argument("--no-nx-full", action="store_true", help="skip networkx on the whole map (slow)")
    parser.add_argument("--locomotion", default="walk")
    parser.add_argument("--json", default=None)
    args = parser.parse_args()

    grid = synthetic_scene(seed=args.seed)
    settings = PlannerSettings(slope_preference=1.0)
    start = np.array([3.05, 3.05])
    # warm up the compiled kernels (numba caches them on disk; the first import may compile)
    small = crop(grid, 0, 0, 60)
    small.landmarks["tower"] = np.array([[50, 50]])
    Planner(small, settings).plan("tower", args.locomotion, start=start)

    rows = [time_full_plan(grid, settings, args.locomotion, start) for _ in range(args.rounds)]
    full = median_dict(rows)
    planner = Planner(grid, settings)
    cm = planner.costmap(args.locomotion)
    plan = plan_path(cm, start, grid.landmarks["tower"], settings=settings)
    prepared = []
    for _ in range(args.rounds):
        t = time.perf_counter()
        plan_path(cm, start, grid.landmarks["tower"], settings=settings)
        prepared.append(time.perf_counter() - t)

    # replan: a ball crossing the path 1.2 s ahead, at a third of the way
    t_cross = plan.trajectory.duration / 3
    p_cross = plan.trajectory.position(t_cross)[:2]
    heading = plan.trajectory.position(t_cross + 0.1)[:2] - p_cross
    normal = np.array([-heading[1], heading[0]]) / max(np.linalg.norm(heading), 1e-9)
    ball = ConstantVelocityObstacle(p_cross - 1.5 * normal, 0.5 * normal, radius=0.3, t0=t_cross - 3.0)
    t_now = t_cross - 1.2
    replans = []
    for _ in range(args.rounds):
        t = time.perf_counter()
        result = replan(plan, [ball], t_now=t_now)
        replans.append(time.perf_counter() - t)
    assert result is not None

    H, W = grid.shape
    size = min(args.crop, H)
    i0 = j0 = (H - size) // 2  # the middle of the map: walls, hills and roofs
    comp = nx_compare(grid, i0, j0, size, settings, args.locomotion, args.rounds)
    full_nx = None if args.no_nx_full else nx_compare(grid, 0, 0, H, settings, args.locomotion, 1)

    report = {
        "map": f"{H} x {W} cells of {grid.cell_size} m ({H * W:.0e} cells)",
        "full_plan": full, "plan_with_costmap_s": statistics.median(prepared),
        "replan_s": statistics.median(replans), "replan_rounds": result.rounds,
        "nx_crop": comp, "nx_full": full_nx,
    }
    print(f"map {report['map']}, locomotion {args.locomotion}, {args.rounds} rounds (medians)")
    print(f"full plan        {full['total'] * 1e3:8.1f} ms  (costmap {full['costmap'] * 1e3:.1f}, A* "
          f"{full['astar'] * 1e3:.1f} [{full['expansions']:.0f} expansions], refine {full['refine'] * 1e3:.1f}, "
          f"QP {full['qp'] * 1e3:.1f} [{full['qp_iterations']:.0f} it]); path {full['length_m']:.1f} m, "
          f"{full['travel_time_s']:.1f} s   target < 1000 ms: {'ok' if full['total'] < 1 else 'MISSED'}")
    print(f"plan, costmap built {report['plan_with_costmap_s'] * 1e3:8.1f} ms")
    print(f"replan           {report['replan_s'] * 1e3:8.1f} ms  ({result.rounds} A* round(s))   "
          f"target < 100 ms: {'ok' if report['replan_s'] < 0.1 else 'MISSED'}")
    for name, c in (("crop", comp), ("full", full_nx)):
        if c is None:
            continue
        print(f"A* vs networkx ({name} {int(math.sqrt(c['cells']))}^2 cells, {c['edges']} edges, "
              f"{c['expansions']} expansions): ours {c['ours_s'] * 1e3:.2f} ms, networkx astar_path {c['nx_s'] * 1e3:.1f} ms, ratio {c['ratio']:.0f}x; "
              f"networkx graph build {c['nx_build_s']:.2f} s; costs {c['cost_ours']:.6f} / {c['cost_nx']:.6f}")
    if full_nx is None:
        print("(networkx on the whole map skipped: --no-nx-full)")
    print(f"peak memory {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(report, f, indent=2, default=float)


if __name__ == "__main__":
    main()
