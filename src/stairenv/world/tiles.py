"""PlaMo's terrain as tiles: one layout of a generated terrain for the collision model.

A PlaMo terrain (``stairenv.world.terrain.terrain_tiles``, a scene's ``generate_scene``) is a grid of
square tiles, one patch of one kind each (``stairenv.world.scenes.patches``), on a grid of height samples
that the task reads (``TerrainTiles.heights``). The collision model holds it as

- **flat**: nothing of its own: the ground plane at z = 0 (the humanoid's floor) is flat ground and the
  flat rim of every other tile;
- **stairs**: one solid box per level (``StairsShape.levels``: the footprint shrunk by a tread per level,
  rotated with it, from z = 0 to the level's top), the shape the generator drew (its samples are the tops
  of these boxes, so the task's heights equal the boxes' at every sample);
- **slope** and **rough**: a height field of the tile's own samples (a hill's inclines and the noise have
  no exact primitive), its flat samples sunk ``BURY_DEPTH`` below the plane so that no contact is made on
  them twice.

``TerrainSlots`` holds the tiles near the character in a fixed set of slots (``slots`` tiles, each with
``max_boxes`` box bodies and one height field; what a slot does not use is parked far below): the model
has the same bodies, geoms and height fields whatever the terrain, every tile is written in place (no
recompilation), and ``focus(model, xy)`` (at a reset and before every step) brings in any non-flat tile that
comes within ``FOCUS_RADIUS`` of the character's root. Every geom is one static body's only geom, so a
slot is rewritten by body poses, sizes, bounding boxes and height-field samples alone (as
``stairenv.world.stairs.StairsSlots`` writes a staircase).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import mujoco
import numpy as np
from scipy import ndimage

from stairenv.rotations import yaw_to_quat_wxyz

#: the tile kinds, in the order of ``TerrainTiles.kinds`` codes (and of ``Scene.terrain_labels``)
TILE_KINDS: tuple[str, ...] = ("flat", "slope", "rough", "stairs")
FLAT, SLOPE, ROUGH, STAIRS = range(4)
#: how far below the plane a height field's flat samples are sunk (m): deeper than a body ever presses into
#: the ground, so MuJoCo's prism test skips them and the plane alone carries what stands there
BURY_DEPTH = 0.05
#: how deep a slot height field's solid base reaches below its lowest point (m)
HFIELD_BASE = 0.1
#: a non-flat tile is brought into a slot when it comes within this distance (m, along x or y) of the root:
#: the farthest point of the body from the pelvis (~1.0 m, a hand or foot) plus a step's travel at the
#: envs' speed bound and a margin
FOCUS_RADIUS = 1.5
#: how far below the plane an unused slot geom waits (m), under the tiles in use: not far away, which would
#: turn the axis MuJoCo's broadphase sorts along (the main axis of all non-world geoms) from the character's
#: spread to the line to the parked geoms and make its every body overlap along it (measured: 24 geoms parked
#: 100 m below cost 13% of a step on the ground, 1 m below under the character under 1%)
PARK_DEPTH = 1.0
_PARKED_HALF = np.array([0.01, 0.01, 0.01])
_PARKED_TOP = 0.01    # a parked height field's height (m); its sides are _PARKED_HALF's
#: empty slots follow the character when it is this far (m, |dx| + |dy|) from where they wait
REPARK_DISTANCE = 4.0
TERRAIN_RGBA = (0.62, 0.6, 0.55, 1.0)


@dataclass(eq=False)
class TerrainTiles:
    """A tiled terrain: the height samples the task reads and what each tile holds.

    | field | meaning |
    |---|---|
    | heights | (N, M) ground heights; sample (i, j) lies at ``origin + (j c, i c)`` |
    | origin | world (x, y) of sample (0, 0) |
    | cell_size | c, the samples' spacing (m) |
    | row_edges, col_edges | tile (p, q) covers sample rows ``row_edges[p]..row_edges[p + 1]`` and columns likewise (ends included: a tile shares its last row and column with the next) |
    | kinds | (P, Q) uint8, indices into ``TILE_KINDS`` |
    | boxes | {(p, q): (centres (k, 3), half sizes (k, 3), quat wxyz (4,))}: a stairs tile's level boxes, world frame |
    | outside | what lies beyond the samples: "zero" (flat ground at 0) or "edge" (the border samples continue) |
    """

    heights: np.ndarray
    origin: tuple[float, float]
    cell_size: float
    row_edges: np.ndarray
    col_edges: np.ndarray
    kinds: np.ndarray
    boxes: dict[tuple[int, int], tuple[np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=dict)
    outside: str = "zero"

    @property
    def shape(self) -> tuple[int, int]:
        """(P, Q): tiles along y and x."""
        return self.kinds.shape

    @property
    def tile_samples(self) -> int:
        """Samples along a side of the largest tile (ends included): the size of a slot's height field."""
        return int(max(np.diff(self.row_edges).max(), np.diff(self.col_edges).max())) + 1

    def tile_window(self, p: int, q: int) -> np.ndarray:
        """The ``tile_samples`` x ``tile_samples`` samples from tile (p, q)'s first one (rows along y), past
        the terrain's edge as ``outside`` says."""
        k = self.tile_samples
        i0, j0 = int(self.row_edges[p]), int(self.col_edges[q])
        block = self.heights[i0:i0 + k, j0:j0 + k]
        pad = ((0, k - block.shape[0]), (0, k - block.shape[1]))
        if pad == ((0, 0), (0, 0)):
            return block
        return np.pad(block, pad, mode="constant" if self.outside == "zero" else "edge")

    def tile_bounds(self, p: int, q: int) -> tuple[float, float, float, float]:
        """(x_min, x_max, y_min, y_max) of tile (p, q)'s samples."""
        x0, y0 = self.origin
        c = self.cell_size
        return (x0 + self.col_edges[q] * c, x0 + self.col_edges[q + 1] * c,
                y0 + self.row_edges[p] * c, y0 + self.row_edges[p + 1] * c)

    def tiles_near(self, xy, radius: float) -> list[tuple[int, int]]:
        """The non-flat tiles whose samples' square comes within ``radius`` of ``xy`` along x and y."""
        x0, y0 = self.origin
        c = self.cell_size
        x, y = float(xy[0]), float(xy[1])
        cols = _overlapping(self.col_edges, (x - radius - x0) / c, (x + radius - x0) / c)
        rows = _overlapping(self.row_edges, (y - radius - y0) / c, (y + radius - y0) / c)
        kinds = self.kinds
        return [(p, q) for p in rows for q in cols if kinds[p, q] != FLAT]

    def max_tiles_near(self, radius: float) -> int:
        """The most tiles ``tiles_near`` can return on this grid for ``radius`` (flat ones counted too)."""
        counts = []
        for edges in (self.row_edges, self.col_edges):
            span = 2.0 * radius / self.cell_size
            n = len(edges) - 1
            # a window that starts at the end of interval k reaches the intervals up to e[k + 1] + span
            last = np.minimum(np.searchsorted(edges, edges[1:] + span, side="right") - 1, n - 1)
            counts.append(int((last - np.arange(n) + 1).max()))
        return counts[0] * counts[1]


