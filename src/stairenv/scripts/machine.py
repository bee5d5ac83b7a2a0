r"""The SIMS finite state machine (Sec. 3.4): run a script's keyframes one skill policy after another.

A :class:`StoryRunner` drives one :class:`~stairenv.environments.sims.SIMSEnv` built on a
room (``SIMSEnv(skill="walk", room=room, ...)``). For each keyframe it switches the env's
goal with ``env.set_task`` (skill, furniture instance, part, hand, caption, style; the
physics is untouched), steps the env with that skill's policy and moves on when the
keyframe has *held* its goal for ``dwell_seconds`` (SIMS, after InterScene: "the next skill
starts when the root has stayed at its target for a set time"):

=========  =====================================================================================
skill      goal and "held" test
=========  =====================================================================================
walk       the root to ``env.approach_point`` of the keyframe's furniture (none: of the next
           interaction's furniture; none either: a random free point of the room); held while
           the root is within ``arrive_radius`` of it (ground distance)
sit, lie   ``info["success"]``: the pelvis within 20 cm (lie: 30 cm) of the seat / bed surface
reach      ``info["success"]``: the hand within 20 cm of a point of the part
getup      ``info["success"]``: the pelvis at standing height in front of the piece (20 cm); a
           getup without furniture gets up from the piece last sat or lain on
=========  =====================================================================================

A keyframe fails on timeout (``max_seconds``), a fall (``info["fell"]``) or diverging physics
(``info["physics_unstable"]``; the env then needs a reset, so the run always stops). After a
failure the run stops (``stop_on_failure=True``; the remaining keyframes are ``"skipped"``) or
goes on with the next keyframe from wherever the character is.

Policies: a mapping skill -> a callable ``obs -> action``, a Stable-Baselines3 model
(``predict(obs, deterministic=True)``) or :data:`KINEMATIC`. Skills SIMS trains without text
(reach, get up: the ``SIMS-Reach-v0`` / ``SIMS-GetUp-v0`` presets) see zeros in the
observation's text slice (``MachineSettings.text_free_skills``).

**No trained skill policy exists yet.** :class:`KinematicStandIn` (``KINEMATIC``) is a
placeholder that is explicitly *not* physics-based: it writes ``qpos`` (and zero velocities)
every step to glide the character along free floor, blend it onto a seat or bed, reach with
inverse kinematics or stand it up, and returns a hold-pose action. It exists to test the
state machine's transitions and to make demo videos; its success rates say nothing about
control.

Example::

    from stairenv.environments.sims import SIMSEnv
    from stairenv.scripts import load_database
    from stairenv.scripts.machine import KINEMATIC, run_script

    script = load_database().get("tired_bedtime")
    result = run_script(script, {s: KINEMATIC for s in ("walk", "sit", "lie", "reach", "getup")},
                        seed=0, video="story.mp4")
    print(result.success, [k.outcome for k in result.keyframes])
"""

from __future__ import annotations

import math
import os
from collections import deque
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np
from scipy import ndimage
from scipy.spatial.transform import Rotation, Slerp

from stairenv.humanoid import DOF_NAMES, STANDING_ROOT_HEIGHT
from stairenv.motion.rsi import humanoid_lowest_z
from stairenv.rotations import yaw_to_quat_wxyz
from stairenv.tasks import sims as task
from stairenv.validation import check_number

if TYPE_CHECKING:
    from stairenv.environments.sims import SIMSEnv
    from stairenv.scripts.retrieval import RoomMatch
    from stairenv.world.furniture import PlacedFurniture
    from stairenv.world.rooms import Room, RoomConfig

#: Policy value that makes :class:`StoryRunner` build a :class:`KinematicStandIn` for its env.
KINEMATIC = "kinematic"
#: What became of a keyframe.
OUTCOMES: tuple[str, ...] = ("success", "timeout", "fell", "unstable", "skipped")
#: Skills that touch furniture (SIMS Table 2 counts these as the script's interactions).
INTERACTIONS: tuple[str, ...] = ("sit", "lie", "reach")
START_POSES: tuple[str, ...] = ("standing", "sitting", "lying")
#: (elevation deg, distance m) of the follow camera when recording in a room.
ROOM_CAMERA: tuple[float, float] = (-65.0, 5.0)

Policy = Callable[[np.ndarray], Any]
_DOF = {name: k for k, name in enumerate(DOF_NAMES)}


class BindingError(ValueError):
    """A keyframe cannot run in the env: unknown furniture instance, a skill the piece does not
    afford, no policy for its skill, or a binding list of the wrong length."""


