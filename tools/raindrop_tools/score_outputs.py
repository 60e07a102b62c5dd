"""Scores images that ``raindrop-remove`` (or anything else) wrote against a rendered set.

``evaluate`` runs the Python reference pipeline; this scores what the C++ program itself
produced, so that its own choices (the working scale, tiling) are measured as a user gets them:

    raindrop-remove data/test/rainy out/removed
    python -m raindrop_tools.score_outputs --data data/test --outputs out/removed
    python -m raindrop_tools.score_outputs --data data/real-pairs --outputs out/rp --split test

For every ``rainy/<name>`` of the set with a ``<name>`` in ``--outputs``: PSNR/SSIM (Y, the pinned
protocol of ``metrics``) of the rainy input and of the output against ``clean/<name>``. Prints
one line (means over the images, and the gain) and, with ``--json``, writes every image's scores.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from . import metrics
from .data import DatasetError, read_manifest
from .imageio import ImageError, read_rgb_strict


def split_names(data: Path, split: str) -> set[str]:
    """The rainy file names of the samples whose manifest ``split`` is ``split`` (the data set's
    manifest, read as training reads it)."""
    try:
        return {s.rainy.name for s in read_manifest(data, [split])}
    except DatasetError as e:
        raise SystemExit(f"score_outputs: --split: {e}") from None


def score(data: Path, outputs: Path, split: str | None = None) -> dict:
    rainy_dir, clean_dir = data / "rainy", data / "clean"
    if not rainy_dir.is_dir() or not clean_dir.is_dir():
        raise SystemExit(f"score_outputs: {data} has no rainy/ and clean/ folders")
    wanted = split_names(data, split) if split else None
    names = sorted(p.name for p in rainy_dir.iterdir()
                   if (outputs / p.name).is_file() and (wanted is None or p.name in wanted))
    if not names:
        raise SystemExit(f"score_outputs: no image of {rainy_dir} has an output in {outputs}")
    rows = []
    for n in names:
        clean = read_rgb_strict(clean_dir / n)
        before = metrics.image_metrics(read_rgb_strict(rainy_dir / n), clean)
        after = metrics.image_metrics(read_rgb_strict(outputs / n), clean)
        rows.append({"name": n, "input_psnr_y": before["psnr_y"], "output_psnr_y": after["psnr_y"],
                     "input_ssim_y": before["ssim_y"], "output_ssim_y": after["ssim_y"]})
    mean = {k: float(np.mean([r[k] for r in rows])) for k in rows[0] if k != "name"}
    mean["gain_psnr_y"] = mean["output_psnr_y"] - mean["input_psnr_y"]
    mean["gain_ssim_y"] = mean["output_ssim_y"] - mean["input_ssim_y"]
    return {"images": len(rows), "mean": mean, "per_image": rows}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", required=True, type=Path, help="rendered set with rainy/ and clean/")
    ap.add_argument("--outputs", required=True, type=Path, help="folder of outputs named as rainy/")
    ap.add_argument("--split", help="only the samples with this manifest split (e.g. test for the real pairs "
                    "that `realpairs prepare` wrote)")
    ap.add_argument("--label", default="", help="text that starts the printed line")
    ap.add_argument("--json", type=Path, help="also write every image's scores here")
    a = ap.parse_args(argv)
    try:
        r = score(a.data, a.outputs, a.split)
    except (ImageError, ValueError, OSError) as e:  # a damaged output, one of another size, an unreadable file
        print(f"score_outputs: error: {e}", file=sys.stderr)
        return 2
    m = r["mean"]
    print(f"{a.label or a.outputs}: {r['images']} images, PSNR-Y {m['input_psnr_y']:.2f} -> {m['output_psnr_y']:.2f} dB "
          f"(gain {m['gain_psnr_y']:+.2f}), SSIM-Y {m['input_ssim_y']:.4f} -> {m['output_ssim_y']:.4f}")
    if a.json:
        try:
            a.json.write_text(json.dumps(r, indent=1))
        except OSError as e:
            print(f"score_outputs: error: --json {a.json}: {e.strerror}", file=sys.stderr)
            return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
