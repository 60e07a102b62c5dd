"""raindrop_tools.surround_fill_area: records a detector's surround-fill area in a model folder
(rdn.onnx's raindrop.surround_fill_area and export.json) and changes nothing else. What raindrop-remove
does with it is tested in C++ (tests/remove/test_model_metadata.cpp, test_detector_router.cpp)."""

import json

import numpy as np
import onnx
import pytest

from helpers import smoke_model_folder
from raindrop_tools import contract as C
from raindrop_tools.detector_metadata import MetadataError
from raindrop_tools.surround_fill_area import main, set_surround_fill_area


@pytest.fixture
def folder(tmp_path):
    return smoke_model_folder(tmp_path)


def _meta(path):
    return {p.key: p.value for p in onnx.load(str(path)).metadata_props}


def test_the_area_is_recorded_as_an_integer_in_the_detector_alone_and_default_gives_the_file_back(folder):
    before = {n: (folder / f).read_bytes() for n, f in C.FILES.items()}
    info = set_surround_fill_area(folder, 1500)
    assert _meta(folder / "rdn.onnx")[C.META_SURROUND_FILL_AREA] == "1500"  # what C++'s parse_int takes
    old = onnx.load_from_string(before["rdn"])
    assert onnx.load(str(folder / "rdn.onnx")).graph.SerializeToString() == old.graph.SerializeToString()
    for n in ("rrn", "rfn"):
        assert (folder / C.FILES[n]).read_bytes() == before[n]
    assert info["pipeline"]["surround_fill_area"] == 1500
    assert json.loads((folder / C.EXPORT_INFO).read_text())["files"] == C.graph_files(folder)
    set_surround_fill_area(folder, 0)  # 0 (off) is an area, recorded
    assert _meta(folder / "rdn.onnx")[C.META_SURROUND_FILL_AREA] == "0"
    assert [p.key for p in onnx.load(str(folder / "rdn.onnx")).metadata_props].count(C.META_SURROUND_FILL_AREA) == 1
    info = set_surround_fill_area(folder, None)
    assert (folder / "rdn.onnx").read_bytes() == before["rdn"]
    assert "surround_fill_area" not in info["pipeline"]


def test_refusals_change_nothing(folder, capsys):
    before = {f: (folder / f).read_bytes() for f in C.FILES.values()}
    assert main([str(folder), "-5"]) == 2
    assert main([str(folder), "1.5"]) == 2
    assert main([str(folder), str(2**31)]) == 2  # past what raindrop-remove reads (a C int)
    assert main([str(folder / "missing"), "100"]) == 2
    err = capsys.readouterr().err
    assert err.count("error:") == 4 and all(len(line) < 300 for line in err.splitlines())
    for bad in (1500.0, True, np.int64(1500)):  # through the API: only a plain int is written
        with pytest.raises(MetadataError):
            set_surround_fill_area(folder, bad)
    assert {f: (folder / f).read_bytes() for f in C.FILES.values()} == before
    assert main([str(folder), "default"]) == 0
    assert main([str(folder), "700"]) == 0
    assert _meta(folder / "rdn.onnx")[C.META_SURROUND_FILL_AREA] == "700"


@pytest.mark.parametrize("area", [0, 150, 1500])
def test_set_then_default_round_trips(folder, area):
    before = (folder / "rdn.onnx").read_bytes()
    set_surround_fill_area(folder, area)
    set_surround_fill_area(folder, None)
    assert (folder / "rdn.onnx").read_bytes() == before


def test_the_threshold_is_recorded_in_every_graph_and_refusals_change_nothing(folder):
    """detector_metadata.set_threshold: a threshold set after export (docs/RESULTS.md 4.50) is in
    all three graphs, as export writes it, and export.json, which lists the new digests."""
    from raindrop_tools.detector_metadata import set_detector_metadata, set_threshold

    before = {n: (folder / f).read_bytes() for n, f in C.FILES.items()}
    for bad in (0.0, 1.0, 1, True, "0.5"):
        with pytest.raises(MetadataError):
            set_threshold(folder, bad)
    with pytest.raises(MetadataError):
        set_detector_metadata(folder, C.META_THRESHOLD, "threshold", None, every_graph=True)
    assert {n: (folder / f).read_bytes() for n, f in C.FILES.items()} == before
    info = set_threshold(folder, 0.5)
    for n, f in C.FILES.items():
        assert _meta(folder / f)[C.META_THRESHOLD] == "0.5", n
        old = onnx.load_from_string(before[n])
        assert onnx.load(str(folder / f)).graph.SerializeToString() == old.graph.SerializeToString(), n
    assert info["pipeline"]["threshold"] == 0.5
    assert json.loads((folder / C.EXPORT_INFO).read_text())["files"] == C.graph_files(folder)
