"""baselines/distill_walk.py: the climber's view of a SIMS walk goal, and the checkpoint it writes."""

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch

import stairenv  # noqa: F401  (registers the ids)
from stairenv.tasks.interlevel import OBSERVATION_STRUCTURE as CLIMBER
from stairenv.training.ppo import read_checkpoint

TEMPLATE = Path(__file__).resolve().parents[1] / "checkpoints" / "SIMS-Walk-v0" / "w4_checkpoint_2500608.pt"


def test_climber_view_of_a_walk_goal_by_hand(baseline_script):
    """The climber sees the walk target as its top marker, in its heading frame (the InterLevel formula
    computed here from the pelvis pose), the start distance as the marker distance, and the heading's
    angle to the target as the angle to the ascent; the proprioception is passed as it is."""
    distill = baseline_script("distill_walk")
    env = gym.make("SIMS-Walk-v0", text_encoder="hashing")
    obs, _ = env.reset(seed=3)
    for _ in range(5):
        obs, *_ = env.step(env.action_space.sample() * 0.2)
    u = env.unwrapped
    pelvis, rotation = u.data.xpos[1], u.data.xmat[1].reshape(3, 3)
    yaw = np.arctan2(rotation[1, 0], rotation[0, 0])
    c, s = np.cos(yaw), np.sin(yaw)
    d = np.asarray(u.goal.root_target) - pelvis
    view = distill.climber_view(obs[None], u.observation_structure, np.array([4.0]))[0]
    np.testing.assert_allclose(view[CLIMBER["target_offset"]], [c * d[0] + s * d[1], -s * d[0] + c * d[1], d[2]],
                               atol=1e-9)
    assert view[CLIMBER["marker_distance"]][0] == 4.0
    target_yaw = np.arctan2(d[1], d[0])
    expected = (yaw - target_yaw + np.pi) % (2 * np.pi) - np.pi
    assert abs(view[CLIMBER["stairs_angle"]][0] - expected) < 1e-9
    np.testing.assert_array_equal(view[:113], obs[:113])
    np.testing.assert_allclose(distill.ground_distance(obs[None], u.observation_structure), [np.hypot(d[0], d[1])],
                               atol=1e-9)


def test_climber_view_needs_one_target_per_world(baseline_script):
    """A goal of several targets (lie: pelvis and head) or of none has no marker for the climber."""
    env = gym.make("SIMS-Walk-v0", text_encoder="hashing")
    obs, _ = env.reset(seed=0)
    structure = env.unwrapped.observation_structure
    view = baseline_script("distill_walk").climber_view
    for mask in (np.zeros(structure["goal_mask"].stop - structure["goal_mask"].start), None):
        bad = obs.copy()
        if mask is None:
            bad[structure["goal_mask"]] = 1.0
        else:
            bad[structure["goal_mask"]] = mask
        with pytest.raises(ValueError, match="one target"):
            view(bad[None], structure, np.ones(1))


def test_distill_writes_the_template_with_a_new_actor(baseline_script, tmp_path):
    """One short DAgger iteration: the output is the template's checkpoint (value network, normaliser,
    discriminator unchanged) whose actor moved towards the climber's actions, readable as a checkpoint."""
    out = tmp_path / "distilled.pt"
    assert baseline_script("distill_walk").main(["--template", str(TEMPLATE), "--out", str(out), "--iterations", "1",
                                                "--steps", "4", "--n-envs", "2", "--epochs", "2"]) == 0
    template, distilled = read_checkpoint(TEMPLATE), read_checkpoint(out)
    assert distilled["config"] == template["config"] and distilled["steps"] == template["steps"]
    for name, value in template["model"].items():
        same = torch.equal(value, distilled["model"][name])
        assert same == (not name.startswith(("policy_net", "action_mean"))), name
    np.testing.assert_array_equal(np.asarray(distilled["obs_rms"]["mean"]), np.asarray(template["obs_rms"]["mean"]))


def test_distill_refuses_another_envs_template(baseline_script, tmp_path, capsys):
    plamo = next((Path(__file__).resolve().parents[1] / "checkpoints" / "PlaMo-v0").glob("*.pt"))  # the lineage's
    assert baseline_script("distill_walk").main(["--template", str(plamo), "--out", str(tmp_path / "x.pt")]) == 2
    assert "SIMS-Walk-v0" in capsys.readouterr().err


