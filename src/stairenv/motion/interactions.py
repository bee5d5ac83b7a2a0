"""Kinematic reference motion for the SIMS interaction skills: sit, stand up, lie, get up, reach, idle.

No licensed clip shows *our* skeleton sitting down or lying on a bed, so, like the walks and
stair climbs of :mod:`stairenv.motion.synthesis`, the AMP style reward's interaction clips are
synthesised: deterministic, pure functions of a few parameters (numpy + scipy; body sizes and
joint limits read off the compiled ``xml/humanoid.xml``). The legs use the analytic leg IK
shared with synthesis (:func:`stairenv.motion.ik.leg_ik`), the arms an analytic shoulder +
elbow IK written here.

How the clips are made
----------------------
* **Keyframed paths.** Each motion is a few phases joined by quintic smoothsteps (zero
  velocity and acceleration at every phase boundary): clips start and end at rest.
* **Legs.** Planted feet stay exactly where they are (flat, soles 2 mm above the floor, as in
  synthesis); each ankle is placed under its hip (lateral offset 0.084 m), so the legs move
  in the pelvis' sagittal planes and the 3-axis hips never pass near their XYZ-Euler
  singularity sideways (hip flexion crosses 90 degrees when sitting); hip angles are
  unwrapped frame to frame onto one Euler branch.
* **Arms.** Analytic IK: elbow flexion from the shoulder-hand distance (saturating smoothly
  beyond 90% of the arm's length, so the elbow never snaps straight), the elbow pointing
  as close as it can to a hint direction (back, out and down by default), the 3-axis
  shoulder angles unwrapped frame to frame.
* **Balance.** Sitting down, the pelvis lands on the front of the seat (at most 8 cm behind
  the edge) and then slides back; standing up, it slides forward before it lifts off. The
  trunk lean at that moment is solved (bisection on the centre of mass, MuJoCo kinematics)
  so that the body's mass is 2 cm ahead of the heels; the seated feet are chosen tucked
  enough (ankles at most 0.18 m ahead of the pelvis at lift-off) for this to need 35-45
  degrees of lean (up to about 55 with the hands on the seat). Reaching, the pelvis shifts
  back to keep the mass over the feet.
* **Resting contacts.** Bodies that rest on a surface (pelvis on a seat; back, head, legs and
  hands on a bed) float ``_REST_GAP`` (2 mm, the sole gap) above it: no initial penetration
  when a simulation starts from a reference state. The tests measure the penetration into
  the furniture box with MuJoCo (< 1 cm at every frame; about 2 mm at most, where the
  thighs of a character on a 0.65 m seat rest on its edge).

Conventions (all clips: z up, lengths in metres, clip format of :mod:`stairenv.motion.clip`)
-------------------------------------------------------------------------------------------
* **Seat** (:func:`sit_down`, :func:`stand_up`): a box whose top is at ``seat_height`` and
  whose front edge is the line x = 0; the seat extends over x < 0 (``meta["furniture"]``: a
  ``seat_depth`` x 0.6 m top centred on y = 0, standing on the floor). The character faces
  +x with its back to the seat, its feet planted side by side in front of the edge (ankles at
  x = ``meta["feet_x"]``, 0.05-0.2 m; y = +-0.084); standing, the pelvis is 3 cm ahead of
  the ankles. Seated, the pelvis centre rests ``pelvis radius + 2 mm`` above the seat,
  ``sit_depth`` behind the front edge (less on seats above about 0.45 m: the thighs slope
  down steeply there and would press into the edge; 2 cm at 0.65 m), the thighs sloping down
  to rest on the edge (low seats: nearly level, 1-3 cm above it), the shins leaning forward
  (feet a little tucked), the hands on the thighs (or on the seat). ``meta["seat_pose"]``
  gives the pose.
* **Bed / sofa** (:func:`lie_down`, :func:`get_up_from_lying`): a box whose top is at
  ``surface_height``, long side (front edge) on x = 0, extending over x < 0 (at least
  ``lie_offset`` + 0.35 m deep) and along y (the body spans about y = -1.0 .. +0.8;
  ``meta["furniture"]``: ``lie_offset`` + 0.45 m deep, 2.1 m long). The clip starts seated
  on the front edge (the end pose of :func:`sit_down` for the same height) and ends lying on
  the back along +y: head towards +y (the character's left while seated), pelvis at (x, y) =
  (-``lie_offset``, 0), the body's left side towards the edge, hands beside the hips, the
  same body frame as ``SIMSEnv`` lays a character on a bed. ``pillow_height`` raises the
  head's resting height (the pillow itself is not in ``meta["furniture"]``).
* **Reach** (:func:`reach`): standing, pelvis above the origin, facing +x, ankles at
  (-0.03, +-0.084); ``target`` is the hand centre's goal (x, y, z) in that frame.
* **Idle** (:func:`idle`): standing as for reach; a looping clip.

Every clip has ``meta``: ``generator``, ``parameters``, ``text`` (a short caption for
text-conditioned AMP), ``skill`` (one of :data:`SKILLS`), ``stance_frames`` and
``push_off_frames`` as in synthesis (inclusive [first, last] ranges of frames in which each
foot is planted flat; no push-offs here), and where it applies ``furniture`` (the box the
clip was made for: ``center``, ``half_size``, ``top``) and ``rest_frames`` (frames in which
the pelvis rests on it). :func:`interaction_reference_set` makes the default set (15 clips,
about 50 s of motion, in about a second).

Joint signs (synthesis' module docstring): hip y < 0 swings the thigh forward, knee > 0 bends
the shin back, ankle y > 0 points the toes down, shoulder y < 0 swings the arm forward,
elbow < 0 bends the forearm forward, abdomen y > 0 and root pitch > 0 lean the trunk forward.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.spatial.transform import Rotation

from stairenv.humanoid import DOF_NAMES, humanoid_model
from stairenv.humanoid.kinematics import forward_kinematics, lowest_body_point
from stairenv.motion.clip import MotionClip
from stairenv.motion.contacts import FLAT, clip_meta
from stairenv.motion.ik import LEFT, RIGHT, SIDE_SIGN, SOLE_GAP, dof_index, leg_geometry, leg_ik
from stairenv.motion.profiles import smoothstep
from stairenv.validation import check_choice, check_number

__all__ = [
    "SKILLS",
    "get_up_from_lying",
    "idle",
    "interaction_reference_set",
    "lie_down",
    "reach",
    "sit_down",
    "stand_up",
]

SOURCE = "stairenv.motion.interactions"
SKILLS: tuple[str, ...] = ("sit", "lie", "reach", "getup", "idle")

_REST_GAP = SOLE_GAP           # resting bodies float this far above the furniture (m)
_STAND_HEIGHT = 0.87           # pelvis height standing still (knees slightly soft)
_STAND_PELVIS_AHEAD = 0.03     # pelvis this far ahead of the ankles standing (over mid-foot)
_RANGE_TOLERANCE = math.radians(0.5)
_ARM_SOFT = 0.93               # share of the arm's length the hand reaches exactly ...
_ARM_MAX = 0.995               # ... and the most it stretches to for targets beyond
_SEAT_HEIGHTS = (0.35, 0.65)
_SURFACE_HEIGHTS = (0.35, 0.65)
_REACH_HEIGHTS = (0.4, 1.6)


# --- the body ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Body:
    """Upper-body dimensions from the compiled model (metres)."""

    pelvis_radius: float
    torso: np.ndarray        # torso body in the pelvis frame
    neck: np.ndarray         # head body in the torso frame
    head_centre: float       # head sphere above the neck joint
    head_radius: float
    shoulder: np.ndarray     # left shoulder in the torso frame (the right one mirrors y)
    upper_arm: float         # shoulder to elbow
    forearm: float           # elbow to hand centre
    hand_radius: float
    mass: float


@lru_cache(maxsize=1)
def _body() -> _Body:
    model = humanoid_model()
    return _Body(
        pelvis_radius=float(model.geom("pelvis").size[0]),
        torso=model.body("torso").pos.copy(),
        neck=model.body("head").pos.copy(),
        head_centre=float(model.geom("head").pos[2]),
        head_radius=float(model.geom("head").size[0]),
        shoulder=model.body("left_upper_arm").pos.copy(),
        upper_arm=float(-model.body("left_lower_arm").pos[2]),
        forearm=float(-model.body("left_hand").pos[2]),
        hand_radius=float(model.geom("left_hand").size[0]),
        mass=float(model.body_subtreemass[model.body("pelvis").id]),
    )


def _ramp(t: np.ndarray, start: float, end: float) -> np.ndarray:
    """Quintic 0 -> 1 over [start, end] (a step at ``start`` if the interval is empty)."""
    if end <= start:
        return (np.asarray(t) >= start).astype(float)
    return smoothstep((np.asarray(t, dtype=float) - start) / (end - start))


def _bump(t: np.ndarray, start: float, peak: float, end: float) -> np.ndarray:
    """0 -> 1 over [start, peak], 1 -> 0 over [peak, end]."""
    return _ramp(t, start, peak) * (1.0 - _ramp(t, peak, end))


def _euler_candidates(rot: Rotation) -> np.ndarray:
    """(N, 2, 3): the two intrinsic XYZ solutions of each rotation (see ``clip.euler_near``)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # gimbal lock: scipy sets the third angle to zero, fine here
        first = rot.as_euler("XYZ")
    second = first + np.array([np.pi, 0.0, np.pi])
    second[:, 1] = np.pi - first[:, 1]
    return np.stack((first, second), axis=1)


