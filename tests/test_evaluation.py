"""stairenv.evaluation.interlevel and baselines/evaluate.py: the paper's metrics for any policy."""

from __future__ import annotations

import csv
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import stairenv  # noqa: F401  (registers the envs)
from stairenv.evaluation.cli import parse_env_kwarg
from stairenv.evaluation.interlevel import PAPER_RESULTS, ROW_FIELDS, EvaluationReport, evaluate
from stairenv.evaluation.policies import RandomPolicy, ZeroPolicy, load_policy

ROOT = Path(__file__).resolve().parents[1]
FAST = {"max_episode_steps": 40, "progress_bar": False}


def _check_group_ranges(report: EvaluationReport) -> None:
    for g in report.groups:
        assert g.n >= 1
        for value in (g.progress_pct, g.et_pct, g.success_pct, g.unstable_pct):
            assert value is not None and 0.0 <= value <= 100.0
        assert (g.time_s is None) == (g.success_pct == 0.0)
        assert g.height_min <= g.height_max


@pytest.mark.parametrize("policy", ["zero", "random"])
def test_report_fields_in_range(policy):
    report = evaluate(policy, "InterLevel-v0", episodes=3, seed=1, **FAST)
    assert report.overall.n == 3 and len(report.episodes) == 3
    assert report.groups[0].group == "all"
    # Random heights are grouped into bins whose sizes add up to the total.
    assert sum(g.n for g in report.groups[1:]) == 3
    _check_group_ranges(report)
    for e in report.episodes:
        assert 0.0 <= e.progress <= 1.0
        assert 0.05 <= e.step_height <= 0.20
        assert 1 <= e.steps <= 40
        assert e.fell or e.success or e.truncated
        assert not (e.fell and e.physics_unstable)
        assert (e.time is None) == (not e.success)
    assert [e.seed for e in report.episodes] == [1, 2, 3]
    table = report.format_table()
    for column in ("Method", "Progress (%)", "ET (%)", "Time (s)", "n", "Success (%)"):
        assert column in table
    assert policy in table


def test_fixed_step_heights_groups():
    heights = (0.05, 0.10, 0.15, 0.20)
    report = evaluate("random", episodes=2, step_heights=heights, **FAST)
    assert report.overall.n == 8
    assert [g.group for g in report.groups] == ["all", *heights]
    for h in heights:
        g = report.group(h)
        assert g.n == 2 and g.height_min == g.height_max == h
    assert all(math.isclose(e.step_height, e.fixed_height) for e in report.episodes)
    _check_group_ranges(report)
    # The published rows join the table with --compare-paper.
    table = report.format_table(compare_paper=True)
    assert "InterLevel (paper)" in table and "8.49" in table and "12.30" in table
    assert "-" in table


def test_same_seed_same_results():
    a = evaluate("random", episodes=3, seed=5, **FAST)
    b = evaluate("random", episodes=3, seed=5, **FAST)
    c = evaluate("random", episodes=3, seed=6, **FAST)
    assert a.episodes == b.episodes
    assert a.to_rows() == b.to_rows()
    assert a.episodes != c.episodes
    # A policy object reused across runs is reseeded per episode.
    policy = RandomPolicy(gym.make("InterLevel-v0").action_space)
    assert evaluate(policy, episodes=2, **FAST).episodes == evaluate(policy, episodes=2, **FAST).episodes


def test_csv_and_json(tmp_path):
    report = evaluate("zero", episodes=2, step_heights=(0.05, 0.10), **FAST)
    csv_path = report.to_csv(tmp_path / "out" / "r.csv")
    json_path = report.to_json(tmp_path / "out" / "r.json")
    with csv_path.open() as f:
        rows = list(csv.DictReader(f))
    assert tuple(rows[0]) == ROW_FIELDS
    assert [r["group"] for r in rows] == ["all", "0.05", "0.1"]
    assert all(r["method"] == "zero" and int(r["n"]) >= 2 for r in rows)
    data = json.loads(json_path.read_text())
    assert data["env_id"] == "InterLevel-v0" and data["step_heights"] == [0.05, 0.1]
    assert len(data["episodes"]) == 4
    assert data["groups"][0]["n"] == 4
    assert data["groups"] == json.loads(json.dumps(report.to_rows()))


