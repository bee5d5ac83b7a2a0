"""Saved files: an AMP state is read without running code from it, and every broken or
mismatched file given to ``train_ppo.py --resume`` or ``evaluate_style.py`` stops with a
message that names it and says what to do."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import torch
from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

import stairenv  # noqa: F401  (registers the envs)
from stairenv.motion.rsi import load_reference_library
from stairenv.style.discriminator import DiscriminatorConfig
from stairenv.style.reference import ReferenceWindows
from stairenv.style.wrappers import AMPStateError, AMPStyleReward

SMALL = DiscriminatorConfig(hidden=(16,), batch_size=8)


class WritesAMarker:
    """Unpickled, this would create a file: stands for any code a crafted file could run."""

    def __init__(self, marker) -> None:
        self.marker = str(marker)

    def __reduce__(self):
        return (open, (self.marker, "w"))


@pytest.fixture(scope="module")
def library():
    return load_reference_library("builtin:stairs")


@pytest.fixture(scope="module")
def reference(library):
    return ReferenceWindows(library, num_frames=2, fps=30.0)


@pytest.fixture
def crafted(tmp_path):
    """An AMP state file whose discriminator entry is a pickled callable, and its marker path."""
    marker = tmp_path / "code_ran"
    path = tmp_path / "crafted_amp.pt"
    torch.save({"discriminator": WritesAMarker(marker), "w_task": 0.5}, path)
    return path, marker


def test_the_amp_state_is_tensors_and_plain_values(reference, tmp_path):
    config = DiscriminatorConfig(hidden=(16,), batch_size=np.int64(8), learning_rate=np.float64(1e-4))
    style = AMPStyleReward(reference, w_task=np.float64(0.25), config=config)
    style.replay.add(reference.sample(16, np.random.default_rng(0)))
    style.train_round(1)
    state = torch.load(style.save(tmp_path / "amp.pt"), weights_only=True)
    assert state["w_task"] == 0.25 and state["config"]["batch_size"] == 8
    loaded = AMPStyleReward.load(tmp_path / "amp.pt", reference)
    assert loaded.config == style.config and loaded.rounds == 1


def test_a_crafted_amp_state_is_refused_and_runs_nothing(reference, crafted):
    path, marker = crafted
    with pytest.raises(AMPStateError, match=rf"{path.name}: refused: .*Python object .*open"):
        AMPStyleReward.load(path, reference)
    assert not marker.exists()


@pytest.mark.parametrize("content", [b"", b"not a torch file", None])
def test_unreadable_amp_states_name_the_file(reference, tmp_path, content):
    path = tmp_path / "amp_512_steps.pt"
    if content is None:  # a real state cut short
        whole = AMPStyleReward(reference, config=SMALL).save(tmp_path / "whole.pt").read_bytes()
        content = whole[: len(whole) // 2]
    path.write_bytes(content)
    with pytest.raises(AMPStateError, match=r"amp_512_steps\.pt: cannot read as an AMP state") as caught:
        AMPStyleReward.load(path, reference)
    assert "weights_only" not in str(caught.value)  # torch's advice to load unsafely is never passed on


def test_other_torch_files_and_other_window_sizes_are_explained(reference, library, tmp_path):
    torch.save(torch.zeros(3), tmp_path / "tensor.pt")
    with pytest.raises(AMPStateError, match=r"tensor\.pt: not an AMP state"):
        AMPStyleReward.load(tmp_path / "tensor.pt", reference)
    with pytest.raises(AMPStateError, match="no AMP state file"):
        AMPStyleReward.load(tmp_path / "missing.pt", reference)
    path = AMPStyleReward(reference, config=SMALL).save(tmp_path / "amp.pt")
    three_frames = ReferenceWindows(library, num_frames=3, fps=30.0)
    with pytest.raises(ValueError, match=r"amp\.pt judges windows of .*\(2 frames\).*\(3 frames\)"):
        AMPStyleReward.load(path, three_frames)


def test_evaluate_style_refuses_a_crafted_discriminator(crafted, tmp_path, baseline_script, capsys):
    path, marker = crafted
    run = tmp_path / "InterLevel-v0" / "seed0"
    run.mkdir(parents=True)
    (run / "final_model.zip").write_bytes(b"")  # never opened: the discriminator is read first
    with pytest.raises(SystemExit):
        baseline_script("evaluate_style").main([str(run), "--discriminator", str(path)])
    assert "refused" in capsys.readouterr().err and not marker.exists()


# --- train_sb3.py --resume -------------------------------------------------------
FAST = ["--n-envs", "1", "--vec-env", "dummy", "--timesteps", "0", "--eval-episodes", "0", "--no-progress-bar"]


def statistics_for(env_id: str, path) -> None:
    """VecNormalize statistics as a run of ``env_id`` saves them."""
    probe = gym.make(env_id)
    VecNormalize(DummyVecEnv([lambda: probe])).save(str(path))  # built, never stepped
    probe.close()


def make_checkpoint(folder, env_id: str):
    """A checkpoint of an ``env_id`` run under ``folder``: the model .zip is junk (every test stops before
    it is opened, or checks that it is reported), the statistics are real."""
    checkpoints = folder / "runs" / env_id / "seed0" / "checkpoints"
    checkpoints.mkdir(parents=True)
    (checkpoints / "ppo_512_steps.zip").write_bytes(b"PK junk")
    statistics_for(env_id, checkpoints / "ppo_vecnormalize_512_steps.pkl")
    return checkpoints / "ppo_512_steps.zip"


@pytest.fixture
def checkpoint(tmp_path):
    return make_checkpoint(tmp_path, "InterLevel-v0")


def resume(train_sb3, checkpoint, tmp_path, *extra) -> str:
    """train_sb3.main's message when it stops."""
    with pytest.raises(SystemExit) as stopped:
        train_sb3.main(["--resume", str(checkpoint), "--logdir", str(tmp_path / "out"), *FAST, *extra])
    return str(stopped.value)


