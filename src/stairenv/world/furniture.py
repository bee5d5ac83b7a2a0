"""Parametric furniture (SIMS): families of convex parts with labels for contact goals.

SIMS (Sec. 3.3, supplement) makes a character sit, lie and reach on furniture: the
contact goal of a joint is "the nearest point of the target part" (seat, backrest,
armrest, bed surface, table top, shelf, ...). Here every piece of furniture is a set of
convex ``Part``\\ s, each with such a label, generated from a frozen config of parameter
ranges by ``make_furniture(family, rng, **overrides)`` (pure: the same rng state gives the
same piece). Because each part is convex, MuJoCo collides with the exact shape (one box or
mesh geom per part): a chair is a seat, four legs and a backrest, not one hull that fills
the space under the seat and in front of the backrest.

Frames and units
----------------
Furniture frame: z up, the front (where a person sits, lies down from, or opens the doors)
faces +x, the footprint (the xy bounding box of all parts) is centred on the origin and the
piece stands on z = 0. Lengths in metres, angles in radians unless a name ends in ``_deg``.
A placed piece has a pose (x, y, yaw): the furniture frame turned by ``yaw`` (rad,
counter-clockwise about +z) and moved to (x, y, 0) in the world.

Families (``FAMILIES``) and their part labels
---------------------------------------------
| family | labels |
|---|---|
| chair | seat, backrest, leg |
| armchair | seat, backrest, armrest, base, leg |
| stool | seat, leg |
| sofa | seat (one per cushion), backrest, armrest, base, leg |
| bed, double_bed | bed_surface, headboard, pillow, base, leg, [footboard] |
| table | table_top, leg (rectangular) or pole, base (round) |
| cabinet, wardrobe | body, door, handle, top, base |
| bookshelf | shelf (bottom to top), side, back, [books] |
| lamp | base, pole, lamp_shade |

``bed`` and ``double_bed`` are one generator (``BedConfig``) with a ``size`` parameter
("single" / "double"); the family name follows the size, so a room's layout graph can tell
a double bed from a bed (SIMS substitutes one for the other when retrieving layouts).

MuJoCo
------
``add_furniture_to_spec(spec, furniture, pose, name)`` adds one static body per piece with
one geom per part (boxes as box geoms, other parts as mesh geoms built from the part's
vertices), named ``{name}/{label}/{k}`` (k counts the parts of that label from 0).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields, replace
from types import MappingProxyType
from typing import Any, ClassVar

import mujoco
import numpy as np
import trimesh
from scipy.spatial import ConvexHull

from stairenv.validation import check_choice, check_number, check_range
from stairenv.world.scenes import Box

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

# Segments of the circles of round parts (cylinders, frustums, rounded edges).
ROUND_SEGMENTS = 24

_BOX_SIGNS = np.array(list(itertools.product((-1.0, 1.0), repeat=3)))


# --- geometry helpers ----------------------------------------------------------------------------
def _rot_y(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rot_z(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _closest_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Closest points on triangles (a, b, c) to points p (Ericson, Real-Time Collision Detection 5.1.5).

    Shapes broadcast: p (P, 1, 3), a/b/c (1, T, 3) -> (P, T, 3).
    """
    ab, ac = b - a, c - a
    ap, bp, cp = p - a, p - b, p - c
    d1, d2 = (ab * ap).sum(-1), (ac * ap).sum(-1)
    d3, d4 = (ab * bp).sum(-1), (ac * bp).sum(-1)
    d5, d6 = (ab * cp).sum(-1), (ac * cp).sum(-1)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = va + vb + vc
        res = a + ab * (vb / denom)[..., None] + ac * (vc / denom)[..., None]
        cond = (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0)
        t = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        res = np.where(cond[..., None], b + (c - b) * t[..., None], res)
        cond = (vb <= 0) & (d2 >= 0) & (d6 <= 0)
        t = d2 / (d2 - d6)
        res = np.where(cond[..., None], a + ac * t[..., None], res)
        res = np.where(((d6 >= 0) & (d5 <= d6))[..., None], c, res)
        cond = (vc <= 0) & (d1 >= 0) & (d3 <= 0)
        t = d1 / (d1 - d3)
        res = np.where(cond[..., None], a + ab * t[..., None], res)
        res = np.where(((d3 >= 0) & (d4 <= d3))[..., None], b, res)
        res = np.where(((d1 <= 0) & (d2 <= 0))[..., None], a, res)
    return res


def cylinder_points(radius: float, z0: float, z1: float, *, center: Sequence[float] = (0.0, 0.0),
                    top_radius: float | None = None, segments: int = ROUND_SEGMENTS) -> np.ndarray:
    """Vertices (2 * segments, 3) of a vertical cylinder (or frustum if ``top_radius`` differs), metres."""
    angles = 2.0 * math.pi * np.arange(segments) / segments
    ring = np.stack((np.cos(angles), np.sin(angles)), axis=1)
    top = radius if top_radius is None else top_radius
    bottom_pts = np.column_stack((center[0] + radius * ring[:, 0], center[1] + radius * ring[:, 1],
                                  np.full(segments, z0)))
    top_pts = np.column_stack((center[0] + top * ring[:, 0], center[1] + top * ring[:, 1], np.full(segments, z1)))
    return np.concatenate((bottom_pts, top_pts))


def rounded_bar_points(lo: Sequence[float], hi: Sequence[float], radius: float, *,
                       segments: int = 8) -> np.ndarray:
    """Vertices of a bar along x whose cross-section (y, z) is a rectangle with rounded top corners.

    ``lo``/``hi`` are the (x, y, z) corners of its bounding box; ``radius`` (m) rounds the two
    upper edges (an armrest's top).
    """
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    r = min(radius, 0.5 * (y1 - y0), z1 - z0)
    profile = [(y0, z0), (y1, z0)]
    for k in range(segments + 1):  # right corner 0..90 deg, then left corner 90..180 deg
        a = 0.5 * math.pi * k / segments
        profile.append((y1 - r + r * math.cos(a), z1 - r + r * math.sin(a)))
    for k in range(segments + 1):
        a = 0.5 * math.pi + 0.5 * math.pi * k / segments
        profile.append((y0 + r + r * math.cos(a), z1 - r + r * math.sin(a)))
    yz = np.array(profile)
    return np.concatenate([np.column_stack((np.full(len(yz), x), yz)) for x in (x0, x1)])


