"""int8 versions of the three exported graphs: static quantization in QDQ form with
onnxruntime's quantization tools (weights int8 per channel, activations uint8: the U8S8
combination ONNX Runtime's x86 kernels are fastest with).

Activation ranges are calibrated on rendered images: each graph sees the inputs it sees in
the real pipeline (RDN and 3RN the rainy image and its edge map, RFN the blend built by the
fp32 models), so RFN is not calibrated on inputs it never meets.

    python -m raindrop_tools.quantize --models models/compact --data data/train --out models/compact-int8

Imports without torch.
"""

from __future__ import annotations

import argparse
import json
import random
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np
import onnx
from onnxruntime.quantization import CalibrationDataReader, CalibrationMethod, QuantFormat, QuantType, quantize_static
from onnxruntime.quantization.shape_inference import quant_pre_process

from .contract import EXPORT_INFO, FILES as GRAPH_FILES, NETWORKS, graph_files
from .imageio import read_rgb
from .manifest import manifest_lines
from .reference import RaindropRemover
from .staging import staged_model_files



class _Feeds(CalibrationDataReader):
    def __init__(self, feeds: list[dict[str, np.ndarray]]):
        self._it = iter(feeds)

    def get_next(self):
        return next(self._it, None)


def calibration_feeds(models_dir: Path, data_dir: Path, count: int, seed: int) -> dict[str, list[dict]]:
    """Inputs of each graph for `count` rainy images of a rendered data set (manifest order,
    a seeded random subset)."""
    lines = [json.loads(text) for _, _, text in manifest_lines(data_dir)]
    if not lines:
        raise ValueError(f"{data_dir}: empty manifest")
    random.Random(seed).shuffle(lines)
    remover = RaindropRemover(models_dir)
    feeds: dict[str, list[dict]] = {n: [] for n in NETWORKS}
    for rec in lines[:count]:
        rgb = read_rgb(data_dir / rec["rainy"])
        R, E, _ = remover.prepare(rgb)
        M = remover.binary_mask(remover.detect(R), remover.threshold, remover.dilation)
        B = remover.blend(M, remover.reconstruct(R, E), R)
        feeds["rdn"].append({"image": R})
        feeds["rrn"].append({"image": R, "edge": E})
        feeds["rfn"].append({"blend": B})
    return feeds


class QuantizeError(ValueError):
    """A request quantize refuses, reported on one line."""


def quantize_models(models_dir: Path, data_dir: Path, out_dir: Path, count: int = 16, seed: int = 0) -> dict:
    models_dir, data_dir, out_dir = Path(models_dir), Path(data_dir), Path(out_dir)
    # The int8 graphs take the fp32 ones' file names: written into the models' own folder they
    # replaced the fp32 model, with nothing left to quantize or compare against.
    if out_dir.resolve() == models_dir.resolve():
        raise QuantizeError(f"--out {out_dir} is the --models folder: the int8 graphs would replace the fp32 ones; "
                            "choose another folder (e.g. models/<name>-int8)")
    if count < 1:
        raise QuantizeError(f"--count must be at least 1, got {count}")
    feeds = calibration_feeds(models_dir, data_dir, count, seed)
    out_dir.mkdir(parents=True, exist_ok=True)
    info = json.loads((models_dir / EXPORT_INFO).read_text()) if (models_dir / EXPORT_INFO).is_file() else {}
    base_config = info.get("config", models_dir.name)
    # Staged and renamed in (staging.py): an interrupted run leaves the folder's model as it was,
    # and a graph there that is a link (to the fp32 model, say) is replaced, not written through.
    with staged_model_files(out_dir, "quantize") as stage:
        _quantize_into(stage, models_dir, data_dir, count, seed, feeds, info, base_config)
    for extra in ("README.md",):
        if (models_dir / extra).is_file() and not (out_dir / extra).exists():
            shutil.copy(models_dir / extra, out_dir / extra)
    return info


def _quantize_into(out_dir: Path, models_dir: Path, data_dir: Path, count: int, seed: int, feeds: dict, info: dict,
                   base_config: str) -> None:
    """The three int8 graphs and their export.json, written into the (staging) folder out_dir;
    `info` (the fp32 export.json) is updated in place."""
    with tempfile.TemporaryDirectory() as tmp:
        for name in NETWORKS:
            src = models_dir / GRAPH_FILES[name]
            pre = Path(tmp) / f"{name}.pre.onnx"
            quant_pre_process(str(src), str(pre), skip_symbolic_shape=True)
            dst_tmp = Path(tmp) / f"{name}.int8.onnx"
            quantize_static(
                str(pre),
                str(dst_tmp),
                _Feeds(feeds[name]),
                quant_format=QuantFormat.QDQ,
                per_channel=True,
                activation_type=QuantType.QUInt8,
                weight_type=QuantType.QInt8,
                calibrate_method=CalibrationMethod.MinMax,
            )
            # Keep the contract's metadata (names, pad multiple, defaults), marked as int8.
            fp32 = onnx.load(str(src))
            q = onnx.load(str(dst_tmp))
            del q.metadata_props[:]
            for p in fp32.metadata_props:
                value = f"{p.value}-int8" if p.key == "raindrop.config" else p.value
                q.metadata_props.add(key=p.key, value=value)
            q.metadata_props.add(key="raindrop.quantization", value="int8 static QDQ, per-channel weights, uint8 activations")
            onnx.checker.check_model(q)
            onnx.save(q, str(out_dir / GRAPH_FILES[name]))
    info.update(
        {
            "config": f"{base_config}-int8",
            "quantized_from": str(models_dir),
            "quantization": {
                "format": "QDQ",
                "weights": "int8, per channel",
                "activations": "uint8",
                "calibration": f"{count} rendered images from {data_dir} (seed {seed}), min-max",
            },
            # The int8 files' own digests (the fp32 entries and the fp32 export's PyTorch
            # parity figures describe other files).
            "files": graph_files(out_dir),
        }
    )
    info.pop("parity_max_abs_diff", None)
    (out_dir / EXPORT_INFO).write_text(json.dumps(info, indent=2) + "\n")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m raindrop_tools.quantize", description=__doc__.split("\n\n")[0])
    ap.add_argument("--models", required=True, help="folder with rdn.onnx, rrn.onnx, rfn.onnx (fp32)")
    ap.add_argument("--data", required=True, help="rendered data set for calibration (manifest.jsonl)")
    ap.add_argument("--out", required=True, help="output folder for the int8 graphs")
    ap.add_argument("--count", type=int, default=16, help="calibration images")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    try:
        info = quantize_models(Path(args.models), Path(args.data), Path(args.out), args.count, args.seed)
    except (ValueError, OSError) as e:  # QuantizeError, a missing or empty data set, unreadable files
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(json.dumps(info["files"], indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
