r"""Evaluate SIMS skill policies the way the SIMS paper does (Tables 1 and 2).

* **Table 1** (:func:`evaluate_skills`): for each skill, ``episodes`` episodes of its registered
  env (``SIMS-Sit-v0``, ...: one generated piece of furniture per scene, as SIMS trains and
  tests its skills). **Success rate (%)**: episodes whose primary contact came within the
  threshold at some step (``info["success_once"]``: 20 cm sit and reach, 30 cm lie; walk and
  get up, not in the paper, 20 cm on the pelvis target). **Contact error (m)**: the primary
  contact's distance to its target at the episode's last step, averaged over episodes; we
  also report the mean of each episode's smallest error, the falls (early terminations) and
  the unstable-physics truncations. With ``push_speed`` each episode's character is kicked once
  (:mod:`stairenv.evaluation.pushes`: the same push in the same episode for every policy).
* **Table 2** (:func:`evaluate_scripts`): the database's short scripts, grouped by difficulty
  (``Script.difficulty``: simple 2, mid 3-4, hard 5+ interactions), each run through the state
  machine (:mod:`stairenv.stories.machine`) in a room generated with the furniture it needs.
  **Success (%)**: scripts whose every keyframe succeeded; **contact error (m)**: the final
  error of the interaction keyframes (sit, lie, reach) that ran; **success steps**: interactions
  that succeeded per script (the paper's last column).

Both give a :class:`~stairenv.evaluation.report.Report` with rows of the columns of :data:`ROW_FIELDS`
(``table`` is "skills" or "scripts", ``group`` the skill or difficulty), written as CSV / JSON and
printed with the published numbers (:data:`PAPER_RESULTS`) beside ours on request; :func:`evaluate`
is Table 1 for the skill of one env. Policies are
specs for :func:`stairenv.policy_loading.load_policy` ("zero", "random", an SB3 .zip) or
callables, one for all skills or one per skill; ``"kinematic"`` is the state machine's
stand-in that writes qpos (not physics-based: it tests the pipeline, it is not a result).

Example::

    from stairenv.evaluation.sims import evaluate_skills, evaluate_scripts
    report = evaluate_skills("zero", skills=("sit", "lie"), episodes=10)
    print(report.format_table(compare_paper=True))
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import gymnasium as gym
import numpy as np

import stairenv  # noqa: F401  (registers the envs)
from stairenv.evaluation.pushes import EpisodePush, check_push_speed, push_meta
from stairenv.evaluation.report import Column, Layout, Report, write_reports
from stairenv.evaluation.report import merge_paper_rows as _merge_paper_rows
from stairenv.policy_loading import load_policy, policy_label
from stairenv.pretrained import with_trained_captions
from stairenv.screenplays.database import DIFFICULTIES
from stairenv.stories import KINEMATIC, KinematicStandIn, MachineSettings
from stairenv.tasks.sims import SKILL_ENV_IDS

#: Skills in Table 1 order (the paper's three first).
TABLE1_SKILLS: tuple[str, ...] = ("sit", "lie", "reach", "walk", "getup")

#: SIMS' published numbers: Table 1 (its "SIMS (ours)" row; 4096 trials with random text
#: conditions) and Table 2 (scripts by difficulty, 3D-FRONT scenes; success steps = interactions
#: completed). Walk and get up are not in the paper.
PAPER_RESULTS: dict[str, dict[str, dict[str, float]]] = {
    "skills": {
        "sit": {"success_pct": 90.0, "contact_error_m": 0.065},
        "lie": {"success_pct": 79.2, "contact_error_m": 0.089},
        "reach": {"success_pct": 95.2, "contact_error_m": 0.026},
    },
    "scripts": {
        "simple": {"success_pct": 74.3, "contact_error_m": 0.072, "success_steps": 1.5},
        "mid": {"success_pct": 42.2, "contact_error_m": 0.128, "success_steps": 3.1},
        "hard": {"success_pct": 31.5, "contact_error_m": 0.325, "success_steps": 4.2},
    },
}
PAPER_TRIALS = 4096

#: Columns of the result rows and the CSV, in order (None / empty where not defined).
ROW_FIELDS: tuple[str, ...] = (
    "table", "method", "group", "n", "success_pct", "contact_error_m", "min_contact_error_m",
    "success_steps", "fell_pct", "unstable_pct", "timeout_pct",
)

PolicySpec = str | os.PathLike | Callable[[np.ndarray], Any]


# --- per-run results ---------------------------------------------------------------------------
@dataclass(frozen=True)
class SkillEpisode:
    """One Table 1 episode."""

    skill: str
    index: int
    seed: int
    furniture: str | None       # the family touched (None: walk)
    success: bool               # success_once
    contact_error: float        # last valid step
    min_contact_error: float
    fell: bool
    unstable: bool
    steps: int
    success_time: float | None  # first success (s)
    push_step: int | None = None  # the step before which the push came (``push_speed``), None if none came
    push_angle: float | None = None  # its direction in the world's xy plane (rad)


@dataclass(frozen=True)
class ScriptRun:
    """One Table 2 script run through the state machine."""

    script_id: str
    difficulty: str
    seed: int
    success: bool
    interactions: int
    interactions_succeeded: int
    contact_error: float | None   # mean final error of the interaction keyframes that ran
    outcomes: tuple[str, ...]     # per keyframe
    seconds: float
    room: str | None


# --- policies ------------------------------------------------------------------------------------
def _per_skill(policy: PolicySpec | Mapping[str, PolicySpec], skills: Sequence[str]) -> dict[str, PolicySpec]:
    if isinstance(policy, Mapping):
        missing = [s for s in skills if s not in policy]
        if missing:
            raise ValueError(f"no policy for skill(s) {missing}; given for {sorted(policy)}")
        return {s: policy[s] for s in skills}
    if not isinstance(policy, (str, os.PathLike)) and not callable(policy):
        raise TypeError(f"policy must be a spec string, a callable or a mapping skill -> policy, got {policy!r}")
    return {s: policy for s in skills}


def _label(policies: Mapping[str, PolicySpec]) -> str:
    names = {policy_label(p, detailed=isinstance(p, str)) for p in policies.values()}
    return names.pop() if len(names) == 1 else "per-skill policies"


def _policy_names(policies: Mapping[str, PolicySpec]) -> dict[str, str]:
    return {s: policy_label(p, detailed=isinstance(p, str)) for s, p in policies.items()}


# --- Table 1 -------------------------------------------------------------------------------------
def _run_skill_episode(env: gym.Env, policy: Callable[[np.ndarray], Any], skill: str, seed: int,
                       index: int, push_speed: float = 0.0) -> SkillEpisode:
    if callable(getattr(policy, "reset", None)):
        policy.reset(seed)
    obs, info = env.reset(seed=seed)
    push = EpisodePush(seed, push_speed)
    error = best = float(info["contact_error"])
    success_time = float(info["time"]) if info["success"] else None
    fell = unstable = False
    steps = 0
    while True:
        push.before_step(env.unwrapped, steps)
        obs, _, terminated, truncated, info = env.step(np.asarray(policy(obs)))
        steps += 1
        unstable = bool(info.get("physics_unstable", False))
        if not unstable:  # an unstable step repeats the last valid error
            error = float(info["contact_error"])
            best = min(best, error)
            if info["success"] and success_time is None:
                success_time = float(info["time"])
        if terminated or truncated:
            fell = bool(info.get("fell", False)) and not unstable
            break
    return SkillEpisode(skill, index, seed, _family(env, info), bool(info["success_once"]), error, best, fell,
                        unstable, steps, success_time, push.step, push.angle)


def _family(env: gym.Env, info: Mapping[str, Any]) -> str | None:
    placed = env.unwrapped.furniture.get(info.get("furniture"))
    return None if placed is None else placed.family


def skill_row(skill: str, episodes: Sequence[SkillEpisode], label: str) -> dict[str, Any]:
    """The Table 1 row of one skill's episodes."""
    n = len(episodes)
    return {
        "table": "skills", "method": label, "group": skill, "n": n,
        "success_pct": 100.0 * sum(e.success for e in episodes) / n,
        "contact_error_m": float(np.mean([e.contact_error for e in episodes])),
        "min_contact_error_m": float(np.mean([e.min_contact_error for e in episodes])),
        "success_steps": None,
        "fell_pct": 100.0 * sum(e.fell for e in episodes) / n,
        "unstable_pct": 100.0 * sum(e.unstable for e in episodes) / n,
        "timeout_pct": None,
    }