# --- parts ---------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Part:
    """One convex piece of a furniture, in the furniture frame (z up, front +x, metres).

    ``kind`` is "box" (an oriented box: ``center``, ``half_extents`` along the columns of
    ``rotation``) or "mesh" (the convex hull of ``vertices``). Every part has ``vertices``
    (its hull's corners) and ``planes`` (F, 4): rows (n, d) with outward unit normals n,
    inside where n . p <= d. Build with ``Part.box`` or ``Part.convex``.
    """

    label: str
    kind: str
    vertices: np.ndarray
    planes: np.ndarray
    center: np.ndarray
    rotation: np.ndarray
    half_extents: np.ndarray | None = None
    _triangles: np.ndarray | None = field(default=None, repr=False)

    @classmethod
    def box(cls, label: str, center: Sequence[float], half_extents: Sequence[float],
            rotation: np.ndarray | None = None) -> Part:
        """An oriented box: centre (3,), half extents (3,) along the columns of ``rotation`` (3, 3)."""
        c = np.asarray(center, dtype=float).reshape(3)
        h = np.asarray(half_extents, dtype=float).reshape(3)
        if np.any(h <= 0.0):
            raise ValueError(f"part {label!r}: half extents must be > 0, got {h.tolist()}")
        r = np.eye(3) if rotation is None else np.asarray(rotation, dtype=float).reshape(3, 3)
        vertices = c + (_BOX_SIGNS * h) @ r.T
        normals = np.concatenate((r.T, -r.T))
        offsets = normals @ c + np.concatenate((h, h))
        return cls(label, "box", vertices, np.column_stack((normals, offsets)), c, r, h)

    @classmethod
    def from_bounds(cls, label: str, lo: Sequence[float], hi: Sequence[float]) -> Part:
        """An axis-aligned box between corners ``lo`` and ``hi`` (x, y, z)."""
        lo_, hi_ = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
        return cls.box(label, 0.5 * (lo_ + hi_), 0.5 * (hi_ - lo_))

    @classmethod
    def convex(cls, label: str, points: np.ndarray) -> Part:
        """The convex hull of ``points`` (N, 3) (interior points are dropped)."""
        pts = np.asarray(points, dtype=float).reshape(-1, 3)
        hull = ConvexHull(pts)
        vertices = pts[hull.vertices]
        eq = hull.equations  # n . x + offset <= 0 inside
        planes = np.column_stack((eq[:, :3], -eq[:, 3]))
        mesh = trimesh.convex.convex_hull(vertices)
        return cls(label, "mesh", vertices, planes, vertices.mean(axis=0), np.eye(3), None,
                   np.asarray(mesh.triangles))

    @property
    def is_box(self) -> bool:
        return self.kind == "box"

    @property
    def bounds(self) -> np.ndarray:
        """(2, 3): min and max corner of the axis-aligned bounding box."""
        return np.stack((self.vertices.min(axis=0), self.vertices.max(axis=0)))

    @property
    def triangles(self) -> np.ndarray:
        """(T, 3, 3) surface triangles."""
        if self._triangles is None:
            return np.asarray(self.mesh().triangles)
        return self._triangles

    def mesh(self) -> trimesh.Trimesh:
        """The part as a closed convex trimesh (furniture frame)."""
        if self.is_box:
            transform = np.eye(4)
            transform[:3, :3] = self.rotation
            transform[:3, 3] = self.center
            return trimesh.creation.box(extents=2.0 * self.half_extents, transform=transform)
        return trimesh.convex.convex_hull(self.vertices)

    def translated(self, offset: Sequence[float]) -> Part:
        off = np.asarray(offset, dtype=float)
        planes = self.planes.copy()
        planes[:, 3] += planes[:, :3] @ off
        tris = None if self._triangles is None else self._triangles + off
        return replace(self, vertices=self.vertices + off, planes=planes, center=self.center + off,
                       _triangles=tris)

    def contains(self, points: np.ndarray, tol: float = 1e-9) -> np.ndarray:
        """Whether points (..., 3) lie inside the part (boundary included, within ``tol`` m)."""
        p = np.asarray(points, dtype=float)
        return np.all(p @ self.planes[:, :3].T <= self.planes[:, 3] + tol, axis=-1)

    def nearest_point(self, points: np.ndarray) -> np.ndarray:
        """The nearest point of the (solid) part to each point (..., 3): the point itself if inside."""
        p = np.asarray(points, dtype=float)
        flat = p.reshape(-1, 3)
        if self.is_box:
            local = (flat - self.center) @ self.rotation
            out = np.clip(local, -self.half_extents, self.half_extents) @ self.rotation.T + self.center
        else:
            tris = self.triangles
            cand = _closest_on_triangles(flat[:, None, :], tris[None, :, 0], tris[None, :, 1], tris[None, :, 2])
            dist = np.sum((cand - flat[:, None, :]) ** 2, axis=-1)
            out = cand[np.arange(len(flat)), np.argmin(dist, axis=1)]
            out = np.where(self.contains(flat)[:, None], flat, out)
        return out.reshape(p.shape)

    def face(self, direction: Sequence[float], tol: float = 0.01) -> ContactSurface:
        """The face of the part whose outward normal points most along ``direction`` (furniture frame).

        Boxes: that face exactly. Meshes: the rectangle spanned by the vertices within ``tol``
        (m) of the support plane along ``direction`` (a flat top, or the crest of a rounded
        one), at the support height.
        """
        d = np.asarray(direction, dtype=float)
        d = d / np.linalg.norm(d)
        if self.is_box:
            local = self.rotation.T @ d
            i = int(np.argmax(np.abs(local)))
            sign = 1.0 if local[i] >= 0 else -1.0
            j, k = [a for a in range(3) if a != i]
            normal = sign * self.rotation[:, i]
            center = self.center + sign * self.half_extents[i] * self.rotation[:, i]
            axes = np.stack((self.rotation[:, j], self.rotation[:, k]))
            return ContactSurface(self.label, center, normal, axes, self.half_extents[[j, k]].copy())
        axes = _tangent_axes(d)
        support = self.vertices @ d
        top = self.vertices[support >= support.max() - tol]
        proj = top @ axes.T
        lo, hi = proj.min(axis=0), proj.max(axis=0)
        center = axes.T @ (0.5 * (lo + hi)) + d * support.max()
        return ContactSurface(self.label, center, d, axes, np.maximum(0.5 * (hi - lo), 0.0))


def _tangent_axes(direction: np.ndarray) -> np.ndarray:
    """Two unit axes (2, 3) spanning the plane normal to ``direction``: x/y for up, y/z for +-x."""
    d = direction / np.linalg.norm(direction)
    ref = np.array([1.0, 0.0, 0.0]) if abs(d[2]) > 0.7 else np.array([0.0, 0.0, 1.0])
    if abs(d[2]) > 0.7:
        a1 = ref - (ref @ d) * d
        a1 /= np.linalg.norm(a1)
        a2 = np.cross(d, a1)
    else:
        a2 = ref - (ref @ d) * d
        a2 /= np.linalg.norm(a2)
        a1 = np.cross(a2, d)
    return np.stack((a1, a2))


@dataclass(frozen=True, eq=False)
class ContactSurface:
    """A flat rectangle a body part should touch: centre (3,), unit ``normal`` (3,) pointing
    away from the furniture, tangent ``axes`` (2, 3) and ``half_extents`` (2,) along them (m).

    In the furniture frame from ``Furniture.contact_surface``, in the world frame from
    ``PlacedFurniture.contact_surface``.
    """

    label: str
    center: np.ndarray
    normal: np.ndarray
    axes: np.ndarray
    half_extents: np.ndarray

    def corners(self) -> np.ndarray:
        """(4, 3) corners, counter-clockwise seen from the normal's side."""
        s = np.array([[1, 1], [-1, 1], [-1, -1], [1, -1]], dtype=float) * self.half_extents
        return self.center + s @ self.axes

    def grid(self, count: int = 3) -> np.ndarray:
        """(count * count, 3) evenly spread points on the surface (its centre for count = 1)."""
        t = np.linspace(-1.0, 1.0, count) if count > 1 else np.zeros(1)
        uu, vv = np.meshgrid(t, t, indexing="ij")
        st = np.stack((uu.ravel(), vv.ravel()), axis=1) * self.half_extents
        return self.center + st @ self.axes

    def sample(self, rng: np.random.Generator, count: int = 1, *, margin: float = 0.0) -> np.ndarray:
        """(count, 3) uniform points on the surface, at least ``margin`` (m) from its edges."""
        h = np.maximum(self.half_extents - margin, 0.0)
        st = rng.uniform(-1.0, 1.0, size=(count, 2)) * h
        return self.center + st @ self.axes

    def transformed(self, rotation: np.ndarray, translation: Sequence[float]) -> ContactSurface:
        """This surface moved by p -> rotation @ p + translation."""
        r = np.asarray(rotation, dtype=float)
        return ContactSurface(self.label, r @ self.center + np.asarray(translation, dtype=float),
                              r @ self.normal, self.axes @ r.T, self.half_extents.copy())


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

    def mesh(self) -> trimesh.Trimesh:
        """All parts concatenated into one mesh with per-face colours (furniture frame; for export)."""
        meshes = []
        counts: dict[str, int] = {}
        for part in self.part_list:
            k = counts.get(part.label, 0)
            counts[part.label] = k + 1
            m = part.mesh()
            rgba = np.round(np.asarray(part_rgba(self.family, part.label, k)) * 255).astype(np.uint8)
            m.visual.face_colors = np.tile(rgba, (len(m.faces), 1))
            meshes.append(m)
        return trimesh.util.concatenate(meshes)

    def scene(self) -> trimesh.Scene:
        """A trimesh scene with one geometry per part, named ``{label}/{k}`` (for rendering)."""
        scene = trimesh.Scene()
        counts: dict[str, int] = {}
        for part in self.part_list:
            k = counts.get(part.label, 0)
            counts[part.label] = k + 1
            m = part.mesh()
            rgba = np.round(np.asarray(part_rgba(self.family, part.label, k)) * 255).astype(np.uint8)
            m.visual.face_colors = np.tile(rgba, (len(m.faces), 1))
            scene.add_geometry(m, geom_name=f"{part.label}/{k}", node_name=f"{part.label}/{k}")
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