def _euler_near_reference(rot: Rotation, reference: np.ndarray) -> np.ndarray:
    """XYZ angles (N, 3) of ``rot``: per frame the solution (and 2 pi wrap) nearest ``reference``."""
    cands = _euler_candidates(rot)
    cands = cands + 2.0 * np.pi * np.round((reference[:, None, :] - cands) / (2.0 * np.pi))
    k = np.argmin(np.sum((cands - reference[:, None, :]) ** 2, axis=2), axis=1)
    return cands[np.arange(len(cands)), k]


def _continuous_euler(rot: Rotation, start: np.ndarray) -> np.ndarray:
    """XYZ angles (N, 3) of ``rot``, each frame the solution (and 2 pi wrap) nearest the previous
    frame's, the first nearest ``start``: no jumps between Euler branches."""
    cands = _euler_candidates(rot)
    out = np.empty((len(cands), 3))
    ref = np.asarray(start, dtype=float)
    for t in range(len(cands)):
        c = cands[t] + 2.0 * np.pi * np.round((ref - cands[t]) / (2.0 * np.pi))
        k = int(np.argmin(np.sum((c - ref) ** 2, axis=1)))
        out[t] = ref = c[k]
    return out


def _xyz(angles: np.ndarray) -> Rotation:
    return Rotation.from_euler("XYZ", angles)


# --- kinematics of the trunk and the arms --------------------------------------------------------
def _torso_frame(pelvis_pos: np.ndarray, pelvis_rot: Rotation, abdomen: np.ndarray) -> tuple[np.ndarray, Rotation]:
    """World position and orientation of the torso body."""
    body = _body()
    return pelvis_pos + pelvis_rot.apply(body.torso), pelvis_rot * _xyz(abdomen)


def _shoulder_world(torso_pos: np.ndarray, torso_rot: Rotation, side: int) -> np.ndarray:
    offset = _body().shoulder * np.array([1.0, SIDE_SIGN[side], 1.0])
    return torso_pos + torso_rot.apply(offset)


def _arm_ik(target: np.ndarray, torso_pos: np.ndarray, torso_rot: Rotation, side: int,
            start: np.ndarray | None = None, elbow_hint: Sequence[float] | np.ndarray = (-1.0, 0.5, -0.5)
            ) -> tuple[np.ndarray, np.ndarray]:
    """Shoulder XYZ angles (T, 3) and elbow angle (T,) putting the hand centre at ``target``
    (T, 3, world), for the torso pose given.

    Elbow flexion follows from the shoulder-hand distance (targets within ``_ARM_SOFT`` of the
    arm's length are reached exactly, farther ones approached along the line); the elbow points as close as it can to
    ``elbow_hint`` (thorax frame, lateral component outward for either arm; default back, out
    and down; one for all frames or (T, 3)), and the 3-axis shoulder angles are unwrapped from ``start`` frame to frame.
    """
    body = _body()
    l1, l2 = body.upper_arm, body.forearm
    shoulder = _shoulder_world(torso_pos, torso_rot, side)
    p = torso_rot.inv().apply(np.asarray(target, dtype=float) - shoulder)   # thorax frame
    dist = np.linalg.norm(p, axis=1)
    d = p / np.maximum(dist, 1e-9)[:, None]
    # Beyond _ARM_SOFT of the arm's length the distance saturates smoothly (its slope falls
    # linearly from 1 to 0 over twice the remaining margin) at _ARM_MAX of it: the elbow
    # neither snaps straight nor stops dead as a target moves out of reach.
    soft, top = _ARM_SOFT * (l1 + l2), _ARM_MAX * (l1 + l2)
    width = 2.0 * (top - soft)
    over = np.clip(dist - soft, 0.0, width)
    dist = np.where(dist > soft, soft + over - over**2 / (2.0 * width), dist)
    dist = np.maximum(dist, abs(l1 - l2) + 1e-6)
    elbow = -np.arccos(np.clip((dist**2 - l1**2 - l2**2) / (2.0 * l1 * l2), -1.0, 1.0))
    s = (l1**2 - l2**2 + dist**2) / (2.0 * dist)          # elbow circle: centre s d, radius rho
    rho = np.sqrt(np.maximum(l1**2 - s**2, 0.0))
    hint = np.broadcast_to(np.asarray(elbow_hint, dtype=float), d.shape) * np.array([1.0, SIDE_SIGN[side], 1.0])
    w = hint - np.sum(d * hint, axis=1)[:, None] * d                      # elbow direction, perpendicular to d
    w /= np.maximum(np.linalg.norm(w, axis=1), 1e-9)[:, None]
    u = (s[:, None] * d + rho[:, None] * w) / l1             # shoulder -> elbow
    x_u = (rho[:, None] * d - s[:, None] * w) / l1           # forearm side, perpendicular to u
    z_u = -u
    y_u = np.cross(z_u, x_u)
    rot = Rotation.from_matrix(np.stack((x_u, y_u, z_u), axis=2))
    angles = _continuous_euler(rot, np.zeros(3) if start is None else start)
    return angles, elbow


def _hang_arms(joints: np.ndarray, lean: np.ndarray | float = 0.0) -> None:
    """Arms relaxed: slightly abducted, elbows soft, hanging roughly vertical under a trunk
    leaning forward by ``lean`` (rad)."""
    for name, sign in (("right", -1.0), ("left", 1.0)):
        joints[:, dof_index(f"{name}_shoulder_x")] = sign * 0.10
        joints[:, dof_index(f"{name}_shoulder_y")] = -0.7 * np.asarray(lean)
        joints[:, dof_index(f"{name}_elbow")] = -0.25


# --- legs ----------------------------------------------------------------------------------------
def _solve_legs(joints: np.ndarray, pelvis_pos: np.ndarray, pelvis_rot: Rotation, ankles: np.ndarray,
                foot_rots: Sequence[Rotation]) -> None:
    """Hip, knee and ankle angles (written into ``joints``) putting each ankle (T, 2, 3) at its
    place with the foot at ``foot_rots[side]`` (synthesis' analytic leg IK); the hip angles
    are unwrapped frame to frame (flexion beyond 90 degrees stays on one Euler branch)."""
    for side, name in ((RIGHT, "right"), (LEFT, "left")):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            hip, knee, ankle = leg_ik(pelvis_pos, pelvis_rot, ankles[:, side], foot_rots[side], side)
        # Per frame, the Euler solution nearest to pure flexion by the thigh's sagittal angle.
        hip_rot = _xyz(hip)
        thigh = hip_rot.apply(np.array([0.0, 0.0, -1.0]))
        flexion = np.arctan2(-thigh[:, 0], -thigh[:, 2])
        hip = _euler_near_reference(hip_rot, np.column_stack((np.zeros_like(flexion), flexion,
                                                              np.zeros_like(flexion))))
        joints[:, dof_index(f"{name}_hip_x"):dof_index(f"{name}_hip_z") + 1] = hip
        joints[:, dof_index(f"{name}_knee")] = knee
        joints[:, dof_index(f"{name}_ankle_x"):dof_index(f"{name}_ankle_z") + 1] = ankle


def _planted_ankles(feet_x: float, count: int) -> np.ndarray:
    """(T, 2, 3) ankles of flat feet planted side by side, each under its hip."""
    geo = leg_geometry()
    ankles = np.empty((count, 2, 3))
    for side in (RIGHT, LEFT):
        ankles[:, side] = (feet_x, SIDE_SIGN[side] * geo.hip_offset[1], SOLE_GAP + geo.ankle_to_sole)
    return ankles


def _flat_feet(count: int, yaw: float = 0.0) -> list[Rotation]:
    rot = Rotation.from_euler("z", np.full((count, 1), yaw))
    return [rot, rot]


