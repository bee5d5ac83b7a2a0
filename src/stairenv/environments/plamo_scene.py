"""PlaMo in a scene: instructions are planned into a path online and the humanoid follows it to the last landmark."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from stairenv.environments.base import StepOutcome
# named here too, as before (they moved to the config)
from stairenv.environments.config import (  # noqa: F401
    MAX_TERRAIN_CELLS,
    SCENE_BYTES_PER_CELL,
    SCENE_KINDS,
    SPEED_PROFILES,
    check_instructions,
    check_landmark_room,
    scene_config,
)
from stairenv.environments.config import PlaMoSceneConfig, document_keywords, keyword_signature, resolve
from stairenv.environments.plamo import NUM_WAYPOINTS, WAYPOINT_SPACING, PlaMoEnv
from stairenv.humanoid import load_humanoid_spec
from stairenv.planning.errors import InstructionError, PlanningError, check_samples, quote
from stairenv.planning.planner import Plan, Planner, plan_path
from stairenv.planning.replan import predict_collision, replan, wait_for_obstacles
from stairenv.planning.waypoints import Trajectory
from stairenv.tasks import plamo as task
from stairenv.world.scenes import add_scene_to_spec, generate_scene, slalom_scene
from stairenv.world.terrain import clamped_bilinear_heights

LOCOMOTION_VERBS = {"crawl": "crawl", "crouch-walk": "crouch", "walk": "walk", "run": "run"}
PATH_DT = 0.1  # the followed path is sampled every 0.1 s


def random_instructions(landmarks: list[str], rng: np.random.Generator, segments: int = 2) -> tuple[str, str]:
    """A start landmark and instructions visiting ``segments`` other landmarks with random locomotions."""
    order = list(rng.permutation(landmarks))
    start, stops = order[0], order[1:segments + 1]
    verbs = [LOCOMOTION_VERBS[k] for k in rng.choice(["crouch-walk", "walk", "walk", "run"], size=len(stops))]
    parts = [f"{verbs[0].capitalize()} to the {stops[0]}"]
    parts += [f"{verb} from the {a} to the {b}" for verb, a, b in zip(verbs[1:], stops[:-1], stops[1:])]
    return start, ", then ".join(parts)


def path_from_trajectory(trajectory: Trajectory, ground_height, duration: float) -> task.PathSamples:
    """Sample a planned trajectory every PATH_DT seconds (held at the end) as the env's PathSamples.

    Raises ValueError, before anything is allocated, for a ``duration`` that is not a finite number >= 0 or
    would need over ``MAX_SAMPLES`` samples (27.8 hours), or a trajectory whose times are not finite."""
    count = check_samples("the path's duration", duration, PATH_DT)
    if not (np.all(np.isfinite(trajectory.t)) and len(trajectory.t)):
        raise ValueError("the trajectory's times must be finite numbers")
    times = trajectory.start_time + np.arange(count) * PATH_DT
    xyz, v, _ = trajectory.sample(times)
    step = np.diff(xyz, axis=0, append=xyz[-1:] + (xyz[-1:] - xyz[-2:-1] if len(xyz) > 1 else 0))
    moving = np.hypot(step[:, 0], step[:, 1]) > 1e-6
    yaw = np.where(moving, np.arctan2(step[:, 1], step[:, 0]), np.nan)
    yaw = _direction_while_still(yaw, moving)
    pitch = np.where(moving, np.arctan2(step[:, 2], np.maximum(np.hypot(step[:, 0], step[:, 1]), 1e-9)), 0.0)
    head = xyz[:, 2] - ground_height(xyz[:, :2])
    return task.PathSamples(xyz, head, v, yaw, pitch, PATH_DT)


@document_keywords(PlaMoSceneConfig)
class PlaMoSceneEnv(PlaMoEnv):
    r"""A generated scene (terrain patches, walls, low ceilings, a moving ball, 4 landmarks) and
    instructions such as "Walk to the tree, then crawl from the tree to the swing".

    A new scene (``stairenv.world.scenes.generate_scene``) is built every
    ``scene_resample_every`` resets and whenever ``reset`` gets a seed (so a seeded
    episode does not depend on the episodes before it; the slalom scene is built once).
    Each reset parses the instructions (random ones over the scene's landmarks if ``instructions`` is None),
    plans them with ``stairenv.planning.Planner`` (A*, refiner, speed QP) from a start
    landmark, and samples the timed head path. While the episode runs, every
    ``replan_every`` seconds the planner predicts collisions with the ball over
    ``replan_horizon`` seconds and replans around it. Observation and reward are
    PlaMo-v0's; the episode succeeds (``info["success"]``, terminated) when the head
    is within ``success_radius`` of the last landmark's centre after its planned
    arrival time. When no detour exists, the character stops on its path and waits for the
    ball to pass (``stairenv.planning.replan.wait_for_obstacles``). ``info`` also carries
    ``instructions``, ``replans`` (detours and waits), ``waits``, ``replan_failures`` and
    ``planned_time``.

    **Keywords** are checked at construction, as ``PlaMoEnv``'s (``instructions`` too: an unknown verb or
    landmark raises ``InstructionError``, a ``ValueError``, naming it). They are the fields of
    ``PlaMoSceneConfig`` (``stairenv.environments.config``: defaults and ranges live there);
    ``config=PlaMoSceneConfig(...)`` may be given instead (keywords beside it must agree with it), and
    ``env.unwrapped.config`` is the resolved config (its path follower's ``PlaMoConfig``:
    ``config.path_follower()``).

    **Memory bound**: the scene's height map (``size / cell_size + 1`` samples along x and y) may hold at
    most ``MAX_TERRAIN_CELLS`` = 2001^2 samples, e.g. 100 m x 100 m at 0.05 m; a scene costs ~175 bytes a
    sample, ~670 MB at the bound.

    {keyword table}
    """

    #: what a built env takes (``configure``, ``set_attr``): the episode's end bounds
    LIVE_KEYWORDS = frozenset(("success_radius", "max_xy_error"))
    STATE_ATTRIBUTES = frozenset(("scene",))    # the episode's scene (the keyword: what scenes to draw)

    def __init__(self, *, config: PlaMoSceneConfig | None = None, **keywords) -> None:
        # the keywords (signature below: PlaMoSceneConfig's fields) -> the one resolved, checked config,
        # checked before PlaMoEnv's constructor builds a model
        config = resolve(PlaMoSceneConfig, config, keywords)
        scene, planner = config.scene, config.planner
        self.instructions = planner.instructions
        self.scene_kind, self.scene_config, self.scene_resample_every = scene.kind, scene.config, scene.resample_every
        self.speed_profile, self.constant_speed = planner.speed_profile, planner.constant_speed
        self._resets = 0
        self.replan_horizon, self.replan_every = planner.replan_horizon, planner.replan_every
        self.success_radius = config.termination.success_radius
        super().__init__(config=config.path_follower())
        #: the resolved config (PlaMoEnv's constructor set its path follower's, ``config.path_follower()``)
        self.config = config
        self.scene = None

    # the keywords: PlaMoSceneConfig's fields, defaults included (``config=`` stays out of the signature)
    __init__.__signature__ = keyword_signature(PlaMoSceneConfig)

    @property
    def trajectory(self) -> Trajectory:
        """The episode's planned head trajectory (every segment's plan concatenated, replans included):
        positions ``xyz`` and speeds ``v`` over time. Set by ``reset``."""
        return self._trajectory

    def _build_initial_world(self, pd_gains: str, terrain_size: float, terrain_cell_size: float) -> None:
        """Nothing yet: the first ``reset`` builds the scene (its model); the time step is the humanoid's."""
        self._pd_gains = pd_gains
        self.dt = load_humanoid_spec(pd_gains).option.timestep * self.frame_skip
        self._terrain_slots = self._terrain_view = None    # the scene's (``_build_scene``)

    def ground_height(self, xy: np.ndarray) -> np.ndarray:
        """The scene's ground (``Scene.height_at``'s bilinear reading, compiled)."""
        xy = np.asarray(xy, dtype=np.float64)
        flat = np.ascontiguousarray(xy[..., :2].reshape(-1, 2))
        scene = self.scene
        out = clamped_bilinear_heights(scene.heights, scene.origin[0], scene.origin[1], scene.cell_size, flat,
                                       np.empty(flat.shape[0]))
        return out.reshape(xy.shape[:-1])

    def _terrain_samples(self, out: np.ndarray, root: np.ndarray, c: float, s: float,
                         head: np.ndarray) -> tuple[float, float]:
        """``PlaMoEnv``'s, compiled on the scene's height map."""
        scene = self.scene
        return task.write_grid_heightmap(out, scene.heights, scene.origin[0], scene.origin[1], scene.cell_size,
                                         root, c, s, self.heightmap_size, self.heightmap_extent, head)

    # --- episode ------------------------------------------------------------
    def _build_world(self, rng: np.random.Generator, options: dict[str, Any] | None) -> None:
        """The scene (kept between resets, see the class docstring) and the episode's planned route."""
        if self._seeded_reset:  # the resample count restarts: a seeded reset fixes every episode after it
            self._resets = 0
        if self.scene is None or (self.scene_kind == "random" and (
                self._seeded_reset or self._resets % self.scene_resample_every == 0)):
            self._build_scene(rng)
        self._resets += 1
        # Random instructions are redrawn if the planner finds them impossible in this scene;
        # the user's own instructions raise the PlanningError (it says why).
        for attempt in range(10):
            start_name, text = (None, self.instructions)
            if self.scene_kind == "slalom":
                start_name, text = "start", text or "Run to the goal"
            elif text is None:
                start_name, text = random_instructions(self.scene.landmark_names, rng)
            start_xy = (self._planner.landmark_point(start_name) if start_name is not None
                        else np.asarray(self.scene.landmark(self.scene.landmark_names[0]).center, dtype=float))
            try:
                self._plans: list[Plan] = self._planner.route(text, start=start_xy)
                _check_joined(self._plans)
                break
            except (PlanningError, InstructionError) as error:
                if self.instructions is not None:  # the user's own: say which keyword and scene
                    message = (f"instructions {quote(self.instructions)} cannot be planned in this episode's scene "
                               f"(landmarks {list(self.scene.landmark_names)}): {error}")
                    if isinstance(error, PlanningError):
                        raise PlanningError(error.reason, message) from None
                    raise InstructionError(message) from None
                if attempt == 9 or isinstance(error, InstructionError):  # drawn instructions: as before
                    raise
        if self.speed_profile == "constant":
            self._plans = _constant_speed(self._plans, self.constant_speed)
        self._trajectory = _concatenate([p.trajectory for p in self._plans])
        self.instructions_text = text
        self._replans = 0
        self._replan_failures = 0
        self._waits = 0
        self._refresh_path()
        goal = self.scene.landmark(self._plans[-1].segment.target)
        self._goal_xy = np.asarray(goal.center, dtype=float)
        # where the route starts: "from the swing ..." starts at the swing, not where a route without one would
        first = self._plans[0]
        self._start_xy = first.start_xy if first.segment.source is not None else np.asarray(start_xy, dtype=float)

    def _place_character(self, rng: np.random.Generator, options: dict[str, Any] | None) -> bool:
        """Standing at the route's start, facing along it; the scene's moving obstacles at time 0."""
        self._scene_handles.update(self.model, self.data, 0.0)
        self._focus_terrain(self._start_xy)
        self._place_at(self._start_xy, float(self.path.yaw[0]), None, self._floor_under(self._start_xy))
        return False

    def _new_goal(self, rng: np.random.Generator, options: dict[str, Any] | None) -> None:
        """Nothing: the route is planned with the world (the start depends on it)."""

    def _before_physics(self) -> None:
        """The terrain's tiles within reach (``PlaMoEnv``'s), move the obstacles; every ``replan_every`` seconds
        replan around them."""
        super()._before_physics()
        self._scene_handles.update(self.model, self.data, self.data.time)
        if self._steps % max(int(round(self.replan_every / self.dt)), 1) == 0:
            self._maybe_replan(self._steps * self.dt)

    #: world by world in a batched env: each world's scene is its own model (its bodies differ in number), so
    #: their states cannot be read as one batch
    BATCH_OUTCOMES = False

    @classmethod
    def _step_outcomes(cls, envs: list[PlaMoSceneEnv], state) -> list[StepOutcome]:
        """PlaMo's, and success: the head within ``success_radius`` of the last landmark after its
        planned arrival (never at the episode's start)."""
        outcomes = super()._step_outcomes(envs, state)
        for k, env in enumerate(envs):
            success = env._steps > 0 and env._steps * env.dt >= env._trajectory.end_time - 1e-9 and \
                float(np.hypot(*(env._head()[0][:2] - env._goal_xy))) < env.success_radius
            outcome = outcomes[k]
            outcomes[k] = outcome._replace(terminated=bool(outcome.terminated or success),
                                           results={**outcome.results, "success": bool(success)})
        return outcomes

    def _render_lines(self) -> tuple:
        """The followed path's next waypoints (PlaMo's, green) and the whole planned route (blue),
        one segment per ``PATH_DT`` at the height of the head target."""
        upcoming = super()._render_lines()
        if self.path is None:
            return upcoming
        times = np.arange(0.0, self._trajectory.end_time + PATH_DT, PATH_DT)
        points = self.path.at(times)
        route = tuple((a, b, (0.2, 0.4, 1.0, 0.8)) for a, b in zip(points[:-1], points[1:]))
        return upcoming + route

    def _info(self, results: dict[str, Any]) -> dict[str, Any]:
        return {**super()._info(results), "instructions": self.instructions_text, "replans": self._replans,
                "replan_failures": self._replan_failures, "waits": self._waits,
                "planned_time": self._trajectory.end_time}

    # --- pieces -------------------------------------------------------------
    def _build_scene(self, rng: np.random.Generator) -> None:
        """A new scene, compiled with the humanoid into a new model, and its planner."""
        self.close()
        try:
            self.scene = generate_scene(self.scene_config, rng) if self.scene_kind == "random" else slalom_scene()
        except RuntimeError as error:  # the generator gave up: name the keyword that asked for it
            config = self.scene_config
            raise RuntimeError(f"scene (the keyword: size {config.size}, num_landmarks {config.num_landmarks}, "
                               f"landmark_separation {config.landmark_separation:g}): {error}") from None
        spec = load_humanoid_spec(self._pd_gains)
        # the terrain as tiles (stairs boxes, a height field per slope or rough patch, near the character),
        # drawn whole only when it renders
        self._scene_handles = add_scene_to_spec(spec, self.scene, tiles=True, view=self.render_mode is not None)
        self._compile(spec)
        self._scene_handles.bind(self.model)
        self._terrain_slots, self._terrain_view = self._scene_handles.terrain_slots, self._scene_handles.terrain_view
        self._terrain_dirty = False    # a renderer made for this model uploads its height fields itself
        self._camera_distance, self._camera_elevation = 7.0, -30.0
        self._planner = Planner(self.scene.planning_grid(cell_size=0.1))

    def _refresh_path(self) -> None:
        duration = self._trajectory.end_time + NUM_WAYPOINTS * WAYPOINT_SPACING + 1.0
        self.path = path_from_trajectory(self._trajectory, self.ground_height, duration)
        self.episode_seconds = self._trajectory.end_time

    def _maybe_replan(self, t_now: float) -> None:
        obstacles = [_GroundTrack(o) for o in self.scene.dynamic_obstacles]
        if not obstacles or predict_collision(self._trajectory, obstacles, t_now=t_now,
                                              horizon=self.replan_horizon) is None:
            return
        # Replan the segment being followed now (its own trajectory: a detour ends at its
        # landmark); the later segments shift in time with it.
        index = next((k for k, p in enumerate(self._plans) if p.trajectory.end_time >= t_now), len(self._plans) - 1)
        segment = self._plans[index]
        waited = False
        try:
            result = replan(segment, obstacles, t_now=t_now, horizon=self.replan_horizon)
        except PlanningError:
            try:  # no detour (e.g. the ball fills a passage): stop on the path and let it pass
                result = wait_for_obstacles(segment, obstacles, t_now=t_now, horizon=self.replan_horizon)
                waited = True
            except PlanningError:
                # Waiting does not help either (the ball comes at the character): keep the plan.
                self._replan_failures += 1
                return
        if result is None:
            return
        self._plans[index] = dataclasses.replace(result.plan, trajectory=result.trajectory)
        self._chain_later_segments(index)
        self._trajectory = _concatenate([p.trajectory for p in self._plans])
        self._replans += 1
        self._waits += int(waited)
        self._refresh_path()

    def _chain_later_segments(self, index: int) -> None:
        """Start every segment after ``index`` when and where the one before it now ends: shifted in
        time, or planned again from the new end point if a detour arrived at another cell of the landmark."""
        before = self._plans[index].trajectory
        for k in range(index + 1, len(self._plans)):
            plan = self._plans[k]
            end_xy = before.xyz[-1, :2]
            if np.hypot(*(plan.trajectory.xyz[0, :2] - end_xy)) > 0.05:
                try:
                    plan = plan_path(plan.costmap, end_xy, plan.target, settings=plan.settings,
                                     t0=before.end_time, segment=plan.segment)
                except PlanningError:  # keep the old path (a short jump inside the landmark)
                    pass
            if plan.trajectory.start_time != before.end_time:
                plan = dataclasses.replace(plan, trajectory=_shifted(plan.trajectory,
                                                                     before.end_time - plan.trajectory.start_time))
            self._plans[k] = plan
            before = plan.trajectory


