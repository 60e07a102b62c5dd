"""Small drops over smooth surroundings filled from them (CONTRACTS.md section 2, "Small drops
filled from their surround"): the numpy twin of include/raindrop/remove/surround_fill.h, for the
reference pipeline. The rule, in short: an 8-connected part of the mask of at most ``max_area``
pixels whose surround (unmasked pixels in its bounding box grown by 4) has an upper-median
absolute deviation of its luma of at most ``max_mad`` levels takes a push-pull interpolation of
the image from outside the mask, over its bounding box grown by max(8, 2 x its larger side), or
over the whole image when those rectangles add up to more than 4 times its pixels.

With ``rim`` > 0 each chosen part first grows into its rim (``grow_into_rims``): up to ``rim``
steps of 3x3 dilation into the pixels outside the mask whose luma is more than 12 levels from the
part's surround median, kept only when the next step would take at most 0.25 times what the last
one took (a ring ends; a pole or an edge goes on) and none of it touches the mask's edge (where a
band may go on unseen). The mask grows with the parts.
"""

from __future__ import annotations

import cv2
import numpy as np

SURROUND_RING = 4
SURROUND_WINDOW = 2
SURROUND_WINDOW_BUDGET = 4.0
RIM_LEVELS = np.float32(12.0)
RIM_CONTINUATION = 0.25