# --- assembling clips ----------------------------------------------------------------------------
def _check_ranges(joints: np.ndarray, what: str) -> np.ndarray:
    geo = leg_geometry()
    excess = np.maximum(geo.dof_low - joints, joints - geo.dof_high)
    if np.max(excess) > _RANGE_TOLERANCE:
        frame, dof = np.unravel_index(np.argmax(excess), excess.shape)
        raise ValueError(
            f"{what}: the motion leaves the range of {DOF_NAMES[dof]} by "
            f"{math.degrees(excess[frame, dof]):.1f} deg at frame {frame}: these parameters ask too much of the body"
        )
    return np.clip(joints, geo.dof_low, geo.dof_high)


def _qpos(pelvis_pos: np.ndarray, pelvis_rot: Rotation, joints: np.ndarray, what: str) -> np.ndarray:
    joints = _check_ranges(joints, what)
    return np.column_stack((pelvis_pos, pelvis_rot.as_quat(scalar_first=True), joints))


def _frame_ranges(mask: np.ndarray) -> list[list[int]]:
    flags = np.concatenate(([False], np.asarray(mask, dtype=bool), [False]))
    edges = np.flatnonzero(np.diff(flags.astype(int)))
    return [[int(a), int(b) - 1] for a, b in zip(edges[::2], edges[1::2])]


def _meta(generator: str, params: dict, skill: str, text: str, feet_planted: np.ndarray,
          **extra) -> dict:
    """synthesis' clip meta (stance frames from the feet planted flat) plus text and skill."""
    contact = np.where(np.asarray(feet_planted, dtype=bool), FLAT, 0)
    return {**clip_meta(generator, params, contact, **extra), "text": text, "skill": skill}


def _box(front_x: float, top: float, depth: float, width: float, centre_y: float = 0.0) -> dict:
    """A furniture box standing on the floor: top at ``top``, front face at ``front_x``, extending
    ``depth`` towards -x and ``width`` along y."""
    return {"center": [front_x - 0.5 * depth, centre_y, 0.5 * top],
            "half_size": [0.5 * depth, 0.5 * width, 0.5 * top], "top": top}


def _times(duration: float, fps: float) -> np.ndarray:
    return np.arange(round(duration * fps) + 1) / fps


def _centre_of_mass(qpos: np.ndarray) -> np.ndarray:
    model = humanoid_model()
    mass = model.body_mass[:, None]
    return np.array([np.sum(mass * data.xipos, axis=0) / mass.sum() for data in forward_kinematics(qpos)])


# --- sitting -------------------------------------------------------------------------------------
_SIT_SHIN_PREFERENCE = -0.15   # rad; preferred shin angle seated (negative: ankle a little behind the knee)
_RISE_REACH = 0.18             # m; preferred ankle distance ahead of the pelvis at seat-off
_FRONT_FACE_CLEARANCE = 0.01   # m; shins and heels keep this far in front of the seat's front face
_MIN_SEAT_OVERLAP = 0.02       # m; the pelvis centre rests at least this far behind the front edge
_SEAT_LEAN = {"thighs": 0.10, "seat": 0.30}   # rad; trunk lean seated, per hand placement
_SEAT_HAND = (0.12, 0.23)      # m; hands on the seat (hands="seat"): ahead of the pelvis, to either side
HAND_PLACEMENTS: tuple[str, ...] = ("thighs", "seat")
_STANDING_GAZE = 0.12          # rad; head pitched down a little


@dataclass(frozen=True)
class _Seat:
    """The seated pose on a box seat whose front edge is x = 0, top at ``height``: pelvis centre
    (``pelvis_x``, 0, ``pelvis_z``), ankles at x = ``feet_x``, shins at ``shin_angle`` from vertical
    (positive: ankle ahead of the knee), thighs sloping down by ``thigh_slope``; ``thigh_gap`` is
    the thighs' clearance above the front edge beyond the 2 mm rest gap (m)."""

    height: float
    pelvis_x: float
    pelvis_z: float
    feet_x: float
    shin_angle: float
    thigh_slope: float
    thigh_gap: float


def _segment_distance(px: float, pz: float, hx: np.ndarray, hz: float, dx: float, dz: float,
                      lo: float, hi: float) -> np.ndarray:
    """Distance (x-z plane) from a point to the segments hip + s (dx, dz), s in [lo, hi]."""
    vx, vz = px - hx, pz - hz
    s = np.clip(vx * dx + vz * dz, lo, hi)
    return np.hypot(vx - s * dx, vz - s * dz)


@lru_cache(maxsize=64)
def _seat_pose(seat_height: float, sit_depth: float) -> _Seat:
    """Solve the seated pose (see :class:`_Seat`) on a grid of shin angles.

    The pelvis rests ``pelvis radius + 2 mm`` above the seat. For each shin angle the thigh
    slope follows from the feet flat on the floor; the pelvis sits ``sit_depth`` behind the
    front edge unless the thigh would then press into the edge (then as far back as the
    thigh clears it, at least ``_MIN_SEAT_OVERLAP``). The chosen angle trades a thigh resting
    on the edge, the requested depth and a near-vertical shin, with the shins and heels
    clear of the seat's front face.
    """
    geo, body = leg_geometry(), _body()
    model = humanoid_model()
    thigh_r = float(model.geom("left_thigh").size[0])
    thigh_c, thigh_h = float(-model.geom("left_thigh").pos[2]), float(model.geom("left_thigh").size[1])
    shin_r = float(model.geom("left_shin").size[0])
    shin_c, shin_h = float(-model.geom("left_shin").pos[2]), float(model.geom("left_shin").size[1])
    l1, l2 = geo.thigh, geo.shin
    pelvis_z = seat_height + body.pelvis_radius + _REST_GAP
    ankle_z = SOLE_GAP + geo.ankle_to_sole
    xs_grid = -np.arange(0.0, 0.6, 0.001)
    best = None
    for beta in np.linspace(-0.5, 0.5, 201):
        sin_a = (pelvis_z - ankle_z - l2 * math.cos(beta)) / l1
        if abs(sin_a) > 1.0:
            continue
        alpha = math.asin(sin_a)
        dx, dz = math.cos(alpha), -math.sin(alpha)
        clear = _segment_distance(0.0, seat_height, xs_grid, pelvis_z, dx, dz, thigh_c - thigh_h,
                                  thigh_c + thigh_h) - thigh_r - _REST_GAP
        bad = np.flatnonzero(clear < 0.0)
        x_clear = -0.6 if len(bad) == 0 else xs_grid[max(bad[0] - 1, 0)]
        pelvis_x = min(max(-sit_depth, x_clear), -_MIN_SEAT_OVERLAP)
        gap = float(_segment_distance(0.0, seat_height, np.array([pelvis_x]), pelvis_z, dx, dz,
                                      thigh_c - thigh_h, thigh_c + thigh_h)[0] - thigh_r - _REST_GAP)
        knee_x = pelvis_x + l1 * dx
        feet_x = knee_x + l2 * math.sin(beta)
        # Shin capsule ends and heel in front of the seat's front face.
        shin_ends = knee_x + np.array([shin_c - shin_h, shin_c + shin_h]) * math.sin(beta)
        front = min(shin_ends.min() - shin_r, feet_x - geo.heel)
        if front < _FRONT_FACE_CLEARANCE:
            continue
        # Balance when standing up: the ankles at most _RISE_REACH ahead of the pelvis as it
        # lifts off (near the front of the seat).
        spread = max(0.0, feet_x - max(pelvis_x, -_TRANSFER_DEPTH) - _RISE_REACH)
        cost = ((gap / 0.02) ** 2 + ((beta - _SIT_SHIN_PREFERENCE) / 0.5) ** 2
                + ((pelvis_x + sit_depth) / 0.05) ** 2 + (spread / 0.02) ** 2)
        if best is None or cost < best[0]:
            best = (cost, _Seat(seat_height, pelvis_x, pelvis_z, feet_x, float(beta), alpha, gap))
    if best is None:
        raise ValueError(f"no seated pose found for seat_height {seat_height}")
    return best[1]


@lru_cache(maxsize=128)
def _seated_along(seat: _Seat) -> float:
    """Where along the thighs (share of hip to knee) the seated hands rest: half-way, or nearer
    the hips where steep thighs (high seats) put mid-thigh beyond the arms' easy reach."""
    pos = np.array([[seat.pelvis_x, 0.0, seat.pelvis_z]])
    rot, joints = _trunk(np.array([_SEAT_LEAN["thighs"]]))
    _solve_legs(joints, pos, rot, _planted_ankles(seat.feet_x, 1), _flat_feet(1))
    torso_pos, torso_rot = _torso_frame(pos, rot, joints[:, dof_index("abdomen_x"):dof_index("abdomen_z") + 1])
    reach = _ARM_SOFT * (_body().upper_arm + _body().forearm)
    shoulder = _shoulder_world(torso_pos, torso_rot, RIGHT)
    for along in np.arange(0.5, 0.195, -0.02):
        target = _rest_targets(joints, pos, rot, RIGHT, "thighs", seat, float(along))
        if np.linalg.norm(target - shoulder) <= reach:
            return float(along)
    return 0.2


