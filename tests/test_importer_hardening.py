"""Motion files from strangers: nothing in them runs, and every corrupt or absurd one is refused.

Each crafted file is built here, in ``tmp_path``: pickles whose ``__reduce__`` would run a
command or write a marker file, pickles that claim far more memory than they hold, and
DeepMimic, BVH and IsaacGymEnvs files with absurd frame rates, durations, sizes, nesting
or values. All must raise ``MotionFileError`` naming the file, quickly; legitimate files
(built the way poselib saves them, and the shipped ones in ``../shared/motions``) still
import. The converter reports each failing file and converts the others.
"""

from __future__ import annotations

import builtins
import json
import os
import struct
import time
from collections import OrderedDict
from pathlib import Path

import numpy as np
import pytest

from stairenv.humanoid import BODY_NAMES, PARENT_INDICES
from stairenv.motion import convert
from stairenv.motion.clip import MotionClip, MotionFileError, humanoid_model
from stairenv.motion.importers import MAX_FILE_BYTES, MAX_FRAMES, MAX_JOINTS, import_motion
from stairenv.motion.importers.isaac_npy import read_isaac_npy

ISAAC = Path(__file__).resolve().parents[2] / "shared" / "motions" / "IsaacGymEnvs"

# Longest a refusal may take: the issue's 36 KB DeepMimic file with 1000 s frames ran past 90 s.
REFUSAL_SECONDS = 10.0


def assert_refused(path: Path, match: str = "", **kwargs) -> MotionFileError:
    """import_motion(path) raises MotionFileError naming the file (and ``match``), within REFUSAL_SECONDS."""
    start = time.perf_counter()
    with pytest.raises(MotionFileError) as caught:
        import_motion(path, **kwargs)
    elapsed = time.perf_counter() - start
    message = str(caught.value)
    assert str(path) in message, message
    if match:
        assert match in message, message
    assert elapsed < REFUSAL_SECONDS, f"{path.name}: refused after {elapsed:.1f} s"
    return caught.value


# ------------------------------------------------------------------------------------------
# legitimate files, built as their tools write them
# ------------------------------------------------------------------------------------------
def our_offsets() -> np.ndarray:
    model = humanoid_model()
    return np.array([model.body_pos[model.body(b).id] for b in BODY_NAMES])


def poselib_motion(frames: int = 12, fps: object = None) -> OrderedDict:
    """A ``SkeletonMotion`` as poselib pickles it: nested dicts of float32/int64 arrays, is_local, fps."""
    def tensor(array: np.ndarray) -> dict:
        return {"arr": array, "context": {"dtype": str(array.dtype)}}

    rotation = np.zeros((frames, len(BODY_NAMES), 4), dtype=np.float32)
    rotation[..., 3] = 1.0
    knee = np.sin(np.linspace(0.0, 1.0, frames)).astype(np.float32)
    rotation[:, BODY_NAMES.index("left_shin"), 1] = np.sin(0.5 * knee)  # bend about y
    rotation[:, BODY_NAMES.index("left_shin"), 3] = np.cos(0.5 * knee)
    root = np.stack([np.linspace(0.0, 0.5, frames), np.zeros(frames), np.full(frames, 0.9)], axis=1)
    tree = OrderedDict(
        node_names=list(BODY_NAMES),
        parent_indices=tensor(np.array(PARENT_INDICES, dtype=np.int64)),
        local_translation=tensor(our_offsets().astype(np.float32)),
    )
    return OrderedDict(
        rotation=tensor(rotation),
        root_translation=tensor(root.astype(np.float32)),
        global_velocity=tensor(np.zeros((frames, len(BODY_NAMES), 3), dtype=np.float32)),
        global_angular_velocity=tensor(np.zeros((frames, len(BODY_NAMES), 3), dtype=np.float32)),
        skeleton_tree=tree,
        is_local=True,
        fps=np.array(60, dtype=np.int32) if fps is None else fps,
        __name__="SkeletonMotion",
    )


def save_npy(path: Path, content: object) -> Path:
    np.save(path, np.array(content, dtype=object) if not isinstance(content, np.ndarray) else content,
            allow_pickle=True)
    return path


def deepmimic_frames(frames: int = 10, duration: float = 1 / 30) -> list[list[float]]:
    """Standing frames: duration, root (y up), identity quaternions (w first), straight knees and elbows."""
    identity = [1.0, 0.0, 0.0, 0.0]
    pose = identity * 2 + (identity + [0.0] + identity + identity + [0.0]) * 2  # chest, neck, right, left limbs
    return [[duration, 0.01 * k, 0.9, 0.0, *identity, *pose] for k in range(frames)]


