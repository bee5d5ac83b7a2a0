"""One rank of ``tests/test_distributed.py``'s data-parallel runs (started by torchrun; not a test module).

``python -m torch.distributed.run --standalone --nproc-per-node 2 tests/distributed_worker.py OUT [FLAGS]``
writes ``OUT/rank<r>.pt`` per rank: the weights and statistics after the first update of ``FIRST_UPDATE``,
a discriminator after two updates on its half of ``disc_batches``, whether a run resumed from a
checkpoint equals the run that was never stopped, the climbs it holds after train_ppo.py's shared climb
cache fill, and with train_ppo.py FLAGS what the script printed
training 64 steps (to ``OUT/a``) and going on from its last checkpoint (to ``OUT/b``). One launch:
every process start costs seconds of imports.
"""

from __future__ import annotations

import contextlib
import importlib.util
import io
import sys
from pathlib import Path

import numpy as np
import torch

from stairenv.motion import stair_starts
from stairenv.style.discriminator import AMPDiscriminator, DiscriminatorConfig
from stairenv.style.wrappers import default_reference
from stairenv.training import TrainConfig, Trainer, build_style, make_env, read_checkpoint
from stairenv.training.cli import fill_climb_cache
from stairenv.training.distributed import LOCAL, DataParallel

#: one epoch, the whole rollout one minibatch, no discriminator round before the update: the update of
#: R ranks x N worlds is then, in exact arithmetic, that of one process with R x N worlds
FIRST_UPDATE = dict(physics="serial", rollout_steps=8, epochs=1, minibatch_size=10**6, hidden=(32, 32),
                    disc_hidden=(16,), disc_update_interval=10**6, disc_scoring="torch")
#: a short PPO + AMP run with a discriminator round every iteration, checkpointed halfway
RESUME = dict(num_envs=2, physics="serial", rollout_steps=8, minibatch_size=8, epochs=2, hidden=(32, 32),
              disc_hidden=(16,), disc_replay_size=40, disc_update_interval=16, disc_updates=1, disc_batch_size=8,
              disc_scoring="torch")
DISC = DiscriminatorConfig(hidden=(16, 8), batch_size=8, input_noise=0.0, grad_penalty=5.0)


def trainer(config: TrainConfig, parallel=LOCAL) -> Trainer:
    venv = make_env(config)
    return Trainer(config, build_style(config, default_reference(venv), parallel.rank), venv, parallel)


def first_update(num_envs: int, parallel=LOCAL) -> dict:
    """Weights, statistics and actions after one rollout and one update."""
    t = trainer(TrainConfig(num_envs=num_envs, **FIRST_UPDATE), parallel)
    t.collect()
    t.update()
    out = {"model": {k: v.clone() for k, v in t.model.state_dict().items()}, "actions": t.rollout.actions.clone(),
           "obs_mean": t.normalizer.obs_rms.mean, "obs_var": t.normalizer.obs_rms.var,
           "ret_var": t.normalizer.ret_rms.var, "steps": t.steps}
    t.close()
    return out


def disc_batches(ranks: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(0)
    shape = (2, ranks * DISC.batch_size, 12)    # two batches of reference and agent windows
    return rng.normal(1.0, 2.0, shape), rng.normal(0.0, 1.0, shape)


def disc_updates(ranks: int, parallel=None) -> dict:
    """A discriminator after two updates on its rank's rows of ``disc_batches`` (all of them in one process)."""
    torch.manual_seed(0)
    disc = AMPDiscriminator(12, DISC, scoring="torch")
    disc.parallel = parallel
    reference, agent = disc_batches(ranks)
    rows = slice(0, None) if parallel is None else slice(parallel.rank * DISC.batch_size,
                                                         (parallel.rank + 1) * DISC.batch_size)
    for ref, fake in zip(reference, agent):
        disc.update(ref[rows], fake[rows])
    return {k: v.clone() for k, v in disc.state_dict().items()}


def resume_is_exact(parallel, folder: Path) -> bool:
    """A 2-rank run to 64 steps against the same run stopped at 32 and resumed from its checkpoint."""
    config = TrainConfig(total_steps=64, checkpoint_every=32, **RESUME)
    whole = trainer(config, parallel)
    whole.learn(checkpoint_dir=folder / "whole")
    first = trainer(config.replace(total_steps=32), parallel)
    first.learn(checkpoint_dir=folder / "first")
    first.close()
    resumed = trainer(config, parallel)
    state = read_checkpoint(folder / "first" / "checkpoint_32.pt")
    resumed.load_state(state)
    assert resumed.load_replay(folder / "first" / "checkpoint_32.pt", state)
    resumed.learn(checkpoint_dir=folder / "resumed")
    same = (whole.steps == resumed.steps == 64
            and all(torch.equal(a, b) for a, b in zip(whole.model.parameters(), resumed.model.parameters()))
            and all(torch.equal(a, b) for a, b in zip(whole.style.disc.state_dict().values(),
                                                      resumed.style.disc.state_dict().values()))
            and np.array_equal(whole.normalizer.obs_rms.var, resumed.normalizer.obs_rms.var)
            and np.array_equal(whole.style.replay.data, resumed.style.replay.data))
    whole.close()
    resumed.close()
    return same


def train_ppo_module():
    spec = importlib.util.spec_from_file_location("train_ppo", Path(__file__).parents[1] / "baselines" / "train_ppo.py")
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    return script


def train_ppo(argv: list[str]) -> str:
    """What ``baselines/train_ppo.py`` prints, run in this rank (as torchrun would start it)."""
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        train_ppo_module().main(argv)
    return printed.getvalue()


#: stair starts on 2 heights x 1 depth x 1 count x 2 lead feet: 4 grid climbs
CLIMB_KWARGS = dict(stairs_start_fraction=1.0, step_height=(0.10, 0.11), step_depth=(0.30, 0.30), num_steps=(3, 3))


def climb_cache(parallel) -> dict:
    """``cli.fill_climb_cache`` in this rank: what it printed, and the climbs this rank then holds."""
    printed = []
    config = TrainConfig(env_kwargs=CLIMB_KWARGS)
    fill_climb_cache(config, 1, lambda *words: printed.append(" ".join(map(str, words))), parallel)
    return {"printed": printed, "climbs": stair_starts.cached(stair_starts.grid_keys((0.10, 0.11), (0.30, 0.30),
                                                                                     (3, 3)))}


def main(out: Path, script_args: list[str]) -> None:
    parallel = DataParallel.from_environment()
    assert parallel is not None and parallel.world_size == 2, "run me with torchrun --nproc-per-node 2"
    result = {"first_update": first_update(2, parallel), "disc": disc_updates(2, parallel),
              "resume_exact": resume_is_exact(parallel, out), "climb_cache": climb_cache(parallel)}
    if script_args:    # train_ppo.py: 64 steps, then on from its last checkpoint
        result["script"] = train_ppo(["--timesteps", "64", "--logdir", str(out / "a"), *script_args])
        checkpoint = out / "a" / "InterLevel-v0" / "seed0" / "checkpoints" / "checkpoint_64.pt"
        result["script_resumed"] = train_ppo(["--resume", str(checkpoint), "--timesteps", "32", "--logdir",
                                              str(out / "b"), *script_args])
    torch.save(result, out / f"rank{parallel.rank}.pt")
    parallel.close()


if __name__ == "__main__":
    main(Path(sys.argv[1]), sys.argv[2:])
