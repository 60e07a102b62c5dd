"""raindrop_tools.large_drop_growth: records the coarse pass's large-drop growth in a model
folder (rdn.onnx's raindrop.large_drop_growth and export.json) and changes nothing else. What the
growth does is raindrop-remove's (tests/remove/test_large_drops.cpp, test_mask.cpp)."""

import json

import numpy as np
import onnx
import pytest

from helpers import smoke_model_folder
from raindrop_tools import contract as C
from raindrop_tools.large_drop_growth import GrowthError, main, set_large_drop_growth
from raindrop_tools.reference import RaindropRemover


@pytest.fixture
def folder(tmp_path):
    return smoke_model_folder(tmp_path)


def _meta(path):
    return {p.key: p.value for p in onnx.load(str(path)).metadata_props}


def test_growth_is_recorded_in_the_detector_alone_and_zero_gives_the_file_back(folder):
    before = {n: (folder / f).read_bytes() for n, f in C.FILES.items()}
    info = set_large_drop_growth(folder, 0.35)
    assert _meta(folder / "rdn.onnx")[C.META_LARGE_DROP_GROWTH] == "0.35"
    # Nothing else in the graph changed: the old metadata, and the graph itself.
    old = onnx.load_from_string(before["rdn"])
    new = onnx.load(str(folder / "rdn.onnx"))
    assert new.graph.SerializeToString() == old.graph.SerializeToString()
    assert {k: v for k, v in _meta(folder / "rdn.onnx").items() if k != C.META_LARGE_DROP_GROWTH} == {
        p.key: p.value for p in old.metadata_props
    }
    for n in ("rrn", "rfn"):
        assert (folder / C.FILES[n]).read_bytes() == before[n]
    # export.json follows the files.
    assert info["pipeline"]["large_drop_growth"] == 0.35
    assert json.loads((folder / C.EXPORT_INFO).read_text())["files"] == C.graph_files(folder)
    # Set again: one entry, the new value.
    set_large_drop_growth(folder, 0.5)
    keys = [p.key for p in onnx.load(str(folder / "rdn.onnx")).metadata_props]
    assert keys.count(C.META_LARGE_DROP_GROWTH) == 1
    assert _meta(folder / "rdn.onnx")[C.META_LARGE_DROP_GROWTH] == "0.5"
    # 0: the entry goes, and the file is the original again.
    info = set_large_drop_growth(folder, 0)
    assert (folder / "rdn.onnx").read_bytes() == before["rdn"]
    assert "large_drop_growth" not in info["pipeline"]


def test_the_reference_runs_a_folder_with_a_growth_as_before(folder):
    # The reference pipeline has no coarse pass: the entry changes nothing there.
    rng = np.random.default_rng(3)
    img = (rng.random((40, 52, 3)) * 255).astype(np.uint8)
    before = RaindropRemover(folder).remove(img)
    set_large_drop_growth(folder, 0.35)
    after = RaindropRemover(folder).remove(img)
    assert np.array_equal(before.output, after.output) and np.array_equal(before.mask, after.mask)


def test_refusals(folder, tmp_path, capsys):
    for bad in (-0.1, 10.5, float("nan")):
        with pytest.raises(GrowthError, match="between 0 and 10"):
            set_large_drop_growth(folder, bad)
    with pytest.raises(GrowthError, match="no such file"):
        set_large_drop_growth(tmp_path / "nowhere", 0.3)
    assert main([str(tmp_path / "nowhere"), "0.3"]) == 2
    (tmp_path / "junk").mkdir()
    (tmp_path / "junk" / "rdn.onnx").write_bytes(b"not onnx")
    assert main([str(tmp_path / "junk"), "0.3"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and all(line.startswith("error: ") for line in err)
    assert (tmp_path / "junk" / "rdn.onnx").read_bytes() == b"not onnx"
    assert main([str(folder), "0.35"]) == 0
    assert _meta(folder / "rdn.onnx")[C.META_LARGE_DROP_GROWTH] == "0.35"


def test_a_bad_export_json_or_a_missing_graph_changes_nothing(folder):
    before = (folder / "rdn.onnx").read_bytes()
    (folder / C.EXPORT_INFO).write_text("{not json")
    with pytest.raises(GrowthError, match="export.json: not JSON"):
        set_large_drop_growth(folder, 0.35)
    assert (folder / "rdn.onnx").read_bytes() == before
    (folder / C.EXPORT_INFO).write_text("{}")
    (folder / "rfn.onnx").unlink()
    with pytest.raises(GrowthError, match="rfn.onnx: no such file"):
        set_large_drop_growth(folder, 0.35)
    assert (folder / "rdn.onnx").read_bytes() == before
    assert not list(folder.glob(".*.tmp"))