def _leaning_along(seat: _Seat) -> float:
    """Where along the thighs the hands rest while the trunk leans far forward (sitting down,
    standing up): near the knees, or 0.4 further out than seated on high seats."""
    return min(0.85, _seated_along(seat) + 0.4)


def _seated_frame(seat: _Seat, hands: str = "thighs") -> tuple[np.ndarray, Rotation, np.ndarray]:
    """One frame of the settled seated pose: pelvis position, rotation, joints."""
    pos = np.array([[seat.pelvis_x, 0.0, seat.pelvis_z]])
    rot, joints = _trunk(np.array([_SEAT_LEAN[hands]]))
    _solve_legs(joints, pos, rot, _planted_ankles(seat.feet_x, 1), _flat_feet(1))
    _rest_hands(joints, pos, rot, np.ones(1), hands, seat, _seated_along(seat))
    return pos, rot, joints


def _trunk(lean: np.ndarray, pelvis_share: float = 0.55) -> tuple[Rotation, np.ndarray]:
    """Pelvis rotation (facing +x, pitched forward by ``pelvis_share`` of ``lean``) and joints
    with the rest of the lean in the abdomen, the head looking a little down, arms hanging."""
    joints = np.zeros((len(lean), len(DOF_NAMES)))
    rot = Rotation.from_euler("y", (pelvis_share * lean)[:, None])
    joints[:, dof_index("abdomen_y")] = (1.0 - pelvis_share) * lean
    joints[:, dof_index("neck_y")] = _STANDING_GAZE - 0.6 * lean
    _hang_arms(joints, lean)
    return rot, joints


def _rest_targets(joints: np.ndarray, pelvis_pos: np.ndarray, pelvis_rot: Rotation, side: int,
                  hands: str = "thighs", seat: _Seat | None = None,
                  along_thigh: np.ndarray | float = 0.5) -> np.ndarray:
    """World targets (T, 3) of a hand's centre resting on its thigh (``hands="thighs"``:
    ``along_thigh`` of the way from hip to knee, given the legs in ``joints``) or on the seat
    beside the hip (``"seat"``; ahead of the pelvis' current position)."""
    geo, body = leg_geometry(), _body()
    if hands == "seat":
        # Beside the hips, moving with the pelvis (the hands help it slide on the seat).
        return np.column_stack((pelvis_pos[:, 0] + _SEAT_HAND[0],
                                np.full(len(pelvis_pos), SIDE_SIGN[side] * _SEAT_HAND[1]),
                                np.full(len(pelvis_pos), seat.height + body.hand_radius + _REST_GAP)))
    name = ("right", "left")[side]
    rest = float(humanoid_model().geom("left_thigh").size[0]) + body.hand_radius + _REST_GAP
    hip = pelvis_pos + pelvis_rot.apply(geo.hip_offset * np.array([1.0, SIDE_SIGN[side], 1.0]))
    thigh_rot = pelvis_rot * _xyz(joints[:, dof_index(f"{name}_hip_x"):dof_index(f"{name}_hip_z") + 1])
    along = thigh_rot.apply(np.array([0.0, 0.0, -1.0]))
    up = thigh_rot.apply(np.array([1.0, 0.0, 0.0]))  # the thigh's top side when flexed 90 deg
    outward = thigh_rot.apply(np.array([0.0, SIDE_SIGN[side], 0.0]))
    share = np.reshape(np.asarray(along_thigh, dtype=float), (-1, 1))
    return hip + share * geo.thigh * along + rest * up + 0.01 * outward


def _rest_hands(joints: np.ndarray, pelvis_pos: np.ndarray, pelvis_rot: Rotation,
                weight: np.ndarray, hands: str = "thighs", seat: _Seat | None = None,
                along_thigh: np.ndarray | float = 0.5, lift: np.ndarray | float = 0.0) -> None:
    """Blend the arms (by ``weight`` per frame) from their current angles to the hands at their
    resting place (:func:`_rest_targets`, raised by ``lift``, m; per-frame IK)."""
    torso_pos, torso_rot = _torso_frame(pelvis_pos, pelvis_rot,
                                        joints[:, dof_index("abdomen_x"):dof_index("abdomen_z") + 1])
    for side, name in ((RIGHT, "right"), (LEFT, "left")):
        target = _rest_targets(joints, pelvis_pos, pelvis_rot, side, hands, seat, along_thigh)
        target = target + np.reshape(np.asarray(lift, dtype=float), (-1, 1)) * np.array([0.0, 0.0, 1.0])
        cols = slice(dof_index(f"{name}_shoulder_x"), dof_index(f"{name}_shoulder_z") + 1)
        shoulder, elbow = _arm_ik(target, torso_pos, torso_rot, side, start=joints[0, cols])
        w = np.asarray(weight, dtype=float)[:, None]
        joints[:, cols] = (1.0 - w) * joints[:, cols] + w * shoulder
        e = dof_index(f"{name}_elbow")
        joints[:, e] = (1.0 - w[:, 0]) * joints[:, e] + w[:, 0] * elbow


def _sit_path(seat: _Seat, u: np.ndarray, x_lead: float = 0.8) -> np.ndarray:
    """Pelvis (T, 3) from standing over the feet (u = 0) to the transfer point on the front of the
    seat (u = 1): backwards first, then down (the horizontal motion ends at ``x_lead`` of the
    path), so the pelvis comes down onto the seat from above."""
    start = np.array([seat.feet_x + _STAND_PELVIS_AHEAD, 0.0, _STAND_HEIGHT])
    end = np.array([_transfer_x(seat), 0.0, seat.pelvis_z])
    x = start[0] + (end[0] - start[0]) * smoothstep(u / x_lead)
    z = start[2] + (end[2] - start[2]) * smoothstep(u)
    return np.column_stack((x, np.zeros_like(x), z))


_TRANSFER_DEPTH = 0.08         # m; the pelvis lands (lifts off) at most this far behind the front edge
_BALANCE_MARGIN = 0.02         # m; centre of mass this far ahead of the heels at seat contact / seat-off
_LEAN_RANGE = (0.6, 1.3)       # rad; trunk lean at seat contact / seat-off


def _transfer_x(seat: _Seat) -> float:
    """Where the pelvis lands and lifts off: near the front of the seat (the seated pose may be deeper)."""
    return max(seat.pelvis_x, -_TRANSFER_DEPTH)


def _sit_frames(seat: _Seat, u: np.ndarray, scoot: np.ndarray, lean: np.ndarray, weight: np.ndarray,
                hands: str, along_thigh: np.ndarray | float, lift: np.ndarray | float
                ) -> tuple[np.ndarray, Rotation, np.ndarray]:
    """Pelvis, rotation and joints for path progress ``u`` (0 standing, 1 at the transfer point),
    ``scoot`` (0 at the transfer point, 1 at the seated depth), trunk ``lean``, and the weight of
    the hands' resting place (``hands``) against hanging arms; feet planted."""
    pos = _sit_path(seat, u)
    pos[:, 0] += np.asarray(scoot) * (seat.pelvis_x - _transfer_x(seat))
    rot, joints = _trunk(lean)
    _solve_legs(joints, pos, rot, _planted_ankles(seat.feet_x, len(pos)), _flat_feet(len(pos)))
    _rest_hands(joints, pos, rot, weight, hands, seat, along_thigh, lift)
    return pos, rot, joints


@lru_cache(maxsize=64)
def _transfer_lean(seat: _Seat, hands: str) -> tuple[float, float]:
    """Trunk lean at the transfer point (the pelvis just on the seat, hands at their resting place)
    that puts the centre of mass ``_BALANCE_MARGIN`` ahead of the heels, within ``_LEAN_RANGE``
    (bisection); returns the lean and the centre of mass' margin ahead of the heels (m)."""
    heel = seat.feet_x - leg_geometry().heel

    def margin(lean: float) -> float:
        pos, rot, joints = _sit_frames(seat, np.ones(1), np.zeros(1), np.array([lean]), np.ones(1),
                                       hands, _leaning_along(seat), 0.0)
        qpos = np.column_stack((pos, rot.as_quat(scalar_first=True), joints))
        return float(_centre_of_mass(qpos)[0, 0] - heel)

    lo, hi = _LEAN_RANGE
    if margin(lo) >= _BALANCE_MARGIN:
        return lo, margin(lo)
    if margin(hi) < _BALANCE_MARGIN:
        return hi, margin(hi)
    for _ in range(20):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if margin(mid) < _BALANCE_MARGIN else (lo, mid)
    return hi, margin(hi)


