"""Reference samples for the discriminator: K-frame feature windows of a motion library,
optionally each followed by a condition vector of its clip (text-conditioned AMP, as SIMS)."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from stairenv.motion.clip import MotionClip
from stairenv.motion.library import MotionLibrary
from stairenv.style.features import AMP_FEATURE_SIZE, reference_features


def clip_text(clip: MotionClip) -> str:
    """The clip's description: ``meta["text"]``, else its name with underscores as spaces."""
    text = clip.meta.get("text") if isinstance(clip.meta, dict) else None
    return str(text) if text else clip.name.replace("_", " ")


def text_conditions(library: MotionLibrary, embed: Callable[[str], np.ndarray]) -> np.ndarray:
    """One condition row per clip: ``embed`` of :func:`clip_text` (e.g. a SIMS env's ``embed_text``,
    so reference and env captions share one encoder)."""
    rows = [np.asarray(embed(clip_text(clip)), dtype=np.float32).ravel() for clip in library.clips]
    if len({row.shape for row in rows}) != 1:
        raise ValueError(f"embed returned vectors of different sizes: {sorted({row.size for row in rows})}")
    return np.stack(rows)


class ReferenceWindows:
    """Every K-frame window of every clip, at the env's control rate, flattened oldest first.

    Windows are drawn with each clip's library weight spread evenly over its windows.
    A clip shorter than K frames is padded at the front with its first frame.

    ``conditions`` (one row per clip, e.g. :func:`text_conditions`) makes the samples
    ``[window, condition of its clip]``: the discriminator then judges motion given its
    condition, and the wrappers append the env's ``info["amp_condition"]`` to agent windows.
    """

    def __init__(self, library: MotionLibrary, num_frames: int = 2, fps: float = 30.0,
                 conditions: np.ndarray | Sequence[Sequence[float]] | None = None) -> None:
        if num_frames < 1:
            raise ValueError(f"num_frames must be >= 1, got {num_frames}")
        self.num_frames = int(num_frames)
        self.fps = float(fps)
        windows, weights, owners = [], [], []
        for index, (clip, prob) in enumerate(zip(library.clips, library.probabilities)):
            feats = reference_features(clip, fps)
            if len(feats) < num_frames:
                feats = np.concatenate((np.repeat(feats[:1], num_frames - len(feats), axis=0), feats))
            count = len(feats) - num_frames + 1
            idx = np.arange(count)[:, None] + np.arange(num_frames)[None, :]
            windows.append(feats[idx].reshape(count, num_frames * AMP_FEATURE_SIZE))
            weights.append(np.full(count, prob / count))
            owners.append(np.full(count, index))
        self.windows = np.concatenate(windows).astype(np.float32)
        self.clip_index = np.concatenate(owners)
        weights = np.concatenate(weights)
        self.probabilities = weights / weights.sum()
        if conditions is None:
            self.conditions = np.zeros((len(library.clips), 0), dtype=np.float32)
        else:
            self.conditions = np.asarray(conditions, dtype=np.float32)
            if self.conditions.ndim != 2 or len(self.conditions) != len(library.clips):
                raise ValueError(f"conditions must have one row per clip ({len(library.clips)}), "
                                 f"got shape {self.conditions.shape}")
            if not np.all(np.isfinite(self.conditions)):
                raise ValueError("conditions must be finite")

    @property
    def feature_dim(self) -> int:
        """Numbers per motion window (K frames of style features)."""
        return self.windows.shape[1]

    @property
    def condition_dim(self) -> int:
        """Numbers per condition (0: unconditioned)."""
        return self.conditions.shape[1]

    @property
    def dim(self) -> int:
        """The discriminator's input size: window plus condition."""
        return self.feature_dim + self.condition_dim

    def __len__(self) -> int:
        return len(self.windows)

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        rows = rng.choice(len(self.windows), size=n, p=self.probabilities)
        if self.condition_dim == 0:
            return self.windows[rows]
        return np.concatenate((self.windows[rows], self.conditions[self.clip_index[rows]]), axis=1)
