"""The three training losses (paper eqs. 2, 3 and 6)."""

from __future__ import annotations

import torch
import torch.nn.functional as F
from pytorch_msssim import ssim


def detection_loss(logits: torch.Tensor, mask: torch.Tensor, weight: torch.Tensor | None = None) -> torch.Tensor:
    """RDN: binary cross-entropy, mean over pixels, in the numerically stable logits form.
    ``weight`` (one value per crop, shape (N,)) scales each crop's term; the mean stays over all
    pixels of the batch, so a crop of weight 0 adds nothing to the loss or its gradient and the
    others keep their scale. (A batch of weight-0 crops only gives a zero gradient, but Adam's
    momentum still moves the weights a little on that step.)"""
    if weight is None:
        return F.binary_cross_entropy_with_logits(logits, mask)
    w = weight.to(logits.dtype).reshape(-1, *([1] * (logits.dim() - 1)))
    return F.binary_cross_entropy_with_logits(logits, mask, weight=w.expand_as(logits))


def reconstruction_loss(
    pred: torch.Tensor, target: torch.Tensor, mask: torch.Tensor, inside_weight: float = 20.0
) -> torch.Tensor:
    """3RN: L1 weighted by ``inside_weight`` where the ground-truth mask is 1 and by 1
    elsewhere, mean over all pixels and channels (the mask broadcasts over channels)."""
    weight = 1.0 + (inside_weight - 1.0) * mask
    return (weight * (pred - target).abs()).mean()


def refine_loss(pred: torch.Tensor, target: torch.Tensor, alpha: float = 0.3, window: int = 11) -> torch.Tensor:
    """RFN: alpha (1 - SSIM) + (1 - alpha) L1, SSIM of pytorch_msssim (Gaussian window,
    sigma 1.5, data range 1). Finite on flat patches: SSIM's stabilising constants keep the
    denominators positive. Inputs must be at least ``window`` pixels high and wide."""
    s = ssim(pred, target, data_range=1.0, size_average=True, win_size=window)
    return alpha * (1.0 - s) + (1.0 - alpha) * (pred - target).abs().mean()
