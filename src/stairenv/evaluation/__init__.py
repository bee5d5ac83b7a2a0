"""The papers' evaluations, one module each, all giving a :class:`~stairenv.evaluation.report.Report`.

| module | holds |
|---|---|
| ``report`` | :class:`Report`: result rows, the published rows merged in, table / CSV / JSON |
| ``interlevel`` | InterLevel Tables 1-3: progress, early termination, completion time on stairs |
| ``plamo`` | PlaMo Table 2 tracking errors, scene episodes, the slalom test |
| ``sims`` | SIMS Table 1 (skills) and Table 2 (scripts through the state machine) |
| ``pushes`` | robustness: one seeded kick per episode (``push_speed``), for each paper module's evaluation |
| ``policies`` | the old home of :func:`load_policy` (now :mod:`stairenv.policy_loading`), re-exported |
| ``cli`` | command-line helpers (``--env-kwarg key=value``) |

Each paper module has ``evaluate(policy, env_id, episodes, seed, env_kwargs, max_episode_steps,
progress_bar, label) -> Report``; :func:`evaluator_for` picks the one of an env's family.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable

import gymnasium as gym
from gymnasium.envs.registration import load_env_creator

from stairenv.evaluation.report import Report
from stairenv.policy_loading import load_policy

#: The evaluation module of each env family; an env belongs to the family of the
#: ``stairenv.environments`` module that defines its class (or a base class).
EVALUATORS: dict[str, str] = {
    "interlevel": "stairenv.evaluation.interlevel",
    "plamo": "stairenv.evaluation.plamo",
    "sims": "stairenv.evaluation.sims",
}
#: The family of envs outside the others (InterLevel's metrics need only its info keys).
DEFAULT_FAMILY = "interlevel"


def env_family(env_id: str) -> str:
    """The family (a key of :data:`EVALUATORS`) of a registered env id."""
    entry_point = gym.spec(env_id).entry_point
    creator = load_env_creator(entry_point) if isinstance(entry_point, str) else entry_point
    for cls in getattr(creator, "__mro__", (creator,)):
        package, _, name = getattr(cls, "__module__", "").rpartition(".")
        if package == "stairenv.environments" and name in EVALUATORS:
            return name
    return DEFAULT_FAMILY


def evaluator_for(env_id: str) -> Callable[..., Report]:
    """The ``evaluate`` function of ``env_id``'s family."""
    return importlib.import_module(EVALUATORS[env_family(env_id)]).evaluate


__all__ = ["DEFAULT_FAMILY", "EVALUATORS", "Report", "env_family", "evaluator_for", "load_policy"]
