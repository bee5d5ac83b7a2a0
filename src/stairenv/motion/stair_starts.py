"""Reference states on a staircase: frames of a climb synthesised for that staircase.

Reference-state initialisation from level-ground clips starts every episode on the
floor, so a policy meets the treads only once it has learnt to walk to them. A start
drawn from a climb of the episode's own staircase (``synthesis.climb_stairs`` with its
step height, depth and count) puts the character anywhere from the approach to the
landing, its feet on the treads the clip planned them on.

Synthesis takes ~80-170 ms, so climbs are cached per staircase on a grid: height and depth
are rounded to :data:`GRID` (1 cm); the env snaps the staircase of such an episode to the
same grid (``snap``), so the treads and the clip agree exactly. The cache is per process and
fills as episodes draw staircases, and each climb synthesised is also kept on the disk
(``stairenv.assets.cache_dir() / "climbs"``, one ``.npz`` of two float32 arrays per staircase,
read without pickle; in a folder named by a fingerprint of the synthesis code and the numerical
libraries' versions, so that a change to either starts a new folder): a run on a machine that
has climbed before reads them instead of synthesising (early in training, when episodes are
short, nearly every stair start would otherwise miss, and synthesis was ~90% of the env's time).
A file that cannot be read as such a climb is synthesised again and replaced; a cache folder
that cannot be written is left alone. ``fill_cache`` synthesises a range of staircases on
several processes first (``train_ppo.py --climb-cache-workers N``): the same arrays, sooner.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Iterable
from concurrent.futures import ProcessPoolExecutor
import functools
import hashlib
import importlib
import importlib.metadata
import multiprocessing
import os
from pathlib import Path
import tempfile
import zipfile

import numpy as np

from stairenv.assets import cache_dir, xml_path
from stairenv.motion.ik import leg_geometry
from stairenv.motion.synthesis import MAX_STEP_DEPTH, MAX_STEP_HEIGHT, climb_stairs

#: Height and depth grid (m) of the cached climbs.
GRID = 0.01
#: Root positions along the ascent (m, from the first riser) a start may be drawn from:
#: from a little before the first riser to just past the top riser (``landing_start``).
BEFORE_FIRST_RISER = 0.6
PAST_TOP_RISER = 0.3
# Every grid staircase of the paper's ranges (16 heights x 16 depths x 8 counts x 2 lead feet) at
# ~40 KB each (~140 frames of qpos + qvel in float32 on average): ~160 MB.
CACHE_SIZE = 4096


#: The staircases a climb can be synthesised for (``synthesis.climb_stairs``: one foot per tread, a
#: tread at least 1 cm longer than the foot).
HEIGHT_RANGE = (0.01, MAX_STEP_HEIGHT)
DEPTH_RANGE = (leg_geometry().foot_length + 0.01, MAX_STEP_DEPTH)


def check_staircases(heights, depths) -> None:
    """``ValueError`` naming the keyword when the step heights or depths an env draws leave the
    range climbs are synthesised for (:data:`HEIGHT_RANGE`, :data:`DEPTH_RANGE`)."""
    for name, values, (low, high) in (("step_height", heights, HEIGHT_RANGE),
                                      ("step_depth", depths, DEPTH_RANGE)):
        if min(values) < low or max(values) > high:
            raise ValueError(f"stairs_start_fraction > 0 needs {name} within [{low}, {high}] m (a climb is "
                             f"synthesised for each staircase), got {tuple(values)}")


def snap(value: float, low: float, high: float) -> float:
    """``value`` on the :data:`GRID`, kept within [low, high] (on grid points inside it)."""
    snapped = round(value / GRID) * GRID
    low_point, high_point = np.ceil(low / GRID - 1e-9) * GRID, np.floor(high / GRID + 1e-9) * GRID
    return float(round(min(max(snapped, low_point), high_point), 6))


#: (height_cm, depth_cm, num_steps, lead_foot) -> (qpos, qvel): the cached climbs, least recently used first
_CLIMBS: OrderedDict[tuple[int, int, int, str], tuple[np.ndarray, np.ndarray]] = OrderedDict()
LEAD_FEET = ("right", "left")


def _climb(height_cm: int, depth_cm: int, num_steps: int, lead_foot: str) -> tuple[np.ndarray, np.ndarray]:
    """The cached climb of this grid staircase, read from the disk or synthesised (and kept there) on a miss
    (least recently used dropped beyond :data:`CACHE_SIZE`)."""
    key = (height_cm, depth_cm, num_steps, lead_foot)
    climb = _CLIMBS.get(key)
    if climb is None:
        climb = load_climb(key)
        if climb is None:
            climb = _synthesise(*key)
            store_climb(key, climb)
        climb = _remember(key, climb)
    else:
        _CLIMBS.move_to_end(key)
    return climb


#: the modules whose code makes a climb (their source bytes are part of the disk cache's fingerprint)
_SYNTHESIS_MODULES = ("stairenv.motion.synthesis", "stairenv.motion.ik", "stairenv.motion.stair_starts",
                      "stairenv.motion.clip", "stairenv.humanoid.model")


@functools.cache
def _fingerprint() -> str:
    """A digest of the synthesis code's source, the humanoid's MJCF and the numerical libraries' versions (not
    of any float)."""
    digest = hashlib.sha256()
    for name in _SYNTHESIS_MODULES:
        digest.update(Path(importlib.import_module(name).__file__).read_bytes())
    digest.update(xml_path("humanoid.xml").read_bytes())    # the body the climb is solved for
    for package in ("numpy", "scipy", "mujoco"):
        digest.update(f"{package}={importlib.metadata.version(package)};".encode())
    return digest.hexdigest()[:16]


def climb_path(key: tuple[int, int, int, str]) -> Path:
    """The disk cache's file of a grid staircase (``key`` as ``grid_keys``' entries)."""
    height_cm, depth_cm, num_steps, lead_foot = key
    return cache_dir() / "climbs" / _fingerprint() / f"h{height_cm}_d{depth_cm}_n{num_steps}_{lead_foot}.npz"


def load_climb(key: tuple[int, int, int, str]) -> tuple[np.ndarray, np.ndarray] | None:
    """The climb kept on the disk for ``key``, or None where there is none or the file is not such a climb
    (read with ``allow_pickle=False``: a file cannot run code; shapes, types and finiteness are checked)."""
    path = climb_path(key)
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as data:
            qpos, qvel = data["qpos"], data["qvel"]
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):
        return None
    good = (qpos.dtype == np.float32 and qvel.dtype == np.float32 and qpos.ndim == 2 and qvel.ndim == 2
            and qpos.shape[1] == 35 and qvel.shape[1] == 34 and len(qpos) == len(qvel) and len(qpos) > 0
            and np.isfinite(qpos).all() and np.isfinite(qvel).all())
    return (qpos, qvel) if good else None


def store_climb(key: tuple[int, int, int, str], climb: tuple[np.ndarray, np.ndarray]) -> None:
    """Keep ``climb`` on the disk for ``key`` (written whole, then renamed into place); nothing where the
    cache folder cannot be written."""
    path = climb_path(key)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        handle = tempfile.NamedTemporaryFile(dir=path.parent, suffix=".tmp", delete=False)
    except OSError:
        return
    try:
        with handle:
            np.savez(handle, qpos=climb[0], qvel=climb[1])
        os.replace(handle.name, path)
    except OSError:    # a full disk: no half-written file stays behind
        Path(handle.name).unlink(missing_ok=True)


def _remember(key: tuple[int, int, int, str], climb: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    _CLIMBS[key] = climb
    if len(_CLIMBS) > CACHE_SIZE:
        _CLIMBS.popitem(last=False)
    return climb


def _synthesise(height_cm: int, depth_cm: int, num_steps: int, lead_foot: str) -> tuple[np.ndarray, np.ndarray]:
    step_depth = depth_cm * GRID
    clip = climb_stairs(height_cm * GRID, step_depth, num_steps, lead_foot=lead_foot)
    x = clip.qpos[:, 0]
    keep = (x >= -BEFORE_FIRST_RISER) & (x <= (num_steps - 1) * step_depth + PAST_TOP_RISER)
    # only the frames starts are drawn from, in single precision: every grid staircase fits in the cache
    return clip.qpos[keep].astype(np.float32), clip.qvel()[keep].astype(np.float32)


def climb_frames(step_height: float, step_depth: float, num_steps: int, lead_foot: str = "right"
                 ) -> tuple[np.ndarray, np.ndarray]:
    """qpos (T, 35) and qvel (T, 34) (float32) of the cached climb of a staircase on the grid, in the
    staircase's own frame (first riser at x = 0, ascent along +x), restricted to the frames
    whose root is between :data:`BEFORE_FIRST_RISER` before the first riser and
    :data:`PAST_TOP_RISER` past the top one."""
    height_cm, depth_cm = round(step_height / GRID), round(step_depth / GRID)
    if abs(height_cm * GRID - step_height) > 1e-6 or abs(depth_cm * GRID - step_depth) > 1e-6:
        raise ValueError(f"step height {step_height} and depth {step_depth} must lie on the {GRID} m grid "
                         "(snap the staircase first)")
    return _climb(height_cm, depth_cm, int(num_steps), lead_foot)


def climb_state(step_height: float, step_depth: float, num_steps: int, rng: np.random.Generator
                ) -> tuple[np.ndarray, np.ndarray]:
    """One state (qpos (35,), qvel (34,)) drawn uniformly from the climb frames of
    :func:`climb_frames`, either foot leading, in the staircase's frame."""
    rest, qvel = climb_start(step_height, step_depth, num_steps, rng)
    return rest[0], qvel


