"""Image reading/writing and the two value conversions every part shares.

Images are 8-bit sRGB-encoded values; all arithmetic is on those values scaled to [0, 1]
(CONTRACTS.md section 1). ``to_float`` and ``to_uint8`` are the only places where that
scaling happens, so training, the reference pipeline and evaluation agree bit for bit.
numpy + OpenCV only (no torch).
"""

from __future__ import annotations

import os
import struct
from pathlib import Path

import cv2
import numpy as np

from .read_only import read_only_problem

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
# TIFF and BigTIFF, little- and big-endian.
_TIFF_SIGNATURES = (b"II*\0", b"MM\0*", b"II+\0", b"MM\0+")

# OpenCV's own log lines ("[ WARN:0@0.1] global loadsave.cpp ... findDecoder ...") came before
# the tools' one-line errors, which say the same in the tools' words. $OPENCV_LOG_LEVEL, where a
# user sets it, still decides.
if "OPENCV_LOG_LEVEL" not in os.environ:
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)


class ImageError(ValueError):
    """An image that cannot be read or does not have the expected format."""


# Extensions of the image files the tools take from a folder of photographs or frames.
IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp"}


def to_float(img_u8: np.ndarray) -> np.ndarray:
    """uint8 -> float32 in [0, 1]: ``x / 255`` computed in float32 (correctly rounded)."""
    if img_u8.dtype != np.uint8:
        raise TypeError(f"expected uint8, got {img_u8.dtype}")
    return img_u8.astype(np.float32) / np.float32(255.0)


def to_uint8(img: np.ndarray) -> np.ndarray:
    """float in [0, 1] (any range; clamped) -> uint8: ``floor(clamp(x, 0, 1) * 255 + 0.5)`` in
    float32, i.e. round half up. C++ must do the same: ``(uint8_t)std::floor(v * 255.f + 0.5f)``
    after clamping."""
    x = np.clip(np.asarray(img, dtype=np.float32), np.float32(0.0), np.float32(1.0))
    return np.floor(x * np.float32(255.0) + np.float32(0.5)).astype(np.uint8)


def _imread(path: str | os.PathLike, flags: int) -> np.ndarray | None:
    """cv2.imread, and where it fails on a file that exists, cv2.imdecode of the file's bytes.
    The pinned OpenCV (5.0) fails inside imread on a TIFF whose EXIF orientation turns it (5-8:
    its decoder turns the image, and imread refuses a result of other sides than the header's);
    imdecode returns the same pixels turned upright, as raindrop-remove reads them."""
    try:  # cv2.error: a header OpenCV's decoder refuses by raising (a TIFF of absurd sides)
        img = cv2.imread(str(path), flags)
    except cv2.error:
        img = None
    if img is not None:
        return img
    try:
        with open(path, "rb") as f:
            if f.read(4) not in _TIFF_SIGNATURES:  # only TIFFs: no other file read whole
                return None
        data = np.fromfile(str(path), dtype=np.uint8)
        return cv2.imdecode(data, flags)
    except (OSError, ValueError, cv2.error):  # missing, a folder, unreadable, refused
        return None


def _read_upright(path: str | os.PathLike, flags: int) -> np.ndarray:
    """cv2.imread with `flags`, RGB. PNG is read as stored, eXIf chunk or not, as raindrop-remove
    reads it (JPEG and TIFF are turned upright by both)."""
    if str(path).lower().endswith(".png"):
        flags |= cv2.IMREAD_IGNORE_ORIENTATION
    img = _imread(path, flags)
    if img is None:
        raise ImageError(f"{path}: cannot read image (missing or not an image)")
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


def read_rgb(path: str | os.PathLike) -> np.ndarray:
    """Any image OpenCV reads -> HxWx3 uint8 RGB. Grey images are replicated, an alpha channel
    is dropped, 16-bit images are reduced to 8 bits (OpenCV's IMREAD_COLOR conversion)."""
    return _read_upright(path, cv2.IMREAD_COLOR)


def read_rgb_native(path: str | os.PathLike) -> np.ndarray:
    """Any image OpenCV reads -> HxWx3 RGB at its own depth (uint8, uint16 or float32), as
    raindrop-remove reads it: grey replicated, alpha dropped, JPEG and TIFF turned upright, PNG
    as stored."""
    return _read_upright(path, cv2.IMREAD_COLOR | cv2.IMREAD_ANYDEPTH)


