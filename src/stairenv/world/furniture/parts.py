"""Convex parts (``Part``), the contact surfaces on them (``ContactSurface``) and the point
sets of round parts (``cylinder_points``, ``rounded_bar_points``); furniture frame, metres."""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import trimesh
from scipy.spatial import ConvexHull

# Segments of the circles of round parts (cylinders, frustums, rounded edges).
ROUND_SEGMENTS = 24

_BOX_SIGNS = np.array(list(itertools.product((-1.0, 1.0), repeat=3)))

# --- geometry helpers ----------------------------------------------------------------------------
def rot_y(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


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
