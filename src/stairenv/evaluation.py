"""Evaluate a policy the way the InterLevel paper does (Tables 1-3).

The paper reports, over many trials on unseen staircases:

- **Progress (%)**: the mean of the highest height progress each episode reached
  (``info["progress"]``, 0 at the foot of the stairs, 1 standing on the landing);
- **ET (%)**: the share of episodes ended by early termination (a fall, ``info["fell"]``);
- **Time (s)**: the mean completion time of the successful climbs (``-`` when none).

:func:`evaluate` adds the episode count ``n``, the success rate and the share of
episodes truncated because the physics went unstable (``info["physics_unstable"]``;
counted separately, never as early termination). Results come overall and per
step height: with ``step_heights`` each height gets its own ``episodes`` episodes
(env keyword ``step_height_set=(h,)``); without, the env samples its own heights and
the episodes are also grouped into bins around the paper's test heights.

Example::

    import stairenv
    from stairenv.evaluation import evaluate

    report = evaluate("random", "InterLevel-v0", episodes=20, step_heights=(0.05, 0.10))
    print(report.format_table(compare_paper=True))
    report.to_csv("random.csv")

The published numbers are in :data:`PAPER_RESULTS`.
"""

from __future__ import annotations

import csv
import json
import math
import os
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from stairenv.world.stairs import PAPER_TEST_HEIGHTS

Policy = Callable[[np.ndarray], Any]

#: Policy specs understood by :func:`load_policy` besides a model path.
BUILTIN_POLICIES: tuple[str, ...] = ("random", "zero")

#: Group name of the results over all episodes.
OVERALL = "all"

#: Interior bin edges (m) used to group random step heights: bins centred on the
#: paper's test heights 0.05 / 0.10 / 0.15 / 0.20 m.
HEIGHT_BIN_EDGES: tuple[float, ...] = (0.075, 0.125, 0.175)

#: Published results (Shilton et al., AAAI 2025, Tables 1-3; 4096 trials each).
#: ``group`` is ``"all"`` (Table 1, heights 0.05-0.20 m) or a fixed step height;
#: ``time_s`` is None where the paper shows "-" (no successful climb).
PAPER_RESULTS: tuple[dict[str, Any], ...] = (
    # Table 1: staircases of varying heights.
    {"method": "InterScene", "env_id": "InterSceneStairs-v0", "group": OVERALL, "progress_pct": 30.1, "et_pct": 6.8, "time_s": None},
    {"method": "InterLevel-2D", "env_id": "InterLevel2D-v0", "group": OVERALL, "progress_pct": 34.8, "et_pct": 19.4, "time_s": None},
    {"method": "InterLevel", "env_id": "InterLevel-v0", "group": OVERALL, "progress_pct": 46.8, "et_pct": 24.9, "time_s": 8.49},
    # Table 2: 0.05 m steps.
    {"method": "InterScene", "env_id": "InterSceneStairs-v0", "group": 0.05, "progress_pct": 42.5, "et_pct": 10.0, "time_s": None},
    {"method": "InterLevel-2D", "env_id": "InterLevel2D-v0", "group": 0.05, "progress_pct": 59.7, "et_pct": 23.2, "time_s": None},
    {"method": "InterLevel", "env_id": "InterLevel-v0", "group": 0.05, "progress_pct": 48.8, "et_pct": 17.2, "time_s": 12.8},
    # Table 3: 0.10 m steps.
    {"method": "InterScene", "env_id": "InterSceneStairs-v0", "group": 0.10, "progress_pct": 30.4, "et_pct": 4.6, "time_s": None},
    {"method": "InterLevel-2D", "env_id": "InterLevel2D-v0", "group": 0.10, "progress_pct": 33.9, "et_pct": 7.6, "time_s": None},
    {"method": "InterLevel", "env_id": "InterLevel-v0", "group": 0.10, "progress_pct": 55.2, "et_pct": 16.4, "time_s": 12.3},
)

