"""BVH (Biovision hierarchy): a parser, forward kinematics, and a retargeter to our humanoid.

Parsing (:func:`parse_bvh`, :func:`read_bvh`)
    ``HIERARCHY`` with ``ROOT``/``JOINT``/``End Site`` blocks, each ``OFFSET x y z`` and
    (joints) ``CHANNELS n name...``; then ``MOTION``, ``Frames: F``, ``Frame Time: dt``
    and F lines of numbers, one per channel in hierarchy order. Everything is checked:
    braces, channel names and counts, the number of frames and of values per frame,
    finite numbers, and the importers' limits (frame rate, duration, frames, joints, size
    of numbers). Faults raise ``MotionFileError`` with the file (and line) and what is wrong.

Conventions of the BVH itself (:func:`forward_kinematics`)
    A joint's rotation channels, in the order written, compose intrinsically: channels
    ``Zrotation Yrotation Xrotation`` mean R = Rz Ry Rx (``Rotation.from_euler("ZYX", ...)``)
    and ``Xrotation Zrotation Yrotation`` would mean R = Rx Rz Ry; the order is always read
    from the file. Angles are degrees. Position channels give that component of the
    joint's translation from its parent (replacing the ``OFFSET`` component; for a root
    they are its world position). World rotation of a joint = parent's world rotation x
    local rotation; a joint sits at parent position + parent's world rotation applied to
    its translation. All-zero channels are the rest pose the offsets describe.

Retargeting (:func:`retarget`, :func:`import_bvh`)
    A :class:`SourceSkeleton` names, for each of our bodies, the source joint whose world
    rotation drives it, and the two source points that span the same bone in the rest
    pose. With C the change of axes (for y-up sources (x, y, z) -> (x, -z, y), i.e. +90
    degrees about x) our body's world rotation is

        G_ours(b) = C G_src(j(b)) C^-1 A_b,

    where A_b, the rest-pose alignment, is our body's orientation when the source is in
    its rest pose: the pelvis frame of the rest pose (facing the source's forward, see
    below) turned by the smallest rotation that takes our bone direction in the zero pose
    (limbs point down their -z axis, the spine and head up, the feet forward along x)
    onto the source bone. So the retargeted pose keeps the source's bone directions
    (checked: ``meta["limb_direction_error_deg"]``), and the twist about each bone follows
    the source joint. Our local rotations are G_ours(parent)^-1 G_ours(b); joints the
    source has and we lack (CMU's zero-length LHipJoint, RHipJoint, LowerBack, Neck,
    shoulders, and Spine) are merged because only world rotations of the mapped joints
    enter. Three-axis joints become XYZ Euler angles (``importers.joints_to_qpos``), knees
    and elbows the twist about y. Three calibrations complete the rest alignment where
    rest offsets say nothing:

    * pelvis: from positions, not from the source's root rotation (which carries the
      capture's pelvic tilt, about 24 degrees for CMU): y along the hip line, z towards
      the top of the trunk (``trunk_top``, CMU's Spine1, where our abdomen joint sits),
      x = y cross z, so our pelvis-to-torso segment follows the source's trunk;
    * knee and elbow axes (``align_hinges``): the twist of each limb about its bone that
      puts the source's hinge axis, measured from the motion, on our y axis (CMU's elbow
      axis sits 21 degrees off a swing-only alignment);
    * feet (``flat_feet``): a constant tilt so the soles are level when the ankles are at
      rest (CMU's rest feet are rolled about 20 degrees against a flat stance).

    The root (our pelvis origin, the centre of the hip joints) follows the midpoint of the
    source's hip joints, scaled by our leg length (hip-knee 0.422 + knee-ankle 0.409 m)
    over the source's (in file units), so strides and step heights scale with the legs.
    The pose is resampled to ``fps`` (default 30) by slerp of the rotations before the
    projection onto joint angles (Euler angles are never interpolated), and shifted so
    the lowest point of the body over the clip touches the floor.

Source skeletons: ``"cmu"`` (the CMU mocap BVH conversion by B. Hahne / cgspeed, 31
joints, y up, about 0.0564 m per unit, frame 0 a tool-written reference pose).
"""

from __future__ import annotations

import math
import re
import sys
from collections.abc import Collection, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from stairenv.humanoid import BODY_NAMES, JOINTS, PARENT_INDICES, humanoid_model
from stairenv.humanoid.kinematics import body_rotations
from stairenv.motion.clip import MotionClip, MotionFileError
from stairenv.motion.importers.common import (COMPILED_VITERBI_FRAMES, MAX_ABS_VALUE, MAX_JOINTS, check_timing,
                                              check_values, compose, euler_rotation, joints_to_qpos, make_clip,
                                              read_limited, snap_fps)

