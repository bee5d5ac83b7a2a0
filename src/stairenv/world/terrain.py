"""Terrain for the path-following task: generated per episode, written in place.

``terrain_tiles(kind, rng, ...)`` tiles square patches of one terrain kind
(``stairenv.world.scenes`` patch generators: flat, slope, rough, stairs; "mixed"
draws a kind per patch) into one height array (``terrain_heights``: the same draws, the
same array); patches are 0 on their rims, so neighbours meet without cliffs. Sample
(i, j) sits at x = -L/2 + j c, y = -L/2 + i c; the task reads the ground between samples
bilinearly (``bilinear_height``). The collision model holds the same terrain as tiles
(``stairenv.world.tiles``: the ground plane for flat ground, boxes for stairs, a height
field of its own samples for a slope or rough tile), near the character only.
"""

from __future__ import annotations

import math

import numpy as np

from stairenv.numba_jit import jit
from stairenv.validation import check_choice
from stairenv.world.scenes.patches import (
    FlatPatchConfig,
    RoughPatchConfig,
    SlopePatchConfig,
    StairsPatchConfig,
    generate_patch_shape,
)
from stairenv.world.tiles import TILE_KINDS, TerrainTiles, stairs_boxes

TERRAIN_KINDS = ("flat", "slope", "rough", "stairs", "mixed")
_PATCH_CONFIGS = {
    "flat": FlatPatchConfig(),
    "slope": SlopePatchConfig(),
    "rough": RoughPatchConfig(),
    "stairs": StairsPatchConfig(),
}
# Highest terrain the height field can hold (m); patches stay well below it.
MAX_TERRAIN_HEIGHT = 2.0
#: most boxes a stairs tile of ``terrain_tiles`` holds (its levels)
MAX_STAIRS_LEVELS = _PATCH_CONFIGS["stairs"].num_steps[1]


def terrain_heights(kind: str, rng: np.random.Generator, size: float = 16.0, cell_size: float = 0.1,
                    patch_size: float = 4.0) -> np.ndarray:
    """A (N, N) height array, N = size / cell_size + 1, of ``patch_size`` patches of ``kind``."""
    return terrain_tiles(kind, rng, size, cell_size, patch_size).heights


def terrain_tiles(kind: str, rng: np.random.Generator, size: float = 16.0, cell_size: float = 0.1,
                  patch_size: float = 4.0) -> TerrainTiles:
    """``terrain_heights``' terrain (the same draws, the same array) as tiles, one per patch: their kinds
    and each stairs patch's level boxes (``stairenv.world.tiles``)."""
    check_choice("terrain", kind, TERRAIN_KINDS)
    n = int(round(size / cell_size)) + 1
    per_patch = int(round(patch_size / cell_size))
    spacing = size / (n - 1)     # where the samples lie (the patches are drawn on cell_size)
    heights = np.zeros((n, n))
    kinds = tuple(_PATCH_CONFIGS)
    starts = list(range(0, n - 1, per_patch))
    codes = np.zeros((len(starts), len(starts)), dtype=np.uint8)
    shapes = {}
    for p, i0 in enumerate(starts):
        for q, j0 in enumerate(starts):
            rows, cols = min(per_patch, n - i0), min(per_patch, n - j0)
            patch_kind = kinds[rng.integers(len(kinds))] if kind == "mixed" else kind
            patch, shape = generate_patch_shape(_PATCH_CONFIGS[patch_kind], rng, shape=(rows, cols),
                                                cell_size=cell_size)
            heights[i0:i0 + rows, j0:j0 + cols] = patch
            codes[p, q] = TILE_KINDS.index(patch_kind)
            if patch_kind == "stairs":
                centre = (-size / 2 + (j0 + 0.5 * (cols - 1)) * spacing, -size / 2 + (i0 + 0.5 * (rows - 1)) * spacing)
                boxes = stairs_boxes(shape, centre, spacing / cell_size, MAX_TERRAIN_HEIGHT)
                if boxes is not None:
                    shapes[p, q] = boxes
    edges = np.array(starts + [n - 1])
    return TerrainTiles(np.clip(heights, 0.0, MAX_TERRAIN_HEIGHT), (-size / 2, -size / 2), spacing, edges, edges,
                        codes, shapes, outside="zero")


def bilinear_height(heights: np.ndarray, size: float, xy: np.ndarray) -> np.ndarray:
    """Terrain height at world points (..., 2), bilinear between samples (0 outside)."""
    xy = np.asarray(xy, dtype=np.float64)
    flat = np.ascontiguousarray(xy.reshape(-1, 2))
    out = np.empty(flat.shape[0])
    bilinear_heights(heights, size, flat, out)
    return out.reshape(xy.shape[:-1])


@jit
def bilinear_at(heights, size, x, y):
    """``bilinear_height`` of one point (x, y): the same operations in the same order, so the same bits."""
    n = heights.shape[0]
    cell = size / (n - 1)
    u = (x + size / 2) / cell
    v = (y + size / 2) / cell
    if not (u >= 0 and u <= n - 1 and v >= 0 and v <= n - 1):
        return 0.0
    top = n - 1.000001
    u, v = min(u, top), min(v, top)  # (inside: u, v >= 0 already)
    j, i = int(math.floor(u)), int(math.floor(v))
    fu, fv = u - j, v - i
    return ((1 - fv) * ((1 - fu) * heights[i, j] + fu * heights[i, j + 1])
            + fv * ((1 - fu) * heights[i + 1, j] + fu * heights[i + 1, j + 1]))


@jit
def bilinear_heights(heights, size, xy, out):
    """``bilinear_at`` of each row of ``xy`` (P, 2) into ``out`` (P,); returns ``out``."""
    for p in range(xy.shape[0]):
        out[p] = bilinear_at(heights, size, xy[p, 0], xy[p, 1])
    return out


@jit
def clamped_bilinear_at(heights, x0, y0, cell, x, y):
    """The height at (x, y) on a grid of cell-centre samples (sample (i, j) at x0 + (j + 0.5) cell,
    y0 + (i + 0.5) cell; at least 2 x 2), bilinear between them and the border samples continued beyond
    (``Scene.height_at``'s reading: ``map_coordinates`` of order 1, mode "nearest"; equal to ~1e-15 m)."""
    rows, cols = heights.shape
    u = min(max((x - x0) / cell - 0.5, 0.0), cols - 1.0)
    v = min(max((y - y0) / cell - 0.5, 0.0), rows - 1.0)
    j, i = min(int(math.floor(u)), cols - 2), min(int(math.floor(v)), rows - 2)
    fu, fv = u - j, v - i
    return ((1 - fv) * ((1 - fu) * heights[i, j] + fu * heights[i, j + 1])
            + fv * ((1 - fu) * heights[i + 1, j] + fu * heights[i + 1, j + 1]))


@jit
def clamped_bilinear_heights(heights, x0, y0, cell, xy, out):
    """``clamped_bilinear_at`` of each row of ``xy`` (P, 2) into ``out`` (P,); returns ``out``."""
    for p in range(xy.shape[0]):
        out[p] = clamped_bilinear_at(heights, x0, y0, cell, xy[p, 0], xy[p, 1])
    return out
