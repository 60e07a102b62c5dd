"""The three networks of Hao et al. (ICCV-W 2019), section 4, built from ``config.NetworkConfig``.

* RDN (detection) and 3RN (region reconstruction, ``RRN`` here) share one design,
  ``HalfResNet``: conv1 3x3 -> conv2 3x3 stride 2 (the blocks run at half resolution) ->
  conv3 1x1 to the expanded width -> bottleneck residual blocks -> conv4, a 4x4 stride-2
  transposed convolution back to full resolution -> conv5 3x3 to the output channels.
  BN + ReLU follow every convolution except the last one (which has a bias and is linear).
  Blocks are ResNet v1 bottlenecks: 1x1 down, 3x3, 1x1 up (BN, no ReLU), identity added,
  then ReLU.
* RFN (refine): conv 3x3 -> basic residual blocks (two 3x3) -> conv 3x3, linear output.

All networks accept any H, W >= 1. At an odd height or width the stride-2 convolution's own
zero padding covers the last row or column, conv4 returns one more, and conv5's result is
cropped back (a slice to the symbolic input size, which the ONNX exporter writes as
shape-generic Slice nodes). The pipelines never show the networks an odd size: they pad the
image to even first (replicate; docs/CONTRACTS.md section 2), and the networks were trained on
even crops. Where H and W are even nothing is padded or cropped. (Earlier exports padded the
feature map to even size inside the graph, replicate, before the stride-2 convolution, and
cropped before conv5: at even sizes the same function, but the pad and the slices copied
full-resolution tensors and cost the RDN 10% of its time; ``inner_padding.py`` rewrites such
graphs.)

Weights: Xavier (Glorot) uniform, zero biases, BN weight 1 / bias 0. With
``global_residual`` the last convolution starts at zero so the network starts as the
identity (a choice of ours, not the paper's, which has no global residual).
"""

from __future__ import annotations

import torch
import torch.nn as nn
import torch.nn.functional as F

from .config import HalfResConfig, NetworkConfig, RefineConfig