# --- configs -------------------------------------------------------------------------------------
class _Config:
    """Shared validation: range fields (min, max) within hard bounds, integer ranges, choices.

    Subclasses list ``_bounds`` {field: (low, high)}, ``_integers`` (range fields of whole
    numbers), ``_numbers`` {field: (low, high)} for scalars and ``_choices`` {field: options}.
    """

    _bounds: ClassVar[dict[str, tuple[float, float]]] = {}
    _integers: ClassVar[frozenset[str]] = frozenset()
    _numbers: ClassVar[dict[str, tuple[float, float]]] = {}
    _choices: ClassVar[dict[str, tuple[str, ...]]] = {}

    def __post_init__(self) -> None:
        for name, (low, high) in self._bounds.items():
            value = getattr(self, name)
            if isinstance(value, (int, float)):
                value = (value, value)
            lo, hi = check_range(name, value, low, high)
            if name in self._integers:
                if int(lo) != lo or int(hi) != hi:
                    raise ValueError(f"{name} must be a (min, max) pair of integers within [{low}, {high}], "
                                     f"got {value!r}")
                lo, hi = int(lo), int(hi)
            object.__setattr__(self, name, (lo, hi))
        for name, (low, high) in self._numbers.items():
            object.__setattr__(self, name, check_number(name, getattr(self, name), low, high))
        for name, options in self._choices.items():
            check_choice(name, getattr(self, name), options)


def _u(rng: np.random.Generator, r: tuple[float, float]) -> float:
    return float(rng.uniform(r[0], r[1]))


def _i(rng: np.random.Generator, r: tuple[int, int]) -> int:
    return int(rng.integers(r[0], r[1] + 1))


@dataclass(frozen=True)
class ChairConfig(_Config):
    """A dining chair: four legs, a seat, a backrest tilted back. Ranges (min, max), metres, degrees.

    | field | default | valid |
    |---|---|---|
    | seat_height | (0.42, 0.48) | within [0.25, 0.9]: top of the seat above the floor |
    | seat_width | (0.40, 0.50) | within [0.3, 0.8] (y) |
    | seat_depth | (0.40, 0.48) | within [0.3, 0.8] (x) |
    | seat_thickness | (0.03, 0.06) | within [0.015, 0.15] |
    | leg_thickness | (0.03, 0.05) | within [0.015, 0.1] |
    | backrest_height | (0.35, 0.50) | within [0.1, 1.0]: above the seat |
    | backrest_thickness | (0.025, 0.05) | within [0.01, 0.15] |
    | backrest_tilt_deg | (0, 12) | within [0, 30]: backwards from vertical |
    """

    seat_height: tuple[float, float] = (0.42, 0.48)
    seat_width: tuple[float, float] = (0.40, 0.50)
    seat_depth: tuple[float, float] = (0.40, 0.48)
    seat_thickness: tuple[float, float] = (0.03, 0.06)
    leg_thickness: tuple[float, float] = (0.03, 0.05)
    backrest_height: tuple[float, float] = (0.35, 0.50)
    backrest_thickness: tuple[float, float] = (0.025, 0.05)
    backrest_tilt_deg: tuple[float, float] = (0.0, 12.0)
    _bounds: ClassVar[dict[str, tuple[float, float]]] = {
        "seat_height": (0.25, 0.9), "seat_width": (0.3, 0.8), "seat_depth": (0.3, 0.8),
        "seat_thickness": (0.015, 0.15), "leg_thickness": (0.015, 0.1), "backrest_height": (0.1, 1.0),
        "backrest_thickness": (0.01, 0.15), "backrest_tilt_deg": (0.0, 30.0),
    }


@dataclass(frozen=True)
class ArmchairConfig(_Config):
    """An upholstered armchair: short legs, a base, a seat cushion, a backrest and two armrests.

    | field | default | valid |
    |---|---|---|
    | seat_height | (0.42, 0.48) | within [0.25, 0.9]: top of the cushion |
    | seat_width | (0.50, 0.62) | within [0.35, 1.2]: between the armrests |
    | seat_depth | (0.48, 0.58) | within [0.3, 1.0]: backrest to front edge |
    | cushion_thickness | (0.08, 0.14) | within [0.02, 0.3] |
    | leg_height | (0.05, 0.14) | within [0.01, 0.3] |
    | arm_width | (0.08, 0.18) | within [0.04, 0.4] |
    | arm_height | (0.16, 0.24) | within [0.05, 0.5]: armrest top above the seat |
    | back_thickness | (0.12, 0.20) | within [0.04, 0.4] |
    | back_height | (0.40, 0.55) | within [0.1, 1.2]: above the seat |
    """

    seat_height: tuple[float, float] = (0.42, 0.48)
    seat_width: tuple[float, float] = (0.50, 0.62)
    seat_depth: tuple[float, float] = (0.48, 0.58)
    cushion_thickness: tuple[float, float] = (0.08, 0.14)
    leg_height: tuple[float, float] = (0.05, 0.14)
    arm_width: tuple[float, float] = (0.08, 0.18)
    arm_height: tuple[float, float] = (0.16, 0.24)
    back_thickness: tuple[float, float] = (0.12, 0.20)
    back_height: tuple[float, float] = (0.40, 0.55)
    _bounds: ClassVar[dict[str, tuple[float, float]]] = {
        "seat_height": (0.25, 0.9), "seat_width": (0.35, 1.2), "seat_depth": (0.3, 1.0),
        "cushion_thickness": (0.02, 0.3), "leg_height": (0.01, 0.3), "arm_width": (0.04, 0.4),
        "arm_height": (0.05, 0.5), "back_thickness": (0.04, 0.4), "back_height": (0.1, 1.2),
    }


@dataclass(frozen=True)
class StoolConfig(_Config):
    """A stool: a round or square seat on 3 or 4 legs.

    | field | default | valid |
    |---|---|---|
    | seat_height | (0.42, 0.50) | within [0.25, 0.9] |
    | seat_radius | (0.16, 0.21) | within [0.1, 0.4]: radius (round) or half side (square) |
    | seat_thickness | (0.03, 0.05) | within [0.015, 0.15] |
    | leg_thickness | (0.025, 0.04) | within [0.015, 0.1] |
    | num_legs | (3, 4) | integers within [3, 6] |
    | round_probability | 0.5 | [0, 1]: chance of a round seat |
    """

    seat_height: tuple[float, float] = (0.42, 0.50)
    seat_radius: tuple[float, float] = (0.16, 0.21)
    seat_thickness: tuple[float, float] = (0.03, 0.05)
    leg_thickness: tuple[float, float] = (0.025, 0.04)
    num_legs: tuple[int, int] = (3, 4)
    round_probability: float = 0.5
    _bounds: ClassVar[dict[str, tuple[float, float]]] = {
        "seat_height": (0.25, 0.9), "seat_radius": (0.1, 0.4), "seat_thickness": (0.015, 0.15),
        "leg_thickness": (0.015, 0.1), "num_legs": (3, 6),
    }
    _integers: ClassVar[frozenset[str]] = frozenset({"num_legs"})
    _numbers: ClassVar[dict[str, tuple[float, float]]] = {"round_probability": (0.0, 1.0)}


