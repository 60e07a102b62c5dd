"""The networks' 4x4 stride-2 transposed convolution (conv4 of RDN and 3RN) as four 2x2
convolutions, one per output phase, interleaved by DepthToSpace: the same function, a faster graph.

Output pixel (2m + a, 2n + b) of ``ConvTranspose(k=4, stride=2, pad=1)`` sums the input's 2x2
window at rows (m - 1 + a, m + a) and columns (n - 1 + b, n + b) against kernel taps TAPS[a] x
TAPS[b]; so phase (a, b) is a 2x2 convolution with pads (top 1 - a, left 1 - b, bottom a, right
b), and DepthToSpace (DCR, block 2) puts the four phases, concatenated in the order (0,0),
(0,1), (1,0), (1,1), back in place. Same sums, summed in another order: outputs agree to float
rounding (about 1e-6).

Why: ONNX Runtime runs the transposed convolution as a matrix product and a scatter, and its
int8 quantizer leaves it in float; it was 40% of the float RDN's time and 50% of the int8 one's
(docs/RESULTS.md 3.6). As four ordinary convolutions it runs on the blocked convolution kernels
(and, quantized, on the int8 ones).

    python -m raindrop_tools.phase_conv --models models/compact-multiscale

rewrites a model folder's graphs in place (checked against the old graphs with ONNX Runtime
first, export.json's digests updated). ``export`` writes new graphs this way already, and
``onnx_weights`` reads both forms back. Imports without torch.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import onnx
from onnx import helper, numpy_helper

from . import graph_rewrite

# Kernel taps that phase 0 / phase 1 of an axis uses, in the order of its two input positions.
TAPS = {0: (3, 1), 1: (2, 0)}
PHASES = ((0, 0), (0, 1), (1, 0), (1, 1))
# Largest |old graph - new graph| accepted by the folder rewrite (float32 rounding).
MAX_ABS_DIFF = 1e-4


class PhaseConvError(graph_rewrite.GraphRewriteError):
    pass


def _splittable(node: onnx.NodeProto, weights: dict) -> bool:
    a = graph_rewrite.attrs(node)
    return (
        node.op_type == "ConvTranspose"
        and node.input[1] in weights
        and weights[node.input[1]].ndim == 4
        and weights[node.input[1]].shape[2:] == (4, 4)
        and list(a.get("strides", [1, 1])) == [2, 2]
        and list(a.get("pads", [0, 0, 0, 0])) == [1, 1, 1, 1]
        and list(a.get("dilations", [1, 1])) == [1, 1]
        and list(a.get("output_padding", [0, 0])) == [0, 0]
        and a.get("group", 1) == 1
        and not a.get("output_shape")
        and a.get("auto_pad", b"NOTSET") in (b"NOTSET", "NOTSET")
    )


def phase_kernels(w: np.ndarray) -> list[np.ndarray]:
    """A ConvTranspose weight (Cin, Cout, 4, 4) as the four phases' Conv weights (Cout, Cin, 2, 2)."""
    return [np.ascontiguousarray(w[:, :, list(TAPS[a]), :][:, :, :, list(TAPS[b])].transpose(1, 0, 2, 3)) for a, b in PHASES]


def transposed_kernel(kernels: list[np.ndarray]) -> np.ndarray:
    """The inverse of phase_kernels: four (Cout, Cin, 2, 2) weights -> (Cin, Cout, 4, 4)."""
    cout, cin = kernels[0].shape[:2]
    w = np.zeros((cin, cout, 4, 4), dtype=kernels[0].dtype)
    for k, (a, b) in zip(kernels, PHASES):
        for i in range(2):
            for j in range(2):
                w[:, :, TAPS[a][i], TAPS[b][j]] = k[:, :, i, j].T
    return w


