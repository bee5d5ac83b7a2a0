"""Long-script assembly: retrieve short scripts for a theme and order them into a story.

SIMS (Sec. 3.2, "Long-Term Script Matching") asks an LLM to pick short scripts from the
database by their summaries and emotions and to arrange them chronologically. Offline, by
default, :func:`assemble_story` does it with embeddings:

1. embed the theme and every script's summary with its moods (``Script.retrieval_text``; any :class:`~stairenv.screenplays.embeddings.TextEncoder`);
   the ``pool`` scripts most similar to the theme (cosine) are the candidates;
2. greedy chain: the opener is the most theme-similar candidate that starts standing; each
   next script maximises ``w_theme * sim(theme, s) + w_chain * sim(previous, s)`` plus
   ``continue_bonus`` when it picks up where the previous one ended (it starts with the
   getup from the very seat/bed the previous script ended on) or minus ``getup_penalty``
   when a getup has to be inserted; scripts whose start is incompatible with the previous
   end are skipped (:func:`transition`). With an ``rng`` the choice is sampled from a
   softmax of those scores (``temperature``) instead of the argmax;
3. keyframes are concatenated, with a neutral "gets up" keyframe inserted where a script
   ended seated or lying and the next starts standing; the result passes
   :func:`~stairenv.screenplays.schema.semantic_errors`.

An LLM can take over the ordering and write the narrative through :class:`LLMBackend`;
the default :class:`NoLLM` does neither (greedy order, a template narrative). To plug in a
client, wrap a ``prompt -> reply`` function in :class:`CompletionLLM` or implement the two
methods. An LLM's order is checked: unknown or repeated ids and invalid transitions are
dropped, and an empty result falls back to the greedy chain.
"""

from __future__ import annotations

import itertools
import json
import re
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import networkx as nx
import numpy as np

from stairenv.screenplays.database import Keyframe, Script
from stairenv.screenplays.embeddings import TextEncoder, cosine_similarity
from stairenv.screenplays.schema import semantic_errors


@dataclass(frozen=True)
class Transition:
    """How script ``b`` follows script ``a``: ``"direct"`` (a ends standing, b starts standing),
    ``"continue"`` (b starts with the getup from where a ended) or ``"getup"`` (a getup keyframe
    is inserted; ``inserted`` holds it)."""

    kind: str
    inserted: Keyframe | None = None


def transition(a: Script, b: Script) -> Transition | None:
    """The transition from ``a``'s end to ``b``'s start, or None if b cannot follow a."""
    pose, at = a.end_state
    if pose == "standing":
        return Transition("direct") if b.start_pose == "standing" else None
    if b.start_pose == pose and b.start_at == at:
        return Transition("continue")
    if b.start_pose == "standing" and at is not None:
        cat, inst = at
        return Transition("getup", Keyframe(skill="getup", style="neutral", caption=f"gets up from the {cat}",
                                            furniture=cat, instance=inst))
    return None


@runtime_checkable
class LLMBackend(Protocol):
    """An optional language model for the planner. Either method may return None to let the
    offline planner decide."""

    def order(self, theme: str, candidates: Sequence[Script], length: int) -> Sequence[str] | None:
        """Script ids, chosen from ``candidates``, in story order."""
        ...

    def narrate(self, theme: str, scripts: Sequence[Script]) -> str | None:
        """A narrative joining the ordered scripts' summaries for the theme."""
        ...


class NoLLM:
    """The default backend: no language model (greedy ordering, template narrative)."""

    def order(self, theme: str, candidates: Sequence[Script], length: int) -> None:
        return None

    def narrate(self, theme: str, scripts: Sequence[Script]) -> None:
        return None


