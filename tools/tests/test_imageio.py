"""The tools turn an image by its EXIF orientation as the EXIF standard says (Pillow's
exif_transpose is the yardstick here), which is what raindrop-remove does (docs/CONTRACTS.md
section 1; the two were compared by hand, the program with --threshold 1 --keep-outside-mask)."""

import struct

import numpy as np
import pytest

from raindrop_tools.imageio import ImageError, read_mask, read_rgb, read_rgb_native


@pytest.mark.parametrize("orientation", range(1, 9))
@pytest.mark.parametrize("big_tiff", [False, True])
def test_a_tiff_turned_by_its_exif_orientation_reads_upright(tmp_path, orientation, big_tiff):
    # OpenCV 5.0's imread fails inside on orientations 5-8 (its TIFF decoder turns the image and
    # imread refuses sides other than the header's); the tools then decode the file's bytes.
    image_module = pytest.importorskip("PIL.Image")
    ops = pytest.importorskip("PIL.ImageOps")
    rgb = (np.arange(10 * 14 * 3) * 37 % 251).astype(np.uint8).reshape(10, 14, 3)
    exif = image_module.Exif()
    exif[0x0112] = orientation
    path = tmp_path / f"o{orientation}.tif"
    image_module.fromarray(rgb).save(path, exif=exif, big_tiff=big_tiff)
    assert path.read_bytes()[:4] in ((b"II+\0",) if big_tiff else (b"II*\0",))
    upright = np.asarray(ops.exif_transpose(image_module.open(path)))
    assert upright.shape[:2] == ((14, 10) if orientation >= 5 else (10, 14))
    np.testing.assert_array_equal(read_rgb(path), upright)
    native = read_rgb_native(path)
    assert native.dtype == np.uint8
    np.testing.assert_array_equal(native, upright)
    assert read_mask(path).shape == upright.shape[:2]


@pytest.mark.parametrize("orientation", [1, 6])
def test_a_16_bit_grey_tiff_reads_upright_at_its_depth(tmp_path, orientation):
    # Pillow's exif_transpose leaves 16-bit grey as stored, so the yardstick is numpy's: 6 is a
    # quarter turn clockwise.
    image_module = pytest.importorskip("PIL.Image")
    grey = (np.arange(10 * 14, dtype=np.uint16) * 401).reshape(10, 14)
    exif = image_module.Exif()
    exif[0x0112] = orientation
    path = tmp_path / f"g{orientation}.tif"
    image_module.fromarray(grey).save(path, exif=exif)
    upright = np.rot90(grey, k=-1) if orientation == 6 else grey
    native = read_rgb_native(path)
    assert native.dtype == np.uint16 and native.shape == upright.shape + (3,)
    for c in range(3):
        np.testing.assert_array_equal(native[..., c], upright)


def test_files_that_are_not_images_are_still_refused_in_one_line(tmp_path):
    for name, data in [("x.tif", b"II*\0" + b"\0" * 12), ("b.tif", b"II+\0" + b"\0" * 12), ("y.png", b"not a png"),
                       ("z.tif", b"")]:
        (tmp_path / name).write_bytes(data)
        with pytest.raises(ImageError, match="cannot read image"):
            read_rgb(tmp_path / name)
    with pytest.raises(ImageError, match="cannot read image"):
        read_rgb(tmp_path / "missing.tif")
    with pytest.raises(ImageError, match="cannot read image"):
        read_rgb(tmp_path)  # a folder


def test_a_tiff_of_absurd_sides_is_refused_in_one_line(tmp_path):
    # OpenCV raises cv2.error from imread for a header claiming 2^30 x 2^30 pixels.
    entries = [(256, 4, 1, 1 << 30), (257, 4, 1, 1 << 30), (258, 3, 1, 8), (259, 3, 1, 1), (262, 3, 1, 1),
               (273, 4, 1, 8 + 2 + 12 * 8 + 4), (278, 4, 1, 1 << 30), (279, 4, 1, 16)]
    data = b"II*\0" + struct.pack("<IH", 8, len(entries))
    data += b"".join(struct.pack("<HHII", *e) for e in entries) + struct.pack("<I", 0) + b"\0" * 16
    (tmp_path / "huge.tif").write_bytes(data)
    with pytest.raises(ImageError, match="cannot read image"):
        read_rgb(tmp_path / "huge.tif")
