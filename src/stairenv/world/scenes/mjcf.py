"""The MuJoCo model of a scene: ``add_scene_to_spec`` (a height field, box geoms, mocap balls,
landmark markers) and ``SceneHandles``, which moves the balls over time."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

from stairenv.rotations import yaw_to_quat_wxyz
from stairenv.world.scenes.model import TERRAIN_KINDS, Scene
from stairenv.world.scenes.shapes import Box
from stairenv.world.tiles import FOCUS_RADIUS, TerrainSlots, TerrainTiles, TerrainView, slot_contents


# --- MuJoCo --------------------------------------------------------------------------------------
# Depth of the height field's solid base below the scene's lowest point (MuJoCo size[3], m).
HFIELD_BASE_DEPTH = 0.5
# Ground planes already in the spec are lowered this far below the scene's lowest point, so
# that they neither poke through the height field nor render in the same place.
GROUND_PLANE_DROP = 0.01

GROUND_RGB = ((0.42, 0.47, 0.40), (0.36, 0.41, 0.35))
WALL_RGBA = (0.66, 0.62, 0.56, 1.0)
CEILING_RGBA = (0.55, 0.42, 0.30, 1.0)
BALL_RGBA = (0.15, 0.75, 0.25, 1.0)
LANDMARK_RGBA: tuple[tuple[float, float, float, float], ...] = (
    (0.90, 0.20, 0.20, 1.0), (0.20, 0.45, 0.90, 1.0), (0.95, 0.75, 0.10, 1.0), (0.65, 0.25, 0.80, 1.0),
    (0.10, 0.75, 0.75, 1.0), (0.95, 0.50, 0.15, 1.0), (0.55, 0.55, 0.55, 1.0), (0.90, 0.40, 0.70, 1.0),
)
LANDMARK_POST_RADIUS = 0.04
LANDMARK_DISC_HALF_HEIGHT = 0.005


@dataclass(eq=False)
class SceneHandles:
    """What ``add_scene_to_spec`` added (names), and their ids once bound to a compiled model.

    Call ``bind(model)`` after compiling (``update`` binds on first use): it writes the
    height field's elevation into ``model.hfield_data`` (the spec carries it too, so a
    fresh compile already has it; a renderer created before ``bind`` needs
    ``mujoco.mjr_uploadHField``) and looks up the ids. Call
    ``update(model, data, t)`` with t = ``data.time`` before each step to move the
    dynamic obstacles' mocap bodies to ``motion.position(t)``.

    Built with ``tiles=True`` the terrain is the scene's tiles instead (``terrain_slots``, a
    ``stairenv.world.tiles.TerrainSlots``; ``hfield_name`` and ``terrain_geom_name`` are empty,
    ``terrain_view`` the drawn height field or None): ``bind`` gives the slots the scene's
    terrain, and ``focus(model, xy)`` brings the tiles near the character's root into them.
    """

    scene: Scene
    prefix: str
    hfield_name: str
    terrain_geom_name: str
    wall_geom_names: tuple[str, ...]
    ceiling_geom_names: tuple[str, ...]
    obstacle_body_names: tuple[str, ...]
    obstacle_geom_names: tuple[str, ...]
    landmark_geom_names: dict[str, tuple[str, ...]]
    elevation: np.ndarray  # (nrow * ncol,) float32 in [0, 1], MuJoCo's row-major order
    terrain_slots: TerrainSlots | None = None
    terrain_view: TerrainView | None = None
    terrain_geom_id: int = -1
    wall_geom_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    ceiling_geom_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    obstacle_geom_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    obstacle_mocap_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    _bound_to: Any = field(default=None, repr=False)

    def bind(self, model: mujoco.MjModel) -> None:
        """Write the elevation data (or the tiles) into ``model`` and look up the ids of the scene's parts."""
        if self.terrain_slots is not None:
            self.terrain_slots.bind(model)
            self.terrain_slots.set_terrain(model, scene_tiles(self.scene))
            if self.terrain_view is not None:
                self.terrain_view.bind(model)
                self.terrain_view.write(model, self.scene.heights, self.terrain_slots.tiles.origin)
        else:
            hfield = model.hfield(self.hfield_name)
            count = int(hfield.nrow[0]) * int(hfield.ncol[0])
            if count != self.elevation.size:
                raise ValueError(f"height field {self.hfield_name!r} holds {count} samples, the scene "
                                 f"{self.elevation.size}: was the model compiled from another scene?")
            start = int(model.hfield_adr[hfield.id])
            model.hfield_data[start:start + count] = self.elevation
            self.terrain_geom_id = model.geom(self.terrain_geom_name).id
        self.wall_geom_ids = np.array([model.geom(n).id for n in self.wall_geom_names], dtype=np.int64)
        self.ceiling_geom_ids = np.array([model.geom(n).id for n in self.ceiling_geom_names], dtype=np.int64)
        self.obstacle_geom_ids = np.array([model.geom(n).id for n in self.obstacle_geom_names], dtype=np.int64)
        bodies = [model.body(n).id for n in self.obstacle_body_names]
        self.obstacle_mocap_ids = np.array([model.body_mocapid[b] for b in bodies], dtype=np.int64)
        self._bound_to = model

    def focus(self, model: mujoco.MjModel, xy) -> None:
        """The terrain's tiles within reach of ``xy`` (the character's root) in the model (tiles only)."""
        if self.terrain_slots is not None:
            if self._bound_to is not model:
                self.bind(model)
            self.terrain_slots.focus(model, xy)

    def obstacle_positions(self, t: float) -> np.ndarray:
        """(K, 3) world centres of the dynamic obstacles at time ``t`` (s)."""
        return self.scene.dynamic_positions(t)

    def update(self, model: mujoco.MjModel, data: mujoco.MjData, t: float) -> None:
        """Move the dynamic obstacles' mocap bodies to their positions at time ``t`` (s)."""
        if self._bound_to is not model:
            self.bind(model)
        if len(self.obstacle_mocap_ids):
            data.mocap_pos[self.obstacle_mocap_ids] = self.obstacle_positions(t)


