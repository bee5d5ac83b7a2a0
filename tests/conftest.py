import os

# Offscreen rendering in tests (must be set before mujoco is imported).
os.environ.setdefault("MUJOCO_GL", "egl")
