"""The ``info`` of a batched step: columns over the worlds, a world's dict made only when it is asked for.

A batched env whose task computes its step outcomes as arrays (InterLevel) hands its ``info`` over as
columns, one array per key with a row per world (a nested dict, such as InterLevel's ``stairs``, is a
nested dict of columns). ``WorldInfos`` holds them and reads as the list of per-world dicts the
single env would give: ``infos[i]`` builds world i's dict (Python numbers, as the single env's) the
first time it is asked for. A world whose info is not in the columns (a reset, an unstable step, a
task that finishes world by world) has its dict set whole: ``infos[i] = {...}``.

Consumers that need one key of every world (the trainer's ``amp_obs``) read ``column(infos, key)``, one
key of some worlds as numbers ``floats_of(infos, worlds, key)`` (the trainer's episode log), and the
gymnasium ``step`` reads ``infos.stacked()``: all from the columns, with no dict per world.
``stack_infos`` is the per-world route (``SyncVectorEnv``'s layout), used where there are no columns.
Gymnasium has only that route (``VectorEnv._add_info``, world by world), hence this module.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from typing import Any

import numpy as np

Columns = dict[str, Any]    # key -> (n, ...) array, or a nested ``Columns``


class WorldInfos(Sequence):
    """The infos of ``n`` worlds (see the module docstring). ``put(rows, columns)`` adds the columns of a
    group of worlds; ``infos[i] = info`` sets world i's dict whole."""

    def __init__(self, n: int) -> None:
        self.n = n
        self.columns: Columns = {}
        #: which worlds' info is in ``columns``
        self.in_columns = np.zeros(n, dtype=bool)
        #: worlds' dicts: set whole (``explicit``) or built from the columns when first asked for
        self._dicts: list[dict[str, Any] | None] = [None] * n
        self._explicit = np.zeros(n, dtype=bool)

    def put(self, rows, columns: Columns) -> None:
        """Rows ``rows`` of every column (each column of ``columns`` has one row per world of ``rows``), once per
        world and before its dict is read. The first group decides the keys, dtypes and shapes; every later
        group must bring the same keys (``ValueError`` otherwise)."""
        _scatter(self.columns, columns, rows, self.n)
        self.in_columns[rows] = True
        self._explicit[rows] = False

    def __len__(self) -> int:
        return self.n

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(self.n))]
        info = self._dicts[i]
        if info is None:
            info = self._dicts[i] = _row(self.columns, i) if self.in_columns[i] else {}
        return info

    def __setitem__(self, i: int, info: dict[str, Any]) -> None:
        self._dicts[i] = info
        self._explicit[i] = True
        self.in_columns[i] = False

    def stacked(self) -> dict[str, Any]:
        """The infos as one dict of arrays with ``_key`` masks, as ``stack_infos`` of the per-world dicts
        gives them: from the columns, and from the dicts set whole of the other worlds."""
        if not self.in_columns.any():
            return stack_infos(list(self))
        explicit = np.flatnonzero(self._explicit)
        batched = _masked(self.columns, self.in_columns)
        if explicit.size:
            others = stack_infos([self._dicts[i] if self._explicit[i] else {} for i in range(self.n)])
            if not _merge(batched, others):    # a key of different dtype or shape: the per-world route
                return stack_infos(list(self))
        return batched


def column(infos: Sequence[dict[str, Any]], key: str) -> np.ndarray:
    """``np.stack([info[key] for info in infos])``, read from the columns where ``infos`` has them."""
    if isinstance(infos, WorldInfos) and key in infos.columns and not isinstance(infos.columns[key], dict):
        values = infos.columns[key].copy()
        for i in np.flatnonzero(~infos.in_columns):
            values[i] = infos[i][key]
        return values
    return np.stack([info[key] for info in infos])


