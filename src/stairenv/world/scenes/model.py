"""The scene data model: ``Scene`` (terrain, walls, ceilings, obstacles, landmarks), its
landmarks, and its file format (``Scene.save`` / ``Scene.load``, with the size limits a
loaded file must meet)."""

from __future__ import annotations

import json
import math
import zipfile
import zlib
from dataclasses import dataclass, field
from os import PathLike
from typing import Any

import numpy as np
from scipy import ndimage

from stairenv.planning.grid import PlanningGrid
from stairenv.validation import check_number
from stairenv.world.scenes.obstacles import DynamicObstacle
from stairenv.world.scenes.shapes import Box, check_floats, kwargs_from_json

# Terrain kinds, in the order of ``Scene.terrain_labels`` codes and ``SceneConfig.terrain_weights``.
TERRAIN_KINDS: tuple[str, ...] = ("flat", "slope", "rough", "stairs")

# Landmark names of the paper's scenes (Fig. 1, 9) and a few more of the same kind.
DEFAULT_LANDMARK_NAMES: tuple[str, ...] = (
    "tree", "swing", "car", "bench", "fountain", "slide", "statue", "lamp",
)

SCENE_FILE_FORMAT = "stairenv.scene"
SCENE_FILE_VERSION = 1

# Height of a landmark's display position (its marker's top) above the ground (m).
LANDMARK_MARKER_HEIGHT = 1.0

# What ``Scene.load`` reads at most. A compressed file can declare arrays far larger than
# itself (3 MB of zeros inflate to 3 GB), so the declared sizes are checked first.
#: Cells of the height map (and of ``terrain_labels``): 4096 x 4096, 128 MiB of float64
#: (e.g. 200 m x 200 m at 5 cm).
MAX_SCENE_CELLS = 4096 * 4096
#: Bytes of the scene description (``scene_json``).
MAX_SCENE_JSON_BYTES = 16 * 2**20
#: Largest |height| (m) of a loaded height map; taller terrain means a corrupt file.
MAX_SCENE_HEIGHT = 1000.0


class SceneFileError(ValueError):
    """A scene file that cannot be read: not an ``.npz``, corrupt, incomplete or of another version."""

# --- landmarks -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Landmark:
    """A named goal region: the disc of ``radius`` (m) around ``center`` (x, y).

    On a grid, the landmark is the set of cells whose centre lies in the disc, plus the
    cell that contains ``center`` (so a small disc still has a cell). ``display_position``
    (x, y, z) is where a marker or label is drawn (the top of the marker post).
    """

    name: str
    center: tuple[float, float]
    radius: float
    display_position: tuple[float, float, float]

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"a landmark needs a non-empty name, got {self.name!r}")
        object.__setattr__(self, "center", check_floats("center", self.center, 2))
        object.__setattr__(self, "radius", check_number("radius", self.radius, 0.0))
        object.__setattr__(self, "display_position", check_floats("display_position", self.display_position, 3))

    def cells(self, shape: tuple[int, int], cell_size: float, origin: tuple[float, float]) -> np.ndarray:
        """(K, 2) int cells (i, j) of the landmark on a grid; may be empty if it lies off the grid."""
        x0, y0 = origin
        cx, cy = self.center
        j_lo = max(math.floor((cx - self.radius - x0) / cell_size), 0)
        j_hi = min(math.ceil((cx + self.radius - x0) / cell_size) + 1, shape[1])
        i_lo = max(math.floor((cy - self.radius - y0) / cell_size), 0)
        i_hi = min(math.ceil((cy + self.radius - y0) / cell_size) + 1, shape[0])
        ii, jj = np.mgrid[i_lo:max(i_hi, i_lo), j_lo:max(j_hi, j_lo)]
        dx = x0 + (jj + 0.5) * cell_size - cx
        dy = y0 + (ii + 0.5) * cell_size - cy
        inside = dx * dx + dy * dy <= self.radius * self.radius + 1e-12
        cells = np.stack((ii[inside], jj[inside]), axis=-1).reshape(-1, 2)
        own = (math.floor((cy - y0) / cell_size), math.floor((cx - x0) / cell_size))
        if 0 <= own[0] < shape[0] and 0 <= own[1] < shape[1] and not (
            (cells[:, 0] == own[0]) & (cells[:, 1] == own[1])
        ).any():
            cells = np.concatenate((cells, np.array([own])), axis=0)
        return cells.astype(np.int64)

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "center": list(self.center), "radius": self.radius,
                "display_position": list(self.display_position)}

    @classmethod
    def from_dict(cls, data: Any) -> Landmark:
        return cls(**kwargs_from_json(cls, data, "landmark"))


