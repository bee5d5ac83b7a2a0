"""IsaacGymEnvs / ASE ``.npy`` motions (poselib ``SkeletonMotion``), read without poselib.

The file is a pickled dict (what ``np.load(path, allow_pickle=True).item()`` returns). A
pickle can name any function to call, so it is never given to ``np.load``: a restricted
unpickler builds only the dict, list, string and number objects of the pickle itself,
``OrderedDict``, and stand-ins for numpy's arrays, dtypes and scalars (``_SAFE_GLOBALS``);
any other name (``os.system``, ``builtins.eval``, ...) is refused before anything runs. The
arrays are then made from their pickled bytes after checking that shape, type and data
agree (plain bool, integer and float types only), so no claimed size is ever allocated.

* ``rotation["arr"]``: (T, J, 4) quaternions x, y, z, w. With ``is_local`` true (the
  usual case) each is the joint's body relative to its parent body; the root's is its
  world orientation. With ``is_local`` false they are world orientations.
* ``root_translation["arr"]``: (T, 3) root (pelvis) position, metres, z up.
* ``skeleton_tree``: ``node_names`` (J,), ``parent_indices["arr"]`` (J,),
  ``local_translation["arr"]`` (J, 3), the bone offsets in the parent's frame.
* ``fps``: a number or a 0-d array. A ``SkeletonState`` (one pose, no ``fps``) is read as a
  one-frame clip at the ``fps`` passed in (30 by default); several frames without ``fps`` are refused.

The AMP humanoid of these files has our 15 bodies under the same names, the same
zero pose (upright, facing +x, arms down) and the same axes, so the conversion is
exact up to clamping: three-axis joints are the intrinsic XYZ Euler angles of the
local quaternion, knees and elbows the twist about y (for their pure y rotations,
the y component of the rotation vector). The skeleton's bone offsets differ from
ours by a few millimetres (e.g. upper arm 0.2748 vs 0.274 m), which bounds the
forward-kinematics difference (see ``meta["max_offset_difference_m"]``).

The root height is shifted so that the lowest point of the body over the clip (the
lowest foot sole, for motion on the feet) touches the floor (``ground="body"``; the
file's own heights leave the soles 0.02-0.09 m below it in the six motions, 0.02 m above
it in the T-pose); the shift is ``meta["root_height_offset"]``.
"""

from __future__ import annotations

import io
import math
import pickle
from collections import OrderedDict
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from stairenv.humanoid import BODY_NAMES, JOINTS, PARENT_INDICES, humanoid_model
from stairenv.motion.clip import MotionClip, MotionFileError
from stairenv.motion.importers.common import (MAX_JOINTS, check_timing, check_values, compose, fk_position_error,
                                       joints_to_qpos, make_clip, read_limited)
from stairenv.safe_pickle import NUMBER_OR_OBJECT_CODES, PickledArray, numpy_globals, pickled_array

_SAFE_GLOBALS: dict[tuple[str, str], Any] = {("collections", "OrderedDict"): OrderedDict, **numpy_globals()}


class _SafeUnpickler(pickle.Unpickler):
    """Resolves only the names of ``_SAFE_GLOBALS``: nothing else can be called."""

    def find_class(self, module: str, name: str) -> Any:
        if (module, name) not in _SAFE_GLOBALS:
            raise pickle.UnpicklingError(f"refused {module}.{name} (not a numpy array, dtype or dict)")
        return _SAFE_GLOBALS[(module, name)]


def _array(value: PickledArray) -> np.ndarray:
    """The array a pickled ndarray state describes (numbers, or a container's objects)."""
    return pickled_array(value, codes=NUMBER_OR_OBJECT_CODES)


def _unpickle(path: Path) -> object:
    """The object a ``.npy`` file's pickle describes, built by ``_SafeUnpickler``."""
    stream = io.BytesIO(read_limited(path))
    header_readers = {(1, 0): np.lib.format.read_array_header_1_0, (2, 0): np.lib.format.read_array_header_2_0}
    try:
        version = np.lib.format.read_magic(stream)
        if version not in header_readers:
            raise MotionFileError(f"{path}: unsupported .npy format version {version}")
        shape, _, dtype = header_readers[version](stream)
        if not dtype.hasobject:
            raise MotionFileError(
                f"{path}: expected a pickled dict (poselib SkeletonMotion), got a {dtype} array of shape {shape}")
        if shape != ():
            raise MotionFileError(f"{path}: expected one pickled dict, got an object array of shape {shape}")
        top = _SafeUnpickler(stream).load()
        return _array(top).item() if isinstance(top, PickledArray) else top
    except MotionFileError:
        raise
    except Exception as err:  # refused names, truncation, malformed opcodes or arrays: many types
        raise MotionFileError(f"{path}: cannot read as a numpy pickle ({type(err).__name__}: {err})") from err