def evaluate_skills(
    policy: PolicySpec | Mapping[str, PolicySpec],
    skills: Sequence[str] = TABLE1_SKILLS,
    episodes: int = 100,
    seed: int = 0,
    env_kwargs: Mapping[str, Any] | None = None,
    max_episode_steps: int | None = None,
    progress_bar: bool = False,
    label: str | None = None,
    policy_captions: bool = False,
    push_speed: float = 0.0,
) -> Report:
    """SIMS Table 1: success rate and contact error per skill over ``episodes`` episodes each.

    | keyword | default | meaning |
    |---|---|---|
    | policy | - | one spec / callable for all skills, or skill -> spec / callable ("kinematic": the stand-in) |
    | skills | sit, lie, reach, walk, getup | which skills (envs :data:`SKILL_ENV_IDS`) |
    | episodes | 100 | per skill; episode i is reset with ``seed + i`` |
    | env_kwargs | None | extra ``gym.make`` keywords for every skill env (e.g. ``text_encoder="hashing"``) |
    | max_episode_steps | None | time limit in steps (None: the preset's, 10 s; get up 5 s) |
    | policy_captions | False | each skill with the captions its exported policy recorded (else the env's) |
    | push_speed | 0.0 | m/s in [0, 10]: each episode's character is kicked once (:mod:`stairenv.evaluation.pushes`: a random step 30-179 and direction, both from the episode's seed; an episode that ends first gets none); 0 = no push |
    """
    if isinstance(episodes, bool) or not isinstance(episodes, (int, np.integer)) or episodes < 1:
        raise ValueError(f"episodes must be an integer >= 1, got {episodes!r}")
    for skill in skills:
        if skill not in SKILL_ENV_IDS:
            raise ValueError(f"skills must be among {list(SKILL_ENV_IDS)}, got {skill!r}")
    push_speed = check_push_speed(push_speed)
    specs = _per_skill(policy, skills)
    label = label or _label(specs)
    make_kwargs = dict(env_kwargs or {})
    if max_episode_steps is not None:
        make_kwargs["max_episode_steps"] = int(max_episode_steps)
    from tqdm.auto import tqdm

    rows, details, used_captions = [], [], {}
    bar = tqdm(total=episodes * len(skills), desc=f"SIMS skills: {label}", unit="ep", disable=not progress_bar)
    try:
        for skill in skills:
            env = gym.make(SKILL_ENV_IDS[skill], **make_kwargs)
            try:
                spec = specs[skill]
                if isinstance(spec, str) and spec == KINEMATIC:
                    act = KinematicStandIn(env.unwrapped)
                elif isinstance(spec, (str, os.PathLike)):
                    act = load_policy(os.fspath(spec), env, seed=seed)
                else:
                    act = spec
                skill_kwargs = with_trained_captions(make_kwargs, act) if policy_captions else make_kwargs
                if skill_kwargs is not make_kwargs:
                    env.close()
                    env = gym.make(SKILL_ENV_IDS[skill], **skill_kwargs)
                    used_captions[skill] = [list(pair) for pair in skill_kwargs["captions"]]
                results = []
                for i in range(episodes):
                    results.append(_run_skill_episode(env, act, skill, seed + i, i, push_speed))
                    bar.update(1)
            finally:
                env.close()
            rows.append(skill_row(skill, results, label))
            details.extend(results)
    finally:
        bar.close()
    settings = {"skills": list(skills), "episodes": episodes, "seed": seed, "env_kwargs": dict(env_kwargs or {}),
                "max_episode_steps": max_episode_steps, "policies": _policy_names(specs)}
    if policy_captions:
        settings["policy_captions"] = used_captions
    settings.update(push_meta(push_speed, sum(e.push_step is not None for e in details)))
    return _report("skills", label, rows, details, settings)


