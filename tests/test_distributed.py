"""Data-parallel training (``stairenv.training.distributed``): 2 CPU processes under torchrun (gloo).

The first update of 2 ranks x N worlds equals that of one process with 2N worlds (one epoch, the
whole rollout one minibatch: equal in exact arithmetic, here within float32 rounding), so does a
discriminator trained on each rank's half of the batch; every rank keeps the same weights; a run
resumed from a 2-rank checkpoint with 2 ranks equals the run never stopped; ``train_ppo.py`` under
torchrun checkpoints and resumes with 2 ranks and with 1. Two torchrun agents standing in for two machines
(``--nnodes 2``) resume as the 2 ranks of one machine do, bit for bit, and stop together, saying why, when
one machine cannot start.
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import torch
import torch.distributed as dist

ROOT = Path(__file__).resolve().parents[1]
WORKER = ROOT / "tests" / "distributed_worker.py"
SCRIPT = ROOT / "baselines" / "train_ppo.py"

pytestmark = [pytest.mark.skipif(not (dist.is_available() and dist.is_gloo_available()),
                                 reason="this torch has no torch.distributed with the gloo backend"),
              pytest.mark.slow]    # torchrun ranks in subprocesses: CI runs them (-m slow)

#: weights after the first update, 2 ranks x 2 worlds against 1 x 4: float32 rounding of sums taken in
#: another order (the normalisers' merged moments, the averaged gradients) through one Adam step
#: (measured: 3e-8)
ATOL = 1e-5


def torchrun(args: list[str], cwd: Path) -> str:
    command = [sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc-per-node=2", *args]
    # a cache of the launch's own: what its ranks synthesise does not depend on earlier tests' climbs
    env = {**os.environ, "MUJOCO_GL": "egl", "OMP_NUM_THREADS": "1", "STAIRENV_CACHE": str(cwd / "stairenv-cache")}
    done = subprocess.run(command, cwd=cwd, env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-4000:]
    return done.stdout


#: train_ppo.py's flags for a tiny PPO + AMP run
SCRIPT_FLAGS = ["--n-envs", "2", "--n-steps", "8", "--batch-size", "16", "--checkpoint-every", "32", "--eval-episodes",
                "0", "--no-progress-bar", "--policy-hidden", "32,32", "--disc-hidden", "16", "--disc-replay-size", "64",
                "--disc-update-interval", "16", "--disc-updates", "1", "--disc-batch-size", "8", "--disc-scoring",
                "torch"]


@pytest.fixture(scope="module")
def ranks(tmp_path_factory):
    """What each of 2 ranks of ``distributed_worker.py`` wrote (one launch for every test here)."""
    out = tmp_path_factory.mktemp("ranks")
    torchrun([str(WORKER), str(out), *SCRIPT_FLAGS], out)
    return [{**torch.load(out / f"rank{r}.pt", weights_only=False), "out": out} for r in range(2)]


@pytest.fixture(scope="module")
def worker():
    sys.path.insert(0, str(WORKER.parent))
    try:
        import distributed_worker
    finally:
        sys.path.remove(str(WORKER.parent))
    return distributed_worker


def test_two_ranks_keep_the_same_weights(ranks):
    for name, weights in ranks[0]["first_update"]["model"].items():
        assert torch.equal(weights, ranks[1]["first_update"]["model"][name]), name
    for name, weights in ranks[0]["disc"].items():
        assert torch.equal(weights, ranks[1]["disc"][name]), name
    np.testing.assert_array_equal(ranks[0]["first_update"]["obs_var"], ranks[1]["first_update"]["obs_var"])


def test_first_update_of_two_ranks_equals_one_process_with_twice_the_worlds(ranks, worker):
    one = worker.first_update(4)
    two = ranks[0]["first_update"]
    assert two["steps"] == one["steps"] == 4 * 8    # steps count every rank's worlds
    difference = max((weights - two["model"][name]).abs().max().item() for name, weights in one["model"].items())
    print(f"largest weight difference, 2 ranks x 2 worlds against 1 x 4: {difference:.2g}")
    assert difference <= ATOL
    # world j of rank r is world 2r + j of the single process, acting with the same noise
    both = torch.cat([ranks[0]["first_update"]["actions"], ranks[1]["first_update"]["actions"]], dim=1)
    np.testing.assert_allclose(both.numpy(), one["actions"].numpy(), atol=ATOL)
    # the observations differ as the actions do (float32 rounding through 8 physics steps)
    np.testing.assert_allclose(two["obs_mean"], one["obs_mean"], rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(two["obs_var"], one["obs_var"], rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(two["ret_var"], one["ret_var"], rtol=1e-5)


def test_discriminator_of_two_ranks_equals_one_on_the_whole_batch(ranks, worker):
    one = worker.disc_updates(2)
    for name, weights in one.items():
        np.testing.assert_allclose(ranks[0]["disc"][name].numpy(), weights.numpy(), atol=ATOL, err_msg=name)


def test_resume_with_the_same_ranks_is_exact(ranks):
    assert ranks[0]["resume_exact"] and ranks[1]["resume_exact"]


def test_ranks_share_the_climb_cache_fill_and_each_holds_every_climb(ranks):
    """--climb-cache-workers under torchrun: each rank synthesises half of the 4 climbs, then takes the other
    rank's; both hold all 4, equal to what one process synthesises (the same deterministic arrays)."""
    from stairenv.motion import stair_starts
    for rank in ranks:    # said by each rank here (train_ppo.py's own say prints on rank 0 only)
        printed = rank["climb_cache"]["printed"]
        assert len(printed) == 1 and "4 staircases synthesised by 2 ranks ([2, 2])" in printed[0], printed
    keys = stair_starts.grid_keys((0.10, 0.11), (0.30, 0.30), (3, 3))
    stair_starts.fill_cache(keys, 1)
    here = stair_starts.cached(keys)
    assert len(here) == 4
    for rank in ranks:
        held = rank["climb_cache"]["climbs"]
        assert set(held) == set(here)
        for key, (qpos, qvel) in here.items():
            np.testing.assert_array_equal(held[key][0], qpos)
            np.testing.assert_array_equal(held[key][1], qvel)


