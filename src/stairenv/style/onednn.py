"""oneDNN matrix products for the AMP discriminator (torch).

``onednn_linear`` calls oneDNN's linear kernel directly (dense or pre-packed weights, an
optional fused activation); ``matmul`` and ``linear`` route a product to it where it is worth
it and are differentiable any number of times (their backward is made of ``matmul`` again),
so the gradient penalty's double backward runs on oneDNN too. Everything is float32 and equals
the plain torch (ATen) path up to rounding. Which back-end trains is chosen by
:func:`use_onednn`: ``"onednn"``, ``"aten"``, or ``"auto"`` (oneDNN where it works here;
``STAIRENV_AMP_BACKEND=aten`` forces plain torch for every discriminator left at "auto").
"""

from __future__ import annotations

import os

import torch
from torch import nn
from torch.nn import functional as F

from stairenv.validation import check_choice

__all__ = ["BACKENDS", "MIN_ONEDNN_DIM", "linear", "matmul", "onednn_available", "onednn_linear", "use_onednn"]

BACKENDS = ("auto", "onednn", "aten")
# Below this size in any dimension a product goes to ATen: oneDNN's setup costs more than it saves.
MIN_ONEDNN_DIM = 16
_onednn_ok: bool | None = None


def onednn_linear(x: torch.Tensor, weight: torch.Tensor, bias: torch.Tensor | None = None,
                  act: str = "none") -> torch.Tensor:
    """x @ weight.T + bias (then ``act``) by oneDNN; ``weight`` dense (out, in) or pre-packed."""
    return torch.ops.mkldnn._linear_pointwise(x, weight, bias, act, [None], "")


def onednn_available() -> bool:
    """Whether this torch's oneDNN linear kernels exist and agree with ATen (probed once)."""
    global _onednn_ok
    if _onednn_ok is None:
        try:
            gen = torch.Generator().manual_seed(0)
            a = torch.randn(40, 24, generator=gen)
            w = torch.randn(20, 24, generator=gen)
            b = torch.randn(20, generator=gen)
            c = torch.randn(40, 20, generator=gen)
            with torch.no_grad():
                packed = torch.ops.mkldnn._reorder_linear_weight(w, 8)
                checks = [
                    (onednn_linear(a, w, b, "relu"), torch.relu(F.linear(a, w, b))),
                    (onednn_linear(a[:5], packed, b, "relu"), torch.relu(F.linear(a[:5], w, b))),
                    (onednn_linear(a.t(), c.t()), a.t() @ c),  # transposed (strided) operands
                ]
            _onednn_ok = bool(torch.backends.mkldnn.is_available()) and all(
                x.shape == y.shape and torch.allclose(x, y, rtol=1e-4, atol=1e-4) for x, y in checks)
        except Exception:  # noqa: BLE001  (no oneDNN or a torch without these ops: ATen does it)
            _onednn_ok = False
    return _onednn_ok


def use_onednn(backend: str) -> bool:
    """``backend``: "onednn", "aten", or "auto" (oneDNN if it works here; ``STAIRENV_AMP_BACKEND`` overrides)."""
    check_choice("backend", backend, BACKENDS)
    if backend == "auto":
        backend = check_choice("STAIRENV_AMP_BACKEND", os.environ.get("STAIRENV_AMP_BACKEND", "auto"), BACKENDS)
    if backend == "aten":
        return False
    if not onednn_available():
        if backend == "onednn":
            raise RuntimeError("backend='onednn' but this torch has no working oneDNN linear kernels")
        return False
    return True


def _onednn_shape(dtype: torch.dtype, *dims: int) -> bool:
    return dtype == torch.float32 and min(dims) >= MIN_ONEDNN_DIM


class _MatMul(torch.autograd.Function):
    """``a @ b`` by oneDNN. Its backward is made of ``matmul`` again, so it can be
    differentiated any number of times (the gradient penalty needs a double backward)."""

    @staticmethod
    def forward(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
        return onednn_linear(a, b.t())

    @staticmethod
    def setup_context(ctx, inputs, output) -> None:
        ctx.save_for_backward(*inputs)

    @staticmethod
    def backward(ctx, grad: torch.Tensor):
        a, b = ctx.saved_tensors
        grad_a = matmul(grad, b.t(), True) if ctx.needs_input_grad[0] else None
        grad_b = matmul(a.t(), grad, True) if ctx.needs_input_grad[1] else None
        return grad_a, grad_b


def matmul(a: torch.Tensor, b: torch.Tensor, onednn: bool) -> torch.Tensor:
    """``a @ b`` for 2-D tensors, by oneDNN when asked and worth it, else ATen; differentiable."""
    if onednn and _onednn_shape(a.dtype, a.shape[0], a.shape[1], b.shape[1]) and b.dtype == a.dtype:
        return _MatMul.apply(a, b)
    return a @ b


class _Linear(torch.autograd.Function):
    """``F.linear`` by oneDNN, differentiable any number of times (via ``matmul``)."""

    @staticmethod
    def forward(x: torch.Tensor, weight: torch.Tensor, bias: torch.Tensor) -> torch.Tensor:
        return onednn_linear(x, weight, bias)

    @staticmethod
    def setup_context(ctx, inputs, output) -> None:
        x, weight, _ = inputs
        ctx.save_for_backward(x, weight)

    @staticmethod
    def backward(ctx, grad: torch.Tensor):
        x, weight = ctx.saved_tensors
        grad_x = matmul(grad, weight, True) if ctx.needs_input_grad[0] else None
        grad_w = matmul(grad.t(), x, True) if ctx.needs_input_grad[1] else None
        grad_b = grad.sum(0) if ctx.needs_input_grad[2] else None
        return grad_x, grad_w, grad_b


def linear(x: torch.Tensor, layer: nn.Linear, onednn: bool) -> torch.Tensor:
    """``layer(x)`` for a batch (N, in), by oneDNN when asked and worth it; differentiable."""
    w = layer.weight
    if onednn and x.dim() == 2 and _onednn_shape(x.dtype, x.shape[0], w.shape[0], w.shape[1]):
        return _Linear.apply(x, w, layer.bias)
    return F.linear(x, w, layer.bias)