def _overlapping(edges: np.ndarray, low: float, high: float) -> range:
    """Indices k of the intervals [edges[k], edges[k + 1]] that meet [low, high] (sample units; touching
    counts)."""
    first = max(int(np.searchsorted(edges, low, side="left")) - 1, 0)
    last = min(int(np.searchsorted(edges, high, side="right")) - 1, len(edges) - 2)
    return range(first, last + 1)


def _bucket(edges: np.ndarray, value: float, side: str) -> tuple[float, float]:
    """The two edges between which ``value`` lies as ``np.searchsorted(edges, value, side)`` places it
    (``side`` "left": edges[k - 1] < value <= edges[k]; "right": edges[k - 1] <= value < edges[k])."""
    k = int(np.searchsorted(edges, value, side=side))
    return (float(edges[k - 1]) if k > 0 else -math.inf), (float(edges[k]) if k < len(edges) else math.inf)


def stairs_boxes(shape, centre_xy, scale: float = 1.0,
                 max_height: float = math.inf) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """A ``StairsShape``'s level boxes in the world: centres (k, 3), half sizes (k, 3), quat (4,); None if it
    has none. ``scale``: world metres per metre of the patch's own grid (1 unless the terrain stretched it);
    ``max_height``: the terrain's clip on heights, applied to the tops."""
    levels = shape.levels()
    if not levels:
        return None
    tops = np.minimum([top for _, _, top in levels], max_height)
    halves = np.array([[hl * scale, hs * scale, 0.5 * t] for (hl, hs, _), t in zip(levels, tops)])
    centres = np.column_stack((np.full(len(levels), centre_xy[0]), np.full(len(levels), centre_xy[1]), 0.5 * tops))
    return centres, halves, yaw_to_quat_wxyz(shape.footprint.yaw)