def write_deepmimic(path: Path, frames: list, loop: str = "none") -> Path:
    path.write_text(json.dumps({"Loop": loop, "Frames": frames}))
    return path


# A small skeleton with the CMU joint names the "cmu" retargeting reads (y up, ~0.056 m per unit).
CMU_LIKE: tuple[tuple[str, str | None, tuple[float, float, float]], ...] = (
    ("Hips", None, (0.0, 0.0, 0.0)),
    ("LeftUpLeg", "Hips", (1.6, -0.8, 0.0)), ("LeftLeg", "LeftUpLeg", (0.0, -7.4, 0.0)),
    ("LeftFoot", "LeftLeg", (0.0, -7.2, 0.0)), ("LeftToeBase", "LeftFoot", (0.0, -0.6, 2.2)),
    ("RightUpLeg", "Hips", (-1.6, -0.8, 0.0)), ("RightLeg", "RightUpLeg", (0.0, -7.4, 0.0)),
    ("RightFoot", "RightLeg", (0.0, -7.2, 0.0)), ("RightToeBase", "RightFoot", (0.0, -0.6, 2.2)),
    ("LowerBack", "Hips", (0.0, 0.8, 0.0)), ("Spine1", "LowerBack", (0.0, 3.5, 0.0)),
    ("Neck", "Spine1", (0.0, 3.0, 0.0)), ("Head", "Neck", (0.0, 1.2, 0.0)),
    ("LeftArm", "Spine1", (3.0, 2.6, 0.0)), ("LeftForeArm", "LeftArm", (4.8, 0.0, 0.0)),
    ("LeftHand", "LeftForeArm", (4.6, 0.0, 0.0)),
    ("RightArm", "Spine1", (-3.0, 2.6, 0.0)), ("RightForeArm", "RightArm", (-4.8, 0.0, 0.0)),
    ("RightHand", "RightForeArm", (-4.6, 0.0, 0.0)),
)


def bvh_text(frames: int = 13, frame_time: str = "0.0333333", offset_scale: float = 1.0,
             root_x: float = 0.0) -> str:
    """A CMU-like BVH: the root walks along z, the left knee bends; everything else at rest."""
    children: dict[str | None, list[int]] = {}
    for i, (_, parent, _) in enumerate(CMU_LIKE):
        children.setdefault(parent, []).append(i)
    lines: list[str] = ["HIERARCHY"]

    def joint(i: int, depth: int) -> None:
        name, parent, offset = CMU_LIKE[i]
        pad = "  " * depth
        lines.append(f"{pad}{'ROOT' if parent is None else 'JOINT'} {name}")
        lines.append(f"{pad}{{")
        lines.append(f"{pad}  OFFSET {' '.join(str(offset_scale * v) for v in offset)}")
        channels = "6 Xposition Yposition Zposition" if parent is None else "3"
        lines.append(f"{pad}  CHANNELS {channels} Zrotation Yrotation Xrotation")
        for child in children.get(name, []):
            joint(child, depth + 1)
        if name not in children:
            lines.extend([f"{pad}  End Site", f"{pad}  {{", f"{pad}    OFFSET 0 1 0", f"{pad}  }}"])
        lines.append(f"{pad}}}")

    joint(0, 0)
    lines += ["MOTION", f"Frames: {frames}", f"Frame Time: {frame_time}"]
    knee = 3 + 3 * [name for name, _, _ in CMU_LIKE].index("LeftLeg") + 2  # its Xrotation column
    for k in range(frames):
        values = [0.0] * (6 + 3 * (len(CMU_LIKE) - 1))
        values[0], values[1], values[2] = root_x, 16.5, 0.3 * k
        values[knee] = 20.0 * np.sin(k / 4)
        lines.append(" ".join(f"{v:g}" for v in values))
    return "\n".join(lines) + "\n"


