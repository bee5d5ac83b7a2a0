"""The PlaMo planner (``stairenv.planning``): parser, A*, refiner, speed QP, waypoints, replanning.

References are independent of the code under test where possible: networkx's Dijkstra on
the same graph for A*, ``scipy.ndimage.distance_transform_edt`` for clearance, the
analytic trapezoidal profile for the speed QP, and explicit geometry for replanning.
"""

from __future__ import annotations

import itertools
import math
import re

import networkx as nx
import numpy as np
import pytest
from scipy import ndimage

from stairenv.planning.astar import astar, edge_list, edge_weights
from stairenv.planning.costmap import build_costmap
from stairenv.planning.errors import InstructionError, PlanningError
from stairenv.planning.grid import PlanningGrid
from stairenv.planning.instructions import Segment, parse_instructions
from stairenv.planning.locomotion import LOCOMOTIONS, get_locomotion
from stairenv.planning.planner import Planner, PlannerSettings, plan_path
from stairenv.planning.refine import head_profile
from stairenv.planning.replan import (
    ClosedLoopObstacle,
    ConstantVelocityObstacle,
    predict_collision,
    replan,
    wait_for_obstacles,
)
from stairenv.planning.speed import speed_limits, speed_profile, time_optimal_reference, travel_time
from stairenv.planning.waypoints import Trajectory, timed_waypoints

LANDMARKS = ["car", "swing", "bench", "tree", "park_bench"]
DI = np.array([-1, -1, -1, 0, 0, 1, 1, 1])
DJ = np.array([-1, 0, 1, -1, 1, -1, 0, 1])


def flat_grid(h: int, w: int, cell: float = 0.1, landmarks: dict | None = None) -> PlanningGrid:
    return PlanningGrid(np.zeros((h, w)), np.zeros((h, w), bool), np.full((h, w), np.inf), cell, (0.0, 0.0),
                        landmarks or {})


def square(i: int, j: int, r: int = 1) -> np.ndarray:
    ii, jj = np.mgrid[i - r:i + r + 1, j - r:j + r + 1]
    return np.stack((ii.ravel(), jj.ravel()), axis=1)


def path_cost(weights: np.ndarray, cells: np.ndarray) -> float:
    """Sum of edge weights along consecutive cells (inf if a step is not an edge)."""
    total = 0.0
    for (i, j), (ni, nj) in itertools.pairwise(cells):
        d = np.nonzero((DI == ni - i) & (DJ == nj - j))[0]
        if len(d) != 1:
            return math.inf
        total += weights[i, j, d[0]]
    return total


# ------------------------------------------------------------------------------------ parser
def test_parse_paper_sentences():
    assert parse_instructions("Run to the car, then crawl from the car to the swing", LANDMARKS) == [
        Segment(None, "car", "run"), Segment("car", "swing", "crawl")]
    assert parse_instructions("Walk crouching to the bench", LANDMARKS) == [Segment(None, "bench", "crouch-walk")]
    # Fig. 9 (c): a list of sentences; missing sources chain from the previous target
    segs = parse_instructions(["Crawl to the bench", "crawl to the tree", "walk crouching to the bench",
                               "sprint to the car"], LANDMARKS)
    assert segs == [Segment(None, "bench", "crawl"), Segment("bench", "tree", "crawl"),
                    Segment("tree", "bench", "crouch-walk"), Segment("bench", "car", "sprint")]


@pytest.mark.parametrize("text, expected", [
    ("jog to the tree", "run"),
    ("Crouch-walk to the tree", "crouch-walk"),
    ("crouch walk to the tree", "crouch-walk"),
    ("go crawling to the tree", "crawl"),
    ("dash to the tree", "sprint"),
    ("stroll to the tree", "walk"),
    ("please walk back to the tree", "walk"),
])
def test_parse_synonyms(text, expected):
    assert parse_instructions(text, LANDMARKS)[0].locomotion == expected


def test_parse_sources_landmark_names_and_separators():
    segs = parse_instructions("walk from the tree to the Park Bench and run to the car; crawl to the swing. "
                              "Walk to the tree from the swing", LANDMARKS)
    assert segs == [Segment("tree", "park_bench", "walk"), Segment("park_bench", "car", "run"),
                    Segment("car", "swing", "crawl"), Segment("swing", "tree", "walk")]


def test_parse_errors_list_what_is_known():
    with pytest.raises(InstructionError, match="unknown landmark 'lake'") as err:
        parse_instructions("Run from the tree to the lake", LANDMARKS)
    assert all(name in str(err.value) for name in LANDMARKS)
    with pytest.raises(InstructionError, match="unknown locomotion verb 'fly'") as err:
        parse_instructions("Fly to the car", LANDMARKS)
    assert all(name in str(err.value) for name in LOCOMOTIONS)
    assert isinstance(err.value, ValueError)
    with pytest.raises(InstructionError, match="expected"):
        parse_instructions("walk the car", LANDMARKS)
    with pytest.raises(InstructionError, match="ambiguous"):
        parse_instructions("run crawling to the car", LANDMARKS)


def test_locomotion_table():
    heads = {name: loc.head_height for name, loc in LOCOMOTIONS.items()}
    assert heads == {"crawl": 0.4, "crouch-walk": 0.8, "walk": 1.47, "run": 1.47, "sprint": 1.47}
    assert LOCOMOTIONS["crawl"].speed_max == 1.0 and LOCOMOTIONS["crouch-walk"].speed_max == 2.0
    assert LOCOMOTIONS["run"].speed_max == 4.0 and LOCOMOTIONS["sprint"].speed_max == 5.0
    for loc in LOCOMOTIONS.values():
        assert 0 < loc.head_min <= loc.head_height and 0 < loc.speed_min < loc.speed_max
    assert get_locomotion("Crouching").name == "crouch-walk"
    with pytest.raises(ValueError, match="locomotion must be one of"):
        get_locomotion("swim")


