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


def test_bad_arguments(tmp_path):
    result = _run("--policy", "nope", "--out", str(tmp_path / "v.mp4"))
    assert result.returncode == 2 and "policy must be one of" in result.stderr
    result = _run("--seconds", "0", "--out", str(tmp_path / "v.mp4"))
    assert result.returncode == 2 and "seconds" in result.stderr