@dataclass(frozen=True)
class SofaConfig(_Config):
    """A sofa: short legs, a base, 2-3 seat cushions (each labelled "seat"), backrest, armrests.

    | field | default | valid |
    |---|---|---|
    | width | (1.6, 2.4) | within [1.0, 4.0]: overall, armrests included |
    | seat_depth | (0.52, 0.65) | within [0.3, 1.2] |
    | seat_height | (0.42, 0.48) | within [0.25, 0.9] |
    | cushion_thickness | (0.10, 0.18) | within [0.02, 0.3] |
    | leg_height | (0.04, 0.12) | within [0.01, 0.3] |
    | arm_width | (0.10, 0.22) | within [0.04, 0.4] |
    | arm_height | (0.12, 0.24) | within [0.05, 0.5]: above the seat |
    | back_thickness | (0.15, 0.25) | within [0.04, 0.5] |
    | back_height | (0.35, 0.50) | within [0.1, 1.2]: above the seat |
    | num_seats | (2, 3) | integers within [1, 6]: cushions |
    """

    width: tuple[float, float] = (1.6, 2.4)
    seat_depth: tuple[float, float] = (0.52, 0.65)
    seat_height: tuple[float, float] = (0.42, 0.48)
    cushion_thickness: tuple[float, float] = (0.10, 0.18)
    leg_height: tuple[float, float] = (0.04, 0.12)
    arm_width: tuple[float, float] = (0.10, 0.22)
    arm_height: tuple[float, float] = (0.12, 0.24)
    back_thickness: tuple[float, float] = (0.15, 0.25)
    back_height: tuple[float, float] = (0.35, 0.50)
    num_seats: tuple[int, int] = (2, 3)
    _bounds: ClassVar[dict[str, tuple[float, float]]] = {
        "width": (1.0, 4.0), "seat_depth": (0.3, 1.2), "seat_height": (0.25, 0.9),
        "cushion_thickness": (0.02, 0.3), "leg_height": (0.01, 0.3), "arm_width": (0.04, 0.4),
        "arm_height": (0.05, 0.5), "back_thickness": (0.04, 0.5), "back_height": (0.1, 1.2),
        "num_seats": (1, 6),
    }
    _integers: ClassVar[frozenset[str]] = frozenset({"num_seats"})


@dataclass(frozen=True)
class BedConfig(_Config):
    """A bed: legs, a frame ("base"), a mattress ("bed_surface"), a headboard at the back (-x),
    pillows at the head end, sometimes a footboard. ``size`` "double" makes a "double_bed".

    | field | default | valid |
    |---|---|---|
    | size | "single" | "single" or "double" |
    | single_width | (0.9, 1.2) | within [0.6, 3.0]: mattress width of a single bed |
    | double_width | (1.4, 1.8) | within [0.6, 3.0]: mattress width of a double bed |
    | length | (1.95, 2.15) | within [1.0, 3.0]: mattress length |
    | surface_height | (0.45, 0.58) | within [0.2, 1.0]: top of the mattress |
    | mattress_thickness | (0.15, 0.25) | within [0.05, 0.5] |
    | leg_height | (0.05, 0.18) | within [0.01, 0.4] |
    | frame_margin | (0.02, 0.05) | within [0, 0.3]: frame beyond the mattress |
    | headboard_height | (0.85, 1.2) | within [0.3, 2.0]: top above the floor |
    | headboard_thickness | (0.04, 0.10) | within [0.01, 0.3] |
    | pillow_height | (0.08, 0.13) | within [0.02, 0.3] |
    | footboard_probability | 0.3 | [0, 1] |
    """

    size: str = "single"
    single_width: tuple[float, float] = (0.9, 1.2)
    double_width: tuple[float, float] = (1.4, 1.8)
    length: tuple[float, float] = (1.95, 2.15)
    surface_height: tuple[float, float] = (0.45, 0.58)
    mattress_thickness: tuple[float, float] = (0.15, 0.25)
    leg_height: tuple[float, float] = (0.05, 0.18)
    frame_margin: tuple[float, float] = (0.02, 0.05)
    headboard_height: tuple[float, float] = (0.85, 1.2)
    headboard_thickness: tuple[float, float] = (0.04, 0.10)
    pillow_height: tuple[float, float] = (0.08, 0.13)
    footboard_probability: float = 0.3
    _bounds: ClassVar[dict[str, tuple[float, float]]] = {
        "single_width": (0.6, 3.0), "double_width": (0.6, 3.0), "length": (1.0, 3.0),
        "surface_height": (0.2, 1.0), "mattress_thickness": (0.05, 0.5), "leg_height": (0.01, 0.4),
        "frame_margin": (0.0, 0.3), "headboard_height": (0.3, 2.0), "headboard_thickness": (0.01, 0.3),
        "pillow_height": (0.02, 0.3),
    }
    _numbers: ClassVar[dict[str, tuple[float, float]]] = {"footboard_probability": (0.0, 1.0)}
    _choices: ClassVar[dict[str, tuple[str, ...]]] = {"size": ("single", "double")}


@dataclass(frozen=True)
class TableConfig(_Config):
    """A table: a rectangular top on four legs, or a round top on a pedestal ("pole" + "base").

    | field | default | valid |
    |---|---|---|
    | top_height | (0.72, 0.78) | within [0.3, 1.2]: top surface above the floor |
    | top_thickness | (0.025, 0.05) | within [0.01, 0.15] |
    | depth | (0.7, 1.0) | within [0.3, 2.0]: rectangular, along x |
    | length | (0.8, 1.8) | within [0.3, 4.0]: rectangular, along y |
    | diameter | (0.7, 1.1) | within [0.3, 2.0]: round |
    | leg_thickness | (0.04, 0.07) | within [0.015, 0.15] |
    | leg_inset | (0.03, 0.08) | within [0, 0.3]: from the top's edge |
    | round_probability | 0.3 | [0, 1] |
    """

    top_height: tuple[float, float] = (0.72, 0.78)
    top_thickness: tuple[float, float] = (0.025, 0.05)
    depth: tuple[float, float] = (0.7, 1.0)
    length: tuple[float, float] = (0.8, 1.8)
    diameter: tuple[float, float] = (0.7, 1.1)
    leg_thickness: tuple[float, float] = (0.04, 0.07)
    leg_inset: tuple[float, float] = (0.03, 0.08)
    round_probability: float = 0.3
    _bounds: ClassVar[dict[str, tuple[float, float]]] = {
        "top_height": (0.3, 1.2), "top_thickness": (0.01, 0.15), "depth": (0.3, 2.0), "length": (0.3, 4.0),
        "diameter": (0.3, 2.0), "leg_thickness": (0.015, 0.15), "leg_inset": (0.0, 0.3),
    }
    _numbers: ClassVar[dict[str, tuple[float, float]]] = {"round_probability": (0.0, 1.0)}