# ------------------------------------------------------------------------------------ A*
def random_grid(rng, h=18, w=22):
    heights = np.cumsum(rng.normal(0.0, 0.03, (h, w)), axis=1) + np.cumsum(rng.normal(0.0, 0.03, (h, w)), axis=0)
    blocked = rng.random((h, w)) < 0.15
    ceiling = np.where(rng.random((h, w)) < 0.08, heights + rng.uniform(0.5, 2.0, (h, w)), np.inf)
    return PlanningGrid(heights, blocked, ceiling, 0.1)


@pytest.mark.parametrize("seed", range(8))
def test_astar_is_optimal_against_networkx_dijkstra(seed):
    rng = np.random.default_rng(seed)
    grid = random_grid(rng)
    cm = build_costmap(grid, ["crawl", "crouch-walk", "walk"][seed % 3], body_radius=[0.0, 0.1][seed % 2],
                       head_radius=0.0, slope_window=[0.0, 0.3][seed % 2], max_slope=1.5, max_step=0.12,
                       height_cost=rng.uniform(0.0, 3.0), slope_preference=rng.uniform(0.0, 4.0))
    u, v, w = edge_list(cm)
    graph = nx.Graph()
    graph.add_weighted_edges_from(zip(u.tolist(), v.tolist(), w.tolist()))
    weights = edge_weights(cm)
    free = np.argwhere(cm.passable)
    W = grid.shape[1]
    checked = 0
    for _ in range(6):
        start = tuple(free[rng.integers(len(free))])
        goals = free[rng.choice(len(free), size=int(rng.integers(1, 5)), replace=False)]
        g = graph.copy()
        g.add_node(start[0] * W + start[1])
        for gi, gj in goals:
            g.add_edge(int(gi * W + gj), "goal", weight=0.0)
        try:
            expected = nx.dijkstra_path_length(g, start[0] * W + start[1], "goal")
        except nx.NetworkXNoPath:
            expected = None
        if expected is None:
            with pytest.raises(PlanningError):
                astar(cm, start, goals, reach=0.0)
            continue
        result = astar(cm, start, goals, reach=0.0)
        assert result.cost == pytest.approx(expected, rel=1e-9, abs=1e-12)
        assert tuple(result.cells[0]) == start and any((result.cells[-1] == goals).all(axis=1))
        assert path_cost(weights, result.cells) == pytest.approx(result.cost, rel=1e-9)
        checked += 1
    assert checked >= 2


def door_scene(door_ceiling: float, second_door: bool = False) -> PlanningGrid:
    """A wall across x = 5 m with a door (y 4.5..5.5 m) under a ceiling; optionally an open door at y 0..1 m."""
    h, w = 100, 100
    grid = flat_grid(h, w, landmarks={"a": square(50, 20), "b": square(50, 80)})
    grid.blocked[:, 49:51] = True
    grid.blocked[45:55, 49:51] = False
    grid.ceiling[40:60, 45:55] = door_ceiling
    if second_door:
        grid.blocked[0:12, 49:51] = False
    return grid


def test_removed_edges_are_respected_and_crawl_passes_where_walk_cannot():
    grid = door_scene(0.6, second_door=True)
    planner = Planner(grid)
    crawl = planner.plan("b", "crawl", start="a")
    walk = planner.plan("b", "walk", start="a")
    for plan in (crawl, walk):
        cm = plan.costmap
        cells = plan.search.cells
        assert not grid.blocked[cells[:, 0], cells[:, 1]].any()
        assert (cm.headroom[cells[:, 0], cells[:, 1]] >= cm.required_headroom).all()
        assert np.isfinite(path_cost(edge_weights(cm, plan.search.passable), cells))
    # crawl goes through the low door, walk around through the open one
    assert (crawl.search.cells[:, 0] >= 40).all()
    assert walk.search.cells[:, 0].min() < 12
    assert walk.length > crawl.length + 3.0
    # the ceiling is under the crawl's head all the way
    cells = grid.cell_of(crawl.path.xy)
    assert (crawl.path.z_head <= grid.ceiling[cells[:, 0], cells[:, 1]] - 0.1 + 1e-9).all()


def test_slope_preference_goes_around_the_hill():
    h, w = 80, 140
    y, x = (np.mgrid[0:h, 0:w] + 0.5) * 0.1
    heights = 2.0 * np.exp(-((x - 7.0) ** 2 + (y - 4.0) ** 2) / (2 * 1.5 ** 2))
    grid = PlanningGrid(heights, np.zeros((h, w), bool), np.full((h, w), np.inf), 0.1, (0.0, 0.0),
                        {"goal": np.array([[40, 130]])})
    max_height, length = [], []
    for c in (0.0, 2.0, 5.0, 10.0):
        cm = build_costmap(grid, "walk", height_cost=0.0, slope_preference=c, max_slope=5.0, max_step=1.0)
        cells = astar(cm, (40, 10), grid.landmarks["goal"]).cells
        max_height.append(heights[cells[:, 0], cells[:, 1]].max())
        length.append(float(np.sum(np.linalg.norm(np.diff(cells, axis=0), axis=1))) * 0.1)
    assert max_height[0] > 1.9  # straight over the top
    assert all(a >= b - 1e-12 for a, b in itertools.pairwise(max_height))
    assert all(a <= b + 1e-12 for a, b in itertools.pairwise(length))
    assert max_height[-1] < 0.5 * max_height[0] and length[-1] > length[0] + 0.5


