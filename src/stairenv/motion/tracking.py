"""A clip as a reference to track: played on from a start frame, placed where the character started.

DeepMimic-style imitation compares the character, step by step, with its reference clip played on
from the frame the episode started in (reference-state initialisation). ``reference_track`` gives
that reference for one episode as arrays at the env's step rate, in the world:

- the clip is played on from ``start_time``; a looping clip (``clip.loop``) carries on cycle after
  cycle, each cycle's root moved on by one cycle's travel (DeepMimic's cycle offset), so a crawl keeps
  crawling forwards; a clip that does not loop holds its last frame; ``rate`` plays it faster or
  slower and ``turn_rate`` bends its course (``bend``);
- the frames are moved rigidly (a turn about z and a shift) so that the start frame's root lies on
  the root the character was placed with (``placement.place_reference_state`` turns the start frame
  to the start heading and rests it on the floor): the track starts where the character is;
- forward kinematics gives every body's position and the head's centre, yaw and pitch.

The env's tracking terms (``stairenv.tasks.terms.tracking_terms``) and its path made from the clip's
head (``clip_path``) read these arrays.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from stairenv.humanoid.kinematics import body_poses
from stairenv.humanoid.model import BODY_NAMES, HEAD_CENTRE_OFFSET, humanoid_model
from stairenv.motion.clip import MotionClip


@dataclass(frozen=True)
class ReferenceTrack:
    """One episode's reference, frame k at time k * dt after the start (world frame)."""

    qpos: np.ndarray      # (T, 35) placed frames
    body_pos: np.ndarray  # (T, 15, 3) body positions, BODY_NAMES order
    root_vel: np.ndarray  # (T, 3) the root's linear velocity (central differences)
    head: np.ndarray      # (T, 3) the head sphere's centre
    head_yaw: np.ndarray  # (T,) the head's forward axis: yaw
    head_pitch: np.ndarray  # (T,) ... and pitch
    dt: float

    def frame(self, step: int) -> int:
        """The row of step ``step`` (the last row after the track's end)."""
        return min(max(int(step), 0), len(self.qpos) - 1)


def _yaw_of(quat_wxyz: np.ndarray) -> np.ndarray:
    """The yaw of the body x axis of (..., 4) w, x, y, z quaternions."""
    forward = Rotation.from_quat(np.asarray(quat_wxyz, dtype=np.float64), scalar_first=True).apply([1.0, 0.0, 0.0])
    return np.arctan2(forward[..., 1], forward[..., 0])


def yaw_between(quat_from: np.ndarray, quat_to: np.ndarray) -> float:
    """The turn about z (rad) taking the w, x, y, z rotation ``quat_from`` onto ``quat_to``: the yaw of
    their relative rotation, well defined even where the body's own x axis points up or down (a crawl's
    pelvis), unlike the difference of the two bodies' x-axis yaws."""
    relative = (Rotation.from_quat(np.asarray(quat_to, dtype=np.float64), scalar_first=True)
                * Rotation.from_quat(np.asarray(quat_from, dtype=np.float64), scalar_first=True).inv())
    x_axis = relative.apply([1.0, 0.0, 0.0])
    return float(np.arctan2(x_axis[1], x_axis[0]))


def turn_frames(qpos: np.ndarray, angle: float | np.ndarray, pivot: np.ndarray, to: np.ndarray) -> np.ndarray:
    """Frames ``qpos`` (T, 35) turned about z by ``angle`` (a scalar or (T,)) around ``pivot`` (x, y), the
    pivot moved to ``to`` (x, y); joints and heights unchanged."""
    out = qpos.copy()
    angle = np.broadcast_to(np.asarray(angle, dtype=np.float64), (len(qpos),))
    c, s = np.cos(angle), np.sin(angle)
    dx, dy = qpos[:, 0] - pivot[0], qpos[:, 1] - pivot[1]
    out[:, 0] = to[0] + c * dx - s * dy
    out[:, 1] = to[1] + s * dx + c * dy
    turn = Rotation.from_euler("z", angle[:, None])
    out[:, 3:7] = (turn * Rotation.from_quat(qpos[:, 3:7], scalar_first=True)).as_quat(scalar_first=True)
    return out


def clip_frames(clip: MotionClip, start_time: float, steps: int, dt: float) -> np.ndarray:
    """``steps`` + 1 frames (qpos) of ``clip`` played on from ``start_time`` every ``dt`` seconds, in the
    clip's own frame: a looping clip carried on cycle after cycle, each cycle's root moved on by one
    cycle's horizontal travel (the last frame's root less the first's) and not turned, as DeepMimic plays
    its loops (``cMotionController::CalcRootCycleOffset``): a loop whose last frame faces a little otherwise
    than its first (DeepMimic's jog by 0.11 rad, its crawl by 0.18) keeps its course rather than circling.
    Other clips are held at their last frame."""
    times = start_time + dt * np.arange(steps + 1)
    if not clip.loop or clip.num_frames < 2:
        return clip.sample(times)
    duration = clip.duration
    cycles = np.floor(times / duration).astype(int)
    frames = clip.sample(times - cycles * duration)
    travel = clip.qpos[-1, :2] - clip.qpos[0, :2]
    frames[:, :2] += cycles[:, None] * travel
    return frames