def floats_of(infos: Sequence[dict[str, Any]], worlds: np.ndarray, key: str) -> tuple[np.ndarray, np.ndarray]:
    """``float(infos[i][key])`` of each of ``worlds`` (0 where a world's info lacks the key) and which have it,
    read from the columns where ``infos`` has them (no dict made), from the other worlds' dicts."""
    values, present = np.zeros(len(worlds)), np.zeros(len(worlds), dtype=bool)
    others = range(len(worlds))
    if isinstance(infos, WorldInfos):    # a world in the columns has the key if the columns have it
        in_columns = infos.in_columns[worlds]
        columns = infos.columns.get(key)
        if columns is not None:
            values[in_columns], present[in_columns] = columns[worlds[in_columns]], True
        others = np.flatnonzero(~in_columns).tolist()
    for k in others:
        value = infos[int(worlds[k])].get(key)
        if value is not None:
            values[k], present[k] = float(value), True
    return values, present


def stack_infos(infos: list[dict[str, Any]]) -> dict[str, Any]:
    """``VectorEnv._add_info`` over all worlds at once: the same keys, arrays, dtypes (the first world
    with the key decides) and ``_key`` masks, a key at a time instead of a world at a time."""
    n = len(infos)
    # Worlds grouped by their keys, in order: a step's infos have one set (every world stepped) or a few
    # (worlds just reset report fewer keys), so a key's worlds come from its groups, not a test per world.
    groups: dict[tuple[str, ...], list[int]] = {}
    for i, info in enumerate(infos):
        groups.setdefault(tuple(info), []).append(i)
    batched: dict[str, Any] = {}
    for key in dict.fromkeys(key for keys in groups for key in keys):    # first seen first, as world by world
        holders = [worlds for keys, worlds in groups.items() if key in keys]
        worlds = holders[0] if len(holders) == 1 else sorted(itertools.chain.from_iterable(holders))
        everyone = len(worlds) == n
        where = slice(None) if everyone else worlds
        values = [info[key] for info in infos] if everyone else [infos[i][key] for i in worlds]
        first = values[0]
        if key != "final_obs" and isinstance(first, dict):
            inner: list[dict[str, Any]] = values if everyone else [{}] * n
            if not everyone:
                for i, value in zip(worlds, values):
                    inner[i] = value
            array = stack_infos(inner)
        elif key != "final_obs" and (type(first) in (int, float, bool) or isinstance(first, np.number)):
            array = np.zeros(n, dtype=type(first))
            array[where] = values
        elif key != "final_obs" and isinstance(first, np.ndarray):
            array = np.zeros((n, *first.shape), dtype=first.dtype)
            array[where] = values
        else:    # one object per world (a tuple stays a tuple): not unpacked as a sequence would be
            array = np.full(n, None, dtype=object)
            array[where] = np.fromiter(values, dtype=object, count=len(values))
        mask = np.zeros(n, dtype=bool)
        mask[where] = True
        batched[key], batched[f"_{key}"] = array, mask
    return batched


def flatten(info: dict[str, Any], prefix: tuple[str, ...] = ()) -> tuple[tuple[tuple[str, ...], ...], tuple]:
    """A dict (nested dicts of numbers and arrays) as its key paths and its values, in order: what
    ``columns_of_rows`` stacks over worlds."""
    paths, values = [], []
    for key, value in info.items():
        if isinstance(value, dict):
            inner_paths, inner_values = flatten(value, (*prefix, key))
            paths.extend(inner_paths)
            values.extend(inner_values)
        else:
            paths.append((*prefix, key))
            values.append(value)
    return tuple(paths), tuple(values)


def columns_of_rows(paths: tuple[tuple[str, ...], ...], rows: list[tuple]) -> Columns:
    """Worlds' ``flatten``ed dicts (the same ``paths``; ``rows[k]`` world k's values) as columns, with the
    dtype ``stack_infos`` would give (the first world's type) where every world's value has that type, else
    one that holds them all (``np.result_type``: an int first and a float later make a float column), so
    that no world's value is cut (``stack_infos`` would cut it)."""
    columns: Columns = {}
    for path, values in zip(paths, zip(*rows)):
        first = values[0]
        node = columns
        for key in path[:-1]:
            node = node.setdefault(key, {})
        if type(first) in (int, float, bool) or isinstance(first, np.number):
            kinds = {type(value) for value in values}
            node[path[-1]] = np.array(values, dtype=type(first) if len(kinds) == 1 else np.result_type(*kinds))
        elif isinstance(first, np.ndarray):
            kinds = {np.asarray(value).dtype for value in values}
            node[path[-1]] = np.array(values, dtype=first.dtype if len(kinds) == 1 else np.result_type(*kinds))
        else:    # one object per world, as stack_infos keeps it
            node[path[-1]] = np.fromiter(values, dtype=object, count=len(values))
    return columns


