"""Reference samples for the discriminator: K-frame feature windows of a motion library."""

from __future__ import annotations

import numpy as np

from stairenv.motion.library import MotionLibrary
from stairenv.style.features import AMP_FEATURE_SIZE, reference_features


class ReferenceWindows:
    """Every K-frame window of every clip, at the env's control rate, flattened oldest first.

    Windows are drawn with each clip's library weight spread evenly over its windows.
    A clip shorter than K frames is padded at the front with its first frame.
    """

    def __init__(self, library: MotionLibrary, num_frames: int = 2, fps: float = 30.0) -> None:
        if num_frames < 1:
            raise ValueError(f"num_frames must be >= 1, got {num_frames}")
        self.num_frames = int(num_frames)
        self.fps = float(fps)
        windows, weights = [], []
        for clip, prob in zip(library.clips, library.probabilities):
            feats = reference_features(clip, fps)
            if len(feats) < num_frames:
                feats = np.concatenate((np.repeat(feats[:1], num_frames - len(feats), axis=0), feats))
            count = len(feats) - num_frames + 1
            idx = np.arange(count)[:, None] + np.arange(num_frames)[None, :]
            windows.append(feats[idx].reshape(count, num_frames * AMP_FEATURE_SIZE))
            weights.append(np.full(count, prob / count))
        self.windows = np.concatenate(windows).astype(np.float32)
        weights = np.concatenate(weights)
        self.probabilities = weights / weights.sum()

    @property
    def dim(self) -> int:
        return self.windows.shape[1]

    def __len__(self) -> int:
        return len(self.windows)

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        return self.windows[rng.choice(len(self.windows), size=n, p=self.probabilities)]
