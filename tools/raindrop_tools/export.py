"""Export a trained run to the three ONNX graphs of CONTRACTS.md section 2.

    python -m raindrop_tools.export --run tools/runs/compact --out models/compact

Writes ``rdn.onnx`` (image -> mask_prob, sigmoid inside), ``rrn.onnx`` (image, edge ->
reconstruction) and ``rfn.onnx`` (blend -> restored): opset 18, float32 NCHW, dynamic N, H
and W, metadata ``raindrop.*``, each checked with ``onnx.checker`` and against PyTorch in
ONNX Runtime. Also writes ``export.json`` (configuration, GFLOPs at 256x512, sha256 of each
graph). The networks accept any H, W, so ``raindrop.pad_multiple`` is 1; the pipelines still pad
to even sizes (CONTRACTS.md section 2: the stride-2 body was trained on even crops).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import datetime as _dt
import io
import json
import logging
import os
import sys
import warnings
from pathlib import Path

import numpy as np
import onnx
import torch
import torch.nn as nn

from . import checkpoint as ckpt
from . import contract as C
from . import onnx_weights
from .config import RunConfig, config_from_dict, is_safe_name, to_dict
from .flops import gflops, parameter_count
from .networks import build_networks
from .phase_conv import split_transposed_convs
from .phase_final_conv import fold_final_convs
from .staging import staged_model_files

OPSET = 18
PAD_MULTIPLE = 1
PARITY_TOLERANCE = 1e-4


class ExportError(RuntimeError):
    pass


class _DetectionProbability(nn.Module):
    """RDN with the sigmoid inside: the graph outputs the probability."""

    def __init__(self, rdn: nn.Module):
        super().__init__()
        self.rdn = rdn

    def forward(self, image: torch.Tensor) -> torch.Tensor:
        return torch.sigmoid(self.rdn(image))


def graph_module(name: str, net: nn.Module) -> nn.Module:
    """The module whose forward is exactly the graph's function."""
    return _DetectionProbability(net) if name == "rdn" else net


def _metadata(name: str, cfg: RunConfig) -> dict[str, str]:
    return {
        C.META_PAD_MULTIPLE: str(PAD_MULTIPLE),
        C.META_CONFIG: cfg.name,
        C.META_NETWORK: name,
        C.META_THRESHOLD: repr(float(cfg.pipeline.threshold)),
        C.META_DILATION: str(int(cfg.pipeline.dilation)),
    }


def _fix_io(model: onnx.ModelProto, name: str) -> None:
    """Name the dynamic dimensions N, H, W on every input and output (the exporter writes the
    outputs' symbolic size expressions) and drop the exporter's per-input metadata."""
    for value, channels in [(v, C.INPUT_CHANNELS[v.name]) for v in model.graph.input] + [
        (model.graph.output[0], C.OUTPUT_CHANNELS[name])
    ]:
        dims = value.type.tensor_type.shape.dim
        if len(dims) != 4:
            raise ExportError(f"{name}: {value.name} has rank {len(dims)}, expected 4")
        for d, label in zip(dims, ("N", None, "H", "W")):
            if label is None:
                d.Clear()
                d.dim_value = channels
            else:
                d.Clear()
                d.dim_param = label
        del value.metadata_props[:]


def _strip_debug_info(model: onnx.ModelProto) -> None:
    """Drop the exporter's per-node provenance (FX node text, Python stack traces): most of a
    small graph's bytes, and nothing a consumer needs."""
    for node in model.graph.node:
        del node.metadata_props[:]
        node.doc_string = ""
    for value in model.graph.value_info:
        del value.metadata_props[:]
    for init in model.graph.initializer:
        del init.metadata_props[:]


def export_network(name: str, net: nn.Module, cfg: RunConfig, path: Path) -> onnx.ModelProto:
    """Export one network (in eval mode) to ``path``; returns the saved model."""
    module = graph_module(name, net).eval()
    inputs = tuple(
        torch.rand(2, C.INPUT_CHANNELS[i], 37, 53, generator=torch.Generator().manual_seed(k))
        for k, i in enumerate(C.INPUTS[name])
    )
    N = torch.export.Dim("N", min=1)
    H = torch.export.Dim("H", min=1)
    W = torch.export.Dim("W", min=1)
    dyn = tuple({0: N, 2: H, 3: W} for _ in inputs)
    # The exporter prints progress to stdout and logs warnings about optional packages
    # (torchvision): keep the tool's output to what concerns the user.
    logging.getLogger("torch.onnx").setLevel(logging.ERROR)
    with warnings.catch_warnings(), torch.no_grad(), contextlib.redirect_stdout(io.StringIO()):
        warnings.simplefilter("ignore")
        program = torch.onnx.export(
            module,
            inputs,
            None,
            input_names=list(C.INPUTS[name]),
            output_names=[C.OUTPUTS[name]],
            opset_version=OPSET,
            dynamic_shapes=dyn,
            dynamo=True,
            external_data=False,
            verbose=False,
        )
    model = program.model_proto
    if [i.name for i in model.graph.input] != list(C.INPUTS[name]) or [o.name for o in model.graph.output] != [
        C.OUTPUTS[name]
    ]:
        raise ExportError(
            f"{name}: exported inputs/outputs {[i.name for i in model.graph.input]} -> "
            f"{[o.name for o in model.graph.output]} do not match the contract"
        )
    _fix_io(model, name)
    _strip_debug_info(model)
    # conv4's transposed convolution as four phase convolutions: the same function, 1.1-1.5x
    # faster networks in ONNX Runtime (phase_conv.py; checked against PyTorch by parity()).
    split_transposed_convs(model)
    # conv5 on those phases before they are interleaved: no full-resolution feature map
    # (phase_final_conv.py; also checked against PyTorch by parity()).
    fold_final_convs(model)
    del model.metadata_props[:]
    onnx.helper.set_model_props(model, _metadata(name, cfg))
    model.doc_string = f"raindrop {name} ({cfg.name}); see docs/CONTRACTS.md section 2"
    onnx.checker.check_model(model, full_check=True)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".tmp-{path.name}.{os.getpid()}")
    onnx.save(model, str(tmp))
    os.replace(tmp, path)
    return model


