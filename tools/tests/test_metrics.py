import math

import cv2
import numpy as np
import pytest
from skimage.metrics import structural_similarity

from helpers import procedural_image
from raindrop_tools import metrics as MT


def test_psnr_identical_images_is_capped():
    a = procedural_image(20, 30, 1)
    assert MT.psnr(a, a) == MT.PSNR_CAP_DB
    m = MT.image_metrics(a, a)
    assert m["psnr_y"] == m["psnr_rgb"] == MT.PSNR_CAP_DB
    assert m["ssim_y"] == pytest.approx(1.0) and m["ssim_rgb"] == pytest.approx(1.0)


def test_psnr_known_values():
    a = np.full((8, 8, 3), 100, np.uint8)
    b = a + np.uint8(1)  # MSE 1 -> 20 log10(255)
    assert MT.psnr(a, b) == pytest.approx(20 * math.log10(255))
    c = a.copy()
    c[0, 0, 0] = 110  # MSE = 100 / 192
    assert MT.psnr(a, c) == pytest.approx(10 * math.log10(255**2 / (100 / 192)))


def test_literature_convention_uses_8bit_luma_and_crops_to_multiples_of_4():
    a = procedural_image(30, 42, 2)
    b = procedural_image(30, 42, 3)
    m = MT.image_metrics(a, b)
    ya, yb = MT.luma(a[:28, :40]), MT.luma(b[:28, :40])
    f = a[:28, :40].astype(np.float64) @ np.array([0.299, 0.587, 0.114])
    assert np.abs(ya.astype(np.float64) - f).max() <= 0.5
    # what the literature's code computes (OpenCV, fixed point): at most one level apart, rarely
    cv = cv2.cvtColor(a[:28, :40], cv2.COLOR_RGB2YCrCb)[:, :, 0].astype(int)
    assert np.abs(cv - ya).max() <= 1 and np.mean(cv != ya) < 0.01
    mse = np.mean((ya.astype(float) - yb.astype(float)) ** 2)
    assert m["psnr_y"] == pytest.approx(10 * math.log10(255**2 / mse))
    assert m["ssim_y"] == pytest.approx(
        structural_similarity(ya, yb, win_size=7, gaussian_weights=False, data_range=255)
    )
    rgb = structural_similarity(a, b, win_size=7, gaussian_weights=False, data_range=255, channel_axis=2)
    assert m["ssim_rgb"] == pytest.approx(rgb)
    # the crop matters: a difference only in the last 2 rows is invisible to (a), not to (b)
    c = a.copy()
    c[28:] = 0
    m2 = MT.image_metrics(c, a)
    assert m2["psnr_y"] == MT.PSNR_CAP_DB and m2["psnr_rgb"] < 40


def test_ssim_rejects_tiny_images_and_mismatched_pairs():
    with pytest.raises(ValueError, match="at least 7x7"):
        MT.ssim(np.zeros((6, 9), np.uint8), np.zeros((6, 9), np.uint8))
    with pytest.raises(ValueError, match="differ"):
        MT.psnr(np.zeros((6, 9), np.uint8), np.zeros((6, 8), np.uint8))


def test_ap_of_a_perfect_detector_is_one():
    rng = np.random.default_rng(0)
    gt = rng.random((200, 300)) > 0.8
    acc = MT.PRAccumulator()
    acc.add(gt.astype(np.float32), gt)
    assert acc.average_precision() == pytest.approx(1.0)
    # ... and of any detector ranking every drop pixel above every background pixel
    acc = MT.PRAccumulator()
    acc.add(np.where(gt, 0.6, 0.4).astype(np.float32), gt)
    assert acc.average_precision() == pytest.approx(1.0)


def test_ap_of_an_uninformative_detector_is_the_prevalence():
    gt = np.zeros((100, 100), bool)
    gt[:, :25] = True
    acc = MT.PRAccumulator()
    acc.add(np.full(gt.shape, 0.5, np.float32), gt)
    assert acc.average_precision() == pytest.approx(0.25)


def _exact_ap(prob, gt):
    """Average precision by sorting (ties share a threshold), for comparison."""
    order = np.argsort(-prob, kind="stable")
    p, g = prob[order], gt[order]
    distinct = np.r_[np.nonzero(np.diff(p))[0], p.size - 1]
    tp = np.cumsum(g)[distinct]
    fp = (distinct + 1) - tp
    precision = tp / (tp + fp)
    recall = tp / g.sum()
    return float(np.sum(np.diff(np.r_[0, recall]) * precision))


def test_ap_matches_the_exact_definition_on_quantised_scores():
    rng = np.random.default_rng(1)
    gt = rng.random(50000) > 0.9
    score = np.clip(gt * 0.3 + rng.normal(0.4, 0.2, gt.size), 0, 1)
    score = (np.floor(score * MT.AP_BINS) + 0.5) / MT.AP_BINS  # bin centres: no quantisation error
    acc = MT.PRAccumulator()
    for part in np.array_split(np.arange(gt.size), 7):  # accumulation over "images"
        acc.add(score[part], gt[part])
    assert acc.average_precision() == pytest.approx(_exact_ap(score, gt), abs=1e-12)
    thresholds, precision, recall = acc.curve()
    assert recall[-1] == 1.0 and precision[-1] == pytest.approx(gt.mean())
    assert np.all(np.diff(recall) >= 0) and np.all(np.diff(thresholds) < 0)


def test_ap_without_positives_is_nan():
    acc = MT.PRAccumulator()
    acc.add(np.zeros((4, 4), np.float32), np.zeros((4, 4), bool))
    assert math.isnan(acc.average_precision())


def test_mask_counts():
    mc = MT.MaskCounts()
    mc.add(np.array([[1, 1, 0, 0]]), np.array([[1, 0, 1, 0]]))
    s = mc.summary()
    assert (mc.tp, mc.fp, mc.fn, mc.tn) == (1, 1, 1, 1)
    assert s["precision"] == 0.5 and s["recall"] == 0.5 and s["iou"] == pytest.approx(1 / 3) and s["coverage"] == 0.5
