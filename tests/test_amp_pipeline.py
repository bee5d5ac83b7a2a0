"""Pipelined AMP scoring (style.pipeline): the same rewards as scoring after the step, whatever the timing."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import torch
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv, VecNormalize
from test_amp import gait_clip

import stairenv  # noqa: F401
from stairenv.motion import MotionLibrary
from stairenv.style.discriminator import AMPDiscriminator, DiscriminatorConfig
from stairenv.style.pipeline import PipelinedScorer, in_process_envs, pipeline_unavailable_reason, set_amp_sink
from stairenv.style.reference import ReferenceWindows
from stairenv.style.wrappers import AMPStyleReward, AMPVecEnvWrapper, AMPVectorWrapper

pytestmark = pytest.mark.skipif(pipeline_unavailable_reason() is not None,
                                reason=str(pipeline_unavailable_reason()))

SMALL = DiscriminatorConfig(hidden=(64, 32), batch_size=64)


@pytest.fixture(scope="module")
def reference() -> ReferenceWindows:
    return ReferenceWindows(MotionLibrary([gait_clip()]), num_frames=2, fps=30.0)


def style_for(reference, scoring_path: str, **kwargs) -> AMPStyleReward:
    """A style reward; ``scoring_path="window"``: scores after the step with the one-window kernel
    (what the pipeline must reproduce bit for bit)."""
    style = AMPStyleReward(reference, update_interval=64, config=SMALL, seed=0, **kwargs)
    if scoring_path == "window":
        style.disc.logits = style.disc.window_logits
    return style


def run_sb3(venv, steps: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    venv.seed(seed)
    venv.reset()
    rewards, styles = [], []
    for _ in range(steps):
        _, reward, _, infos = venv.step(rng.uniform(-1, 1, (venv.num_envs, 28)).astype(np.float32))
        rewards.append(reward)
        styles.append([info["style_reward"] for info in infos])
    return np.array(rewards), np.array(styles)


@pytest.mark.parametrize("background", [False, True])
def test_pipelined_rewards_are_the_bits_of_unpipelined_scoring(reference, background):
    runs = {}
    for mode, path in (("on", "pipeline"), ("off", "window")):
        style = style_for(reference, path, background_training=background)
        venv = AMPVecEnvWrapper(make_vec_env("InterLevel-v0", n_envs=4, seed=0), style, pipeline=mode)
        assert (venv.pipeline is not None) == (mode == "on")
        runs[mode] = run_sb3(venv, 200)  # 800 transitions: 12 training rounds, episodes end and reset
        if mode == "on":
            stats = dict(venv.pipeline.stats)
        assert style.rounds >= 10
        venv.close()
    np.testing.assert_array_equal(runs["on"][0], runs["off"][0])
    np.testing.assert_array_equal(runs["on"][1], runs["off"][1])
    assert stats["pipelined"] + stats["rescored"] == 800
    # How many the worker scored depends on the machine's load (on an idle 2-core machine most of them;
    # with background training the caller scores while a round runs): only that it took part is certain.
    assert stats["pipelined"] > 0


def test_pipelined_logits_match_torch(reference):
    style = style_for(reference, "pipeline")
    venv = AMPVecEnvWrapper(make_vec_env("InterLevel-v0", n_envs=3, seed=0), style, pipeline="on")
    venv.reset()
    seen = []
    original = venv.pipeline.logits

    def recorded(windows, slots=None):
        seen.append((windows.copy(), original(windows, slots)))
        return seen[-1][1]

    venv.pipeline.logits = recorded
    for _ in range(70):  # across training rounds
        venv.step(np.zeros((3, 28), dtype=np.float32))
    style.train = False  # the last steps are scored with the weights compared below
    for _ in range(5):
        venv.step(np.zeros((3, 28), dtype=np.float32))
    for windows, logits in seen[-5:]:
        with torch.no_grad():
            expected = style.disc(torch.from_numpy(windows)).numpy()
        np.testing.assert_allclose(logits, expected, rtol=1e-5, atol=1e-5)
    venv.close()


class EditAMP(gym.Wrapper):
    """Replaces info['amp_obs'] by an edited copy: the posted window is no longer the step's."""

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        info["amp_obs"] = info["amp_obs"] * 0.5
        return obs, reward, terminated, truncated, info