_POSITION_CHANNELS = {"xposition": 0, "yposition": 1, "zposition": 2}
_ROTATION_CHANNELS = {"xrotation": "X", "yrotation": "Y", "zrotation": "Z"}


# --------------------------------------------------------------------------------------
# Parsing
# --------------------------------------------------------------------------------------
@dataclass
class BvhJoint:
    """One joint: its name, parent index (-1 for a root), offset, channels and end sites."""

    name: str
    parent: int
    offset: np.ndarray
    channels: tuple[str, ...]
    channel_start: int
    end_sites: list[np.ndarray] = field(default_factory=list)

    @property
    def rotation_order(self) -> str:
        """Intrinsic Euler sequence of the rotation channels, e.g. "ZYX" (R = Rz Ry Rx)."""
        return "".join(_ROTATION_CHANNELS[c.lower()] for c in self.channels if c.lower() in _ROTATION_CHANNELS)


@dataclass
class BvhMotion:
    """A parsed BVH file: joints in file order (parents before children), frames (F, channels)."""

    joints: list[BvhJoint]
    frame_time: float
    frames: np.ndarray
    path: str = ""

    @property
    def names(self) -> list[str]:
        return [j.name for j in self.joints]

    @property
    def num_channels(self) -> int:
        return sum(len(j.channels) for j in self.joints)

    @property
    def fps(self) -> float:
        return 1.0 / self.frame_time

    def index(self, name: str) -> int:
        for i, joint in enumerate(self.joints):
            if joint.name == name:
                return i
        raise KeyError(name)

    def rest_positions(self) -> dict[str, np.ndarray]:
        """Rest-pose positions (file units) of every joint and of end sites ("Joint/End")."""
        pos: dict[str, np.ndarray] = {}
        for joint in self.joints:
            base = pos[self.joints[joint.parent].name] if joint.parent >= 0 else np.zeros(3)
            pos[joint.name] = base + joint.offset
            for k, end in enumerate(joint.end_sites):
                pos[f"{joint.name}/End" + (str(k) if k else "")] = pos[joint.name] + end
        return pos


class _Tokens:
    """Whitespace tokens of the hierarchy with their line numbers."""

    def __init__(self, lines: list[str], path: str) -> None:
        self.items = [(tok, n + 1) for n, line in enumerate(lines) for tok in line.split()]
        self.pos = 0
        self.path = path

    def error(self, message: str) -> MotionFileError:
        line = self.items[min(self.pos, len(self.items) - 1)][1] if self.items else 1
        return MotionFileError(f"{self.path}, line {line}: {message}")

    def next(self, what: str) -> str:
        if self.pos >= len(self.items):
            raise self.error(f"unexpected end of the hierarchy, expected {what}")
        tok = self.items[self.pos][0]
        self.pos += 1
        return tok

    def expect(self, word: str) -> None:
        tok = self.next(repr(word))
        if tok.upper() != word.upper():
            self.pos -= 1
            raise self.error(f"expected {word!r}, found {tok!r}")

    def number(self, what: str) -> float:
        tok = self.next(what)
        try:
            value = float(tok)
        except ValueError:
            self.pos -= 1
            raise self.error(f"expected a number for {what}, found {tok!r}") from None
        if not abs(value) <= MAX_ABS_VALUE:
            self.pos -= 1
            raise self.error(f"{what} is {tok[:30]}, not a finite number within +-{MAX_ABS_VALUE:g}")
        return value

    def peek(self) -> str | None:
        return self.items[self.pos][0] if self.pos < len(self.items) else None


def _parse_joint(tokens: _Tokens, name: str, parent: int, joints: list[BvhJoint], channel_start: int) -> int:
    tokens.expect("{")
    tokens.expect("OFFSET")
    offset = np.array([tokens.number(f"OFFSET of {name}") for _ in range(3)])
    channels: tuple[str, ...] = ()
    if (tokens.peek() or "").upper() == "CHANNELS":
        tokens.next("CHANNELS")
        count_tok = tokens.next(f"channel count of {name}")
        if not re.fullmatch("[0-6]", count_tok):  # three positions and three rotations at most
            tokens.pos -= 1
            raise tokens.error(f"channel count of {name} must be an integer from 0 to 6, found {count_tok[:30]!r}")
        names = []
        for _ in range(int(count_tok)):
            tok = tokens.next(f"channel name of {name}")
            if tok.lower() not in _POSITION_CHANNELS and tok.lower() not in _ROTATION_CHANNELS:
                tokens.pos -= 1
                raise tokens.error(
                    f"joint {name}: unknown channel {tok!r} (CHANNELS {count_tok} announced; "
                    "expected X/Y/Z position or rotation)"
                )
            names.append(tok)
        if len({n.lower() for n in names}) != len(names):
            raise tokens.error(f"joint {name}: repeated channel in {names}")
        channels = tuple(names)
    if len(joints) >= MAX_JOINTS:
        raise tokens.error(f"more than {MAX_JOINTS} joints")
    joint = BvhJoint(name, parent, offset, channels, channel_start)
    index = len(joints)
    joints.append(joint)
    channel_start += len(channels)
    while True:
        tok = tokens.next(f"'}}' closing joint {name}")
        upper = tok.upper()
        if upper == "}":
            return channel_start
        if upper == "JOINT":
            child = tokens.next("joint name")
            if child in {j.name for j in joints}:
                raise tokens.error(f"joint name {child!r} used twice")
            channel_start = _parse_joint(tokens, child, index, joints, channel_start)
        elif upper == "END":
            tokens.expect("Site")
            tokens.expect("{")
            tokens.expect("OFFSET")
            joint.end_sites.append(np.array([tokens.number(f"End Site OFFSET of {name}") for _ in range(3)]))
            tokens.expect("}")
        else:
            tokens.pos -= 1
            raise tokens.error(f"expected JOINT, End Site or '}}' in joint {name}, found {tok!r}")