def parity(name: str, net: nn.Module, path: Path, inputs: tuple[torch.Tensor, ...]) -> float:
    """Max abs difference between ONNX Runtime (CPU) and PyTorch on ``inputs``."""
    import onnxruntime as ort

    so = ort.SessionOptions()
    so.intra_op_num_threads = 1
    sess = ort.InferenceSession(str(path), so, providers=["CPUExecutionProvider"])
    feed = {k: v.numpy() for k, v in zip(C.INPUTS[name], inputs)}
    got = sess.run(None, feed)[0]
    with torch.no_grad():
        want = graph_module(name, net).eval()(*inputs).numpy()
    if got.shape != want.shape:
        raise ExportError(f"{name}: ONNX output shape {got.shape} != PyTorch {want.shape}")
    # NaN compares false with everything: max(0.0, nan) is 0.0, so a network with NaN weights
    # passed as a perfect match and was shipped writing black images.
    if not (np.isfinite(got).all() and np.isfinite(want).all()):
        raise ExportError(f"{name}: the network's outputs are not finite (NaN or Inf weights in the checkpoint?)")
    return float(np.abs(got - want).max())


def load_run(run_dir: Path, checkpoint: Path | None = None, allow_incomplete: bool = False,
             detector_only: bool = False):
    """(config, networks in eval mode, checkpoint info) of a run's latest checkpoint.
    ``detector_only``: only the detector will be taken from it, so a complete stage 1 is
    finished training."""
    run_dir = Path(run_dir)
    if checkpoint is None:
        ref = ckpt.latest_checkpoint(run_dir)
        if ref is None:
            raise ExportError(f"{run_dir}: no checkpoints (train first)")
        checkpoint = ref.path
    try:
        state = ckpt.load_checkpoint(checkpoint)
    except ckpt.CheckpointError as e:
        raise ExportError(str(e)) from e
    # Only the detector taken: any stage-2 checkpoint follows a complete stage 1, whose detector is final.
    finished = (state["stage"] == 2 and state["complete"]) or (
        detector_only and (state["stage"] == 2 or state["complete"])
    )
    if not allow_incomplete and not finished:
        needed = "stage 1 complete" if detector_only else "stage 2 complete"
        raise ExportError(
            f"{checkpoint}: stage {state['stage']} step {state['step']} of {state['total_steps']}: "
            f"training is not finished (an export needs {needed}); pass --allow-incomplete to export anyway"
        )
    cfg = config_from_dict(state["config"])
    nets = build_networks(cfg.network)
    for k, net in nets.items():
        net.load_state_dict(state["models"][k])
        net.eval()
    info = {"path": str(checkpoint), "stage": state["stage"], "step": state["step"], "complete": state["complete"]}
    return cfg, nets, info


def take_reconstruction(nets: dict[str, nn.Module], folder: Path, source: dict | None) -> dict:
    """Replaces 3RN and RFN in ``nets`` by those of the exported model folder ``folder``
    (weights read back from its graphs, checked against ONNX Runtime: onnx_weights.py). A
    detector fine-tuned alone is shipped with the reconstruction it was tuned beside, not with
    the copies its run trained on the way. Returns ``source`` with the folder recorded."""
    try:
        onnx_weights.load_model_folder({n: nets[n] for n in ("rrn", "rfn")}, folder)
    except onnx_weights.OnnxWeightsError as e:
        raise ExportError(f"--reconstruction-from {e}") from e
    return {**(source or {}), "reconstruction_from": str(folder)}


