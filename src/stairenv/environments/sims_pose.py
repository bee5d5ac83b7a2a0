"""The SIMS env's pose API: the character's pose read and written, furniture to sit or lie on, the floor
to plan on. What a scripted controller (``stairenv.stories``: the kinematic stand-in, the state machine)
uses besides ``reset`` and ``step``; ``SIMSEnv`` inherits it (``ScenePoseAPI``), and its get-up starts
(``place_on``) use it too."""

from __future__ import annotations

import math

import mujoco
import numpy as np
from scipy import ndimage
from scipy.spatial.transform import Rotation

from stairenv.humanoid import DOF_NAMES
from stairenv.humanoid.kinematics import humanoid_lowest_z
from stairenv.planning.grid import PlanningGrid
from stairenv.tasks import sims as task
from stairenv.world.furniture import PlacedFurniture

_DOF = {name: k for k, name in enumerate(DOF_NAMES)}

def seated_joint_angles() -> np.ndarray:
    """(28,) a sitting pose: hips flexed 90 deg, knees 90 deg, elbows slightly bent."""
    q = np.zeros(len(DOF_NAMES))
    for side in ("right", "left"):
        q[_DOF[f"{side}_hip_y"]] = -math.pi / 2
        q[_DOF[f"{side}_knee"]] = math.pi / 2
        q[_DOF[f"{side}_elbow"]] = -0.4
    return q

def surface_hi(surface, placed: PlacedFurniture) -> np.ndarray:
    """Largest furniture-frame (x, y) of a world contact surface's corners."""
    return placed.to_local(surface.corners()).max(axis=0)