def test_resume_without_the_amp_state_stops(checkpoint, tmp_path, baseline_script):
    message = resume(baseline_script("train_sb3"), checkpoint, tmp_path)
    assert str(checkpoint.with_name("amp_512_steps.pt")) in message and "--fresh-discriminator" in message


def test_resume_from_a_missing_checkpoint_names_it(tmp_path, baseline_script):
    missing = tmp_path / "runs" / "ppo_100_steps.zip"
    message = resume(baseline_script("train_sb3"), missing, tmp_path)
    assert f"--resume {missing}: no such checkpoint file" in message


def test_resume_without_statistics_names_them(checkpoint, tmp_path, baseline_script):
    checkpoint.with_name("ppo_vecnormalize_512_steps.pkl").unlink()
    message = resume(baseline_script("train_sb3"), checkpoint, tmp_path, "--style", "none")
    assert str(checkpoint) in message and "no VecNormalize statistics" in message


def test_resume_with_truncated_statistics_names_them(checkpoint, tmp_path, baseline_script):
    stats = checkpoint.with_name("ppo_vecnormalize_512_steps.pkl")
    stats.write_bytes(stats.read_bytes()[:100])
    message = resume(baseline_script("train_sb3"), checkpoint, tmp_path, "--style", "none")
    assert f"cannot read the VecNormalize statistics {str(stats)!r}" in message and "truncated" in message


def test_resume_on_another_env_names_both(tmp_path, baseline_script):
    plamo = make_checkpoint(tmp_path, "PlaMo-v0")
    message = resume(baseline_script("train_sb3"), plamo, tmp_path, "--style", "none")  # --env InterLevel-v0
    assert f"--resume {plamo}: trained on observations of shape (399,)" in message
    assert "(its run folder is PlaMo-v0's), but --env InterLevel-v0 gives (118,)" in message
    assert "pass the --env and --env-kwarg it was trained with" in message


def test_resume_from_a_broken_model_names_it(checkpoint, tmp_path, baseline_script):
    message = resume(baseline_script("train_sb3"), checkpoint, tmp_path, "--style", "none")
    assert f"--resume {checkpoint}: cannot load it as a PPO checkpoint" in message


def test_resume_refuses_a_crafted_amp_state(checkpoint, crafted, tmp_path, baseline_script):
    path, marker = crafted
    path.rename(checkpoint.with_name("amp_512_steps.pt"))
    message = resume(baseline_script("train_sb3"), checkpoint, tmp_path)
    assert "amp_512_steps.pt: refused" in message and "--fresh-discriminator" in message
    assert not marker.exists()


