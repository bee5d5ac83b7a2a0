"""PlaMo's physics against InterLevel's, its env step against its physics, PlaMoScene's reset: ratios from one run.

    python benchmarks/bench_plamo_physics.py [--seeds 3] [--ground-steps 200] [--walk-steps 300] [--rounds 5]
                                             [--env-seeds 8] [--env-steps 300] [--resets 30] [--json out.json]

1. **Physics per step** (``mj_step`` x frame_skip, nothing else): the env's own model and a recorded state are
   copied, then the recorded ctrl is replayed on the copy. Cases: InterLevel-v0, and PlaMo-v0 on each terrain
   (flat, slope, rough, stairs, mixed), in three modes:
   - ``walk``: the shipped policy (``stairenv.pretrained.load``) drives the env from seeded resets (PlaMo-v0 on
     walk paths, ``locomotion="walk"``) until its episode ends or ``--walk-steps``; the ctrl it wrote is
     replayed (each segment checked to end in the env's own state, bit for bit);
   - ``ground``: after a seeded reset, a collapse (1.5 s of zero PD targets, not timed), then ``--ground-steps``
     of small random targets (uniform in +-0.1 rad), as issue #54 measured it (3 seeds x 200 steps);
   - ``hill`` (PlaMo only): the same collapse with the character moved 1 m off the centre of the tile at
     (2, 2) m first: on the slope's hill or the stairs (the starts, near the origin, are at tile corners).
   Where the env keeps its terrain's tiles near the character (``TerrainSlots``), the replay brings them in
   before each step as the env's step does (``focus``, timed with the physics).
   Printed: us a step, contacts a step (``data.ncon`` after each step), and PlaMo / InterLevel per mode
   (the median over rounds of each round's ratio; cases interleaved, their order rotated every round).
2. **Env step / physics** for PlaMo-v0 (its preset) and PlaMoScene-v0: the shipped policy's actions are
   recorded once per seeded episode; then ``env.step`` (``gym.make``, wrappers included) is timed against the
   raw replay of the same ctrl from the same seeded reset (the scene's ball moved as the env moves it), both
   checked to end in the same state; rounds alternate which goes first.
3. **PlaMoScene-v0 reset**: ``reset()`` as a trainer calls it (no seed: a new scene every
   ``scene_resample_every`` = 10 resets), in ms, and a seeded reset (always a new scene) apart.
Targets (issue #54, item 0): PlaMo / InterLevel physics <= 1.15 walking and on the ground; env / physics <= 1.15
for PlaMo-v0 and PlaMoScene-v0; a PlaMoScene reset <= 3 ms.
"""

from __future__ import annotations

import argparse
import copy
import json
import statistics
import time
from dataclasses import dataclass, field

import gymnasium as gym
import mujoco
import numpy as np

import stairenv  # noqa: F401  (registers the envs)
from stairenv import pretrained

TERRAINS = ("flat", "slope", "rough", "stairs", "mixed")
STATE = mujoco.mjtState.mjSTATE_INTEGRATION
COLLAPSE_STEPS = 45      # 1.5 s of zero PD targets before the timed steps
SMALL_TARGETS = 0.1      # rad


@dataclass
class Segment:
    """A model (copied with its terrain), a state and the ctrl (and mocap positions) to replay from it."""

    model: mujoco.MjModel
    state: np.ndarray
    ctrls: np.ndarray
    frame_skip: int
    mocap: np.ndarray | None = None
    end: bytes | None = None     # the env's own end state, where it has one
    slots: object = None         # the env's terrain slots (``TerrainSlots``) as they were, where it has them


@dataclass
class Case:
    name: str
    mode: str
    segments: list[Segment] = field(default_factory=list)
    times: list[float] = field(default_factory=list)
    contacts: float = 0.0

    @property
    def steps(self) -> int:
        return sum(len(s.ctrls) for s in self.segments)


def terrain_slots(env):
    """A copy of the env's terrain slots as they are now (None for an env without them)."""
    slots = getattr(env.unwrapped, "_terrain_slots", None)
    return None if slots is None else copy.deepcopy(slots)


