"""Text-conditioned AMP (SIMS): reference windows carry their clip's condition, the wrappers append
the env's ``info["amp_condition"]``, and the discriminator learns motion *given* its condition."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import torch
from stable_baselines3.common.vec_env import DummyVecEnv

import stairenv  # noqa: F401
from stairenv.environments.sims import reference_captions
from stairenv.motion import MotionLibrary
from stairenv.motion.rsi import BUILTIN_REFERENCE_SETS, load_reference_library, standing_clips
from stairenv.motion.synthesis import climb_stairs, walk
from stairenv.style.discriminator import AMPDiscriminator, DiscriminatorConfig
from stairenv.style.reference import ReferenceWindows, clip_text, text_conditions
from stairenv.style.wrappers import AMPStyleReward, AMPVecEnvWrapper
from stairenv.training import cli

FAST_SIMS = {"text_encoder": "hashing", "text_dim": 8}


@pytest.fixture(scope="module")
def two_clips() -> MotionLibrary:
    return MotionLibrary([walk(1.0, duration=3.0), climb_stairs(0.15, 0.30, 4)])


def test_reference_windows_append_their_clips_condition(two_clips):
    conditions = np.array([[1.0, 0.0], [0.0, 1.0]])
    plain = ReferenceWindows(two_clips, num_frames=2)
    conditioned = ReferenceWindows(two_clips, num_frames=2, conditions=conditions)
    assert plain.condition_dim == 0 and plain.dim == plain.feature_dim
    assert conditioned.dim == plain.dim + 2 and conditioned.feature_dim == plain.feature_dim
    samples = conditioned.sample(500, np.random.default_rng(0))
    assert samples.shape == (500, conditioned.dim)
    # Every sample is a real window followed by the one-hot of the clip that window belongs to.
    rows = {tuple(w) for w in plain.windows}
    assert all(tuple(s[:-2]) in rows for s in samples[:50])
    first_clip_windows = {tuple(w) for w in plain.windows[plain.clip_index == 0]}
    for s in samples[:50]:
        expected = [1.0, 0.0] if tuple(s[:-2]) in first_clip_windows else [0.0, 1.0]
        assert s[-2:].tolist() == expected
    with pytest.raises(ValueError, match="one row per clip"):
        ReferenceWindows(two_clips, conditions=np.zeros((3, 2)))
    with pytest.raises(ValueError, match="finite"):
        ReferenceWindows(two_clips, conditions=np.full((2, 2), np.nan))


def test_clip_texts_and_text_conditions(two_clips):
    assert [clip_text(c) for c in two_clips.clips] == ["walk", "walk up the stairs"]
    lengths = text_conditions(two_clips, lambda text: np.array([len(text), 1.0]))
    assert lengths.tolist() == [[4.0, 1.0], [18.0, 1.0]]
    with pytest.raises(ValueError, match="different sizes"):
        text_conditions(two_clips, lambda text: np.ones(len(text)))


@pytest.mark.slow
def test_conditioned_discriminator_rejects_motion_with_the_wrong_condition(two_clips):
    """Same walking windows, two conditions: only the walk's own condition is real. An
    unconditioned discriminator could not tell these apart; the conditioned one must."""
    torch.manual_seed(0)
    rng = np.random.default_rng(0)
    onehot = np.eye(2, dtype=np.float32)
    reference = ReferenceWindows(two_clips, num_frames=2, conditions=onehot)
    walk_windows = reference.windows[reference.clip_index == 0]
    order = rng.permutation(len(walk_windows))
    train, held = walk_windows[order[: len(order) // 2]], walk_windows[order[len(order) // 2:]]
    mislabelled = lambda w: np.concatenate((w, np.repeat(onehot[1:], len(w), 0)), axis=1)  # noqa: E731
    labelled = lambda w: np.concatenate((w, np.repeat(onehot[:1], len(w), 0)), axis=1)  # noqa: E731
    disc = AMPDiscriminator(reference.dim, DiscriminatorConfig(batch_size=128))
    for _ in range(300):
        disc.update(reference.sample(128, rng), mislabelled(train[rng.integers(0, len(train), 128)]))
    d_real, d_fake = disc.logits(labelled(held)), disc.logits(mislabelled(held))
    accuracy = 0.5 * ((d_real > 0).mean() + (d_fake < 0).mean())
    assert accuracy > 0.9
    assert disc.reward(labelled(held)).mean() > disc.reward(mislabelled(held)).mean() + 0.2


def test_styled_walks_are_told_apart_by_their_captions():
    """Each styled walk under its own style is real; the same windows under another style's
    condition are fake. Held-out windows are judged right only if the styles differ in the
    AMP features themselves (a tired walk does not look like a happy one)."""
    from stairenv.motion.library import MotionLibrary
    from stairenv.motion.synthesis import WALK_STYLES, styled_walk

    torch.manual_seed(0)
    rng = np.random.default_rng(1)
    names = [n for n in WALK_STYLES if n != "neutral"]
    library = MotionLibrary([styled_walk(n, duration=3.0) for n in names])
    onehot = np.eye(len(names), dtype=np.float32)
    reference = ReferenceWindows(library, num_frames=2, conditions=onehot)
    order = rng.permutation(len(reference.windows))
    train, held = order[: len(order) // 2], order[len(order) // 2:]

    def with_condition(rows, shift):  # each window under its own style (shift 0) or another one
        return np.concatenate((reference.windows[rows], onehot[(reference.clip_index[rows] + shift) % len(names)]),
                              axis=1)

    disc = AMPDiscriminator(reference.dim, DiscriminatorConfig(hidden=(256, 128), batch_size=128))
    for _ in range(300):
        real = rng.choice(train, 128)
        fake = rng.choice(train, 128)
        disc.update(with_condition(real, 0), with_condition(fake, rng.integers(1, len(names), 128)))
    d_real = disc.logits(with_condition(held, 0))
    d_fake = disc.logits(with_condition(held, rng.integers(1, len(names), len(held))))
    accuracy = 0.5 * ((d_real > 0).mean() + (d_fake < 0).mean())
    assert accuracy > 0.9


def test_vec_wrapper_appends_the_envs_condition():
    library = load_reference_library("builtin:sims")
    probe = gym.make("SIMS-Sit-v0", **FAST_SIMS).unwrapped
    captions = reference_captions(library, "sit")
    assert captions == (("neutral", "sit down"),)
    conditions = text_conditions(library, probe.embed_text)
    reference = ReferenceWindows(library, num_frames=2, fps=1.0 / probe.dt, conditions=conditions)
    style = AMPStyleReward(reference, update_interval=8, config=DiscriminatorConfig(hidden=(32, 16), batch_size=16))
    seen: list[np.ndarray] = []
    original = style.disc.reward
    style.disc.reward = lambda x: (seen.append(np.array(x)), original(x))[1]
    venv = AMPVecEnvWrapper(DummyVecEnv([lambda: gym.make("SIMS-Sit-v0", captions=captions, **FAST_SIMS)] * 2),
                            style)
    venv.seed(3)
    venv.reset()
    for _ in range(10):
        _, reward, _, infos = venv.step(np.zeros((2, 28), dtype=np.float32))
        assert np.all(np.isfinite(reward))
    # The discriminator saw [window, embedding of "sit down"], and trained on it.
    sit_down = probe.embed_text("sit down").astype(np.float32)
    assert seen[-1].shape == (2, reference.dim)
    np.testing.assert_allclose(seen[-1][:, -8:], np.repeat(sit_down[None], 2, 0), rtol=1e-6)
    np.testing.assert_allclose(seen[-1][:, :-8], np.stack([i["amp_obs"] for i in infos]), rtol=1e-6)
    assert style.rounds >= 1
    venv.close()


def test_condition_mismatches_are_explained(two_clips, tmp_path):
    conditioned = ReferenceWindows(two_clips, conditions=np.eye(2))
    style = AMPStyleReward(conditioned, config=DiscriminatorConfig(hidden=(16,)))
    windows = conditioned.windows[:3]
    with pytest.raises(KeyError, match="amp_condition"):
        style.agent_inputs(list(windows), None)
    with pytest.raises(ValueError, match="3 numbers per env"):
        style.agent_inputs(list(windows), np.zeros((3, 3)))
    assert style.agent_inputs(list(windows), np.ones((3, 2))).shape == (3, conditioned.dim)
    path = style.save(tmp_path / "amp.pt")
    with pytest.raises(ValueError, match="2-number conditions"):
        AMPStyleReward.load(path, ReferenceWindows(two_clips))
    assert AMPStyleReward.load(path, conditioned).reference.condition_dim == 2


def test_builtin_sets_and_standing_starts():
    sims = load_reference_library("builtin:sims")
    skills = {clip.meta["skill"] for clip in sims.clips}
    assert skills == {"walk", "sit", "getup", "lie", "reach", "idle"}
    standing = standing_clips(sims)
    assert {clip.meta["skill"] for clip in standing.clips} == {"walk", "idle"}
    assert np.isclose(standing.probabilities.sum(), 1.0)
    assert len(load_reference_library("builtin:stairs").clips) == len(load_reference_library(None).clips)
    with pytest.raises(ValueError, match="builtin:sims"):
        load_reference_library("builtin:nope")
    assert "builtin:sims" in BUILTIN_REFERENCE_SETS
    with pytest.raises(ValueError, match="no clip"):
        reference_captions(standing, "sit")
    with pytest.raises(ValueError, match="skill"):
        reference_captions(sims, "dance")
    # SIMS reference starts come from the walk and idle clips only: standing, never seated in mid-air.
    env = gym.make("SIMS-Walk-v0", init="reference", **FAST_SIMS)
    for seed in range(6):
        env.reset(seed=seed)
        assert env.unwrapped.data.qpos[2] > 0.75
    env.close()


def test_condition_captions_give_the_discriminator_the_styles_text():
    """``condition_captions``: the observation keeps the drawn caption's embedding, ``info["amp_condition"]``
    is the embedding of its style's text; a repeated style, an uncovered style and an env without text
    are refused at construction, naming the keyword."""
    styles = {"happy": "walks with light, springy steps", "sad": "walks slowly with the head bowed"}
    captions = [("happy", "skips lightly across the room with a wide smile"),
                ("happy", "walks with light, springy steps"),
                ("sad", "walks slowly to the bed"), ("sad", "takes a few dragging steps")]
    env = gym.make("SIMS-Walk-v0", captions=captions, condition_captions=list(styles.items()), **FAST_SIMS)
    unwrapped = env.unwrapped
    z = unwrapped.observation_structure["text"]
    seen = set()
    for seed in range(12):
        obs, info = env.reset(seed=seed)
        seen.add(info["caption"])
        np.testing.assert_allclose(info["amp_condition"], unwrapped.embed_text(styles[info["style"]]), atol=1e-6)
        np.testing.assert_allclose(obs[z], unwrapped.embed_text(info["caption"]), atol=1e-6)
        obs, _, _, _, info = env.step(np.zeros(28, dtype=np.float32))
        np.testing.assert_allclose(info["amp_condition"], unwrapped.embed_text(styles[info["style"]]), atol=1e-6)
    assert len(seen) >= 3  # the condition does not depend on which of a style's captions was drawn
    without = gym.make("SIMS-Walk-v0", captions=captions, **FAST_SIMS)
    _, info = without.reset(seed=0)
    np.testing.assert_allclose(info["amp_condition"], without.unwrapped.embed_text(info["caption"]), atol=1e-6)
    for kwargs, match in ((dict(condition_captions=[*styles.items(), ("sad", "x")]), "each style once"),
                          (dict(condition_captions=[("happy", "x")]), r"style\(s\) \['sad'\]"),
                          (dict(condition_captions=list(styles.items()), text_conditioned=False), "text_conditioned")):
        with pytest.raises(ValueError, match=match):
            gym.make("SIMS-Walk-v0", captions=captions, **{**FAST_SIMS, **kwargs})


def test_style_conditions_fall_back_to_the_neutral_clips_text(baseline_script):
    """train_ppo --amp-text-captions all: a style of the env's captions that no reference clip has (sit's clips
    are unstyled) is conditioned on the neutral clip's text; a style with its own clip keeps its text."""
    library = load_reference_library("builtin:sims")
    sit_captions = gym.make("SIMS-Sit-v0", **FAST_SIMS).unwrapped.captions
    sit = cli.style_conditions(reference_captions(library, "sit"), sit_captions)
    assert dict(sit) == {style: "sit down" for style in {s for s, _ in sit}} and len(sit) > 1
    walk_reference = reference_captions(library, "walk")
    walk = dict(cli.style_conditions(walk_reference, (("happy", "skips"), ("sad", "shuffles"))))
    assert walk == dict(walk_reference)
    gym.make("SIMS-Sit-v0", condition_captions=sit, **FAST_SIMS).reset(seed=0)  # covers every caption's style