def write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def test_legitimate_synthetic_files_import(tmp_path):
    clip = import_motion(save_npy(tmp_path / "walk.npy", poselib_motion(frames=12)))
    assert clip.num_frames == 12 and clip.fps == 60.0 and clip.meta["importer"] == "isaac_npy"
    assert clip.meta["fk_error"]["max_m"] < 1e-5  # our offsets: exact
    clip = import_motion(write_deepmimic(tmp_path / "stand.txt", deepmimic_frames(10)))
    assert clip.num_frames == 10 and clip.fps == 30.0
    clip = import_motion(write(tmp_path / "cmu_like.bvh", bvh_text()))
    assert clip.num_frames == 12 and clip.fps == 30.0 and clip.meta["limb_direction_error_deg"]["max"] < 1.0


@pytest.mark.parametrize("fps, is_local", [
    (np.array(60, dtype=np.int32), True),  # as the shipped files hold them
    (60, np.bool_(True)),                  # Python int, numpy bool scalar
    (np.float32(60.0), True),              # numpy float scalar
    (np.array([60.0]), np.array(True)),    # one-element arrays
])
def test_poselib_value_types_load(tmp_path, fps, is_local):
    motion = poselib_motion(frames=5, fps=fps)
    motion["is_local"] = is_local
    src = read_isaac_npy(save_npy(tmp_path / "m.npy", motion))
    assert src["fps"] == 60.0 and src["is_local"] is True
    np.testing.assert_array_equal(src["rotation"], motion["rotation"]["arr"])
    np.testing.assert_array_equal(src["local_translation"], motion["skeleton_tree"]["local_translation"]["arr"])


def test_single_pose_skeleton_state_loads(tmp_path):
    state = poselib_motion(frames=1)
    for key in ("fps", "global_velocity", "global_angular_velocity"):
        del state[key]
    state["rotation"]["arr"] = state["rotation"]["arr"][0]
    state["root_translation"]["arr"] = state["root_translation"]["arr"][0]
    state["__name__"] = "SkeletonState"
    clip = import_motion(save_npy(tmp_path / "tpose.npy", state))
    assert clip.num_frames == 1 and clip.fps == 30.0


@pytest.mark.skipif(not ISAAC.is_dir(), reason=f"IsaacGymEnvs motions not found at {ISAAC}")
def test_shipped_isaac_files_read_exactly_as_numpy_does():
    files = sorted(ISAAC.glob("*.npy"))
    assert files
    for path in files:
        trusted = np.load(path, allow_pickle=True).item()  # our own copies: trusted
        src = read_isaac_npy(path)
        np.testing.assert_array_equal(src["rotation"].reshape(trusted["rotation"]["arr"].shape),
                                      trusted["rotation"]["arr"])
        np.testing.assert_array_equal(src["root_translation"].reshape(trusted["root_translation"]["arr"].shape),
                                      trusted["root_translation"]["arr"])
        np.testing.assert_array_equal(src["parent_indices"], trusted["skeleton_tree"]["parent_indices"]["arr"])
        assert src["node_names"] == trusted["skeleton_tree"]["node_names"]
        assert src["is_local"] is bool(trusted["is_local"])
        assert src["fps"] == (float(trusted["fps"]) if "fps" in trusted else None)
        import_motion(path)


# ------------------------------------------------------------------------------------------
# item 1: opening a file runs nothing from it
# ------------------------------------------------------------------------------------------
class Payload:
    """Pickles as a call of ``function(*args)``: what a crafted motion file would run on load."""

    def __init__(self, function, *args) -> None:
        self.function, self.args = function, args

    def __reduce__(self):
        return self.function, self.args


def payloads(marker: Path) -> dict[str, Payload]:
    return {
        "os_system": Payload(os.system, f"touch {marker}"),
        "exec": Payload(builtins.exec, f"open({str(marker)!r}, 'w').close()"),
        "open": Payload(builtins.open, str(marker), "w"),
        "eval": Payload(builtins.eval, f"__import__('os').system('touch {marker}')"),
    }


@pytest.mark.parametrize("where", ["top", "fps", "rotation", "node_names", "context"])
@pytest.mark.parametrize("kind", ["os_system", "exec", "open", "eval"])
def test_pickled_code_is_never_run(tmp_path, where, kind):
    marker = tmp_path / "ran"
    payload = payloads(marker)[kind]
    motion = poselib_motion()
    if where == "top":
        content = payload
    else:
        content = motion
        if where == "fps":
            motion["fps"] = payload
        elif where == "rotation":
            motion["rotation"]["arr"] = payload
        elif where == "node_names":
            motion["skeleton_tree"]["node_names"][3] = payload
        else:
            motion["root_translation"]["context"]["dtype"] = payload
    path = save_npy(tmp_path / "evil.npy", content)
    with pytest.raises(MotionFileError) as caught:
        import_motion(path)
    assert not marker.exists(), "the pickle ran code"
    assert str(path) in str(caught.value) and "refused" in str(caught.value)
    assert any(name in str(caught.value) for name in ("system", "exec", "open", "eval"))


