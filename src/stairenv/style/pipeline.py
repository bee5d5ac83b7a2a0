"""Pipelined AMP scoring: each env's window is scored on a second core while the next envs step.

In an in-process vec env (SB3 ``DummyVecEnv``, gymnasium ``SyncVectorEnv``) the envs
step one after another in the calling thread. :func:`set_amp_sink` has a stairenv env
hand its style window to a sink at the end of its ``step`` (the env itself knows nothing
of it); :class:`PipelinedScorer` copies it into a shared buffer and wakes a worker thread,
which scores it with the discriminator's one-window kernel while the next env
steps. When the vec env returns, only the last env's window may still be in
flight, so the forward pass leaves the step loop's critical path.

The worker never holds the GIL: it lives in one compiled (numba, ``nogil``) call.
While envs step it polls the posted counters (a ``sched_yield`` between polls, so
a post costs the envs no system call); after ~5 ms without work it sleeps in a
POSIX semaphore that every post also increments (``sem_post``, whose atomics order
the window before the count). Any Python code in a second thread would stall the
envs: MuJoCo releases the GIL in every ``mj_step`` and may then wait for the
interpreter's switch interval (5 ms) to take it back. For the same reason the
envs' side keeps the GIL in its short calls (``sem_post`` through ``ctypes.PyDLL``,
the final wait, the windows it scores itself).

When the vec env returns, the caller waits ~25 us for the worker, then scores the
windows it has not reached itself, from the last one down. The wrappers pause the
pipeline (``paused``: nothing is posted, the caller scores) while a background
training round runs: three busy threads on two cores cost the envs more than
scoring the step in the calling thread.

Correctness does not depend on timing:

- a logit is used only if the window the worker scored equals the one in the
  step's ``info`` (a wrapper that edits ``amp_obs``, an env that posted nothing, or
  a condition that differs is scored in the calling thread instead);
- the worker reads its own copy of the weights and normaliser, loaded from the
  discriminator's scoring plan between steps; if the plan changed since (training
  outside the wrapper's schedule), the step is scored in the calling thread and
  the copy reloaded;
- both paths run the same one-window kernel (``window_logit``), so the rewards are
  the same bits either way, and equal ``AMPDiscriminator.window_logits``.

A worker that does not answer within ``timeout`` seconds (it never should) makes the
scorer warn, score in the calling thread and stay off from then on.

Linux only (unnamed POSIX semaphores from the C library). ``pipeline="auto"`` in the
wrappers turns it on for in-process vec envs of stairenv envs on x86-64 (whose stores
are seen in program order) with at least two usable cores and numba scoring.
"""

from __future__ import annotations

import ctypes
import os
import platform
import threading
import time
import warnings
import weakref

import gymnasium as gym
import numpy as np
from numba import njit
from stable_baselines3.common.vec_env import DummyVecEnv

from stairenv.style.discriminator import AMPDiscriminator
from stairenv.style.scoring import window_logit

PIPELINE_CHOICES = ("auto", "on", "off")


def _load_semaphores():
    """The C library's semaphore functions, a compiler barrier and ``sched_yield``, or None."""
    if not platform.system() == "Linux":
        return None
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        init, wait, trywait, destroy = libc.sem_init, libc.sem_wait, libc.sem_trywait, libc.sem_destroy
        # sem_post never blocks: called through PyDLL it keeps the GIL. A ctypes call that lets
        # the GIL go for a microsecond invites a training thread to take it, and the envs then
        # wait for that thread's next torch call to get it back.
        post = ctypes.PyDLL(None).sem_post
        # A size_t address rather than a pointer: numba passes plain integers to ctypes functions.
        for function in (wait, trywait):
            function.argtypes, function.restype = [ctypes.c_size_t], ctypes.c_int
        init.argtypes, init.restype = [ctypes.c_void_p, ctypes.c_int, ctypes.c_uint], ctypes.c_int
        post.argtypes, post.restype = [ctypes.c_void_p], ctypes.c_int
        destroy.argtypes, destroy.restype = [ctypes.c_void_p], ctypes.c_int
        barrier = libc.labs  # any foreign call: the compiler must assume it reads and writes memory
        barrier.argtypes, barrier.restype = [ctypes.c_long], ctypes.c_long
        pause = libc.sched_yield
        pause.argtypes, pause.restype = [], ctypes.c_int
    except (OSError, AttributeError):
        return None
    return init, wait, trywait, post, destroy, barrier, pause