def test_train_ppo_under_torchrun_checkpoints_and_resumes_with_two_ranks_and_one(ranks, baseline_script, capsys,
                                                                                tmp_path):
    out, run = ranks[0]["script"], ranks[0]["out"] / "a" / "InterLevel-v0" / "seed0"
    assert "2 ranks x 2 worlds" in out and "trained 64 env steps" in out
    checkpoint = run / "checkpoints" / "checkpoint_64.pt"
    for name in ("checkpoints/checkpoint_32.pt", "checkpoints/replay_64.npy", "checkpoints/replay_64_rank1.npy",
                 "final_checkpoint.pt", "final_policy.npz"):
        assert (run / name).exists(), name
    assert len((run / "log.jsonl").read_text().splitlines()) == 2    # rank 0 alone logs: 64 / (2 x 2 x 8)
    state = torch.load(checkpoint, weights_only=True)
    assert state["world_size"] == 2 and state["steps"] == 64 and len(state["style"]["ranks"]) == 1
    assert ranks[1]["script"] == ""    # rank 1 prints nothing
    # on with 2 ranks (in the same launch), and with 1 (a plain process: 2 worlds)
    out = ranks[0]["script_resumed"]
    assert "at 64 steps" in out and "trained 32 env steps" in out and "not exact" not in out
    baseline_script("train_ppo").main(["--resume", str(checkpoint), "--timesteps", "32", "--logdir",
                                       str(tmp_path), *SCRIPT_FLAGS])
    out = capsys.readouterr().out
    assert "at 64 steps" in out and "written by 2 ranks, going on with 1" in out and "trained 32 env steps" in out
    final = torch.load(tmp_path / "InterLevel-v0" / "seed0" / "final_checkpoint.pt", weights_only=True)
    assert final["world_size"] == 1


