"""``python -m raindrop_tools.train`` with a probe, for test_distributed.py to start under
torchrun: every rank appends the sample ids of each of its batches to
``$RAINDROP_PROBE/ids-rank<R>.jsonl`` and, when training returns, saves its own networks to
``$RAINDROP_PROBE/nets-rank<R>.pt`` (only rank 0 writes checkpoints, so the other ranks'
weights are not visible otherwise). ``RAINDROP_PROBE_NAN=R:N`` makes the N-th detection loss
of rank R NaN."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import torch

from raindrop_tools import losses, train

PROBE = Path(os.environ["RAINDROP_PROBE"])
RANK = os.environ.get("RANK", "0")

_to_device, _run = train.Trainer._to_device, train.Trainer.run


def _recording_to_device(self, batch):
    with open(PROBE / f"ids-rank{RANK}.jsonl", "a") as f:
        f.write(json.dumps(list(batch["id"])) + "\n")
    return _to_device(self, batch)


def _saving_run(self, stages, resume):
    result = _run(self, stages, resume)
    torch.save({k: net.state_dict() for k, net in self.nets.items()}, PROBE / f"nets-rank{RANK}.pt")
    return result


def _poison(at: str) -> None:
    rank, call = at.split(":")
    if rank != RANK:
        return
    original, calls = losses.detection_loss, [0]

    def poisoned(*args, **kwargs):
        calls[0] += 1
        loss = original(*args, **kwargs)
        return loss * float("nan") if calls[0] == int(call) else loss

    losses.detection_loss = poisoned


if os.environ.get("RAINDROP_PROBE_NAN"):
    _poison(os.environ["RAINDROP_PROBE_NAN"])
train.Trainer._to_device = _recording_to_device
train.Trainer.run = _saving_run

if __name__ == "__main__":
    sys.exit(train.main(sys.argv[1:]))
