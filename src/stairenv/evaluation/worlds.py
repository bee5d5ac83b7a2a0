"""Evaluation episodes on the worlds of a batched env, side by side: one home for every evaluator.

An evaluator that runs its episodes one after another (``env.reset(seed=s)``, step until the end) can
run the same episodes on the worlds of ``gym.make_vec(env_id, num_envs=N,
vectorization_mode="vector_entry_point")``: each world takes the next episode when its last one ends
(reset with that episode's seed, as the sequential run does), the policy is called on the batch of
observations, and the physics of all worlds runs on every core (or on a device back-end). A world's
episode is the sequential one step for step wherever the policy gives each row the action it gives that
observation alone (``batch_actions``; a policy that reseeds itself per episode is run sequentially by
its evaluator).

The evaluator supplies an episode tracker per episode (``start``): ``before_step(env)`` before each
step (a push), ``update(reward, terminated, truncated, info) -> bool`` (True once the episode is over)
and ``result()``, handed to ``on_result`` as each episode ends.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, Protocol

import numpy as np


class EpisodeTracker(Protocol):
    def before_step(self, env: Any) -> None: ...

    def update(self, reward: float, terminated: bool, truncated: bool, info: dict[str, Any]) -> bool: ...

    def result(self) -> Any: ...


def batch_actions(policy: Callable[[np.ndarray], Any], obs: np.ndarray, action_shape: tuple[int, ...]) -> np.ndarray:
    """The policy's actions for a batch of observations: one call where the policy takes a batch
    (returns ``(N, *action_shape)``), else one call per row."""
    actions = np.asarray(policy(obs))
    if actions.shape == (len(obs), *action_shape):
        return actions
    return np.stack([np.asarray(policy(row)) for row in obs])


def run_on_worlds(vec: Any, policy: Callable[[np.ndarray], Any], episodes: Sequence[tuple[int, int]],
                  start: Callable[[int, int, int, dict[str, Any]], EpisodeTracker],
                  on_result: Callable[[Any], None]) -> None:
    """Run ``episodes`` ((index, seed) pairs) on the worlds of the batched env ``vec``: world k takes the
    next episode when its last one ends, reset with that episode's seed; ``start(k, index, seed, info)``
    makes the episode's tracker (``info``: the world's own reset info, as the single env gives it). Worlds
    left without an episode step on, unrecorded, until all are done."""
    n = vec.num_envs
    pending = list(episodes)
    first = pending[:n]
    del pending[:n]
    # the vector env wants one full reset before it steps; each world's own reset below gives its info
    # dict as the single env does (the vector reset's infos are stacked), at the cost of n extra resets
    obs, _ = vec.reset(seed=[seed for _, seed in first] + [None] * (n - len(first)))
    trackers: list[EpisodeTracker | None] = [None] * n
    for k, (index, seed) in enumerate(first):
        obs[k], info = vec.reset_world(k, seed=seed)
        trackers[k] = start(k, index, seed, info)
    action_shape = vec.single_action_space.shape
    while any(tracker is not None for tracker in trackers):
        for k, tracker in enumerate(trackers):
            if tracker is not None:
                tracker.before_step(vec.envs[k])
        obs, rewards, terminated, truncated, infos, _ = vec.step_worlds(batch_actions(policy, obs, action_shape))
        for k, tracker in enumerate(trackers):
            if tracker is None or not tracker.update(rewards[k], terminated[k], truncated[k], infos[k]):
                continue
            on_result(tracker.result())
            trackers[k] = None
            if pending:
                index, seed = pending.pop(0)
                obs[k], info = vec.reset_world(k, seed=seed)
                trackers[k] = start(k, index, seed, info)


def check_num_envs(num_envs: Any) -> int:
    """``num_envs``: an integer >= 1 (``ValueError`` naming it otherwise)."""
    if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
        raise ValueError(f"num_envs must be an integer >= 1, got {num_envs!r}")
    return int(num_envs)


__all__ = ["EpisodeTracker", "batch_actions", "check_num_envs", "run_on_worlds"]
