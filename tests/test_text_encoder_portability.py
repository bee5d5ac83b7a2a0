"""Text embeddings are the same on any machine: the SIMS text encoder's id names what it is (the model
and the shipped projection's digest, or the texts a projection was fitted on), never a hash of floats
computed at run time, and policies compare embeddings within a tolerance.

Another CPU computes MiniLM's vectors with other low bits; these tests stand in for it by moving the
encoder's outputs by ~1e-6."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

import stairenv  # noqa: F401
from stairenv import pretrained
from stairenv.pretrained import PolicyFileError, load, shipped_policy_path, with_trained_captions
from stairenv.screenplays import embeddings as emb_mod
from stairenv.screenplays.embeddings import (
    CallableEncoder,
    HashingEncoder,
    corpus_digest,
    fit_reduction,
    get_encoder,
    reduction_corpus,
    shipped_basis,
    shipped_projection,
)

MINILM = pytest.mark.skipif(not emb_mod.minilm_available(), reason="needs the sims extra (MiniLM)")


@pytest.fixture
def another_cpu(monkeypatch):
    """MiniLM's 384-d vectors moved by a seeded ~1e-6 (what another machine's BLAS does), memory and
    disk caches bypassed (a fresh cache directory)."""
    original = emb_mod.MiniLMEncoder.encode
    rng = np.random.default_rng(7)

    def jittered(self, texts):
        x = original(self, texts)
        return emb_mod._normalize(x + 1e-6 * rng.standard_normal(x.shape).astype(np.float32))

    def use(cache_dir):
        monkeypatch.setenv("STAIRENV_CACHE", str(cache_dir))
        monkeypatch.setattr(emb_mod.MiniLMEncoder, "encode", jittered)

    return use


def test_a_projection_fitted_on_your_texts_is_named_by_them(tmp_path):
    """``fit_reduction`` on other texts: its id is the digest of the texts (the same on any machine),
    and vectors moved by 1e-6 fit a projection with the same id and nearly the same matrix."""
    base = HashingEncoder(dim=128)
    texts = [f"caption number {i} about {w}" for i, w in enumerate(["sofa", "bed", "chair", "lamp"] * 10)]
    rng = np.random.default_rng(0)
    moved = CallableEncoder(lambda t: base.encode(t) + 1e-6 * rng.standard_normal((len(t), 128)),
                            base.model_id, 128)
    a = fit_reduction(base, 16, texts, cache=False)
    b = fit_reduction(moved, 16, texts, cache=False)
    assert a.id == b.id == f"svd16-fit-{corpus_digest(texts)[:12]}"
    np.testing.assert_allclose(np.abs(a.components @ b.components.T), np.eye(16), atol=1e-3)
    # a projection stored on disk under that name is read back with it
    stored = fit_reduction(base, 16, texts, cache_dir=tmp_path)
    assert fit_reduction(base, 16, texts, cache_dir=tmp_path).id == stored.id == a.id


@MINILM
def test_the_shipped_basis_is_of_the_shipped_texts():
    """The shipped basis was fitted on today's database (its texts' digest), MiniLM's, with orthonormal
    rows; refitted here it spans the same 64-d subspace (the shipped file decides, not the refit)."""
    basis = shipped_basis()
    texts = reduction_corpus()
    assert basis["corpus_digest"] == corpus_digest(texts), \
        "the database's texts changed: run stairenv.screenplays.embeddings.write_shipped_basis()"
    assert basis["model_id"] == emb_mod.MiniLMEncoder.MODEL_ID
    comps = basis["components"].astype(np.float64)
    assert comps.shape == (384, 384)
    np.testing.assert_allclose(comps[:64] @ comps[:64].T, np.eye(64), atol=1e-5)
    refit = emb_mod.SubspaceProjection.fit(emb_mod.MiniLMEncoder().encode(texts), 64)
    overlap = comps[:64] @ refit.components.T.astype(np.float64)   # rotation between the two bases
    assert np.linalg.svd(overlap, compute_uv=False).min() > 0.999


@MINILM
def test_the_encoder_id_and_embeddings_survive_another_cpu(tmp_path, another_cpu):
    """With MiniLM's outputs moved by 1e-6 the default 64-d encoder keeps its id (the model and the
    shipped basis's digest) and gives embeddings within 1e-4 of the unmoved ones."""
    texts = ["walks slowly with the head bowed", "hurries over, leaning forward", "sits down on the sofa"]
    here = get_encoder("minilm", dim=64, cache=False)
    before = here.encode(texts)
    another_cpu(tmp_path)
    there = get_encoder("minilm", dim=64, cache=False)
    assert there.model_id == here.model_id
    assert there.model_id == f"all-MiniLM-L6-v2+{shipped_projection('all-MiniLM-L6-v2', 64).id}"
    assert np.abs(there.encode(texts) - before).max() < 1e-4
    assert not np.array_equal(there.encode(texts), before)   # the outputs did move


