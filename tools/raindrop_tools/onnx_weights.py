"""Network weights back from exported ONNX graphs, so that a committed model folder
(``models/<config>/``, ONNX only) can start a fine-tuning run: ``train --init-from models/compact``.

The export folds every BatchNorm into the convolution before it (``W' = W g/s``,
``b' = beta - mean g/s``) and renames what it folds, so weights are matched by structure, not by
name: the graph's Conv/ConvTranspose nodes in graph order against the network's Conv2d and
ConvTranspose2d modules in the order a forward pass runs them (the export traced that pass). Each
folded pair gets the folded weight on the convolution and an identity BatchNorm carrying the
folded bias (``gamma = 1``, ``beta = b'``, running mean 0, running variance ``1 - eps``), so in
eval mode the network computes exactly what the graph computes (checked against ONNX Runtime
before returning). In train mode BatchNorm would normalise by batch statistics instead, which
the folded weights never saw; runs started this way therefore keep BatchNorm in eval mode
(``train.freeze_batchnorm``), a usual choice for fine-tuning with small batches anyway.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import onnx
import torch
from onnx import numpy_helper
from torch import nn

from . import contract as C
from .networks import example_inputs
from .phase_conv import phase_groups, transposed_kernel
from .phase_final_conv import final_kernel, folded_final_convs

CONV_OPS = ("Conv", "ConvTranspose")
CONV_MODULES = (nn.Conv2d, nn.ConvTranspose2d)
# Largest |torch - ONNX Runtime| accepted after loading (float32 rounding of 20-odd layers).
MAX_ABS_DIFF = 1e-4


class OnnxWeightsError(ValueError):
    pass


def _graph_convs(model: onnx.ModelProto, head_only: bool = False) -> list[tuple[str, np.ndarray, np.ndarray | None]]:
    """(op, weight, bias or None) of every convolution node, in graph order; with ``head_only``,
    those of the second detector's head that shared_detector.py spliced onto the RDN instead."""
    # A second detector's head on the RDN (shared_detector.py) is not the RDN's: left out,
    # unless the graph's own map is the head's (that folder's detector is a head, not an RDN).
    head = [n for n in model.graph.node if n.name.startswith(C.HEAD_NODE_PREFIX)]
    if head_only:
        if not head:
            raise OnnxWeightsError("the graph holds no second detector's head (shared_detector.py)")
        only = onnx.ModelProto()
        only.CopyFrom(model)
        del only.graph.node[:]
        only.graph.node.extend(head)
        model = only
    elif head:
        if any(C.OUTPUTS["rdn"] in n.output for n in head):
            raise OnnxWeightsError("this detector is a head on another model's RDN (shared_detector.py), not an RDN: "
                                   "start from that model's folder (export.json names it)")
        without = onnx.ModelProto()
        without.CopyFrom(model)
        del without.graph.node[:]
        without.graph.node.extend(n for n in model.graph.node if not n.name.startswith(C.HEAD_NODE_PREFIX))
        model = without
    tensors = {t.name: numpy_helper.to_array(t) for t in model.graph.initializer}
    for node in model.graph.node:
        if node.op_type == "Constant":
            for a in node.attribute:
                if a.name == "value":
                    tensors[node.output[0]] = numpy_helper.to_array(a.t)
    # A transposed convolution split into four phase convolutions (phase_conv.py) is read back
    # as the one it was.
    groups = phase_groups(model)
    in_group = {n for names in groups.values() for n in names[1:]}
    # So is a final convolution computed on those phases (phase_final_conv.py).
    folded = folded_final_convs(model)
    nodes = {n.name: n for n in model.graph.node}
    out = []
    for node in model.graph.node:
        if node.op_type not in CONV_OPS or node.name in in_group:
            continue
        members = [nodes[n] for n in groups.get(node.name, [node.name])]
        if any(m.input[1] not in tensors for m in members):
            raise OnnxWeightsError(f"{node.op_type} node {node.name!r}: its weight is computed, not stored")
        bias = tensors.get(node.input[2]) if len(node.input) > 2 and node.input[2] else None
        if node.name in groups:
            out.append(("ConvTranspose", transposed_kernel([tensors[m.input[1]] for m in members]), bias))
        elif node.name in folded:
            w = final_kernel(tensors[node.input[1]])
            out.append(("Conv", w, None if bias is None else bias[: w.shape[0]]))
        else:
            out.append((node.op_type, tensors[node.input[1]], bias))
    return out


