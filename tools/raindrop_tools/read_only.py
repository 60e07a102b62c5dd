"""A file made read-only is kept: no tool of the project writes over it.

The tools write a file beside its name and rename it over that name, which needs only the
folder's write permission, and root may open any file for writing. Either way a file whose
mode grants nobody write permission (``chmod a-w``, how people protect a result) used to be
replaced without a word. The rule is the C++ programs' (``check_replaceable`` in
src/common/image_io.cpp): a regular file with no write bit is refused, for every user, with
the same one-line message, before anything is written over it. Imports without torch.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path


class ReadOnlyFileError(PermissionError):
    """A read-only file a tool would have replaced. A PermissionError, so that every tool's
    ``except OSError`` reports it on one line and exits non-zero."""


def read_only_problem(path: str | os.PathLike, follow_links: bool = True) -> str | None:
    """Why ``path`` may not be replaced, in the C++ programs' words; None when it may (it does not
    exist, is not a regular file, or someone may write it). ``follow_links``: the file a link
    names is what a write through the link changes; where a file is renamed over the name
    instead, only the link itself goes and its target is kept, so such sites pass False."""
    try:
        mode = (os.stat if follow_links else os.lstat)(path).st_mode
    except OSError:
        return None  # absent (or unreadable metadata): nothing there to lose
    if stat.S_ISREG(mode) and not mode & (stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH):
        return f"'{Path(path)}': read-only (no write permission for anyone); make it writable, or remove it"
    return None


def first_read_only_problem(*paths: str | os.PathLike, follow_links: bool = True) -> str | None:
    """read_only_problem of the first of ``paths`` that is a read-only file; None when none is."""
    return next(filter(None, (read_only_problem(path, follow_links) for path in paths)), None)


def refuse_read_only(*paths: str | os.PathLike, follow_links: bool = True) -> None:
    """Raises ReadOnlyFileError for the first of ``paths`` that is a read-only file."""
    problem = first_read_only_problem(*paths, follow_links=follow_links)
    if problem:
        raise ReadOnlyFileError(problem)