@MINILM
def test_the_shipped_walker_loads_and_acts_alike_on_another_cpu(tmp_path, another_cpu):
    """The shipped SIMS walker records its encoder's id and its captions' embeddings; with MiniLM's
    outputs moved by 1e-6 it still loads (ids equal, embeddings within the tolerance), and on the same
    observations but for the moved text embedding its actions agree within 1e-3."""
    policy = load("SIMS-Walk-v0")
    recorded = policy.config["text_embeddings"]
    assert len(recorded) > 10 and all(len(v) == 64 for v in recorded.values())
    env = gym.make("SIMS-Walk-v0", **with_trained_captions({"max_episode_steps": 40}, policy))
    obs, _ = env.reset(seed=5)
    observations = [obs]
    for _ in range(39):
        obs, *_ = env.step(policy(obs))
        observations.append(obs)
    caption = env.unwrapped.caption
    env.close()
    another_cpu(tmp_path)
    moved = load("SIMS-Walk-v0")
    env = gym.make("SIMS-Walk-v0")
    z = env.unwrapped.embed_text(caption)
    env.close()
    x = np.array(observations)
    dim = len(z)
    # the env's embedding here against the one recorded on the machine that exported the walker: within
    # what the loader allows (another CPU's MiniLM differs in the low bits), not the 1e-6 of this machine
    np.testing.assert_allclose(x[:, -dim:], np.broadcast_to(recorded[caption], (len(x), dim)),
                               atol=pretrained.TEXT_EMBEDDING_TOLERANCE, rtol=0)
    x_moved = x.copy()
    x_moved[:, -dim:] = z
    assert np.abs(x_moved - x).max() > 0                         # the embedding moved
    assert np.abs(moved(x_moved) - policy(x)).max() < 1e-3


def _walker_arrays(**config_changes):
    arrays = dict(np.load(shipped_policy_path("SIMS-Walk-v0")))
    config = json.loads(str(arrays["config"]))
    config.update(config_changes)
    arrays["config"] = np.array(json.dumps(config))
    return arrays, config


def _install(tmp_path, monkeypatch, arrays):
    path = tmp_path / "SIMS-Walk-v0.npz"
    np.savez(path, **arrays)
    monkeypatch.setattr(pretrained, "shipped_policy_path", lambda env_id: path)
    return path


@MINILM
def test_a_recorded_embedding_is_compared_within_a_tolerance(tmp_path, monkeypatch):
    """A caption's recorded embedding moved by 1e-4 (within the tolerance) loads; moved by 0.05 (another
    projection) it is refused, naming the caption and the gap; a malformed record is named."""
    arrays, config = _walker_arrays()
    caption = sorted(config["text_embeddings"])[0]
    vector = np.asarray(config["text_embeddings"][caption])
    for shift, refused in ((1e-4, False), (0.05, True)):
        arrays, _ = _walker_arrays(text_embeddings={caption: list(vector + shift)})
        _install(tmp_path, monkeypatch, arrays)
        if refused:
            with pytest.raises(PolicyFileError, match="embeds the caption .* away from the embedding"):
                load("SIMS-Walk-v0")
        else:
            assert load("SIMS-Walk-v0").config["text_embeddings"][caption][0] == pytest.approx(vector[0] + shift)
    arrays, _ = _walker_arrays(text_embeddings={caption: [0.0] * 3})
    _install(tmp_path, monkeypatch, arrays)
    with pytest.raises(PolicyFileError, match="text_embeddings must map captions to lists of 64 numbers"):
        load("SIMS-Walk-v0")


@MINILM
def test_an_id_from_a_run_time_fit_says_how_to_mend_it(tmp_path, monkeypatch):
    """A policy recording an id that hashed a projection fitted at run time (before 2026-12-07) is
    refused with the way out: export it again from its checkpoint."""
    arrays, _ = _walker_arrays(text_encoder_id="all-MiniLM-L6-v2+svd64-4f4ff26baa3b")
    _install(tmp_path, monkeypatch, arrays)
    with pytest.raises(PolicyFileError, match="fitted at run time.*export the policy again"):
        load("SIMS-Walk-v0")