def test_fresh_discriminator_needs_resume(baseline_script):
    with pytest.raises(SystemExit, match="--fresh-discriminator only applies to --resume"):
        baseline_script("train_sb3").main(["--fresh-discriminator"])


class Calls:
    """Unpickled, this would call ``function(*args)``: any callable a crafted file could name."""

    def __init__(self, function, *args) -> None:
        self.function, self.args = function, args

    def __reduce__(self):
        return (self.function, self.args)


def _crafted_payloads(marker):
    import builtins
    import os
    import subprocess

    return {
        "os_system": Calls(os.system, f"touch {marker}"),  # a module torch 2.13 blocks outright
        "subprocess": Calls(subprocess.Popen, ["touch", str(marker)]),
        "eval": Calls(builtins.eval, f"open({str(marker)!r}, 'w')"),
        "exec": Calls(builtins.exec, f"open({str(marker)!r}, 'w')"),
        "own_class": WritesAMarker(marker),  # a class of this test module
    }


@pytest.mark.parametrize("payload", ["os_system", "subprocess", "eval", "exec", "own_class"])
def test_the_installed_torch_refusal_is_recognised_and_its_advice_never_passed_on(reference, tmp_path, payload):
    """Whatever torch's weights-only unpickler says (its wording changed between 2.1 and 2.13), the file
    is reported as refused, naming the object it asks for, and torch's advice to load it with
    ``weights_only=False`` is not repeated."""
    marker = tmp_path / "code_ran"
    path = tmp_path / "crafted_amp.pt"
    torch.save({"discriminator": _crafted_payloads(marker)[payload], "w_task": 0.5}, path)
    _refusal(reference, path, marker)


def _refusal(reference, path, marker) -> str:
    """The error loading a crafted AMP state, checked: refused naming an object, torch's advice not passed
    on, nothing run."""
    with pytest.raises(AMPStateError) as caught:
        AMPStyleReward.load(path, reference)
    message = str(caught.value)
    assert message.startswith(f"{path}: refused: it asks to build the Python object "), message
    assert "weights_only" not in message and "truncated" not in message and "trust" not in message, message
    assert not marker.exists()
    return message


@pytest.mark.parametrize("wording", [
    # torch 2.1-2.3
    "Weights only load failed. Re-running `torch.load` with `weights_only` set to `False` will likely succeed, "
    "but it can result in arbitrary code execution.Do it only if you get the file from a trusted source. "
    "WeightsUnpickler error: Unsupported global: GLOBAL posix.system was not an allowed global by default.",
    # torch 2.4-2.12
    "Weights only load failed. This file can still be loaded, to do so you have two options \n\t(1) Re-running "
    "`torch.load` with `weights_only` set to `False` will likely succeed, but it can result in arbitrary code "
    "execution. Do it only if you got the file from a trusted source.\n\t(2) Alternatively, to load with "
    "`weights_only=True` please check the recommended steps in the following error message.\n\tWeightsUnpickler "
    "error: Unsupported global: GLOBAL posix.system was not an allowed global by default. Please use "
    "`torch.serialization.add_safe_globals([system])` to allowlist this global if you trust this class/function.",
    # torch 2.13
    "Weights only load failed. In PyTorch 2.6, we changed the default value of the `weights_only` argument in "
    "`torch.load` from `False` to `True`. Re-running `torch.load` with `weights_only` set to `False` will likely "
    "succeed, but it can result in arbitrary code execution. Do it only if you got the file from a trusted "
    "source.\n\n\nTrying to load unsupported GLOBAL posix.system whose module posix is blocked.\n\n",
])
def test_refusals_in_every_torch_wording_are_recognised(reference, tmp_path, monkeypatch, wording):
    import pickle

    path = AMPStyleReward(reference, config=SMALL).save(tmp_path / "amp.pt")

    def refuse(*args, **kwargs):
        raise pickle.UnpicklingError(wording)

    monkeypatch.setattr(torch, "load", refuse)
    with pytest.raises(AMPStateError, match=r"amp\.pt: refused: it asks to build the Python object posix\.system,") \
            as caught:
        AMPStyleReward.load(path, reference)
    assert "weights_only" not in str(caught.value)


