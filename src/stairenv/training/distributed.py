"""Data-parallel training across processes and machines (``torchrun``), in the few collectives the
lean trainer needs.

``torchrun --nproc-per-node P baselines/train_ppo.py ...`` starts P copies of the script; each is
one *rank*, stepping its own batched env of ``num_envs`` worlds. After every backward pass the ranks
average their gradients (one all-reduce of the flattened gradients), so the weights stay equal on
every rank without ever being sent; the normalisers' statistics and the advantages' mean and std
are taken over every rank's batch together. ``DataParallel.from_environment()`` joins the run that
torchrun describes in the environment (``RANK``, ``WORLD_SIZE``, ``LOCAL_RANK``, ``MASTER_ADDR``...),
None in a plain ``python`` process.

Why a hand-written gradient all-reduce and not ``DistributedDataParallel``: the update calls the
policy's and value's sub-networks directly (not ``forward``, which DDP's hooks need), the
discriminator's gradient penalty is a double backward (which DDP does not support) and its weight
decay is added to the gradients after the backward; one call after ``backward()`` is also the
whole of the change a reader has to follow (as rsl_rl does it).

``LOCAL`` is the single-process stand-in: the same methods, returning their inputs, so the trainer
has one code path and a plain run computes exactly what it did before data-parallel training existed.
"""

from __future__ import annotations

import os
import socket
import traceback
from collections.abc import Callable
from typing import Any, Iterable, TypeVar

import numpy as np
import torch
import torch.distributed as dist

T = TypeVar("T")


#: how far (relative) the ranks' weights may drift apart before a checkpoint calls it a fault: ranks on other
#: CPUs round in other low bits (~1e-7 relative after many updates), a real fault (a rank updating without
#: the others' gradients) moves them by far more
RANK_DRIFT_TOLERANCE = 1e-5


def relative_gap(parts: list[torch.Tensor]) -> float:
    """The largest difference between rank 0's and another rank's (sum, sum of magnitudes) of a tensor,
    relative to rank 0's sum of magnitudes (rows: tensors; ``parts``: one (N, 2) array per rank)."""
    first = parts[0].double()
    scale = first[:, 1].abs().clamp_min(1e-300)
    gaps = [((part.double() - first).abs().max(dim=1).values / scale).max() for part in parts[1:]]
    return float(max(gaps, default=torch.zeros(())))


