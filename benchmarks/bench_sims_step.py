"""The SIMS envs' step cost over their physics: env step / raw ``mj_step`` x frame_skip, per id, in one run.

    python benchmarks/bench_sims_step.py [--ids SIMS-Sit-v0 ...] [--steps 600] [--rounds 5]
                                         [--policy walker|zero|random] [--json out.json]

For every SIMS id (default all of ``stairenv.ENV_IDS`` that start with ``SIMS-``):

1. a recording run: ``gym.make(id)`` (wrappers included) from a seeded reset, driven by ``--policy`` for
   ``--steps`` steps (resetting when an episode ends): ``walker``, the shipped SIMS walker
   (``stairenv.pretrained.load("SIMS-Walk-v0")``; every SIMS id has its 493-d observation and 28-d action,
   so it drives them all: on walk it walks to its goal, elsewhere it walks about the piece), ``zero`` or
   ``random`` (seeded uniform in [-1, 1]). Recorded per step: the action, the ctrl the env wrote, the
   ``MjData`` integration state at the start of the step (``mj_getState(mjSTATE_INTEGRATION)``) and the
   model and data the env stepped (a scene rebuild makes new ones);
2. rounds, interleaved (which goes first flips every round), each timing
   - ``env``: the same env from the same seeded reset, the recorded actions again (no policy in the
     loop), each ``env.step`` timed alone; the resets the episodes' ends call are timed apart (``reset``);
   - ``raw``: per recorded step, the start state restored (untimed), the recorded ctrl written (untimed),
     then ``mujoco.mj_step(model, data, frame_skip)`` on the model and data the env stepped in the recording
     (the timed env's seeded reset rebuilds its scenes: models of the same build), timed alone. Its
     end state must equal, bit for bit, the start state of the next step the env took in that episode
     (checked every round: the two time the same trajectory).
   Per round: the mean env step, the mean raw step and their ratio; printed are the medians over rounds, and
   ``best``: each step's fastest env time over the rounds summed over the fastest raw times (on a machine
   that other jobs load, a step's slowest times are theirs).

Why replay instead of a separate raw run: the env's episodes (falls, time limits, scene rebuilds every
``scene_resample_every`` resets) are what its physics costs; the replay steps exactly those states.
Issue target (the SIMS issue, item 0): env / raw <= 1.15 for every id.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
import warnings

import gymnasium as gym
import mujoco
import numpy as np

import stairenv
import stairenv.pretrained

STATE = mujoco.mjtState.mjSTATE_INTEGRATION
SIMS_IDS = tuple(i for i in stairenv.ENV_IDS if i.startswith("SIMS-"))


def _state(model, data) -> np.ndarray:
    out = np.empty(mujoco.mj_stateSize(model, STATE))
    mujoco.mj_getState(model, data, out, STATE)
    return out


class Recording:
    """One run of an env: per step its action, ctrl, start state and (model, data); the steps after which
    the episode ended (a reset followed)."""

    def __init__(self, env_id: str, steps: int, policy: str, seed: int) -> None:
        self.env_id, self.seed = env_id, seed
        env = self.env = gym.make(env_id)
        unwrapped = env.unwrapped
        self.frame_skip = unwrapped.frame_skip
        walker = stairenv.pretrained.load("SIMS-Walk-v0") if policy == "walker" else None
        rng = np.random.default_rng(seed)
        obs, _ = env.reset(seed=seed)
        self.actions, self.ctrls, self.starts, self.worlds, self.ends = [], [], [], [], []
        for k in range(steps):
            if walker is not None:
                action = np.asarray(walker(obs), dtype=np.float64)
            elif policy == "zero":
                action = np.zeros(env.action_space.shape)
            else:
                action = rng.uniform(-1.0, 1.0, env.action_space.shape)
            model, data = unwrapped.model, unwrapped.data
            self.actions.append(action)
            self.starts.append(_state(model, data))
            self.worlds.append((model, data))
            obs, _, terminated, truncated, _ = env.step(action)
            self.ctrls.append(data.ctrl.copy())
            if terminated or truncated:
                self.ends.append(k)
                obs, _ = env.reset()
        self.ends_set = set(self.ends)

    def time_env(self) -> tuple[np.ndarray, float, int]:
        """(seconds of each env step, seconds per reset, resets) of the recorded actions from the seeded reset."""
        env = self.env
        env.reset(seed=self.seed)
        clock = time.perf_counter
        steps = np.empty(len(self.actions))
        resetting = 0.0
        resets = 0
        for k, action in enumerate(self.actions):
            t0 = clock()
            _, _, terminated, truncated, _ = env.step(action)
            t1 = clock()
            steps[k] = t1 - t0
            if terminated or truncated:
                env.reset()
                resetting += clock() - t1
                resets += 1
        if resets != len(self.ends):
            raise RuntimeError(f"{self.env_id}: the timed run ended {resets} episodes, the recording {len(self.ends)}")
        return steps, resetting / max(resets, 1), resets

    def time_raw(self) -> np.ndarray:
        """Seconds of each ``mj_step(frame_skip)`` replaying the recorded ctrl from the recorded start states;
        ``RuntimeError`` where a step does not end in the state the env went on from."""
        clock = time.perf_counter
        n = len(self.actions)
        steps = np.empty(n)
        for k in range(n):
            model, data = self.worlds[k]
            mujoco.mj_setState(model, data, self.starts[k], STATE)
            data.ctrl[:] = self.ctrls[k]
            t0 = clock()
            mujoco.mj_step(model, data, self.frame_skip)
            steps[k] = clock() - t0
            if k + 1 < n and k not in self.ends_set:
                if _state(model, data).tobytes() != self.starts[k + 1].tobytes():
                    raise RuntimeError(f"{self.env_id}: raw step {k} does not end where the env's did")
        return steps


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--ids", nargs="+", default=list(SIMS_IDS))
    parser.add_argument("--steps", type=int, default=600)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--policy", choices=("walker", "zero", "random"), default="walker")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)
    warnings.filterwarnings("ignore")    # the unstable-physics warning, should a step of the policy diverge

    recordings = [Recording(env_id, args.steps, args.policy, args.seed) for env_id in args.ids]
    # one warm-up pass of each (compiled kernels, caches)
    for rec in recordings:
        rec.time_env()
        rec.time_raw()
    samples: dict[str, dict[str, list]] = {rec.env_id: {"env": [], "raw": [], "reset": []} for rec in recordings}
    for r in range(args.rounds):
        for rec in recordings:
            s = samples[rec.env_id]
            if r % 2 == 0:
                env_steps, reset, _ = rec.time_env()
                raw_steps = rec.time_raw()
            else:
                raw_steps = rec.time_raw()
                env_steps, reset, _ = rec.time_env()
            s["env"].append(env_steps)
            s["raw"].append(raw_steps)
            s["reset"].append(reset)

    print(f"policy: {args.policy}; {args.steps} steps per id, {args.rounds} rounds. env/raw: the median over rounds of "
          f"a round's mean env step / mean raw step;\nbest: each step's fastest time over the rounds, summed (what "
          f"other jobs' load on the machine adds to a step's time left out)")
    print(f"{'id':16s} {'env us':>8s} {'raw us':>8s} {'over us':>8s} {'env/raw':>8s} {'min':>6s} {'max':>6s} "
          f"{'best':>6s} {'resets':>6s} {'reset ms':>9s}")
    results = {"policy": args.policy, "steps": args.steps, "rounds": args.rounds, "ids": {}}
    for rec in recordings:
        s = samples[rec.env_id]
        env_means, raw_means = [float(x.mean()) for x in s["env"]], [float(x.mean()) for x in s["raw"]]
        ratios = [e / r for e, r in zip(env_means, raw_means)]
        env_us, raw_us = 1e6 * statistics.median(env_means), 1e6 * statistics.median(raw_means)
        ratio = statistics.median(ratios)
        best = float(np.min(s["env"], axis=0).sum() / np.min(s["raw"], axis=0).sum())
        reset_ms = 1e3 * statistics.median(s["reset"])
        results["ids"][rec.env_id] = {"env_step_us": env_us, "raw_step_us": raw_us, "ratio": ratio,
                                      "ratio_min": min(ratios), "ratio_max": max(ratios), "ratio_best": best,
                                      "resets": len(rec.ends), "reset_ms": reset_ms}
        print(f"{rec.env_id:16s} {env_us:8.1f} {raw_us:8.1f} {env_us - raw_us:8.1f} {ratio:8.3f} "
              f"{min(ratios):6.3f} {max(ratios):6.3f} {best:6.3f} {len(rec.ends):6d} {reset_ms:9.2f}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=2)
    return results


if __name__ == "__main__":
    sys.exit(main() and 0)
