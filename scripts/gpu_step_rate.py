"""Optimizer steps per second of stage 1 (RDN and 3RN, forward, backward, Adam) for a config,
on random crops of its batch and crop size, for the seconds given. scripts/gpu-train.sh starts
one per run at the same time, so each rate is the rate while sharing the GPU with the others,
and sizes each run's step counts to the time the GPU is lent for.

    python scripts/gpu_step_rate.py CONFIG SECONDS [DEVICE]  ->  prints steps per second
"""

import sys
import time

import torch

from raindrop_tools.config import load_config
from raindrop_tools.networks import build_networks, example_inputs

cfg = load_config(sys.argv[1], resolve_paths=False)
seconds = float(sys.argv[2])
dev = torch.device(sys.argv[3] if len(sys.argv) > 3 else "cuda")
fmt = torch.channels_last if cfg.train.channels_last else torch.contiguous_format
nets = {k: v.to(dev, memory_format=fmt) for k, v in build_networks(cfg.network).items()}
opts = {k: torch.optim.Adam(nets[k].parameters(), lr=1e-4) for k in ("rdn", "rrn")}
b, c = cfg.train.batch_size, cfg.data.crop
x, edge = (t.to(dev).contiguous(memory_format=fmt) for t in example_inputs("rrn", b, c, c))
target = torch.rand(b, 1, c, c, device=dev).round()


def step():
    for name, out in (("rdn", lambda: nets["rdn"](x)), ("rrn", lambda: nets["rrn"](x, edge))):
        opts[name].zero_grad(set_to_none=True)
        y = out()
        loss = (y.mean(1, keepdim=True) - target).abs().mean()
        loss.backward()
        opts[name].step()
        loss.item()  # the trainer reads every loss back, so each step waits for the GPU as it does


for _ in range(5):
    step()
n, t0 = 0, time.time()
while time.time() - t0 < seconds:
    step()
    n += 1
print(f"{n / (time.time() - t0):.3f}")
