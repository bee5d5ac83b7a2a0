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


def test_pretrained_is_the_policy_shipped_for_the_envs_id():
    """``"pretrained"``: the numpy policy shipped for the env's registered id (its preset's ``policy`` id
    where it names one); an id without one, or an env without an id, is a clear error."""
    import pytest

    from stairenv.environments.sims import SIMSEnv
    from stairenv.pretrained import NumpyPolicy

    walk = loading.load_policy("pretrained", gym.make("SIMS-Walk-v0"))
    assert isinstance(walk, NumpyPolicy) and walk.config["env_id"] == "SIMS-Walk-v0"
    assert loading.load_policy("pretrained", gym.make("PlaMoScene-v0")).config["env_id"] == "PlaMo-v0"
    with pytest.raises(ValueError, match="SIMS-Lie-v0"):
        loading.load_policy("pretrained", gym.make("SIMS-Lie-v0"))
    bare = SIMSEnv(skill="walk")
    with pytest.raises(ValueError, match="no registered id"):
        loading.load_policy("pretrained", bare)
    # the stories resolve it per skill, whatever env gives the spaces
    resolved = stories.load_skill_policies({"walk": "pretrained", "sit": KINEMATIC}, bare)
    assert resolved["walk"].config["env_id"] == "SIMS-Walk-v0" and resolved["sit"] == KINEMATIC
    with pytest.raises(ValueError, match="SIMS-Sit-v0"):
        stories.load_skill_policies({"sit": "pretrained"}, bare)
    bare.close()
