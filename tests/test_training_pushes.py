"""Training pushes (``push_speed``, ``push_interval``): a training aid of every family that kicks the root's
horizontal velocity now and then, so that a policy learns to recover; dropped by the final evaluation."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import stairenv  # noqa: F401  (registers the ids)
import stairenv.environments.base as base
from stairenv.environments.base import HumanoidEnv

IDS = ["InterLevel-v0", "PlaMo-v0", "SIMS-Walk-v0"]
SPEED, INTERVAL = (0.8, 1.2), (0.1, 0.2)     # 3-6 steps apart at 30 Hz: kicks before a zero action's fall


def record_pushes(monkeypatch, env):
    """The kicks ``env`` gives: (step, speed, angle, root velocity before, after)."""
    calls = []
    push_root = base.push_root

    def recording(model, data, speed, angle):
        before = data.qvel[:3].copy()
        push_root(model, data, speed, angle)
        calls.append((env.unwrapped._steps, speed, angle, before, data.qvel[:3].copy()))

    monkeypatch.setattr(base, "push_root", recording)
    return calls


def run(env, seed, steps=25):
    obs, _ = env.reset(seed=seed)
    observations = [obs]
    for _ in range(steps):
        obs, _, terminated, truncated, _ = env.step(np.zeros(env.action_space.shape))
        observations.append(obs)
        if terminated or truncated:
            break
    return observations


@pytest.mark.parametrize("env_id", IDS)
def test_pushes_kick_the_root_by_a_drawn_speed_at_drawn_intervals(monkeypatch, env_id):
    env = gym.make(env_id, push_speed=SPEED, push_interval=INTERVAL)
    calls = record_pushes(monkeypatch, env)
    observations = run(env, seed=3)
    assert len(calls) >= 2, "a kick every 3-6 steps: several before the episode ends"
    steps = [step for step, *_ in calls]
    assert 3 <= steps[0] <= 6 and all(3 <= b - a <= 6 for a, b in zip(steps, steps[1:]))
    for _, speed, angle, before, after in calls:
        assert SPEED[0] <= speed <= SPEED[1] and -math.pi <= angle <= math.pi
        np.testing.assert_allclose(after - before, [speed * math.cos(angle), speed * math.sin(angle), 0.0],
                                   atol=1e-12)
    # the same seed meets the same kicks, and the steps before the first are those of an env without them
    calls.clear()
    again = run(env, seed=3)
    assert [c[0] for c in calls] == steps
    assert len(again) == len(observations) and all(np.array_equal(a, b) for a, b in zip(again, observations))
    plain = run(gym.make(env_id), seed=3)
    first = steps[0]
    assert all(np.array_equal(a, b) for a, b in zip(plain[:first + 1], observations[:first + 1]))
    assert not np.array_equal(plain[first + 1], observations[first + 1]), "the kick changes the next step"


def test_without_the_aid_nothing_is_kicked(monkeypatch):
    env = gym.make("SIMS-Walk-v0")
    calls = record_pushes(monkeypatch, env)
    run(env, seed=0)
    assert calls == [] and env.unwrapped._push_speed is None


@pytest.mark.parametrize("env_id", ["InterLevel-v0", "SIMS-Walk-v0"])
def test_a_batched_env_pushes_each_world_as_its_single_env(env_id):
    n, kwargs = 2, dict(push_speed=SPEED, push_interval=INTERVAL, max_episode_steps=30)
    vec = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)
    ref = gym.make_vec(env_id, num_envs=n, vectorization_mode="sync", **kwargs)
    got, want = vec.reset(seed=5), ref.reset(seed=5)
    np.testing.assert_array_equal(got[0], want[0])
    rng = np.random.default_rng(2)
    for _ in range(60):
        action = rng.uniform(-0.3, 0.3, (n, 28))
        got, want = vec.step(action), ref.step(action)
        for a, b in zip(got[:4], want[:4]):
            np.testing.assert_array_equal(a, b)
    vec.close()
    ref.close()


@pytest.mark.parametrize("keyword, value, match", [
    ("push_speed", (1.0, 0.5), "push_speed"), ("push_speed", (-1.0, 1.0), "push_speed"),
    ("push_speed", "fast", "push_speed"), ("push_speed", (1.0, 11.0), "push_speed"),
    ("push_interval", (0.0, 1.0), "push_interval"), ("push_interval", (2.0, 1.0), "push_interval"),
])
def test_bad_push_keywords_are_refused_by_name(keyword, value, match):
    with pytest.raises((TypeError, ValueError), match=match):
        gym.make("InterLevel-v0", **{keyword: value})


def test_pushed_worlds_cannot_keep_their_state_on_the_device():
    pushed = gym.make("InterLevel-v0", push_speed=SPEED).unwrapped
    plain = gym.make("InterLevel-v0").unwrapped
    actions = np.zeros((2, 28))
    assert type(plain)._action_targets([plain, plain], actions).shape == (2, 28)
    with pytest.raises(ValueError, match="push_speed"):
        type(pushed)._action_targets([plain, pushed], actions)
    assert isinstance(pushed, HumanoidEnv)