def evaluate(
    policy: PolicySpec,
    env_id: str = "SIMS-Sit-v0",
    episodes: int = 100,
    seed: int = 0,
    env_kwargs: Mapping[str, Any] | None = None,
    max_episode_steps: int | None = None,
    progress_bar: bool = False,
    label: str | None = None,
    push_speed: float = 0.0,
) -> Report:
    """SIMS Table 1 for the skill of ``env_id`` (its ``skill`` keyword, or the one in ``env_kwargs``),
    as :func:`evaluate_skills` runs it; ``env_kwargs`` go to the skill's env."""
    kwargs = dict(env_kwargs or {})
    skill = kwargs.pop("skill", None) or gym.spec(env_id).kwargs.get("skill")
    return evaluate_skills(policy, skills=[skill], episodes=episodes, seed=seed, env_kwargs=kwargs,
                           max_episode_steps=max_episode_steps, progress_bar=progress_bar, label=label,
                           push_speed=push_speed)


# --- Table 2 -------------------------------------------------------------------------------------
def script_row(group: str, runs: Sequence[ScriptRun], label: str) -> dict[str, Any]:
    """The Table 2 row of some script runs (a difficulty or "all")."""
    n = len(runs)
    errors = [r.contact_error for r in runs if r.contact_error is not None]
    failed = [r for r in runs if not r.success]
    return {
        "table": "scripts", "method": label, "group": group, "n": n,
        "success_pct": 100.0 * sum(r.success for r in runs) / n if n else None,
        "contact_error_m": float(np.mean(errors)) if errors else None,
        "min_contact_error_m": None,
        "success_steps": float(np.mean([r.interactions_succeeded for r in runs])) if n else None,
        "fell_pct": 100.0 * sum("fell" in r.outcomes for r in failed) / n if n else None,
        "unstable_pct": 100.0 * sum("unstable" in r.outcomes for r in failed) / n if n else None,
        "timeout_pct": 100.0 * sum("timeout" in r.outcomes for r in failed) / n if n else None,
    }


