"""The evaluation protocol (docs/DESIGN.md section 6), pinned in one place. No torch.

Image quality, on 8-bit images (``pred`` against the clean ground truth):

* (a) the raindrop literature's convention (Qian et al.'s evaluation code): both images
  cropped to multiples of 4 in height and width (top-left kept), converted to 8-bit luma
  Y = round(0.299 R + 0.587 G + 0.114 B) of the 8-bit values (see ``luma``), then PSNR and
  SSIM on Y.
* (b) on RGB, full image: PSNR over all three channels; SSIM per channel, averaged.
* SSIM everywhere: scikit-image ``structural_similarity`` with a 7x7 uniform window
  (``gaussian_weights=False, win_size=7``), ``data_range=255``, sample covariance (its
  defaults otherwise). PSNR: ``10 log10(255^2 / MSE)`` in float64, capped at
  ``PSNR_CAP_DB`` (identical images would give infinity; the cap keeps means finite).
  Data-set figures are means over images of the per-image values.

Detection (RDN probability against the ground-truth mask), pixel level over a whole test
set: the probabilities are histogrammed into ``AP_BINS`` = 10000 equal bins on [0, 1]
(bin ``min(floor(p * 10000), 9999)``), which needs O(bins) memory whatever the pixel count.
A pixel is predicted positive at threshold ``t_j = j / 10000`` when its bin is >= j.
``AP = sum_j (R_j - R_{j+1}) P_j`` over the thresholds from high to low (R = recall,
P = precision), i.e. scikit-learn's average_precision_score on probabilities quantised to
1e-4.
"""

from __future__ import annotations

import math

import numpy as np
from skimage.metrics import structural_similarity

PSNR_CAP_DB = 100.0
SSIM_WINDOW = 7
CROP_MULTIPLE = 4
AP_BINS = 10000


def _check_pair(a: np.ndarray, b: np.ndarray) -> None:
    if a.shape != b.shape:
        raise ValueError(f"image sizes differ: {a.shape} vs {b.shape}")
    if a.dtype != np.uint8 or b.dtype != np.uint8:
        raise TypeError(f"expected uint8 images, got {a.dtype} and {b.dtype}")


def crop_to_multiple(img: np.ndarray, m: int = CROP_MULTIPLE) -> np.ndarray:
    h, w = img.shape[:2]
    return img[: h - h % m, : w - w % m]


LUMA_WEIGHTS = np.array([0.299, 0.587, 0.114], dtype=np.float64)


def luma_float(rgb: np.ndarray) -> np.ndarray:
    """Unrounded Y of an HxWx3 RGB image in its own scale, float32 (for masks and statistics,
    where the pinned 8-bit rounding of ``luma`` would only add quantisation)."""
    return rgb.astype(np.float32) @ LUMA_WEIGHTS.astype(np.float32)


def luma(rgb_u8: np.ndarray) -> np.ndarray:
    """8-bit Y of an HxWx3 uint8 RGB image: ``floor(0.299 R + 0.587 G + 0.114 B + 0.5)`` in
    float64. OpenCV's ``COLOR_RGB2YCrCb`` (what the literature's code calls) computes the same
    in fixed point and differs by one level on a few pixels that sit at .5; the explicit
    formula is the pinned one."""
    if rgb_u8.dtype != np.uint8 or rgb_u8.ndim != 3 or rgb_u8.shape[2] != 3:
        raise TypeError(f"expected HxWx3 uint8, got {rgb_u8.dtype} {rgb_u8.shape}")
    return np.floor(rgb_u8.astype(np.float64) @ LUMA_WEIGHTS + 0.5).astype(np.uint8)


def psnr_from_mse(mse: float, data_range: float = 255.0) -> float:
    """PSNR of a mean squared error, capped at PSNR_CAP_DB (0 error included)."""
    if mse == 0.0:
        return PSNR_CAP_DB
    return min(PSNR_CAP_DB, 10.0 * math.log10(data_range**2 / mse))


def psnr(a: np.ndarray, b: np.ndarray, data_range: float = 255.0) -> float:
    _check_pair(a, b)
    return psnr_from_mse(float(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2)), data_range)


