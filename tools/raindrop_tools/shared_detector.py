"""One detector graph, two maps: a router's alternative detector as a head on the main detector.

The default's router (include/raindrop/remove/detector_router.h) sends most photographs to a
second detector, which used to be a whole second network: on a routed 1280x720 photograph a
third of the program's time. Here the second detector is an ``AlternativeHead`` (networks.py) on
the main RDN's own layers, trained to give the old alternative's map (train_head.py), and this
tool writes it out in two forms:

* the main folder's ``rdn.onnx`` gets a second output, ``alternative_mask_prob``: the head's
  nodes appended to the main graph, which is otherwise kept node for node (so its ``mask_prob``
  keeps its bits), and the metadata ``raindrop.alternative_detector`` naming the head's folder;
* the head's own folder (``--out``) gets the same nodes as a standalone detector: the main
  graph with the head's map as ``mask_prob``, so that ``--model-config <out>`` and a routed image
  give the same mask. Its 3RN and RFN and its pipeline metadata (threshold, dilation, growth,
  fill area) are copied from ``--like``, the detector the head was trained to reproduce.

Both are checked with ONNX Runtime before anything is replaced: the main graph's first output
bit for bit as before, the second bit for bit the standalone graph's output, and both against
PyTorch to 1e-4. raindrop-remove reads the second output only where the folder's ROUTER names
``--out``'s folder as its alternative (model.h, kAlternativeOutput).

    python -m raindrop_tools.shared_detector --main models/compact-multiscale \\
        --head tools/runs/compact-windshield-head/head.pt --like models/compact-windshield \\
        --out models/compact-windshield-head
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import hashlib
import io
import json
import logging
import shutil
import sys
import warnings
from pathlib import Path

import numpy as np
import onnx
import torch
from onnx import helper

from . import contract as C
from . import graph_rewrite
from .config import HalfResConfig
from .export import OPSET, _strip_debug_info
from .flops import count_macs, parameter_count
from .networks import RDN, AlternativeHead, rdn_taps
from .onnx_weights import MAX_ABS_DIFF as LOAD_MAX_ABS_DIFF
from .onnx_weights import OnnxWeightsError, _graph_convs, load_network
from .phase_conv import phase_groups, split_transposed_convs
from .phase_final_conv import fold_final_convs
from .read_only import refuse_read_only
from .staging import staged_model_files

MAX_ABS_DIFF = 1e-4
CHECK_SIZES = ((37, 53), (64, 96), (288, 512))


class SharedDetectorError(RuntimeError):
    pass


def rdn_config(folder: Path) -> HalfResConfig:
    """The RDN's shape from the folder's export.json (network.rdn)."""
    info = json.loads((Path(folder) / C.EXPORT_INFO).read_text())
    r = info["network"]["rdn"]
    return HalfResConfig(width=int(r["width"]), expanded=int(r["expanded"]), blocks=int(r["blocks"]))


def load_rdn(folder: Path) -> RDN:
    """The folder's detector as a frozen PyTorch RDN (eval mode: exactly the graph's function)."""
    net = RDN(rdn_config(folder))
    load_network(net, "rdn", Path(folder) / C.FILES["rdn"])
    net.eval()
    for p in net.parameters():
        p.requires_grad_(False)
    return net


def load_head(folder: Path) -> AlternativeHead:
    """The second detector's head that this script spliced into ``folder``'s rdn.onnx beside the
    RDN's own map (the default's folder, whose router uses it), as a PyTorch AlternativeHead, so that
    a committed model can start a head's fine-tune (train_head's ``init``) without the run that
    made it. Its widths come from the graph; checked against ONNX Runtime before returning."""
    import onnxruntime as ort

    path = Path(folder) / C.FILES["rdn"]
    model = onnx.load(str(path))
    if C.ALTERNATIVE_OUTPUT not in [o.name for o in model.graph.output]:
        raise SharedDetectorError(f"{path}: no {C.ALTERNATIVE_OUTPUT} output: give the folder whose detector carries the "
                                  "head beside its own map (the default's, e.g. models/compact-multiscale)")
    try:
        convs = _graph_convs(model, head_only=True)
    except OnnxWeightsError as e:
        raise SharedDetectorError(f"{path}: {e}") from None
    ops = [op for op, _, _ in convs]
    if ops != ["Conv", "Conv", "ConvTranspose", "Conv"]:
        raise SharedDetectorError(f"{path}: the head's convolutions are {ops}, not an AlternativeHead's")
    rc = rdn_config(Path(folder))
    mix, up = convs[0][1], convs[2][1]
    if mix.shape[1] != rc.width + rc.expanded:
        raise SharedDetectorError(f"{path}: the head reads {mix.shape[1]} channels, its RDN gives {rc.width + rc.expanded}")
    head = AlternativeHead(rc.width, rc.expanded, mid=mix.shape[0], up=up.shape[1])
    with torch.no_grad():
        for conv, (_, w, b) in zip((head.mix, head.conv, head.up, head.out), convs):
            if tuple(w.shape) != tuple(conv.weight.shape) or b is None:
                raise SharedDetectorError(f"{path}: a head convolution of shape {list(w.shape)} does not fit {list(conv.weight.shape)}")
            conv.weight.copy_(torch.from_numpy(w.copy()))
            conv.bias.copy_(torch.from_numpy(b.copy()))
    head.eval()
    # The graph's head map against PyTorch's: the folder's RDN read from the same graph, the
    # head on its taps.
    rdn = load_rdn(Path(folder))
    sess = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    x = torch.rand(1, 3, 48, 64, generator=torch.Generator().manual_seed(1))
    (theirs,) = sess.run([C.ALTERNATIVE_OUTPUT], {"image": x.numpy()})
    with torch.no_grad():
        ours = torch.sigmoid(head(*rdn_taps(rdn, x))).numpy()
    diff = float(np.abs(ours - theirs).max())
    if not diff <= LOAD_MAX_ABS_DIFF:
        raise SharedDetectorError(f"{path}: the head read back differs from the graph by {diff:.3g} (> {LOAD_MAX_ABS_DIFF})")
    return head


def find_taps(model: onnx.ModelProto) -> tuple[str, str, str]:
    """The main graph's tensors that ``rdn_taps`` names: conv2's output after its ReLU, the
    blocks' output (what conv4's phase convolutions read) and the logits (the final Sigmoid's
    input)."""
    g = model.graph
    producer = {o: n for n in g.node for o in n.output}
    consumers = graph_rewrite.consumers(model)
    convs = [n for n in g.node if n.op_type == "Conv"]
    if len(convs) < 2:
        raise SharedDetectorError("the main graph has fewer than two convolutions: not an RDN")
    relu = graph_rewrite.only_consumer(consumers, convs[1].output[0], "Relu")
    groups = list(phase_groups(model).values())
    sigmoid = producer.get(C.OUTPUTS["rdn"])
    if relu is None or len(groups) != 1 or sigmoid is None or sigmoid.op_type != "Sigmoid":
        raise SharedDetectorError("the main graph is not an exported RDN (conv2 -> Relu, one split conv4, a final Sigmoid)")
    conv4 = {n.name: n for n in g.node}[groups[0][0]]
    return relu.output[0], conv4.input[0], sigmoid.input[0]


def export_head(head: AlternativeHead, width: int, expanded: int) -> onnx.ModelProto:
    """The head alone as a graph: inputs f2, f4, logits; output logits (the corrected ones), with
    its transposed convolution split into phases and its last convolution folded onto them, as
    the exporter does for the networks (phase_conv.py, phase_final_conv.py)."""
    head = head.eval()
    g = torch.Generator().manual_seed(0)
    inputs = (torch.rand(2, width, 19, 27, generator=g), torch.rand(2, expanded, 19, 27, generator=g),
              torch.randn(2, 1, 37, 53, generator=g))
    N, h, w = torch.export.Dim("N", min=1), torch.export.Dim("h", min=1), torch.export.Dim("w", min=1)
    H, W = torch.export.Dim("H", min=1), torch.export.Dim("W", min=1)
    logging.getLogger("torch.onnx").setLevel(logging.ERROR)
    with warnings.catch_warnings(), torch.no_grad(), contextlib.redirect_stdout(io.StringIO()):
        warnings.simplefilter("ignore")
        program = torch.onnx.export(head, inputs, None, input_names=["f2", "f4", "logits"], output_names=["head_logits"],
                                     opset_version=OPSET, dynamic_shapes=({0: N, 2: h, 3: w}, {0: N, 2: h, 3: w}, {0: N, 2: H, 3: W}),
                                     dynamo=True, external_data=False, verbose=False)
    model = program.model_proto
    _strip_debug_info(model)
    for value in [*model.graph.input, *model.graph.output]:
        del value.metadata_props[:]
    if split_transposed_convs(model) != 1 or fold_final_convs(model) != 1:
        raise SharedDetectorError("the head's graph did not take the phase rewrites (one transposed convolution, one final conv)")
    return model


def splice(main: onnx.ModelProto, head: onnx.ModelProto, alternative: str) -> onnx.ModelProto:
    """The main graph with the head's nodes appended, reading the main graph's taps, and a second
    output ``alternative_mask_prob`` (the head's logits through a Sigmoid). The main graph's nodes,
    initializers and first output are kept as they are."""
    f2, f4, logits = find_taps(main)
    merged = copy.deepcopy(main)
    outer = {"f2": f2, "f4": f4, "logits": logits}
    names = {t.name for t in merged.graph.initializer} | {o for n in merged.graph.node for o in n.output}

    def rename(name: str) -> str:
        if not name:
            return name
        if name in outer:
            return outer[name]
        new = C.HEAD_NODE_PREFIX + name
        if new in names:
            raise SharedDetectorError(f"the main graph already has a tensor named {new!r}")
        return new

    for t in head.graph.initializer:
        t2 = copy.deepcopy(t)
        t2.name = rename(t.name)
        merged.graph.initializer.append(t2)
    for n in head.graph.node:
        n2 = copy.deepcopy(n)
        n2.input[:] = [rename(x) for x in n.input]
        n2.output[:] = [rename(x) for x in n.output]
        n2.name = C.HEAD_NODE_PREFIX + (n.name or n.output[0])
        merged.graph.node.append(n2)
    head_out = rename(head.graph.output[0].name)
    merged.graph.node.append(
        helper.make_node("Sigmoid", [head_out], [C.ALTERNATIVE_OUTPUT], name=C.HEAD_NODE_PREFIX + "sigmoid"))
    out = copy.deepcopy(merged.graph.output[0])
    out.name = C.ALTERNATIVE_OUTPUT
    merged.graph.output.append(out)
    props = {p.key: p.value for p in main.metadata_props}
    props[C.META_ALTERNATIVE_DETECTOR] = alternative
    del merged.metadata_props[:]
    helper.set_model_props(merged, props)
    onnx.checker.check_model(merged, full_check=True)
    return merged


def strip_head(merged: onnx.ModelProto) -> onnx.ModelProto:
    """A merged graph without its head: what ``splice`` was given (the head's nodes and
    initializers, all named with HEAD_NODE_PREFIX, its second output and the metadata naming it
    taken out), so that a fine-tuned head can replace the one a committed graph carries."""
    model = copy.deepcopy(merged)
    g = model.graph
    kept = [n for n in g.node if not n.name.startswith(C.HEAD_NODE_PREFIX)]
    del g.node[:]
    g.node.extend(kept)
    inits = [t for t in g.initializer if not t.name.startswith(C.HEAD_NODE_PREFIX)]
    del g.initializer[:]
    g.initializer.extend(inits)
    outputs = [o for o in g.output if o.name != C.ALTERNATIVE_OUTPUT]
    del g.output[:]
    g.output.extend(outputs)
    props = {p.key: p.value for p in merged.metadata_props if p.key != C.META_ALTERNATIVE_DETECTOR}
    del model.metadata_props[:]
    helper.set_model_props(model, props)
    onnx.checker.check_model(model, full_check=True)
    return model


def standalone(merged: onnx.ModelProto, metadata: dict[str, str]) -> onnx.ModelProto:
    """The merged graph as the head's own detector: its second output renamed ``mask_prob``, the
    main detector's Sigmoid and first output gone, ``metadata`` as the graph's."""
    model = copy.deepcopy(merged)
    g = model.graph
    kept = [n for n in g.node if C.OUTPUTS["rdn"] not in n.output]
    del g.node[:]
    g.node.extend(kept)
    for n in g.node:
        n.output[:] = [C.OUTPUTS["rdn"] if o == C.ALTERNATIVE_OUTPUT else o for o in n.output]
    first = copy.deepcopy(g.output[0])
    del g.output[:]
    g.output.append(first)
    graph_rewrite.prune(model)
    del model.metadata_props[:]
    helper.set_model_props(model, {k: v for k, v in metadata.items() if k != C.META_ALTERNATIVE_DETECTOR})
    onnx.checker.check_model(model, full_check=True)
    return model


def check(main: onnx.ModelProto, merged: onnx.ModelProto, alone: onnx.ModelProto, rdn: RDN, head: AlternativeHead,
          threads: int = 1) -> dict[str, float]:
    """ONNX Runtime on random images: the merged graph's first output bit for bit the main
    graph's, its second bit for bit the standalone graph's, and that against PyTorch (1e-4)."""
    import onnxruntime as ort

    so = ort.SessionOptions()
    so.intra_op_num_threads = threads
    run = {k: ort.InferenceSession(m.SerializeToString(), so, providers=["CPUExecutionProvider"])
           for k, m in (("main", main), ("merged", merged), ("alone", alone))}
    worst = 0.0
    gen = torch.Generator().manual_seed(1)
    for h, w in CHECK_SIZES:
        x = torch.rand(1, 3, h, w, generator=gen)
        feed = {"image": x.numpy()}
        (p_main,) = run["main"].run(None, feed)
        p0, p1 = run["merged"].run(None, feed)
        (p_alone,) = run["alone"].run(None, feed)
        if not np.array_equal(p0, p_main):
            raise SharedDetectorError(f"at {w}x{h} the merged graph's {C.OUTPUTS['rdn']} differs from the main graph's "
                                      f"(max {np.abs(p0 - p_main).max():.3g})")
        if not np.array_equal(p1, p_alone):
            raise SharedDetectorError(f"at {w}x{h} the merged graph's {C.ALTERNATIVE_OUTPUT} differs from the standalone "
                                      f"graph's (max {np.abs(p1 - p_alone).max():.3g})")
        with torch.no_grad():
            want = torch.sigmoid(head(*rdn_taps(rdn, x))).numpy()
        if not (np.isfinite(p1).all() and np.isfinite(want).all()):
            raise SharedDetectorError("the head's outputs are not finite (NaN or Inf weights?)")
        worst = max(worst, float(np.abs(p1 - want).max()))
    if worst > MAX_ABS_DIFF:
        raise SharedDetectorError(f"the head's graph differs from PyTorch by {worst:.3g} (> {MAX_ABS_DIFF})")
    return {"parity_max_abs_diff": worst}


def head_gflops(cfg: HalfResConfig, head: AlternativeHead, h: int = 256, w: int = 512) -> float:
    """GFLOPs (2 x MACs, flops.py's count) of the head at h x w: its share of a routed image's
    detection."""
    hh, hw = (h + 1) // 2, (w + 1) // 2
    taps = (torch.zeros(1, cfg.width, hh, hw), torch.zeros(1, cfg.expanded, hh, hw), torch.zeros(1, 1, h, w))
    return 2 * count_macs(head, taps) / 1e9


def write(main_dir: Path, like_dir: Path, out_dir: Path, head_path: Path, replace: bool = False) -> dict:
    """Builds, checks and writes both graphs (nothing is replaced unless every check passes).
    ``replace``: a main graph with a head already has it taken out first (strip_head)."""
    main_dir, like_dir, out_dir = Path(main_dir), Path(like_dir), Path(out_dir)
    # A read-only file is kept (read_only.py): refused before any work.
    refuse_read_only(main_dir / C.FILES["rdn"], main_dir / C.EXPORT_INFO, out_dir / C.EXPORT_INFO, out_dir / "LARGE_DROPS",
                     *(out_dir / C.FILES[n] for n in C.NETWORKS), follow_links=False)
    cfg = rdn_config(main_dir)
    rdn = load_rdn(main_dir)
    try:
        state = torch.load(head_path, map_location="cpu", weights_only=True)
    except Exception as e:  # pickle, zip and torch's own errors: not a head file either way
        raise SharedDetectorError(f"--head {head_path}: not a readable head file "
                                  f"({str(e).splitlines()[0] if str(e) else type(e).__name__})") from None
    if not isinstance(state, dict) or any(not (isinstance(state.get(k), torch.Tensor) and state[k].ndim == 4)
                                          for k in ("mix.weight", "up.weight")):
        raise SharedDetectorError(f"--head {head_path}: not a head (train_head's head.pt): no 4-D mix.weight and up.weight; "
                                  "a train run's checkpoint is not one")
    head = AlternativeHead(cfg.width, cfg.expanded, mid=state["mix.weight"].shape[0], up=state["up.weight"].shape[1])
    try:
        head.load_state_dict(state)
    except RuntimeError as e:  # a head trained on another configuration's detector (its widths)
        raise SharedDetectorError(f"--head {head_path}: not a head for {main_dir}'s detector (width {cfg.width}, "
                                  f"expanded {cfg.expanded}): {str(e).splitlines()[-1].strip()}") from None
    head.eval()
    main_file = main_dir / C.FILES["rdn"]
    main = onnx.load(str(main_file))
    if any(o.name == C.ALTERNATIVE_OUTPUT for o in main.graph.output):
        if not replace:
            raise SharedDetectorError(f"{main_file} has a head already: --replace takes it out first (or take the "
                                      "graph without it from git)")
        # check() then holds the new graph's first output bit for bit to the graph without the old head.
        main = strip_head(main)
    merged = splice(main, export_head(head, cfg.width, cfg.expanded), out_dir.name)
    like = {p.key: p.value for p in onnx.load(str(like_dir / C.FILES["rdn"])).metadata_props}
    like[C.META_CONFIG] = out_dir.name
    alone = standalone(merged, like)
    report = check(main, merged, alone, rdn, head)
    report.update(head_gflops_256x512=head_gflops(cfg, head), head_params=parameter_count(head))

    out_dir.mkdir(parents=True, exist_ok=True)
    like_info = json.loads((like_dir / C.EXPORT_INFO).read_text())
    checkpoint_sha256 = hashlib.sha256(Path(head_path).read_bytes()).hexdigest()
    out_dir.mkdir(parents=True, exist_ok=True)
    # Each folder's graphs and export.json replaced whole or not at all (staging.py); the main
    # folder's export.json after its rdn.onnx, with every graph's digest, as detector_metadata does.
    with staged_model_files(out_dir, "shared-detector") as stage:
        for name in ("rrn", "rfn"):
            m = onnx.load(str(like_dir / C.FILES[name]))
            props = {p.key: p.value for p in m.metadata_props}
            props[C.META_CONFIG] = out_dir.name
            del m.metadata_props[:]
            helper.set_model_props(m, props)
            onnx.save(m, str(stage / C.FILES[name]))
        onnx.save(alone, str(stage / C.FILES["rdn"]))
        info = {
            "config": out_dir.name,
            "made_by": "python -m raindrop_tools.shared_detector",
            "detector": f"{main_dir.name}'s RDN with an AlternativeHead (tools/raindrop_tools/networks.py) trained to "
                        f"give {like_dir.name}'s map; its 3RN and RFN are {like_dir.name}'s",
            "head": {"checkpoint_sha256": checkpoint_sha256, **report},
            "network": {**like_info["network"],
                        "rdn_head": {"on": main_dir.name, "mid": head.mix.out_channels, "up": head.up.out_channels}},
            "pipeline": like_info.get("pipeline", {}),
            "files": dict(sorted(C.graph_files(stage).items())),
        }
        (stage / C.EXPORT_INFO).write_text(json.dumps(info, indent=2) + "\n")
    if (like_dir / "LARGE_DROPS").exists():
        shutil.copyfile(like_dir / "LARGE_DROPS", out_dir / "LARGE_DROPS")
    with staged_model_files(main_dir, "shared-detector") as stage:
        onnx.save(merged, str(stage / C.FILES["rdn"]))
    main_info = json.loads((main_dir / C.EXPORT_INFO).read_text())
    main_info["files"] = C.graph_files(main_dir)
    main_info["alternative_head"] = {"folder": out_dir.name, "checkpoint_sha256": checkpoint_sha256}
    with staged_model_files(main_dir, "shared-detector") as stage:
        (stage / C.EXPORT_INFO).write_text(json.dumps(main_info, indent=2) + "\n")
    return report


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m raindrop_tools.shared_detector", description=__doc__.split("\n\n")[0])
    ap.add_argument("--main", type=Path, required=True, help="the main model folder (its rdn.onnx gets the second output)")
    ap.add_argument("--head", type=Path, required=True, help="the head's weights (train_head.py's head.pt)")
    ap.add_argument("--like", type=Path, required=True, help="the detector the head reproduces: its pipeline metadata, 3RN and RFN")
    ap.add_argument("--out", type=Path, required=True, help="the head's own model folder")
    ap.add_argument("--replace", action="store_true",
                    help="the main graph carries a head already (a fine-tuned head's predecessor): take it out first")
    args = ap.parse_args(argv)
    try:
        report = write(args.main, args.like, args.out, args.head, replace=args.replace)
    except (SharedDetectorError, OSError, KeyError) as e:  # ReadOnlyFileError is an OSError
        print(f"error: {e}", file=sys.stderr)
        return 1
    print(f"{args.main}/rdn.onnx: second output {C.ALTERNATIVE_OUTPUT} ({args.out.name}); {args.out}: its own detector; "
          f"head {report['head_gflops_256x512']:.2f} GFLOP at 256x512, {report['head_params']} parameters, "
          f"max |ONNX - PyTorch| {report['parity_max_abs_diff']:.2g}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
