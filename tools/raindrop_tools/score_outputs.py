"""Scores images that ``raindrop-remove`` (or anything else) wrote against a rendered set.

``evaluate`` runs the Python reference pipeline; this scores what the C++ program itself
produced, so that its own choices (the working scale, tiling) are measured as a user gets them:

    raindrop-remove data/test/rainy out/removed
    python -m raindrop_tools.score_outputs --data data/test --outputs out/removed
    python -m raindrop_tools.score_outputs --data data/real-pairs --outputs out/rp --split test

For every ``rainy/<name>`` of the set with a ``<name>`` in ``--outputs``: PSNR/SSIM (Y, the pinned
protocol of ``metrics``) of the rainy input and of the output against ``clean/<name>``. Prints
one line (means over the images, and the gain) and, with ``--json``, writes every image's scores.

With ``--masks DIR`` (the masks ``raindrop-remove --mask-dir DIR`` wrote, ``<stem>.png``) it also
says where the error that is left lies, against the set's own masks (``mask/<name>``, or
``--true-masks``; for real pairs the rough masks of ``realpairs``): the output's squared Y error
summed over all images and split by true x detected mask (drops found, drops missed, false
detections, the rest), the share of the input's error removed inside found drops, and the
masks' pixel recall and precision. It tells a detector's misses from a reconstruction's.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from . import metrics
from .data import DatasetError, read_manifest
from .imageio import ImageError, read_mask, read_rgb_strict
from .report_file import report_path_problem, write_report


def split_names(data: Path, split: str) -> set[str]:
    """The rainy file names of the samples whose manifest ``split`` is ``split`` (the data set's
    manifest, read as training reads it)."""
    try:
        return {s.rainy.name for s in read_manifest(data, [split])}
    except DatasetError as e:
        raise SystemExit(f"score_outputs: --split: {e}") from None


REGIONS = ("found", "missed", "false", "rest")  # true & detected, true only, detected only, neither


class MaskSplit:
    """Where the squared Y error (8-bit, ``metrics.luma``) of the input and of the output lies,
    summed over images, by true mask x detected mask (any non-zero pixel is in a mask); with the
    masks' pooled pixel recall and precision."""

    def __init__(self):
        self.sums = {f"{w}_{r}": 0.0 for w in ("input", "output") for r in REGIONS}
        self.count = {r: 0 for r in REGIONS}

    def add(self, name: str, rainy: np.ndarray, output: np.ndarray, clean: np.ndarray,
            true: np.ndarray, det: np.ndarray) -> None:
        y = metrics.luma(clean).astype(np.float64)
        if true.shape != y.shape or det.shape != y.shape:
            raise ValueError(f"{name}: a mask's size differs from the image's {y.shape[::-1]}")
        err = {"input": (metrics.luma(rainy) - y) ** 2, "output": (metrics.luma(output) - y) ** 2}
        for r, where in zip(REGIONS, (true & det, true & ~det, ~true & det, ~true & ~det)):
            self.count[r] += int(where.sum())
            for w in err:
                self.sums[f"{w}_{r}"] += float(err[w][where].sum())

    def summary(self) -> dict:
        sums, count = self.sums, self.count
        out_total = sum(sums[f"output_{r}"] for r in REGIONS)
        found_in = sums["input_found"]
        return {
            "recall": count["found"] / max(count["found"] + count["missed"], 1),
            "precision": count["found"] / max(count["found"] + count["false"], 1),
            "output_error_share": {r: sums[f"output_{r}"] / out_total if out_total > 0 else 0.0 for r in REGIONS},
            "found_error_removed": 1.0 - sums["output_found"] / found_in if found_in > 0 else 0.0,
            "squared_error_sums": dict(sums),
            "pixels": dict(count),
        }


