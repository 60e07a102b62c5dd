"""Dilation with OpenCV's elliptical structuring element (CONTRACTS.md section 2, step 4).

``dilate_numpy`` is ``cv2.dilate`` itself (the reference pipeline). ``Dilation`` is the
parameter-free torch layer used in stage-2 training; it reproduces ``cv2.dilate`` exactly:

* the kernel is ``cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))``, anchor at
  (k // 2, k // 2) (OpenCV's default anchor);
* ``dst(y, x) = max over kernel cells (i, j) of src(y + i - k//2, x + j - k//2)``;
* pixels outside the image never win (OpenCV's default border value for dilation).

The torch layer computes a true grey-level maximum (unfold + max), so it matches OpenCV on
any values, not only on binary masks. This module imports without torch; the layer is then
not defined.
"""

from __future__ import annotations

import cv2
import numpy as np

try:  # torch is optional for this module (the reference pipeline runs without it)
    import torch
    import torch.nn as nn
    import torch.nn.functional as F
except ImportError:  # pragma: no cover - exercised in the no-torch environment
    torch = None


def ellipse_kernel(k: int) -> np.ndarray:
    """k x k uint8 0/1 elliptical structuring element, exactly OpenCV's."""
    if int(k) != k or k < 1:
        raise ValueError(f"dilation size must be an integer >= 1, got {k!r}")
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (int(k), int(k)))


def dilate_numpy(mask: np.ndarray, k: int) -> np.ndarray:
    """HxW mask (any dtype OpenCV dilates, e.g. uint8 0/1) dilated with the k x k ellipse."""
    if k == 1:
        return mask.copy()
    return cv2.dilate(mask, ellipse_kernel(k))


if torch is not None:

    class Dilation(nn.Module):
        """Grey-level dilation of an NxCxHxW tensor with the k x k OpenCV ellipse."""

        def __init__(self, k: int):
            super().__init__()
            kernel = ellipse_kernel(k)
            self.k = int(k)
            # Flat indices (row-major, as F.unfold orders them) of the kernel's cells.
            idx = torch.from_numpy(np.flatnonzero(kernel.reshape(-1)).astype(np.int64))
            self.register_buffer("cells", idx, persistent=False)

        def forward(self, x: "torch.Tensor") -> "torch.Tensor":
            if self.k == 1:
                return x
            n, c, h, w = x.shape
            a = self.k // 2  # anchor; padding before = anchor, after = k - 1 - anchor
            flat = x.reshape(n * c, 1, h, w)
            lowest = torch.finfo(x.dtype).min if x.is_floating_point() else torch.iinfo(x.dtype).min
            padded = F.pad(flat, (a, self.k - 1 - a, a, self.k - 1 - a), value=lowest)
            cols = F.unfold(padded, kernel_size=self.k)  # (n*c, k*k, h*w)
            out = cols.index_select(1, self.cells).amax(dim=1)
            return out.reshape(n, c, h, w)

        def extra_repr(self) -> str:
            return f"k={self.k}"
