"""The numba decorator shared by the compiled kernels (task functions, style features, planning).

``@jit``: compiled on first call, cached on disk next to the module (``cache=True``), and
releasing the GIL while it runs (``nogil=True``). Kernels that need other options (fastmath,
parallel) call :func:`numba.njit` themselves.
"""

from __future__ import annotations

from numba import njit

__all__ = ["jit"]

jit = njit(cache=True, nogil=True)