class CompletionLLM:
    """Adapts a text-completion function (``complete(prompt) -> reply``) to :class:`LLMBackend`.

    ``order`` asks for a JSON list of ids and parses the first ``[...]`` in the reply;
    ``narrate`` returns the reply stripped. Any exception or unparsable reply -> None.
    """

    def __init__(self, complete: Callable[[str], str]):
        self.complete = complete

    def order(self, theme: str, candidates: Sequence[Script], length: int) -> list[str] | None:
        lines = [f'- id "{s.id}" (style: {s.main_style}, starts {s.start_pose}, ends {s.end_state[0]}): {s.summary}'
                 for s in candidates]
        prompt = (
            f"Story theme: {theme}\n"
            f"Choose {length} of these short scripts and put them in chronological order so they "
            "form one coherent story with a consistent emotional flow. A script that starts sitting "
            "or lying must directly follow one that ends that way.\n" + "\n".join(lines) +
            "\nAnswer with a JSON list of ids only."
        )
        try:
            reply = self.complete(prompt)
            m = re.search(r"\[.*?\]", reply, re.DOTALL)
            ids = json.loads(m.group(0)) if m else None
        except Exception:  # noqa: BLE001 - any failure of a user's client means "no answer"
            return None
        return [str(i) for i in ids] if isinstance(ids, list) else None

    def narrate(self, theme: str, scripts: Sequence[Script]) -> str | None:
        prompt = (f"Story theme: {theme}\nWrite a short third-person story that follows these scenes "
                  "in order:\n" + "\n".join(f"{i + 1}. {s.summary}" for i, s in enumerate(scripts)))
        try:
            reply = self.complete(prompt)
        except Exception:  # noqa: BLE001 - any failure of a user's client means "no answer"
            return None
        return reply.strip() or None


def template_narrative(theme: str, scripts: Sequence[Script]) -> str:
    connectors = ["First,", "Then", "After that,", "Later,", "Next,"]
    parts = [theme.strip().rstrip(".") + "."]
    for i, s in enumerate(scripts):
        text = s.summary.strip()
        if i == len(scripts) - 1 and i > 0:
            lead = "Finally,"
        else:
            lead = connectors[min(i, len(connectors) - 1)] if i < len(connectors) else "Then"
        parts.append(f"{lead} {text[0].lower() + text[1:]}")
    return " ".join(parts)


@dataclass
class Story:
    theme: str
    scripts: list[Script]
    keyframes: list[Keyframe]
    sources: list[str | None]
    """Script id of each keyframe; None for an inserted transition keyframe."""
    narrative: str
    theme_similarity: list[float] = field(default_factory=list)
    chain_similarity: list[float] = field(default_factory=list)
    transitions: list[str] = field(default_factory=list)
    planner: str = "greedy"

    @property
    def script_ids(self) -> list[str]:
        return [s.id for s in self.scripts]

    def errors(self) -> list[str]:
        """Pose-rule violations of the concatenated keyframes (empty for a valid story)."""
        if not self.scripts:
            return []
        first = self.scripts[0]
        return semantic_errors(self.keyframes, start_pose=first.start_pose, start_at=first.start_at)

    def layout_graph(self) -> nx.Graph:
        from stairenv.screenplays.retrieval import layout_graph_of

        return layout_graph_of(self)

    def required_furniture(self) -> Counter:
        from stairenv.screenplays.retrieval import required_furniture

        return required_furniture(self)

    def to_dict(self) -> dict:
        return {
            "theme": self.theme,
            "scripts": self.script_ids,
            "narrative": self.narrative,
            "keyframes": [dict(k.to_dict(), script=src) for k, src in zip(self.keyframes, self.sources)],
        }


def _concat(scripts: Sequence[Script]) -> tuple[list[Keyframe], list[str | None], list[str]]:
    keyframes: list[Keyframe] = []
    sources: list[str | None] = []
    kinds: list[str] = []
    for i, s in enumerate(scripts):
        if i > 0:
            t = transition(scripts[i - 1], s)
            if t is None:
                raise ValueError(f"script {s.id!r} cannot follow {scripts[i - 1].id!r}")
            kinds.append(t.kind)
            if t.inserted is not None:
                keyframes.append(t.inserted)
                sources.append(None)
        keyframes.extend(s.keyframes)
        sources.extend([s.id] * len(s.keyframes))
    return keyframes, sources, kinds


