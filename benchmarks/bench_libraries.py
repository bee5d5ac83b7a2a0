"""The lean trainer against the field's libraries: PPO (and AMP) throughput on InterLevel-v0's batched env.

    python benchmarks/bench_libraries.py [--num-envs 128] [--iterations 10] [--rounds 2] [--seed 0]
                                         [--trainers lean,lean-amp,skrl,skrl-amp,rsl-rl] [--physics threads]

Issue #22's question before writing our own trainer: how fast do the field's libraries train on our
natively batched env (target: >= 5,000 env steps/s end to end on 2 cores, InterLevel-v0, PPO with the
training script's defaults)? Compared, every one on the same ``HumanoidVectorEnv`` (``gym.make_vec(
"InterLevel-v0", num_envs=N, vectorization_mode="vector_entry_point", autoreset_mode=SAME_STEP,
init="hybrid")``, one env built once and reset with the same seed before each run):

- ``lean``: ``stairenv.training.Trainer`` with ``TrainConfig(style="none")`` (PPO, task reward only) — the
  reference every ratio is taken to;
- ``lean-amp``: the same with ``style="amp"`` (the AMP discriminator on the env's reference windows, trained
  in the background as the training script does);
- ``skrl``: skrl's PPO agent (``skrl.agents.torch.ppo``) over ``skrl.envs.wrappers.torch.wrap_env(venv,
  wrapper="gymnasium")``, ``RandomMemory(memory_size=16)``, Gaussian / Deterministic model mixins,
  ``RunningStandardScaler`` for the observations and the values, no TensorBoard, no checkpoints; driven by
  the body of skrl's ``SequentialTrainer`` loop (act / step / record_transition / post_interaction) so that
  exactly K iterations are timed;
- ``skrl-amp``: skrl's AMP agent (``skrl.agents.torch.amp``) with the env's Isaac Lab-style
  ``amp_observation_space`` and ``collect_reference_motions``, ``info["amp_obs"]`` as the style windows;
- ``rsl-rl``: rsl-rl-lib's ``OnPolicyRunner`` (its ``PPO``, ``MLPModel`` actor and critic with empirical
  observation normalisation) over a thin ``rsl_rl.env.VecEnv`` adapter around ``step_worlds``.

Shared settings (the training script's defaults): policy and value separate MLPs (256, 256) ReLU, initial
log std -2, 16 steps per world per rollout, 5 epochs, minibatches of 1024 samples, Adam lr 1e-4 (fixed),
gamma 0.99, GAE lambda 0.95, clip 0.2, entropy 0, value loss weight 0.5, gradient-norm clip 1.0, no value
clipping, one torch thread, actions clipped to the action space, the same seed. Each run: build, one
warm-up iteration (collect + update), then ``--iterations`` timed iterations; the rate is
``iterations x rollout x num_envs / time``. Rounds are interleaved (round r runs every trainer once, the
order rotating between rounds); printed are each run's env steps/s and its split between rollout and
update, then the median over rounds and each trainer's median ratio to ``lean`` in the same round.
Run it on an idle machine: absolute rates move with the load, back-to-back ratios much less.

What differs between the libraries (their own conventions, kept as they are): skrl bootstraps
truncations from the next observation, which under SAME_STEP autoreset is the reset one, so its
``time_limit_bootstrap`` stays off (its default); rsl-rl bootstraps time-outs with the value of the
current observation; ours with the value of the ended step's own final observation. skrl normalises the
values (``value_preprocessor``), ours the rewards (VecNormalize's return scaling), rsl-rl neither. Each
library initialises its networks its own way (ours orthogonally, as SB3); skrl's Gaussian mixin clips the
sampled actions before their log-probability, ours and the rsl-rl adapter clip only what the env gets.
skrl-amp trains its discriminator inside every PPO minibatch (one optimiser for all networks, batch
256), ours 2 minibatches of 256 per 2048 transitions in a background thread. skrl steps through the
gymnasium ``step`` (the per-world info dicts stacked into arrays with masks, as ``SyncVectorEnv`` gives:
about 2 ms per step of 128 worlds), rsl-rl's adapter and ours through ``step_worlds`` (per-world dicts);
skrl-amp's windows are taken from ``info["amp_obs"]``, for the worlds reset in the step from
``info["final_info"]["amp_obs"]`` (the ended step's window, not the reset's).

The libraries are optional (the smoke test runs without them; a missing one is skipped with a note)::

    pip install skrl rsl-rl-lib        # skrl 2.x, rsl-rl-lib 5.x (with tensordict and GitPython)

(or installed elsewhere, e.g. ``pip install --target DIR``, then ``PYTHONPATH=DIR python
benchmarks/bench_libraries.py``; rsl-rl-lib imports GitPython at import time, so a ``--no-deps`` install
needs ``pip install GitPython`` beside it).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import logging
import math
import statistics
import tempfile
import time
from typing import Any, Callable

import gymnasium as gym
import numpy as np
import torch
from gymnasium.vector import AutoresetMode
from torch import nn

import stairenv  # noqa: F401  (registers the ids)
from stairenv.style.wrappers import default_reference
from stairenv.training import Trainer, TrainConfig, build_style

ENV_ID = "InterLevel-v0"
ENV_KWARGS = {"init": "hybrid"}    # the training script's default start (half standing, half reference)
DEFAULTS = TrainConfig(env_id=ENV_ID, env_kwargs=ENV_KWARGS, style="none")
TRAINERS = ("lean", "lean-amp", "skrl", "skrl-amp", "rsl-rl")


class Timing:
    """Seconds spent in the rollouts and in the updates of the timed iterations."""

    def __init__(self) -> None:
        self.rollout = 0.0
        self.update = 0.0

    def result(self, steps: int) -> dict[str, float]:
        total = self.rollout + self.update
        return {"rate": steps / total, "rollout_s": self.rollout, "update_s": self.update}


def _mlp(sizes: list[int]) -> nn.Sequential:
    layers: list[nn.Module] = []
    for a, b in zip(sizes[:-1], sizes[1:]):
        layers += [nn.Linear(a, b), nn.ReLU()]
    return nn.Sequential(*layers)


def minibatches(num_envs: int) -> int:
    """The number of minibatches of ``DEFAULTS.minibatch_size`` samples in one rollout (at least 1)."""
    return max(1, math.ceil(num_envs * DEFAULTS.rollout_steps / DEFAULTS.minibatch_size))


# --- ours --------------------------------------------------------------------------------------------
def run_lean(venv, args: argparse.Namespace, amp: bool = False) -> dict[str, float]:
    config = DEFAULTS.replace(num_envs=args.num_envs, seed=args.seed, physics=args.physics,
                              style="amp" if amp else "none")
    style = build_style(config, default_reference(venv)) if amp else None
    trainer = Trainer(config, style, venv=venv)
    try:
        trainer.collect()
        trainer.update()                       # warm-up
        timing = Timing()
        for _ in range(args.iterations):
            start = time.perf_counter()
            trainer.collect()
            middle = time.perf_counter()
            trainer.update()
            timing.rollout += middle - start
            timing.update += time.perf_counter() - middle
        if style is not None:                  # a discriminator round still training belongs to this run
            start = time.perf_counter()
            style.wait()
            timing.update += time.perf_counter() - start
        return timing.result(args.iterations * config.batch_size)
    finally:
        if style is not None:
            style.close()                      # not trainer.close(): the env is shared by every run


# --- skrl --------------------------------------------------------------------------------------------
def _skrl_models(env, device, amp_space=None) -> dict[str, Any]:
    from skrl.models.torch import DeterministicMixin, GaussianMixin, Model

    hidden = list(DEFAULTS.hidden)

    class Policy(GaussianMixin, Model):
        def __init__(self) -> None:
            Model.__init__(self, observation_space=env.observation_space, action_space=env.action_space,
                           device=device)
            GaussianMixin.__init__(self, clip_actions=True, role="policy")
            self.net = _mlp([self.num_observations, *hidden])
            self.mean = nn.Linear(hidden[-1], self.num_actions)
            self.log_std = nn.Parameter(torch.full((self.num_actions,), DEFAULTS.log_std_init))

        def compute(self, inputs, role=""):
            return self.mean(self.net(inputs["observations"])), {"log_std": self.log_std}

    class Value(DeterministicMixin, Model):
        def __init__(self, space, sizes) -> None:
            Model.__init__(self, observation_space=space, action_space=env.action_space, device=device)
            DeterministicMixin.__init__(self, clip_actions=False, role="value")
            self.net = _mlp([self.num_observations, *sizes])
            self.head = nn.Linear(sizes[-1], 1)

        def compute(self, inputs, role=""):
            return self.head(self.net(inputs["observations"])), {}

    models = {"policy": Policy(), "value": Value(env.observation_space, hidden)}
    if amp_space is not None:
        models["discriminator"] = Value(amp_space, list(DEFAULTS.disc_hidden))
    return models


def _skrl_common(env, device) -> dict[str, Any]:
    from skrl.resources.preprocessors.torch import RunningStandardScaler

    return dict(
        rollouts=DEFAULTS.rollout_steps, learning_epochs=DEFAULTS.epochs, mini_batches=minibatches(env.num_envs),
        discount_factor=DEFAULTS.gamma, gae_lambda=DEFAULTS.gae_lambda, learning_rate=DEFAULTS.learning_rate,
        grad_norm_clip=DEFAULTS.max_grad_norm, ratio_clip=DEFAULTS.clip_range, value_clip=0.0,
        entropy_loss_scale=DEFAULTS.ent_coef, value_loss_scale=DEFAULTS.vf_coef, time_limit_bootstrap=False,
        observation_preprocessor=RunningStandardScaler,
        observation_preprocessor_kwargs={"size": env.observation_space, "clip_threshold": DEFAULTS.clip_obs,
                                         "device": device},
        value_preprocessor=RunningStandardScaler, value_preprocessor_kwargs={"size": 1, "device": device},
    )


def _amp_windows(infos: dict[str, Any]) -> torch.Tensor:
    """``info["amp_obs"]`` as skrl's AMP agent reads it: a float32 tensor, and for a world whose episode
    ended in the step (SAME_STEP) the ended step's window (in ``final_info``), not the reset's."""
    amp = np.asarray(infos["amp_obs"], dtype=np.float32)
    ended = infos.get("_final_info")
    if ended is not None and ended.any():
        amp[ended] = infos["final_info"]["amp_obs"][ended]
    return torch.from_numpy(amp)


def run_skrl(venv, args: argparse.Namespace, amp: bool = False) -> dict[str, float]:
    from skrl.envs.wrappers.torch import wrap_env
    from skrl.memories.torch import RandomMemory
    from skrl import logger as skrl_logger
    from skrl.utils import set_seed

    skrl_logger.setLevel(logging.WARNING)      # no "Seed: 0" line in the table
    set_seed(args.seed)                        # also the seed of the wrapper's first reset
    env = wrap_env(venv, wrapper="gymnasium", verbose=False)
    device = env.device
    memory = RandomMemory(memory_size=DEFAULTS.rollout_steps, num_envs=env.num_envs, device=device)
    cfg = _skrl_common(env, device)
    with tempfile.TemporaryDirectory() as folder:
        experiment = {"directory": folder, "experiment_name": "bench", "write_interval": 0, "checkpoint_interval": 0}
        if amp:
            from skrl.agents.torch.amp import AMP, AMP_CFG
            from skrl.resources.preprocessors.torch import RunningStandardScaler

            world = venv.envs[0]
            amp_space = world.amp_observation_space
            cfg.update(amp_observation_preprocessor=RunningStandardScaler,
                       amp_observation_preprocessor_kwargs={"size": amp_space, "device": device},
                       task_reward_scale=DEFAULTS.w_task, style_reward_scale=DEFAULTS.w_style,
                       discriminator_batch_size=DEFAULTS.disc_batch_size,
                       discriminator_gradient_penalty_scale=DEFAULTS.disc_grad_penalty,
                       discriminator_weight_decay_scale=DEFAULTS.disc_weight_decay,
                       discriminator_logit_regularization_scale=DEFAULTS.disc_logit_reg)
            agent = AMP(models=_skrl_models(env, device, amp_space), memory=memory,
                        observation_space=env.observation_space, state_space=env.state_space,
                        action_space=env.action_space, device=device, cfg=AMP_CFG(**cfg, experiment=experiment),
                        amp_observation_space=amp_space,
                        motion_dataset=RandomMemory(memory_size=DEFAULTS.disc_replay_size, device=device),
                        reply_buffer=RandomMemory(memory_size=DEFAULTS.disc_replay_size, device=device),
                        collect_reference_motions=lambda n: torch.as_tensor(world.collect_reference_motions(n),
                                                                            dtype=torch.float32))
        else:
            from skrl.agents.torch.ppo import PPO, PPO_CFG

            agent = PPO(models=_skrl_models(env, device), memory=memory, observation_space=env.observation_space,
                        state_space=env.state_space, action_space=env.action_space, device=device,
                        cfg=PPO_CFG(**cfg, experiment=experiment))
        agent.init()
        agent.enable_training_mode(True)
        total = (args.iterations + 1) * DEFAULTS.rollout_steps
        observations, _ = env.reset()
        states = env.state()
        timing, step = Timing(), 0

        def iteration(timing: Timing) -> None:   # SequentialTrainer.train's loop body, rollout_steps times
            nonlocal observations, states, step
            for _ in range(DEFAULTS.rollout_steps):
                start = time.perf_counter()
                agent.pre_interaction(timestep=step, timesteps=total)
                with torch.no_grad():
                    actions, _ = agent.act(observations, states, timestep=step, timesteps=total)
                    next_observations, rewards, terminated, truncated, infos = env.step(actions)
                    next_states = env.state()
                    if amp:
                        infos["amp_obs"] = _amp_windows(infos)
                    agent.record_transition(observations=observations, states=states, actions=actions,
                                            rewards=rewards, next_observations=next_observations,
                                            next_states=next_states, terminated=terminated, truncated=truncated,
                                            infos=infos, timestep=step, timesteps=total)
                middle = time.perf_counter()
                agent.post_interaction(timestep=step, timesteps=total)   # the update, after the last step
                timing.rollout += middle - start
                timing.update += time.perf_counter() - middle
                observations, states, step = next_observations, next_states, step + 1

        iteration(Timing())                    # warm-up
        for _ in range(args.iterations):
            iteration(timing)
        return timing.result(args.iterations * DEFAULTS.rollout_steps * env.num_envs)


# --- rsl-rl ------------------------------------------------------------------------------------------
def rsl_adapter(venv, seed: int):
    """A thin ``rsl_rl.env.VecEnv`` over the batched env (SAME_STEP resets inside ``step_worlds``)."""
    from rsl_rl.env import VecEnv
    from tensordict import TensorDict

    class BatchedVecEnv(VecEnv):
        def __init__(self) -> None:
            self.venv = venv
            self.num_envs = venv.num_envs
            self.num_actions = int(np.prod(venv.single_action_space.shape))
            self.max_episode_length = venv.max_episode_steps or 10**9
            self.episode_length_buf = torch.zeros(self.num_envs, dtype=torch.long)
            self.device = "cpu"
            self.cfg = {"env_id": ENV_ID, "env_kwargs": ENV_KWARGS}
            self.low = venv.single_action_space.low.astype(np.float32)
            self.high = venv.single_action_space.high.astype(np.float32)
            obs, _ = venv.reset(seed=seed)
            self.obs = self._wrap(obs)

        def _wrap(self, obs: np.ndarray):
            return TensorDict({"policy": torch.as_tensor(obs, dtype=torch.float32)}, batch_size=[self.num_envs])

        def get_observations(self):
            return self.obs

        def step(self, actions: torch.Tensor):
            clipped = np.clip(actions.numpy(), self.low, self.high)
            obs, rewards, terminated, truncated, _infos, _finals = self.venv.step_worlds(clipped, reset_ended=True)
            dones = terminated | truncated
            self.episode_length_buf += 1
            self.episode_length_buf[torch.from_numpy(dones)] = 0
            self.obs = self._wrap(obs)
            extras = {"time_outs": torch.from_numpy(truncated & ~terminated)}
            return self.obs, torch.as_tensor(rewards, dtype=torch.float32), torch.from_numpy(dones).long(), extras

    return BatchedVecEnv()


def rsl_config(num_envs: int) -> dict[str, Any]:
    """rsl-rl-lib 5.x's runner configuration with the training script's defaults."""
    from rsl_rl.algorithms import PPO
    from rsl_rl.models import MLPModel
    from rsl_rl.modules.distribution import GaussianDistribution

    model = {"class_name": MLPModel, "hidden_dims": list(DEFAULTS.hidden), "activation": "relu",
             "obs_normalization": True}
    return {
        "num_steps_per_env": DEFAULTS.rollout_steps, "save_interval": 10**9, "check_for_nan": True,
        "obs_groups": {"actor": ["policy"], "critic": ["policy"]},
        "algorithm": {"class_name": PPO, "num_learning_epochs": DEFAULTS.epochs,
                      "num_mini_batches": minibatches(num_envs), "clip_param": DEFAULTS.clip_range,
                      "gamma": DEFAULTS.gamma, "lam": DEFAULTS.gae_lambda, "value_loss_coef": DEFAULTS.vf_coef,
                      "entropy_coef": DEFAULTS.ent_coef, "learning_rate": DEFAULTS.learning_rate,
                      "max_grad_norm": DEFAULTS.max_grad_norm, "use_clipped_value_loss": False,
                      "schedule": "fixed", "desired_kl": None, "normalize_advantage_per_mini_batch": True},
        "actor": {**model, "distribution_cfg": {"class_name": GaussianDistribution,
                                                "init_std": math.exp(DEFAULTS.log_std_init), "std_type": "log"}},
        "critic": model,
    }


def run_rsl(venv, args: argparse.Namespace) -> dict[str, float]:
    from rsl_rl.runners import OnPolicyRunner

    torch.manual_seed(args.seed)
    env = rsl_adapter(venv, args.seed)
    with contextlib.redirect_stdout(io.StringIO()):    # the runner prints its models
        runner = OnPolicyRunner(env, rsl_config(env.num_envs), log_dir=None, device="cpu")
    timing = Timing()
    update = runner.alg.update

    def timed_update() -> dict[str, float]:             # the split: the runner's learn() times both itself
        start = time.perf_counter()
        try:
            return update()
        finally:
            timing.update += time.perf_counter() - start

    runner.alg.update = timed_update
    runner.learn(num_learning_iterations=1)             # warm-up
    timing.update = 0.0
    start = time.perf_counter()
    runner.learn(num_learning_iterations=args.iterations)
    timing.rollout = time.perf_counter() - start - timing.update
    return timing.result(args.iterations * DEFAULTS.rollout_steps * env.num_envs)


# --- the rounds --------------------------------------------------------------------------------------
def available(names: list[str]) -> dict[str, Callable]:
    runners: dict[str, Callable] = {}
    for name in names:
        if name.startswith("skrl"):
            try:
                import skrl  # noqa: F401
                import skrl.agents.torch.ppo  # noqa: F401
            except ImportError as err:
                print(f"note: {name} skipped, skrl is not importable ({err}); pip install skrl")
                continue
            runners[name] = (lambda v, a, amp=name.endswith("amp"): run_skrl(v, a, amp))
        elif name == "rsl-rl":
            try:
                import rsl_rl.runners  # noqa: F401
                import tensordict  # noqa: F401
            except ImportError as err:
                print(f"note: rsl-rl skipped, rsl_rl is not importable ({err}); pip install rsl-rl-lib")
                continue
            runners[name] = run_rsl
        elif name in ("lean", "lean-amp"):
            runners[name] = (lambda v, a, amp=name == "lean-amp": run_lean(v, a, amp))
        else:
            raise SystemExit(f"unknown trainer {name!r}; choose from {', '.join(TRAINERS)}")
    return runners


def main(argv: list[str] | None = None) -> dict[str, list[dict[str, float]]]:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--num-envs", type=int, default=DEFAULTS.num_envs, help="worlds of the batched env")
    p.add_argument("--iterations", type=int, default=10, help="timed iterations (collect + update) per run")
    p.add_argument("--rounds", type=int, default=2, help="rounds; each runs every trainer once")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--physics", default=DEFAULTS.physics, choices=("threads", "serial"))
    p.add_argument("--trainers", default=",".join(TRAINERS), help=f"comma-separated, of {', '.join(TRAINERS)}")
    args = p.parse_args(argv)
    torch.set_num_threads(1)
    runners = available([name for name in args.trainers.split(",") if name])
    if "lean" not in runners:
        raise SystemExit("--trainers must include lean (the reference of the ratios)")
    start = time.perf_counter()
    venv = gym.make_vec(ENV_ID, num_envs=args.num_envs, vectorization_mode="vector_entry_point",
                        autoreset_mode=AutoresetMode.SAME_STEP, physics=args.physics, **ENV_KWARGS)
    print(f"{ENV_ID}: {args.num_envs} worlds (built in {time.perf_counter() - start:.1f} s), "
          f"{args.iterations} x {DEFAULTS.rollout_steps * args.num_envs} env steps timed per run, "
          f"torch threads {torch.get_num_threads()}", flush=True)
    results: dict[str, list[dict[str, float]]] = {name: [] for name in runners}
    ratios: dict[str, list[float]] = {name: [] for name in runners}
    names = list(runners)
    try:
        for r in range(args.rounds):
            order = names[r % len(names):] + names[:r % len(names)]
            for name in order:
                result = runners[name](venv, args)
                results[name].append(result)
                print(f"round {r}: {name:9s} {result['rate']:8.0f} env steps/s  (rollout {result['rollout_s']:6.2f} s,"
                      f" update {result['update_s']:6.2f} s)", flush=True)
            for name in names:
                ratios[name].append(results[name][-1]["rate"] / results["lean"][-1]["rate"])
    finally:
        venv.close()
    print("median over rounds (ratio: the median of each round's rate / lean's):")
    for name in names:
        rate = statistics.median(x["rate"] for x in results[name])
        rollout = statistics.median(x["rollout_s"] / (x["rollout_s"] + x["update_s"]) for x in results[name])
        print(f"  {name:9s} {rate:8.0f} env steps/s  {statistics.median(ratios[name]):5.2f}x lean  "
              f"(rollout {100 * rollout:3.0f}% of the time, update {100 - 100 * rollout:3.0f}%)")
    return results


if __name__ == "__main__":
    main()
