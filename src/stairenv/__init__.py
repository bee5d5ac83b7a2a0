"""stairenv: physics-based humanoid scene navigation for MuJoCo and Gymnasium.

``import stairenv`` registers the envs whose presets are in ``envs/``:
``InterLevel-v0``, ``InterLevel2D-v0`` and ``InterSceneStairs-v0``.
"""

from stairenv.registration import register_all

__version__ = "0.1.0"

ENV_IDS: tuple[str, ...] = tuple(register_all())

__all__ = ["ENV_IDS", "__version__"]