def parse_bvh(text: str, path: str = "<bvh>") -> BvhMotion:
    """Parse BVH text. Raises ``MotionFileError`` naming ``path``, the line and the fault."""
    lines = text.splitlines()
    motion_line = next((i for i, line in enumerate(lines) if line.strip().upper() == "MOTION"), None)
    if not lines or lines[0].strip().upper() != "HIERARCHY" and not text.lstrip().upper().startswith("HIERARCHY"):
        raise MotionFileError(f"{path}: not a BVH file (does not start with HIERARCHY)")
    if motion_line is None:
        raise MotionFileError(f"{path}: no MOTION section (file truncated in the hierarchy?)")
    tokens = _Tokens(lines[:motion_line], path)
    tokens.expect("HIERARCHY")
    joints: list[BvhJoint] = []
    channels = 0
    while tokens.peek() is not None:
        tokens.expect("ROOT")
        name = tokens.next("root name")
        channels = _parse_joint(tokens, name, -1, joints, channels)
    if not joints:
        raise MotionFileError(f"{path}: the hierarchy has no ROOT")
    if channels == 0:
        raise MotionFileError(f"{path}: the hierarchy has no channels")

    def header(line_no: int, key: str) -> str:
        if line_no >= len(lines):
            raise MotionFileError(f"{path}: truncated after MOTION (missing {key!r})")
        line = lines[line_no].strip()
        match = re.match(rf"{key}\s*:?\s*(\S+)\s*$", line, flags=re.IGNORECASE)
        if not match:
            raise MotionFileError(f"{path}, line {line_no + 1}: expected '{key}: <number>', found {line[:60]!r}")
        return match.group(1)

    n_text = header(motion_line + 1, "Frames")
    if not re.fullmatch("[0-9]{1,18}", n_text):
        raise MotionFileError(f"{path}, line {motion_line + 2}: frame count {n_text[:30]!r} is not an integer")
    declared = int(n_text)
    try:
        frame_time = float(header(motion_line + 2, "Frame Time"))
    except ValueError:
        raise MotionFileError(f"{path}, line {motion_line + 3}: frame time is not a number") from None
    if not (math.isfinite(frame_time) and frame_time > 0):
        raise MotionFileError(f"{path}, line {motion_line + 3}: frame time must be positive, got {frame_time}")
    check_timing(path, declared, 1.0 / frame_time, max(declared - 1, 0) * frame_time)

    frames = _parse_frames_compiled(lines[motion_line + 3:], declared, channels)
    if frames is None:
        frames = _parse_frames(lines, motion_line, declared, channels, path)
    check_values(path, "frame values", frames)
    return BvhMotion(joints, frame_time, frames, path)


def _parse_frames_compiled(lines: list[str], declared: int, channels: int) -> np.ndarray | None:
    """The frame values parsed by the compiled ``kernels.parse_frames`` (the same doubles as ``float()``),
    where the clip is long enough to load numba anyway (as the Viterbi pass does: ``COMPILED_VITERBI_FRAMES``
    frames, or 500 in a process that has loaded it); None where it is not, or where the lines (after
    the header; blank ones skipped) are not ``declared`` lines of ``channels`` numbers of the plain form
    that parser takes (``_parse_frames`` then reads them, or names the fault)."""
    if not (declared >= COMPILED_VITERBI_FRAMES or (declared >= 500 and "numba" in sys.modules)):
        return None
    block = "\n".join(lines)
    if not block.isascii():
        return None
    from stairenv.motion.importers.kernels import parse_frames

    frames, status = parse_frames(np.frombuffer(block.encode("ascii"), dtype=np.uint8), declared, channels)
    return frames if status == 0 else None


