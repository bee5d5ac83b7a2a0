"""Room-layout graphs and room retrieval by graph edit distance (SIMS Sec. 3.2, "Scene Graph
Matching").

**Layout graphs.** A room is a :class:`networkx.Graph` whose nodes carry ``category`` (one
of :data:`~stairenv.screenplays.schema.FURNITURE`) and optionally ``position``; an edge joins
two items that are near each other (``stairenv.world.rooms.Room.layout_graph()`` builds
these; :func:`random_layout_graph` makes synthetic ones). A script's *query* graph has one
node per (category, instance) it uses, with the skills and parts used on it, and an edge
between items the script visits one after the other (they belong to one small scene, so
they should be near each other: a soft requirement). Several scripts merge as in SIMS:
the union of the (category, instance) nodes - which is the per-category maximum of
instances over the scripts (greedy node consolidation) - and of the edges.

**Costs.** Matching the query Q against a room R with ``nx.optimize_edit_paths(Q, R)``:

=========================================  ================================================
edit                                       cost (:class:`GEDCosts` defaults)
=========================================  ================================================
query item matched to same category        0
query item matched to an allowed substitute  :data:`DEFAULT_SUBSTITUTIONS` (0.2-0.5), only
                                           if the substitute affords the skills and has the
                                           parts the script uses on it
query item matched to anything else        ``missing + extra`` (never better than
                                           deleting + inserting; reported as unmatched)
query item deleted (room lacks it)         ``missing`` = 1
room item inserted (room has more)         ``extra`` = 0.01
query edge deleted (items not near)        ``edge_missing`` = 0.1
room edge inserted                         ``edge_extra`` = 0
=========================================  ================================================

Extra furniture is nearly free (a room normally has more than a script uses; plain GED
with insertion cost 1 would prefer an empty room lacking an item to a full room that has
it); the small cost prefers compact rooms among equals. With these numbers and rooms of
fewer than 20 items: exact category < substitute < missing. Ranking is lexicographic:
during the search a deletion also costs ``incomplete_penalty`` (100), so any room that
hosts every item (however many substitutes and missing adjacencies) ranks above any room
that lacks one; ``RoomMatch.distance`` is reported without it.

**Speed.** The node part of the edit distance alone, solved as a linear sum assignment
over categories (``scipy.optimize.linear_sum_assignment`` on the usual (n+m)^2 matrix with
deletion and insertion blocks), is a lower bound of the GED (edge costs are >= 0). Rooms
are visited in increasing bound; exact GED runs only while the bound is below the best
distance found, with that distance as networkx's ``upper_bound`` and a per-room
``timeout``. When the query has no edges (and ``edge_extra`` is 0) the bound *is* the GED
and networkx is not needed. ``benchmarks/bench_retrieval.py`` times 1,000 rooms.

**Fallback.** If the best room leaves a required item unmatched (or exceeds
``max_distance``), ``fallback(categories)`` builds a room with those categories (e.g.
:func:`world_room_builder`, which calls ``stairenv.world.rooms.generate_room(config, rng,
categories=cats)``, importing that module only then); its
layout graph (``.layout_graph()``, or the returned graph itself) is matched the same way.
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable, Hashable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import networkx as nx
import numpy as np
from scipy.optimize import linear_sum_assignment

from stairenv.screenplays.schema import AFFORDANCES, FURNITURE, FURNITURE_PARTS

#: required category -> {acceptable substitute category: cost}. Directional: a script that
#: wants a chair accepts a stool; whether the substitute fits the script's use (lying,
#: a backrest) is checked against AFFORDANCES / FURNITURE_PARTS at match time.
DEFAULT_SUBSTITUTIONS: dict[str, dict[str, float]] = {
    "chair": {"armchair": 0.2, "stool": 0.3},
    "stool": {"chair": 0.2, "armchair": 0.3},
    "armchair": {"chair": 0.3, "sofa": 0.3},
    "sofa": {"armchair": 0.4, "bed": 0.5},
    "bed": {"double bed": 0.2},
    "double bed": {"bed": 0.3},
    "table": {"cabinet": 0.5},
    "cabinet": {"wardrobe": 0.4, "bookshelf": 0.4, "table": 0.5},
    "wardrobe": {"cabinet": 0.4},
    "bookshelf": {"cabinet": 0.4},
    "lamp": {},
}


@dataclass(frozen=True)
class GEDCosts:
    """Edit costs (see the module docstring). ``incomplete_penalty`` is added to every
    deletion *during the search only*, so that a room hosting every required item always
    ranks above one that lacks any (lexicographic: completeness first, then distance); the
    reported ``RoomMatch.distance`` leaves it out. 0 gives plain GED ranking."""

    missing: float = 1.0
    extra: float = 0.01
    edge_missing: float = 0.1
    edge_extra: float = 0.0
    incomplete_penalty: float = 100.0

    @property
    def deletion(self) -> float:
        """Search cost of a required item the room lacks."""
        return self.missing + self.incomplete_penalty

    @property
    def mismatch(self) -> float:
        """Search cost of matching unrelated categories (= deletion + insertion)."""
        return self.deletion + self.extra


class NoRoomFoundError(LookupError):
    """No room hosts the required furniture and no fallback builder was given (or the
    fallback's room does not either). ``best`` is the closest :class:`RoomMatch` or None."""

    def __init__(self, message: str, best: RoomMatch | None = None):
        super().__init__(message)
        self.best = best


@dataclass
class RoomMatch:
    room_id: Any
    graph: nx.Graph
    distance: float
    """Graph edit distance with the :class:`GEDCosts` (missing item = ``missing``)."""
    mapping: dict[Hashable, Hashable | None]
    """query node -> room node (None: the room lacks it)."""
    substitutions: dict[Hashable, tuple[str, str]] = field(default_factory=dict)
    """query node -> (wanted category, room's category) where a substitute was used."""
    lower_bound: float = 0.0
    """The category-assignment bound on ``search_cost``."""
    exact: bool = True
    """False when a networkx timeout cut the search (distance is then an upper bound)."""
    generated: bool = False
    room: Any = None
    """What the fallback builder returned (generated rooms only)."""
    stats: dict[str, Any] = field(default_factory=dict)
    search_cost: float = 0.0
    """distance + incomplete_penalty per missing item: what the search ranks by."""

    @property
    def complete(self) -> bool:
        return all(v is not None for v in self.mapping.values())

    @property
    def missing(self) -> list[Hashable]:
        return [k for k, v in self.mapping.items() if v is None]


# --------------------------------------------------------------------------- query graphs


def _add_item(g: nx.Graph, node: tuple[str, int], skills=(), parts=()) -> None:
    if node not in g:
        g.add_node(node, category=node[0], skills=set(), parts=set())
    g.nodes[node]["skills"].update(skills)
    g.nodes[node]["parts"].update(p for p in parts if p)


def script_layout_graph(script) -> nx.Graph:
    """Query graph of one script: (category, instance) nodes with the ``skills`` and ``parts``
    used on them; edges between items visited one after the other."""
    g = nx.Graph()
    prev: tuple[str, int] | None = None
    for kf in script.keyframes:
        node = kf.node
        if node is None:
            continue
        _add_item(g, node, [kf.skill], [kf.part])
        if prev is not None and prev != node:
            g.add_edge(prev, node)
        prev = node
    return g


def merge_layout_graphs(graphs: Iterable[nx.Graph]) -> nx.Graph:
    """SIMS' merge of script sub-layouts: union of (category, instance) nodes (so each
    category gets the most instances any script needs) and of edges; uses are unioned."""
    out = nx.Graph()
    for g in graphs:
        for n, d in g.nodes(data=True):
            _add_item(out, n, d.get("skills", ()), d.get("parts", ()))
        out.add_edges_from(g.edges())
    return out


def layout_graph_of(obj) -> nx.Graph:
    """Query graph of a Script, a Story (anything with ``scripts``), a sequence of scripts,
    a category list/Counter, or a graph (returned with ``skills``/``parts`` defaults)."""
    if isinstance(obj, nx.Graph):
        g = obj.copy()
        for _, d in g.nodes(data=True):
            if "category" not in d:
                raise ValueError("query graph nodes need a 'category' attribute")
            d["category"] = canonical_category(d["category"])
            d["skills"] = set(d.get("skills", ()))
            d["parts"] = set(d.get("parts", ()))
        return g
    if hasattr(obj, "keyframes") and not hasattr(obj, "scripts"):
        return script_layout_graph(obj)
    if hasattr(obj, "scripts"):
        return merge_layout_graphs(script_layout_graph(s) for s in obj.scripts)
    if isinstance(obj, Mapping):  # Counter of categories
        cats = [c for c, k in obj.items() for _ in range(int(k))]
        return layout_graph_of(cats)
    items = list(obj)
    if items and all(hasattr(s, "keyframes") for s in items):
        return merge_layout_graphs(script_layout_graph(s) for s in items)
    g = nx.Graph()
    seen: Counter = Counter()
    for c in items:
        if not isinstance(c, str):
            raise TypeError(f"expected furniture categories, got {c!r}")
        c = canonical_category(c)
        _add_item(g, (c, seen[c]))
        seen[c] += 1
    return g


def required_furniture(obj) -> Counter:
    """Category multiset a room must offer for a script, a story or a list of scripts
    (per category, the most instances any one script uses)."""
    g = layout_graph_of(obj)
    return Counter(d["category"] for _, d in g.nodes(data=True))


# --------------------------------------------------------------------------- costs


class _CostModel:
    """Category-level costs for one query (node attrs -> cost) and the category LSAP bound."""

    def __init__(self, query: nx.Graph, substitutions: Mapping[str, Mapping[str, float]], costs: GEDCosts):
        self.query = query
        self.costs = costs
        self.subs = substitutions
        self.qnodes = list(query.nodes)
        self.cat_index = {c: i for i, c in enumerate(FURNITURE)}
        n_cat = len(FURNITURE) + 1  # last column: unknown category
        table = np.full((len(self.qnodes), n_cat), costs.mismatch)
        for i, q in enumerate(self.qnodes):
            d = query.nodes[q]
            for c, j in self.cat_index.items():
                table[i, j] = self.pair_cost(d["category"], c, d.get("skills", ()), d.get("parts", ()))
        self.table = table

    def pair_cost(self, want: str, have: str, skills=(), parts=()) -> float:
        if want == have:
            return 0.0
        cost = self.subs.get(want, {}).get(have)
        if cost is None:
            return self.costs.mismatch
        if any(have not in AFFORDANCES.get(s, ()) for s in skills):
            return self.costs.mismatch
        if any(p not in FURNITURE_PARTS.get(have, ()) for p in parts):
            return self.costs.mismatch
        return float(min(cost, self.costs.mismatch))

    def room_columns(self, categories: Sequence[str]) -> np.ndarray:
        unknown = len(FURNITURE)
        return np.fromiter((self.cat_index.get(c, unknown) for c in categories), dtype=np.intp,
                           count=len(categories))

    def assignment(self, cols: np.ndarray) -> tuple[float, list[int | None]]:
        """Node-only edit distance (LSAP) and, per query node, the room node index or None."""
        n, m = len(self.qnodes), len(cols)
        c = self.costs
        big = 1e9
        mat = np.zeros((n + m, m + n))
        mat[:n, :m] = self.table[:, cols]
        mat[:n, m:] = big
        mat[np.arange(n), m + np.arange(n)] = c.deletion
        mat[n:, :m] = big
        mat[n + np.arange(m), np.arange(m)] = c.extra
        rows, colsel = linear_sum_assignment(mat)
        total = float(mat[rows, colsel].sum())
        assign: list[int | None] = [None] * n
        for r, k in zip(rows, colsel):
            if r < n and k < m and mat[r, k] < c.mismatch:
                assign[r] = int(k)
        return total, assign


def canonical_category(name: str) -> str:
    """One spelling for categories: scripts write "double bed", ``stairenv.world.furniture``
    families are "double_bed"."""
    return str(name).replace("_", " ")


def _room_graph(obj) -> nx.Graph:
    if isinstance(obj, nx.Graph):
        graph = obj
    elif hasattr(obj, "layout_graph"):
        graph = obj.layout_graph()
    else:
        raise TypeError(f"expected a networkx graph or an object with layout_graph(), got {type(obj).__name__}")
    if any("_" in str(d.get("category", "")) for _, d in graph.nodes(data=True)):
        graph = graph.copy()
        for _, d in graph.nodes(data=True):
            if "category" in d:
                d["category"] = canonical_category(d["category"])
    return graph


class RoomIndex:
    """Rooms prepared for repeated retrieval: ``RoomIndex([(room_id, graph_or_room), ...])``."""

    def __init__(self, rooms: Iterable[tuple[Any, Any]]):
        self.ids: list[Any] = []
        self.graphs: list[nx.Graph] = []
        self.nodes: list[list[Hashable]] = []
        self.categories: list[list[str]] = []
        for room_id, obj in rooms:
            g = _room_graph(obj)
            nodes = list(g.nodes)
            self.ids.append(room_id)
            self.graphs.append(g)
            self.nodes.append(nodes)
            self.categories.append([g.nodes[n].get("category", "") for n in nodes])

    def __len__(self) -> int:
        return len(self.ids)

    def retrieve(self, required, *, substitutions: Mapping[str, Mapping[str, float]] = DEFAULT_SUBSTITUTIONS,
                 costs: GEDCosts | None = None, timeout: float = 0.05, max_distance: float | None = None,
                 fallback: Callable[[list[str]], Any] | None = None) -> RoomMatch:
        """Best room for ``required`` (see :func:`retrieve_room`)."""
        costs = costs or GEDCosts()
        query = layout_graph_of(required)
        if query.number_of_nodes() == 0:
            raise ValueError("nothing required: the query has no furniture")
        model = _CostModel(query, substitutions, costs)
        best = self._search(query, model, timeout) if len(self) else None
        if best is not None and best.complete and (max_distance is None or best.distance <= max_distance + 1e-12):
            return best
        cats = [d["category"] for _, d in query.nodes(data=True)]
        if fallback is None:
            if best is None:
                raise NoRoomFoundError("no rooms to search and no fallback builder", None)
            why = (f"lacks {best.missing}" if not best.complete
                   else f"is at distance {best.distance:.3f} > max_distance {max_distance}")
            raise NoRoomFoundError(f"the best room ({best.room_id!r}) {why}; pass fallback= to build one", best)
        built = fallback(cats)
        room_id = getattr(built, "room_id", None) or getattr(built, "name", None) or "generated"
        graph = _room_graph(built)
        if query.number_of_edges() == 0 and costs.edge_extra == 0.0:
            nodes = list(graph.nodes)
            lb, assign = model.assignment(model.room_columns([graph.nodes[n].get("category", "") for n in nodes]))
            match = _assignment_match(query, model, room_id, graph, nodes, lb, assign)
        else:  # one room: allow the exact search more time
            match = _match_one(query, model, room_id, graph, max(timeout, 1.0), upper_bound=None)
        if match is None or not match.complete:
            raise NoRoomFoundError(
                f"the fallback builder's room does not host {cats} (missing {match.missing if match else cats})",
                best)
        match.generated = True
        match.room = built
        match.stats["searched"] = best.stats if best is not None else {}
        return match

    def _search(self, query: nx.Graph, model: _CostModel, timeout: float) -> RoomMatch | None:
        t0 = time.perf_counter()
        bounds = np.empty(len(self))
        assigns: list[list[int | None]] = []
        for i, cats in enumerate(self.categories):
            bounds[i], a = model.assignment(model.room_columns(cats))
            assigns.append(a)
        order = np.lexsort((np.array([len(c) for c in self.categories]), bounds))
        exact_is_bound = query.number_of_edges() == 0 and model.costs.edge_extra == 0.0
        best: RoomMatch | None = None
        n_ged = 0
        for i in order:
            lb = float(bounds[i])
            if best is not None and lb >= best.search_cost - 1e-9:
                break
            if exact_is_bound:
                match = _assignment_match(query, model, self.ids[i], self.graphs[i], self.nodes[i], lb, assigns[i])
            else:
                n_ged += 1
                match = _match_one(query, model, self.ids[i], self.graphs[i], timeout,
                                   upper_bound=best.search_cost if best is not None else None, lower_bound=lb)
                if match is None:
                    continue
            if best is None or match.search_cost < best.search_cost - 1e-9:
                best = match
        if best is not None:
            best.stats.update(rooms=len(self), ged_runs=n_ged, seconds=time.perf_counter() - t0)
        return best


def _assignment_match(query: nx.Graph, model: _CostModel, room_id, room: nx.Graph, nodes: list[Hashable],
                      cost: float, assign: list[int | None]) -> RoomMatch:
    """Match from the category assignment (exact when the query has no edges)."""
    mapping = {q: (nodes[k] if k is not None else None) for q, k in zip(model.qnodes, assign)}
    return _finish(RoomMatch(room_id, room, cost, mapping, lower_bound=cost), query, model)


def _finish(match: RoomMatch, query: nx.Graph, model: _CostModel) -> RoomMatch:
    """Record substitutions; turn the search cost into the reported distance."""
    _fill_substitutions(match, query, match.graph)
    penalty = model.costs.incomplete_penalty * len(match.missing)
    match.search_cost = match.distance
    match.distance = match.distance - penalty
    return match


def _fill_substitutions(match: RoomMatch, query: nx.Graph, room: nx.Graph) -> None:
    for q, r in match.mapping.items():
        if r is not None:
            want, have = query.nodes[q]["category"], room.nodes[r].get("category")
            if want != have:
                match.substitutions[q] = (want, have)


def _match_one(query: nx.Graph, model: _CostModel, room_id, room: nx.Graph, timeout: float,
               upper_bound: float | None, lower_bound: float | None = None) -> RoomMatch | None:
    """Exact (or timed-out best) GED match of the query against one room with networkx."""
    c = model.costs

    def node_subst(a, b):
        return model.pair_cost(a["category"], b.get("category", ""), a.get("skills", ()), a.get("parts", ()))

    if lower_bound is None:
        cats = [room.nodes[n].get("category", "") for n in room.nodes]
        lower_bound, _ = model.assignment(model.room_columns(cats))
    t0 = time.perf_counter()
    last = None
    for path in nx.optimize_edit_paths(
        query, room,
        node_subst_cost=node_subst,
        node_del_cost=lambda a: c.deletion,
        node_ins_cost=lambda b: c.extra,
        edge_subst_cost=lambda a, b: 0.0,
        edge_del_cost=lambda a: c.edge_missing,
        edge_ins_cost=lambda b: c.edge_extra,
        upper_bound=upper_bound,
        strictly_decreasing=True,
        timeout=timeout,
    ):
        last = path
        if abs(path[2] - lower_bound) < 1e-9:  # cannot do better than the bound
            break
    elapsed = time.perf_counter() - t0
    if last is None:
        return None
    node_path, _, cost = last
    mapping: dict[Hashable, Hashable | None] = {q: None for q in query.nodes}
    for u, v in node_path:
        if u is not None:
            ok = v is not None and node_subst(query.nodes[u], room.nodes[v]) < c.mismatch
            mapping[u] = v if ok else None
    timed_out = timeout is not None and elapsed >= timeout and abs(cost - lower_bound) > 1e-9
    match = RoomMatch(room_id, room, float(cost), mapping, lower_bound=float(lower_bound), exact=not timed_out)
    return _finish(match, query, model)


def retrieve_room(required, rooms: Iterable[tuple[Any, Any]] | RoomIndex, *,
                  substitutions: Mapping[str, Mapping[str, float]] = DEFAULT_SUBSTITUTIONS,
                  costs: GEDCosts | None = None, timeout: float = 0.05, max_distance: float | None = None,
                  fallback: Callable[[list[str]], Any] | None = None) -> RoomMatch:
    """The room that best hosts ``required`` by graph edit distance, or a built one.

    ``required``: a list (or Counter) of categories, a query graph (nodes with ``category``,
    optional ``skills``/``parts``; edges = items that should be near each other), a Script,
    a Story or a list of scripts. ``rooms``: ``(room_id, graph)`` pairs (a room object with
    ``layout_graph()`` also works) or a prepared :class:`RoomIndex`. ``timeout``: seconds per
    networkx GED run (a run cut short keeps the best edit path found so far, and the match is
    flagged ``exact=False``; a room whose run finds nothing under the best distance so far
    before its timeout is passed over). ``max_distance``: reject a best room farther than this. A best room that
    lacks an item (or is too far) goes to ``fallback(categories)``; with no fallback,
    :class:`NoRoomFoundError` is raised. Returns a :class:`RoomMatch` whose ``mapping`` takes
    each query node ((category, instance)) to the room node used.
    """
    index = rooms if isinstance(rooms, RoomIndex) else RoomIndex(rooms)
    return index.retrieve(required, substitutions=substitutions, costs=costs, timeout=timeout,
                          max_distance=max_distance, fallback=fallback)


def world_room_builder(config: Any = None, rng: Any = None) -> Callable[[list[str]], Any]:
    """A ``fallback`` for :func:`retrieve_room` that calls
    ``stairenv.world.rooms.generate_room(config, rng, categories=categories)``; the module is
    imported only when a room is actually built."""

    def build(categories: list[str]) -> Any:
        from stairenv.world.rooms import generate_room

        # stairenv.world.furniture spells multi-word families with underscores.
        return generate_room(config, rng, categories=[str(c).replace(" ", "_") for c in categories])

    return build


def bind_keyframes(keyframes: Iterable[Any], match: RoomMatch) -> list[tuple[Any, Hashable | None]]:
    """Pair each keyframe with the room node its furniture maps to (None: no furniture)."""
    return [(kf, match.mapping.get(kf.node) if kf.node is not None else None) for kf in keyframes]


# --------------------------------------------------------------------------- synthetic rooms


def random_layout_graph(rng: np.random.Generator | int | None = None, n_items: int | None = None,
                        categories: Sequence[str] | None = None, size: tuple[float, float] = (6.0, 5.0),
                        near: float = 1.8) -> nx.Graph:
    """A synthetic room layout graph: ``categories`` (or ``n_items`` random ones, 3-12) at
    random positions in a ``size`` room, edges between items closer than ``near`` metres.
    For tests, benchmarks and as a stand-in room builder."""
    rng = np.random.default_rng(rng)
    if categories is None:
        n = int(rng.integers(3, 13)) if n_items is None else int(n_items)
        categories = [str(c) for c in rng.choice(FURNITURE, size=n)]
    pos = rng.uniform((0.0, 0.0), size, size=(len(categories), 2))
    g = nx.Graph()
    for i, c in enumerate(categories):
        g.add_node(i, category=c, position=(float(pos[i, 0]), float(pos[i, 1])))
    d = np.linalg.norm(pos[:, None] - pos[None], axis=-1)
    for i, j in zip(*np.nonzero(np.triu(d < near, 1))):
        g.add_edge(int(i), int(j))
    return g
