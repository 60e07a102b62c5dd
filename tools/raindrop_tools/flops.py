"""Multiply-accumulate counts of the networks at a given input size.

Counts the convolutions (Conv2d, ConvTranspose2d) and linear layers, which are all but a
fraction of a percent of the work; batch norm (folded into the convolutions at inference),
ReLU, the residual additions and the sigmoid are not counted. GFLOPs = 2 x GMACs (one
multiply and one add per MAC), the convention most papers quote.

    python -m raindrop_tools.flops --config tools/configs/compact.yaml --size 512x256

--size is WIDTHxHEIGHT, as for the project's other programs (``raindrop-render --size``,
``raindrop-bench remove --size``): the default 512x256 is the paper's training size, 512 wide
and 256 high.
"""

from __future__ import annotations

import argparse
import json
import sys

import torch
import torch.nn as nn

from .cli_args import width_x_height
from .config import ConfigError, NetworkConfig, load_config
from .networks import NETWORK_NAMES, build_network, example_inputs


def count_macs(model: nn.Module, inputs: tuple) -> int:
    """MACs of one forward pass of ``model`` on ``inputs`` (shapes matter, values do not)."""
    total = 0

    def conv_hook(m: nn.Module, inp, out):
        nonlocal total
        if isinstance(m, nn.Conv2d):
            # every output element: (cin / groups) * kh * kw MACs
            k = m.kernel_size[0] * m.kernel_size[1] * (m.in_channels // m.groups)
            total += out.numel() * k
        elif isinstance(m, nn.ConvTranspose2d):
            # every input element is scattered to (cout / groups) * kh * kw outputs
            k = m.kernel_size[0] * m.kernel_size[1] * (m.out_channels // m.groups)
            total += inp[0].numel() * k
        elif isinstance(m, nn.Linear):
            total += out.numel() * m.in_features

    hooks = [
        m.register_forward_hook(conv_hook)
        for m in model.modules()
        if isinstance(m, (nn.Conv2d, nn.ConvTranspose2d, nn.Linear))
    ]
    was_training = model.training
    try:
        model.eval()
        with torch.no_grad():
            model(*inputs)
    finally:
        for h in hooks:
            h.remove()
        model.train(was_training)
    return total


def network_macs(name: str, cfg: NetworkConfig, height: int = 256, width: int = 512) -> int:
    model = build_network(name, cfg)
    return count_macs(model, example_inputs(name, 1, height, width))


def gflops(cfg: NetworkConfig, height: int = 256, width: int = 512) -> dict[str, float]:
    """GFLOPs (2 x MACs / 1e9) per network and in total, for one image of height x width."""
    out = {name: 2.0 * network_macs(name, cfg, height, width) / 1e9 for name in NETWORK_NAMES}
    out["total"] = sum(out.values())
    return out


def parameter_count(model: nn.Module) -> int:
    return sum(p.numel() for p in model.parameters())


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m raindrop_tools.flops", description=__doc__.split("\n")[0])
    ap.add_argument("--config", required=True, action="append", help="run configuration(s) (YAML)")
    ap.add_argument(
        "--size",
        default="512x256",
        type=width_x_height,  # it used to be HxW, the other way round from every other program
        metavar="WIDTHxHEIGHT",
        help="WIDTHxHEIGHT, as for the project's other programs (default 512x256: 512 wide, 256 high)",
    )
    ap.add_argument("--json", action="store_true", help="print JSON")
    args = ap.parse_args(argv)
    torch.set_num_threads(1)
    w, h = args.size
    rows = {}
    for path in args.config:
        try:
            cfg = load_config(path, resolve_paths=False)
        except ConfigError as e:
            print(f"error: {e}", file=sys.stderr)
            return 2
        g = gflops(cfg.network, h, w)
        params = {n: parameter_count(build_network(n, cfg.network)) for n in NETWORK_NAMES}
        rows[cfg.name] = {"gflops": g, "params": params}
    if args.json:
        print(json.dumps({"width": w, "height": h, "configs": rows}, indent=2))
        return 0
    print(f"GFLOPs (2 x MACs) at {w}x{h} (width x height):")
    print(f"{'config':<12}{'rdn':>10}{'rrn':>10}{'rfn':>10}{'total':>10}   params rdn/rrn/rfn")
    for name, r in rows.items():
        g, p = r["gflops"], r["params"]
        print(
            f"{name:<12}{g['rdn']:>10.2f}{g['rrn']:>10.2f}{g['rfn']:>10.2f}{g['total']:>10.2f}"
            f"   {p['rdn']:,} / {p['rrn']:,} / {p['rfn']:,}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
