"""PlaMo's planner end to end: instruction -> A* -> refiner -> speed QP -> timed waypoints.

    planner = Planner(grid)                       # costmaps are built once per locomotion
    plans = planner.route("Run to the car, then crawl from the car to the swing", start=(1.0, 2.0))
    waypoints = plans[0].waypoints(dt=0.5)        # (t, x y z_head, v) every 0.5 s

Each stage is a function of its own module (``astar``, ``refine``, ``speed``,
``waypoints``); ``plan_path`` chains them for one start and one set of target cells.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np

from .astar import AStarResult, astar, goal_cells
from .costmap import Costmap, build_costmap
from .errors import InstructionError, check_cells, check_range, quote
from .grid import PlanningGrid
from .instructions import Segment, parse_instructions
from .locomotion import Locomotion, get_locomotion
from .refine import RefinedPath, refine_path
from .speed import A_MAX, A_MIN, SpeedProfile, speed_limits, speed_profile
from .waypoints import Trajectory, Waypoints, bridge_stops, timed_waypoints


@dataclass(frozen=True)
class PlannerSettings:
    """Every planner keyword in one place (defaults: PlaMo's numbers where it gives them).

    Costmap (``build_costmap``): body_radius, ceiling_margin, head_radius, max_slope, max_step,
    slope_window, height_cost, slope_preference. A* (``astar``): reach, max_expansions.
    Refiner (``refine_path``): ds, smoothing, comfort, curvature_scale, head_slope, head_smoothing. Speed
    (``speed_limits``, ``speed_profile``): a_max, a_min, a_lat, uphill_gain, downhill_gain,
    min_speed_fraction, knot_spacing, max_knots.
    """

    body_radius: float = 0.25
    ceiling_margin: float = 0.1
    head_radius: float = 0.15
    max_slope: float = 1.0
    max_step: float = 0.3
    slope_window: float = 0.5
    height_cost: float = 1.0
    slope_preference: float = 0.0
    reach: float = 0.5
    max_expansions: int | None = None
    ds: float = 0.05
    smoothing: float = 0.75
    comfort: float = 0.25
    curvature_scale: float = 0.25
    head_slope: float = 0.5
    head_smoothing: float = 0.5
    a_max: float = A_MAX
    a_min: float = A_MIN
    a_lat: float = 1.0
    uphill_gain: float = 1.0
    downhill_gain: float = 0.5
    min_speed_fraction: float = 0.3
    knot_spacing: float = 0.5
    max_knots: int = 400

    def __post_init__(self) -> None:
        for name in ("body_radius", "ceiling_margin", "max_slope", "max_step"):
            check_range(name, getattr(self, name), 0.0)
        # finite: these become cell counts, window widths or cost factors
        for name in ("head_radius", "slope_window", "reach", "head_smoothing", "curvature_scale",
                     "height_cost", "smoothing", "comfort", "uphill_gain", "downhill_gain"):
            check_range(name, getattr(self, name), 0.0, math.inf, high_open=True)
        check_range("slope_preference", self.slope_preference, 0.0, 50.0)
        check_range("min_speed_fraction", self.min_speed_fraction, 0.0, 1.0, low_open=True)
        check_range("ds", self.ds, 0.0, math.inf, low_open=True, high_open=True)
        check_range("head_slope", self.head_slope, 0.0, math.inf, low_open=True)
        check_range("a_max", self.a_max, 0.0, math.inf, low_open=True, high_open=True)
        check_range("a_min", self.a_min, -math.inf, 0.0, low_open=True, high_open=True)
        check_range("a_lat", self.a_lat, 0.0, math.inf, low_open=True)
        check_range("knot_spacing", self.knot_spacing, 0.0, math.inf, low_open=True, high_open=True)
        if int(self.max_knots) < 2:
            raise ValueError(f"max_knots must be an integer >= 2, got {self.max_knots!r}")
        if self.max_expansions is not None and int(self.max_expansions) < 1:
            raise ValueError(f"max_expansions must be None or an integer >= 1, got {self.max_expansions!r}")

    def costmap_kwargs(self) -> dict:
        keys = ("body_radius", "ceiling_margin", "head_radius", "max_slope", "max_step", "slope_window",
                "height_cost", "slope_preference")
        d = asdict(self)
        return {k: d[k] for k in keys}


@dataclass(frozen=True, eq=False)
class Plan:
    """One planned segment: the A* search, the refined path, the speeds and the timed trajectory."""

    locomotion: Locomotion
    costmap: Costmap
    search: AStarResult
    path: RefinedPath
    speed: SpeedProfile
    trajectory: Trajectory
    target: np.ndarray                 # (K, 2) the target landmark's cells
    settings: PlannerSettings
    segment: Segment | None = None
    extra_blocked: np.ndarray | None = None   # dynamic-obstacle cells avoided (replanning)

    @property
    def length(self) -> float:
        return self.path.length

    @property
    def travel_time(self) -> float:
        return self.trajectory.duration

    @property
    def start_xy(self) -> np.ndarray:
        return self.path.xy[0].copy()

    @property
    def end_xy(self) -> np.ndarray:
        return self.path.xy[-1].copy()

    def waypoints(self, dt: float = 0.1) -> Waypoints:
        return timed_waypoints(self.trajectory, dt=dt)


def plan_path(
    costmap: Costmap,
    start_xy: Sequence[float] | np.ndarray,
    target: np.ndarray,
    *,
    settings: PlannerSettings = PlannerSettings(),
    v_start: float = 0.0,
    v_end: float = 0.0,
    t0: float = 0.0,
    extra_blocked: np.ndarray | None = None,
    segment: Segment | None = None,
) -> Plan:
    """Plan from the world point ``start_xy`` to any of the ``target`` cells ((K, 2)).

    v_start, v_end (m/s): speeds at the ends; t0 (s, finite): the trajectory's start time;
    extra_blocked: (H, W) bool cells to avoid as well (dynamic obstacles).
    Raises ValueError for a start off the grid or target cells outside it (see ``astar``), and
    ``PlanningError`` (unreachable, see ``astar``; or no speed profile).
    """
    grid = costmap.grid
    start_xy = _point_on_grid("start_xy", start_xy, grid)
    start = tuple(int(x) for x in grid.cell_of(start_xy))
    target = check_cells("target", target, grid.shape)
    t0 = check_range("t0", t0, -math.inf, math.inf, low_open=True, high_open=True)
    search = astar(costmap, start, target, reach=settings.reach, extra_blocked=extra_blocked,
                   max_expansions=settings.max_expansions)
    path = refine_path(costmap, search.cells, passable=search.passable, start_xy=start_xy, ds=settings.ds,
                       smoothing=settings.smoothing, comfort=settings.comfort, head_slope=settings.head_slope,
                       head_smoothing=settings.head_smoothing, curvature_scale=settings.curvature_scale)
    return timed_plan(costmap, search, path, target, settings, v_start, v_end, t0, extra_blocked, segment)


def _point_on_grid(name: str, xy: Sequence[float] | np.ndarray, grid: PlanningGrid) -> np.ndarray:
    """``xy`` as a finite world point (2,) over the grid, else ValueError naming ``name`` and the grid's extent."""
    try:
        point = np.asarray(xy, dtype=np.float64).ravel()
    except (TypeError, ValueError):
        point = np.empty(0)
    if point.shape == (2,) and np.isfinite(point).all():
        i, j = grid.cell_of(point)
        if 0 <= i < grid.shape[0] and 0 <= j < grid.shape[1]:
            return point
    x0, y0 = grid.origin
    x1, y1 = x0 + grid.shape[1] * grid.cell_size, y0 + grid.shape[0] * grid.cell_size
    raise ValueError(f"{name} must be a point (x, y) on the grid, x in [{x0}, {x1}) and y in [{y0}, {y1}) m, "
                     f"got {quote(xy)}")


def timed_plan(costmap, search, path, target, settings, v_start, v_end, t0, extra_blocked, segment,
                emergency_brake: float | None = None) -> Plan:
    """The speed QP along ``path`` and the timed plan. ``emergency_brake`` (m/s^2, < 0; replanning
    only): speeds on the braking curve from ``v_start`` at that rate are allowed even where the
    path's curvature or slope bound is lower, so a swerve that starts at speed stays feasible."""
    loc = costmap.locomotion
    if len(path.s) < 2:
        speed = SpeedProfile(path.s, np.array([v_start]), np.array([loc.speed_max]), path.s.copy(),
                             np.array([v_start ** 2]), 0, "trivial")
    else:
        v_upper = speed_limits(path.s, path.curvature, path.ground, loc.speed_max, a_lat=settings.a_lat,
                               uphill_gain=settings.uphill_gain, downhill_gain=settings.downhill_gain,
                               min_speed_fraction=settings.min_speed_fraction)
        if emergency_brake is not None:
            # the envelope of braking at 80 % of the rate, two knots late: the QP bounds each knot by
            # the lowest bound one knot either side, and keeps slack at the full rate
            knot = max(settings.knot_spacing, float(path.s[-1] - path.s[0]) / max(settings.max_knots - 1, 1))
            late = np.maximum(path.s - path.s[0] - 2.0 * knot, 0.0)
            braking = np.sqrt(np.maximum(v_start * v_start + 1.6 * emergency_brake * late, 0.0))
            v_upper = np.maximum(v_upper, braking)
        speed = speed_profile(path.s, v_upper, a_max=settings.a_max, a_min=settings.a_min, v_start=v_start,
                              v_end=v_end, knot_spacing=settings.knot_spacing, max_knots=settings.max_knots)
    xyz = np.column_stack((path.xy, path.z_head))
    # A path shorter than its sample spacing has samples at its ends only, both at rest (the speed QP's
    # knot between them is not a sample): a midpoint joins them, reached at the gentler of the accelerations.
    s, xyz, v = bridge_stops(path.s, xyz, speed.v, min(settings.a_max, -settings.a_min))
    trajectory = Trajectory.from_profile(s, xyz, v, t0=t0)
    return Plan(loc, costmap, search, path, speed, trajectory, np.asarray(target), settings, segment, extra_blocked)


class Planner:
    """Plans on one grid; keeps one costmap per locomotion (they share every map but ``tall``)."""

    def __init__(self, grid: PlanningGrid, settings: PlannerSettings = PlannerSettings()) -> None:
        if not isinstance(grid, PlanningGrid):
            raise TypeError(f"grid must be a PlanningGrid, got {type(grid).__name__}")
        self.grid = grid
        self.settings = settings
        self._costmaps: dict[str, Costmap] = {}

    def costmap(self, locomotion: str | Locomotion) -> Costmap:
        loc = get_locomotion(locomotion)
        if loc.name not in self._costmaps:
            if self._costmaps:
                self._costmaps[loc.name] = next(iter(self._costmaps.values())).with_locomotion(loc)
            else:
                self._costmaps[loc.name] = build_costmap(self.grid, loc, **self.settings.costmap_kwargs())
        return self._costmaps[loc.name]

    def landmark(self, name: str) -> np.ndarray:
        if name not in self.grid.landmarks:
            raise InstructionError(f"unknown landmark {quote(name)}; known landmarks are "
                                   f"{sorted(self.grid.landmarks)}")
        return self.grid.landmarks[name]

    def landmark_point(self, name: str, locomotion: str | Locomotion = "walk",
                       near: np.ndarray | None = None) -> np.ndarray:
        """A passable point of a landmark: the cell nearest ``near`` (default: the landmark's centroid)."""
        cells = self.landmark(name)
        cm = self.costmap(locomotion)
        ok = goal_cells(cm.passable, cells, self.settings.reach / self.grid.cell_size)
        if len(ok) == 0:
            ok = cells
        xy = self.grid.cell_center(ok[:, 0], ok[:, 1])
        ref = self.grid.cell_center(*cells.mean(axis=0)) if near is None else np.asarray(near, dtype=np.float64)
        return xy[np.argmin(np.sum((xy - ref) ** 2, axis=1))]

    def plan(self, target: str, locomotion: str | Locomotion = "walk", *,
             start: str | Sequence[float] | np.ndarray, v_start: float = 0.0, v_end: float = 0.0,
             t0: float = 0.0) -> Plan:
        """One segment: to the landmark ``target`` from ``start`` (a landmark name or a world point)."""
        loc = get_locomotion(locomotion)
        if isinstance(start, str):
            start_xy = self.landmark_point(start, loc)
        else:
            start_xy = _point_on_grid("start", start, self.grid)
        segment = Segment(start if isinstance(start, str) else None, target, loc.name)
        return plan_path(self.costmap(loc), start_xy, self.landmark(target), settings=self.settings,
                         v_start=v_start, v_end=v_end, t0=t0, segment=segment)

    def route(self, instructions: str | Sequence[str] | Sequence[Segment], *,
              start: Sequence[float] | np.ndarray | None = None) -> list[Plan]:
        """Plans for every segment of ``instructions`` (text, sentences or ``Segment`` objects).

        The first segment without a source starts at ``start`` (the current position); each
        later segment starts where the previous one arrived (at its source landmark's
        nearest point if that is another landmark). Times run on from segment to segment.
        """
        if isinstance(instructions, str) or (len(instructions) and isinstance(instructions[0], str)):
            segments = parse_instructions(instructions, self.grid.landmarks)
        else:
            segments = list(instructions)
        plans: list[Plan] = []
        position = None if start is None else _point_on_grid("start", start, self.grid)
        t0 = 0.0
        for seg in segments:
            loc = get_locomotion(seg.locomotion)
            if plans and seg.source == plans[-1].segment.target:
                start_xy = plans[-1].end_xy
            elif seg.source is not None:
                start_xy = self.landmark_point(seg.source, loc, near=position)
            elif position is not None:
                start_xy = position
            else:
                raise InstructionError(f"{quote(seg)} has no source: pass start=(x, y), the current position")
            plan = plan_path(self.costmap(loc), start_xy, self.landmark(seg.target), settings=self.settings,
                             t0=t0, segment=seg)
            plans.append(plan)
            position = plan.end_xy
            t0 = plan.trajectory.end_time
        return plans