# --- settings and results --------------------------------------------------------------------
@dataclass(frozen=True)
class MachineSettings:
    """How the state machine decides transitions.

    | field | default | meaning |
    |---|---|---|
    | dwell_seconds | 1.0 | the goal must hold this long (consecutively) before the next keyframe |
    | max_seconds | 20.0 | a keyframe not held by then fails with ``"timeout"`` |
    | arrive_radius | 0.2 | walks: the root within this ground distance (m) of the target holds the goal |
    | stop_on_failure | True | stop at the first failed keyframe (the rest: ``"skipped"``) or go on |
    | text_free_skills | ("reach", "getup") | skills whose policy sees zeros for z (SIMS trains them without text) |
    | part_fallback | True | a part the bound piece lacks (e.g. a script's cabinet "shelf") -> the skill's default part, noted in the result; False: ``BindingError`` |
    | target_speed | None | v* given to ``set_task`` (None: the middle of the env's ``target_speed``) |
    """

    dwell_seconds: float = 1.0
    max_seconds: float = 20.0
    arrive_radius: float = 0.2
    stop_on_failure: bool = True
    text_free_skills: tuple[str, ...] = ("reach", "getup")
    part_fallback: bool = True
    target_speed: float | None = None

    def __post_init__(self) -> None:
        check_number("dwell_seconds", self.dwell_seconds, 0.0, 3600.0)
        check_number("max_seconds", self.max_seconds, 0.0, 36000.0, low_open=True)
        check_number("arrive_radius", self.arrive_radius, 0.0, 10.0, low_open=True)
        if self.dwell_seconds >= self.max_seconds:
            raise ValueError(f"dwell_seconds ({self.dwell_seconds}) must be below max_seconds ({self.max_seconds})")
        object.__setattr__(self, "text_free_skills", tuple(self.text_free_skills))
        for skill in self.text_free_skills:
            if skill not in task.SKILLS:
                raise ValueError(f"text_free_skills must name skills of {list(task.SKILLS)}, got {skill!r}")
        if self.target_speed is not None:
            check_number("target_speed", self.target_speed, 0.0, 10.0)


@dataclass
class KeyframeResult:
    """One keyframe's run. Times in seconds from the keyframe's start; errors in metres."""

    index: int
    skill: str
    category: str | None         # the script's furniture category (None: none)
    furniture: str | None        # the instance used (walk: the piece walked to, if any)
    part: str | None             # the part touched (the goal's label)
    caption: str
    style: str
    outcome: str                 # one of OUTCOMES
    success: bool
    contact_error: float | None  # at the last step (walk: root to target, ground distance)
    min_contact_error: float | None
    seconds: float               # time spent in the keyframe
    steps: int
    held_from: float | None = None  # when the final, completed hold began (success only)
    note: str = ""               # e.g. a part fallback


@dataclass
class StoryResult:
    """A state-machine run: per-keyframe results plus what it ran in."""

    keyframes: list[KeyframeResult]
    room: str | None = None
    script_ids: list[str] = field(default_factory=list)
    video: str | None = None
    frames: int = 0
    policies: dict[str, str] = field(default_factory=dict)
    details: dict[str, Any] = field(default_factory=dict)

    @property
    def success(self) -> bool:
        """Every keyframe succeeded (SIMS Table 2's script success)."""
        return bool(self.keyframes) and all(k.success for k in self.keyframes)

    @property
    def seconds(self) -> float:
        return float(sum(k.seconds for k in self.keyframes))

    @property
    def skills(self) -> list[str]:
        """Skills of the keyframes that ran (not skipped), in order."""
        return [k.skill for k in self.keyframes if k.outcome != "skipped"]

    @property
    def interactions(self) -> list[KeyframeResult]:
        return [k for k in self.keyframes if k.skill in INTERACTIONS]

    @property
    def interactions_succeeded(self) -> int:
        """SIMS Table 2's "success steps": interactions (sit, lie, reach) that succeeded."""
        return sum(k.success for k in self.interactions)

    def to_dict(self) -> dict[str, Any]:
        return {
            "success": self.success,
            "seconds": self.seconds,
            "interactions": len(self.interactions),
            "interactions_succeeded": self.interactions_succeeded,
            "room": self.room,
            "script_ids": list(self.script_ids),
            "video": self.video,
            "frames": self.frames,
            "policies": dict(self.policies),
            "details": self.details,
            "keyframes": [asdict(k) for k in self.keyframes],
        }


# --- policies --------------------------------------------------------------------------------
def describe_policy(policy: Any) -> str:
    """A short human-readable name; the stand-in says that it is not physics-based."""
    if isinstance(policy, KinematicStandIn) or policy == KINEMATIC:
        return "kinematic stand-in (NOT physics-based: writes qpos)"
    if isinstance(policy, (str, os.PathLike)):
        return os.fspath(policy)
    return repr(policy) if type(policy).__repr__ is not object.__repr__ else type(policy).__name__


def as_policy(policy: Any, env: SIMSEnv) -> Policy:
    """A callable ``obs -> action`` from a callable, an SB3 model (deterministic ``predict``) or
    :data:`KINEMATIC` (a :class:`KinematicStandIn` for ``env``)."""
    if isinstance(policy, str) and policy == KINEMATIC:
        return KinematicStandIn(env)
    if callable(policy):
        return policy
    if callable(getattr(policy, "predict", None)):
        def predict(obs: np.ndarray) -> np.ndarray:
            return policy.predict(obs, deterministic=True)[0]

        predict.__name__ = type(policy).__name__
        return predict
    raise TypeError(f"a policy must be callable (obs -> action), have predict(), or be {KINEMATIC!r}; "
                    f"got {type(policy).__name__}")


