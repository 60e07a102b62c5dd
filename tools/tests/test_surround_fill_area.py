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


@pytest.mark.parametrize(
    "setter, key, pipeline_key, good, written, bads",
    [
        # docs/RESULTS.md 4.50: a threshold, strictly between 0 and 1, a float
        ("set_threshold", C.META_THRESHOLD, "threshold", 0.5, "0.5", (0.0, 1.0, 1, True, "0.5")),
        # 4.51: a dilation, odd, 1 to 1023, a whole number
        ("set_dilation", C.META_DILATION, "dilation", 7, "7", (0, 4, 1025, 5.0, True, "5")),
    ],
)
def test_a_value_every_graph_carries_is_recorded_in_all_three_and_refusals_change_nothing(
        folder, setter, key, pipeline_key, good, written, bads):
    """detector_metadata.set_threshold / set_dilation: a value set after export is in all three
    graphs, as export writes it, and in export.json, which lists the new digests; the graphs' nodes
    are unchanged; bad values, and removing such a key, are refused and change nothing."""
    from raindrop_tools import detector_metadata

    set_value = getattr(detector_metadata, setter)
    before = {n: (folder / f).read_bytes() for n, f in C.FILES.items()}
    for bad in bads:
        with pytest.raises(MetadataError):
            set_value(folder, bad)
    with pytest.raises(MetadataError):
        detector_metadata.set_detector_metadata(folder, key, pipeline_key, None, every_graph=True)
    assert {n: (folder / f).read_bytes() for n, f in C.FILES.items()} == before
    info = set_value(folder, good)
    for n, f in C.FILES.items():
        assert _meta(folder / f)[key] == written, n
        old = onnx.load_from_string(before[n])
        assert onnx.load(str(folder / f)).graph.SerializeToString() == old.graph.SerializeToString(), n
    assert info["pipeline"][pipeline_key] == good
    assert json.loads((folder / C.EXPORT_INFO).read_text())["files"] == C.graph_files(folder)
