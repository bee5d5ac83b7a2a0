"""Evaluate a path-following policy the way PlaMo does: tracking errors (Table 2), scene episodes
and the slalom test.

For every terrain (flat, slope, rough, stairs) and locomotion (crawl,
crouch-walk, walk, run), :func:`tracking_errors` runs ``episodes`` episodes of
``PlaMo-v0`` with that terrain and paths restricted to that locomotion, each path at one
head height and one speed as in the paper's Table 2 (``constant_paths``; a constant turn rate too), and
reports the mean horizontal (XY) and vertical (Z) distance between the head and
the path point due at each step, over all steps of all episodes; :func:`evaluate`
gives them as a :class:`~stairenv.evaluation.report.Report`, with each episode's ending
(:class:`TrackingEpisode`: early termination, a fall, off the path) as its details. Published
numbers (PlaMo Table 2, e.g. walk on stairs 0.39 / 0.27 m) are in ``PAPER_TABLE2``
and stand in each row's ``paper_*`` columns. With ``push_speed`` each episode's character is
kicked once (:mod:`stairenv.evaluation.pushes`: the same push in the same episode for every policy).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import stairenv  # noqa: F401  (registers the envs)
from stairenv.evaluation.pushes import EpisodePush, check_push_speed, push_meta
from stairenv.evaluation.report import Column, Layout, Report
from stairenv.evaluation.worlds import check_num_envs, run_on_worlds
from stairenv.policy_loading import load_policy, policy_label

TERRAINS: tuple[str, ...] = ("flat", "slope", "rough", "stairs")
LOCOMOTIONS: tuple[str, ...] = ("crawl", "crouch-walk", "walk", "run")
#: PlaMo Table 2 (XY, Z mean head error in m along constant-speed, constant-height paths) by
#: (terrain, locomotion): every cell of the paper's table.
PAPER_TABLE2: dict[tuple[str, str], tuple[float, float]] = {
    ("flat", "crawl"): (0.20, 0.07), ("flat", "crouch-walk"): (0.20, 0.03),
    ("flat", "walk"): (0.24, 0.21), ("flat", "run"): (0.52, 0.26),
    ("slope", "crawl"): (0.21, 0.09), ("slope", "crouch-walk"): (0.22, 0.03),
    ("slope", "walk"): (0.25, 0.21), ("slope", "run"): (0.60, 0.27),
    ("rough", "crawl"): (0.25, 0.10), ("rough", "crouch-walk"): (0.25, 0.04),
    ("rough", "walk"): (0.29, 0.24), ("rough", "run"): (0.79, 0.31),
    ("stairs", "crawl"): (0.45, 0.13), ("stairs", "crouch-walk"): (0.41, 0.07),
    ("stairs", "walk"): (0.39, 0.27), ("stairs", "run"): (1.01, 0.35),
}

#: The tracking evaluation's height field side (m): no 10 s path (a run: 4 m/s, 40 m, plus the 5 s the
#: observation looks ahead) turns back at the field's edge. The policy sees only its egocentric heightmap,
#: so the field's size is not part of what it was trained on.
TRACKING_TERRAIN_SIZE = 100.0

#: Columns of the tracking-error rows and their CSV, in order.
ROW_FIELDS: tuple[str, ...] = (
    "terrain", "locomotion", "episodes", "steps", "xy_error_m", "z_error_m", "early_termination_pct",
    "paper_xy_error_m", "paper_z_error_m",
)
#: Columns of the scene-episode rows (:func:`scene_episodes`), in order.
SCENE_FIELDS: tuple[str, ...] = (
    "label", "episodes", "success_pct", "completion_time_s", "planned_time_s", "replans_per_episode",
    "waits_per_episode", "replan_failures_per_episode",
)


def _paper_cell(row: Mapping[str, Any]) -> str:
    if row["paper_xy_error_m"] is None:
        return "-"
    return f"{row['paper_xy_error_m']:.2f}/{row['paper_z_error_m']:.2f}"


#: The rows, CSV and table of the tracking errors (the published values are columns of the rows).
LAYOUT = Layout(
    fields=ROW_FIELDS,
    columns=(
        Column("Terrain", "terrain", text=True), Column("Locomotion", "locomotion", text=True),
        Column("XY err (m)", "xy_error_m", 3), Column("Z err (m)", "z_error_m", 3),
        Column("ET (%)", "early_termination_pct", 1), Column("Paper XY/Z (m)", show=_paper_cell),
    ),
)

#: The rows, CSV and table of scene episodes and the slalom test.
SCENE_LAYOUT = Layout(
    fields=SCENE_FIELDS,
    columns=(
        Column("Run", "label", text=True), Column("n", "episodes"), Column("Success (%)", "success_pct", 1),
        Column("Time (s)", "completion_time_s", 2), Column("Planned (s)", "planned_time_s", 2),
        Column("Replans", "replans_per_episode", 2), Column("Waits", "waits_per_episode", 2),
        Column("No way", "replan_failures_per_episode", 2),
    ),
)


@dataclass(frozen=True)
class TrackingEpisode:
    """One tracking episode (a Table 2 cell has ``episodes`` of them)."""

    terrain: str
    locomotion: str
    index: int                    # episode number within its cell
    seed: int                     # the ``env.reset`` seed
    steps: int                    # policy steps taken
    terminated: bool              # ended early: a fall or off the path (the row's early termination)
    fell: bool                    # the head came within ``min_head_height`` of the terrain
    off_path: bool                # the head came more than ``max_xy_error`` from its target
    push_step: int | None = None  # the step before which the push came (``push_speed``), None if none came
    push_angle: float | None = None  # its direction in the world's xy plane (rad)


class _TrackingRun:
    """One Table 2 episode's bookkeeping, fed each step (one home for the sequential and the batched run)."""

    def __init__(self, terrain: str, locomotion: str, index: int, seed: int, push_speed: float) -> None:
        self.terrain, self.locomotion, self.index, self.seed = terrain, locomotion, index, seed
        self.push = EpisodePush(seed, push_speed)
        self.steps, self.terminated, self.info = 0, False, {}
        self.xy: list[float] = []
        self.z: list[float] = []

    def before_step(self, env: Any) -> None:
        self.push.before_step(env, self.steps)

    def update(self, reward: float, terminated: bool, truncated: bool, info: dict[str, Any]) -> bool:
        self.steps += 1
        if not info["physics_unstable"]:
            self.xy.append(info["xy_error"])
            self.z.append(info["z_error"])
        if terminated or truncated:
            self.terminated, self.info = bool(terminated), info
            return True
        return False

    def result(self) -> _TrackingRun:
        return self

    def episode(self) -> TrackingEpisode:
        terminated, info = self.terminated, self.info
        return TrackingEpisode(self.terrain, self.locomotion, self.index, self.seed, self.steps, terminated,
                               bool(terminated and info.get("fell", False)),
                               bool(terminated and info.get("off_path", False)), self.push.step, self.push.angle)