def get_state(model, data) -> np.ndarray:
    state = np.empty(mujoco.mj_stateSize(model, STATE))
    mujoco.mj_getState(model, data, state, STATE)
    return state


def end_state(data) -> bytes:
    return data.qpos.tobytes() + data.qvel.tobytes() + np.float64(data.time).tobytes()


def replay(segment: Segment, count_contacts: bool = False) -> tuple[float, float, bytes]:
    """Seconds for the segment's steps, mean contacts a step (if asked), the end state."""
    model = segment.model
    data = mujoco.MjData(model)
    mujoco.mj_setState(model, data, segment.state, STATE)
    mujoco.mj_forward(model, data)
    contacts = 0
    mocap = segment.mocap
    slots = None if segment.slots is None else copy.deepcopy(segment.slots)
    root = data.qpos[:2]
    start = time.perf_counter()
    for k, ctrl in enumerate(segment.ctrls):
        data.ctrl[:] = ctrl
        if mocap is not None:
            data.mocap_pos[:] = mocap[k]
        if slots is not None:    # the tiles within reach in the model, as the env's step puts them
            slots.focus(model, root)
        mujoco.mj_step(model, data, segment.frame_skip)
        if count_contacts:
            contacts += data.ncon
    elapsed = time.perf_counter() - start
    return elapsed, contacts / max(len(segment.ctrls), 1), end_state(data)


def make_env(env_id: str, terrain: str | None, **kwargs):
    if env_id.startswith("PlaMo") and terrain is not None:
        kwargs["terrain"] = terrain
    return gym.make(env_id, **kwargs)


def record_walk(env_id: str, terrain: str | None, seeds: int, steps: int) -> list[Segment]:
    kwargs = {"locomotion": "walk"} if env_id == "PlaMo-v0" else {}
    env = make_env(env_id, terrain, **kwargs)
    policy = pretrained.load(env_id)
    u = env.unwrapped
    segments = []
    for seed in range(seeds):
        obs, _ = env.reset(seed=seed)
        model, slots = copy.copy(u.model), terrain_slots(env)
        state = get_state(u.model, u.data)
        ctrls = []
        for _ in range(steps):
            obs, _, terminated, truncated, info = env.step(np.asarray(policy(obs), dtype=np.float64))
            ctrls.append(u.data.ctrl.copy())
            if terminated or truncated:
                break
        segments.append(Segment(model, state, np.array(ctrls), u.frame_skip, end=end_state(u.data), slots=slots))
    env.close()
    return segments


def collapse_segment(env, seed: int, steps: int, shift=None) -> Segment:
    """The env's seeded start, optionally moved to ``shift`` (x, y) and onto the ground there; a collapse
    under zero targets (not recorded); then ``steps`` of small random targets to replay."""
    u = env.unwrapped
    env.reset(seed=seed)
    model, data = u.model, u.data
    if shift is not None:
        ground = u.ground_height
        old = np.asarray(data.qpos[:2]).copy()
        new = np.asarray(shift, dtype=float)
        lift = float(np.max(ground(new + 0.5 * np.array([[0, 0], [1, 0], [-1, 0], [0, 1], [0, -1]]))))
        data.qpos[:2] = new
        data.qpos[2] += lift - float(ground(old))
    slots = getattr(u, "_terrain_slots", None)
    data.ctrl[:] = 0.0
    for _ in range(COLLAPSE_STEPS):
        if slots is not None:
            slots.focus(model, data.qpos[:2])
        mujoco.mj_step(model, data, u.frame_skip)
    rng = np.random.default_rng(1000 + seed)
    ctrls = rng.uniform(-SMALL_TARGETS, SMALL_TARGETS, (steps, model.nu))
    return Segment(copy.copy(model), get_state(model, data), ctrls, u.frame_skip, slots=terrain_slots(env))


def record_ground(env_id: str, terrain: str | None, seeds: int, steps: int, shift=None) -> list[Segment]:
    env = make_env(env_id, terrain)
    segments = [collapse_segment(env, seed, steps, shift) for seed in range(seeds)]
    env.close()
    return segments


