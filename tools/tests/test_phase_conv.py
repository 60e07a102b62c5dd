"""phase_conv.py: the transposed convolution as four phase convolutions (no torch needed)."""

from __future__ import annotations

import hashlib
import json
import shutil

import numpy as np
import onnx
import onnxruntime as ort
import pytest
from onnx import TensorProto, helper, numpy_helper

from helpers import FIXTURE_MODELS
from raindrop_tools import contract as C
from raindrop_tools.phase_conv import (PhaseConvError, main, phase_groups, phase_kernels, rewrite_folder,
                                       split_transposed_convs, transposed_kernel)


def _transposed_conv_model(cin=5, cout=3, bias=True, seed=0):
    rng = np.random.default_rng(seed)
    w = rng.normal(size=(cin, cout, 4, 4)).astype(np.float32)
    inits = [numpy_helper.from_array(w, "w")]
    inputs = ["x", "w"]
    if bias:
        inits.append(numpy_helper.from_array(rng.normal(size=cout).astype(np.float32), "b"))
        inputs.append("b")
    node = helper.make_node("ConvTranspose", inputs, ["y"], name="up", strides=[2, 2], pads=[1, 1, 1, 1])
    graph = helper.make_graph([node], "g", [helper.make_tensor_value_info("x", TensorProto.FLOAT, [1, cin, "H", "W"])],
                              [helper.make_tensor_value_info("y", TensorProto.FLOAT, [1, cout, None, None])], inits)
    return helper.make_model(graph, opset_imports=[helper.make_opsetid("", 18)], ir_version=9)


def _run(model, x):
    return ort.InferenceSession(model.SerializeToString(), providers=["CPUExecutionProvider"]).run(None, {"x": x})[0]


@pytest.mark.parametrize("bias", [True, False])
@pytest.mark.parametrize("h,w", [(1, 1), (2, 3), (7, 5), (16, 24)])
def test_the_split_graph_computes_the_transposed_convolution(bias, h, w):
    before = _transposed_conv_model(bias=bias)
    after = onnx.ModelProto()
    after.CopyFrom(before)
    assert split_transposed_convs(after) == 1
    onnx.checker.check_model(after, full_check=True)
    ops = [n.op_type for n in after.graph.node]
    assert ops == ["Conv"] * 4 + ["Concat", "DepthToSpace"]
    x = np.random.default_rng(1).normal(size=(1, 5, h, w)).astype(np.float32)
    a, b = _run(before, x), _run(after, x)
    assert a.shape == b.shape == (1, 3, 2 * h, 2 * w)
    assert np.abs(a - b).max() < 1e-5


def test_the_phase_kernels_give_back_the_transposed_kernel_exactly():
    w = np.random.default_rng(2).normal(size=(6, 4, 4, 4)).astype(np.float32)
    ks = phase_kernels(w)
    assert [k.shape for k in ks] == [(4, 6, 2, 2)] * 4
    assert np.array_equal(transposed_kernel(ks), w)


def test_other_transposed_convolutions_are_left_alone():
    model = _transposed_conv_model()
    for a in model.graph.node[0].attribute:
        if a.name == "pads":
            a.ints[:] = [0, 0, 0, 0]
    assert split_transposed_convs(model) == 0
    assert [n.op_type for n in model.graph.node] == ["ConvTranspose"]


def test_the_groups_are_found_in_a_split_graph():
    model = _transposed_conv_model()
    split_transposed_convs(model)
    groups = phase_groups(model)
    assert list(groups.values()) == [["up.phase00", "up.phase01", "up.phase10", "up.phase11"]]


def test_a_model_folder_is_rewritten_in_place_with_its_digests(tmp_path):
    folder = tmp_path / "m"
    shutil.copytree(FIXTURE_MODELS, folder)
    (folder / "NOTES.txt").write_text("mine\n")
    before = {n: ort.InferenceSession(str(folder / C.FILES[n]), providers=["CPUExecutionProvider"]) for n in C.NETWORKS}
    counts = rewrite_folder(folder)
    assert counts["rdn"] == 1 and counts["rrn"] == 1 and counts["rfn"] == 0
    info = json.loads((folder / C.EXPORT_INFO).read_text())
    for f, entry in info["files"].items():
        assert entry["sha256"] == hashlib.sha256((folder / f).read_bytes()).hexdigest(), f
    rng = np.random.default_rng(3)
    for n in C.NETWORKS:
        after = ort.InferenceSession(str(folder / C.FILES[n]), providers=["CPUExecutionProvider"])
        feed = {i.name: rng.random((1, i.shape[1], 30, 44), dtype=np.float32) for i in after.get_inputs()}
        assert np.abs(before[n].run(None, feed)[0] - after.run(None, feed)[0]).max() < 1e-5, n
        assert {p.key: p.value for p in onnx.load(str(folder / C.FILES[n])).metadata_props} == {
            p.key: p.value for p in onnx.load(str(FIXTURE_MODELS / C.FILES[n])).metadata_props}
    assert (folder / "NOTES.txt").read_text() == "mine\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m"], "no staging folder left"
    assert rewrite_folder(folder) == {"rdn": 0, "rrn": 0, "rfn": 0}  # once is enough


def test_the_command_reports_a_missing_folder_in_one_line(tmp_path, capsys):
    assert main(["--models", str(tmp_path / "nothing")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("phase_conv: error:") and err.count("\n") == 1