@dataclass(frozen=True)
class CabinetConfig(_Config):
    """A closed case: plinth ("base"), "body", "door"s with "handle"s on the front, a "top".

    Defaults describe a sideboard / chest; ``WardrobeConfig`` has the same fields.

    | field | default | valid |
    |---|---|---|
    | width | (0.5, 1.2) | within [0.2, 4.0] (y) |
    | depth | (0.38, 0.55) | within [0.15, 1.5] (x) |
    | height | (0.6, 1.1) | within [0.2, 3.0]: top surface |
    | plinth_height | (0.04, 0.10) | within [0, 0.3] |
    | top_thickness | (0.02, 0.04) | within [0.005, 0.1] |
    | door_width | (0.35, 0.6) | within [0.15, 1.5]: the number of doors is round(width / door_width) |
    """

    width: tuple[float, float] = (0.5, 1.2)
    depth: tuple[float, float] = (0.38, 0.55)
    height: tuple[float, float] = (0.6, 1.1)
    plinth_height: tuple[float, float] = (0.04, 0.10)
    top_thickness: tuple[float, float] = (0.02, 0.04)
    door_width: tuple[float, float] = (0.35, 0.6)
    _bounds: ClassVar[dict[str, tuple[float, float]]] = {
        "width": (0.2, 4.0), "depth": (0.15, 1.5), "height": (0.2, 3.0), "plinth_height": (0.0, 0.3),
        "top_thickness": (0.005, 0.1), "door_width": (0.15, 1.5),
    }


@dataclass(frozen=True)
class WardrobeConfig(CabinetConfig):
    """A wardrobe: a tall ``CabinetConfig`` (same fields) with 2-4 doors.

    | field | default |
    |---|---|
    | width | (0.8, 2.0) |
    | depth | (0.55, 0.65) |
    | height | (1.8, 2.2) |
    | plinth_height | (0.05, 0.10) |
    | top_thickness | (0.02, 0.05) |
    | door_width | (0.4, 0.6) |
    """

    width: tuple[float, float] = (0.8, 2.0)
    depth: tuple[float, float] = (0.55, 0.65)
    height: tuple[float, float] = (1.8, 2.2)
    plinth_height: tuple[float, float] = (0.05, 0.10)
    top_thickness: tuple[float, float] = (0.02, 0.05)
    door_width: tuple[float, float] = (0.4, 0.6)


@dataclass(frozen=True)
class BookshelfConfig(_Config):
    """An open bookshelf: two "side"s, a "back", ``num_shelves + 1`` boards labelled "shelf"
    (bottom to top), and blocks of "books" on some shelves.

    | field | default | valid |
    |---|---|---|
    | width | (0.6, 1.2) | within [0.2, 4.0] (y) |
    | depth | (0.25, 0.40) | within [0.1, 1.0] (x) |
    | height | (1.2, 2.0) | within [0.3, 3.0] |
    | board_thickness | (0.018, 0.03) | within [0.005, 0.08] |
    | num_shelves | (3, 6) | integers within [1, 12]: compartments |
    | books_probability | 0.7 | [0, 1]: chance of books in a compartment |
    """

    width: tuple[float, float] = (0.6, 1.2)
    depth: tuple[float, float] = (0.25, 0.40)
    height: tuple[float, float] = (1.2, 2.0)
    board_thickness: tuple[float, float] = (0.018, 0.03)
    num_shelves: tuple[int, int] = (3, 6)
    books_probability: float = 0.7
    _bounds: ClassVar[dict[str, tuple[float, float]]] = {
        "width": (0.2, 4.0), "depth": (0.1, 1.0), "height": (0.3, 3.0), "board_thickness": (0.005, 0.08),
        "num_shelves": (1, 12),
    }
    _integers: ClassVar[frozenset[str]] = frozenset({"num_shelves"})
    _numbers: ClassVar[dict[str, tuple[float, float]]] = {"books_probability": (0.0, 1.0)}


@dataclass(frozen=True)
class LampConfig(_Config):
    """A floor lamp: a round "base", a "pole" and a conical "lamp_shade".

    | field | default | valid |
    |---|---|---|
    | height | (1.4, 1.8) | within [0.3, 2.5]: top of the shade |
    | base_radius | (0.12, 0.20) | within [0.05, 0.5] |
    | base_thickness | (0.02, 0.04) | within [0.005, 0.2] |
    | pole_radius | (0.012, 0.02) | within [0.005, 0.1] |
    | shade_radius | (0.15, 0.24) | within [0.05, 0.6]: bottom radius |
    | shade_taper | (0.55, 0.85) | within [0.1, 1.0]: top radius / bottom radius |
    | shade_height | (0.2, 0.3) | within [0.05, 0.8] |
    """

    height: tuple[float, float] = (1.4, 1.8)
    base_radius: tuple[float, float] = (0.12, 0.20)
    base_thickness: tuple[float, float] = (0.02, 0.04)
    pole_radius: tuple[float, float] = (0.012, 0.02)
    shade_radius: tuple[float, float] = (0.15, 0.24)
    shade_taper: tuple[float, float] = (0.55, 0.85)
    shade_height: tuple[float, float] = (0.2, 0.3)
    _bounds: ClassVar[dict[str, tuple[float, float]]] = {
        "height": (0.3, 2.5), "base_radius": (0.05, 0.5), "base_thickness": (0.005, 0.2),
        "pole_radius": (0.005, 0.1), "shade_radius": (0.05, 0.6), "shade_taper": (0.1, 1.0),
        "shade_height": (0.05, 0.8),
    }


# --- builders (config, rng) -> (parts, params) ----------------------------------------------------
Built = tuple[list[Part], dict[str, Any]]


def _build_chair(c: ChairConfig, rng: np.random.Generator) -> Built:
    h, w, d = _u(rng, c.seat_height), _u(rng, c.seat_width), _u(rng, c.seat_depth)
    ts, lt = _u(rng, c.seat_thickness), _u(rng, c.leg_thickness)
    bh, bt = _u(rng, c.backrest_height), _u(rng, c.backrest_thickness)
    tilt = math.radians(_u(rng, c.backrest_tilt_deg))
    parts = [Part.from_bounds("seat", (-d / 2, -w / 2, h - ts), (d / 2, w / 2, h))]
    for sx, sy in itertools.product((1.0, -1.0), repeat=2):
        x0 = d / 2 - lt if sx > 0 else -d / 2
        y0 = w / 2 - lt if sy > 0 else -w / 2
        parts.append(Part.from_bounds("leg", (x0, y0, 0.0), (x0 + lt, y0 + lt, h - ts)))
    rot = _rot_y(-tilt)  # the top leans back (towards -x)
    pivot = np.array([-d / 2 + bt / 2, 0.0, h])
    parts.append(Part.box("backrest", pivot + rot @ np.array([0.0, 0.0, bh / 2]), (bt / 2, w / 2, bh / 2), rot))
    return parts, {"seat_height": h, "seat_width": w, "seat_depth": d, "seat_thickness": ts,
                   "leg_thickness": lt, "backrest_height": bh, "backrest_tilt_deg": math.degrees(tilt)}


def _upholstered(label_seats: int, width_inner: float, arm_w: float, depth: float, back_t: float,
                 seat_h: float, cushion_t: float, leg_h: float, arm_h: float, back_h: float,
                 leg_t: float) -> list[Part]:
    """Armchair / sofa: legs, base, seat cushion(s), backrest over the full width, rounded armrests."""
    total_w = width_inner + 2.0 * arm_w
    xb, xf = -(depth + back_t) / 2, (depth + back_t) / 2
    parts = []
    for sx, sy in itertools.product((1.0, -1.0), repeat=2):
        x0 = xf - leg_t - 0.02 if sx > 0 else xb + 0.02
        y0 = total_w / 2 - leg_t - 0.02 if sy > 0 else -total_w / 2 + 0.02
        parts.append(Part.from_bounds("leg", (x0, y0, 0.0), (x0 + leg_t, y0 + leg_t, leg_h)))
    parts.append(Part.from_bounds("base", (xb + back_t, -width_inner / 2, leg_h),
                                  (xf, width_inner / 2, seat_h - cushion_t)))
    seat_w = width_inner / label_seats
    for k in range(label_seats):
        y0 = -width_inner / 2 + k * seat_w
        parts.append(Part.from_bounds("seat", (xb + back_t, y0, seat_h - cushion_t), (xf, y0 + seat_w, seat_h)))
    parts.append(Part.from_bounds("backrest", (xb, -total_w / 2, leg_h), (xb + back_t, total_w / 2, seat_h + back_h)))
    for side in (-1.0, 1.0):
        y_in, y_out = side * width_inner / 2, side * total_w / 2
        lo = (xb + back_t * 0.5, min(y_in, y_out), leg_h)
        hi = (xf, max(y_in, y_out), seat_h + arm_h)
        parts.append(Part.convex("armrest", rounded_bar_points(lo, hi, radius=0.5 * arm_w)))
    return parts


