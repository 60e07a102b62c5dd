import json
import shutil

import cv2
import numpy as np
import pytest

from helpers import write_dataset
from raindrop_tools.data import DatasetError, RaindropDataset, StepBatchSampler, read_manifest
from raindrop_tools.edge import edge_map_numpy
from raindrop_tools.imageio import to_float


def test_reads_the_contract_format(tiny_dataset):
    ds = RaindropDataset(tiny_dataset, crop=32)
    assert len(ds) == 6
    assert ds.sizes == [(48, 64)] * 6
    item = ds[(2, 5, 9, False)]
    assert item["id"] == ds.samples[2].id
    assert item["rainy"].shape == (3, 32, 32) and item["rainy"].dtype == np.float32
    assert item["clean"].shape == (3, 32, 32)
    assert item["mask"].shape == (1, 32, 32) and set(np.unique(item["mask"])) <= {0.0, 1.0}
    assert item["edge"].shape == (1, 32, 32)
    rainy, clean, mask = ds.load(2)
    np.testing.assert_array_equal(item["rainy"], to_float(rainy[5:37, 9:41]).transpose(2, 0, 1))
    np.testing.assert_array_equal(item["clean"], to_float(clean[5:37, 9:41]).transpose(2, 0, 1))
    np.testing.assert_array_equal(item["mask"][0], (mask[5:37, 9:41] > 0).astype(np.float32))
    # the edge map is the full image's, cropped (not the crop's own: the crop's border differs)
    full = edge_map_numpy(to_float(rainy))
    np.testing.assert_array_equal(item["edge"][0], full[5:37, 9:41])
    assert not np.array_equal(item["edge"][0], edge_map_numpy(to_float(rainy[5:37, 9:41])))


def test_flip_flips_everything_consistently(tiny_dataset):
    ds = RaindropDataset(tiny_dataset, crop=32, cache=True)
    a, b = ds[(1, 3, 7, False)], ds[(1, 3, 7, True)]
    for k in ("rainy", "clean", "mask", "edge"):
        np.testing.assert_array_equal(b[k], a[k][:, :, ::-1])


def test_plain_index_gives_a_random_crop(tiny_dataset):
    ds = RaindropDataset(tiny_dataset, crop=16, validate="header")
    item = ds[0]
    assert item["rainy"].shape == (3, 16, 16)


def test_splits_filter(tmp_path):
    root = write_dataset(tmp_path / "d", n=4, h=20, w=20, splits=("train", "test"))
    assert len(read_manifest(root, ["train"])) == 2
    assert len(read_manifest(root, None)) == 4
    with pytest.raises(DatasetError, match="no samples"):
        read_manifest(root, ["val"])


def test_a_split_filter_says_what_it_leaves_out(tmp_path):
    # CamVid frames carry split "none": a [train] filter kept 36 of 2844 samples without a word
    root = write_dataset(tmp_path / "d", n=6, h=20, w=20, splits=("train", "none", "none"))
    said = []
    ds = RaindropDataset(root, crop=16, splits=["train"], validate="header", log=said.append)
    assert len(ds) == 2
    assert len(said) == 1 and "keep 2 of 6 samples; left out: 'none' x 4" in said[0]
    said.clear()
    RaindropDataset(root, crop=16, splits=["train", "none"], validate="header", log=said.append)
    RaindropDataset(root, crop=16, splits=None, validate="header", log=said.append)
    assert said == []  # nothing left out, nothing said


def test_training_refuses_held_out_real_pairs_unless_their_split_is_named(tmp_path):
    # A user's own pairs, prepared by realpairs with a test split, trained on with no split named:
    # 'evaluate --split test' then scored pairs the model had trained on, without a word.
    root = write_dataset(tmp_path / "d", n=4, h=20, w=20, splits=("train", "test"))
    lines = [json.loads(t) for t in (root / "manifest.jsonl").read_text().splitlines()]
    (root / "manifest.jsonl").write_text("".join(json.dumps({**r, "source": "real-pairs"}) + "\n" for r in lines))
    with pytest.raises(DatasetError, match="2 of its real pairs are in the 'test' split"):
        RaindropDataset(root, crop=16, validate="header")
    assert len(RaindropDataset(root, crop=16, splits=["train"], validate="header")) == 2
    assert len(RaindropDataset(root, crop=16, splits=["train", "test"], validate="header")) == 4
    assert len(read_manifest(root, None)) == 4  # reading (evaluate, stats) is not training
    # rendered sets' splits are their backgrounds' (Cityscapes' test frames): not refused
    rendered = write_dataset(tmp_path / "r", n=4, h=20, w=20, splits=("train", "test"))
    assert len(RaindropDataset(rendered, crop=16, validate="header")) == 4


def test_real_pairs_source_name_is_realpairs_own():
    from raindrop_tools import data, realpairs

    assert data.REAL_PAIRS_SOURCE == realpairs.SOURCE


