"""int8 quantization of the exported graphs (no torch needed)."""

from __future__ import annotations

import hashlib
import json

import numpy as np
import onnx
import onnxruntime as ort
import pytest

from helpers import FIXTURE_MODELS, procedural_image
from raindrop_tools.contract import FILES, META_CONFIG, META_DILATION, META_THRESHOLD, NETWORKS
from raindrop_tools.quantize import quantize_models
from raindrop_tools.reference import RaindropRemover


def test_quantized_graphs_keep_the_contract_and_stay_close(tmp_path, tiny_dataset):
    out = tmp_path / "int8"
    info = quantize_models(FIXTURE_MODELS, tiny_dataset, out, count=3)
    assert info["config"].endswith("-int8")
    for name in NETWORKS:
        q = onnx.load(str(out / FILES[name]))
        ops = {n.op_type for n in q.graph.node}
        assert "QuantizeLinear" in ops and "DequantizeLinear" in ops, name
        meta = {p.key: p.value for p in q.metadata_props}
        fp = {p.key: p.value for p in onnx.load(str(FIXTURE_MODELS / FILES[name])).metadata_props}
        assert meta[META_CONFIG] == fp[META_CONFIG] + "-int8"
        assert meta[META_THRESHOLD] == fp[META_THRESHOLD] and meta[META_DILATION] == fp[META_DILATION]
        # Same inputs and outputs, dynamic sizes still accepted (odd size).
        s = ort.InferenceSession(str(out / FILES[name]), providers=["CPUExecutionProvider"])
        feeds = {i.name: np.random.default_rng(0).random((1, i.shape[1], 37, 53), dtype=np.float32) for i in s.get_inputs()}
        assert s.run(None, feeds)[0].shape[2:] == (37, 53)
    # The int8 graphs' outputs stay near the fp32 ones on an image they were not calibrated
    # on: mean error under 15% of the outputs' spread (measured: 3-4% on these tiny random
    # fixture models; the full pipeline is not compared because thresholding an untrained
    # detector's output amplifies any difference).
    fp32, int8 = RaindropRemover(FIXTURE_MODELS), RaindropRemover(out)
    R, E, _ = fp32.prepare(procedural_image(64, 96, seed=123))
    for run in (lambda m: m.detect(R), lambda m: m.reconstruct(R, E)):
        a, b = run(fp32), run(int8)
        assert np.abs(a - b).mean() < 0.15 * a.std()
    assert int8.remove(procedural_image(40, 50, seed=9)).output.shape == (40, 50, 3)
    info = json.loads((out / "export.json").read_text())
    assert set(info["files"]) == {FILES[n] for n in NETWORKS}
    for f, entry in info["files"].items():  # the int8 files' digests, not the fp32 ones
        assert entry["sha256"] == hashlib.sha256((out / f).read_bytes()).hexdigest(), f
    assert "parity_max_abs_diff" not in info


def test_quantize_refuses_its_own_models_folder_and_bad_input(tmp_path, tiny_dataset, capsys):
    """--out equal to --models replaced the fp32 graphs with int8 ones, exit 0."""
    import shutil

    from raindrop_tools import quantize as Q

    models = tmp_path / "m"
    shutil.copytree(FIXTURE_MODELS, models)
    before = {p.name: p.read_bytes() for p in models.iterdir()}
    for out in (models, tmp_path / "m" / ".." / "m"):
        assert Q.main(["--models", str(models), "--data", str(tiny_dataset), "--out", str(out)]) == 2
        assert "is the --models folder" in capsys.readouterr().err
    assert {p.name: p.read_bytes() for p in models.iterdir()} == before
    assert Q.main(["--models", str(models), "--data", str(tiny_dataset), "--out", str(tmp_path / "q"),
                   "--count", "0"]) == 2
    assert "--count must be at least 1" in capsys.readouterr().err
    assert Q.main(["--models", str(models), "--data", str(tmp_path / "none"), "--out", str(tmp_path / "q")]) == 2
    assert capsys.readouterr().err.startswith("error: ")
    assert not (tmp_path / "q").exists()


