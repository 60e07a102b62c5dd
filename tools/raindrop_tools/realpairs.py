"""Real rainy/clean photograph pairs: listing, a group-wise split, rough drop masks, and a
data-set folder in the CONTRACTS.md section 1 layout that training and evaluation can read.

    python -m raindrop_tools.realpairs list DIR [--holdout SPEC]
    python -m raindrop_tools.realpairs prepare DIR --out DATASET [--holdout SPEC]
        [--blur 5] [--mask-threshold 12] [--open 3] [--close 7] [--min-area 16]

**Pairs.** A pair is ``X_rain.<ext>`` (or ``X_rainy.<ext>``) beside ``X_clean.<ext>`` in one
folder (png, jpg, jpeg, bmp, tif, tiff; any case). ``X`` is the pair's id. A rainy image
without its clean partner (or the reverse) is an error that names the file.

**Groups.** Pairs cropped from one scene must never be on both sides of a split. The group of
a pair is ``X`` without a trailing ``_t<digits>`` (``robotcar_i1600_t3`` -> ``robotcar_i1600``),
or ``X`` itself when it has no such part.

**Split rule** (``split_groups``): the groups are ordered by the SHA-256 of their UTF-8 name
(hex digest, ties - impossible in practice - by name), which depends neither on the file order
nor on which other groups exist; with a held-out fraction ``f``, the group at position ``i`` of
that order goes to ``test`` when ``floor((i + 1) f) > floor(i f)``, else to ``train``. For the
default ``f = 0.5`` that is every second group (positions 1, 3, 5, ...): 5 of 10 groups, and
``floor(n f)`` groups in general. ``--holdout`` takes either such a fraction (``0.3``) or a
comma-separated list of group names that form the test split exactly (``robotcar_i0,robotcar_i1600``).

**Rough masks** (``rough_mask``), the paper's way for real data (its section 5: the difference
of the rainy and the clean image, thresholded, cleaned by morphology): 8-bit luma of both
images (``metrics.LUMA_WEIGHTS``, in float32, not rounded), each box-blurred ``blur`` x
``blur`` (absorbs the 1-2 px stereo offset of a two-camera rig), ``|rainy - clean| >
threshold`` levels, then a morphological opening (elliptical, ``open_size``: removes speckle
left by noise and parallax on edges) and closing (elliptical, ``close_size``: fills the flat
inner part of drops, where a drop resembles the scene), then connected components smaller
than ``min_area`` pixels are dropped. These masks are rough: they miss drops that look like
what is behind them and catch parallax on near objects; they serve as training targets for
fine-tuning and as the reference of detection AP, not as truth.

**Data set** (``prepare``): ``rainy/<id>.png``, ``clean/<id>.png``, ``mask/<id>.png`` (0/255)
and ``manifest.jsonl`` (sorted by id) with the contract's keys plus ``split`` (``train`` or
``test``), ``group``, ``source: "real-pairs"``, ``origin`` (the two input file names),
``coverage`` and ``mask_params``; ``realpairs.json`` records the command, the parameters and
the groups of each split. rainy != clean outside the mask in such a set: train with the
source's ``check_outside_mask: false`` (see ``config.SourceConfig``).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import re
import shutil
import sys
from dataclasses import asdict, dataclass
from pathlib import Path

import cv2
import numpy as np

from .imageio import ImageError, read_rgb, write_grey, write_rgb
from .metrics import luma_float

IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")
RAINY_SUFFIXES = ("_rainy", "_rain")
CLEAN_SUFFIX = "_clean"
SOURCE = "real-pairs"
DEFAULT_HOLDOUT = 0.5
SPLITS = ("train", "test")
_GROUP = re.compile(r"^(.+)_t\d+$")


class PairsError(ValueError):
    """A folder of pairs that cannot be used (unpaired files, no pairs, bad --holdout)."""


@dataclass(frozen=True)
class Pair:
    id: str
    group: str
    rainy: Path
    clean: Path
    split: str | None = None


@dataclass(frozen=True)
class MaskParams:
    """Parameters of ``rough_mask`` with their defaults (the measurement of project issue 9)."""

    blur: int = 5  # box blur size (px) applied to both lumas; 1 = none
    threshold: float = 12.0  # |luma difference| in 8-bit levels, strictly greater
    open_size: int = 3  # elliptical opening (px); 1 = none
    close_size: int = 7  # elliptical closing (px); 1 = none
    min_area: int = 16  # connected components (8-connected) smaller than this are dropped

    def mask(self, rainy: np.ndarray, clean: np.ndarray) -> np.ndarray:
        """``rough_mask`` of a rainy/clean pair with these parameters."""
        return rough_mask(rainy, clean, self.blur, self.threshold, self.open_size, self.close_size, self.min_area)


def group_of(pair_id: str) -> str:
    """``X_t<n>`` -> ``X``; an id without such a tail is its own group."""
    m = _GROUP.match(pair_id)
    return m.group(1) if m else pair_id


def _stem_kind(path: Path) -> tuple[str, str] | None:
    stem = path.stem
    for suffix in RAINY_SUFFIXES:
        if stem.endswith(suffix) and len(stem) > len(suffix):
            return stem[: -len(suffix)], "rainy"
    if stem.endswith(CLEAN_SUFFIX) and len(stem) > len(CLEAN_SUFFIX):
        return stem[: -len(CLEAN_SUFFIX)], "clean"
    return None


def find_pairs(folder: str | os.PathLike) -> list[Pair]:
    """The pairs of ``folder`` (not recursive), sorted by id, without a split."""
    folder = Path(folder)
    if not folder.is_dir():
        raise PairsError(f"{folder}: not a folder")
    found: dict[str, dict[str, list[Path]]] = {}
    for p in sorted(folder.iterdir()):
        if not p.is_file() or p.suffix.lower() not in IMAGE_EXTENSIONS:
            continue
        kind = _stem_kind(p)
        if kind is None:
            continue
        pid, role = kind
        found.setdefault(pid, {"rainy": [], "clean": []})[role].append(p)
    problems, pairs = [], []
    for pid, roles in sorted(found.items()):
        for role in ("rainy", "clean"):
            if len(roles[role]) > 1:
                problems.append(f"{pid}: several {role} images: {', '.join(p.name for p in roles[role])}")
        if not roles["rainy"] or not roles["clean"]:
            have = (roles["rainy"] or roles["clean"])[0]
            missing = "clean" if not roles["clean"] else "rainy"
            problems.append(f"{have}: no {missing} partner ({pid}{CLEAN_SUFFIX if missing == 'clean' else '_rain'}.*)")
            continue
        if any(c in pid for c in "/\\\0") or not pid.strip():
            problems.append(f"{pid!r}: not a file-name-safe id")
            continue
        pairs.append(Pair(pid, group_of(pid), roles["rainy"][0], roles["clean"][0]))
    if problems:
        raise PairsError(f"{folder}: {len(problems)} problem(s):\n  " + "\n  ".join(problems))
    if not pairs:
        raise PairsError(f"{folder}: no pairs (X_rain.* or X_rainy.* beside X_clean.*)")
    return pairs


def _hash_order(groups) -> list[str]:
    return sorted(set(groups), key=lambda g: (hashlib.sha256(g.encode("utf-8")).hexdigest(), g))


def split_groups(groups, holdout: float | list[str] | str | None = None) -> dict[str, str]:
    """group -> ``train`` or ``test`` by the rule in the module docstring. ``holdout``: a
    fraction in [0, 1] (default 0.5), a list of test group names, or a CLI string of either."""
    groups = list(groups)
    if holdout is None:
        holdout = DEFAULT_HOLDOUT
    if isinstance(holdout, str):
        holdout = parse_holdout(holdout)
    if isinstance(holdout, (list, tuple, set, frozenset)):
        unknown = sorted(set(holdout) - set(groups))
        if unknown:
            raise PairsError(f"--holdout: unknown group(s) {', '.join(unknown)}; groups: {', '.join(sorted(set(groups)))}")
        return {g: ("test" if g in holdout else "train") for g in set(groups)}
    f = float(holdout)
    if not 0.0 <= f <= 1.0:
        raise PairsError(f"--holdout fraction must be in [0, 1], got {f}")
    return {
        g: ("test" if math.floor((i + 1) * f) > math.floor(i * f) else "train")
        for i, g in enumerate(_hash_order(groups))
    }


def parse_holdout(text: str) -> float | list[str]:
    try:
        return float(text)
    except ValueError:
        names = [t.strip() for t in text.split(",") if t.strip()]
        if not names:
            raise PairsError(f"--holdout: expected a fraction or group names, got {text!r}") from None
        return names


def assign_splits(pairs: list[Pair], holdout=None) -> list[Pair]:
    which = split_groups([p.group for p in pairs], holdout)
    return [Pair(p.id, p.group, p.rainy, p.clean, which[p.group]) for p in pairs]


def select(pairs: list[Pair], split: str | None) -> list[Pair]:
    """Pairs of one split (``None`` or ``all``: every pair)."""
    if split in (None, "all"):
        return list(pairs)
    if split not in SPLITS:
        raise PairsError(f"split must be train, test or all, got {split!r}")
    return [p for p in pairs if p.split == split]


def load_pair(pair: Pair) -> tuple[np.ndarray, np.ndarray]:
    """(rainy, clean) as HxWx3 uint8 RGB; refuses pairs of different sizes."""
    rainy, clean = read_rgb(pair.rainy), read_rgb(pair.clean)
    if rainy.shape != clean.shape:
        raise ImageError(f"{pair.id}: rainy {rainy.shape[1]}x{rainy.shape[0]} and clean "
                         f"{clean.shape[1]}x{clean.shape[0]} (WxH) differ in size")
    return rainy, clean


def _ellipse(k: int) -> np.ndarray:
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))


def luma_difference(rainy: np.ndarray, clean: np.ndarray, blur: int = MaskParams.blur) -> np.ndarray:
    """|blur(Y(rainy)) - blur(Y(clean))| in 8-bit levels, HxW float32."""
    a, b = luma_float(rainy), luma_float(clean)
    if blur > 1:
        a = cv2.blur(a, (blur, blur), borderType=cv2.BORDER_REPLICATE)
        b = cv2.blur(b, (blur, blur), borderType=cv2.BORDER_REPLICATE)
    return np.abs(a - b)


def rough_mask(
    rainy: np.ndarray,
    clean: np.ndarray,
    blur: int = MaskParams.blur,
    threshold: float = MaskParams.threshold,
    open_size: int = MaskParams.open_size,
    close_size: int = MaskParams.close_size,
    min_area: int = MaskParams.min_area,
) -> np.ndarray:
    """HxW uint8 0/255 drop mask of a real pair (module docstring). Defaults: ``MaskParams``."""
    if rainy.shape != clean.shape or rainy.dtype != np.uint8 or rainy.ndim != 3:
        raise ValueError(f"expected two HxWx3 uint8 images of one size, got {rainy.shape} and {clean.shape}")
    for name, k in (("blur", blur), ("open_size", open_size), ("close_size", close_size)):
        if k < 1:
            raise ValueError(f"{name} must be >= 1, got {k}")
    m = (luma_difference(rainy, clean, blur) > np.float32(threshold)).astype(np.uint8)
    if open_size > 1:
        m = cv2.morphologyEx(m, cv2.MORPH_OPEN, _ellipse(open_size))
    if close_size > 1:
        m = cv2.morphologyEx(m, cv2.MORPH_CLOSE, _ellipse(close_size))
    if min_area > 1 and m.any():
        n, labels, stats, _ = cv2.connectedComponentsWithStats(m, connectivity=8)
        keep = np.zeros(n, np.uint8)
        keep[1:] = stats[1:, cv2.CC_STAT_AREA] >= min_area
        m = keep[labels]
    return m * np.uint8(255)


def pair_mask(pair: Pair, params: MaskParams | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(rainy, clean, rough mask 0/255) of a pair."""
    p = params or MaskParams()
    rainy, clean = load_pair(pair)
    return rainy, clean, p.mask(rainy, clean)


