"""python -m stairenv: a short MP4 (and PNG stills) of one policy."""

from __future__ import annotations

import os
import subprocess
import sys

import imageio.v3 as iio
import numpy as np
import pytest


def _run(*args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    env = {**os.environ, "MUJOCO_GL": "egl"}
    return subprocess.run([sys.executable, "-m", "stairenv", *args], capture_output=True, text=True,
                          timeout=timeout, env=env)


def test_writes_video_and_pngs(tmp_path):
    out = tmp_path / "sub" / "v.mp4"
    pngs = tmp_path / "stills"
    result = _run("--seconds", "2", "--width", "160", "--height", "120", "--out", str(out),
                  "--policy", "random", "--frames-png", str(pngs), "--no-progress")
    assert result.returncode == 0, result.stderr
    assert str(out) in result.stdout and "steps" in result.stdout and "progress" in result.stdout
    assert out.stat().st_size > 0
    frames = iio.imread(out)
    assert frames.shape[1:] == (120, 160, 3)
    assert 58 <= frames.shape[0] <= 62  # 2 s at 30 fps, episodes restarted after falls
    assert frames.std() > 5  # not a blank image
    stills = sorted(pngs.glob("*.png"))
    assert len(stills) == 2  # one per second
    image = iio.imread(stills[0])
    assert image.shape == (120, 160, 3) and image.dtype == np.uint8


def test_one_second_defaults(tmp_path):
    out = tmp_path / "v.mp4"
    result = _run("--seconds", "1", "--width", "160", "--height", "120", "--out", str(out))
    assert result.returncode == 0, result.stderr
    assert 28 <= iio.imread(out).shape[0] <= 32


@pytest.mark.parametrize("env_id", ["PlaMoScene-v0", "SIMS-Sit-v0"])
def test_videos_of_the_other_envs(tmp_path, env_id):
    """Envs without InterLevel's stair progress render too (the summary leaves progress out)."""
    from stairenv.__main__ import record

    extra = {"text_encoder": "hashing"} if env_id.startswith("SIMS") else {}
    summary = record(env_id, seconds=0.5, out=tmp_path / "v.mp4", width=96, height=72, env_kwargs=extra,
                     progress_bar=False)
    assert summary["best_progress"] is None and summary["steps"] == summary["frames"] - 1
    frames = iio.imread(tmp_path / "v.mp4")
    assert frames.shape[1:] == (72, 96, 3) and frames.std() > 5


def test_one_episode_to_its_end(tmp_path):
    """Without seconds: one episode until it ends, its outcome held on the last frame, captions drawn."""
    from stairenv.__main__ import OUTCOME_HOLD_SECONDS, caption_frame, outcome_of, record

    summary = record(policy="zero", seconds=None, out=tmp_path / "v.mp4", width=96, height=72, progress_bar=False)
    hold = int(round(OUTCOME_HOLD_SECONDS * summary["fps"]))
    assert summary["episodes"] == 1 and summary["outcome"] == "fell"  # the zero policy collapses
    assert summary["frames"] == summary["steps"] + 1 + hold
    frames = iio.imread(tmp_path / "v.mp4")
    assert frames.shape[0] == summary["frames"]
    assert np.abs(frames[-1].astype(int) - frames[-hold].astype(int)).mean() < 2  # the held last frame
    # the banner is drawn (a dark band with light text) and the outcome words come from info
    blank = np.full((72, 96, 3), 128, np.uint8)
    assert np.abs(caption_frame(blank, ["x"], "FELL").astype(int) - 128).sum() > 0
    assert outcome_of({"success": True}, True, False) == "success"
    assert outcome_of({"physics_unstable": True, "fell": True}, False, True) == "physics diverged"
    assert outcome_of({}, False, True) == "time limit" and outcome_of({}, False, False) == "still running"


def test_bad_arguments(tmp_path):
    result = _run("--policy", "nope", "--out", str(tmp_path / "v.mp4"))
    assert result.returncode == 2 and "policy must be one of" in result.stderr
    result = _run("--seconds", "0", "--out", str(tmp_path / "v.mp4"))
    assert result.returncode == 2 and "seconds" in result.stderr


@pytest.fixture
def shipped(tmp_path, monkeypatch):
    """Point the shipped-policy lookup at a tmp folder; returns that folder (empty: nothing ships)."""
    from stairenv import pretrained

    folder = tmp_path / "policies"
    folder.mkdir()
    monkeypatch.setattr(pretrained, "shipped_policy_path", lambda env_id: folder / f"{env_id}.npz")
    return folder


def test_default_falls_back_to_zero_without_a_shipped_policy(tmp_path, shipped, capsys):
    from stairenv.__main__ import main

    assert main(["--seconds", "0.2", "--width", "64", "--height", "48", "--out", str(tmp_path / "v.mp4"),
                 "--no-progress"]) == 0
    out = capsys.readouterr().out
    notes = [line for line in out.splitlines() if "no trained policy" in line]
    assert len(notes) == 1 and "'zero'" in notes[0]
    assert "zero on InterLevel-v0" in out
    # asking for it explicitly is an error naming the env
    with pytest.raises(SystemExit) as exit_info:
        main(["--policy", "pretrained", "--seconds", "0.2", "--out", str(tmp_path / "w.mp4"), "--no-progress"])
    assert exit_info.value.code == 2
    assert "no trained policy for 'InterLevel-v0'" in capsys.readouterr().err


def test_default_uses_the_shipped_policy(tmp_path, shipped, capsys):
    """A tiny fake policy (a single linear layer) in the monkeypatched lookup folder, never in src/."""
    from stairenv.__main__ import main, record
    from stairenv.pretrained import NumpyPolicy

    rng = np.random.default_rng(0)
    fake = NumpyPolicy([rng.normal(0.0, 0.01, (28, 118))], [np.full(28, 0.3)], np.zeros(118), np.ones(118),
                       config={"env_id": "InterLevel-v0"})
    fake.save(shipped / "InterLevel-v0.npz")
    summary = record(seconds=0.2, out=tmp_path / "v.mp4", width=64, height=48, progress_bar=False)
    assert summary["policy"] == str(shipped / "InterLevel-v0.npz") and "shipped" in summary["note"]
    for argv in ([], ["--policy", "pretrained"]):
        assert main([*argv, "--seconds", "0.2", "--width", "64", "--height", "48",
                     "--out", str(tmp_path / "v.mp4"), "--no-progress"]) == 0
        out = capsys.readouterr().out
        assert "no trained policy" not in out and "pretrained on InterLevel-v0" in out
        assert "policy shipped with stairenv (InterLevel-v0.npz)" in out
    # an explicit policy wins over the shipped one
    assert main(["--policy", "random", "--seconds", "0.2", "--width", "64", "--height", "48",
                 "--out", str(tmp_path / "v.mp4"), "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "random on InterLevel-v0" in out and "shipped with stairenv" not in out


def test_policy_captions_films_on_the_captions_the_policy_trained_on(tmp_path):
    """--policy-captions: a policy that recorded its training captions is filmed on them; without the flag,
    or for a policy that recorded none, the env draws its own."""
    import gymnasium as gym
    import numpy as np

    from stairenv.__main__ import record
    from stairenv.pretrained import NumpyPolicy

    hashing = {"text_encoder": "hashing"}
    size = gym.make("SIMS-Walk-v0", **hashing).observation_space.shape[0]
    trained = [["sad", "walks slowly to the bed"]]
    path = tmp_path / "walk.npz"
    NumpyPolicy([np.zeros((28, size))], [np.zeros(28)], np.zeros(size), np.ones(size),
                config={"env_id": "SIMS-Walk-v0", "training": {"env_kwargs": {"captions": trained}}}).save(path)
    common = dict(seconds=0.2, width=64, height=48, env_kwargs=hashing, progress_bar=False)
    summary = record("SIMS-Walk-v0", policy=str(path), out=tmp_path / "a.mp4", policy_captions=True, **common)
    assert summary["captions"] == (("sad", "walks slowly to the bed"),)
    assert record("SIMS-Walk-v0", policy=str(path), out=tmp_path / "b.mp4", **common)["captions"] is None
    assert record("SIMS-Walk-v0", policy="zero", out=tmp_path / "c.mp4", policy_captions=True,
                  **common)["captions"] is None


def test_each_env_films_to_its_own_default_path_and_bad_ids_or_keywords_are_usage_errors(tmp_path, capsys):
    """The default ``--out`` is the env's own (filming SIMS used to overwrite ``videos/interlevel.mp4``); an
    unknown id is named before any policy is looked up for it; a keyword the film sets itself, or one of the
    wrong type, is a usage error, not a traceback."""
    from stairenv.__main__ import default_out, main

    assert [default_out(i) for i in ("InterLevel-v0", "SIMS-Walk-v0", "PlaMoScene-v0")] == [
        "videos/interlevel.mp4", "videos/sims-walk.mp4", "videos/plamoscene.mp4"]
    for argv, message in ((["--env", "NoSuchEnv-v0", "--policy", "pretrained"], "registered env id"),
                          (["--env-kwarg", "width=100"], "the film sets them itself"),
                          (["--env-kwarg", "step_height_set=abc"], "step_height_set")):
        with pytest.raises(SystemExit) as stop:
            main([*argv, "--seconds", "0.2", "--out", str(tmp_path / "v.mp4"), "--no-progress"])
        assert stop.value.code == 2
        err = capsys.readouterr().err
        assert message in err and "Traceback" not in err and "no trained policy" not in err, err


def test_a_policy_file_is_refused_on_other_text_embeddings_than_it_trained_on(tmp_path):
    """Any policy file, not only ``--policy pretrained``: ``python -m stairenv`` resolves the shipped policy to
    its path, and the shipped SIMS walker used to be filmed on another encoder's embeddings without a word."""
    import gymnasium as gym

    from stairenv.policy_loading import load_policy
    from stairenv.pretrained import NumpyPolicy, PolicyFileError

    env = gym.make("SIMS-Walk-v0", text_encoder="hashing")
    size = env.observation_space.shape[0]
    path = tmp_path / "walk.npz"
    NumpyPolicy([np.zeros((28, size))], [np.zeros(28)], np.zeros(size), np.ones(size),
                config={"env_id": "SIMS-Walk-v0", "text_encoder_id": "another-encoder"}).save(path)
    with pytest.raises(PolicyFileError, match="trained on the text embeddings of 'another-encoder'"):
        load_policy(str(path), env)
    env.close()


@pytest.mark.slow
def test_frames_show_the_filmed_episodes_progress_and_the_camera_set_before_a_reset_holds(tmp_path, monkeypatch):
    """Each frame's label gives the progress of the episode filmed (a new episode used to start with the
    last one's best), and ``set_camera`` before a reset that rebuilds the scene (SIMS) still holds."""
    import gymnasium as gym

    import stairenv.__main__ as cli

    labels = []
    real = cli.caption_frame
    monkeypatch.setattr(cli, "caption_frame", lambda frame, lines, banner=None: labels.append(lines) or
                        real(frame, lines, banner))
    summary = cli.record(policy="pretrained", seconds=11.0, out=tmp_path / "v.mp4", width=64, height=48,
                         env_kwargs={"max_episode_steps": 150}, progress_bar=False)
    assert summary["episodes"] >= 3 and summary["best_progress"] > 0.0
    starts = [lines[1] for lines in labels if "t =  0.0 s" in lines[1]]
    assert len({line.split("  t")[0] for line in starts}) == summary["episodes"]
    assert all(line.endswith("progress 0%") for line in starts)
    env = gym.make("SIMS-Sit-v0", render_mode="rgb_array", width=32, height=32, text_encoder="hashing")
    env.unwrapped.set_camera(-20.0, 3.5)
    env.reset(seed=0)
    env.render()
    camera = env.unwrapped._camera.camera
    assert (camera.distance, camera.elevation) == (3.5, -20.0)
    env.close()


def _crafted_sb3_zip(path, marker):
    """An SB3-looking .zip whose ``data`` carries a pickle that creates ``marker`` when unpickled (SB3's loader
    unpickles every ":serialized:" value), and no weights."""
    import base64
    import json
    import pickle
    import zipfile

    class Payload:
        def __reduce__(self):
            return (open, (str(marker), "w"))

    serialized = {":type:": "<class 'abc.ABCMeta'>", ":serialized:": base64.b64encode(pickle.dumps(Payload())).decode()}
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("data", json.dumps({"policy_class": serialized, "observation_space": serialized}))
    return path


def test_a_crafted_sb3_zip_is_refused_without_running_its_payload(tmp_path):
    """``python -m stairenv --policy x.zip`` used to run the zip's payload, then say "cannot read ... EOFError"."""
    marker = tmp_path / "marker"
    crafted = _crafted_sb3_zip(tmp_path / "x.zip", marker)
    result = _run("--policy", str(crafted), "--seconds", "0.2", "--out", str(tmp_path / "v.mp4"), "--no-progress")
    assert result.returncode == 2, result.stderr
    assert "x.zip: not a Stable-Baselines3 model .zip: it has no 'policy.pth' member" in result.stderr
    assert not marker.exists() and not (tmp_path / "v.mp4").exists()


@pytest.fixture
def nothing_built(monkeypatch):
    """Makes building an env fail the test: the checks must come before any work."""
    import gymnasium as gym

    def refuse(*args, **kwargs):
        raise AssertionError("an env was built before the outputs were checked")

    monkeypatch.setattr(gym, "make", refuse)


@pytest.mark.parametrize(("flags", "message"), [
    (["--out", "{file}/v.mp4"], "--out '{file}/v.mp4': '{file}' is a file, so no folder can be made in it"),
    (["--out", "{file}/sub/v.mp4"], "--out '{file}/sub/v.mp4': '{file}' is a file, so no folder can be made in it"),
    (["--out", "{folder}"], "--out '{folder}': is a folder; give a file path"),
    (["--out", "/proc/stairenv-nowhere/v.mp4"], "--out '/proc/stairenv-nowhere/v.mp4': nothing can be written in "
                                                "'/proc'"),
    (["--frames-png", "{file}"], "--frames-png '{file}': is a file, not a folder"),
    (["--frames-png", "{file}/stills"], "--frames-png '{file}/stills': '{file}' is a file, so no folder can be made"),
    (["--frames-png", "/proc/stairenv-nowhere"], "--frames-png '/proc/stairenv-nowhere': nothing can be written in "
                                                 "'/proc'"),
])
def test_outputs_are_checked_before_the_film(tmp_path, capsys, nothing_built, flags, message):
    """An output that cannot be written used to cost the whole film, then an ffmpeg traceback at its end."""
    from stairenv.__main__ import main

    if "/proc" in message and not os.path.isdir("/proc/self"):
        pytest.skip("no /proc here")
    file, folder = tmp_path / "a_file", tmp_path / "film.mp4"
    file.write_text("x")
    folder.mkdir()
    names = {"file": file, "folder": folder}
    argv = [flag.format(**names) for flag in flags]
    if "--out" not in argv:
        argv += ["--out", str(tmp_path / "v.mp4")]
    with pytest.raises(SystemExit) as stop:
        main([*argv, "--policy", "zero", "--seconds", "0.2", "--no-progress"])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert message.format(**names) in err and "Traceback" not in err, err


def test_a_film_that_stops_leaves_nothing_half_written(tmp_path, monkeypatch):
    """A film that fails part-way leaves no file at --out (an older one stays as it was), no stills and no
    folder made for them; a whole film is written under its own name."""
    import stairenv.__main__ as cli

    real, calls = cli.caption_frame, []

    def failing(frame, lines, banner=None):
        calls.append(1)
        if len(calls) == 4:
            raise RuntimeError("the renderer stopped")
        return real(frame, lines, banner)

    monkeypatch.setattr(cli, "caption_frame", failing)
    out, stills = tmp_path / "new" / "v.mp4", tmp_path / "new" / "stills"
    with pytest.raises(RuntimeError, match="the renderer stopped"):
        cli.record(policy="zero", seconds=0.5, out=out, width=64, height=48, frames_png=stills, progress_bar=False)
    assert list(tmp_path.iterdir()) == []
    out.parent.mkdir()
    out.write_bytes(b"an older film")
    calls.clear()
    with pytest.raises(RuntimeError, match="the renderer stopped"):
        cli.record(policy="zero", seconds=0.5, out=out, width=64, height=48, progress_bar=False)
    assert out.read_bytes() == b"an older film" and sorted(p.name for p in out.parent.iterdir()) == ["v.mp4"]
    monkeypatch.setattr(cli, "caption_frame", real)
    summary = cli.record(policy="zero", seconds=0.5, out=out, width=64, height=48, frames_png=stills,
                         progress_bar=False)
    assert iio.imread(out).shape[0] == summary["frames"] and len(list(stills.glob("*.png"))) == 1
    assert sorted(p.name for p in out.parent.iterdir()) == ["stills", "v.mp4"]


def test_the_first_episodes_seed_is_the_envs_default_unless_given(monkeypatch):
    """InterLevel-v0's film starts on seed 3 (a climb its shipped policy ends at M_T); other envs on 0; --seed wins."""
    import stairenv.__main__ as main_module

    seeds = []
    summary = {"path": "film.mp4", "frames": 1, "fps": 30, "pngs": [], "best_progress": None, "steps": 1,
               "episodes": 1, "successes": 0, "falls": 0, "unstable": 0, "outcome": "time limit"}
    monkeypatch.setattr(main_module, "record", lambda **kwargs: seeds.append(kwargs["seed"]) or summary)
    monkeypatch.setattr(main_module, "resolve_policy", lambda policy, env_id: ("zero", None))
    for argv in ([], ["--env", "PlaMo-v0"], ["--seed", "7"]):
        main_module.main(argv)
    assert seeds == [main_module.DEFAULT_SEEDS["InterLevel-v0"], 0, 7] and seeds[0] == 3