# --- which GPU and which backend a rank takes (no GPU needed: torch.cuda and the process group faked) -------
@pytest.mark.parametrize("ranks_on_node, gpus, device, backend, rank_gpus", [
    (2, 2, "cuda", "nccl", [0, 1]),          # a GPU each
    (4, 1, "cuda", "gloo", [0, 0, 0, 0]),    # four ranks share one GPU: NCCL would refuse them
    (3, 2, "cuda", "gloo", [0, 1, 0]),
    (2, 2, "cpu", "gloo", [0, 1]),           # networks on the CPU, each rank's Warp physics on its own GPU
    (2, 0, "cpu", "gloo", [None, None]),     # no GPU: gloo, Warp's own choice (its CPU device)
])
def test_each_rank_takes_a_gpu_in_turn_and_nccl_only_where_ranks_have_their_own(monkeypatch, ranks_on_node, gpus,
                                                                                device, backend, rank_gpus):
    from stairenv.training import distributed
    chosen = {}
    monkeypatch.setattr(torch.cuda, "is_available", lambda: gpus > 0)
    monkeypatch.setattr(torch.cuda, "device_count", lambda: gpus)
    monkeypatch.setattr(torch.cuda, "set_device", lambda gpu: chosen.__setitem__("set_device", gpu))
    monkeypatch.setattr(dist, "is_initialized", lambda: False)
    monkeypatch.setattr(dist, "init_process_group", lambda backend: chosen.__setitem__("backend", backend))
    monkeypatch.setattr(dist, "new_group", lambda backend: f"{backend} group")
    monkeypatch.setattr(dist, "get_world_size", lambda: ranks_on_node)
    # every rank's start went well (the exchange in which they agree on it)
    monkeypatch.setattr(distributed.DataParallel, "gather", lambda self, value: [value] * self.world_size)
    for local_rank, gpu in enumerate(rank_gpus):
        chosen.clear()
        monkeypatch.setattr(dist, "get_rank", lambda: local_rank)
        monkeypatch.setenv("WORLD_SIZE", str(ranks_on_node))
        monkeypatch.setenv("LOCAL_WORLD_SIZE", str(ranks_on_node))
        monkeypatch.setenv("LOCAL_RANK", str(local_rank))
        rank = distributed.DataParallel.from_environment(device)
        assert chosen["backend"] == backend
        assert rank.physics_device == (None if gpu is None else f"cuda:{gpu}")
        assert rank.for_thread().physics_device == rank.physics_device
        assert rank.ranks_on_node == rank.for_thread().ranks_on_node == ranks_on_node
        if device == "cuda":
            assert chosen["set_device"] == gpu and rank.device == torch.device("cuda", gpu)
        else:
            assert "set_device" not in chosen and rank.device == torch.device("cpu")


