"""A model folder's graphs and export.json replaced whole or not at all.

The tools that write a model folder (export, quantize, phase_conv) write the new files into a
hidden staging folder beside it, ``.<name>.<tag>-<pid>``, check them there, and only then
rename each over its name (export.json last). So a failed check or an interrupted run leaves
the folder's model as it was, not one new graph beside two old ones; a file there that is a
link is replaced, not written through; and other files in the folder (LARGE_DROPS, notes) are
kept. Staging folders that a run stopped by a signal left behind (SIGTERM ends Python without
its ``finally``) are removed by the next run into that folder once their process is gone.
Imports without torch.
"""

from __future__ import annotations

import contextlib
import glob
import os
import shutil
from pathlib import Path

from . import contract as C
from .read_only import refuse_read_only


def remove_stale_stages(out_dir: Path, tag: str) -> None:
    """``tag``'s staging folders beside ``out_dir`` whose process is gone; a running one's is kept."""
    for stage in Path(out_dir).parent.glob(f".{glob.escape(Path(out_dir).name)}.{tag}-*"):
        pid = stage.name.rsplit("-", 1)[-1]
        if not pid.isdigit() or not stage.is_dir():
            continue
        try:
            os.kill(int(pid), 0)
        except ProcessLookupError:
            shutil.rmtree(stage, ignore_errors=True)
        except (PermissionError, OverflowError):
            pass  # another user's process, or no process id at all: not ours to judge


@contextlib.contextmanager
def staged_model_files(out_dir: Path, tag: str):
    """Yields a fresh staging folder for ``out_dir``'s new files (``tag``: the tool writing
    them). When the block ends normally the three graphs and export.json staged there replace
    those in ``out_dir`` (export.json last); in every case the staging folder is removed."""
    out_dir = Path(out_dir)
    # Before any work: a graph or export.json made read-only is kept (read_only.py).
    targets = [out_dir / name for name in [*(C.FILES[n] for n in C.NETWORKS), C.EXPORT_INFO]]
    refuse_read_only(*targets, follow_links=False)  # renamed over: a link is replaced, its target kept
    remove_stale_stages(out_dir, tag)
    stage = out_dir.parent / f".{out_dir.name}.{tag}-{os.getpid()}"
    shutil.rmtree(stage, ignore_errors=True)
    stage.mkdir()
    try:
        yield stage
        refuse_read_only(*targets, follow_links=False)  # again: the work may have taken minutes
        for name in [*(C.FILES[n] for n in C.NETWORKS), C.EXPORT_INFO]:
            if (stage / name).exists():
                os.replace(stage / name, out_dir / name)
    finally:
        shutil.rmtree(stage, ignore_errors=True)
