"""How far rendered drops are from real ones (project issue 9, items 1 and 5).

    python -m raindrop_tools.realism [--real-pairs DIR] [--split train|test|all] [--real-photos DIR] \\
        [--rendered DATASET ...] [--limit N] [--crops-per-image 4] [--folds 5] [--seed 0] [--paired] [--json FILE]

(a) **Statistics of drops** from (rainy, clean, mask) triples. Real pairs: the rough masks of
``realpairs.rough_mask`` (its mask options apply). Rendered data sets (CONTRACTS.md section 1):
by default the same rough masks, made from their rainy/clean pairs with the same options
(``--rendered-masks rough``), so that both sides are measured alike; ``--rendered-masks own``
uses the renderer's masks instead, which describe the drops themselves. The two differ most
for semi-transparent thin-lens drops: a rendered mask includes every pixel a drop touches, a
rough mask only those that change by more than the threshold, so inside-drop brightness is
+3 levels with own masks and +20 with rough ones on one set (docs/RESULTS.md 4.2). Per image,
on 8-bit luma Y (``metrics.LUMA_WEIGHTS``, float):

* ``coverage``: fraction of mask pixels;
* drops = 8-connected components of the mask: ``drops`` per image; per drop the equivalent
  diameter ``2 sqrt(area / pi)`` in px and as a fraction of the image width, and the
  eccentricity ``sqrt(1 - l2 / l1)`` of its second central moments (l1 >= l2; 0 = circle,
  -> 1 = elongated; drops under ``MIN_DROP_AREA`` px are counted but get no eccentricity), and
  the solidity, its outline's area over its convex hull's (1 = convex, as a round or oval drop;
  lower = lobed, irregular or merged outlines; only drops of ``MIN_SOLIDITY_AREA`` px or more,
  whose outline is more than a few pixels);
* ``brightness``: median over mask pixels of ``Y(rainy) - Y(clean)`` (levels; > 0 = drops
  brighter than the scene behind them);
* ``sharpness``: mean |Laplacian(Y(rainy))| over the mask's interior (the mask eroded by
  3x3, so that the drop's own outline does not count; the whole mask when nothing is left)
  divided by the same of Y(clean) (3x3 Laplacian; < 1 = drops blurrier than the scene);
* ``edge_width``: at the mask boundary (mask minus its 3x3 erosion), the local contrast of
  Y(rainy) (max - min in a 21x21 window) divided by its Sobel gradient magnitude (/8, i.e.
  levels per px), median over boundary pixels whose contrast exceeds ``EDGE_MIN_CONTRAST``
  levels. A linear ramp of width w gives w, a Gaussian-blurred step about 2.5 sigma; values
  are capped at 21 px by the window;
* ``veil``: std of Y(rainy) outside the mask divided by std of Y(clean) outside the mask (< 1 =
  a low-contrast haze over the whole glass; 1 where rainy == clean outside the mask, as
  CONTRACTS.md section 1 asks of rendered sets). NaN when less than 5% of the image is outside;
* ``highlights``: the fraction of clipped pixels (brightest channel >= ``CLIPPED``) in the rainy
  image divided by that in the clean one (1 = a wet glass keeps the highlights; < 1 = drops
  darken them; > 1 = they bloom). NaN when under ``MIN_CLIPPED`` of the clean image is clipped.
  A drop over a clipped sky or lamp sees light far above full scale, so it stays clipped in a
  real photograph; a render that spreads the stored values instead darkens it.

Per data set: means, medians and quantiles of these (drop sizes and eccentricities pooled
over all drops).

(c) **Realism score** of each rendered set against the real set:

* per statistic, the 1-D Wasserstein distance between the rendered and the real
  distributions (per-image values; pooled per-drop values for diameter fraction and
  eccentricity), divided by the real distribution's standard deviation (``distance``, in
  units of the real spread; 0 = same distribution); ``mean distance`` averages them;
* ``classifier accuracy``: balanced cross-validated accuracy (``folds`` folds, grouped: every
  crop of one real group or one rendered source image is in the same fold) of an
  L2-regularised logistic regression (numpy) on ``crop_features`` of 64x64 crops of the rainy
  images, real against rendered; 0.5 = indistinguishable. The crops are taken at native
  resolution, and scene content (city, camera, time of day) differs between sets too, so the
  classifier also separates scenes: read it as an upper bound of the drop realism gap;
* ``street alone``: the same classifier against the rendered set's *clean* crops at the same
  places (the street without drops), and ``drops' effect``, the rainy accuracy minus that: the
  drops' own share with the scenes held fixed (below 0, the drops bring the renders closer to
  the real rainy images; above 0, they give the renders away).

(d) **Against real photographs without clean images** (``--real-photos DIR``, e.g. windshield
photographs, which the real pairs, all lens covers, do not represent): only the classifier,
real photographs' crops against each rendered set's, the photographs resized to 512 px wide
(the renders' width) first. No mask, so no statistics.

Prints a markdown table of statistics per data set and one of scores; ``--json`` writes it all.
No torch.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from . import realpairs as RP
from .cli_args import at_least
from .data import DatasetError, read_manifest
from .imageio import IMAGE_SUFFIXES, ImageError, read_mask_strict, read_rgb, read_rgb_strict
from .metrics import luma_float
from .report_file import report_path_problem, write_report

MIN_DROP_AREA = 5
MIN_SOLIDITY_AREA = 50
EDGE_WINDOW = 21
EDGE_MIN_CONTRAST = 8.0
MIN_OUTSIDE = 0.05
CROP = 64
CLIPPED = 250
MIN_CLIPPED = 0.01
# per-image statistics and the per-drop ones, in table order
IMAGE_STATS = ("coverage", "drops", "brightness", "sharpness", "edge_width", "veil", "highlights")
DROP_STATS = ("diameter_px", "diameter_frac", "eccentricity", "solidity")
DISTANCE_STATS = ("coverage", "drops", "diameter_frac", "eccentricity", "solidity", "brightness", "sharpness",
                  "edge_width", "veil", "highlights")


def solidity(component: np.ndarray) -> float:
    """Area of a component's outer outline over that of its convex hull (both polygons through
    the boundary pixels' centres, so a filled convex shape gives 1 whatever its size)."""
    contours, _ = cv2.findContours(component, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    outline = max(contours, key=cv2.contourArea)
    hull = cv2.contourArea(cv2.convexHull(outline))
    return float(cv2.contourArea(outline) / hull) if hull > 0 else float("nan")


def drop_components(mask: np.ndarray) -> tuple[list[float], list[float], list[float]]:
    """(areas, eccentricities, solidities) of the 8-connected components of a 0/nonzero mask;
    NaN eccentricity for components under MIN_DROP_AREA px, NaN solidity under
    MIN_SOLIDITY_AREA px."""
    m = (mask > 0).astype(np.uint8)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(m, connectivity=8)
    areas, ecc, sol = [], [], []
    for k in range(1, n):
        area = int(stats[k, cv2.CC_STAT_AREA])
        areas.append(float(area))
        if area < MIN_DROP_AREA:
            ecc.append(float("nan"))
            sol.append(float("nan"))
            continue
        x, y, w, h = (int(v) for v in stats[k, :4])
        component = (labels[y : y + h, x : x + w] == k).astype(np.uint8)
        sol.append(solidity(np.pad(component, 1)) if area >= MIN_SOLIDITY_AREA else float("nan"))
        mo = cv2.moments(component, binaryImage=True)
        a, b, c = mo["mu20"] / mo["m00"], mo["mu02"] / mo["m00"], mo["mu11"] / mo["m00"]
        root = math.sqrt(max(0.0, ((a - b) / 2) ** 2 + c * c))
        l1, l2 = (a + b) / 2 + root, (a + b) / 2 - root
        ecc.append(math.sqrt(max(0.0, 1.0 - l2 / l1)) if l1 > 0 else 0.0)
    return areas, ecc, sol


def image_stats(rainy: np.ndarray, clean: np.ndarray, mask: np.ndarray) -> dict:
    """The statistics of one (rainy, clean, mask) triple (module docstring); per-drop lists
    under ``diameter_px``, ``diameter_frac``, ``eccentricity`` and ``solidity``."""
    if rainy.shape != clean.shape or rainy.shape[:2] != mask.shape:
        raise ValueError(f"sizes differ: rainy {rainy.shape}, clean {clean.shape}, mask {mask.shape}")
    h, w = mask.shape
    m = mask > 0
    yr, yc = luma_float(rainy), luma_float(clean)
    areas, ecc, sol = drop_components(mask)
    diam = [2.0 * math.sqrt(a / math.pi) for a in areas]
    nan = float("nan")
    out = {
        "coverage": float(m.mean()),
        "drops": len(areas),
        "diameter_px": diam,
        "diameter_frac": [d / w for d in diam],
        "eccentricity": [e for e in ecc if not math.isnan(e)],
        "solidity": [v for v in sol if not math.isnan(v)],
        "brightness": float(np.median(yr[m] - yc[m])) if m.any() else nan,
    }
    if m.any():
        interior = cv2.erode(m.astype(np.uint8), np.ones((3, 3), np.uint8), borderType=cv2.BORDER_REPLICATE) > 0
        inner = interior if interior.any() else m
        lap_r = np.abs(cv2.Laplacian(yr, cv2.CV_32F, ksize=1))[inner].mean()
        lap_c = np.abs(cv2.Laplacian(yc, cv2.CV_32F, ksize=1))[inner].mean()
        out["sharpness"] = float(lap_r / lap_c) if lap_c > 0 else nan
        boundary = m & ~interior
        k = np.ones((EDGE_WINDOW, EDGE_WINDOW), np.uint8)
        contrast = cv2.dilate(yr, k) - cv2.erode(yr, k)
        gx = cv2.Sobel(yr, cv2.CV_32F, 1, 0, ksize=3) / 8.0
        gy = cv2.Sobel(yr, cv2.CV_32F, 0, 1, ksize=3) / 8.0
        grad = np.sqrt(gx * gx + gy * gy)
        sel = boundary & (contrast > EDGE_MIN_CONTRAST) & (grad > 0)
        out["edge_width"] = float(np.median(np.minimum(contrast[sel] / grad[sel], EDGE_WINDOW))) if sel.any() else nan
    else:
        out["sharpness"] = out["edge_width"] = nan
    outside = ~m
    if outside.mean() >= MIN_OUTSIDE and yc[outside].std() > 0:
        out["veil"] = float(yr[outside].std() / yc[outside].std())
    else:
        out["veil"] = nan
    clipped_clean = float((clean.max(axis=2) >= CLIPPED).mean())
    out["highlights"] = (float((rainy.max(axis=2) >= CLIPPED).mean()) / clipped_clean
                         if clipped_clean >= MIN_CLIPPED else nan)
    return out


@dataclass
class SetStats:
    """Statistics of one data set: per-image values, pooled per-drop values, crops."""

    name: str
    kind: str  # "real" or "rendered"
    width: list[int] = field(default_factory=list)
    per_image: dict[str, list[float]] = field(default_factory=lambda: {k: [] for k in IMAGE_STATS})
    per_drop: dict[str, list[float]] = field(default_factory=lambda: {k: [] for k in DROP_STATS})
    crops: list[np.ndarray] = field(default_factory=list)
    crop_groups: list[str] = field(default_factory=list)
    # The clean image's crops at the same places: the street alone, the classifier's control.
    clean_crops: list[np.ndarray] = field(default_factory=list)

    def add(self, rainy, clean, mask, group: str, rng: np.random.Generator, crops_per_image: int) -> None:
        st = image_stats(rainy, clean, mask)
        self.width.append(rainy.shape[1])
        for k in IMAGE_STATS:
            self.per_image[k].append(st[k])
        for k in DROP_STATS:
            self.per_drop[k].extend(st[k])
        for y, x in crop_places(rainy, crops_per_image, rng):
            self.crops.append(rainy[y : y + CROP, x : x + CROP])
            self.clean_crops.append(clean[y : y + CROP, x : x + CROP])
            self.crop_groups.append(f"{self.kind}:{group}")

    def values(self, stat: str) -> np.ndarray:
        v = np.asarray(self.per_drop[stat] if stat in DROP_STATS else self.per_image[stat], dtype=np.float64)
        return v[np.isfinite(v)]

    def summary(self) -> dict:
        def q(stat, p):
            v = self.values(stat)
            return float(np.percentile(v, p)) if v.size else float("nan")

        out = {"images": len(self.width), "drops_total": len(self.per_drop["diameter_px"])}
        for stat in IMAGE_STATS + DROP_STATS:
            v = self.values(stat)
            out[stat] = {
                "mean": float(v.mean()) if v.size else float("nan"),
                "p10": q(stat, 10),
                "median": q(stat, 50),
                "p90": q(stat, 90),
                "n": int(v.size),
            }
        return out


def crop_places(rgb: np.ndarray, n: int, rng: np.random.Generator, size: int = CROP) -> list[tuple[int, int]]:
    """Top-left corners (y, x) of n random size x size crops of rgb."""
    h, w = rgb.shape[:2]
    if h < size or w < size or n <= 0:
        return []
    return list(zip(rng.integers(0, h - size + 1, n), rng.integers(0, w - size + 1, n)))


def random_crops(rgb: np.ndarray, n: int, rng: np.random.Generator, size: int = CROP) -> list[np.ndarray]:
    return [rgb[y : y + size, x : x + size] for y, x in crop_places(rgb, n, rng, size)]


def crop_features(rgb: np.ndarray) -> np.ndarray:
    """Simple features of an RGB uint8 crop: luma quantiles and contrast, chromaticity and
    saturation, log mean |Laplacian| and gradient-magnitude histogram (edge sharpness), and
    log energy in 4 radial frequency bands (blur, haze)."""
    x = rgb.astype(np.float32)
    y = luma_float(x)
    f = list(np.percentile(y, [5, 25, 50, 75, 95]) / 255.0)
    f.append(y.std() / 255.0)
    s = x.sum(axis=2) + 1.0
    f += [float((x[..., 0] / s).mean()), float((x[..., 2] / s).mean())]
    mx, mn = x.max(axis=2), x.min(axis=2)
    f.append(float(((mx - mn) / (mx + 1.0)).mean()))
    f.append(float((mx >= 250).mean()))
    f.append(math.log1p(float(np.abs(cv2.Laplacian(y, cv2.CV_32F, ksize=1)).mean())))
    gx, gy = cv2.Sobel(y, cv2.CV_32F, 1, 0, ksize=3) / 8.0, cv2.Sobel(y, cv2.CV_32F, 0, 1, ksize=3) / 8.0
    g = np.sqrt(gx * gx + gy * gy)
    hist, _ = np.histogram(np.log1p(g), bins=6, range=(0.0, 5.0))
    f += list(hist / g.size)
    spec = np.abs(np.fft.fftshift(np.fft.fft2(y - y.mean()))) ** 2
    hh, ww = y.shape
    yy, xx = np.mgrid[0:hh, 0:ww]
    r = np.hypot((yy - hh // 2) / hh, (xx - ww // 2) / ww)
    for lo, hi in ((0.0, 0.0625), (0.0625, 0.125), (0.125, 0.25), (0.25, 0.75)):
        f.append(math.log1p(float(spec[(r >= lo) & (r < hi)].mean())))
    return np.asarray(f, dtype=np.float64)


def logistic_fit(x: np.ndarray, y: np.ndarray, l2: float = 1e-2, steps: int = 500) -> np.ndarray:
    """L2-regularised logistic regression by Newton's method (weights incl. bias last). Classes
    are weighted to balance them."""
    xb = np.hstack([x, np.ones((len(x), 1))])
    wcls = np.where(y == 1, 0.5 / max(1, (y == 1).sum()), 0.5 / max(1, (y == 0).sum()))
    w = np.zeros(xb.shape[1])
    reg = l2 * np.eye(xb.shape[1])
    reg[-1, -1] = 0.0
    for _ in range(steps):
        p = 1.0 / (1.0 + np.exp(-np.clip(xb @ w, -30, 30)))
        grad = xb.T @ (wcls * (p - y)) + reg @ w
        hess = (xb * (wcls * p * (1 - p))[:, None]).T @ xb + reg
        step = np.linalg.solve(hess + 1e-9 * np.eye(len(w)), grad)
        w -= step
        if np.abs(step).max() < 1e-8:
            break
    return w


def classifier_accuracy(
    real: list[np.ndarray], rendered: list[np.ndarray], real_groups: list[str], rendered_groups: list[str],
    folds: int = 5, seed: int = 0,
) -> dict:
    """Balanced accuracy (mean of the two classes' recalls) of ``logistic_fit`` on
    ``crop_features``, cross-validated over ``folds`` folds of groups (a group's crops stay in
    one fold). NaN when a class has fewer than ``folds`` groups."""
    x = np.array([crop_features(c) for c in real + rendered])
    y = np.array([1] * len(real) + [0] * len(rendered))
    groups = np.array(list(real_groups) + list(rendered_groups))
    rng = np.random.default_rng(seed)
    fold = np.zeros(len(y), dtype=np.int64)
    for cls in (0, 1):
        names = np.unique(groups[y == cls])
        if len(names) < folds:
            return {"accuracy": float("nan"), "folds": folds, "crops": [len(real), len(rendered)],
                    "note": f"fewer than {folds} groups in a class"}
        rng.shuffle(names)
        of = {g: i % folds for i, g in enumerate(names)}
        for i in np.flatnonzero(y == cls):
            fold[i] = of[groups[i]]
    correct = {0: 0, 1: 0}
    for k in range(folds):
        tr, te = fold != k, fold == k
        mu, sd = x[tr].mean(axis=0), x[tr].std(axis=0) + 1e-9
        w = logistic_fit((x[tr] - mu) / sd, y[tr])
        pred = (np.hstack([(x[te] - mu) / sd, np.ones((te.sum(), 1))]) @ w > 0).astype(int)
        for cls in (0, 1):
            correct[cls] += int(((pred == cls) & (y[te] == cls)).sum())
    acc = 0.5 * (correct[1] / max(1, (y == 1).sum()) + correct[0] / max(1, (y == 0).sum()))
    return {"accuracy": float(acc), "folds": folds, "crops": [len(real), len(rendered)]}


def wasserstein1(a: np.ndarray, b: np.ndarray, grid: int = 1000) -> float:
    """W1 between two empirical 1-D distributions (mean |quantile difference|)."""
    if a.size == 0 or b.size == 0:
        return float("nan")
    u = (np.arange(grid) + 0.5) / grid
    return float(np.abs(np.quantile(a, u) - np.quantile(b, u)).mean())


def distances(real: SetStats, other: SetStats) -> dict:
    """Per statistic W1(other, real) / std(real); ``mean`` averages the finite ones."""
    out = {}
    for stat in DISTANCE_STATS:
        a, b = real.values(stat), other.values(stat)
        spread = a.std() if a.size > 1 else float("nan")
        out[stat] = wasserstein1(b, a) / spread if spread and spread > 0 else float("nan")
    finite = [v for v in out.values() if np.isfinite(v)]
    out["mean"] = float(np.mean(finite)) if finite else float("nan")
    return out


def collect_real(folder, split, params: RP.MaskParams, rng, crops_per_image, holdout=None, limit=None) -> SetStats:
    pairs = RP.select(RP.assign_splits(RP.find_pairs(folder), holdout), split)[: limit or None]
    st = SetStats(f"real ({Path(folder).name}, {split})", "real")
    for p in pairs:
        rainy, clean, mask = RP.pair_mask(p, params)
        st.add(rainy, clean, mask, p.group, rng, crops_per_image)
    return st


def collect_rendered(root, rng, crops_per_image, limit=None, splits=None,
                     rough: RP.MaskParams | None = None) -> SetStats:
    """Statistics of a rendered set: with its own masks, or with ``rough`` the rough masks of
    its rainy/clean pairs (as real pairs are measured)."""
    samples = read_manifest(root, splits)
    if limit and len(samples) > limit:  # spread over the set, not its first ids
        samples = [samples[i] for i in np.linspace(0, len(samples) - 1, limit).round().astype(int)]
    st = SetStats(f"rendered ({Path(root).name}, {'rough' if rough else 'own'} masks)", "rendered")
    for s in samples:
        rainy, clean = read_rgb_strict(s.rainy), read_rgb_strict(s.clean)
        if rough is not None:
            mask = rough.mask(rainy, clean)
        else:
            mask = read_mask_strict(s.mask)
        group = s.id.rsplit("_v", 1)[0]  # variants of one source image stay in one fold
        st.add(rainy, clean, mask, group, rng, crops_per_image)
    return st


PHOTO_WIDTH = 512


def collect_photos(folder, rng, crops_per_image, width=PHOTO_WIDTH) -> tuple[list[np.ndarray], list[str], int]:
    """Crops of real rainy photographs without clean images (for the classifier alone: no
    mask, so no drop statistics). Each photograph is first resized to ``width`` px wide, the
    width of the rendered sets (512x256 renders) and the scale the networks work at, so that
    a 64x64 crop covers about as much of a scene on both sides. -> (crops, groups, photos)."""
    files = sorted(p for p in Path(folder).iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES)
    if not files:
        raise ValueError(f"{folder}: no images ({', '.join(sorted(IMAGE_SUFFIXES))})")
    crops, groups = [], []
    for f in files:
        rgb = read_rgb(f)
        if rgb.shape[1] != width:
            h = max(1, round(rgb.shape[0] * width / rgb.shape[1]))
            rgb = cv2.resize(rgb, (width, h), interpolation=cv2.INTER_AREA if rgb.shape[1] > width else cv2.INTER_LINEAR)
        for c in random_crops(rgb, crops_per_image, rng):
            crops.append(c)
            groups.append(f"photo:{f.name}")
    return crops, groups, len(files)


def _f(v, digits=3) -> str:
    return "-" if v is None or not np.isfinite(v) else f"{v:.{digits}f}"


LABELS = {
    "coverage": "coverage (fraction of pixels)",
    "drops": "drops per image",
    "diameter_px": "drop diameter (px)",
    "diameter_frac": "drop diameter / image width",
    "eccentricity": "eccentricity",
    "solidity": "solidity (area / convex hull, per drop)",
    "brightness": "inside-drop brightness vs clean (levels)",
    "sharpness": "sharpness (|Laplacian| rainy / clean, in mask)",
    "edge_width": "edge width (px)",
    "veil": "veil (std rainy / clean outside mask)",
    "highlights": "highlights (clipped pixels rainy / clean)",
}


def stats_table(st: SetStats) -> str:
    s = st.summary()
    lines = [f"### {st.name}: {s['images']} images, {s['drops_total']} drops", "",
             "| statistic | mean | p10 | median | p90 |", "| --- | ---: | ---: | ---: | ---: |"]
    for stat in ("coverage", "drops", "diameter_px", "diameter_frac", "eccentricity", "solidity", "brightness",
                 "sharpness", "edge_width", "veil", "highlights"):
        v = s[stat]
        d = 4 if stat == "diameter_frac" else (1 if stat in ("diameter_px", "brightness", "drops") else 3)
        lines.append(f"| {LABELS[stat]} | {_f(v['mean'], d)} | {_f(v['p10'], d)} | {_f(v['median'], d)} | "
                     f"{_f(v['p90'], d)} |")
    return "\n".join(lines) + "\n"


def drops_effect(classifier: dict, street: dict) -> float:
    """What the drops add to the classifier's accuracy: rainy crops' minus the same places' clean
    crops' (the street alone). The sets' streets differ from the real photographs' (other cities,
    cameras, hours) and the classifier uses that too; the difference leaves the drops' share. Below
    0: the drops bring the renders closer to the real rainy images; above 0: further away."""
    return classifier["accuracy"] - street["accuracy"]


def score_table(scores: list[dict]) -> str:
    head = ["set", *DISTANCE_STATS, "mean distance", "classifier accuracy", "street alone", "drops' effect"]
    lines = ["| " + " | ".join(head) + " |", "| --- |" + " ---: |" * (len(head) - 1)]
    for sc in scores:
        d = sc["distance"]
        lines.append("| " + " | ".join([sc["name"], *(_f(d[k], 2) for k in DISTANCE_STATS), _f(d["mean"], 2),
                                        _f(sc["classifier"]["accuracy"], 3), _f(sc["street"]["accuracy"], 3),
                                        _f(sc["drops_effect"], 3)]) + " |")
    return "\n".join(lines) + "\n"


def classifier_scores(real_crops, real_groups, st: SetStats, folds: int, seed: int) -> dict:
    """The classifier against a rendered set's rainy crops, against its clean crops at the same
    places (the street alone, the control), and the difference (drops_effect)."""
    rainy = classifier_accuracy(real_crops, st.crops, real_groups, st.crop_groups, folds, seed)
    street = classifier_accuracy(real_crops, st.clean_crops, real_groups, st.crop_groups, folds, seed)
    return {"classifier": rainy, "street": street, "drops_effect": drops_effect(rainy, street)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m raindrop_tools.realism",
                                 description="Statistics of real and rendered drops, and a realism score.")
    ap.add_argument("--real-pairs", metavar="DIR", help="folder of X_rain.* / X_clean.* pairs")
    ap.add_argument("--real-photos", metavar="DIR",
                    help="folder of real rainy photographs without clean images (e.g. windshield photographs): each "
                    "rendered set also gets the classifier's accuracy against their crops (no masks, so no drop "
                    f"statistics), the photographs resized to {PHOTO_WIDTH} px wide first")
    ap.add_argument("--photo-crops", type=at_least(1), default=16, help="crops per real photograph (default 16)")
    ap.add_argument("--split", default="train", choices=["all", "train", "test"],
                    help="real pairs to use (realpairs group split; default train: the test split is kept for "
                    "evaluating removal, so presets are not tuned on it)")
    ap.add_argument("--holdout", help="realpairs --holdout for --split")
    ap.add_argument("--rendered", action="append", default=[], metavar="DATASET",
                    help="rendered data set folder (repeatable)")
    ap.add_argument("--rendered-split", action="append", help="only samples of this manifest split (repeatable)")
    ap.add_argument("--rendered-masks", choices=["rough", "own"], default="rough",
                    help="masks of the rendered sets: rough (default: derived from each rainy/clean pair like the "
                    "real pairs' masks, so both are measured alike) or own (the renderer's masks)")
    ap.add_argument("--limit", type=at_least(1), help="at most N images per set (rendered: spread over the set)")
    ap.add_argument("--crops-per-image", type=at_least(0), default=4, help=f"{CROP}x{CROP} crops per image for the classifier")
    ap.add_argument("--folds", type=at_least(2), default=5)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--paired", action="store_true",
                    help="crop every rendered set at the same places (one random stream for all, whatever their "
                    "order): renders of the same frames are then compared crop for crop, and a set scores the same "
                    "in any call. Without it each set draws its own places by its position in the call")
    ap.add_argument("--json", help="write everything to this JSON file")
    RP.add_mask_arguments(ap)
    args = ap.parse_args(argv)
    if not args.real_pairs and not args.real_photos:
        ap.error("give --real-pairs, --real-photos or both")
    if args.real_photos and not args.rendered:
        ap.error("--real-photos scores rendered sets: give at least one --rendered")
    if args.json and (problem := report_path_problem(Path(args.json))):
        print(f"realism: error: {problem}", file=sys.stderr)
        return 2
    if args.real_photos and not Path(args.real_photos).is_dir():
        print(f"realism: error: --real-photos {args.real_photos}: not a folder", file=sys.stderr)
        return 2
    try:
        params = RP.mask_params_from_args(args, ap)
        real = None
        if args.real_pairs:
            real = collect_real(args.real_pairs, args.split, params,
                                np.random.default_rng([args.seed, 0]), args.crops_per_image,
                                RP.parse_holdout(args.holdout) if args.holdout else None, args.limit)
        photos = None
        if args.real_photos:
            photos = collect_photos(args.real_photos, np.random.default_rng([args.seed, 1000]), args.photo_crops)
        sets = [real] if real else []
        for i, root in enumerate(args.rendered):
            stream = [args.seed, 1] if args.paired else [args.seed, i + 1]
            sets.append(collect_rendered(root, np.random.default_rng(stream), args.crops_per_image,
                                         args.limit, args.rendered_split,
                                         params if args.rendered_masks == "rough" else None))
    except (RP.PairsError, DatasetError, ImageError, ValueError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    rendered_sets = sets[1:] if real else sets
    scores = [{
        "name": st.name,
        "distance": distances(real, st),
        **classifier_scores(real.crops, real.crop_groups, st, args.folds, args.seed),
    } for st in rendered_sets] if real else []
    photo_scores = [{
        "name": st.name,
        **classifier_scores(photos[0], photos[1], st, args.folds, args.seed),
    } for st in rendered_sets] if photos else []
    text = "\n".join(stats_table(st) for st in sets)
    if photo_scores:
        text += (f"\n### Classifier against real photographs ({Path(args.real_photos).name}: {photos[2]} photographs, "
                 f"{len(photos[0])} crops)\n\nBalanced {args.folds}-fold grouped cross-validated accuracy telling "
                 f"real from rendered rainy {CROP}x{CROP} crops, the photographs at {PHOTO_WIDTH} px wide "
                 "(0.5 = indistinguishable); *street alone*: the same against the rendered clean images' crops "
                 "at the same places; *drops' effect*: the first minus the second (below 0: the drops bring the "
                 "renders closer to the photographs).\n\n"
                 "| set | classifier accuracy | street alone | drops' effect |\n| --- | ---: | ---: | ---: |\n" +
                 "".join(f"| {sc['name']} | {_f(sc['classifier']['accuracy'], 3)} | "
                         f"{_f(sc['street']['accuracy'], 3)} | {_f(sc['drops_effect'], 3)} |\n"
                         for sc in photo_scores))
    if scores:
        text += ("\n### Realism score against the real set\n\nDistances: 1-D Wasserstein distance to the real "
                 "distribution in units of its standard deviation (0 = same); classifier: balanced "
                 f"{args.folds}-fold grouped cross-validated accuracy telling real from rendered rainy "
                 f"{CROP}x{CROP} crops (0.5 = indistinguishable); street alone and drops' effect: as above, "
                 "against the rendered clean images' crops at the same places.\n\n" + score_table(scores))
    print(text)
    if args.json:
        write_report(Path(args.json), {
            "argv": sys.argv if argv is None else ["python -m raindrop_tools.realism", *argv],
            "sets": [{"name": st.name, "kind": st.kind, **st.summary()} for st in sets],
            "scores": scores,
            "photo_scores": photo_scores,
        })
    return 0


if __name__ == "__main__":
    sys.exit(main())
