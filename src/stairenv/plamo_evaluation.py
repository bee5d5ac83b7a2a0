"""Tracking errors of a path-following policy, as in PlaMo's Table 2.

For every terrain (flat, slope, rough, stairs) and locomotion (crawl,
crouch-walk, walk, run), ``tracking_errors`` runs ``episodes`` episodes of
``PlaMo-v0`` with that terrain and paths restricted to that locomotion, and
reports the mean horizontal (XY) and vertical (Z) distance between the head and
the path point due at each step, over all steps of all episodes. Published
numbers (PlaMo Table 2, e.g. walk on stairs 0.39 / 0.27 m) are in ``PAPER_TABLE2``.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import stairenv  # noqa: F401  (registers the envs)

TERRAINS: tuple[str, ...] = ("flat", "slope", "rough", "stairs")
LOCOMOTIONS: tuple[str, ...] = ("crawl", "crouch-walk", "walk", "run")
# The one published cell the brief quotes; the paper's Table 2 holds the rest.
PAPER_TABLE2: dict[tuple[str, str], tuple[float, float]] = {("stairs", "walk"): (0.39, 0.27)}


def tracking_errors(
    policy: Callable[[np.ndarray], Any],
    terrains: Sequence[str] = TERRAINS,
    locomotions: Sequence[str] = LOCOMOTIONS,
    episodes: int = 10,
    seed: int = 0,
    env_id: str = "PlaMo-v0",
    max_episode_steps: int | None = None,
) -> list[dict[str, Any]]:
    """One row per (terrain, locomotion): mean XY and Z error (m), steps, early terminations."""
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    rows = []
    for terrain in terrains:
        for locomotion in locomotions:
            kwargs: dict[str, Any] = {"terrain": terrain, "locomotion": locomotion}
            if max_episode_steps is not None:
                kwargs["max_episode_steps"] = max_episode_steps
            env = gym.make(env_id, **kwargs)
            xy, z, terminated_count = [], [], 0
            for episode in range(episodes):
                if callable(getattr(policy, "reset", None)):
                    policy.reset(seed + episode)
                obs, _ = env.reset(seed=seed + episode)
                while True:
                    obs, _, terminated, truncated, info = env.step(np.asarray(policy(obs)))
                    if not info["physics_unstable"]:
                        xy.append(info["xy_error"])
                        z.append(info["z_error"])
                    if terminated or truncated:
                        terminated_count += bool(terminated)
                        break
            env.close()
            paper = PAPER_TABLE2.get((terrain, locomotion))
            rows.append({
                "terrain": terrain, "locomotion": locomotion, "episodes": episodes, "steps": len(xy),
                "xy_error_m": float(np.mean(xy)), "z_error_m": float(np.mean(z)),
                "early_termination_pct": 100.0 * terminated_count / episodes,
                "paper_xy_error_m": None if paper is None else paper[0],
                "paper_z_error_m": None if paper is None else paper[1],
            })
    return rows


def format_rows(rows: Sequence[dict[str, Any]]) -> str:
    header = f"{'terrain':8s} {'locomotion':12s} {'XY err (m)':>10s} {'Z err (m)':>10s} {'ET (%)':>7s} {'paper XY/Z':>12s}"
    lines = [header, "-" * len(header)]
    for r in rows:
        paper = "-" if r["paper_xy_error_m"] is None else f"{r['paper_xy_error_m']:.2f}/{r['paper_z_error_m']:.2f}"
        lines.append(f"{r['terrain']:8s} {r['locomotion']:12s} {r['xy_error_m']:10.3f} {r['z_error_m']:10.3f} "
                     f"{r['early_termination_pct']:7.1f} {paper:>12s}")
    return "\n".join(lines)


def write_rows(rows: Sequence[dict[str, Any]], csv_path: str | Path | None = None,
               json_path: str | Path | None = None) -> None:
    if csv_path is not None:
        with open(csv_path, "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
    if json_path is not None:
        Path(json_path).write_text(json.dumps(list(rows), indent=2))


def scene_episodes(
    policy: Callable[[np.ndarray], Any],
    episodes: int = 20,
    seed: int = 0,
    env_kwargs: dict[str, Any] | None = None,
    max_episode_steps: int | None = None,
    label: str = "",
) -> dict[str, Any]:
    """Run ``PlaMoScene-v0`` episodes: success rate, mean completion time of successes, replans
    (detours and waits), waits, and checks where neither a detour nor a wait avoided the ball."""
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    make_kwargs = dict(env_kwargs or {})
    if max_episode_steps is not None:
        make_kwargs["max_episode_steps"] = max_episode_steps
    env = gym.make("PlaMoScene-v0", **make_kwargs)
    successes, times, replans, waits, failures, planned = 0, [], [], [], [], []
    for episode in range(episodes):
        if callable(getattr(policy, "reset", None)):
            policy.reset(seed + episode)
        obs, info = env.reset(seed=seed + episode)
        planned.append(info["planned_time"])
        while True:
            obs, _, terminated, truncated, info = env.step(np.asarray(policy(obs)))
            if terminated or truncated:
                break
        successes += bool(info["success"])
        if info["success"]:
            times.append(info["time"])
        replans.append(info["replans"])
        waits.append(info["waits"])
        failures.append(info["replan_failures"])
    env.close()
    return {
        "label": label, "episodes": episodes, "success_pct": 100.0 * successes / episodes,
        "completion_time_s": float(np.mean(times)) if times else None,
        "planned_time_s": float(np.mean(planned)), "replans_per_episode": float(np.mean(replans)),
        "waits_per_episode": float(np.mean(waits)), "replan_failures_per_episode": float(np.mean(failures)),
    }


def slalom_comparison(policy: Callable[[np.ndarray], Any], episodes: int = 10, seed: int = 0,
                      constant_speeds: Sequence[float] = (1.0, 2.0, 3.0, 4.0),
                      max_episode_steps: int | None = None) -> list[dict[str, Any]]:
    """PlaMo's slalom test: the planned (QP) speed profile against constant speeds along the same path."""
    rows = [scene_episodes(policy, episodes, seed, {"scene_kind": "slalom"}, max_episode_steps, "planned speed")]
    for speed in constant_speeds:
        rows.append(scene_episodes(policy, episodes, seed,
                                   {"scene_kind": "slalom", "speed_profile": "constant", "constant_speed": speed},
                                   max_episode_steps, f"constant {speed:g} m/s"))
    return rows


def format_scene_rows(rows: Sequence[dict[str, Any]]) -> str:
    header = (f"{'run':22s} {'n':>4s} {'success (%)':>11s} {'time (s)':>9s} {'planned (s)':>11s} {'replans':>8s} "
              f"{'waits':>6s} {'no way':>7s}")
    lines = [header, "-" * len(header)]
    for r in rows:
        time_s = "-" if r["completion_time_s"] is None else f"{r['completion_time_s']:.2f}"
        lines.append(f"{r['label']:22s} {r['episodes']:4d} {r['success_pct']:11.1f} {time_s:>9s} "
                     f"{r['planned_time_s']:11.2f} {r['replans_per_episode']:8.2f} {r['waits_per_episode']:6.2f} "
                     f"{r['replan_failures_per_episode']:7.2f}")
    return "\n".join(lines)


def plot_planned_path(env_kwargs: dict[str, Any] | None = None, seed: int = 0, path: str | Path = "plamo_plan.png"):
    """A top view of a scene with the planned head path coloured by speed (as PlaMo's Fig. 8); returns the path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    env = gym.make("PlaMoScene-v0", **(env_kwargs or {})).unwrapped
    env.reset(seed=seed)
    scene, traj = env.scene, env._trajectory
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
