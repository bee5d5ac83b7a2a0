"""The filmstrip scripts render the synthesised reference motion (offscreen, EGL)."""

from __future__ import annotations

import imageio.v3 as iio
import numpy as np
import pytest


@pytest.mark.parametrize("extra", [[], ["--walk-style", "tired"]], ids=["climb", "styled-walk"])
def test_synthesis_filmstrip(tmp_path, extra, baseline_script):
    out = tmp_path / "strip.png"
    assert baseline_script("filmstrip_synthesis").main(["--frames", "3", "--width", "64", "--height", "96",
                                                "--out", str(out), *extra]) == 0
    image = iio.imread(out)
    assert image.shape == (96, 3 * 64 + 2 * 4, 3)
    frames = [image[:, k * 68:k * 68 + 64] for k in range(3)]
    assert all(frame.std() > 5 for frame in frames)  # something is drawn in every frame
    assert not np.array_equal(frames[0], frames[2])  # and it moves


def test_interactions_filmstrip(tmp_path, baseline_script):
    out = tmp_path / "strip.png"
    assert baseline_script("filmstrip_interactions").main(["--clips", "sit_down", "--frames", "2", "--width", "64",
                                                   "--height-px", "96", "--out", str(out)]) == 0
    image = iio.imread(out)
    assert image.shape[0] >= 96 and image.shape[2] == 3 and image.std() > 5


def test_plamo_filmstrip(tmp_path, baseline_script):
    out = tmp_path / "plamo.png"
    assert baseline_script("filmstrip_plamo").main(["--clips", "dm_walk", "crouch_walk_1.0mps", "--frames", "2",
                                                    "--width", "64", "--height", "80", "--combined", str(out)]) == 0
    image = iio.imread(out)
    assert image.shape[0] == 2 * (80 + 16) + 4 and image.std() > 5


def test_tracking_filmstrip(tmp_path, baseline_script):
    out = tmp_path / "tracking.png"
    assert baseline_script("filmstrip_tracking").main(["--policy", "zero", "--locomotions", "walk", "crawl",
                                                       "--frames", "2", "--every", "1000", "--width", "64",
                                                       "--height", "64", "--combined", str(out)]) == 0
    image = iio.imread(out)
    assert image.shape[0] > 2 * 64 and image.std() > 5  # two strips, something drawn


def test_sims_filmstrip(tmp_path, baseline_script, capsys):
    """One strip per seed; ``--level`` starts the front curriculum at that level (a zero policy stands
    by the seat and does not sit: no success in its caption)."""
    out = tmp_path / "sims.png"
    assert baseline_script("filmstrip_sims").main(["--policy", "zero", "--seeds", "0", "1", "--frames", "3",
                                                   "--every", "20", "--width", "64", "--height", "64",
                                                   "--env-kwarg", "start_from_front=True",
                                                   "--env-kwarg", "start_distance_levels=10", "--level", "0",
                                                   "--combined", str(out)]) == 0
    image = iio.imread(out)
    assert image.shape[0] > 2 * 64 and image.std() > 5  # two strips, something drawn
    lines = [line for line in capsys.readouterr().out.splitlines() if line.startswith("seed ")]
    assert len(lines) == 2 and not any("succeeded" in line for line in lines)
    assert baseline_script("filmstrip_sims").main(["--policy", "zero", "--level", "0", "--combined", str(out)]) == 2


def test_sims_filmstrip_names_the_aids_endings(baseline_script):
    """A run with the grounded or stall aid ends so, and its caption says which, not 'time limit'."""
    ending_of = baseline_script("filmstrip_sims").ending_of
    assert ending_of({"grounded": True, "fell": False}) == "grounded"
    assert ending_of({"stalled": True}) == "stalled"
    assert ending_of({"fell": True, "grounded": False}) == "fell"
    assert ending_of({"success": True}) == "succeeded"
    assert ending_of({"grounded": False, "stalled": False}) == "time limit"


def test_sims_filmstrip_policy_captions(tmp_path, baseline_script, monkeypatch):
    """--policy-captions: the env is made again with the captions the policy recorded from its training."""
    import gymnasium as gym
    import numpy as np

    from stairenv.pretrained import NumpyPolicy

    size = gym.make("SIMS-Walk-v0", text_encoder="hashing").observation_space.shape[0]
    path = tmp_path / "walk.npz"
    NumpyPolicy([np.zeros((28, size))], [np.zeros(28)], np.zeros(size), np.ones(size),
                config={"training": {"env_kwargs": {"captions": [["sad", "walks slowly to the bed"]]}}}).save(path)
    module = baseline_script("filmstrip_sims")
    made, make = [], module.gym.make
    monkeypatch.setattr(module.gym, "make", lambda *args, **kwargs: (made.append(kwargs), make(*args, **kwargs))[1])
    assert module.main(["--env", "SIMS-Walk-v0", "--policy", str(path), "--policy-captions", "--seeds", "0",
                        "--frames", "2", "--every", "50", "--width", "48", "--height", "48",
                        "--env-kwarg", "text_encoder=hashing", "--combined", str(tmp_path / "walk.png")]) == 0
    assert "captions" not in made[0] and made[-1]["captions"] == (("sad", "walks slowly to the bed"),)