def test_unreachable_goals_say_why():
    # blocked: the goal is walled in
    grid = flat_grid(60, 60, landmarks={"a": square(10, 10), "b": square(40, 40)})
    grid.blocked[30:51, 30] = grid.blocked[30:51, 50] = grid.blocked[30, 30:51] = grid.blocked[50, 30:51] = True
    with pytest.raises(PlanningError, match="obstacles block") as err:
        Planner(grid).plan("b", "walk", start="a")
    assert err.value.reason == "blocked"
    # ceiling: the only door is too low for walking; crawling fits
    grid = door_scene(0.6)
    with pytest.raises(PlanningError, match="too low for walk") as err:
        Planner(grid).plan("b", "walk", start="a")
    assert err.value.reason == "ceiling" and "crawl would fit" in str(err.value)
    assert Planner(grid).plan("b", "crawl", start="a").length > 5.0
    # slope: the goal stands on a 1 m plateau with cliff edges
    grid = flat_grid(60, 60, landmarks={"a": square(10, 10), "b": square(40, 40)})
    grid.heights[30:51, 30:51] = 1.0
    with pytest.raises(PlanningError, match="too steep") as err:
        Planner(grid).plan("b", "walk", start="a")
    assert err.value.reason == "slope"
    # both: a low roof over the plateau
    grid.ceiling[28:53, 28:53] = 1.6
    with pytest.raises(PlanningError) as err:
        Planner(grid).plan("b", "walk", start="a")
    assert err.value.reason == "ceiling+slope"
    # the search is bounded
    with pytest.raises(PlanningError, match="max_expansions") as err:
        Planner(flat_grid(60, 60, landmarks={"a": square(5, 5), "b": square(55, 55)}),
                PlannerSettings(max_expansions=10)).plan("b", "walk", start="a")
    assert err.value.reason == "budget"
    # the start inside a wall
    grid = flat_grid(60, 60, landmarks={"b": square(40, 40)})
    grid.blocked[5:15, 5:15] = True
    with pytest.raises(PlanningError, match="inside an obstacle"):
        Planner(grid).plan("b", "walk", start=(1.0, 1.0))


# ------------------------------------------------------------------------------------ refiner
def walls_scene(seed: int) -> PlanningGrid:
    rng = np.random.default_rng(seed)
    h = w = 150
    grid = flat_grid(h, w, landmarks={"a": square(8, 8), "b": square(141, 141)})
    for _ in range(14):
        i, j = rng.integers(20, 130, 2)
        if rng.random() < 0.5:
            grid.blocked[i:i + 3, max(j - 25, 0):j + 25] = True
        else:
            grid.blocked[max(i - 25, 0):i + 25, j:j + 3] = True
    return grid


@pytest.mark.parametrize("seed", range(3))
def test_refiner_keeps_clearance(seed):
    grid = walls_scene(seed)
    settings = PlannerSettings(body_radius=0.3)
    plan = Planner(grid, settings).plan("b", "walk", start="a")
    clearance = ndimage.distance_transform_edt(~grid.blocked) * grid.cell_size
    cells = grid.cell_of(plan.path.xy)
    assert clearance[cells[:, 0], cells[:, 1]].min() >= settings.body_radius - 1e-9
    # smooth where there is room: the refined path is no longer than the A* path and turns gently
    astar_length = float(np.sum(np.linalg.norm(np.diff(plan.search.cells, axis=0), axis=1))) * grid.cell_size
    assert plan.length <= astar_length
    assert np.median(plan.path.curvature) < 0.05
    assert np.allclose(plan.path.xy[0], plan.trajectory.xyz[0, :2])


def test_head_ducks_under_a_ceiling_with_bounded_slope():
    grid = flat_grid(40, 200, landmarks={"a": square(20, 5), "b": square(20, 194)})
    grid.heights[:] = np.linspace(0.0, 1.5, 200)[None, :]  # a gentle ramp
    grid.ceiling[:, 80:120] = grid.heights[:, 80:120] + 1.4  # walk ducks to 1.3 m
    settings = PlannerSettings(head_slope=0.4)
    plan = Planner(grid, settings).plan("b", "walk", start="a")
    p = plan.path
    cells = grid.cell_of(p.xy)
    assert (p.z_head <= grid.ceiling[cells[:, 0], cells[:, 1]] - settings.ceiling_margin + 1e-9).all()
    assert (p.head <= LOCOMOTIONS["walk"].head_height + 1e-12).all()
    assert p.head.min() < 1.31 and p.head.min() >= LOCOMOTIONS["walk"].head_min
    assert p.head[0] == pytest.approx(1.47) and p.head[-1] == pytest.approx(1.47)
    assert np.all(np.abs(np.diff(p.head)) <= settings.head_slope * np.diff(p.s) + 1e-12)


def test_head_profile_envelope_properties():
    rng = np.random.default_rng(3)
    s = np.cumsum(rng.uniform(0.02, 0.06, 600))
    ground = np.cumsum(rng.normal(0, 0.01, 600))
    ceiling = ground + np.where(rng.random(600) < 0.02, rng.uniform(0.5, 1.5, 600), np.inf)
    ceiling = ndimage.minimum_filter1d(ceiling, 15)
    h = head_profile(s, ground, ceiling, 1.47, margin=0.1, head_slope=0.5, head_smoothing=0.5)
    assert (ground + h <= ceiling - 0.1 + 1e-12).all() and (h <= 1.47).all()
    assert np.all(np.abs(np.diff(h)) <= 0.5 * np.diff(s) + 1e-12)
    open_sky = ndimage.minimum_filter1d(np.isinf(ceiling), 200)
    assert np.allclose(h[open_sky], 1.47)  # far from any ceiling the head is at its nominal height
    with pytest.raises(ValueError, match="head_slope"):
        head_profile(s, ground, ceiling, 1.47, head_slope=0.0)


# ------------------------------------------------------------------------------------ speed QP
def trapezoid_time(length: float, v_max: float, a_max: float, decel: float) -> float:
    d1, d2 = v_max ** 2 / (2 * a_max), v_max ** 2 / (2 * decel)
    if d1 + d2 <= length:
        return v_max / a_max + v_max / decel + (length - d1 - d2) / v_max
    vp = math.sqrt(2 * length * a_max * decel / (a_max + decel))
    return vp / a_max + vp / decel


