"""The one result type of every paper's evaluation: rows, the published rows merged in, and a
plain-text table, CSV and JSON of them.

A :class:`Report` holds result rows (dicts with the keys of its :class:`Layout`'s ``fields``),
the per-episode or per-run details behind them (dataclasses) and a JSON header (settings). The
layout, one per paper table, names the columns, how each is printed, and the published rows
with the keys that pair them with ours.
"""

from __future__ import annotations

import csv
import json
import math
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Column:
    """One column of the text table: ``header`` above the row values under ``key``.

    Numbers (``digits`` set) print with that many decimals; text (``text``) is left-aligned;
    ``show`` prints a cell from the whole row. A None value prints as "-" (as in the papers).
    """

    header: str
    key: str = ""
    digits: int | None = None
    text: bool = False
    show: Callable[[Mapping[str, Any]], str] | None = None

    def cell(self, row: Mapping[str, Any]) -> str:
        if self.show is not None:
            return self.show(row)
        value = row[self.key] if self.text else row.get(self.key)
        if self.text:
            return str(value)
        if value is None:
            return "-"
        return str(value) if self.digits is None else f"{value:.{self.digits}f}"


@dataclass(frozen=True)
class Layout:
    """How a paper's rows are written: their ``fields`` (the CSV columns, in order), the text
    ``columns``, the published rows (``paper``) paired with ours by the ``match`` keys, and the
    JSON keys of the rows and details."""

    fields: tuple[str, ...]
    columns: tuple[Column, ...]
    paper: Callable[[], list[dict[str, Any]]] | None = None
    match: tuple[str, ...] = ("group",)
    append_unmatched_paper: bool = False  # published rows pairing none of ours come last
    group_rules: bool = False             # rules between groups (by ``match``) of several rows
    rows_key: str = "rows"
    details_key: str = "details"


@dataclass
class Report:
    """Rows (see :class:`Layout`), the details behind them and a JSON header, of one evaluation."""

    label: str
    rows: list[dict[str, Any]]
    layout: Layout
    details: list[Any] = field(default_factory=list)
    meta: dict[str, Any] = field(default_factory=dict)

    def to_rows(self) -> list[dict[str, Any]]:
        """The rows, one dict each with the keys of the layout's ``fields`` (None where undefined)."""
        return [dict(row) for row in self.rows]

    def format_table(self, compare_paper: bool = False) -> str:
        """A plain-text table; with ``compare_paper`` the published rows stand before ours."""
        rows = merge_paper_rows(self.rows, self.layout) if compare_paper else self.rows
        return format_rows(rows, self.layout)

    def to_csv(self, path: str | os.PathLike) -> Path:
        """Write the rows as CSV (empty cells for None); returns the path."""
        return write_csv(path, self.layout.fields, self.rows)

    def to_dict(self) -> dict[str, Any]:
        """The header, the rows and the details as plain JSON-able data."""
        return {**jsonable(self.meta), self.layout.rows_key: self.to_rows(),
                self.layout.details_key: [jsonable(asdict(d)) for d in self.details]}

    def to_json(self, path: str | os.PathLike) -> Path:
        """Write :meth:`to_dict` as JSON (null for None); returns the path."""
        return write_json(path, self.to_dict())

    def __str__(self) -> str:
        return self.format_table()


def write_reports(reports: Sequence[Report], csv_path: str | os.PathLike | None = None,
                  json_path: str | os.PathLike | None = None) -> list[Path]:
    """One CSV of all reports' rows (the first report's columns) and / or one JSON list of
    their :meth:`Report.to_dict`; returns the paths written."""
    written: list[Path] = []
    if csv_path is not None:
        fields = reports[0].layout.fields if reports else ()
        written.append(write_csv(csv_path, fields, [row for report in reports for row in report.rows]))
    if json_path is not None:
        written.append(write_json(json_path, [report.to_dict() for report in reports]))
    return written


def write_csv(path: str | os.PathLike, fields: Sequence[str], rows: Sequence[Mapping[str, Any]]) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(fields))
        writer.writeheader()
        for row in rows:
            writer.writerow({k: "" if row.get(k) is None else row[k] for k in fields})
    return path


def write_json(path: str | os.PathLike, data: Any) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=2) + "\n")
    return path


def jsonable(value: Any) -> Any:
    """``value`` as plain JSON data: sequences as lists, mappings with string keys, NumPy scalars
    as Python ones, anything else as its ``repr``."""
    if isinstance(value, (str, int, float, bool)) or value is None:
        return value
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, np.generic):
        return value.item()
    return repr(value)


def same_value(a: Any, b: Any) -> bool:
    """Equal, numbers within 1e-9 (so a step height 0.1 matches 0.10000000000000001)."""
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        return math.isclose(a, b, abs_tol=1e-9)
    return a == b


def _same_key(row: Mapping[str, Any], other: Mapping[str, Any], keys: Sequence[str]) -> bool:
    return all(same_value(row[k], other[k]) for k in keys)


def merge_paper_rows(rows: Sequence[Mapping[str, Any]], layout: Layout) -> list[dict[str, Any]]:
    """``rows`` with the layout's published rows of each group (``match`` keys) inserted before
    the group's first row; with ``append_unmatched_paper`` the published rows of groups absent
    from ``rows`` (e.g. 0.05 m steps when heights were random) come last."""
    paper = layout.paper() if layout.paper is not None else []
    merged: list[dict[str, Any]] = []
    used: set[int] = set()
    seen: list[Mapping[str, Any]] = []
    for row in rows:
        if not any(_same_key(row, s, layout.match) for s in seen):
            seen.append(row)
            for i, p in enumerate(paper):
                if i not in used and _same_key(p, row, layout.match):
                    merged.append(p)
                    used.add(i)
        merged.append(dict(row))
    if layout.append_unmatched_paper:
        merged.extend(p for i, p in enumerate(paper) if i not in used)
    return merged


def format_rows(rows: Sequence[Mapping[str, Any]], layout: Layout) -> str:
    """A plain-text table of ``rows`` with the layout's columns: text left-aligned, numbers
    right-aligned, "-" where a number is not defined."""
    columns = layout.columns
    header = [c.header for c in columns]
    body = [[c.cell(r) for c in columns] for r in rows]
    widths = [max(len(h), *(len(b[i]) for b in body)) if body else len(h) for i, h in enumerate(header)]

    def line(cells: Sequence[str]) -> str:
        return "  ".join(c.ljust(w) if col.text else c.rjust(w)
                         for c, w, col in zip(cells, widths, columns)).rstrip()

    rule = "-" * len(line(header))
    out = [line(header), rule]
    boundaries: list[int] = []
    if layout.group_rules:  # rules between groups only help when groups hold several rows
        boundaries = [k for k in range(1, len(rows)) if not _same_key(rows[k], rows[k - 1], layout.match)]
        if len(boundaries) + 1 >= len(rows):
            boundaries = []
    for k, cells in enumerate(body):
        if k in boundaries:
            out.append(rule)
        out.append(line(cells))
    return "\n".join(out)


__all__ = ["Column", "Layout", "Report", "format_rows", "jsonable", "merge_paper_rows", "write_reports"]
