"""Short scripts as objects, and the script database shipped in ``stairenv/screenplays/data``.

The database is our own set of short scripts (JSON files in ``data/``, each a list of
scripts; see :mod:`stairenv.screenplays.schema` for the format). Difficulty follows SIMS
Table 2's buckets by number of interactions (sit, lie, reach): simple 2, mid 3-4, hard
4-6. The paper's mid and hard buckets overlap at 4; here 4 is mid, so hard means 5 or
more. Scripts with fewer than 2 interactions count as simple (the shipped ones all
have at least 2).
"""

from __future__ import annotations

import json
from collections import Counter
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from stairenv.screenplays.schema import (
    INTERACTIONS,
    ScriptValidationError,
    pose_after,
    script_errors,
)

DATA_DIR = Path(__file__).resolve().parent / "data"
DIFFICULTIES: tuple[str, ...] = ("simple", "mid", "hard")


@dataclass(frozen=True)
class Keyframe:
    skill: str
    style: str
    caption: str
    furniture: str | None = None
    part: str | None = None
    hand: str | None = None
    instance: int = 0

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Keyframe:
        return cls(
            skill=d["skill"], style=d["style"], caption=d["caption"], furniture=d.get("furniture"),
            part=d.get("part"), hand=d.get("hand"), instance=int(d.get("instance", 0)),
        )

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"skill": self.skill, "style": self.style, "caption": self.caption}
        for name in ("furniture", "part", "hand"):
            if getattr(self, name) is not None:
                out[name] = getattr(self, name)
        if self.instance:
            out["instance"] = self.instance
        return out

    @property
    def node(self) -> tuple[str, int] | None:
        """The (category, instance) layout node this keyframe targets, if any."""
        return (self.furniture, self.instance) if self.furniture else None


@dataclass(frozen=True)
class Script:
    id: str
    title: str
    summary: str
    keyframes: tuple[Keyframe, ...]
    scene: str | None = None
    start_pose: str = "standing"
    source: str | None = field(default=None, compare=False)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], validate: bool = True, source: str | None = None) -> Script:
        if validate:
            errors = script_errors(d)
            if errors:
                sid = d.get("id") if isinstance(d, Mapping) and isinstance(d.get("id"), str) else None
                raise ScriptValidationError(errors, sid)
        return cls(
            id=d["id"], title=d["title"], summary=d["summary"],
            keyframes=tuple(Keyframe.from_dict(k) for k in d["keyframes"]),
            scene=d.get("scene"), start_pose=d.get("start_pose", "standing"), source=source,
        )

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"id": self.id, "title": self.title, "summary": self.summary}
        if self.scene is not None:
            out["scene"] = self.scene
        if self.start_pose != "standing":
            out["start_pose"] = self.start_pose
        out["keyframes"] = [k.to_dict() for k in self.keyframes]
        return out

    def errors(self) -> list[str]:
        """What the file validation (:func:`~stairenv.screenplays.schema.script_errors`) finds in
        this script: a Script built in code has skipped the checks ``from_dict`` runs."""
        if not isinstance(self.keyframes, (tuple, list)):
            return [f"keyframes: expected a sequence of Keyframe objects, got {type(self.keyframes).__name__}"]
        wrong = [f"keyframes[{i}]: expected a Keyframe, got {type(k).__name__}"
                 for i, k in enumerate(self.keyframes) if not isinstance(k, Keyframe)]
        return wrong or script_errors(self.to_dict())

    # -- derived facts
    @property
    def skills(self) -> frozenset[str]:
        return frozenset(k.skill for k in self.keyframes)

    @property
    def styles(self) -> Counter:
        """Style counts over the keyframes, neutral left out."""
        return Counter(k.style for k in self.keyframes if k.style != "neutral")

    @property
    def main_style(self) -> str:
        """The most frequent non-neutral style (ties: first to appear); neutral if none."""
        counts = self.styles
        if not counts:
            return "neutral"
        best = max(counts.values())
        return next(k.style for k in self.keyframes if counts.get(k.style) == best)

    @property
    def retrieval_text(self) -> str:
        """What story retrieval embeds: the summary and the moods (SIMS gives its LLM the
        summaries and emotions), e.g. ``"... on the bed. Mood: tired."``."""
        moods = [s for s, _ in self.styles.most_common()]
        return f"{self.summary} Mood: {', '.join(moods) if moods else 'neutral'}."

    @property
    def n_interactions(self) -> int:
        return sum(k.skill in INTERACTIONS for k in self.keyframes)

    @property
    def difficulty(self) -> str:
        return difficulty_of(self.n_interactions)

    @property
    def start_at(self) -> tuple[str, int] | None:
        """Where a script that starts sitting/lying is (its first getup's furniture)."""
        if self.start_pose == "standing":
            return None
        return self.keyframes[0].node

    @property
    def end_state(self) -> tuple[str, tuple[str, int] | None]:
        """(pose, (category, instance)) after the last keyframe."""
        return pose_after(self.keyframes, self.start_pose, self.start_at)

    @property
    def furniture_nodes(self) -> list[tuple[str, int]]:
        """Distinct (category, instance) items the script uses, in first-use order."""
        seen: dict[tuple[str, int], None] = {}
        for k in self.keyframes:
            if k.node is not None:
                seen.setdefault(k.node)
        return list(seen)