def buried_flat(samples: np.ndarray) -> np.ndarray:
    """The samples at 0 whose every neighbour (within the array) is 0 as well: every cell of a height field
    that holds one of them is flat at 0, so it can sink below the plane without changing the ground."""
    zero = samples == 0.0
    return ndimage.minimum_filter(zero.astype(np.uint8), size=3, mode="nearest").astype(bool)


def slot_contents(kinds) -> tuple[bool, bool]:
    """What the slots of a terrain that may hold tiles of ``kinds`` (names from ``TILE_KINDS``) need:
    (boxes, a height field)."""
    kinds = set(kinds)
    return "stairs" in kinds, bool(kinds & {"slope", "rough"})


class TerrainSlots:
    """``slots`` tile slots in a spec, built once; ``set_terrain`` and ``focus`` write tiles into them.

    A slot is one static body with ``max_boxes`` boxes and one height field of ``samples`` x ``samples``
    at ``cell_size`` (a stairs tile uses the boxes, a slope or rough tile the height field; what it does not
    use waits ``PARK_DEPTH`` below it, shrunk). One body a slot, not one a geom: every body is in MuJoCo's
    passes over bodies at every substep (measured with four tiles of stairs around a character on the
    ground: one body a box 7-10% of a step over the bare model, one body a slot 5-6%). A slot is rewritten by its body's pose, its geoms' poses, sizes and bounding boxes,
    its height-field samples and its bounding-volume hierarchy, recomputed from them (``_refit``).

    Call ``bind(model)`` after compiling. Per episode: ``set_terrain(model, tiles)`` (empties every slot),
    then ``focus(model, xy)`` with the character's root position at the start and before every step.
    ``dirty`` holds the height fields written since a renderer last uploaded them.
    """

    def __init__(self, spec: mujoco.MjSpec, samples: int, cell_size: float, max_boxes: int, slots: int = 4,
                 field: bool = True, prefix: str = "terrain", material: str | None = None) -> None:
        self.samples, self.cell_size = int(samples), float(cell_size)
        self.max_boxes, self.field, self.prefix = int(max_boxes), bool(field), prefix
        # a terrain of flat tiles needs none (``for_kinds``)
        self.slots = int(slots) if (self.max_boxes or self.field) else 0
        half = 0.5 * (self.samples - 1) * self.cell_size
        self._half = half
        look = {"material": material} if material else {"rgba": list(TERRAIN_RGBA)}
        for s in range(self.slots):
            body = spec.worldbody.add_body(name=f"{prefix}{s}", pos=[0.0, 0.0, 0.0])
            for b in range(self.max_boxes):
                body.add_geom(name=f"{prefix}{s}_box{b}", type=mujoco.mjtGeom.mjGEOM_BOX, size=_PARKED_HALF.tolist(),
                              pos=[0.0, 0.0, -PARK_DEPTH], condim=3, **look)
            if self.field:
                name = f"{prefix}{s}_field"
                spec.add_hfield(name=name, nrow=self.samples, ncol=self.samples,
                                size=[half, half, _PARKED_TOP, HFIELD_BASE],
                                userdata=np.zeros(self.samples ** 2).tolist())
                body.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_HFIELD, hfieldname=name,
                              pos=[0.0, 0.0, -PARK_DEPTH], condim=3, **look)
        self._ids = None
        self.tiles: TerrainTiles | None = None
        self._slot_tile: list[tuple[int, int] | None] = [None] * self.slots
        self._empty_at: tuple[float, float] | None = None
        self._known: tuple[float, ...] | None = None    # the span ends' edge brackets of the last search
        self._fields: dict[tuple[int, int], tuple[np.ndarray, float]] = {}
        #: height fields written since the last upload (ids, for ``mujoco.mjr_uploadHField``)
        self.dirty: set[int] = set()

    # --- binding ---------------------------------------------------------------------------------
    def bind(self, model: mujoco.MjModel) -> None:
        """Look up the ids in the compiled model (call once after compiling); the slot bodies' inertial frames
        are set to their body frames (a static body's inertia does nothing; its bounding volumes are kept
        in that frame)."""
        p = self.prefix
        bodies = np.array([model.body(f"{p}{s}").id for s in range(self.slots)], dtype=np.int64)
        boxes = np.array([[model.geom(f"{p}{s}_box{b}").id for b in range(self.max_boxes)]
                          for s in range(self.slots)], dtype=np.int64).reshape(self.slots, self.max_boxes)
        named = range(self.slots) if self.field else ()
        field_geoms = np.array([model.geom(f"{p}{s}_field").id for s in named], dtype=np.int64)
        fields = np.array([model.hfield(f"{p}{s}_field").id for s in named], dtype=np.int64)
        model.body_ipos[bodies] = 0.0
        model.body_iquat[bodies] = (1.0, 0.0, 0.0, 0.0)
        # the compiler marks geoms that share their body's frame or rotation (kinematics then skips their own
        # pose); a slot's geoms move within their body
        model.geom_sameframe[np.concatenate((boxes.ravel(), field_geoms))] = mujoco.mjtSameFrame.mjSAMEFRAME_NONE
        model.body_sameframe[bodies] = mujoco.mjtSameFrame.mjSAMEFRAME_NONE
        self._ids = {"bodies": bodies, "boxes": boxes, "field_geoms": field_geoms, "fields": fields,
                     "field_adr": model.hfield_adr[fields].copy(),
                     "bvh": [(int(model.body_bvhadr[b]), int(model.body_bvhnum[b])) for b in bodies]}
        for s in range(self.slots):
            self._park(model, s, (0.0, 0.0))

    @property
    def hfield_ids(self) -> np.ndarray:
        return self._ids["fields"]

    def geom_ids(self) -> np.ndarray:
        """Every slot geom's id (boxes, then height fields)."""
        return np.concatenate((self._ids["boxes"].ravel(), self._ids["field_geoms"]))

    # --- writing ---------------------------------------------------------------------------------
    def set_terrain(self, model: mujoco.MjModel, tiles: TerrainTiles) -> None:
        """This episode's terrain: every slot emptied (parked); ``focus`` brings its tiles in."""
        if tiles.tile_samples > self.samples or not math.isclose(tiles.cell_size, self.cell_size):
            raise ValueError(f"the terrain's tiles hold {tiles.tile_samples} samples a side at "
                             f"{tiles.cell_size} m; these slots {self.samples} at {self.cell_size} m")
        for _, (_, halves, _) in tiles.boxes.items():
            if len(halves) > self.max_boxes:
                raise ValueError(f"a tile has {len(halves)} boxes; these slots hold {self.max_boxes}")
        if not self.field:
            kinds = tiles.kinds
            fielded = (kinds == SLOPE) | (kinds == ROUGH)
            fielded |= (kinds == STAIRS) & ~np.isin(np.arange(kinds.size).reshape(kinds.shape),
                                                    [p * kinds.shape[1] + q for p, q in tiles.boxes])
            if fielded.any():
                raise ValueError("the terrain has slope or rough tiles; these slots hold no height field")
        if self.slots == 0 and (tiles.kinds != FLAT).any():
            raise ValueError("the terrain has tiles that are not flat; this model holds no slots for them")
        self.tiles = tiles
        self._fields = {}
        self._slot_tile = [None] * self.slots
        self._known = None
        self._park_empty(model, (0.0, 0.0))

    def focus(self, model: mujoco.MjModel, xy) -> bool:
        """Bring every non-flat tile within ``FOCUS_RADIUS`` of ``xy`` into a slot (those already in one stay
        where they are); True if a slot was written. Slots that hold nothing wait under ``xy``."""
        if not self.slots:
            return False
        x, y = float(xy[0]), float(xy[1])
        tiles = self.tiles
        c, (x0, y0), r = tiles.cell_size, tiles.origin, FOCUS_RADIUS
        # the span around xy in sample units, as ``tiles_near`` computes it: while each end stays between the
        # same two tile edges, the tiles near are the ones found last time (a few comparisons a step)
        span = ((x - r - x0) / c, (x + r - x0) / c, (y - r - y0) / c, (y + r - y0) / c)
        known = self._known
        if (known is not None and known[0] < span[0] <= known[1] and known[2] <= span[1] < known[3]
                and known[4] < span[2] <= known[5] and known[6] <= span[3] < known[7]):
            empty = self._empty_at
            if empty is not None and abs(empty[0] - x) + abs(empty[1] - y) > REPARK_DISTANCE:
                self._park_empty(model, xy)
                return True
            return False
        self._known = (*_bucket(tiles.col_edges, span[0], "left"), *_bucket(tiles.col_edges, span[1], "right"),
                       *_bucket(tiles.row_edges, span[2], "left"), *_bucket(tiles.row_edges, span[3], "right"))
        needed = tiles.tiles_near(xy, r)
        held = self._slot_tile
        missing = [tile for tile in needed if tile not in held]
        if not missing:
            return False
        # a slot is free if it holds nothing or a tile out of reach (the empty ones first)
        free = sorted((s for s in range(self.slots) if held[s] is None or held[s] not in needed),
                      key=lambda s: held[s] is not None)
        if len(free) < len(missing):
            raise RuntimeError(f"{len(needed)} tiles near {tuple(xy)}; the model holds {self.slots} slots")
        for tile, s in zip(missing, free):
            self._place(model, s, tile)
        self._park_empty(model, xy)
        return True

    def held(self) -> list[tuple[int, int] | None]:
        """The tile each slot holds (None: empty)."""
        return list(self._slot_tile)

    def _park_empty(self, model: mujoco.MjModel, xy) -> None:
        empty = [s for s in range(self.slots) if self._slot_tile[s] is None]
        for s in empty:
            self._park(model, s, xy)
        self._empty_at = (float(xy[0]), float(xy[1])) if empty else None

    def _park(self, model: mujoco.MjModel, s: int, xy) -> None:
        """Slot ``s`` empty, its body at ``xy``: every geom shrunk and sunk ``PARK_DEPTH``."""
        model.body_pos[self._ids["bodies"][s]] = (float(xy[0]), float(xy[1]), 0.0)
        self._park_boxes(model, s, 0)
        self._park_field(model, s)
        self._refit(model, s)

    def _park_boxes(self, model: mujoco.MjModel, s: int, first: int) -> None:
        geoms = self._ids["boxes"][s][first:]
        model.geom_pos[geoms] = (0.0, 0.0, -PARK_DEPTH)
        model.geom_quat[geoms] = (1.0, 0.0, 0.0, 0.0)
        model.geom_size[geoms] = _PARKED_HALF
        model.geom_aabb[geoms, :3] = 0.0
        model.geom_aabb[geoms, 3:] = _PARKED_HALF
        model.geom_rbound[geoms] = np.linalg.norm(_PARKED_HALF)

    def _park_field(self, model: mujoco.MjModel, s: int) -> None:
        if not self.field:
            return
        # shrunk to a few centimetres: a parked height field of the tile's size would still pass MuJoCo's
        # bounding-sphere test against every geom near it (measured: 25% of a step on the ground)
        self._write_field(model, s, _PARKED_TOP, -PARK_DEPTH, _PARKED_HALF[0])

    def _write_field(self, model: mujoco.MjModel, s: int, top: float, z: float, half: float | None = None) -> None:
        ids = self._ids
        half = self._half if half is None else half
        f, geom = int(ids["fields"][s]), ids["field_geoms"][s]
        model.hfield_size[f] = (half, half, top, HFIELD_BASE)
        model.geom_pos[geom] = (0.0, 0.0, z)
        model.geom_aabb[geom] = (0.0, 0.0, 0.5 * (top - HFIELD_BASE), half, half, 0.5 * (top + HFIELD_BASE))
        model.geom_rbound[geom] = math.sqrt(2 * half * half + max(top, HFIELD_BASE) ** 2)

    def _place(self, model: mujoco.MjModel, s: int, tile: tuple[int, int]) -> None:
        tiles, ids = self.tiles, self._ids
        x0, x1, y0, y1 = tiles.tile_bounds(*tile)
        centre = (x0 + self._half, y0 + self._half)    # the slot height field's centre, from the tile's first sample
        model.body_pos[ids["bodies"][s]] = (centre[0], centre[1], 0.0)
        self._slot_tile[s] = tile
        if int(tiles.kinds[tile]) == STAIRS and tile in tiles.boxes:
            centres, halves, quat = tiles.boxes[tile]
            k = len(centres)
            geoms = ids["boxes"][s][:k]
            model.geom_pos[geoms] = centres - (centre[0], centre[1], 0.0)
            model.geom_quat[geoms] = quat
            model.geom_size[geoms] = halves
            model.geom_aabb[geoms, :3] = 0.0
            model.geom_aabb[geoms, 3:] = halves
            model.geom_rbound[geoms] = np.linalg.norm(halves, axis=1)
            self._park_boxes(model, s, k)
            self._park_field(model, s)
        else:    # a slope or rough tile (or stairs drawn without a shape): its samples as a height field
            data, top = self._field_data(tile)
            adr = int(ids["field_adr"][s])
            model.hfield_data[adr:adr + data.size] = data
            self._write_field(model, s, top + BURY_DEPTH, -BURY_DEPTH)
            self._park_boxes(model, s, 0)
            self.dirty.add(int(ids["fields"][s]))
        self._refit(model, s)

    def _refit(self, model: mujoco.MjModel, s: int) -> None:
        """Slot ``s``'s bounding-volume hierarchy (in its body frame) refitted to its geoms: each leaf the
        axis-aligned box around its geom, each inner node the box around its children."""
        adr, num = self._ids["bvh"][s]
        aabb, child, nodeid = model.bvh_aabb, model.bvh_child, model.bvh_nodeid
        low, high = np.empty((num, 3)), np.empty((num, 3))
        for k in range(num - 1, -1, -1):
            node = adr + k
            g = int(nodeid[node])
            if g >= 0:
                rot = np.empty(9)
                mujoco.mju_quat2Mat(rot, model.geom_quat[g])
                centre = model.geom_pos[g] + rot.reshape(3, 3) @ model.geom_aabb[g, :3]
                half = np.abs(rot.reshape(3, 3)) @ model.geom_aabb[g, 3:]
                low[k], high[k] = centre - half, centre + half
            else:
                a, b = int(child[node, 0]), int(child[node, 1])    # (indices within the body's tree)
                low[k], high[k] = np.minimum(low[a], low[b]), np.maximum(high[a], high[b])
            aabb[node, :3] = 0.5 * (low[k] + high[k])
            aabb[node, 3:] = 0.5 * (high[k] - low[k])

    def _field_data(self, tile: tuple[int, int]) -> tuple[np.ndarray, float]:
        """A tile's height-field samples, normalised as MuJoCo keeps them (its flat samples sunk
        ``BURY_DEPTH`` below the plane), and its top (m); made once per episode and tile."""
        cached = self._fields.get(tile)
        if cached is None:
            window = self.tiles.tile_window(*tile)
            top = max(float(window.max()), 1e-3)
            sunk = np.where(buried_flat(window), -BURY_DEPTH, window)
            data = ((sunk + BURY_DEPTH) / (top + BURY_DEPTH)).astype(np.float32).ravel()
            cached = self._fields[tile] = (data, top)
        return cached


