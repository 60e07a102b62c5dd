"""The small text files that tune raindrop-remove beside its models (a detector router's ROUTER,
a camera's wet gate): one key and its words per line, '#' starting a comment line, each key
once. Read here as raindrop-remove reads them (include/raindrop/remove/key_file.h), so that the
tools refuse what the program refuses, naming the file."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np


# The largest key file read, as raindrop-remove's kMaxKeyFileBytes (a few hundred bytes in use).
MAX_KEY_FILE_BYTES = 64 * 1024


def read_fields(path: str | os.PathLike, error: type[Exception]) -> dict[str, list[str]]:
    """Each key's words; `error` naming the file where it is not a regular file (a FIFO blocked
    the read, /dev/zero grew it without end), is larger than MAX_KEY_FILE_BYTES, cannot be read,
    or gives a key twice."""
    path = Path(path)
    if not path.exists():
        raise error(f"'{path}': cannot read it (no such file)")
    if not path.is_file():
        raise error(f"'{path}': not a file")
    try:
        with open(path, "rb") as f:
            data = f.read(MAX_KEY_FILE_BYTES + 1)
        if len(data) > MAX_KEY_FILE_BYTES:
            raise error(f"'{path}': larger than {MAX_KEY_FILE_BYTES // 1024} KiB: not a key file")
        text = data.decode("utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise error(f"'{path}': cannot read it ({e})") from None
    fields: dict[str, list[str]] = {}
    for line in text.splitlines():
        parts = line.split()
        if not parts or parts[0].startswith("#"):
            continue
        if parts[0] in fields:
            raise error(f"'{path}': '{parts[0]}' is given twice")
        fields[parts[0]] = parts[1:]
    return fields


def finite_vector(fields: dict[str, list[str]], key: str, n: int, path, error: type[Exception],
                  positive: bool = False) -> np.ndarray:
    """Exactly `n` finite numbers under `key` (with `positive`, each above 0), else `error` naming the file."""
    try:
        v = np.array([float(x) for x in fields.get(key, [])], np.float64)
    except ValueError:
        raise error(f"'{path}': '{key}' holds something that is not a number") from None
    if len(v) != n or not np.all(np.isfinite(v)):
        raise error(f"'{path}': '{key}' must hold {n} finite number{'s' if n > 1 else ''}")
    if positive and np.any(v <= 0):
        raise error(f"'{path}': '{key}' must be positive")
    return v


def check_format(fields: dict[str, list[str]], fmt: int, path, error: type[Exception]) -> None:
    if fields.get("format") != [str(fmt)]:
        raise error(f"'{path}': expected 'format {fmt}'")


def single_name(fields: dict[str, list[str]], key: str, path, error: type[Exception], what: str) -> str:
    """The one folder name under `key` (no path: '.', '..' and '/' refused), else `error` saying `what` it must be."""
    words = fields.get(key, [])
    if len(words) != 1 or words[0] in (".", "..") or "/" in words[0]:
        raise error(f"'{path}': '{key}' must name {what}")
    return words[0]


def key_file_path_problem(path: str | os.PathLike, error: type[Exception], kind_key: str) -> str | None:
    """Why a key file may not be written at `path`, in one line; None when it may. It takes a new
    or empty file, a link (renamed over: the link is replaced, its target kept), or an earlier key
    file of the same kind (its 'format' line and `kind_key`: a gate's 'models', a ROUTER's
    'alternative'): a gate once replaced a wet frame it was fitted on, and could replace a
    model folder's ROUTER. Check it before the work."""
    from .read_only import read_only_problem

    raw = os.fspath(path)
    path = Path(path)
    if raw.endswith("/"):
        return f"'{raw}': names a folder; give a file name"
    if not path.is_symlink() and path.exists() and not path.is_file():
        return f"'{path}': not a plain file"
    problem = read_only_problem(path, follow_links=False)
    if problem:
        return problem
    if path.is_file() and not path.is_symlink() and path.stat().st_size > 0:
        try:
            fields = read_fields(path, error)
        except error as e:
            return f"exists and is not a key file ({e}); choose another name"
        if "format" not in fields or kind_key not in fields:
            return f"'{path}': exists and is not a key file of this kind (no 'format' and '{kind_key}' lines); choose another name"
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        return f"'{path}': folder '{parent}' does not exist"
    return None


def write_fields(path: str | os.PathLike, fields: list[tuple[str, object]], error: type[Exception],
                 comment: str = "") -> None:
    """Writes `comment` as '#' lines, then one line per key (a sequence as its numbers' reprs),
    to a hidden temporary beside `path` and renames it over it (never a half-written file); what
    key_file_path_problem refuses is refused, with `error` (the file's kind is its second key: a
    gate's 'models', a ROUTER's 'alternative')."""
    from .read_only import refuse_read_only

    path = Path(path)
    refuse_read_only(path, follow_links=False)  # its own error (a PermissionError), as before
    problem = key_file_path_problem(path, error, fields[1][0])
    if problem:
        raise error(problem)
    lines = [f"# {line}" for line in comment.splitlines()]
    for key, value in fields:
        words = " ".join(repr(float(v)) for v in value) if isinstance(value, (list, tuple, np.ndarray)) else str(value)
        lines.append(f"{key} {words}")
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    try:
        tmp.write_text("\n".join(lines) + "\n")
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