def difficulty_of(n_interactions: int) -> str:
    """SIMS Table 2 bucket: <= 2 simple, 3-4 mid, >= 5 hard (the paper's 4 overlap goes to mid)."""
    if n_interactions <= 2:
        return "simple"
    if n_interactions <= 4:
        return "mid"
    return "hard"


class ScriptDatabase(Sequence[Script]):
    """An ordered, id-indexed collection of validated short scripts."""

    def __init__(self, scripts: Iterable[Script | Mapping[str, Any]]):
        items: list[Script] = []
        index: dict[str, Script] = {}
        for s in scripts:
            script = s if isinstance(s, Script) else Script.from_dict(s)
            if script.id in index:
                raise ValueError(f"duplicate script id {script.id!r} ({script.source} and {index[script.id].source})")
            index[script.id] = script
            items.append(script)
        self._scripts = items
        self._index = index

    def __len__(self) -> int:
        return len(self._scripts)

    def __getitem__(self, i):  # type: ignore[override]
        return self._scripts[i]

    def __iter__(self) -> Iterator[Script]:
        return iter(self._scripts)

    def __contains__(self, item: object) -> bool:
        return item in self._index if isinstance(item, str) else item in self._scripts

    def get(self, script_id: str) -> Script:
        try:
            return self._index[script_id]
        except KeyError:
            raise KeyError(f"no script {script_id!r} in the database") from None

    @property
    def ids(self) -> list[str]:
        return [s.id for s in self._scripts]

    def filter(self, *, style: str | None = None, skill: str | None = None,
               difficulty: str | None = None, furniture: str | None = None) -> ScriptDatabase:
        def keep(s: Script) -> bool:
            if style is not None and style not in s.styles:
                return False
            if skill is not None and skill not in s.skills:
                return False
            if difficulty is not None and s.difficulty != difficulty:
                return False
            return furniture is None or any(k.furniture == furniture for k in s.keyframes)

        return ScriptDatabase(s for s in self._scripts if keep(s))

    def coverage(self) -> dict[str, Counter]:
        """Counts of scripts per style, skill, difficulty and furniture category."""
        out = {"style": Counter(), "skill": Counter(), "difficulty": Counter(), "furniture": Counter()}
        for s in self._scripts:
            out["style"].update(set(s.styles))
            out["skill"].update(s.skills)
            out["difficulty"][s.difficulty] += 1
            out["furniture"].update({k.furniture for k in s.keyframes if k.furniture})
        return out


class ScriptFileError(ValueError):
    """A script file that is not JSON text (not UTF-8, malformed or nested too deeply)."""


def _read_scripts(path: Path) -> list[Script]:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, RecursionError, ValueError) as e:  # ValueError: JSONDecodeError, huge numbers
        raise ScriptFileError(f"{path}: not a JSON script file: {e}") from e
    items = data if isinstance(data, list) else [data]
    out = []
    for i, d in enumerate(items):
        try:
            out.append(Script.from_dict(d, source=f"{path.name}[{i}]"))
        except ScriptValidationError as e:
            raise ScriptValidationError(e.errors, f"{e.script_id or '?'} in {path.name}[{i}]") from None
    return out


def load_database(paths: str | Path | Iterable[str | Path] | None = None) -> ScriptDatabase:
    """Load and validate scripts from JSON files or directories (default: the shipped data).

    A file holds one script object or a list of them; a directory contributes its ``*.json``
    files in name order. Raises :class:`ScriptFileError` naming a file that is not JSON, and
    :class:`~stairenv.screenplays.schema.ScriptValidationError` naming the file and index of an
    invalid script.
    """
    if paths is None:
        paths = [DATA_DIR]
    elif isinstance(paths, (str, Path)):
        paths = [paths]
    files: list[Path] = []
    for p in map(Path, paths):
        files.extend(sorted(p.glob("*.json")) if p.is_dir() else [p])
    scripts: list[Script] = []
    for f in files:
        scripts.extend(_read_scripts(f))
    return ScriptDatabase(scripts)