def prepare(
    src: str | os.PathLike,
    out: str | os.PathLike,
    holdout=None,
    params: MaskParams | None = None,
    argv: list[str] | None = None,
) -> list[dict]:
    """Write the data set folder ``out`` from the pairs in ``src``; returns the manifest lines.

    ``out`` must be new or empty: the set is written into a hidden folder beside it and renamed
    into place when complete, so a pair that fails leaves nothing behind, and files already in
    ``out`` (a user's, a rendered or sharded set's) are never replaced."""
    params = params or MaskParams()
    pairs = assign_splits(find_pairs(src), holdout)
    final = Path(out)
    if final.exists() and (not final.is_dir() or any(final.iterdir())):
        what = "is not a folder" if not final.is_dir() else "is not empty"
        raise PairsError(f"{final}: {what}; choose a new --out")
    out = final.parent / f".{final.name}.prepare-{os.getpid()}"
    shutil.rmtree(out, ignore_errors=True)
    try:
        records = _write_pairs(src, out, pairs, holdout, params, argv)
        if final.is_dir():
            final.rmdir()  # empty, checked above
        os.replace(out, final)
    finally:
        shutil.rmtree(out, ignore_errors=True)
    return records


def _write_pairs(src, out: Path, pairs, holdout, params: MaskParams, argv) -> list[dict]:
    records = []
    for p in pairs:
        rainy, clean, mask = pair_mask(p, params)
        h, w = mask.shape
        write_rgb(out / "rainy" / f"{p.id}.png", rainy)
        write_rgb(out / "clean" / f"{p.id}.png", clean)
        write_grey(out / "mask" / f"{p.id}.png", mask)
        records.append(
            {
                "id": p.id,
                "rainy": f"rainy/{p.id}.png",
                "clean": f"clean/{p.id}.png",
                "mask": f"mask/{p.id}.png",
                "width": w,
                "height": h,
                "source": SOURCE,
                "split": p.split,
                "group": p.group,
                "variant": 0,
                "origin": {"rainy": p.rainy.name, "clean": p.clean.name},
                "coverage": float((mask > 0).mean()),
                "mask_params": asdict(params),
            }
        )
    records.sort(key=lambda r: r["id"])
    out.mkdir(parents=True, exist_ok=True)
    (out / "manifest.jsonl").write_text("".join(json.dumps(r) + "\n" for r in records))
    groups = {s: sorted({p.group for p in pairs if p.split == s}) for s in SPLITS}
    info = {
        "source": SOURCE,
        "from": str(src),
        "argv": argv,
        "holdout": holdout if holdout is not None else DEFAULT_HOLDOUT,
        "mask_params": asdict(params),
        "pairs": {s: sum(p.split == s for p in pairs) for s in SPLITS},
        "groups": groups,
    }
    (out / "realpairs.json").write_text(json.dumps(info, indent=2) + "\n")
    return records