def raw_npy(path: Path, pickle_bytes: bytes) -> Path:
    """An object-array .npy header followed by hand-made pickle bytes."""
    header = "{'descr': '|O', 'fortran_order': False, 'shape': (), }"
    header += " " * (63 - (10 + len(header)) % 64) + "\n"
    path.write_bytes(b"\x93NUMPY\x01\x00" + struct.pack("<H", len(header)) + header.encode() + pickle_bytes)
    return path


class ArrayState:
    """Pickles like an ndarray (numpy's own _reconstruct + BUILD) but with the state we choose."""

    def __init__(self, shape, dtype, data) -> None:
        self.state = (1, shape, np.dtype(dtype), False, data)

    def __reduce__(self):
        return np.ndarray.__reduce__(np.zeros(0))[0], (np.ndarray, (0,), b"b"), self.state


def shared_list_bomb(levels: int = 40) -> list:
    """A list whose pickle is ~levels entries but which is 2**levels numbers deep down."""
    nested: list = [0.0, 0.0, 0.0, 1.0]
    for _ in range(levels):
        nested = [nested, nested]
    return nested


def test_pickle_memory_and_shape_bombs_are_refused(tmp_path):
    cases = {}
    # An array whose state claims 10**12 float32s but carries 4 bytes.
    motion = poselib_motion()
    motion["rotation"]["arr"] = ArrayState((10**12,), "f4", b"\0" * 4)
    cases["claimed_shape"] = save_npy(tmp_path / "claimed_shape.npy", motion)
    # An object array claiming 10**9 elements (numpy would fill 8 GB with None before checking).
    cases["object_shape"] = save_npy(tmp_path / "object_shape.npy", ArrayState((10**9,), object, [motion]))
    # Nested lists that share themselves: tiny pickle, 2**40 numbers once flattened.
    motion = poselib_motion()
    motion["rotation"]["arr"] = shared_list_bomb()
    cases["shared_lists"] = save_npy(tmp_path / "shared_lists.npy", motion)
    # BINBYTES8 announcing a terabyte.
    cases["binbytes"] = raw_npy(tmp_path / "binbytes.npy", b"\x80\x04\x8e" + struct.pack("<Q", 2**40) + b"xx")
    # A structured dtype and a string dtype where numbers belong.
    motion = poselib_motion()
    motion["root_translation"]["arr"] = np.zeros(3, dtype=[("x", "f4"), ("y", "O")])
    cases["structured"] = save_npy(tmp_path / "structured.npy", motion)
    motion = poselib_motion()
    motion["root_translation"]["arr"] = np.array(["1e30"] * 36).reshape(12, 3)
    cases["strings"] = save_npy(tmp_path / "strings.npy", motion)
    # 1000 joints, deep pickle nesting.
    motion = poselib_motion()
    motion["skeleton_tree"]["node_names"] = [f"j{k}" for k in range(MAX_JOINTS + 1)]
    cases["joints"] = save_npy(tmp_path / "joints.npy", motion)
    cases["nesting"] = raw_npy(tmp_path / "nesting.npy", b"\x80\x02" + b"]" * 200_000 + b"a" * 199_999 + b".")
    for path in cases.values():
        assert_refused(path)