def _parse_frames(lines: list[str], motion_line: int, declared: int, channels: int, path: str) -> np.ndarray:
    """The frame values (the lines after the MOTION header, blank ones skipped) through ``float()``;
    ``MotionFileError`` naming the line of a fault."""
    data_lines = [(n, line) for n, line in enumerate(lines[motion_line + 3:], start=motion_line + 4) if line.strip()]
    if len(data_lines) < declared:
        raise MotionFileError(
            f"{path}: truncated motion: 'Frames: {declared}' declared but only {len(data_lines)} frame lines"
        )
    if len(data_lines) > declared:
        raise MotionFileError(
            f"{path}: 'Frames: {declared}' declared but {len(data_lines)} frame lines follow "
            f"(first extra at line {data_lines[declared][0]})"
        )
    tokens: list[str] = []
    for k, (line_no, line) in enumerate(data_lines):
        parts = line.split()
        if len(parts) != channels:
            raise MotionFileError(
                f"{path}, line {line_no}: frame {k} has {len(parts)} values, the hierarchy declares {channels} channels"
            )
        tokens += parts
    try:  # every value through float(), as before, but in one pass over the frames
        frames = np.array(list(map(float, tokens)), dtype=np.float64).reshape(declared, channels)
    except ValueError:
        for k, (line_no, line) in enumerate(data_lines):
            bad = next((p for p in line.split() if not _is_float(p)), None)
            if bad is not None:
                raise MotionFileError(f"{path}, line {line_no}: frame {k}: {bad[:30]!r} is not a number") from None
        raise
    return frames


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def read_bvh(path: str | Path) -> BvhMotion:
    """Read and parse a BVH file (``MotionFileError`` on unreadable or corrupt files)."""
    path = Path(path)
    try:
        text = read_limited(path).decode("utf-8")
    except UnicodeDecodeError as err:
        raise MotionFileError(f"{path}: not a text file ({err.reason} at byte {err.start})") from err
    return parse_bvh(text, str(path))


# --------------------------------------------------------------------------------------
# Forward kinematics of the source
# --------------------------------------------------------------------------------------
def forward_kinematics(motion: BvhMotion, frames: np.ndarray | None = None,
                       only: Collection[str] | None = None) -> tuple[list[Rotation | None], np.ndarray]:
    """World rotations (one (F,) ``Rotation`` per joint) and positions (F, J, 3), file units and axes.

    ``only``: the joints wanted (with their ancestors, which they need); the others are skipped
    (rotation None, position 0), the same values for the rest."""
    frames = motion.frames if frames is None else np.atleast_2d(frames)
    n = frames.shape[0]
    wanted = None
    if only is not None:
        wanted = set()
        for name in only:
            j = motion.index(name)
            while j >= 0 and j not in wanted:
                wanted.add(j)
                j = motion.joints[j].parent
    rotations: list[Rotation | None] = []
    positions = np.zeros((n, len(motion.joints), 3))
    for j, joint in enumerate(motion.joints):
        if wanted is not None and j not in wanted:
            rotations.append(None)
            continue
        translation = np.repeat(joint.offset[None], n, axis=0)
        angles, order = [], ""
        for k, channel in enumerate(joint.channels):
            c = channel.lower()
            column = frames[:, joint.channel_start + k]
            if c in _POSITION_CHANNELS:
                translation[:, _POSITION_CHANNELS[c]] = column
            else:
                angles.append(column)
                order += _ROTATION_CHANNELS[c]
        local = (euler_rotation(order, np.stack(angles, axis=1), degrees=True) if order
                 else Rotation.identity(n))
        if joint.parent < 0:
            rotations.append(local)
            positions[:, j] = translation
        else:
            parent = rotations[joint.parent]
            rotations.append(compose(parent, local))
            positions[:, j] = positions[:, joint.parent] + parent.apply(translation)
    return rotations, positions


# --------------------------------------------------------------------------------------
# Source skeletons
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SourceSkeleton:
    """How a source skeleton maps onto ours.

    ``bodies``: our body -> source joint whose world rotation drives it (every body with a
    joint of ours; the pelvis entry names the source root). ``bones``: our body -> (start,
    end) source points (joint names, or "Joint/End" for an end site) spanning the same
    bone in the rest pose; our bone is the body's direction in ``our_bones()``. ``hips``:
    (left, right) hip joints: the root follows their midpoint, and with ``trunk_top`` (the
    source joint nearest our abdomen joint) they give the pelvis frame (``pelvis_frame``).
    ``legs``: (hip, knee, ankle) chains for the leg length. ``to_z_up``: source axes -> ours.
    ``unit``: metres per file unit (nominal; the root path is scaled by leg lengths).
    ``skip_frames``: leading frames that are not motion.
    """

    name: str
    bodies: Mapping[str, str]
    bones: Mapping[str, tuple[str, str]]
    hips: tuple[str, str]
    trunk_top: str
    legs: tuple[tuple[str, str, str], ...]
    to_z_up: Rotation
    unit: float
    skip_frames: int = 0


