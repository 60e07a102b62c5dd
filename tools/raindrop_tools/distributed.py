"""Training in several processes (PyTorch DistributedDataParallel under ``torchrun``).

``torchrun`` starts one process per GPU (or per share of a CPU) and tells each its place in
the environment: ``WORLD_SIZE`` processes in all, this one's ``RANK`` among them and its
``LOCAL_RANK`` on its node. ``from_env`` reads them; with ``WORLD_SIZE`` unset or 1 training
runs as a single process, exactly as without torchrun.

How the trainer uses a ``World``:

* the step samplers still draw the GLOBAL batch of every step (``train.batch_size`` crops, a
  pure function of seed, stage and step); ``RankSlice`` hands rank r the crops r, r + N,
  r + 2N, ... of it, so the processes see disjoint parts of the batch a single process would
  see, and a resumed run sees the same batches whatever the number of processes;
* DistributedDataParallel averages the gradients, so a step follows the gradient of the
  global batch's mean loss (BatchNorm layers in training mode normalise with each process's
  own batch statistics, as usual under DDP);
* rank 0 alone reads and writes the run folder; what it finds there (configuration,
  checkpoint to continue from) reaches the others through ``share``, and errors that some
  ranks meet end every rank (``share``, ``agree``), so that no process is left waiting in a
  collective operation.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Callable, Iterator, Mapping, TypeVar

import torch
import torch.distributed as dist

T = TypeVar("T")


class WorldError(RuntimeError):
    """The torchrun environment or the run does not fit several processes."""


@dataclass
class World:
    """This process's place among ``size`` processes, and the device its tensors live on."""

    rank: int
    local_rank: int
    size: int
    device: torch.device = torch.device("cpu")

    @property
    def is_main(self) -> bool:
        return self.rank == 0

    # ------------------------------------------------------------------ process group

    def start(self, device: torch.device) -> torch.device:
        """Join the process group: NCCL on CUDA, this process pinned to ``cuda:LOCAL_RANK``;
        gloo on the CPU. Returns the device this process trains on."""
        if device.type == "cuda":
            if self.local_rank >= torch.cuda.device_count():
                raise WorldError(
                    f"LOCAL_RANK {self.local_rank} but this node has {torch.cuda.device_count()} CUDA device(s); "
                    "start at most one process per GPU (--nproc_per_node)"
                )
            device = torch.device("cuda", self.local_rank)
            torch.cuda.set_device(device)
            dist.init_process_group("nccl", device_id=device)
        else:
            dist.init_process_group("gloo")
        self.device = device
        return device

    @staticmethod
    def stop() -> None:
        if dist.is_available() and dist.is_initialized():
            dist.destroy_process_group()

    # ------------------------------------------------------------------ collectives

    def share(self, fn: Callable[[], T], errors: tuple[type[BaseException], ...]) -> T:
        """Run ``fn`` on rank 0 only and give every rank its result; when it raises one of
        ``errors``, every rank raises that error."""
        box: list = [None]
        if self.is_main:
            try:
                box[0] = (fn(), None)
            except errors as e:
                box[0] = (None, e)
        dist.broadcast_object_list(box, src=0)
        result, error = box[0]
        if error is not None:
            raise error
        return result

    def agree(self, fn: Callable[[], T], errors: tuple[type[BaseException], ...]) -> T:
        """Run ``fn`` on every rank; when it raises one of ``errors`` on any rank, every rank
        raises the error of the lowest such rank (named in the message unless it is 0)."""
        try:
            result, error = fn(), None
        except errors as e:
            result, error = None, e
        found = self.gather(error)
        for rank, e in enumerate(found):
            if e is not None:
                if rank == self.rank or rank == 0:
                    raise e
                raise type(e)(f"rank {rank}: {e}")
        return result

    def gather(self, obj) -> list:
        """``obj`` of every rank, in rank order."""
        out: list = [None] * self.size
        dist.all_gather_object(out, obj)
        return out

    def any(self, flag: bool) -> bool:
        """True on every rank when ``flag`` is true on one."""
        t = torch.tensor([1.0 if flag else 0.0], device=self.device)
        dist.all_reduce(t, op=dist.ReduceOp.MAX)
        return bool(t.item())

    def mean(self, value: torch.Tensor) -> torch.Tensor:
        """The mean over the ranks of a tensor (non-finite on every rank when it is on one)."""
        t = value.detach().clone()
        dist.all_reduce(t, op=dist.ReduceOp.SUM)
        return t / self.size

    def barrier(self) -> None:
        dist.barrier()

    # ------------------------------------------------------------------ data

    def local_batch(self, batch_size: int) -> int:
        """Crops per process of a global batch of ``batch_size``; refuses a remainder."""
        if batch_size % self.size:
            raise WorldError(
                f"train.batch_size {batch_size} is not divisible by the {self.size} processes (WORLD_SIZE); "
                f"it is the global batch, split evenly: use a multiple of {self.size}"
            )
        return batch_size // self.size


def from_env(environ: Mapping[str, str] = os.environ) -> World | None:
    """This process's ``World`` when torchrun (or a launcher that sets the same variables)
    started several, else None."""
    try:
        size = int(environ.get("WORLD_SIZE") or 1)
        if size <= 1:
            return None
        missing = [k for k in ("RANK", "LOCAL_RANK", "MASTER_ADDR", "MASTER_PORT") if not environ.get(k)]
        if missing:
            raise WorldError(f"WORLD_SIZE is {size} but {', '.join(missing)} not set; start training with torchrun")
        rank, local_rank = int(environ["RANK"]), int(environ["LOCAL_RANK"])
    except ValueError:
        raise WorldError("WORLD_SIZE, RANK and LOCAL_RANK must be integers") from None
    if not 0 <= rank < size or local_rank < 0:
        raise WorldError(f"RANK {rank} / LOCAL_RANK {local_rank} do not fit WORLD_SIZE {size}")
    return World(rank, local_rank, size)


class RankSlice:
    """A batch sampler yielding this rank's part of each of ``sampler``'s (global) batches:
    the keys at positions rank, rank + size, ... Every rank's parts together are the global
    batch, each key in exactly one of them."""

    def __init__(self, sampler, rank: int, size: int):
        self.sampler = sampler
        self.rank = rank
        self.size = size

    def __iter__(self) -> Iterator[list]:
        for keys in self.sampler:
            yield keys[self.rank :: self.size]

    def __len__(self) -> int:
        return len(self.sampler)