#: Number of trials behind every published number.
PAPER_TRIALS = 4096

#: The paper's fixed test heights (m), for ``step_heights=PAPER_STEP_HEIGHTS``.
PAPER_STEP_HEIGHTS: tuple[float, ...] = tuple(PAPER_TEST_HEIGHTS)

#: Columns of :meth:`EvaluationReport.to_rows` (and the CSV file), in order.
ROW_FIELDS: tuple[str, ...] = (
    "method", "env_id", "group", "height_min", "height_max", "n",
    "progress_pct", "et_pct", "success_pct", "time_s", "unstable_pct",
)


# --- policies -----------------------------------------------------------------
class ZeroPolicy:
    """All-zero actions: the PD targets stay at the middle of their ranges."""

    def __init__(self, action_space: gym.spaces.Box) -> None:
        self.action = np.zeros(action_space.shape, dtype=action_space.dtype)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return self.action.copy()

    def __repr__(self) -> str:
        return "ZeroPolicy()"


class RandomPolicy:
    """Uniform actions in the Box action space from a seeded generator.

    ``reset(seed)`` reseeds it; :func:`evaluate` calls it with each episode's seed,
    so an episode's actions do not depend on the episodes run before it.
    """

    def __init__(self, action_space: gym.spaces.Box, seed: int | None = 0) -> None:
        if not isinstance(action_space, gym.spaces.Box) or not (
            np.isfinite(action_space.low).all() and np.isfinite(action_space.high).all()
        ):
            raise ValueError(f"policy 'random' needs a bounded Box action space, got {action_space!r}")
        self.low, self.high, self.dtype = action_space.low, action_space.high, action_space.dtype
        self.reset(seed)

    def reset(self, seed: int | None = None) -> None:
        self.rng = np.random.default_rng(seed)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return self.rng.uniform(self.low, self.high).astype(self.dtype)

    def __repr__(self) -> str:
        return "RandomPolicy()"


class SB3Policy:
    """A Stable-Baselines3 model used as ``obs -> action`` (deterministic ``predict``),
    with the observation normalisation of a ``VecNormalize`` saved beside it, if any."""

    def __init__(self, model: Any, obs_normalizer: Any | None = None, path: str = "") -> None:
        self.model = model
        self.obs_normalizer = obs_normalizer
        self.path = path

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        if self.obs_normalizer is not None:
            obs = self.obs_normalizer.normalize_obs(np.asarray(obs, dtype=np.float32))
        action, _ = self.model.predict(obs, deterministic=True)
        return action

    def __repr__(self) -> str:
        norm = ", normalised obs" if self.obs_normalizer is not None else ""
        return f"SB3Policy({type(self.model).__name__}: {self.path}{norm})"


class _SpacesEnv(gym.Env):
    """A stand-in env with given spaces, only for ``VecNormalize.load``."""

    def __init__(self, observation_space: gym.Space, action_space: gym.Space) -> None:
        self.observation_space, self.action_space = observation_space, action_space

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        return self.observation_space.sample(), {}

    def step(self, action):
        return self.observation_space.sample(), 0.0, True, False, {}


def _policy_spec_error(spec: Any, reason: str) -> ValueError:
    return ValueError(
        f"policy must be one of {list(BUILTIN_POLICIES)}, a path to a Stable-Baselines3 model .zip, "
        f"or 'ALGO:path' (e.g. 'SAC:runs/model.zip'); got {spec!r}: {reason}"
    )


def _sb3_algorithm(name: str) -> type:
    import stable_baselines3

    modules = [stable_baselines3]
    try:
        import sb3_contrib  # optional: RecurrentPPO, TQC, ...

        modules.append(sb3_contrib)
    except ImportError:
        pass
    for module in modules:
        for attr in dir(module):
            cls = getattr(module, attr)
            if attr.lower() == name.lower() and isinstance(cls, type) and hasattr(cls, "load"):
                return cls
    known = sorted(a for a in dir(stable_baselines3) if a.isupper() and hasattr(getattr(stable_baselines3, a), "load"))
    raise ValueError(f"policy algorithm must be a Stable-Baselines3 algorithm {known}, got {name!r}")


