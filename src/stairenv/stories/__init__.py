"""Acting out SIMS scripts and stories in a room: the state machine and the kinematic stand-in.

* :mod:`~stairenv.stories.machine` - :class:`StoryRunner` (the SIMS finite state machine,
  Sec. 3.4: one skill policy after another, moving on once a keyframe has held its goal),
  :func:`run_script` (room retrieval, binding, env, runner), policies and results;
* :mod:`~stairenv.stories.standin` - :class:`KinematicStandIn` (:data:`KINEMATIC`), a
  placeholder policy that writes poses and is NOT physics-based.

Both drive a :class:`~stairenv.environments.sims.SIMSEnv` through its public methods. The
scripts, their schema, embeddings and room retrieval are :mod:`stairenv.screenplays`, which does
not import this package.

Example::

    from stairenv.screenplays import load_database
    from stairenv.stories import KINEMATIC, run_script

    result = run_script(load_database().get("tired_bedtime"), KINEMATIC, seed=0)
"""

from stairenv.stories.machine import (
    INTERACTIONS,
    OUTCOMES,
    ROOM_CAMERA,
    BindingError,
    KeyframeResult,
    MachineSettings,
    StoryResult,
    StoryRunner,
    VideoWriter,
    as_policy,
    describe_policy,
    load_skill_policies,
    policy_specs,
    run_script,
    story_room,
)
from stairenv.stories.standin import KINEMATIC, KinematicStandIn

__all__ = [
    "INTERACTIONS",
    "KINEMATIC",
    "OUTCOMES",
    "ROOM_CAMERA",
    "BindingError",
    "KeyframeResult",
    "KinematicStandIn",
    "MachineSettings",
    "StoryResult",
    "StoryRunner",
    "VideoWriter",
    "as_policy",
    "describe_policy",
    "load_skill_policies",
    "policy_specs",
    "run_script",
    "story_room",
]