def add_mask_arguments(ap: argparse.ArgumentParser) -> None:
    d = MaskParams()
    ap.add_argument("--blur", type=int, default=d.blur, help=f"box blur of both lumas, px (default {d.blur})")
    ap.add_argument("--mask-threshold", "--threshold-levels", dest="mask_threshold", type=float, default=d.threshold,
                    help=f"|luma difference| threshold, 8-bit levels (default {d.threshold:g})")
    ap.add_argument("--open", dest="open_size", type=int, default=d.open_size,
                    help=f"elliptical opening size, px (default {d.open_size})")
    ap.add_argument("--close", dest="close_size", type=int, default=d.close_size,
                    help=f"elliptical closing size, px (default {d.close_size})")
    ap.add_argument("--min-area", type=int, default=d.min_area,
                    help=f"drop components smaller than this, px (default {d.min_area})")


def mask_params_from_args(args, ap: argparse.ArgumentParser) -> MaskParams:
    """The rough mask's parameters from the command line; a usage error (``ap.error``) for values
    it cannot use: a size of 100000 px ended in OpenCV's allocation error, a NaN threshold gave
    an empty mask without a word."""
    for name, value in (("--blur", args.blur), ("--open", args.open_size), ("--close", args.close_size)):
        if not 1 <= value <= 1023:
            ap.error(f"{name} must be 1 to 1023 px (1: none), got {value}")
    if not (math.isfinite(args.mask_threshold) and args.mask_threshold >= 0):
        ap.error(f"--mask-threshold must be a number >= 0, got {args.mask_threshold}")
    if args.min_area < 0:
        ap.error(f"--min-area must be >= 0, got {args.min_area}")
    return MaskParams(args.blur, args.mask_threshold, args.open_size, args.close_size, args.min_area)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m raindrop_tools.realpairs", description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="command", required=True)
    holdout_help = (f"test split: a fraction of the groups (default {DEFAULT_HOLDOUT}: every second group in "
                    "SHA-256 order) or comma-separated group names")
    ls = sub.add_parser("list", help="list pairs, groups and splits")
    ls.add_argument("folder")
    ls.add_argument("--holdout", help=holdout_help)
    pr = sub.add_parser("prepare", help="write a data set folder (rainy/, clean/, mask/, manifest.jsonl)")
    pr.add_argument("folder")
    pr.add_argument("--out", required=True, help="data set folder to create")
    pr.add_argument("--holdout", help=holdout_help)
    add_mask_arguments(pr)
    args = ap.parse_args(argv)
    try:
        if args.command == "list":
            pairs = assign_splits(find_pairs(args.folder), args.holdout)
            for p in pairs:
                print(f"{p.split}\t{p.group}\t{p.id}\t{p.rainy.name}\t{p.clean.name}")
            for s in SPLITS:
                sel = select(pairs, s)
                print(f"# {s}: {len(sel)} pairs, groups {', '.join(sorted({p.group for p in sel}))}", file=sys.stderr)
        else:
            records = prepare(args.folder, args.out, args.holdout, mask_params_from_args(args, ap),
                              argv=sys.argv if argv is None else ["python -m raindrop_tools.realpairs", *argv])
            n = {s: sum(r["split"] == s for r in records) for s in SPLITS}
            cov = float(np.mean([r["coverage"] for r in records]))
            print(f"{args.out}: {len(records)} pairs ({n['train']} train, {n['test']} test), "
                  f"mean rough-mask coverage {cov:.3f}")
    except (PairsError, ImageError, ValueError, OSError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