def score(data: Path, outputs: Path, split: str | None = None, masks: Path | None = None,
          true_masks: Path | None = None) -> dict:
    """The scores; with `masks` (the detected masks, ``<stem>.png``) also ``mask_split``, the
    error left split by the true masks (`true_masks`, default the set's ``mask/``) x those."""
    rainy_dir, clean_dir = data / "rainy", data / "clean"
    if not rainy_dir.is_dir() or not clean_dir.is_dir():
        raise SystemExit(f"score_outputs: {data} has no rainy/ and clean/ folders")
    wanted = split_names(data, split) if split else None
    names = sorted(p.name for p in rainy_dir.iterdir()
                   if (outputs / p.name).is_file() and (wanted is None or p.name in wanted))
    if not names:
        raise SystemExit(f"score_outputs: no image of {rainy_dir} has an output in {outputs}")
    split_by_mask = MaskSplit() if masks else None
    rows = []
    for n in names:
        clean = read_rgb_strict(clean_dir / n)
        rainy, output = read_rgb_strict(rainy_dir / n), read_rgb_strict(outputs / n)
        before = metrics.image_metrics(rainy, clean)
        after = metrics.image_metrics(output, clean)
        rows.append({"name": n, "input_psnr_y": before["psnr_y"], "output_psnr_y": after["psnr_y"],
                     "input_ssim_y": before["ssim_y"], "output_ssim_y": after["ssim_y"]})
        if split_by_mask:
            split_by_mask.add(n, rainy, output, clean, read_mask((true_masks or data / "mask") / n) > 0,
                              read_mask(masks / (Path(n).stem + ".png")) > 0)
    mean = {k: float(np.mean([r[k] for r in rows])) for k in rows[0] if k != "name"}
    mean["gain_psnr_y"] = mean["output_psnr_y"] - mean["input_psnr_y"]
    mean["gain_ssim_y"] = mean["output_ssim_y"] - mean["input_ssim_y"]
    r = {"images": len(rows), "mean": mean, "per_image": rows}
    if split_by_mask:
        r["mask_split"] = split_by_mask.summary()
    return r


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", required=True, type=Path, help="rendered set with rainy/ and clean/")
    ap.add_argument("--outputs", required=True, type=Path, help="folder of outputs named as rainy/")
    ap.add_argument("--split", help="only the samples with this manifest split (e.g. test for the real pairs "
                    "that `realpairs prepare` wrote)")
    ap.add_argument("--label", default="", help="text that starts the printed line")
    ap.add_argument("--json", type=Path, help="also write every image's scores here")
    ap.add_argument("--masks", type=Path, help="the detected masks (raindrop-remove --mask-dir): also split the "
                    "error that is left by true x detected mask")
    ap.add_argument("--true-masks", type=Path, help="the true (or rough) masks, named as rainy/ (default: the "
                    "set's mask/)")
    a = ap.parse_args(argv)
    if a.json and (problem := report_path_problem(a.json)):
        print(f"score_outputs: error: {problem}", file=sys.stderr)
        return 2
    try:
        r = score(a.data, a.outputs, a.split, a.masks, a.true_masks)
    except (ImageError, ValueError, OSError) as e:  # a damaged output, one of another size, an unreadable file
        print(f"score_outputs: error: {e}", file=sys.stderr)
        return 2
    m = r["mean"]
    print(f"{a.label or a.outputs}: {r['images']} images, PSNR-Y {m['input_psnr_y']:.2f} -> {m['output_psnr_y']:.2f} dB "
          f"(gain {m['gain_psnr_y']:+.2f}), SSIM-Y {m['input_ssim_y']:.4f} -> {m['output_ssim_y']:.4f}")
    if a.masks:
        ms = r["mask_split"]
        sh = ms["output_error_share"]
        print(f"{a.label or a.outputs}: masks recall {ms['recall']:.3f}, precision {ms['precision']:.3f}; the output's "
              f"squared error: {sh['found']:.0%} in drops found ({ms['found_error_removed']:.0%} of their input's "
              f"removed), {sh['missed']:.0%} in drops missed, {sh['false']:.0%} in false detections, "
              f"{sh['rest']:.0%} elsewhere")
    if a.json:
        try:
            write_report(a.json, r)
        except OSError as e:
            print(f"score_outputs: error: --json {a.json}: {e.strerror}", file=sys.stderr)
            return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