def export_networks(cfg: RunConfig, nets: dict[str, nn.Module], out_dir: Path, source: dict | None = None) -> dict:
    """Export, check and describe the three networks into ``out_dir``; returns export.json.

    Everything is written and checked in a staging folder first (staging.py): a failed check or
    an interrupted export leaves the folder's model as it was. Other files in ``out_dir``
    (LARGE_DROPS, notes) are kept."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    with staged_model_files(out_dir, "export") as stage:
        g = torch.Generator().manual_seed(0)
        diffs = {}
        for name in C.NETWORKS:
            net = nets[name].eval()
            path = stage / C.FILES[name]
            export_network(name, net, cfg, path)
            worst = 0.0
            for n, h, w in [(1, 37, 53), (1, 1, 1), (2, 64, 48)]:
                inputs = tuple(torch.rand(n, C.INPUT_CHANNELS[i], h, w, generator=g) for i in C.INPUTS[name])
                worst = max(worst, parity(name, net, path, inputs))
            if not worst <= PARITY_TOLERANCE:
                raise ExportError(f"{name}: ONNX Runtime differs from PyTorch by {worst:g} > {PARITY_TOLERANCE}")
            diffs[name] = worst
        info = {
            "config": cfg.name,
            "network": to_dict(cfg.network),
            "pipeline": {"threshold": cfg.pipeline.threshold, "dilation": cfg.pipeline.dilation},
            "pad_multiple": PAD_MULTIPLE,
            "opset": OPSET,
            "gflops_256x512": gflops(cfg.network, 256, 512),
            "params": {k: parameter_count(v) for k, v in nets.items()},
            "files": C.graph_files(stage),
            "parity_max_abs_diff": diffs,
            "checkpoint": source,
            "exported": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
            "versions": {"torch": torch.__version__, "onnx": onnx.__version__},
        }
        (stage / C.EXPORT_INFO).write_text(json.dumps(info, indent=2) + "\n")
    return info


def _refuse_another_runs_folder(out: Path, source: dict | None) -> None:
    """The default folder, models/<name>, may hold a shipped model of that name (a run's
    config keeps the name it was copied with): replaced only when it came from the same run.
    An --out given by name is the user's choice and is replaced as asked."""
    info_file = out / C.EXPORT_INFO
    if not info_file.exists():
        return
    try:
        before = (json.loads(info_file.read_text()).get("checkpoint") or {}).get("path")
    except (OSError, ValueError, AttributeError):
        before = None
    now = (source or {}).get("path")
    same_run = before and now and Path(before).parent.parent.resolve() == Path(now).parent.parent.resolve()
    if not same_run:
        raise ExportError(f"{out} already holds a model exported from {before or 'another run'}; this run would replace "
                          f"it: give --out {out} to replace it, or another --out (or --name)")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m raindrop_tools.export", description="Export a run to ONNX.")
    ap.add_argument("--run", required=True, help="run folder (from raindrop_tools.train)")
    ap.add_argument("--out", help="output folder (default: models/<config name>)")
    ap.add_argument("--checkpoint", help="a specific checkpoint file (default: the run's latest)")
    ap.add_argument("--allow-incomplete", action="store_true", help="export before stage 2 has finished")
    ap.add_argument("--threads", type=int, help="torch CPU threads (default: torch's choice)")
    ap.add_argument("--name", help="configuration name recorded in the graphs and the default folder (default: the "
                                   "run's; e.g. a fine-tuned model shipped beside the one it started from)")
    ap.add_argument("--reconstruction-from", metavar="DIR",
                    help="take 3RN and RFN from this exported model folder instead of the run, and the run's "
                         "detector alone (a run that fine-tuned the detector: its stage 1 suffices)")
    ap.add_argument("--threshold", type=float, metavar="T",
                    help="detection threshold recorded in the graphs (default: the run's pipeline.threshold); a "
                         "deployment choice made on validation sets after training, which it does not change")
    args = ap.parse_args(argv)
    if args.threshold is not None and not 0.0 < args.threshold < 1.0:
        print(f"error: --threshold {args.threshold} must be between 0 and 1", file=sys.stderr)
        return 2
    if args.threads:
        torch.set_num_threads(args.threads)
    try:
        cfg, nets, source = load_run(
            Path(args.run), Path(args.checkpoint) if args.checkpoint else None,
            args.allow_incomplete, detector_only=bool(args.reconstruction_from),
        )
        if args.reconstruction_from:
            source = take_reconstruction(nets, Path(args.reconstruction_from), source)
        if args.name:
            if not is_safe_name(args.name):
                raise ExportError(f"--name {args.name!r} is not a file-name-safe word (letters, digits, '.', '_', '-'; "
                                  "not starting with '.' or '-')")
            cfg = dataclasses.replace(cfg, name=args.name)
        if args.threshold is not None:
            cfg = dataclasses.replace(cfg, pipeline=dataclasses.replace(cfg.pipeline, threshold=args.threshold))
        out = Path(args.out) if args.out else Path("models") / cfg.name
        if out.exists() and not out.is_dir():
            raise ExportError(f"--out {out}: a file, not a folder; a model is a folder of graphs")
        if not args.out:
            _refuse_another_runs_folder(out, source)
        info = export_networks(cfg, nets, out, source)
    except (ExportError, OSError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    g = info["gflops_256x512"]
    print(
        f"exported {cfg.name} to {out}: rdn {g['rdn']:.2f}, rrn {g['rrn']:.2f}, rfn {g['rfn']:.2f} "
        f"GFLOPs at 256x512; max |onnx - torch| {max(info['parity_max_abs_diff'].values()):.2e}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
