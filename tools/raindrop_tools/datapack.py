"""Carry a data set to a training machine in fewer bytes, and back, without losing a pixel.

A rendered data set is mostly redundant: every variant of a frame has the same clean image,
and a rainy image equals its clean one wherever no drop touches it. A GPU machine that takes
a few tens of megabytes per transfer (and has no renderer: no Embree there) can still train on
hundreds of samples if they travel as:

* each distinct clean image once, as lossless WebP;
* per sample, the rainy image's differing pixels only (zero elsewhere) as lossless WebP, with
  a one-bit "differs" map as PNG, and the mask as it is.

``pack OUT SRC...`` writes that (a subset with ``--split``/``--frames``/``--variants``), ``unpack
PACK DST`` turns it back into data sets the trainer reads (DST/<source folder name>: manifest.jsonl
without the per-drop lists, PNG files at the original paths) and
checks every image against the SHA-256 of the original's decoded pixels: a pack that does not
give back the exact pixels is refused, not trained on.

    python -m raindrop_tools.datapack pack out/pack data/train data/train-mix --frames 90 --variants 4
    python -m raindrop_tools.datapack unpack out/pack data   # -> data/train, data/train-mix
"""

from __future__ import annotations

import argparse
import functools
import hashlib
import json
import os
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import cv2
import numpy as np

from .manifest import MANIFEST, ManifestError, manifest_records
from .read_only import ReadOnlyFileError, refuse_read_only

INDEX = "datapack.json"
LOSSLESS_WEBP = [cv2.IMWRITE_WEBP_QUALITY, 101]  # above 100: lossless


class PackError(Exception):
    pass


def _read(path: Path) -> np.ndarray:
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise PackError(f"{path}: cannot read image")
    return img


def _digest(img: np.ndarray) -> str:
    h = hashlib.sha256()
    h.update(f"{img.shape}|{img.dtype}".encode())
    h.update(np.ascontiguousarray(img).tobytes())
    return h.hexdigest()


def _write(path: Path, img: np.ndarray, params: list[int] | None = None) -> None:
    refuse_read_only(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(path), img, params or []):
        raise PackError(f"{path}: cannot write image")


