"""stairenv: physics-based humanoid scene navigation for MuJoCo and Gymnasium.

``import stairenv`` registers one env per preset in ``envs/`` (their ids: ``ENV_IDS``):

- InterLevel / InterScene stairs: ``InterLevel-v0``, ``InterLevel2D-v0``, ``InterSceneStairs-v0``;
- PlaMo: ``PlaMo-v0``, ``PlaMoNaivePaths-v0``, ``PlaMoScene-v0``;
- SIMS: ``SIMS-Walk-v0``, ``SIMS-Sit-v0``, ``SIMS-Lie-v0``, ``SIMS-Reach-v0``, ``SIMS-GetUp-v0``.
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
