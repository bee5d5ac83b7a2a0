"""Tasks: observation, reward and termination as pure array functions.

Every function takes arrays with a leading batch dimension (B, ...) and returns
arrays with the same leading dimension, so that a single-world env (B = 1), a
natively batched vector env, or a JAX port can all call the same code. SIMS' and PlaMo's envs
batch their worlds with the same bits as one world alone (``sims.skill_step``, world by world, and its
specification ``sims.skill_observations``, ``sims.skill_reward_values``; ``plamo.write_terrain_heightmap``,
``plamo.write_path_observation``, ``plamo.path_reward_values``).
Each task holds its reward weights in one frozen dataclass; ``terms`` has the named-term helpers.
"""
