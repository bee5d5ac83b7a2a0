"""Forward kinematics of the humanoid over frames, and its lowest point.

``forward_kinematics`` is the one frame-by-frame FK loop: the importers, the
interaction synthesis and the AMP features read bodies and geoms off the
``MjData`` it yields. ``humanoid_lowest_z`` is the one "lowest body point": the
exact lowest world z of sphere, capsule and box geoms in any ``MjData`` after
kinematics (an env's, with its scene, or the bare model's);
``lowest_body_point`` and ``foot_sole_heights`` apply it to every frame of a clip.
"""

from __future__ import annotations

from collections.abc import Iterator
from functools import lru_cache

import mujoco
import numpy as np

from stairenv.humanoid.model import BODY_NAMES, FOOT_BODIES, HumanoidIndices, humanoid_model


def forward_kinematics(qpos: np.ndarray, qvel: np.ndarray | None = None) -> Iterator[mujoco.MjData]:
    """Yield the bare humanoid's ``MjData`` after ``mj_kinematics`` of each frame of ``qpos`` (T, 35),
    with the frame of ``qvel`` (T, 34) written too when given. One ``MjData`` serves every frame of
    a call: read what is needed from it before taking the next."""
    model = humanoid_model()
    data = mujoco.MjData(model)
    for t in range(qpos.shape[0]):
        data.qpos[:] = qpos[t]
        if qvel is not None:
            data.qvel[:] = qvel[t]
        mujoco.mj_kinematics(model, data)
        yield data


def humanoid_geoms(model: mujoco.MjModel, idx: HumanoidIndices) -> np.ndarray:
    """Ids of the geoms on the humanoid's bodies in ``model`` (which may hold a scene too)."""
    return np.flatnonzero(np.isin(model.geom_bodyid, idx.body_ids))


# plain ints: comparing an array with mujoco's enum objects costs tens of microseconds
_SPHERE, _CAPSULE, _BOX = (int(t) for t in (mujoco.mjtGeom.mjGEOM_SPHERE, mujoco.mjtGeom.mjGEOM_CAPSULE,
                                          mujoco.mjtGeom.mjGEOM_BOX))


def humanoid_lowest_z(model: mujoco.MjModel, data: mujoco.MjData, geom_ids: np.ndarray) -> float:
    """Exact lowest world z of the given sphere, capsule and box geoms (after kinematics)."""
    geom_ids = np.asarray(geom_ids, dtype=np.int64)
    kind = model.geom_type[geom_ids]
    z, size = data.geom_xpos[geom_ids, 2], model.geom_size[geom_ids]
    r22 = np.abs(data.geom_xmat[geom_ids, 8])
    # Spheres and capsules element-wise (the same operations as one geom at a time, so the same bits);
    # boxes and other shapes are few.
    bottom = np.where(kind == _SPHERE, z - size[:, 0], z - r22 * size[:, 1] - size[:, 0])
    for k in np.flatnonzero((kind != _SPHERE) & (kind != _CAPSULE)):
        g = geom_ids[k]
        if kind[k] == _BOX:
            bottom[k] = z[k] - np.abs(data.geom_xmat[g].reshape(3, 3)[2]) @ model.geom_size[g]
        else:
            bottom[k] = z[k] - model.geom_rbound[g]
    return float(np.fmin.reduce(bottom, initial=np.inf))    # NaN ignored, as min() one at a time did


def _kinematics_arrays(qpos: np.ndarray, fields: tuple[str, ...]) -> list[np.ndarray]:
    """``forward_kinematics``'s loop for whole arrays: each of the ``MjData`` arrays ``fields`` (e.g.
    "xpos") after ``mj_kinematics`` of each frame, stacked (T, ...). A plain copy per frame and array,
    without a generator step and a gather per frame (a few microseconds a frame over long clips)."""
    model = humanoid_model()
    data = mujoco.MjData(model)
    sources = [getattr(data, name) for name in fields]  # views into data, refreshed in place
    outs = [np.empty((qpos.shape[0], *source.shape)) for source in sources]
    frame = data.qpos
    kinematics = mujoco.mj_kinematics
    for t in range(qpos.shape[0]):
        frame[:] = qpos[t]
        kinematics(model, data)
        for out, source in zip(outs, sources):
            out[t] = source
    return outs