def test_step_sampler_is_a_pure_function_of_the_step():
    sizes = [(48, 64)] * 5 + [(40, 50)] * 2
    a = StepBatchSampler(sizes, 32, 3, seed=1, stage=1, total_steps=10)
    b = StepBatchSampler(sizes, 32, 3, seed=1, stage=1, total_steps=10, start_step=6)
    steps_a = list(a)
    assert len(steps_a) == 10 and list(b) == steps_a[6:]
    # without replacement within an epoch: the first 7 draws (steps 0-1 and one of step 2) are distinct
    first = [k[0] for step in steps_a for k in step][:7]
    assert sorted(first) == list(range(7))
    for step in steps_a:
        for i, y0, x0, flip in step:
            h, w = sizes[i]
            assert 0 <= y0 <= h - 32 and 0 <= x0 <= w - 32 and isinstance(flip, bool)
    assert list(StepBatchSampler(sizes, 32, 3, seed=2, stage=1, total_steps=10)) != steps_a
    assert list(StepBatchSampler(sizes, 32, 3, seed=1, stage=2, total_steps=10)) != steps_a


# ---------------------------------------------------------------- refusals


def _copy(tiny_dataset, tmp_path):
    root = tmp_path / "ds"
    shutil.copytree(tiny_dataset, root)
    return root


def _lines(root):
    return (root / "manifest.jsonl").read_text().splitlines()


def _write_lines(root, lines):
    (root / "manifest.jsonl").write_text("\n".join(lines) + "\n")


def _edit_record(root, index, **changes):
    lines = _lines(root)
    rec = json.loads(lines[index])
    for k, v in changes.items():
        if v is None:
            del rec[k]
        else:
            rec[k] = v
    lines[index] = json.dumps(rec)
    _write_lines(root, lines)
    return rec


def _refused(root, *patterns, crop=32):
    with pytest.raises(DatasetError) as e:
        RaindropDataset(root, crop=crop)
    msg = str(e.value)
    for p in patterns:
        assert p in msg, f"{p!r} not in:\n{msg}"
    return msg


def test_refuses_unparsable_line(tiny_dataset, tmp_path):
    root = _copy(tiny_dataset, tmp_path)
    lines = _lines(root)
    lines[2] = lines[2][:-5]
    _write_lines(root, lines)
    _refused(root, "manifest.jsonl:3", "not valid JSON")


def test_refuses_missing_keys(tiny_dataset, tmp_path):
    root = _copy(tiny_dataset, tmp_path)
    _edit_record(root, 1, mask=None, width=None)
    _refused(root, "manifest.jsonl:2", "missing key(s) mask, width")


def test_refuses_wrong_types(tiny_dataset, tmp_path):
    root = _copy(tiny_dataset, tmp_path)
    _edit_record(root, 0, width="64")
    _refused(root, "manifest.jsonl:1", "width (expected int, got str)")


def test_refuses_missing_files(tiny_dataset, tmp_path):
    root = _copy(tiny_dataset, tmp_path)
    rec = json.loads(_lines(root)[4])
    (root / rec["clean"]).unlink()
    _refused(root, "manifest.jsonl:5", "missing file", rec["clean"])


def test_refuses_size_mismatch(tiny_dataset, tmp_path):
    root = _copy(tiny_dataset, tmp_path)
    rec = json.loads(_lines(root)[3])
    mask = cv2.imread(str(root / rec["mask"]), cv2.IMREAD_UNCHANGED)
    cv2.imwrite(str(root / rec["mask"]), mask[:-1])
    _refused(root, "manifest.jsonl:4", "size mismatch", "mask 64x47")
    # the header-only level catches it too
    with pytest.raises(DatasetError, match="size mismatch"):
        RaindropDataset(root, crop=32, validate="header")


def test_refuses_manifest_size_disagreeing_with_images(tiny_dataset, tmp_path):
    root = _copy(tiny_dataset, tmp_path)
    _edit_record(root, 0, width=65)
    _refused(root, "manifest.jsonl:1", "size mismatch")


def test_refuses_non_binary_mask(tiny_dataset, tmp_path):
    root = _copy(tiny_dataset, tmp_path)
    rec = json.loads(_lines(root)[2])
    mask = cv2.imread(str(root / rec["mask"]), cv2.IMREAD_UNCHANGED)
    mask[0, 0] = 128
    cv2.imwrite(str(root / rec["mask"]), mask)
    _refused(root, "manifest.jsonl:3", "not binary", "128")


def test_refuses_rgb_mask(tiny_dataset, tmp_path):
    root = _copy(tiny_dataset, tmp_path)
    rec = json.loads(_lines(root)[2])
    mask = cv2.imread(str(root / rec["mask"]), cv2.IMREAD_UNCHANGED)
    cv2.imwrite(str(root / rec["mask"]), cv2.cvtColor(mask, cv2.COLOR_GRAY2BGR))
    _refused(root, "manifest.jsonl:3", "single-channel")


