import math

import pytest

pytestmark = pytest.mark.torch
torch = pytest.importorskip("torch")

from raindrop_tools.losses import detection_loss, reconstruction_loss, refine_loss  # noqa: E402


def _finite_with_grad(fn, pred, *args):
    pred = pred.clone().requires_grad_(True)
    loss = fn(pred, *args)
    loss.backward()
    assert torch.isfinite(loss), f"loss {loss}"
    assert torch.isfinite(pred.grad).all(), "gradient not finite"
    return loss.item()


@pytest.mark.parametrize(
    "value_pred,value_gt", [(0.0, 0.0), (1.0, 1.0), (0.5, 0.5), (0.0, 1.0), (0.3, 0.7), (-0.2, 1.3)]
)
def test_refine_loss_finite_on_flat_patches(value_pred, value_gt):
    pred = torch.full((2, 3, 100, 100), value_pred)
    gt = torch.full((2, 3, 100, 100), value_gt)
    loss = _finite_with_grad(refine_loss, pred, gt)
    if value_pred == value_gt:
        assert loss == pytest.approx(0.0, abs=1e-6)
    else:
        assert loss > 0


def test_refine_loss_finite_on_realistic_crops_and_matches_definition():
    g = torch.Generator().manual_seed(0)
    gt = torch.rand(4, 3, 100, 100, generator=g)
    pred = (gt + 0.1 * torch.randn(4, 3, 100, 100, generator=g)).clamp(-0.5, 1.5)
    loss = _finite_with_grad(refine_loss, pred, gt)
    from pytorch_msssim import ssim

    want = 0.3 * (1 - ssim(pred, gt, data_range=1.0).item()) + 0.7 * (pred - gt).abs().mean().item()
    assert loss == pytest.approx(want, rel=1e-5)


def test_reconstruction_loss_weights_the_mask_20x():
    gt = torch.zeros(1, 3, 4, 5)
    mask = torch.zeros(1, 1, 4, 5)
    mask[0, 0, 1, 2] = 1
    pred = gt.clone()
    pred[0, :, 1, 2] = 0.5  # error inside the mask
    inside = reconstruction_loss(pred, gt, mask).item()
    pred2 = gt.clone()
    pred2[0, :, 0, 0] = 0.5  # same error outside
    outside = reconstruction_loss(pred2, gt, mask).item()
    assert inside == pytest.approx(20 * 0.5 * 3 / 60)
    assert outside == pytest.approx(1 * 0.5 * 3 / 60)
    _finite_with_grad(reconstruction_loss, torch.zeros(1, 3, 8, 8), torch.zeros(1, 3, 8, 8), torch.ones(1, 1, 8, 8))


def test_detection_loss_is_bce_on_logits_and_stable_for_large_logits():
    logits = torch.tensor([[[[0.0, 2.0], [-3.0, 100.0]]]])
    mask = torch.tensor([[[[1.0, 0.0], [0.0, 0.0]]]])
    want = (math.log(2) + (2 + math.log1p(math.exp(-2))) + math.log1p(math.exp(-3)) + 100.0) / 4
    assert detection_loss(logits, mask).item() == pytest.approx(want, rel=1e-6)
    _finite_with_grad(detection_loss, torch.full((1, 1, 4, 4), 1e4), torch.zeros(1, 1, 4, 4))


def test_detection_loss_weights_each_crop():
    torch.manual_seed(0)
    logits, mask = torch.randn(2, 1, 8, 8), (torch.rand(2, 1, 8, 8) > 0.5).float()
    plain = detection_loss(logits, mask)
    assert detection_loss(logits, mask, torch.ones(2)).item() == pytest.approx(plain.item(), rel=1e-6)
    # crop 0 weighted out: half the mean of crop 1 alone (the mean stays over every pixel)
    half = detection_loss(logits, mask, torch.tensor([0.0, 1.0])).item()
    assert half == pytest.approx(0.5 * detection_loss(logits[1:], mask[1:]).item(), rel=1e-6)
    assert detection_loss(logits, mask, torch.zeros(2)).item() == 0.0