def _build_armchair(c: ArmchairConfig, rng: np.random.Generator) -> Built:
    h, w, d = _u(rng, c.seat_height), _u(rng, c.seat_width), _u(rng, c.seat_depth)
    ct, lh = _u(rng, c.cushion_thickness), _u(rng, c.leg_height)
    aw, ah = _u(rng, c.arm_width), _u(rng, c.arm_height)
    bt, bh = _u(rng, c.back_thickness), _u(rng, c.back_height)
    ct = min(ct, 0.5 * h)
    lh = min(lh, h - ct - 0.03)
    parts = _upholstered(1, w, aw, d, bt, h, ct, lh, ah, bh, 0.05)
    return parts, {"seat_height": h, "seat_width": w, "seat_depth": d, "cushion_thickness": ct,
                   "leg_height": lh, "arm_width": aw, "arm_height": ah, "back_height": bh}


def _build_sofa(c: SofaConfig, rng: np.random.Generator) -> Built:
    total, d, h = _u(rng, c.width), _u(rng, c.seat_depth), _u(rng, c.seat_height)
    ct, lh = _u(rng, c.cushion_thickness), _u(rng, c.leg_height)
    aw, ah = _u(rng, c.arm_width), _u(rng, c.arm_height)
    bt, bh = _u(rng, c.back_thickness), _u(rng, c.back_height)
    n = _i(rng, c.num_seats)
    aw = min(aw, 0.25 * total)
    ct = min(ct, 0.5 * h)
    lh = min(lh, h - ct - 0.03)
    parts = _upholstered(n, total - 2.0 * aw, aw, d, bt, h, ct, lh, ah, bh, 0.05)
    return parts, {"seat_height": h, "width": total, "seat_width": total - 2.0 * aw, "seat_depth": d,
                   "num_seats": n, "arm_height": ah, "back_height": bh}


def _build_stool(c: StoolConfig, rng: np.random.Generator) -> Built:
    h, r, ts, lt = _u(rng, c.seat_height), _u(rng, c.seat_radius), _u(rng, c.seat_thickness), _u(rng, c.leg_thickness)
    n = _i(rng, c.num_legs)
    is_round = bool(rng.uniform() < c.round_probability)
    if is_round:
        seat = Part.convex("seat", cylinder_points(r, h - ts, h))
    else:
        seat = Part.from_bounds("seat", (-r, -r, h - ts), (r, r, h))
    parts = [seat]
    leg_r = r - 0.75 * lt - 0.02  # leg centres this far from the axis (round seats)
    if not is_round and n == 4:
        leg_r *= math.sqrt(2.0)  # square seats: legs under the corners
    for k in range(n):
        a = 2.0 * math.pi * k / n + (math.pi / 4 if n == 4 else 0.0)
        center = (leg_r * math.cos(a), leg_r * math.sin(a), 0.5 * (h - ts))
        parts.append(Part.box("leg", center, (lt / 2, lt / 2, 0.5 * (h - ts)), _rot_z(a)))
    return parts, {"seat_height": h, "seat_radius": r, "num_legs": n, "round": is_round}


def _build_bed(c: BedConfig, rng: np.random.Generator) -> Built:
    double = c.size == "double"
    w = _u(rng, c.double_width if double else c.single_width)
    length, h = _u(rng, c.length), _u(rng, c.surface_height)
    mt, lh = _u(rng, c.mattress_thickness), _u(rng, c.leg_height)
    m, hh, ht = _u(rng, c.frame_margin), _u(rng, c.headboard_height), _u(rng, c.headboard_thickness)
    ph = _u(rng, c.pillow_height)
    footboard = bool(rng.uniform() < c.footboard_probability)
    mt = min(mt, 0.6 * h)
    lh = min(lh, h - mt - 0.03)
    hh = max(hh, h + 0.15)
    fw = w + 2.0 * m  # frame width
    x0 = 0.0
    parts = [Part.from_bounds("headboard", (x0, -fw / 2, 0.0), (x0 + ht, fw / 2, hh))]
    fx0, fx1 = x0 + ht, x0 + ht + length + 2.0 * m
    parts.append(Part.from_bounds("base", (fx0, -fw / 2, lh), (fx1, fw / 2, h - mt)))
    parts.append(Part.from_bounds("bed_surface", (fx0 + m, -w / 2, h - mt), (fx1 - m, w / 2, h)))
    for sx, sy in itertools.product((0, 1), repeat=2):
        lx = fx0 + 0.03 if sx == 0 else fx1 - 0.09
        ly = -fw / 2 + 0.03 if sy == 0 else fw / 2 - 0.09
        parts.append(Part.from_bounds("leg", (lx, ly, 0.0), (lx + 0.06, ly + 0.06, lh)))
    if footboard:
        top = h + float(rng.uniform(-0.05, 0.15))
        parts.append(Part.from_bounds("footboard", (fx1, -fw / 2, 0.0), (fx1 + 0.04, fw / 2, top)))
    n_pillows = 2 if double else 1
    pw = min(0.7, (w - 0.1) / n_pillows - 0.05)
    pd = float(rng.uniform(0.32, 0.42))
    for k in range(n_pillows):
        yc = 0.0 if n_pillows == 1 else (k - 0.5) * (w / 2)
        parts.append(Part.from_bounds("pillow", (fx0 + m + 0.04, yc - pw / 2, h),
                                      (fx0 + m + 0.04 + pd, yc + pw / 2, h + ph)))
    return parts, {"size": c.size, "width": w, "length": length, "surface_height": h,
                   "mattress_thickness": mt, "headboard_height": hh, "footboard": footboard}


def _build_table(c: TableConfig, rng: np.random.Generator) -> Built:
    h, tt = _u(rng, c.top_height), _u(rng, c.top_thickness)
    is_round = bool(rng.uniform() < c.round_probability)
    lt, inset = _u(rng, c.leg_thickness), _u(rng, c.leg_inset)
    if is_round:
        diameter = _u(rng, c.diameter)
        r = diameter / 2
        pole_r = max(0.04, 0.5 * lt + 0.02)
        base_r = min(0.6 * r, max(0.2, 0.35 * diameter))
        parts = [Part.convex("table_top", cylinder_points(r, h - tt, h)),
                 Part.convex("base", cylinder_points(base_r, 0.0, 0.03)),
                 Part.convex("pole", cylinder_points(pole_r, 0.03, h - tt))]
        return parts, {"top_height": h, "round": True, "diameter": diameter}
    d, length = _u(rng, c.depth), _u(rng, c.length)
    inset = min(inset, 0.25 * min(d, length))
    parts = [Part.from_bounds("table_top", (-d / 2, -length / 2, h - tt), (d / 2, length / 2, h))]
    for sx, sy in itertools.product((1.0, -1.0), repeat=2):
        x0 = d / 2 - inset - lt if sx > 0 else -d / 2 + inset
        y0 = length / 2 - inset - lt if sy > 0 else -length / 2 + inset
        parts.append(Part.from_bounds("leg", (x0, y0, 0.0), (x0 + lt, y0 + lt, h - tt)))
    return parts, {"top_height": h, "round": False, "depth": d, "length": length}