def normalizer_beside(model_path: str | os.PathLike) -> Path | None:
    """The VecNormalize statistics saved with a model: a checkpoint's own
    (SB3's ``CheckpointCallback``: ``ppo_1000_steps.zip`` -> ``ppo_vecnormalize_1000_steps.pkl``),
    else ``vecnormalize.pkl`` in its folder; None if neither exists."""
    model_path = Path(model_path)
    found = re.fullmatch(r"(.*)_(\d+)_steps", model_path.stem)
    candidates = [model_path.with_name(f"{found[1]}_vecnormalize_{found[2]}_steps.pkl")] if found else []
    candidates.append(model_path.parent / "vecnormalize.pkl")
    return next((path for path in candidates if path.is_file()), None)


def read_normalizer(path: str | os.PathLike):
    """VecNormalize statistics from ``path``, not yet attached to an env (``VecNormalize.load`` is
    this plus ``set_venv``). The file is a pickle: only open files you trust. ``ValueError`` names the
    file when it cannot be read."""
    import pickle

    from stable_baselines3.common.vec_env import VecNormalize

    try:
        with open(path, "rb") as f:
            normalizer = pickle.load(f)
    except Exception as err:  # truncated pickles, wrong magic, ... surface as many types
        raise ValueError(f"cannot read the VecNormalize statistics {str(path)!r} ({type(err).__name__}: {err}): "
                         "the file is truncated or not a VecNormalize .pkl") from err
    if not isinstance(normalizer, VecNormalize):
        raise ValueError(  # noqa: TRY004  (a wrong file, not a wrong argument)
            f"{str(path)!r} holds a {type(normalizer).__name__}, not VecNormalize statistics")
    return normalizer


def load_policy(spec: str, env: gym.Env, seed: int | None = 0, device: str = "cpu") -> Policy:
    """Turn a policy spec into a callable ``obs -> action``.

    | spec | policy |
    |---|---|
    | ``"random"`` | uniform actions in ``env.action_space`` from ``np.random.default_rng(seed)`` |
    | ``"zero"`` | all-zero actions |
    | ``"path/model.zip"`` | ``stable_baselines3.PPO.load(path)``, deterministic ``predict`` |
    | ``"SAC:path/model.zip"`` | the same with another algorithm (SB3, or sb3_contrib if installed) |

    For a model, its VecNormalize statistics (``normalizer_beside``) normalise the
    observations before ``predict`` (statistics frozen).
    ``env`` provides the spaces; it is not stepped. ``device`` is passed to the SB3 loader.
    A model .zip and its statistics .pkl are pickles (SB3's formats): load only files you trust.
    """
    if not isinstance(spec, (str, os.PathLike)):
        raise _policy_spec_error(spec, "expected a string")
    spec = os.fspath(spec)
    if spec in BUILTIN_POLICIES:
        if spec == "zero":
            return ZeroPolicy(env.action_space)
        return RandomPolicy(env.action_space, seed)
    if not spec.strip():
        raise _policy_spec_error(spec, "empty string")

    algo_name, path = "PPO", spec
    head, sep, tail = spec.partition(":")
    # "ALGO:path"; a one-letter head is a Windows drive ("C:\\...").
    if sep and len(head) > 1 and head.replace("_", "").isalnum() and not os.path.exists(spec):
        algo_name, path = head, tail
    model_path = Path(path).expanduser()
    if not model_path.is_file():
        if model_path.suffix != ".zip" and model_path.with_name(model_path.name + ".zip").is_file():
            model_path = model_path.with_name(model_path.name + ".zip")
        else:
            raise _policy_spec_error(spec, f"no such file {str(model_path)!r}")
    algorithm = _sb3_algorithm(algo_name)
    try:
        model = algorithm.load(str(model_path), device=device)
    except Exception as err:  # a truncated .zip, another algorithm's model, ...
        raise ValueError(f"cannot read the policy model {str(model_path)!r} as {algorithm.__name__} "
                         f"({type(err).__name__}: {err})") from err
    expected = getattr(env.observation_space, "shape", None)
    if model.observation_space.shape != expected:
        raise ValueError(
            f"policy model {str(model_path)!r} expects observations of shape {model.observation_space.shape}, "
            f"the env gives {expected}"
        )
    if model.action_space.shape != env.action_space.shape:
        raise ValueError(
            f"policy model {str(model_path)!r} outputs actions of shape {model.action_space.shape}, "
            f"the env expects {env.action_space.shape}"
        )

    normalizer = None
    stats = normalizer_beside(model_path)
    if stats is not None:
        from stable_baselines3.common.vec_env import DummyVecEnv

        normalizer = read_normalizer(stats)
        if normalizer.observation_space.shape != expected:
            raise ValueError(f"VecNormalize statistics {str(stats)!r} are for observations of shape "
                             f"{normalizer.observation_space.shape}, the env gives {expected}")
        normalizer.set_venv(DummyVecEnv([lambda: _SpacesEnv(env.observation_space, env.action_space)]))
        normalizer.training = False
        normalizer.norm_reward = False
    return SB3Policy(model, normalizer, str(model_path))


