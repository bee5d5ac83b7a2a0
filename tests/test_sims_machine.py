"""The SIMS state machine: transitions after the dwell time, failures, bindings, whole scripts, the CLI."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import mujoco
import networkx as nx
import numpy as np
import pytest

from stairenv.environments.sims import SIMSEnv
from stairenv.screenplays import (
    Keyframe,
    RoomMatch,
    Script,
    ScriptValidationError,
    assemble_story,
    get_encoder,
    load_database,
)
from stairenv.stories import machine as machine_module
from stairenv.stories.machine import (
    KINEMATIC,
    BindingError,
    KinematicStandIn,
    MachineSettings,
    StoryRunner,
    policy_specs,
    run_script,
)
from stairenv.tasks.sims import SUCCESS_DISTANCE
from stairenv.world.rooms import RoomConfig, generate_room

SKILLS = ("walk", "sit", "lie", "reach", "getup")
RUN_STORY = Path(__file__).resolve().parents[1] / "baselines" / "run_story.py"

STORY = [
    Keyframe("walk", "tired", "drags the feet to the chair", "chair"),
    Keyframe("sit", "tired", "slumps on the chair", "chair", "seat"),
    Keyframe("getup", "neutral", "gets up from the chair", "chair"),
    Keyframe("walk", "happy", "skips to the bookshelf", "bookshelf"),
    Keyframe("reach", "happy", "takes a book with the right hand", "bookshelf", "shelf", "right"),
]
BINDING = ["chair_0", "chair_0", "chair_0", "bookshelf_0", "bookshelf_0"]


@pytest.fixture(scope="module")
def env():
    room = generate_room(RoomConfig(size_x=(4.0, 4.0), size_y=(4.0, 4.0)), np.random.default_rng(3),
                         categories=["chair", "table", "bookshelf", "cabinet"])
    env = SIMSEnv(skill="walk", room=room, text_encoder="hashing")
    yield env
    env.close()


def stand_ins(env) -> dict:
    return dict.fromkeys(SKILLS, KINEMATIC)


class Freeze:
    """Holds the character where it stands by re-writing its pose (a policy that does nothing
    and never falls): every goal times out."""

    def __init__(self, env):
        self.env, self.qpos = env, None

    def __call__(self, obs):
        env = self.env
        if self.qpos is None:
            self.qpos = env.data.qpos.copy()
        env.data.qpos[:] = self.qpos
        env.data.qvel[:] = 0.0
        mujoco.mj_forward(env.model, env.data)
        q = self.qpos[env._idx.qpos_joints]
        return np.clip((q - env._ctrl_offset) / env._ctrl_scale, -1, 1)


def test_story_runs_in_order_and_moves_on_after_the_dwell_time(env):
    goals = []
    stand_in = KinematicStandIn(env)

    def traced(obs):  # one stand-in behind every skill, recording which goal each step served
        goals.append(env.goal)
        return stand_in(obs)

    runs = {}
    for dwell in (0.5, 1.0):
        goals.clear()
        runner = StoryRunner(env, dict.fromkeys(SKILLS, traced), MachineSettings(dwell_seconds=dwell))
        runs[dwell] = result = runner.run(STORY, BINDING, seed=0)
        assert result.success and [k.outcome for k in result.keyframes] == ["success"] * 5
        assert result.skills == ["walk", "sit", "getup", "walk", "reach"]
        assert result.interactions_succeeded == 2
        # steps per goal, in order, are exactly the keyframes' steps: one goal at a time
        per_goal = [sum(1 for g in goals if g is goal) for goal in dict.fromkeys(goals)]
        assert per_goal == [k.steps for k in result.keyframes]
        dwell_steps = math.ceil(dwell / env.dt - 1e-9)
        for k in result.keyframes:
            # the goal held for the whole dwell time right before the transition
            assert k.seconds - k.held_from == pytest.approx(dwell_steps * env.dt)
            assert k.contact_error < (MachineSettings().arrive_radius if k.skill == "walk" else SUCCESS_DISTANCE[k.skill])
            assert k.min_contact_error <= k.contact_error
        assert [k.furniture for k in result.keyframes] == BINDING
        assert result.keyframes[4].part == "shelf"
    # a longer dwell only adds the extra hold: the goals were reached at the same times
    for short, long in zip(runs[0.5].keyframes, runs[1.0].keyframes):
        assert long.held_from == pytest.approx(short.held_from, abs=2 * env.dt)
        assert long.seconds - short.seconds == pytest.approx(0.5, abs=2 * env.dt)


def test_a_policy_that_does_nothing_times_out(env):
    policies = {**stand_ins(env), "walk": Freeze(env)}
    settings = MachineSettings(dwell_seconds=0.2, max_seconds=1.0)
    result = StoryRunner(env, policies, settings).run(STORY, BINDING, seed=1)
    first = result.keyframes[0]
    assert (first.outcome, first.success, first.held_from) == ("timeout", False, None)
    assert first.seconds == pytest.approx(1.0) and first.steps == 30
    assert [k.outcome for k in result.keyframes[1:]] == ["skipped"] * 4
    assert not result.success and result.skills == ["walk"]

    # going on after the failure: the stand-in takes the character to the chair itself
    policies["walk"] = Freeze(env)
    result = StoryRunner(env, policies, MachineSettings(dwell_seconds=0.2, max_seconds=8.0, stop_on_failure=False)
                         ).run(STORY[:3], BINDING[:3], seed=1)
    assert [k.outcome for k in result.keyframes] == ["timeout", "success", "success"]
    assert not result.success and result.skills == ["walk", "sit", "getup"]


def test_zero_actions_fail_by_falling_or_timeout(env):
    zero = np.zeros(28)
    result = StoryRunner(env, {"walk": lambda obs: zero}, MachineSettings(max_seconds=3.0)).run(
        STORY[:1], BINDING[:1], seed=2)
    assert result.keyframes[0].outcome in ("fell", "timeout") and not result.success


def test_bad_bindings_raise_clear_errors(env):
    runner = StoryRunner(env, stand_ins(env))
    with pytest.raises(BindingError, match=r"keyframe 1 .*no furniture instance 'sofa_9'.*chair_0"):
        runner.run(STORY, ["chair_0", "sofa_9", "chair_0", "bookshelf_0", "bookshelf_0"])
    with pytest.raises(BindingError, match="sit needs a furniture instance"):
        runner.run(STORY[:2], ["chair_0", None])
    with pytest.raises(BindingError, match="3 entries for 5 keyframes"):
        runner.run(STORY, BINDING[:3])
    with pytest.raises(BindingError, match="cannot sit on a table"):
        runner.run([Keyframe("sit", "neutral", "sits on the table", "table")], ["table_0"])
    with pytest.raises(BindingError, match="no policy for 'reach'"):
        StoryRunner(env, {"walk": KINEMATIC}).run(STORY[3:], BINDING[3:])
    with pytest.raises(BindingError, match="getup without furniture"):
        runner.run([Keyframe("getup", "neutral", "gets up")], [None])
    with pytest.raises(ValueError, match="render_mode"):
        runner.run(STORY[:1], BINDING[:1], video=[])
    with pytest.raises(ValueError, match="dwell_seconds"):
        MachineSettings(dwell_seconds=5.0, max_seconds=2.0)


def test_getup_without_furniture_part_fallback_and_seated_start(env):
    keyframes = [
        Keyframe("getup", "neutral", "gets up"),  # from the chair the run starts on
        Keyframe("walk", "neutral", "walks to the cabinet", "cabinet"),
        Keyframe("reach", "neutral", "leans on the cabinet", "cabinet", "armrest"),  # no such part
        Keyframe("walk", "neutral", "wanders about"),  # no target: a random free point
    ]
    runner = StoryRunner(env, stand_ins(env), MachineSettings(dwell_seconds=0.3))
    result = runner.run(keyframes, [None, "cabinet_0", "cabinet_0", None], seed=4, start_pose="sitting",
                        start_on="chair_0")
    assert result.success, [(k.skill, k.outcome) for k in result.keyframes]
    getup, _, reach, wander = result.keyframes
    assert getup.furniture == "chair_0"
    assert reach.note and "'armrest'" in reach.note and reach.part != "armrest"
    assert wander.furniture is None
    # every walk target is free floor the stand-in could reach
    for name in ("chair_0", "bookshelf_0", "cabinet_0"):
        assert env.room.free_space().label_at(env.approach_point(env.furniture[name])[None])[0] > 0


def test_run_script_generates_a_room_and_films_it(tmp_path):
    script = load_database().get("angry_after_argument")
    video = tmp_path / "story.mp4"
    result = run_script(script, seed=0, env_kwargs={"text_encoder": "hashing"}, video=video, video_every=15,
                        width=160, height=120)
    assert result.success and result.script_ids == ["angry_after_argument"]
    assert [k.skill for k in result.keyframes] == [k.skill for k in script.keyframes]
    assert result.details["room_generated"]
    assert {"bed", "wardrobe"} <= {f["category"] for f in result.details["room_summary"]["furniture"]}
    assert video.stat().st_size > 0 and result.frames == sum(k.steps for k in result.keyframes) // 15
    assert set(result.policies.values()) == {"kinematic stand-in (NOT physics-based: writes qpos)"}
    json.dumps(result.to_dict())  # plain data


def test_run_story_cli(tmp_path):
    env = {**os.environ, "MUJOCO_GL": "egl"}
    out = tmp_path / "story.json"
    cmd = [sys.executable, str(RUN_STORY), "--script", "tired_bedtime", "--no-video", "--json", str(out),
           "--text-encoder", "hashing", "--dwell", "0.5"]
    done = subprocess.run(cmd, check=False, capture_output=True, text=True, timeout=300, env=env)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "kinematic stand-in (NOT physics-based" in done.stdout and "story succeeded" in done.stdout
    data = json.loads(out.read_text())
    assert data["script"] == "tired_bedtime" and data["result"]["success"]
    assert len(data["result"]["keyframes"]) == len(data["story"]["keyframes"])
    bad = subprocess.run([sys.executable, str(RUN_STORY), "--script", "no_such_script", "--no-video"],
                         check=False, capture_output=True, text=True, timeout=300, env=env)
    assert bad.returncode != 0 and "no_such_script" in bad.stderr


# --- arguments checked before a room or an env is built ---------------------------------------
def code_built(*keyframes: Keyframe) -> Script:
    return Script("code_built", "Built in code", "A script built in code, not read from a file.", keyframes)


LAMP = Keyframe("walk", "neutral", "walks to the lamp", "lamp")
CHAIR = [Keyframe("walk", "neutral", "walks to the chair", "chair"),
         Keyframe("sit", "neutral", "sits on the chair", "chair", "seat")]


@pytest.mark.parametrize(("script", "message"), [
    # used to report success on a lamp with the part swapped for its switch
    (code_built(LAMP, Keyframe("reach", "neutral", "touches the lamp", "lamp", "antenna")),
     r"keyframes\[1\]\.part: 'antenna' is not one of"),
    (code_built(LAMP, Keyframe("reach", "neutral", "touches the lamp", "lamp", "shelf")),
     r"keyframes\[1\]\.part: a lamp has no 'shelf' \(it has \['switch'\]\)"),
    # both used to bind to chair_0
    (code_built(*(Keyframe(**{**k.__dict__, "instance": -1}) for k in CHAIR)),
     r"keyframes\[0\]\.instance: -1 is less than the minimum 0"),
    (code_built(*(Keyframe(**{**k.__dict__, "instance": 99}) for k in CHAIR)),
     r"keyframes\[0\]\.instance: 99 is greater than the maximum 9"),
    (code_built(CHAIR[1]), r"keyframes\[0\]\.skill: sit on the chair must be preceded by a walk"),
    (code_built(*[Keyframe("fly", "x", "c")] * 100_000), r"and 299981 more problem\(s\)$"),
])
def test_run_script_validates_scripts_built_in_code(script, message):
    with pytest.raises(ScriptValidationError, match=message) as info:
        run_script(script, seed=0, env_kwargs={"text_encoder": "hashing"})
    assert len(str(info.value)) < 5000


def test_run_script_validates_stories_built_in_code():
    story = assemble_story("a tired evening at home", load_database(), get_encoder("hashing"), length=2)
    story.keyframes[1] = Keyframe(**{**story.keyframes[1].__dict__, "part": "antenna"})
    with pytest.raises(ScriptValidationError, match=r"keyframes\[1\]\.part: 'antenna'"):
        run_script(story)
    story.keyframes[1] = {"skill": "walk"}
    with pytest.raises(ScriptValidationError, match=r"keyframes\[1\]: expected a Keyframe, got dict"):
        run_script(story)
    story.scripts = []
    with pytest.raises(ScriptValidationError, match="a story needs a list of at least one Script"):
        run_script(story)


class FakeModel:
    """Stands for an SB3 model: not callable, has predict()."""

    def predict(self, obs, deterministic=True):
        return np.zeros(28), None


def test_run_script_type_checks_its_arguments():
    script = load_database().get("tired_bedtime")
    with pytest.raises(TypeError, match=r"script must be a Script or a Story, got dict \(build one with "
                                        r"Script.from_dict\)"):
        run_script(script.to_dict())
    with pytest.raises(TypeError, match="script must be a Script or a Story, got str"):
        run_script("tired_bedtime")
    with pytest.raises(TypeError, match=r"policies must be a mapping skill -> policy, or one policy for every "
                                        r"skill .*; got int"):
        run_script(script, 5)
    with pytest.raises(TypeError, match=r"policies\['walk'\] must be a callable obs -> action.*; got int"):
        run_script(script, {"walk": 5})
    with pytest.raises(ValueError, match="policy skills must be among .* got 'fly'"):
        run_script(script, {"fly": KINEMATIC})
    model = FakeModel()
    assert policy_specs(model) == dict.fromkeys(SKILLS, model)  # one model for every skill
    assert policy_specs({"walk": "zero", "sit": KINEMATIC}) == {"walk": "zero", "sit": KINEMATIC}


def test_an_unbound_keyframe_is_named(monkeypatch):
    # retrieval maps every node it is given; a match that misses one must not send the walk elsewhere
    match = RoomMatch("room", nx.Graph(), 0.0, {("chair", 0): "chair_0"})
    monkeypatch.setattr(machine_module, "story_room", lambda *args, **kwargs: (None, match))
    second = [Keyframe(**{**k.__dict__, "instance": 1}) for k in CHAIR]
    with pytest.raises(BindingError, match=r"keyframe 0 \(walk 'walks to the chair'\): the room has no item for "
                                           r"chair instance 1"):
        run_script(code_built(*second))


@pytest.mark.parametrize("seed, error, message", [(-1, ValueError, r"seed must lie in \[0, "),
                                                  (1.5, ValueError, "seed must be an integer"),
                                                  ("7", TypeError, "seed must be an integer")])
def test_run_script_names_a_bad_seed(seed, error, message):
    script = load_database()[0]
    with pytest.raises(error, match=message):
        run_script(script, seed=seed, env_kwargs={"text_encoder": "hashing"})


# --- run_story.py: settings and outputs checked before the run ------------------------------------
@pytest.fixture
def no_run(monkeypatch):
    """Makes a run fail the test: the checks must come before it."""
    import stairenv.stories

    def refuse(*args, **kwargs):
        raise AssertionError("the story ran before its settings and outputs were checked")

    monkeypatch.setattr(stairenv.stories, "run_script", refuse)


@pytest.mark.parametrize(("argv", "message"), [
    (["--theme", ""], "--theme: an empty theme"),
    (["--theme", "   "], "--theme: an empty theme"),
    (["--theme", "a tired evening", "--length", "1000000"], "--length must be in [1, {n}]"),
    (["--theme", "a tired evening", "--length", "0"], "--length must be in [1, {n}]"),
    (["--script", "tired_bedtime", "--length", "2"], "--length: a --theme story's length; --script runs one"),
    (["--script", "tired_bedtime", "--json", "{file}/story.json"],
     "--json '{file}/story.json': '{file}' is a file, so no folder can be made in it"),
    (["--script", "tired_bedtime", "--json", "{folder}"], "--json '{folder}': is a folder; give a file path"),
    (["--script", "tired_bedtime", "--json", "/proc/stairenv-nowhere/s.json"],
     "--json '/proc/stairenv-nowhere/s.json': nothing can be written in '/proc'"),
    (["--script", "tired_bedtime", "--out", "{file}/story.mp4"],
     "--out '{file}/story.mp4': '{file}' is a file, so no folder can be made in it"),
    (["--script", "tired_bedtime", "--out", "{tmp}/story.avi"], "--out must be an .mp4 path"),
])
def test_run_story_refuses_settings_and_outputs_before_the_run(tmp_path, capsys, no_run, baseline_script, argv,
                                                               message):
    """An empty theme and a length of a million were taken (the story silently capped), and an output that
    cannot be written failed after the whole run."""
    if "/proc" in message and not os.path.isdir("/proc/self"):
        pytest.skip("no /proc here")
    names = {"file": tmp_path / "a_file", "folder": tmp_path / "folder", "tmp": tmp_path, "n": len(load_database())}
    names["file"].write_text("x")
    names["folder"].mkdir()
    with pytest.raises(SystemExit) as stop:
        baseline_script("run_story").main([arg.format(**names) for arg in argv])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert message.format(**names) in err and "Traceback" not in err, err


def test_run_story_refuses_a_crafted_policy_zip_without_running_it(tmp_path, capsys, baseline_script):
    """``--walk x.zip`` went through SB3's loader, which unpickles the zip's ``data``: its payload ran."""
    import base64
    import pickle
    import zipfile

    marker = tmp_path / "marker"

    class Payload:
        def __reduce__(self):
            return (open, (str(marker), "w"))

    data = {"policy_class": {":type:": "<class 'abc.ABCMeta'>",
                             ":serialized:": base64.b64encode(pickle.dumps(Payload())).decode()}}
    crafted = tmp_path / "x.zip"
    with zipfile.ZipFile(crafted, "w") as archive:
        archive.writestr("data", json.dumps(data))
    with pytest.raises(SystemExit) as stop:
        baseline_script("run_story").main(["--script", "tired_bedtime", "--no-video", "--text-encoder", "hashing",
                                           "--walk", str(crafted)])
    assert stop.value.code == 2
    assert "x.zip: not a Stable-Baselines3 model .zip: it has no 'policy.pth' member" in capsys.readouterr().err
    assert not marker.exists()


def test_run_story_says_when_a_story_is_shorter_than_its_length(capsys, no_run, baseline_script):
    """A --length the database cannot chain to is taken as asked and the story's shortfall said, not hidden."""
    n = len(load_database())
    with pytest.raises(AssertionError, match="the story ran"):  # no_run: the story is assembled, not run
        baseline_script("run_story").main(["--theme", "a tired evening", "--length", str(n), "--encoder", "hashing",
                                           "--no-video"])
    out = capsys.readouterr().out
    assert "short scripts asked for (--length): no other script can follow its last one" in out
    assert f"of the {n} short scripts" in out