def load_skill_policies(specs: Mapping[str, Any] | str, env: Any, seed: int | None = 0) -> dict[str, Any]:
    """Resolve policy specs for every skill: a single spec for all, or skill -> spec.

    Strings go through :func:`stairenv.evaluation.load_policy` ("zero", "random", an SB3 .zip,
    ``ALGO:path``) with ``env`` giving the spaces; :data:`KINEMATIC` stays as it is (the
    runner binds a stand-in to its own env); callables and models pass through. Skills not
    in a mapping are left out.
    """
    from stairenv.evaluation import load_policy

    out: dict[str, Any] = {}
    loaded: dict[str, Any] = {}
    for skill, spec in policy_specs(specs).items():
        if isinstance(spec, (str, os.PathLike)) and os.fspath(spec) != KINEMATIC:
            key = os.fspath(spec)
            if key not in loaded:  # one model (or random generator) per distinct spec
                loaded[key] = load_policy(key, env, seed=seed)
            out[skill] = loaded[key]
        else:
            out[skill] = spec
    return out


def policy_specs(specs: Any) -> dict[str, Any]:
    """``specs`` as skill -> policy spec: a mapping is checked, one spec goes to every skill.

    A spec is a string (:data:`KINEMATIC`, "zero", "random", an SB3 .zip, ``ALGO:path``), a
    callable ``obs -> action`` or a model with ``predict()``. Raises TypeError for anything
    else and ValueError for a key that is not a skill.
    """
    if not isinstance(specs, Mapping):
        if not _is_policy_spec(specs):
            raise TypeError(f"policies must be a mapping skill -> policy, or one policy for every skill "
                            f"({_POLICY_KINDS}); got {type(specs).__name__}")
        return dict.fromkeys(task.SKILLS, specs)
    for skill, spec in specs.items():
        if skill not in task.SKILLS:
            raise ValueError(f"policy skills must be among {list(task.SKILLS)}, got {skill!r}")
        if not _is_policy_spec(spec):
            raise TypeError(f"policies[{skill!r}] must be {_POLICY_KINDS}; got {type(spec).__name__}")
    return dict(specs)


_POLICY_KINDS = (f"a callable obs -> action, a model with predict(), or a spec string ({KINEMATIC!r}, 'zero', "
                 f"'random', an SB3 .zip)")


def _is_policy_spec(spec: Any) -> bool:
    return isinstance(spec, (str, os.PathLike)) or callable(spec) or callable(getattr(spec, "predict", None))


# --- the kinematic stand-in ------------------------------------------------------------------
def _smoothstep(t: float) -> float:
    t = min(max(t, 0.0), 1.0)
    return t * t * (3.0 - 2.0 * t)


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