# --- results ------------------------------------------------------------------
@dataclass(frozen=True)
class EpisodeResult:
    """One evaluation episode."""

    index: int               # episode number within its height group
    seed: int                # the ``env.reset`` seed
    step_height: float       # the staircase's step height (m)
    fixed_height: float | None  # the requested fixed height, None for the env's random heights
    progress: float          # highest height progress reached, 0-1
    fell: bool               # ended by early termination
    success: bool            # reached M_T on the top floor
    time: float | None       # time of the first success (s), None without one
    physics_unstable: bool   # truncated because the simulation diverged
    truncated: bool          # ended by the time limit (or an unstable-physics truncation)
    steps: int               # policy steps taken
    episode_return: float    # sum of rewards


@dataclass(frozen=True)
class GroupStats:
    """Paper metrics over a group of episodes (all, one fixed height, or a height bin)."""

    group: str | float             # "all", a fixed height (m) or a bin label such as "0.075-0.125"
    n: int
    progress_pct: float | None     # mean highest progress, %
    et_pct: float | None           # early terminations, %
    success_pct: float | None      # successful climbs, %
    time_s: float | None           # mean completion time of the successful climbs (s); None if none
    unstable_pct: float | None     # unstable-physics truncations, %
    height_min: float | None = None  # lowest and highest step height (m) of the group's episodes
    height_max: float | None = None

    @classmethod
    def from_episodes(cls, group: str | float, episodes: Sequence[EpisodeResult],
                      height_min: float | None = None, height_max: float | None = None) -> "GroupStats":
        n = len(episodes)
        if n == 0:
            return cls(group, 0, None, None, None, None, None, height_min, height_max)
        times = [e.time for e in episodes if e.success and e.time is not None]
        heights = [e.step_height for e in episodes]
        return cls(
            group=group,
            n=n,
            progress_pct=100.0 * float(np.mean([e.progress for e in episodes])),
            et_pct=100.0 * sum(e.fell for e in episodes) / n,
            success_pct=100.0 * sum(e.success for e in episodes) / n,
            time_s=float(np.mean(times)) if times else None,
            unstable_pct=100.0 * sum(e.physics_unstable for e in episodes) / n,
            height_min=min(heights) if height_min is None else height_min,
            height_max=max(heights) if height_max is None else height_max,
        )


