"""numpy's pickled names as inert stand-ins, for unpicklers that must not run code from a file.

A pickle of numpy arrays calls ``numpy.core.multiarray._reconstruct`` (which allocates the declared
shape), ``numpy.dtype``, ``ndarray.__setstate__`` and, for scalars, ``multiarray.scalar``. An unpickler
whose ``find_class`` resolves those names (``numpy_globals``) to the stand-ins here, and nothing else it
does not allow, builds no array and calls nothing: ``pickled_array`` then makes the array from its own
bytes once its shape, type and data agree. Used by the SB3 ``VecNormalize`` statistics reader
(``stairenv.policy_loading``) and the poselib ``.npy`` importer (``stairenv.motion.importers.isaac_npy``).
"""

from __future__ import annotations

import re
from typing import Any

import numpy as np

#: numpy's type codes of numbers: bool, integers, floats
NUMBER_CODES = re.compile(r"b1|[iu][1248]|f[248]")
#: the same and objects (``O8``: a container's elements, built by the unpickler itself)
NUMBER_OR_OBJECT_CODES = re.compile(r"b1|[iu][1248]|f[248]|O8")
#: the most dimensions an array read here may have
MAX_DIMENSIONS = 8


class PickledDtype:
    """Stands in for ``numpy.dtype``: the type code and byte order only."""

    def __init__(self, code: object = None, align: object = False, copy: object = False) -> None:
        self.code, self.byteorder = code, "="

    def __setstate__(self, state: object) -> None:
        if isinstance(state, tuple) and len(state) > 1 and state[1] in ("<", ">"):
            self.byteorder = state[1]

    def resolve(self, codes: re.Pattern = NUMBER_CODES) -> np.dtype:
        """The dtype, if its code is one of ``codes`` (else ``ValueError``)."""
        if not (isinstance(self.code, str) and codes.fullmatch(self.code)):
            raise ValueError(f"unsupported array type {self.code!r}")
        return np.dtype(self.code).newbyteorder(self.byteorder)


class PickledArray:
    """Stands in for ``numpy.ndarray``: its pickled state, made an array by :func:`pickled_array`."""

    def __init__(self, state: object = None) -> None:
        self.state = state

    def __setstate__(self, state: object) -> None:
        self.state = state


def _reconstruct(subtype: object, shape: object, typecode: object) -> PickledArray:
    return PickledArray()  # numpy's allocates ``shape``; nothing is allocated before the bytes are checked


def _frombuffer(buffer: object, dtype: object, shape: object, order: object) -> PickledArray:
    return PickledArray((1, shape, dtype, order == "F", bytes(buffer) if isinstance(buffer, (bytes, bytearray))
                         else None))


def _scalar(dtype: object, data: object = None) -> np.generic:
    """numpy's ``scalar(dtype, bytes)``: one bool, integer or float from its bytes."""
    resolved = dtype.resolve() if isinstance(dtype, PickledDtype) else None
    if resolved is None or not isinstance(data, bytes) or len(data) != resolved.itemsize:
        raise ValueError("malformed numpy scalar")
    return np.frombuffer(data, resolved)[0]


def numpy_globals(frombuffer: bool = False) -> dict[tuple[str, str], Any]:
    """``(module, name) -> stand-in`` for numpy's arrays, dtypes and scalars (both ``numpy.core`` and
    ``numpy._core`` spellings); with ``frombuffer`` also ``numeric._frombuffer`` (numpy 2's pickles of
    arrays with a buffer protocol)."""
    names: dict[tuple[str, str], Any] = {("numpy", "ndarray"): PickledArray, ("numpy", "dtype"): PickledDtype}
    for core in ("core", "_core"):
        names[(f"numpy.{core}.multiarray", "_reconstruct")] = _reconstruct
        names[(f"numpy.{core}.multiarray", "scalar")] = _scalar
        if frombuffer:
            names[(f"numpy.{core}.numeric", "_frombuffer")] = _frombuffer
    return names


def pickled_array(value: object, what: str = "array", codes: re.Pattern = NUMBER_CODES) -> np.ndarray:
    """The array a :class:`PickledArray` describes, once its shape (at most ``MAX_DIMENSIONS``), type (one of
    ``codes``) and data agree (``ValueError`` naming ``what`` otherwise). An object array's elements are the
    unpickler's own objects, one per entry."""
    state = value.state if isinstance(value, PickledArray) else None
    if not (isinstance(state, tuple) and len(state) == 5 and isinstance(state[2], PickledDtype)):
        raise ValueError(f"{what} is not a numpy array")
    _, shape, dtype, fortran, data = state
    if not (isinstance(shape, tuple) and len(shape) <= MAX_DIMENSIONS
            and all(type(n) is int and n >= 0 for n in shape)):
        raise ValueError(f"{what}: malformed array shape {shape!r}")
    resolved = dtype.resolve(codes)
    count = int(np.prod(shape, dtype=object))  # python ints: no overflow
    order = "F" if fortran else "C"
    if resolved.hasobject:
        if not (isinstance(data, list) and len(data) == count):
            raise ValueError(f"{what}: an object array of shape {shape} does not match its data")
        out = np.empty(count, dtype=object)
        for i, item in enumerate(data):
            out[i] = item
        return out.reshape(shape, order=order)
    if not (isinstance(data, (bytes, bytearray)) and len(data) == count * resolved.itemsize):
        raise ValueError(f"{what}: an array of shape {shape} and type {resolved} does not match its data")
    return np.frombuffer(bytes(data), resolved).reshape(shape, order=order).copy()
