"""The edge map E of the paper's eq. 4 (CONTRACTS.md section 2, step 2).

For every pixel: the sum over the colour channels of the absolute differences to its 4
neighbours, divided by 4. At the image border the missing neighbour is the pixel itself
(replicate), so it contributes 0.

The float32 order of operations is fixed, so that the torch and numpy versions (and the C++
one, which should do the same) give bit-identical results::

    d = ((|x - right| + |x - left|) + |x - below|) + |x - above|     per channel
    E = ((d_R + d_G) + d_B) * 0.25                                    (0.25: exact /4)

``edge_map_numpy`` is the one used by the data loader and the reference pipeline,
``edge_map_torch`` the one for tensors; tests check they agree exactly.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    import torch


def edge_map_numpy(img: np.ndarray) -> np.ndarray:
    """HxWxC float32 (values in [0, 1]) -> HxW float32 edge map."""
    x = np.asarray(img)
    if x.dtype != np.float32:
        raise TypeError(f"edge_map_numpy expects float32, got {x.dtype}")
    if x.ndim != 3:
        raise ValueError(f"edge_map_numpy expects HxWxC, got shape {x.shape}")
    p = np.pad(x, ((1, 1), (1, 1), (0, 0)), mode="edge")
    right = np.abs(x - p[1:-1, 2:])
    left = np.abs(x - p[1:-1, :-2])
    below = np.abs(x - p[2:, 1:-1])
    above = np.abs(x - p[:-2, 1:-1])
    d = ((right + left) + below) + above
    s = d[:, :, 0].copy()
    for c in range(1, d.shape[2]):
        s = s + d[:, :, c]
    return s * np.float32(0.25)


def edge_map_torch(img: "torch.Tensor") -> "torch.Tensor":
    """NxCxHxW float32 tensor -> Nx1xHxW float32 edge map (same arithmetic as the numpy one)."""
    import torch
    import torch.nn.functional as F

    if img.dtype != torch.float32:
        raise TypeError(f"edge_map_torch expects float32, got {img.dtype}")
    if img.dim() != 4:
        raise ValueError(f"edge_map_torch expects NxCxHxW, got shape {tuple(img.shape)}")
    p = F.pad(img, (1, 1, 1, 1), mode="replicate")
    right = (img - p[:, :, 1:-1, 2:]).abs()
    left = (img - p[:, :, 1:-1, :-2]).abs()
    below = (img - p[:, :, 2:, 1:-1]).abs()
    above = (img - p[:, :, :-2, 1:-1]).abs()
    d = ((right + left) + below) + above
    s = d[:, 0:1]
    for c in range(1, d.shape[1]):
        s = s + d[:, c : c + 1]
    return s * 0.25


def edge_map_window(img: np.ndarray, y0: int, x0: int, h: int, w: int) -> np.ndarray:
    """The edge map of the FULL image ``img`` (HxWxC float32), restricted to the window
    [y0, y0+h) x [x0, x0+w). Computed on the window grown by one pixel (clipped at the
    image border), which is exactly the full-image result: E at a pixel only depends on its
    4 neighbours, and where the grown window is clipped the window border is the image
    border, where the replicate rule applies in both. Saves computing E on the whole frame
    for every 100x100 training crop."""
    H, W = img.shape[:2]
    if not (0 <= y0 and 0 <= x0 and h >= 1 and w >= 1 and y0 + h <= H and x0 + w <= W):
        raise ValueError(f"window ({y0},{x0},{h},{w}) outside a {H}x{W} image")
    ya, yb = max(y0 - 1, 0), min(y0 + h + 1, H)
    xa, xb = max(x0 - 1, 0), min(x0 + w + 1, W)
    e = edge_map_numpy(img[ya:yb, xa:xb])
    return e[y0 - ya : y0 - ya + h, x0 - xa : x0 - xa + w]
