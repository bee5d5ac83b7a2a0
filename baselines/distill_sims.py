#!/usr/bin/env python
"""Distil a SIMS skill's interaction clip, played back open-loop through the PD servos, into a SIMS actor
(DAgger), as the start of the skill's imitation-first run.

Played back from a frame of the clip made for the episode's piece (``interaction_start_fraction=1``: each
episode starts in such a frame, ``track_reward``: the env keeps the clip's frames in the world), each step's
PD targets the clip's joint angles one step ahead, the sit clip sits on the seat without a fall in most
starts (``docs/sims_training.md``, 2026-12-08). So the playback is the teacher: every visited state is
labelled with the playback's action for its own clip and time, and the student, an actor of the
``--template`` run's shape and observation normaliser, is fitted to the labels of the states it visits
(Ross et al. 2011; the loop is ``stairenv.training.dagger``'s). A world whose start found no frame that fits
its piece starts standing; its label is the template's own action, so that the student keeps the template's
behaviour where it has no clip. PPO (``train_ppo.py --init-from OUT``) then has to reach the piece
from a standing start and hold the contact goal.

    python baselines/distill_sims.py --template checkpoints/SIMS-Sit-v0/s13_checkpoint_6500352.pt \\
        --skill sit --out runs/sit_distilled.pt

With ``--walker`` (sit, lie) the standing starts get a teacher too, a script of three phases as the SIMS state
machine would run them: the walker (a SIMS-Walk run's checkpoint, shown a walk goal in place of the skill's)
walks to the spot where the clip's first frame stands (the seat's front edge), then to a goal out of the front
until it faces away from the piece (it turns round), then the clip plays back from its first frame. Half the
episodes start standing (``--standing-fraction``) so that the student learns the approach with the sit.
Measured on 2026-12-08 with the shipped walker (W9), the script is not yet a usable teacher: on 37 standing
starts it sat in 7 and fell in 27, at the furniture or while turning (the walker stops 0.5-1 m before its goal,
so it is shown a carrot 1 m beyond each waypoint, which takes it into the piece). It needs a walker that stops on
a mark and turns on the spot (issue #55 gate 1's gap):

    python baselines/distill_sims.py --template checkpoints/SIMS-Sit-v0/s13_checkpoint_6500352.pt \\
        --walker checkpoints/SIMS-Walk-v0/w9_checkpoint_1001472.pt --skill sit --out runs/sit_walk_distilled.pt
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
import torch

from stairenv.humanoid import STANDING_ROOT_HEIGHT
from stairenv.humanoid.state import PELVIS
from stairenv.motion.tracking import frames_in_world
from stairenv.rotations import wrap_angle
from stairenv.tasks.sims import JOINT, NUM_CONTACT_JOINTS

from stairenv.training.dagger import Student, add_arguments, distil, read_template
from stairenv.training.ppo import make_env

#: the env of each skill that has interaction clips
SKILL_ENVS = {"sit": "SIMS-Sit-v0", "lie": "SIMS-Lie-v0", "reach": "SIMS-Reach-v0"}
#: every episode starts in a frame of its clip, which the env keeps in the world (the tracking aid)
PLAYBACK_KWARGS = {"interaction_start_fraction": 1.0, "track_reward": 2.0, "max_track_error": 0.5}


def playback_action(env) -> np.ndarray | None:
    """The action whose PD targets are the world's start clip (the tracking aid's track) one step ahead, its
    last frame held once it ends; None for a world without a clip."""
    track = env._track
    if track is None:
        return None
    return env.action_of_targets(track.qpos[track.frame(env._steps + 1), 7:])


#: the approach script's bounds: a waypoint counts as reached within PASSED (m of the pelvis), the last one (the
#: clip's first frame) within ARRIVED, the turn as done within FACING (rad) of the clip's facing; the walk goes
#: round the piece on a circle CLEARANCE (m) outside its footprint, by at most ARC (rad) a waypoint, to a point
#: OUT (m) out of the front, then to the spot; the turn's walk goal lies OUT out of the front of the spot
PASSED, ARRIVED, FACING, CLEARANCE, ARC, OUT = 0.5, 0.45, math.radians(25.0), 0.8, math.radians(60.0), 0.8
CARROT = 1.0


def walk_view(env, obs: np.ndarray, goal_xy: np.ndarray, text: np.ndarray) -> np.ndarray:
    """``obs`` of a SIMS world as a SIMS-Walk policy sees a walk goal at ``goal_xy``: the same proprioception and
    heightmap, the skill's goal replaced by a pelvis target at standing height (relative to the root, in the
    heading frame; the other joints masked out) and the text by ``text`` (the walker's caption's embedding)."""
    view = obs.copy()
    parts = env.observation_structure
    root, yaw = _root(env)
    c, s = math.cos(yaw), math.sin(yaw)
    rel = np.array([goal_xy[0] - root[0], goal_xy[1] - root[1], STANDING_ROOT_HEIGHT - root[2]])
    goals = np.zeros((NUM_CONTACT_JOINTS, 3))
    goals[JOINT["pelvis"]] = (c * rel[0] + s * rel[1], -s * rel[0] + c * rel[1], rel[2])
    mask = np.zeros(NUM_CONTACT_JOINTS)
    mask[JOINT["pelvis"]] = 1.0
    view[parts["goal_positions"]] = goals.ravel()
    view[parts["goal_mask"]] = mask
    view[parts["text"]] = text
    return view


def _root(env) -> tuple[np.ndarray, float]:
    """The pelvis' world position and yaw."""
    body = env._idx.body_ids[PELVIS]
    frame = env.data.xmat[body].reshape(3, 3)
    return env.data.xpos[body], math.atan2(frame[1, 0], frame[0, 0])