# --- the scene -----------------------------------------------------------------------------------
@dataclass(eq=False)
class Scene:
    """A PlaMo scene in the world frame (z up, metres).

    | field | meaning |
    |---|---|
    | heights | (H, W) ground height (world z) at cell centres; rows are y, columns are x |
    | cell_size | grid spacing c (m) |
    | origin | (x0, y0): the corner of cell (0, 0) at minimal x and y (m) |
    | walls | static obstacles (``Box``): impassable, from ``bottom`` to ``top`` |
    | ceilings | top obstacles (``Box``): ``bottom`` is the underside (world z) the head must stay below |
    | dynamic_obstacles | moving balls (``DynamicObstacle``) with predictable motion |
    | landmarks | named goal regions (``Landmark``), names unique |
    | terrain_labels | optional (H, W) uint8: index into ``TERRAIN_KINDS`` of the patch each cell belongs to |
    | tiles | optional ``stairenv.world.tiles.TerrainTiles``: the terrain as its patches (kinds, stairs boxes), which ``add_scene_to_spec`` builds the collision model from; set by ``generate_scene``, not compared, not saved (a loaded scene's terrain is one height field) |

    ``Scene`` compares by value (``==``), arrays included.
    """

    heights: np.ndarray
    cell_size: float
    origin: tuple[float, float] = (0.0, 0.0)
    walls: list[Box] = field(default_factory=list)
    ceilings: list[Box] = field(default_factory=list)
    dynamic_obstacles: list[DynamicObstacle] = field(default_factory=list)
    landmarks: list[Landmark] = field(default_factory=list)
    terrain_labels: np.ndarray | None = None
    tiles: Any = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        self.heights = np.array(self.heights, dtype=np.float64)
        if self.heights.ndim != 2 or min(self.heights.shape) < 2:
            raise ValueError(f"heights must be a 2-D array of at least 2 x 2 cells, got shape {self.heights.shape}")
        if not np.isfinite(self.heights).all():
            raise ValueError("heights must be finite")
        self.cell_size = check_number("cell_size", self.cell_size, 0.0, low_open=True)
        self.origin = check_floats("origin", self.origin, 2)
        self.walls = list(self.walls)
        self.ceilings = list(self.ceilings)
        self.dynamic_obstacles = list(self.dynamic_obstacles)
        self.landmarks = list(self.landmarks)
        for name, items, cls in (("walls", self.walls, Box), ("ceilings", self.ceilings, Box),
                                 ("dynamic_obstacles", self.dynamic_obstacles, DynamicObstacle),
                                 ("landmarks", self.landmarks, Landmark)):
            for item in items:
                if not isinstance(item, cls):
                    raise TypeError(f"{name} must hold {cls.__name__} objects, got {type(item).__name__}")
        for what, names in (("landmark", [lm.name for lm in self.landmarks]),
                            ("dynamic obstacle", [ob.name for ob in self.dynamic_obstacles])):
            if len(set(names)) != len(names):
                raise ValueError(f"{what} names must be unique, got {names}")
        if self.terrain_labels is not None:
            labels = np.array(self.terrain_labels)
            if labels.shape != self.heights.shape or (labels.size and (labels.min() < 0 or labels.max() >= len(TERRAIN_KINDS))):
                raise ValueError(
                    f"terrain_labels must be an array of the heights' shape {self.heights.shape} with values in "
                    f"[0, {len(TERRAIN_KINDS) - 1}] (indices into TERRAIN_KINDS)"
                )
            self.terrain_labels = labels.astype(np.uint8)

    # --- geometry ----------------------------------------------------------------------------
    @property
    def shape(self) -> tuple[int, int]:
        return self.heights.shape

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(x_min, x_max, y_min, y_max) of the grid (m)."""
        x0, y0 = self.origin
        return x0, x0 + self.shape[1] * self.cell_size, y0, y0 + self.shape[0] * self.cell_size

    @property
    def landmark_names(self) -> tuple[str, ...]:
        return tuple(lm.name for lm in self.landmarks)

    def landmark(self, name: str) -> Landmark:
        for lm in self.landmarks:
            if lm.name == name:
                return lm
        raise KeyError(f"no landmark {name!r}; this scene has {list(self.landmark_names)}")

    def cell_center(self, i: np.ndarray | int, j: np.ndarray | int) -> np.ndarray:
        """World (x, y) of cell centres; broadcasts over arrays of indices."""
        i, j = np.asarray(i), np.asarray(j)
        return np.stack((self.origin[0] + (j + 0.5) * self.cell_size,
                         self.origin[1] + (i + 0.5) * self.cell_size), axis=-1)

    def height_at(self, points: np.ndarray) -> np.ndarray:
        """Ground height (world z) under world points (..., 2 or 3): bilinear between cell centres.

        Outside the grid the border values continue (as in the MuJoCo height field's
        half-cell rim).
        """
        xy = np.asarray(points, dtype=float)[..., :2]
        col = (xy[..., 0] - self.origin[0]) / self.cell_size - 0.5
        row = (xy[..., 1] - self.origin[1]) / self.cell_size - 0.5
        coords = np.stack((row.ravel(), col.ravel()))
        values = ndimage.map_coordinates(self.heights, coords, order=1, mode="nearest")
        return values.reshape(xy.shape[:-1])

    def surface_height_at(self, points: np.ndarray) -> np.ndarray:
        """Top of whatever is under world points (..., 2 or 3): ground or the top of a wall."""
        xy = np.asarray(points, dtype=float)[..., :2]
        top = self.height_at(xy)
        for wall in self.walls:
            top = np.where(wall.contains_xy(xy), np.maximum(top, wall.top), top)
        return top

    def dynamic_positions(self, t: float) -> np.ndarray:
        """(K, 3) centres of the dynamic obstacles at time ``t``."""
        if not self.dynamic_obstacles:
            return np.zeros((0, 3))
        return np.stack([ob.position(t) for ob in self.dynamic_obstacles])

    # --- the planner's view ------------------------------------------------------------------
    def planning_grid(self, cell_size: float | None = None) -> PlanningGrid:
        """Rasterise the scene for the planner (``PlanningGrid``, same origin).

        ``cell_size`` None keeps the scene's grid (heights copied). Another size covers the
        same area (the last row/column may reach past it) and samples ``height_at`` at the
        new cell centres. A cell is ``blocked`` if its square shares area with a wall's
        footprint; its ``ceiling`` is the lowest underside (world z) of the ceilings whose
        footprint shares area with it (inf under open sky). Landmarks become their cells.
        Dynamic obstacles are left to the planner's prediction.
        """
        if cell_size is None or float(cell_size) == self.cell_size:
            c = self.cell_size
            shape = self.shape
            heights = self.heights.copy()
        else:
            c = check_number("cell_size", cell_size, 0.0, low_open=True)
            width, depth = self.shape[1] * self.cell_size, self.shape[0] * self.cell_size
            shape = (max(math.ceil(depth / c - 1e-9), 1), max(math.ceil(width / c - 1e-9), 1))
            ii, jj = np.mgrid[0:shape[0], 0:shape[1]]
            heights = self.height_at(np.stack((self.origin[0] + (jj + 0.5) * c,
                                               self.origin[1] + (ii + 0.5) * c), axis=-1))
        blocked = np.zeros(shape, dtype=bool)
        for wall in self.walls:
            blocked |= wall.overlapping_cells(shape, c, self.origin)
        ceiling = np.full(shape, np.inf)
        for slab in self.ceilings:
            mask = slab.overlapping_cells(shape, c, self.origin)
            ceiling[mask] = np.minimum(ceiling[mask], slab.bottom)
        landmarks = {lm.name: lm.cells(shape, c, self.origin) for lm in self.landmarks}
        return PlanningGrid(heights=heights, blocked=blocked, ceiling=ceiling, cell_size=c,
                            origin=self.origin, landmarks=landmarks)

    # --- comparison --------------------------------------------------------------------------
    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Scene):
            return NotImplemented
        labels_equal = (self.terrain_labels is None and other.terrain_labels is None) or (
            self.terrain_labels is not None and other.terrain_labels is not None
            and np.array_equal(self.terrain_labels, other.terrain_labels)
        )
        return (
            np.array_equal(self.heights, other.heights) and self.cell_size == other.cell_size
            and self.origin == other.origin and self.walls == other.walls and self.ceilings == other.ceilings
            and self.dynamic_obstacles == other.dynamic_obstacles and self.landmarks == other.landmarks
            and labels_equal
        )

    __hash__ = None  # type: ignore[assignment]

    # --- files -------------------------------------------------------------------------------
    def to_json_dict(self) -> dict[str, Any]:
        """The structured parts (everything but the arrays), JSON-ready."""
        return {
            "format": SCENE_FILE_FORMAT,
            "version": SCENE_FILE_VERSION,
            "cell_size": self.cell_size,
            "origin": list(self.origin),
            "walls": [w.to_dict() for w in self.walls],
            "ceilings": [c.to_dict() for c in self.ceilings],
            "dynamic_obstacles": [ob.to_dict() for ob in self.dynamic_obstacles],
            "landmarks": [lm.to_dict() for lm in self.landmarks],
        }

    def save(self, path: str | PathLike[str]) -> None:
        """Write the scene to ``path`` (an ``.npz``: arrays ``heights``, optional
        ``terrain_labels``, and ``scene_json``, the UTF-8 JSON of ``to_json_dict``)."""
        arrays: dict[str, np.ndarray] = {
            "heights": self.heights,
            "scene_json": np.frombuffer(json.dumps(self.to_json_dict()).encode("utf-8"), dtype=np.uint8),
        }
        if self.terrain_labels is not None:
            arrays["terrain_labels"] = self.terrain_labels
        with open(path, "wb") as f:
            np.savez_compressed(f, **arrays)

    @classmethod
    def load(cls, path: str | PathLike[str]) -> Scene:
        """Read a file written by ``save``. Raises ``FileNotFoundError`` for a missing file and
        ``SceneFileError`` (a ``ValueError``) naming the file for anything else that is not a
        valid scene file.

        Sizes are bounded before anything is decompressed, from the shapes the arrays' ``.npy``
        headers declare: ``heights`` and ``terrain_labels`` at most ``MAX_SCENE_CELLS``
        (4096 x 4096) cells, ``scene_json`` at most ``MAX_SCENE_JSON_BYTES`` (16 MiB). Heights
        must be finite with |h| <= ``MAX_SCENE_HEIGHT`` (1000 m).
        """
        try:
            loaded = np.load(path, allow_pickle=False)
            if not isinstance(loaded, np.lib.npyio.NpzFile):
                raise SceneFileError(f"{path}: not a scene file (a single .npy array, not an .npz archive)")
            with loaded as npz:
                missing = {"heights", "scene_json"} - set(npz.files)
                if missing:
                    raise SceneFileError(f"{path}: not a scene file (missing {sorted(missing)})")
                has_labels = "terrain_labels" in npz.files
                _check_declared(path, npz, "heights", 2, "iuf", MAX_SCENE_CELLS, "MAX_SCENE_CELLS")
                _check_declared(path, npz, "scene_json", 1, "iu", MAX_SCENE_JSON_BYTES, "MAX_SCENE_JSON_BYTES")
                if has_labels:
                    _check_declared(path, npz, "terrain_labels", 2, "iu", MAX_SCENE_CELLS, "MAX_SCENE_CELLS")
                heights = npz["heights"]
                raw_json = npz["scene_json"]
                labels = npz["terrain_labels"] if has_labels else None
        except (FileNotFoundError, SceneFileError):
            raise
        except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, zlib.error) as e:
            raise SceneFileError(f"{path}: not a readable scene file (.npz): {e}") from e
        _check_loaded_heights(path, heights)
        try:
            meta = json.loads(raw_json.astype(np.uint8).tobytes().decode("utf-8"))
        except (UnicodeDecodeError, json.JSONDecodeError, ValueError) as e:
            raise SceneFileError(f"{path}: corrupt scene description (scene_json): {e}") from e
        if not isinstance(meta, dict) or meta.get("format") != SCENE_FILE_FORMAT:
            found = meta.get("format") if isinstance(meta, dict) else None
            raise SceneFileError(f"{path}: not a scene file (format {found!r}, expected {SCENE_FILE_FORMAT!r})")
        if meta.get("version") != SCENE_FILE_VERSION:
            raise SceneFileError(
                f"{path}: scene file version {meta.get('version')!r}; this stairenv reads version {SCENE_FILE_VERSION}"
            )
        try:
            scene = cls(
                heights=heights,
                cell_size=meta["cell_size"],
                origin=meta["origin"],
                walls=[Box.from_dict(d) for d in meta["walls"]],
                ceilings=[Box.from_dict(d) for d in meta["ceilings"]],
                dynamic_obstacles=[DynamicObstacle.from_dict(d) for d in meta["dynamic_obstacles"]],
                landmarks=[Landmark.from_dict(d) for d in meta["landmarks"]],
                terrain_labels=labels,
            )
        except (KeyError, TypeError, ValueError) as e:
            raise SceneFileError(f"{path}: invalid scene data: {e!r}") from e
        x_min, x_max, y_min, y_max = scene.bounds
        for lm in scene.landmarks:  # a landmark off the grid cannot be planned to: refuse it here, not at reset
            (x, y), display = lm.center, lm.display_position
            if not (x_min <= x <= x_max and y_min <= y <= y_max):
                raise SceneFileError(f"{path}: landmark {lm.name!r} at ({x:g}, {y:g}) lies outside the scene's grid "
                                     f"x [{x_min:g}, {x_max:g}], y [{y_min:g}, {y_max:g}]")
            if max(abs(display[0] - x), abs(display[1] - y), abs(display[2])) > MAX_SCENE_HEIGHT:
                raise SceneFileError(f"{path}: landmark {lm.name!r} has its display_position {display} more than "
                                     f"{MAX_SCENE_HEIGHT:g} m from it (MAX_SCENE_HEIGHT)")
        return scene


def _check_declared(path: Any, npz: Any, key: str, ndim: int, kinds: str, limit: int, limit_name: str) -> None:
    """SceneFileError unless member ``key`` of an open ``.npz`` declares an ``ndim``-D array of
    a numeric kind in ``kinds`` with at most ``limit`` elements. Reads the ``.npy`` header only."""
    member = f"{key}.npy" if f"{key}.npy" in npz.zip.namelist() else key
    npy = np.lib.format
    with npz.zip.open(member) as f:
        version = npy.read_magic(f)
        read_header = npy.read_array_header_1_0 if version == (1, 0) else npy.read_array_header_2_0
        shape, _, dtype = read_header(f)
    if len(shape) != ndim or min(shape, default=0) < 0 or dtype.kind not in kinds:
        raise SceneFileError(f"{path}: {key} must be a {ndim}-D numeric array, the file declares shape {shape} "
                             f"of {dtype}")
    size = math.prod(shape)
    if size > limit:
        raise SceneFileError(f"{path}: {key} declares shape {shape} ({size} elements), more than the {limit} "
                             f"Scene.load reads ({limit_name})")


def _check_loaded_heights(path: Any, heights: np.ndarray) -> None:
    bad = ~(np.abs(heights) <= MAX_SCENE_HEIGHT)  # NaN fails the comparison too
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise SceneFileError(f"{path}: heights must be finite with |h| <= {MAX_SCENE_HEIGHT} m "
                             f"(MAX_SCENE_HEIGHT); {int(bad.sum())} cells are not, e.g. cell ({i}, {j}) holds "
                             f"{float(heights[i, j])}")