def evaluate_scripts(
    policies: PolicySpec | Mapping[str, PolicySpec],
    database: Sequence[Any] | None = None,
    difficulties: Sequence[str] = DIFFICULTIES,
    scripts_per_difficulty: int | None = None,
    repeats: int = 1,
    seed: int = 0,
    settings: MachineSettings | None = None,
    room_config: Any = None,
    env_kwargs: Mapping[str, Any] | None = None,
    progress_bar: bool = False,
    label: str | None = None,
) -> Report:
    """SIMS Table 2: run scripts through the state machine; success per difficulty.

    | keyword | default | meaning |
    |---|---|---|
    | policies | - | one spec / callable for all skills, or skill -> spec / callable ("kinematic": the stand-in) |
    | database | None | scripts (default: the shipped database) |
    | difficulties | simple, mid, hard | which buckets (``Script.difficulty``) |
    | scripts_per_difficulty | None | the first k scripts of each bucket (None: all) |
    | repeats | 1 | runs per script, each with its own generated room and seed |
    | settings | None | :class:`~stairenv.stories.MachineSettings` (dwell 1 s, 20 s per keyframe, stop at a failure) |
    | room_config | None | ``stairenv.world.rooms.RoomConfig`` for the generated rooms |
    | env_kwargs | None | extra ``SIMSEnv`` keywords (e.g. ``text_encoder="hashing"``) |

    Run k (over all scripts and repeats, in order) uses seed ``seed + k`` for its room and run.
    Rows: one per difficulty then ``"all"``.
    """
    from stairenv.environments.sims import SIMSEnv
    from stairenv.screenplays import load_database
    from stairenv.stories import load_skill_policies, run_script

    if isinstance(repeats, bool) or not isinstance(repeats, (int, np.integer)) or repeats < 1:
        raise ValueError(f"repeats must be an integer >= 1, got {repeats!r}")
    for d in difficulties:
        if d not in DIFFICULTIES:
            raise ValueError(f"difficulties must be among {list(DIFFICULTIES)}, got {d!r}")
    database = list(load_database() if database is None else database)
    chosen = []
    for d in difficulties:
        bucket = [s for s in database if s.difficulty == d]
        chosen.extend(bucket if scripts_per_difficulty is None else bucket[:int(scripts_per_difficulty)])
    if not chosen:
        raise ValueError(f"no scripts of difficulty {list(difficulties)} in the database")
    specs = _per_skill(policies, ("walk", "sit", "lie", "reach", "getup"))
    label = label or _label(specs)
    # Models are loaded once (spaces from an object-scene env with the same keywords).
    probe = SIMSEnv(skill="walk", **dict(env_kwargs or {}))
    try:
        resolved = load_skill_policies(specs, probe, seed=seed)
    finally:
        probe.close()
    from tqdm.auto import tqdm

    runs: list[ScriptRun] = []
    k = 0
    with tqdm(total=len(chosen) * repeats, desc=f"SIMS scripts: {label}", unit="script",
              disable=not progress_bar) as bar:
        for script in chosen:
            for _ in range(repeats):
                result = run_script(script, resolved, seed=seed + k, settings=settings, room_config=room_config,
                                    env_kwargs=env_kwargs)
                errors = [kf.contact_error for kf in result.interactions
                          if kf.outcome != "skipped" and kf.contact_error is not None]
                runs.append(ScriptRun(
                    script_id=script.id, difficulty=script.difficulty, seed=seed + k, success=result.success,
                    interactions=len(result.interactions), interactions_succeeded=result.interactions_succeeded,
                    contact_error=float(np.mean(errors)) if errors else None,
                    outcomes=tuple(kf.outcome for kf in result.keyframes), seconds=result.seconds, room=result.room,
                ))
                k += 1
                bar.update(1)
    rows = [script_row(d, [r for r in runs if r.difficulty == d], label) for d in difficulties]
    rows.append(script_row("all", runs, label))
    machine = asdict(settings or MachineSettings())
    info = {"difficulties": list(difficulties), "scripts_per_difficulty": scripts_per_difficulty, "repeats": repeats,
            "seed": seed, "env_kwargs": dict(env_kwargs or {}), "machine": machine,
            "policies": _policy_names(specs)}
    return _report("scripts", label, rows, runs, info)