def native_to_float(img: np.ndarray) -> np.ndarray:
    """read_rgb_native's pixels -> float32 in [0, 1] as raindrop-remove converts them (v / 255 or
    v / 65535 in float32; float clamped, NaN -> 0; include/raindrop/remove/pixels.h)."""
    if img.dtype == np.uint8:
        return to_float(img)
    if img.dtype == np.uint16:
        return img.astype(np.float32) / np.float32(65535.0)
    return np.clip(np.nan_to_num(img.astype(np.float32), nan=0.0), np.float32(0.0), np.float32(1.0))


def read_rgb_strict(path: str | os.PathLike) -> np.ndarray:
    """Data-set image: must be 8-bit, 3 channels (RGB). -> HxWx3 uint8 RGB."""
    img = _imread(path, cv2.IMREAD_UNCHANGED)
    if img is None:
        raise ImageError(f"{path}: cannot read image (missing or not an image)")
    if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] != 3:
        raise ImageError(f"{path}: expected 8-bit RGB, got dtype {img.dtype} shape {img.shape}")
    if str(path).lower().endswith((".jpg", ".jpeg")):
        # IMREAD_UNCHANGED ignores a JPEG's EXIF orientation; IMREAD_COLOR applies it, as
        # raindrop-remove and raindrop-render do (the same pixels, upright).
        img = _imread(path, cv2.IMREAD_COLOR)
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


def read_mask_strict(path: str | os.PathLike) -> np.ndarray:
    """Data-set mask: must be 8-bit single channel. -> HxW uint8 (values not checked here)."""
    img = _imread(path, cv2.IMREAD_UNCHANGED)
    if img is None:
        raise ImageError(f"{path}: cannot read image (missing or not an image)")
    if img.dtype != np.uint8 or img.ndim != 2:
        raise ImageError(f"{path}: expected an 8-bit single-channel mask, got dtype {img.dtype} shape {img.shape}")
    return img


def read_mask(path: str | os.PathLike) -> np.ndarray:
    """Lenient mask reader (e.g. a mask a user passes): any image -> HxW uint8 grey."""
    img = _imread(path, cv2.IMREAD_GRAYSCALE)
    if img is None:
        raise ImageError(f"{path}: cannot read image (missing or not an image)")
    return img


def check_writable(path: str | os.PathLike) -> None:
    """Raises ImageError if OpenCV has no writer for ``path``'s extension, or ``path`` is a
    folder: for checking every destination before the work, so that a bad second one does not
    leave the first written."""
    if Path(path).is_dir():
        raise ImageError(f"{path}: is a folder, not an image file")
    if not cv2.haveImageWriter(str(path)):
        raise ImageError(f"{path}: cannot write this format (no writer for '{Path(path).suffix}')")
    _keep_read_only(path)


def _keep_read_only(path: str | os.PathLike) -> None:
    """Root may write any file; a read-only one is kept (read_only.py), as an ImageError."""
    problem = read_only_problem(path)
    if problem:
        raise ImageError(problem)


def _imwrite(path: str | os.PathLike, image: np.ndarray) -> None:
    _keep_read_only(path)
    # OpenCV raises cv2.error for an extension it has no writer for, returns False otherwise.
    try:
        ok = cv2.imwrite(str(path), image)
    except cv2.error as e:
        raise ImageError(f"{path}: cannot write image ({str(e).strip().splitlines()[-1]})") from e
    if not ok:
        raise ImageError(f"{path}: cannot write image")


def write_rgb(path: str | os.PathLike, rgb_u8: np.ndarray) -> None:
    if rgb_u8.dtype != np.uint8 or rgb_u8.ndim != 3 or rgb_u8.shape[2] != 3:
        raise ImageError(f"write_rgb: expected HxWx3 uint8, got {rgb_u8.dtype} {rgb_u8.shape}")
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    _imwrite(path, cv2.cvtColor(rgb_u8, cv2.COLOR_RGB2BGR))


def write_grey(path: str | os.PathLike, grey_u8: np.ndarray) -> None:
    if grey_u8.dtype != np.uint8 or grey_u8.ndim != 2:
        raise ImageError(f"write_grey: expected HxW uint8, got {grey_u8.dtype} {grey_u8.shape}")
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    _imwrite(path, grey_u8)


def png_header(path: str | os.PathLike) -> tuple[int, int, int, int]:
    """(width, height, bit depth, colour type) from a PNG's IHDR chunk without decoding.
    Colour types: 0 grey, 2 RGB, 3 palette, 4 grey+alpha, 6 RGBA."""
    with open(path, "rb") as f:
        head = f.read(33)
    if len(head) < 33 or head[:8] != _PNG_SIGNATURE or head[12:16] != b"IHDR":
        raise ImageError(f"{path}: not a PNG file")
    width, height, depth, colour = struct.unpack(">IIBB", head[16:26])
    return width, height, depth, colour
