"""Checkpoint files of a run folder: ``RUNDIR/checkpoints/stage<S>_step<NNNNNNNN>.pt``.

A checkpoint holds the states of all three networks (stage-2 checkpoints carry the frozen
RDN and 3RN too, so any checkpoint is enough to export), the optimizers and schedulers of
the stage, the stage, the number of steps done and the resolved configuration. Files are
written to a temporary name in the same folder, flushed to disk and renamed, so a crash
never leaves a truncated checkpoint under a real name.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

import torch

from .read_only import read_only_problem, refuse_read_only

CHECKPOINT_DIR = "checkpoints"
_NAME = re.compile(r"^stage([12])_step(\d{8})\.pt$")
_TMP_PREFIX = ".tmp-"


@dataclass(frozen=True, order=True)
class CheckpointRef:
    stage: int
    step: int
    path: Path


def checkpoint_path(run_dir: Path, stage: int, step: int) -> Path:
    return Path(run_dir) / CHECKPOINT_DIR / f"stage{stage}_step{step:08d}.pt"


def list_checkpoints(run_dir: Path, stage: int | None = None) -> list[CheckpointRef]:
    """Checkpoints of the run, oldest first (by stage, then step)."""
    folder = Path(run_dir) / CHECKPOINT_DIR
    if not folder.is_dir():
        return []
    refs = []
    for p in folder.iterdir():
        m = _NAME.match(p.name)
        if m and (stage is None or int(m.group(1)) == stage):
            refs.append(CheckpointRef(int(m.group(1)), int(m.group(2)), p))
    return sorted(refs)


def latest_checkpoint(run_dir: Path, stage: int | None = None) -> CheckpointRef | None:
    refs = list_checkpoints(run_dir, stage)
    return refs[-1] if refs else None


def save_atomic(obj: dict, path: Path) -> None:
    path = Path(path)
    refuse_read_only(path, follow_links=False)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f"{_TMP_PREFIX}{path.name}.{os.getpid()}")
    try:
        with open(tmp, "wb") as f:
            torch.save(obj, f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    # Make the rename itself durable.
    fd = os.open(path.parent, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


class CheckpointError(ValueError):
    """A file that is not a readable checkpoint (cut short, another format), in one line."""


def load_checkpoint(path: Path, map_location: str | torch.device = "cpu") -> dict:
    try:
        state = torch.load(path, map_location=map_location, weights_only=False)
    except FileNotFoundError as e:
        raise CheckpointError(f"{path}: no such checkpoint") from e
    except Exception as e:  # torch raises whatever the bytes provoke: RuntimeError, UnpicklingError, EOFError...
        first = (str(e).strip().splitlines() or [type(e).__name__])[0]
        raise CheckpointError(f"{path}: not a readable checkpoint: a .pt file that train wrote ({first})") from e
    if not isinstance(state, dict) or "models" not in state:
        raise CheckpointError(f"{path}: not a raindrop training checkpoint (no networks in it)")
    return state


def remove_stale_temporaries(run_dir: Path) -> None:
    """Temporary files of a writer that crashed mid-save."""
    folder = Path(run_dir) / CHECKPOINT_DIR
    if folder.is_dir():
        for p in folder.iterdir():
            if p.name.startswith(_TMP_PREFIX):
                p.unlink()


def prune(run_dir: Path, stage: int, keep: int, protect: set[Path] = frozenset()) -> None:
    """Delete all but the newest ``keep`` checkpoints of ``stage`` (never those in ``protect``)."""
    refs = list_checkpoints(run_dir, stage)
    for ref in refs[: max(0, len(refs) - keep)]:
        # A checkpoint made read-only is someone's to keep (read_only.py): not removed.
        if ref.path not in protect and not read_only_problem(ref.path, follow_links=False):
            ref.path.unlink()