_SEMAPHORES = _load_semaphores()
_SEM_BYTES = 64  # sem_t is 32 bytes on 64-bit glibc and musl; room to spare
# Polls (~0.5 us each) the worker spins through before it sleeps: ~5 ms, longer than the
# policy's turn between two vectorised steps, so it stays awake while envs step.
SPIN_POLLS = 10_000
# Polls the wrapper waits for windows the worker has not scored before scoring them itself
# (~25 us, most of a window's scoring: the worker is behind only when a training round shares its core).
TAKEOVER_POLLS = 48


def pipeline_unavailable_reason() -> str | None:
    """Why pipelined scoring cannot run on this machine, or None if it can."""
    if _SEMAPHORES is None:
        return "pipelined scoring needs Linux (POSIX semaphores from the C library)"
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover  (Linux has it)
        cores = os.cpu_count() or 1
    if cores < 2:
        return "pipelined scoring needs a second core (this process may use one)"
    return None


def pipeline_recommended() -> bool:
    """Whether ``pipeline="auto"`` turns it on here: available, and on x86-64, whose stores other
    cores see in program order (elsewhere, ``"on"`` still runs it: the semaphore orders each
    window before its wake-up, and only the worker's logit-before-flag stores rely on it)."""
    return pipeline_unavailable_reason() is None and platform.machine().lower() in ("x86_64", "amd64")


if _SEMAPHORES is not None:
    _sem_init, _sem_wait, _sem_trywait, _sem_post, _sem_destroy, _barrier, _pause = _SEMAPHORES

    @njit(nogil=True)
    def _serve(sem, windows, posted, scored, logits, control, mean, std, clip, weights, biases, a, b, spin_polls):
        """The worker: score every posted window not yet scored, until ``control[0]`` is set.

        Between windows it polls (a ``sched_yield`` each) for ``spin_polls`` rounds, so while
        envs step a post costs the poster no system call; then it sleeps in the semaphore,
        which every post also increments. Before sleeping it takes the counts of the posts it
        has seen, then looks once more: a post it has not seen either shows up then or left
        a count behind, so ``sem_wait`` returns (the semaphore's atomics order the post's
        number before its count)."""
        n = posted.shape[0]
        idle = 0
        while control[0] == 0:
            busy = False
            for i in range(n):
                seq = posted[i]
                if seq == scored[i]:
                    continue
                _barrier(0)  # read the post's number before its window
                logits[i] = window_logit(windows[i: i + 1], mean, std, clip, weights, biases, a, b)
                _barrier(0)  # store the logit before the number that says it is there
                scored[i] = seq
                busy = True
            if busy:
                idle = 0
            elif idle < spin_polls:
                idle += 1
                _pause()
            else:
                while _sem_trywait(sem) == 0:
                    pass
                pending = False
                for i in range(n):
                    if posted[i] != scored[i]:
                        pending = True
                if not pending and control[0] == 0:
                    _sem_wait(sem)
                idle = 0
        return 0

    @njit  # keeps the GIL (see sem_post): a short wait in the envs' thread
    def _wait_scored(posted, scored, polls):
        """True once every posted window is scored; False after ``polls`` checks (a yield each)."""
        for _ in range(polls):
            done = True
            for i in range(posted.shape[0]):
                if scored[i] != posted[i]:
                    done = False
                    break
            if done:
                return True
            _pause()
        return False


def set_amp_sink(env, sink) -> None:
    """Have ``env`` (a stairenv env, or a wrapper of one) call ``sink(amp_obs, amp_condition_or_None)``
    with its ``info`` at the end of every ``step`` (``reset`` posts nothing); None stops it.

    The pipeline's side of the envs: it shadows the env's ``step`` on that one instance (every
    wrapper above calls it) and records the sink as ``env.unwrapped._amp_sink``."""
    if sink is not None and not callable(sink):
        raise TypeError(f"sink must be callable or None, got {type(sink).__name__}")
    base = env.unwrapped
    base.__dict__.pop("step", None)
    base._amp_sink = sink
    if sink is None:
        return
    step = base.step

    def posting_step(action):
        result = step(action)
        info = result[4]
        sink(info["amp_obs"], info.get("amp_condition"))
        return result
    base.step = posting_step


def _worker(sem_buffer, *arrays) -> None:
    # A module function holding only arrays, so the scorer itself can be garbage-collected.
    _serve(ctypes.addressof(sem_buffer), *arrays)


def _stop(control: np.ndarray, sem_buffer, thread: threading.Thread) -> None:
    control[0] = 1
    _sem_post(sem_buffer)
    thread.join(timeout=5.0)
    if not thread.is_alive():
        _sem_destroy(sem_buffer)