# --- printing ------------------------------------------------------------------------------------
def paper_rows() -> list[dict[str, Any]]:
    """:data:`PAPER_RESULTS` as rows of :data:`ROW_FIELDS`."""
    rows = []
    for table, groups in PAPER_RESULTS.items():
        for group, values in groups.items():
            row = dict.fromkeys(ROW_FIELDS)
            row.update(table=table, method="SIMS (paper)", group=group, n=PAPER_TRIALS if table == "skills" else None,
                       **values)
            rows.append(row)
    return rows


#: The rows, CSV and table of SIMS Tables 1 and 2; the published row of the same table and group
#: stands before ours.
LAYOUT = Layout(
    fields=ROW_FIELDS,
    columns=(
        Column("Table", "table", text=True), Column("Method", "method", text=True),
        Column("Group", "group", text=True), Column("n", "n"),
        Column("Success (%)", "success_pct", 1), Column("Contact err (m)", "contact_error_m", 3),
        Column("Min err (m)", "min_contact_error_m", 3), Column("Success steps", "success_steps", 2),
        Column("Fell (%)", "fell_pct", 1), Column("Unstable (%)", "unstable_pct", 1),
        Column("Timeout (%)", "timeout_pct", 1),
    ),
    paper=paper_rows,
    match=("table", "group"),
)

def merge_paper_rows(rows: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """``rows`` with the published row of the same table and group placed before each."""
    return _merge_paper_rows(rows, LAYOUT)


def _report(table: str, label: str, rows: list[dict[str, Any]], details: list[Any],
            settings: dict[str, Any]) -> Report:
    return Report(label, rows, LAYOUT, details, {"table": table, "label": label, "settings": settings})

__all__ = [
    "LAYOUT", "PAPER_RESULTS", "PAPER_TRIALS", "ROW_FIELDS", "SKILL_ENV_IDS", "TABLE1_SKILLS",
    "ScriptRun", "SkillEpisode", "evaluate", "evaluate_scripts", "evaluate_skills", "merge_paper_rows",
    "paper_rows", "script_row", "skill_row", "write_reports",
]
