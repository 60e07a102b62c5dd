"""int8 versions of the three exported graphs: static quantization in QDQ form with
onnxruntime's quantization tools (weights int8 per channel, activations uint8: the U8S8
combination ONNX Runtime's x86 kernels are fastest with).

Activation ranges are calibrated on rendered images: each graph sees the inputs it sees in
the real pipeline (RDN and 3RN the rainy image and its edge map, RFN the blend built by the
fp32 models), so RFN is not calibrated on inputs it never meets.

A detector with a router's alternative head (shared_detector.py: a second output
``alternative_mask_prob``) is quantized head and all, and its metadata then names the head
folder's int8 copy (``<head folder>-int8``), made by quantizing the head's own folder with the
same data: the two int8 maps are then the same bits (min-max ranges depend only on the tensors
and the calibration images, which both graphs share), as they are in fp32. That folder
reconstructs with the main folder's networks, so it takes the main int8 folder's 3RN and RFN
(``--reuse-reconstruction models/<main>-int8``) instead of quantizing its own:

    python -m raindrop_tools.quantize --models models/compact-windshield-head --data data/train \
        --out models/compact-windshield-head-int8 --reuse-reconstruction models/compact-multiscale-int8

    python -m raindrop_tools.quantize --models models/compact --data data/train --out models/compact-int8

``--keep-float rfn`` leaves a network in float32 (its graph copied, under the int8 folder's
configuration name): the default's int8 RFN cost 0.2-0.3 dB on sparse rendered drops for no
measurable time (docs/RESULTS.md 4.60), so its int8 copy keeps the RFN in float:

    python -m raindrop_tools.quantize --models models/compact-multiscale --data data/train \
        --out models/compact-multiscale-int8 --keep-float rfn

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

from .contract import EXPORT_INFO, FILES as GRAPH_FILES, META_ALTERNATIVE_DETECTOR, META_CONFIG, NETWORKS, graph_files
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


def alternative_head_folder(out_dir: Path) -> Path | None:
    """The sibling folder an int8 detector's head map belongs to (its metadata), or None."""
    meta = {p.key: p.value for p in onnx.load(str(Path(out_dir) / GRAPH_FILES["rdn"])).metadata_props}
    name = meta.get(META_ALTERNATIVE_DETECTOR)
    return None if name is None else Path(out_dir).parent / name


class QuantizeError(ValueError):
    """A request quantize refuses, reported on one line."""


def same_weights(a: Path, b: Path) -> bool:
    """Whether two fp32 graphs have the same initializers, bit for bit (names and values)."""
    wa, wb = ({t.name: t.SerializeToString() for t in onnx.load(str(p)).graph.initializer} for p in (a, b))
    return wa == wb


def reused_reconstruction(models_dir: Path, reuse_dir: Path) -> dict[str, onnx.ModelProto]:
    """The int8 3RN and RFN of ``reuse_dir`` for ``models_dir``: allowed where the fp32 folder
    ``reuse_dir`` was quantized from (its export.json) has the same 3RN and RFN weights as
    ``models_dir``. A router's head folder reconstructs with its main folder's networks, so its
    int8 copy takes the main int8 folder's graphs: quantized on their own, their calibration
    would see the head's masks and round differently (up to 3 levels in a routed image)."""
    info = json.loads((Path(reuse_dir) / EXPORT_INFO).read_text())
    source = info.get("quantized_from")
    if source is None:
        raise QuantizeError(f"--reuse-reconstruction {reuse_dir}: its export.json says no 'quantized_from'")
    source = Path(source)
    if not source.is_absolute() and not source.is_dir():  # written relative to the repository root
        source = Path(reuse_dir).resolve().parent.parent / source
    graphs = {}
    for name in ("rrn", "rfn"):
        if not same_weights(models_dir / GRAPH_FILES[name], source / GRAPH_FILES[name]):
            raise QuantizeError(f"--reuse-reconstruction {reuse_dir}: {source}/{GRAPH_FILES[name]}, which it was quantized "
                                f"from, has other weights than {models_dir}/{GRAPH_FILES[name]}")
        graphs[name] = onnx.load(str(Path(reuse_dir) / GRAPH_FILES[name]))
    return graphs


def quantize_models(models_dir: Path, data_dir: Path, out_dir: Path, count: int = 16, seed: int = 0,
                    reuse_dir: Path | None = None, keep_float: tuple[str, ...] = ()) -> dict:
    models_dir, data_dir, out_dir = Path(models_dir), Path(data_dir), Path(out_dir)
    # The int8 graphs take the fp32 ones' file names: written into the models' own folder they
    # replaced the fp32 model, with nothing left to quantize or compare against.
    if out_dir.resolve() == models_dir.resolve():
        raise QuantizeError(f"--out {out_dir} is the --models folder: the int8 graphs would replace the fp32 ones; "
                            "choose another folder (e.g. models/<name>-int8)")
    if count < 1:
        raise QuantizeError(f"--count must be at least 1, got {count}")
    keep_float = tuple(keep_float)
    if any(n not in NETWORKS for n in keep_float):
        raise QuantizeError(f"--keep-float takes {', '.join(NETWORKS)}, got {', '.join(keep_float)}")
    reused = reused_reconstruction(models_dir, Path(reuse_dir)) if reuse_dir is not None else {}
    for name in keep_float:
        if name in reused and is_quantized(reused[name]):
            raise QuantizeError(f"--keep-float {name}: --reuse-reconstruction {reuse_dir} gives an int8 {GRAPH_FILES[name]}")
    feeds = calibration_feeds(models_dir, data_dir, count, seed)
    out_dir.mkdir(parents=True, exist_ok=True)
    info = json.loads((models_dir / EXPORT_INFO).read_text()) if (models_dir / EXPORT_INFO).is_file() else {}
    base_config = info.get("config", models_dir.name)
    # Staged and renamed in (staging.py): an interrupted run leaves the folder's model as it was,
    # and a graph there that is a link (to the fp32 model, say) is replaced, not written through.
    with staged_model_files(out_dir, "quantize") as stage:
        _quantize_into(stage, models_dir, data_dir, count, seed, feeds, info, base_config, reused, reuse_dir, keep_float)
    for extra in ("README.md",):
        if (models_dir / extra).is_file() and not (out_dir / extra).exists():
            shutil.copy(models_dir / extra, out_dir / extra)
    return info


