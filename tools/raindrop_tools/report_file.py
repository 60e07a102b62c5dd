"""Where a tool's JSON report (``--json FILE``) may go, checked before the work: a report once
replaced the data set's own manifest.jsonl and an output image it was scoring. A report file is
a new file or an earlier report (a JSON object), named .json; it is written whole or not at all."""

from __future__ import annotations

import json
import os
from pathlib import Path

from .read_only import read_only_problem


def report_path_problem(path: Path) -> str | None:
    """Why ``path`` may not take a report, in a few words; None when it may."""
    path = Path(path)
    if path.suffix.lower() != ".json":
        return f"--json {path}: name the report .json (it would replace a file of another kind)"
    if path.is_symlink() or (path.exists() and not path.is_file()):
        return f"--json {path}: not a plain file"
    problem = read_only_problem(path, follow_links=False)  # renamed over: a link is replaced, its target kept
    if problem:
        return f"--json {problem}"
    if path.exists():
        try:
            if not isinstance(json.loads(path.read_text()), dict):
                raise ValueError
        except (OSError, ValueError, UnicodeDecodeError):
            return f"--json {path}: exists and is not an earlier report (a JSON object); choose another name"
    parent = path.parent if str(path.parent) else Path(".")
    if parent.exists() and not parent.is_dir():
        return f"--json {path}: {parent} is not a folder"
    return None


def write_report(path: Path, obj) -> None:
    """``obj`` as indented JSON at ``path`` (its folder made if needed), through a temporary."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}-0")
    try:
        tmp.write_text(json.dumps(obj, indent=1) + "\n")
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
