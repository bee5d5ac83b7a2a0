r"""The kinematic stand-in: a placeholder skill policy that is explicitly NOT physics-based.

**No trained skill policy exists yet.** :class:`KinematicStandIn` (the policy value
:data:`KINEMATIC` of :mod:`stairenv.stories.machine`) writes ``qpos`` (and zero velocities)
every step to glide the character along free floor, blend it onto a seat or bed, reach with
inverse kinematics or stand it up, and returns a hold-pose action. It exists to test the
state machine's transitions and to make demo videos; its success rates say nothing about
control.

It drives a :class:`~stairenv.environments.sims.SIMSEnv` through public methods only
(``pose``, ``set_pose``, ``pose_action``, ``pose_kinematics``, ``joint_limits``,
``resting_pose``, ``approach_point``, ``planning_grid``); its walking paths come from the
planner's A* (:func:`stairenv.planning.astar.astar`) on ``env.planning_grid()``.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from stairenv.humanoid import DOF_NAMES, STANDING_ROOT_HEIGHT
from stairenv.planning.astar import astar
from stairenv.planning.costmap import Costmap, build_costmap
from stairenv.planning.errors import PlanningError
from stairenv.policy_loading import KINEMATIC
from stairenv.rotations import yaw_to_quat_wxyz
from stairenv.tasks import sims as task
from stairenv.validation import check_number

if TYPE_CHECKING:
    from stairenv.environments.sims import SIMSEnv

#: :data:`KINEMATIC` (defined in :mod:`stairenv.policy_loading`, with the other policy specs) is the
#: policy value that makes :class:`~stairenv.stories.machine.StoryRunner` build a
#: :class:`KinematicStandIn` for its env.

_DOF = {name: k for k, name in enumerate(DOF_NAMES)}


def _smoothstep(t: float) -> float:
    t = min(max(t, 0.0), 1.0)
    return t * t * (3.0 - 2.0 * t)


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi




class _Floor:
    """Where the character may stand: the cells ``env.planning_grid(body_radius)`` does not
    block (off that grid the floor is open in object scenes, closed in rooms). Paths are the
    planner's A* (:func:`stairenv.planning.astar.astar`) over those cells."""

    def __init__(self, env: SIMSEnv, body_radius: float | None = None) -> None:
        self.grid = env.planning_grid(body_radius)
        self.free = ~self.grid.blocked
        self.off_grid_free = env.room is None  # object scenes: open floor around the height grid
        self._costmap: Costmap | None = None

    def cell_of(self, xy: np.ndarray) -> tuple[int, int]:
        i, j = self.grid.cell_of(np.asarray(xy, dtype=float)[:2])
        return int(i), int(j)

    def inside(self, i: int, j: int) -> bool:
        rows, cols = self.free.shape
        return 0 <= i < rows and 0 <= j < cols

    def is_free(self, xy: np.ndarray) -> bool:
        i, j = self.cell_of(xy)
        return bool(self.free[i, j]) if self.inside(i, j) else self.off_grid_free

    def nearest_free(self, xy: np.ndarray) -> np.ndarray:
        """The centre of the free cell nearest to ``xy`` (``xy`` itself if it is free)."""
        if self.is_free(xy) or not self.free.any():
            return np.asarray(xy, dtype=float)[:2].copy()
        centres = self.grid.cell_center(*np.nonzero(self.free))
        return centres[int(np.argmin(np.sum(np.square(centres - np.asarray(xy)[:2]), axis=1)))]

    def visible(self, a: np.ndarray, b: np.ndarray) -> bool:
        n = max(2, math.ceil(float(np.linalg.norm(b - a)) / (0.5 * self.grid.cell_size)) + 1)
        return all(self.is_free(p) for p in np.linspace(a, b, n))

    def path(self, start: np.ndarray, goal: np.ndarray) -> np.ndarray:
        """A polyline (K, 2) over free cells from ``start`` to ``goal`` (the planner's A* between
        the free cells nearest to them, then shortcuts between mutually visible points); a
        straight line when no free path exists."""
        start, goal = np.asarray(start, dtype=float)[:2], np.asarray(goal, dtype=float)[:2]
        straight = np.stack((start, goal))
        if self.visible(start, goal):
            return straight
        s, g = self.cell_of(self.nearest_free(start)), self.cell_of(self.nearest_free(goal))
        if not (self.inside(*s) and self.inside(*g)):
            return straight
        if self._costmap is None:  # flat, open sky: passable = the free cells, edge cost = length
            self._costmap = build_costmap(self.grid, body_radius=0.0, slope_window=0.0)
        try:
            cells = astar(self._costmap, s, np.array([g]), reach=0.0).cells
        except PlanningError:
            return straight
        points = [start, *self.grid.cell_center(cells[:, 0], cells[:, 1]), goal]
        # string pulling: from each kept point jump to the farthest visible one
        kept, k = [points[0]], 0
        while k < len(points) - 1:
            nxt = k + 1
            for m in range(len(points) - 1, k + 1, -1):
                if self.visible(points[k], points[m]):
                    nxt = m
                    break
            kept.append(points[nxt])
            k = nxt
        return np.asarray(kept)


