"""Terrain patch generators, pure functions of (config, rng): ``flat_patch``, ``slope_patch``,
``rough_patch``, ``stairs_patch``; ``generate_patch`` dispatches on the config's type. The ``*_shape``
forms also return what was drawn (``StairsShape``, ``SlopeShape``), from which the terrain's collision
geometry is built (``stairenv.world.terrain``: stairs as boxes)."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from stairenv.validation import check_number, check_range
from stairenv.world.scenes.shapes import check_int_range

# --- terrain patches -----------------------------------------------------------------------------
# A patch is an (h, w) array of heights (m) on the scene's grid. Every generator leaves the
# patch's rim at height 0 (features start ``border`` metres inside it, the rough noise fades
# out towards the rim), so that patches of any kinds tile without a cliff at their borders.


@dataclass(frozen=True)
class FlatPatchConfig:
    """Level ground at height 0 (no parameters)."""


@dataclass(frozen=True)
class SlopePatchConfig:
    """A hill of inclines: a truncated pyramid on a rotated rectangular footprint.

    Inside the footprint (random yaw, the largest rectangle of the sampled aspect ratio
    that fits ``border`` metres inside the patch) the ground rises at the sampled angle
    from the footprint's edge up to a plateau at the sampled height (a ridge if the
    footprint is too small to reach it). Every incline has the sampled angle.

    | field | default | valid |
    |---|---|---|
    | angle_deg | (5, 20) | within [0, 45]: incline angle (degrees) |
    | height | (0.3, 1.0) | within [0, 5]: plateau height (m) |
    | aspect | (0.4, 1.0) | within [0.05, 1]: footprint short side / long side |
    | border | 0.3 | [0, 10]: flat rim around the footprint (m) |
    """

    angle_deg: tuple[float, float] = (5.0, 20.0)
    height: tuple[float, float] = (0.3, 1.0)
    aspect: tuple[float, float] = (0.4, 1.0)
    border: float = 0.3

    def __post_init__(self) -> None:
        object.__setattr__(self, "angle_deg", check_range("angle_deg", self.angle_deg, 0.0, 45.0))
        object.__setattr__(self, "height", check_range("height", self.height, 0.0, 5.0))
        object.__setattr__(self, "aspect", check_range("aspect", self.aspect, 0.05, 1.0))
        object.__setattr__(self, "border", check_number("border", self.border, 0.0, 10.0))


@dataclass(frozen=True)
class RoughPatchConfig:
    """Gravel-like ground: Gaussian-smoothed white noise scaled to [0, amplitude].

    The noise fades (smoothstep) to 0 over the ``border`` metres next to the patch's rim;
    the outermost cells are 0.

    | field | default | valid |
    |---|---|---|
    | amplitude | (0.03, 0.08) | within [0, 0.5]: peak-to-valley height (m) |
    | smoothing | 0.1 | [0, 2]: standard deviation of the Gaussian filter (m); 0 = raw noise |
    | border | 0.3 | [0, 10]: fade-out band at the rim (m) |
    """

    amplitude: tuple[float, float] = (0.03, 0.08)
    smoothing: float = 0.1
    border: float = 0.3

    def __post_init__(self) -> None:
        object.__setattr__(self, "amplitude", check_range("amplitude", self.amplitude, 0.0, 0.5))
        object.__setattr__(self, "smoothing", check_number("smoothing", self.smoothing, 0.0, 2.0))
        object.__setattr__(self, "border", check_number("border", self.border, 0.0, 10.0))


@dataclass(frozen=True)
class StairsPatchConfig:
    """Stairs: steps rising from the edge of a rotated rectangular footprint to a top landing.

    The footprint is fitted as for ``SlopePatchConfig`` (random yaw = the direction the
    flights run in). Walking inwards from any side of it, the ground rises one
    ``step_height`` every ``tread_depth``, ``num_steps`` times at most (a stepped pyramid:
    no side of the stairs is a cliff).

    | field | default | valid |
    |---|---|---|
    | step_height | (0.05, 0.20) | within [0.01, 0.30] (m) |
    | tread_depth | (0.25, 0.40) | within [0.10, 1.0] (m) |
    | num_steps | (2, 5) | integers within [1, 30] |
    | aspect | (0.5, 1.0) | within [0.05, 1]: footprint short side / long side |
    | border | 0.3 | [0, 10]: flat rim around the footprint (m) |
    """

    step_height: tuple[float, float] = (0.05, 0.20)
    tread_depth: tuple[float, float] = (0.25, 0.40)
    num_steps: tuple[int, int] = (2, 5)
    aspect: tuple[float, float] = (0.5, 1.0)
    border: float = 0.3

    def __post_init__(self) -> None:
        object.__setattr__(self, "step_height", check_range("step_height", self.step_height, 0.01, 0.30))
        object.__setattr__(self, "tread_depth", check_range("tread_depth", self.tread_depth, 0.10, 1.0))
        object.__setattr__(self, "num_steps", check_int_range("num_steps", self.num_steps, 1, 30))
        object.__setattr__(self, "aspect", check_range("aspect", self.aspect, 0.05, 1.0))
        object.__setattr__(self, "border", check_number("border", self.border, 0.0, 10.0))


PatchConfig = FlatPatchConfig | SlopePatchConfig | RoughPatchConfig | StairsPatchConfig


def _check_patch_shape(shape: tuple[int, int], cell_size: float) -> tuple[int, int]:
    rows, cols = (int(n) for n in shape)
    if rows < 1 or cols < 1:
        raise ValueError(f"shape must be (rows, columns) >= (1, 1), got {shape!r}")
    check_number("cell_size", cell_size, 0.0, low_open=True)
    return rows, cols


@functools.lru_cache(maxsize=64)
def _patch_xy(shape: tuple[int, int], cell_size: float) -> tuple[np.ndarray, np.ndarray]:
    """x, y (h, w) of the cell centres relative to the patch centre (m); read-only, made once per shape
    and cell size (a terrain of many patches of one size asks for the same grid every time)."""
    rows, cols = shape
    x = (np.arange(cols) + 0.5 - 0.5 * cols) * cell_size
    y = (np.arange(rows) + 0.5 - 0.5 * rows) * cell_size
    grid = np.meshgrid(x, y)
    for axis in grid:
        axis.flags.writeable = False
    return tuple(grid)


@dataclass(frozen=True)
class Footprint:
    """A patch's feature footprint: a rectangle centred on the patch, its long side along ``yaw``
    (``u`` = x cos(yaw) + y sin(yaw) in the patch frame), half sides ``half_long`` (along u) and
    ``half_short``."""

    yaw: float
    half_long: float
    half_short: float


@dataclass(frozen=True)
class StairsShape:
    """What ``stairs_patch`` drew: level k (1..``num_steps``) is the footprint shrunk by (k - 1) ``tread``
    on every side, ``k step_height`` high (a solid box from 0). ``footprint`` None: no room, no stairs."""

    footprint: Footprint | None
    step_height: float
    tread: float
    num_steps: int

    def levels(self) -> list[tuple[float, float, float]]:
        """(half_long, half_short, top) of each level's box, bottom level first (empty levels left out)."""
        if self.footprint is None:
            return []
        out = []
        for k in range(1, self.num_steps + 1):
            inset = (k - 1) * self.tread
            half_long, half_short = self.footprint.half_long - inset, self.footprint.half_short - inset
            if half_long <= 0.0 or half_short <= 0.0:
                break
            out.append((half_long, half_short, k * self.step_height))
        return out


