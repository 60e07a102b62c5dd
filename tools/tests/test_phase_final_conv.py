"""conv5 computed on conv4's phases (raindrop_tools.phase_final_conv): the same function at odd
and even sizes, the kernel's round trip, folders rewritten whole. No torch needed."""

from __future__ import annotations

import hashlib
import json
import shutil

import numpy as np
import onnx

from helpers import FIXTURE_MODELS, quiet_session
from raindrop_tools import contract as C
from raindrop_tools import inner_padding, phase_conv
from raindrop_tools.phase_final_conv import (final_kernel, fold_final_convs, folded_final_convs, main, phase_kernel,
                                             rewrite_folder)


def _split_folder(tmp_path):
    """The fixture folder as exports before phase_final_conv wrote it: conv4 split, no inner padding."""
    folder = tmp_path / "m"
    shutil.copytree(FIXTURE_MODELS, folder)
    phase_conv.rewrite_folder(folder)
    inner_padding.rewrite_folder(folder)
    return folder


def test_the_phase_kernel_gives_back_conv5_exactly():
    w = np.random.default_rng(0).standard_normal((3, 5, 3, 3)).astype(np.float32)
    v = phase_kernel(w)
    assert v.shape == (12, 20, 3, 3)
    assert np.array_equal(final_kernel(v), w)
    # Each output phase uses all nine taps once, spread over the four input phases.
    for ph in range(4):
        assert np.count_nonzero(v[ph * 3:(ph + 1) * 3]) == np.count_nonzero(w) * 1


def test_the_folded_graph_computes_the_same_at_odd_and_even_sizes(tmp_path):
    folder = _split_folder(tmp_path)
    rng = np.random.default_rng(4)
    for name in ("rdn", "rrn"):
        model = onnx.load(str(folder / C.FILES[name]))
        before = quiet_session(model)
        assert fold_final_convs(model) == 1
        onnx.checker.check_model(model)
        ops = [n.op_type for n in model.graph.node]
        assert ops.count("DepthToSpace") == 1 and ops.count("Relu") >= 4, name
        assert len(folded_final_convs(model)) == 1 and len(phase_conv.phase_groups(model)) == 1, name
        after = quiet_session(model)
        for h, w in ((1, 1), (2, 2), (37, 53), (64, 96)):
            feed = {i.name: rng.random((1, i.shape[1], h, w), dtype=np.float32) for i in before.get_inputs()}
            a, b = before.run(None, feed)[0], after.run(None, feed)[0]
            assert a.shape == b.shape == (1, a.shape[1], h, w)
            assert np.abs(a - b).max() < 1e-5, (name, h, w)
        assert fold_final_convs(model) == 0  # once is enough


def test_a_model_folder_is_rewritten_in_place_with_its_digests(tmp_path):
    folder = _split_folder(tmp_path)
    (folder / "NOTES.txt").write_text("mine\n")
    assert rewrite_folder(folder) == {"rdn": 1, "rrn": 1, "rfn": 0}
    info = json.loads((folder / C.EXPORT_INFO).read_text())
    assert "phase_final_conv" in info
    for f, entry in info["files"].items():
        assert entry["sha256"] == hashlib.sha256((folder / f).read_bytes()).hexdigest(), f
    assert (folder / "NOTES.txt").read_text() == "mine\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m"], "no staging folder left"
    files = {p.name: p.read_bytes() for p in folder.iterdir()}
    assert rewrite_folder(folder) == {"rdn": 0, "rrn": 0, "rfn": 0}
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == files


def test_a_graph_without_the_split_is_left_alone(tmp_path):
    # The fixture as exported long ago: conv4 a ConvTranspose, so there are no phases to fold onto.
    model = onnx.load(str(FIXTURE_MODELS / C.FILES["rdn"]))
    before = model.SerializeToString()
    assert fold_final_convs(model) == 0
    assert model.SerializeToString() == before


def test_the_command_reports_a_missing_folder_in_one_line(tmp_path, capsys):
    assert main(["--models", str(tmp_path / "nothing")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("phase_final_conv: error:") and err.count("\n") == 1