def chain_scripts(scripts: Sequence[Script], theme: str = "", narrative: str | None = None) -> Story:
    """A story from scripts in the given order (raises ValueError on an impossible transition)."""
    keyframes, sources, kinds = _concat(scripts)
    return Story(theme, list(scripts), keyframes, sources,
                 narrative if narrative is not None else template_narrative(theme, scripts),
                 transitions=kinds, planner="given")


def assemble_story(theme: str, database: Sequence[Script], encoder: TextEncoder, length: int = 4,
                   rng: np.random.Generator | int | None = None, *, llm: LLMBackend | None = None,
                   pool: int | None = None, w_theme: float = 1.0, w_chain: float = 0.5,
                   continue_bonus: float = 0.05, getup_penalty: float = 0.05,
                   temperature: float = 0.05) -> Story:
    """Retrieve and order up to ``length`` short scripts into a story for ``theme``.

    ``rng``: None for the deterministic argmax chain, a Generator or seed to sample.
    ``llm``: an :class:`LLMBackend` (default :class:`NoLLM`, i.e. fully offline).
    ``pool``: how many theme-nearest scripts are candidates (default ``max(3 * length, 10)``).
    The story may be shorter than ``length`` if no candidate can follow.
    """
    scripts = list(database)
    if not scripts:
        raise ValueError("empty script database")
    if length < 1:
        raise ValueError("length must be >= 1")
    llm = llm or NoLLM()
    vecs = np.asarray(encoder.encode([theme] + [s.retrieval_text for s in scripts]), dtype=np.float32)
    theme_sim = cosine_similarity(vecs[:1], vecs[1:])[0]
    pair_sim = cosine_similarity(vecs[1:], vecs[1:])
    k = min(len(scripts), pool if pool is not None else max(3 * length, 10))
    cand = [int(i) for i in np.argsort(-theme_sim, kind="stable")[:k]]
    gen = np.random.default_rng(rng) if rng is not None else None

    chosen: list[int] = []
    planner = "greedy"
    ids = llm.order(theme, [scripts[i] for i in cand], length)
    if ids:
        pos = {scripts[i].id: i for i in cand}
        for sid in ids:
            i = pos.get(sid)
            if i is None or i in chosen:
                continue
            if not chosen and scripts[i].start_pose != "standing":
                continue
            if chosen and transition(scripts[chosen[-1]], scripts[i]) is None:
                continue
            chosen.append(i)
            if len(chosen) == length:
                break
        planner = "llm" if chosen else "greedy"

    def pick(options: list[int], scores: list[float]) -> int:
        if gen is None:
            return options[int(np.argmax(scores))]
        z = np.asarray(scores) / max(temperature, 1e-6)
        p = np.exp(z - z.max())
        return options[int(gen.choice(len(options), p=p / p.sum()))]

    if not chosen:
        openers = [i for i in cand if scripts[i].start_pose == "standing"]
        if not openers:
            raise ValueError("no candidate script starts standing")
        chosen.append(pick(openers, [w_theme * float(theme_sim[i]) for i in openers]))
        while len(chosen) < length:
            prev = chosen[-1]
            options, scores = [], []
            for i in cand:
                if i in chosen:
                    continue
                t = transition(scripts[prev], scripts[i])
                if t is None:
                    continue
                s = w_theme * float(theme_sim[i]) + w_chain * float(pair_sim[prev, i])
                s += continue_bonus if t.kind == "continue" else 0.0
                s -= getup_penalty if t.kind == "getup" else 0.0
                options.append(i)
                scores.append(s)
            if not options:
                break
            chosen.append(pick(options, scores))

    ordered = [scripts[i] for i in chosen]
    keyframes, sources, kinds = _concat(ordered)
    narrative = llm.narrate(theme, ordered) or template_narrative(theme, ordered)
    return Story(
        theme=theme, scripts=ordered, keyframes=keyframes, sources=sources, narrative=narrative,
        theme_similarity=[float(theme_sim[i]) for i in chosen],
        chain_similarity=[float(pair_sim[a, b]) for a, b in itertools.pairwise(chosen)],
        transitions=kinds, planner=planner,
    )
