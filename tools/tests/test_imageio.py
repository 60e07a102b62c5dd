"""The tools read an image as raindrop-remove does (docs/CONTRACTS.md section 1)."""

import numpy as np
import pytest

from raindrop_tools.imageio import ImageError, read_mask, read_rgb, read_rgb_native


@pytest.mark.parametrize("orientation", range(1, 9))
def test_a_tiff_turned_by_its_exif_orientation_reads_upright(tmp_path, orientation):
    # OpenCV 5.0's imread fails inside on orientations 5-8 (its TIFF decoder turns the image and
    # imread refuses sides other than the header's); the tools then decode the file's bytes.
    image_module = pytest.importorskip("PIL.Image")
    ops = pytest.importorskip("PIL.ImageOps")
    rgb = (np.arange(10 * 14 * 3) * 37 % 251).astype(np.uint8).reshape(10, 14, 3)
    exif = image_module.Exif()
    exif[0x0112] = orientation
    path = tmp_path / f"o{orientation}.tif"
    image_module.fromarray(rgb).save(path, exif=exif)
    upright = np.asarray(ops.exif_transpose(image_module.open(path)))
    assert upright.shape[:2] == ((14, 10) if orientation >= 5 else (10, 14))
    np.testing.assert_array_equal(read_rgb(path), upright)
    native = read_rgb_native(path)
    assert native.dtype == np.uint8
    np.testing.assert_array_equal(native, upright)
    assert read_mask(path).shape == upright.shape[:2]


def test_files_that_are_not_images_are_still_refused_in_one_line(tmp_path):
    for name, data in [("x.tif", b"II*\0" + b"\0" * 12), ("y.png", b"not a png"), ("z.tif", b"")]:
        (tmp_path / name).write_bytes(data)
        with pytest.raises(ImageError, match="cannot read image"):
            read_rgb(tmp_path / name)
    with pytest.raises(ImageError, match="cannot read image"):
        read_rgb(tmp_path / "missing.tif")
    with pytest.raises(ImageError, match="cannot read image"):
        read_rgb(tmp_path)  # a folder
