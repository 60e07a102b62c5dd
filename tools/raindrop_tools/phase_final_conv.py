"""The networks' last convolution (conv5 of RDN and 3RN) computed on conv4's four phases, before
they are interleaved: the same function, and no full-resolution feature map at all.

After phase_conv.py, conv4's output is four half-resolution phases (24 channels each),
concatenated, interleaved by DepthToSpace into a full-resolution map, passed through ReLU, and
read by conv5 (3x3, pad 1) into 1 (RDN) or 3 (3RN) channels. A 3x3 window at full-resolution
row 2m + p reads rows 2m + p + dy (dy in -1, 0, 1), which are phase (p + dy) mod 2 of half-row
m + floor((p + dy) / 2); so conv5 on the interleaved map equals a 3x3 convolution (pad 1) at half
resolution on the concatenated phases, into 4 x C channels (one set per output phase, DCR order),
then one DepthToSpace. ReLU moves onto each phase (it is elementwise, and interleaving moves
values, not changes them). The zero padding of the full-resolution map's border is the zero
padding of the half-resolution one, so odd sizes (cropped after conv5) agree too. Same products,
summed in another order: outputs agree to float rounding (about 1e-7).

Why: ONNX Runtime's blocked convolutions pad their output channels to 8 or 16, so conv5 at full
resolution computed 16 channels for the RDN's one and was the largest single node of both
networks (10-11 ms of about 105-115 at 512x288 on one thread here), and the full-resolution
interleave, ReLU and layout reorders around it cost as much again (docs/RESULTS.md 3.12).

    python -m raindrop_tools.phase_final_conv --models models/compact-multiscale

rewrites a model folder's float graphs in place (graph_rewrite.py; int8 graphs are left alone).
``export`` writes new graphs this way; ``onnx_weights`` reads conv5 back from either form.
Imports without torch.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import onnx
from onnx import helper, numpy_helper

from . import graph_rewrite
from .phase_conv import PHASES, phase_groups

MAX_ABS_DIFF = 1e-4
CHECK_SIZES = ((37, 53), (64, 96))
# For output phase p and tap dy (-1, 0, 1): the input phase and the half-resolution offset.
_SOURCE = {(p, dy): ((p + dy) % 2, (p + dy) // 2) for p in (0, 1) for dy in (-1, 0, 1)}


class PhaseFinalConvError(graph_rewrite.GraphRewriteError):
    pass


def phase_kernel(w: np.ndarray) -> np.ndarray:
    """conv5's weight (C, K, 3, 3) as the phase-domain weight (4C, 4K, 3, 3): output channel
    (2p + q) C + c, input channel (2a + b) K + k (the phases' DCR order)."""
    c_out, k_in = w.shape[:2]
    v = np.zeros((4 * c_out, 4 * k_in, 3, 3), dtype=w.dtype)
    for p, q in PHASES:
        for dy in (-1, 0, 1):
            a, u = _SOURCE[(p, dy)]
            for dx in (-1, 0, 1):
                b, t = _SOURCE[(q, dx)]
                v[(2 * p + q) * c_out:(2 * p + q + 1) * c_out, (2 * a + b) * k_in:(2 * a + b + 1) * k_in, u + 1, t + 1] += \
                    w[:, :, dy + 1, dx + 1]
    return v


def final_kernel(v: np.ndarray) -> np.ndarray:
    """The inverse of phase_kernel: output phase (0, 0) holds every tap of conv5 once."""
    c_out, k_in = v.shape[0] // 4, v.shape[1] // 4
    w = np.zeros((c_out, k_in, 3, 3), dtype=v.dtype)
    for dy in (-1, 0, 1):
        a, u = _SOURCE[(0, dy)]
        for dx in (-1, 0, 1):
            b, t = _SOURCE[(0, dx)]
            w[:, :, dy + 1, dx + 1] = v[:c_out, (2 * a + b) * k_in:(2 * a + b + 1) * k_in, u + 1, t + 1]
    return w


def fold_final_convs(model: onnx.ModelProto) -> int:
    """Rewrites every split conv4 followed by DepthToSpace -> Relu -> a 3x3 pad-1 Conv in place;
    returns how many. The Conv's output keeps its name. Graphs without that chain (int8 graphs,
    with QuantizeLinear/DequantizeLinear between, and graphs already folded) are left alone."""
    g = model.graph
    weights = {t.name: t for t in g.initializer}
    nodes = {n.name: n for n in g.node}
    count = 0
    for names in phase_groups(model).values():
        consumers = graph_rewrite.consumers(model)
        convs = [nodes[n] for n in names]
        concat = graph_rewrite.only_consumer(consumers, convs[0].output[0], "Concat")
        d2s = concat and graph_rewrite.only_consumer(consumers, concat.output[0], "DepthToSpace")
        relu = d2s and graph_rewrite.only_consumer(consumers, d2s.output[0], "Relu")
        conv5 = relu and graph_rewrite.only_consumer(consumers, relu.output[0], "Conv")
        if conv5 is None:
            continue
        has_bias = len(conv5.input) > 2 and conv5.input[2]
        if conv5.input[1] not in weights or (has_bias and conv5.input[2] not in weights):
            continue
        a = graph_rewrite.attrs(conv5)
        if (list(a.get("kernel_shape", [3, 3])) != [3, 3] or list(a.get("pads", [0, 0, 0, 0])) != [1, 1, 1, 1]
                or list(a.get("strides", [1, 1])) != [1, 1] or list(a.get("dilations", [1, 1])) != [1, 1]
                or a.get("group", 1) != 1):
            continue
        w = numpy_helper.to_array(weights[conv5.input[1]])
        bias = numpy_helper.to_array(weights[conv5.input[2]]) if has_bias else np.zeros(w.shape[0], w.dtype)
        # ReLU on each phase, then the phase-domain convolution and one interleave.
        relus = []
        for c in convs:
            r = helper.make_node("Relu", [c.output[0]], [c.output[0] + ".relu"], name=c.name + ".relu")
            g.node.append(r)
            relus.append(r.output[0])
        concat.input[:] = relus
        v_name, b_name, phases = conv5.input[1] + ".phases", conv5.name + ".phase_bias", conv5.output[0] + ".phases"
        g.initializer.append(numpy_helper.from_array(phase_kernel(w), v_name))
        g.initializer.append(numpy_helper.from_array(np.tile(bias, 4).astype(w.dtype), b_name))
        g.node.append(helper.make_node("Conv", [concat.output[0], v_name, b_name], [phases], name=conv5.name + ".phases",
                                       kernel_shape=[3, 3], pads=[1, 1, 1, 1]))
        g.node.append(helper.make_node("DepthToSpace", [phases], [conv5.output[0]], name=conv5.name + ".interleave",
                                       blocksize=2, mode="DCR"))
        kept = [n for n in g.node if n is not d2s and n is not relu and n is not conv5]
        del g.node[:]
        g.node.extend(kept)
        count += 1
    if count:
        graph_rewrite.prune(model)
        graph_rewrite.topological_sort(model)
    return count


def folded_final_convs(model: onnx.ModelProto) -> set[str]:
    """Names of the phase-domain final convolutions: a Conv on a split conv4's Concat whose
    output only an interleaving DepthToSpace reads."""
    consumers = graph_rewrite.consumers(model)
    nodes = {n.name: n for n in model.graph.node}
    out = set()
    for names in phase_groups(model).values():
        relu = graph_rewrite.only_consumer(consumers, nodes[names[0]].output[0], "Relu")
        concat = relu and graph_rewrite.only_consumer(consumers, relu.output[0], "Concat")
        conv = concat and graph_rewrite.only_consumer(consumers, concat.output[0], "Conv")
        if conv is not None and graph_rewrite.only_consumer(consumers, conv.output[0], "DepthToSpace") is not None:
            out.add(conv.name)
    return out


def rewrite_folder(models_dir: Path) -> dict[str, int]:
    """Rewrites a model folder's graphs in place (graph_rewrite.rewrite_folder), each checked
    against the old one to MAX_ABS_DIFF at even and odd sizes. Returns the count per graph."""
    return graph_rewrite.rewrite_folder(
        models_dir, "phase-final-conv", fold_final_convs, CHECK_SIZES, MAX_ABS_DIFF,
        "conv5 computed on conv4's phases before they are interleaved (phase_final_conv.py)", PhaseFinalConvError)


def main(argv: list[str] | None = None) -> int:
    return graph_rewrite.command("phase_final_conv", __doc__.split("\n\n")[0], rewrite_folder,
                                 "final convolutions folded", argv)


if __name__ == "__main__":
    raise SystemExit(main())