class _GroundTrack:
    """A scene obstacle as the planner sees it: its (x, y) over time and its radius."""

    def __init__(self, obstacle) -> None:
        self.obstacle = obstacle
        self.radius = obstacle.radius

    def position(self, t):
        return np.asarray(self.obstacle.position(t))[..., :2]


def _direction_while_still(yaw: np.ndarray, moving: np.ndarray) -> np.ndarray:
    """The path's direction where it stands still: the last direction of travel held at the ends, and during a
    stop (a wait for the ball) turned evenly from the direction before it to the one after, the shorter way
    round (a stop between +3.1 and -3.1 rad turns 0.08 rad, not 6.2 through due east)."""
    valid = np.flatnonzero(moving)
    if not len(valid):
        return np.zeros(len(yaw))
    index = np.arange(len(yaw))
    out = np.interp(index, valid, yaw[valid])
    before = np.searchsorted(valid, index, side="right") - 1    # the last moving sample at or before each
    stop = ~moving & (before >= 0) & (before < len(valid) - 1)
    a, b = valid[before[stop]], valid[before[stop] + 1]
    seam = np.abs(yaw[b] - yaw[a]) > np.pi    # across +-pi: np.interp would turn the long way round
    if seam.any():
        a, b, at = a[seam], b[seam], index[stop][seam]
        turn = np.mod(yaw[b] - yaw[a] + np.pi, 2 * np.pi) - np.pi
        out[at] = np.mod(yaw[a] + (at - a) / (b - a) * turn + np.pi, 2 * np.pi) - np.pi
    return out