Y_UP_TO_Z_UP = Rotation.from_euler("x", 90.0, degrees=True)  # (x, y, z) -> (x, -z, y)

CMU = SourceSkeleton(
    name="cmu",
    bodies={
        "pelvis": "Hips",
        "torso": "Spine1",
        "head": "Head",
        "right_upper_arm": "RightArm",
        "right_lower_arm": "RightForeArm",
        "left_upper_arm": "LeftArm",
        "left_lower_arm": "LeftForeArm",
        "right_thigh": "RightUpLeg",
        "right_shin": "RightLeg",
        "right_foot": "RightFoot",
        "left_thigh": "LeftUpLeg",
        "left_shin": "LeftLeg",
        "left_foot": "LeftFoot",
    },
    bones={
        "torso": ("LowerBack", "Neck"),
        "head": ("Head", "Head/End"),
        "right_upper_arm": ("RightArm", "RightForeArm"),
        "right_lower_arm": ("RightForeArm", "RightHand"),
        "left_upper_arm": ("LeftArm", "LeftForeArm"),
        "left_lower_arm": ("LeftForeArm", "LeftHand"),
        "right_thigh": ("RightUpLeg", "RightLeg"),
        "right_shin": ("RightLeg", "RightFoot"),
        "right_foot": ("RightFoot", "RightToeBase"),
        "left_thigh": ("LeftUpLeg", "LeftLeg"),
        "left_shin": ("LeftLeg", "LeftFoot"),
        "left_foot": ("LeftFoot", "LeftToeBase"),
    },
    hips=("LeftUpLeg", "RightUpLeg"),
    trunk_top="Spine1",
    legs=(("LeftUpLeg", "LeftLeg", "LeftFoot"), ("RightUpLeg", "RightLeg", "RightFoot")),
    to_z_up=Y_UP_TO_Z_UP,
    unit=0.0564,
    skip_frames=1,
)

SKELETONS: dict[str, SourceSkeleton] = {"cmu": CMU}


def our_bones() -> dict[str, np.ndarray]:
    """Unit bone direction of each of our jointed bodies in the zero pose (its own frame = world).

    Towards the child body where there is one (torso -> head: up; upper arm -> lower arm,
    thigh -> shin, ...: down), the head up, the feet forward (+x, along the foot box).
    """
    model = humanoid_model()
    out: dict[str, np.ndarray] = {}
    children = {BODY_NAMES[p]: BODY_NAMES[c] for c, p in enumerate(PARENT_INDICES) if p >= 0}
    for body in BODY_NAMES[1:]:
        if body == "head":
            out[body] = np.array([0.0, 0.0, 1.0])
        elif body.endswith("_foot"):
            out[body] = np.array([1.0, 0.0, 0.0])
        elif body.endswith("_hand"):
            continue
        else:
            offset = model.body_pos[model.body(children[body]).id]
            if body == "torso":  # towards the neck, not a shoulder
                offset = model.body_pos[model.body("head").id]
            out[body] = offset / np.linalg.norm(offset)
    return out


def _min_rotation(a: np.ndarray, b: np.ndarray) -> Rotation:
    """The smallest rotation taking unit vector a onto unit vector b."""
    axis = np.cross(a, b)
    s, c = np.linalg.norm(axis), float(np.dot(a, b))
    if s < 1e-12:
        if c > 0:
            return Rotation.identity()
        perp = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
        return Rotation.from_rotvec(np.pi * perp / np.linalg.norm(perp))
    return Rotation.from_rotvec(axis / s * math.atan2(s, c))


def pelvis_frame(left_hip: np.ndarray, right_hip: np.ndarray, trunk_top: np.ndarray, source: str = "") -> Rotation:
    """Pelvis orientation (T,) from points (T, 3) in our axes: y along the hip line (right to
    left), z towards the trunk top (made orthogonal to y), x = y cross z (forward).

    ``MotionFileError`` (naming ``source``) where the hips coincide or the trunk top lies on
    the hip line: no frame is defined there (a file with zero offsets, say).
    """
    def unit(vectors: np.ndarray, fault: str) -> np.ndarray:
        norms = np.linalg.norm(vectors, axis=1, keepdims=True)
        short = np.flatnonzero(norms[:, 0] < 1e-9)
        if short.size:
            raise MotionFileError(f"{source}: frame {short[0]}: {fault} (no pelvis frame)")
        return vectors / norms

    left = unit(left_hip - right_hip, "the hips coincide")
    up = trunk_top - 0.5 * (left_hip + right_hip)
    up = unit(up - np.sum(up * left, axis=1, keepdims=True) * left, "the trunk top lies on the hip line")
    forward = np.cross(left, up)
    return Rotation.from_matrix(np.stack((forward, left, up), axis=2))