def test_refuses_duplicate_ids(tiny_dataset, tmp_path):
    root = _copy(tiny_dataset, tmp_path)
    lines = _lines(root)
    first = json.loads(lines[0])["id"]
    _edit_record(root, 3, id=first)
    _refused(root, "manifest.jsonl:4", f"duplicate id '{first}'", "first on line 1")


def test_refuses_images_smaller_than_the_crop(tiny_dataset, tmp_path):
    root = _copy(tiny_dataset, tmp_path)
    _refused(root, "smaller than the 50x50 crop", crop=50)


def test_refuses_rainy_differing_from_clean_outside_the_mask(tiny_dataset, tmp_path):
    root = _copy(tiny_dataset, tmp_path)
    rec = json.loads(_lines(root)[5])
    mask = cv2.imread(str(root / rec["mask"]), cv2.IMREAD_UNCHANGED)
    rainy = cv2.imread(str(root / rec["rainy"]), cv2.IMREAD_UNCHANGED)
    y, x = np.argwhere(mask == 0)[0]
    rainy[y, x] = 255 - rainy[y, x]
    cv2.imwrite(str(root / rec["rainy"]), rainy)
    _refused(root, "manifest.jsonl:6", "outside the mask")
    # can be switched off (e.g. for real pairs with rough masks)
    assert len(RaindropDataset(root, crop=32, check_outside_mask=False)) == 6


def test_refuses_paths_outside_the_data_set(tiny_dataset, tmp_path):
    root = _copy(tiny_dataset, tmp_path)
    _edit_record(root, 0, rainy="../elsewhere.png")
    _refused(root, "manifest.jsonl:1", "must be relative to the data set folder")


def test_refuses_missing_manifest(tmp_path):
    with pytest.raises(DatasetError, match="no manifest.jsonl"):
        RaindropDataset(tmp_path, crop=8)


def test_lists_every_problem(tiny_dataset, tmp_path):
    root = _copy(tiny_dataset, tmp_path)
    for i in (1, 4):
        (root / json.loads(_lines(root)[i])["rainy"]).unlink()
    msg = _refused(root, "2 problem(s)", "manifest.jsonl:2", "manifest.jsonl:5")
    assert msg.count("missing file") == 2


def test_visible_difference_keeps_what_a_drop_visibly_changes():
    from raindrop_tools.data import visible_difference

    clean = np.full((40, 40, 3), 100, np.uint8)
    rainy = clean.copy()
    rainy[10:30, 10:20] = 130  # +30 levels: visible
    rainy[10:30, 25:35] = 103  # +3 levels: a faint halo
    v = visible_difference(rainy, clean, 6)
    assert v.dtype == np.float32 and set(np.unique(v)) <= {0.0, 1.0}
    assert v[20, 15] == 1 and v[20, 30] == 0 and v[5, 5] == 0
    # the 5x5 box blur widens it where the averaged difference still exceeds 6 levels:
    # 2 of 5 columns at +30 average +12 (x = 9), 1 of 5 only +6 (x = 8)
    assert v[20, 9] == 1 and v[20, 8] == 0


def test_visible_levels_narrow_the_training_mask_to_visible_pixels(tmp_path):
    from raindrop_tools.data import visible_difference

    root = write_dataset(tmp_path / "d", n=2, h=48, w=64)
    plain = RaindropDataset(root, crop=48, flip=False)
    visible = RaindropDataset(root, crop=48, flip=False, visible_levels=6)
    a, b = plain[(0, 0, 0, False)], visible[(0, 0, 0, False)]
    rainy, clean, _ = plain.load(0)
    expect = a["mask"][0] * visible_difference(rainy[:, :48], clean[:, :48], 6)
    assert np.array_equal(b["mask"][0], expect)
    assert b["mask"].sum() <= a["mask"].sum()
    assert np.array_equal(a["rainy"], b["rainy"]) and np.array_equal(a["clean"], b["clean"])


def test_visible_levels_are_validated():
    from raindrop_tools.config import ConfigError, config_from_dict

    with pytest.raises(ConfigError, match="visible_levels"):
        config_from_dict({"data": {"sources": [{"path": "x", "visible_levels": -1}]}})


def test_a_manifest_that_is_not_text_is_named_in_one_error(tmp_path):
    """A manifest.jsonl that is not UTF-8 (a binary file by that name) raised UnicodeDecodeError,
    a traceback in train and an error without the file's name in evaluate."""
    (tmp_path / "manifest.jsonl").write_bytes(b'{"id": "a"}\n\xff\xfe\x00binary\n')
    with pytest.raises(DatasetError, match=r"manifest\.jsonl: not UTF-8 text \(byte 12\)"):
        read_manifest(tmp_path)
