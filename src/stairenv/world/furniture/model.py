"""A piece of furniture (``Furniture``: labelled convex parts) and the family vocabulary
(``FAMILIES``, seating / lying families, substitutes, top-surface labels)."""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import numpy as np
import trimesh

from stairenv.validation import check_choice
from stairenv.world.furniture.colors import part_rgba
from stairenv.world.furniture.parts import ContactSurface, Part

FAMILIES: tuple[str, ...] = (
    "chair", "armchair", "stool", "sofa", "bed", "double_bed", "table",
    "cabinet", "wardrobe", "bookshelf", "lamp",
)
# Families a character sits on (their "seat" parts are the sitting surface).
SEATING_FAMILIES: tuple[str, ...] = ("chair", "armchair", "stool", "sofa")
# Families a character lies on (their "bed_surface" / "seat" parts).
LYING_FAMILIES: tuple[str, ...] = ("bed", "double_bed", "sofa")
# SIMS' fault-tolerant retrieval: categories that may stand in for each other.
SUBSTITUTES: Mapping[str, tuple[str, ...]] = MappingProxyType({
    "stool": ("chair",), "chair": ("stool", "armchair"), "armchair": ("chair", "sofa"),
    "double_bed": ("bed",), "bed": ("double_bed",), "cabinet": ("wardrobe",),
    "wardrobe": ("cabinet",), "sofa": ("armchair",),
})

# Labels whose contact surface is, by default, the upward face ("top"); all others: the front (+x) face.
TOP_LABELS: frozenset[str] = frozenset({
    "seat", "bed_surface", "table_top", "shelf", "armrest", "pillow", "top", "base", "books",
})