def _seat_box(seat: _Seat, seat_depth: float) -> dict:
    return _box(0.0, seat.height, seat_depth, 0.6)


def _check_seat(seat_height: float, sit_depth: float, seat_depth: float, hands: str) -> tuple[float, float, float]:
    check_choice("hands", hands, HAND_PLACEMENTS)
    seat_height = check_number("seat_height", seat_height, *_SEAT_HEIGHTS)
    sit_depth = check_number("sit_depth", sit_depth, 0.05, 0.3)
    seat_depth = check_number("seat_depth", seat_depth, 0.3, 1.0)
    if seat_depth < sit_depth + _body().pelvis_radius:
        raise ValueError(f"seat_depth must be at least sit_depth + {_body().pelvis_radius} m "
                         f"(the pelvis on the seat), got {seat_depth} with sit_depth {sit_depth}")
    return seat_height, sit_depth, seat_depth


def sit_down(seat_height: float = 0.45, sit_depth: float = 0.2, seat_depth: float = 0.45,
             hands: str = "thighs", descent_time: float = 1.6, fps: float = 30.0,
             name: str | None = None) -> MotionClip:
    """Standing with the back to a seat, sit down on it and settle (module docstring: the seat's
    frame).

    0.4 s standing still, then ``descent_time`` s in which the hips move back and down onto
    the front of the seat (at most 8 cm behind the edge; the horizontal motion finishes first,
    so the pelvis comes down onto the seat from above) while the trunk leans forward, as far
    as it takes (35-45 degrees; up to 55 with ``hands="seat"``) to keep the body's mass over
    the feet until the pelvis lands; then 0.8 s in which the pelvis slides back to its seated
    depth and the trunk comes back up to a slight forward lean; then 0.5 s seated still. The
    feet stay planted throughout. The arms come forward from hanging as the trunk leans, the
    hands reaching their resting place as the pelvis lands (``hands``: "thighs", towards the
    knees and then sliding back to half-way along the thighs, nearer the hips on high seats;
    or "seat", on the seat 0.23 m to either side of and 0.12 m ahead of the pelvis, the trunk
    then leaning a little more). ``seat_height`` 0.35-0.65 m. The pelvis sits ``sit_depth``
    behind the edge on low seats; from about 0.45 m up the feet, tucked for standing up
    again, make the thighs slope so steeply that it sits closer to the edge (10 cm at
    0.45 m, 2 cm at 0.65 m; :func:`_seat_pose`). ``seat_depth`` only sizes
    ``meta["furniture"]``.
    ``meta["balance_margin"]``: the centre of mass ahead of the heels as the pelvis lands (m).
    """
    seat_height, sit_depth, seat_depth = _check_seat(seat_height, sit_depth, seat_depth, hands)
    descent_time = check_number("descent_time", descent_time, 0.8, 4.0)
    fps = check_number("fps", fps, 10.0, 1000.0)
    seat = _seat_pose(seat_height, sit_depth)
    peak, balance = _transfer_lean(seat, hands)
    t0, t1 = 0.4, 0.4 + descent_time
    times = _times(t1 + 1.3, fps)
    u = np.clip((times - t0) / descent_time, 0.0, 1.0)
    scoot = _ramp(times, t1, t1 + 0.8)
    # The lean keeps pace with the hips moving back (they finish at 80% of the descent).
    lean = (peak * _ramp(times, t0, t0 + 0.8 * descent_time) * (1.0 - _ramp(times, t1, t1 + 0.8))
            + _SEAT_LEAN[hands] * _ramp(times, t1, t1 + 0.8))
    weight = _ramp(times, t0 + 0.3 * descent_time, t0 + 1.0 * descent_time)
    leaning, seated = _leaning_along(seat), _seated_along(seat)
    along = leaning + (seated - leaning) * _ramp(times, t1, t1 + 0.8)  # towards the knees, then back
    lift = 0.12 * (1.0 - _ramp(times, t0 + 0.3 * descent_time, t1))  # "seat": coming down from above
    qpos = _qpos(*_sit_frames(seat, u, scoot, lean, weight, hands, along, lift), "sit_down")
    params = {"seat_height": seat_height, "sit_depth": sit_depth, "seat_depth": seat_depth,
                  "hands": hands, "descent_time": descent_time, "fps": fps}
    return MotionClip(
        qpos, fps, name or f"sit_down_h{seat_height:.2f}", loop=False, source=SOURCE,
        meta=_meta("sit_down", params, "sit", "sit down", np.ones((len(times), 2)),
                   furniture=_seat_box(seat, seat_depth), rest_frames=_frame_ranges(times >= t1 - 1e-9),
                   feet_x=seat.feet_x, seat_pose=_seat_meta(seat), balance_margin=balance),
    )


def stand_up(seat_height: float = 0.45, sit_depth: float = 0.2, seat_depth: float = 0.45,
             hands: str = "thighs", rise_time: float = 1.3, fps: float = 30.0,
             name: str | None = None) -> MotionClip:
    """Seated (the end pose of :func:`sit_down` with the same arguments), stand up.

    Not the time-reversed sit, though it shares its path: 0.4 s seated still, then 0.8 s in
    which the trunk leans forward while the pelvis slides forward to the front of the seat
    (the flexion-momentum phase), the pelvis lifting off at the strongest lean (35-55 degrees:
    the body's mass just over the feet) and rising over ``rise_time`` s (up first, then
    forward) while the trunk straightens, then 0.4 s standing still. The hands push off their
    resting place (``hands``, as in :func:`sit_down`) at seat-off and swing down to hang. Feet
    planted throughout. ``meta["balance_margin"]``: the centre of mass ahead of the heels at
    seat-off (m).
    """
    seat_height, sit_depth, seat_depth = _check_seat(seat_height, sit_depth, seat_depth, hands)
    rise_time = check_number("rise_time", rise_time, 0.6, 4.0)
    fps = check_number("fps", fps, 10.0, 1000.0)
    seat = _seat_pose(seat_height, sit_depth)
    peak, balance = _transfer_lean(seat, hands)
    t_lean, t_off = 0.4, 1.2
    t_up = t_off + rise_time
    times = _times(t_up + 0.4, fps)
    u = 1.0 - np.clip((times - t_off) / rise_time, 0.0, 1.0)
    scoot = 1.0 - _ramp(times, t_lean, t_off)
    # The lean holds until the hips, rising first, have moved forward over the feet.
    lean = (_SEAT_LEAN[hands] * (1.0 - _ramp(times, t_lean, t_off))
            + peak * _ramp(times, t_lean, t_off) * (1.0 - _ramp(times, t_off + 0.2 * rise_time, t_up)))
    weight = 1.0 - _ramp(times, t_off - 0.2, t_up)
    # Hands slide towards the knees while leaning, then back up the thighs as they push off.
    leaning, seated = _leaning_along(seat), _seated_along(seat)
    along = (seated + (leaning - seated) * _ramp(times, t_lean, t_off)
             - 0.6 * _ramp(times, t_off, t_up))
    lift = 0.15 * _ramp(times, t_off, t_off + 0.4 * rise_time)       # "seat": pushing off upwards
    qpos = _qpos(*_sit_frames(seat, u, scoot, lean, weight, hands, along, lift), "stand_up")
    params = {"seat_height": seat_height, "sit_depth": sit_depth, "seat_depth": seat_depth,
                  "hands": hands, "rise_time": rise_time, "fps": fps}
    return MotionClip(
        qpos, fps, name or f"stand_up_h{seat_height:.2f}", loop=False, source=SOURCE,
        meta=_meta("stand_up", params, "getup", "stand up", np.ones((len(times), 2)),
                   furniture=_seat_box(seat, seat_depth), rest_frames=_frame_ranges(times <= t_off + 1e-9),
                   feet_x=seat.feet_x, seat_pose=_seat_meta(seat), balance_margin=balance),
    )


def _seat_meta(seat: _Seat) -> dict:
    return {"pelvis": [seat.pelvis_x, 0.0, seat.pelvis_z], "shin_angle": seat.shin_angle,
            "thigh_slope": seat.thigh_slope, "thigh_gap": seat.thigh_gap}


# --- lying ---------------------------------------------------------------------------------------
_LONG_SIT_LEAN = -0.35         # rad; pelvis pitch (leaning back) with the legs up on the bed
_LIE_HIP_ANKLE = 0.815         # m; hip-ankle distance lying (knees a little soft)
_LIE_ANKLE = 0.30              # rad; ankle y lying (toes relaxed away from the shin)
_FOOT_LIFT = 0.035             # m; least clearance of the lifted feet over the surface
_SUPPORT_HAND = (-0.20, 0.26)  # hands beside and behind the hips (heading frame: back, out)
_LYING_HAND = (0.04, 0.27)     # hands beside the hips lying (heading frame: towards the feet, out)
_HAND_LIFT = 0.03              # m; hands lift this much while they move


