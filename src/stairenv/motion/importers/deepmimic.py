"""DeepMimic ``.txt`` motions (JSON) -> ``MotionClip``.

File: ``{"Loop": "wrap" | "none", "Frames": [[44 numbers], ...]}`` (other keys are
ignored). Each frame is

====================  =====  ===========================================
field                 size   our joint
====================  =====  ===========================================
duration (s)          1      (frame timing)
root position         3      pelvis position
root rotation         4      pelvis orientation
chest                 4      abdomen
neck                  4      neck
right hip             4      right_hip
right knee            1      right_knee
right ankle           4      right_ankle
right shoulder        4      right_shoulder
right elbow           1      right_elbow
left hip              4      left_hip
left knee             1      left_knee
left ankle            4      left_ankle
left shoulder         4      left_shoulder
left elbow            1      left_elbow
====================  =====  ===========================================

Quaternions are w, x, y, z; spherical joints are local rotations (child body relative
to parent body), the root's is its world orientation. DeepMimic is y up, x forward,
z to the character's right; we are z up, x forward, y left. The change of frame is the
rotation C = +90 degrees about x, p' = C p = (x, -z, y), and a rotation R becomes
C R C^-1 (for the root and every joint alike, since both skeletons share the zero pose:
upright, arms down). DeepMimic's knees and elbows are revolute joints about its z axis;
C maps z to -y, so an angle theta becomes -theta about our y axis. Bone offsets are
the AMP humanoid's, i.e. ours to a few millimetres.

The frame rate is 1 / (median frame duration), rounded to an integer when within
0.05 % (durations are written as 0.033332 s); every frame must last 1 / ``MAX_FPS`` to
1 / ``MIN_FPS`` s and the clip keep within the importers' other limits. ``Loop: "wrap"`` sets ``loop``.
DeepMimic's last frame of a looping clip repeats the first pose (with the root moved
on); it is kept. A file whose frame durations vary (humanoid3d_roll.txt has one double
frame) is resampled onto a uniform grid, slerping rotations (``importers.make_clip``).
The root height is shifted so that the lowest point of the body over the clip touches
the floor (``ground="body"``: the lowest sole for locomotion, hands or
back for crawling, rolling and getting up; ``"feet"`` looks at the soles only).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from stairenv.humanoid import BODY_NAMES, JOINTS, PARENT_INDICES, humanoid_model
from stairenv.motion.clip import MotionClip, MotionFileError
from stairenv.motion.importers.common import (MAX_FPS, MIN_FPS, check_timing, check_values, compose, fk_position_error,
                                       joints_to_qpos, make_clip, read_limited, snap_fps)

FRAME_SIZE = 44

# (field name, size, our joint or None) in file order.
LAYOUT: tuple[tuple[str, int, str | None], ...] = (
    ("duration", 1, None),
    ("root_position", 3, None),
    ("root_rotation", 4, None),
    ("chest", 4, "abdomen"),
    ("neck", 4, "neck"),
    ("right_hip", 4, "right_hip"),
    ("right_knee", 1, "right_knee"),
    ("right_ankle", 4, "right_ankle"),
    ("right_shoulder", 4, "right_shoulder"),
    ("right_elbow", 1, "right_elbow"),
    ("left_hip", 4, "left_hip"),
    ("left_knee", 1, "left_knee"),
    ("left_ankle", 4, "left_ankle"),
    ("left_shoulder", 4, "left_shoulder"),
    ("left_elbow", 1, "left_elbow"),
)
assert sum(size for _, size, _ in LAYOUT) == FRAME_SIZE

# y-up (DeepMimic) -> z-up (ours): +90 degrees about x.
Y_UP_TO_Z_UP = Rotation.from_euler("x", 90.0, degrees=True)


def read_deepmimic(path: str | Path) -> tuple[np.ndarray, str]:
    """Frames (T, 44) and the ``Loop`` mode of a DeepMimic file; ``MotionFileError`` on faults."""
    path = Path(path)
    try:
        text = read_limited(path).decode("utf-8")
    except UnicodeDecodeError as err:
        raise MotionFileError(f"{path}: cannot read ({type(err).__name__}: {err})") from err
    try:
        # Integers are read as floats: an int of thousands of digits is no frame value.
        data = json.loads(text, parse_int=float)
    except json.JSONDecodeError as err:
        raise MotionFileError(f"{path}: not valid JSON ({err}); truncated or not a DeepMimic motion?") from err
    except RecursionError as err:
        raise MotionFileError(f"{path}: JSON nested too deeply for a DeepMimic motion") from err
    if not isinstance(data, dict) or "Frames" not in data:
        raise MotionFileError(f"{path}: expected a JSON object with 'Frames' (a DeepMimic motion)")
    frames = data["Frames"]
    if not isinstance(frames, list) or not frames:
        raise MotionFileError(f"{path}: 'Frames' must be a non-empty list")
    for i, frame in enumerate(frames):
        if not isinstance(frame, list) or len(frame) != FRAME_SIZE:
            got = len(frame) if isinstance(frame, list) else type(frame).__name__
            raise MotionFileError(f"{path}: frame {i} has {got} values, expected {FRAME_SIZE}")
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in frame):
            raise MotionFileError(f"{path}: frame {i} holds non-numeric values")
    array = np.asarray(frames, dtype=np.float64)
    check_values(path, "Frames", array)
    loop = data.get("Loop", "none")
    if loop not in ("wrap", "none"):
        raise MotionFileError(f"{path}: 'Loop' must be 'wrap' or 'none', got {loop!r}")
    return array, loop


def split_fields(frames: np.ndarray) -> dict[str, np.ndarray]:
    """Column blocks of the (T, 44) frames by field name (see ``LAYOUT``)."""
    out, col = {}, 0
    for name, size, _ in LAYOUT:
        out[name] = frames[:, col:col + size]
        col += size
    return out


def _quat_wxyz(path: Path, fields: dict[str, np.ndarray], name: str, meta: dict[str, Any]) -> Rotation:
    """A (T,) Rotation from the w, x, y, z block ``name``, normalised.

    DeepMimic normalises on load and some files hold quaternions far from unit length
    (humanoid3d_roll.txt: 0.81); lengths in [0.5, 1.5] are accepted and the worst
    deviation is recorded in ``meta["max_quaternion_norm_error"]``; others are corrupt.
    """
    q = fields[name]
    norms = np.linalg.norm(q, axis=1)
    if np.any((norms < 0.5) | (norms > 1.5)):
        bad = int(np.flatnonzero((norms < 0.5) | (norms > 1.5))[0])
        raise MotionFileError(
            f"{path}: {name} quaternion of length {norms[bad]:.4f} in frame {bad} (expected unit w, x, y, z)"
        )
    worst = float(np.abs(norms - 1.0).max())
    meta["max_quaternion_norm_error"] = round(max(meta.get("max_quaternion_norm_error", 0.0), worst), 6)
    return Rotation.from_quat(q / norms[:, None], scalar_first=True)


def source_positions(fields: dict[str, np.ndarray], offsets: np.ndarray | None = None) -> np.ndarray:
    """(T, 15, 3) body positions by DeepMimic's own kinematics, mapped to z up.

    Forward kinematics in DeepMimic's y-up frame with its quaternions (knees and elbows
    about z), using ``offsets`` (15, 3) given in our z-up body frames (default: our MJCF's;
    DeepMimic's humanoid3d has the same to a few millimetres), then p -> (x, -z, y).
    """
    if offsets is None:
        model = humanoid_model()
        offsets = np.array([model.body_pos[model.body(b).id] for b in BODY_NAMES])
    c = Y_UP_TO_Z_UP
    offsets_y_up = c.inv().apply(offsets)
    by_body = {joint_body: field for field, _, joint in LAYOUT if joint
               for j, joint_body, _ in JOINTS if j == joint}
    n = len(fields["duration"])
    world: list[Rotation] = []
    pos = np.zeros((n, len(BODY_NAMES), 3))
    for b, body in enumerate(BODY_NAMES):
        parent = PARENT_INDICES[b]
        if parent < 0:
            q = fields["root_rotation"]
            world.append(Rotation.from_quat(q / np.linalg.norm(q, axis=1, keepdims=True), scalar_first=True))
            pos[:, b] = fields["root_position"]
            continue
        value = fields.get(by_body.get(body, ""), None)
        if value is None:
            local = Rotation.identity(n)
        elif value.shape[1] == 4:
            local = Rotation.from_quat(value / np.linalg.norm(value, axis=1, keepdims=True), scalar_first=True)
        else:
            local = Rotation.from_rotvec(value * np.array([0.0, 0.0, 1.0]))
        world.append(compose(world[parent], local))
        pos[:, b] = pos[:, parent] + world[parent].apply(offsets_y_up[b])
    return c.apply(pos.reshape(-1, 3)).reshape(pos.shape)


def import_deepmimic(
    path: str | Path,
    fps: float | None = None,
    ground: str = "body",
    name: str | None = None,
    **unused: Any,
) -> MotionClip:
    """Convert a DeepMimic motion into a ``MotionClip`` (conventions in the module docstring).

    ``fps``: resample to this rate (slerp); by default keep the file's rate. ``ground``:
    "feet", "body" or "none" (``importers.ground_offset``). Unknown keywords are ignored.
    """
    path = Path(path)
    frames, loop = read_deepmimic(path)
    fields = split_fields(frames)
    durations = fields["duration"][:, 0]
    # The last frame's duration is unused by DeepMimic (often 0): time comes from the others.
    steps = durations[:-1] if len(durations) > 1 else durations
    out_of_range = ~((steps >= 1.0 / MAX_FPS) & (steps <= 1.0 / MIN_FPS))
    if out_of_range.any():
        bad = int(np.flatnonzero(out_of_range)[0])
        raise MotionFileError(
            f"{path}: frame {bad} has duration {steps[bad]:g} s (a frame rate outside [{MIN_FPS:g}, {MAX_FPS:g}] fps)")
    source_fps = snap_fps(1.0 / float(np.median(steps)))
    uniform = bool(np.all(np.abs(steps - np.median(steps)) <= 0.01 * np.median(steps)))
    if uniform:
        times = np.arange(len(frames)) / source_fps
    else:  # frames at their own times, resampled onto a uniform grid by make_clip
        times = np.concatenate(([0.0], np.cumsum(steps)))[: len(frames)]
    check_timing(path, len(frames), source_fps, float(times[-1]))

    c = Y_UP_TO_Z_UP
    quality: dict[str, Any] = {}
    root_pos = c.apply(fields["root_position"])
    root_rot = compose(c, _quat_wxyz(path, fields, "root_rotation", quality), c.inv())
    local: dict[str, Rotation] = {}
    for field, size, joint in LAYOUT:
        if joint is None:
            continue
        if size == 4:
            local[joint] = compose(c, _quat_wxyz(path, fields, field, quality), c.inv())
        else:  # revolute about DeepMimic's z = our -y
            local[joint] = Rotation.from_euler("y", -fields[field])

    # FK check on the file's own frames: DeepMimic's kinematics vs. ours, same root path.
    qpos_src, clamping = joints_to_qpos(root_pos, root_rot, local)
    fk_error = {**fk_position_error(qpos_src, source_positions(fields)),
                "reference": "DeepMimic FK (y up) with our bone offsets"}
    meta = {"importer": "deepmimic", "source_fps": round(source_fps, 6), "source_frames": int(len(frames)),
            **quality, "fk_error": fk_error}
    if not uniform:
        meta["irregular_durations"] = True
    return make_clip(times, root_pos, root_rot, local, fps or source_fps, name=name or path.stem,
                     loop=loop == "wrap", source=str(path), meta=meta, ground=ground,
                     projected=(qpos_src, clamping))