def test_a_window_edited_after_the_post_is_scored_in_the_calling_thread(reference):
    def make():
        return DummyVecEnv([lambda: EditAMP(gym.make("InterLevel-v0"))] * 2)

    runs = {}
    for mode, path in (("on", "pipeline"), ("off", "window")):
        venv = AMPVecEnvWrapper(make(), style_for(reference, path), pipeline=mode)
        runs[mode] = run_sb3(venv, 40)
        if mode == "on":
            assert venv.pipeline.stats == {"pipelined": 0, "rescored": 80}
        venv.close()
    np.testing.assert_array_equal(runs["on"][1], runs["off"][1])


def test_a_stopped_worker_is_reported_and_scoring_goes_on(reference):
    expected = run_sb3(AMPVecEnvWrapper(make_vec_env("InterLevel-v0", n_envs=2, seed=0),
                                        style_for(reference, "window"), pipeline="off"), 60)
    venv = AMPVecEnvWrapper(make_vec_env("InterLevel-v0", n_envs=2, seed=0), style_for(reference, "pipeline"),
                            pipeline="on")
    venv.pipeline._finalizer()  # the worker thread ends; the envs still post
    with pytest.warns(RuntimeWarning, match="worker stopped"):
        got = run_sb3(venv, 60)
    assert not venv.pipeline.active
    np.testing.assert_array_equal(got[1], expected[1])
    venv.close()


def test_a_worker_that_does_not_answer_times_out(reference):
    venv = AMPVecEnvWrapper(make_vec_env("InterLevel-v0", n_envs=2, seed=0), style_for(reference, "pipeline"),
                            pipeline="on")
    pipeline = venv.pipeline
    pipeline._finalizer()

    class Alive:  # a worker that is there but never scores
        @staticmethod
        def is_alive():
            return True

    pipeline._thread = Alive()
    pipeline.timeout = 0.2
    with pytest.warns(RuntimeWarning, match="did not answer within 0.2 s"):
        run_sb3(venv, 40)  # the first training round's new weights wait for the worker
    assert not pipeline.active
    venv.close()


def test_pipeline_mode_follows_the_vec_env(reference):
    # Wrappers in between are looked through.
    normalised = VecNormalize(make_vec_env("InterLevel-v0", n_envs=2, seed=0))
    wrapped = AMPVecEnvWrapper(normalised, style_for(reference, "pipeline"), pipeline="on")
    assert wrapped.pipeline is not None and in_process_envs(normalised) is not None
    wrapped.close()

    class Opaque(VecEnv):
        """A vec env whose envs live out of reach (as in subprocesses)."""

        def __init__(self, inner):
            self._inner = inner
            super().__init__(inner.num_envs, inner.observation_space, inner.action_space)

        def reset(self):
            return self._inner.reset()

        def step_async(self, actions):
            self._inner.step_async(actions)

        def step_wait(self):
            return self._inner.step_wait()

        def close(self):
            self._inner.close()

        def get_attr(self, *a, **k):
            return self._inner.get_attr(*a, **k)

        def set_attr(self, *a, **k):
            return self._inner.set_attr(*a, **k)

        def env_method(self, *a, **k):
            return self._inner.env_method(*a, **k)

        def env_is_wrapped(self, *a, **k):
            return self._inner.env_is_wrapped(*a, **k)

    opaque = Opaque(make_vec_env("InterLevel-v0", n_envs=2, seed=0))
    assert AMPVecEnvWrapper(opaque, style_for(reference, "pipeline")).pipeline is None  # auto: off
    with pytest.raises(ValueError, match="in-process vec env"):
        AMPVecEnvWrapper(opaque, style_for(reference, "pipeline"), pipeline="on")
    with pytest.raises(ValueError, match="numba kernel"):
        style = AMPStyleReward(reference, config=SMALL, scoring="torch")
        AMPVecEnvWrapper(make_vec_env("InterLevel-v0", n_envs=2), style, pipeline="on")
    with pytest.raises(ValueError, match="pipeline"):
        AMPVecEnvWrapper(make_vec_env("InterLevel-v0", n_envs=2), style_for(reference, "pipeline"), pipeline="yes")
    opaque.close()


