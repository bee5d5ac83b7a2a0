"""Templated navigation instructions -> (source, target, locomotion) segments.

PlaMo's planner reads instructions such as "Run from the tree to the lake", one per
segment, and turns each into a triplet (source landmark, target landmark, locomotion).
Grammar accepted here (case-insensitive; articles and a few filler words ignored)::

    text    := clause ((", then" | "then" | "," | ";" | "." | "and" VERB) clause)*
    clause  := VERB+ ["from" LANDMARK] "to" LANDMARK ["from" LANDMARK]

VERB is any word of the locomotion table (``stairenv.planning.locomotion``); a walk word
with one other locomotion word means the other ("walk crouching", "crouch walk" and
"crouch-walk" are crouch-walk, "go crawling" is crawl); other mixtures are ambiguous. A clause without "from" starts at the
current position (first clause, ``source=None``) or at the previous clause's target.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from .errors import InstructionError, quote
from .locomotion import LOCOMOTION_WORDS

_FILLER = frozenset(("please", "now", "then", "and", "back", "over", "straight", "all", "the", "way",
                     "slowly", "quickly", "fast", "carefully", "on", "your", "you", "should", "must", "to"))
_ARTICLES = ("the ", "a ", "an ")
_CLAUSE = re.compile(r"^(?P<verb>.+?)\s+(?:from\s+(?P<src>.+?)\s+)?to\s+(?P<tgt>.+?)(?:\s+from\s+(?P<src2>.+?))?$")


@dataclass(frozen=True)
class Segment:
    """One leg of a route: from ``source`` (None: the current position) to ``target`` by ``locomotion``."""

    source: str | None
    target: str
    locomotion: str


def _norm(name: str) -> str:
    name = re.sub(r"[_\-]+", " ", name.strip().lower())
    return re.sub(r"\s+", " ", name)


def _split_clauses(text: str) -> list[str]:
    # every run of white space read as one space first: the patterns below start with \s*, and a run of a
    # million spaces made them try every suffix of it (quadratic: 16,000 spaces took 40 s)
    text = re.sub(r"\s+", " ", text.lower())
    verbs = "|".join(sorted((re.escape(w) for w in LOCOMOTION_WORDS), key=len, reverse=True))
    # "and" + a locomotion word starts a clause; "then", ",", ";", "." always do.
    text = re.sub(rf"\band\s+(?=(?:then\s+)?(?:{verbs})\b)", " ; ", text)
    parts = re.split(r"\s*(?:[,;.!?]\s*(?:and\s+)?then\b|\bthen\b|[,;.!?])\s*", text)
    return [p.strip() for p in parts if p and p.strip()]


def _locomotion(verb_phrase: str, clause: str) -> str:
    names = []
    for word in re.split(r"[\s\-]+", verb_phrase.strip()):
        if word in LOCOMOTION_WORDS:
            names.append(LOCOMOTION_WORDS[word])
        elif word and word not in _FILLER:
            raise InstructionError(_unknown_verb(word, clause))
    found = set(names)
    if not found:
        raise InstructionError(_unknown_verb(verb_phrase, clause))
    if len(found) == 2 and "walk" in found:  # "walk crouching", "go crawling": the manner word wins
        found.discard("walk")
    if len(found) > 1:
        raise InstructionError(f"ambiguous locomotion in {quote(clause)}: {sorted(found)}; use one of "
                               f"{sorted(set(LOCOMOTION_WORDS.values()))}")
    return found.pop()


def _unknown_verb(word: str, clause: str) -> str:
    by_name: dict[str, list[str]] = {}
    for w, name in LOCOMOTION_WORDS.items():
        by_name.setdefault(name, []).append(w)
    known = "; ".join(f"{name}: {', '.join(ws)}" for name, ws in by_name.items())
    return f"unknown locomotion verb {quote(word)} in {quote(clause)}; known verbs are {known}"


def _landmark(phrase: str, known: dict[str, str], clause: str) -> str:
    phrase = _norm(phrase)
    for article in _ARTICLES:
        if phrase.startswith(article):
            phrase = phrase[len(article):]
            break
    if phrase in known:
        return known[phrase]
    raise InstructionError(f"unknown landmark {quote(phrase)} in {quote(clause)}; known landmarks are "
                           f"{sorted(known.values())}")


def parse_instructions(text: str | Sequence[str], landmarks: Iterable[str]) -> list[Segment]:
    """Segments of an instruction text (or of a list of instruction sentences).

    ``landmarks`` are the scene's landmark names (e.g. ``grid.landmarks``); names match
    case-insensitively with ``_`` and ``-`` read as spaces. Raises ``InstructionError``
    (a ValueError) listing the known landmarks or verbs when a name or verb is unknown; a message quotes
    at most ``QUOTE_CHARS`` (80) characters of the text (``errors.quote``).
    """
    known = {_norm(name): name for name in landmarks}
    if not known:
        raise InstructionError("the scene has no landmarks to navigate to")
    texts = [text] if isinstance(text, str) else list(text)
    clauses = [c for t in texts for c in _split_clauses(str(t))]
    if not clauses:
        raise InstructionError(f"no instruction found in {quote(text)}")
    segments: list[Segment] = []
    for clause in clauses:
        m = _CLAUSE.match(clause)
        if m is None:
            raise InstructionError(f"cannot read {quote(clause)}: expected '<verb> [from <landmark>] to <landmark>', "
                                   f"e.g. 'crawl from the car to the swing'")
        locomotion = _locomotion(m["verb"], clause)
        target = _landmark(m["tgt"], known, clause)
        src = m["src"] or m["src2"]
        if src is not None:
            source = _landmark(src, known, clause)
        else:
            source = segments[-1].target if segments else None
        segments.append(Segment(source, target, locomotion))
    return segments