def physics_cases(args) -> list[Case]:
    cases = []
    ids = [("InterLevel-v0", None)] + [("PlaMo-v0", t) for t in TERRAINS]
    for env_id, terrain in ids:
        name = env_id if terrain is None else f"{env_id} {terrain}"
        cases.append(Case(name, "walk", record_walk(env_id, terrain, args.seeds, args.walk_steps)))
        cases.append(Case(name, "ground", record_ground(env_id, terrain, args.seeds, args.ground_steps)))
        if terrain in ("slope", "stairs", "rough", "mixed"):
            # the tile whose centre is near (2, 2): 1 m off its centre along x
            cases.append(Case(name, "hill", record_ground(env_id, terrain, args.seeds, args.ground_steps,
                                                          shift=(2.95, 1.95))))
    for case in cases:    # the replays reproduce the env's own runs; contacts counted on the way
        contacts = 0.0
        for k, segment in enumerate(case.segments):
            _, mean_contacts, end = replay(segment, count_contacts=True)
            if segment.end is not None and end != segment.end:
                raise RuntimeError(f"{case.name} {case.mode} segment {k}: the replay left the env's trajectory")
            contacts += mean_contacts * len(segment.ctrls)
        case.contacts = contacts / max(case.steps, 1)
    return cases


def time_physics(cases: list[Case], rounds: int) -> None:
    for r in range(rounds):
        order = cases[r % len(cases):] + cases[:r % len(cases)]
        if r % 2:
            order = order[::-1]
        for case in order:
            elapsed = sum(replay(s)[0] for s in case.segments)
            case.times.append(elapsed / case.steps)


# --- env step against its physics ------------------------------------------------------------------
def record_episodes(env_id: str, seeds: int, steps: int) -> list[tuple[int, np.ndarray]]:
    env = gym.make(env_id)
    policy = pretrained.load(env_id)
    episodes = []
    for seed in range(seeds):
        obs, _ = env.reset(seed=seed)
        actions = []
        for _ in range(steps):
            action = np.asarray(policy(obs), dtype=np.float64)
            actions.append(action)
            obs, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                break
        episodes.append((seed, np.array(actions)))
    env.close()
    return episodes


def time_env(env, episodes) -> tuple[float, list[bytes]]:
    total, steps, ends = 0.0, 0, []
    for seed, actions in episodes:
        env.reset(seed=seed)
        start = time.perf_counter()
        for action in actions:
            env.step(action)
        total += time.perf_counter() - start
        steps += len(actions)
        ends.append(end_state(env.unwrapped.data))
    return total / steps, ends


def time_raw(env, episodes, mocaps) -> tuple[float, list[bytes]]:
    """The env's ctrl for the same actions (its action map), replayed from the same seeded reset."""
    u = env.unwrapped
    total, steps, ends = 0.0, 0, []
    for (seed, actions), mocap in zip(episodes, mocaps):
        env.reset(seed=seed)
        model, data, frame_skip = u.model, u.data, u.frame_skip
        ctrls = u._ctrl_offset + u._ctrl_scale * actions
        slots, root = getattr(u, "_terrain_slots", None), data.qpos[:2]
        start = time.perf_counter()
        for k, ctrl in enumerate(ctrls):
            data.ctrl[:] = ctrl
            if mocap is not None:
                data.mocap_pos[:] = mocap[k]
            if slots is not None:    # the tiles within reach in the model, as the env's step puts them
                slots.focus(model, root)
            mujoco.mj_step(model, data, frame_skip)
        total += time.perf_counter() - start
        steps += len(actions)
        ends.append(end_state(data))
    return total / steps, ends


def mocap_positions(env, episodes) -> list[np.ndarray | None]:
    """Where the env puts the scene's mocap bodies before each step's physics (None: it has none)."""
    u = env.unwrapped
    out = []
    for seed, actions in episodes:
        env.reset(seed=seed)
        if not u.model.nmocap:
            out.append(None)
            continue
        rows = []
        for action in actions:
            env.step(action)
            rows.append(u.data.mocap_pos.copy())
        out.append(np.array(rows))
    return out


