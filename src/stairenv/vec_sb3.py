"""Stable-Baselines3 ``VecEnv`` over the natively batched env (``stairenv.environments.vector``).

``SB3BatchedVecEnv(vector_env)`` or ``make_sb3_vec_env("InterLevel-v0", n_envs=64)``: SB3 PPO and
``AMPVecEnvWrapper`` use it as any ``VecEnv``. It follows SB3's conventions, not Gymnasium's: a world
whose episode ends is reset in the same step, its last observation in ``info["terminal_observation"]``,
``info["TimeLimit.truncated"]`` set when the end was a truncation (the episode limit or a physics
blow-up), rewards float32, ``dones = terminated | truncated``, ``infos`` a list of per-world dicts.
Seeds from ``seed(s)`` (world i gets ``s + i``) and options from ``set_options`` apply to the next
``reset()`` only, as in ``DummyVecEnv``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env import VecEnv

from stairenv.environments.vector import HumanoidVectorEnv


class SB3BatchedVecEnv(VecEnv):
    """A ``HumanoidVectorEnv`` as an SB3 ``VecEnv`` (see the module docstring)."""

    def __init__(self, venv: HumanoidVectorEnv) -> None:
        if not isinstance(venv, HumanoidVectorEnv):
            raise TypeError(f"SB3BatchedVecEnv wraps a HumanoidVectorEnv, got {type(venv).__name__}")
        self.venv = venv
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)
        self.metadata = {**venv.metadata, **self.metadata}
        self._actions: np.ndarray | None = None

    def reset(self):
        obs, infos = self.venv.reset_each(self._seeds, self._options)
        self.reset_infos[:] = infos
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self):
        if self._actions is None:
            raise RuntimeError("step_wait() without step_async()")
        actions, self._actions = self._actions, None
        self.venv.check_open()
        # ended worlds are reset inside the step, while the other worlds' physics runs
        obs, rewards, terminated, truncated, infos, finals = self.venv.step_worlds(actions, reset_ended=True)
        infos = [dict(info) for info in infos]
        dones = terminated | truncated
        for i in range(self.num_envs):
            infos[i]["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
        for i, (final_obs, reset_info) in finals.items():
            infos[i]["terminal_observation"] = final_obs
            self.reset_infos[i] = reset_info
        return obs, rewards.astype(np.float32), dones, infos

    def close(self) -> None:
        self.venv.close()

    def _worlds(self, indices) -> list:
        return [self.venv.envs[i] for i in self._get_indices(indices)]

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        return [getattr(env, attr_name) for env in self._worlds(indices)]

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        self.venv.set_world_attrs(attr_name, dict.fromkeys(self._get_indices(indices), value))

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list[Any]:
        return [getattr(env, method_name)(*method_args, **method_kwargs) for env in self._worlds(indices)]

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices=None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]    # the worlds are bare envs

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [env.render() for env in self.venv.envs]


def make_sb3_vec_env(env_id: str, n_envs: int, seed: int | None = None, **kwargs: Any) -> SB3BatchedVecEnv:
    """``gym.make_vec(env_id, n_envs, vectorization_mode="vector_entry_point", **kwargs)`` as an SB3 ``VecEnv``;
    ``seed`` (world i gets ``seed + i``) applies to the first ``reset()``."""
    venv = SB3BatchedVecEnv(gym.make_vec(env_id, num_envs=n_envs, vectorization_mode="vector_entry_point", **kwargs))
    if seed is not None:
        venv.seed(seed)
    return venv
