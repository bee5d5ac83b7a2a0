"""stairenv.evaluation.pushes: one seeded kick per episode, for the PlaMo Table 2 and SIMS skills evaluations
(and InterLevel's, whose tests are in test_evaluation.py), and the scripts' ``--push-speed``."""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import stairenv  # noqa: F401  (registers the envs)
from stairenv.evaluation import pushes
from stairenv.evaluation.pushes import PUSH_STEPS, EpisodePush, push_plan

#: episode SEED is pushed before its step 31 (``push_plan``); episode SEED + 1's push would come before
#: step 84, after the LIMIT-step episode has ended: it gets none
SEED, LIMIT, SPEED = 82, 34, 1.0
BASELINES = Path(__file__).resolve().parents[1] / "baselines"


def test_the_push_plan_of_the_test_episodes():
    assert push_plan(SEED, SPEED)[0] == 31 and push_plan(SEED + 1, SPEED)[0] == 84 > LIMIT
    assert PUSH_STEPS[0] <= 31 < PUSH_STEPS[1]


def test_the_push_machinery_keeps_its_old_home():
    from stairenv.evaluation import interlevel

    assert interlevel.push_plan is pushes.push_plan and interlevel.apply_push is pushes.apply_push
    assert interlevel.PUSH_STEPS is pushes.PUSH_STEPS and interlevel.PUSH_STREAM == pushes.PUSH_STREAM


def test_an_episode_push_comes_once_at_its_step_and_never_without_a_speed():
    class Env:  # what EpisodePush touches: the model and data apply_push writes
        def __init__(self):
            inner = gym.make("PlaMo-v0").unwrapped
            self.model, self.data = inner.model, inner.data

    env = Env()
    step, angle = push_plan(SEED, 2.0)
    push = EpisodePush(SEED, 2.0)
    came = [push.before_step(env, k) for k in range(200)]
    assert came.count(True) == 1 and came.index(True) == step
    assert (push.step, push.angle) == (step, angle)
    calm = EpisodePush(SEED, 0.0)
    assert not any(calm.before_step(env, k) for k in range(200)) and (calm.step, calm.angle) == (None, None)
    late = EpisodePush(SEED, 2.0)  # an episode that ended before its push step
    assert not any(late.before_step(env, k) for k in range(step)) and late.step is None
    for bad in (-0.5, 10.5, float("nan"), True, "1"):
        with pytest.raises(ValueError, match="push_speed"):
            pushes.check_push_speed(bad)


class _Recorder:
    """The shipped policy of ``env_id``, recording the root's velocity (``qvel``, read from the env the
    evaluator made last) at every call: a call comes after the push that precedes its step."""

    def __init__(self, env_id: str, made: list) -> None:
        from stairenv.pretrained import load

        self.policy, self.made, self.qvel = load(env_id), made, []

    def __call__(self, obs):
        self.qvel.append(self.made[-1].unwrapped.data.qvel.copy())
        return self.policy(obs)


def _pushed_and_calm(monkeypatch, env_id: str, run):
    """``run(policy, push_speed)`` of the shipped policy with no push, push_speed 0 and SPEED: each run's
    report, its recorded velocities and the pushes ``apply_push`` gave."""
    made, applied = [], []
    real_make, real_apply = gym.make, pushes.apply_push
    outcomes = {}
    for speed in (None, 0.0, SPEED):
        recorder = _Recorder(env_id, made)  # loaded (its own gym.make) before the evaluator's envs are recorded
        monkeypatch.setattr(gym, "make", lambda *a, **k: made.append(real_make(*a, **k)) or made[-1])
        monkeypatch.setattr(pushes, "apply_push", lambda *a: applied.append(a[2:]) or real_apply(*a))
        del applied[:]
        report = run(recorder, speed)
        monkeypatch.setattr(gym, "make", real_make)
        outcomes[speed] = report, recorder.qvel, list(applied)
    return outcomes


