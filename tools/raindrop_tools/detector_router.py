"""Which of two detectors finds the drops in an image: a small router fitted on validation sets.

    python -m raindrop_tools.detector_router fit --models models/compact-multiscale \\
        --alternative compact-windshield --set DATA MAIN_OUT ALT_OUT [--set ...] --out FILE
    python -m raindrop_tools.detector_router decide --models models/compact-multiscale IMAGE...

No single detector is best everywhere: the default's finds the soft, defocused drops of lens
covers and the drops of its synthetic training mix; compact-windshield's (fine-tuned on sharp
windshield drops, threshold 0.75) finds the small sharp drops that photographs of a wet
windshield are full of, and costs the default about 0.4 dB elsewhere (docs/RESULTS.md 4.33).
Both share the 3RN and RFN. The router looks at what the default detector already computed,
its probability map at the working scale, and says whether the other detector should decide
the mask instead.

Features (``features``), ten numbers from the probability map P (HxW, float32) of the image's
working-scale copy (the long side brought to 512 by area averaging, never enlarged: what
raindrop-remove's networks see by default):

    share of P > 0.3, share of 0.05 < P <= 0.3, mean of P, share of P > 0.02;
    for t in 0.05, 0.15, 0.3, of the 8-connected parts of P > t: the number of at most
    30 pixels per 10^4 pixels of the image, and the median area (0 when there is none);

each as log(1 + 100 f). Comparisons are in float32, as numpy compares a float32 map with a
Python number. The decision is a logistic regression:

    z = bias + sum_i weight_i (f_i - mean_i) / std_i;   z > 0: the alternative detector

fitted (``fit``) on images whose outputs both models made: the label is "the alternative's
output has the higher PSNR-Y", each image weighted by how much it matters (|difference| +
0.05 dB), with an L2 penalty. The file it writes (``write_router``), ROUTER in a model folder,
is read by raindrop-remove (include/raindrop/remove/detector_router.h, docs/CONTRACTS.md):

    # comment lines
    format 1
    alternative compact-windshield        (a sibling model folder: its rdn.onnx and threshold)
    mean   <10 numbers>
    std    <10 numbers>
    weight <10 numbers>
    bias   <number>
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from . import metrics
from .imageio import ImageError, read_rgb, read_rgb_strict
from .key_file import check_format, finite_vector, key_file_path_problem, read_fields, single_name, write_fields
from .read_only import ReadOnlyFileError

FEATURES = 10
WORKING_SIZE = 512
FORMAT = 1
_LEVELS = (np.float32(0.3), np.float32(0.05), np.float32(0.02))
_PART_THRESHOLDS = (np.float32(0.05), np.float32(0.15), np.float32(0.3))
_SMALL_PART = 30  # pixels


class RouterError(ValueError):
    """A router file or request refused, reported on one line."""


def working_copy(rgb: np.ndarray, working_size: int = WORKING_SIZE) -> np.ndarray:
    """The image at raindrop-remove's automatic working scale: the long side brought to
    `working_size` by area averaging, each side rounded half up (src/remove/working_scale.cpp),
    never enlarged."""
    h, w = rgb.shape[:2]
    if max(h, w) <= working_size:
        return rgb
    s = working_size / max(h, w)
    size = (max(1, math.floor(w * s + 0.5)), max(1, math.floor(h * s + 0.5)))
    return cv2.resize(rgb, size, interpolation=cv2.INTER_AREA)


def features(prob: np.ndarray) -> np.ndarray:
    """The ten router features of one probability map (HxW float32, the image's own size)."""
    p = np.asarray(prob, np.float32)
    if p.ndim != 2 or p.size == 0:
        raise RouterError(f"expected an HxW probability map, got shape {p.shape}")
    hi, mid, lo = _LEVELS
    f = [float((p > hi).mean()), float(((p > mid) & (p <= hi)).mean()), float(p.astype(np.float64).mean()),
         float((p > lo).mean())]
    for t in _PART_THRESHOLDS:
        _, _, stats, _ = cv2.connectedComponentsWithStats((p > t).astype(np.uint8), connectivity=8)
        areas = stats[1:, cv2.CC_STAT_AREA]
        f += [float(np.sum(areas <= _SMALL_PART)) / p.size * 1e4, float(np.median(areas)) if len(areas) else 0.0]
    return np.log1p(np.array(f, np.float64) * 100)


def working_size_of(remover) -> int:
    """The models' working size: rdn.onnx's optional ``raindrop.working_size``, else 512, as
    raindrop-remove reads it (include/raindrop/remove/model.h)."""
    return int(remover.metadata.get("rdn", {}).get("raindrop.working_size", WORKING_SIZE))


def image_features(remover, rgb: np.ndarray) -> np.ndarray:
    """The features of an RGB uint8 image, from `remover`'s (reference.RaindropRemover) detector
    on the image's working-scale copy."""
    small = working_copy(rgb, working_size_of(remover))
    h, w = small.shape[:2]
    R, _, _ = remover.prepare(small)
    return features(remover.detect(R)[0, 0][:h, :w])


@dataclass
class Router:
    alternative: str
    mean: np.ndarray
    std: np.ndarray
    weight: np.ndarray
    bias: float

    def score(self, f: np.ndarray) -> np.ndarray:
        """z per row of `f` (N x FEATURES, or one row): above 0, the alternative detector."""
        return (np.atleast_2d(f) - self.mean) / self.std @ self.weight + self.bias

    def prefers_alternative(self, f: np.ndarray) -> np.ndarray:
        return self.score(f) > 0


def fit(X: np.ndarray, y: np.ndarray, w: np.ndarray, alternative: str, l2: float = 1e-2, iters: int = 3000,
        lr: float = 0.5) -> Router:
    """Weighted, L2-penalised logistic regression by gradient descent on standardised features
    (the bias unpenalised). Deterministic: starts from zero."""
    X, y, w = np.asarray(X, np.float64), np.asarray(y, np.float64), np.asarray(w, np.float64)
    mu, sd = X.mean(0), X.std(0) + 1e-9
    Xs = np.hstack([(X - mu) / sd, np.ones((len(X), 1))])
    b = np.zeros(Xs.shape[1])
    w = w / w.mean()
    for _ in range(iters):
        p = 1 / (1 + np.exp(-Xs @ b))
        b -= lr * (Xs.T @ (w * (p - y)) / len(y) + l2 * np.r_[b[:-1], 0])
    return Router(alternative, mu, sd, b[:-1].copy(), float(b[-1]))


def write_router(path: str | os.PathLike, router: Router, comment: str = "") -> None:
    """Writes the ROUTER file (format above) beside itself and renames it over `path`."""
    write_fields(path, [("format", FORMAT), ("alternative", router.alternative), ("mean", router.mean), ("std", router.std),
                        ("weight", router.weight), ("bias", repr(float(router.bias)))], RouterError, comment)


def read_router(path: str | os.PathLike) -> Router:
    """Reads a ROUTER file; RouterError naming the file and what is wrong."""
    path = Path(path)
    fields = read_fields(path, RouterError)
    check_format(fields, FORMAT, path, RouterError)
    alternative = single_name(fields, "alternative", path, RouterError, "one sibling model folder")

    def vector(key: str, n: int, positive: bool = False) -> np.ndarray:
        return finite_vector(fields, key, n, path, RouterError, positive)

    std = vector("std", FEATURES, positive=True)
    return Router(alternative, vector("mean", FEATURES), std, vector("weight", FEATURES), float(vector("bias", 1)[0]))


def _psnr_y(a: np.ndarray, b: np.ndarray) -> float:
    return metrics.psnr(metrics.luma(metrics.crop_to_multiple(a)), metrics.luma(metrics.crop_to_multiple(b)))


def _rainy_files(data: Path) -> dict[str, Path]:
    return {p.stem: p for p in sorted((data / "rainy").iterdir())}


def _fit_command(args) -> int:
    problem = key_file_path_problem(args.out, RouterError, "alternative")  # before the work
    if problem:
        raise RouterError(problem)
    from .reference import RaindropRemover

    remover = RaindropRemover(args.models, threads=args.threads)
    X, D = [], []
    for data, main_out, alt_out in args.set:
        data, main_out, alt_out = Path(data), Path(main_out), Path(alt_out)
        if not (data / "rainy").is_dir() or not (data / "clean").is_dir():
            raise RouterError(f"'{data}': no rainy/ and clean/ folders")
        n = 0
        for stem, rainy_path in _rainy_files(data).items():
            outs = [d / rainy_path.name for d in (main_out, alt_out)]
            if not all(o.is_file() for o in outs):
                continue
            rainy = read_rgb_strict(rainy_path)
            clean = read_rgb_strict(next((data / "clean").glob(stem + ".*")))
            main, alt = (read_rgb_strict(o) for o in outs)
            X.append(image_features(remover, rainy))
            D.append(_psnr_y(alt, clean) - _psnr_y(main, clean))
            n += 1
        if n == 0:
            raise RouterError(f"no image of '{data}/rainy' has an output in both '{main_out}' and '{alt_out}'")
        print(f"{data}: {n} images", file=sys.stderr)
    X, D = np.array(X), np.array(D)
    router = fit(X, (D > 0).astype(float), np.abs(D) + 0.05, args.alternative)
    chosen = router.prefers_alternative(X)
    comment = (f"raindrop detector router: the detector of '{args.alternative}' decides the mask where z > 0.\n"
               f"Fitted by raindrop_tools.detector_router on {len(X)} images of {len(args.set)} sets "
               f"(the alternative better on {np.mean(D > 0):.0%}); on them it picks the alternative for "
               f"{chosen.mean():.0%}, mean gain over the main detector {np.mean(np.where(chosen, D, 0)):+.3f} dB.")
    write_router(args.out, router, comment)
    print(comment.replace("\n", " "))
    return 0


def _decide_command(args) -> int:
    from .reference import RaindropRemover

    router = read_router(Path(args.models) / "ROUTER")
    remover = RaindropRemover(args.models, threads=args.threads)
    for image in args.images:
        z = float(router.score(image_features(remover, read_rgb(image)))[0])
        print(f"{image} {z:+.6f} {router.alternative if z > 0 else 'main'}")
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m raindrop_tools.detector_router", description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="command", required=True)
    f = sub.add_parser("fit", help="fit a router from two models' outputs on sets with clean images")
    f.add_argument("--models", required=True, help="the main model folder (its detector gives the features)")
    f.add_argument("--alternative", required=True, help="the sibling model folder whose detector may take over")
    f.add_argument("--set", nargs=3, action="append", required=True, metavar=("DATA", "MAIN_OUT", "ALT_OUT"),
                   help="a set (rainy/, clean/) and the folders of both models' outputs on it")
    f.add_argument("--out", required=True, help="the ROUTER file to write")
    f.add_argument("--threads", type=int, default=2)
    d = sub.add_parser("decide", help="print each image's router score and the detector it chooses")
    d.add_argument("--models", required=True, help="a model folder with a ROUTER file")
    d.add_argument("images", nargs="+")
    d.add_argument("--threads", type=int, default=2)
    args = ap.parse_args(argv)
    try:
        return _fit_command(args) if args.command == "fit" else _decide_command(args)
    except (RouterError, ImageError, ReadOnlyFileError, OSError) as e:
        print(f"detector_router: {e}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
