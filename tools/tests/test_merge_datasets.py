"""merge_datasets: one manifest over several sets, ids prefixed, images linked."""

import json

import numpy as np
import pytest

from raindrop_tools.data import read_manifest
from raindrop_tools.imageio import read_rgb, write_grey, write_rgb
from raindrop_tools.merge_datasets import main, merge


def _set(root, ids, value):
    lines = []
    for i in ids:
        write_rgb(root / "rainy" / f"{i}.png", np.full((8, 8, 3), value, np.uint8))
        write_rgb(root / "clean" / f"{i}.png", np.full((8, 8, 3), value, np.uint8))
        write_grey(root / "mask" / f"{i}.png", np.zeros((8, 8), np.uint8))
        lines.append(json.dumps({"id": i, "rainy": f"rainy/{i}.png", "clean": f"clean/{i}.png",
                                 "mask": f"mask/{i}.png", "width": 8, "height": 8, "extra": value}))
    (root / "manifest.jsonl").write_text("\n".join(lines) + "\n")


def test_same_ids_from_two_sets_stay_two_samples(tmp_path):
    for sub in ("rainy", "clean", "mask"):
        (tmp_path / "train-a" / sub).mkdir(parents=True)
        (tmp_path / "train-b" / sub).mkdir(parents=True)
    _set(tmp_path / "train-a", ["x", "y"], 10)
    _set(tmp_path / "train-b", ["x"], 200)
    assert merge(tmp_path / "mix", [tmp_path / "train-a", tmp_path / "train-b"]) == 3
    samples = read_manifest(tmp_path / "mix")
    assert sorted(s.id for s in samples) == ["a_x", "a_y", "b_x"]
    lines = [json.loads(x) for x in (tmp_path / "mix" / "manifest.jsonl").read_text().splitlines()]
    by_id = {r["id"]: r for r in lines}
    assert by_id["b_x"]["extra"] == 200  # other keys kept
    # The linked image is the source's, not the other set's same-named one.
    assert read_rgb(tmp_path / "mix" / by_id["b_x"]["rainy"])[0, 0, 0] == 200
    assert read_rgb(tmp_path / "mix" / by_id["a_x"]["rainy"])[0, 0, 0] == 10


def test_colliding_set_names_are_refused(tmp_path):
    for name in ("train-a", "a"):
        for sub in ("rainy", "clean", "mask"):
            (tmp_path / name / sub).mkdir(parents=True)
        _set(tmp_path / name, ["x"], 5)
    assert main(["--out", str(tmp_path / "mix"), str(tmp_path / "train-a"), str(tmp_path / "a")]) == 1
    assert not (tmp_path / "mix").exists(), "nothing is linked before the ids are checked"


def test_a_data_set_in_out_is_never_replaced(tmp_path, capsys):
    """--out holding a rendered set (or being a source) replaced its manifest with the merged
    one; a rerun of the same merge into its own earlier output still works."""
    for name in ("train-a", "train-b"):
        for sub in ("rainy", "clean", "mask"):
            (tmp_path / name / sub).mkdir(parents=True)
    _set(tmp_path / "train-a", ["x"], 10)
    _set(tmp_path / "train-b", ["y"], 20)
    before = (tmp_path / "train-a" / "manifest.jsonl").read_bytes()
    for argv in (["--out", str(tmp_path / "train-a"), str(tmp_path / "train-b")],
                 ["--out", str(tmp_path / "train-a"), str(tmp_path / "train-a"), str(tmp_path / "train-b")]):
        assert main(argv) == 1
        assert capsys.readouterr().err.startswith("merge_datasets: error: ")
    assert (tmp_path / "train-a" / "manifest.jsonl").read_bytes() == before
    assert sorted(p.name for p in (tmp_path / "train-a" / "rainy").iterdir()) == ["x.png"]
    argv = ["--out", str(tmp_path / "mix"), str(tmp_path / "train-a"), str(tmp_path / "train-b")]
    assert main(argv) == 0
    first = (tmp_path / "mix" / "manifest.jsonl").read_bytes()
    assert main(argv) == 0, "the same merge again, into its own output"
    assert (tmp_path / "mix" / "manifest.jsonl").read_bytes() == first


@pytest.mark.parametrize("bad, says", [
    ('{"id": "z", "rainy": "rainy/z.png"', "not JSON"),      # cut short
    ('["not", "a", "record"]', "not a sample record"),
    ('{"rainy": "rainy/z.png"}', "not a sample record"),       # no id
    ('{"id": 7}', "not a sample record"),                      # id not text
    ('{"id": "z", "rainy": 3}', "'rainy' is not a path"),
])
def test_a_bad_manifest_line_is_one_line_naming_its_file_and_line(tmp_path, capsys, bad, says):
    for sub in ("rainy", "clean", "mask"):
        (tmp_path / "train-a" / sub).mkdir(parents=True)
    _set(tmp_path / "train-a", ["x", "y"], 10)
    manifest = tmp_path / "train-a" / "manifest.jsonl"
    manifest.write_text(manifest.read_text() + bad + "\n")
    assert main(["--out", str(tmp_path / "mix"), str(tmp_path / "train-a")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("merge_datasets: error: ")
    assert f"{manifest}:3: " in err and says in err
    assert not (tmp_path / "mix").exists(), "nothing is linked before every line is read"


def test_a_manifest_of_ids_and_notes_is_not_taken_for_an_earlier_merge(tmp_path, capsys):
    """A manifest.jsonl of records with an id and no images (someone's notes) passed for one
    this tool wrote (no image that is not a link), and was replaced."""
    src = tmp_path / "set"
    for sub in ("rainy", "clean", "mask"):
        (src / sub).mkdir(parents=True)
    _set(src, ["x"], 10)
    out = tmp_path / "mg"
    out.mkdir()
    (out / "manifest.jsonl").write_text('{"id": "note1", "text": "keep"}\n')
    assert main(["--out", str(out), str(src)]) == 1
    assert "holds a data set of its own" in capsys.readouterr().err
    assert (out / "manifest.jsonl").read_text() == '{"id": "note1", "text": "keep"}\n'
