"""Height-field terrain for the path-following task: generated per episode, written in place.

``terrain_heights(kind, rng, ...)`` tiles square patches of one terrain kind
(``stairenv.world.scenes`` patch generators: flat, slope, rough, stairs; "mixed"
draws a kind per patch) into one height array; patches are 0 on their rims, so
neighbours meet without cliffs. ``HeightfieldSlot`` adds a MuJoCo height field of a
fixed size to a spec once and ``write`` replaces its samples at every reset (no
recompilation). Sample (i, j) sits at x = -L/2 + j c, y = -L/2 + i c.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from stairenv.numba_jit import jit
from stairenv.validation import check_choice, check_number
from stairenv.world.scenes import (
    FlatPatchConfig,
    RoughPatchConfig,
    SlopePatchConfig,
    StairsPatchConfig,
    generate_patch,
)

TERRAIN_KINDS = ("flat", "slope", "rough", "stairs", "mixed")
_PATCH_CONFIGS = {
    "flat": FlatPatchConfig(),
    "slope": SlopePatchConfig(),
    "rough": RoughPatchConfig(),
    "stairs": StairsPatchConfig(),
}
# Highest terrain the height field can hold (m); patches stay well below it.
MAX_TERRAIN_HEIGHT = 2.0


def terrain_heights(kind: str, rng: np.random.Generator, size: float = 16.0, cell_size: float = 0.1,
                    patch_size: float = 4.0) -> np.ndarray:
    """A (N, N) height array, N = size / cell_size + 1, of ``patch_size`` patches of ``kind``."""
    check_choice("terrain", kind, TERRAIN_KINDS)
    n = int(round(size / cell_size)) + 1
    per_patch = int(round(patch_size / cell_size))
    heights = np.zeros((n, n))
    kinds = tuple(_PATCH_CONFIGS)
    for i0 in range(0, n - 1, per_patch):
        for j0 in range(0, n - 1, per_patch):
            rows, cols = min(per_patch, n - i0), min(per_patch, n - j0)
            patch_kind = kinds[rng.integers(len(kinds))] if kind == "mixed" else kind
            heights[i0:i0 + rows, j0:j0 + cols] = generate_patch(
                _PATCH_CONFIGS[patch_kind], rng, shape=(rows, cols), cell_size=cell_size)
    return np.clip(heights, 0.0, MAX_TERRAIN_HEIGHT)


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


class HeightfieldSlot:
    """A square MuJoCo height field of fixed size and resolution whose samples change per episode."""

    def __init__(self, spec: mujoco.MjSpec, size: float = 16.0, cell_size: float = 0.1, name: str = "terrain") -> None:
        self.size = check_number("terrain_size", size, 2.0, 200.0)
        self.cell_size = check_number("terrain_cell_size", cell_size, 0.01, 1.0)
        self.n = int(round(self.size / self.cell_size)) + 1
        self.name = name
        spec.add_hfield(name=name, nrow=self.n, ncol=self.n,
                        size=[self.size / 2, self.size / 2, MAX_TERRAIN_HEIGHT, 0.1],
                        userdata=np.zeros(self.n * self.n).tolist())
        spec.worldbody.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_HFIELD, hfieldname=name,
                                rgba=[0.62, 0.6, 0.55, 1.0], condim=3)
        # The humanoid's flat floor would cover the valleys' bottoms: sink it below the field.
        for geom in spec.geoms:
            if geom.type == mujoco.mjtGeom.mjGEOM_PLANE:
                geom.pos = [geom.pos[0], geom.pos[1], -0.01]
        self._adr: int | None = None

    def bind(self, model: mujoco.MjModel) -> None:
        hfield = model.hfield(self.name)
        self._adr = int(hfield.adr[0])

    def write(self, model: mujoco.MjModel, heights: np.ndarray) -> None:
        if self._adr is None:
            raise RuntimeError("HeightfieldSlot.bind(model) must be called before write()")
        if heights.shape != (self.n, self.n):
            raise ValueError(f"heights must have shape {(self.n, self.n)}, got {heights.shape}")
        model.hfield_data[self._adr:self._adr + self.n * self.n] = (heights / MAX_TERRAIN_HEIGHT).ravel()