@pytest.mark.parametrize("length, v_max", [(10.0, 2.0), (60.0, 2.0), (150.0, 4.0), (30.0, 1.0)])
def test_speed_qp_straight_line_matches_the_trapezoid(length, v_max):
    s = np.linspace(0.0, length, int(length / 0.05) + 1)
    prof = speed_profile(s, np.full_like(s, v_max))
    optimum = trapezoid_time(length, v_max, 0.5, 0.1)
    assert optimum <= prof.travel_time <= 1.10 * optimum
    assert prof.travel_time == pytest.approx(optimum, rel=0.01)


def check_bounds(prof, v_upper, a_max, a_min, v_start, v_end, tol=1e-6):
    assert (prof.v <= v_upper + tol).all() and (prof.b >= -tol).all()
    delta = np.diff(prof.knots)
    accel = np.diff(prof.b) / (2 * delta)
    assert (accel <= a_max + tol).all() and (accel >= a_min - tol).all()
    assert prof.v[0] == pytest.approx(v_start, abs=1e-6) and prof.v[-1] == pytest.approx(v_end, abs=1e-6)
    # and between samples (b is linear in s between knots)
    sample_accel = np.diff(prof.v ** 2) / (2 * np.diff(prof.s))
    assert (sample_accel <= a_max + tol).all() and (sample_accel >= a_min - tol).all()


@pytest.mark.parametrize("seed", range(4))
def test_speed_qp_satisfies_every_bound_and_is_near_optimal(seed):
    rng = np.random.default_rng(seed)
    s = np.r_[0.0, np.cumsum(rng.uniform(0.03, 0.05, 2000))]
    kappa = np.abs(ndimage.gaussian_filter1d(rng.normal(0, 3.0, len(s)), 20))
    ground = np.cumsum(rng.normal(0, 0.004, len(s)))
    a_lat, a_max, a_min = rng.uniform(0.5, 2.0), rng.uniform(0.3, 1.0), -rng.uniform(0.1, 0.5)
    v_start, v_end = [(0.0, 0.0), (1.0, 0.0), (0.5, 0.8), (1.0, 0.3)][seed]
    kappa[:100] = 0.0  # room to brake from v_start
    v_upper = speed_limits(s, kappa, ground, 4.0, a_lat=a_lat)
    assert (v_upper ** 2 * kappa <= a_lat + 1e-9).all()
    prof = speed_profile(s, v_upper, a_max=a_max, a_min=a_min, v_start=v_start, v_end=v_end)
    check_bounds(prof, v_upper, a_max, a_min, v_start, v_end)
    assert (prof.v ** 2 * kappa <= a_lat + 1e-6).all()  # lateral acceleration
    best = travel_time(s, time_optimal_reference(s, v_upper, a_max=a_max, a_min=a_min, v_start=v_start,
                                                 v_end=v_end))
    # knots every 0.5 m with one bound each (the lowest of both neighbouring intervals) cost a few percent
    assert best <= prof.travel_time + 1e-9 and prof.travel_time <= 1.10 * best


def test_speed_limits_slope_and_keyword_errors():
    s = np.linspace(0, 10, 101)
    flat = speed_limits(s, np.zeros_like(s), np.zeros_like(s), 2.0)
    uphill = speed_limits(s, np.zeros_like(s), 0.3 * s, 2.0)
    downhill = speed_limits(s, np.zeros_like(s), -0.3 * s, 2.0)
    assert np.allclose(flat, 2.0) and np.allclose(uphill, 2.0 * 0.7) and np.allclose(downhill, 2.0 * 0.85)
    with pytest.raises(ValueError, match=r"a_max must be a number in \(0.0, inf\)"):
        speed_profile(s, flat, a_max=0.0)
    with pytest.raises(ValueError, match="a_min"):
        speed_profile(s, flat, a_min=0.1)
    with pytest.raises(ValueError, match="a_lat"):
        speed_limits(s, s, s, 2.0, a_lat=-1)
    with pytest.raises(ValueError, match="slope_preference"):
        build_costmap(flat_grid(5, 5), slope_preference=-1.0)
    with pytest.raises(ValueError, match="body_radius"):
        build_costmap(flat_grid(5, 5), body_radius=-0.1)
    with pytest.raises(ValueError, match=r"body_radius must be a number in \[0.0, inf\]"):
        PlannerSettings(body_radius=-0.1)
    with pytest.raises(ValueError, match="min_speed_fraction"):
        PlannerSettings(min_speed_fraction=0.0)
    with pytest.raises(PlanningError) as err:  # cannot stop from 3 m/s within 1 m at -0.1 m/s^2
        speed_profile(np.linspace(0, 1, 21), np.full(21, 4.0), v_start=3.0, v_end=0.0)
    assert err.value.reason == "speed"


# ------------------------------------------------------------------------------------ waypoints
def test_waypoints_reproduce_the_planned_speed():
    grid = walls_scene(1)
    plan = Planner(grid).plan("b", "run", start="a")
    wp = plan.waypoints(dt=0.1)
    assert np.allclose(np.diff(wp.t)[:-1], 0.1) and 0 < wp.t[-1] - wp.t[-2] <= 0.1 + 1e-9
    assert wp.t[-1] == pytest.approx(plan.travel_time)
    assert np.allclose(wp.xyz[0], plan.trajectory.xyz[0]) and np.allclose(wp.xyz[-1], plan.trajectory.xyz[-1])
    step = np.linalg.norm(np.diff(wp.xyz[:, :2], axis=0), axis=1)[:-1] / 0.1
    mean_v = 0.5 * (wp.v[1:] + wp.v[:-1])[:-1]
    assert np.allclose(step, mean_v, rtol=0.02, atol=0.02)
    assert wp.v.max() <= LOCOMOTIONS["run"].speed_max + 1e-6
    # a hand-made trajectory: uniform acceleration from rest, s = a t^2 / 2
    s = np.linspace(0, 8, 81)
    v = np.sqrt(2 * 0.5 * s)
    traj = Trajectory.from_profile(s, np.column_stack((s, 0 * s, 0 * s)), v)
    wp = timed_waypoints(traj, dt=0.5)
    assert np.allclose(wp.xyz[:, 0], 0.25 * wp.t ** 2, atol=1e-9)
    assert np.allclose(wp.v, 0.5 * wp.t, atol=1e-9)
    with pytest.raises(ValueError, match="dt"):
        timed_waypoints(traj, dt=0)


