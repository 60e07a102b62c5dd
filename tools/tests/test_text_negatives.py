"""Lettering drawn onto drop-free images (text_negatives.py): deterministic, visible, within the
image's range; and the damage measure counts what a remover changed."""
import random

import cv2
import numpy as np

from raindrop_tools import text_negatives as T


def test_lettering_is_drawn_the_same_for_a_seed_and_changes_the_image():
    image = np.full((128, 192, 3), 200, np.uint8)
    a = T.draw_text(image, random.Random(4))
    b = T.draw_text(image, random.Random(4))
    c = T.draw_text(image, random.Random(5))
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    assert a.dtype == np.uint8 and a.shape == image.shape
    changed = np.abs(a.astype(int) - image).max(axis=2) > 20
    assert 0.001 < changed.mean() < 0.9
    assert np.array_equal(image, np.full((128, 192, 3), 200, np.uint8))  # the input is left alone


def test_damage_is_the_cap_for_untouched_outputs_and_counts_changed_ones(tmp_path):
    inputs, outputs, masks = tmp_path / "in", tmp_path / "out", tmp_path / "masks"
    for d in (inputs, outputs, masks):
        d.mkdir()
    rng = np.random.default_rng(0)
    for i in range(4):
        im = rng.integers(0, 255, (32, 48, 3), dtype=np.uint8)
        cv2.imwrite(str(inputs / f"{i}.png"), im)
        out, mask = im.copy(), np.zeros((32, 48), np.uint8)
        if i == 0:
            out[:8, :8] = 0
            mask[:8, :8] = 255
        cv2.imwrite(str(outputs / f"{i}.png"), out)
        cv2.imwrite(str(masks / f"{i}.png"), mask)
    r = T.damage(inputs, outputs, masks)
    assert r["images"] == 4 and r["changed"] == 0.25
    assert r["psnr_y"] < 100.0 and r["psnr_y"] > 75.0  # three at the cap, one lower
    assert abs(r["marked"] - 64 / (32 * 48) / 4) < 1e-9


def test_make_keeps_a_read_only_file_and_writes_nothing(tmp_path):
    import os

    import pytest

    from raindrop_tools.read_only import ReadOnlyFileError

    src, out = tmp_path / "src", tmp_path / "out"
    src.mkdir()
    out.mkdir()
    for name in ("a", "b"):
        cv2.imwrite(str(src / f"{name}.png"), np.full((64, 96, 3), 120, np.uint8))
    (out / "b.png").write_bytes(b"keep me")
    os.chmod(out / "b.png", 0o444)
    with pytest.raises(ReadOnlyFileError):
        T.make_set(sorted(src.iterdir()), out, size=None)
    assert sorted(p.name for p in out.iterdir()) == ["b.png"] and (out / "b.png").read_bytes() == b"keep me"


def test_make_refuses_its_images_own_folder_a_name_twice_and_a_damaged_image_before_writing(tmp_path):
    import pytest

    src = tmp_path / "src"
    (src / "sub").mkdir(parents=True)
    for name in ("a", "b"):
        cv2.imwrite(str(src / f"{name}.png"), np.full((64, 96, 3), 120, np.uint8))
    before = {p.name: p.read_bytes() for p in src.glob("*.png")}
    files = sorted(src.glob("*.png"))
    # Into the images' own folder: the originals were replaced. A folder above it holds none.
    with pytest.raises(OSError, match="the images' own folder"):
        T.make_set(files, src, size=None)
    assert {p.name: p.read_bytes() for p in src.glob("*.png")} == before
    assert T.make_set(files, tmp_path, size=None, lettering=False) == 2
    # a.png and a.jpg: one output overwrote the other, and both were counted.
    cv2.imwrite(str(src / "sub" / "a.jpg"), np.full((64, 96, 3), 60, np.uint8))
    with pytest.raises(OSError, match="would both be written"):
        T.make_set([src / "a.png", src / "sub" / "a.jpg"], tmp_path / "out1", size=None)
    assert not (tmp_path / "out1").exists()
    # A damaged image: nothing written (8 of 20 were, before).
    (src / "c.png").write_bytes(b"\x89PNG\r\n\x1a\n broken")
    with pytest.raises(Exception):
        T.make_set([src / "a.png", src / "b.png", src / "c.png"], tmp_path / "out2", size=None)
    assert not (tmp_path / "out2").exists()


def test_make_into_a_folder_of_an_earlier_larger_set_is_refused(tmp_path):
    # Four lettered images, then a baseline of two into the same folder: it said "2 images" and
    # left two lettered ones for 'damage' to score as baseline.
    import pytest

    src = tmp_path / "src"
    src.mkdir()
    for i in range(4):
        cv2.imwrite(str(src / f"f{i}.png"), np.full((64, 96, 3), 40 * i + 20, np.uint8))
    files = sorted(src.glob("*.png"))
    assert T.make_set(files, tmp_path / "neg", size=None) == 4
    before = {p.name: p.read_bytes() for p in (tmp_path / "neg").glob("*.png")}
    with pytest.raises(OSError, match="holds 2 PNG image"):
        T.make_set(files[:2], tmp_path / "neg", size=None, lettering=False)
    assert {p.name: p.read_bytes() for p in (tmp_path / "neg").glob("*.png")} == before
    assert T.make_set(files, tmp_path / "neg", size=None, lettering=False) == 4  # the same set again: fine


def test_damage_refuses_a_mask_of_another_size(tmp_path):
    import pytest

    for d in ("in", "out", "masks"):
        (tmp_path / d).mkdir()
    im = np.full((32, 48, 3), 90, np.uint8)
    cv2.imwrite(str(tmp_path / "in" / "0.png"), im)
    cv2.imwrite(str(tmp_path / "out" / "0.png"), im)
    cv2.imwrite(str(tmp_path / "masks" / "0.png"), np.full((2, 2), 255, np.uint8))
    with pytest.raises(SystemExit, match="the mask is 2x2, the image 48x32"):
        T.damage(tmp_path / "in", tmp_path / "out", tmp_path / "masks")