def tracking_errors(
    policy: Callable[[np.ndarray], Any],
    terrains: Sequence[str] = TERRAINS,
    locomotions: Sequence[str] = LOCOMOTIONS,
    episodes: int = 10,
    seed: int = 0,
    env_id: str = "PlaMo-v0",
    max_episode_steps: int | None = None,
    env_kwargs: Mapping[str, Any] | None = None,
    progress_bar: bool = False,
    constant_paths: bool = True,
    push_speed: float = 0.0,
    num_envs: int = 1,
    physics: str | None = None,
    physics_device: str | None = None,
) -> list[dict[str, Any]]:
    """One row (:data:`ROW_FIELDS`) per (terrain, locomotion): mean XY and Z error (m), steps,
    early terminations. ``env_kwargs`` go to every env (``terrain``, ``locomotion`` and
    ``constant_paths`` are set here; ``constant_paths=False``: heights and speeds change along a path
    within the locomotion's ranges, as in training); the height field is ``TRACKING_TERRAIN_SIZE`` on a
    side unless ``env_kwargs`` says otherwise. ``push_speed`` (m/s, 0 = none): each episode's character
    is kicked once (:mod:`stairenv.evaluation.pushes`; an episode that ends before its push step gets none).
    ``num_envs`` > 1: a cell's episodes run on that many worlds of the batched env side by side
    (:mod:`stairenv.evaluation.worlds`; the same episodes, step for step, for a policy that acts on each row
    of a batch as on that observation alone), its physics back-end ``physics`` ("mujoco", "threads",
    "warp"; None: the vector env's default) on ``physics_device`` (Warp's: "cuda:0", "cpu"; None: its first GPU)."""
    return _tracking(policy, terrains, locomotions, episodes, seed, env_id, max_episode_steps, env_kwargs,
                     progress_bar, constant_paths, push_speed, num_envs, physics, physics_device)[0]