class Local:
    """One process: rank 0 of 1; every collective returns its input."""

    rank, world_size = 0, 1
    #: the device of a GPU physics back-end (``physics="warp"``): None, Warp's own choice (its first GPU)
    physics_device: str | None = None
    #: the processes of this run on this machine, sharing its cores (``LOCAL_WORLD_SIZE``)
    ranks_on_node = 1

    def moments(self, mean, var, count):
        return mean, var, count

    def mean_std(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return x.mean(), x.std()

    def average_gradients(self, parameters: Iterable[torch.nn.Parameter]) -> None:
        pass

    def mean_of(self, values: dict[str, float]) -> dict[str, float]:
        return values

    def gather(self, value: Any) -> list[Any]:
        return [value]

    def gather_to_first(self, value: Any) -> list[Any] | None:
        return [value]

    def weights_gap(self, tensors: Iterable[torch.Tensor]) -> float:
        return 0.0

    def broadcast(self, module: torch.nn.Module) -> None:
        pass

    def agree(self, step: Callable[[], T], what: str) -> T:
        return step()

    def for_thread(self) -> "Local":
        return self


LOCAL = Local()


def rank_gpu(local_rank: int, gpus: int) -> int | None:
    """The GPU of local rank ``local_rank`` on a node with ``gpus`` GPUs (None without one): a GPU each
    while there are enough, then shared in turn (8 ranks on 2 GPUs: 0, 1, 0, 1, ...)."""
    return local_rank % gpus if gpus > 0 else None


def process_group_backend(on_gpu: bool, ranks_on_node: int, gpus: int) -> str:
    """nccl for networks on GPUs where each of the node's ranks has a GPU of its own, else gloo (NCCL
    refuses two ranks on one GPU; the trainer's collectives use a gloo group in any case)."""
    return "nccl" if on_gpu and 0 < ranks_on_node <= gpus else "gloo"


def _in_place_on_host(tensor: torch.Tensor, collective) -> None:
    """``collective(t)`` writing into ``tensor``: the groups are gloo (host memory), so a tensor on
    another device goes through a host copy and back."""
    if tensor.device.type == "cpu":
        collective(tensor)
        return
    host = tensor.cpu()
    collective(host)
    tensor.copy_(host)


class DataParallel(Local):
    """This rank's place in a data-parallel run and the collectives over ``group`` (a gloo group; the
    tensors of a trainer on a GPU go through host copies, which only the weights' broadcast at the start
    and the gradients' all-reduce after each backward pass make large)."""

    def __init__(self, rank: int, world_size: int, local_rank: int, device: torch.device, group=None,
                 owns_process_group: bool = False, physics_device: str | None = None,
                 ranks_on_node: int | None = None) -> None:
        self.rank, self.world_size, self.local_rank, self.device = rank, world_size, local_rank, device
        self.group = group
        self.owns_process_group = owns_process_group
        self.physics_device = physics_device
        self.ranks_on_node = world_size if ranks_on_node is None else ranks_on_node

    @classmethod
    def from_environment(cls, device: str = "cpu") -> "DataParallel | None":
        """Join the run torchrun started this process in (None without torchrun's ``WORLD_SIZE``, or with
        one process: that is a plain run, computing exactly what ``python`` alone would).
        GPUs: local rank r takes the node's GPU ``r mod (GPUs)`` (``rank_gpu``) for its networks with
        ``device="cuda"`` and for its physics with ``physics="warp"`` (``physics_device``), so several ranks
        may share a GPU (each rank's task runs on a core of its own). Backend: nccl with ``device="cuda"``
        where every rank of the node has a GPU of its own (NCCL refuses two ranks on one GPU), else gloo;
        the collectives go through a gloo group either way (device tensors as host copies). With
        ``device="cuda"`` a machine where torch sees no GPU stops every rank with the reason (``agree``)."""
        if int(os.environ.get("WORLD_SIZE", "1")) < 2:
            return None
        local_rank = int(os.environ.get("LOCAL_RANK", 0))
        ranks_on_node = int(os.environ.get("LOCAL_WORLD_SIZE", os.environ["WORLD_SIZE"]))
        gpus = torch.cuda.device_count() if torch.cuda.is_available() else 0
        on_gpu = str(device).startswith("cuda")
        gpu = rank_gpu(local_rank, gpus)
        if on_gpu and gpu is not None:
            torch.cuda.set_device(gpu)
        owns = not dist.is_initialized()    # else the caller's process group, which close() leaves open
        if owns:
            dist.init_process_group(backend=process_group_backend(on_gpu, ranks_on_node, gpus))
        group = dist.new_group(backend="gloo") if on_gpu else None
        parallel = cls(dist.get_rank(), dist.get_world_size(), local_rank,
                       torch.device("cuda", gpu) if on_gpu and gpu is not None else torch.device("cpu"), group,
                       owns, physics_device=None if gpu is None else f"cuda:{gpu}", ranks_on_node=ranks_on_node)

        def gpu_here() -> None:    # refused on every rank when one machine has none (joined first, so all hear)
            if on_gpu and gpu is None:
                raise RuntimeError(f"device={device!r} but torch sees no GPU on this machine")
        try:
            parallel.agree(gpu_here, "Joining the run with its networks on GPUs")
        except SystemExit:
            parallel.close()
            raise
        return parallel

    def for_thread(self) -> "DataParallel":
        """The same ranks over a group of their own, for collectives issued from another thread (the
        discriminator's background training): collectives of one group must come in the same order on
        every rank, which two threads sharing a group would not keep. Every rank must call this,
        in the same order."""
        return DataParallel(self.rank, self.world_size, self.local_rank, self.device, dist.new_group(backend="gloo"),
                            physics_device=self.physics_device, ranks_on_node=self.ranks_on_node)

    def close(self) -> None:
        """Leave the run (when ``from_environment`` joined it)."""
        if self.owns_process_group and dist.is_initialized():
            dist.destroy_process_group()

    # --- statistics over every rank's batch -----------------------------------------------------------
    def moments(self, mean, var, count):
        """The mean, (population) variance and count of every rank's batch together, from each rank's
        own: Chan et al.'s combination, in rank order on every rank (the same numbers everywhere).
        numpy or torch in, the same kind out."""
        own = torch.cat([torch.as_tensor(count, dtype=torch.float64).reshape(1).cpu(),
                         torch.as_tensor(mean, dtype=torch.float64).reshape(-1).cpu(),
                         torch.as_tensor(var, dtype=torch.float64).reshape(-1).cpu()])
        parts = [torch.empty_like(own) for _ in range(self.world_size)]
        dist.all_gather(parts, own, group=self.group)
        table = torch.stack(parts)
        size = (len(own) - 1) // 2
        counts, means, variances = table[:, :1], table[:, 1:1 + size], table[:, 1 + size:]
        total = counts.sum()
        merged_mean = (counts * means).sum(0) / total
        merged_var = (counts * (variances + (means - merged_mean) ** 2)).sum(0) / total
        if isinstance(mean, torch.Tensor):
            return (merged_mean.reshape(mean.shape).to(mean.device, mean.dtype),
                    merged_var.reshape(var.shape).to(var.device, var.dtype), total)
        shape = np.shape(mean)
        return merged_mean.numpy().reshape(shape), merged_var.numpy().reshape(shape), float(total)

    def mean_std(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Mean and (unbiased) std of ``x`` over every rank's values, as ``x.mean(), x.std()`` of them all."""
        x64 = x.detach().to(torch.float64)
        mean, var, n = self.moments(x64.mean(), x64.var(unbiased=False), x.numel())
        return mean.to(x.dtype), torch.sqrt(var * n / (n - 1)).to(x.dtype)

    def mean_of(self, values: dict[str, float]) -> dict[str, float]:
        """Each value averaged over the ranks (the same keys on every rank)."""
        keys = sorted(values)
        summed = torch.tensor([values[key] for key in keys], dtype=torch.float64)
        dist.all_reduce(summed, group=self.group)
        return {key: float(v) / self.world_size for key, v in zip(keys, summed.tolist())}

    # --- gradients and weights --------------------------------------------------------------------
    def average_gradients(self, parameters: Iterable[torch.nn.Parameter]) -> None:
        """Replace every gradient by its mean over the ranks (one all-reduce of them all, flattened)."""
        grads = [p.grad for p in parameters if p.grad is not None]
        flat = torch.cat([g.reshape(-1) for g in grads])
        _in_place_on_host(flat, lambda t: dist.all_reduce(t, group=self.group))
        flat /= self.world_size
        offset = 0
        for g in grads:
            g.copy_(flat[offset:offset + g.numel()].view_as(g))
            offset += g.numel()

    def broadcast(self, module: torch.nn.Module) -> None:
        """Rank 0's parameters and buffers on every rank (written in place through ``detach()``, which
        shares their version counters: caches keyed on them, such as the discriminator's scoring plan,
        see the change)."""
        with torch.no_grad():
            for tensor in [*module.parameters(), *module.buffers()]:
                _in_place_on_host(tensor.detach(), lambda t: dist.broadcast(t, src=0, group=self.group))

    def weights_gap(self, tensors: Iterable[torch.Tensor]) -> float:
        """How far ``tensors`` differ between the ranks (``relative_gap`` of their float64 sums): 0.0 where
        every rank holds the same numbers, as ranks on one kind of CPU do; ranks on machines with other
        CPUs round their optimiser steps in other low bits and drift apart by ~1e-7 and less."""
        checks = torch.stack([torch.stack([t.detach().double().sum(), t.detach().double().abs().sum()])
                              for t in tensors]).cpu()
        parts = [torch.empty_like(checks) for _ in range(self.world_size)]
        dist.all_gather(parts, checks, group=self.group)
        return relative_gap(parts)

    def gather(self, value: Any) -> list[Any]:
        """Every rank's ``value`` (any picklable object), in rank order, on every rank."""
        values: list[Any] = [None] * self.world_size
        dist.all_gather_object(values, value, group=self.group)
        return values

    def agree(self, step: Callable[[], T], what: str) -> T:
        """``step()`` on every rank, then one exchange of how it went: if it failed on any rank (an
        exception, or ``SystemExit`` with its message), every rank stops with ``SystemExit`` naming each
        failed rank, its machine and its reason; else ``step``'s result. For the per-rank parts of a start
        that touch only this machine (reading a checkpoint, building the worlds), which a rank on another
        machine may fail alone: without it the others may wait at their next collective until the
        process group's timeout (30 minutes by default), and never hear the reason. ``step`` must not call a
        collective (a failed rank would not reach it)."""
        try:
            result, failure = step(), None
        except SystemExit as stop:
            result, failure = None, str(stop.code)
        except Exception as error:    # noqa: BLE001  (reported to every rank, then raised as SystemExit)
            traceback.print_exc()    # this rank's output keeps where it failed
            result, failure = None, f"{type(error).__name__}: {error}"
        reports = self.gather((socket.gethostname(), failure))
        failed = [f"rank {rank} on {host}: {why}" for rank, (host, why) in enumerate(reports) if why is not None]
        if failed:
            raise SystemExit(f"{what} failed on {len(failed)} of {self.world_size} ranks, so every rank "
                             "stops. " + "; ".join(failed))
        return result

    def gather_to_first(self, value: Any) -> list[Any] | None:
        """Every rank's ``value`` in rank order on rank 0 (None on the others): large things, such as
        the replay buffers a checkpoint keeps."""
        values: list[Any] | None = [None] * self.world_size if self.rank == 0 else None
        dist.gather_object(value, values, dst=0, group=self.group)    # every group spans every rank
        return values
