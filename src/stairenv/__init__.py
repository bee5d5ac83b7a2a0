"""stairenv: physics-based humanoid scene navigation for MuJoCo and Gymnasium.

``import stairenv`` registers the envs whose presets are in ``envs/``:
``InterLevel-v0``, ``InterLevel2D-v0`` and ``InterSceneStairs-v0``.
"""

import os as _os
import sys as _sys

# MuJoCo picks its OpenGL backend when first imported: on a Linux machine with no
# display, default to headless EGL unless the user chose a backend.
if _sys.platform.startswith("linux") and not _os.environ.get("DISPLAY"):
    _os.environ.setdefault("MUJOCO_GL", "egl")

from stairenv.registration import register_all  # noqa: E402

__version__ = "0.1.0"

ENV_IDS: tuple[str, ...] = tuple(register_all())

__all__ = ["ENV_IDS", "__version__"]
