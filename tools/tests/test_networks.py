import json

import pytest

pytestmark = pytest.mark.torch
torch = pytest.importorskip("torch")
import torch.nn as nn  # noqa: E402

from helpers import CONFIGS  # noqa: E402
from raindrop_tools import flops  # noqa: E402
from raindrop_tools.config import HalfResConfig, NetworkConfig, RefineConfig, load_config  # noqa: E402
from raindrop_tools.flops import count_macs, gflops  # noqa: E402
from raindrop_tools.networks import RDN, RFN, RRN, build_networks, example_inputs  # noqa: E402

SMALL = NetworkConfig(
    rdn=HalfResConfig(width=8, expanded=16, blocks=2),
    rrn=HalfResConfig(width=8, expanded=16, blocks=2),
    rfn=RefineConfig(width=8, blocks=1),
)
OUT_CHANNELS = {"rdn": 1, "rrn": 3, "rfn": 3}


@pytest.mark.parametrize("size", [(1, 1), (1, 2), (2, 1), (3, 3), (37, 53), (64, 48), (5, 100)])
def test_any_size_in_same_size_out(size):
    h, w = size
    nets = build_networks(SMALL)
    for name, net in nets.items():
        for mode in ("train", "eval"):
            net.train(mode == "train")
            n = 2  # batch norm in training mode needs more than one value per channel
            out = net(*example_inputs(name, n, h, w))
            assert out.shape == (n, OUT_CHANNELS[name], h, w), (name, mode)
            assert torch.isfinite(out).all()


def test_paper_architecture_layers():
    rdn = RDN(HalfResConfig(blocks=6))
    body = rdn.body
    assert body.conv1[0].in_channels == 3 and body.conv1[0].out_channels == 64
    assert body.conv2[0].stride == (2, 2) and body.conv2[0].kernel_size == (3, 3)
    assert body.conv3[0].kernel_size == (1, 1) and body.conv3[0].out_channels == 256
    assert len(body.blocks) == 6
    b = body.blocks[0]
    assert (b.reduce[0].in_channels, b.reduce[0].out_channels) == (256, 64)
    assert (b.conv[0].kernel_size, b.conv[0].out_channels) == ((3, 3), 64)
    assert (b.expand[0].in_channels, b.expand[0].out_channels) == (64, 256)
    assert isinstance(body.conv4[0], nn.ConvTranspose2d) and body.conv4[0].stride == (2, 2)
    assert body.conv5.out_channels == 1 and body.conv5.bias is not None
    rrn = RRN(HalfResConfig(blocks=8))
    assert rrn.body.conv1[0].in_channels == 4 and len(rrn.body.blocks) == 8 and rrn.body.conv5.out_channels == 3
    rfn = RFN(RefineConfig())
    assert len(rfn.blocks) == 2 and rfn.head[0].out_channels == 64 and rfn.tail.out_channels == 3
    # BN + ReLU after every conv except the last one
    n_bn = sum(isinstance(m, nn.BatchNorm2d) for m in rdn.modules())
    n_conv = sum(isinstance(m, (nn.Conv2d, nn.ConvTranspose2d)) for m in rdn.modules())
    assert n_bn == n_conv - 1


def test_xavier_init_and_probability():
    torch.manual_seed(0)
    rdn = RDN(SMALL.rdn)
    w = rdn.body.conv3[0].weight  # 1x1 conv, fan_in 8, fan_out 16
    bound = (6.0 / (8 + 16)) ** 0.5
    assert w.abs().max() <= bound and w.abs().max() > 0.8 * bound
    x = torch.rand(1, 3, 9, 11)
    rdn.eval()
    torch.testing.assert_close(rdn.probability(x), torch.sigmoid(rdn(x)))


def test_global_residual_starts_as_identity():
    cfg = NetworkConfig(
        rdn=SMALL.rdn,
        rrn=HalfResConfig(width=8, expanded=16, blocks=1, global_residual=True),
        rfn=RefineConfig(width=8, blocks=1, global_residual=True),
    )
    nets = build_networks(cfg)
    img, edge = torch.rand(1, 3, 13, 17), torch.rand(1, 1, 13, 17)
    torch.testing.assert_close(nets["rrn"](img, edge), img)
    torch.testing.assert_close(nets["rfn"](img), img)
    with pytest.raises(ValueError):
        RDN(HalfResConfig(global_residual=True))


def test_count_macs_simple_layers():
    conv = nn.Conv2d(3, 8, 3, padding=1)
    assert count_macs(conv, (torch.zeros(1, 3, 10, 20),)) == 10 * 20 * 8 * 3 * 9
    up = nn.ConvTranspose2d(4, 2, 4, stride=2, padding=1)
    assert count_macs(up, (torch.zeros(1, 4, 5, 6),)) == 5 * 6 * 4 * 2 * 16


def test_paper_and_compact_flops():
    paper = gflops(load_config(CONFIGS / "paper.yaml", resolve_paths=False).network)
    compact = gflops(load_config(CONFIGS / "compact.yaml", resolve_paths=False).network)
    # conv1 3->64 at 256x512: 131072 * 64 * 27 MACs ... the full paper count, hand-derived:
    rdn_macs = (
        131072 * 64 * 27
        + 32768 * 64 * 576
        + 32768 * 64 * 256
        + 6 * 32768 * (256 * 64 + 576 * 64 + 64 * 256)
        + 32768 * 256 * 64 * 16
        + 131072 * 576
    )
    assert paper["rdn"] == pytest.approx(2 * rdn_macs / 1e9)
    assert paper["total"] == pytest.approx(146.45, abs=0.01)
    ratio = paper["total"] / compact["total"]
    assert 8.0 <= ratio <= 12.0, ratio


def test_flops_size_is_width_x_height(monkeypatch, capsys):
    """--size is WIDTHxHEIGHT like every other program of the project (it was HxW):
    512x256 is 512 wide and 256 high, also the default."""
    seen = []

    def fake_gflops(cfg, height, width):
        seen.append((height, width))
        return {"rdn": 1.0, "rrn": 2.0, "rfn": 3.0, "total": 6.0}

    monkeypatch.setattr(flops, "gflops", fake_gflops)
    smoke = str(CONFIGS / "smoke.yaml")
    assert flops.main(["--config", smoke, "--size", "512x256", "--json"]) == 0
    assert seen == [(256, 512)], "gflops(cfg, height, width) got the sides swapped"
    out = json.loads(capsys.readouterr().out)
    assert (out["width"], out["height"]) == (512, 256)
    assert flops.main(["--config", smoke, "--size", "640x96"]) == 0
    assert "at 640x96 (width x height)" in capsys.readouterr().out
    assert flops.main(["--config", smoke]) == 0
    assert seen == [(256, 512), (96, 640), (256, 512)]


@pytest.mark.parametrize("size", ["512", "512x256x3", "0x256", "axb"])
def test_flops_bad_size_is_a_usage_error(size, capsys):
    with pytest.raises(SystemExit) as e:
        flops.main(["--config", str(CONFIGS / "smoke.yaml"), "--size", size])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "--size" in err and ("WIDTHxHEIGHT" in err or "at least 1" in err), err
