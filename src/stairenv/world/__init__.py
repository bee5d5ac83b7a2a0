"""The world: terrain and scene generators (pure functions of parameters and an rng)
and the code that writes their output into MuJoCo models."""