def test_networks_on_cuda_on_a_machine_without_a_gpu_stop_every_rank(monkeypatch):
    """Rank 1's machine has no GPU: it joins the run anyway (gloo), so that rank 0, whose machine has one,
    hears why and stops too instead of waiting for rank 1 until the process group's timeout."""
    from stairenv.training import distributed
    left = []
    monkeypatch.setattr(dist, "is_initialized", lambda: False)
    monkeypatch.setattr(dist, "init_process_group", lambda backend: None)
    monkeypatch.setattr(dist, "new_group", lambda backend: "gloo group")
    monkeypatch.setattr(dist, "get_world_size", lambda: 2)
    monkeypatch.setattr(distributed.DataParallel, "close", lambda self: left.append(self.rank))
    monkeypatch.setattr(torch.cuda, "set_device", lambda gpu: None)
    monkeypatch.setenv("WORLD_SIZE", "2")
    monkeypatch.setenv("LOCAL_WORLD_SIZE", "1")    # one rank on each of two machines
    monkeypatch.setenv("LOCAL_RANK", "0")
    reasons = {}
    for rank, gpus in ((1, 0), (0, 1)):    # rank 1 reports first, then rank 0 hears it
        monkeypatch.setattr(dist, "get_rank", lambda rank=rank: rank)
        monkeypatch.setattr(torch.cuda, "is_available", lambda gpus=gpus: gpus > 0)
        monkeypatch.setattr(torch.cuda, "device_count", lambda gpus=gpus: gpus)

        def gather(self, value, rank=rank):    # every rank's report, as all_gather_object would give it
            reasons[rank] = value
            return [reasons.get(0, ("gpu-host", None)), reasons[1]]
        monkeypatch.setattr(distributed.DataParallel, "gather", gather)
        with pytest.raises(SystemExit, match="failed on 1 of 2 ranks") as stop:
            distributed.DataParallel.from_environment("cuda")
        assert "rank 1 on" in str(stop.value.code) and "torch sees no GPU" in str(stop.value.code)
    assert left == [1, 0]    # each left the process group it had joined


def test_agree_returns_the_step_or_stops_every_rank_naming_the_ranks_that_failed(monkeypatch):
    from stairenv.training.distributed import LOCAL, DataParallel
    reports = {}
    rank0 = DataParallel(0, 3, 0, torch.device("cpu"))
    monkeypatch.setattr(DataParallel, "gather", lambda self, value: [value, *reports.values()])
    reports.update({1: ("b", None), 2: ("c", None)})
    assert rank0.agree(lambda: 7, "Counting") == 7 and LOCAL.agree(lambda: 7, "Counting") == 7
    reports.update({1: ("b", "--resume x: no checkpoint file"), 2: ("c", "ImportError: no module named warp")})
    with pytest.raises(SystemExit) as stop:    # this rank's step went well: it stops all the same
        rank0.agree(lambda: 7, "Counting")
    assert stop.value.code == ("Counting failed on 2 of 3 ranks, so every rank stops. rank 1 on b: --resume x: no "
                               "checkpoint file; rank 2 on c: ImportError: no module named warp")
    reports.update({1: ("b", None), 2: ("c", None)})

    def fails():
        raise SystemExit("--init-from y: cannot take it")
    with pytest.raises(SystemExit, match=r"failed on 1 of 3 ranks.*rank 0 on .*: --init-from y: cannot take it"):
        rank0.agree(fails, "Counting")
    with pytest.raises(SystemExit, match="--init-from y: cannot take it"):    # one process: its own error
        LOCAL.agree(fails, "Counting")


# --- two machines (two torchrun agents here, one rank each, meeting through a c10d rendezvous) -----------
def two_machines(args: list[list[str]], cwd: Path, timeout: float) -> list[str]:
    """``torchrun --nnodes 2 --nproc-per-node 1 --rdzv-backend c10d`` started twice on this machine, as on
    two machines, machine m running ``train_ppo.py args[m]``; each machine's output (stdout and stderr) and
    exit status, after both end. Fails when they have not ended within ``timeout`` s (both killed)."""
    with socket.socket() as free:
        free.bind(("127.0.0.1", 0))
        port = free.getsockname()[1]
    env = {**os.environ, "MUJOCO_GL": "egl", "OMP_NUM_THREADS": "1"}
    machines = [subprocess.Popen([sys.executable, "-m", "torch.distributed.run", "--nnodes=2", "--nproc-per-node=1",
                                  "--rdzv-backend=c10d", f"--rdzv-endpoint=127.0.0.1:{port}", f"--rdzv-id=run{port}",
                                  str(SCRIPT), *machine_args], cwd=cwd, env=env, stdout=subprocess.PIPE,
                                 stderr=subprocess.STDOUT, text=True) for machine_args in args]
    deadline = time.monotonic() + timeout
    try:
        outputs = [machine.communicate(timeout=max(1.0, deadline - time.monotonic()))[0] for machine in machines]
    except subprocess.TimeoutExpired:
        for machine in machines:
            machine.kill()
        pytest.fail(f"the two machines had not ended after {timeout:.0f} s: " + " | ".join(
            machine.communicate()[0][-1500:] for machine in machines))
    return [(machine.returncode, output) for machine, output in zip(machines, outputs)]


