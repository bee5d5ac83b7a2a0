"""The SIMS env's starts: where a standing start stands, where a walk goes, and the interaction starts
(a training aid: a frame of the skill's clip made for the episode's piece). ``SIMSEnv`` inherits them
(``SIMSStarts``); its ``_place_character`` chooses among them."""

from __future__ import annotations

import math

import mujoco
import numpy as np

from stairenv.humanoid.placement import place_state_in_frame
from stairenv.motion import interaction_starts
from stairenv.motion.tracking import frames_in_world, track_of_frames
from stairenv.tasks import sims as task
from stairenv.world.furniture import PlacedFurniture

#: Most a start drawn from an interaction clip may press into the furniture or the floor (m), and how
#: many of its frames are tried before the episode starts as the others do.
START_PENETRATION = 0.01
START_TRIES = 4
#: Turns (rad) from facing the reach target from the piece's outside tried for a reach start, nearest first.
REACH_TURNS = (0.0, *(sign * k * math.pi / 8 for k in range(1, 8) for sign in (1.0, -1.0)), math.pi)
CONTACT_NAMES = task.CONTACT_JOINTS


class SIMSStarts:
    """The start-placement methods of ``SIMSEnv`` (a mixin: it reads the env's model, data, furniture,
    free-floor map, skill and start settings)."""

    def _random_start(self, rng: np.random.Generator, target: PlacedFurniture | None,
                      distance: tuple[float, float] | None = None) -> np.ndarray:
        """A free floor point (rooms), or one ``distance`` (default ``start_distance``) from the
        target's centre and clear of the furniture (object scenes)."""
        if self._free_xy is not None and len(self._free_xy):
            return self._free_xy[int(rng.integers(0, len(self._free_xy)))].copy()
        distance = self.start_distance if distance is None else distance
        centre = target.position if target is not None else np.zeros(2)
        found = self._clear_point(rng, centre, distance)
        if found is not None:
            return found[0]
        radius = max(max(p.furniture.footprint) for p in self.furniture.values()) + 0.5
        return centre + np.array([radius, 0.0])

    def _clear_point(self, rng: np.random.Generator, centre: np.ndarray, distance: tuple[float, float],
                     bearing: float = 0.0, spread: float = math.pi) -> tuple[np.ndarray, float] | None:
        """A point ``distance`` from ``centre`` at a bearing within ``bearing`` +- ``spread``, clear of the
        furniture, and that bearing (100 tries; None if none was clear)."""
        boxes = [p.footprint_box(margin=0.35) for p in self.furniture.values()]
        for _ in range(100):
            angle = bearing + rng.uniform(-spread, spread)
            xy = centre + rng.uniform(*distance) * np.array([math.cos(angle), math.sin(angle)])
            if not any(b.contains_xy(xy[None])[0] for b in boxes):
                return xy, angle
        return None

    def _front_start(self, rng: np.random.Generator, target: PlacedFurniture) -> tuple[np.ndarray, float]:
        """A standing start of the ``start_from_front`` curriculum: the spot where the interaction start
        stands (the seat's front edge, ``_seat_start_frames``), and from it ``episode_start_distance()``
        away at a bearing within +-180 deg x (level + 1) / N of the direction out of the front, the heading
        within as much of facing away from the piece; clear of the furniture. The top level: any bearing
        and any heading, as a plain start's."""
        _, _, facing, origin = self._seat_start_frames(rng, target, self.skill)
        spread = math.pi * (self.curriculum_level + 1) / self.start_distance_levels
        distance = self.episode_start_distance()
        found = self._clear_point(rng, origin[:2], distance, facing, spread)
        if found is not None:
            xy, bearing = found
            return xy, float(bearing + rng.uniform(-spread, spread))
        return self._random_start(rng, target, distance), float(rng.uniform(-math.pi, math.pi))

    def random_walk_target(self, rng: np.random.Generator, start: np.ndarray) -> np.ndarray:
        """(x, y) of a random walk goal ``episode_walk_distance()`` from ``start``: a free floor point
        (rooms; any free point if none is that far) or a point clear of the furniture (object scenes)."""
        low, high = self.episode_walk_distance()
        if self._free_xy is not None and len(self._free_xy):
            d = np.linalg.norm(self._free_xy - start, axis=1)
            ok = np.flatnonzero((d >= low) & (d <= high))
            pool = ok if len(ok) else np.arange(len(self._free_xy))
            return self._free_xy[int(rng.choice(pool))].copy()
        boxes = [p.footprint_box(margin=0.35) for p in self.furniture.values()]
        for _ in range(100):
            angle = rng.uniform(-math.pi, math.pi)
            xy = start + rng.uniform(low, high) * np.array([math.cos(angle), math.sin(angle)])
            if not any(b.contains_xy(xy[None])[0] for b in boxes):
                return xy
        return start.copy()

    # --- interaction starts (training aid) -------------------------------------------------------
    def _place_interaction_start(self, rng: np.random.Generator, placed: PlacedFurniture) -> bool:
        """Put the character in a frame of the skill's clip made for ``placed`` (class docstring,
        training aids); False (the data then to be overwritten) when no frame tried fits."""
        if self.skill == "reach":
            # the goal first: the clip is made for its target (``_new_goal`` then keeps it)
            self._start_goal = goal = task.contact_goal("reach", placed, rng, details=self.details)
            return self._place_reach_start(rng, goal)
        qpos, qvel, yaw, origin = self._seat_start_frames(rng, placed, self.skill)
        return self._try_start_frames(rng, qpos, qvel, yaw, origin)

    def _seat_start_frames(self, rng: np.random.Generator, placed: PlacedFurniture, skill: str):
        """The sit (or sit-and-lie) clip's frames for ``placed`` and the frame (yaw, origin) that puts
        its seat edge (x = 0) on the piece's front edge: for sit facing out of the seat's front (a bed's
        long side), for lie facing the side whose left is the pillow's end (a sofa's front)."""
        furniture = placed.furniture
        label = task.resolve_part(placed.family, None, skill)
        surface = furniture.contact_surface(label)          # furniture frame
        corners = surface.corners()
        lo, hi = corners.min(axis=0), corners.max(axis=0)
        centre, top = surface.center, float(surface.center[2])
        bed = placed.family in ("bed", "double_bed")
        axis, sign = (1, 1.0) if bed else (0, 1.0)
        pillow = None
        if skill == "lie" and "pillow" in furniture.labels:
            pillow = furniture.contact_surface("pillow", index=0)
            # the character's left (the clip's head end) is (-sign) along x facing +-y: towards the pillow
            sign = 1.0 if pillow.center[0] <= centre[0] else -1.0
        lateral = 1 - axis
        left_sign = -sign if axis == 1 else sign           # the left's direction along the lateral axis
        half_lateral = 0.5 * float(hi[lateral] - lo[lateral])
        if skill == "sit":
            spread = max(half_lateral - (0.6 if bed else 0.45), 0.0)
            along = float(centre[lateral] + rng.uniform(-spread, spread)) if spread > 0.0 else float(centre[lateral])
        else:
            edge = float(hi[axis] if sign > 0 else lo[axis])
            offset = abs(edge - float(centre[axis]))
            pillow_height = 0.0 if pillow is None else max(p.vertices[:, 2].max() for p in furniture.parts("pillow")) - top
            qpos, qvel, head = interaction_starts.lie_frames(top, offset, pillow_height)
            # the head ends over the pillow's centre; without one the body (about -1.0 .. +0.8 m along
            # the clip's y from the pelvis) is centred on the surface
            along = (float(pillow.center[lateral]) - left_sign * float(head[1]) if pillow is not None
                     else float(centre[lateral]) + left_sign * 0.1)
        # the front: the outermost face, along the facing axis, of the parts below the seat across the body
        front = sign * float(hi[axis] if sign > 0 else lo[axis])
        for part in furniture.part_list:
            v = part.vertices
            if v[:, 2].max() <= top + 0.01 and v[:, lateral].min() < along + 0.25 and v[:, lateral].max() > along - 0.25:
                front = max(front, float((sign * v[:, axis]).max()))
        if skill == "sit":
            qpos, qvel = interaction_starts.sit_frames(top)
        origin_local = np.zeros(3)
        origin_local[axis], origin_local[lateral] = sign * front, along
        facing = placed.rotation @ (sign * np.eye(3)[axis])
        return qpos, qvel, math.atan2(facing[1], facing[0]), placed.to_world(origin_local[None])[0]

    def _place_reach_start(self, rng: np.random.Generator, goal: task.ContactGoal) -> bool:
        """Stand 0.45-0.75 m from the reach target, facing it from the piece's outside (turned by up to
        180 deg, nearest first, where that side is blocked), in a frame of a reach made for it."""
        hand = CONTACT_NAMES[goal.primary].removesuffix("_hand")
        target = goal.root_target
        out = target[:2] - self._target.position
        if np.hypot(*out) < 1e-6:
            out = (self._target.rotation @ np.array([1.0, 0.0, 0.0]))[:2]
        base = math.atan2(-out[1], -out[0])
        side = interaction_starts.REACH_SIDE * (-1.0 if hand == "right" else 1.0)
        for ahead in interaction_starts.REACH_AHEAD:
            frames = interaction_starts.reach_frames(ahead, float(target[2]), hand)
            if frames is None:
                continue
            qpos, qvel, _ = frames
            for turn in REACH_TURNS:
                yaw = base + turn
                c, s = math.cos(yaw), math.sin(yaw)
                origin = np.array([target[0] - (c * ahead - s * side), target[1] - (s * ahead + c * side), 0.0])
                # the stance and the hold pose must fit before frames are drawn
                if all(self._start_fits(qpos[k], qvel[k], yaw, origin) for k in (0, len(qpos) - 1)):
                    return self._try_start_frames(rng, qpos, qvel, yaw, origin)
        return False

    def _try_start_frames(self, rng: np.random.Generator, qpos: np.ndarray, qvel: np.ndarray, yaw: float,
                          origin: np.ndarray) -> bool:
        """Up to ``START_TRIES`` frames drawn uniformly until one fits (it stays placed)."""
        for _ in range(START_TRIES):
            k = int(rng.integers(len(qpos)))
            if self._start_fits(qpos[k], qvel[k], yaw, origin):
                self._start = self.data.qpos[self._idx.qpos_root][:2].copy()
                if self._tracking_on:  # the tracking aid follows the clip's frames from here on, in the world
                    self._track = track_of_frames(frames_in_world(qpos[k:], yaw, origin), self.dt)
                return True
        return False

    def _start_fits(self, qpos: np.ndarray, qvel: np.ndarray, yaw: float, origin: np.ndarray) -> bool:
        """Place the state (given in the frame ``yaw``, ``origin``), servos holding it; whether it presses
        at most ``START_PENETRATION`` into anything but itself."""
        model, data = self.model, self.data
        place_state_in_frame(model, data, self._idx, qpos.astype(np.float64), qvel.astype(np.float64), yaw,
                             origin, lift=0.0)
        self._hold_pose_ctrl()
        mujoco.mj_forward(model, data)
        return self.start_penetration() <= START_PENETRATION

    def start_penetration(self) -> float:
        """The deepest contact (m) between the character and anything else (furniture, walls, floor) in
        the current state (after ``mj_forward``); 0 when none presses in."""
        data, ours = self.data, self._humanoid_geom_mask
        n = data.ncon
        if n == 0:
            return 0.0
        geoms = data.contact.geom[:n]
        other = ours[geoms[:, 0]] != ours[geoms[:, 1]]
        return float(max(0.0, -data.contact.dist[:n][other].min())) if other.any() else 0.0