def _real_number(value: object) -> float | None:
    """A real number given as int, float, numpy scalar or one-element array, else None (bools too)."""
    if isinstance(value, np.ndarray) and value.size == 1:
        value = value.reshape(()).item()
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        return None
    try:
        return float(value)
    except OverflowError:  # an int of hundreds of digits
        return math.inf


def _flag(value: object) -> bool | None:
    """A bool given as bool, numpy bool or one-element bool array, else None."""
    if isinstance(value, np.ndarray) and value.size == 1 and value.dtype == np.bool_:
        value = value.reshape(()).item()
    return bool(value) if isinstance(value, (bool, np.bool_)) else None


def read_isaac_npy(path: str | Path) -> dict[str, Any]:
    """Load and validate a poselib file: a dict with plain numpy arrays.

    Returns ``rotation`` (T, J, 4) xyzw, ``root_translation`` (T, 3), ``node_names`` (J,),
    ``parent_indices`` (J,), ``local_translation`` (J, 3), ``is_local`` (bool) and ``fps``
    (float, or None for a ``SkeletonState``). Nothing in the file is run (see the module
    docstring); any fault, or a value beyond the importers' limits, raises ``MotionFileError``.
    """
    path = Path(path)
    data = _unpickle(path)
    if not isinstance(data, dict):
        raise MotionFileError(f"{path}: expected a pickled dict (poselib SkeletonMotion), got {type(data).__name__}")

    def plain(value: object, what: str) -> object:
        """``value`` with a pickled array made into an ndarray."""
        try:
            return _array(value) if isinstance(value, PickledArray) else value
        except ValueError as err:
            raise MotionFileError(f"{path}: {what}: {err}") from err

    def numbers(container: object, key: str, what: str) -> np.ndarray:
        """The numeric array ``container[key]["arr"]`` (poselib's tensor), as float64."""
        value = container.get(key) if isinstance(container, dict) else None
        if not isinstance(value, dict) or "arr" not in value:
            raise MotionFileError(f"{path}: missing {what} (a dict with an 'arr' array)")
        array = plain(value["arr"], what)
        if not isinstance(array, np.ndarray) or array.dtype.hasobject:
            raise MotionFileError(f"{path}: {what} is not a numeric array ({type(array).__name__})")
        array = array.astype(np.float64)
        check_values(path, what, array)
        return array

    rotation = numbers(data, "rotation", "rotation")
    root_translation = numbers(data, "root_translation", "root_translation")
    tree = data.get("skeleton_tree")
    if not isinstance(tree, dict):
        raise MotionFileError(f"{path}: missing 'skeleton_tree'")
    names = tree.get("node_names")
    if not isinstance(names, (list, tuple)) or not all(isinstance(n, str) for n in names):
        raise MotionFileError(f"{path}: skeleton_tree has no list of node_names")
    num_joints = len(names)
    if not 1 <= num_joints <= MAX_JOINTS:
        raise MotionFileError(f"{path}: {num_joints} joints; 1 to {MAX_JOINTS} are allowed")
    parents = numbers(tree, "parent_indices", "skeleton_tree parent_indices")
    offsets = numbers(tree, "local_translation", "skeleton_tree local_translation")
    if parents.shape != (num_joints,) or offsets.shape != (num_joints, 3):
        raise MotionFileError(
            f"{path}: skeleton_tree has {num_joints} names but parent_indices {parents.shape} "
            f"and local_translation {offsets.shape}"
        )
    if not np.array_equal(parents, np.round(parents)):
        raise MotionFileError(f"{path}: skeleton_tree parent_indices are not integers")
    parents = parents.astype(np.int64)

    single = "fps" not in data
    if single and rotation.ndim == 2:
        rotation, root_translation = rotation[None], root_translation.reshape(1, -1)
    if single and rotation.ndim == 3 and rotation.shape[0] > 1:  # its rate is unknown: never guess 30 fps
        raise MotionFileError(f"{path}: {rotation.shape[0]} frames but no fps (a SkeletonMotion stores its fps; "
                              "only a one-pose SkeletonState may leave it out)")
    if rotation.ndim != 3 or rotation.shape[1:] != (num_joints, 4):
        raise MotionFileError(f"{path}: rotation must be (T, {num_joints}, 4), got {rotation.shape}")
    if root_translation.shape != (rotation.shape[0], 3):
        raise MotionFileError(
            f"{path}: root_translation must be ({rotation.shape[0]}, 3) like rotation, got {root_translation.shape}"
        )
    if rotation.shape[0] < 1:
        raise MotionFileError(f"{path}: no frames")
    norms = np.linalg.norm(rotation, axis=-1)
    if np.any(np.abs(norms - 1.0) > 1e-2):
        worst = np.unravel_index(np.argmax(np.abs(norms - 1.0)), norms.shape)
        raise MotionFileError(
            f"{path}: quaternion of length {norms[worst]:.4f} at frame {worst[0]}, joint {names[worst[1]]!r} "
            "(expected unit quaternions x, y, z, w)"
        )
    fps = None
    if not single:
        fps = _real_number(plain(data["fps"], "fps"))
        if fps is None:
            raise MotionFileError(f"{path}: fps is not a number ({type(data['fps']).__name__})")
        check_timing(path, rotation.shape[0], fps, (rotation.shape[0] - 1) / fps if fps > 0 else math.nan)
    is_local = _flag(plain(data.get("is_local", True), "is_local"))
    if is_local is None:
        raise MotionFileError(f"{path}: is_local must be true or false, got {type(data['is_local']).__name__}")
    return {
        "rotation": rotation,
        "root_translation": root_translation,
        "node_names": list(names),
        "parent_indices": parents,
        "local_translation": offsets,
        "is_local": is_local,
        "fps": fps,
    }