def _tracking(
    policy: Callable[[np.ndarray], Any],
    terrains: Sequence[str],
    locomotions: Sequence[str],
    episodes: int,
    seed: int,
    env_id: str,
    max_episode_steps: int | None,
    env_kwargs: Mapping[str, Any] | None,
    progress_bar: bool,
    constant_paths: bool,
    push_speed: float,
    num_envs: int = 1,
    physics: str | None = None,
    physics_device: str | None = None,
) -> tuple[list[dict[str, Any]], list[TrackingEpisode]]:
    """:func:`tracking_errors`'s rows and the episodes behind them."""
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    push_speed = check_push_speed(push_speed)
    num_envs = check_num_envs(num_envs)
    # a policy that reseeds itself per episode keeps the sequential order its seeds assume
    batched = num_envs > 1 and not callable(getattr(policy, "reset", None))
    if (physics is not None or physics_device is not None) and not batched:
        raise ValueError(f"physics={physics!r}, physics_device={physics_device!r} need the batched env: num_envs > 1 "
                         "(and a policy without reset)")
    vec_kwargs = {key: value for key, value in (("physics", physics), ("physics_device", physics_device))
                  if value is not None}
    from tqdm.auto import tqdm

    rows, details = [], []
    bar = tqdm(total=episodes * len(terrains) * len(locomotions), desc=f"tracking on {env_id}", unit="ep",
               disable=not progress_bar)
    try:
        for terrain in terrains:
            for locomotion in locomotions:
                kwargs: dict[str, Any] = {"terrain_size": TRACKING_TERRAIN_SIZE, **(env_kwargs or {}),
                                          "terrain": terrain, "locomotion": locomotion,
                                          "constant_paths": constant_paths}
                if max_episode_steps is not None:
                    kwargs["max_episode_steps"] = max_episode_steps
                runs: list[_TrackingRun] = []

                def done(run: _TrackingRun) -> None:
                    runs.append(run)
                    bar.update(1)

                if batched:
                    vec = gym.make_vec(env_id, num_envs=min(num_envs, episodes), vectorization_mode="vector_entry_point",
                                       **kwargs, **vec_kwargs)
                    try:
                        run_on_worlds(vec, policy, [(i, seed + i) for i in range(episodes)],
                                      lambda k, i, s, info: _TrackingRun(terrain, locomotion, i, s, push_speed), done)
                    finally:
                        vec.close()
                else:
                    env = gym.make(env_id, **kwargs)
                    try:
                        for episode in range(episodes):
                            if callable(getattr(policy, "reset", None)):
                                policy.reset(seed + episode)
                            obs, _ = env.reset(seed=seed + episode)
                            run = _TrackingRun(terrain, locomotion, episode, seed + episode, push_speed)
                            while True:
                                run.before_step(env.unwrapped)
                                obs, reward, terminated, truncated, info = env.step(np.asarray(policy(obs)))
                                if run.update(reward, terminated, truncated, info):
                                    break
                            done(run)
                    finally:
                        env.close()
                runs.sort(key=lambda run: run.index)
                details.extend(run.episode() for run in runs)
                xy = [e for run in runs for e in run.xy]
                z = [e for run in runs for e in run.z]
                paper = PAPER_TABLE2.get((terrain, locomotion))
                rows.append({
                    "terrain": terrain, "locomotion": locomotion, "episodes": episodes, "steps": len(xy),
                    "xy_error_m": float(np.mean(xy)), "z_error_m": float(np.mean(z)),
                    "early_termination_pct": 100.0 * sum(run.terminated for run in runs) / episodes,
                    "paper_xy_error_m": None if paper is None else paper[0],
                    "paper_z_error_m": None if paper is None else paper[1],
                })
    finally:
        bar.close()
    return rows, details