def _build_case(c: CabinetConfig, rng: np.random.Generator) -> Built:
    w, d, h = _u(rng, c.width), _u(rng, c.depth), _u(rng, c.height)
    ph, tt, dw = _u(rng, c.plinth_height), _u(rng, c.top_thickness), _u(rng, c.door_width)
    doors = max(1, round(w / dw))
    door_t = 0.02
    xb, xf = -d / 2, d / 2 - door_t
    parts = []
    if ph > 0.0:
        parts.append(Part.from_bounds("base", (xb, -w / 2 + 0.02, 0.0), (xf - 0.03, w / 2 - 0.02, ph)))
    parts.append(Part.from_bounds("body", (xb, -w / 2, ph), (xf, w / 2, h - tt)))
    parts.append(Part.from_bounds("top", (xb, -w / 2 - 0.01, h - tt), (d / 2 + 0.01, w / 2 + 0.01, h)))
    each = w / doors
    handle_z = min(0.5 * (ph + h - tt) + 0.15, 1.05) if h > 1.2 else h - tt - 0.1
    handles = []
    for k in range(doors):
        y0 = -w / 2 + k * each
        parts.append(Part.from_bounds("door", (xf, y0 + 0.002, ph + 0.005), (d / 2, y0 + each - 0.002, h - tt - 0.005)))
        # Handles sit next to the door's free edge (pairs of doors meet in the middle).
        right_hinged = (k % 2 == 0) if doors > 1 else True
        yh = y0 + each - 0.05 if right_hinged else y0 + 0.05
        handles.append(Part.from_bounds("handle", (d / 2, yh - 0.01, handle_z - 0.06), (d / 2 + 0.025, yh + 0.01, handle_z + 0.06)))
    parts.extend(handles)
    return parts, {"width": w, "depth": d, "height": h, "doors": doors}


def _build_bookshelf(c: BookshelfConfig, rng: np.random.Generator) -> Built:
    w, d, h = _u(rng, c.width), _u(rng, c.depth), _u(rng, c.height)
    t, n = _u(rng, c.board_thickness), _i(rng, c.num_shelves)
    back = 0.01
    n = max(1, min(n, int((h - t) / (0.15 + t))))
    parts = [Part.from_bounds("side", (-d / 2, -w / 2, 0.0), (d / 2, -w / 2 + t, h)),
             Part.from_bounds("side", (-d / 2, w / 2 - t, 0.0), (d / 2, w / 2, h)),
             Part.from_bounds("back", (-d / 2, -w / 2 + t, 0.0), (-d / 2 + back, w / 2 - t, h))]
    step = (h - t) / n
    inner = w - 2.0 * t
    books = []
    for k in range(n + 1):
        z = k * step
        parts.append(Part.from_bounds("shelf", (-d / 2 + back, -w / 2 + t, z), (d / 2, w / 2 - t, z + t)))
        if k < n and rng.uniform() < c.books_probability:
            gap = step - t
            bw = inner * float(rng.uniform(0.2, 0.7))
            bh = gap * float(rng.uniform(0.55, 0.85))
            bd = (d - back) * float(rng.uniform(0.6, 0.9))
            y0 = -w / 2 + t + float(rng.uniform(0.0, inner - bw))
            books.append(Part.from_bounds("books", (-d / 2 + back, y0, z + t), (-d / 2 + back + bd, y0 + bw, z + t + bh)))
    parts.extend(books)
    return parts, {"width": w, "depth": d, "height": h, "num_shelves": n, "shelf_heights": [k * step + t for k in range(n + 1)]}


def _build_lamp(c: LampConfig, rng: np.random.Generator) -> Built:
    h, br, bt = _u(rng, c.height), _u(rng, c.base_radius), _u(rng, c.base_thickness)
    pr, sr, taper, sh = _u(rng, c.pole_radius), _u(rng, c.shade_radius), _u(rng, c.shade_taper), _u(rng, c.shade_height)
    sh = min(sh, 0.5 * h)
    parts = [Part.convex("base", cylinder_points(br, 0.0, bt)),
             Part.convex("pole", cylinder_points(pr, bt, h - 0.5 * sh, segments=12)),
             Part.convex("lamp_shade", cylinder_points(sr, h - sh, h, top_radius=sr * taper))]
    return parts, {"height": h, "shade_radius": sr}


FURNITURE_CONFIGS: Mapping[str, _Config] = MappingProxyType({
    "chair": ChairConfig(), "armchair": ArmchairConfig(), "stool": StoolConfig(), "sofa": SofaConfig(),
    "bed": BedConfig(size="single"), "double_bed": BedConfig(size="double"), "table": TableConfig(),
    "cabinet": CabinetConfig(), "wardrobe": WardrobeConfig(), "bookshelf": BookshelfConfig(),
    "lamp": LampConfig(),
})

_BUILDERS: dict[type, Any] = {
    ChairConfig: _build_chair, ArmchairConfig: _build_armchair, StoolConfig: _build_stool,
    SofaConfig: _build_sofa, BedConfig: _build_bed, TableConfig: _build_table, CabinetConfig: _build_case,
    WardrobeConfig: _build_case, BookshelfConfig: _build_bookshelf, LampConfig: _build_lamp,
}


def furniture_config(family: str, **overrides: Any) -> _Config:
    """The default config of ``family`` with ``overrides`` (a scalar fixes a range: x -> (x, x))."""
    check_choice("family", family, FAMILIES)
    base = FURNITURE_CONFIGS[family]
    names = [f.name for f in fields(base)]
    unknown = sorted(set(overrides) - set(names))
    if unknown:
        raise ValueError(f"{family} has no parameter(s) {unknown}; valid: {names}")
    return replace(base, **overrides) if overrides else base


def make_furniture(family: str, rng: np.random.Generator, *, config: _Config | None = None,
                   **overrides: Any) -> Furniture:
    """Sample one piece of ``family`` (see ``FAMILIES``) from its config with ``rng`` (pure).

    ``config`` replaces the family's default config (``FURNITURE_CONFIGS``); ``overrides``
    then change single fields: a (min, max) pair sets a range, a number fixes it, e.g.
    ``make_furniture("chair", rng, seat_height=0.45)``. Invalid values raise ``ValueError``
    naming the parameter and its valid range. A bed's family is "double_bed" when its
    ``size`` is "double" and "bed" otherwise.
    """
    check_choice("family", family, FAMILIES)
    if config is None:
        cfg = furniture_config(family, **overrides)
    else:
        names = [f.name for f in fields(config)]
        unknown = sorted(set(overrides) - set(names))
        if unknown:
            raise ValueError(f"{type(config).__name__} has no parameter(s) {unknown}; valid: {names}")
        cfg = replace(config, **overrides) if overrides else config
    builder = _BUILDERS.get(type(cfg))
    if builder is None:
        raise TypeError(f"config must be one of {[c.__name__ for c in _BUILDERS]}, got {type(cfg).__name__}")
    parts, params = builder(cfg, rng)
    if isinstance(cfg, BedConfig):
        family = "double_bed" if cfg.size == "double" else "bed"
    return Furniture.from_parts(family, parts, params)


