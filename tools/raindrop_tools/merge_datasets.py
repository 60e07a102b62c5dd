"""Several rendered data sets as one, without copying images.

    python -m raindrop_tools.merge_datasets --out data/train-mix data/train-a data/train-b

Each sample's id becomes ``<set>_<id>`` (the set folder's name without a ``train-`` prefix), so
that the same background rendered by two presets stays two samples. The images are symbolic
links into the source folders; the merged manifest.jsonl keeps every other key of the sources'
records (CONTRACTS.md section 1).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

from .manifest import manifest_lines
from .read_only import refuse_read_only

IMAGE_KEYS = ("rainy", "clean", "mask", "alpha")


def _record(folder: Path, name: str, number: int, line: str) -> dict:
    """One manifest line as a sample record; a line that is not one is an error naming its
    file and line."""
    try:
        r = json.loads(line)
    except json.JSONDecodeError as e:
        raise ValueError(f"{folder / name}:{number}: not JSON ({e.msg}): {line.strip()[:80]}") from None
    if not isinstance(r, dict) or not isinstance(r.get("id"), str):
        raise ValueError(f"{folder / name}:{number}: not a sample record (no id): {line.strip()[:80]}")
    return r


def _is_earlier_merge(out: Path) -> bool:
    """Whether ``out`` holds a manifest this tool wrote: every image of every record a link."""
    for name, number, line in manifest_lines(out):
        r = _record(out, name, number, line)
        # rainy, clean and mask present (a record of ids and notes alone is someone else's file),
        # and every image a link.
        if not all(k in r for k in ("rainy", "clean", "mask")):
            return False
        if not all(isinstance(r[k], str) and (out / r[k]).is_symlink() for k in IMAGE_KEYS if k in r):
            return False
    return True


def merge(out: Path, sources: list[Path]) -> int:
    """Links the sources' images into ``out`` and writes its manifest. Everything is checked
    before the first link: a rendered or prepared data set in ``out`` (its manifest was replaced
    by the merged one), a source that is ``out``, and clashing ids or links."""
    refuse_read_only(out / "manifest.jsonl", follow_links=False)  # before the first link
    resolved = out.resolve()
    for src in sources:
        if src.resolve() == resolved:
            raise ValueError(f"{src} is both a source and --out; merge into a new folder")
    if manifest_lines(out) and not _is_earlier_merge(out):
        raise ValueError(f"{out} holds a data set of its own (its manifest would be replaced); merge into a new folder")
    records, links = [], {}
    for src in sources:
        tag = src.name.removeprefix("train-")
        lines = manifest_lines(src)
        if not lines:
            raise ValueError(f"{src}: no manifest.jsonl (nor the parts of a sharded render)")
        for name, number, line in lines:
            r = _record(src, name, number, line)
            r["id"] = f"{tag}_{r['id']}"
            for key in IMAGE_KEYS:
                if key not in r:
                    continue
                if not isinstance(r[key], str):
                    raise ValueError(f"{src / name}:{number}: '{key}' is not a path: {r[key]!r}")
                dst = out / key / f"{r['id']}.png"
                target = (src / r[key]).resolve()
                if dst in links and links[dst] != target:
                    raise ValueError(f"two sources give the sample id {r['id']}; give the set folders distinct names")
                if (dst.is_symlink() or dst.exists()) and dst.resolve() != target:
                    raise ValueError(f"{dst} already links elsewhere; merge into an empty folder")
                links[dst] = target
                r[key] = f"{key}/{r['id']}.png"
            records.append(r)
    ids = [r["id"] for r in records]
    if len(set(ids)) != len(ids):
        raise ValueError("two sources give the same sample id; give the set folders distinct names")
    for dst, target in links.items():
        if not (dst.is_symlink() or dst.exists()):
            dst.parent.mkdir(parents=True, exist_ok=True)
            os.symlink(target, dst)
    records.sort(key=lambda r: r["id"])
    out.mkdir(parents=True, exist_ok=True)
    refuse_read_only(out / "manifest.jsonl", follow_links=False)
    tmp = out / f".manifest.jsonl.tmp-{os.getpid()}"
    tmp.write_text("".join(json.dumps(r) + "\n" for r in records))
    os.replace(tmp, out / "manifest.jsonl")
    return len(records)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, type=Path)
    ap.add_argument("sources", nargs="+", type=Path)
    a = ap.parse_args(argv)
    try:
        n = merge(a.out, a.sources)
    except (OSError, ValueError) as e:  # ManifestError is a ValueError
        print(f"merge_datasets: error: {e}", file=sys.stderr)
        return 1
    print(f"merge_datasets: {n} samples in {a.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