@dataclass(frozen=True)
class SlopeShape:
    """What ``slope_patch`` drew: a hill rising at ``angle`` (rad) from the footprint's edge to a
    plateau ``height`` high (``footprint`` None: no room, no hill)."""

    footprint: Footprint | None
    angle: float
    height: float


def _fitted_footprint(rng: np.random.Generator, shape: tuple[int, int], cell_size: float,
                      border: float, aspect: tuple[float, float]) -> tuple[np.ndarray, Footprint | None]:
    """How far each cell centre lies inside a random rotated rectangle (negative outside), and the rectangle.

    The rectangle has a random yaw and aspect ratio and is the largest such that fits
    ``border`` inside the patch, centred on it. Depth = min(hu - |u|, hv - |v|), which grows
    by 1 m per metre walked inwards (the distance to the nearest side).
    """
    yaw = rng.uniform(0.0, math.pi)
    ratio = rng.uniform(*aspect)
    x, y = _patch_xy(shape, cell_size)
    room_x = 0.5 * shape[1] * cell_size - border
    room_y = 0.5 * shape[0] * cell_size - border
    if room_x <= 0.0 or room_y <= 0.0:
        return np.full(shape, -1.0), None
    c, s = abs(math.cos(yaw)), abs(math.sin(yaw))
    half_long = min(room_x / (c + ratio * s), room_y / (s + ratio * c))
    half_short = ratio * half_long
    u = x * math.cos(yaw) + y * math.sin(yaw)
    v = -x * math.sin(yaw) + y * math.cos(yaw)
    return np.minimum(half_long - np.abs(u), half_short - np.abs(v)), Footprint(yaw, half_long, half_short)


def flat_patch(config: FlatPatchConfig, rng: np.random.Generator, *, shape: tuple[int, int],
               cell_size: float) -> np.ndarray:
    """Level ground: an (h, w) array of zeros (m). Draws nothing from ``rng``."""
    return np.zeros(_check_patch_shape(shape, cell_size))