def test_two_machines_go_on_from_a_checkpoint_exactly_as_two_ranks_of_one_machine(ranks, tmp_path):
    """``--nnodes 2``: the 2-rank checkpoint resumed by one rank on each of two machines, 32 steps on: the
    same weights as the 2 ranks of one machine resuming it (``ranks``' run; the rank count decides the run,
    not where the ranks are)."""
    checkpoint = ranks[0]["out"] / "a" / "InterLevel-v0" / "seed0" / "checkpoints" / "checkpoint_64.pt"
    flags = ["--resume", str(checkpoint), "--timesteps", "32", "--logdir", str(tmp_path), *SCRIPT_FLAGS]
    ended = two_machines([flags, flags], tmp_path, timeout=300)
    assert [code for code, _ in ended] == [0, 0], ended
    printed = "".join(output for _, output in ended)    # rank 0 is on whichever machine the rendezvous chose
    assert "2 ranks x 2 worlds" in printed and "at 64 steps" in printed and "trained 32 env steps" in printed
    assert "not exact" not in printed
    here = torch.load(tmp_path / "InterLevel-v0" / "seed0" / "final_checkpoint.pt", weights_only=True)
    one_machine = torch.load(ranks[0]["out"] / "b" / "InterLevel-v0" / "seed0" / "final_checkpoint.pt",
                             weights_only=True)
    assert here["world_size"] == 2 and here["steps"] == one_machine["steps"] == 96
    for name, weights in one_machine["model"].items():
        assert torch.equal(here["model"][name], weights), name


def test_a_machine_that_cannot_read_the_checkpoint_stops_both_with_its_reason(ranks, tmp_path):
    """Without a shared folder, the second machine has no ``--resume`` file: both stop within seconds, each
    saying which rank failed and why (before, the first waited in its first collective for 30 minutes)."""
    checkpoint = ranks[0]["out"] / "a" / "InterLevel-v0" / "seed0" / "checkpoints" / "checkpoint_64.pt"
    absent = tmp_path / "elsewhere" / "checkpoint_64.pt"
    flags = ["--timesteps", "32", "--logdir", str(tmp_path), *SCRIPT_FLAGS]
    ended = two_machines([["--resume", str(checkpoint), *flags], ["--resume", str(absent), *flags]], tmp_path,
                         timeout=150)
    for code, output in ended:
        assert code != 0
        assert "failed on 1 of 2 ranks, so every rank stops" in output, output[-3000:]
        assert f"no checkpoint file '{absent}'" in output


def test_ranks_on_one_machine_share_its_cores_in_their_physics_pools():
    """Each rank's C physics pool gets the node's cores divided by its ranks (not every core each: K ranks x
    all cores of threads would contend), unless the run sets physics_threads; one process keeps every core."""
    from stairenv.training import TrainConfig, make_env
    from stairenv.training.distributed import Local

    class TwoOnThisNode(Local):
        ranks_on_node = 2

    cores = os.cpu_count()
    for parallel, physics_threads, want in ((TwoOnThisNode(), None, max(1, cores // 2)), (TwoOnThisNode(), 3, 3),
                                            (Local(), None, cores)):
        venv = make_env(TrainConfig(num_envs=2, physics_threads=physics_threads), parallel)
        assert venv.physics.nthread == want, (parallel, physics_threads)
        venv.close()