def write_rows(into: Columns, columns: Columns, rows: np.ndarray, n: int) -> None:
    """``columns`` (a group's: row k for world ``rows[k]``) into those rows of ``into``, columns of ``n``
    rows made at the first write (with the group's dtypes). A column whose dtype cannot hold a later
    group's values exactly is widened first (``np.result_type``: an int column given floats becomes float),
    so that no value is cut."""
    for key, values in columns.items():
        if isinstance(values, dict):
            write_rows(into.setdefault(key, {}), values, rows, n)
            continue
        column = into.get(key)
        if column is None:
            column = into[key] = np.zeros((n, *values.shape[1:]), dtype=values.dtype)
        elif not np.can_cast(values.dtype, column.dtype, "safe"):
            column = into[key] = column.astype(np.result_type(column.dtype, values.dtype))
        column[rows] = values


def take_rows(columns: Columns, rows: np.ndarray) -> Columns:
    """Rows ``rows`` of every column (nested columns alike), as new arrays."""
    return {key: take_rows(values, rows) if isinstance(values, dict) else values[rows]
            for key, values in columns.items()}


# --- helpers -------------------------------------------------------------------------------------
def _scatter(into: Columns, columns: Columns, rows, n: int) -> None:
    if into and into.keys() != columns.keys():
        raise ValueError(f"a group's info keys {sorted(columns)} differ from the first group's {sorted(into)}")
    for key, values in columns.items():
        if isinstance(values, dict):
            _scatter(into.setdefault(key, {}), values, rows, n)
            continue
        if key not in into:
            into[key] = np.zeros((n, *values.shape[1:]), dtype=values.dtype)
        into[key][rows] = values


def _row(columns: Columns, i: int) -> dict[str, Any]:
    """World i's dict: numbers as Python numbers (``item()``), array rows as arrays, nested dicts alike."""
    return {key: _row(values, i) if isinstance(values, dict) else
            (values.item(i) if values.ndim == 1 else values[i]) for key, values in columns.items()}


def _masked(columns: Columns, mask: np.ndarray) -> dict[str, Any]:
    """The columns with ``_key`` masks; rows outside ``mask`` cleared (zero, or None for objects) as
    ``stack_infos`` leaves a world without the key."""
    everyone = mask.all()
    batched: dict[str, Any] = {}
    for key, values in columns.items():
        if isinstance(values, dict):
            values = _masked(values, mask)
        elif not everyone:
            values = values.copy()
            values[~mask] = None if values.dtype == object else 0
        batched[key] = values
        batched[f"_{key}"] = mask.copy()
    return batched


def _merge(batched: dict[str, Any], others: dict[str, Any]) -> bool:
    """Add ``others`` (``stack_infos`` of the other worlds) into ``batched`` in place; False where a key's
    arrays differ in kind (dtype or shape), which only the per-world route stacks as ``stack_infos`` does."""
    for key, values in others.items():
        if key.startswith("_") and key[1:] in others:
            continue
        mask = others[f"_{key}"]
        if key not in batched:
            batched[key], batched[f"_{key}"] = values, mask
        elif isinstance(values, dict) != isinstance(batched[key], dict):
            return False
        elif isinstance(values, dict):
            if not _merge(batched[key], values):
                return False
            batched[f"_{key}"] = batched[f"_{key}"] | mask
        elif values.dtype != batched[key].dtype or values.shape != batched[key].shape:
            return False
        else:
            batched[key][mask] = values[mask]
            batched[f"_{key}"] = batched[f"_{key}"] | mask
    return True
