"""PlaMo scenes: terrain, walls, low ceilings, moving obstacles and named landmarks.

A scene (PlaMo, Sec. 3) is

1. a terrain height map ``h(x, y)``,
2. static obstacles (walls) the character must go around,
3. dynamic obstacles whose motion the planner can predict,
4. top obstacles (low ceilings) the character must crouch or crawl under,
5. named landmarks ("tree", "swing", ...), each a set of grid cells.

Frames and units
----------------
World frame: z up, lengths in metres, angles in radians (unless a name ends in
``_deg``), time in seconds. The height map is sampled at the centres of the cells of
the grid that ``stairenv.planning.grid.PlanningGrid`` uses: cell (i, j) covers
x in [x0 + j c, x0 + (j + 1) c) and y in [y0 + i c, y0 + (i + 1) c), with
c = ``cell_size`` and (x0, y0) = ``origin``; **rows are y, columns are x**, and
``heights[i, j]`` is the ground height (world z) at the cell's centre. Between
centres the ground is interpolated (``Scene.height_at``: bilinear; MuJoCo's height
field: two planar triangles per square, equal at the centres and on planar ground).

Boxes (walls, ceilings) have vertical sides: a footprint rectangle centred at
``center`` with half extents ``half_size`` along its own axes u, v, where u is the
world x axis turned by ``yaw`` counter-clockwise about +z, and a z span
[``bottom``, ``top``]. A ceiling's ``bottom`` is the underside, in world z: the
planner compares it with the ground height and the head height of a locomotion.

What lives where (one module per job)
-------------------------------------
- ``shapes``: ``Box`` (walls, ceilings, pillars) and the checks the parts share.
- ``obstacles``: ``DynamicObstacle`` and its ``MotionModel`` (``ConstantVelocity``,
  ``Loop``, ``WaypointLoop``).
- ``model``: ``Scene`` and ``Landmark``; ``Scene.planning_grid`` rasterises a scene for the
  planner; ``Scene.save`` / ``Scene.load`` store it as one ``.npz`` file (size limits
  ``MAX_SCENE_*``).
- ``patches``: terrain patch generators, pure functions of (config, rng): ``flat_patch``,
  ``slope_patch``, ``rough_patch``, ``stairs_patch`` (``generate_patch`` dispatches).
- ``reachability``: ``connected_free_space``, the regions a character can move between.
- ``generation``: ``generate_scene(config, rng)``: PlaMo's random 4-landmark scenes (Sec. 5.4).
- ``slalom``: ``slalom_scene(...)``: the slalom test of Sec. 5.3 / Fig. 8.
- ``mjcf``: ``add_scene_to_spec(spec, scene)``: the MuJoCo model of a scene (a height field,
  one box geom per static body, mocap spheres for the dynamic obstacles, visual-only
  landmark markers); ``SceneHandles.update`` moves the obstacles over time.

Everything is importable from ``stairenv.world.scenes`` itself.
"""

from stairenv.world.scenes.generation import SceneConfig, generate_scene, scene_patch_edges
from stairenv.world.scenes.mjcf import (
    BALL_RGBA,
    CEILING_RGBA,
    GROUND_PLANE_DROP,
    GROUND_RGB,
    HFIELD_BASE_DEPTH,
    LANDMARK_DISC_HALF_HEIGHT,
    LANDMARK_POST_RADIUS,
    LANDMARK_RGBA,
    WALL_RGBA,
    SceneHandles,
    add_scene_to_spec,
)
from stairenv.world.scenes.model import (
    DEFAULT_LANDMARK_NAMES,
    LANDMARK_MARKER_HEIGHT,
    MAX_SCENE_CELLS,
    MAX_SCENE_HEIGHT,
    MAX_SCENE_JSON_BYTES,
    SCENE_FILE_FORMAT,
    SCENE_FILE_VERSION,
    TERRAIN_KINDS,
    Landmark,
    Scene,
    SceneFileError,
)
from stairenv.world.scenes.obstacles import (
    MOTION_MODELS,
    ConstantVelocity,
    DynamicObstacle,
    Loop,
    MotionModel,
    WaypointLoop,
)
from stairenv.world.scenes.patches import (
    FlatPatchConfig,
    PatchConfig,
    RoughPatchConfig,
    SlopePatchConfig,
    StairsPatchConfig,
    flat_patch,
    generate_patch,
    rough_patch,
    slope_patch,
    stairs_patch,
)
from stairenv.world.scenes.reachability import connected_free_space
from stairenv.world.scenes.shapes import Box
from stairenv.world.scenes.slalom import slalom_scene

__all__ = [
    "BALL_RGBA", "CEILING_RGBA", "DEFAULT_LANDMARK_NAMES", "GROUND_PLANE_DROP", "GROUND_RGB", "HFIELD_BASE_DEPTH",
    "LANDMARK_DISC_HALF_HEIGHT", "LANDMARK_MARKER_HEIGHT", "LANDMARK_POST_RADIUS", "LANDMARK_RGBA",
    "MAX_SCENE_CELLS", "MAX_SCENE_HEIGHT", "MAX_SCENE_JSON_BYTES", "MOTION_MODELS", "SCENE_FILE_FORMAT",
    "SCENE_FILE_VERSION", "TERRAIN_KINDS", "WALL_RGBA", "Box", "ConstantVelocity", "DynamicObstacle",
    "FlatPatchConfig", "Landmark", "Loop", "MotionModel", "PatchConfig", "RoughPatchConfig", "Scene",
    "SceneConfig", "SceneFileError", "SceneHandles", "SlopePatchConfig", "StairsPatchConfig", "WaypointLoop",
    "add_scene_to_spec", "connected_free_space", "flat_patch", "generate_patch", "generate_scene",
    "rough_patch", "scene_patch_edges", "slalom_scene", "slope_patch", "stairs_patch",
]