def test_quantize_replaces_a_linked_graph_instead_of_writing_through_it(tmp_path, tiny_dataset):
    """A graph in --out that is a link to the fp32 model's file was written through: the fp32
    model became int8. Now the link itself is replaced, and no staging folder is left."""
    import shutil

    fp32 = tmp_path / "fp32"
    shutil.copytree(FIXTURE_MODELS, fp32)
    before = (fp32 / FILES["rdn"]).read_bytes()
    out = tmp_path / "int8"
    out.mkdir()
    (out / FILES["rdn"]).symlink_to(fp32 / FILES["rdn"])
    quantize_models(fp32, tiny_dataset, out, count=1)
    assert (fp32 / FILES["rdn"]).read_bytes() == before
    assert not (out / FILES["rdn"]).is_symlink()
    assert not any(p.name.startswith(".int8.quantize-") for p in tmp_path.iterdir())


def test_a_network_kept_in_float_is_the_fp32_graph_under_the_int8_folders_name(tmp_path, tiny_dataset, capsys):
    """--keep-float rfn: the RFN is the fp32 graph bit for bit (weights and nodes), named as the
    int8 folder's and marked as float; the others are quantized as without the option, to the
    byte; a folder reusing this one's reconstruction gets the float RFN marked so too; export.json
    lists what stayed float; an unknown network is refused."""
    from raindrop_tools import quantize as Q

    full, mixed = tmp_path / "full-int8", tmp_path / "mixed-int8"
    quantize_models(FIXTURE_MODELS, tiny_dataset, full, count=2)
    info = quantize_models(FIXTURE_MODELS, tiny_dataset, mixed, count=2, keep_float=("rfn",))
    assert info["quantization"]["kept_float"] == [FILES["rfn"]]
    for name in ("rdn", "rrn"):
        assert (mixed / FILES[name]).read_bytes() == (full / FILES[name]).read_bytes(), name
    kept, fp32 = onnx.load(str(mixed / FILES["rfn"])), onnx.load(str(FIXTURE_MODELS / FILES["rfn"]))
    assert not Q.is_quantized(kept) and Q.is_quantized(onnx.load(str(full / FILES["rfn"])))
    assert kept.graph.SerializeToString() == fp32.graph.SerializeToString()
    meta = {p.key: p.value for p in kept.metadata_props}
    fp_meta = {p.key: p.value for p in fp32.metadata_props}
    assert meta == {**fp_meta, META_CONFIG: fp_meta[META_CONFIG] + "-int8", Q.META_QUANTIZATION: Q.KEPT_FLOAT}
    # The pipeline loads it (one configuration name across the three graphs).
    assert RaindropRemover(mixed).remove(procedural_image(40, 50, seed=9)).output.shape == (40, 50, 3)
    # Reused by a folder with the same fp32 reconstruction: the float RFN comes along, marked float.
    info = quantize_models(FIXTURE_MODELS, tiny_dataset, tmp_path / "reusing-int8", count=2, reuse_dir=mixed)
    assert info["quantization"]["kept_float"] == [FILES["rfn"]]
    reused = onnx.load(str(tmp_path / "reusing-int8" / FILES["rfn"]))
    assert {p.key: p.value for p in reused.metadata_props}[Q.META_QUANTIZATION] == Q.KEPT_FLOAT
    assert "kept_float" not in json.loads((full / "export.json").read_text())["quantization"]
    with pytest.raises(ValueError, match="gives an int8 rfn.onnx"):  # a reused int8 RFN cannot be kept in float
        quantize_models(FIXTURE_MODELS, tiny_dataset, tmp_path / "r2", count=1, reuse_dir=full, keep_float=("rfn",))
    with pytest.raises(SystemExit) as exit_:
        Q.main(["--models", str(FIXTURE_MODELS), "--data", str(tiny_dataset), "--out", str(tmp_path / "q"),
                "--keep-float", "head"])
    assert exit_.value.code == 2 and "invalid choice" in capsys.readouterr().err
    with pytest.raises(ValueError, match="--keep-float takes"):
        quantize_models(FIXTURE_MODELS, tiny_dataset, tmp_path / "q", count=1, keep_float=("head",))
