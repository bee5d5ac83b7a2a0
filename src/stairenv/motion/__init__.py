"""Reference motion: our clip format, the motion library, importers and synthesis."""

from stairenv.motion.clip import MotionClip, MotionFileError, humanoid_model
from stairenv.motion.library import MotionLibrary

__all__ = ["MotionClip", "MotionFileError", "MotionLibrary", "humanoid_model"]