@dataclass
class EvaluationReport:
    """Per-episode results and per-group paper metrics of one :func:`evaluate` run."""

    label: str
    env_id: str
    seed: int
    episodes_per_group: int
    step_heights: tuple[float, ...] | None
    env_kwargs: dict[str, Any]
    max_episode_steps: int | None
    episodes: list[EpisodeResult]
    groups: list[GroupStats] = field(default_factory=list)

    @property
    def overall(self) -> GroupStats:
        """The group over all episodes."""
        return self.group(OVERALL)

    def group(self, name: str | float) -> GroupStats:
        """The group named ``name`` ("all", a fixed height such as 0.05, or a bin label)."""
        for g in self.groups:
            if g.group == name or (isinstance(name, float) and isinstance(g.group, float) and math.isclose(g.group, name)):
                return g
        raise KeyError(f"no group {name!r}; groups: {[g.group for g in self.groups]}")

    def to_rows(self) -> list[dict[str, Any]]:
        """One dict per group with the keys of :data:`ROW_FIELDS` (None where undefined)."""
        return [
            {
                "method": self.label,
                "env_id": self.env_id,
                "group": g.group,
                "height_min": g.height_min,
                "height_max": g.height_max,
                "n": g.n,
                "progress_pct": g.progress_pct,
                "et_pct": g.et_pct,
                "success_pct": g.success_pct,
                "time_s": g.time_s,
                "unstable_pct": g.unstable_pct,
            }
            for g in self.groups
        ]

    def to_csv(self, path: str | os.PathLike) -> Path:
        """Write :meth:`to_rows` as CSV (empty cells for None); returns the path."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        with path.open("w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(ROW_FIELDS))
            writer.writeheader()
            for row in self.to_rows():
                writer.writerow({k: "" if v is None else v for k, v in row.items()})
        return path

    def to_dict(self) -> dict[str, Any]:
        """Settings, per-group rows and per-episode results as plain JSON-able data."""
        return {
            "label": self.label,
            "env_id": self.env_id,
            "seed": self.seed,
            "episodes_per_group": self.episodes_per_group,
            "step_heights": list(self.step_heights) if self.step_heights is not None else None,
            "env_kwargs": {k: _jsonable(v) for k, v in self.env_kwargs.items()},
            "max_episode_steps": self.max_episode_steps,
            "groups": self.to_rows(),
            "episodes": [asdict(e) for e in self.episodes],
        }

    def to_json(self, path: str | os.PathLike) -> Path:
        """Write :meth:`to_dict` as JSON (null for None); returns the path."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(self.to_dict(), indent=2) + "\n")
        return path

    def format_table(self, compare_paper: bool = False) -> str:
        """A plain-text table with the paper's columns plus n, Success and Unstable.

        With ``compare_paper`` the published rows of :data:`PAPER_RESULTS` (marked
        "(paper)", n = 4096) are listed before this run's row of the same group.
        """
        rows = self.to_rows()
        if compare_paper:
            rows = merge_paper_rows(rows)
        return format_table(rows)

    def __str__(self) -> str:
        return self.format_table()


def _jsonable(value: Any) -> Any:
    if isinstance(value, (str, int, float, bool)) or value is None:
        return value
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, Mapping):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, np.generic):
        return value.item()
    return repr(value)


def paper_rows() -> list[dict[str, Any]]:
    """:data:`PAPER_RESULTS` as rows in the format of :meth:`EvaluationReport.to_rows`."""
    rows = []
    for r in PAPER_RESULTS:
        fixed = r["group"] != OVERALL
        rows.append({
            "method": f"{r['method']} (paper)",
            "env_id": r["env_id"],
            "group": r["group"],
            "height_min": r["group"] if fixed else 0.05,
            "height_max": r["group"] if fixed else 0.20,
            "n": PAPER_TRIALS,
            "progress_pct": r["progress_pct"],
            "et_pct": r["et_pct"],
            "success_pct": None,
            "time_s": r["time_s"],
            "unstable_pct": None,
        })
    return rows


def _same_group(a: Any, b: Any) -> bool:
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        return math.isclose(a, b, abs_tol=1e-9)
    return a == b