def test_callable_policy_and_label():
    calls = []

    def still(obs):
        calls.append(obs.shape)
        return np.zeros(28)

    report = evaluate(still, episodes=1, **FAST)
    assert calls and calls[0] == (118,)
    assert report.label == "still"
    assert evaluate(still, episodes=1, label="mine", **FAST).label == "mine"


def test_bad_arguments():
    with pytest.raises(ValueError, match="episodes"):
        evaluate("zero", episodes=0)
    with pytest.raises(ValueError, match="policy"):
        evaluate("no-such-policy", episodes=1, **FAST)
    with pytest.raises(ValueError, match="env_id"):
        evaluate("zero", env_id="NoSuchEnv-v0", episodes=1)
    with pytest.raises(ValueError, match="step_heights"):
        evaluate("zero", episodes=1, step_heights=(), **FAST)
    with pytest.raises(ValueError, match="step_height_set"):
        evaluate("zero", episodes=1, step_heights=(0.1,), env_kwargs={"step_height_set": (0.1,)}, **FAST)
    env = gym.make("InterLevel-v0")
    with pytest.raises(ValueError, match="algorithm"):
        load_policy(f"NOPE:{__file__}", env)
    assert isinstance(load_policy("zero", env), ZeroPolicy)
    a = load_policy("random", env, seed=3)(None)
    assert a.shape == (28,) and np.all(np.abs(a) <= 1)
    env.close()


def test_parse_env_kwarg():
    assert parse_env_kwarg("step_height_set=(0.1, 0.2)") == ("step_height_set", (0.1, 0.2))
    assert parse_env_kwarg("pd_gains=stiff") == ("pd_gains", "stiff")
    assert parse_env_kwarg("progress_scaling=False") == ("progress_scaling", False)
    assert parse_env_kwarg("matched_starts=true") == ("matched_starts", True)    # as TOML writes it
    assert parse_env_kwarg("speed_levels_by_locomotion=FALSE") == ("speed_levels_by_locomotion", False)
    assert parse_env_kwarg("min_root_height=none") == ("min_root_height", None)
    with pytest.raises(ValueError, match="key=value"):
        parse_env_kwarg("oops")


def test_paper_results_table():
    assert len(PAPER_RESULTS) == 9
    ours = {(r["method"], r["group"]): (r["progress_pct"], r["et_pct"], r["time_s"]) for r in PAPER_RESULTS}
    assert ours[("InterLevel", "all")] == (46.8, 24.9, 8.49)
    assert ours[("InterScene", 0.10)] == (30.4, 4.6, None)


def test_sb3_model_loads_and_evaluates(tmp_path):
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    env = gym.make("InterLevel-v0", max_episode_steps=32)
    model = PPO("MlpPolicy", env, n_steps=64, batch_size=32, device="cpu", seed=0)
    model.learn(64)
    model.save(tmp_path / "model.zip")
    policy = load_policy(str(tmp_path / "model.zip"), env)
    obs, _ = env.reset(seed=0)
    action = policy(obs)
    assert action.shape == (28,) and np.all(np.abs(action) <= 1)
    report = evaluate(str(tmp_path / "model.zip"), episodes=2, **FAST)
    assert report.overall.n == 2
    # "ALGO:path" and a VecNormalize saved beside the model.
    venv = VecNormalize(DummyVecEnv([lambda: gym.make("InterLevel-v0", max_episode_steps=32)]))
    venv.reset()
    for _ in range(5):
        venv.step(np.zeros((1, 28)))
    venv.save(tmp_path / "vecnormalize.pkl")
    policy = load_policy(f"PPO:{tmp_path / 'model.zip'}", env)
    assert policy.obs_normalizer is not None and not policy.obs_normalizer.training
    assert policy(obs).shape == (28,)
    venv.close()
    env.close()


