import json

import cv2
import numpy as np
import pytest

from helpers import write_dataset
from raindrop_tools import datapack
from raindrop_tools.datapack import PackError, main, pack, unpack


def _images(root, entry):
    return [cv2.imread(str(root / entry[k]), cv2.IMREAD_UNCHANGED) for k in ("rainy", "clean", "mask")]


def _manifest(root):
    return [json.loads(line) for line in (root / "manifest.jsonl").read_text().splitlines()]


@pytest.fixture
def two_sets(tmp_path):
    # two data sets over the same procedural frames (same seed: the same clean images, as the
    # paper preset and the thin-lens presets share CamVid frames), other drops
    a = write_dataset(tmp_path / "paper", n=6, seed=3)
    b = write_dataset(tmp_path / "lens", n=6, seed=3)
    for e in _manifest(b):  # other drops over the same clean images
        rainy = cv2.imread(str(b / e["rainy"]))
        rainy[5:9, 7:30] = 255 - rainy[5:9, 7:30]
        cv2.imwrite(str(b / e["rainy"]), rainy)
    return a, b


def test_unpack_gives_back_every_pixel_and_stores_shared_clean_images_once(two_sets, tmp_path):
    a, b = two_sets
    # one sample whose rainy image differs everywhere, as a real pair's does
    e0 = _manifest(a)[0]
    clean = cv2.imread(str(a / e0["clean"]))
    cv2.imwrite(str(a / e0["rainy"]), np.clip(clean.astype(int) + 1, 0, 255).astype(np.uint8))
    r = pack([a, b], tmp_path / "pack", None, None, [None, None], threads=2)
    assert r["samples"] == {"paper": 6, "lens": 6}
    assert r["cleans"] == 3  # 3 frames x 2 variants x 2 sets share 3 clean images
    assert unpack(tmp_path / "pack", tmp_path / "out", threads=2) == {"paper": 6, "lens": 6}
    for src in (a, b):
        got = _manifest(tmp_path / "out" / src.name)
        want = _manifest(src)
        assert got == [{k: v for k, v in e.items() if k != "drops"} for e in want]
        for e in want:
            for x, y in zip(_images(src, e), _images(tmp_path / "out" / src.name, e)):
                np.testing.assert_array_equal(x, y)


def test_frames_and_variants_choose_a_subset(two_sets, tmp_path):
    a, b = two_sets
    r = pack([a, b], tmp_path / "pack", None, 2, [1, 2], threads=1)
    assert r["samples"] == {"paper": 2, "lens": 4} and r["cleans"] == 2
    unpack(tmp_path / "pack", tmp_path / "out", threads=1)
    ids = [e["id"] for e in _manifest(tmp_path / "out" / "paper")]
    assert ids == ["src000_v0", "src002_v0"]  # the first and last frame, one variant each


def test_a_damaged_pack_is_refused_and_leaves_no_data_set(two_sets, tmp_path):
    a, _ = two_sets
    pack([a], tmp_path / "pack", None, None, [None], threads=1)
    layer = tmp_path / "pack" / "layer" / "paper" / "src001_v1.webp"
    img = cv2.imread(str(layer))
    img[0, 0] ^= 1
    img[0, 0, 0] |= 1  # a differing pixel is never pure black
    cv2.imwrite(str(layer), img, datapack.LOSSLESS_WEBP)
    mark = cv2.imread(str(tmp_path / "pack" / "differs" / "paper" / "src001_v1.png"), cv2.IMREAD_UNCHANGED)
    mark[0, 0] = 255
    cv2.imwrite(str(tmp_path / "pack" / "differs" / "paper" / "src001_v1.png"), mark)
    with pytest.raises(PackError, match="src001_v1.*rainy differs"):
        unpack(tmp_path / "pack", tmp_path / "out", threads=1)
    assert not (tmp_path / "out" / "paper" / "manifest.jsonl").exists()


def test_cli_refuses_bad_input_in_one_line(two_sets, tmp_path, capsys):
    a, _ = two_sets
    assert main(["pack", str(tmp_path / "p"), f"{a}:0"]) == 1
    assert main(["pack", str(tmp_path / "p"), str(a), "--frames", "0"]) == 1
    assert main(["unpack", str(tmp_path / "nothing"), str(tmp_path / "o")]) == 1
    assert main(["pack", str(tmp_path / "p"), str(a)]) == 0
    assert main(["pack", str(tmp_path / "p"), str(a)]) == 1  # never into a used folder
    assert main(["unpack", str(tmp_path / "p"), str(tmp_path / "o")]) == 0
    assert main(["unpack", str(tmp_path / "p"), str(tmp_path / "o")]) == 1  # never over a data set
    errors = [line for line in capsys.readouterr().err.splitlines() if line]
    assert len(errors) == 5 and all(line.startswith("error: ") for line in errors)


@pytest.mark.parametrize("where", ["/tmp/elsewhere.png", "../../victim.png", "../paper2/x.png", "a.txt"])
def test_an_index_cannot_make_unpack_write_outside_its_set(two_sets, tmp_path, where):
    """A pack's index is data: a path in it that leaves the set's folder (absolute, '..') or is
    not a PNG is refused before anything is written, and nothing outside is touched."""
    a, _ = two_sets
    pack([a], tmp_path / "pack", None, None, [None], threads=1)
    index = json.loads((tmp_path / "pack" / datapack.INDEX).read_text())
    index["samples"][1]["entry"]["clean"] = where
    (tmp_path / "pack" / datapack.INDEX).write_text(json.dumps(index))
    victim = tmp_path / "victim.png"
    victim.write_bytes(b"mine")
    with pytest.raises(PackError, match="leaves the data set's folder|is not a .png"):
        unpack(tmp_path / "pack", tmp_path / "out" / "deep", threads=1)
    assert victim.read_bytes() == b"mine"
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").rglob("*.png"))


def test_unpack_never_writes_over_a_file_already_there(two_sets, tmp_path):
    a, _ = two_sets
    pack([a], tmp_path / "pack", None, None, [None], threads=1)
    first = _manifest(a)[0]
    mine = tmp_path / "out" / "paper" / first["clean"]
    mine.parent.mkdir(parents=True)
    mine.write_bytes(b"mine")
    with pytest.raises(PackError, match="already exists"):
        unpack(tmp_path / "pack", tmp_path / "out", threads=1)
    assert mine.read_bytes() == b"mine"