class PipelinedScorer:
    """Scores windows posted by in-process envs in a worker thread; see the module docstring.

    ``attach(envs)`` sets each env's sink (``set_amp_sink``; env ``i`` posts to slot ``i``, see ``sink``);
    ``logits(windows)`` is the wrapper's, after the vec env stepped:
    the logits of the step's windows (as the wrapper stacked them from ``info``); ``refresh()``
    after the discriminator may have trained; ``close()`` detaches the envs and stops the worker.
    """

    def __init__(self, disc: AMPDiscriminator, num_envs: int, feature_dim: int, timeout: float = 60.0) -> None:
        reason = pipeline_unavailable_reason()
        if reason is not None:
            raise RuntimeError(reason)
        self.disc = disc
        self.num_envs = int(num_envs)
        self.feature_dim = int(feature_dim)
        self.condition_dim = disc.input_dim - self.feature_dim
        if self.num_envs < 1 or self.condition_dim < 0:
            raise ValueError(f"num_envs {num_envs} and feature_dim {feature_dim} do not fit a "
                             f"{disc.input_dim}-input discriminator")
        self.timeout = float(timeout)
        self.windows = np.zeros((self.num_envs, disc.input_dim), dtype=np.float32)
        self.posted = np.zeros(self.num_envs, dtype=np.int64)
        self.scored = np.zeros(self.num_envs, dtype=np.int64)
        self._logits = np.zeros(self.num_envs, dtype=np.float32)
        self._control = np.zeros(1, dtype=np.int64)  # 1: stop
        # The worker's own copy of the weights: training may change the discriminator's at any time.
        plan = disc.scoring_plan()
        weights, biases = disc.fused_layers(plan)
        self._weights = tuple(np.zeros_like(w) for w in weights)
        self._biases = tuple(np.zeros_like(b) for b in biases)
        self._mean = np.zeros(disc.input_dim, dtype=np.float32)
        self._std = np.ones(disc.input_dim, dtype=np.float32)
        self._loaded: dict | None = None
        self._load(plan)
        arrays = (self.windows, self.posted, self.scored, self._logits, self._control, self._mean, self._std,
                  np.float32(disc.norm.clip), self._weights, self._biases, *disc.window_scratch(), SPIN_POLLS)
        self._sem = ctypes.create_string_buffer(_SEM_BYTES)
        if _sem_init(self._sem, 0, 0) != 0:
            raise OSError(ctypes.get_errno(), "sem_init failed")
        # Compile in this thread (the first call returns at once: control is set), then start.
        self._control[0] = 1
        _serve(ctypes.addressof(self._sem), *arrays)
        _wait_scored(self.posted, self.scored, 1)
        self._control[0] = 0
        self._thread = threading.Thread(target=_worker, args=(self._sem, *arrays), name="amp-scoring", daemon=True)
        self._thread.start()
        self._finalizer = weakref.finalize(self, _stop, self._control, self._sem, self._thread)
        self.active = True
        # Set between steps: the next step's windows are not posted, the caller scores them (the
        # wrappers pause while a background training round shares the worker's core).
        self.paused = False
        self.stats = {"pipelined": 0, "rescored": 0}
        self._envs: list = []
        self._slots = np.arange(self.num_envs)

    def attach(self, envs: list) -> None:
        """Have each env (a stairenv env, or a wrapper of one) post its windows here, env ``i`` to slot ``i``."""
        if len(envs) != self.num_envs:
            raise ValueError(f"{len(envs)} envs for {self.num_envs} slots")
        for slot, env in enumerate(envs):
            set_amp_sink(env, self.sink(slot))
        self._envs = list(envs)

    # --- the env side -------------------------------------------------------------
    def sink(self, slot: int):
        """The callable env ``slot`` posts its windows to: ``sink(window, condition_or_None)``
        copies them into the shared buffer and wakes the worker. A window of the wrong size,
        or a missing condition, is not posted: the wrapper then scores that env itself, or
        raises its own error about the mismatch."""
        slot = int(slot)
        if not 0 <= slot < self.num_envs:
            raise ValueError(f"slot must be in [0, {self.num_envs - 1}], got {slot}")
        row = self.windows[slot]
        features, conditions = row[: self.feature_dim], row[self.feature_dim:]
        shape, condition_shape = (self.feature_dim,), (self.condition_dim,)
        posted, sem = self.posted, self._sem

        def post(window, condition=None) -> None:
            if self.paused or not self.active or np.shape(window) != shape:
                return
            if self.condition_dim:
                if condition is None or np.shape(condition) != condition_shape:
                    return
                conditions[:] = condition
            features[:] = window
            posted[slot] += 1
            _sem_post(sem)
        return post

    # --- the wrapper side -----------------------------------------------------------
    def logits(self, windows: np.ndarray, slots: np.ndarray | None = None) -> np.ndarray:
        """The logits of one step's windows (float32; rows as ``slots``, default every env).

        The worker's where it has scored exactly these windows with the current plan; after
        a short wait (``TAKEOVER_POLLS``) the windows it has not reached yet are scored here
        by the same kernel, as is any window that differs from the one posted."""
        plan = self.disc.scoring_plan()
        if self.active and not self._thread.is_alive():
            self._give_up("the AMP scoring worker stopped")
        if self.paused or not self.active or plan is not self._loaded:
            self.stats["rescored"] += len(windows)
            return self.disc.window_logits(windows, plan)
        every = slots is None
        all_scored = _wait_scored(self.posted, self.scored, TAKEOVER_POLLS)
        if every and all_scored:  # the usual case: every env posted, every window scored
            out = self._logits.copy()  # read after the numbers: the worker stores the logits first
            if np.array_equal(self.windows, windows) and (self.posted > self._posted_at_load).all():
                self.stats["pipelined"] += len(windows)
                return out
        slots = self._slots if every else np.asarray(slots)
        # Windows the worker has not reached: score them here from the last one down while it
        # works up from the first (it may score one of them too: the same bits, unused).
        here = np.zeros(len(windows), dtype=bool)
        mine = np.empty(len(windows), dtype=np.float32)
        while not all_scored:
            waiting = np.flatnonzero((self.scored[slots] != self.posted[slots]) & ~here)
            if len(waiting) == 0:
                break
            j = waiting[-1]
            mine[j] = self.disc.window_logits(windows[j: j + 1], plan)[0]
            here[j] = True
        # Every other window is scored: its logit was stored before the number read above.
        out = self._logits[slots]
        posted = self.windows[slots]
        out[here] = mine[here]
        # Also windows posted before the weights were last loaded: scored with the old ones.
        stale = ~here & ((posted != windows).any(axis=1) | (self.posted[slots] <= self._posted_at_load[slots]))
        if stale.any():
            out[stale] = self.disc.window_logits(windows[stale], plan)
        self.stats["rescored"] += int(here.sum() + stale.sum())
        self.stats["pipelined"] += int(len(windows) - here.sum() - stale.sum())
        return out

    def refresh(self) -> None:
        """Load the discriminator's scoring plan into the worker's copy if it changed (training)."""
        plan = self.disc.scoring_plan()
        if plan is not self._loaded and self.active and self._wait():
            self._load(plan)

    def _load(self, plan: dict) -> None:
        # Only while the worker is idle (every post scored): it reads these only when scoring.
        weights, biases = self.disc.fused_layers(plan)
        for dst, src in zip(self._weights + self._biases, weights + biases):
            dst[...] = src
        self._mean[:] = plan["mean"].numpy()
        self._std[:] = plan["std"].numpy()
        self._loaded = plan
        self._posted_at_load = self.posted.copy()  # logits of earlier posts are of the old weights

    def _wait(self) -> bool:
        """Wait until the worker has scored every posted window; False (and off from now on)
        if it stopped or did not answer within ``timeout`` seconds."""
        deadline = None
        while not _wait_scored(self.posted, self.scored, 4096):
            if not self._thread.is_alive():
                return self._give_up("the AMP scoring worker stopped")
            deadline = deadline or time.monotonic() + self.timeout
            if time.monotonic() > deadline:
                return self._give_up(f"the AMP scoring worker did not answer within {self.timeout:g} s")
        return True

    def _give_up(self, why: str) -> bool:
        warnings.warn(f"{why}; scoring in the calling thread from now on", RuntimeWarning, stacklevel=3)
        self.active = False
        return False

    def close(self) -> None:
        """Detach the envs and stop the worker (idempotent); later calls score in the calling thread."""
        self.active = False
        for env in self._envs:
            set_amp_sink(env, None)
        self._envs = []
        self._finalizer()


def in_process_envs(venv) -> list | None:
    """The envs of an in-process vec env (SB3 ``DummyVecEnv``, gymnasium ``SyncVectorEnv``), looked
    for through vec-env wrappers; None for any other (subprocess) vec env."""
    seen: set[int] = set()
    while venv is not None and id(venv) not in seen:
        seen.add(id(venv))
        if isinstance(venv, DummyVecEnv):
            return list(venv.envs)
        if isinstance(venv, gym.vector.SyncVectorEnv):
            return list(venv.envs)
        venv = getattr(venv, "venv", None) or getattr(venv, "env", None)
    return None
