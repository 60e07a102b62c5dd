"""Street frames made piecewise flat, as backgrounds the detector must not take for drops.

    python -m raindrop_tools.flatten <camvid>/train data/flat-frames --limit 300

Real camera frames always carry some noise and texture; a region with none at all (graphics,
heavily compressed JPEG, denoised camera output, the renderer's own demo street) is out of what
models trained on camera frames have seen, and the fine-tuned detectors took such regions for
drops (docs/RESULTS.md 4.5). Each frame is brought to the training size (bicubic), median
filtered and reduced to a few colours without dithering: real scene layouts, flat regions.
raindrop-render then puts drops on them (or none: tools/configs/scenes/no-drops.json).
Imports without torch.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np
from PIL import Image, ImageFilter, ImageOps

from .cli_args import width_x_height
from .imageio import IMAGE_SUFFIXES
from .read_only import first_read_only_problem, refuse_read_only


def flatten(image: Image.Image, size: tuple[int, int] = (512, 256), median: int = 7, colours: int = 12) -> Image.Image:
    """``image`` resized to ``size`` (width, height), median filtered (odd window) and
    quantised to at most ``colours`` colours (median cut, no dither): 8-bit RGB."""
    if median < 1 or median % 2 == 0:
        raise ValueError(f"median window must be odd and positive, got {median}")
    if not 2 <= colours <= 256:
        raise ValueError(f"colours must be 2-256, got {colours}")
    im = image.convert("RGB").resize(size, Image.BICUBIC)
    if median > 1:
        im = im.filter(ImageFilter.MedianFilter(median))
    return im.quantize(colors=colours, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE).convert("RGB")


def flat_fraction(image: Image.Image) -> float:
    """Fraction of pixels whose 3x3 neighbourhood is one colour (for the model card and tests)."""
    a = np.asarray(image.convert("RGB"), dtype=np.int16)
    same = np.ones(a.shape[:2], dtype=bool)[1:-1, 1:-1]
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            shifted = a[1 + dy : a.shape[0] - 1 + dy, 1 + dx : a.shape[1] - 1 + dx]
            same &= (shifted == a[1:-1, 1:-1]).all(axis=2)
    return float(same.mean())


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("input", type=Path, help="folder of frames (not recursive), read in name order")
    ap.add_argument("output", type=Path, help="folder for the flattened PNGs (same names)")
    ap.add_argument("--limit", type=int, default=0, help="the first N frames only (0: all)")
    ap.add_argument("--size", default="512x256", help="WIDTHxHEIGHT")
    ap.add_argument("--median", type=int, default=7, help="median filter window (odd)")
    ap.add_argument("--colours", type=int, default=12, help="colours per frame")
    args = ap.parse_args(argv)
    try:
        w, h = width_x_height(args.size)
    except argparse.ArgumentTypeError:
        print(f"flatten: error: --size {args.size!r} must be WIDTHxHEIGHT", file=sys.stderr)
        return 2
    frames = sorted(p for p in args.input.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES) if args.input.is_dir() else []
    if not frames:
        print(f"flatten: error: no images in {args.input}", file=sys.stderr)
        return 1
    frames = [p for p in frames if p.is_file()]
    if args.limit > 0:
        frames = frames[: args.limit]
    # The outputs are <stem>.png: written into the input folder they replaced the frames
    # (a.png by its own flattened copy), and a.png and a.jpg were both out/a.png.
    if args.output.resolve() == args.input.resolve():
        print(f"flatten: error: the output folder {args.output} is the input folder: the flattened frames would "
              "replace the frames; choose another folder", file=sys.stderr)
        return 2
    stems: dict[str, Path] = {}
    for p in frames:
        if p.stem in stems:
            print(f"flatten: error: {stems[p.stem].name} and {p.name} would both be written as {p.stem}.png",
                  file=sys.stderr)
            return 2
        stems[p.stem] = p
    if args.output.exists() and not args.output.is_dir():
        print(f"flatten: error: the output {args.output} is not a folder", file=sys.stderr)
        return 2
    # An output folder that holds the input folder, or lies inside it, may hold the user's own
    # pictures under the names the outputs take (photos/a.png for photos/wet/a.png): none is
    # replaced there. Elsewhere a rerun replaces its own earlier outputs.
    out_dir, in_dir = args.output.resolve(), args.input.resolve()
    if out_dir in in_dir.parents or in_dir in out_dir.parents:
        for p in frames:
            if (args.output / (p.stem + ".png")).exists():
                print(f"flatten: error: {args.output / (p.stem + '.png')} already exists in the output folder, which "
                      f"{'holds' if out_dir in in_dir.parents else 'lies inside'} the input folder, and would be "
                      "replaced; choose an output folder apart from the input", file=sys.stderr)
                return 2
    # A read-only output is kept (read_only.py): refused before the first frame.
    problem = first_read_only_problem(*(args.output / (p.stem + ".png") for p in frames), follow_links=False)
    if problem:
        print(f"flatten: error: {problem}", file=sys.stderr)
        return 2
    args.output.mkdir(parents=True, exist_ok=True)
    try:
        for p in frames:
            try:
                image = Image.open(p)
                if image.format != "PNG":  # upright, as the programs read a photograph's EXIF orientation
                    image = ImageOps.exif_transpose(image)
                image.load()
            except OSError as e:  # PIL.UnidentifiedImageError is one
                raise ValueError(f"{p}: cannot read the image ({e})") from e
            # Written beside its final name and renamed: an interrupted run leaves no half file.
            final = args.output / (p.stem + ".png")
            refuse_read_only(final, follow_links=False)
            tmp = final.with_name(f".{final.name}.tmp-{os.getpid()}")
            flatten(image, (w, h), args.median, args.colours).save(tmp, format="PNG")
            os.replace(tmp, final)
    except (ValueError, OSError) as e:
        print(f"flatten: error: {e}", file=sys.stderr)
        return 2
    print(f"flatten: {len(frames)} frames -> {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
