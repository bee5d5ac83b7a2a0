"""stairenv.evaluation.sims and baselines/evaluate_sims.py: SIMS Tables 1 and 2 for any policy."""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from stairenv.evaluation.sims import (
    PAPER_RESULTS,
    ROW_FIELDS,
    ScriptRun,
    SkillEpisode,
    evaluate_scripts,
    evaluate_skills,
    merge_paper_rows,
    write_reports,
)
from stairenv.stories import MachineSettings

HASHING = {"text_encoder": "hashing"}
SCRIPT = Path(__file__).resolve().parents[1] / "baselines" / "evaluate_sims.py"


def test_skill_rows_have_the_table_columns():
    report = evaluate_skills("zero", skills=("sit", "getup"), episodes=2, env_kwargs=HASHING, max_episode_steps=30)
    assert [r["group"] for r in report.rows] == ["sit", "getup"]
    for row in report.rows:
        assert tuple(row) == ROW_FIELDS and row["table"] == "skills" and row["method"] == "zero" and row["n"] == 2
        assert 0.0 <= row["success_pct"] <= 100.0 and 0.0 <= row["fell_pct"] <= 100.0
        assert 0.0 <= row["min_contact_error_m"] <= row["contact_error_m"] + 1e-12
    assert len(report.details) == 4 and all(isinstance(e, SkillEpisode) for e in report.details)
    assert [e.seed for e in report.details] == [0, 1, 0, 1]
    assert all(e.steps <= 30 for e in report.details)


def test_kinematic_stand_in_passes_every_skill():
    report = evaluate_skills({"sit": "kinematic", "reach": "kinematic"}, skills=("sit", "reach"), episodes=2,
                             env_kwargs=HASHING)
    assert [r["success_pct"] for r in report.rows] == [100.0, 100.0]
    assert all(r["contact_error_m"] < 0.2 for r in report.rows)
    assert "NOT physics-based" in report.label


def test_script_rows_by_difficulty():
    report = evaluate_scripts("kinematic", difficulties=("simple", "mid"), scripts_per_difficulty=1,
                              settings=MachineSettings(dwell_seconds=0.3), env_kwargs=HASHING)
    assert [r["group"] for r in report.rows] == ["simple", "mid", "all"]
    assert all(tuple(r) == ROW_FIELDS and r["table"] == "scripts" for r in report.rows)
    runs = report.details
    assert [r.difficulty for r in runs] == ["simple", "mid"] and all(isinstance(r, ScriptRun) for r in runs)
    assert all(r.success and r.interactions_succeeded == r.interactions for r in runs)
    assert report.rows[-1]["n"] == 2 and report.rows[-1]["success_pct"] == 100.0
    assert report.rows[0]["success_steps"] == runs[0].interactions

    failing = evaluate_scripts("zero", difficulties=("simple",), scripts_per_difficulty=1,
                               settings=MachineSettings(dwell_seconds=0.3, max_seconds=1.0), env_kwargs=HASHING)
    run = failing.details[0]
    assert not run.success and run.outcomes[0] in ("fell", "timeout") and set(run.outcomes[1:]) == {"skipped"}
    assert failing.rows[0]["success_pct"] == 0.0 and failing.rows[0]["success_steps"] == 0.0


def test_paper_comparison_and_files(tmp_path):
    report = evaluate_skills("zero", skills=("lie",), episodes=1, env_kwargs=HASHING, max_episode_steps=10)
    merged = merge_paper_rows(report.rows)
    assert merged[0]["method"] == "SIMS (paper)" and merged[0]["success_pct"] == 79.2
    table = report.format_table(compare_paper=True)
    assert "SIMS (paper)" in table and "79.2" in table and "0.089" in table
    assert PAPER_RESULTS["scripts"]["hard"]["success_pct"] == 31.5
    paths = write_reports([report], tmp_path / "rows.csv", tmp_path / "rows.json")
    with paths[0].open() as f:
        rows = list(csv.DictReader(f))
    assert tuple(rows[0]) == ROW_FIELDS and rows[0]["group"] == "lie"
    data = json.loads(paths[1].read_text())
    assert data[0]["table"] == "skills" and data[0]["details"][0]["skill"] == "lie"