class _FreeGrid:
    """Where the character may stand, on a grid: the room's free space, or (object scenes)
    cells of the env's height grid farther than ``body_radius`` from any surface above the floor."""

    def __init__(self, env: SIMSEnv, body_radius: float | None = None) -> None:
        if env.room is not None:
            space = env.room.free_space(body_radius=body_radius)
            self.free = space.free
            self.origin, self.cell = np.asarray(space.origin, dtype=float), float(space.cell_size)
            self.off_grid_free = False
        else:
            heights = env._heights
            blocked = heights.heights > 0.03
            dist = ndimage.distance_transform_edt(~blocked) * heights.cell_size
            self.free = dist - 0.5 * heights.cell_size >= (0.25 if body_radius is None else body_radius)
            self.origin, self.cell = np.asarray(heights.origin, dtype=float), float(heights.cell_size)
            self.off_grid_free = True  # object scenes: open floor around the height grid

    def cell_of(self, xy: np.ndarray) -> tuple[int, int]:
        j, i = np.floor((np.asarray(xy, dtype=float)[:2] - self.origin) / self.cell).astype(int)
        return int(i), int(j)

    def centre(self, i: int, j: int) -> np.ndarray:
        return self.origin + (np.array([j, i]) + 0.5) * self.cell

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
        ii, jj = np.nonzero(self.free)
        centres = self.origin + (np.column_stack((jj, ii)) + 0.5) * self.cell
        return centres[int(np.argmin(np.sum(np.square(centres - np.asarray(xy)[:2]), axis=1)))]

    def visible(self, a: np.ndarray, b: np.ndarray) -> bool:
        n = max(2, math.ceil(float(np.linalg.norm(b - a)) / (0.5 * self.cell)) + 1)
        return all(self.is_free(p) for p in np.linspace(a, b, n))

    def path(self, start: np.ndarray, goal: np.ndarray) -> np.ndarray:
        """A polyline (K, 2) over free cells from ``start`` to ``goal`` (breadth-first search, then
        shortcuts between mutually visible points); a straight line when no free path exists."""
        start, goal = np.asarray(start, dtype=float)[:2], np.asarray(goal, dtype=float)[:2]
        if self.visible(start, goal):
            return np.stack((start, goal))
        s, g = self.cell_of(self.nearest_free(start)), self.cell_of(self.nearest_free(goal))
        if not (self.inside(*s) and self.inside(*g)):
            return np.stack((start, goal))
        parent = {s: s}
        queue = deque([s])
        steps = ((1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (1, -1), (-1, 1), (-1, -1))
        while queue:
            cur = queue.popleft()
            if cur == g:
                break
            for di, dj in steps:
                nxt = (cur[0] + di, cur[1] + dj)
                if nxt not in parent and self.inside(*nxt) and self.free[nxt]:
                    parent[nxt] = cur
                    queue.append(nxt)
        if g not in parent:
            return np.stack((start, goal))
        cells = [g]
        while cells[-1] != s:
            cells.append(parent[cells[-1]])
        points = [start, *(self.centre(*c) for c in reversed(cells)), goal]
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
      over ``blend_seconds`` into the pose ``env._place_on`` gives (seated / lying on it);
    * reach: glide to the floor nearest to the target point (``reach_clearance`` m from any
      obstacle), face it, and blend a hip bend, the trunk and the arm into an inverse-kinematics
      pose putting the hand on it (if within reach);
    * getup: blend from the current (seated / lying) pose to standing at the goal's pelvis
      target, facing away from the piece.

    Use it to test the state machine and to make demo videos, never as a result about control.
    One instance serves one env (several skills may share it).
    """

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
        self._grid = _FreeGrid(env)
        # reaching, the character may stand closer to furniture than while walking
        self._reach_grid = _FreeGrid(env, body_radius=self.reach_clearance)
        idx = env._idx
        self._root, self._joints = idx.qpos_root, idx.qpos_joints
        self._dof0 = idx.qvel_joints.start
        self._lo, self._hi = env.model.jnt_range[env.model.dof_jntid[idx.qvel_joints]].T.copy()
        # the standing root height with all joints at 0 (feet 2 mm above the floor)
        q = self._scratch.qpos
        q[:] = env.data.qpos
        q[self._root] = (0.0, 0.0, STANDING_ROOT_HEIGHT, 1.0, 0.0, 0.0, 0.0)
        q[self._joints] = 0.0
        mujoco.mj_kinematics(env.model, self._scratch)
        self._stand_z = STANDING_ROOT_HEIGHT + 0.002 - humanoid_lowest_z(env.model, self._scratch, env._geoms)

    # -- poses as (root 7, joints 28)
    def _standing(self, xy: np.ndarray, heading: float, joints: np.ndarray | None = None) -> np.ndarray:
        q = np.zeros(7 + len(DOF_NAMES))
        q[:3] = (xy[0], xy[1], self._stand_z)
        q[3:7] = yaw_to_quat_wxyz(heading)
        if joints is not None:
            q[7:] = joints
        return q

    def _write(self, q: np.ndarray) -> None:
        env = self.env
        env.data.qpos[self._root] = q[:7]
        env.data.qpos[self._joints] = q[7:]
        env.data.qvel[env._idx.qvel_root] = 0.0
        env.data.qvel[env._idx.qvel_joints] = 0.0
        mujoco.mj_forward(env.model, env.data)

    def _action(self, q: np.ndarray) -> np.ndarray:
        env = self.env
        return np.clip((q[7:] - env._ctrl_offset) / env._ctrl_scale, -1.0, 1.0).astype(np.float32)

    # -- planning
    def _new_plan(self, goal: task.ContactGoal) -> None:
        env = self.env
        self._goal = goal
        self._pose = np.concatenate((env.data.qpos[self._root], env.data.qpos[self._joints]))
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
                self._target = self._placed_pose(arg[1], arg[2])
            elif what == "reach":
                self._target = self._reach_pose(arg[1], arg[2])
            else:
                self._target = arg[1]
            self._from = self._pose.copy()

    def _placed_pose(self, placed: PlacedFurniture, pose: str) -> np.ndarray:
        """The pose ``env._place_on`` gives (computed on the live data, which is then restored)."""
        env, data = self.env, self.env.data
        saved = data.qpos.copy(), data.qvel.copy(), data.ctrl.copy()
        env._place_on(placed, pose)
        q = np.concatenate((data.qpos[self._root], data.qpos[self._joints]))
        data.qpos[:], data.qvel[:], data.ctrl[:] = saved
        mujoco.mj_forward(env.model, data)
        return q

    def _bent(self, xy: np.ndarray, heading: float, params: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """A standing pose bent forward at the hips by ``params[0]`` rad (legs kept vertical), with
        ``params[1:]`` the angles of joints ``cols``; feet put back 2 mm above the floor."""
        pitch = params[0]
        q = self._standing(xy, heading)
        rot = Rotation.from_euler("z", heading) * Rotation.from_euler("y", pitch)
        q[3:7] = rot.as_quat(scalar_first=True)
        q[7 + _DOF["right_hip_y"]] = q[7 + _DOF["left_hip_y"]] = -pitch  # thighs back to vertical
        q[7 + cols] = params[1:]
        scratch = self._scratch
        scratch.qpos[self._root], scratch.qpos[self._joints] = q[:7], q[7:]
        mujoco.mj_kinematics(self.env.model, scratch)
        q[2] += 0.002 - humanoid_lowest_z(self.env.model, scratch, self.env._geoms)
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
        self._write(self._pose)
        return self._action(self._pose)

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


# --- the state machine -----------------------------------------------------------------------
class VideoWriter:
    """An MP4 writer (imageio + ffmpeg, libx264 as ``python -m stairenv``) that can print a
    caption on each frame."""

    def __init__(self, path: str | os.PathLike, fps: int, caption: bool = True) -> None:
        import imageio.v2 as imageio

        self.path = Path(path)
        if self.path.suffix.lower() != ".mp4":
            raise ValueError(f"video must be an .mp4 path, got {str(self.path)!r}")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        # libx264 needs even frame sizes; macro_block_size=2 rounds odd ones up without a warning.
        self._writer = imageio.get_writer(self.path, fps=fps, codec="libx264", quality=7, macro_block_size=2,
                                          pixelformat="yuv420p")
        self.caption = caption
        self.frames = 0
        self._font = None

    def append(self, frame: np.ndarray, text: str = "") -> None:
        if self.caption and text:
            frame = self._overlay(frame, text)
        self._writer.append_data(frame)
        self.frames += 1

    def _overlay(self, frame: np.ndarray, text: str) -> np.ndarray:
        from PIL import Image, ImageDraw, ImageFont

        if self._font is None:
            try:
                self._font = ImageFont.load_default(size=max(12, frame.shape[0] // 32))
            except TypeError:  # Pillow < 10.1: one fixed-size bitmap font
                self._font = ImageFont.load_default()
        image = Image.fromarray(frame)
        draw = ImageDraw.Draw(image)
        box = draw.textbbox((8, 6), text, font=self._font)
        draw.rectangle((box[0] - 4, box[1] - 3, box[2] + 4, box[3] + 3), fill=(0, 0, 0))
        draw.text((8, 6), text, fill=(255, 255, 255), font=self._font)
        return np.asarray(image)

    def close(self) -> None:
        self._writer.close()

    def __enter__(self):  # -> Self
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _keyframe_field(kf: Any, name: str, default: Any = None) -> Any:
    return kf.get(name, default) if isinstance(kf, Mapping) else getattr(kf, name, default)


class StoryRunner:
    """Runs keyframes through skill policies in one SIMS env (see the module docstring).

    ``env``: a :class:`~stairenv.environments.sims.SIMSEnv` (gym wrappers are unwrapped; its
    ``render_mode`` must be ``"rgb_array"`` to record video). ``policies``: skill -> policy
    (a callable, an SB3 model or :data:`KINEMATIC`); only the skills a run uses are needed.
    """

    def __init__(self, env: Any, policies: Mapping[str, Any], settings: MachineSettings | None = None) -> None:
        self.env: SIMSEnv = getattr(env, "unwrapped", env)
        if not hasattr(self.env, "set_task"):
            raise TypeError(f"env must be a SIMSEnv, got {type(self.env).__name__}")
        self.settings = settings or MachineSettings()
        unknown = set(policies) - set(task.SKILLS)
        if unknown:
            raise ValueError(f"policies must be keyed by skills of {list(task.SKILLS)}, got {sorted(unknown)}")
        self.policy_names = {skill: describe_policy(p) for skill, p in policies.items()}
        shared: dict[int, Policy] = {}
        self.policies: dict[str, Policy] = {}
        for skill, p in policies.items():
            # one stand-in for all skills that ask for it (it keeps the character's pose between them)
            key = id(KINEMATIC) if isinstance(p, str) and p == KINEMATIC else id(p)
            if key not in shared:
                shared[key] = as_policy(p, self.env)
            self.policies[skill] = shared[key]

    # -- binding
    def bind(self, keyframes: Sequence[Any], binding: Sequence[str | None] | Mapping[int, str | None] | None
             ) -> list[tuple[Any, str | None]]:
        """Pair keyframes with instances: ``binding`` a list (one per keyframe), a mapping
        index -> instance, or None when ``keyframes`` already are (keyframe, instance) pairs."""
        if binding is None:
            pairs = [tuple(item) for item in keyframes]
            if any(len(p) != 2 for p in pairs):
                raise BindingError("without binding, keyframes must be (keyframe, instance) pairs")
            return [(kf, inst) for kf, inst in pairs]
        if isinstance(binding, Mapping):
            return [(kf, binding.get(i)) for i, kf in enumerate(keyframes)]
        binding = list(binding)
        if len(binding) != len(keyframes):
            raise BindingError(f"binding has {len(binding)} entries for {len(keyframes)} keyframes")
        return list(zip(keyframes, binding))

    def _check(self, pairs: Sequence[tuple[Any, str | None]], seat: str | None = None
               ) -> list[tuple[str | None, str]]:
        """Validate every keyframe before running (``seat``: what the character starts on);
        returns (part label or None, note) per keyframe."""
        env = self.env
        parts: list[tuple[str | None, str]] = []
        for i, (kf, inst) in enumerate(pairs):
            skill = _keyframe_field(kf, "skill")
            where = f"keyframe {i} ({skill} {_keyframe_field(kf, 'caption', '')!r})"
            if skill not in task.SKILLS:
                raise BindingError(f"{where}: skill must be one of {list(task.SKILLS)}")
            if skill not in self.policies:
                raise BindingError(f"{where}: no policy for {skill!r}; policies: {sorted(self.policies)}")
            if inst is not None and inst not in env.furniture:
                raise BindingError(f"{where}: no furniture instance {inst!r} in the env; it has {sorted(env.furniture)}")
            if skill in INTERACTIONS and inst is None:
                raise BindingError(f"{where}: {skill} needs a furniture instance, got None")
            if skill == "getup" and inst is None and seat is None:
                raise BindingError(f"{where}: getup without furniture, and nothing was sat or lain on before")
            part, note = None, ""
            if skill in INTERACTIONS or skill == "getup":
                placed = env.furniture[inst if inst is not None else seat]
                wanted = _keyframe_field(kf, "part") if skill != "getup" else None
                try:
                    part = task.resolve_part(placed.family, wanted, skill)
                except ValueError as error:  # the piece does not afford the skill
                    raise BindingError(f"{where}: {error}") from None
                if part not in placed.furniture.labels:
                    if not self.settings.part_fallback:
                        raise BindingError(f"{where}: {placed.family} {placed.name!r} has no part {part!r}; "
                                           f"its parts: {list(placed.furniture.labels)}")
                    fallback = task.resolve_part(placed.family, None, skill)
                    note = f"part {wanted!r} not on {placed.family}; used {fallback!r}"
                    part = fallback
                if wanted is None:
                    part = None  # let the env pick (reach: one of the family's reachable parts)
            if skill in ("sit", "lie"):
                seat = inst
            parts.append((part, note))
        return parts

    # -- running
    def run(self, keyframes: Sequence[Any], binding: Sequence[str | None] | Mapping[int, str | None] | None = None,
            *, seed: int | None = None, reset: bool = True, start_pose: str = "standing", start_on: str | None = None,
            video: str | os.PathLike | Any | None = None, video_every: int = 1) -> StoryResult:
        """Run ``keyframes`` (``Keyframe`` objects or dicts with skill, style, caption, part, hand).

        ``seed``: ``env.reset`` seed (with ``reset``) and the seed of walk targets / reach points.
        ``start_pose``: "sitting" / "lying" seats / lays the character on ``start_on`` (default:
        the first keyframe's instance) first. ``video``: an .mp4 path, or any object with
        ``append(frame, text)`` (e.g. a :class:`VideoWriter`) that receives a frame every
        ``video_every`` steps (the MP4 plays at the env's rate / ``video_every``: offscreen
        rendering costs far more than a step). In a room the camera looks down from above the
        walls (:data:`ROOM_CAMERA`). Raises :class:`BindingError` (before stepping) for keyframes that cannot run.
        """
        if start_pose not in START_POSES:
            raise ValueError(f"start_pose must be one of {list(START_POSES)}, got {start_pose!r}")
        pairs = self.bind(keyframes, binding)
        if start_pose != "standing":
            start_on = start_on if start_on is not None else (pairs[0][1] if pairs else None)
            if start_on not in self.env.furniture:
                raise BindingError(f"start_pose {start_pose!r} needs start_on, a furniture instance of "
                                   f"{sorted(self.env.furniture)}; got {start_on!r}")
        parts = self._check(pairs, start_on if start_pose != "standing" else None)
        env, settings = self.env, self.settings
        if video is not None and env.render_mode != "rgb_array":
            raise ValueError("recording a video needs the env built with render_mode='rgb_array'")
        video_every = int(check_number("video_every", video_every, 1, 10**6))
        if video is not None and env.room is not None:
            self._room_camera()

        if reset:
            env.reset(seed=seed)
        rng = np.random.default_rng(seed)
        for policy in {id(p): p for p in self.policies.values()}.values():
            if callable(getattr(policy, "reset", None)):
                policy.reset(seed)
        seat: str | None = None
        if start_pose != "standing":
            env._place_on(env.furniture[start_on], "sit" if start_pose == "sitting" else "lie")
            seat = start_on

        writer, own_writer = video, False
        if isinstance(video, (str, os.PathLike)):
            fps = max(1, round(env.metadata["render_fps"] / video_every))
            writer, own_writer = VideoWriter(video, fps), True
        results: list[KeyframeResult] = []
        stopped = False
        self._steps_run = 0
        try:
            for i, ((kf, inst), (part, note)) in enumerate(zip(pairs, parts)):
                skill = _keyframe_field(kf, "skill")
                caption = _keyframe_field(kf, "caption") or skill
                style = _keyframe_field(kf, "style") or "neutral"
                if stopped:
                    results.append(KeyframeResult(i, skill, _keyframe_field(kf, "furniture"), inst, part, caption, style,
                                                  "skipped", False, None, None, 0.0, 0))
                    continue
                if skill == "getup" and inst is None:
                    inst = seat
                result = self._run_keyframe(i, len(pairs), kf, inst, part, pairs, rng, writer, video_every)
                result.note = note
                results.append(result)
                if skill in ("sit", "lie"):
                    seat = inst
                if not result.success and (settings.stop_on_failure or result.outcome == "unstable"):
                    stopped = True
        finally:
            if own_writer:
                writer.close()
        frames = writer.frames if own_writer else int(getattr(writer, "frames", 0) or 0)
        return StoryResult(results, room=getattr(env.room, "name", None),
                           video=str(writer.path) if own_writer else None, frames=frames,
                           policies=dict(self.policy_names))

    def _room_camera(self) -> None:
        """Look down on the character from above the walls (the default follow camera, 4.5 m
        away at -18 deg, sees mostly wall inside a room)."""
        env = self.env
        env._camera_elevation, env._camera_distance = ROOM_CAMERA
        if env._camera is not None:
            env._camera.camera.elevation, env._camera.camera.distance = ROOM_CAMERA

    def _walk_target(self, index: int, inst: str | None, pairs: Sequence[tuple[Any, str | None]],
                     rng: np.random.Generator) -> tuple[np.ndarray, str | None]:
        env = self.env
        if inst is None:  # no target of its own: the next interaction's piece, if it comes next
            for kf, nxt in pairs[index + 1:]:
                skill = _keyframe_field(kf, "skill")
                if skill == "walk":
                    break
                if skill in INTERACTIONS and nxt is not None:
                    inst = nxt
                    break
        if inst is not None:
            return env.approach_point(env.furniture[inst]), inst
        here = env.data.qpos[env._idx.qpos_root][:2].copy()
        return np.asarray(env._random_walk_target(rng, here), dtype=float), None

    def _run_keyframe(self, i: int, n: int, kf: Any, inst: str | None, part: str | None,
                      pairs: Sequence[tuple[Any, str | None]], rng: np.random.Generator, writer: Any,
                      video_every: int = 1) -> KeyframeResult:
        env, settings = self.env, self.settings
        skill = _keyframe_field(kf, "skill")
        caption = _keyframe_field(kf, "caption") or skill
        style = _keyframe_field(kf, "style") or "neutral"
        category = _keyframe_field(kf, "furniture")
        if skill == "walk":
            target, inst = self._walk_target(i, inst, pairs, rng)
            obs, info = env.set_task("walk", None, caption=caption, style=style, walk_target=target,
                                     target_speed=settings.target_speed, rng=rng)
        else:
            obs, info = env.set_task(skill, inst, part=part, hand=_keyframe_field(kf, "hand"), caption=caption,
                                     style=style, target_speed=settings.target_speed, rng=rng)
        policy = self.policies[skill]
        text = env.observation_structure["text"]
        blind = skill in settings.text_free_skills
        dwell_steps = max(1, math.ceil(settings.dwell_seconds / env.dt - 1e-9))
        max_steps = max(1, math.ceil(settings.max_seconds / env.dt - 1e-9))
        label = f"[{i + 1}/{n}] {skill} ({style}): {caption}"
        error = float(info["contact_error"])
        best = error
        streak, steps, outcome = 0, 0, "timeout"
        while steps < max_steps:
            if blind:
                obs = obs.copy()
                obs[text] = 0.0
            obs, _, _, _, info = env.step(np.asarray(policy(obs)))
            steps += 1
            if info.get("physics_unstable", False):
                outcome = "unstable"
                break
            self._steps_run += 1
            if writer is not None and self._steps_run % video_every == 0:
                writer.append(env.render(), label)
            error = float(info["contact_error"])
            best = min(best, error)
            held = error < settings.arrive_radius if skill == "walk" else bool(info["success"])
            streak = streak + 1 if held else 0
            if info["fell"]:
                outcome = "fell"
                break
            if streak >= dwell_steps:
                outcome = "success"
                break
        success = outcome == "success"
        return KeyframeResult(
            index=i, skill=skill, category=category, furniture=inst, part=env.goal.part, caption=caption,
            style=style, outcome=outcome, success=success, contact_error=error, min_contact_error=best,
            seconds=steps * env.dt, steps=steps, held_from=(steps - streak) * env.dt if success else None,
        )


# --- whole scripts and stories ---------------------------------------------------------------
def story_room(script: Any, rooms: Iterable[tuple[Any, Room]] | None = None, *, config: RoomConfig | None = None,
               seed: int | np.random.Generator | None = 0, timeout: float = 0.05) -> tuple[Room, RoomMatch]:
    """The room for a Script or Story: the best of ``rooms`` ((id, Room) pairs) by graph edit
    distance, or one generated (``generate_room``) with exactly the furniture it needs."""
    from stairenv.scripts.retrieval import retrieve_room, world_room_builder
    from stairenv.world.rooms import RoomConfig

    candidates = list(rooms or [])
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    match = retrieve_room(script, candidates, fallback=world_room_builder(config or RoomConfig(), rng),
                          timeout=timeout)
    room = match.room if match.generated else dict(candidates)[match.room_id]
    return room, match


def run_script(script: Any, policies: Mapping[str, Any] | str | None = None, *,
               rooms: Iterable[tuple[Any, Room]] | None = None, room_config: RoomConfig | None = None,
               seed: int = 0, settings: MachineSettings | None = None, env_kwargs: Mapping[str, Any] | None = None,
               video: str | os.PathLike | None = None, video_every: int = 1, width: int = 640,
               height: int = 480) -> StoryResult:
    """Run a whole :class:`~stairenv.scripts.Script` or :class:`~stairenv.scripts.Story`.

    Finds or builds its room (:func:`story_room`, seeded by ``seed``), binds the keyframes to the
    room's instances (``bind_keyframes``), builds ``SIMSEnv(skill="walk", room=room,
    **env_kwargs)`` and runs a :class:`StoryRunner`. ``policies``: skill -> policy, or one
    spec/policy for all skills (None: :data:`KINEMATIC`, the stand-in); spec strings other
    than ``KINEMATIC`` are loaded with :func:`load_skill_policies`. A script that starts
    sitting or lying starts on its first keyframe's piece. ``video``: an .mp4 path (a frame
    every ``video_every`` steps, ``width`` x ``height``). ``result.details`` records the room
    (``room_summary``), whether it was generated and the substitutions retrieval made.

    Before a room is sought, ``script`` is validated as scripts loaded from files are
    (``ScriptValidationError``; TypeError if it is not a Script or Story) and ``policies`` is
    type-checked (:func:`policy_specs`); a keyframe whose furniture the room lacks raises
    :class:`BindingError`.
    """
    from stairenv.environments.sims import SIMSEnv
    from stairenv.scripts.retrieval import bind_keyframes

    _check_runnable(script)
    specs = policy_specs(policies if policies is not None else KINEMATIC)
    room, match = story_room(script, rooms, config=room_config, seed=seed)
    pairs = bind_keyframes(script.keyframes, match)
    _check_bound(pairs)
    kwargs = dict(env_kwargs or {})
    if video is not None:
        kwargs.update(render_mode="rgb_array", width=width, height=height)
    env = SIMSEnv(skill="walk", room=room, **kwargs)
    try:
        resolved = load_skill_policies(specs, env, seed=seed)
        runner = StoryRunner(env, resolved, settings)
        scripts = getattr(script, "scripts", None) or [script]
        first = scripts[0]
        result = runner.run(pairs, seed=seed, start_pose=getattr(first, "start_pose", "standing"), video=video,
                            video_every=video_every)
    finally:
        env.close()
    result.room = room.name
    result.script_ids = [s.id for s in scripts]
    from stairenv.world.rooms import room_summary

    result.details.update(room_generated=bool(match.generated), room_distance=float(match.distance),
                          room_summary=room_summary(room),
                          substitutions={f"{q[0]}#{q[1]}": list(v) for q, v in match.substitutions.items()})
    return result


def _check_runnable(script: Any) -> None:
    """Validate a Script or Story as scripts loaded from files are (one built in code has
    skipped that): TypeError for another type, ScriptValidationError listing the problems."""
    from stairenv.scripts.database import Script
    from stairenv.scripts.schema import ScriptValidationError
    from stairenv.scripts.story import Story

    if isinstance(script, Script):
        errors, script_id = script.errors(), script.id
    elif isinstance(script, Story):
        errors, script_id = _story_errors(script), None
    else:
        hint = " (build one with Script.from_dict)" if isinstance(script, Mapping) else ""
        raise TypeError(f"script must be a Script or a Story, got {type(script).__name__}{hint}")
    if errors:
        raise ScriptValidationError(errors, script_id if isinstance(script_id, str) else None)


def _story_errors(story: Any) -> list[str]:
    """Problems of a story's scripts (they choose the room) and of the keyframes it runs."""
    from stairenv.scripts.database import Keyframe, Script
    from stairenv.scripts.schema import keyframe_sequence_errors

    scripts, keyframes = story.scripts, story.keyframes
    if not isinstance(scripts, (list, tuple)) or not scripts:
        return ["scripts: a story needs a list of at least one Script"]
    if not isinstance(keyframes, (list, tuple)):
        return [f"keyframes: expected a list of Keyframe objects, got {type(keyframes).__name__}"]
    errors = [f"scripts[{k}]: expected a Script, got {type(s).__name__}"
              for k, s in enumerate(scripts) if not isinstance(s, Script)]
    errors += [f"keyframes[{i}]: expected a Keyframe, got {type(kf).__name__}"
               for i, kf in enumerate(keyframes) if not isinstance(kf, Keyframe)]
    if errors:
        return errors
    errors = [f"scripts[{k}].{e}" for k, s in enumerate(scripts) for e in s.errors()]
    first = scripts[0]
    return errors or keyframe_sequence_errors([kf.to_dict() for kf in keyframes], first.start_pose, first.start_at)


def _check_bound(pairs: Sequence[tuple[Any, Any]]) -> None:
    """BindingError naming the first keyframe whose furniture has no item in the room."""
    for i, (kf, inst) in enumerate(pairs):
        if kf.node is not None and inst is None:
            category, instance = kf.node
            raise BindingError(f"keyframe {i} ({kf.skill} {kf.caption!r}): the room has no item for "
                               f"{category} instance {instance}")


__all__ = [
    "INTERACTIONS", "KINEMATIC", "OUTCOMES", "ROOM_CAMERA", "BindingError", "KeyframeResult", "KinematicStandIn",
    "MachineSettings", "StoryResult", "StoryRunner", "VideoWriter", "as_policy",
    "describe_policy", "load_skill_policies", "policy_specs", "run_script", "story_room",
]