def _check_joined(plans: list[Plan]) -> None:
    """``InstructionError`` where a leg starts from another landmark than the one the leg before it reaches:
    the character follows one path, and it would have to jump between them."""
    for k in range(1, len(plans)):
        source, reached = plans[k].segment.source, plans[k - 1].segment.target
        if source is not None and source != reached:
            raise InstructionError(f"leg {k + 1} starts from the {source}, but leg {k} ends at the {reached}: "
                                   f"say 'from the {reached}', or leave 'from' out")


def _constant_speed(plans: list[Plan], speed: float) -> list[Plan]:
    """The same paths travelled at one constant speed (the slalom baseline), chained in time."""
    out, t0 = [], 0.0
    for plan in plans:
        path = plan.path
        xyz = np.column_stack((path.xy, path.z_head))
        trajectory = Trajectory.from_profile(path.s, xyz, np.full(len(path.s), speed), t0=t0)
        out.append(dataclasses.replace(plan, trajectory=trajectory))
        t0 = trajectory.end_time
    return out


def _shifted(trajectory: Trajectory, dt: float) -> Trajectory:
    return Trajectory(trajectory.t + dt, trajectory.s, trajectory.xyz, trajectory.v)


def _concatenate(trajectories: list[Trajectory]) -> Trajectory:
    """One trajectory through consecutive ones (arc length runs on; duplicate joints dropped, and with them
    a zero-length leg's one sample: "walk to the tree, then walk to the tree")."""
    t, s, xyz, v = [trajectories[0].t], [trajectories[0].s], [trajectories[0].xyz], [trajectories[0].v]
    t_end, s_end = t[0][-1], s[0][-1]
    for traj in trajectories[1:]:
        keep = traj.t > t_end + 1e-9
        t.append(traj.t[keep])
        s.append(s_end + traj.s[keep] - traj.s[0])
        xyz.append(traj.xyz[keep])
        v.append(traj.v[keep])
        if keep.any():
            t_end, s_end = t[-1][-1], s[-1][-1]
    return Trajectory(np.concatenate(t), np.concatenate(s), np.vstack(xyz), np.concatenate(v))