def conv_bn_relu(cin: int, cout: int, k: int, stride: int = 1) -> nn.Sequential:
    return nn.Sequential(
        nn.Conv2d(cin, cout, k, stride=stride, padding=k // 2, bias=False),
        nn.BatchNorm2d(cout),
        nn.ReLU(inplace=True),
    )


class Bottleneck(nn.Module):
    """1x1 expanded->width, 3x3 width->width, 1x1 width->expanded, identity skip."""

    def __init__(self, expanded: int, width: int):
        super().__init__()
        self.reduce = conv_bn_relu(expanded, width, 1)
        self.conv = conv_bn_relu(width, width, 3)
        self.expand = nn.Sequential(nn.Conv2d(width, expanded, 1, bias=False), nn.BatchNorm2d(expanded))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return F.relu(x + self.expand(self.conv(self.reduce(x))))


class BasicBlock(nn.Module):
    """Two 3x3 convolutions at constant width, identity skip."""

    def __init__(self, width: int):
        super().__init__()
        self.conv1 = conv_bn_relu(width, width, 3)
        self.conv2 = nn.Sequential(nn.Conv2d(width, width, 3, padding=1, bias=False), nn.BatchNorm2d(width))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return F.relu(x + self.conv2(self.conv1(x)))


class HalfResNet(nn.Module):
    """The RDN / 3RN body: full-res conv, stride-2 conv, blocks at half res, upsampling."""

    def __init__(self, in_ch: int, out_ch: int, cfg: HalfResConfig):
        super().__init__()
        w, e = cfg.width, cfg.expanded
        self.conv1 = conv_bn_relu(in_ch, w, 3)
        self.conv2 = conv_bn_relu(w, w, 3, stride=2)
        self.conv3 = conv_bn_relu(w, e, 1)
        self.blocks = nn.Sequential(*[Bottleneck(e, w) for _ in range(cfg.blocks)])
        # Exactly 2x: (h - 1) * 2 - 2 * 1 + 4 = 2h.
        self.conv4 = nn.Sequential(
            nn.ConvTranspose2d(e, w, 4, stride=2, padding=1, bias=False),
            nn.BatchNorm2d(w),
            nn.ReLU(inplace=True),
        )
        self.conv5 = nn.Conv2d(w, out_ch, 3, padding=1, bias=True)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        h, w = x.shape[-2], x.shape[-1]
        y = self.conv4(self.blocks(self.conv3(self.conv2(self.conv1(x)))))
        return self.conv5(y)[:, :, :h, :w]


class RDN(nn.Module):
    """Raindrop detection network: RGB -> mask logits (N,1,H,W). ``probability`` applies the
    sigmoid (the exported graph outputs the probability; the loss uses the logits)."""

    def __init__(self, cfg: HalfResConfig = HalfResConfig(blocks=6)):
        super().__init__()
        if cfg.global_residual:
            raise ValueError("RDN has no global residual")
        self.cfg = cfg
        self.body = HalfResNet(3, 1, cfg)
        init_weights(self)

    def forward(self, image: torch.Tensor) -> torch.Tensor:
        return self.body(image)

    def probability(self, image: torch.Tensor) -> torch.Tensor:
        return torch.sigmoid(self.forward(image))


def rdn_taps(rdn: "RDN", image: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """What an ``AlternativeHead`` reads of a trained RDN: conv2's output (after ReLU; width
    channels at half resolution), the blocks' output (expanded channels, half resolution) and the
    RDN's own logits (N,1,H,W)."""
    b = rdn.body
    h, w = image.shape[-2], image.shape[-1]
    f2 = b.conv2(b.conv1(image))
    f4 = b.blocks(b.conv3(f2))
    return f2, f4, b.conv5(b.conv4(f4))[:, :, :h, :w]


class AlternativeHead(nn.Module):
    """A second detector's logits computed from a trained RDN's own layers (``rdn_taps``): the
    RDN's logits plus a correction from its half-resolution features. A router that sends an
    image to this detector then pays for the head only, about a sixth of a compact RDN, instead
    of a second network (tools/raindrop_tools/shared_detector.py, docs/RESULTS.md 4.48).

    1x1 (width + expanded -> mid) -> ReLU -> 3x3 (mid -> mid) -> ReLU -> transposed 4x4 stride 2
    (mid -> up) -> ReLU -> 3x3 (up -> 1), cropped to the logits' size and added to them. Biases,
    no BatchNorm (trained alone, on a frozen RDN). The last convolution starts at zero: the head
    starts as the RDN it reads."""

    def __init__(self, width: int, expanded: int, mid: int = 24, up: int = 16):
        super().__init__()
        self.mix = nn.Conv2d(width + expanded, mid, 1)
        self.conv = nn.Conv2d(mid, mid, 3, padding=1)
        self.up = nn.ConvTranspose2d(mid, up, 4, stride=2, padding=1)
        self.out = nn.Conv2d(up, 1, 3, padding=1)
        nn.init.zeros_(self.out.weight)
        nn.init.zeros_(self.out.bias)

    def forward(self, f2: torch.Tensor, f4: torch.Tensor, logits: torch.Tensor) -> torch.Tensor:
        h = F.relu(self.conv(F.relu(self.mix(torch.cat([f2, f4], dim=1)))))
        correction = self.out(F.relu(self.up(h)))
        return logits + correction[:, :, : logits.shape[-2], : logits.shape[-1]]


class RRN(nn.Module):
    """Raindrop region reconstruction network (the paper's 3RN): RGB + edge map ->
    RGB (N,3,H,W), linear (unclamped)."""

    def __init__(self, cfg: HalfResConfig = HalfResConfig(blocks=8)):
        super().__init__()
        self.cfg = cfg
        self.body = HalfResNet(4, 3, cfg)
        init_weights(self, zero_last=self.body.conv5 if cfg.global_residual else None)

    def forward(self, image: torch.Tensor, edge: torch.Tensor) -> torch.Tensor:
        out = self.body(torch.cat([image, edge], dim=1))
        return image + out if self.cfg.global_residual else out


class RFN(nn.Module):
    """Refine network: blend B -> RGB (N,3,H,W), linear (unclamped)."""

    def __init__(self, cfg: RefineConfig = RefineConfig()):
        super().__init__()
        self.cfg = cfg
        self.head = conv_bn_relu(3, cfg.width, 3)
        self.blocks = nn.Sequential(*[BasicBlock(cfg.width) for _ in range(cfg.blocks)])
        self.tail = nn.Conv2d(cfg.width, 3, 3, padding=1, bias=True)
        init_weights(self, zero_last=self.tail if cfg.global_residual else None)

    def forward(self, blend: torch.Tensor) -> torch.Tensor:
        out = self.tail(self.blocks(self.head(blend)))
        return blend + out if self.cfg.global_residual else out


def init_weights(module: nn.Module, zero_last: nn.Module | None = None) -> None:
    for m in module.modules():
        if isinstance(m, (nn.Conv2d, nn.ConvTranspose2d)):
            nn.init.xavier_uniform_(m.weight)
            if m.bias is not None:
                nn.init.zeros_(m.bias)
        elif isinstance(m, nn.BatchNorm2d):
            nn.init.ones_(m.weight)
            nn.init.zeros_(m.bias)
    if zero_last is not None:
        nn.init.zeros_(zero_last.weight)
        if zero_last.bias is not None:
            nn.init.zeros_(zero_last.bias)


NETWORK_NAMES = ("rdn", "rrn", "rfn")


def build_network(name: str, cfg: NetworkConfig) -> nn.Module:
    if name == "rdn":
        return RDN(cfg.rdn)
    if name == "rrn":
        return RRN(cfg.rrn)
    if name == "rfn":
        return RFN(cfg.rfn)
    raise ValueError(f"unknown network {name!r}; expected one of {NETWORK_NAMES}")


def build_networks(cfg: NetworkConfig) -> dict[str, nn.Module]:
    return {name: build_network(name, cfg) for name in NETWORK_NAMES}


def example_inputs(name: str, n: int = 1, h: int = 64, w: int = 64, generator=None) -> tuple:
    """Random inputs in [0, 1] of the right arity for ``name`` (RRN takes image and edge)."""
    if name == "rrn":
        return (torch.rand(n, 3, h, w, generator=generator), torch.rand(n, 1, h, w, generator=generator))
    return (torch.rand(n, 3, h, w, generator=generator),)
