"""raindrop_tools.realpairs: pairing, the group split, rough masks, prepare (no torch)."""

import json
import random

import cv2
import numpy as np
import pytest

from raindrop_tools import realpairs as RP
from raindrop_tools.data import RaindropDataset, check_files, read_manifest
from realpairs_helpers import write_pairs


def test_find_pairs_accepts_rain_and_rainy_and_any_extension(tmp_path):
    img = np.full((8, 8, 3), 100, np.uint8)
    for name in ("a_t0_rain.png", "a_t0_clean.png", "b_rainy.jpg", "b_clean.PNG", "other.png"):
        assert cv2.imwrite(str(tmp_path / name), img)
    (tmp_path / "notes_rain.txt").write_text("not an image")
    pairs = RP.find_pairs(tmp_path)
    assert [(p.id, p.group, p.rainy.name, p.clean.name) for p in pairs] == [
        ("a_t0", "a", "a_t0_rain.png", "a_t0_clean.png"),
        ("b", "b", "b_rainy.jpg", "b_clean.PNG"),
    ]


def test_unpaired_files_are_named(tmp_path):
    img = np.zeros((8, 8, 3), np.uint8)
    cv2.imwrite(str(tmp_path / "x_t1_rain.png"), img)
    cv2.imwrite(str(tmp_path / "y_clean.png"), img)
    with pytest.raises(RP.PairsError) as e:
        RP.find_pairs(tmp_path)
    assert "x_t1_rain.png: no clean partner" in str(e.value) and "y_clean.png: no rainy partner" in str(e.value)
    (tmp_path / "empty").mkdir()
    with pytest.raises(RP.PairsError, match="no pairs"):
        RP.find_pairs(tmp_path / "empty")


def test_group_of():
    assert RP.group_of("robotcar_i1600_t3") == "robotcar_i1600"
    assert RP.group_of("robotcar_i1600_t12") == "robotcar_i1600"
    assert RP.group_of("street_01") == "street_01"
    assert RP.group_of("_t3") == "_t3"


def test_default_split_is_half_the_groups_and_independent_of_order():
    groups = [f"robotcar_i{1600 * i}" for i in range(10)]
    split = RP.split_groups(groups)
    assert sum(v == "test" for v in split.values()) == 5
    for seed in range(5):
        shuffled = groups * 3
        random.Random(seed).shuffle(shuffled)
        assert RP.split_groups(shuffled) == split
    # the documented rule: SHA-256 order, every second group to test
    import hashlib

    order = sorted(groups, key=lambda g: hashlib.sha256(g.encode()).hexdigest())
    assert [split[g] for g in order] == ["train", "test"] * 5
    # odd counts and other fractions
    assert sum(v == "test" for v in RP.split_groups(groups[:7]).values()) == 3
    assert sum(v == "test" for v in RP.split_groups(groups, 0.3).values()) == 3
    assert set(RP.split_groups(groups, 0.0).values()) == {"train"}
    assert set(RP.split_groups(groups, 1.0).values()) == {"test"}


def test_explicit_holdout_and_pairs_of_a_group_stay_together(tmp_path):
    folder = write_pairs(tmp_path / "p", groups=4, per_group=3)
    pairs = RP.assign_splits(RP.find_pairs(folder), "scene1,scene3")
    assert {p.group for p in pairs if p.split == "test"} == {"scene1", "scene3"}
    pairs = RP.assign_splits(RP.find_pairs(folder))
    for g in {p.group for p in pairs}:
        assert len({p.split for p in pairs if p.group == g}) == 1
    with pytest.raises(RP.PairsError, match="unknown group"):
        RP.assign_splits(RP.find_pairs(folder), "scene9")
    with pytest.raises(RP.PairsError, match="fraction"):
        RP.split_groups(["a"], 1.5)


def test_rough_mask_finds_a_bright_blob_and_ignores_a_shift_and_noise():
    rng = np.random.default_rng(0)
    clean = np.clip(rng.normal(120, 3, (64, 80, 3)), 0, 255).astype(np.uint8)
    clean[:, 40:] += 40  # a vertical edge
    rainy = clean.copy()
    rainy[:, 1:] = clean[:, :-1]  # stereo offset of 1 px
    yy, xx = np.mgrid[0:64, 0:80]
    drop = (yy - 20) ** 2 + (xx - 20) ** 2 < 8**2
    rainy[drop] = np.clip(rainy[drop].astype(int) + 40, 0, 255)
    m = RP.rough_mask(rainy, clean)
    assert m.dtype == np.uint8 and set(np.unique(m)) <= {0, 255}
    inside = (m[drop] > 0).mean()
    assert inside > 0.9
    near = (yy - 20) ** 2 + (xx - 20) ** 2 < 11**2  # the blur spreads the drop by 2-3 px
    assert not m[~near].any()  # the shifted edge and the noise are not drops
    # parameters are honoured: a higher threshold than the drop's contrast finds nothing
    assert not RP.rough_mask(rainy, clean, threshold=60).any()
    # min_area removes small components
    small = clean.copy()
    small[5:7, 70:72] = 255
    assert RP.rough_mask(small, clean, blur=1, open_size=1, close_size=1, min_area=5).sum() == 0
    assert RP.rough_mask(small, clean, blur=1, open_size=1, close_size=1, min_area=1).sum() == 4 * 255


