"""The lines of a rendered data set's manifest, whether one run wrote it or N shards did.

One run of ``raindrop-render`` writes ``manifest.jsonl``, sorted by id. The shards of a run
(``raindrop-render --shard K/N``) write ``manifest.part-K-of-N.jsonl`` each, until
``raindrop-render --merge-shards DIR`` merges them into the ``manifest.jsonl`` one run would
have written. A folder whose parts were not merged (yet) reads as if they had been: every
record of ``manifest.jsonl`` and of the parts, sorted by id, a record found in two files
(byte-identical) once. Standard library only.
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

MANIFEST = "manifest.jsonl"
PART = re.compile(r"manifest\.part-(\d+)-of-(\d+)\.jsonl")


class ManifestError(ValueError):
    """A manifest file that cannot be read as text, named in one line."""


def _read_text(f: Path) -> str:
    try:
        return f.read_text(encoding="utf-8")
    except UnicodeDecodeError as e:
        raise ManifestError(f"{f}: not UTF-8 text (byte {e.start}); is it a manifest?") from None


def _whole_lines(text: str) -> list[str]:
    """The file's lines, less a last one without a line break that is not whole JSON: a record
    cut short (an interrupted run's append), which the renderer ignores as well and renders
    again on resuming. (A last record that is whole but lacks its line break, written by hand,
    is read.)"""
    lines = text.split("\n")
    if lines and lines[-1].strip():
        try:
            json.loads(lines[-1])
        except json.JSONDecodeError:
            lines.pop()
    return lines


def manifest_files(root: str | os.PathLike) -> list[Path]:
    """``manifest.jsonl`` (when present), then the shards' parts sorted by name."""
    root = Path(root)
    parts = sorted(p for p in root.glob("manifest.part-*-of-*.jsonl") if PART.fullmatch(p.name))
    whole = [root / MANIFEST] if (root / MANIFEST).is_file() else []
    return whole + parts


def manifest_lines(root: str | os.PathLike) -> list[tuple[str, int, str]]:
    """The non-blank lines of the data set's manifest as (file name, 1-based line, text).

    Only ``manifest.jsonl``: its lines in file order. With shard parts: the lines of every
    file sorted by id (lines that are not JSON objects with an id last, in file order), an
    identical line in two files kept once. Empty when there is no manifest at all."""
    files = manifest_files(root)
    lines = [
        (f.name, n, text)
        for f in files
        for n, text in enumerate(_whole_lines(_read_text(f)), start=1)
        if text.strip()
    ]
    if len(files) <= 1:
        return lines

    def sort_id(text: str) -> tuple[int, str]:
        try:
            obj = json.loads(text)
        except json.JSONDecodeError:
            return (1, "")
        sid = obj.get("id") if isinstance(obj, dict) else None
        return (0, sid) if isinstance(sid, str) else (1, "")

    seen: set[str] = set()
    unique = []
    for line in lines:
        if line[2] not in seen:
            seen.add(line[2])
            unique.append(line)
    return sorted(unique, key=lambda line: sort_id(line[2]))  # stable: unsortable lines keep their order


def manifest_records(root: str | os.PathLike) -> list:
    """The parsed records of ``manifest_lines``; a line that is not JSON is a ``ManifestError``
    naming its file and line (json's own message names neither)."""
    root = Path(root)
    records = []
    for file, lineno, text in manifest_lines(root):
        try:
            records.append(json.loads(text))
        except json.JSONDecodeError as e:
            raise ManifestError(f"{root / file}:{lineno}: not valid JSON ({e.msg} at column {e.colno})") from None
    return records