def body_positions(qpos: np.ndarray) -> np.ndarray:
    """(T, 15, 3) world positions of our bodies (BODY_NAMES order) for each frame of qpos."""
    model = humanoid_model()
    ids = [model.body(n).id for n in BODY_NAMES]
    if qpos.shape[0] == 0:
        return np.zeros((0, len(ids), 3))
    return _kinematics_arrays(qpos, ("xpos",))[0][:, ids]


def body_poses(qpos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(T, nbody, 3) world positions and (T, nbody, 9) orientation matrices (row-major) of every body of
    the bare humanoid model (its body ids, the world's included) for each frame of qpos."""
    xpos, xmat = _kinematics_arrays(qpos, ("xpos", "xmat"))
    return xpos, xmat


def body_rotations(qpos: np.ndarray, names: list[str]) -> dict[str, np.ndarray]:
    """(T, 3, 3) world orientation matrices of the bodies ``names`` (and of their ancestors, also in
    the result) in each frame of qpos, computed as ``mj_kinematics`` composes them (the root's
    normalised quaternion, then each body's frame and its hinges' axis-angle rotations) on arrays of
    frames at once: equal to MuJoCo's ``xmat`` to rounding (1e-15), a fraction of the per-frame loop."""
    model = humanoid_model()
    qpos = np.asarray(qpos, dtype=np.float64)
    ids: list[int] = []
    for name in names:
        b = model.body(name).id
        while b > 0 and b not in ids:
            ids.append(b)
            b = model.body_parentid[b]
    out: dict[int, np.ndarray] = {}
    for b in sorted(ids):  # parents before children
        parent = model.body_parentid[b]
        rot = np.broadcast_to(_quat_matrix(model.body_quat[b]), (qpos.shape[0], 3, 3))
        if parent > 0:
            rot = out[parent] @ rot
        for j in range(model.body_jntadr[b], model.body_jntadr[b] + model.body_jntnum[b]):
            adr = model.jnt_qposadr[j]
            if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
                quat = qpos[:, adr + 3:adr + 7]
                rot = rot @ _quat_matrix(quat / np.linalg.norm(quat, axis=1, keepdims=True))
            elif model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE and not model.jnt_pos[j].any():
                rot = rot @ _axis_angle_matrix(model.jnt_axis[j], qpos[:, adr])
            else:
                raise NotImplementedError("body_rotations: hinge joints at the body origin and a free root only")
        out[b] = rot
    return {model.body(b).name: out[b] for b in out}


def _quat_matrix(q: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices of unit (..., 4) w, x, y, z quaternions."""
    w, x, y, z = (q[..., k] for k in range(4))
    return np.stack([np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=-1),
                     np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=-1),
                     np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1)],
                    axis=-2)


def _axis_angle_matrix(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """(T, 3, 3) rotations by ``angle`` (T,) about the unit ``axis`` (3,) (Rodrigues; written out for
    a coordinate axis, the humanoid's hinges)."""
    k = np.asarray(axis, dtype=np.float64)
    if np.count_nonzero(k) == 1 and abs(k.sum()) == 1.0:
        i = int(np.flatnonzero(k)[0])
        j, l = (i + 1) % 3, (i + 2) % 3
        c, s = np.cos(angle), np.sin(angle) * k[i]
        out = np.zeros((len(angle), 3, 3))
        out[:, i, i] = 1.0
        out[:, j, j] = out[:, l, l] = c
        out[:, j, l], out[:, l, j] = -s, s
        return out
    c, s = np.cos(angle)[:, None, None], np.sin(angle)[:, None, None]
    cross = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return c * np.eye(3) + s * cross + (1.0 - c) * np.outer(k, k)


@lru_cache(maxsize=1)
def foot_box_geoms() -> np.ndarray:
    """Geom ids of the right and left foot boxes in the bare humanoid model."""
    model = humanoid_model()
    geoms = []
    for body in FOOT_BODIES:
        bid = model.body(body).id
        boxes = [g for g in range(model.ngeom)
                 if model.geom_bodyid[g] == bid and model.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX]
        if len(boxes) != 1:
            raise RuntimeError(f"expected one box geom on {body}, found {len(boxes)}")
        geoms.append(boxes[0])
    return np.array(geoms)


def _geom_frames(qpos: np.ndarray, geom_ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(T, G, 3) world positions and (T, G, 9) orientations of the bare model's geoms ``geom_ids`` in
    each frame of qpos (one FK pass)."""
    xpos, xmat = _kinematics_arrays(qpos, ("geom_xpos", "geom_xmat"))
    return xpos[:, geom_ids], xmat[:, geom_ids]


def _lowest_z_frames(model: mujoco.MjModel, xpos: np.ndarray, xmat: np.ndarray, geom_ids: np.ndarray) -> np.ndarray:
    """``humanoid_lowest_z`` of every frame at once (the same element-wise operations, so the same
    bits): (T,) from the geoms' (T, G, 3) positions and (T, G, 9) orientations."""
    kind = model.geom_type[geom_ids]
    z, size = xpos[:, :, 2], model.geom_size[geom_ids]
    r22 = np.abs(xmat[:, :, 8])
    bottom = np.where(kind == _SPHERE, z - size[:, 0], z - r22 * size[:, 1] - size[:, 0])
    for k in np.flatnonzero((kind != _SPHERE) & (kind != _CAPSULE)):
        g = geom_ids[k]
        if kind[k] == _BOX:
            bottom[:, k] = z[:, k] - _row_dot(np.abs(xmat[:, k, 6:9]), model.geom_size[g])
        else:
            bottom[:, k] = z[:, k] - model.geom_rbound[g]
    return np.fmin.reduce(bottom, axis=1, initial=np.inf)


def _row_dot(rows: np.ndarray, vector: np.ndarray) -> np.ndarray:
    """(T,) dot products of the rows of ``rows`` (T, 3) with ``vector`` (3,), each as ``row @ vector``
    computes it: a stack of 1 x 3 by 3 x 1 products takes numpy's dot of two vectors, where a (T, 3) x (3,)
    product (a matrix-vector kernel) rounds differently in the last bit."""
    return (rows[:, None, :] @ vector[:, None])[:, 0, 0]


def foot_sole_heights(qpos: np.ndarray) -> np.ndarray:
    """(T, 2) height of the lowest corner of the right and left foot box in each frame."""
    model = humanoid_model()
    geoms = foot_box_geoms()
    xpos, xmat = _geom_frames(qpos, geoms)
    out = np.zeros((qpos.shape[0], 2))
    for k in range(len(geoms)):
        out[:, k] = _lowest_z_frames(model, xpos[:, k:k + 1], xmat[:, k:k + 1], geoms[k:k + 1])
    return out


def geom_lowest_points(qpos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(T, G) lowest point of each of the humanoid's geoms and (T, G, 2) their centres' horizontal
    positions, in each frame of qpos (one FK pass): which body part touches the floor, and whether
    it is planted."""
    model = humanoid_model()
    geom_ids = humanoid_geoms(model, HumanoidIndices.from_model(model))
    xpos, xmat = _geom_frames(qpos, geom_ids)
    lowest = np.stack([_lowest_z_frames(model, xpos[:, k:k + 1], xmat[:, k:k + 1], geom_ids[k:k + 1])
                       for k in range(len(geom_ids))], axis=1)
    return lowest, xpos[..., :2]


def lowest_body_point(qpos: np.ndarray, geom_ids: np.ndarray | None = None) -> np.ndarray:
    """(T,) height of the lowest point of the humanoid's geoms (spheres, capsules, boxes) in each
    frame of qpos; ``geom_ids`` (ids in the bare model) limits it to those geoms."""
    model = humanoid_model()
    if geom_ids is None:
        geom_ids = humanoid_geoms(model, HumanoidIndices.from_model(model))
    geom_ids = np.asarray(geom_ids, dtype=np.int64)
    if qpos.shape[0] == 0:
        return np.full(0, np.inf)
    xpos, xmat = _geom_frames(qpos, geom_ids)
    return _lowest_z_frames(model, xpos, xmat, geom_ids)