def env_over_physics(env_id: str, args) -> dict[str, float]:
    episodes = record_episodes(env_id, args.env_seeds, args.env_steps)
    env = gym.make(env_id)
    mocaps = mocap_positions(env, episodes)
    time_env(env, episodes)     # warm up
    env_t, raw_t = [], []
    for r in range(args.rounds):
        timers = {"env": lambda: time_env(env, episodes), "raw": lambda: time_raw(env, episodes, mocaps)}
        order = ("env", "raw") if r % 2 == 0 else ("raw", "env")
        timed = {name: timers[name]() for name in order}
        if timed["env"][1] != timed["raw"][1]:
            raise RuntimeError(f"{env_id} round {r}: the env and the raw replay ended in different states")
        env_t.append(timed["env"][0])
        raw_t.append(timed["raw"][0])
    env.close()
    return {"env_step_us": statistics.median(env_t) * 1e6, "physics_us": statistics.median(raw_t) * 1e6,
            "env_over_physics": statistics.median(e / p for e, p in zip(env_t, raw_t)),
            "steps": int(sum(len(a) for _, a in episodes))}


def scene_resets(args) -> dict[str, float]:
    env = gym.make("PlaMoScene-v0")
    env.reset(seed=0)
    unseeded, seeded = [], []
    for r in range(args.rounds):
        start = time.perf_counter()
        for _ in range(args.resets):
            env.reset()
        unseeded.append((time.perf_counter() - start) / args.resets)
        start = time.perf_counter()
        env.reset(seed=1000 + r)
        seeded.append(time.perf_counter() - start)
    env.close()
    return {"reset_ms": statistics.median(unseeded) * 1e3, "seeded_reset_ms": statistics.median(seeded) * 1e3}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--ground-steps", type=int, default=200)
    parser.add_argument("--walk-steps", type=int, default=300)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--env-seeds", type=int, default=8)
    parser.add_argument("--env-steps", type=int, default=300)
    parser.add_argument("--resets", type=int, default=30)
    parser.add_argument("--json", default=None)
    args = parser.parse_args()

    cases = physics_cases(args)
    for case in cases:    # warm up
        replay(case.segments[0])
    time_physics(cases, args.rounds)
    base = {case.mode: case for case in cases if case.name == "InterLevel-v0"}
    results: dict = {"physics": [], "mujoco": mujoco.__version__}
    print(f"physics per step (mj_step x frame_skip, replayed; medians of {args.rounds} rounds)")
    print(f"{'case':24s} {'mode':7s} {'us/step':>8s} {'contacts':>8s} {'steps':>6s} {'/InterLevel':>11s}")
    for case in cases:
        ref = base["ground" if case.mode == "hill" else case.mode]
        ratio = statistics.median(t / b for t, b in zip(case.times, ref.times))
        us = statistics.median(case.times) * 1e6
        print(f"{case.name:24s} {case.mode:7s} {us:8.1f} {case.contacts:8.1f} {case.steps:6d} {ratio:11.3f}")
        results["physics"].append({"case": case.name, "mode": case.mode, "us_per_step": us,
                                   "contacts": case.contacts, "steps": case.steps, "over_interlevel": ratio})
    print("  (hill: against InterLevel's ground; target: PlaMo / InterLevel <= 1.15 walking and on the ground)")

    print("env step / physics (shipped policy's actions, same trajectory, checked)")
    for env_id in ("PlaMo-v0", "PlaMoScene-v0"):
        row = env_over_physics(env_id, args)
        results[env_id] = row
        print(f"{env_id:14s} env {row['env_step_us']:8.1f} us  physics {row['physics_us']:8.1f} us  "
              f"env / physics {row['env_over_physics']:6.3f}  ({row['steps']} steps; target <= 1.15)")

    resets = scene_resets(args)
    results["PlaMoScene-v0 reset"] = resets
    print(f"PlaMoScene-v0 reset {resets['reset_ms']:8.2f} ms (a new scene every 10; target <= 3 ms), "
          f"seeded (new scene) {resets['seeded_reset_ms']:8.2f} ms")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=2)


if __name__ == "__main__":
    main()