def bend(qpos: np.ndarray, turn_rate: float, dt: float) -> np.ndarray:
    """Frames ``qpos`` (T, 35), ``dt`` apart, bent onto a path that turns at ``turn_rate`` (rad/s, left > 0):
    frame k is turned about z by ``turn_rate * k * dt``, and so is the root's step to it from frame k - 1,
    so the motion's own sway and pace are kept while its course curves (a path edit of the kind motion
    graphs use). Frame 0 is unchanged; joints and heights are untouched."""
    out = qpos.copy()
    if turn_rate == 0.0 or len(qpos) < 2:
        return out
    theta = turn_rate * dt * np.arange(len(qpos))
    step = np.diff(qpos[:, :2], axis=0)
    c, s = np.cos(theta[1:]), np.sin(theta[1:])
    turned = np.column_stack((c * step[:, 0] - s * step[:, 1], s * step[:, 0] + c * step[:, 1]))
    out[1:, :2] = qpos[0, :2] + np.cumsum(turned, axis=0)
    turn = Rotation.from_euler("z", theta[:, None])
    out[:, 3:7] = (turn * Rotation.from_quat(qpos[:, 3:7], scalar_first=True)).as_quat(scalar_first=True)
    return out


def reference_track(clip: MotionClip, start_time: float, steps: int, dt: float,
                    placed_root: np.ndarray, rate: float = 1.0, turn_rate: float = 0.0) -> ReferenceTrack:
    """The reference of an episode started from ``clip`` at ``start_time`` with the root placed at
    ``placed_root`` (the free joint's 7 qpos: x, y, z, w, qx, qy, qz), ``steps`` + 1 frames ``dt`` apart:
    the clip played ``rate`` times as fast (a faster crawl: the same poses, a quicker cadence) and bent to
    turn at ``turn_rate`` rad/s (``bend``); 1 and 0 play it as it is."""
    frames = clip_frames(clip, start_time, steps, dt * rate)
    if turn_rate:
        frames = bend(frames, turn_rate, dt)
    placed_root = np.asarray(placed_root, dtype=np.float64)
    angle = yaw_between(frames[0, 3:7], placed_root[3:7])
    qpos = turn_frames(frames, angle, frames[0, :2], placed_root[:2])
    qpos[:, 2] += placed_root[2] - frames[0, 2]
    return track_of_frames(qpos, dt)


def track_of_frames(qpos: np.ndarray, dt: float) -> ReferenceTrack:
    """The reference of frames ``qpos`` (T, 35) already in the world, ``dt`` apart: forward kinematics for
    the bodies and the head, central differences for the root's velocity."""
    qpos = np.asarray(qpos, dtype=np.float64)
    model = humanoid_model()
    ids = [model.body(name).id for name in BODY_NAMES]
    head_id = model.body("head").id
    xpos, xmat = body_poses(qpos)
    head_mat = xmat[:, head_id].reshape(-1, 3, 3)
    head = xpos[:, head_id] + head_mat @ HEAD_CENTRE_OFFSET
    forward = head_mat[:, :, 0]
    root_vel = np.gradient(qpos[:, :3], dt, axis=0) if len(qpos) > 1 else np.zeros((1, 3))
    return ReferenceTrack(qpos=qpos, body_pos=xpos[:, ids], root_vel=root_vel, head=head,
                          head_yaw=np.arctan2(forward[:, 1], forward[:, 0]),
                          head_pitch=np.arctan2(forward[:, 2], np.hypot(forward[:, 0], forward[:, 1])), dt=dt)


def frames_in_world(qpos: np.ndarray, yaw: float, origin: np.ndarray) -> np.ndarray:
    """Frames ``qpos`` (T, 35) given in a local frame (turned by ``yaw`` about z, its origin at world
    ``origin``) in the world, as ``humanoid.placement.place_state_in_frame`` places one (without lift)."""
    out = turn_frames(np.asarray(qpos, dtype=np.float64), yaw, np.zeros(2), np.asarray(origin, dtype=np.float64)[:2])
    out[:, 2] += float(origin[2])
    return out


def track_speed(track: ReferenceTrack) -> np.ndarray:
    """(T,) the head's horizontal speed along the track (m/s)."""
    if len(track.head) < 2:
        return np.zeros(len(track.head))
    return np.hypot(*np.gradient(track.head[:, :2], track.dt, axis=0).T)


__all__ = ["ReferenceTrack", "bend", "clip_frames", "frames_in_world", "reference_track", "track_of_frames",
           "track_speed", "turn_frames", "yaw_between"]