def evaluate(
    policy: Callable[[np.ndarray], Any] | str | os.PathLike,
    env_id: str = "PlaMo-v0",
    episodes: int = 10,
    seed: int = 0,
    env_kwargs: Mapping[str, Any] | None = None,
    max_episode_steps: int | None = None,
    progress_bar: bool = False,
    label: str | None = None,
    terrains: Sequence[str] = TERRAINS,
    locomotions: Sequence[str] = LOCOMOTIONS,
    constant_paths: bool = True,
    push_speed: float = 0.0,
    num_envs: int = 1,
    physics: str | None = None,
    physics_device: str | None = None,
) -> Report:
    """PlaMo Table 2: :func:`tracking_errors` of ``policy`` (a callable or a spec for
    :func:`~stairenv.policy_loading.load_policy`) as a report, each episode (:class:`TrackingEpisode`)
    in its details. ``push_speed`` (m/s, 0 = none): one kick per episode (:mod:`stairenv.evaluation.pushes`);
    the settings then record the speed, the window of steps and how many episodes it reached. ``num_envs``,
    ``physics`` and ``physics_device``: as :func:`tracking_errors`'s."""
    push_speed = check_push_speed(push_speed)
    label = label or policy_label(policy)
    if isinstance(policy, (str, os.PathLike)):
        probe = gym.make(env_id, **(env_kwargs or {}))
        try:
            policy = load_policy(os.fspath(policy), probe, seed=seed)
        finally:
            probe.close()
    rows, details = _tracking(policy, terrains, locomotions, episodes, seed, env_id, max_episode_steps, env_kwargs,
                              progress_bar, constant_paths, push_speed, num_envs, physics, physics_device)
    batched = num_envs > 1 and not callable(getattr(policy, "reset", None))
    settings = {"env_id": env_id, "episodes": episodes, "seed": seed, "env_kwargs": dict(env_kwargs or {}),
                "max_episode_steps": max_episode_steps, "constant_paths": constant_paths,
                "num_envs": int(num_envs) if batched else 1, "physics": physics, "physics_device": physics_device,
                **push_meta(push_speed, sum(e.push_step is not None for e in details))}
    return Report(label, rows, LAYOUT, details, meta={"table": "tracking", "label": label, "settings": settings})


def format_rows(rows: Sequence[Mapping[str, Any]]) -> str:
    """The table of :func:`tracking_errors` rows."""
    return Report("", list(rows), LAYOUT).format_table()


def write_rows(rows: Sequence[Mapping[str, Any]], csv_path: str | Path | None = None,
               json_path: str | Path | None = None, label: str = "") -> None:
    """Write :func:`tracking_errors` rows as CSV and / or the report's JSON."""
    report = Report(label, list(rows), LAYOUT, meta={"table": "tracking", "label": label})
    if csv_path is not None:
        report.to_csv(csv_path)
    if json_path is not None:
        report.to_json(json_path)


class _SceneRun:
    """One scene episode's bookkeeping (the sequential and the batched run share it)."""

    def __init__(self, index: int, info: dict[str, Any]) -> None:
        self.index, self.planned, self.info = index, float(info["planned_time"]), info

    def before_step(self, env: Any) -> None:
        pass

    def update(self, reward: float, terminated: bool, truncated: bool, info: dict[str, Any]) -> bool:
        self.info = info
        return bool(terminated or truncated)

    def result(self) -> _SceneRun:
        return self


def scene_episodes(
    policy: Callable[[np.ndarray], Any],
    episodes: int = 20,
    seed: int = 0,
    env_kwargs: dict[str, Any] | None = None,
    max_episode_steps: int | None = None,
    label: str = "",
    num_envs: int = 1,
) -> dict[str, Any]:
    """Run ``PlaMoScene-v0`` episodes: success rate, mean completion time of successes, replans
    (detours and waits), waits, and checks where neither a detour nor a wait avoided the ball.
    ``num_envs`` > 1: the episodes run on that many worlds of the batched env side by side
    (:mod:`stairenv.evaluation.worlds`; the same scenes and, for a policy that acts on each row of a batch
    as on that observation alone, the same episodes)."""
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    num_envs = check_num_envs(num_envs)
    make_kwargs = dict(env_kwargs or {})
    if max_episode_steps is not None:
        make_kwargs["max_episode_steps"] = max_episode_steps
    runs: list[_SceneRun] = []
    if num_envs > 1 and not callable(getattr(policy, "reset", None)):
        vec = gym.make_vec("PlaMoScene-v0", num_envs=min(num_envs, episodes), vectorization_mode="vector_entry_point",
                           **make_kwargs)
        try:
            run_on_worlds(vec, policy, [(i, seed + i) for i in range(episodes)],
                          lambda k, i, s, info: _SceneRun(i, info), runs.append)
        finally:
            vec.close()
    else:
        env = gym.make("PlaMoScene-v0", **make_kwargs)
        try:
            for episode in range(episodes):
                if callable(getattr(policy, "reset", None)):
                    policy.reset(seed + episode)
                obs, info = env.reset(seed=seed + episode)
                run = _SceneRun(episode, info)
                while True:
                    obs, reward, terminated, truncated, info = env.step(np.asarray(policy(obs)))
                    if run.update(reward, terminated, truncated, info):
                        break
                runs.append(run)
        finally:
            env.close()
    runs.sort(key=lambda run: run.index)
    ends = [run.info for run in runs]
    times = [info["time"] for info in ends if info["success"]]
    return {
        "label": label, "episodes": episodes, "success_pct": 100.0 * sum(bool(info["success"]) for info in ends) / episodes,
        "completion_time_s": float(np.mean(times)) if times else None,
        "planned_time_s": float(np.mean([run.planned for run in runs])),
        "replans_per_episode": float(np.mean([info["replans"] for info in ends])),
        "waits_per_episode": float(np.mean([info["waits"] for info in ends])),
        "replan_failures_per_episode": float(np.mean([info["replan_failures"] for info in ends])),
    }