def _execution_order(net: nn.Module, name: str) -> list[tuple[nn.Module, nn.BatchNorm2d | None]]:
    """The network's convolutions as a forward pass runs them, each with the BatchNorm that
    runs right after it on its output (None if none does)."""
    order: list[nn.Module] = []
    hooks = [m.register_forward_hook(lambda m, i, o: order.append(m))
             for m in net.modules() if isinstance(m, CONV_MODULES + (nn.BatchNorm2d,))]
    was_training = net.training
    try:
        net.eval()
        with torch.no_grad():
            net(*example_inputs(name, 1, 32, 32, generator=torch.Generator().manual_seed(0)))
    finally:
        for h in hooks:
            h.remove()
        net.train(was_training)
    pairs = []
    for k, m in enumerate(order):
        if isinstance(m, CONV_MODULES):
            nxt = order[k + 1] if k + 1 < len(order) else None
            pairs.append((m, nxt if isinstance(nxt, nn.BatchNorm2d) else None))
    return pairs


def load_network(net: nn.Module, name: str, onnx_path: str | Path) -> None:
    """Loads ``onnx_path`` (the exported graph of network ``name``) into ``net`` in place."""
    model = onnx.load(str(onnx_path))
    graph = _graph_convs(model)
    convs = _execution_order(net, name)
    if len(graph) != len(convs):
        raise OnnxWeightsError(
            f"{onnx_path}: {len(graph)} convolutions in the graph, {len(convs)} in this configuration's {name} "
            "(network.* must match the model's export.json)"
        )
    with torch.no_grad():
        for k, ((op, w, b), (conv, bn)) in enumerate(zip(graph, convs)):
            want = "Conv" if isinstance(conv, nn.Conv2d) else "ConvTranspose"
            if op != want or tuple(w.shape) != tuple(conv.weight.shape):
                raise OnnxWeightsError(
                    f"{onnx_path}: convolution {k} is {op} {list(w.shape)} in the graph but {want} "
                    f"{list(conv.weight.shape)} in this configuration's {name} (network.* must match the model's)"
                )
            conv.weight.copy_(torch.from_numpy(w.copy()))
            bias = torch.from_numpy(b.copy()) if b is not None else torch.zeros(w.shape[1 if op == "ConvTranspose" else 0])
            if bn is not None:
                # Identity BatchNorm in eval mode; the folded bias is its beta.
                bn.weight.fill_(1.0)
                bn.bias.copy_(bias)
                bn.running_mean.zero_()
                bn.running_var.fill_(1.0 - bn.eps)
                if conv.bias is not None:
                    conv.bias.zero_()
            elif conv.bias is not None:
                conv.bias.copy_(bias)
            elif b is not None and np.any(b != 0):
                raise OnnxWeightsError(f"{onnx_path}: convolution {k} has a bias that this configuration's has no place for")


def check_against_onnxruntime(net: nn.Module, name: str, onnx_path: str | Path) -> float:
    """Largest |eval-mode net - ONNX Runtime| on a random input; raises above MAX_ABS_DIFF."""
    import onnxruntime as ort

    from .export import graph_module  # the graph's function (RDN: with its sigmoid)

    inputs = example_inputs(name, 1, 48, 64, generator=torch.Generator().manual_seed(1))
    was_training = net.training
    net.eval()
    try:
        with torch.no_grad():
            ours = graph_module(name, net)(*inputs).float().numpy()
    finally:
        net.train(was_training)
    sess = ort.InferenceSession(str(onnx_path), providers=["CPUExecutionProvider"])
    theirs = sess.run(None, {n: x.numpy() for n, x in zip(C.INPUTS[name], inputs)})[0]
    diff = float(np.abs(ours - theirs).max())
    if not diff <= MAX_ABS_DIFF:
        raise OnnxWeightsError(f"{onnx_path}: loaded weights differ from the graph by {diff:.3g} (> {MAX_ABS_DIFF})")
    return diff


def load_model_folder(nets: dict[str, nn.Module], folder: str | Path) -> dict[str, float]:
    """Loads rdn.onnx, rrn.onnx and rfn.onnx of ``folder`` into ``nets``; returns each
    network's largest difference to ONNX Runtime."""
    folder = Path(folder)
    diffs = {}
    for name, net in nets.items():
        path = folder / C.FILES[name]
        if not path.is_file():
            raise OnnxWeightsError(f"{folder}: no {path.name}")
        load_network(net, name, path)
        diffs[name] = check_against_onnxruntime(net, name, path)
    return diffs