def climb_start(step_height: float, step_depth: float, num_steps: int, rng: np.random.Generator
                ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`climb_state`'s draw (the same random numbers) as the climb from the drawn frame on: qpos
    (T - k, 35) of frames k.. (what a tracking aid follows) and the start's qvel (34,), float64."""
    lead_foot = ("right", "left")[int(rng.integers(2))]
    qpos, qvel = climb_frames(step_height, step_depth, num_steps, lead_foot)
    k = int(rng.integers(len(qpos)))
    return qpos[k:].astype(np.float64), qvel[k].astype(np.float64)


def grid_keys(step_height: tuple[float, float], step_depth: tuple[float, float],
              num_steps: tuple[int, int]) -> list[tuple[int, int, int, str]]:
    """Every grid staircase (and lead foot) a stair start can draw from these ranges (``snap``'s grid
    points inside them): the keys of the cache."""
    def points(low: float, high: float) -> range:
        return range(int(np.ceil(low / GRID - 1e-9)), int(np.floor(high / GRID + 1e-9)) + 1)
    return [(h, d, n, foot) for h in points(*step_height) for d in points(*step_depth)
            for n in range(int(num_steps[0]), int(num_steps[1]) + 1) for foot in LEAD_FEET]


def _synthesise_key(key: tuple[int, int, int, str]) -> tuple[np.ndarray, np.ndarray]:
    return _synthesise(*key)


def cached(keys: Iterable[tuple[int, int, int, str]]) -> dict[tuple[int, int, int, str], tuple[np.ndarray, ...]]:
    """The climbs of ``keys`` that this process has cached (for another process's ``remember``)."""
    return {key: _CLIMBS[key] for key in keys if key in _CLIMBS}


def remember(climbs: dict[tuple[int, int, int, str], tuple[np.ndarray, ...]]) -> None:
    """Climbs another process synthesised (``cached`` there: a data-parallel run's ranks each fill a share of
    the cache, then take the others'), into this process's cache, as a miss here would have."""
    for key, climb in climbs.items():
        _remember(key, climb)


def fill_cache(keys: Iterable[tuple[int, int, int, str]], workers: int) -> int:
    """Synthesise the climbs of ``keys`` (``grid_keys``) neither cached nor on the disk, on ``workers``
    processes, into this process's cache (at most :data:`CACHE_SIZE`) and onto the disk; the arrays are those
    a miss would compute (the synthesis is deterministic; float32 arrays travel back unchanged). Returns how
    many were synthesised."""
    missing = []
    for key in [key for key in dict.fromkeys(keys) if key not in _CLIMBS][:CACHE_SIZE]:
        climb = load_climb(key)
        if climb is None:
            missing.append(key)
        else:
            _remember(key, climb)
    if not missing:
        return 0
    if workers <= 1:
        for key in missing:
            _climb(*key)
        return len(missing)
    # spawned workers: a fork of a process already running torch or a thread pool can deadlock
    with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        for key, climb in zip(missing, pool.map(_synthesise_key, missing, chunksize=8)):
            _remember(key, climb)
            store_climb(key, climb)
    return len(missing)