# ------------------------------------------------------------------------------------ replanning
def test_replanning_avoids_a_ball_crossing_the_path():
    grid = flat_grid(200, 200, landmarks={"a": square(100, 10), "b": square(100, 190)})
    plan = Planner(grid).plan("b", "walk", start="a")
    t_cross = 12.0
    cross = plan.trajectory.position(t_cross)[:2]
    ball = ConstantVelocityObstacle(cross - np.array([0.0, 1.5]), (0.0, 0.5), radius=0.3, t0=t_cross - 3.0)
    body = plan.costmap.body_radius
    assert predict_collision(plan.trajectory, [ball], t_now=t_cross - 3.0) is None  # more than 1.5 s ahead
    t_now = t_cross - 1.2
    assert replan(plan, [], t_now=t_now) is None
    hit = predict_collision(plan.trajectory, [ball], t_now=t_now)
    assert hit is not None and hit.time <= t_now + 1.5
    result = replan(plan, [ball], t_now=t_now)
    assert result is not None
    new = result.trajectory
    # the same past, the same present
    assert np.allclose(new.position(t_now - 2.0), plan.trajectory.position(t_now - 2.0))
    assert np.allclose(new.position(t_now), plan.trajectory.position(t_now))
    assert result.plan.speed.v[0] == pytest.approx(float(plan.trajectory.sample(t_now)[1]), abs=1e-6)
    # clear of the ball at every time from now until the ball is far away
    times = np.linspace(t_now, t_now + 8.0, 1601)
    gap = np.linalg.norm(new.position(times)[:, :2] - ball.position(times), axis=1)
    assert gap.min() >= ball.radius + body
    # and clear of the predicted position that triggered the replan
    assert np.linalg.norm(result.plan.path.xy - hit.obstacle_xy, axis=1).min() >= ball.radius + body - 0.1
    assert predict_collision(new, [ball], t_now=t_now) is None
    # it still arrives
    assert np.linalg.norm(new.xyz[-1, :2] - plan.trajectory.xyz[-1, :2]) < 0.5


def test_replanning_sidesteps_a_ball_coming_head_on():
    grid = flat_grid(200, 200, landmarks={"a": square(100, 10), "b": square(100, 190)})
    plan = Planner(grid).plan("b", "walk", start="a")
    t_now = 6.0
    here = plan.trajectory.position(t_now)[:2]
    # rolling straight down the path at the character: its future positions cover the current cell
    ball = ConstantVelocityObstacle(here + np.array([4.0, 0.0]), (-1.0, 0.0), radius=0.3, t0=t_now)
    assert predict_collision(plan.trajectory, [ball], t_now=t_now) is not None
    result = replan(plan, [ball], t_now=t_now)
    new = result.trajectory
    times = np.linspace(t_now, t_now + 8.0, 1601)
    gap = np.linalg.norm(new.position(times)[:, :2] - ball.position(times), axis=1)
    assert gap.min() >= ball.radius + plan.costmap.body_radius
    assert np.linalg.norm(new.xyz[-1, :2] - plan.trajectory.xyz[-1, :2]) < 0.2  # ends where the old path ended


def test_waiting_lets_a_ball_cross_a_corridor_with_no_detour():
    # A corridor 1 m wide: the ball (0.3 m + 0.25 m body clearance) fills it, so no detour exists.
    walls = np.ones((40, 200), bool)
    walls[15:25] = False
    grid = PlanningGrid(np.zeros((40, 200)), walls, np.full((40, 200), np.inf), 0.1, (0.0, 0.0),
                        {"a": square(20, 10), "b": square(20, 190)})
    plan = Planner(grid).plan("b", "walk", start="a")
    t_cross = 8.0
    cross = plan.trajectory.position(t_cross)[:2]
    ball = ConstantVelocityObstacle(cross - np.array([0.0, 0.5]), (0.0, 0.2), radius=0.3, t0=t_cross - 2.5)
    t_now = t_cross - 1.4
    assert predict_collision(plan.trajectory, [ball], t_now=t_now) is not None
    with pytest.raises(PlanningError):
        replan(plan, [ball], t_now=t_now)
    result = wait_for_obstacles(plan, [ball], t_now=t_now)
    assert result is not None and result.rounds == 0 and 0.0 < result.waited <= 8.0
    new = result.trajectory
    assert np.allclose(new.position(t_now), plan.trajectory.position(t_now))
    # never within contact distance of the ball, from now until long after it has passed
    times = np.linspace(t_now, new.end_time + 2.0, 4001)
    gap = np.linalg.norm(new.position(times)[:, :2] - ball.position(times), axis=1)
    assert gap.min() >= ball.radius + plan.costmap.body_radius
    # the same path, only later: it still arrives, standing still at the stop for the wait
    np.testing.assert_allclose(new.xyz[-1], plan.trajectory.xyz[-1])
    assert new.end_time > plan.trajectory.end_time + result.waited
    stop = np.flatnonzero((np.diff(new.s) == 0.0) & (np.diff(new.t) > 0.0))
    assert len(stop) == 1 and np.diff(new.t)[stop[0]] == pytest.approx(result.waited)
    assert new.v[stop[0]] == 0.0 and new.v[stop[0] + 1] == 0.0
    # speeds only drop below the old profile; deceleration within the emergency bound, acceleration within a_max
    ds = np.diff(new.s)
    moving = ds > 1e-9
    accel = (new.v[1:] ** 2 - new.v[:-1] ** 2)[moving] / (2 * ds[moving])
    assert accel.min() >= -1.0 - 1e-9 and accel.max() <= plan.settings.a_max + 1e-9
    later = new.t >= t_now
    v_old = np.sqrt(np.interp(new.s[later], plan.trajectory.s, plan.trajectory.v ** 2))  # v^2 is linear in s
    assert np.all(new.v[later] <= v_old + 1e-9)
    assert wait_for_obstacles(plan, [], t_now=t_now) is None
    # a ball that comes down the corridor at the character cannot be waited out
    head_on = ConstantVelocityObstacle(cross, (-1.0, 0.0), radius=0.3, t0=t_now)
    with pytest.raises(PlanningError, match="does not clear"):
        wait_for_obstacles(plan, [head_on], t_now=t_now, max_wait=2.0)


