"""Graphs without their inner even-size padding (raindrop_tools.inner_padding): the same outputs
at even sizes, valid at odd ones, folders rewritten whole. No torch needed."""

from __future__ import annotations

import hashlib
import json
import shutil

import numpy as np
import onnx
import pytest

from helpers import FIXTURE_MODELS, quiet_session
from raindrop_tools import contract as C
from raindrop_tools.inner_padding import InnerPaddingError, drop_inner_padding, main, rewrite_folder
from raindrop_tools.quantize import quantize_models


def _ops(path):
    return [n.op_type for n in onnx.load(str(path)).graph.node]


def _compare(before, after, sizes, seed=3):
    """Max |before - after| over random inputs at each size; raises on a shape mismatch."""
    rng = np.random.default_rng(seed)
    worst = 0.0
    for h, w in sizes:
        feed = {i.name: rng.random((1, i.shape[1], h, w), dtype=np.float32) for i in before.get_inputs()}
        a, b = before.run(None, feed)[0], after.run(None, feed)[0]
        assert a.shape == b.shape == (1, a.shape[1], h, w)
        worst = max(worst, float(np.abs(a - b).max()))
    return worst


def test_a_model_folder_is_rewritten_in_place_with_its_digests(tmp_path):
    folder = tmp_path / "m"
    shutil.copytree(FIXTURE_MODELS, folder)
    (folder / "NOTES.txt").write_text("mine\n")
    assert "Pad" in _ops(folder / C.FILES["rdn"])  # the fixture is an old export
    rfn_bytes = (folder / C.FILES["rfn"]).read_bytes()
    before = {n: quiet_session(str(folder / C.FILES[n])) for n in C.NETWORKS}
    assert rewrite_folder(folder) == {"rdn": 1, "rrn": 1, "rfn": 0}
    info = json.loads((folder / C.EXPORT_INFO).read_text())
    for f, entry in info["files"].items():
        assert entry["sha256"] == hashlib.sha256((folder / f).read_bytes()).hexdigest(), f
    assert "inner_padding" in info
    for n in C.NETWORKS:
        ops = _ops(folder / C.FILES[n])
        assert "Pad" not in ops, n
        after = quiet_session(str(folder / C.FILES[n]))
        # The same operations in the same order at even sizes: the same bits.
        assert _compare(before[n], after, ((2, 2), (30, 44), (64, 96))) == 0.0, n
        # Odd sizes still run and keep their size (the values differ near the bottom and
        # right border, where the old graph replicated a row the pipelines never show it).
        _compare(before[n], after, ((1, 1), (37, 53)))
    assert (folder / C.FILES["rfn"]).read_bytes() == rfn_bytes  # a graph left alone keeps its bytes
    assert (folder / "NOTES.txt").read_text() == "mine\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m"], "no staging folder left"
    # Once is enough: a second run changes nothing, not even a byte of export.json.
    files = {p.name: p.read_bytes() for p in folder.iterdir()}
    assert rewrite_folder(folder) == {"rdn": 0, "rrn": 0, "rfn": 0}
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == files


def test_quantized_graphs_lose_their_padding_and_keep_their_bits(tmp_path, tiny_dataset):
    # An int8 folder made from the old-style fixture: QuantizeLinear/DequantizeLinear pairs sit
    # between the Pad and the Slices (a shared scale), and go with them.
    int8 = tmp_path / "int8"
    quantize_models(FIXTURE_MODELS, tiny_dataset, int8, count=3)
    for n in ("rdn", "rrn"):
        model = onnx.load(str(int8 / C.FILES[n]))
        before = quiet_session(model)
        assert drop_inner_padding(model) == 1
        onnx.checker.check_model(model)
        ops = [x.op_type for x in model.graph.node]
        assert "Pad" not in ops and ops.count("Slice") == 2, n
        assert _compare(before, quiet_session(model), ((38, 54), (64, 96))) == 0.0, n


def test_a_graph_it_does_not_understand_is_refused():
    model = onnx.load(str(FIXTURE_MODELS / C.FILES["rdn"]))
    slices = [n for n in model.graph.node if n.op_type == "Slice"]
    # Something other than a Slice between the Pad and the stride-2 convolution.
    slices[0].op_type = "Relu"
    del slices[0].input[1:]
    with pytest.raises(InnerPaddingError, match="between the Pad and the stride-2 convolution"):
        drop_inner_padding(model)


def test_the_command_reports_a_missing_folder_in_one_line(tmp_path, capsys):
    assert main(["--models", str(tmp_path / "nothing")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("inner_padding: error:") and err.count("\n") == 1
