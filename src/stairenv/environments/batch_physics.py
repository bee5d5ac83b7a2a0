"""The physics of many worlds in one call: the one interface a batched env steps its worlds through.

``BatchPhysics.step(worlds, nstep, then, meanwhile, collect)`` advances every ``(model, data)`` of
``worlds`` by ``nstep`` physics steps. Around the physics, three optional callbacks let the batched env
do its Python work while the physics runs:

- ``then(k)``: once per world, right after that world's physics, from any thread (the per-world
  finish of envs without batched step outcomes: its Python overlaps other worlds' physics);
- ``meanwhile()``: once, in the calling thread, while the physics runs; it must not wait for the
  physics (the batched env resets there the worlds whose episode ended, which ``worlds`` does not hold);
- ``collect(ks)``: in the calling thread, after ``meanwhile``, with lists of worlds whose physics (and
  ``then``) is done, each world in exactly one list; it may run while other worlds' physics still runs
  (the batched env computes the task's step outcomes over each list in one call, so that this overlaps the
  physics of the worlds still stepping).

``step`` returns when every callback has returned. Each world keeps its own ``MjModel`` (InterLevel
writes its staircase into it) and ``MjData`` (its warm start included), so a world stepped here is
bit-identical to the same world stepped alone by ``mujoco.mj_step``. The GPU back-end (MuJoCo Warp,
``warp_physics.WarpPhysics``) launches the whole batch, runs ``meanwhile``, then calls ``then`` for each
world and ``collect`` once with all of them; it also has ``bind(worlds)`` (every world of the batch, once)
and ``world_reset(k)`` (world k was reset on the host), which the batched env calls where they exist.
"""

from __future__ import annotations

import itertools
import os
import queue
import threading
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import Protocol

import mujoco

World = tuple[mujoco.MjModel, mujoco.MjData]


class BatchPhysics(Protocol):
    """Steps a batch of worlds (see the module docstring)."""

    def step(self, worlds: Sequence[World], nstep: int, then: Callable[[int], None] | None = None,
             meanwhile: Callable[[], None] | None = None,
             collect: Callable[[list[int]], None] | None = None) -> None:
        ...

    def close(self) -> None:
        ...


class SerialPhysics:
    """One world after the other in the calling thread (the reference; one core)."""

    def step(self, worlds: Sequence[World], nstep: int, then: Callable[[int], None] | None = None,
             meanwhile: Callable[[], None] | None = None,
             collect: Callable[[list[int]], None] | None = None) -> None:
        if meanwhile is not None:
            meanwhile()
        for k, (model, data) in enumerate(worlds):
            mujoco.mj_step(model, data, nstep)
            if then is not None:
                then(k)
        if collect is not None and worlds:
            collect(list(range(len(worlds))))

    def close(self) -> None:
        pass


