"""InterLevel's ``hold_target_reward`` training aid: success pays each step and does not end the episode (so
that arriving at M_T is worth more than stopping just outside the radius); dropped by the evaluation."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import stairenv  # noqa: F401  (registers the ids)
from stairenv.training import cli

# a radius that every standing start is inside: success from the first step on
AT_TARGET = dict(success_radius=10.0, step_height=(0.05, 0.05), num_steps=(3, 3))


def rollout(steps: int = 4, num_envs: int | None = None, **keywords):
    """(reward, terminated, success, reward_success) of each step of zero actions."""
    env = (gym.make("InterLevel-v0", **AT_TARGET, **keywords) if num_envs is None else
           gym.make_vec("InterLevel-v0", num_envs=num_envs, vectorization_mode="vector_entry_point",
                        **AT_TARGET, **keywords))
    env.reset(seed=3)
    zero = np.zeros(env.action_space.shape)
    rows = []
    for _ in range(steps):
        _, reward, terminated, _, info = env.step(zero)
        rows.append((np.asarray(reward, dtype=float), np.asarray(terminated), np.asarray(info["success"]),
                     np.asarray(info["reward_success"], dtype=float)))
        if num_envs is None and terminated:
            break
    env.close()
    return rows


def test_success_pays_each_step_and_goes_on():
    paper = rollout()
    assert len(paper) == 1 and paper[0][1] and paper[0][3] == 10.0    # the paper's end: one bonus, the end
    held = rollout(hold_target_reward=2.0)
    assert len(held) == 4 and not any(row[1] for row in held) and all(row[2] for row in held)
    assert [float(row[3]) for row in held] == [2.0] * 4
    # the task terms are the paper's: the first step's reward is the paper's but for the bonus
    assert float(held[0][0]) - 2.0 == pytest.approx(float(paper[0][0]) - 10.0, abs=1e-12)
    # the same as the episode's end switched off and the bonus set, to the last bit
    same = rollout(terminate_on_success=False, success_reward=2.0)
    assert all(np.array_equal(a[0], b[0]) for a, b in zip(held, same))


def test_a_batched_env_holds_the_target_as_its_single_env():
    batched = rollout(num_envs=2, hold_target_reward=2.0)
    assert all(not row[1].any() and row[2].all() and (row[3] == 2.0).all() for row in batched)


def test_the_aid_is_refused_out_of_range_and_left_out_of_the_evaluation():
    with pytest.raises(ValueError, match="hold_target_reward"):
        gym.make("InterLevel-v0", hold_target_reward=-1.0)
    assert "hold_target_reward" in cli.TRAINING_AIDS
    assert cli.evaluation_kwargs({"hold_target_reward": 1.0, "target_speed": 0.8}) == {"target_speed": 0.8}