def _where(differs: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a`` where ``differs`` (one flag per pixel), else ``b``, for grey or colour images."""
    return np.where(differs[..., None] if a.ndim == 3 else differs, a, b).astype(a.dtype)


def _frame(e: dict) -> str:
    """The background a sample was rendered over (its manifest's ``source`` path), so that
    frames, not samples, are chosen; a sample without one (real pairs) is its own frame."""
    src = e.get("source")
    return Path(src).name if isinstance(src, str) and "/" in src else e["id"]


def _choose(sets: list[list[dict]], frames: int | None, variants: list[int | None]) -> list[list[dict]]:
    """``frames`` backgrounds spread evenly over the sorted union of the sets' backgrounds, and
    of each at most ``variants`` samples per set. Sets rendered over the same frames at the same
    size share their clean images, which the pack stores once."""
    keep = None
    if frames is not None:
        names = sorted({_frame(e) for entries in sets for e in entries})
        if frames < len(names):
            idx = np.linspace(0, len(names) - 1, frames).round().astype(int)
            keep = {names[i] for i in idx.tolist()}
    chosen = []
    for entries, most in zip(sets, variants):
        count: dict[str, int] = {}
        out = []
        for e in entries:
            f = _frame(e)
            if keep is not None and f not in keep:
                continue
            if most is not None and count.get(f, 0) >= most:
                continue
            count[f] = count.get(f, 0) + 1
            out.append(e)
        chosen.append(out)
    return chosen


def pack(srcs: list[Path], out: Path, splits: list[str] | None, frames: int | None,
         variants: list[int | None], threads: int) -> dict:
    sets = []
    for src in srcs:
        if not (src / "manifest.jsonl").is_file() and not src.is_dir():
            raise PackError(f"{src}: no such folder")
        try:
            entries = manifest_records(src)
        except ManifestError as e:
            raise PackError(str(e)) from None
        if not entries:
            raise PackError(f"{src}: no samples (not a rendered data set: no manifest.jsonl records)")
        for e in entries:
            if not isinstance(e, dict) or not all(isinstance(e.get(k), str) for k in ("id", "rainy", "clean", "mask")):
                raise PackError(f"{src}: a manifest record without the id, rainy, clean and mask of a sample: "
                                f"{json.dumps(e)[:80]}")
        if splits is not None:
            entries = [e for e in entries if e.get("split") in splits]
            if not entries:
                raise PackError(f"{src}: no samples of split {', '.join(splits)}")
        sets.append(entries)
    sets = _choose(sets, frames, variants)
    names = [src.name for src in srcs]
    if len(set(names)) != len(names):
        raise PackError("two sources with the same folder name: " + ", ".join(names))
    if not any(sets):
        raise PackError("no samples to pack")
    if out.exists() and any(out.iterdir()):
        raise PackError(f"{out}: not empty; a pack goes into a new or empty folder (old files would travel too)")
    out.mkdir(parents=True, exist_ok=True)

    def one(job: tuple[Path, str, dict]) -> dict:
        src, name, e = job
        clean = _read(src / e["clean"])
        rainy = _read(src / e["rainy"])
        mask = _read(src / e["mask"])
        if rainy.shape != clean.shape:
            raise PackError(f"{src / e['rainy']}: size differs from its clean image")
        differs = np.any(rainy != clean, axis=2) if rainy.ndim == 3 else rainy != clean
        layer = _where(differs, rainy, np.zeros_like(rainy))
        stem = f"{name}/{e['id']}"
        _write(out / "layer" / f"{stem}.webp", layer, LOSSLESS_WEBP)
        _write(out / "differs" / f"{stem}.png", differs.astype(np.uint8) * 255)
        _write(out / "mask" / f"{stem}.png", mask)
        # The per-drop list is the largest part of a manifest line and no trainer reads it.
        entry = {k: v for k, v in e.items() if k != "drops"}
        return {"set": name, "stem": stem, "entry": entry, "clean": clean,
                "digests": {"rainy": _digest(rainy), "clean": _digest(clean), "mask": _digest(mask)}}

    jobs = [(src, name, e) for src, name, entries in zip(srcs, names, sets) for e in entries]
    with ThreadPoolExecutor(threads) as pool:
        packed = list(pool.map(one, jobs))
    cleans: dict[str, str] = {}  # digest of a clean image -> its file in the pack
    samples = []
    for p in packed:
        d = p["digests"]["clean"]
        img = p.pop("clean")
        if d not in cleans:
            cleans[d] = f"clean/{len(cleans):05d}.webp"
            _write(out / cleans[d], img, LOSSLESS_WEBP)
        p["clean"] = cleans[d]
        samples.append(p)
    refuse_read_only(out / INDEX)
    (out / INDEX).write_text(json.dumps({"sets": names, "samples": samples}))
    return {"samples": {n: len(s) for n, s in zip(names, sets)}, "cleans": len(cleans),
            "bytes": sum(f.stat().st_size for f in out.rglob("*") if f.is_file())}


def unpack(pack_dir: Path, dst: Path, threads: int) -> int:
    try:
        index = json.loads((pack_dir / INDEX).read_text())
    except (OSError, ValueError) as e:
        raise PackError(f"{pack_dir}: not a data pack ({e})") from None
    for name in index["sets"]:
        if (dst / name / MANIFEST).exists():
            raise PackError(f"{dst / name}: already holds a data set; choose an empty folder")
    # Every file lands inside its set's folder, as a new file: a pack's index is data, and a
    # name in it ("/home/x", "../../y") must not make the unpack write anywhere else, nor over a
    # file already there.
    root = dst.resolve()
    for s in index["samples"]:
        for key in ("rainy", "clean", "mask"):
            rel = Path(str(s["set"])) / str(s["entry"][key])
            target = (dst / rel).resolve()
            if rel.is_absolute() or ".." in rel.parts or not target.is_relative_to(root / str(s["set"])):
                raise PackError(f"{pack_dir}: sample {s.get('stem')!r}: {key} path {str(rel)!r} leaves the data set's folder")
            if target.suffix.lower() != ".png":
                raise PackError(f"{pack_dir}: sample {s.get('stem')!r}: {key} path {str(rel)!r} is not a .png")
            if target.exists():
                raise PackError(f"{target}: already exists; unpack into an empty folder")

    # Variants of a frame share one clean file and follow each other in a set: decode it once
    # (a bounded cache: a pack of large frames must not hold them all).
    read_clean = functools.lru_cache(maxsize=64)(_read)

    def one(s: dict) -> None:
        e, stem = s["entry"], s["stem"]
        clean = read_clean(pack_dir / s["clean"])
        layer = _read(pack_dir / "layer" / f"{stem}.webp")
        differs = _read(pack_dir / "differs" / f"{stem}.png") > 0
        rainy = _where(differs, layer, clean)
        mask = _read(pack_dir / "mask" / f"{stem}.png")
        for key, img in (("rainy", rainy), ("clean", clean), ("mask", mask)):
            if _digest(img) != s["digests"][key]:
                raise PackError(f"{pack_dir}: sample {stem!r}: {key} differs from the packed original")
            _write(dst / s["set"] / e[key], img, [cv2.IMWRITE_PNG_COMPRESSION, 1])

    with ThreadPoolExecutor(threads) as pool:
        list(pool.map(one, index["samples"]))
    counts = {}
    for name in index["sets"]:
        lines = [json.dumps(s["entry"]) + "\n" for s in index["samples"] if s["set"] == name]
        (dst / name).mkdir(parents=True, exist_ok=True)
        refuse_read_only(dst / name / MANIFEST)
        tmp = dst / name / (MANIFEST + ".tmp")
        tmp.write_text("".join(lines))
        os.replace(tmp, dst / name / MANIFEST)  # the manifest last: a broken unpack leaves no data set
        counts[name] = len(lines)
    return counts


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m raindrop_tools.datapack", description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="command", required=True)
    p = sub.add_parser("pack", help="data set folder -> pack folder")
    p.add_argument("out")
    p.add_argument("src", nargs="+", metavar="DIR[:VARIANTS]",
                   help="data set folders (their folder names name them in the pack); :K keeps at most K samples "
                   "per frame of that set, overriding --variants")
    p.add_argument("--split", action="append", help="keep samples of this split (repeatable; default all)")
    p.add_argument("--frames", type=int, help="at most this many background frames, spread evenly")
    p.add_argument("--variants", type=int, help="at most this many samples per frame and data set")
    u = sub.add_parser("unpack", help="pack folder -> data set folder (pixels checked)")
    u.add_argument("pack")
    u.add_argument("dst")
    for q in (p, u):
        q.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    args = ap.parse_args(argv)
    try:
        if args.command == "pack":
            for opt in ("frames", "variants"):
                if getattr(args, opt) is not None and getattr(args, opt) < 1:
                    raise PackError(f"--{opt} must be at least 1")
            srcs, variants = [], []
            for item in args.src:
                path, _, k = item.partition(":")
                if k and (not k.isdigit() or int(k) < 1):
                    raise PackError(f"{item}: the number after ':' must be at least 1")
                srcs.append(Path(path))
                variants.append(int(k) if k else args.variants)
            r = pack(srcs, Path(args.out), args.split, args.frames, variants, args.threads)
            sets = ", ".join(f"{n} {k}" for k, n in r["samples"].items())
            print(f"{args.out}: {sets} samples; {r['cleans']} clean images; {r['bytes'] / 2**20:.1f} MiB")
        else:
            counts = unpack(Path(args.pack), Path(args.dst), args.threads)
            sets = ", ".join(f"{n} in {args.dst}/{k}" for k, n in counts.items())
            print(f"{sets}: every pixel as packed")
    except (PackError, ReadOnlyFileError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