# --- colours -------------------------------------------------------------------------------------
# Per family: (frame / wood colour, upholstery / soft colour), RGBA in [0, 1].
FAMILY_RGBA: Mapping[str, tuple[tuple[float, ...], tuple[float, ...]]] = MappingProxyType({
    "chair": ((0.55, 0.36, 0.20, 1.0), (0.62, 0.42, 0.25, 1.0)),
    "armchair": ((0.30, 0.22, 0.16, 1.0), (0.35, 0.50, 0.62, 1.0)),
    "stool": ((0.50, 0.34, 0.20, 1.0), (0.72, 0.55, 0.35, 1.0)),
    "sofa": ((0.25, 0.20, 0.16, 1.0), (0.55, 0.30, 0.30, 1.0)),
    "bed": ((0.48, 0.33, 0.22, 1.0), (0.90, 0.90, 0.86, 1.0)),
    "double_bed": ((0.40, 0.28, 0.20, 1.0), (0.86, 0.88, 0.93, 1.0)),
    "table": ((0.45, 0.30, 0.18, 1.0), (0.60, 0.42, 0.26, 1.0)),
    "cabinet": ((0.70, 0.62, 0.50, 1.0), (0.78, 0.70, 0.58, 1.0)),
    "wardrobe": ((0.60, 0.50, 0.40, 1.0), (0.68, 0.58, 0.47, 1.0)),
    "bookshelf": ((0.52, 0.38, 0.26, 1.0), (0.60, 0.45, 0.32, 1.0)),
    "lamp": ((0.20, 0.20, 0.22, 1.0), (0.95, 0.90, 0.72, 1.0)),
})
_SOFT_LABELS = frozenset({"seat", "bed_surface", "pillow", "lamp_shade", "table_top", "door", "top"})
_UPHOLSTERED = frozenset({"armchair", "sofa"})
_BOOK_RGBA = ((0.60, 0.15, 0.15, 1.0), (0.15, 0.35, 0.55, 1.0), (0.20, 0.50, 0.25, 1.0), (0.75, 0.60, 0.20, 1.0))
HANDLE_RGBA = (0.75, 0.75, 0.78, 1.0)


def part_rgba(family: str, label: str, k: int = 0) -> tuple[float, ...]:
    """Display colour of part ``k`` of ``label`` of a ``family`` piece."""
    if label == "books":
        return _BOOK_RGBA[k % len(_BOOK_RGBA)]
    if label == "handle":
        return HANDLE_RGBA
    frame, soft = FAMILY_RGBA.get(family, ((0.5, 0.5, 0.5, 1.0), (0.6, 0.6, 0.6, 1.0)))
    if label == "pillow":
        return (1.0, 1.0, 1.0, 1.0)
    if label in _SOFT_LABELS or (family in _UPHOLSTERED and label in ("backrest", "armrest", "base")):
        return soft
    return frame


# --- placement and MuJoCo ------------------------------------------------------------------------
def _pose(pose: Sequence[float]) -> tuple[float, float, float]:
    try:
        x, y, yaw = (float(v) for v in pose)
    except (TypeError, ValueError):
        raise ValueError(f"pose must be (x, y, yaw), got {pose!r}") from None
    if not all(math.isfinite(v) for v in (x, y, yaw)):
        raise ValueError(f"pose must be finite, got {pose!r}")
    return x, y, yaw


@dataclass(frozen=True, eq=False)
class PlacedFurniture:
    """A furniture instance in the world: ``name``, the piece and its pose (x, y, yaw).

    World = ``rotation @ p + (x, y, 0)`` for a point p of the furniture frame.
    """

    name: str
    furniture: Furniture
    pose: tuple[float, float, float]

    def __post_init__(self) -> None:
        object.__setattr__(self, "pose", _pose(self.pose))

    @property
    def category(self) -> str:
        return self.furniture.category

    @property
    def family(self) -> str:
        return self.furniture.family

    @property
    def position(self) -> np.ndarray:
        """World (x, y) of the footprint centre."""
        return np.array(self.pose[:2])

    @property
    def yaw(self) -> float:
        return self.pose[2]

    @property
    def rotation(self) -> np.ndarray:
        return _rot_z(self.pose[2])

    @property
    def translation(self) -> np.ndarray:
        return np.array([self.pose[0], self.pose[1], 0.0])

    def to_world(self, points: np.ndarray) -> np.ndarray:
        """Furniture-frame points (..., 3) -> world."""
        return np.asarray(points, dtype=float) @ self.rotation.T + self.translation

    def to_local(self, points: np.ndarray) -> np.ndarray:
        """World points (..., 3) -> furniture frame."""
        return (np.asarray(points, dtype=float) - self.translation) @ self.rotation

    def footprint_box(self, margin: float = 0.0) -> Box:
        """The footprint as a world ``stairenv.world.scenes.Box`` (z from 0 to the height), grown by ``margin``."""
        hx, hy = self.furniture.footprint
        return Box(self.pose[:2], (hx + margin, hy + margin), self.pose[2], 0.0, max(self.furniture.height, 1e-3))

    def contact_surface(self, label: str, index: int | None = None, side: str = "auto") -> ContactSurface:
        """``Furniture.contact_surface`` in the world frame."""
        return self.furniture.contact_surface(label, index, side).transformed(self.rotation, self.translation)

    def nearest_point(self, label: str, points: np.ndarray, index: int | None = None) -> np.ndarray:
        """Nearest world point on the ``label`` part(s) to world points (..., 3)."""
        return self.to_world(self.furniture.nearest_point(label, self.to_local(points), index))

    def contains(self, points: np.ndarray, label: str | None = None) -> np.ndarray:
        return self.furniture.contains(self.to_local(points), label)


@dataclass(eq=False)
class FurnitureHandle:
    """What ``add_furniture_to_spec`` added: the body and the geom names per label.

    ``geom_names[label][k]`` is ``{name}/{label}/{k}``. ``bind(model)`` looks up the ids.
    """

    name: str
    furniture: Furniture
    pose: tuple[float, float, float]
    body_name: str
    geom_names: dict[str, tuple[str, ...]]
    body_id: int = -1
    geom_ids: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def placed(self) -> PlacedFurniture:
        return PlacedFurniture(self.name, self.furniture, self.pose)

    @property
    def all_geom_names(self) -> tuple[str, ...]:
        return tuple(n for names in self.geom_names.values() for n in names)

    def bind(self, model: mujoco.MjModel) -> None:
        self.body_id = model.body(self.body_name).id
        self.geom_ids = {label: np.array([model.geom(n).id for n in names], dtype=np.int64)
                         for label, names in self.geom_names.items()}


def add_furniture_to_spec(spec: mujoco.MjSpec, furniture: Furniture, pose: Sequence[float] = (0.0, 0.0, 0.0),
                          name: str | None = None, *, friction: Sequence[float] = (1.0, 0.005, 0.0001),
                          rgba: Sequence[float] | None = None, group: int = 0) -> FurnitureHandle:
    """Add ``furniture`` at ``pose`` (x, y, yaw; world, m and rad) as one static body ``name``.

    One geom per part, named ``{name}/{label}/{k}``: boxes as box geoms, other parts as
    mesh geoms (a mesh asset of the same name made from the part's vertices; MuJoCo
    collides with its convex hull, which is the part itself). Colours from ``part_rgba``
    unless ``rgba`` is given. ``name`` defaults to the family.
    """
    x, y, yaw = _pose(pose)
    name = furniture.family if name is None else str(name)
    body = spec.worldbody.add_body(name=name, pos=[x, y, 0.0], quat=[math.cos(0.5 * yaw), 0.0, 0.0, math.sin(0.5 * yaw)])
    names: dict[str, list[str]] = {}
    for part in furniture.part_list:
        k = len(names.setdefault(part.label, []))
        geom_name = f"{name}/{part.label}/{k}"
        color = list(rgba) if rgba is not None else list(part_rgba(furniture.family, part.label, k))
        common = {"name": geom_name, "rgba": color, "friction": list(friction), "condim": 3, "group": group}
        if part.is_box:
            quat = np.zeros(4)
            mujoco.mju_mat2Quat(quat, part.rotation.ravel())
            body.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, pos=part.center.tolist(), quat=quat.tolist(),
                          size=part.half_extents.tolist(), **common)
        else:
            spec.add_mesh(name=geom_name, uservert=part.vertices.ravel().tolist())
            body.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname=geom_name, **common)
        names[part.label].append(geom_name)
    return FurnitureHandle(name, furniture, (x, y, yaw), name, {k: tuple(v) for k, v in names.items()})