# ------------------------------------------------------------------------------------------
# item 4: absurd or corrupt files, all formats
# ------------------------------------------------------------------------------------------
def test_absurd_isaac_files_are_refused(tmp_path):
    def variant(name: str, change) -> Path:
        motion = poselib_motion()
        change(motion)
        return save_npy(tmp_path / f"{name}.npy", motion)

    cases = {
        "fps_huge": variant("fps_huge", lambda m: m.update(fps=1e9)),
        "fps_tiny": variant("fps_tiny", lambda m: m.update(fps=1e-9)),
        "fps_nan": variant("fps_nan", lambda m: m.update(fps=float("nan"))),
        "fps_text": variant("fps_text", lambda m: m.update(fps="60")),
        "fps_bool": variant("fps_bool", lambda m: m.update(fps=True)),
        "fps_400_digits": variant("fps_400_digits", lambda m: m.update(fps=int("9" * 400))),
        "is_local_text": variant("is_local_text", lambda m: m.update(is_local="no")),
        "is_local_list": variant("is_local_list", lambda m: m.update(is_local=[])),
        "root_1e30": variant("root_1e30", lambda m: m["root_translation"]["arr"].__setitem__((3, 0), 1e30)),
        "offset_nan": variant("offset_nan", lambda m: m["skeleton_tree"]["local_translation"]["arr"]
                              .__setitem__((2, 1), np.nan)),
        "arr_list": variant("arr_list", lambda m: m["rotation"].update(arr=m["rotation"]["arr"].tolist())),
        "names_not_str": variant("names_not_str", lambda m: m["skeleton_tree"]["node_names"].__setitem__(0, 7)),
    }
    for path in cases.values():
        assert_refused(path)
    assert "is_local" in str(assert_refused(cases["is_local_text"]))
    assert "fps" in str(assert_refused(cases["fps_huge"]))
    # Long enough at 1 fps, but 30 fps asks for more frames than allowed.
    motion = poselib_motion(frames=3601, fps=1)
    assert_refused(save_npy(tmp_path / "one_fps.npy", motion), f"limit of {MAX_FRAMES}", fps=30)


def test_absurd_deepmimic_files_are_refused(tmp_path):
    good = deepmimic_frames(10)
    cases = {
        "nesting": write(tmp_path / "nesting.txt", '{"Frames": ' + "[" * 100_000 + "]" * 100_000 + "}"),
        "digits": write(tmp_path / "digits.txt", json.dumps({"Frames": good}).replace("0.9", "9" * 400, 1)),
        "long_digits": write(tmp_path / "long_digits.txt",
                             json.dumps({"Frames": good}).replace("0.9", "9" * 5000, 1)),
        "thousand_s_frames": write_deepmimic(tmp_path / "thousand_s_frames.txt", deepmimic_frames(60, 1000.0)),
        "fps_1e9": write_deepmimic(tmp_path / "fps_1e9.txt", deepmimic_frames(10, 1e-9)),
        "frame_1e-300": write_deepmimic(tmp_path / "frame_1e-300.txt",
                                        [f if k != 4 else [1e-300, *f[1:]] for k, f in enumerate(good)]),
        "frame_1e5_s": write_deepmimic(tmp_path / "frame_1e5_s.txt",
                                       [f if k != 4 else [1e5, *f[1:]] for k, f in enumerate(good)]),
        "root_1e30": write_deepmimic(tmp_path / "root_1e30.txt",
                                     [f if k != 2 else [f[0], 1e30, *f[2:]] for k, f in enumerate(good)]),
        "infinity": write(tmp_path / "infinity.txt", json.dumps({"Frames": good}).replace("0.9", "Infinity", 1)),
        "loop_list": write(tmp_path / "loop_list.txt", json.dumps({"Loop": [], "Frames": good})),
        "bool_values": write(tmp_path / "bool_values.txt", json.dumps({"Frames": good}).replace("0.9", "true", 1)),
    }
    for path in cases.values():
        assert_refused(path)
    assert "fps" in str(assert_refused(cases["thousand_s_frames"]))


def test_absurd_bvh_files_are_refused(tmp_path):
    text = bvh_text()
    lines = text.splitlines()
    motion_at = lines.index("MOTION")
    deep = "HIERARCHY\nROOT J0\n{\nOFFSET 0 0 0\nCHANNELS 1 Xrotation\n"
    deep += "".join(f"JOINT J{k}\n{{\nOFFSET 0 1 0\nCHANNELS 1 Xrotation\n" for k in range(1, 3000))
    deep += "}\n" * 3000 + "MOTION\nFrames: 1\nFrame Time: 0.01\n" + " 0" * 3000 + "\n"
    cases = {
        "frame_time_1e300": write(tmp_path / "frame_time_1e300.bvh", bvh_text(frame_time="1e300")),
        "frame_time_1e-300": write(tmp_path / "frame_time_1e-300.bvh", bvh_text(frame_time="1e-300")),
        "frame_time_1000": write(tmp_path / "frame_time_1000.bvh", bvh_text(frame_time="1000")),
        "zero_offsets": write(tmp_path / "zero_offsets.bvh", bvh_text(offset_scale=0.0)),
        "offsets_1e300": write(tmp_path / "offsets_1e300.bvh", bvh_text(offset_scale=1e300)),
        "root_1e30": write(tmp_path / "root_1e30.bvh", bvh_text(root_x=1e30)),
        "frames_digits": write(tmp_path / "frames_digits.bvh",
                               "\n".join(lines[:motion_at + 1] + ["Frames: " + "9" * 5000] + lines[motion_at + 2:])),
        "frames_many": write(tmp_path / "frames_many.bvh",
                             "\n".join(lines[:motion_at + 1] + [f"Frames: {MAX_FRAMES + 1}"]
                                       + lines[motion_at + 2:])),
        "channels_digit": write(tmp_path / "channels_digit.bvh", text.replace("CHANNELS 3", "CHANNELS \u00b3", 1)),
        "channels_huge": write(tmp_path / "channels_huge.bvh", text.replace("CHANNELS 3", "CHANNELS " + "9" * 5000)),
        "deep_hierarchy": write(tmp_path / "deep_hierarchy.bvh", deep),
        "collapsed_hips": write(tmp_path / "collapsed_hips.bvh",
                                text.replace("OFFSET 1.6 -0.8 0.0", "OFFSET 0.0 -0.8 0.0")
                                .replace("OFFSET -1.6 -0.8 0.0", "OFFSET 0.0 -0.8 0.0")),
    }
    for path in cases.values():
        assert_refused(path)
    assert "fps" in str(assert_refused(cases["frame_time_1e-300"]))