def slalom_comparison(policy: Callable[[np.ndarray], Any], episodes: int = 10, seed: int = 0,
                      constant_speeds: Sequence[float] = (1.0, 2.0, 3.0, 4.0),
                      max_episode_steps: int | None = None, num_envs: int = 1) -> list[dict[str, Any]]:
    """PlaMo's slalom test: the planned (QP) speed profile against constant speeds along the same path."""
    rows = [scene_episodes(policy, episodes, seed, {"scene_kind": "slalom"}, max_episode_steps, "planned speed",
                           num_envs)]
    for speed in constant_speeds:
        rows.append(scene_episodes(policy, episodes, seed,
                                   {"scene_kind": "slalom", "speed_profile": "constant", "constant_speed": speed},
                                   max_episode_steps, f"constant {speed:g} m/s", num_envs))
    return rows


def scene_report(rows: Sequence[Mapping[str, Any]], label: str = "", settings: Mapping[str, Any] | None = None
                 ) -> Report:
    """Scene-episode rows (:func:`scene_episodes`, :func:`slalom_comparison`) as a report."""
    return Report(label, list(rows), SCENE_LAYOUT, meta={"table": "scenes", "label": label,
                                                         "settings": dict(settings or {})})


def format_scene_rows(rows: Sequence[Mapping[str, Any]]) -> str:
    """The table of scene-episode rows."""
    return scene_report(rows).format_table()


def plot_planned_path(env_kwargs: dict[str, Any] | None = None, seed: int = 0, path: str | Path = "plamo_plan.png"):
    """A top view of a scene with the planned head path coloured by speed (as PlaMo's Fig. 8); returns the path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    env = gym.make("PlaMoScene-v0", **(env_kwargs or {})).unwrapped
    env.reset(seed=seed)
    scene, traj = env.scene, env.trajectory
    xmin, xmax, ymin, ymax = scene.bounds
    fig, ax = plt.subplots(figsize=(7, 7))
    ax.imshow(scene.heights, origin="lower", extent=(xmin, xmax, ymin, ymax), cmap="Greys", alpha=0.6)
    for wall in scene.walls:
        corners = wall.corners_xy()
        ax.fill(corners[:, 0], corners[:, 1], color="saddlebrown")
    for ceiling in scene.ceilings:
        corners = ceiling.corners_xy()
        ax.fill(corners[:, 0], corners[:, 1], color="tab:blue", alpha=0.25)
    for landmark in scene.landmarks:
        ax.add_patch(plt.Circle(landmark.center, landmark.radius, color="tab:green", alpha=0.5))
        ax.annotate(landmark.name, landmark.center, ha="center")
    sc = ax.scatter(traj.xyz[:, 0], traj.xyz[:, 1], c=traj.v, cmap="viridis", s=6)
    fig.colorbar(sc, ax=ax, label="planned speed (m/s)")
    ax.set_title(env.instructions_text, fontsize=9)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)
    return Path(path)


__all__ = [
    "LAYOUT", "LOCOMOTIONS", "PAPER_TABLE2", "ROW_FIELDS", "SCENE_FIELDS", "SCENE_LAYOUT", "TERRAINS",
    "TRACKING_TERRAIN_SIZE", "TrackingEpisode", "evaluate",
    "format_rows", "format_scene_rows", "plot_planned_path", "scene_episodes", "scene_report", "slalom_comparison",
    "tracking_errors", "write_rows",
]