class ApproachScript:
    """One standing world's teacher: walk round the piece to the clip's first frame, turn to face away from the
    piece, play the clip back from its first frame."""

    def __init__(self, env, skill: str, rng: np.random.Generator) -> None:
        placed = env._target
        qpos, _, yaw, origin = env._seat_start_frames(rng, placed, skill)
        self.frames = frames_in_world(qpos, yaw, origin)
        self.facing = yaw
        out = np.array([math.cos(yaw), math.sin(yaw)])
        spot = self.frames[0, :2].copy()
        centre = np.asarray(placed.pose[:2], dtype=np.float64)
        radius = math.hypot(*placed.furniture.footprint) + CLEARANCE
        start = _root(env)[0][:2]
        bearing = math.atan2(start[1] - centre[1], start[0] - centre[0])
        front = math.atan2(out[1], out[0])
        turn = float(wrap_angle(front - bearing))
        arcs = math.ceil(abs(turn) / ARC)
        self.waypoints = [centre + radius * np.array([math.cos(bearing + turn * i / arcs),
                                                      math.sin(bearing + turn * i / arcs)]) for i in range(1, arcs)]
        self.waypoints += [spot + OUT * out, spot]
        self.turn_goal = spot + OUT * out
        self.phase, self.played_from = "approach", 0

    def goal(self, env) -> np.ndarray | None:
        """The walk goal of this step (None once the clip plays), moving on where a waypoint or a phase is done."""
        root, heading = _root(env)
        if self.phase == "approach":
            last = len(self.waypoints) == 1
            if math.hypot(*(self.waypoints[0] - root[:2])) < (ARRIVED if last else PASSED):
                if last:
                    self.phase = "turn"
                else:
                    self.waypoints.pop(0)
        if self.phase == "turn" and abs(wrap_angle(heading - self.facing)) < FACING:
            self.phase, self.played_from = "play", env._steps
        if self.phase != "approach":
            return self.turn_goal if self.phase == "turn" else None
        # the walker slows down and stops ~0.5-1 m before its goal: it is shown a carrot CARROT (m) beyond the
        # waypoint, along the way to it
        ahead = self.waypoints[0] - root[:2]
        return self.waypoints[0] + CARROT * ahead / max(math.hypot(*ahead), 1e-6)

    def playback(self, env) -> np.ndarray:
        return env.action_of_targets(self.frames[min(env._steps - self.played_from + 1, len(self.frames) - 1), 7:])


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--template", type=Path, required=True,
                        help="a lean checkpoint of a SIMS run: the student's shape, normaliser and the rest")
    parser.add_argument("--skill", choices=sorted(SKILL_ENVS), default="sit",
                        help="the skill whose interaction clips are played back (default: %(default)s)")
    parser.add_argument("--walker", type=Path, default=None,
                        help="sit, lie: a SIMS-Walk run's checkpoint that walks the standing starts to the clip "
                             "(module docstring); default: none, every episode starts in a frame of its clip")
    parser.add_argument("--standing-fraction", type=float, default=0.5,
                        help="with --walker: share of the episodes that start standing (default: %(default)s)")
    parser.add_argument("--walk-caption", default="walk", help="with --walker: the text the walker is shown")
    add_arguments(parser)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    template, config = read_template(args.template)
    if not config.env_id.startswith("SIMS-"):
        print(f"--template: a SIMS run's checkpoint is needed, this one is {config.env_id}'s", file=sys.stderr)
        return 2
    if args.walker is not None and args.skill not in ("sit", "lie"):
        print("--walker: only sit and lie start from the seat's front edge", file=sys.stderr)
        return 2
    if not 0.0 <= args.standing_fraction < 1.0:
        print(f"--standing-fraction must be in [0, 1), got {args.standing_fraction}", file=sys.stderr)
        return 2
    # the template's aids that belong to its own skill (a walk's near zone and pushes) stay out
    kept = {key: value for key, value in config.env_kwargs.items() if key in ("init", "amp_history")}
    playback = dict(PLAYBACK_KWARGS)
    if args.walker is not None:
        playback["interaction_start_fraction"] = 1.0 - args.standing_fraction
    config = config.replace(env_id=SKILL_ENVS[args.skill], env_kwargs={**kept, **playback},
                            num_envs=args.n_envs, physics_threads=args.physics_threads, seed=args.seed)
    venv = make_env(config)
    worlds = [env.unwrapped for env in venv.envs]
    torch.manual_seed(args.seed)
    obs_size, action_size = venv.single_observation_space.shape[0], venv.single_action_space.shape[0]
    # the template's curriculum levels measured the template's episodes, not the student's: a run from the output
    # starts its own curriculum at level 0
    student = Student({**template, "curriculum_level": []}, config, obs_size, action_size, args.n_envs,
                      args.learning_rate)
    if args.walker is None:    # a world without a clip keeps the template's own action
        walker = Student(template, config, obs_size, action_size, args.n_envs, args.learning_rate)
    else:
        walker_template, walker_config = read_template(args.walker)
        walker = Student(walker_template, walker_config, obs_size, action_size, args.n_envs, args.learning_rate)
    text = worlds[0].embed_text(args.walk_caption)
    rng = np.random.default_rng(args.seed)
    scripts: dict[int, ApproachScript] = {}
    obs, _ = venv.reset(seed=args.seed)
    ended = {"episodes": 0, "fell": 0, "success": 0, "lost": 0, "standing": 0, "standing success": 0}
    phases = {"approach": 0, "turn": 0, "play": 0}
    clipped = []

    def teacher(obs: np.ndarray) -> np.ndarray:
        actions = [playback_action(env) for env in worlds]
        walking = []
        for k, env in enumerate(worlds):
            if actions[k] is not None:
                continue
            if args.walker is None:
                walking.append((k, obs[k]))
                continue
            if env._steps == 0 or k not in scripts:    # a new standing episode
                scripts[k] = ApproachScript(env, args.skill, rng)
            goal = scripts[k].goal(env)
            phases[scripts[k].phase] += 1
            if goal is None:
                actions[k] = scripts[k].playback(env)
            else:
                walking.append((k, walk_view(env, obs[k], goal, text)))
        if walking:
            own = walker(np.stack([view for _, view in walking]))
            for j, (k, _) in enumerate(walking):
                actions[k] = own[j]
        clipped.append(np.mean(np.abs(student.observations(obs)) >= student.normalizer.clip_obs))
        return np.stack(actions)

    def after_step(obs: np.ndarray, done: np.ndarray, infos: list) -> None:
        for i in np.flatnonzero(done):
            info = infos[i]
            standing = not info.get("interaction_start", True)
            ended["episodes"] += 1
            ended["fell"] += bool(info.get("fell"))
            ended["success"] += bool(info.get("success_once"))
            ended["lost"] += bool(info.get("track_lost"))
            ended["standing"] += standing
            ended["standing success"] += standing and bool(info.get("success_once"))
            scripts.pop(int(i), None)

    def after_iteration(iteration: int, beta: float, samples: int, loss: float, seconds: float) -> None:
        print(f"iteration {iteration}: teacher share {beta:.2f}, {samples:,} samples, episodes ended "
              f"{ended['episodes']} (success {ended['success']}, fell {ended['fell']}, clip lost {ended['lost']}; "
              f"standing {ended['standing']}, of them success {ended['standing success']}), scripted world-steps "
              f"{phases}, observations at the clip bound {100 * np.mean(clipped):.2f}%, fit loss {loss:.4f}, "
              f"{seconds:.0f} s", flush=True)
        ended.update(dict.fromkeys(ended, 0))
        phases.update(dict.fromkeys(phases, 0))
        clipped.clear()

    distil(venv, obs, student, teacher, args, after_step, after_iteration)
    return 0

if __name__ == "__main__":
    raise SystemExit(main())