def test_plamo_distillation_labels_each_world_by_its_paths_locomotion_now(baseline_script):
    """baselines/distill_plamo.py: row k is labelled by the specialist of the locomotion world k's path asks
    for at the world's time (sprint by the run specialist); a world whose path changes locomotion changes
    teacher."""
    distill = baseline_script("distill_plamo")
    from stairenv.environments.plamo import PlaMoEnv

    worlds = [PlaMoEnv(locomotion=kind) for kind in ("crawl", "walk", "sprint")]
    for seed, env in enumerate(worlds):
        env.reset(seed=seed)
    teachers = {kind: (lambda value: lambda obs: np.full((len(obs), 28), value))(value)
                for value, kind in enumerate(("crawl", "crouch-walk", "walk", "run"))}
    teacher = distill.routed_teacher(worlds, teachers)
    labels = teacher(np.zeros((3, worlds[0].observation_space.shape[0])))
    np.testing.assert_array_equal(labels[:, 0], [0, 2, 3])
    assert teacher.counts == {"crawl": 1, "walk": 1, "run": 1}
    mixed = PlaMoEnv()                       # every locomotion: find a step where the path's changes
    mixed.reset(seed=7)
    kinds = []
    for _ in range(300):
        kinds.append(distill.path_locomotion(mixed))
        mixed._steps += 1                     # (the teacher reads the episode's time only)
    assert len(set(kinds)) > 1


def test_the_sims_playback_labels_the_start_clips_next_frame_and_a_run_writes_the_template(baseline_script,
                                                                                            tmp_path, capsys):
    """distill_sims.py: the teacher's action puts the PD targets on the start clip's joint angles one step ahead
    (its last frame held), None for a world without a clip; a short run writes the template with a new actor."""
    script = baseline_script("distill_sims")
    env = gym.make("SIMS-Sit-v0", text_encoder="hashing", interaction_start_fraction=1.0, track_reward=2.0).unwrapped
    env.reset(seed=0)
    clip = env._track.qpos
    for _ in range(3):
        action = script.playback_action(env)
        target = np.clip(clip[min(env._steps + 1, len(clip) - 1), 7:], env._ctrl_offset - env._ctrl_scale,
                         env._ctrl_offset + env._ctrl_scale)
        np.testing.assert_allclose(env._ctrl_offset + env._ctrl_scale * action, target, atol=1e-9)
        env.step(action)
    env._track = None
    assert script.playback_action(env) is None
    sit = Path(__file__).resolve().parents[1] / "checkpoints" / "SIMS-Sit-v0" / "s13_checkpoint_6500352.pt"
    out = tmp_path / "sit.pt"
    assert script.main(["--template", str(sit), "--out", str(out), "--iterations", "1", "--steps", "4",
                        "--n-envs", "2", "--epochs", "2"]) == 0
    template, distilled = read_checkpoint(sit), read_checkpoint(out)
    for name, value in template["model"].items():
        assert torch.equal(value, distilled["model"][name]) == (not name.startswith(("policy_net", "action_mean")))
    assert template["curriculum_level"] and distilled["curriculum_level"] == []    # the student's run starts at 0
    plamo = next((Path(__file__).resolve().parents[1] / "checkpoints" / "PlaMo-v0").glob("*.pt"))
    assert script.main(["--template", str(plamo), "--out", str(tmp_path / "x.pt")]) == 2
    assert "a SIMS run's checkpoint" in capsys.readouterr().err


def test_the_walkers_view_of_a_sims_world_is_the_walk_envs_own_observation(baseline_script):
    """distill_sims.walk_view: a SIMS world's observation with its goal replaced by a walk goal is what SIMS-Walk-v0
    observes for that goal (the same proprioception, heightmap and text; the pelvis target in the heading frame)."""
    script = baseline_script("distill_sims")
    env = gym.make("SIMS-Walk-v0", text_encoder="hashing")
    walk = env.unwrapped
    obs, _ = env.reset(seed=3)
    rng = np.random.default_rng(0)
    for _ in range(5):
        obs, *_ = env.step(0.1 * rng.uniform(-1.0, 1.0, env.action_space.shape))
        view = script.walk_view(walk, obs, walk.goal.root_target[:2], obs[walk.observation_structure["text"]])
        np.testing.assert_allclose(view, obs, rtol=0, atol=1e-12)
    moved = script.walk_view(walk, obs, walk.goal.root_target[:2] + 1.0, obs[walk.observation_structure["text"]])
    assert not np.allclose(moved, obs)