def _lowest(qpos: np.ndarray, geoms: Sequence[str]) -> np.ndarray:
    """Lowest world z of the named humanoid geoms, per frame."""
    model = humanoid_model()
    return lowest_body_point(qpos, np.array([model.geom(name).id for name in geoms]))


_LEG_GEOMS = tuple(f"{side}_{part}" for side in ("right", "left") for part in ("thigh", "shin", "foot"))


def _heading_point(pelvis_xy: np.ndarray, yaw: np.ndarray, forward: np.ndarray, lateral: np.ndarray,
                   z: np.ndarray) -> np.ndarray:
    """World points at (forward, lateral) in the frame of the pelvis' ground position and heading."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.column_stack((pelvis_xy[:, 0] + c * forward - s * lateral,
                            pelvis_xy[:, 1] + s * forward + c * lateral, z))


def _lying_trunk(surface_height: float, pillow_height: float) -> tuple[float, float]:
    """Pelvis pitch and neck y lying on the back (abdomen straight): the chest's back resting
    on the surface, the head resting ``pillow_height`` above it (both 2 mm clear)."""
    body = _body()
    model = humanoid_model()
    chest_r = float(model.geom("chest").size[0])
    chest_c = float(model.geom("chest").pos[2])
    torso, neck = float(body.torso[2]), float(body.neck[2])
    # Heights above the pelvis centre: the chest centre at torso + chest_c along the body axis.
    cos_p = (chest_r - body.pelvis_radius) / (torso + chest_c)
    pitch = -math.acos(cos_p)
    need = pillow_height + body.head_radius - body.pelvis_radius - (torso + neck) * cos_p
    # The head's own pitch (about y; -pi/2 is flat on the back): its centre need above the neck.
    head_pitch = -math.acos(float(np.clip(need / body.head_centre, -1.0, 1.0)))
    return pitch, head_pitch - pitch


def _check_surface(surface_height: float, lie_offset: float, pillow_height: float):
    surface_height = check_number("surface_height", surface_height, *_SURFACE_HEIGHTS)
    lie_offset = check_number("lie_offset", lie_offset, 0.3, 0.6)
    pillow_height = check_number("pillow_height", pillow_height, 0.0, 0.15)
    return surface_height, lie_offset, pillow_height


@lru_cache(maxsize=16)
def _lie_clip(surface_height: float, lie_offset: float, pillow_height: float, sit_depth: float,
              fps: float) -> tuple[np.ndarray, np.ndarray, float, float]:
    """qpos of lying down, the frames with the feet planted, and the times the legs lift off and
    the body lies flat (cached for :func:`get_up_from_lying`: callers copy the arrays)."""
    geo, body = leg_geometry(), _body()
    seat = _seat_pose(surface_height, sit_depth)
    t0, swing, back = 0.4, 2.0, 1.5
    t_back = t0 + 0.8 * swing                  # lying back starts before the swing has finished
    t_flat = t_back + back
    times = _times(t_flat + 0.6, fps)
    count = len(times)
    s = np.clip((times - t0) / swing, 0.0, 1.0)   # swing phase
    b = _ramp(times, t_back, t_flat)              # lying-back progress

    lie_pitch, lie_neck = _lying_trunk(surface_height, pillow_height)
    yaw = -0.5 * math.pi * _ramp(s, 0.25, 0.9)
    px = seat.pelvis_x + (-lie_offset - seat.pelvis_x) * _ramp(s, 0.2, 0.9)
    pelvis_pos = np.column_stack((px, np.zeros(count), np.full(count, seat.pelvis_z)))
    seat_lean = _SEAT_LEAN["thighs"]
    pitch = (0.55 * seat_lean + (_LONG_SIT_LEAN - 0.55 * seat_lean) * _ramp(s, 0.0, 0.6)) * (1.0 - b) + lie_pitch * b
    pelvis_rot = Rotation.from_euler("ZY", np.column_stack((yaw, pitch)))
    joints = np.zeros((count, len(DOF_NAMES)))
    seated_abdomen = 0.45 * seat_lean
    joints[:, dof_index("abdomen_y")] = (seated_abdomen + (0.12 - seated_abdomen) * _ramp(s, 0.0, 0.6)) * (1.0 - b)
    seated_neck = _STANDING_GAZE - 0.6 * seat_lean
    joints[:, dof_index("neck_y")] = ((seated_neck + (0.25 - seated_neck) * _ramp(s, 0.0, 0.6)) * (1.0 - b)
                                      + lie_neck * b)

    # Legs, in the heading frame: lift the feet (knees up), swing round with the pelvis, extend
    # onto the surface. The lying leg pose (ankle height) is solved so that the legs rest on it.
    ankle_z0 = SOLE_GAP + geo.ankle_to_sole
    f0 = seat.feet_x - seat.pelvis_x
    f_end = _LIE_HIP_ANKLE                        # the resting ankle is about level with the hip
    lift_z = surface_height + _FOOT_LIFT + 0.07   # ankle high enough for the foot to clear the top

    def legs(z_end: float) -> np.ndarray:
        forward = f0 + (f_end - f0) * _ramp(s, 0.05, 0.8)
        z = ankle_z0 + (lift_z - ankle_z0) * _ramp(s, 0.0, 0.4) + (z_end - lift_z) * _ramp(s, 0.6, 1.0)
        ankles = np.stack([_heading_point(pelvis_pos[:, :2], yaw, forward,
                                          np.full(count, SIDE_SIGN[side] * geo.hip_offset[1]), z)
                           for side in (RIGHT, LEFT)], axis=1)
        feet = Rotation.from_euler("z", yaw[:, None])
        out = joints.copy()
        _solve_legs(out, pelvis_pos, pelvis_rot, ankles, [feet, feet])
        relax = _ramp(s, 0.0, 0.4)
        for name in ("right", "left"):
            a = dof_index(f"{name}_ankle_y")
            out[:, a] = (1.0 - relax) * out[:, a] + relax * _LIE_ANKLE
        return out

    # Bisection on the lying ankle height: the legs' lowest point 2 mm above the surface.
    lo, hi = surface_height, surface_height + 0.2
    last = slice(count - 1, count)
    for _ in range(25):
        mid = 0.5 * (lo + hi)
        q = np.column_stack((pelvis_pos[last], pelvis_rot[last].as_quat(scalar_first=True), legs(mid)[last]))
        if _lowest(q, _LEG_GEOMS)[0] < surface_height + _REST_GAP:
            lo = mid
        else:
            hi = mid
    joints = legs(hi)

    # Hands: from the thighs to the surface beside and behind the hips (moving with the heading),
    # then beside the hips as the body lies back; lifted a little while they move.
    torso_pos, torso_rot = _torso_frame(pelvis_pos, pelvis_rot,
                                        joints[:, dof_index("abdomen_x"):dof_index("abdomen_z") + 1])
    hand_z = surface_height + body.hand_radius + _REST_GAP
    to_support = _ramp(s, 0.0, 0.45)
    seated = _seated_frame(seat)[2]
    for side, name in ((RIGHT, "right"), (LEFT, "left")):
        cols = slice(dof_index(f"{name}_shoulder_x"), dof_index(f"{name}_shoulder_z") + 1)
        thigh_hand = _rest_targets(joints, pelvis_pos, pelvis_rot, side, along_thigh=_seated_along(seat))
        forward = _SUPPORT_HAND[0] + (_LYING_HAND[0] - _SUPPORT_HAND[0]) * b
        lateral = SIDE_SIGN[side] * (_SUPPORT_HAND[1] + (_LYING_HAND[1] - _SUPPORT_HAND[1]) * b)
        support = _heading_point(pelvis_pos[:, :2], yaw, forward, lateral, np.full(count, hand_z))
        target = (1.0 - to_support)[:, None] * thigh_hand + to_support[:, None] * support
        moving = (_bump(s, 0.0, 0.2, 0.45) + 0.5 * _bump(s, 0.25, 0.55, 0.9)
                  + _bump(times, t_back, 0.5 * (t_back + t_flat), t_flat))
        target[:, 2] += _HAND_LIFT * np.minimum(moving, 1.0)
        # Elbows back while leaning on the hands, out to the side (not into the bed) lying.
        hint = (1.0 - b)[:, None] * np.array([-1.0, 0.5, -0.5]) + b[:, None] * np.array([-0.5, 1.0, 0.0])
        shoulder, elbow = _arm_ik(target, torso_pos, torso_rot, side, start=seated[0, cols], elbow_hint=hint)
        joints[:, cols] = shoulder
        joints[:, dof_index(f"{name}_elbow")] = elbow
    qpos = _qpos(pelvis_pos, pelvis_rot, joints, "lie_down")
    planted = times <= t0
    qpos.setflags(write=False)     # cached: callers copy
    planted.setflags(write=False)
    return qpos, planted, t0, t_flat


def lie_down(surface_height: float = 0.5, lie_offset: float = 0.4, pillow_height: float = 0.0,
             sit_depth: float = 0.2, fps: float = 30.0, name: str | None = None) -> MotionClip:
    """Seated on the long edge of a bed or sofa, lie down on the back along it (module docstring:
    the frame).

    0.4 s seated (the end pose of :func:`sit_down` on a seat of ``surface_height``), then 2 s in
    which the feet lift off the floor (knees up), the body turns a quarter turn on the pelvis
    (feet over the surface, the pelvis shuffling back to ``lie_offset`` behind the edge) and
    the legs extend onto the surface, leaning back on the hands behind the hips; then the trunk
    lies back (1.5 s, overlapping the end of the swing), the hands sliding to beside the hips;
    0.6 s lying still. The pelvis rests on the surface throughout; lying, the back of the chest,
    the legs and the hands rest on it too, the head ``pillow_height`` above it.
    """
    surface_height, lie_offset, pillow_height = _check_surface(surface_height, lie_offset, pillow_height)
    sit_depth = check_number("sit_depth", sit_depth, 0.05, 0.3)
    fps = check_number("fps", fps, 10.0, 1000.0)
    qpos, planted, _, _ = _lie_clip(surface_height, lie_offset, pillow_height, sit_depth, fps)
    params = {"surface_height": surface_height, "lie_offset": lie_offset, "pillow_height": pillow_height,
                  "sit_depth": sit_depth, "fps": fps}
    feet = np.repeat(planted[:, None], 2, axis=1)
    return MotionClip(
        qpos.copy(), fps, name or f"lie_down_h{surface_height:.2f}", loop=False, source=SOURCE,
        meta=_meta("lie_down", params, "lie", "lie down", feet, furniture=_bed_box(surface_height, lie_offset),
                   rest_frames=[[0, len(qpos) - 1]]),
    )


def get_up_from_lying(surface_height: float = 0.5, lie_offset: float = 0.4, pillow_height: float = 0.0,
                      sit_depth: float = 0.2, fps: float = 30.0, name: str | None = None) -> MotionClip:
    """Lying on the back on a bed or sofa, sit up on its edge: :func:`lie_down` played backwards.

    The time reverse is a fair get-up here: lying down is quasi-static (the pelvis rests on the
    surface throughout, no phase relies on momentum, every profile is a symmetric quintic), so
    the reversed motion is as feasible: the trunk sits up onto the hands behind the hips, the
    legs bend, swing round over the edge and the feet come down to the floor; it ends in the
    seated pose that :func:`stand_up` starts from.
    """
    surface_height, lie_offset, pillow_height = _check_surface(surface_height, lie_offset, pillow_height)
    sit_depth = check_number("sit_depth", sit_depth, 0.05, 0.3)
    fps = check_number("fps", fps, 10.0, 1000.0)
    qpos, planted, _, _ = _lie_clip(surface_height, lie_offset, pillow_height, sit_depth, fps)
    params = {"surface_height": surface_height, "lie_offset": lie_offset, "pillow_height": pillow_height,
                  "sit_depth": sit_depth, "fps": fps}
    feet = np.repeat(planted[::-1, None], 2, axis=1)
    return MotionClip(
        qpos[::-1].copy(), fps, name or f"get_up_from_lying_h{surface_height:.2f}", loop=False, source=SOURCE,
        meta=_meta("get_up_from_lying", params, "getup", "get up", feet,
                   furniture=_bed_box(surface_height, lie_offset), rest_frames=[[0, len(qpos) - 1]]),
    )


def _bed_box(surface_height: float, lie_offset: float) -> dict:
    """The bed the lying clips are made for: deep enough for the body and both hands, 2.1 m long."""
    return _box(0.0, surface_height, lie_offset + 0.45, 2.1, centre_y=-0.1)


# --- standing: reach and idle --------------------------------------------------------------------
_STAND_ANKLE_X = -0.03         # ankles this far behind the pelvis standing (reach, idle)
_REACH_SHARE = 0.88            # preferred shoulder-hand distance, share of the arm's length
_REACH_LIMIT = _ARM_SOFT       # beyond this share of the arm's length a target is out of reach
_MAX_THORAX_YAW = 0.8          # rad; the abdomen's twist reaching across (range 0.87)


def _standing(count: int) -> tuple[np.ndarray, np.ndarray]:
    """Pelvis positions (T, 3) standing still over the origin and the planted ankles (T, 2, 3)."""
    pos = np.tile([0.0, 0.0, _STAND_HEIGHT], (count, 1))
    return pos, _planted_ankles(_STAND_ANKLE_X, count)


def _reach_posture(target: np.ndarray, side: int) -> dict:
    """Trunk lean (rad, pelvis and abdomen halves), squat (m), pelvis shift back (m) and thorax
    yaw that bring the shoulder within comfortable reach of ``target`` with the least bending,
    the body's mass kept over the feet (grid search; MuJoCo for the centre of mass)."""
    geo, body = leg_geometry(), _body()
    arm = body.upper_arm + body.forearm
    leans = np.arange(-0.2, 1.401, 0.05)
    squats = np.arange(0.0, 0.451, 0.025)
    lean, squat = (g.ravel() for g in np.meshgrid(leans, squats))
    count = len(lean)
    ankle_z = SOLE_GAP + geo.ankle_to_sole
    shoulder_y = SIDE_SIGN[side] * body.shoulder[1]
    yaw = float(np.clip(0.5 * math.atan2(target[1] - shoulder_y, max(target[0], 0.05)), -0.5, 0.5))  # preferred

    def pose(shift: np.ndarray) -> tuple[np.ndarray, Rotation, np.ndarray]:
        pos = np.column_stack((-shift, np.zeros(count), _STAND_HEIGHT - squat))
        reach = ankle_z + np.sqrt(geo.max_leg_length**2 - (pos[:, 0] - _STAND_ANKLE_X) ** 2)
        pos[:, 2] = np.minimum(pos[:, 2], reach)
        rot = Rotation.from_euler("y", (0.5 * lean)[:, None])
        joints = np.zeros((count, len(DOF_NAMES)))
        joints[:, dof_index("abdomen_y")] = 0.5 * lean
        joints[:, dof_index("abdomen_z")] = yaw
        _hang_arms(joints, lean)
        _solve_legs(joints, pos, rot, _planted_ankles(_STAND_ANKLE_X, count), _flat_feet(count))
        return pos, rot, joints

    # Shift the pelvis back until the centre of mass is over the middle of the feet.
    foot_middle = _STAND_ANKLE_X + geo.foot_centre
    shift = np.zeros(count)
    for _ in range(2):
        pos, rot, joints = pose(shift)
        com = _centre_of_mass(np.column_stack((pos, rot.as_quat(scalar_first=True), joints)))
        shift = np.maximum(shift + (com[:, 0] - foot_middle) * 1.1, 0.0)
    pos, rot, joints = pose(shift)
    # Thorax yaw: preferably half-way towards the target, more where that brings it within reach.
    yaws = np.clip(yaw + np.linspace(-0.6, 0.6, 13), -_MAX_THORAX_YAW, _MAX_THORAX_YAW)
    best = None
    for turn in np.unique(yaws):
        abdomen = joints[:, dof_index("abdomen_x"):dof_index("abdomen_z") + 1].copy()
        abdomen[:, 2] = turn
        torso_pos, torso_rot = _torso_frame(pos, rot, abdomen)
        dist = np.linalg.norm(target - _shoulder_world(torso_pos, torso_rot, side), axis=1) / arm
        cost = (lean**2 + 8.0 * squat**2 + 2.0 * (turn - yaw) ** 2
                + 60.0 * np.maximum(dist - _REACH_SHARE, 0.0) ** 2 + 20.0 * np.maximum(0.55 - dist, 0.0) ** 2)
        cost = np.where(dist <= _REACH_LIMIT, cost, np.inf)
        k = int(np.argmin(cost))
        closest = float(dist.min() * arm) if best is None else min(best[3], float(dist.min() * arm))
        if best is None or cost[k] < best[0]:
            best = (float(cost[k]), k, float(turn), closest)
        else:
            best = (*best[:3], closest)
    cost, k, turn, closest = best
    if not np.isfinite(cost):
        raise ValueError(f"target {np.round(target, 3).tolist()} is out of the {('right', 'left')[side]} hand's "
                         f"reach from a standing pose (closest {closest:.2f} m from the shoulder; it reaches "
                         f"{_REACH_LIMIT * arm:.2f} m)")
    goal = joints[k].copy()
    goal[dof_index("abdomen_z")] = turn
    return {"lean": float(lean[k]), "squat": float(squat[k]), "shift": float(shift[k]), "yaw": turn,
            "pelvis": pos[k], "joints": goal}


