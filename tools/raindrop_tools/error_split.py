"""Where the remaining error is: inside the drops or outside them.

    python -m raindrop_tools.error_split --data data/test --models models/compact --every 10

Runs the reference pipeline on a rendered data set and splits the squared error against the
clean image by the rendered (true) mask: PSNR (RGB, 8-bit) inside and outside the mask for the
rainy input, the 3RN reconstruction, the blend and the final output, and the share of the
output's squared error that lies inside the mask. Errors are summed over all pixels of all
images before the PSNR is taken (so large drops weigh more than small ones). No torch needed.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from .data import DatasetError, read_manifest
from .imageio import ImageError, read_mask_strict, read_rgb_strict, to_uint8
from .metrics import psnr_from_mse
from .reference import ModelError, RaindropRemover

STAGES = ("input", "reconstruction", "blend", "output")


class ErrorSplit:
    """Sums of squared 8-bit errors inside and outside a mask, per stage."""

    def __init__(self) -> None:
        self.sq = {s: {"inside": 0.0, "outside": 0.0} for s in STAGES}
        self.n = {"inside": 0, "outside": 0}

    def add(self, mask: np.ndarray, clean: np.ndarray, images: dict[str, np.ndarray]) -> None:
        inside = mask.astype(bool)
        self.n["inside"] += int(inside.sum()) * clean.shape[2]
        self.n["outside"] += int((~inside).sum()) * clean.shape[2]
        ref = clean.astype(np.float64)
        for stage, img in images.items():
            err = ((img.astype(np.float64) - ref) ** 2).sum(axis=2)
            self.sq[stage]["inside"] += float(err[inside].sum())
            self.sq[stage]["outside"] += float(err[~inside].sum())

    @staticmethod
    def _psnr(sq: float, n: int) -> float:
        return psnr_from_mse(sq / n) if n else float("nan")

    def summary(self) -> dict:
        out = {
            s: {where: self._psnr(self.sq[s][where], self.n[where]) for where in ("inside", "outside")}
            for s in STAGES
        }
        total = self.sq["output"]["inside"] + self.sq["output"]["outside"]
        out["output_error_share_inside"] = self.sq["output"]["inside"] / total if total > 0 else float("nan")
        out["mask_fraction"] = self.n["inside"] / max(1, self.n["inside"] + self.n["outside"])
        return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m raindrop_tools.error_split", description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", required=True, help="rendered data set (manifest.jsonl)")
    ap.add_argument("--models", required=True, help="folder with rdn.onnx, rrn.onnx, rfn.onnx")
    ap.add_argument("--every", type=int, default=1, help="use every N-th sample of the manifest")
    ap.add_argument("--threads", type=int, help="ONNX Runtime intra-op threads")
    args = ap.parse_args(argv)
    if args.every < 1:
        ap.error(f"--every must be 1 or more, got {args.every}")
    try:
        samples = read_manifest(args.data)[:: args.every]
        remover = RaindropRemover(Path(args.models), threads=args.threads)
        split = ErrorSplit()
        for s in samples:
            rainy, clean = read_rgb_strict(s.rainy), read_rgb_strict(s.clean)
            mask = read_mask_strict(s.mask)
            if mask.shape != rainy.shape[:2] or clean.shape != rainy.shape:
                raise ImageError(f"{s.mask}: the sample's rainy, clean and mask images differ in size "
                                 f"({rainy.shape[1]}x{rainy.shape[0]}, {clean.shape[1]}x{clean.shape[0]}, "
                                 f"{mask.shape[1]}x{mask.shape[0]})")
            res = remover.remove(rainy, keep_intermediates=True)
            split.add(mask > 127, clean, {
                "input": rainy, "reconstruction": to_uint8(res.reconstruction),
                "blend": to_uint8(res.blend), "output": res.output})
    except (DatasetError, ImageError, ModelError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    result = {"data": args.data, "models": args.models, "images": len(samples), **split.summary()}
    print(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