def test_cli_script(tmp_path):
    out_csv, out_json = tmp_path / "r.csv", tmp_path / "r.json"
    cmd = [
        sys.executable, str(ROOT / "baselines" / "evaluate.py"), "--policy", "random", "--episodes", "2",
        "--heights", "0.05", "0.10", "--max-episode-steps", "40", "--compare-paper", "--no-progress",
        "--csv", str(out_csv), "--json", str(out_json), "--env-kwarg", "pd_gains=stiff",
    ]
    env = {**os.environ, "MUJOCO_GL": "egl"}
    result = subprocess.run(cmd, capture_output=True, text=True, timeout=120, env=env)
    assert result.returncode == 0, result.stderr
    assert "Progress (%)" in result.stdout and "ET (%)" in result.stdout
    assert "InterScene (paper)" in result.stdout and "random" in result.stdout
    assert out_csv.stat().st_size > 0
    assert json.loads(out_json.read_text())["env_kwargs"] == {"pd_gains": "stiff"}
    bad = subprocess.run(cmd[:2] + ["--policy", "nope", "--episodes", "2"], capture_output=True, text=True,
                         timeout=120, env=env)
    assert bad.returncode == 2 and "policy must be one of" in bad.stderr


class _ScriptedEnv(gym.Env):
    """A stand-in with the InterLevel info keys: climbs 0.1 per step, then ends as scripted."""

    observation_space = gym.spaces.Box(-np.inf, np.inf, (118,), np.float64)
    action_space = gym.spaces.Box(-1.0, 1.0, (28,), np.float32)

    def __init__(self, ending: str = "timeout", step_height_set=None) -> None:
        self.ending = ending

    def _info(self, progress=0.0, **flags):
        info = {"progress": progress, "success": False, "fell": False, "time": self.t / 30,
                "physics_unstable": False, "stairs": {"step_height": 0.1}}
        info.update(flags)
        return info

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self.t = 0
        return np.zeros(118), self._info()

    def step(self, action):
        self.t += 1
        progress = min(0.1 * self.t, 0.6)
        if self.ending == "unstable" and self.t == 5:
            return np.zeros(118), 0.0, False, True, self._info(0.0, physics_unstable=True)
        if self.ending == "fall" and self.t == 5:
            return np.zeros(118), -1.0, True, False, self._info(progress, fell=True)
        if self.ending == "success" and self.t == 9:
            return np.zeros(118), 10.0, True, False, self._info(1.0, success=True)
        return np.zeros(118), 0.0, False, False, self._info(progress)


gym.register("StairenvScripted-v0", entry_point=_ScriptedEnv, max_episode_steps=7)


@pytest.mark.parametrize(
    ("ending", "progress", "fell", "success", "time", "unstable", "steps"),
    [
        ("timeout", 0.6, False, False, None, False, 7),   # truncated by the TimeLimit
        ("fall", 0.5, True, False, None, False, 5),
        ("unstable", 0.4, False, False, None, True, 5),   # progress before the blow-up; not ET
        ("success", 1.0, False, True, 0.3, False, 9),
    ],
)
def test_episode_endings(ending, progress, fell, success, time, unstable, steps):
    report = evaluate("zero", "StairenvScripted-v0", episodes=2, env_kwargs={"ending": ending},
                      max_episode_steps=None if ending != "success" else 20, progress_bar=False)
    e = report.episodes[0]
    assert (e.fell, e.success, e.physics_unstable, e.steps) == (fell, success, unstable, steps)
    assert math.isclose(e.progress, progress)
    assert e.time == pytest.approx(time) if time is not None else e.time is None
    g = report.overall
    assert g.et_pct == (100.0 if fell else 0.0)
    assert g.unstable_pct == (100.0 if unstable else 0.0)
    assert g.time_s == (pytest.approx(time) if time is not None else None)
    assert "-" in report.format_table() or success


def _elementwise_policy(obs):
    """A batch-capable policy computed element by element, so batch and single calls round alike."""
    return np.tanh(0.02 * np.asarray(obs)[..., 90:118])