def merge_paper_rows(rows: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """``rows`` with the published rows of each group inserted before them; published
    groups absent from ``rows`` (e.g. 0.05 m when heights were random) come last."""
    paper = paper_rows()
    merged: list[dict[str, Any]] = []
    used: set[int] = set()
    seen_groups: list[Any] = []
    for row in rows:
        if not any(_same_group(row["group"], g) for g in seen_groups):
            seen_groups.append(row["group"])
            for i, p in enumerate(paper):
                if _same_group(p["group"], row["group"]):
                    merged.append(p)
                    used.add(i)
        merged.append(dict(row))
    merged.extend(p for i, p in enumerate(paper) if i not in used)
    return merged


def _format_group(group: Any) -> str:
    if isinstance(group, (int, float)) and not isinstance(group, bool):
        return f"{group:.2f} m"
    return str(group)


def _fmt(value: float | None, digits: int) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def format_table(rows: Sequence[Mapping[str, Any]]) -> str:
    """Plain-text table of result rows (as from :meth:`EvaluationReport.to_rows`);
    None shows as "-" like the paper. Rules separate step-height groups of several rows."""
    header = ("Method", "Step height", "n", "Progress (%)", "ET (%)", "Success (%)", "Time (s)", "Unstable (%)")
    body = [
        (
            str(r["method"]),
            _format_group(r["group"]),
            "-" if r.get("n") is None else str(r["n"]),
            _fmt(r.get("progress_pct"), 1),
            _fmt(r.get("et_pct"), 1),
            _fmt(r.get("success_pct"), 1),
            _fmt(r.get("time_s"), 2),
            _fmt(r.get("unstable_pct"), 1),
        )
        for r in rows
    ]
    widths = [max(len(h), *(len(b[i]) for b in body)) if body else len(h) for i, h in enumerate(header)]

    def line(cells: Sequence[str]) -> str:
        # Text columns left-aligned, numbers right-aligned.
        return "  ".join(c.ljust(w) if i < 2 else c.rjust(w) for i, (c, w) in enumerate(zip(cells, widths))).rstrip()

    rule = "-" * len(line(header))
    out = [line(header), rule]
    # Rules between groups only help when groups hold several rows (methods).
    boundaries = [k for k in range(1, len(rows)) if not _same_group(rows[k]["group"], rows[k - 1]["group"])]
    grouped = len(boundaries) + 1 < len(rows)
    for k, cells in enumerate(body):
        if grouped and k in boundaries:
            out.append(rule)
        out.append(line(cells))
    return "\n".join(out)


def parse_env_kwarg(text: str) -> tuple[str, Any]:
    """A command-line ``key=value`` -> ``(key, value)``, the value parsed by
    ``ast.literal_eval`` (numbers, tuples, True/None...) or else kept as a string."""
    import ast

    key, sep, raw = text.partition("=")
    key = key.strip()
    if not sep or not key.isidentifier():
        raise ValueError(f"env kwarg must look like key=value (e.g. pd_gains=stiff), got {text!r}")
    try:
        value = ast.literal_eval(raw.strip())
    except (ValueError, SyntaxError, MemoryError, RecursionError):
        value = raw
    return key, value


def env_kwarg_argument(text: str) -> tuple[str, Any]:
    """argparse ``type=`` for ``--env-kwarg key=value`` (see :func:`parse_env_kwarg`)."""
    import argparse

    try:
        return parse_env_kwarg(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


# --- the evaluation loop --------------------------------------------------------
def _height_bins(edges: Sequence[float]) -> list[tuple[str, float, float]]:
    bounds = [-math.inf, *edges, math.inf]
    bins = []
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        if lo == -math.inf:
            label = f"<{hi:g} m"
        elif hi == math.inf:
            label = f">={lo:g} m"
        else:
            label = f"{lo:g}-{hi:g} m"
        bins.append((label, lo, hi))
    return bins


def _run_episode(env: gym.Env, policy: Policy, seed: int, index: int, fixed_height: float | None) -> EpisodeResult:
    if callable(getattr(policy, "reset", None)):
        policy.reset(seed)
    obs, info = env.reset(seed=seed)
    step_height = float(info["stairs"]["step_height"])
    best = float(info["progress"])
    success, success_time = False, None
    fell = unstable = truncated = False
    steps, episode_return = 0, 0.0
    while True:
        action = np.asarray(policy(obs))
        obs, reward, terminated, truncated, info = env.step(action)
        steps += 1
        episode_return += float(reward)
        unstable = bool(info.get("physics_unstable", False))
        if not unstable:  # an unstable step reports no valid progress
            best = max(best, float(info["progress"]))
        if info.get("success") and not success:
            success, success_time = True, float(info["time"])
        if terminated or truncated:
            fell = bool(info.get("fell", False))
            break
    return EpisodeResult(
        index=index, seed=seed, step_height=step_height, fixed_height=fixed_height,
        progress=best, fell=fell, success=success, time=success_time,
        physics_unstable=unstable, truncated=bool(truncated), steps=steps, episode_return=episode_return,
    )


def _policy_label(policy: Any) -> str:
    if isinstance(policy, (str, os.PathLike)):
        return os.fspath(policy)
    return getattr(policy, "__name__", None) or type(policy).__name__


def evaluate(
    policy: Policy | str,
    env_id: str = "InterLevel-v0",
    episodes: int = 100,
    seed: int = 0,
    env_kwargs: Mapping[str, Any] | None = None,
    step_heights: Sequence[float] | None = None,
    progress_bar: bool = True,
    max_episode_steps: int | None = None,
    label: str | None = None,
    height_bins: Sequence[float] | None = HEIGHT_BIN_EDGES,
) -> EvaluationReport:
    """Run ``policy`` for ``episodes`` episodes (per step height) and compute the paper's metrics.

    | keyword | default | meaning |
    |---|---|---|
    | policy | - | a callable ``obs -> action``, or a spec for :func:`load_policy` ("random", "zero", a model path) |
    | env_id | "InterLevel-v0" | a registered env id (``import stairenv`` registers the presets) |
    | episodes | 100 | episodes in all, or per height with ``step_heights`` (>= 1) |
    | seed | 0 | episode ``i`` is reset with ``seed + i`` (the same seeds for every height), so runs repeat exactly |
    | env_kwargs | None | extra ``gym.make`` keywords for the env |
    | step_heights | None | fixed step heights (m), e.g. ``PAPER_STEP_HEIGHTS``; each via ``step_height_set=(h,)`` |
    | progress_bar | True | show a tqdm bar |
    | max_episode_steps | None | ``gym.make``'s time limit; None keeps the preset's (600 steps = 20 s) |
    | label | None | the Method column; None = the policy spec string or the callable's name |
    | height_bins | (0.075, 0.125, 0.175) | interior bin edges (m) grouping random heights; None or () for no bins |

    If ``policy`` has a ``reset(seed)`` method it is called with each episode's seed
    before the episode (:class:`RandomPolicy` reseeds itself).

    Per episode: the highest ``info["progress"]``, whether it ended by a fall
    (``info["fell"]``), success (``info["success"]``) and the first success's
    ``info["time"]``, the step height, and unstable-physics truncations, which are
    counted apart and never as early termination. Groups: ``"all"``, then one per
    fixed height (named by the height, a float) or, for random heights, one per
    non-empty bin (named like ``"0.075-0.125 m"``).
    """
    if isinstance(episodes, bool) or not isinstance(episodes, (int, np.integer)) or episodes < 1:
        raise ValueError(f"episodes must be an integer >= 1, got {episodes!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    if max_episode_steps is not None and (
        isinstance(max_episode_steps, bool) or not isinstance(max_episode_steps, (int, np.integer)) or max_episode_steps < 1
    ):
        raise ValueError(f"max_episode_steps must be None or an integer >= 1, got {max_episode_steps!r}")
    if not isinstance(policy, (str, os.PathLike)) and not callable(policy):
        raise ValueError(f"policy must be a callable (obs -> action) or a policy spec string, got {policy!r}")
    if env_id not in gym.registry:
        raise ValueError(f"env_id must be a registered env id such as {list(_stairenv_ids())}, got {env_id!r}")
    env_kwargs = dict(env_kwargs or {})
    if step_heights is not None:
        if "step_height_set" in env_kwargs:
            raise ValueError("pass step heights either as step_heights or as env_kwargs['step_height_set'], not both")
        try:
            heights = tuple(float(h) for h in step_heights)
        except (TypeError, ValueError):
            raise ValueError(f"step_heights must be a sequence of heights in metres, got {step_heights!r}") from None
        if not heights or not all(math.isfinite(h) and h > 0 for h in heights):
            raise ValueError(f"step_heights must be a non-empty sequence of positive heights (m), got {step_heights!r}")
        if len(set(heights)) != len(heights):
            raise ValueError(f"step_heights must not repeat a height, got {step_heights!r}")
        plan: list[float | None] = list(heights)
    else:
        heights = None
        plan = [None]

    make_kwargs: dict[str, Any] = {}
    if max_episode_steps is not None:
        make_kwargs["max_episode_steps"] = int(max_episode_steps)

    from tqdm.auto import tqdm

    def make_env(fixed: float | None) -> gym.Env:
        kwargs = dict(env_kwargs)
        if fixed is not None:
            kwargs["step_height_set"] = (fixed,)
        return gym.make(env_id, **make_kwargs, **kwargs)

    label = label or _policy_label(policy)
    # The first env is made (and a policy spec loaded) before the bar starts, so
    # that bad keywords or specs fail with a clean error.
    env = make_env(plan[0])
    try:
        if isinstance(policy, (str, os.PathLike)):
            policy = load_policy(os.fspath(policy), env, seed=seed)
    except BaseException:
        env.close()
        raise

    results: list[EpisodeResult] = []
    bar = tqdm(total=episodes * len(plan), desc=f"{label} on {env_id}", unit="ep", disable=not progress_bar)
    try:
        for k, fixed in enumerate(plan):
            if k > 0:
                env = make_env(fixed)
            try:
                for i in range(episodes):
                    results.append(_run_episode(env, policy, seed + i, i, fixed))
                    bar.update(1)
                    if len(results) % 10 == 0 or len(results) == bar.total:
                        bar.set_postfix(
                            progress=f"{100 * np.mean([e.progress for e in results]):.1f}%",
                            et=f"{100 * np.mean([e.fell for e in results]):.0f}%",
                            ok=sum(e.success for e in results),
                        )
            finally:
                env.close()
    finally:
        bar.close()

    groups = [GroupStats.from_episodes(OVERALL, results)]
    if heights is not None:
        for h in heights:
            groups.append(GroupStats.from_episodes(h, [e for e in results if e.fixed_height == h], h, h))
    elif height_bins:
        edges = sorted(float(e) for e in height_bins)
        for name, lo, hi in _height_bins(edges):
            members = [e for e in results if lo <= e.step_height < hi]
            if members:
                groups.append(GroupStats.from_episodes(name, members))
    return EvaluationReport(
        label=label, env_id=env_id, seed=int(seed), episodes_per_group=int(episodes), step_heights=heights,
        env_kwargs=env_kwargs, max_episode_steps=max_episode_steps, episodes=results, groups=groups,
    )


def _stairenv_ids() -> tuple[str, ...]:
    import stairenv

    return stairenv.ENV_IDS


__all__ = [
    "BUILTIN_POLICIES", "HEIGHT_BIN_EDGES", "OVERALL", "PAPER_RESULTS", "PAPER_STEP_HEIGHTS", "PAPER_TRIALS",
    "ROW_FIELDS", "EpisodeResult", "EvaluationReport", "GroupStats", "RandomPolicy", "SB3Policy", "ZeroPolicy",
    "evaluate", "format_table", "load_policy", "merge_paper_rows", "paper_rows", "parse_env_kwarg",
]
