"""Compiled kernels of the importers, imported only for long clips (numba's first load costs ~1 s)."""

from __future__ import annotations

import numpy as np

from stairenv.numba_jit import jit


@jit
def viterbi2(error: np.ndarray, step: np.ndarray) -> np.ndarray:
    """The cheapest choice per frame of two candidates: ``error`` (T, 2) per frame, ``step`` (T - 1, 2, 2)
    from the previous frame's choice to this one's; ties and NaN go as ``np.argmin`` takes them (the
    same double operations, in the same order, as ``importers.common._viterbi2``)."""
    n = error.shape[0]
    back = np.zeros((n, 2), dtype=np.int64)
    cost0, cost1 = error[0, 0], error[0, 1]
    for t in range(1, n):
        a = cost0 + step[t - 1, 0, 0]
        b = cost1 + step[t - 1, 1, 0]
        k0 = 0 if a != a else (1 if b != b or b < a else 0)
        c = cost0 + step[t - 1, 0, 1]
        d = cost1 + step[t - 1, 1, 1]
        k1 = 0 if c != c else (1 if d != d or d < c else 0)
        back[t, 0], back[t, 1] = k0, k1
        cost0, cost1 = (a if k0 == 0 else b) + error[t, 0], (c if k1 == 0 else d) + error[t, 1]
    choice = np.empty(n, dtype=np.int64)
    k = 0 if cost0 != cost0 else (1 if cost1 != cost1 or cost1 < cost0 else 0)
    choice[n - 1] = k
    for t in range(n - 1, 0, -1):
        k = back[t, k]
        choice[t - 1] = k
    return choice