def test_close_stops_the_worker_and_detaches_the_envs(reference):
    venv = AMPVecEnvWrapper(make_vec_env("InterLevel-v0", n_envs=2, seed=0), style_for(reference, "pipeline"),
                            pipeline="on")
    pipeline, envs = venv.pipeline, list(venv.venv.envs)
    run_sb3(venv, 5)
    venv.close()
    assert not pipeline._thread.is_alive()
    assert all(env.unwrapped._amp_sink is None for env in envs)


def test_gymnasium_sync_vector_env_is_pipelined(reference):
    runs = {}
    for mode, path in (("on", "pipeline"), ("off", "window")):
        envs = gym.make_vec("InterLevel-v0", num_envs=3, vectorization_mode="sync")
        wrapped = AMPVectorWrapper(envs, style_for(reference, path), pipeline=mode)
        assert (wrapped.pipeline is not None) == (mode == "on")
        wrapped.reset(seed=0)
        rng = np.random.default_rng(0)
        styles = []
        for _ in range(120):  # episodes end: next-step autoreset steps post nothing
            _, _, _, _, info = wrapped.step(rng.uniform(-1, 1, (3, 28)))
            styles.append(info["style_reward"])
        runs[mode] = np.array(styles)
        wrapped.close()
    np.testing.assert_array_equal(runs["on"], runs["off"])


def test_envs_post_their_step_window_and_only_on_step():
    env = gym.make("InterLevel-v0")
    posts = []
    set_amp_sink(env, lambda window, condition: posts.append((window, condition)))
    env.reset(seed=0)
    assert posts == []
    _, _, _, _, info = env.step(np.zeros(28))
    assert len(posts) == 1 and posts[0][0] is info["amp_obs"] and posts[0][1] is None
    set_amp_sink(env, None)
    env.step(np.zeros(28))
    assert len(posts) == 1
    with pytest.raises(TypeError, match="callable"):
        set_amp_sink(env, "not a function")


def test_a_logit_of_the_old_weights_is_never_reused():
    rng = np.random.default_rng(1)
    disc = AMPDiscriminator(6, DiscriminatorConfig(hidden=(8,), batch_size=4))
    scorer = PipelinedScorer(disc, num_envs=1, feature_dim=6)
    window = rng.normal(size=(1, 6)).astype(np.float32)
    scorer.sink(0)(window[0])
    before = scorer.logits(window)
    assert scorer.stats["pipelined"] == 1
    disc.update(rng.normal(size=(4, 6)).astype(np.float32), rng.normal(size=(4, 6)).astype(np.float32))
    scorer.refresh()  # new weights; the same window, not posted again
    after = scorer.logits(window)
    np.testing.assert_array_equal(after, disc.window_logits(window))
    assert after[0] != before[0] and scorer.stats["rescored"] == 1
    scorer.close()


def test_scorer_posts_only_windows_that_fit():
    rng = np.random.default_rng(0)
    disc = AMPDiscriminator(6 + 2, DiscriminatorConfig(hidden=(8,)))
    scorer = PipelinedScorer(disc, num_envs=2, feature_dim=6)
    windows = rng.normal(size=(2, 8)).astype(np.float32)
    scorer.sink(0)(windows[0, :6], windows[0, 6:])
    scorer.sink(1)(windows[1, :6], None)  # no condition: not posted, scored by the caller
    scorer.sink(1)(np.zeros(5), windows[1, 6:])  # wrong size: not posted either
    assert scorer.posted.tolist() == [1, 0]
    np.testing.assert_array_equal(scorer.logits(windows), disc.window_logits(windows))
    assert scorer.stats == {"pipelined": 1, "rescored": 1}
    nan = windows.copy()
    nan[0, 2] = np.nan
    scorer.sink(0)(nan[0, :6], nan[0, 6:])
    assert np.isnan(scorer.logits(nan)[0])
    with pytest.raises(ValueError, match="slot"):
        scorer.sink(2)
    scorer.close()
    scorer.close()  # idempotent