def rest_alignment(motion: BvhMotion, skeleton: SourceSkeleton) -> dict[str, Rotation]:
    """A_b for each mapped body: our body's world orientation (z up) in the source's rest pose."""
    rest = motion.rest_positions()
    c = skeleton.to_z_up

    def vec(start: str, end: str) -> np.ndarray:
        for name in (start, end):
            if name not in rest:
                raise MotionFileError(
                    f"{motion.path}: skeleton {skeleton.name!r} needs joint {name!r}, not in the file")
        v = c.apply(rest[end] - rest[start])
        norm = np.linalg.norm(v)
        if norm < 1e-9:
            raise MotionFileError(f"{motion.path}: bone {start}->{end} has zero length in the rest pose")
        return v / norm

    for name in (*skeleton.hips, skeleton.trunk_top):
        if name not in rest:
            raise MotionFileError(
                f"{motion.path}: skeleton {skeleton.name!r} needs joint {name!r}, not in the file")
    rest_points = (c.apply(rest[n])[None] for n in (*skeleton.hips, skeleton.trunk_top))
    pelvis = pelvis_frame(*rest_points, source=f"{motion.path} (rest pose)")[0]
    align = {"pelvis": pelvis}
    ours = our_bones()
    for body, (start, end) in skeleton.bones.items():
        align[body] = _min_rotation(pelvis.apply(ours[body]), vec(start, end)) * pelvis
    return align


def leg_length(motion: BvhMotion, skeleton: SourceSkeleton) -> float:
    """Mean hip-knee + knee-ankle length of the source's legs, in file units."""
    rest = motion.rest_positions()
    lengths = [np.linalg.norm(rest[k] - rest[h]) + np.linalg.norm(rest[a] - rest[k]) for h, k, a in skeleton.legs]
    return float(np.mean(lengths))


def our_leg_length() -> float:
    """Hip-knee + knee-ankle of our humanoid (0.422 + 0.409 m)."""
    model = humanoid_model()
    return float(np.linalg.norm(model.body_pos[model.body("left_shin").id])
                 + np.linalg.norm(model.body_pos[model.body("left_foot").id]))


# --------------------------------------------------------------------------------------
# Retargeting
# --------------------------------------------------------------------------------------
def _flatten_foot(foot: Rotation, ankle: np.ndarray, fps: float,
                  stance_speed: float = 0.1) -> tuple[Rotation, float]:
    """Correct a foot's orientation by a constant swing so its sole is level in stance.

    ``foot`` (T,) world orientations of our foot, ``ankle`` (T, 3) its ankle path in metres.
    Stance frames are those where the ankle moves slower than ``stance_speed`` m/s (or the
    slowest 10 % if too few are). The mean direction of world up seen from the foot in
    those frames, u, gives the correction D = smallest rotation taking the foot's z onto u;
    the result is ``foot * D`` (a constant change of the foot's rest alignment, applied in
    its own frame) and D's angle in degrees.
    """
    if len(ankle) < 2:
        stance = np.ones(len(ankle), dtype=bool)  # a single pose: take it as standing
    else:
        speed = np.linalg.norm(np.gradient(ankle, axis=0), axis=1) * fps
        stance = speed < stance_speed
        if stance.sum() < max(3, 0.05 * len(speed)):
            stance = speed <= np.quantile(speed, 0.1)
    up = foot[stance].inv().apply(np.array([0.0, 0.0, 1.0]))
    mean_up = up.mean(axis=0)
    mean_up /= np.linalg.norm(mean_up)
    delta = _min_rotation(np.array([0.0, 0.0, 1.0]), mean_up)
    return compose(foot, delta), float(np.degrees(delta.magnitude()))


@dataclass
class Retargeted:
    """A source motion on our skeleton, at the file's frames (after the skipped ones).

    ``root_pos`` (F, 3) m and ``root_rot`` (F,): the pelvis in our z-up world; ``local``:
    each joint's rotation relative to its parent body (``JOINTS`` names); ``qpos`` and
    ``clamping``: their projection onto our joint angles (``importers.joints_to_qpos``);
    ``report``: scales, calibrations and the limb-direction FK check, for ``meta``.
    """

    root_pos: np.ndarray
    root_rot: Rotation
    local: dict[str, Rotation]
    qpos: np.ndarray
    clamping: dict[str, Any]
    report: dict[str, Any]


