"""One loader and one label function for policies (``stairenv.policy_loading``), under both the
stories and the evaluation, with the old import paths kept."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np

import stairenv.evaluation as evaluation
import stairenv.evaluation.policies as old_home
import stairenv.policy_loading as loading
import stairenv.stories as stories
from stairenv.policy_loading import KINEMATIC, STAND_IN_LABEL, ZeroPolicy, policy_label


def act(obs):
    return obs


class Named:
    def __repr__(self) -> str:
        return "Named(detail)"


class StandIn:
    physics_based = False


def test_old_import_paths_are_the_new_objects():
    for name in old_home.__all__:
        assert getattr(old_home, name) is getattr(loading, name)
    assert evaluation.load_policy is loading.load_policy
    assert stories.KINEMATIC is loading.KINEMATIC
    assert stories.KinematicStandIn.physics_based is False


def test_policy_label_short_and_detailed():
    zero = ZeroPolicy(gym.spaces.Box(-1.0, 1.0, (2,), np.float32))
    cases = [  # policy, short label (reports), detailed label (stories, printouts)
        ("zero", "zero", "zero"),
        (Path("runs/model.zip"), "runs/model.zip", "runs/model.zip"),
        (KINEMATIC, "kinematic", STAND_IN_LABEL),
        (Path(KINEMATIC), "kinematic", "kinematic"),
        (zero, "ZeroPolicy", "ZeroPolicy()"),
        (act, "act", repr(act)),
        (Named(), "Named", "Named(detail)"),
        (object(), "object", "object"),
        (StandIn(), "StandIn", STAND_IN_LABEL),
    ]
    for policy, short, detailed in cases:
        assert (policy_label(policy), policy_label(policy, detailed=True)) == (short, detailed), policy
        assert stories.describe_policy(policy) == detailed