class ScenePoseAPI:
    """The pose and scene methods of ``SIMSEnv`` (a mixin: it reads the env's model, data, ``_idx``,
    ``_geoms``, room, furniture and free-floor map)."""

    def free_floor_point(self, xy: np.ndarray) -> np.ndarray:
        """``xy`` where it is on free floor (or the scene has no free map: an object scene), else the centre of
        the nearest free cell of the room: where a character getting up from a chair at a table stands (the
        point in front of the chair lies in the table)."""
        if self._free_xy is None or not len(self._free_xy):
            return np.array(xy, dtype=float)
        k, squared = self._nearest_free_cell(xy)
        return np.array(xy, dtype=float) if squared <= 0.5 * self._free_cell ** 2 else self._free_xy[k].copy()

    def _nearest_free_cell(self, xy: np.ndarray) -> tuple[int, float]:
        """The room's free cell nearest ``xy``: its index in ``_free_xy`` and squared distance."""
        d = np.sum(np.square(self._free_xy - xy), axis=1)
        k = int(np.argmin(d))
        return k, float(d[k])

    def approach_point(self, placed: PlacedFurniture, distance: float = 0.45) -> np.ndarray:
        """(x, y) where a character stands to use ``placed``: in front of it, on free floor if known."""
        point = task.standing_point(placed, task.resolve_part(placed.family, None, "reach"), distance)[:2]
        if self._free_xy is not None and len(self._free_xy):
            point = self._free_xy[self._nearest_free_cell(point)[0]].copy()    # the caller's own, not a row
        return np.asarray(point, dtype=float)

    def pose(self) -> np.ndarray:
        """(35,) the character's pose: root position (3), root orientation (quaternion w, x, y, z)
        and the 28 joint angles (``DOF_NAMES`` order)."""
        idx = self._idx
        return np.concatenate((self.data.qpos[idx.qpos_root], self.data.qpos[idx.qpos_joints]))

    def set_pose(self, q: np.ndarray) -> None:
        """Put the character in pose ``q`` (as :meth:`pose` gives) at rest (zero velocities) and
        update the derived quantities (``mj_forward``). Not physics: a scripted controller's write."""
        idx, data = self._idx, self.data
        data.qpos[idx.qpos_root] = q[:7]
        data.qpos[idx.qpos_joints] = q[7:]
        data.qvel[idx.qvel_root] = 0.0
        data.qvel[idx.qvel_joints] = 0.0
        mujoco.mj_forward(self.model, data)

    def pose_action(self, q: np.ndarray) -> np.ndarray:
        """The action (float32 in [-1, 1]) whose PD targets are the joint angles of pose ``q``."""
        return np.clip((q[7:] - self._ctrl_offset) / self._ctrl_scale, -1.0, 1.0).astype(np.float32)

    def pose_kinematics(self, q: np.ndarray, data: mujoco.MjData) -> float:
        """Write pose ``q`` into ``data`` (a scratch ``MjData`` of ``self.model``; its other entries
        are kept), run ``mj_kinematics`` on it and return the character's lowest point (m) there."""
        idx = self._idx
        data.qpos[idx.qpos_root], data.qpos[idx.qpos_joints] = q[:7], q[7:]
        mujoco.mj_kinematics(self.model, data)
        return humanoid_lowest_z(self.model, data, self._geoms)

    def joint_limits(self) -> tuple[np.ndarray, np.ndarray]:
        """(low, high), each (28,): the joint angle ranges (rad) in ``DOF_NAMES`` order."""
        low, high = self._joint_limits
        return low.copy(), high.copy()

    def planning_grid(self, body_radius: float | None = None) -> PlanningGrid:
        """The scene's floor as a ``stairenv.planning`` grid for a character of ``body_radius`` (m):
        ``blocked`` where it cannot stand, flat ground, open sky. A room: its free space
        (``Room.free_space``; None: the room's body radius); an object scene: the cells of the
        height grid at least ``body_radius`` (None: 0.25) from any surface above 3 cm (off the
        grid the floor is open)."""
        if self.room is not None:
            space = self.room.free_space(body_radius=body_radius)
            free, origin, cell = space.free, space.origin, space.cell_size
        else:
            heights = self._heights
            blocked = heights.heights > 0.03
            dist = ndimage.distance_transform_edt(~blocked) * heights.cell_size
            free = dist - 0.5 * heights.cell_size >= (0.25 if body_radius is None else body_radius)
            origin, cell = heights.origin, heights.cell_size
        return PlanningGrid(np.zeros(free.shape), ~free, np.full(free.shape, np.inf), float(cell), origin)

    def place_on(self, placed: PlacedFurniture, pose: str) -> None:
        """Seat the character on (``pose="sit"``) or lay it on (``"lie"``) ``placed``, resting on it."""
        model, data = self.model, self.data
        label = task.resolve_part(placed.family, None, "lie" if pose == "lie" else "sit")
        surface = placed.contact_surface(label)
        centre_local = placed.to_local(surface.center[None])[0]
        joints = np.zeros(len(DOF_NAMES))
        if pose == "sit":
            joints = seated_joint_angles()
            bed = placed.family in ("bed", "double_bed")
            # sit 0.3 m inside the front edge (beds: the long side), facing out
            # 0.3 m inside the front edge, less on shallow seats (the back must not hit the backrest)
            axis = 1 if bed else 0
            depth = float(np.ptp(placed.to_local(surface.corners())[:, axis]))
            inset = min(0.3, max(depth - 0.12, 0.5 * depth))
            local = centre_local.copy()
            local[axis] = surface_hi(surface, placed)[axis] - inset
            local[2] = 0.0
            facing_local = np.eye(3)[axis]
            facing = placed.rotation @ facing_local
            rot = Rotation.from_euler("z", math.atan2(facing[1], facing[0]))
        else:
            # head towards the pillow (beds) or along the longer side of the surface (sofas: +y)
            if "pillow" in placed.furniture.labels:
                pillow = placed.furniture.contact_surface("pillow", index=0).center
                head_local = pillow - centre_local
                head_local[2] = 0.0
                head_local /= max(np.linalg.norm(head_local), 1e-9)
            else:
                head_local = np.array([0.0, 1.0, 0.0])
            local = centre_local - 0.1 * head_local
            h = placed.rotation @ head_local
            up = np.array([0.0, 0.0, 1.0])
            rot = Rotation.from_matrix(np.column_stack((up, np.cross(h, up), h)))
        world = placed.to_world(local[None])[0]
        data.qpos[self._idx.qpos_root] = (world[0], world[1], surface.center[2] + 0.12, *rot.as_quat(scalar_first=True))
        data.qpos[self._idx.qpos_joints] = joints
        self._rest_on_contacts(placed.name)
        self._hold_pose_ctrl()
        mujoco.mj_forward(model, data)


    def resting_pose(self, placed: PlacedFurniture, pose: str) -> np.ndarray:
        """The pose (as :meth:`pose` gives) that ``place_on(placed, pose)`` puts the character in,
        computed on the live data, which is then restored (the character does not move)."""
        data = self.data
        saved = data.qpos.copy(), data.qvel.copy(), data.ctrl.copy()
        self.place_on(placed, pose)
        q = self.pose()
        data.qpos[:], data.qvel[:], data.ctrl[:] = saved
        mujoco.mj_forward(self.model, data)
        return q

    def _rest_on_contacts(self, body_name: str, iterations: int = 20) -> None:
        """Raise the character until it no longer penetrates the floor or the piece ``body_name``
        (then 2 mm of clearance). Other pieces (a table a chair stands at) are ignored: rising
        over them would put the character on the table."""
        model, data = self.model, self.data
        support = {model.body(body_name).id, 0}
        for _ in range(iterations):
            mujoco.mj_forward(model, data)
            depth = 0.0
            for c in data.contact[:data.ncon]:
                ours = self._humanoid_geom_mask[c.geom1], self._humanoid_geom_mask[c.geom2]
                if ours[0] == ours[1]:
                    continue
                other = c.geom2 if ours[0] else c.geom1
                if model.geom_bodyid[other] in support:
                    depth = max(depth, -c.dist)
            if depth <= 0.0:
                break
            data.qpos[self._idx.qpos_root.start + 2] += depth + 0.002
        lowest = humanoid_lowest_z(model, data, self._geoms)
        if lowest < 0.002:
            data.qpos[self._idx.qpos_root.start + 2] += 0.002 - lowest