def test_bad_arguments():
    with pytest.raises(ValueError, match="episodes"):
        evaluate_skills("zero", episodes=0)
    with pytest.raises(ValueError, match="skills must be among"):
        evaluate_skills("zero", skills=("fly",), episodes=1)
    with pytest.raises(ValueError, match=r"no policy for skill\(s\) \['lie'\]"):
        evaluate_skills({"sit": "zero"}, skills=("sit", "lie"), episodes=1)
    with pytest.raises(ValueError, match="difficulties"):
        evaluate_scripts("zero", difficulties=("extreme",))


def test_cli_script(tmp_path):
    env = {**os.environ, "MUJOCO_GL": "egl"}
    cmd = [sys.executable, str(SCRIPT), "--policy", "zero", "--walk", "kinematic", "--skills", "sit",
           "--episodes", "1", "--max-episode-steps", "20", "--difficulties", "simple", "--scripts-per-difficulty",
           "1", "--max-seconds", "1", "--dwell", "0.3", "--text-encoder", "hashing", "--compare-paper",
           "--no-progress", "--csv", str(tmp_path / "out.csv"), "--json", str(tmp_path / "out.json")]
    done = subprocess.run(cmd, check=False, capture_output=True, text=True, timeout=300, env=env)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "SIMS (paper)" in done.stdout and "74.3" in done.stdout and "NOT physics-based" in done.stdout
    with (tmp_path / "out.csv").open() as f:
        groups = [(r["table"], r["group"]) for r in csv.DictReader(f)]
    assert groups == [("skills", "sit"), ("scripts", "simple"), ("scripts", "all")]
    bad = subprocess.run([sys.executable, str(SCRIPT), "--tables", "skills", "--skills", "sit"],
                         check=False, capture_output=True, text=True, timeout=300, env=env)
    assert bad.returncode != 0 and "no policy" in bad.stderr


def test_policy_captions_draws_the_captions_the_policy_trained_on(tmp_path):
    """policy_captions: a policy that recorded its training captions is evaluated on them (the env's text
    slice holds their embeddings), the settings say which; without the flag the env draws its own."""
    import gymnasium as gym
    import numpy as np

    from stairenv.pretrained import NumpyPolicy, PolicyFileError, trained_captions, with_trained_captions

    env = gym.make("SIMS-Walk-v0", **HASHING).unwrapped
    text = env.observation_structure["text"]
    size = env.observation_space.shape[0]
    trained = [["sad", "walks slowly to the bed"]]

    class Watching(NumpyPolicy):
        texts: list = []

        def __call__(self, obs):
            Watching.texts.append(np.asarray(obs)[text].copy())
            return super().__call__(obs)

    policy = Watching([np.zeros((28, size))], [np.zeros(28)], np.zeros(size), np.ones(size),
                      config={"training": {"env_kwargs": {"captions": trained}}})
    assert trained_captions(policy) == (("sad", "walks slowly to the bed"),)
    given = {"captions": [("happy", "skips")]}
    assert with_trained_captions(given, policy) is given
    assert with_trained_captions({}, policy)["captions"] == (("sad", "walks slowly to the bed"),)
    report = evaluate_skills({"walk": policy}, skills=("walk",), episodes=3, env_kwargs=HASHING, max_episode_steps=3,
                             policy_captions=True)
    assert report.meta["settings"]["policy_captions"] == {"walk": trained}
    expected = env.embed_text("walks slowly to the bed")
    assert len(Watching.texts) == 9 and all(np.allclose(z, expected, atol=1e-6) for z in Watching.texts)
    Watching.texts.clear()
    evaluate_skills({"walk": policy}, skills=("walk",), episodes=3, env_kwargs=HASHING, max_episode_steps=3)
    assert not all(np.allclose(z, expected, atol=1e-6) for z in Watching.texts)
    for odd in ({"training": {"env_kwargs": "captions"}}, {"training": ["env_kwargs"]}):  # no record: the env's
        policy.config = odd
        assert trained_captions(policy) is None
    policy.config = {"training": {"env_kwargs": {"captions": [["sad"]]}}}
    with pytest.raises(PolicyFileError, match="captions"):
        trained_captions(policy)