# --- the furniture -------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Furniture:
    """One piece of furniture: labelled convex parts in the furniture frame.

    Frame: z up, front facing +x, footprint (xy bounding box of the parts) centred on the
    origin, standing on z = 0; metres. ``footprint`` holds the half extents (along x, y)
    of that box and ``height`` its top. ``params`` records the sampled dimensions
    (e.g. ``seat_height``: the top of the seat above the floor).
    Build with ``make_furniture`` (or ``Furniture.from_parts``, which recentres).
    """

    family: str
    part_list: tuple[Part, ...]
    footprint: tuple[float, float]
    height: float
    params: Mapping[str, Any] = field(default_factory=dict)

    @classmethod
    def from_parts(cls, family: str, parts: Sequence[Part], params: Mapping[str, Any] | None = None) -> Furniture:
        """Recentre ``parts`` so the footprint is centred on the origin and the lowest point is at z = 0."""
        if not parts:
            raise ValueError("a furniture needs at least one part")
        verts = np.concatenate([p.vertices for p in parts])
        lo, hi = verts.min(axis=0), verts.max(axis=0)
        offset = np.array([-0.5 * (lo[0] + hi[0]), -0.5 * (lo[1] + hi[1]), -lo[2]])
        moved = tuple(p.translated(offset) for p in parts)
        footprint = (float(0.5 * (hi[0] - lo[0])), float(0.5 * (hi[1] - lo[1])))
        record = dict(params or {})
        # Heights that were measured before recentring stay valid: z is only shifted if lo_z != 0.
        return cls(family, moved, footprint, float(hi[2] - lo[2]), MappingProxyType(record))

    @property
    def category(self) -> str:
        """The category of the layout graph and SIMS' scripts (the family name)."""
        return self.family

    @property
    def labels(self) -> tuple[str, ...]:
        """The distinct part labels, in order of first appearance."""
        return tuple(dict.fromkeys(p.label for p in self.part_list))

    def parts(self, label: str | None = None) -> tuple[Part, ...]:
        """All parts, or those with ``label`` (in build order; k in the geom names counts these)."""
        if label is None:
            return self.part_list
        return tuple(p for p in self.part_list if p.label == label)

    def _labelled(self, label: str) -> tuple[Part, ...]:
        parts = self.parts(label)
        if not parts:
            raise KeyError(f"{self.family} has no part labelled {label!r}; its labels: {list(self.labels)}")
        return parts

    @property
    def bounds(self) -> np.ndarray:
        """(2, 3) min and max corners of the bounding box (furniture frame)."""
        verts = np.concatenate([p.vertices for p in self.part_list])
        return np.stack((verts.min(axis=0), verts.max(axis=0)))

    def contact_surfaces(self, label: str, side: str = "auto") -> list[ContactSurface]:
        """One ``ContactSurface`` per part with ``label`` (see ``contact_surface``)."""
        direction = _side_direction(label, side)
        return [p.face(direction) for p in self._labelled(label)]

    def contact_surface(self, label: str, index: int | None = None, side: str = "auto") -> ContactSurface:
        """The surface of the ``label`` part(s) a body part should touch (furniture frame).

        ``side``: "top" (the upward face: sit, lie, put a hand on), "front" (the +x face: a
        backrest, a door), "back", or "auto" (top for ``TOP_LABELS`` such as seat,
        bed_surface, table_top, shelf, armrest; front otherwise). With several parts of the
        label, ``index`` picks one (parts in build order, e.g. shelves bottom to top); without
        it, adjoining coplanar faces (a sofa's seat cushions) are merged into one rectangle,
        and separate ones (two armrests) raise ``ValueError``.
        """
        surfaces = self.contact_surfaces(label, side)
        if index is not None:
            if not -len(surfaces) <= index < len(surfaces):
                raise IndexError(f"{self.family} has {len(surfaces)} {label!r} parts, got index {index}")
            return surfaces[index]
        if len(surfaces) == 1:
            return surfaces[0]
        merged = _merge_surfaces(surfaces)
        if merged is None:
            raise ValueError(f"{self.family} has {len(surfaces)} separate {label!r} parts: pass index "
                             f"(0..{len(surfaces) - 1})")
        return merged

    def nearest_point(self, label: str, points: np.ndarray, index: int | None = None) -> np.ndarray:
        """Nearest point (..., 3) on the ``label`` part(s) to each point (..., 3), furniture frame.

        SIMS' contact target g_j: the nearest point of the target part (solid: a point inside
        the part is its own nearest point). ``index`` restricts to one part of the label.
        """
        parts = self._labelled(label)
        if index is not None:
            parts = (parts[index],)
        p = np.asarray(points, dtype=float)
        best = parts[0].nearest_point(p)
        best_d = np.sum((best - p) ** 2, axis=-1)
        for part in parts[1:]:
            q = part.nearest_point(p)
            d = np.sum((q - p) ** 2, axis=-1)
            closer = d < best_d
            best = np.where(closer[..., None], q, best)
            best_d = np.where(closer, d, best_d)
        return best

    def contains(self, points: np.ndarray, label: str | None = None) -> np.ndarray:
        """Whether points (..., 3) lie inside any part (or any part with ``label``)."""
        p = np.asarray(points, dtype=float)
        out = np.zeros(p.shape[:-1], dtype=bool)
        for part in self.parts(label):
            out |= part.contains(p)
        return out

    def _coloured_part_meshes(self) -> Iterator[tuple[str, int, trimesh.Trimesh]]:
        """(label, k, mesh) per part in build order, each mesh with its per-face colour."""
        counts: dict[str, int] = {}
        for part in self.part_list:
            k = counts.get(part.label, 0)
            counts[part.label] = k + 1
            m = part.mesh()
            rgba = np.round(np.asarray(part_rgba(self.family, part.label, k)) * 255).astype(np.uint8)
            m.visual.face_colors = np.tile(rgba, (len(m.faces), 1))
            yield part.label, k, m

    def mesh(self) -> trimesh.Trimesh:
        """All parts concatenated into one mesh with per-face colours (furniture frame; for export)."""
        return trimesh.util.concatenate([m for _, _, m in self._coloured_part_meshes()])

    def scene(self) -> trimesh.Scene:
        """A trimesh scene with one geometry per part, named ``{label}/{k}`` (for rendering)."""
        scene = trimesh.Scene()
        for label, k, m in self._coloured_part_meshes():
            scene.add_geometry(m, geom_name=f"{label}/{k}", node_name=f"{label}/{k}")
        return scene


def _side_direction(label: str, side: str) -> np.ndarray:
    check_choice("side", side, ("auto", "top", "front", "back"))
    if side == "auto":
        side = "top" if label in TOP_LABELS else "front"
    return {"top": np.array([0.0, 0.0, 1.0]), "front": np.array([1.0, 0.0, 0.0]),
            "back": np.array([-1.0, 0.0, 0.0])}[side]


def _merge_surfaces(surfaces: Sequence[ContactSurface]) -> ContactSurface | None:
    """One rectangle covering ``surfaces`` if they share normal and plane and nearly tile it."""
    first = surfaces[0]
    for s in surfaces[1:]:
        if (s.normal @ first.normal < 0.999 or abs((s.center - first.center) @ first.normal) > 0.01
                or abs(abs(s.axes[0] @ first.axes[0]) - 1.0) > 1e-6):
            return None
    corners = np.concatenate([s.corners() for s in surfaces]) @ first.axes.T
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    area = float(np.prod(hi - lo))
    if sum(float(np.prod(2.0 * s.half_extents)) for s in surfaces) < 0.9 * area:
        return None
    height = max(float(s.center @ first.normal) for s in surfaces)
    # (axes, normal) is an orthonormal basis: the centre from its coordinates in it.
    center = first.axes.T @ (0.5 * (lo + hi)) + height * first.normal
    return ContactSurface(first.label, center, first.normal.copy(), first.axes.copy(), 0.5 * (hi - lo))