def _material(spec: mujoco.MjSpec, name: str, rgba: Sequence[float]) -> str:
    spec.add_material(name=name, rgba=list(rgba))
    return name


def _flat_tiles(scene: Scene) -> TerrainTiles:
    """A scene of flat ground (all heights 0) as one flat tile."""
    rows, cols = scene.shape
    c = scene.cell_size
    return TerrainTiles(scene.heights, (scene.origin[0] + 0.5 * c, scene.origin[1] + 0.5 * c), c,
                        np.array([0, rows]), np.array([0, cols]), np.zeros((1, 1), dtype=np.uint8), outside="edge")


def scene_tiles(scene: Scene) -> TerrainTiles | None:
    """The scene's terrain as tiles, if it can be held so: its own (a generated scene's) on ground no lower
    than the plane at 0, or flat ground at 0 (the slalom); else None (one height field holds it)."""
    if scene.tiles is not None and float(scene.heights.min()) == 0.0:
        return scene.tiles
    if not scene.heights.any():
        return _flat_tiles(scene)
    return None


def add_scene_to_spec(spec: mujoco.MjSpec, scene: Scene, *, prefix: str = "scene",
                      lower_ground_planes: bool = True, tiles: bool = False, view: bool = True) -> SceneHandles:
    """Add ``scene`` to ``spec`` (e.g. ``load_humanoid_spec()``); compile, then ``handles.bind(model)``.

    - Ground: a height field on its own static body. Its samples are the scene's cell
      centres plus a one-cell rim that repeats the border values, so it covers the grid
      exactly and half a cell beyond: ``nrow = H + 2`` (along y, data row 0 at the lowest
      y), ``ncol = W + 2`` (along x), ``size = ((W + 1) c / 2, (H + 1) c / 2, h_max - h_min,
      HFIELD_BASE_DEPTH)``, body at the grid's centre at z = h_min, elevation normalised to
      [0, 1]. (With h_min = 0, as in generated scenes, size[2] is the highest point.)
    - Walls and ceilings: one box geom per static body (``{prefix}_wall{k}``,
      ``{prefix}_ceiling{k}``).
    - Dynamic obstacles: a mocap body with a sphere geom each (``{prefix}_obstacle{k}``),
      placed at ``position(0)``; they collide with the character.
    - Landmarks: visual-only markers (contype = conaffinity = 0, group 2): a disc over the
      landmark's area, a post up to ``display_position`` and a ball on top.
    - ``lower_ground_planes``: plane geoms of the world body (the humanoid's floor) are
      moved to ``GROUND_PLANE_DROP`` below the scene's lowest point: they keep catching
      whatever leaves the scene without touching or hiding the height field.
    - ``tiles``: where the scene can be held as tiles (``scene_tiles``: a generated scene, or
      flat ground), the ground instead is the plane at 0 (not lowered) and the tiles near the
      character in ``TerrainSlots`` (``stairenv.world.tiles``: stairs as boxes, a slope or
      rough patch as a height field of its own); with ``view`` the whole terrain is drawn as a
      height field that touches nothing. ``SceneHandles.focus`` keeps the slots filled.
    """
    rows, cols = scene.shape
    c = scene.cell_size
    padded = np.pad(scene.heights, 1, mode="edge")
    low, high = float(padded.min()), float(padded.max())
    span = high - low
    elevation = ((padded - low) / span if span > 0.0 else np.zeros_like(padded)).astype(np.float32).ravel()
    x_min, x_max, y_min, y_max = scene.bounds

    ground_texture = f"{prefix}_ground"
    spec.add_texture(name=ground_texture, type=mujoco.mjtTexture.mjTEXTURE_2D,
                     builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER, rgb1=list(GROUND_RGB[0]),
                     rgb2=list(GROUND_RGB[1]), width=256, height=256)
    ground_material = spec.add_material(name=f"{prefix}_ground", texrepeat=[1.0, 1.0], texuniform=True)
    ground_material.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = ground_texture
    wall_material = _material(spec, f"{prefix}_wall", WALL_RGBA)
    ceiling_material = _material(spec, f"{prefix}_ceiling", CEILING_RGBA)
    ball_material = _material(spec, f"{prefix}_ball", BALL_RGBA)

    tiled = scene_tiles(scene) if tiles else None
    terrain_slots = terrain_view = None
    hfield_name = terrain_geom_name = ""
    if tiled is not None:
        present = {TERRAIN_KINDS[k] for k in np.unique(tiled.kinds)}
        boxes, field = slot_contents(present)
        max_boxes = max((len(h) for _, h, _ in tiled.boxes.values()), default=0) if boxes else 0
        terrain_slots = TerrainSlots(spec, tiled.tile_samples, c, max_boxes,
                                     min(tiled.max_tiles_near(FOCUS_RADIUS), tiled.kinds.size), field,
                                     prefix=f"{prefix}_tile", material=f"{prefix}_ground")
        if view:
            terrain_view = TerrainView(spec, rows, cols, c, name=f"{prefix}_view",
                                       max_height=max(float(scene.heights.max()), 1e-3), material=f"{prefix}_ground")
        for geom in spec.worldbody.geoms:    # the flat ground is the plane: drawn as the scene's ground
            if geom.type == mujoco.mjtGeom.mjGEOM_PLANE:
                geom.material = f"{prefix}_ground"
    else:
        hfield_name = terrain_geom_name = f"{prefix}_terrain"
        hfield = spec.add_hfield(name=hfield_name, nrow=rows + 2, ncol=cols + 2,
                                 size=[0.5 * (cols + 1) * c, 0.5 * (rows + 1) * c, span if span > 0.0 else 1e-3,
                                       HFIELD_BASE_DEPTH])
        # MuJoCo needs the data at compile time too (it normalises it again: a no-op here).
        hfield.userdata = elevation.astype(np.float64).tolist()
        terrain = spec.worldbody.add_body(name=f"{prefix}_terrain",
                                          pos=[0.5 * (x_min + x_max), 0.5 * (y_min + y_max), low])
        terrain.add_geom(name=f"{prefix}_terrain", type=mujoco.mjtGeom.mjGEOM_HFIELD, hfieldname=hfield_name,
                         material=f"{prefix}_ground", condim=3)

        if lower_ground_planes:
            for geom in spec.worldbody.geoms:
                if geom.type == mujoco.mjtGeom.mjGEOM_PLANE:
                    geom.pos = [geom.pos[0], geom.pos[1], min(float(geom.pos[2]), low - GROUND_PLANE_DROP)]

    def add_boxes(boxes: list[Box], kind: str, material: str) -> tuple[str, ...]:
        names = []
        for k, box in enumerate(boxes):
            name = f"{prefix}_{kind}{k}"
            body = spec.worldbody.add_body(name=name, pos=box.center_xyz.tolist(), quat=yaw_to_quat_wxyz(box.yaw).tolist())
            body.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_BOX, size=box.half_extents_xyz.tolist(),
                          material=material, condim=3)
            names.append(name)
        return tuple(names)

    wall_names = add_boxes(scene.walls, "wall", wall_material)
    ceiling_names = add_boxes(scene.ceilings, "ceiling", ceiling_material)

    obstacle_names = []
    for k, obstacle in enumerate(scene.dynamic_obstacles):
        name = f"{prefix}_obstacle{k}"
        body = spec.worldbody.add_body(name=name, mocap=True, pos=obstacle.position(0.0).tolist())
        body.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[obstacle.radius, 0.0, 0.0],
                      material=ball_material, condim=3)
        obstacle_names.append(name)

    landmark_geoms: dict[str, tuple[str, ...]] = {}
    for k, landmark in enumerate(scene.landmarks):
        rgba = LANDMARK_RGBA[k % len(LANDMARK_RGBA)]
        material = _material(spec, f"{prefix}_landmark{k}", rgba)
        x, y = landmark.center
        ground = float(scene.height_at(np.array(landmark.center)))
        top = max(landmark.display_position[2], ground + 0.05)
        disc_rgba = [rgba[0], rgba[1], rgba[2], 0.35]
        parts = (
            (f"{prefix}_landmark{k}_area", [x, y, ground + LANDMARK_DISC_HALF_HEIGHT + 0.001],
             {"type": mujoco.mjtGeom.mjGEOM_CYLINDER,
              "size": [max(landmark.radius, 0.05), LANDMARK_DISC_HALF_HEIGHT, 0.0], "rgba": disc_rgba}),
            (f"{prefix}_landmark{k}_post", [x, y, 0.5 * (ground + top)],
             {"type": mujoco.mjtGeom.mjGEOM_CYLINDER, "size": [LANDMARK_POST_RADIUS, 0.5 * (top - ground), 0.0],
              "material": material}),
            (f"{prefix}_landmark{k}_top", [x, y, top],
             {"type": mujoco.mjtGeom.mjGEOM_SPHERE, "size": [0.1, 0.0, 0.0], "material": material}),
        )
        for name, pos, geom in parts:
            body = spec.worldbody.add_body(name=name, pos=pos)
            body.add_geom(name=name, contype=0, conaffinity=0, group=2, **geom)
        landmark_geoms[landmark.name] = tuple(name for name, _, _ in parts)

    return SceneHandles(
        scene=scene, prefix=prefix, hfield_name=hfield_name, terrain_geom_name=terrain_geom_name,
        wall_geom_names=wall_names, ceiling_geom_names=ceiling_names,
        obstacle_body_names=tuple(obstacle_names), obstacle_geom_names=tuple(obstacle_names),
        landmark_geom_names=landmark_geoms, elevation=elevation, terrain_slots=terrain_slots,
        terrain_view=terrain_view,
    )