def _push(n: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Means of N (3xhxw) and W (hxw) over 2x2 blocks, counting the pixels of a block that exist."""
    h, wd = w.shape
    h2, w2 = (h + 1) // 2, (wd + 1) // 2
    ones = np.zeros((2 * h2, 2 * w2), np.float32)
    ones[:h, :wd] = 1.0
    wp = np.zeros_like(ones)
    wp[:h, :wd] = w
    np_ = np.zeros((3, 2 * h2, 2 * w2), np.float32)
    np_[:, :h, :wd] = n
    count = ones.reshape(h2, 2, w2, 2).sum(axis=(1, 3))
    inv = (np.float32(1.0) / count).astype(np.float32)
    w_next = wp.reshape(h2, 2, w2, 2).sum(axis=(1, 3)) * inv
    n_next = np_.reshape(3, h2, 2, w2, 2).sum(axis=(2, 4)) * inv
    return n_next.astype(np.float32), w_next.astype(np.float32)


def _taps(fine: int, coarse: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    pos = np.clip((np.arange(fine, dtype=np.float32) + np.float32(0.5)) * np.float32(0.5) - np.float32(0.5),
                  np.float32(0.0), np.float32(coarse - 1))
    i0 = pos.astype(np.int64)
    i1 = np.minimum(i0 + 1, coarse - 1)
    return i0, i1, (pos - i0.astype(np.float32)).astype(np.float32)


def push_pull_fill(rgb: np.ndarray, hole: np.ndarray) -> np.ndarray | None:
    """3xhxw float32 image, hxw hole (non-zero: fill) -> 3xhxw with the hole filled; None when
    every pixel is in the hole."""
    known = (hole == 0).astype(np.float32)
    if not known.any():
        return None
    levels = [(rgb.astype(np.float32) * known[None], known)]
    while levels[-1][1].shape[0] > 1 or levels[-1][1].shape[1] > 1:
        levels.append(_push(*levels[-1]))
    n, w = levels[-1]
    v = np.where(w[None] > 0, n / np.where(w > 0, w, np.float32(1.0))[None], np.float32(0.0)).astype(np.float32)
    for n, w in reversed(levels[:-1]):
        ch, cw = v.shape[1:]
        a0, a1, ta = _taps(w.shape[0], ch)
        b0, b1, tb = _taps(w.shape[1], cw)
        top = v[:, a0][:, :, b0] * (np.float32(1.0) - tb) + v[:, a0][:, :, b1] * tb
        bottom = v[:, a1][:, :, b0] * (np.float32(1.0) - tb) + v[:, a1][:, :, b1] * tb
        u = top * (np.float32(1.0) - ta)[None, :, None] + bottom * ta[None, :, None]
        v = (n + (np.float32(1.0) - w)[None] * u).astype(np.float32)
    return np.where(hole[None] != 0, v, rgb).astype(np.float32)


def _luma(rgb: np.ndarray) -> np.ndarray:
    return ((np.float32(0.299) * rgb[0] + np.float32(0.587) * rgb[1]) + np.float32(0.114) * rgb[2]) * np.float32(255.0)


def _choose_parts(mask: np.ndarray, rgb: np.ndarray, max_area: int, max_mad: float):
    """``choose_parts``, with each chosen part's surround median (the upper one) beside it."""
    if max_area <= 0:
        return None, [], []
    m = (mask != 0).astype(np.uint8)
    count, labels, stats, _ = cv2.connectedComponentsWithStats(m, connectivity=8, ltype=cv2.CV_32S)
    h, w = m.shape
    luma = _luma(rgb)
    chosen, medians = [], []
    for k in range(1, count):
        x, y, bw, bh, area = (int(v) for v in stats[k])
        if area > max_area:
            continue
        x0, y0 = max(0, x - SURROUND_RING), max(0, y - SURROUND_RING)
        x1, y1 = min(w, x + bw + SURROUND_RING), min(h, y + bh + SURROUND_RING)
        ring = luma[y0:y1, x0:x1][m[y0:y1, x0:x1] == 0]
        if ring.size < 4:
            continue
        mid = ring.size // 2
        median = np.partition(ring, mid)[mid]
        mad = np.partition(np.abs(ring - median), mid)[mid]
        if float(mad) <= max_mad:
            chosen.append((k, x, y, bw, bh))
            medians.append(median)
    return labels, chosen, medians


def choose_parts(mask: np.ndarray, rgb: np.ndarray, max_area: int, max_mad: float):
    """Labels (hxw int32) and the chosen parts as (label, x, y, width, height)."""
    labels, chosen, _ = _choose_parts(mask, rgb, max_area, max_mad)
    return labels, chosen


def grow_into_rims(labels: np.ndarray, chosen: list, medians: list, rgb: np.ndarray, mask: np.ndarray,
                   rim: int) -> list:
    """Each chosen part grown into its rim, in turn, from its surround median as chosen (before any
    growth): ``labels`` and ``mask`` written in place (the mask's new pixels set to 1); returns the
    parts with their grown bounding boxes."""
    if rim <= 0 or not chosen:
        return chosen
    h, w = mask.shape
    luma = _luma(rgb)
    kernel = np.ones((3, 3), np.uint8)
    out = []
    for (k, x, y, bw, bh), median in zip(chosen, medians):
        reach = rim + 2
        x0, y0 = max(0, x - reach), max(0, y - reach)
        x1, y1 = min(w, x + bw + reach), min(h, y + bh + reach)
        off = (mask[y0:y1, x0:x1] == 0) & (np.abs(luma[y0:y1, x0:x1] - median) > RIM_LEVELS)
        grown = (labels[y0:y1, x0:x1] == k).astype(np.uint8)
        taken = np.zeros_like(grown, dtype=bool)
        last, nxt = 0, 0
        for step in range(rim + 1):
            ring = (cv2.dilate(grown, kernel) != 0) & off & ~taken
            n = int(ring.sum())
            if step == rim or n == 0:
                nxt = n
                break
            taken |= ring
            grown[ring] = 1
            last = n
        ys, xs = np.nonzero(taken)
        at_edge = bool(ys.size) and (y0 + ys.min() == 0 or y0 + ys.max() == h - 1 or x0 + xs.min() == 0
                                     or x0 + xs.max() == w - 1)
        if last == 0 or nxt > RIM_CONTINUATION * last or at_edge:  # no rim, scenery going on, or the edge
            out.append((k, x, y, bw, bh))
            continue
        labels[y0:y1, x0:x1][taken] = k
        mask[y0:y1, x0:x1][taken] = 1
        gx0, gy0 = min(x, x0 + int(xs.min())), min(y, y0 + int(ys.min()))
        gx1, gy1 = max(x + bw, x0 + int(xs.max()) + 1), max(y + bh, y0 + int(ys.max()) + 1)
        out.append((k, gx0, gy0, gx1 - gx0, gy1 - gy0))
    return out


def fill_small_drops_from_surround(rgb: np.ndarray, mask: np.ndarray, max_area: int, max_mad: float,
                                   ihat: np.ndarray, rim: int = 0) -> int:
    """Replaces ``ihat`` (3xhxw, in place) by the fill in the chosen parts; returns their number.
    With ``rim``, the parts first grow into their rims and ``mask`` (written in place) with them."""
    labels, chosen, medians = _choose_parts(mask, rgb, max_area, max_mad)
    if not chosen:
        return 0
    chosen = grow_into_rims(labels, chosen, medians, rgb, mask, rim)
    h, w = mask.shape
    windows = []
    for _, x, y, bw, bh in chosen:
        grow = max(2 * SURROUND_RING, SURROUND_WINDOW * max(bw, bh))
        x0, y0 = max(0, x - grow), max(0, y - grow)
        windows.append((x0, y0, min(w, x + bw + grow), min(h, y + bh + grow)))
    if sum((x1 - x0) * (y1 - y0) for x0, y0, x1, y1 in windows) > SURROUND_WINDOW_BUDGET * h * w:
        windows = [(0, 0, w, h)] * len(chosen)
    hole = (mask != 0).astype(np.uint8)
    filled_win, fill = None, None  # the window `fill` holds (parts share the whole image's)
    for (k, x, y, bw, bh), win in zip(chosen, windows):
        x0, y0, x1, y1 = win
        if win != filled_win:
            fill = push_pull_fill(rgb[:, y0:y1, x0:x1], hole[y0:y1, x0:x1])
            filled_win = win
        part = labels[y:y + bh, x:x + bw] == k
        ihat[:, y:y + bh, x:x + bw][:, part] = fill[:, y - y0:y - y0 + bh, x - x0:x - x0 + bw][:, part]
    return len(chosen)
