"""Kinematic reference motion for our humanoid: flat walking, stair ascent and stair descent.

No licensed clip shows *our* skeleton climbing stairs, so the AMP style reward's
reference clips are synthesised here, as pure functions of a few parameters
(numpy + scipy; the body's dimensions and joint limits are read off
``xml/humanoid.xml``). The pipeline, shared by every generator:

1. **Footsteps.** Planted foot poses (ankle position, side) with touch-down times.
   On stairs: one foot per tread (step-over-step), each foot centred on its tread
   so that heel and toe keep equal margins from the tread's front edge and from the
   next riser; on the floor and on the landing, regular walking steps. Feet always
   land flat.
2. **Gait timing** (:class:`GaitTiming`). A foot stays flat and still from landing
   until shortly before the other foot lands (35% of the cycle by default), then
   rolls over its toe edge, the heel rising (push-off; the toe stays put), and lifts
   off once both feet have shared a double support (20% of the cycle in all); it
   swings for 40% of the cycle. The push-off angle is reduced where a riser close
   in front of the toe leaves no room for the foot to tip forward.
3. **Swing.** Lift-then-forward: the ankle's forward progress and height are smooth
   (quintic) profiles of the swing phase, and the height gets the smallest bump that
   keeps the foot box (pitched as it is) ``edge_clearance`` above any ground other
   than its own tread that it reaches over, widened front and back by 2 cm once it
   moves. Several timings (how long the foot lifts before moving forward, how early
   it arrives above its tread, how wide the bump is) are solved in closed form and
   the lowest is kept. The swinging foot hangs with a relaxed ankle (roughly square
   to the shin, toes down after push-off) and is flattened before it lands.
4. **Pelvis.** Forward: a spline through points between the feet at each double
   support (60% of the way to the leading foot; halfway on descent); sideways: a
   small sway over the stance foot; yaw: a small pelvic rotation following the legs;
   roll: the pelvis drops about 3 degrees towards the swinging leg (most at mid-swing).
   Height: the lowest of (a) what both legs reach with the knees never fully
   straight, (b) a nominal height over the ground the feet stand on; on stairs
   monotone (non-decreasing up, non-increasing down) and equal, over the ground, on
   the flat before and after the flight; then smoothed from below (erosion and a
   Gaussian of no wider support), so it never asks a leg for more than it reaches.
5. **Inverse kinematics** (:mod:`stairenv.motion.ik`). Analytic two-link legs: knee flexion from the hip-ankle
   distance, the thigh turned so that the knee hinge axis is parallel to the foot's
   lateral axis (knees point where the feet point and bend forward), the ankle from
   the remaining rotation so the foot has exactly the orientation planned. The swing
   foot's relaxed pitch depends on the shin, so the legs are solved three times.
6. **Upper body.** Trunk lean (more on ascent), head level and looking down a little
   more on stairs, arms swinging opposite to the legs with the elbows flexing as the
   arm comes forward (swinging slightly out and turning inward as they come forward),
   thorax counter-rotating the pelvis and leaning against its roll, so that the head
   stays level. Every degree of freedom the AMP features see moves in the clips
   (their roll too): a discriminator cannot tell an agent from them by a feature
   that never varies.

Walking styles (``styled_walk``, ``WALK_STYLES``): the eight SIMS styles as gait and
posture numbers (speed, step length and width, foot lift, trunk lean, head drop, arm
swing, elbow bend, hip sway) through the same pipeline, each captioned with a walking
caption of its style from the script database.

Every joint angle stays inside the model's range; parameters that would need more
raise ``ValueError`` (validated for step heights 0.05-0.20 m and step depths from
the foot length + 1 cm to 0.5 m; 0.25 m steps work for ascents).

Conventions
-----------
* World: z up. Flat walking goes along +x. Stairs use the geometry of
  :class:`stairenv.world.stairs.Staircase` in its own frame (``yaw=0``,
  ``distance=0``): the first riser is at ``x = 0``; tread ``k`` (1..n-1) covers
  ``x`` in ``[(k-1) d, k d]`` with its top at ``k h``; tread ``n`` is the
  landing, from ``x = (n-1) d`` on, at height ``n h``. ``num_steps`` is ``n``,
  exactly ``Staircase.num_steps`` (risers, the landing's included). Ascent walks
  along +x from the floor (``x < 0``) onto the landing; descent walks along -x
  from the landing down to the floor, facing -x.
* Clip format: :class:`stairenv.motion.clip.MotionClip`, ``qpos`` (T, 35) = root
  position, root quaternion (w, x, y, z), 28 hinge angles in ``DOF_NAMES``
  order; 3-axis joints are intrinsic XYZ Euler angles. Joint signs (checked
  with MuJoCo forward kinematics): hip y < 0 swings the thigh forward, knee > 0
  bends the shin backwards, ankle y > 0 points the toes down, shoulder y < 0
  swings the arm forward, elbow < 0 bends the forearm forward, abdomen y > 0
  and root pitch > 0 lean the trunk forward.
* Planted soles float 2 mm above the ground (no initial penetration when a
  simulation starts from a reference state).
* Looping walks repeat their first frame as the last one (``qpos[-1]`` equals
  ``qpos[0]`` except the root's forward position, which has advanced by the
  distance walked), so ``MotionClip.sample`` wraps continuously.
* ``meta`` of every clip: ``generator`` and ``parameters``; the frames in which
  each foot is planted flat and still (``meta["stance_frames"]["right_foot"]``, a
  list of inclusive ``[first, last]`` frame ranges) and rolls over its toe
  (``meta["push_off_frames"]``); for stairs the staircase (``meta["stairs"]``: the
  keyword arguments of ``Staircase``, ``yaw=0``, ``distance=0``, a landing deep
  enough for the clip); for walks ``cycle_frames``.

Every generator is deterministic: the same arguments give the same clip.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.ndimage import gaussian_filter1d, minimum_filter1d
from scipy.spatial.transform import Rotation

from stairenv.humanoid import DOF_NAMES
from stairenv.motion.clip import MotionClip
from stairenv.motion.contacts import FLAT, PUSH_OFF, SWINGING, clip_meta
from stairenv.motion.ik import LEFT, RIGHT, SIDE_SIGN, SOLE_GAP, LegGeometry, dof_index, leg_geometry, leg_ik
from stairenv.motion.profiles import bump, smoothstep

__all__ = [
    "GaitTiming",
    "LegGeometry",
    "climb_stairs",
    "crouch_step_length",
    "crouch_walk",
    "default_stair_step_time",
    "default_step_length",
    "leg_geometry",
    "reference_set",
    "save_reference_set",
    "speed_change",
    "walk",
]

SOURCE = "stairenv.motion.synthesis"

# Gait constants (documented in the generators' docstrings).
_RISER_GAP = 0.015              # least gap between a rolling or lifting foot and the riser ahead (m)
_HORIZONTAL_CLEARANCE = 0.02    # a moving swing foot, widened by this front and back, clears the edges (m)
_WALK_PELVIS_HEIGHT = 0.865     # nominal pelvis height over flat ground at mid-stance (m)
_SWAY_GAIN = 0.3                # pelvis sway: this share of the stance foot's lateral offset
_LEAD_SHARE = 0.6               # pelvis at mid double support: share of the way to the leading foot
_DESCENT_LEAD_SHARE = 0.5       # the same when the leading foot is lower (descent)
_PELVIC_ROTATION_GAIN = 0.12    # pelvis yaw (rad) per metre the left foot leads the right
_THORAX_COUNTER_ROTATION = 1.6  # abdomen z = -this * pelvic rotation (thorax turns the other way)
_ELBOW_SWING_GAIN = 0.7         # extra elbow flexion per radian of forward arm swing
_SHOULDER_ABDUCTION = 0.10      # rad; keeps the arms off the trunk
_SHOULDER_ABDUCTION_SWING = 0.04  # extra abduction (rad) as the arm swings out of the hanging pose
_SHOULDER_ROTATION_GAIN = 0.3   # shoulder z (rad, inward) per radian of forward arm swing
_OBLIQUITY_RATE = 1.0           # m/s of foot lead change at which the drop is ~76% of full
_THORAX_COUNTER_ROLL = 0.8      # abdomen x = -this * pelvic roll (the thorax stays nearly level)
_HEIGHT_SMOOTHING = 0.12        # s; half-width of the pelvis-height smoothing window
_LEAN_SMOOTHING = 0.35          # s; sigma of the walk-to-stairs blend of lean and gaze
_RANGE_TOLERANCE = math.radians(0.5)  # joint-limit excursions clipped silently; larger ones raise


# --- terrain -------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Terrain:
    """Piecewise-flat ground along x: segment i covers [starts[i], ends[i]) at heights[i]."""

    starts: np.ndarray
    ends: np.ndarray
    heights: np.ndarray

    @classmethod
    def flat(cls) -> "_Terrain":
        return cls(np.array([-np.inf]), np.array([np.inf]), np.array([0.0]))

    @classmethod
    def stairs(cls, step_height: float, step_depth: float, num_steps: int) -> "_Terrain":
        """Floor for x < 0, treads 1..n-1 of depth ``step_depth``, the landing from (n-1) d on."""
        k = np.arange(1, num_steps + 1)
        starts = np.concatenate(([-np.inf], (k - 1) * step_depth))
        ends = np.concatenate(((k - 1) * step_depth, [np.inf]))
        heights = np.concatenate(([0.0], k * step_height))
        return cls(starts, ends, heights)

    def max_height(self, low: np.ndarray, high: np.ndarray) -> np.ndarray:
        """Highest ground over each interval [low, high] (arrays of equal shape)."""
        low, high = np.asarray(low, dtype=float), np.asarray(high, dtype=float)
        overlap = (self.starts < high[..., None]) & (self.ends > low[..., None])
        return np.max(np.where(overlap, self.heights, -np.inf), axis=-1)


# --- footsteps and timing ------------------------------------------------------------------------
@dataclass(frozen=True)
class _GaitPlan:
    """Footsteps in order, alternating sides, the ground they stand on, and the gait timing.

    ``ankles[i]`` is the planted ankle position of footstep i (foot flat), ``sides[i]`` its
    foot, ``touchdown[i]`` the time it lands. That foot stays flat until ``heel_off[i]``
    (``heel_off_lead`` of the step before footstep i+1 lands), then rolls over its toe edge,
    the heel rising to ``push_off[i]`` (rad, toes down) at ``liftoff[i]`` (once footstep
    i+1 has landed and ``double_support`` of the step to footstep i+2 has passed), then swings
    to footstep i+2.
    """

    sides: np.ndarray
    ankles: np.ndarray
    soles: np.ndarray
    touchdown: np.ndarray
    heel_off: np.ndarray
    liftoff: np.ndarray
    push_off: np.ndarray
    facing: float
    terrain: _Terrain

    @classmethod
    def build(cls, xs: np.ndarray, soles: np.ndarray, first_side: int, step_width: float,
              durations: np.ndarray, double_support: float, heel_off_lead: float,
              push_off_angle: float, facing: float, terrain: _Terrain) -> "_GaitPlan":
        """Footsteps at ankle x ``xs`` on ground at heights ``soles``; ``durations[i]`` is the
        time from footstep i to footstep i+1 (one fewer than footsteps)."""
        geo = leg_geometry()
        n = len(xs)
        sides = (first_side + np.arange(n)) % 2
        # Lateral placement: the sides swap when facing -x (left is then -y in the world).
        ys = SIDE_SIGN[sides] * facing * 0.5 * step_width
        ankles = np.stack((xs, ys, soles + SOLE_GAP + geo.ankle_to_sole), axis=1)
        touchdown = np.concatenate(([0.0], np.cumsum(durations)))
        heel_off = np.full(n, np.inf)
        heel_off[:-1] = touchdown[1:] - heel_off_lead * durations
        liftoff = np.full(n, np.inf)
        liftoff[:-2] = touchdown[1:-1] + double_support * durations[1:]
        # Rolling over the toe tips the foot box's top front corner forward, and the foot
        # flattening about its lifted ankle early in the swing reaches further forward still:
        # keep both _RISER_GAP short of a riser in front of the toe.
        toe_tips = xs + facing * geo.toe
        ahead = np.searchsorted(terrain.starts, toe_tips, side="right") - 1
        ahead = np.clip(ahead + (1 if facing > 0 else -1), 0, len(terrain.heights) - 1)
        riser_x = terrain.starts[ahead] if facing > 0 else terrain.ends[ahead]
        room = np.where(terrain.heights[ahead] > soles + 1e-9, facing * (riser_x - toe_tips), np.inf)
        angles = np.linspace(0.0, push_off_angle, 64)
        reach = _toe_reach(angles)
        fits = reach[None, :] <= (room - _RISER_GAP)[:, None]
        push_off = np.where(fits.all(axis=1), push_off_angle,
                            angles[np.maximum(np.argmin(fits, axis=1) - 1, 0)])
        return cls(sides, ankles, np.asarray(soles, dtype=float), touchdown, heel_off, liftoff,
                   push_off, float(facing), terrain)

    @property
    def heading(self) -> float:
        return 0.0 if self.facing > 0 else math.pi

    def mid_double_support(self, i: int) -> float:
        """Middle of the double support that starts when footstep i (>= 1) lands."""
        return 0.5 * (self.touchdown[i] + self.liftoff[i - 1])

    def foot_rotation(self, pitch: np.ndarray) -> Rotation:
        """World orientation of feet pointing along the heading, pitched toes-down by ``pitch``."""
        pitch = np.atleast_1d(pitch)
        return Rotation.from_euler("ZY", np.column_stack((np.full(len(pitch), self.heading), pitch)))


def _toe_reach(angle: np.ndarray) -> np.ndarray:
    """How far beyond the planted toe tip the foot box reaches (m) when rolled over its toe by
    ``angle`` and when, from there, it turns flat about the lifted ankle."""
    rolled = _foot_outline(angle, 1.0)                    # relative to the rolled ankle
    toe_sole = rolled[:, _TOE_SOLE, 0]                     # planted toe tip, from the rolled ankle
    flat = _foot_outline(np.zeros(1), 1.0)[0, :, 0].max()  # flat box front, from the same ankle
    return np.maximum(rolled[:, :, 0].max(axis=1), flat) - toe_sole


def _foot_outline(pitch: np.ndarray, facing: float) -> np.ndarray:
    """The foot box's side view relative to the ankle: corners (N, 4, 2) as world (x, z), in the
    order heel-sole, toe-sole, heel-top, toe-top, for feet facing ``facing`` (+1/-1 along x)
    and pitched toes-down by ``pitch`` (N,)."""
    geo = leg_geometry()
    top = geo.foot_box_top
    local = np.array([[-geo.heel, -geo.ankle_to_sole], [geo.toe, -geo.ankle_to_sole],
                      [-geo.heel, top], [geo.toe, top]])
    c, s = np.cos(pitch)[:, None], np.sin(pitch)[:, None]
    # Rotation about y by +pitch: (x, z) -> (x cos + z sin, -x sin + z cos).
    x = local[:, 0] * c + local[:, 1] * s
    z = -local[:, 0] * s + local[:, 1] * c
    return np.stack((facing * x, z), axis=2)


_TOE_SOLE = 1  # index of the toe-sole corner in _foot_outline


@dataclass(frozen=True)
class _Swing:
    """One swing of the ankle from ``start`` to ``end`` (phase 0 -> 1).

    Forward progress: quintic over [move_start, move_end] of the phase (the foot lifts
    first and arrives above its target before it sets down). Height: a quintic blend from
    start to end height plus ``lift`` times a bump that rises over the first ``bump_share``
    of the phase and falls over the last. Pitch (toes down): ``pitch_profile`` sampled at
    ``_SWING_SAMPLES``, from the push-off angle at lift-off to flat at touch-down.
    """

    start: np.ndarray
    end: np.ndarray
    pitch_profile: np.ndarray
    move_start: float
    move_end: float
    bump_share: float
    lift: float

    def ankle(self, phase: np.ndarray) -> np.ndarray:
        phase = np.clip(phase, 0.0, 1.0)
        progress = smoothstep((phase - self.move_start) / (self.move_end - self.move_start))
        out = self.start + (self.end - self.start) * progress[:, None]
        out[:, 2] = self.start[2] + (self.end[2] - self.start[2]) * smoothstep(phase)
        out[:, 2] += self.lift * bump(phase, self.bump_share)
        return out

    def pitch(self, phase: np.ndarray) -> np.ndarray:
        return np.interp(phase, _SWING_SAMPLES, self.pitch_profile)


def _default_swing_pitch(start_pitch: float) -> np.ndarray:
    """First-guess swing pitch: the push-off angle relaxing to flat over the first
    ``_SWING_PITCH_SHARE`` of the swing (refined from the legs' posture, see ``_synthesise``)."""
    return start_pitch * (1.0 - smoothstep(_SWING_SAMPLES / _SWING_PITCH_SHARE))


def _relaxed_swing_pitch(start_pitch: float, shin_pitch: np.ndarray) -> np.ndarray:
    """Swing pitch with the ankle relaxed: ``_SWING_ANKLE`` from the shin (``shin_pitch``, the
    pitch a foot square to the shin would have, sampled at ``_SWING_SAMPLES``), blended from
    the push-off angle after lift-off and to flat before touch-down."""
    relaxed = np.clip(shin_pitch + _SWING_ANKLE, -_SWING_PITCH_LIMIT, _SWING_PITCH_LIMIT)
    after_lift = smoothstep(_SWING_SAMPLES / _SWING_RELAX_SHARE)
    flatten_from, flat_by = _SWING_FLATTEN
    before_land = 1.0 - smoothstep((_SWING_SAMPLES - flatten_from) / (flat_by - flatten_from))
    return ((1.0 - after_lift) * start_pitch + after_lift * relaxed) * before_land


# Swing timings tried: (move_start, move_end, bump_share); the preference cost favours the first.
_SWING_TIMINGS = tuple(
    (s0, s1, share)
    for share in (0.5, 0.4, 0.3)
    for s0 in (0.0, 0.1, 0.2, 0.3)
    for s1 in (1.0, 0.9, 0.8, 0.7)
)
_SWING_SAMPLES = np.linspace(0.0, 1.0, 241)
# Forward progress and bump of every candidate timing at the samples: (candidates, samples).
_SWING_PROGRESS = np.array([smoothstep((_SWING_SAMPLES - s0) / (s1 - s0)) for s0, s1, _ in _SWING_TIMINGS])
_SWING_BUMPS = np.array([bump(_SWING_SAMPLES, share) for _, _, share in _SWING_TIMINGS])
_SWING_TIMING_PENALTY = np.array([s0 + 1.0 - s1 + 0.5 - share for s0, s1, share in _SWING_TIMINGS])
# Metres of extra peak height worth one unit of (lift delay + early arrival + narrower bump):
# overlapping lift and forward motion look natural, so they win unless they cost height.
_SWING_TIMING_PREFERENCE = 0.08
# Share of the swing over which the foot's push-off pitch returns to flat (first guess).
_SWING_PITCH_SHARE = 0.4
# The relaxed swing foot: ankle angle (ankle y; negative = toes up) kept during the swing,
# reached over the first _SWING_RELAX_SHARE of it, flattened between these phases for landing.
_SWING_ANKLE = -0.6
_SWING_RELAX_SHARE = 0.25
_SWING_FLATTEN = (0.5, 0.9)
_SWING_PITCH_LIMIT = 1.0
_POSTURE_PASSES = 3
MAX_STEP_HEIGHT = 0.25  # m; one foot per tread, the legs' reach and the ankles' range
MAX_STEP_DEPTH = 0.5    # m; deeper treads need more than one step each
_ASCENT_SET_BACK = 0.02  # m; feet behind the tread centre on ascent ...
_HEEL_ON_TREAD = 0.015   # m; ... keeping at least this much tread behind the heel
_MAX_SWING_LIFT = 0.8  # m; a swing bump beyond this marks an infeasible timing
_UNMOVED = 1e-3        # m; a swing foot closer than this to its start (end) has not moved yet


@dataclass(frozen=True)
class _Clearance:
    """Swing clearances (m): above ground the foot passes over, horizontally around the foot
    box, and the least height of the swing bump."""

    edge: float
    horizontal: float
    min_lift: float


class _NoSwing(ValueError):
    """No swing profile clears the ground for the given footsteps and foot pitch."""


def _plan_swing(start: np.ndarray, pitch_profile: np.ndarray, end: np.ndarray, start_region: tuple,
                end_region: tuple, terrain: _Terrain, facing: float, clearance: _Clearance) -> _Swing:
    """The swing from ``start`` (ankle at lift-off) to ``end`` (planted flat) with the lowest
    peak that clears the ground, the foot pitched by ``pitch_profile`` (at ``_SWING_SAMPLES``).

    The foot box seen from the side (pitched as it is at each phase) is widened front and
    back by ``clearance.horizontal`` (less while the foot is within that distance of its
    start or end position). While this widened box lies within the flat region of the start
    or of the end footstep (``start_region``/``end_region``: start x, end x, height), or the
    foot has not moved yet and has no higher ground under it, it only has to stay above that
    ground; as soon as it reaches over any other ground (a riser ahead, a tread edge to
    pass), its lowest corner must be ``clearance.edge`` above the highest ground under it.
    So a moving foot keeps at least min(edge, horizontal) from every tread edge; a foot
    lifting off beside a riser keeps the ``_RISER_GAP`` the push-off left. The bump is at
    least ``clearance.min_lift``. For each candidate timing the smallest bump meeting the
    requirement is solved in closed form (the height is linear in it).
    """
    corners = _foot_outline(pitch_profile, facing)  # (N, 4, 2)
    corner_low = corners[:, :, 0].min(axis=1)
    corner_high = corners[:, :, 0].max(axis=1)
    lowest = corners[:, :, 1].min(axis=1)  # z of the lowest corner relative to the ankle
    base = start[2] + (end[2] - start[2]) * smoothstep(_SWING_SAMPLES)
    # All candidate timings at once: (candidates, samples).
    x = start[0] + (end[0] - start[0]) * _SWING_PROGRESS
    # The horizontal clearance grows with the distance travelled from the start and shrinks
    # with the distance left to the end: a foot lifting off (or setting down) beside a riser
    # is not asked to keep away from it before it has moved.
    widen = np.minimum(clearance.horizontal, np.minimum(np.abs(x - start[0]), np.abs(end[0] - x)))
    low = x + corner_low - widen
    high = x + corner_high + widen
    ground = terrain.max_height(low, high)
    # Resting: within the start or end footstep's flat region, or not yet moved (still over
    # that footstep) with nothing higher than its ground under the foot (a toe rolled out over
    # the drop beyond a nose, lifting straight up).
    not_higher = lambda region: ground <= region[2] + 1e-9  # noqa: E731
    resting = ((low >= start_region[0]) & (high <= start_region[1])) | (
        (low >= end_region[0]) & (high <= end_region[1]))
    resting |= (np.abs(x - start[0]) < _UNMOVED) & not_higher(start_region)
    resting |= (np.abs(end[0] - x) < _UNMOVED) & not_higher(end_region)
    required_ankle = ground + np.where(resting, 0.0, clearance.edge) + SOLE_GAP - lowest
    deficit = required_ankle - base
    bump = _SWING_BUMPS
    free = bump < 1e-12
    feasible = ~np.any(free & (deficit > 1e-9), axis=1)  # no rise needed where the bump is zero
    if not np.any(feasible):
        raise _NoSwing(f"no swing from {start.round(3).tolist()} to {end.round(3).tolist()} clears "
                       "the ground: the foot would have to rise while it stands")
    ratio = np.where(free, -np.inf, deficit / np.where(free, 1.0, bump))
    lift = np.maximum(clearance.min_lift, ratio.max(axis=1))
    feasible &= lift < _MAX_SWING_LIFT
    if not np.any(feasible):
        raise _NoSwing(f"no swing from {start.round(3).tolist()} to {end.round(3).tolist()} "
                       f"clears the ground with a lift below {_MAX_SWING_LIFT} m")
    peak = np.max(base + lift[:, None] * bump, axis=1) - max(start[2], end[2])
    cost = np.where(feasible, peak + _SWING_TIMING_PREFERENCE * _SWING_TIMING_PENALTY, np.inf)
    best = int(np.argmin(cost))
    move_start, move_end, share = _SWING_TIMINGS[best]
    return _Swing(start.copy(), end.copy(), pitch_profile, move_start, move_end, share, float(lift[best]))


@dataclass(frozen=True)
class _FootTracks:
    """Both feet over time: ankle positions (T, 2, 3), pitch toes-down (T, 2), contact state
    (T, 2) in {SWINGING, FLAT, PUSH_OFF}, the ground height under a foot in contact (T, 2; NaN
    in swing), and for swinging feet the footstep they swing to and the swing phase (T, 2;
    -1 and NaN otherwise)."""

    ankle: np.ndarray
    pitch: np.ndarray
    contact: np.ndarray
    ground: np.ndarray
    swing_target: np.ndarray
    swing_phase: np.ndarray


def _foot_tracks(plan: _GaitPlan, times: np.ndarray, clearance: _Clearance,
                 swing_pitch: dict[int, np.ndarray] | None = None) -> _FootTracks:
    """Where both feet are at ``times``: planted, rolling over the toe, or swinging.

    ``swing_pitch`` maps a footstep to the pitch profile of the swing that lands on it
    (default :func:`_default_swing_pitch`).
    """
    geo = leg_geometry()
    count = len(times)
    ankle = np.empty((count, 2, 3))
    pitch = np.zeros((count, 2))
    contact = np.full((count, 2), SWINGING)
    ground = np.full((count, 2), np.nan)
    swing_target = np.full((count, 2), -1)
    swing_phase = np.full((count, 2), np.nan)
    # The toe edge the foot rolls over, relative to the planted ankle (world, facing applied).
    toe_edge = np.array([plan.facing * geo.toe, 0.0, -geo.ankle_to_sole])

    def rolled(planted: np.ndarray, angle: np.ndarray) -> np.ndarray:
        """Ankle of a foot rolled over its toe edge by ``angle`` (toes down)."""
        corner = _foot_outline(np.atleast_1d(angle), plan.facing)[:, _TOE_SOLE]  # (x, z)
        out = np.repeat(planted[None], len(corner), axis=0)
        out[:, 0] += toe_edge[0] - corner[:, 0]
        out[:, 2] += toe_edge[2] - corner[:, 1]
        return out

    def region(step: int) -> tuple[float, float, float]:
        """The flat stretch of ground footstep ``step`` stands on: (start x, end x, height)."""
        centre = plan.ankles[step, 0] + plan.facing * geo.foot_centre
        i = int(np.searchsorted(plan.terrain.starts, centre, side="right") - 1)
        return float(plan.terrain.starts[i]), float(plan.terrain.ends[i]), float(plan.terrain.heights[i])

    for side in (RIGHT, LEFT):
        steps = np.flatnonzero(plan.sides == side)
        # The last footstep of this side landed at or before each time.
        which = np.searchsorted(plan.touchdown[steps], times, side="right") - 1
        if np.any(which < 0) or np.any(which >= len(steps) - 1):
            raise ValueError("times outside the planned footsteps")
        for j in np.unique(which):
            rows = np.flatnonzero(which == j)
            step, following = steps[j], steps[j + 1]
            t = times[rows]
            flat = rows[t < plan.heel_off[step]]
            ankle[flat, side] = plan.ankles[step]
            contact[flat, side] = FLAT
            rolling = rows[(t >= plan.heel_off[step]) & (t < plan.liftoff[step])]
            roll_time = plan.liftoff[step] - plan.heel_off[step]
            if len(rolling):
                angle = plan.push_off[step] * smoothstep((times[rolling] - plan.heel_off[step]) / roll_time)
                ankle[rolling, side] = rolled(plan.ankles[step], angle)
                pitch[rolling, side] = angle
                contact[rolling, side] = PUSH_OFF
            ground[np.concatenate((flat, rolling)), side] = plan.soles[step]
            airborne = rows[t >= plan.liftoff[step]]
            if len(airborne):
                start = rolled(plan.ankles[step], plan.push_off[step])[0]
                default = _default_swing_pitch(plan.push_off[step])
                profile = (swing_pitch or {}).get(int(following), default)
                args = (plan.ankles[following], region(step), region(following), plan.terrain,
                        plan.facing, clearance)
                try:
                    swing = _plan_swing(start, profile, *args)
                except _NoSwing:
                    if profile is default:
                        raise
                    swing = _plan_swing(start, default, *args)  # a relaxed pitch that does not fit
                swing_time = plan.touchdown[following] - plan.liftoff[step]
                phase = (times[airborne] - plan.liftoff[step]) / swing_time
                ankle[airborne, side] = swing.ankle(phase)
                pitch[airborne, side] = swing.pitch(phase)
                swing_target[airborne, side] = following
                swing_phase[airborne, side] = phase
    return _FootTracks(ankle, pitch, contact, ground, swing_target, swing_phase)


# --- pelvis --------------------------------------------------------------------------------------
def _pelvis_horizontal(plan: _GaitPlan, times: np.ndarray) -> np.ndarray:
    """Pelvis (x, y) at ``times``: splines through the double- and single-support midpoints.

    At the middle of each double support the pelvis is between the two ankles, ``_LEAD_SHARE``
    of the way from the trailing to the leading foot (``_DESCENT_LEAD_SHARE`` when the
    leading foot is lower: on descent the body stays over the upper foot); at the middle of
    each single support it sways ``_SWAY_GAIN`` of the way over the stance foot.
    """
    key_t, key_x = [], []
    sway_t, sway_y = [], []
    for i in range(1, len(plan.sides) - 1):
        trailing, leading = plan.ankles[i - 1], plan.ankles[i]
        share = _DESCENT_LEAD_SHARE if leading[2] < trailing[2] - 1e-6 else _LEAD_SHARE
        t_ds = plan.mid_double_support(i)
        key_t.append(t_ds)
        key_x.append(trailing[0] + share * (leading[0] - trailing[0]))
        sway_t.append(t_ds)
        sway_y.append(_SWAY_GAIN * 0.5 * (trailing[1] + leading[1]))
        sway_t.append(0.5 * (plan.liftoff[i - 1] + plan.touchdown[i + 1]))
        sway_y.append(_SWAY_GAIN * leading[1])
    x = CubicSpline(np.array(key_t), np.array(key_x))(times)
    y = CubicSpline(np.array(sway_t), np.array(sway_y))(times)
    return np.stack((x, y), axis=1)


def _smooth_from_below(values: np.ndarray, radius: int) -> np.ndarray:
    """A smooth curve that never exceeds ``values``: erosion, then a Gaussian of no wider support."""
    if radius < 1:
        return values.copy()
    eroded = minimum_filter1d(values, size=2 * radius + 1, mode="nearest")
    sigma = radius / 2.5
    return gaussian_filter1d(eroded, sigma, mode="nearest", truncate=radius / sigma)


def _pelvis_height(hips_xy: np.ndarray, feet: _FootTracks, nominal_over_support: float,
                   monotone: str | None, level_reference: np.ndarray | None, radius: int,
                   hips_dz: np.ndarray | None = None) -> np.ndarray:
    """Pelvis height (T,): as high as ``nominal_over_support`` above the ground the feet stand
    on, but never higher than both legs reach with ``LegGeometry.max_leg_length``
    (``hips_dz`` (T, 2): each hip's height above the pelvis centre, from the pelvic roll).

    ``monotone`` is "up" (non-decreasing; the support is the higher foot's ground), "down"
    (non-increasing; the lower foot's ground) or None (flat walking, support = the ground).
    On stairs the pelvis keeps, on the flat before and after the flight, the least height over
    the ground it has in the flat walk before the flight (frames ``level_reference``), so the
    clip rises (or drops) by exactly the height of the flight.
    """
    geo = leg_geometry()
    reach = geo.max_leg_length
    horizontal = np.linalg.norm(hips_xy - feet.ankle[:, :, :2], axis=2)
    if np.any(horizontal >= reach):
        raise ValueError("a footstep is out of the legs' reach: shorten the steps")
    lift = 0.0 if hips_dz is None else hips_dz
    bound = np.min(feet.ankle[:, :, 2] + np.sqrt(reach**2 - horizontal**2) - lift, axis=1)
    if monotone == "down":
        support = np.nanmin(feet.ground, axis=1)
    else:
        support = np.nanmax(feet.ground, axis=1)
    raw = np.minimum(bound, support + nominal_over_support)
    if monotone is None:
        return _smooth_from_below(raw, radius)
    # The height over the ground that the flat walk before the stairs allows everywhere.
    over_ground = np.min((raw - support)[level_reference])
    raw = np.minimum(raw, support + over_ground)
    if monotone == "up":
        raw = np.minimum.accumulate(raw[::-1])[::-1]
    else:
        raw = np.minimum.accumulate(raw)
    return _smooth_from_below(raw, radius)


# --- whole-body synthesis ------------------------------------------------------------------------
@dataclass(frozen=True)
class _Style:
    """Posture targets for walking and for the stairs (radians); blended along the clip."""

    walk_lean: float = 0.06         # trunk pitch on flat ground (pelvis + abdomen)
    stairs_lean: float = 0.06       # trunk pitch on the stairs
    walk_gaze: float = 0.12         # head pitch (down) on flat ground
    stairs_gaze: float = 0.12       # head pitch (down) on the stairs
    pelvis_share: float = 0.6       # share of the trunk lean taken by the pelvis, the rest by the abdomen
    arm_swing: float = 0.55         # shoulder y (rad) per metre of foot lead
    elbow: float = 0.25             # elbow flexion (rad) with the arm hanging
    obliquity: float = 0.05         # pelvic drop towards the swinging leg (rad)
    arm_pitch: float = 0.0          # shoulder y (rad) added to the swing: > 0 carries the arms back
    deep_flexion: bool = False      # hips flexed to 90 degrees and beyond (leg_ik's deep_flexion)
    pelvis_forward: float = 0.0     # m the pelvis is carried ahead of (< 0: behind) its place between the feet
    arm_abduction: float = 0.0      # rad of shoulder abduction added (arms held out, clear of the legs)


def _synthesise(plan: _GaitPlan, times: np.ndarray, crop: slice, fps: float, *, style: _Style,
                on_stairs: np.ndarray | None, nominal_height: float, monotone: str | None,
                level_reference: np.ndarray | None, clearance: _Clearance) -> tuple[np.ndarray, np.ndarray]:
    """qpos (T, 35) and the feet's contact states (T, 2) at ``times[crop]``.

    ``times`` extends beyond the clip so that smoothing has no edge effects; ``on_stairs``
    (len(times),) is 1 where the stairs posture applies, 0 for walking (None: all walking).
    ``level_reference`` marks the flat walk before the stairs (see ``_pelvis_height``).

    The swing foot's pitch depends on the legs' posture (a relaxed ankle keeps the foot
    roughly square to the shin) and the posture on the swing (clearing the ground with the
    toes down needs more lift), so the legs are solved ``_POSTURE_PASSES`` times: first with
    a default swing pitch, then with the pitch the previous pass's shins give.
    """
    geo = leg_geometry()

    # Posture blend between walking and stairs (smooth in time).
    if on_stairs is None:
        blend = np.zeros(len(times))
    else:
        blend = gaussian_filter1d(on_stairs.astype(float), _LEAN_SMOOTHING * fps, mode="nearest")
        blend = np.clip(blend, 0.0, 1.0)
    lean = style.walk_lean + (style.stairs_lean - style.walk_lean) * blend
    gaze = style.walk_gaze + (style.stairs_gaze - style.walk_gaze) * blend
    pelvis_pitch = style.pelvis_share * lean
    abdomen_pitch = lean - pelvis_pitch
    pelvis_xy = _pelvis_horizontal(plan, times)
    if style.pelvis_forward:  # (only when set: the other clips keep their exact bits)
        pelvis_xy[:, 0] += plan.facing * style.pelvis_forward
    radius = max(1, int(round(_HEIGHT_SMOOTHING * fps)))

    swing_pitch: dict[int, np.ndarray] | None = None
    for _ in range(_POSTURE_PASSES):
        feet = _foot_tracks(plan, times, clearance, swing_pitch)
        # Pelvis: yaw from the feet, then the height the legs allow.
        left_lead = plan.facing * (feet.ankle[:, LEFT, 0] - feet.ankle[:, RIGHT, 0])  # m the left foot leads
        pelvic_rotation = -_PELVIC_ROTATION_GAIN * left_lead
        yaw = plan.heading + pelvic_rotation
        lateral = np.stack((-np.sin(yaw), np.cos(yaw)), axis=1)
        hips_xy = np.stack([pelvis_xy + SIDE_SIGN[s] * geo.hip_offset[1] * lateral for s in (RIGHT, LEFT)],
                           axis=1)
        # Pelvic obliquity: the pelvis drops towards the swinging leg (roll > 0 lifts the left
        # hip), most at mid-swing, when the feet's lead changes fastest.
        lead_rate = np.gradient(left_lead, times)
        roll = -style.obliquity * np.tanh(lead_rate / _OBLIQUITY_RATE)
        hips_dz = np.stack([SIDE_SIGN[s] * geo.hip_offset[1] * np.sin(roll) for s in (RIGHT, LEFT)], axis=1)
        pelvis_z = _pelvis_height(hips_xy, feet, nominal_height, monotone, level_reference, radius, hips_dz)
        pelvis_pos = np.column_stack((pelvis_xy, pelvis_z))
        pelvis_rot = Rotation.from_euler("ZYX", np.column_stack((yaw, pelvis_pitch, roll)))

        joints = np.zeros((len(times), len(DOF_NAMES)))
        shin_pitch = np.zeros((len(times), 2))
        for side, name in zip((RIGHT, LEFT), ("right", "left")):
            foot_rot = plan.foot_rotation(feet.pitch[:, side])
            hip, knee, ankle = leg_ik(pelvis_pos, pelvis_rot, feet.ankle[:, side], foot_rot, side,
                                      deep_flexion=style.deep_flexion)
            joints[:, dof_index(f"{name}_hip_x"):dof_index(f"{name}_hip_z") + 1] = hip
            joints[:, dof_index(f"{name}_knee")] = knee
            joints[:, dof_index(f"{name}_ankle_x"):dof_index(f"{name}_ankle_z") + 1] = ankle
            shin_pitch[:, side] = feet.pitch[:, side] - ankle[:, 1]
        # Next pass: each swing's pitch from the shin it had in this pass.
        swing_pitch = {}
        for side in (RIGHT, LEFT):
            for target in np.unique(feet.swing_target[:, side]):
                if target < 0:
                    continue
                rows = feet.swing_target[:, side] == target
                shin = np.interp(_SWING_SAMPLES, feet.swing_phase[rows, side], shin_pitch[rows, side])
                swing_pitch[int(target)] = _relaxed_swing_pitch(plan.push_off[target - 2], shin)

    # Trunk and head: lean, thorax counter-rotation and counter-roll, head level with the
    # heading, gaze down.
    joints[:, dof_index("abdomen_x")] = -_THORAX_COUNTER_ROLL * roll
    joints[:, dof_index("abdomen_y")] = abdomen_pitch
    joints[:, dof_index("abdomen_z")] = -_THORAX_COUNTER_ROTATION * pelvic_rotation
    joints[:, dof_index("neck_x")] = -(roll + joints[:, dof_index("abdomen_x")])
    joints[:, dof_index("neck_y")] = gaze - lean
    joints[:, dof_index("neck_z")] = -(pelvic_rotation + joints[:, dof_index("abdomen_z")])

    # Arms swing opposite to the legs: the right arm forward (shoulder y < 0) when the left foot leads.
    for name, sign in (("right", 1.0), ("left", -1.0)):
        swing_forward = sign * style.arm_swing * left_lead
        joints[:, dof_index(f"{name}_shoulder_y")] = -swing_forward
        if style.arm_pitch:  # (only when set: the other clips keep their exact bits)
            joints[:, dof_index(f"{name}_shoulder_y")] += style.arm_pitch
        # The arm swings slightly out (abduction) the further it leaves the hanging pose, and
        # turns inward as it swings forward.
        out = np.sqrt(swing_forward**2 + 0.05**2) - 0.05  # smooth |swing|
        joints[:, dof_index(f"{name}_shoulder_x")] = -sign * (_SHOULDER_ABDUCTION + _SHOULDER_ABDUCTION_SWING * out)
        if style.arm_abduction:  # (only when set: the other clips keep their exact bits)
            joints[:, dof_index(f"{name}_shoulder_x")] -= sign * style.arm_abduction
        joints[:, dof_index(f"{name}_shoulder_z")] = sign * _SHOULDER_ROTATION_GAIN * swing_forward
        forward = 0.5 * (swing_forward + np.sqrt(swing_forward**2 + 0.05**2))  # smooth max(0, .)
        joints[:, dof_index(f"{name}_elbow")] = -(style.elbow + _ELBOW_SWING_GAIN * forward)

    # Safety net: the plan keeps every joint inside its range; clip rounding-level excursions.
    excess = np.maximum(geo.dof_low - joints, joints - geo.dof_high)[crop]
    if np.max(excess) > _RANGE_TOLERANCE:
        worst = np.unravel_index(np.argmax(excess), excess.shape)
        raise ValueError(
            f"synthesised motion leaves the range of {DOF_NAMES[worst[1]]} by "
            f"{math.degrees(excess[worst]):.1f} deg at frame {worst[0]}: these parameters ask too "
            "much of the body (lower steps, deeper treads or a slower gait)"
        )
    joints = np.clip(joints, geo.dof_low, geo.dof_high)
    quat = pelvis_rot.as_quat(scalar_first=True)
    qpos = np.column_stack((pelvis_pos, quat, joints))
    return qpos[crop], feet.contact[crop]


# --- public generators ---------------------------------------------------------------------------
def default_step_length(speed: float) -> float:
    """Step length (m, one foot to the other) of an unhurried walk at ``speed`` (m/s).

    0.30 m + 0.20 s * speed, within [0.30, 0.70]: 0.50 m at 1 m/s (120 steps per minute),
    0.46 m at 0.8 m/s, 0.54 m at 1.2 m/s. Feet land flat, so a humanoid with 0.88 m legs
    takes somewhat shorter steps than a heel-striking person would.
    """
    return float(np.clip(0.30 + 0.20 * speed, 0.30, 0.70))


def default_stair_step_time(step_height: float, direction: str) -> float:
    """Seconds per step on stairs: 0.55 s + 0.5 s/m * step height going up (0.65 s at 0.20 m),
    0.5 s + 0.5 s/m * step height going down (about 90-110 steps per minute)."""
    return (0.55 if direction == "up" else 0.50) + 0.5 * step_height


def _check_number(name: str, value: float, low: float, high: float, low_open: bool = True) -> float:
    value = float(value)
    above = value > low if low_open else value >= low
    if not (math.isfinite(value) and above and value <= high):
        raise ValueError(f"{name} must be in {'(' if low_open else '['}{low}, {high}], got {value!r}")
    return value


def _check_count(name: str, value: int, low: int, high: int) -> int:
    if isinstance(value, bool) or int(value) != value or not low <= value <= high:
        raise ValueError(f"{name} must be an integer in [{low}, {high}], got {value!r}")
    return int(value)


def _side(lead_foot: str) -> int:
    if lead_foot not in ("right", "left"):
        raise ValueError(f"lead_foot must be 'right' or 'left', got {lead_foot!r}")
    return RIGHT if lead_foot == "right" else LEFT


@dataclass(frozen=True)
class GaitTiming:
    """Shares of a step (the time from one foot landing to the other landing).

    ``double_support``: both feet flat or rolling after the leading foot lands (0.2 gives
    20% of the gait cycle in double support, 40% in swing). ``heel_off``: how long before the
    other foot lands the stance heel starts rising (the foot rolls over its toe edge, the
    push-off), reaching ``push_off_angle`` (rad, toes down) at lift-off. Feet are flat from
    landing to heel-off: 35% of the cycle with the defaults.
    """

    double_support: float = 0.2
    heel_off: float = 0.3
    push_off_angle: float = 0.4

    def __post_init__(self) -> None:
        _check_number("double_support", self.double_support, 0.0, 0.6)
        _check_number("heel_off", self.heel_off, 0.0, 0.6, low_open=False)
        _check_number("push_off_angle", self.push_off_angle, 0.0, 0.8, low_open=False)


def walk(speed: float = 1.0, step_length: float | None = None, duration: float = 4.0,
         fps: float = 30.0, step_width: float = 0.16, swing_height: float = 0.05,
         timing: GaitTiming = GaitTiming(), lead_foot: str = "right",
         name: str | None = None) -> MotionClip:
    """Walking straight along +x on flat ground, as a looping clip.

    ``speed`` (m/s) is the pelvis' constant forward speed; ``step_length`` (m between
    successive footsteps; default :func:`default_step_length`) sets the cadence. The gait
    cycle (two steps) is rounded to a whole number of frames, adjusting the step length by
    at most half a frame's travel, and the clip holds ``round(duration / cycle)`` (at least
    1) cycles. ``step_width`` is the lateral distance between the ankles, ``swing_height``
    the swing foot's lift (m), ``timing`` the gait phases (:class:`GaitTiming`).
    ``lead_foot`` is the foot that lands just before the first frame (the clip starts in
    the middle of a double support).

    The clip loops: its last frame repeats its first (root x advanced by the distance
    walked), and velocities are continuous across the seam. Feet land flat, so steps longer
    than about 0.6 m (speeds above about 1.5 m/s with the default step length) lower the
    pelvis into a crouched gait; there is no flight phase (no running).
    """
    return _walk_clip(speed, step_length, duration, fps, step_width, swing_height, timing, lead_foot, name,
                      _Style(), text="walk", style="neutral")


@dataclass(frozen=True)
class WalkStyle:
    """A walking style as gait and posture numbers (``WALK_STYLES``: SIMS' eight styles and neutral).

    Gait: ``speed`` (m/s), ``step_length`` (m; None: :func:`default_step_length`),
    ``step_width`` and ``swing_height`` (m), as :func:`walk`. Posture (rad): ``lean`` (trunk
    pitch forward), ``gaze`` (head pitch down from level; < 0 looks up), ``arm_swing``
    (shoulder swing per metre of foot lead), ``elbow`` (flexion with the arm hanging),
    ``obliquity`` (pelvic drop towards the swinging leg: the hip sway). ``text``: the
    clip's caption (``meta["text"]``), one of the script database's walking captions.
    """

    speed: float = 1.0
    step_length: float | None = None
    step_width: float = 0.16
    swing_height: float = 0.05
    lean: float = _Style.walk_lean          # posture defaults: the neutral walk's (_Style)
    gaze: float = _Style.walk_gaze
    arm_swing: float = _Style.arm_swing
    elbow: float = _Style.elbow
    obliquity: float = _Style.obliquity
    text: str = "walks calmly with an easy, smooth gait"

    def __post_init__(self) -> None:
        _check_number("speed", self.speed, 0.0, 3.0)
        _check_number("lean", self.lean, -0.2, 0.4, low_open=False)
        _check_number("gaze", self.gaze, -0.3, 0.6, low_open=False)
        _check_number("arm_swing", self.arm_swing, 0.0, 1.2, low_open=False)
        _check_number("elbow", self.elbow, 0.0, 1.5, low_open=False)
        _check_number("obliquity", self.obliquity, 0.0, 0.15, low_open=False)


#: The eight SIMS styles (and neutral) as walks: how fast, how long and wide the steps, how
#: high the feet, how far the trunk leans and the head drops, how much the arms swing.
WALK_STYLES: dict[str, WalkStyle] = {
    "neutral": WalkStyle(),
    "happy": WalkStyle(speed=1.25, swing_height=0.08, lean=0.0, gaze=-0.05, arm_swing=0.8, obliquity=0.07,
                       text="walks with light, springy steps"),
    "angry": WalkStyle(speed=1.35, step_width=0.2, lean=0.14, gaze=0.02, arm_swing=0.75, elbow=0.7,
                       text="stomps heavily with clenched fists"),
    "hurried": WalkStyle(speed=1.5, lean=0.16, gaze=0.1, arm_swing=0.7, elbow=0.5,
                         text="hurries over, leaning forward"),
    "tired": WalkStyle(speed=0.55, step_width=0.2, swing_height=0.03, lean=0.22, gaze=0.3, arm_swing=0.2,
                       elbow=0.1, text="trudges in slowly, body bent forward"),
    "sad": WalkStyle(speed=0.6, step_length=0.36, swing_height=0.03, lean=0.18, gaze=0.45, arm_swing=0.15,
                     elbow=0.1, text="walks slowly with the head bowed"),
    "stressed": WalkStyle(speed=1.1, step_length=0.42, lean=0.1, gaze=0.2, arm_swing=0.25, elbow=0.9,
                          text="walks with tight shoulders and short steps"),
    "drunk": WalkStyle(speed=0.7, step_width=0.3, lean=-0.04, gaze=0.0, arm_swing=0.6, obliquity=0.12,
                       text="staggers drunkenly, swaying from side to side"),
    "relaxed": WalkStyle(speed=0.85, lean=0.03, gaze=0.05, arm_swing=0.6, elbow=0.2,
                         text="ambles with loose, easy arms"),
}


def styled_walk(style: str | WalkStyle, duration: float = 4.0, fps: float = 30.0, lead_foot: str = "right",
                timing: GaitTiming = GaitTiming(), name: str | None = None) -> MotionClip:
    """A looping walk in a style (a name in :data:`WALK_STYLES` or a :class:`WalkStyle`), like
    :func:`walk` with the style's gait and posture; ``meta["style"]`` and ``meta["text"]`` say which."""
    if isinstance(style, str):
        if style not in WALK_STYLES:
            raise ValueError(f"style must be one of {sorted(WALK_STYLES)} or a WalkStyle, got {style!r}")
        label, style = style, WALK_STYLES[style]
    elif isinstance(style, WalkStyle):
        label = "custom"
    else:
        raise TypeError(f"style must be a style name or a WalkStyle, got {type(style).__name__}")
    posture = _Style(walk_lean=style.lean, stairs_lean=style.lean, walk_gaze=style.gaze, stairs_gaze=style.gaze,
                     arm_swing=style.arm_swing, elbow=style.elbow, obliquity=style.obliquity)
    return _walk_clip(style.speed, style.step_length, duration, fps, style.step_width, style.swing_height, timing,
                      lead_foot, name or f"walk_{label}", posture, text=style.text, style=label)


def _walk_clip(speed: float, step_length: float | None, duration: float, fps: float, step_width: float,
               swing_height: float, timing: GaitTiming, lead_foot: str, name: str | None, posture: _Style,
               *, text: str, style: str, nominal_height: float = _WALK_PELVIS_HEIGHT,
               generator: str = "walk", extra: dict | None = None) -> MotionClip:
    speed = _check_number("speed", speed, 0.0, 3.0)
    fps = _check_number("fps", fps, 0.0, 1000.0)
    step_length = default_step_length(speed) if step_length is None else _check_number(
        "step_length", step_length, 0.0, 0.9)
    _check_number("duration", duration, 0.0, 3600.0)
    swing_height = _check_number("swing_height", swing_height, 0.0, 0.3)
    step_width = _check_number("step_width", step_width, 0.0, 0.4)
    lead = _side(lead_foot)
    frames_per_cycle = max(4, int(round(2.0 * step_length / speed * fps)))
    cycle = frames_per_cycle / fps
    step_length = speed * cycle / 2.0
    cycles = max(1, int(round(duration / cycle)))

    pad_steps = 8
    count = 2 * pad_steps + 2 * cycles + 2
    xs = (np.arange(count) - pad_steps) * step_length
    plan = _GaitPlan.build(
        xs, np.zeros(count), (lead + pad_steps) % 2, step_width, np.full(count - 1, cycle / 2.0),
        timing.double_support, timing.heel_off, timing.push_off_angle, 1.0, _Terrain.flat(),
    )
    start = plan.mid_double_support(pad_steps)
    num_frames = cycles * frames_per_cycle + 1
    pad_frames = int(round(1.5 * fps))
    times = start + np.arange(-pad_frames, num_frames + pad_frames) / fps
    qpos, contact = _synthesise(
        plan, times, slice(pad_frames, pad_frames + num_frames), fps, style=posture,
        on_stairs=None, nominal_height=nominal_height, monotone=None, level_reference=None,
        clearance=_Clearance(edge=swing_height, horizontal=0.0, min_lift=swing_height),
    )
    # The frames are periodic up to spline round-off far from the padded ends: make the seam exact.
    qpos[-1, 1:] = qpos[0, 1:]
    qpos[-1, 0] = qpos[0, 0] + cycles * 2.0 * step_length
    params = dict(speed=speed, step_length=step_length, duration=cycles * cycle, fps=fps,
                  step_width=step_width, swing_height=swing_height, lead_foot=lead_foot,
                  **asdict(timing))
    return MotionClip(
        qpos, fps, name or f"walk_{speed:.2f}mps", loop=True, source=SOURCE,
        meta=clip_meta(generator, {**params, **(extra or {})}, contact, cycle_frames=frames_per_cycle, text=text,
                       skill="walk", style=style),
    )


#: Crouch-walk gait: the trailing heel rises early (half a step before the other foot lands), so that
#: the shin leaning far over a flat foot stays within the ankle's 55 degrees of dorsiflexion.
CROUCH_TIMING = GaitTiming(heel_off=0.5, push_off_angle=0.6)


def crouch_walk(speed: float = 1.0, pelvis_height: float = 0.6, lean: float = 1.5, duration: float = 4.0,
                fps: float = 30.0, step_length: float | None = None, step_width: float = 0.22,
                swing_height: float = 0.06, gaze: float | None = None, arm_pitch: float | None = None,
                elbow: float = 0.6, arm_abduction: float = 0.2, pelvis_share: float = 0.7, pelvis_back: float = 0.15,
                timing: GaitTiming = CROUCH_TIMING, lead_foot: str = "right", name: str | None = None) -> MotionClip:
    """A crouched walk (knees deeply bent, trunk leaning forward, head low) along +x, looping.

    The gait of :func:`walk` with the pelvis held at most ``pelvis_height`` (m) above the
    floor (the legs bend to reach it) and the trunk pitched forward by ``lean`` (rad;
    ``pelvis_share`` of it at the pelvis, the rest at the abdomen). The head looks ``gaze`` rad
    below level (default ``lean - 0.4``: the neck lifts the head 0.4 rad); the arms are carried
    ``arm_pitch`` rad at the shoulders (< 0 forward; default ``-0.8 * lean``) with the elbows
    bent ``elbow`` rad, so that they hang roughly vertically under the leaning trunk, held out by
    ``arm_abduction`` rad more than in a walk so that they clear the knees (self-collision). Steps are
    ``0.25 + 0.15 * speed`` m long by default; the trailing heel rises early
    (:data:`CROUCH_TIMING`). Hips flex past 90 degrees (``leg_ik``'s ``deep_flexion``). The pelvis
    is carried ``pelvis_back`` m behind its place between the feet, so that the leaning trunk keeps
    the centre of mass behind the front toe (without it the CoM passes the toe by up to 10 cm in a
    third of the frames; mocap walks never pass it). With the
    defaults (pelvis 0.6 m, the trunk nearly horizontal) the head centre is about 0.81 m above
    the floor, PlaMo's crouch-walk (``stairenv.planning.locomotion``), at every speed from 0.5 to
    1.5 m/s. Every joint stays in range (``ValueError`` otherwise); ``meta["skill"]`` is "walk"
    and ``meta["style"]`` "crouch".
    """
    pelvis_height = _check_number("pelvis_height", pelvis_height, 0.35, _WALK_PELVIS_HEIGHT)
    lean = _check_number("lean", lean, 0.0, 1.5, low_open=False)
    step_length = crouch_step_length(speed) if step_length is None else step_length
    gaze = lean - 0.4 if gaze is None else _check_number("gaze", gaze, -0.3, 1.3, low_open=False)
    arm_pitch = -0.8 * lean if arm_pitch is None else _check_number(
        "arm_pitch", arm_pitch, -1.5, 1.0, low_open=False)
    elbow = _check_number("elbow", elbow, 0.0, 1.5, low_open=False)
    arm_abduction = _check_number("arm_abduction", arm_abduction, 0.0, 0.8, low_open=False)
    pelvis_share = _check_number("pelvis_share", pelvis_share, 0.0, 1.0, low_open=False)
    pelvis_back = _check_number("pelvis_back", pelvis_back, -0.1, 0.3, low_open=False)
    posture = _crouch_style(lean, gaze, arm_pitch, elbow, arm_abduction, pelvis_share, pelvis_back)
    return _walk_clip(speed, step_length, duration, fps, step_width, swing_height, timing, lead_foot,
                      name or f"crouch_walk_{speed:.2f}mps", posture, text="crouch-walks, knees bent and head low",
                      style="crouch", nominal_height=pelvis_height, generator="crouch_walk",
                      extra=dict(pelvis_height=pelvis_height, lean=lean, gaze=gaze, arm_pitch=arm_pitch,
                                 elbow=elbow, arm_abduction=arm_abduction, pelvis_share=pelvis_share,
                                 pelvis_back=pelvis_back))


def _crouch_style(lean: float, gaze: float, arm_pitch: float, elbow: float, arm_abduction: float,
                  pelvis_share: float, pelvis_back: float) -> _Style:
    return _Style(walk_lean=lean, stairs_lean=lean, walk_gaze=gaze, stairs_gaze=gaze, arm_swing=0.35,
                  elbow=elbow, obliquity=0.03, arm_pitch=arm_pitch, pelvis_share=pelvis_share,
                  deep_flexion=True, pelvis_forward=-pelvis_back, arm_abduction=arm_abduction)


def crouch_step_length(speed: np.ndarray | float) -> np.ndarray | float:
    """Step length (m) of :func:`crouch_walk` at ``speed`` (m/s): 0.25 m + 0.15 s * speed."""
    return 0.25 + 0.15 * speed


def speed_change(speed_from: float, speed_to: float, ramp_steps: int = 6, steady_steps: int = 2,
                 crouch: bool = False, fps: float = 30.0, lead_foot: str = "right",
                 name: str | None = None) -> MotionClip:
    """A straight walk (or crouch-walk) that speeds up or slows down: ``steady_steps`` steps at
    ``speed_from`` (m/s), ``ramp_steps`` steps over which the speed changes smoothly (quintic in
    the step count) to ``speed_to``, ``steady_steps`` steps at ``speed_to``; not looping.

    The step length follows the speed (:func:`default_step_length`, or :func:`crouch_step_length`
    with ``crouch``), each step lasting its length over its speed, so the cadence changes with it.
    Speeds are 0.2-3 m/s: a walk cannot start from or come to a standstill here (every step swings
    a foot), so a start is a change from a slow walk, a stop one to it. ``crouch`` takes
    :func:`crouch_walk`'s posture and gait (default parameters: head ~0.81 m). ``meta["skill"]``
    is "walk"; ``meta["parameters"]`` holds both speeds.
    """
    speed_from = _check_number("speed_from", speed_from, 0.2, 3.0, low_open=False)
    speed_to = _check_number("speed_to", speed_to, 0.2, 3.0, low_open=False)
    ramp_steps = _check_count("ramp_steps", ramp_steps, 1, 50)
    steady_steps = _check_count("steady_steps", steady_steps, 0, 50)
    fps = _check_number("fps", fps, 0.0, 1000.0)
    if not isinstance(crouch, bool):
        raise TypeError(f"crouch must be a bool, got {type(crouch).__name__}")
    lead = _side(lead_foot)
    if crouch:
        lean = 1.5
        posture = _crouch_style(lean, lean - 0.4, -0.8 * lean, 0.6, 0.2, 0.7, 0.15)
        nominal, timing, step_width, swing_height = 0.6, CROUCH_TIMING, 0.22, 0.06
        step_of = crouch_step_length
    else:
        posture, nominal, timing, step_width, swing_height = _Style(), _WALK_PELVIS_HEIGHT, GaitTiming(), 0.16, 0.05
        step_of = np.vectorize(default_step_length)
    pad_steps = 8
    before = pad_steps + steady_steps
    n_steps = 2 * before + ramp_steps  # step intervals; footsteps are one more
    share = smoothstep((np.arange(n_steps) - before + 0.5) / ramp_steps)
    speeds = speed_from + share * (speed_to - speed_from)
    lengths = np.asarray(step_of(speeds), dtype=float)
    durations = lengths / speeds
    xs = np.concatenate(([0.0], np.cumsum(lengths)))
    xs -= xs[pad_steps]
    plan = _GaitPlan.build(
        xs, np.zeros(n_steps + 1), (lead + pad_steps) % 2, step_width, durations,
        timing.double_support, timing.heel_off, timing.push_off_angle, 1.0, _Terrain.flat(),
    )
    start = plan.mid_double_support(pad_steps)
    end = plan.mid_double_support(n_steps - pad_steps)
    num_frames = int(math.floor((end - start) * fps + 1e-9)) + 1
    pad_frames = int(round(1.5 * fps))
    times = start + np.arange(-pad_frames, num_frames + pad_frames) / fps
    qpos, contact = _synthesise(
        plan, times, slice(pad_frames, pad_frames + num_frames), fps, style=posture,
        on_stairs=None, nominal_height=nominal, monotone=None, level_reference=None,
        clearance=_Clearance(edge=swing_height, horizontal=0.0, min_lift=swing_height),
    )
    kind = "crouch_walk" if crouch else "walk"
    params = dict(speed_from=speed_from, speed_to=speed_to, ramp_steps=ramp_steps, steady_steps=steady_steps,
                  crouch=crouch, fps=fps, step_width=step_width, swing_height=swing_height, lead_foot=lead_foot,
                  **asdict(timing))
    verb = "speeds up" if speed_to > speed_from else "slows down"
    return MotionClip(
        qpos, fps, name or f"{kind}_{speed_from:.1f}_to_{speed_to:.1f}mps", loop=False, source=SOURCE,
        meta=clip_meta("speed_change", params, contact, skill="walk", style="crouch" if crouch else "neutral",
                       text=f"{'crouch-walks' if crouch else 'walks'} and {verb}"),
    )


def climb_stairs(step_height: float, step_depth: float, num_steps: int, approach_steps: int = 2,
                 direction: str = "up", fps: float = 30.0, landing_steps: int = 2,
                 walk_speed: float = 0.9, walk_step_length: float | None = None,
                 step_time: float | None = None, step_width: float = 0.16,
                 edge_clearance: float = 0.04, swing_height: float = 0.05,
                 timing: GaitTiming = GaitTiming(), lead_foot: str = "right",
                 name: str | None = None) -> MotionClip:
    """Walking up (or down) a straight staircase, step over step, one foot per tread.

    The staircase is ``Staircase(step_height, step_depth, width, num_steps, landing_depth,
    yaw=0, distance=0)`` in its own frame (module docstring): risers at x = 0, d, ...,
    (n-1) d, the landing from (n-1) d on at height n h. ``num_steps`` counts the risers,
    the landing's included (n-1 treads, then the landing).

    ``direction="up"``: the clip starts mid-walk on the floor, takes ``approach_steps``
    floor steps (the last one about ``step_depth`` before the first riser), one step onto
    each tread, one onto the landing, then ``landing_steps`` more steps on the landing,
    ending in the middle of a double support. ``"down"``: the mirror image, from the landing
    (``approach_steps`` on it, facing -x) down to the floor (``landing_steps`` on it).

    ``walk_speed`` and ``walk_step_length`` set the walk on the floor and the landing;
    ``step_time`` (s) is the time per step on the stairs (default
    :func:`default_stair_step_time`); step durations blend over the transitions.
    ``lead_foot`` is the foot that steps onto the first tread (ascent) or down the first
    riser (descent). ``edge_clearance`` is the least height of the sole over any tread edge
    it passes (from the moment the foot, widened by 2 cm, reaches beyond its own tread),
    ``swing_height`` the least lift of a swing, ``timing`` the gait phases
    (:class:`GaitTiming`).

    Each foot is centred on its tread (equal heel and toe margins, (d - foot length) / 2 each;
    on ascent up to 2 cm further back, keeping 1.5 cm of tread behind the heel, so that the
    shin leaning over the foot stays clear of the next nose), so ``step_depth`` must exceed
    the foot length (0.177 m) by at least 1 cm; treads under
    about 0.22 m leave a foot less than 2 cm from the risers. One foot per tread limits
    ``step_depth`` to 0.5 m and ``step_height`` to 0.25 m; steep descents (0.25 m steps on
    treads of 0.3 m and deeper) exceed the ankles' range and raise ``ValueError``. The flat
    walk before and after the flight keeps one pelvis height over the ground, so the pelvis
    rises (drops) by exactly ``num_steps * step_height``, monotonically.
    ``meta["stairs"]`` holds the staircase, with a landing deep enough for the clip.
    """
    if direction not in ("up", "down"):
        raise ValueError(f"direction must be 'up' or 'down', got {direction!r}")
    geo = leg_geometry()
    step_height = _check_number("step_height", step_height, 0.0, MAX_STEP_HEIGHT)
    step_depth = _check_number("step_depth", step_depth, 0.0, MAX_STEP_DEPTH)
    num_steps = _check_count("num_steps", num_steps, 1, 30)
    approach_steps = _check_count("approach_steps", approach_steps, 0, 100)
    landing_steps = _check_count("landing_steps", landing_steps, 0, 100)
    margin = 0.5 * (step_depth - geo.foot_length)
    if margin < 0.005:
        raise ValueError(
            f"step_depth {step_depth} m leaves no room for a flat foot (foot length "
            f"{geo.foot_length:.4f} m; need at least {geo.foot_length + 0.01:.3f} m)"
        )
    fps = _check_number("fps", fps, 0.0, 1000.0)
    walk_speed = _check_number("walk_speed", walk_speed, 0.0, 3.0)
    walk_step = default_step_length(walk_speed) if walk_step_length is None else _check_number(
        "walk_step_length", walk_step_length, 0.0, 0.9)
    stair_time = default_stair_step_time(step_height, direction) if step_time is None else _check_number(
        "step_time", step_time, 0.0, 5.0)
    edge_clearance = _check_number("edge_clearance", edge_clearance, 0.0, 0.3)
    swing_height = _check_number("swing_height", swing_height, 0.0, 0.3)
    step_width = _check_number("step_width", step_width, 0.0, 0.4)
    lead = _side(lead_foot)
    up = direction == "up"
    facing = 1.0 if up else -1.0
    pad_steps = 6

    # Footsteps in ascent order: flat floor steps, "tread 0" (the last floor step, placed as
    # if on a tread of depth d just before the first riser), treads 1..n-1, the first landing
    # step (centred on a virtual tread n), flat landing steps. Reversed for descent.
    tread = np.arange(0, num_steps + 1)
    # On ascent the feet sit a little behind the tread centres: the shin, leaning forward over
    # the foot, then has more room in front of the next nose.
    set_back = min(_ASCENT_SET_BACK, max(0.0, margin - _HEEL_ON_TREAD)) if up else 0.0
    tread_centres = (tread - 0.5) * step_depth - set_back
    floor_before = (approach_steps if up else landing_steps) + pad_steps
    landing_after = (landing_steps if up else approach_steps) + pad_steps
    centres = np.concatenate((
        tread_centres[0] - walk_step * np.arange(floor_before, 0, -1), tread_centres,
        tread_centres[-1] + walk_step * np.arange(1, landing_after + 1),
    ))
    soles = np.concatenate((np.zeros(floor_before), tread * step_height,
                            np.full(landing_after, num_steps * step_height)))
    if up:
        first_riser_step = floor_before + 1       # the footstep onto tread 1
    else:
        centres, soles = centres[::-1], soles[::-1]
        first_riser_step = landing_after + 1      # the first footstep down
    first_clip_step = pad_steps                   # the clip starts as this footstep has landed
    last_clip_step = len(centres) - 1 - pad_steps
    xs = centres - facing * geo.foot_centre       # foot centre on the (set-back) tread centre
    first_side = (lead - first_riser_step) % 2
    # Step durations: walking cadence on the flat, stair cadence across risers, blended.
    across_riser = np.abs(np.diff(soles)) > 1e-9
    durations = np.where(across_riser, stair_time, walk_step / walk_speed)
    durations = np.convolve(np.pad(durations, 1, mode="edge"), [0.25, 0.5, 0.25], mode="valid")
    plan = _GaitPlan.build(
        xs, soles, first_side, step_width, durations, timing.double_support, timing.heel_off,
        timing.push_off_angle, facing, _Terrain.stairs(step_height, step_depth, num_steps),
    )

    start = plan.mid_double_support(first_clip_step)
    end = plan.mid_double_support(last_clip_step)
    num_frames = int(math.floor((end - start) * fps + 1e-9)) + 1
    pad_frames = int(round(1.5 * fps))
    times = start + np.arange(-pad_frames, num_frames + pad_frames) / fps
    # Walk-to-stairs posture blend: on while the pelvis is over the flight.
    track_x = _pelvis_horizontal(plan, times)[:, 0]
    on_stairs = (track_x > -0.3 * step_depth) & (track_x < (num_steps - 0.7) * step_depth)
    steepness = math.atan2(step_height, step_depth)
    style = _Style(
        stairs_lean=0.06 + 0.25 * steepness if up else 0.03,
        stairs_gaze=0.30 if up else 0.40,
    )
    qpos, contact = _synthesise(
        plan, times, slice(pad_frames, pad_frames + num_frames), fps, style=style,
        on_stairs=on_stairs, nominal_height=_WALK_PELVIS_HEIGHT, monotone=direction,
        level_reference=times < plan.liftoff[first_riser_step - 2],
        clearance=_Clearance(edge=edge_clearance, horizontal=_HORIZONTAL_CLEARANCE,
                             min_lift=swing_height),
    )
    top_riser = (num_steps - 1) * step_depth
    landing_needed = float(np.max(qpos[:, 0]) - top_riser) + 0.6
    stairs = dict(step_height=step_height, step_depth=step_depth, width=1.5, num_steps=num_steps,
                  landing_depth=float(max(2.0, math.ceil(landing_needed * 2.0) / 2.0)),
                  yaw=0.0, distance=0.0)
    params = dict(step_height=step_height, step_depth=step_depth, num_steps=num_steps,
                  approach_steps=approach_steps, direction=direction, fps=fps,
                  landing_steps=landing_steps, walk_speed=walk_speed, walk_step_length=walk_step,
                  step_time=stair_time, step_width=step_width, edge_clearance=edge_clearance,
                  swing_height=swing_height, lead_foot=lead_foot, **asdict(timing))
    default_name = f"stairs_{direction}_h{step_height:.2f}_d{step_depth:.2f}_n{num_steps}_{lead_foot}"
    return MotionClip(
        qpos, fps, name or default_name, loop=False, source=SOURCE,
        meta=clip_meta("climb_stairs", params, contact, stairs=stairs, skill="walk",
                        text="walk up the stairs" if direction == "up" else "walk down the stairs"),
    )


# --- the default reference set -------------------------------------------------------------------
def reference_set(fps: float = 30.0, walk_speeds: Sequence[float] = (0.8, 1.2),
                  step_heights: Sequence[float] = (0.05, 0.10, 0.15, 0.20),
                  step_depths: Sequence[float] = (0.28, 0.35), num_steps: int = 5,
                  descents: bool = True) -> list[MotionClip]:
    """The env's default reference clips: flat walks at ``walk_speeds`` (4 s loops), and
    for every step height and depth an ascent (and a descent) of ``num_steps`` risers.

    The lead foot alternates from clip to clip so both feet lead equally often.
    Defaults: 2 walks + 8 ascents + 8 descents = 18 clips (about 90 s of motion,
    synthesised in about a second).
    """
    clips = [walk(speed, duration=4.0, fps=fps, lead_foot=("right", "left")[i % 2])
             for i, speed in enumerate(walk_speeds)]
    directions = ("up", "down") if descents else ("up",)
    index = 0
    for direction in directions:
        for height in step_heights:
            for depth in step_depths:
                clips.append(climb_stairs(height, depth, num_steps, direction=direction, fps=fps,
                                          lead_foot=("right", "left")[index % 2]))
                index += 1
    return clips


def save_reference_set(folder: str | Path, **kwargs) -> list[Path]:
    """Write :func:`reference_set` (``kwargs`` passed on) as ``<folder>/<clip name>.npz``;
    returns the paths."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    return [clip.save(folder / f"{clip.name}.npz") for clip in reference_set(**kwargs)]