class ThreadPoolPhysics:
    """A persistent pool of ``nthread`` threads (default ``os.cpu_count()``) that take the worlds one at a
    time, in order, from a shared counter (worlds differ in cost: a fallen character's contacts cost
    three times a standing one's, so fixed shares leave a thread idle) and run
    ``mujoco.mj_step(model, data, nstep)`` (GIL released) and ``then``. The calling thread runs
    ``meanwhile``, then ``collect`` over the finished worlds in groups of at least ``group`` worlds
    (default an eighth of the batch; the last group may be smaller), while the pool steps the rest."""

    def __init__(self, nthread: int | None = None, group: int | None = None) -> None:
        self.nthread = max(1, int(nthread or os.cpu_count() or 1))
        if group is not None and (isinstance(group, bool) or not isinstance(group, int) or group < 1):
            raise ValueError(f"group must be None or a positive integer, got {group!r}")
        self.group = group
        self._pool = ThreadPoolExecutor(self.nthread, thread_name_prefix="stairenv-physics") \
            if self.nthread > 1 else None
        self._lock = threading.Lock()

    def step(self, worlds: Sequence[World], nstep: int, then: Callable[[int], None] | None = None,
             meanwhile: Callable[[], None] | None = None,
             collect: Callable[[list[int]], None] | None = None) -> None:
        n = len(worlds)
        if self._pool is None or n < 2:
            SerialPhysics().step(worlds, nstep, then, meanwhile, collect)
            return
        claims = itertools.count()    # next() is atomic under the GIL
        done: queue.SimpleQueue[int | None] = queue.SimpleQueue()

        def work() -> None:
            try:
                while (k := next(claims)) < n:
                    model, data = worlds[k]
                    mujoco.mj_step(model, data, nstep)
                    if then is not None:
                        then(k)
                    if collect is not None:
                        done.put(k)
            except BaseException:
                done.put(None)    # wakes the collecting caller, which then re-raises
                raise

        with self._lock:    # one batch at a time per pool
            futures = [self._pool.submit(work) for _ in range(min(self.nthread, n))]
            try:
                if meanwhile is not None:
                    meanwhile()
                if collect is not None:
                    self._collect(done, n, collect)
            finally:
                for future in futures:
                    future.exception()    # all done before anything is raised
            for future in futures:
                future.result()    # re-raises a worker's exception

    def _collect(self, done: queue.SimpleQueue, n: int, collect: Callable[[list[int]], None]) -> None:
        group = self.group or max(1, n // 8)
        remaining, pending = n, []
        while remaining:
            k = done.get()
            while k is not None:
                pending.append(k)
                try:
                    k = done.get_nowait()
                except queue.Empty:
                    break
            if k is None:
                return    # a worker failed: step re-raises its exception
            if len(pending) >= min(group, remaining):
                remaining -= len(pending)
                collect(pending)
                pending = []

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None


#: back-ends by name: "mujoco" (the default; the thread pool of MuJoCo's C library, also called
#: "threads"), "serial" (one world after the other, one core) and "warp" (MuJoCo Warp on a GPU or on
#: Warp's CPU device: ``stairenv.environments.warp_physics``; needs the ``gpu`` extra)
PHYSICS_BACKENDS = ("mujoco", "threads", "serial", "warp")


def make_physics(backend: str | BatchPhysics = "mujoco", nthread: int | None = None,
                 device: str | None = None, state_on_device: bool = False) -> BatchPhysics:
    """A back-end by name (``PHYSICS_BACKENDS``) or an object that already implements ``BatchPhysics``.
    ``nthread``: the threads of the "mujoco" pool (default ``os.cpu_count()``); the other back-ends
    take none. ``device``: the Warp device of "warp" ("cuda:1", "cpu"; default Warp's first GPU, else its
    CPU device; a data-parallel rank passes its own GPU); the C back-ends run on the host only.
    ``state_on_device``: "warp" keeps the state on the device between resets (``WarpPhysics``)."""
    check_physics_device(backend, device)
    check_state_on_device(backend, state_on_device)
    if not isinstance(backend, str):
        return backend
    if backend not in PHYSICS_BACKENDS:
        raise ValueError(f"physics must be one of {list(PHYSICS_BACKENDS)} or a BatchPhysics, got {backend!r}")
    if nthread is not None and (isinstance(nthread, bool) or not isinstance(nthread, int) or nthread < 1):
        raise ValueError(f"physics_threads must be None or a positive integer, got {nthread!r}")
    if backend == "warp":
        from stairenv.environments.warp_physics import WarpPhysics
        return WarpPhysics(device=device, state_on_device=state_on_device)
    return ThreadPoolPhysics(nthread) if backend in ("mujoco", "threads") else SerialPhysics()


def check_physics_device(backend: str | BatchPhysics, device: str | None) -> None:
    """``physics_device``: None, or a device name with ``physics="warp"`` (the C back-ends run on the host,
    a ``BatchPhysics`` object has its device already)."""
    if device is None:
        return
    if not isinstance(device, str) or not device:
        raise TypeError(f"physics_device must be None or a device name such as 'cuda:0', got {device!r}")
    if backend != "warp":
        raise ValueError(f"physics_device={device!r} is for physics='warp' only; physics={backend!r} chooses "
                         "its own device")


def check_state_on_device(backend: str | BatchPhysics, state_on_device: bool) -> None:
    """``state_on_device``: True or False, True with ``physics="warp"`` only (the C back-ends step each
    world's ``MjData`` on the host; a ``BatchPhysics`` object is built with its own setting)."""
    if not isinstance(state_on_device, bool):
        raise TypeError(f"state_on_device must be True or False, got {state_on_device!r}")
    if state_on_device and backend != "warp":
        raise ValueError(f"state_on_device=True is for physics='warp' only (the C back-ends step each world's "
                         f"MjData on the host; a back-end object takes its own setting); got physics={backend!r}")
