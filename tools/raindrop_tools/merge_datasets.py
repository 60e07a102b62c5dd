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
from pathlib import Path

from .manifest import manifest_lines

IMAGE_KEYS = ("rainy", "clean", "mask", "alpha")


def merge(out: Path, sources: list[Path]) -> int:
    records = []
    for src in sources:
        tag = src.name.removeprefix("train-")
        lines = manifest_lines(src)
        if not lines:
            raise ValueError(f"{src}: no manifest.jsonl (nor the parts of a sharded render)")
        for _, _, line in lines:
            r = json.loads(line)
            r["id"] = f"{tag}_{r['id']}"
            for key in IMAGE_KEYS:
                if key not in r:
                    continue
                dst = out / key / f"{r['id']}.png"
                dst.parent.mkdir(parents=True, exist_ok=True)
                target = (src / r[key]).resolve()
                if dst.is_symlink() or dst.exists():
                    if dst.resolve() != target:
                        raise ValueError(f"{dst} already links elsewhere; merge into an empty folder")
                else:
                    os.symlink(target, dst)
                r[key] = f"{key}/{r['id']}.png"
            records.append(r)
    ids = [r["id"] for r in records]
    if len(set(ids)) != len(ids):
        raise ValueError("two sources give the same sample id; give the set folders distinct names")
    records.sort(key=lambda r: r["id"])
    out.mkdir(parents=True, exist_ok=True)
    (out / "manifest.jsonl").write_text("".join(json.dumps(r) + "\n" for r in records))
    return len(records)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, type=Path)
    ap.add_argument("sources", nargs="+", type=Path)
    a = ap.parse_args(argv)
    try:
        n = merge(a.out, a.sources)
    except (OSError, ValueError, KeyError) as e:
        print(f"merge_datasets: {e}")
        return 1
    print(f"merge_datasets: {n} samples in {a.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
