"""The physics of many worlds in one call: the one interface a batched env steps its worlds through.

``BatchPhysics.step(worlds, nstep, then, meanwhile)`` advances every ``(model, data)`` of ``worlds`` by
``nstep`` physics steps and calls ``then(k)`` for the k-th world once its physics is done, and
``meanwhile()`` once in the calling thread while the physics runs (work on other worlds: the batched
env resets there the worlds whose episode ended, which ``worlds`` does not hold). Each world keeps its
own ``MjModel`` (InterLevel writes its staircase into it) and ``MjData`` (its warm start included), so a
world stepped here is bit-identical to the same world stepped alone by ``mujoco.mj_step``.

``then`` is where the batched env finishes a world's step (divergence check, evaluation). An
implementation may call it from any thread and in any order, but once per world and only after that
world's physics; ``step`` returns when every ``then`` and ``meanwhile`` has returned. A GPU back-end
(MuJoCo Warp) would launch the whole batch, run ``meanwhile``, then call ``then`` for each world; ``ThreadPoolPhysics`` calls it in the
worker thread right after the world's ``mj_step``, so that one world's Python-side finish overlaps
other worlds' physics (``mj_step`` releases the GIL).
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import Protocol

import mujoco

World = tuple[mujoco.MjModel, mujoco.MjData]


class BatchPhysics(Protocol):
    """Steps a batch of worlds (see the module docstring)."""

    def step(self, worlds: Sequence[World], nstep: int, then: Callable[[int], None] | None = None,
             meanwhile: Callable[[], None] | None = None) -> None:
        ...

    def close(self) -> None:
        ...


class SerialPhysics:
    """One world after the other in the calling thread (the reference; one core)."""

    def step(self, worlds: Sequence[World], nstep: int, then: Callable[[int], None] | None = None,
             meanwhile: Callable[[], None] | None = None) -> None:
        if meanwhile is not None:
            meanwhile()
        for k, (model, data) in enumerate(worlds):
            mujoco.mj_step(model, data, nstep)
            if then is not None:
                then(k)

    def close(self) -> None:
        pass


class ThreadPoolPhysics:
    """A persistent pool of ``nthread`` threads (default ``os.cpu_count()``), each running
    ``mujoco.mj_step(model, data, nstep)`` (GIL released) over its contiguous share of the worlds, and
    ``then`` after each world."""

    def __init__(self, nthread: int | None = None) -> None:
        self.nthread = max(1, int(nthread or os.cpu_count() or 1))
        self._pool = ThreadPoolExecutor(self.nthread, thread_name_prefix="stairenv-physics") \
            if self.nthread > 1 else None
        self._lock = threading.Lock()

    def step(self, worlds: Sequence[World], nstep: int, then: Callable[[int], None] | None = None,
             meanwhile: Callable[[], None] | None = None) -> None:
        if self._pool is None or len(worlds) < 2:
            SerialPhysics().step(worlds, nstep, then, meanwhile)
            return

        def share(start: int, stop: int) -> None:
            for k in range(start, stop):
                model, data = worlds[k]
                mujoco.mj_step(model, data, nstep)
                if then is not None:
                    then(k)

        n = len(worlds)
        parts = min(self.nthread, n)
        bounds = [n * p // parts for p in range(parts + 1)]
        with self._lock:    # one batch at a time per pool
            futures = [self._pool.submit(share, bounds[p], bounds[p + 1]) for p in range(parts)]
            try:
                if meanwhile is not None:
                    meanwhile()
            finally:
                for future in futures:
                    future.exception()    # all done before anything is raised
            for future in futures:
                future.result()    # re-raises a worker's exception

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None


PHYSICS_BACKENDS = {"threads": ThreadPoolPhysics, "serial": SerialPhysics}


def make_physics(backend: str | BatchPhysics = "threads", nthread: int | None = None) -> BatchPhysics:
    """A back-end by name ("threads", "serial") or an object that already implements ``BatchPhysics``."""
    if not isinstance(backend, str):
        return backend
    if backend not in PHYSICS_BACKENDS:
        raise ValueError(f"physics must be one of {sorted(PHYSICS_BACKENDS)} or a BatchPhysics, got {backend!r}")
    return ThreadPoolPhysics(nthread) if backend == "threads" else SerialPhysics()