def split_transposed_convs(model: onnx.ModelProto) -> int:
    """Rewrites every 4x4 stride-2 pad-1 ConvTranspose with a stored weight in place; returns
    how many. The outputs keep their names, so the rest of the graph is untouched."""
    g = model.graph
    weights = {t.name: numpy_helper.to_array(t) for t in g.initializer}
    nodes, count = [], 0
    for n in g.node:
        if not _splittable(n, weights):
            nodes.append(n)
            continue
        bias = [n.input[2]] if len(n.input) > 2 and n.input[2] else []
        phases = []
        for (a, b), k in zip(PHASES, phase_kernels(weights[n.input[1]])):
            w_name, y = f"{n.input[1]}.phase{a}{b}", f"{n.output[0]}.phase{a}{b}"
            g.initializer.append(numpy_helper.from_array(k, w_name))
            nodes.append(helper.make_node("Conv", [n.input[0], w_name, *bias], [y], name=f"{n.name}.phase{a}{b}",
                                          kernel_shape=[2, 2], pads=[1 - a, 1 - b, a, b]))
            phases.append(y)
        cat = f"{n.output[0]}.phases"
        nodes.append(helper.make_node("Concat", phases, [cat], name=f"{n.name}.concat", axis=1))
        nodes.append(helper.make_node("DepthToSpace", [cat], [n.output[0]], name=f"{n.name}.interleave", blocksize=2,
                                      mode="DCR"))
        count += 1
    if count:
        del g.node[:]
        g.node.extend(nodes)
        graph_rewrite.prune(model)
    return count


def _is_interleave(node: onnx.NodeProto) -> bool:
    """A DepthToSpace that interleaves four phases (DCR, block 2)."""
    a = graph_rewrite.attrs(node)
    return node.op_type == "DepthToSpace" and a.get("blocksize") == 2 and a.get("mode", b"DCR") in (b"DCR", "DCR")


def _is_interleaved_conv(node: onnx.NodeProto, consumers: dict) -> bool:
    """A Conv whose output only an interleaving DepthToSpace reads (phase_final_conv.py)."""
    after = consumers.get(node.output[0], [])
    return node.op_type == "Conv" and len(after) == 1 and _is_interleave(after[0])


def phase_groups(model: onnx.ModelProto) -> dict[str, list[str]]:
    """The four Conv nodes (by name, in phase order) of every split transposed convolution, keyed
    by the first one's name: four 2x2 Convs on one input, concatenated in that order (each
    directly, or through its own Relu) and interleaved by DepthToSpace (DCR, block 2), or read
    by the phase-domain final convolution that phase_final_conv.py makes of conv5."""
    by_output = {o: n for n in model.graph.node for o in n.output}
    consumers = graph_rewrite.consumers(model)
    groups = {}
    for n in model.graph.node:
        if n.op_type != "Concat" or len(n.input) != 4 or graph_rewrite.attrs(n).get("axis") != 1:
            continue
        after = consumers.get(n.output[0], [])
        if len(after) != 1 or not (_is_interleave(after[0]) or _is_interleaved_conv(after[0], consumers)):
            continue
        convs = [by_output.get(i) for i in n.input]
        convs = [by_output.get(c.input[0]) if c is not None and c.op_type == "Relu" else c for c in convs]
        if any(c is None or c.op_type != "Conv" for c in convs) or len({c.input[0] for c in convs}) != 1:
            continue
        if [list(graph_rewrite.attrs(c).get("pads", [])) for c in convs] != [[1 - a, 1 - b, a, b] for a, b in PHASES]:
            continue
        groups[convs[0].name] = [c.name for c in convs]
    return groups


def rewrite_folder(models_dir: Path) -> dict[str, int]:
    """Splits the transposed convolutions of a model folder's three graphs in place: each new
    graph is checked against the old one with ONNX Runtime on random inputs (MAX_ABS_DIFF), and
    the graphs and export.json's digests replace the old ones only when all three pass (staged
    beside the folder and renamed in). Returns the count per graph."""
    return graph_rewrite.rewrite_folder(
        models_dir, "phase-conv", split_transposed_convs, ((37, 53), (64, 96)), MAX_ABS_DIFF,
        "4x4 stride-2 transposed convolutions as four 2x2 phase convolutions (phase_conv.py)", PhaseConvError)


def main(argv: list[str] | None = None) -> int:
    return graph_rewrite.command("phase_conv", __doc__.split("\n\n")[0], rewrite_folder,
                                 "transposed convolutions split", argv)


if __name__ == "__main__":
    raise SystemExit(main())