def source_positions(src: dict[str, Any]) -> np.ndarray:
    """(T, J, 3) world joint positions of the source skeleton (its own offsets), as poselib computes them."""
    quat, parents, offsets = src["rotation"], src["parent_indices"], src["local_translation"]
    n, num_joints = quat.shape[:2]
    world: list[Rotation] = []
    pos = np.zeros((n, num_joints, 3))
    for j in range(num_joints):  # poselib orders parents before children
        rot = Rotation.from_quat(quat[:, j])
        p = parents[j]
        if p < 0:
            world.append(rot)
            pos[:, j] = src["root_translation"]
        else:
            world.append(compose(world[p], rot) if src["is_local"] else rot)
            pos[:, j] = pos[:, p] + world[p].apply(offsets[j])
    return pos


def import_isaac_npy(
    path: str | Path,
    fps: float | None = None,
    ground: str = "body",
    name: str | None = None,
    **unused: Any,
) -> MotionClip:
    """Convert an IsaacGymEnvs/ASE ``.npy`` motion into a ``MotionClip``.

    ``fps``: resample to this rate (slerp); by default keep the file's rate (a single-pose
    ``SkeletonState`` gets ``fps`` or 30). ``ground``: see ``importers.ground_offset``.
    Other keywords (e.g. ``skeleton``, ``skip_frames`` of the BVH importer) are ignored.
    """
    path = Path(path)
    src = read_isaac_npy(path)
    names, parents = src["node_names"], src["parent_indices"]
    index = {n: i for i, n in enumerate(names)}
    missing = [b for b in BODY_NAMES if b not in index]
    if missing:
        raise MotionFileError(f"{path}: skeleton lacks bodies {missing} (has {names})")
    for body, parent in zip(BODY_NAMES, PARENT_INDICES):
        p = parents[index[body]]
        want = None if parent < 0 else BODY_NAMES[parent]
        got = None if p < 0 else (names[p] if p < len(names) else f"index {p}")
        if want != got:
            raise MotionFileError(f"{path}: body {body!r} has parent {got!r}, expected {want!r}")

    if any(parents[j] >= j for j in range(len(names)) if parents[j] >= 0):
        raise MotionFileError(f"{path}: skeleton_tree lists a child before its parent")

    quat = src["rotation"]
    rots = [Rotation.from_quat(quat[:, j]) for j in range(len(names))]
    if not src["is_local"]:  # world orientations -> relative to the parent
        rots = [rots[j] if parents[j] < 0 else compose(rots[parents[j]].inv(), rots[j]) for j in range(len(names))]
    local = {joint: rots[index[body]] for joint, body, _ in JOINTS}
    root_pos, root_rot = src["root_translation"], rots[index["pelvis"]]

    # FK check on the file's own frames (before any resampling): our bodies vs. the source's.
    qpos_src, clamping = joints_to_qpos(root_pos, root_rot, local)
    reference = source_positions(src)[:, [index[b] for b in BODY_NAMES]]
    fk_error = {**fk_position_error(qpos_src, reference), "reference": "source skeleton offsets"}

    model = humanoid_model()
    ours = np.array([model.body_pos[model.body(b).id] for b in BODY_NAMES[1:]])
    theirs = src["local_translation"][[index[b] for b in BODY_NAMES[1:]]]
    source_fps = src["fps"]
    meta = {
        "importer": "isaac_npy",
        "source_fps": source_fps,
        "source_frames": int(quat.shape[0]),
        "max_offset_difference_m": round(float(np.abs(ours - theirs).max()), 6),
        "fk_error": fk_error,
    }
    rate = source_fps or fps or 30.0
    out_fps = fps or rate
    times = np.arange(len(root_pos)) / rate
    return make_clip(times, root_pos, root_rot, local, out_fps, name=name or path.stem, loop=False,
                     source=str(path), meta=meta, ground=ground,
                     projected=(qpos_src, clamping))
