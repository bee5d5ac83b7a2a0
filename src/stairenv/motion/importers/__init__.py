"""Importers: motion-capture files of other formats -> our ``MotionClip``.

``import_motion(path, **kwargs)`` picks the importer from the file suffix:

========  =====================================================  ==========================
suffix    format                                                 module
========  =====================================================  ==========================
``.npy``  IsaacGymEnvs / ASE poselib ``SkeletonMotion`` (and     :mod:`.isaac_npy`
          single-frame ``SkeletonState``), read without poselib
``.txt``  DeepMimic motion (JSON, 44 numbers per frame)          :mod:`.deepmimic`
``.bvh``  Biovision hierarchy, retargeted from a named skeleton  :mod:`.bvh`
          (``skeleton="cmu"``)
========  =====================================================  ==========================

Every importer ends in the same place, the shared helpers of :mod:`.common` (re-exported here):

* :func:`joints_to_qpos` turns per-joint *local* rotations (each joint's body
  relative to its parent body, in our z-up, x-forward, y-left body frames, the
  zero pose being our MJCF zero pose) into the 28 hinge angles. Three-axis joints
  are intrinsic ``XYZ`` Euler angles (``Rotation.from_euler("XYZ", [ax, ay, az])``
  is MuJoCo's x-then-y-then-z hinge chain); of the two Euler solutions
  ``(x, y, z)`` and ``(x + pi, pi - y, z + pi)`` the one that fits the joint
  ranges is taken (hip and shoulder flexion go past 90 degrees), each angle
  wrapped by 2 pi towards its range; a rotation out of the joint's reach becomes
  a nearby reachable one, chosen along the clip so that the angles do not hop
  between the two solutions (``ball_joint_angles``). Hinges (elbows, knees)
  take the twist of the rotation about their y axis (swing-twist decomposition;
  exact for a pure hinge rotation), clamped. How much the source exceeds the
  ranges goes into the clip's ``meta`` (``clamped_fraction``, ``max_clamp_deg``,
  ``clamp_deg_by_dof``).
* :func:`make_clip` resamples to the requested frame rate *before* that
  projection, by slerp of the rotations, so Euler angles are never interpolated.
* :func:`ground_offset` measures, by forward kinematics of our humanoid, how far
  the clip must be raised (or lowered) so that its lowest point over the whole
  clip touches ``z = 0``: for motion on the feet the lowest foot sole (soles are
  the bottom faces of the foot boxes, 0.05 m below the ankles), for crawling or
  rolling whatever body part is lowest (``ground="body"``, the default; ``"feet"``
  considers the soles only). Source root heights are not trusted: the
  IsaacGymEnvs clips need +0.02 to +0.09 m, depending on the clip.

Corrupt or unreadable files raise :class:`~stairenv.motion.clip.MotionFileError`
naming the file and the fault.

Motion files come from strangers, so reading one runs nothing from it (``.npy`` pickles go
through an allow-list unpickler, :mod:`.isaac_npy`) and every file is held to the same
limits, checked before any work that grows with them:

=======================  ===========  =================================================
limit                    value        applies to
=======================  ===========  =================================================
``MAX_FILE_BYTES``       32 MiB       the file (:func:`read_limited`; shipped: <= 1.5 MB)
``MAX_FRAMES``           100 000      frames of the source and of the clip made
``MAX_DURATION_S``       3600 s       duration of the source and of the clip
``MIN_FPS``/``MAX_FPS``  1-1000 fps   frame rate of the source and of the clip
``MAX_JOINTS``           256          joints of a source skeleton (CMU 31, AMP 15)
``MAX_ABS_VALUE``        1e6          every number read: angles, offsets, positions
``MAX_ROOT_DISTANCE_M``  1000 m       root position of the clip, from the origin
=======================  ===========  =================================================

:func:`check_timing` (frame rate, duration, frames) and :func:`check_values` (finite,
within a bound) are the shared checks; :func:`make_clip` applies both to every clip.

Cost: the work is on arrays of all frames at once; the per-frame loops that remain are
compiled (:mod:`.kernels`, numba, cached on disk: the first use on a machine compiles them,
~10 s or more, once): the bounded fit of a three-axis joint beyond its range (a port of
scipy's ``least_squares``, the same results), the Viterbi pass along long clips and the
frame values of long BVH files. ``benchmarks/bench_importers.py`` times long clips against
the code before (#23): a 20,000-frame CMU file ~0.5 s once numba is loaded (~10x), a
4,000-frame DeepMimic file whose every frame fits joints into range ~0.5-0.8 s (20-35x).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from stairenv.motion.clip import MotionClip, MotionFileError
from stairenv.motion.importers.common import (
    MAX_ABS_VALUE,
    MAX_DURATION_S,
    MAX_FILE_BYTES,
    MAX_FPS,
    MAX_FRAMES,
    MAX_JOINTS,
    MAX_ROOT_DISTANCE_M,
    MIN_FPS,
    ball_joint_angles,
    body_positions,
    check_timing,
    check_values,
    compose,
    euler_rotation,
    fk_position_error,
    foot_sole_heights,
    ground_offset,
    joints_to_qpos,
    lowest_body_point,
    make_clip,
    read_limited,
    snap_fps,
)

__all__ = [
    "MAX_ABS_VALUE",
    "MAX_DURATION_S",
    "MAX_FILE_BYTES",
    "MAX_FPS",
    "MAX_FRAMES",
    "MAX_JOINTS",
    "MAX_ROOT_DISTANCE_M",
    "MIN_FPS",
    "SUFFIXES",
    "MotionFileError",
    "ball_joint_angles",
    "body_positions",
    "check_timing",
    "check_values",
    "compose",
    "euler_rotation",
    "fk_position_error",
    "foot_sole_heights",
    "ground_offset",
    "import_motion",
    "joints_to_qpos",
    "lowest_body_point",
    "make_clip",
    "read_limited",
    "snap_fps",
]

# suffix -> (module, function name); modules are imported on first use.
SUFFIXES: dict[str, tuple[str, str]] = {
    ".npy": ("stairenv.motion.importers.isaac_npy", "import_isaac_npy"),
    ".txt": ("stairenv.motion.importers.deepmimic", "import_deepmimic"),
    ".bvh": ("stairenv.motion.importers.bvh", "import_bvh"),
}


def import_motion(path: str | Path, **kwargs: Any) -> MotionClip:
    """Read the motion file ``path`` into a ``MotionClip``; the importer is chosen by suffix.

    ``kwargs`` go to the importer (see each module; e.g. ``fps``/``skeleton``/``skip_frames``
    for BVH). Raises ``MotionFileError`` for unknown suffixes and unreadable files.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise MotionFileError(
            f"{path}: unknown motion file type {path.suffix or '(no suffix)'!r}; "
            f"supported: {', '.join(sorted(SUFFIXES))}"
        )
    if not path.is_file():
        raise MotionFileError(f"{path}: no such file")
    module_name, function = SUFFIXES[suffix]
    import importlib

    importer = getattr(importlib.import_module(module_name), function)
    return importer(path, **kwargs)