@pytest.mark.parametrize("suffix", [".npy", ".txt", ".bvh"])
def test_oversized_files_are_refused_before_reading(tmp_path, suffix):
    path = tmp_path / f"huge{suffix}"
    with path.open("wb") as f:
        f.truncate(MAX_FILE_BYTES + 1)  # sparse: nothing is written
    assert_refused(path, "bytes")


# ------------------------------------------------------------------------------------------
# item 3: the converter reports each failing file and converts the others
# ------------------------------------------------------------------------------------------
def test_converter_reports_each_failure_and_converts_the_rest(tmp_path, capsys):
    folder = tmp_path / "in"
    folder.mkdir()
    write_deepmimic(folder / "a_good.txt", deepmimic_frames(10))
    write(folder / "b_corrupt.bvh", bvh_text(frame_time="1e300"))
    save_npy(folder / "c_evil.npy", Payload(os.system, f"touch {tmp_path / 'ran'}"))
    save_npy(folder / "d_good.npy", poselib_motion())
    write_deepmimic(folder / "e_slow.txt", deepmimic_frames(60, 1000.0))
    out = tmp_path / "out"
    status = convert.main([str(folder), str(tmp_path / "missing.txt"), "--out", str(out)])
    captured = capsys.readouterr()
    assert status == 1
    assert sorted(p.stem for p in out.glob("*.npz")) == ["a_good", "d_good"]
    assert not (tmp_path / "ran").exists()
    for name in ("b_corrupt.bvh", "c_evil.npy", "e_slow.txt", "missing.txt"):
        assert name in captured.err
    assert "4 of 6 input(s) failed" in captured.err
    assert MotionClip.load(out / "d_good.npz").num_frames == 6  # 12 frames at 60 fps -> the default 30 fps


def test_converter_survives_an_unexpected_exception(tmp_path, capsys, monkeypatch):
    import stairenv.motion.importers as importers

    real = importers.import_motion

    def flaky(path, **kwargs):
        if Path(path).stem == "b":
            raise RuntimeError("importer bug")
        return real(path, **kwargs)

    monkeypatch.setattr(importers, "import_motion", flaky)
    for name in "abc":
        write_deepmimic(tmp_path / f"{name}.txt", deepmimic_frames(5))
    status = convert.main([str(tmp_path / f"{n}.txt") for n in "abc"] + ["--out", str(tmp_path / "out")])
    captured = capsys.readouterr()
    assert status == 1
    assert sorted(p.stem for p in (tmp_path / "out").glob("*.npz")) == ["a", "c"]
    assert "b.txt: RuntimeError: importer bug" in captured.err and "1 of 3 input(s) failed" in captured.err


def test_several_frames_without_fps_are_refused(tmp_path):
    """A SkeletonState-like file (no fps) holding several frames: its rate is unknown, never guessed as 30."""
    motion = poselib_motion(frames=12)
    del motion["fps"]
    assert_refused(save_npy(tmp_path / "no_fps.npy", motion), "12 frames but no fps")
    assert_refused(save_npy(tmp_path / "no_fps.npy", motion), "12 frames but no fps", fps=30)