# (proximal body, hinged distal body): our elbows and knees, hinges about the distal body's y.
HINGED_LIMBS: tuple[tuple[str, str], ...] = (
    ("right_upper_arm", "right_lower_arm"), ("left_upper_arm", "left_lower_arm"),
    ("right_thigh", "right_shin"), ("left_thigh", "left_shin"),
)


def _hinge_twist(upper: Rotation, lower: Rotation, min_range_deg: float = 10.0) -> float | None:
    """Twist (rad) about the limb's bone axis (z) that puts the source's hinge axis on our y.

    The source's knee or elbow rotation, seen in our proximal body's frame, is
    upper^-1 lower; its best single axis is the principal direction of the rotation
    vectors over the clip (for a true hinge all of them lie on one line). The returned
    psi turns that axis about z onto the nearer of +y and -y; applying Rz(psi) to both
    segments' alignments leaves every bone direction unchanged and makes the source's
    flexion a rotation about our hinge axis. None if the joint bends less than
    ``min_range_deg`` over the clip (no axis to measure).
    """
    rotvec = compose(upper.inv(), lower).as_rotvec()
    angles = np.linalg.norm(rotvec, axis=1)
    if np.degrees(angles.max()) < min_range_deg:
        return None
    axis = np.linalg.svd(rotvec, full_matrices=False)[2][0]
    in_plane = math.atan2(axis[1], axis[0])
    psi = in_plane - math.pi / 2.0  # onto +y ...
    psi = (psi + math.pi / 2.0) % math.pi - math.pi / 2.0  # ... or -y, whichever is nearer
    return psi


def retarget(motion: BvhMotion, skeleton: SourceSkeleton | str = "cmu",
             skip_frames: int | None = None, flat_feet: bool = True,
             align_hinges: bool = True) -> Retargeted:
    """Our pose at the file's frames (a ``Retargeted``); heights are not yet put on the floor.

    ``align_hinges``: turn each elbow's and knee's limb about its bone so that the source's
    hinge axis, measured from the motion (``_hinge_twist``), is our hinge axis. Rest offsets
    fix bone directions but not the twist about them; CMU's elbow axis sits about 21
    degrees from the one a swing-only alignment gives, which would otherwise cost 10-16
    degrees of forearm direction when the hinge keeps only the flexion.

    ``flat_feet``: level the feet in stance (``_flatten_foot``). Source rest poses do not
    say how a foot sits on the floor: a bone from ankle to toe fixes the foot's direction
    but not its roll, and in the CMU conversion a foot standing flat is rolled about 20
    degrees and pitched 7 degrees from its rest frame (the legs' rest pose is splayed).
    """
    if isinstance(skeleton, str):
        if skeleton not in SKELETONS:
            raise ValueError(f"unknown source skeleton {skeleton!r}; known: {sorted(SKELETONS)}")
        skeleton = SKELETONS[skeleton]
    skip = skeleton.skip_frames if skip_frames is None else int(skip_frames)
    if skip < 0:
        raise ValueError(f"skip_frames must be >= 0, got {skip}")
    if motion.frames.shape[0] <= skip:
        raise MotionFileError(f"{motion.path}: {motion.frames.shape[0]} frames, none left after skipping {skip}")
    names = set(motion.names)
    needed = set(skeleton.bodies.values()) | set(skeleton.hips) | {skeleton.trunk_top}
    missing = sorted(needed - names)
    if missing:
        raise MotionFileError(
            f"{motion.path}: not a {skeleton.name!r} skeleton: joints {missing} missing "
            f"(file has {motion.names[:8]}...)"
        )
    align = rest_alignment(motion, skeleton)
    limb_points = {point for body in LIMBS for point in skeleton.bones[body]}
    rotations, positions = forward_kinematics(motion, motion.frames[skip:], only={
        *skeleton.bodies.values(), *skeleton.hips, skeleton.trunk_top, *limb_points})
    c = skeleton.to_z_up
    world = {body: compose(c, rotations[motion.index(joint)], c.inv(), align[body])
             for body, joint in skeleton.bodies.items() if body != "pelvis"}
    left_hip = c.apply(positions[:, motion.index(skeleton.hips[0])])
    right_hip = c.apply(positions[:, motion.index(skeleton.hips[1])])
    trunk_top = c.apply(positions[:, motion.index(skeleton.trunk_top)])
    world["pelvis"] = pelvis_frame(left_hip, right_hip, trunk_top, source=motion.path)
    src_leg = leg_length(motion, skeleton)
    if not src_leg > 1e-9:
        raise MotionFileError(f"{motion.path}: the legs have no length in the rest pose")
    scale = our_leg_length() / src_leg
    hinge_twist: dict[str, float] = {}
    if align_hinges:
        for upper, lower in HINGED_LIMBS:
            psi = _hinge_twist(world[upper], world[lower])
            if psi is not None:
                twist = Rotation.from_rotvec([0.0, 0.0, psi])
                world[upper], world[lower] = compose(world[upper], twist), compose(world[lower], twist)
                hinge_twist[lower] = round(math.degrees(psi), 3)
    calibration: dict[str, float] = {}
    if flat_feet:
        fps = motion.fps
        for body in ("right_foot", "left_foot"):
            ankle = scale * c.apply(positions[:, motion.index(skeleton.bodies[body])])
            world[body], calibration[body] = _flatten_foot(world[body], ankle, fps)
    local: dict[str, Rotation] = {}
    for joint, body, _ in JOINTS:
        parent = BODY_NAMES[PARENT_INDICES[BODY_NAMES.index(body)]]
        local[joint] = compose(world[parent].inv(), world[body])

    root_pos = scale * 0.5 * (left_hip + right_hip)
    qpos, clamping = joints_to_qpos(root_pos, world["pelvis"], local)
    bone_error = limb_direction_error(qpos, {name: c.apply(positions[:, motion.index(name)])
                                             for name in limb_points}, skeleton)
    report = {
        "importer": "bvh",
        "skeleton": skeleton.name,
        "source_fps": round(motion.fps, 6),
        "source_frames": int(motion.frames.shape[0]),
        "skipped_frames": skip,
        "source_leg_length_units": round(src_leg, 4),
        "source_leg_length_m": round(src_leg * skeleton.unit, 4),
        "root_scale_m_per_unit": round(scale, 6),
        "hinge_axis_twist_deg": hinge_twist,
        "foot_calibration_deg": {k: round(v, 3) for k, v in calibration.items()},
        "limb_direction_error_deg": bone_error,
    }
    return Retargeted(root_pos, world["pelvis"], local, qpos, clamping, report)