def test_closed_loop_obstacle():
    loop = ClosedLoopObstacle([(0, 0), (4, 0), (4, 2), (0, 2)], speed=2.0, radius=0.4)
    assert np.allclose(loop.position(0.0), (0, 0)) and np.allclose(loop.position(1.0), (2, 0))
    assert np.allclose(loop.position(2.5), (4, 1)) and np.allclose(loop.position(6.0), loop.position(0.0))
    assert loop.position(np.array([0.0, 1.0])).shape == (2, 2)


# ------------------------------------------------------------------------------------ routes
def test_route_from_instructions():
    grid = door_scene(0.6, second_door=True)
    grid.landmarks["swing"] = square(90, 90)
    plans = Planner(grid).route("Run to the b, then crawl from the b to the a. Walk to the swing",
                                start=(2.05, 5.05))
    assert [p.segment.locomotion for p in plans] == ["run", "crawl", "walk"]
    assert np.allclose(plans[0].trajectory.xyz[0, :2], (2.05, 5.05))
    for prev, nxt in itertools.pairwise(plans):
        assert np.allclose(prev.end_xy, nxt.path.xy[0])
        assert nxt.trajectory.start_time == pytest.approx(prev.trajectory.end_time)
    assert plans[1].path.head.max() == pytest.approx(0.4)
    for plan in plans:
        assert plan.speed.v.max() <= plan.locomotion.speed_max + 1e-6 and plan.speed.v[-1] == 0.0
    with pytest.raises(InstructionError, match="start"):
        Planner(grid).route("walk to the b")


# ------------------------------------------------------------------------------------ bad inputs
OFF_GRID = r"target cells must lie in rows 0\.\.19 and columns 0\.\.19 of the grid"


@pytest.mark.parametrize(("target", "message"), [
    (np.array([[-1, -1]]), OFF_GRID + r"; 1 of 1 do not, e\.g\. \(-1, -1\)"),  # used to wrap to the far corner
    (np.array([[100, 100]]), OFF_GRID + r"; 1 of 1 do not, e\.g\. \(100, 100\)"),  # used to be an IndexError
    (np.array([[5, 5], [5, 20]]), OFF_GRID + r"; 1 of 2 do not, e\.g\. \(5, 20\)"),
    (np.array([[5.0, 1e300]]), OFF_GRID),
    (np.zeros((0, 2), np.int64), "target must hold at least one"),  # used to be a numpy reduction error
    ([], "target must hold at least one"),
    (np.array([[2.5, 3.0]]), "target must be integer"),
    (np.array([[np.nan, 3.0]]), "target must be integer"),
    (np.array([["a", "b"]]), "target must be integer"),
    (np.array([1, 2, 3]), r"target must be \(i, j\) grid cells"),
])
def test_target_cells_are_checked_against_the_grid(target, message):
    grid = flat_grid(20, 20)
    cm = build_costmap(grid)
    with pytest.raises(ValueError, match=message):
        astar(cm, (2, 2), target)
    with pytest.raises(ValueError, match=message):
        plan_path(cm, (0.25, 0.25), target)
    grid.landmarks["bad"] = target  # set after the grid's own check: the planner checks it again
    with pytest.raises(ValueError, match=message):
        Planner(grid).plan("bad", start=(0.25, 0.25))


def test_cells_on_the_grid_edge_and_one_cell_pairs_are_accepted():
    cm = build_costmap(flat_grid(20, 20))
    assert astar(cm, (0, 0), np.array([[19, 19]])).cells[-1].tolist() == [19, 19]
    assert astar(cm, np.array([0, 0]), (19, 0)).cells[-1].tolist() == [19, 0]
    assert astar(cm, (0, 0), np.array([[3.0, 4.0]])).cells[-1].tolist() == [3, 4]
    with pytest.raises(ValueError, match=r"start cells must lie in rows 0\.\.19"):
        astar(cm, (-1, 0), np.array([[5, 5]]))
    with pytest.raises(ValueError, match="start must be one"):
        astar(cm, np.array([[0, 0], [1, 1]]), np.array([[5, 5]]))
    with pytest.raises(ValueError, match="extra_blocked must be a bool array of the grid's shape"):
        astar(cm, (0, 0), np.array([[5, 5]]), extra_blocked=np.zeros((3, 3), bool))


@pytest.mark.parametrize("reach", [math.nan, math.inf, -0.1, "far"])
def test_reach_must_be_a_finite_distance(reach):
    cm = build_costmap(flat_grid(20, 20))
    message = r"reach must be a number in \[0.0, inf\)"
    with pytest.raises(ValueError, match=message):
        astar(cm, (2, 2), np.array([[10, 10]]), reach=reach)
    with pytest.raises(ValueError, match=message):
        PlannerSettings(reach=reach)


@pytest.mark.parametrize(("change", "message"), [
    ({"cell_size": math.inf}, r"cell_size must be a number in \(0.0, inf\), got inf"),
    ({"cell_size": math.nan}, r"cell_size must be a number in \(0.0, inf\), got nan"),
    ({"cell_size": 0.0}, r"cell_size must be a number in \(0.0, inf\)"),
    ({"origin": (math.nan, 0.0)}, r"origin must be two finite numbers"),
    ({"origin": (0.0, 0.0, 0.0)}, r"origin must be two finite numbers"),
])
def test_grid_keywords_are_checked(change, message):
    h = w = 6
    kwargs = {"heights": np.zeros((h, w)), "blocked": np.zeros((h, w), bool), "ceiling": np.full((h, w), np.inf),
              "cell_size": 0.1}
    with pytest.raises(ValueError, match=message):
        PlanningGrid(**{**kwargs, **change})


