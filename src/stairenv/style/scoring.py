"""Scoring back-ends of the AMP discriminator: logits of feature windows from a scoring plan,
without autograd.

A plan (:meth:`stairenv.style.discriminator.AMPDiscriminator.scoring_plan`) holds the
normaliser's float32 mean and std, the layers (``plan["linears"]``, ``plan["relu"]``) and numpy
views of their float32 weights (``plan["numba"]``); the back-ends here cache what they derive
from it in the plan itself (packed, bfloat16 and contiguous copies of the weights), so a new
plan, built when a parameter or statistic changed, starts afresh. Back-ends
(``AMPDiscriminator(scoring=...)``, :data:`SCORERS`):

- ``"numba"``: compiled numba kernels (single-threaded, no BLAS, no torch dispatch), cheapest
  for the few windows of a vectorised step; ``"auto"`` uses it up to
  :data:`NUMBA_MAX_WINDOWS` windows.
- ``"torch"``: torch's kernels in ``torch.inference_mode``, hidden layers pre-packed for
  oneDNN where it is used; ``"auto"`` above :data:`NUMBA_MAX_WINDOWS` windows.
- ``"bf16"``: torch with bfloat16 weights and activations (normalisation in float32).
- ``"numba-parallel"``: each layer's output units split over numba's threads.

A vectorised step's N windows go through one call of a back-end (the wrappers score every
step that way); grouping changes only float32 rounding. The torch back-ends run where the plan's
tensors live (a CUDA plan has no numba views: its discriminator scores with torch). Timings: ``docs/amp-speed.md``.
"""

from __future__ import annotations

import numba
import numpy as np
import torch
from numba import njit, prange
from torch.nn import functional as F

from stairenv.style.onednn import MIN_ONEDNN_DIM, onednn_linear

__all__ = [
    "MIN_PARALLEL_UNITS",
    "NUMBA_MAX_WINDOWS",
    "SCORERS",
    "bf16_layers",
    "dense",
    "dense_parallel",
    "normalise",
    "plan_logits",
    "torch_layers",
]

SCORERS = ("auto", "numba", "numba-parallel", "torch", "bf16")
# "auto" scoring: the numba kernel up to this many windows (a vectorised step), torch's kernels above.
NUMBA_MAX_WINDOWS = 64
# Layers narrower than this are not worth splitting over threads.
MIN_PARALLEL_UNITS = 64

# Reassociation and contraction let the dot products vectorise and fuse; no finite-math
# assumptions, so NaN and inf propagate as in torch.
_FASTMATH = {"reassoc", "contract", "nsz"}


@njit(cache=True, nogil=True, fastmath=_FASTMATH)
def normalise(x, mean, std, clip, out):
    for i in range(x.shape[0]):
        for t in range(x.shape[1]):
            v = (x[i, t] - mean[t]) / std[t]
            out[i, t] = clip if v > clip else (-clip if v < -clip else v)  # noqa: FURB136  (NaN stays NaN)
    return out


@njit(cache=True, nogil=True, fastmath=_FASTMATH)
def _dot(w, x, j, i, k):
    acc = np.float32(0.0)
    for t in range(k):
        acc += w[j, t] * x[i, t]
    return acc


@njit(cache=True, nogil=True, fastmath=_FASTMATH)
def dense(x, w, b, out, relu):
    """out = x @ w.T + b (then ReLU), register-blocked: 2 weight rows x 4 windows per pass,
    so each loaded weight feeds 4 products and each loaded input 2."""
    n, k = x.shape
    m = w.shape[0]
    n4, m2 = n - n % 4, m - m % 2
    for j in range(0, m2, 2):
        w0, w1 = w[j], w[j + 1]
        for i in range(0, n4, 4):
            x0, x1, x2, x3 = x[i], x[i + 1], x[i + 2], x[i + 3]
            a0 = a1 = a2 = a3 = c0 = c1 = c2 = c3 = np.float32(0.0)
            for t in range(k):
                u, v = w0[t], w1[t]
                y0, y1, y2, y3 = x0[t], x1[t], x2[t], x3[t]
                a0 += u * y0
                a1 += u * y1
                a2 += u * y2
                a3 += u * y3
                c0 += v * y0
                c1 += v * y1
                c2 += v * y2
                c3 += v * y3
            out[i, j], out[i + 1, j], out[i + 2, j], out[i + 3, j] = a0, a1, a2, a3
            out[i, j + 1], out[i + 1, j + 1], out[i + 2, j + 1], out[i + 3, j + 1] = c0, c1, c2, c3
        for i in range(n4, n):
            out[i, j] = _dot(w, x, j, i, k)
            out[i, j + 1] = _dot(w, x, j + 1, i, k)
    for j in range(m2, m):
        for i in range(n):
            out[i, j] = _dot(w, x, j, i, k)
    for i in range(n):
        for j in range(m):
            v = out[i, j] + b[j]
            out[i, j] = (np.float32(0.0) if v <= 0.0 else v) if relu else v  # NaN stays NaN, as in torch
    return out