def test_prepare_writes_a_data_set_training_can_read(tmp_path):
    folder = write_pairs(tmp_path / "p", groups=4, per_group=2, rainy_suffix="_rainy")
    out = tmp_path / "ds"
    assert RP.main(["prepare", str(folder), "--out", str(out), "--mask-threshold", "10"]) == 0
    lines = [json.loads(x) for x in (out / "manifest.jsonl").read_text().splitlines()]
    assert [r["id"] for r in lines] == sorted(r["id"] for r in lines) and len(lines) == 8
    assert {r["source"] for r in lines} == {"real-pairs"}
    assert {r["split"] for r in lines} == {"train", "test"}
    assert all(r["mask_params"]["threshold"] == 10 for r in lines)
    info = json.loads((out / "realpairs.json").read_text())
    assert not set(info["groups"]["train"]) & set(info["groups"]["test"])
    samples = read_manifest(out, ["train"])
    assert len(samples) == 4
    # real pairs differ outside the mask: refused with the check, accepted without it
    with pytest.raises(ValueError, match="outside the mask"):
        check_files(read_manifest(out), check_outside_mask=True)
    ds = RaindropDataset(out, crop=32, splits=["test"], check_outside_mask=False)
    item = ds[0]
    assert item["rainy"].shape == (3, 32, 32) and set(np.unique(item["mask"])) <= {0.0, 1.0}
    # refuses to write over an existing set
    assert RP.main(["prepare", str(folder), "--out", str(out)]) == 2


def test_prepare_writes_all_or_nothing_and_never_over_files(tmp_path, capsys):
    """A pair that failed after others left rainy/clean/mask images without a manifest, and a
    user's file in --out was replaced; --out as a file was a traceback."""
    import cv2

    folder = write_pairs(tmp_path / "p", groups=3, per_group=1)
    clean = sorted(folder.glob("*_clean.png"))[-1]
    cv2.imwrite(str(clean), np.zeros((7, 9, 3), np.uint8))  # the last pair's sizes differ
    out = tmp_path / "ds"
    assert RP.main(["prepare", str(folder), "--out", str(out)]) == 2
    assert "differ" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p"], "nothing left behind"
    clean.unlink()
    (folder / clean.name.replace("_clean", "_rain")).unlink()
    mine = out / "rainy" / "scene0_t0.png"
    mine.parent.mkdir(parents=True)
    mine.write_bytes(b"a user's file")
    assert RP.main(["prepare", str(folder), "--out", str(out)]) == 2
    assert "is not empty" in capsys.readouterr().err
    assert mine.read_bytes() == b"a user's file"
    (tmp_path / "afile").write_text("x")
    assert RP.main(["prepare", str(folder), "--out", str(tmp_path / "afile")]) == 2
    assert "is not a folder" in capsys.readouterr().err
    (tmp_path / "empty").mkdir()
    assert RP.main(["prepare", str(folder), "--out", str(tmp_path / "empty")]) == 0
    assert len((tmp_path / "empty" / "manifest.jsonl").read_text().splitlines()) == 2


def test_list_command(tmp_path, capsys):
    folder = write_pairs(tmp_path / "p", groups=2, per_group=1)
    assert RP.main(["list", str(folder), "--holdout", "scene0"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out == ["test\tscene0\tscene0_t0\tscene0_t0_rain.png\tscene0_t0_clean.png",
                   "train\tscene1\tscene1_t0\tscene1_t0_rain.png\tscene1_t0_clean.png"]


def test_the_shared_real_pairs_split_is_the_one_the_cpp_test_names():
    """tests/remove/test_trained_models.cpp (TrainedModels.DefaultRemovesRealLensCoverDrops)
    names the test groups of the shared real pairs itself; the rule must still give those."""
    groups = [f"robotcar_i{n}" for n in (0, 1600, 3200, 4800, 6400, 8000, 9600, 11200, 12800, 14400)]
    split = RP.split_groups(groups)
    assert sorted(g for g, s in split.items() if s == "test") == [
        "robotcar_i0", "robotcar_i14400", "robotcar_i4800", "robotcar_i8000", "robotcar_i9600"]