def reach(target: Sequence[float] = (0.45, -0.2, 1.1), hand: str = "right", reach_time: float = 1.0,
          hold_time: float = 0.6, fps: float = 30.0, name: str | None = None) -> MotionClip:
    """Standing, move one hand to ``target`` (the hand centre, m, in the standing frame: pelvis over
    the origin, facing +x, module docstring), hold it there, and bring it back.

    0.3 s still, ``reach_time`` s to the target, ``hold_time`` s holding, ``reach_time`` s back,
    0.3 s still. The posture at the target is the least bending (trunk lean from the hips,
    knee bend) that brings the shoulder within 88% of the arm's length, the pelvis shifted back
    so the body's mass stays over the feet, the thorax turned half-way towards the target and
    the head looking at it; the arm reaches it by analytic IK. The body moves there with
    quintic joint-space profiles (the hand arrives exactly), the feet planted. Targets: height
    0.4-1.6 m, 0.15-0.8 m ahead, at most 0.6 m to the side; ``ValueError`` if out of reach.
    """
    try:
        target = np.asarray([float(v) for v in target], dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"target must be three numbers (x, y, z), got {target!r}") from None
    if target.shape != (3,):
        raise ValueError(f"target must be three numbers (x, y, z), got {target.tolist()}")
    check_number("target x", target[0], 0.15, 0.8)
    check_number("target y", target[1], -0.6, 0.6)
    check_number("target z", target[2], *_REACH_HEIGHTS)
    check_choice("hand", hand, ("right", "left"))
    reach_time = check_number("reach_time", reach_time, 0.4, 4.0)
    hold_time = check_number("hold_time", hold_time, 0.0, 10.0)
    fps = check_number("fps", fps, 10.0, 1000.0)
    side = RIGHT if hand == "right" else LEFT
    posture = _reach_posture(target, side)

    t0 = 0.3
    t1 = t0 + reach_time
    t2 = t1 + hold_time
    t3 = t2 + reach_time
    times = _times(t3 + 0.3, fps)
    count = len(times)
    w = _ramp(times, t0, t1) * (1.0 - _ramp(times, t2, t3))
    stand_pos, ankles = _standing(count)
    pos = stand_pos + w[:, None] * (posture["pelvis"] - stand_pos)
    lean = posture["lean"] * w
    rot = Rotation.from_euler("y", (0.5 * lean)[:, None])
    rest = np.zeros((1, len(DOF_NAMES)))
    rest[:, dof_index("neck_y")] = _STANDING_GAZE
    _hang_arms(rest)
    goal = posture["joints"].copy()
    # The arm's final pose, solved for the final trunk; the head looks at the target.
    goal_pos = posture["pelvis"][None]
    goal_rot = Rotation.from_euler("y", [[0.5 * posture["lean"]]])
    torso_pos, torso_rot = _torso_frame(goal_pos, goal_rot,
                                        goal[None, dof_index("abdomen_x"):dof_index("abdomen_z") + 1])
    name_side = hand
    cols = slice(dof_index(f"{name_side}_shoulder_x"), dof_index(f"{name_side}_shoulder_z") + 1)
    shoulder, elbow = _arm_ik(target[None], torso_pos, torso_rot, side, start=rest[0, cols])
    goal[cols] = shoulder[0]
    goal[dof_index(f"{name_side}_elbow")] = elbow[0]
    head = torso_pos[0] + torso_rot[0].apply(_body().neck)
    look = target - head
    look_down = math.atan2(-look[2], math.hypot(look[0], look[1]))
    goal[dof_index("neck_y")] = float(np.clip(look_down - posture["lean"], -0.6, 0.9))
    goal[dof_index("neck_z")] = float(np.clip(math.atan2(look[1], look[0]) - posture["yaw"], -0.6, 0.6))
    joints = rest + w[:, None] * (goal - rest[0])[None]
    _solve_legs(joints, pos, rot, ankles, _flat_feet(count))
    qpos = _qpos(pos, rot, joints, "reach")
    params = {"target": target.tolist(), "hand": hand, "reach_time": reach_time, "hold_time": hold_time, "fps": fps}
    default = f"reach_{hand}_x{target[0]:.2f}_y{target[1]:+.2f}_z{target[2]:.2f}"
    return MotionClip(
        qpos, fps, name or default, loop=False, source=SOURCE,
        meta=_meta("reach", params, "reach", "reach", np.ones((count, 2)), target=target.tolist(),
                   hand=f"{hand}_hand", hold_frames=_frame_ranges((times >= t1) & (times <= t2)),
                   posture={k: posture[k] for k in ("lean", "squat", "shift", "yaw")}),
    )


