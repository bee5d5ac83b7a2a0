"""Rendering: an offscreen renderer with a camera that follows the character.

``render_mode="rgb_array"`` needs an OpenGL backend; on Linux without a display
``import stairenv`` defaults ``MUJOCO_GL`` to ``egl`` (set it to ``osmesa`` before
importing if EGL is missing). ``"human"`` opens MuJoCo's passive
viewer and needs a display.
"""

from __future__ import annotations

import mujoco
import numpy as np

RENDER_MODES = ("human", "rgb_array")


class FollowCamera:
    """Offscreen frames from a camera tracking one body, with optional line overlays."""

    def __init__(
        self,
        model: mujoco.MjModel,
        body_id: int,
        width: int = 640,
        height: int = 480,
        distance: float = 4.5,
        elevation: float = -18.0,
    ) -> None:
        if width > model.vis.global_.offwidth or height > model.vis.global_.offheight:
            raise ValueError(
                f"render size {width}x{height} exceeds the model's offscreen buffer "
                f"{model.vis.global_.offwidth}x{model.vis.global_.offheight}"
            )
        self.renderer = mujoco.Renderer(model, height=height, width=width)
        self.camera = mujoco.MjvCamera()
        self.camera.type = mujoco.mjtCamera.mjCAMERA_TRACKING
        self.camera.trackbodyid = body_id
        self.camera.distance = distance
        self.camera.elevation = elevation
        self.camera.azimuth = 135.0

    def render(self, data: mujoco.MjData, lines: tuple[tuple[np.ndarray, np.ndarray, tuple], ...] = ()) -> np.ndarray:
        """An (H, W, 3) uint8 frame; ``lines`` are (from, to, rgba) segments drawn on top."""
        self.renderer.update_scene(data, camera=self.camera)
        scene = self.renderer.scene
        for start, end, rgba in lines:
            if scene.ngeom >= scene.maxgeom:
                break
            geom = scene.geoms[scene.ngeom]
            mujoco.mjv_initGeom(geom, mujoco.mjtGeom.mjGEOM_LINE, np.zeros(3), np.zeros(3), np.zeros(9),
                                np.asarray(rgba, dtype=np.float32))
            mujoco.mjv_connector(geom, mujoco.mjtGeom.mjGEOM_LINE, 4.0, np.asarray(start, float), np.asarray(end, float))
            scene.ngeom += 1
        return self.renderer.render()

    def close(self) -> None:
        self.renderer.close()


class HumanViewer:
    """MuJoCo's passive viewer window (needs a display)."""

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, body_id: int) -> None:
        import mujoco.viewer

        self.handle = mujoco.viewer.launch_passive(model, data)
        self.handle.cam.type = mujoco.mjtCamera.mjCAMERA_TRACKING
        self.handle.cam.trackbodyid = body_id
        self.handle.cam.distance = 4.5

    def sync(self) -> None:
        self.handle.sync()

    def close(self) -> None:
        self.handle.close()
