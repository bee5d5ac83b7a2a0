"""SIMS' layout graph: items near each other with no wall between (``footprint_distance``)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import networkx as nx
import numpy as np

from stairenv.world.furniture import PlacedFurniture
from stairenv.world.rooms.config import MINOR_FAMILIES
from stairenv.world.scenes import Box


# --- room and house ------------------------------------------------------------------------------
def segment_hits_box(p: np.ndarray, q: np.ndarray, box: Box) -> bool:
    """Whether the segment p-q (world xy) crosses the footprint of ``box`` (Liang-Barsky)."""
    u, v = box.axes
    a = np.array([(p - box.center) @ u, (p - box.center) @ v])
    d = np.array([(q - p) @ u, (q - p) @ v])
    t0, t1 = 0.0, 1.0
    for k in range(2):
        h = box.half_size[k]
        if abs(d[k]) < 1e-12:
            if abs(a[k]) > h:
                return False
            continue
        ta, tb = (-h - a[k]) / d[k], (h - a[k]) / d[k]
        if ta > tb:
            ta, tb = tb, ta
        t0, t1 = max(t0, ta), min(t1, tb)
        if t0 > t1:
            return False
    return True


def _point_segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    ab = b - a
    t = np.clip((p - a) @ ab / max(ab @ ab, 1e-18), 0.0, 1.0)
    return float(np.linalg.norm(p - (a + t * ab)))


def footprint_distance(a: Box, b: Box) -> float:
    """Gap (m) between two footprints (0 if they overlap)."""
    if a.footprint_overlaps(b):
        return 0.0
    ca, cb = a.corners_xy(), b.corners_xy()
    best = math.inf
    for corners, other in ((ca, cb), (cb, ca)):
        for p in corners:
            for k in range(4):
                best = min(best, _point_segment_distance(p, other[k], other[(k + 1) % 4]))
    return best


def build_layout_graph(items: Sequence[PlacedFurniture], walls: Sequence[Box], room_of: Mapping[str, str],
                  threshold: float, obstruction_height: float | None) -> nx.Graph:
    graph = nx.Graph()
    boxes = {f.name: f.footprint_box() for f in items}
    for f in items:
        graph.add_node(f.name, category=f.category, family=f.family, position=(float(f.pose[0]), float(f.pose[1])),
                       yaw=float(f.pose[2]), footprint=tuple(f.furniture.footprint), height=float(f.furniture.height),
                       room=room_of.get(f.name, ""), important=f.family not in MINOR_FAMILIES)
    for i, a in enumerate(items):
        for b in items[i + 1:]:
            gap = footprint_distance(boxes[a.name], boxes[b.name])
            if gap > threshold:
                continue
            p, q = a.position, b.position
            if any(segment_hits_box(p, q, w) for w in walls):
                continue
            if obstruction_height is not None and any(
                    segment_hits_box(p, q, boxes[o.name]) for o in items
                    if o.name not in (a.name, b.name) and o.furniture.height > obstruction_height):
                continue
            graph.add_edge(a.name, b.name, distance=gap)
    return graph