def slope_patch(config: SlopePatchConfig, rng: np.random.Generator, *, shape: tuple[int, int],
                cell_size: float) -> np.ndarray:
    """Heights (m) of a hill with inclines of a random angle (see ``SlopePatchConfig``); in [0, height]."""
    return slope_patch_shape(config, rng, shape=shape, cell_size=cell_size)[0]


def slope_patch_shape(config: SlopePatchConfig, rng: np.random.Generator, *, shape: tuple[int, int],
                      cell_size: float) -> tuple[np.ndarray, SlopeShape]:
    """``slope_patch``'s heights (the same draws, the same bits) and the hill they sample."""
    shape = _check_patch_shape(shape, cell_size)
    angle = math.radians(rng.uniform(*config.angle_deg))
    height = rng.uniform(*config.height)
    depth, footprint = _fitted_footprint(rng, shape, cell_size, config.border, config.aspect)
    return np.minimum(height, math.tan(angle) * np.maximum(depth, 0.0)), SlopeShape(footprint, angle, height)


def rough_patch(config: RoughPatchConfig, rng: np.random.Generator, *, shape: tuple[int, int],
                cell_size: float) -> np.ndarray:
    """Heights (m) of gravel-like ground (see ``RoughPatchConfig``); in [0, amplitude]."""
    shape = _check_patch_shape(shape, cell_size)
    amplitude = rng.uniform(*config.amplitude)
    noise = rng.standard_normal(shape)
    if config.smoothing > 0.0:
        noise = ndimage.gaussian_filter(noise, sigma=config.smoothing / cell_size, mode="reflect")
    spread = noise.max() - noise.min()
    unit = (noise - noise.min()) / spread if spread > 0.0 else np.zeros(shape)
    if config.border > 0.0:
        x, y = _patch_xy(shape, cell_size)
        to_rim = np.minimum(0.5 * shape[1] * cell_size - np.abs(x), 0.5 * shape[0] * cell_size - np.abs(y))
        ramp = np.clip((to_rim - 0.5 * cell_size) / config.border, 0.0, 1.0)  # 0 on the outermost cells
        unit = unit * ramp * ramp * (3.0 - 2.0 * ramp)
    return amplitude * unit


def stairs_patch(config: StairsPatchConfig, rng: np.random.Generator, *, shape: tuple[int, int],
                 cell_size: float) -> np.ndarray:
    """Heights (m) of stairs (see ``StairsPatchConfig``): multiples of the sampled step height
    in [0, num_steps * step_height]."""
    return stairs_patch_shape(config, rng, shape=shape, cell_size=cell_size)[0]


def stairs_patch_shape(config: StairsPatchConfig, rng: np.random.Generator, *, shape: tuple[int, int],
                       cell_size: float) -> tuple[np.ndarray, StairsShape]:
    """``stairs_patch``'s heights (the same draws, the same bits) and the stairs they sample: at every cell
    centre the height is the top of the highest level (``StairsShape.levels``) whose box holds it."""
    shape = _check_patch_shape(shape, cell_size)
    step_height = rng.uniform(*config.step_height)
    tread = rng.uniform(*config.tread_depth)
    num_steps = int(rng.integers(config.num_steps[0], config.num_steps[1] + 1))
    depth, footprint = _fitted_footprint(rng, shape, cell_size, config.border, config.aspect)
    level = np.where(depth > 0.0, np.minimum(num_steps, np.floor(depth / tread) + 1), 0.0)
    return step_height * level, StairsShape(footprint, step_height, tread, num_steps)


def generate_patch(config: PatchConfig, rng: np.random.Generator, *, shape: tuple[int, int],
                   cell_size: float) -> np.ndarray:
    """Heights (m) of one patch of the kind ``config`` describes (dispatches on its type)."""
    return generate_patch_shape(config, rng, shape=shape, cell_size=cell_size)[0]


def generate_patch_shape(config: PatchConfig, rng: np.random.Generator, *, shape: tuple[int, int],
                         cell_size: float) -> tuple[np.ndarray, StairsShape | SlopeShape | None]:
    """``generate_patch``'s heights (the same draws, the same bits) and, for stairs and slopes, the shape
    they sample (``StairsShape``, ``SlopeShape``; None for flat and rough patches)."""
    generators = {FlatPatchConfig: lambda *a, **k: (flat_patch(*a, **k), None), SlopePatchConfig: slope_patch_shape,
                  RoughPatchConfig: lambda *a, **k: (rough_patch(*a, **k), None), StairsPatchConfig: stairs_patch_shape}
    generator = generators.get(type(config))
    if generator is None:
        raise ValueError(f"config must be one of {[c.__name__ for c in generators]}, got {type(config).__name__}")
    return generator(config, rng, shape=shape, cell_size=cell_size)