@pytest.mark.parametrize(("array", "value", "message"), [
    ("ceiling", math.nan, (r"ceiling must hold heights \(m\) or inf \(open sky\); 1 cells do not, e\.g\. "
                           r"cell \(3, 4\) holds nan")),
    ("ceiling", -math.inf, r"ceiling must hold heights \(m\) or inf \(open sky\)"),
    ("heights", math.inf, r"heights must hold finite heights \(m\); 1 cells do not, e\.g\. cell \(3, 4\) holds inf"),
    ("heights", math.nan, r"heights must hold finite heights"),
])
def test_non_finite_maps_are_rejected_not_misdiagnosed(array, value, message):
    values = np.zeros((20, 20)) if array == "heights" else np.full((20, 20), np.inf)
    values[3, 4] = value
    maps = {"heights": np.zeros((20, 20)), "blocked": np.zeros((20, 20), bool), "ceiling": np.full((20, 20), np.inf)}
    with pytest.raises(ValueError, match=message):
        PlanningGrid(**{**maps, array: values}, cell_size=0.1)
    # edited in place after the grid was built: the costmap checks again (a NaN ceiling used
    # to come back as PlanningError "ceiling too low")
    grid = flat_grid(20, 20, landmarks={"a": square(2, 2), "b": square(15, 15)})
    getattr(grid, array)[3, 4] = value
    with pytest.raises(ValueError, match=message):
        Planner(grid).plan("b", start="a")
    grid = flat_grid(20, 20)
    grid.cell_size = math.inf
    with pytest.raises(ValueError, match="cell_size"):
        build_costmap(grid)
    with pytest.raises(TypeError, match="grid must be a PlanningGrid"):
        build_costmap("grid")


def test_landmarks_and_start_points_are_checked():
    with pytest.raises(ValueError, match=r"landmark 'x' cells must lie in rows 0\.\.5 and columns 0\.\.5"):
        flat_grid(6, 6, landmarks={"x": np.array([[-1, 2]])})
    with pytest.raises(ValueError, match="landmark 'x' must hold at least one"):
        flat_grid(6, 6, landmarks={"x": np.zeros((0, 2))})
    grid = flat_grid(20, 20, landmarks={"b": square(15, 15)})
    cm = build_costmap(grid)
    on_grid = r"must be a point \(x, y\) on the grid, x in \[0.0, 2.0\) and y in \[0.0, 2.0\) m"
    for start in ((math.nan, 0.5), (2.0, 0.5), (-0.01, 0.5), (0.5, 0.5, 0.5), "here"):
        with pytest.raises(ValueError, match="start_xy " + on_grid):
            plan_path(cm, start, grid.landmarks["b"])
    for start in ((math.nan, 0.5), (0.5, math.inf), (1.0,)):
        with pytest.raises(ValueError, match="start " + on_grid):
            Planner(grid).plan("b", start=start)
        with pytest.raises(ValueError, match="start " + on_grid):
            Planner(grid).route("walk to the b", start=start)
    with pytest.raises(ValueError, match=r"t0 must be a number in \(-inf, inf\)"):
        plan_path(cm, (0.25, 0.25), grid.landmarks["b"], t0=math.nan)


@pytest.mark.parametrize(("keyword", "value"), [("head_radius", math.inf), ("slope_window", math.inf),
                                                ("head_smoothing", math.inf), ("curvature_scale", math.nan)])
def test_window_widths_must_be_finite(keyword, value):
    # each becomes a window width in cells: inf used to end in an OverflowError
    with pytest.raises(ValueError, match=rf"{keyword} must be a number in \[0.0, inf\)"):
        PlannerSettings(**{keyword: value})
    if keyword in ("head_radius", "slope_window"):
        with pytest.raises(ValueError, match=keyword):
            build_costmap(flat_grid(5, 5), **{keyword: value})


def test_collision_prediction_needs_a_finite_time():
    trajectory = Trajectory.from_profile(np.array([0.0, 1.0]), np.zeros((2, 3)), np.array([1.0, 1.0]))
    ball = ConstantVelocityObstacle((0.5, 0.0), (0.0, 0.0))
    assert predict_collision(trajectory, [ball], t_now=0.0) is not None
    with pytest.raises(ValueError, match=r"t_now must be a number in \(-inf, inf\), got nan"):
        predict_collision(trajectory, [ball], t_now=math.nan)  # used to predict no collision at all


# ------------------------------------------------------------------------------------ degenerate routes
def test_a_leg_to_the_landmark_it_starts_at_has_zero_length():
    """Starting on a cell of the target landmark, the leg is the start point alone, timed 0 s. It used to be a
    step of a few cm to the cell's centre, sampled at its two ends, both at rest: timed at a floor speed of
    1e-12 m/s it took 7e10 s, and the env's path sampler asked for 5 TiB."""
    grid = flat_grid(40, 40, landmarks={"a": square(20, 20, 2), "b": square(35, 35)})
    planner = Planner(grid)
    for start in ((2.02, 1.98), (2.05, 2.05), (1.81, 2.19)):   # off a cell's centre, on it, at the edge
        plans = planner.route("walk to the a", start=start)
        trajectory = plans[0].trajectory
        assert len(trajectory.t) == 1 and trajectory.duration == 0.0 and plans[0].length == 0.0
        np.testing.assert_array_equal(trajectory.xyz[0, :2], start)
        assert len(plans[0].waypoints(dt=0.1).t) == 1
    # a zero-length leg between two others: times and positions run on
    plans = planner.route("crawl to the a, then walk to the a, then run to the b", start=(2.02, 1.98))
    assert [p.trajectory.duration for p in plans[:2]] == [0.0, 0.0] and 0.0 < plans[2].trajectory.duration < 60.0
    assert plans[2].trajectory.start_time == 0.0 and np.allclose(plans[2].start_xy, (2.02, 1.98))


