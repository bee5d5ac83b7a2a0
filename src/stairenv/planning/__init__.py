"""PlaMo planning: instructions -> segments -> grid paths -> refined, timed waypoints.

Stages (one module each): ``instructions`` (text -> segments), ``locomotion`` (the table
of head heights and speeds), ``costmap`` (a grid prepared for a locomotion), ``astar``,
``refine`` (string pulling, smoothing, head heights), ``speed`` (the QP), ``waypoints``
(timing), ``replan`` (dynamic obstacles); ``planner`` chains them.

Names are imported lazily so that ``stairenv.planning.grid`` stays light; the functions
``astar.astar`` and ``replan.replan`` share their module's name, import them from there.
"""

from __future__ import annotations

import importlib

_EXPORTS = {
    "PlanningGrid": "grid",
    "PlanningError": "errors",
    "InstructionError": "errors",
    "Locomotion": "locomotion",
    "LOCOMOTIONS": "locomotion",
    "get_locomotion": "locomotion",
    "Segment": "instructions",
    "parse_instructions": "instructions",
    "Costmap": "costmap",
    "build_costmap": "costmap",
    "refine_path": "refine",
    "speed_limits": "speed",
    "speed_profile": "speed",
    "Trajectory": "waypoints",
    "Waypoints": "waypoints",
    "timed_waypoints": "waypoints",
    "ConstantVelocityObstacle": "replan",
    "ClosedLoopObstacle": "replan",
    "predict_collision": "replan",
    "wait_for_obstacles": "replan",
    "Plan": "planner",
    "Planner": "planner",
    "PlannerSettings": "planner",
    "plan_path": "planner",
}

__all__ = tuple(sorted(_EXPORTS))


def __getattr__(name: str):
    if name in _EXPORTS:
        module = importlib.import_module(f"{__name__}.{_EXPORTS[name]}")
        value = getattr(module, name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