LIMBS: tuple[str, ...] = (
    "right_upper_arm", "right_lower_arm", "left_upper_arm", "left_lower_arm",
    "right_thigh", "right_shin", "left_thigh", "left_shin",
)


def limb_direction_error(qpos: np.ndarray, source: Mapping[str, np.ndarray],
                         skeleton: SourceSkeleton) -> dict[str, float]:
    """Angles (degrees) between our limb segments after import and the source's.

    An FK check that does not depend on bone lengths: for the upper and lower arms, thighs
    and shins, the direction from the body to its child body in our FK versus the
    direction between the source points of ``skeleton.bones`` (``source``: name -> (T, 3)
    world positions in our axes). Returns mean, max and the worst limb. Our directions come from
    ``body_rotations`` (all frames at once; MuJoCo's to rounding), not a per-frame FK loop.
    """
    model = humanoid_model()
    rotations = body_rotations(qpos, list(LIMBS))
    errors = {}
    for body in LIMBS:
        child = BODY_NAMES[PARENT_INDICES.index(BODY_NAMES.index(body))]
        ours = rotations[body] @ model.body_pos[model.body(child).id]  # the child's position less the body's
        start, end = skeleton.bones[body]
        theirs = source[end] - source[start]
        cos = np.sum(ours * theirs, axis=1) / (np.linalg.norm(ours, axis=1) * np.linalg.norm(theirs, axis=1))
        errors[body] = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    stacked = np.stack(list(errors.values()))
    return {
        "mean": round(float(stacked.mean()), 3),
        "max": round(float(stacked.max()), 3),
        "worst_limb": max(errors, key=lambda k: errors[k].max()),
    }


def import_bvh(
    path: str | Path,
    fps: float | None = 30.0,
    skeleton: str = "cmu",
    skip_frames: int | None = None,
    ground: str = "body",
    name: str | None = None,
    loop: bool = False,
    flat_feet: bool = True,
    align_hinges: bool = True,
    **unused: Any,
) -> MotionClip:
    """Read a BVH file and retarget it onto our humanoid (see the module docstring).

    ``fps``: output rate (default 30; ``None`` keeps the file's); ``skeleton``: source
    skeleton name (``SKELETONS``); ``skip_frames``: leading frames to drop (default: the
    skeleton's, 1 for "cmu"); ``ground``: see ``importers.ground_offset``.
    """
    path = Path(path)
    motion = read_bvh(path)
    pose = retarget(motion, skeleton, skip_frames, flat_feet, align_hinges)
    rate = snap_fps(motion.fps)
    times = np.arange(len(pose.root_pos)) / rate
    return make_clip(times, pose.root_pos, pose.root_rot, pose.local, fps or rate, name=name or path.stem,
                     loop=loop, source=str(path), meta=pose.report, ground=ground,
                     projected=(pose.qpos, pose.clamping))

