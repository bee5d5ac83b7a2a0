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
    from stairenv.evaluation.interlevel import evaluate

    report = evaluate("random", "InterLevel-v0", episodes=20, step_heights=(0.05, 0.10))
    print(report.format_table(compare_paper=True))
    report.to_csv("random.csv")

The published numbers are in :data:`PAPER_RESULTS`.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import gymnasium as gym
import numpy as np

from stairenv.evaluation.gait import GAIT_FIELDS, GaitRecorder, GaitSummary, gait_columns, summarize
from stairenv.evaluation.pushes import (  # noqa: F401  (PUSH_STREAM, apply_push, push_plan: their old home)
    PUSH_STEPS,
    PUSH_STREAM,
    EpisodePush,
    apply_push,
    check_push_speed,
    push_meta,
    push_plan,
)
from stairenv.evaluation.report import Column, Layout, Report
from stairenv.evaluation.worlds import check_num_envs, run_on_worlds
from stairenv.policy_loading import Policy, load_policy, policy_label
from stairenv.world.stairs import PAPER_TEST_HEIGHTS

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
    gait: GaitSummary | None = None  # the gait metrics (``evaluate(..., gait=True)``), else None
    push_step: int | None = None  # the step before which the push came (``push_speed``), None if none came
    push_angle: float | None = None  # its direction in the world's xy plane (rad)


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
                      height_min: float | None = None, height_max: float | None = None) -> GroupStats:
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
class EvaluationReport(Report):
    """A :class:`~stairenv.evaluation.report.Report` of one :func:`evaluate` run: a row per
    group, the episodes as details, and the groups' :class:`GroupStats`."""

    groups: list[GroupStats] = field(default_factory=list)

    @property
    def episodes(self) -> list[EpisodeResult]:
        """The episodes, in the order they ran."""
        return self.details

    @property
    def overall(self) -> GroupStats:
        """The group over all episodes."""
        return self.group(OVERALL)

    def to_dict(self) -> dict[str, Any]:
        """:meth:`Report.to_dict`; episodes carry their ``gait`` only when it was measured."""
        data = super().to_dict()
        for episode in data[self.layout.details_key]:
            if episode.get("gait", 0) is None:
                del episode["gait"]
        return data

    def group(self, name: str | float) -> GroupStats:
        """The group named ``name`` ("all", a fixed height such as 0.05, or a bin label)."""
        for g in self.groups:
            if g.group == name or (isinstance(name, float) and isinstance(g.group, float) and math.isclose(g.group, name)):
                return g
        raise KeyError(f"no group {name!r}; groups: {[g.group for g in self.groups]}")


