"""A weighted set of clips that yields reference states at sampled times."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from stairenv.motion.clip import MotionClip


class MotionLibrary:
    """Many clips with sampling weights.

    ``sample(n, rng)`` draws (clip, time) pairs: a clip with probability
    proportional to its weight, a time uniform over its duration.
    ``states(clip_ids, times)`` returns interpolated ``qpos`` (N, 35) and ``qvel`` (N, 34).
    """

    def __init__(self, clips: Sequence[MotionClip], weights: Sequence[float] | None = None) -> None:
        if len(clips) == 0:
            raise ValueError("a MotionLibrary needs at least one clip")
        weights = np.ones(len(clips)) if weights is None else np.asarray(weights, dtype=np.float64)
        if weights.shape != (len(clips),):
            raise ValueError(f"weights must have one entry per clip ({len(clips)}), got shape {weights.shape}")
        if not np.all(np.isfinite(weights)) or np.any(weights < 0) or weights.sum() <= 0:
            raise ValueError(f"weights must be finite, >= 0 and not all zero, got {weights.tolist()}")
        self.clips = list(clips)
        self.probabilities = weights / weights.sum()
        self._qvel = [clip.qvel() for clip in self.clips]

    @classmethod
    def load(cls, paths: str | Path | Sequence[str | Path], weights: Sequence[float] | None = None) -> "MotionLibrary":
        """Clips from ``.npz`` files, or every ``.npz`` in a folder."""
        if isinstance(paths, (str, Path)) and Path(paths).is_dir():
            files = sorted(Path(paths).glob("*.npz"))
            if not files:
                raise ValueError(f"no .npz clips in {paths}")
        else:
            files = [Path(p) for p in ([paths] if isinstance(paths, (str, Path)) else paths)]
        return cls([MotionClip.load(f) for f in files], weights)

    def __len__(self) -> int:
        return len(self.clips)

    @property
    def names(self) -> list[str]:
        return [c.name for c in self.clips]

    def sample(self, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """``n`` (clip id, time) pairs."""
        clip_ids = rng.choice(len(self.clips), size=n, p=self.probabilities)
        durations = np.array([self.clips[i].duration for i in clip_ids])
        return clip_ids, rng.uniform(0.0, 1.0, n) * durations

    def states(self, clip_ids: np.ndarray, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Interpolated qpos (N, 35) and qvel (N, 34) of each (clip, time)."""
        clip_ids = np.atleast_1d(clip_ids)
        times = np.atleast_1d(np.asarray(times, dtype=np.float64))
        qpos = np.empty((len(clip_ids), self.clips[0].qpos.shape[1]))
        qvel = np.empty((len(clip_ids), self._qvel[0].shape[1]))
        for cid in np.unique(clip_ids):
            rows = np.flatnonzero(clip_ids == cid)
            clip = self.clips[cid]
            qpos[rows] = clip.sample(times[rows])
            qvel[rows] = _interp_rows(self._qvel[cid], times[rows], clip)
        return qpos, qvel


def _interp_rows(frames: np.ndarray, times: np.ndarray, clip: MotionClip) -> np.ndarray:
    if clip.num_frames == 1:
        return np.repeat(frames, len(times), axis=0)
    t = np.mod(times, clip.duration) if clip.loop else np.clip(times, 0.0, clip.duration)
    f = t * clip.fps
    i0 = np.minimum(np.floor(f).astype(int), clip.num_frames - 2)
    alpha = (f - i0)[:, None]
    return (1.0 - alpha) * frames[i0] + alpha * frames[i0 + 1]