def ssim(a: np.ndarray, b: np.ndarray) -> float:
    """SSIM of two uint8 images, HxW or HxWxC (channel mean)."""
    _check_pair(a, b)
    if min(a.shape[:2]) < SSIM_WINDOW:
        raise ValueError(f"SSIM needs images of at least {SSIM_WINDOW}x{SSIM_WINDOW}, got {a.shape[:2]}")
    return float(
        structural_similarity(
            a,
            b,
            win_size=SSIM_WINDOW,
            gaussian_weights=False,
            data_range=255,
            channel_axis=2 if a.ndim == 3 else None,
        )
    )


def image_metrics(pred_u8: np.ndarray, gt_u8: np.ndarray) -> dict[str, float]:
    """PSNR and SSIM both ways for one HxWx3 uint8 RGB image against its ground truth."""
    _check_pair(pred_u8, gt_u8)
    py, gy = luma(crop_to_multiple(pred_u8)), luma(crop_to_multiple(gt_u8))
    return {
        "psnr_y": psnr(py, gy),
        "ssim_y": ssim(py, gy),
        "psnr_rgb": psnr(pred_u8, gt_u8),
        "ssim_rgb": ssim(pred_u8, gt_u8),
    }


class PRAccumulator:
    """Pixel-level precision-recall over many images, by histogram."""

    def __init__(self, bins: int = AP_BINS):
        self.bins = int(bins)
        self.pos = np.zeros(self.bins, dtype=np.int64)
        self.neg = np.zeros(self.bins, dtype=np.int64)

    def add(self, prob: np.ndarray, gt: np.ndarray) -> None:
        """``prob``: probabilities in [0, 1]; ``gt``: boolean (or 0/1) mask of the same shape."""
        if prob.shape != gt.shape:
            raise ValueError(f"probability {prob.shape} and mask {gt.shape} sizes differ")
        p = np.asarray(prob, dtype=np.float64).ravel()
        if np.isnan(p).any():
            raise ValueError("probabilities contain NaN")
        idx = np.clip(np.floor(p * self.bins), 0, self.bins - 1).astype(np.int64)
        g = np.asarray(gt).ravel().astype(bool)
        self.pos += np.bincount(idx[g], minlength=self.bins)
        self.neg += np.bincount(idx[~g], minlength=self.bins)

    def curve(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(thresholds, precision, recall), thresholds decreasing from (bins-1)/bins to 0.
        Precision is 1 where nothing is predicted positive (the usual convention)."""
        tp = np.cumsum(self.pos[::-1])
        fp = np.cumsum(self.neg[::-1])
        total = int(self.pos.sum())
        thresholds = np.arange(self.bins - 1, -1, -1) / self.bins
        predicted = tp + fp
        precision = np.where(predicted > 0, tp / np.maximum(predicted, 1), 1.0)
        recall = tp / total if total > 0 else np.full(self.bins, np.nan)
        return thresholds, precision, recall

    def average_precision(self) -> float:
        """NaN when the ground truth has no positive pixel."""
        if self.pos.sum() == 0:
            return float("nan")
        _, precision, recall = self.curve()
        prev = np.concatenate([[0.0], recall[:-1]])
        return float(np.sum((recall - prev) * precision))


class MaskCounts:
    """Pixel counts of a binary mask against the ground truth."""

    def __init__(self):
        self.tp = self.fp = self.fn = self.tn = 0

    def add(self, pred: np.ndarray, gt: np.ndarray) -> None:
        p = np.asarray(pred).astype(bool)
        g = np.asarray(gt).astype(bool)
        if p.shape != g.shape:
            raise ValueError(f"mask sizes differ: {p.shape} vs {g.shape}")
        self.tp += int(np.count_nonzero(p & g))
        self.fp += int(np.count_nonzero(p & ~g))
        self.fn += int(np.count_nonzero(~p & g))
        self.tn += int(np.count_nonzero(~p & ~g))

    def summary(self) -> dict[str, float]:
        def ratio(a: int, b: int) -> float:
            return a / b if b else float("nan")

        return {
            "precision": ratio(self.tp, self.tp + self.fp),
            "recall": ratio(self.tp, self.tp + self.fn),
            "iou": ratio(self.tp, self.tp + self.fp + self.fn),
            "coverage": ratio(self.tp + self.fp, self.tp + self.fp + self.fn + self.tn),
        }