def group_row(label: str, env_id: str, g: GroupStats) -> dict[str, Any]:
    """The row (keys :data:`ROW_FIELDS`) of one group."""
    return {
        "method": label,
        "env_id": env_id,
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


def _format_group(group: Any) -> str:
    if isinstance(group, (int, float)) and not isinstance(group, bool):
        return f"{group:.2f} m"
    return str(group)


#: The rows, CSV and table of InterLevel's Tables 1-3: the paper's columns plus n, Success and
#: Unstable; published rows (marked "(paper)", n = 4096) before this run's row of the same group.
LAYOUT = Layout(
    fields=ROW_FIELDS,
    columns=(
        Column("Method", "method", text=True),
        Column("Step height", "group", text=True, show=lambda r: _format_group(r["group"])),
        Column("n", "n"),
        Column("Progress (%)", "progress_pct", 1),
        Column("ET (%)", "et_pct", 1),
        Column("Success (%)", "success_pct", 1),
        Column("Time (s)", "time_s", 2),
        Column("Unstable (%)", "unstable_pct", 1),
    ),
    paper=paper_rows,
    append_unmatched_paper=True,
    group_rules=True,
    rows_key="groups",
    details_key="episodes",
)

#: :data:`LAYOUT` with the gait columns of ``evaluate(..., gait=True)`` (``stairenv.evaluation.gait``):
#: alternating feet among the successful climbs, touchdowns per tread, hop / crawl episodes, sliding stance.
GAIT_LAYOUT = replace(
    LAYOUT,
    fields=ROW_FIELDS + GAIT_FIELDS,
    columns=LAYOUT.columns + (
        Column("Alt. (%)", "alternating_pct", 1),
        Column("TD/tread", "touchdowns_per_tread", 2),
        Column("Hop (%)", "hop_pct", 1),
        Column("Crawl (%)", "crawl_pct", 1),
        Column("Slide (%)", "slide_pct", 1),
    ),
)


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


class _EpisodeTracker:
    """One evaluation episode's bookkeeping, fed its reset and then each step (one home for what the
    sequential and the batched evaluation record)."""

    def __init__(self, index: int, seed: int, fixed_height: float | None, info: dict[str, Any],
                 recorder: GaitRecorder | None = None, data: Any = None, push_speed: float = 0.0,
                 dt: float | None = None) -> None:
        self.index, self.seed, self.fixed_height, self.dt = index, seed, fixed_height, dt
        self.push = EpisodePush(seed, push_speed)
        self.recorder, self.data = recorder, data
        self.num_steps = int(info["stairs"]["num_steps"]) if recorder is not None else None
        self.step_height = float(info["stairs"]["step_height"])
        self.best = float(info["progress"])
        self.success, self.success_time = False, None
        self.fell = self.unstable = self.truncated = False
        self.steps, self.episode_return = 0, 0.0
        if recorder is not None:  # the env's MuJoCo state, read after the reset and every stable step
            recorder.reset()
            recorder.record(data)

    def before_step(self, env: Any) -> None:
        """The push, if this episode's comes before the step about to run (``env``: the unwrapped env)."""
        self.push.before_step(env, self.steps)

    def update(self, reward: float, terminated: bool, truncated: bool, info: dict[str, Any]) -> bool:
        """Record one step; True when it ended the episode."""
        self.steps += 1
        self.episode_return += float(reward)
        self.unstable = bool(info.get("physics_unstable", False))
        if not self.unstable:  # an unstable step reports no valid progress
            self.best = max(self.best, float(info["progress"]))
            if self.recorder is not None:
                self.recorder.record(self.data)
        if info.get("success") and not self.success:
            self.success, self.success_time = True, float(info["time"])
        if terminated or truncated:
            self.fell, self.truncated = bool(info.get("fell", False)), bool(truncated)
            return True
        return False

    def result(self, dt: float | None = None) -> EpisodeResult:
        """The episode's result (``dt``: the env's step, for the gait; by default the one given at the start)."""
        dt = self.dt if dt is None else dt
        gait = summarize(self.recorder.trace(dt, self.num_steps)) if self.recorder is not None else None
        return EpisodeResult(
            index=self.index, seed=self.seed, step_height=self.step_height, fixed_height=self.fixed_height,
            progress=self.best, fell=self.fell, success=self.success, time=self.success_time,
            physics_unstable=self.unstable, truncated=self.truncated, steps=self.steps,
            episode_return=self.episode_return, gait=gait,
            push_step=self.push.step, push_angle=self.push.angle,
        )


def _run_episode(env: gym.Env, policy: Policy, seed: int, index: int, fixed_height: float | None,
                 recorder: GaitRecorder | None = None, push_speed: float = 0.0) -> EpisodeResult:
    if callable(getattr(policy, "reset", None)):
        policy.reset(seed)
    obs, info = env.reset(seed=seed)
    data = env.unwrapped.data if recorder is not None else None
    tracker = _EpisodeTracker(index, seed, fixed_height, info, recorder, data, push_speed)
    while True:
        tracker.before_step(env.unwrapped)
        obs, reward, terminated, truncated, info = env.step(np.asarray(policy(obs)))
        if tracker.update(reward, terminated, truncated, info):
            return tracker.result(env.unwrapped.dt if recorder is not None else None)


def _run_batched(vec: Any, policy: Policy, episodes: Sequence[tuple[int, int]], fixed_height: float | None,
                 gait: bool, on_result: Any, push_speed: float = 0.0) -> None:
    """Run ``episodes`` ((index, seed) pairs) on the worlds of the batched env ``vec``
    (``evaluation.worlds.run_on_worlds``: each world takes the next episode when its last one ends, reset
    with that episode's seed, as the sequential evaluation does)."""
    recorders = [GaitRecorder(env.model) for env in vec.envs] if gait else [None] * vec.num_envs
    dt = vec.envs[0].dt

    def start(k: int, index: int, seed: int, info: dict[str, Any]) -> _EpisodeTracker:
        return _EpisodeTracker(index, seed, fixed_height, info, recorders[k], vec.envs[k].data, push_speed, dt)

    run_on_worlds(vec, policy, episodes, start, on_result)


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
    gait: bool = False,
    num_envs: int = 1,
    push_speed: float = 0.0,
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
    | gait | False | also record foot contacts and add the gait columns (:data:`GAIT_LAYOUT`) |
    | num_envs | 1 | worlds of the env's batched vector env that run the episodes side by side (physics on every core, the policy called on the batch); 1 = one env, episode after episode |
    | push_speed | 0.0 | m/s in [0, 10]: each episode's character is kicked once, this horizontal speed added to its root in a random direction before a random step in ``PUSH_STEPS`` (1-6 s), both drawn from the episode's seed (``stairenv.evaluation.pushes``: the same push for every policy; an episode that ends first gets none); 0 = no push |

    If ``policy`` has a ``reset(seed)`` method it is called with each episode's seed
    before the episode (:class:`~stairenv.policy_loading.RandomPolicy` reseeds itself);
    such a policy is always run one episode at a time.

    With ``num_envs`` > 1 the same episodes (same seeds, same staircases) run on the worlds of
    ``gym.make_vec(env_id, vectorization_mode="vector_entry_point")``, each world taking the next
    episode when its last one ends; a world's physics is bit-identical to the single env's. The
    policy is called on the whole batch (row by row if it does not take a batch), and a network's
    batched matrix products may round differently from one observation's in the last bits, so a
    chaotic episode (a stumble) can end differently; the metrics agree within sampling noise.

    Per episode: the highest ``info["progress"]``, whether it ended by a fall
    (``info["fell"]``), success (``info["success"]``) and the first success's
    ``info["time"]``, the step height, and unstable-physics truncations, which are
    counted apart and never as early termination. Groups: ``"all"``, then one per
    fixed height (named by the height, a float) or, for random heights, one per
    non-empty bin (named like ``"0.075-0.125 m"``).

    With ``gait`` every episode's contacts are recorded after the reset and after every stable
    step (``stairenv.evaluation.gait``): each episode gets its :class:`~stairenv.evaluation.gait.GaitSummary`
    (``EpisodeResult.gait``) and each row the columns of :func:`~stairenv.evaluation.gait.gait_columns`:
    % of the successful climbs with alternating feet, touchdowns per tread, % of episodes with a hop,
    with a crawl, and % of stance frames that slide.
    """
    if isinstance(episodes, bool) or not isinstance(episodes, (int, np.integer)) or episodes < 1:
        raise ValueError(f"episodes must be an integer >= 1, got {episodes!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    if max_episode_steps is not None and (
        isinstance(max_episode_steps, bool) or not isinstance(max_episode_steps, (int, np.integer)) or max_episode_steps < 1
    ):
        raise ValueError(f"max_episode_steps must be None or an integer >= 1, got {max_episode_steps!r}")
    num_envs = check_num_envs(num_envs)
    push_speed = check_push_speed(push_speed)
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

    def kwargs_for(fixed: float | None) -> dict[str, Any]:
        return {**make_kwargs, **env_kwargs, **({"step_height_set": (fixed,)} if fixed is not None else {})}

    def make_env(fixed: float | None) -> gym.Env:
        return gym.make(env_id, **kwargs_for(fixed))

    def make_vec(fixed: float | None) -> gym.vector.VectorEnv:
        return gym.make_vec(env_id, num_envs=min(int(num_envs), episodes), vectorization_mode="vector_entry_point",
                            **kwargs_for(fixed))

    label = label or policy_label(policy)
    # The first env is made (and a policy spec loaded) before the bar starts, so
    # that bad keywords or specs fail with a clean error.
    env = make_env(plan[0])
    try:
        if isinstance(policy, (str, os.PathLike)):
            policy = load_policy(os.fspath(policy), env, seed=seed)
    except BaseException:
        env.close()
        raise

    # a policy that reseeds itself per episode keeps the sequential order its seeds assume
    batched = num_envs > 1 and not callable(getattr(policy, "reset", None))
    results: list[EpisodeResult] = []
    bar = tqdm(total=episodes * len(plan), desc=f"{label} on {env_id}", unit="ep", disable=not progress_bar)
    try:
        for k, fixed in enumerate(plan):
            if batched:
                env.close()
                env = make_vec(fixed)
            elif k > 0:
                env = make_env(fixed)
            group: list[EpisodeResult] = []

            def done(result: EpisodeResult) -> None:
                group.append(result)
                bar.update(1)
                done_so_far = results + group
                if len(done_so_far) % 10 == 0 or len(done_so_far) == bar.total:
                    bar.set_postfix(
                        progress=f"{100 * np.mean([e.progress for e in done_so_far]):.1f}%",
                        et=f"{100 * np.mean([e.fell for e in done_so_far]):.0f}%",
                        ok=sum(e.success for e in done_so_far),
                    )

            try:
                if batched:
                    _run_batched(env, policy, [(i, seed + i) for i in range(episodes)], fixed, gait, done,
                                 push_speed)
                else:
                    recorder = GaitRecorder(env.unwrapped.model) if gait else None
                    for i in range(episodes):
                        done(_run_episode(env, policy, seed + i, i, fixed, recorder, push_speed))
            finally:
                env.close()
            results.extend(sorted(group, key=lambda e: e.index))
    finally:
        bar.close()

    grouped = [(GroupStats.from_episodes(OVERALL, results), results)]
    if heights is not None:
        for h in heights:
            members = [e for e in results if e.fixed_height == h]
            grouped.append((GroupStats.from_episodes(h, members, h, h), members))
    elif height_bins:
        edges = sorted(float(e) for e in height_bins)
        for name, lo, hi in _height_bins(edges):
            members = [e for e in results if lo <= e.step_height < hi]
            if members:
                grouped.append((GroupStats.from_episodes(name, members), members))
    groups = [g for g, _ in grouped]
    rows = [group_row(label, env_id, g) for g in groups]
    meta = {"label": label, "env_id": env_id, "seed": int(seed), "episodes_per_group": int(episodes),
            "step_heights": heights, "env_kwargs": env_kwargs, "max_episode_steps": max_episode_steps,
            "num_envs": int(num_envs) if batched else 1}
    meta.update(push_meta(push_speed, sum(e.push_step is not None for e in results)))
    if gait:
        for row, (_, members) in zip(rows, grouped):
            row.update(gait_columns([e.gait for e in members], [e.success for e in members]))
        meta["gait"] = True
    return EvaluationReport(label=label, rows=rows, layout=GAIT_LAYOUT if gait else LAYOUT,
                            details=results, meta=meta, groups=groups)


def _stairenv_ids() -> tuple[str, ...]:
    import stairenv

    return stairenv.ENV_IDS


__all__ = [
    "GAIT_LAYOUT", "HEIGHT_BIN_EDGES", "LAYOUT", "OVERALL", "PAPER_RESULTS", "PAPER_STEP_HEIGHTS", "PAPER_TRIALS", "ROW_FIELDS",
    "PUSH_STEPS", "EpisodeResult", "EvaluationReport", "GroupStats", "apply_push", "evaluate", "group_row",
    "paper_rows", "push_plan",
]