class KinematicStandIn:
    """A placeholder skill policy that is explicitly NOT physics-based.

    Called with an observation it reads ``env.goal`` and *writes the character's qpos* (with
    zero velocities) one control step further towards it, then returns the action that holds
    the written joint angles; the env's physics step that follows barely moves a character
    that is re-posed every step. Per goal:

    * walk: glide along free floor (a grid path) at ``speed`` m/s, standing, turning at most
      ``turn_rate`` rad/s; then stand at the target;
    * sit / lie: glide to the piece's approach point if farther than ``near`` m, then blend
      over ``blend_seconds`` into the pose ``env.resting_pose`` gives (seated / lying on it);
    * reach: glide to the floor nearest to the target point (``reach_clearance`` m from any
      obstacle), face it, and blend a hip bend, the trunk and the arm into an inverse-kinematics
      pose putting the hand on it (if within reach);
    * getup: blend from the current (seated / lying) pose to standing at the goal's pelvis
      target, facing away from the piece.

    Use it to test the state machine and to make demo videos, never as a result about control.
    One instance serves one env (several skills may share it).
    """

    #: Read by :func:`stairenv.policy_loading.policy_label`: the label says it is not physics-based.
    physics_based = False

    def __init__(self, env: SIMSEnv, speed: float = 1.0, blend_seconds: float = 0.6, turn_rate: float = 4.0,
                 near: float = 0.6, reach_clearance: float = 0.12) -> None:
        self.env = getattr(env, "unwrapped", env)
        self.speed = check_number("speed", speed, 0.0, 10.0, low_open=True)
        self.blend_seconds = check_number("blend_seconds", blend_seconds, 0.0, 10.0)
        self.turn_rate = check_number("turn_rate", turn_rate, 0.0, 100.0, low_open=True)
        self.near = check_number("near", near, 0.0, 10.0)
        self.reach_clearance = check_number("reach_clearance", reach_clearance, 0.0, 1.0)
        self._model: mujoco.MjModel | None = None
        self._goal: task.ContactGoal | None = None
        self._plan: list[tuple[str, Any]] = []

    def __repr__(self) -> str:
        return "KinematicStandIn(not physics-based)"

    def reset(self, seed: int | None = None) -> None:
        """Forget the current plan (the next call plans from the character's pose)."""
        self._goal = None

    # -- model-dependent caches
    def _bind_model(self) -> None:
        env = self.env
        if self._model is env.model:
            return
        self._model = env.model
        self._scratch = mujoco.MjData(env.model)
        self._grid = _Floor(env)
        # reaching, the character may stand closer to furniture than while walking
        self._reach_grid = _Floor(env, body_radius=self.reach_clearance)
        self._lo, self._hi = env.joint_limits()
        # the standing root height with all joints at 0 (feet 2 mm above the floor)
        self._scratch.qpos[:] = env.data.qpos
        q = np.zeros(7 + len(DOF_NAMES))
        q[:7] = (0.0, 0.0, STANDING_ROOT_HEIGHT, 1.0, 0.0, 0.0, 0.0)
        self._stand_z = STANDING_ROOT_HEIGHT + 0.002 - env.pose_kinematics(q, self._scratch)

    # -- poses as (root 7, joints 28)
    def _standing(self, xy: np.ndarray, heading: float, joints: np.ndarray | None = None) -> np.ndarray:
        q = np.zeros(7 + len(DOF_NAMES))
        q[:3] = (xy[0], xy[1], self._stand_z)
        q[3:7] = yaw_to_quat_wxyz(heading)
        if joints is not None:
            q[7:] = joints
        return q

    # -- planning
    def _new_plan(self, goal: task.ContactGoal) -> None:
        env = self.env
        self._goal = goal
        self._pose = env.pose()
        self._heading = self._yaw(self._pose)
        here = self._pose[:2].copy()
        placed = env.furniture.get(goal.furniture) if goal.furniture is not None else None
        plan: list[tuple[str, Any]] = []
        if goal.skill == "walk":
            plan.append(("glide", self._grid.path(here, goal.root_target[:2])))
        elif goal.skill in ("sit", "lie"):
            stand = env.approach_point(placed)
            if np.linalg.norm(stand - here) > self.near or not self._upright():
                plan.append(("glide", self._grid.path(here, stand)))
            plan.append(("blend", ("place", placed, "sit" if goal.skill == "sit" else "lie")))
        elif goal.skill == "reach":
            target = goal.points[goal.primary][0]
            stand = self._reach_grid.nearest_free(target[:2])
            if np.linalg.norm(stand - here) > 0.05:
                # walk on the wide-berth grid, then step in to the reaching spot
                path = self._grid.path(here, self._grid.nearest_free(stand))
                plan.append(("glide", np.vstack((path, stand[None]))))
            plan.append(("blend", ("reach", target, env.model.body(task.CONTACT_JOINTS[goal.primary]).id)))
        else:  # getup
            target = goal.root_target[:2]
            away = target - (placed.position if placed is not None else here)
            heading = math.atan2(away[1], away[0]) if np.linalg.norm(away) > 1e-6 else self._heading
            plan.append(("blend", ("pose", self._standing(target, heading))))
        self._plan = plan
        self._start_step()

    def _upright(self) -> bool:
        return abs(self._pose[2] - self._stand_z) < 0.1 and not np.any(np.abs(self._pose[7:]) > 0.5)

    @staticmethod
    def _yaw(q: np.ndarray) -> float:
        w, x, y, z = q[3:7]
        return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))

    def _start_step(self) -> None:
        """Prepare the first remaining plan step (targets that depend on where the character is)."""
        self._t = 0.0
        if not self._plan:
            return
        kind, arg = self._plan[0]
        if kind == "glide":
            seg = np.diff(arg, axis=0)
            self._lengths = np.concatenate(([0.0], np.cumsum(np.linalg.norm(seg, axis=1))))
            if not self._upright():  # e.g. after a fall: stand up where the character is first
                self._pose = self._standing(self._pose[:2], self._heading)
        else:
            what = arg[0]
            if what == "place":
                self._target = self.env.resting_pose(arg[1], arg[2])
            elif what == "reach":
                self._target = self._reach_pose(arg[1], arg[2])
            else:
                self._target = arg[1]
            self._from = self._pose.copy()

    def _bent(self, xy: np.ndarray, heading: float, params: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """A standing pose bent forward at the hips by ``params[0]`` rad (legs kept vertical), with
        ``params[1:]`` the angles of joints ``cols``; feet put back 2 mm above the floor."""
        pitch = params[0]
        q = self._standing(xy, heading)
        rot = Rotation.from_euler("z", heading) * Rotation.from_euler("y", pitch)
        q[3:7] = rot.as_quat(scalar_first=True)
        q[7 + _DOF["right_hip_y"]] = q[7 + _DOF["left_hip_y"]] = -pitch  # thighs back to vertical
        q[7 + cols] = params[1:]
        q[2] += 0.002 - self.env.pose_kinematics(q, self._scratch)
        return q

    def _reach_pose(self, target: np.ndarray, hand_body: int, iterations: int = 40) -> np.ndarray:
        """Standing here facing ``target``: a hip bend, the trunk and the arm joints by damped
        least squares (finite-difference Jacobian) so that the hand body's origin reaches it, as
        near as the joint ranges allow."""
        model, scratch = self.env.model, self._scratch
        delta = target[:2] - self._pose[:2]
        heading = math.atan2(delta[1], delta[0])
        xy = self._pose[:2].copy()
        side = "right" if model.body(hand_body).name.startswith("right") else "left"
        names = ["abdomen_x", "abdomen_y", "abdomen_z",
                 f"{side}_shoulder_x", f"{side}_shoulder_y", f"{side}_shoulder_z", f"{side}_elbow"]
        cols = np.array([_DOF[n] for n in names])
        lo = np.concatenate(([0.0], self._lo[cols]))
        hi = np.concatenate(([1.3], self._hi[cols]))  # bend at most ~75 deg
        scratch.qpos[:] = self.env.data.qpos

        def hand(params: np.ndarray) -> np.ndarray:
            self._bent(xy, heading, params, cols)
            return scratch.xpos[hand_body].copy()

        params = np.clip(np.zeros(len(cols) + 1), lo, hi)
        eps = 1e-4
        for _ in range(iterations):
            at = hand(params)
            err = target - at
            if np.linalg.norm(err) < 0.01:
                break
            jac = np.empty((3, len(params)))
            for k in range(len(params)):
                nudged = params.copy()
                nudged[k] += eps
                jac[:, k] = (hand(nudged) - at) / eps
            # bending costs more than moving the arm: a standing reach stays upright when it can
            weights = np.ones(len(params))
            weights[0] = 4.0
            jw = jac / weights
            step = (jw.T @ np.linalg.solve(jw @ jw.T + 0.01 * np.eye(3), err)) / weights
            params = np.clip(params + np.clip(step, -0.3, 0.3), lo, hi)
        return self._bent(xy, heading, params, cols)

    # -- acting
    def __call__(self, obs: np.ndarray) -> np.ndarray:
        env = self.env
        self._bind_model()
        if env.goal is not self._goal:
            self._new_plan(env.goal)
        dt = env.dt
        while self._plan:
            kind, arg = self._plan[0]
            if kind == "glide" and self._glide(arg, dt):
                break
            if kind == "blend" and self._blend(dt):
                break
            self._plan.pop(0)
            self._start_step()
        env.set_pose(self._pose)
        return env.pose_action(self._pose)

    def _glide(self, path: np.ndarray, dt: float) -> bool:
        """Advance along ``path``; False once at its end."""
        self._t += dt
        total = self._lengths[-1]
        s = min(self._t * self.speed, total)
        k = int(np.clip(np.searchsorted(self._lengths, s, side="right") - 1, 0, len(path) - 2))
        seg = path[k + 1] - path[k]
        length = max(self._lengths[k + 1] - self._lengths[k], 1e-9)
        xy = path[k] + seg * (s - self._lengths[k]) / length
        if np.linalg.norm(seg) > 1e-6:
            want = math.atan2(seg[1], seg[0])
            turn = float(np.clip(_wrap(want - self._heading), -self.turn_rate * dt, self.turn_rate * dt))
            self._heading = _wrap(self._heading + turn)
        self._pose = self._standing(xy, self._heading)
        return s < total - 1e-9

    def _blend(self, dt: float) -> bool:
        """Ease from the pose at the step's start to its target; False once there."""
        self._t += dt
        u = 1.0 if self.blend_seconds <= 0 else _smoothstep(self._t / self.blend_seconds)
        a, b = self._from, self._target
        q = a + u * (b - a)
        rots = Rotation.from_quat(np.stack((a[3:7], b[3:7])), scalar_first=True)
        q[3:7] = Slerp([0.0, 1.0], rots)(u).as_quat(scalar_first=True)
        self._pose = q
        self._heading = self._yaw(q)
        return u < 1.0