@pytest.mark.parametrize("entry, value", [("rounds", "many"), ("rounds", -1), ("rounds", 2.5), ("w_task", "x"),
                                          ("w_style", float("nan")), ("update_interval", 0),
                                          ("background_training", "yes"), ("scoring", 3), ("discriminator", [1])])
def test_amp_state_entries_of_the_wrong_type_name_the_entry(reference, tmp_path, entry, value):
    path = AMPStyleReward(reference, config=SMALL).save(tmp_path / "amp.pt")
    state = torch.load(path, weights_only=True)
    state[entry] = value
    torch.save(state, path)
    with pytest.raises(AMPStateError, match=rf"amp\.pt: entry '{entry}'"):
        AMPStyleReward.load(path, reference)


def _crafted_in_format(path, marker, form):
    """A file holding a ``WritesAMarker`` in one of the forms torch.load(weights_only=True) reads."""
    import pickle

    payload = {"discriminator": WritesAMarker(marker), "w_task": 0.5}
    if form == "torch_zip":
        torch.save(payload, path)
    elif form == "torch_legacy":
        torch.save(payload, path, _use_new_zipfile_serialization=False)
    else:  # a plain pickle, as pickle.dump writes it
        path.write_bytes(pickle.dumps(payload, protocol=int(form[-1])))
    return path


@pytest.mark.parametrize("form", ["torch_zip", "torch_legacy", "pickle_0", "pickle_2", "pickle_4", "pickle_5"])
def test_a_crafted_amp_state_in_any_form_is_refused_as_such(reference, tmp_path, recwarn, form):
    """torch 2.13 refuses a plain pickle at its first unsupported opcode ("Unsupported operand 149"),
    before it reaches the global: still a refusal, the object named from the pickle's own opcodes,
    never "truncated", and torch's warning asking to report the protocol to them is not shown."""
    marker = tmp_path / "code_ran"
    path = _crafted_in_format(tmp_path / "crafted_amp.pt", marker, form)
    assert "the Python object io.open," in _refusal(reference, path, marker)
    assert not [w for w in recwarn if "pickle protocol" in str(w.message)]


# a refusal in a wording no torch version has used yet, with the advice to load the file unsafely
FUTURE_WORDING = ("Refused to unpickle this checkpoint. If you trust it, pass weights_only=False to torch.load "
                  "to load it anyway.")


@pytest.mark.parametrize("content", ["crafted", "plain"])
def test_a_refusal_in_a_new_wording_is_recognised_by_its_type(reference, tmp_path, monkeypatch, content):
    marker = tmp_path / "code_ran"
    if content == "crafted":
        path = _crafted_in_format(tmp_path / "amp.pt", marker, "torch_zip")
    else:  # nothing but torch's own globals in it: the refusal names no object
        path = AMPStyleReward(reference, config=SMALL).save(tmp_path / "amp.pt")

    def refuse(*args, **kwargs):
        import pickle

        raise pickle.UnpicklingError(FUTURE_WORDING)

    monkeypatch.setattr(torch, "load", refuse)
    if content == "crafted":
        assert "the Python object io.open," in _refusal(reference, path, marker)
        return
    with pytest.raises(AMPStateError) as caught:
        AMPStyleReward.load(path, reference)
    message = str(caught.value)
    assert message.startswith(f"{path}: cannot read as an AMP state"), message
    assert "its pickle holds instructions that a safe load refuses" in message, message
    assert "weights_only" not in message and "trust" not in message, message


@pytest.mark.parametrize("form", ["torch_zip", "pickle_4"])
def test_a_crafted_lean_trainer_checkpoint_is_refused_naming_the_object(tmp_path, form):
    from stairenv.training import CheckpointError, read_checkpoint

    marker = tmp_path / "code_ran"
    path = _crafted_in_format(tmp_path / "checkpoint.pt", marker, form)
    with pytest.raises(CheckpointError, match=r"checkpoint\.pt: refused: it asks to build the Python object io\.open"
                       r".*nothing in it was run") as caught:
        read_checkpoint(path)
    assert "weights_only" not in str(caught.value)
    assert not marker.exists()