class TerrainView:
    """The whole terrain as one height field that is drawn but touches nothing (contype = conaffinity = 0),
    so that a film shows the tiles far from the character too; 2 mm below the collision geometry, which
    draws over it where it is held."""

    def __init__(self, spec: mujoco.MjSpec, rows: int, cols: int, cell_size: float, name: str = "terrain_view",
                 max_height: float = 2.0, material: str | None = None) -> None:
        self.rows, self.cols, self.cell_size, self.name = int(rows), int(cols), float(cell_size), name
        self.max_height = float(max_height)
        spec.add_hfield(name=name, nrow=self.rows, ncol=self.cols,
                        size=[0.5 * (self.cols - 1) * cell_size, 0.5 * (self.rows - 1) * cell_size,
                              self.max_height, 0.05],
                        userdata=np.zeros(self.rows * self.cols).tolist())
        body = spec.worldbody.add_body(name=name, pos=[0.0, 0.0, -0.002])
        look = {"material": material} if material else {"rgba": list(TERRAIN_RGBA)}
        body.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_HFIELD, hfieldname=name, contype=0, conaffinity=0,
                      **look)
        self._adr = None

    def bind(self, model: mujoco.MjModel) -> None:
        hfield = model.hfield(self.name)
        self.hfield_id, self._adr = int(hfield.id), int(hfield.adr[0])
        self._body = model.body(self.name).id

    def write(self, model: mujoco.MjModel, heights: np.ndarray, origin: tuple[float, float]) -> None:
        """Draw ``heights`` (rows x cols; sample (0, 0) at ``origin``)."""
        if heights.shape != (self.rows, self.cols):
            raise ValueError(f"heights must have shape {(self.rows, self.cols)}, got {heights.shape}")
        n = self.rows * self.cols
        model.hfield_data[self._adr:self._adr + n] = np.clip(heights / self.max_height, 0.0, 1.0).ravel()
        model.body_pos[self._body, :2] = (origin[0] + 0.5 * (self.cols - 1) * self.cell_size,
                                         origin[1] + 0.5 * (self.rows - 1) * self.cell_size)
