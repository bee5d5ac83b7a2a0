"""One loader and one label function for policies (``stairenv.policy_loading``), under both the
stories and the evaluation, with the old import paths kept."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

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


# --- Stable-Baselines3 files are read without running code from them --------------------------
class _Payload:
    """Unpickled, it creates ``marker`` (what a crafted file's code would do first)."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return (open, (str(self.marker), "w"))


def _sb3_model(folder: Path, algorithm: str = "PPO", **kwargs) -> Path:
    import stable_baselines3

    folder.mkdir(parents=True, exist_ok=True)
    model = getattr(stable_baselines3, algorithm)("MlpPolicy", gym.make("InterLevel-v0"), device="cpu", seed=0,
                                                  **kwargs)
    model.save(folder / "model.zip")
    return folder / "model.zip"


def _rewritten(source: Path, target: Path, **members: bytes) -> Path:
    """``source``'s zip with the named members replaced (or added), at ``target``."""
    import zipfile

    with zipfile.ZipFile(source) as old, zipfile.ZipFile(target, "w") as new:
        for name in old.namelist():
            new.writestr(name, members.pop(name, None) or old.read(name))
        for name, data in members.items():
            new.writestr(name, data)
    return target


def _crafted_data(model: Path, marker: Path) -> bytes:
    """``model``'s ``data`` JSON with every ":serialized:" value (the policy class, the spaces, ...) a payload."""
    import base64
    import json
    import pickle
    import zipfile

    data = json.loads(zipfile.ZipFile(model).read("data"))
    payload = base64.b64encode(pickle.dumps(_Payload(marker))).decode()
    for value in data.values():
        if isinstance(value, dict) and ":serialized:" in value:
            value[":serialized:"] = payload
    return json.dumps(data).encode()


def test_a_crafted_sb3_zip_runs_nothing_and_acts_as_sb3s_own_loader(tmp_path):
    """SB3's loader unpickles the ``data`` member's ":serialized:" values: a crafted .zip ran its payload
    through ``load_policy`` (``python -m stairenv --policy``, ``run_story.py --walk``). Read from plain JSON
    and ``weights_only`` tensors, it runs nothing, and the policy acts bit for bit as SB3's ``predict``."""
    from stable_baselines3 import PPO

    model = _sb3_model(tmp_path / "clean", policy_kwargs={"net_arch": [16, 8]})
    marker = tmp_path / "marker"
    crafted = _rewritten(model, tmp_path / "crafted.zip", data=_crafted_data(model, marker))
    env = gym.make("InterLevel-v0")
    policy = loading.load_policy(str(crafted), env)
    assert not marker.exists()
    reference = PPO.load(model, device="cpu")  # the clean file, through SB3's own loader
    obs = np.random.default_rng(0).normal(size=(4, *env.observation_space.shape))
    for o in obs:
        np.testing.assert_array_equal(policy(o), reference.predict(o, deterministic=True)[0])
    # only the data member, as a crafted file has it: refused, naming the file and what it lacks
    only_data = tmp_path / "only_data.zip"
    import zipfile

    with zipfile.ZipFile(only_data, "w") as archive:
        archive.writestr("data", _crafted_data(model, marker))
    with pytest.raises(ValueError, match=r"only_data\.zip: not a Stable-Baselines3 model \.zip: it has no "
                                         r"'policy\.pth'"):
        loading.load_policy(str(only_data), env)
    assert not marker.exists()


def test_a_crafted_policy_pth_or_statistics_pkl_is_refused_without_running(tmp_path):
    """The weights are read with ``torch.load(weights_only=True)`` and the VecNormalize statistics beside a
    model by an unpickler that builds nothing it names: a payload in either is refused, naming the file."""
    import io
    import pickle

    import torch

    model = _sb3_model(tmp_path / "run", policy_kwargs={"net_arch": [8]})
    marker = tmp_path / "marker"
    buffer = io.BytesIO()
    torch.save({"action_net.weight": _Payload(marker)}, buffer)
    weights = _rewritten(model, tmp_path / "weights.zip", **{"policy.pth": buffer.getvalue()})
    env = gym.make("InterLevel-v0")
    with pytest.raises(ValueError, match=r"weights\.zip: its policy\.pth asks to build Python objects besides "
                                         r"tensors, which a safe load refuses \(nothing in it was run\)") as info:
        loading.load_policy(str(weights), env)
    assert "weights_only=False" not in str(info.value)
    (tmp_path / "run" / "vecnormalize.pkl").write_bytes(pickle.dumps(_Payload(marker)))
    with pytest.raises(ValueError, match=r"vecnormalize\.pkl: not read as VecNormalize statistics: it names "
                                         r"(builtins|io)\.open"):
        loading.load_policy(str(model), env)
    assert not marker.exists()
    (tmp_path / "run" / "vecnormalize.pkl").write_bytes(pickle.dumps({"obs_rms": None}))
    with pytest.raises(ValueError, match=r"vecnormalize\.pkl: holds a dict, not VecNormalize statistics"):
        loading.load_policy(str(model), env)


def test_sb3_models_and_statistics_act_as_sb3_loads_them(tmp_path):
    """Valid files act as before: PPO with its VecNormalize statistics, SAC and TD3 (``ALGO:path``), each
    action bit for bit SB3's ``predict`` after ``normalize_obs``."""
    import stable_baselines3
    import torch
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import VecNormalize

    venv = VecNormalize(make_vec_env("InterLevel-v0", n_envs=2, seed=3))  # seeded spaces: their generators pickled
    venv.reset()
    for _ in range(4):
        venv.step(np.random.default_rng(0).uniform(-1, 1, (2, 28)))
    (tmp_path / "ppo").mkdir()
    venv.save(tmp_path / "ppo" / "vecnormalize.pkl")
    env = gym.make("InterLevel-v0")
    obs = np.random.default_rng(1).normal(size=(4, *env.observation_space.shape))
    for algorithm, kwargs in (("PPO", {"policy_kwargs": {"net_arch": [16], "activation_fn": torch.nn.ReLU}}),
                              ("SAC", {"buffer_size": 64}), ("TD3", {"buffer_size": 64})):
        path = _sb3_model(tmp_path / algorithm.lower(), algorithm, **kwargs)
        policy = loading.load_policy(f"{algorithm}:{path}", env)
        reference = getattr(stable_baselines3, algorithm).load(path, device="cpu")
        normalizer = None
        if algorithm == "PPO":  # SB3's own loader (a trusted file)
            normalizer = VecNormalize.load(str(tmp_path / "ppo" / "vecnormalize.pkl"), venv)
        for o in obs:
            seen = o if normalizer is None else normalizer.normalize_obs(np.asarray(o, dtype=np.float32))
            np.testing.assert_array_equal(policy(o), reference.predict(seen, deterministic=True)[0])
        assert (policy.obs_normalizer is not None) == (algorithm == "PPO")
    venv.close()
