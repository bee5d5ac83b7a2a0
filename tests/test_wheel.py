"""A built wheel carries the MJCF assets and presets, and works installed outside the repo."""

from __future__ import annotations

import os
import subprocess
import sys
import sysconfig
import venv
import zipfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_wheel_installs_and_makes_env(tmp_path):
    dist = tmp_path / "dist"
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--quiet", "-w", str(dist), str(REPO)],
        check=True,
    )
    (wheel,) = dist.glob("stairenv-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    assert "stairenv/xml/humanoid.xml" in names
    assert "stairenv/screenplays/data/happy.json" in names  # SIMS script database
    assert "stairenv/scripts.py" in names  # its old name, a deprecated alias for one release
    presets = {n for n in names if n.startswith("stairenv/envs/") and n.endswith(".toml")}
    assert {"stairenv/envs/InterLevel-v0.toml", "stairenv/envs/InterLevel2D-v0.toml"} <= presets
    assert "stairenv/policies/InterLevel-v0.npz" in names  # the shipped climbing policy
    assert {"stairenv/policies/PlaMo-v0.npz", "stairenv/policies/SIMS-Walk-v0.npz"} <= set(names)  # interim ones
    assert "stairenv/motion/data/plamo/NOTICE.txt" in names  # builtin:plamo's clips and their notice
    assert len([n for n in names if n.startswith("stairenv/motion/data/plamo/") and n.endswith(".npz")]) >= 12

    # A fresh venv that borrows the dependencies from this one (a .pth path line, which
    # does not run this venv's own .pth files, so the editable stairenv stays out)
    # and gets stairenv only from the wheel.
    env_dir = tmp_path / "venv"
    venv.create(env_dir, with_pip=True)
    python = env_dir / "bin" / "python"
    new_site = subprocess.run(
        [str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        check=True, capture_output=True, text=True,
    ).stdout.strip()
    borrowed = {sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]}
    Path(new_site, "borrowed-deps.pth").write_text("\n".join(sorted(borrowed)) + "\n")
    subprocess.run([str(python), "-m", "pip", "install", "--quiet", "--no-deps", str(wheel)], check=True)
    script = (
        "import pathlib, gymnasium as gym, stairenv\n"
        "from stairenv.assets import asset_dir\n"
        "print(pathlib.Path(stairenv.__file__).resolve())\n"
        "print(asset_dir('xml').resolve())\n"
        "env = gym.make('InterLevel-v0')\n"
        "print(env.reset(seed=0)[0].shape)\n"
        "print(sorted(stairenv.ENV_IDS))\n"
        "from stairenv.pretrained import load\n"
        "print(load('InterLevel-v0').action_size)\n"
        "print(load('PlaMoScene-v0').config['env_id'])\n"
    )
    clean_env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    out = subprocess.run(
        [str(python), "-c", script], cwd=tmp_path, env=clean_env, check=True, capture_output=True, text=True
    ).stdout.splitlines()
    site = str(env_dir.resolve())
    assert out[0].startswith(site), f"stairenv imported from {out[0]}, not the wheel in {site}"
    assert out[1].startswith(site)
    assert out[2] == "(118,)"
    assert "InterLevel-v0" in out[3] and "InterSceneStairs-v0" in out[3]
    assert out[4] == "28"  # the shipped policy loads from the installed wheel
    assert out[5] == "PlaMo-v0"  # an id runs the policy its installed preset names