def _check(outcomes, details_of, settings_of):
    (none, none_qvel, none_applied), (zero, zero_qvel, zero_applied), (pushed, qvel, applied) = (
        outcomes[None], outcomes[0.0], outcomes[SPEED])
    # the default changes nothing: push_speed 0 is no push at all, and no push is the evaluation as before
    assert zero.rows == none.rows and details_of(zero) == details_of(none)
    assert none_applied == zero_applied == [] and all(e.push_step is None for e in details_of(none))
    assert "push_speed" not in settings_of(none) and "pushed" not in settings_of(zero)
    for a, b in zip(zero_qvel, none_qvel, strict=True):
        np.testing.assert_array_equal(a, b)
    calm, calm_qvel = details_of(none), none_qvel
    # one push, in the first episode, at its planned step and in its planned direction
    step, angle = push_plan(SEED, SPEED)
    first, second = details_of(pushed)
    assert applied == [(SPEED, angle)]
    assert (first.push_step, first.push_angle) == (step, angle) and first.steps > step
    assert (second.push_step, second.push_angle) == (None, None)
    assert second.steps <= LIMIT < push_plan(SEED + 1, SPEED)[0]
    assert settings_of(pushed)["push_speed"] == SPEED and settings_of(pushed)["pushed"] == 1
    assert settings_of(pushed)["push_steps"] == list(PUSH_STEPS)
    for k in range(step):  # before the push: the very same episode as without
        np.testing.assert_array_equal(qvel[k], calm_qvel[k])
    change = qvel[step] - calm_qvel[step]
    kick = [SPEED * math.cos(angle), SPEED * math.sin(angle)]  # by hand: the root's x and y velocity
    np.testing.assert_allclose(change[:2], kick, rtol=0, atol=1e-12)
    assert not change[2:].any()  # nothing else: not its height, not its spin, not a joint
    # the episode whose push did not come (it ended first) is the same episode as without pushes
    n = calm[0].steps
    assert second == calm[1] and len(qvel) - first.steps == len(calm_qvel) - n
    for a, b in zip(qvel[first.steps:], calm_qvel[n:], strict=True):
        np.testing.assert_array_equal(a, b)


def test_plamo_tracking_pushes(monkeypatch):
    from stairenv.evaluation.plamo import TrackingEpisode, evaluate

    def run(policy, speed):
        keywords = {} if speed is None else {"push_speed": speed}
        return evaluate(policy, "PlaMo-v0", episodes=2, seed=SEED, max_episode_steps=LIMIT, terrains=("flat",),
                        locomotions=("walk",), **keywords)

    outcomes = _pushed_and_calm(monkeypatch, "PlaMo-v0", run)
    _check(outcomes, lambda r: r.details, lambda r: r.meta["settings"])
    report = outcomes[SPEED][0]
    assert all(isinstance(e, TrackingEpisode) for e in report.details)
    assert [(e.terrain, e.locomotion, e.index, e.seed) for e in report.details] == [
        ("flat", "walk", 0, SEED), ("flat", "walk", 1, SEED + 1)]
    row = report.rows[0]
    assert row["early_termination_pct"] == 100.0 * sum(e.terminated for e in report.details) / 2
    assert all(e.terminated == (e.fell or e.off_path) for e in report.details)


def test_sims_skill_pushes(monkeypatch):
    from stairenv.evaluation.sims import evaluate_skills

    def run(policy, speed):
        keywords = {} if speed is None else {"push_speed": speed}
        return evaluate_skills({"walk": policy}, skills=("walk",), episodes=2, seed=SEED, max_episode_steps=LIMIT,
                               **keywords)

    outcomes = _pushed_and_calm(monkeypatch, "SIMS-Walk-v0", run)
    _check(outcomes, lambda r: r.details, lambda r: r.meta["settings"])


def _script(name: str):
    spec = importlib.util.spec_from_file_location(name, BASELINES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_plamo_script_pushes(capsys, tmp_path):
    import json

    plamo = _script("evaluate_plamo")
    plamo.main(["--policy", "zero", "--episodes", "2", "--seed", str(SEED), "--terrains", "flat", "--locomotions",
                "walk", "--max-episode-steps", str(LIMIT), "--push-speed", "1.5", "--json", str(tmp_path / "p.json")])
    out = capsys.readouterr().out
    saved = json.loads((tmp_path / "p.json").read_text())
    assert saved["settings"]["push_speed"] == 1.5 and len(saved["details"]) == 2
    assert f"pushes: 1.5 m/s, {saved['settings']['pushed']} of 2 episodes pushed" in out
    assert "end" in " ".join(plamo.__doc__.split()) and "--push-speed" in plamo.__doc__
    with pytest.raises(SystemExit):
        plamo.main(["--policy", "zero", "--episodes", "1", "--push-speed", "-1"])
    assert "push_speed" in capsys.readouterr().err


def test_sims_script_pushes(capsys):
    sims = _script("evaluate_sims")
    help_text = " ".join(sims.build_parser().format_help().split())
    assert "--push-speed" in help_text and "ends before its push step gets none" in help_text
    with pytest.raises(SystemExit):  # Table 2's scripts are not pushed: asked for, it says so
        sims.main(["--policy", "zero", "--push-speed", "1.0"])
    assert "--tables skills" in capsys.readouterr().err
    sims.main(["--walk", "zero", "--tables", "skills", "--skills", "walk", "--episodes", "2", "--seed", str(SEED),
               "--max-episode-steps", str(LIMIT), "--push-speed", "1.0", "--no-progress",
               "--text-encoder", "hashing"])
    assert "pushes: 1 m/s" in capsys.readouterr().out