@njit(cache=True, nogil=True, parallel=True, fastmath=_FASTMATH)
def dense_parallel(x, w, b, out, relu, parts):
    """:func:`dense` with the output units split into ``parts`` even blocks, one per thread."""
    m = w.shape[0]
    block = (m // parts + 1) // 2 * 2
    for part in prange(parts):
        j0 = min(m, part * block)
        j1 = m if part == parts - 1 else min(m, j0 + block)
        if j1 > j0:
            tmp = np.empty((x.shape[0], j1 - j0), dtype=np.float32)
            dense(x, w[j0:j1], b[j0:j1], tmp, relu)
            out[:, j0:j1] = tmp
    return out


# --- plans ----------------------------------------------------------------------------------
def bf16_layers(plan: dict) -> list:
    """A plan's layers as (weight, bias, relu) in bfloat16."""
    if plan.get("bf16") is None:
        with torch.inference_mode():
            plan["bf16"] = [(layer.weight.detach().to(torch.bfloat16), layer.bias.detach().to(torch.bfloat16), r)
                            for layer, r in zip(plan["linears"], plan["relu"])]
    return plan["bf16"]


def torch_layers(plan: dict, onednn: bool) -> list:
    """A plan's layers as (weight, bias, relu, packed): with ``onednn``, hidden layers of at least
    ``MIN_ONEDNN_DIM`` units get their weights pre-packed for oneDNN."""
    if plan["torch"] is None:
        layers = []
        with torch.inference_mode():
            for layer, r in zip(plan["linears"], plan["relu"]):
                w, b = layer.weight.detach(), layer.bias.detach()
                packed = onednn and r and min(w.shape) >= MIN_ONEDNN_DIM
                layers.append((torch.ops.mkldnn._reorder_linear_weight(w, 8) if packed else w, b, r, packed))
        plan["torch"] = layers
    return plan["torch"]


# --- back-ends ------------------------------------------------------------------------------
def _normalised(x: np.ndarray, plan: dict, clip: float) -> torch.Tensor:
    """``x`` on the plan's device, normalised and clipped (float32)."""
    return torch.clamp((torch.from_numpy(x).to(plan["mean"].device) - plan["mean"]) / plan["std"], -clip, clip)


def plan_logits(x: np.ndarray, plan: dict, clip: float, scoring: str, onednn: bool,
                threads: int | None = None) -> np.ndarray:
    """Logits (N,) of raw feature windows ``x`` (N, input_dim; float32, contiguous, N > 0) by
    ``plan``, with the back-end ``scoring`` (one of :data:`SCORERS`). ``clip``: the normaliser's
    clip; ``onednn``: whether torch's layers run on oneDNN; ``threads``: "numba-parallel"'s
    thread count (None: numba's)."""
    if scoring == "bf16":
        with torch.inference_mode():
            h = _normalised(x, plan, clip).to(torch.bfloat16)
            for w, b, relu in bf16_layers(plan):
                h = torch.relu(F.linear(h, w, b)) if relu else F.linear(h, w, b)
            return h[:, 0].float().cpu().numpy()
    if scoring == "numba-parallel":
        parts = numba.get_num_threads() if threads is None else threads
        h = normalise(x, plan["mean"].numpy(), plan["std"].numpy(), np.float32(clip), np.empty_like(x))
        for w, b, relu in plan["numba"]:
            out = np.empty((len(h), w.shape[0]), dtype=np.float32)
            if parts > 1 and w.shape[0] >= MIN_PARALLEL_UNITS:
                h = dense_parallel(h, w, b, out, relu, parts)
            else:
                h = dense(h, w, b, out, relu)
        return h[:, 0]
    if scoring == "numba" or (scoring == "auto" and len(x) <= NUMBA_MAX_WINDOWS):
        h = normalise(x, plan["mean"].numpy(), plan["std"].numpy(), np.float32(clip), np.empty_like(x))
        for w, b, relu in plan["numba"]:
            h = dense(h, w, b, np.empty((len(h), w.shape[0]), dtype=np.float32), relu)
        return h[:, 0]
    layers = torch_layers(plan, onednn)
    with torch.inference_mode():
        h = _normalised(x, plan, clip)
        for w, b, relu, packed in layers:
            if packed:
                h = onednn_linear(h, w, b, "relu")
            else:
                h = torch.relu(F.linear(h, w, b)) if relu else F.linear(h, w, b)
        return h[:, 0].cpu().numpy()