def test_a_path_sampled_at_its_two_ends_at_rest_is_timed():
    """Two samples 3.5 cm apart, both at rest (a detour of a few cm from a standstill): a midpoint joins them at
    the gentler acceleration, rest to rest in 2 sqrt(d / a) (it used to take 7e10 s); ``Trajectory.from_profile``
    refuses two samples apart at rest."""
    from stairenv.planning.astar import AStarResult
    from stairenv.planning.planner import timed_plan
    from stairenv.planning.refine import profile_along

    grid = flat_grid(20, 20)
    costmap = build_costmap(grid, get_locomotion("walk"))
    path = profile_along(costmap, np.array([[1.025, 0.975], [1.05, 1.0]]))
    assert len(path.s) == 2
    search = AStarResult(np.array([[9, 10], [10, 10]]), 0.1, 1, costmap.passable, np.array([[10, 10]]))
    settings = PlannerSettings()
    plan = timed_plan(costmap, search, path, np.array([[10, 10]]), settings, 0.0, 0.0, 0.0, None, None)
    gentle = min(settings.a_max, -settings.a_min)
    assert plan.trajectory.duration == pytest.approx(2.0 * math.sqrt(path.s[-1] / gentle))
    np.testing.assert_allclose(plan.trajectory.xyz[[0, -1], :2], path.xy)
    with pytest.raises(ValueError, match=r"v\[0\] and v\[1\] are both 0 over 0\.0353553 m"):
        Trajectory.from_profile(path.s, np.zeros((2, 3)), np.zeros(2))


@pytest.mark.parametrize("case", ["waypoints dt", "prediction dt", "replan sweep", "wait step", "refiner ds"])
def test_samplers_refuse_absurd_sample_counts(case):
    """A step near zero (or a span near infinity) is refused with a ValueError naming it before anything is
    allocated (each used to ask for terabytes)."""
    grid = flat_grid(40, 40, landmarks={"a": square(5, 5), "b": square(35, 35)})
    plan = Planner(grid).plan("b", "walk", start="a")
    ball = ConstantVelocityObstacle((0.9, 0.9), (0.0, 0.0))   # on the path, met within the horizon
    assert predict_collision(plan.trajectory, [ball], t_now=0.0) is not None
    call, message = {
        "waypoints dt": (lambda: timed_waypoints(plan.trajectory, dt=1e-13), "the waypoints' time span"),
        "prediction dt": (lambda: predict_collision(plan.trajectory, [ball], t_now=0.0, dt=1e-13), "horizon"),
        "replan sweep": (lambda: replan(plan, [ball], t_now=0.0, sweep=1e9, dt=1e-4), "sweep"),
        "wait step": (lambda: wait_for_obstacles(plan, [ball], t_now=0.0, max_wait=1e9, wait_step=1e-5),
                      "max_wait"),
        "refiner ds": (lambda: Planner(grid, PlannerSettings(ds=1e-13)).plan("b", "walk", start="a"),
                       "the path's length"),
    }[case]
    with pytest.raises(ValueError, match=rf"^{re.escape(message)}.* samples; at most 1,000,000 are built"):
        call()


# ------------------------------------------------------------------------------------ quoted text
def test_messages_quote_at_most_80_characters_of_the_text():
    """A megabyte of instruction text gave a message of two megabytes (the text and its clause, each in full):
    every message quotes at most 80 characters, with an ellipsis and the whole length (here 256 KiB)."""
    tail = "x" * 2 ** 18
    cases = [
        (lambda: parse_instructions(f"Walk to the {tail}", LANDMARKS), "unknown landmark"),
        (lambda: parse_instructions(f"Walk {tail} to the car", LANDMARKS), "unknown locomotion verb"),
        (lambda: parse_instructions(f"walk the {tail}", LANDMARKS), "cannot read"),
        (lambda: parse_instructions("run crawling " + "please " * 2 ** 15 + "to the car", LANDMARKS), "ambiguous"),
        (lambda: parse_instructions("." * 2 ** 18, LANDMARKS), "no instruction found"),
        (lambda: Planner(flat_grid(5, 5)).landmark(tail), "unknown landmark"),
        (lambda: Planner(flat_grid(5, 5, landmarks={"a": square(2, 2)})).route(
            [Segment(None, tail, "walk")]), "has no source"),
        (lambda: get_locomotion(tail), "locomotion must be one of"),
        (lambda: PlannerSettings(ds=tail), "ds must be a number"),
    ]
    for call, start in cases:
        with pytest.raises(ValueError) as err:
            call()
        message = str(err.value)
        assert start in message and len(message) < 1200, (start, len(message))
        if "(1,0" in message or "characters)" in message:
            assert re.search(r"'\.\.\. \([\d,]+ characters\)", message)
    with pytest.raises(InstructionError, match=r"^unknown landmark 'x{80}'\.\.\. \(262,144 characters\) in "
                                               r"'walk to the x{68}'\.\.\. \(262,156 characters\); known landmarks"):
        parse_instructions(f"Walk to the {tail}", LANDMARKS)
    # short text is quoted whole, as before
    with pytest.raises(InstructionError, match=r"^unknown landmark 'lake' in 'run from the tree to the lake'; "):
        parse_instructions("Run from the tree to the lake", LANDMARKS)


def test_a_long_run_of_white_space_is_parsed_in_linear_time():
    """The clause splitter's patterns start with \\s*: on a run of n spaces they tried every suffix of it (6,000
    took ~5 s, 16,000 40 s, a megabyte would take days). White space is read as one space first (~1 ms here)."""
    import time

    start = time.perf_counter()
    assert parse_instructions("walk" + " \t\n" * 2000 + "to the car", LANDMARKS) == [Segment(None, "car", "walk")]
    assert time.perf_counter() - start < 1.0
