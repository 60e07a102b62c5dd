"""The RDN's and 3RN's graphs without their inner even-size padding: the same outputs at every
even size, 10% faster.

Graphs exported before 2026-12-05 padded conv1's output to even size (a Pad, replicate, and two
Slices to the even length) before the stride-2 convolution, and cropped conv4's output back to
the input size (two Slices) before conv5. The pipelines pad every image to even size first
(docs/CONTRACTS.md section 2), so at run time those nodes copied full-resolution tensors and
changed nothing; they also kept ONNX Runtime from chaining conv1 to conv2 in its blocked
layout. ``drop_inner_padding`` reads conv1's output straight into the stride-2 convolution and
moves the crop after conv5 (before the 3RN's global residual), as networks.py now exports: the
same function at even sizes (the same operations in the same order, so the same bits), and at
an odd size the stride-2 convolution's zero padding instead of the replicated row.
Quantized (QDQ) graphs are rewritten the same way: their QuantizeLinear/DequantizeLinear pairs
between the removed nodes go with them.

    python -m raindrop_tools.inner_padding --models models/compact-multiscale

rewrites a model folder in place (graph_rewrite.py: checked against the old graphs with ONNX
Runtime at even sizes, export.json's digests updated). Imports without torch.
"""

from __future__ import annotations

from pathlib import Path

import onnx

from . import graph_rewrite

# The old and new graphs compute the same operations in the same order at even sizes.
MAX_ABS_DIFF = 1e-6
CHECK_SIZES = ((38, 54), (64, 96))
_PASS_THROUGH = {"Slice", "QuantizeLinear", "DequantizeLinear"}


class InnerPaddingError(graph_rewrite.GraphRewriteError):
    pass


def _rewire_start(model: onnx.ModelProto, pad: onnx.NodeProto, consumers: dict) -> None:
    """Pad (-> Q/DQ) -> Slice (-> Q/DQ) -> Slice (-> Q/DQ) -> Conv(stride 2): the Conv reads
    the Pad's input instead."""
    node, slices = pad, 0
    while True:
        nxt = graph_rewrite.only_consumer(consumers, node.output[0])
        if nxt is None:
            raise InnerPaddingError(f"{pad.name}: its output is read by more than one node")
        if nxt.op_type == "Conv":
            break
        if nxt.op_type not in _PASS_THROUGH:
            raise InnerPaddingError(f"{pad.name}: a {nxt.op_type} between the Pad and the stride-2 convolution")
        slices += nxt.op_type == "Slice"
        node = nxt
    if slices != 2 or list(graph_rewrite.attrs(nxt).get("strides", [1, 1])) != [2, 2]:
        raise InnerPaddingError(f"{pad.name}: not the even-size padding before a stride-2 convolution")
    nxt.input[0] = pad.input[0]


def _move_end_crop(model: onnx.ModelProto, conv5: onnx.NodeProto, by_output: dict, consumers: dict) -> None:
    """Y -> Slice -> Slice (-> Q/DQ) -> conv5 becomes Y (-> Q/DQ) -> conv5 -> [Q/DQ] -> Slice ->
    Slice -> what read conv5's result."""
    slices = []  # from conv5's input back: the second Slice, then the first
    tensor = conv5.input[0]
    while len(slices) < 2 and tensor in by_output and by_output[tensor].op_type in _PASS_THROUGH:
        node = by_output[tensor]
        if len(consumers.get(node.output[0], [])) != 1:
            raise InnerPaddingError(f"{conv5.name}: the crop before it is read elsewhere too")
        if node.op_type == "Slice":
            slices.append(node)
        tensor = node.input[0]
    if len(slices) != 2:
        raise InnerPaddingError(f"{conv5.name}: its input is not cropped by two Slices")
    second, first = slices  # in graph order: Y -> first -> ... -> second
    # What read the second slice now reads Y (the Q/DQ pairs between the Slices fall away).
    reader = graph_rewrite.only_consumer(consumers, second.output[0])
    reader.input[0] = first.input[0]
    # The crop after conv5, or after the QuantizeLinear/DequantizeLinear pair that follows it.
    result = conv5.output[0]
    q = graph_rewrite.only_consumer(consumers, result, "QuantizeLinear")
    dq = q and graph_rewrite.only_consumer(consumers, q.output[0], "DequantizeLinear")
    if dq:
        result = dq.output[0]
    second.input[0] = first.output[0]  # not through the Q/DQ pair between them: its scale is Y's
    if any(o.name == result for o in model.graph.output):
        # The result is the graph's output (a 3RN without global residual): it keeps its name,
        # now on the crop, and its producer writes the uncropped tensor.
        uncropped = result + ".uncropped"
        by_output[result].output[0] = uncropped
        first.input[0] = uncropped
        second.output[0] = result
        return
    readers = consumers.get(result, [])
    cropped = result + ".cropped"
    first.input[0] = result
    second.output[0] = cropped
    for r in readers:
        for k, i in enumerate(r.input):
            if i == result:
                r.input[k] = cropped


def drop_inner_padding(model: onnx.ModelProto) -> int:
    """Rewrites a graph in place; returns 1 if it had the inner padding, 0 if not (the RFN, or a
    graph already rewritten or exported without it)."""
    pads = [n for n in model.graph.node if n.op_type == "Pad"]
    if not pads:
        return 0
    if len(pads) != 1:
        raise InnerPaddingError(f"{len(pads)} Pad nodes; expected the one before the stride-2 convolution")
    consumers = graph_rewrite.consumers(model)
    by_output = {o: n for n in model.graph.node for o in n.output}
    _rewire_start(model, pads[0], consumers)
    convs = [n for n in model.graph.node if n.op_type == "Conv"]
    _move_end_crop(model, convs[-1], by_output, consumers)
    graph_rewrite.prune(model)
    graph_rewrite.topological_sort(model)
    return 1


def rewrite_folder(models_dir: Path) -> dict[str, int]:
    """Rewrites a model folder's graphs in place (graph_rewrite.rewrite_folder): each new graph
    must give the old one's outputs at even sizes to MAX_ABS_DIFF. Returns the count per graph."""
    return graph_rewrite.rewrite_folder(
        models_dir, "inner-padding", drop_inner_padding, CHECK_SIZES, MAX_ABS_DIFF,
        "the inner even-size padding of the RDN and 3RN removed (inner_padding.py)", InnerPaddingError)


def main(argv: list[str] | None = None) -> int:
    return graph_rewrite.command("inner_padding", __doc__.split("\n\n")[0], rewrite_folder,
                                 "graphs rewritten", argv)


if __name__ == "__main__":
    raise SystemExit(main())