@pytest.mark.parametrize("gait", [False, True])
def test_batched_evaluation_equals_sequential(gait):
    # 5 episodes per height on 3 worlds: worlds take new episodes as theirs end, and one stays idle at the end
    kwargs = dict(episodes=5, seed=11, step_heights=(0.05, 0.20), progress_bar=False, max_episode_steps=80, gait=gait)
    one = evaluate(_elementwise_policy, **kwargs)
    batched = evaluate(_elementwise_policy, num_envs=3, **kwargs)
    assert batched.details == one.details
    assert batched.rows == one.rows
    assert [e.index for e in batched.details] == [0, 1, 2, 3, 4] * 2
    assert batched.meta["num_envs"] == 3 and one.meta["num_envs"] == 1
    # episodes that end at different times are what makes the hand-over between worlds matter
    assert len({e.steps for e in one.details}) > 3


def test_batched_evaluation_of_single_observation_policies():
    calls = []

    def single(obs):    # takes one observation only: called row by row
        calls.append(np.shape(obs))
        return np.zeros(28) if np.ndim(obs) == 1 else np.zeros(5)

    report = evaluate(single, episodes=3, num_envs=2, **FAST)
    assert report.overall.n == 3 and (118,) in calls
    # a policy that reseeds itself per episode runs one episode at a time, as sequential as ever
    random_one = evaluate("random", episodes=3, seed=4, **FAST)
    random_batched = evaluate("random", episodes=3, seed=4, num_envs=2, **FAST)
    assert random_batched.details == random_one.details and random_batched.meta["num_envs"] == 1
    for bad in (0, -1, 2.5, True):
        with pytest.raises(ValueError, match="num_envs"):
            evaluate("zero", episodes=1, num_envs=bad, **FAST)


def test_push_plan_and_kick():
    from stairenv.evaluation.interlevel import PUSH_STEPS, apply_push, push_plan

    assert push_plan(3, 0.0) is None
    plans = [push_plan(seed, 1.0) for seed in range(200)]
    assert plans == [push_plan(seed, 1.5) for seed in range(200)]  # the same step and direction at every speed
    assert all(PUSH_STEPS[0] <= step < PUSH_STEPS[1] and -math.pi <= angle <= math.pi for step, angle in plans)
    assert len({step for step, _ in plans}) > 50
    env = gym.make("InterLevel-v0").unwrapped
    env.reset(seed=0)
    before = env.data.qvel.copy()
    apply_push(env.model, env.data, 1.5, math.pi / 2)
    change = env.data.qvel - before
    np.testing.assert_allclose(change[:3], [0.0, 1.5, 0.0], atol=1e-12)  # the root's world-frame velocity
    assert not change[3:].any()


def test_pushes_come_the_same_way_sequentially_and_batched():
    kwargs = dict(episodes=4, seed=0, progress_bar=False, max_episode_steps=PUSH_TEST_STEPS)
    from stairenv.pretrained import shipped_policy_path

    policy = str(shipped_policy_path("InterLevel-v0"))  # stays up long enough for the pushes to come
    calm = evaluate(policy, **kwargs)
    pushed = evaluate(policy, push_speed=3.0, **kwargs)
    batched = evaluate(policy, push_speed=3.0, num_envs=2, **kwargs)
    assert [(e.push_step, e.push_angle) for e in batched.details] == [(e.push_step, e.push_angle)
                                                                       for e in pushed.details]
    came = [e for e in pushed.details if e.push_step is not None]
    assert pushed.meta["push_speed"] == 3.0 and pushed.meta["pushed"] == len(came) >= 2
    assert all(e.push_step is None for e in calm.details) and "push_speed" not in calm.meta
    assert sum(e.fell for e in pushed.details) > sum(e.fell for e in calm.details)  # 3 m/s topples it
    with pytest.raises(ValueError, match="push_speed"):
        evaluate("zero", episodes=1, push_speed=-1.0, progress_bar=False)
    with pytest.raises(ValueError, match="push_speed"):
        evaluate("zero", episodes=1, push_speed=float("nan"), progress_bar=False)


PUSH_TEST_STEPS = 200