META_QUANTIZATION = "raindrop.quantization"
KEPT_FLOAT = "none: kept in float32"


def is_quantized(graph: onnx.ModelProto) -> bool:
    """Whether a graph holds quantized operators (QDQ pairs), i.e. is not a float graph."""
    return any(n.op_type in ("QuantizeLinear", "DequantizeLinear") for n in graph.graph.node)


def _set_int8_metadata(q: onnx.ModelProto, fp32: onnx.ModelProto) -> None:
    """The fp32 graph's contract metadata (names, pad multiple, defaults) on the int8 folder's
    graph, marked as int8 (or as kept in float, for a graph without quantized operators); a
    head's map is the int8 head's, so its folder is named as the int8 copy's."""
    del q.metadata_props[:]
    for p in fp32.metadata_props:
        if p.key == META_QUANTIZATION:
            continue
        value = f"{p.value}-int8" if p.key in (META_CONFIG, META_ALTERNATIVE_DETECTOR) else p.value
        q.metadata_props.add(key=p.key, value=value)
    q.metadata_props.add(key=META_QUANTIZATION,
                         value="int8 static QDQ, per-channel weights, uint8 activations" if is_quantized(q) else KEPT_FLOAT)


def _quantize_into(out_dir: Path, models_dir: Path, data_dir: Path, count: int, seed: int, feeds: dict, info: dict,
                   base_config: str, reused: dict[str, onnx.ModelProto], reuse_dir: Path | None,
                   keep_float: tuple[str, ...] = ()) -> None:
    """The three int8 graphs and their export.json, written into the (staging) folder out_dir;
    `info` (the fp32 export.json) is updated in place. Graphs in `reused` are taken as they are,
    under this folder's configuration name; those in `keep_float` are the fp32 graphs, likewise."""
    # What stays float: the graphs asked for, and a reused folder's float graphs.
    kept = set(keep_float) | {n for n, q in reused.items() if not is_quantized(q)}
    with tempfile.TemporaryDirectory() as tmp:
        for name, q in reused.items():
            _set_int8_metadata(q, onnx.load(str(models_dir / GRAPH_FILES[name])))
            onnx.save(q, str(out_dir / GRAPH_FILES[name]))
        for name in keep_float:
            if name in reused:
                continue
            fp32 = onnx.load(str(models_dir / GRAPH_FILES[name]))
            graph = onnx.ModelProto()
            graph.CopyFrom(fp32)
            _set_int8_metadata(graph, fp32)
            onnx.save(graph, str(out_dir / GRAPH_FILES[name]))
        for name in NETWORKS:
            if name in reused or name in keep_float:
                continue
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
            q = onnx.load(str(dst_tmp))
            _set_int8_metadata(q, onnx.load(str(src)))
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
                **({"reconstruction": f"{', '.join(GRAPH_FILES[n] for n in reused)} taken from {reuse_dir}"}
                   if reused else {}),
                **({"kept_float": [GRAPH_FILES[n] for n in NETWORKS if n in kept]} if kept else {}),
            },
            # The int8 files' own digests (the fp32 entries and the fp32 export's PyTorch
            # parity figures describe other files).
            "files": graph_files(out_dir),
        }
    )
    info.pop("parity_max_abs_diff", None)
    if "alternative_head" in info:  # shared_detector.py's record: the head map is now the int8 folder's
        info["alternative_head"] = {**info["alternative_head"], "folder": f"{info['alternative_head']['folder']}-int8"}
    (out_dir / EXPORT_INFO).write_text(json.dumps(info, indent=2) + "\n")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m raindrop_tools.quantize", description=__doc__.split("\n\n")[0])
    ap.add_argument("--models", required=True, help="folder with rdn.onnx, rrn.onnx, rfn.onnx (fp32)")
    ap.add_argument("--data", required=True, help="rendered data set for calibration (manifest.jsonl)")
    ap.add_argument("--out", required=True, help="output folder for the int8 graphs")
    ap.add_argument("--count", type=int, default=16, help="calibration images")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--reuse-reconstruction", type=Path, default=None, metavar="DIR",
                    help="take the int8 3RN and RFN of DIR (quantized from fp32 graphs with the same weights), e.g. a "
                         "router head's folder from its main folder's int8 copy")
    ap.add_argument("--keep-float", action="append", default=[], choices=list(NETWORKS), metavar="NET",
                    help=f"leave network NET ({', '.join(NETWORKS)}) in float32; repeatable")
    args = ap.parse_args(argv)
    try:
        info = quantize_models(Path(args.models), Path(args.data), Path(args.out), args.count, args.seed,
                               args.reuse_reconstruction, tuple(args.keep_float))
    except (ValueError, OSError) as e:  # QuantizeError, a missing or empty data set, unreadable files
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(json.dumps(info["files"], indent=2))
    head = alternative_head_folder(Path(args.out))
    if head is not None and not head.is_dir():
        print(f"note: {Path(args.out) / GRAPH_FILES['rdn']} computes the map of {head.name}, which does not exist yet: "
              f"quantize the head's folder into it (--models <the fp32 head's folder> --out {head})", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