def idle(duration: float = 4.0, fps: float = 30.0, breathing_period: float = 4.0,
         name: str | None = None) -> MotionClip:
    """Standing still (pelvis over the origin, facing +x), breathing, as a looping clip.

    Breathing (the chest rising about 1 degree, the shoulders with it) at about
    ``breathing_period`` s, rounded so that a whole number of breaths fills ``duration``; a
    slow postural sway of the pelvis (5 mm sideways, 4 mm fore-aft, one cycle per clip) and a
    2 mm breathing bob; feet planted, arms hanging. The last frame repeats the first.
    """
    duration = check_number("duration", duration, 1.0, 60.0)
    fps = check_number("fps", fps, 10.0, 1000.0)
    breathing_period = check_number("breathing_period", breathing_period, 2.0, 10.0)
    frames = round(duration * fps)
    duration = frames / fps
    breaths = max(1, round(duration / breathing_period))
    times = np.arange(frames + 1) / fps
    breath = np.sin(2.0 * math.pi * breaths * times / duration)
    sway = 2.0 * math.pi * times / duration
    pos, ankles = _standing(len(times))
    pos[:, 0] += 0.004 * np.sin(sway)
    pos[:, 1] += 0.005 * np.sin(sway + 0.5 * math.pi)
    pos[:, 2] += -0.001 - 0.001 * breath
    rot = Rotation.from_euler("y", np.full((len(times), 1), 0.02))
    joints = np.zeros((len(times), len(DOF_NAMES)))
    joints[:, dof_index("abdomen_y")] = 0.02 - 0.012 * breath
    joints[:, dof_index("neck_y")] = _STANDING_GAZE - 0.04 + 0.012 * breath
    _hang_arms(joints)
    for name_side in ("right", "left"):
        joints[:, dof_index(f"{name_side}_shoulder_y")] += 0.02 * breath
    _solve_legs(joints, pos, rot, ankles, _flat_feet(len(times)))
    qpos = _qpos(pos, rot, joints, "idle")
    qpos[-1] = qpos[0]
    params = {"duration": duration, "fps": fps, "breathing_period": duration / breaths}
    return MotionClip(qpos, fps, name or f"idle_{duration:.1f}s", loop=True, source=SOURCE,
                      meta=_meta("idle", params, "idle", "stand still", np.ones((len(times), 2))))


# --- the default set -----------------------------------------------------------------------------
def interaction_reference_set(fps: float = 30.0, seat_heights: Sequence[float] = (0.40, 0.45, 0.55),
                              surface_heights: Sequence[float] = (0.45, 0.55),
                              reach_targets: Sequence[tuple[Sequence[float], str]] = (
                                  ((0.45, -0.20, 1.10), "right"), ((0.40, 0.25, 1.45), "left"),
                                  ((0.50, -0.15, 0.60), "right"), ((0.55, 0.20, 0.90), "left")),
                              idle_duration: float = 4.0) -> list[MotionClip]:
    """The default interaction clips: sit down and stand up at each seat height, lie down and get
    up from lying at each surface height, a reach to each (target, hand), and an idle loop.

    Defaults: 6 + 4 + 4 + 1 = 15 clips, about 50 s of motion, each with ``meta["text"]`` and
    ``meta["skill"]``.
    """
    clips: list[MotionClip] = []
    for height in seat_heights:
        clips.append(sit_down(height, fps=fps))
        clips.append(stand_up(height, fps=fps))
    for height in surface_heights:
        clips.append(lie_down(height, fps=fps))
        clips.append(get_up_from_lying(height, fps=fps))
    for target, hand in reach_targets:
        clips.append(reach(target, hand=hand, fps=fps))
    clips.append(idle(idle_duration, fps=fps))
    return clips
