"""Lettering drawn onto clean images: negatives for a detector that takes text for drops.

Dark strokes on a bright sign, slightly out of focus, look to a detector trained on sharp
windshield drops much like the drops' dark bands: the default's windshield head marked a word of
a sign in one of the real photographs, and the fill that follows wiped it out (docs/RESULTS.md
4.54, 4.56). Street scenes are full of lettering (signs, shop fronts, number plates, road
markings), and wiping it is worse than leaving a drop. ``draw_text`` draws one or two blocks of random
letters onto an image (a crop of a clean frame), each on a plate of uniform colour or straight onto
the scene, in a contrasting colour, with OpenCV's stroke fonts at heights from a few pixels to
tens, and blurred a little as a lens focused elsewhere would: what a drop-free crop of a street
with signs looks like at the working scale. The detector's target there is no drop at all.
"""

from __future__ import annotations

import argparse
import random
import string
import sys
from pathlib import Path

import cv2
import numpy as np

from .imageio import IMAGE_SUFFIXES, ImageError, read_rgb
from .metrics import PSNR_CAP_DB, luma, psnr
from .read_only import refuse_read_only

FONTS = (
    cv2.FONT_HERSHEY_SIMPLEX,
    cv2.FONT_HERSHEY_DUPLEX,
    cv2.FONT_HERSHEY_COMPLEX,
    cv2.FONT_HERSHEY_TRIPLEX,
    cv2.FONT_HERSHEY_PLAIN,
)


def _word(rng: random.Random) -> str:
    letters = string.ascii_letters + string.digits if rng.random() < 0.2 else string.ascii_letters
    text = "".join(rng.choice(letters) for _ in range(rng.randint(2, 9)))
    return text.upper() if rng.random() < 0.4 else text


def draw_text(image: np.ndarray, rng: random.Random, blocks: tuple[int, int] = (1, 2)) -> np.ndarray:
    """A copy of ``image`` (uint8, H x W x 3) with ``blocks`` (a range) blocks of lettering drawn on it."""
    out = image.copy()
    h, w = out.shape[:2]
    for _ in range(rng.randint(*blocks)):
        font = rng.choice(FONTS)
        height = rng.uniform(4.0, min(24.0, h / 4))  # letter height in pixels
        base = cv2.getTextSize("Hg", font, 1.0, 1)[0][1]
        scale = height / max(base, 1)
        thickness = max(1, int(round(height * rng.uniform(0.06, 0.16))))
        lines = [" ".join(_word(rng) for _ in range(rng.randint(1, 3))) for _ in range(rng.randint(1, 3))]
        sizes = [cv2.getTextSize(line, font, scale, thickness)[0] for line in lines]
        block_w = max(s[0] for s in sizes)
        line_h = int(height * 1.6) + thickness
        block_h = line_h * len(lines)
        margin = int(height * rng.uniform(0.3, 1.0))
        x0 = rng.randint(-block_w // 2, max(-block_w // 2, w - block_w // 2))
        y0 = rng.randint(-block_h // 2, max(-block_h // 2, h - block_h // 2))
        # Drawn on a layer of its own, then blurred and laid over the image where it is drawn.
        layer = np.zeros_like(out)
        cover = np.zeros((h, w), np.uint8)
        light = rng.random() < 0.7  # most signs: dark letters on a light plate
        plate = np.array([rng.randint(170, 255) if light else rng.randint(0, 90) for _ in range(3)], np.uint8)
        ink = np.array([rng.randint(0, 80) if light else rng.randint(180, 255) for _ in range(3)], np.uint8)
        if rng.random() < 0.6:
            cv2.rectangle(layer, (x0 - margin, y0 - margin), (x0 + block_w + margin, y0 + block_h + margin),
                          tuple(int(c) for c in plate), -1)
            cv2.rectangle(cover, (x0 - margin, y0 - margin), (x0 + block_w + margin, y0 + block_h + margin), 255, -1)
        for i, line in enumerate(lines):
            org = (x0, y0 + i * line_h + int(height))
            cv2.putText(layer, line, org, font, scale, tuple(int(c) for c in ink), thickness, cv2.LINE_AA)
            cv2.putText(cover, line, org, font, scale, 255, thickness, cv2.LINE_AA)
        sigma = rng.uniform(0.0, 1.5)
        if sigma > 0.3:
            layer = cv2.GaussianBlur(layer, (0, 0), sigma)
            cover = cv2.GaussianBlur(cover, (0, 0), sigma)
        a = cover.astype(np.float32)[..., None] / 255
        # The layer was blurred premultiplied by its cover (zero outside): divide it back out.
        colour = layer.astype(np.float32) / np.maximum(a, 1e-3)
        out = np.clip(out.astype(np.float32) * (1 - a) + colour * a, 0, 255).astype(np.uint8)
    return out


def make_set(images: list, out, seed: int = 0, size: tuple[int, int] | None = (512, 256), lettering: bool = True) -> int:
    """Lettering drawn onto each image (resized to ``size`` first), written to ``out`` as PNG:
    photographs without drops in which every change a remover makes is damage. Without
    ``lettering``, the resized images alone (the baseline). Returns the count."""
    out = Path(out)
    targets = [out / (Path(p).stem + ".png") for p in images]
    # Refused before anything is written: an output folder that is the images' own
    # (their originals were replaced by lettered copies), two images of one name (a.png and
    # a.jpg: one replaced the other, and both were counted), a read-only file (read_only.py).
    sources = {Path(p).resolve().parent for p in images}
    if out.exists() and out.resolve() in sources:
        raise OSError(f"{out}: the images' own folder: choose another output folder")
    seen: dict[Path, Path] = {}
    for path, target in zip(images, targets):
        if target in seen:
            raise OSError(f"{seen[target]} and {path} would both be written as {target}")
        seen[target] = Path(path)
    # `damage` scores every PNG in the folder: images an earlier, larger set left there would be
    # scored with this one (lettered ones in a baseline, say).
    if out.is_dir():
        others = sorted(p.name for p in out.glob("*.png") if p not in seen)
        if others:
            raise OSError(f"{out}: holds {len(others)} PNG image(s) this set does not write ({others[0]}, ...), "
                          "which 'damage' would score with it: choose a new or empty folder")
    refuse_read_only(*targets)  # written through the name
    # Every image read first: a damaged one stops the run before any file is written.
    pictures = [read_rgb(path) for path in images]
    out.mkdir(parents=True, exist_ok=True)
    rng = random.Random(seed)
    for im, target in zip(pictures, targets):
        if size:
            im = cv2.resize(im, size, interpolation=cv2.INTER_AREA)
        lettered = draw_text(np.ascontiguousarray(im), rng, blocks=(2, 4)) if lettering else im
        if not cv2.imwrite(str(target), cv2.cvtColor(lettered, cv2.COLOR_RGB2BGR)):
            raise OSError(f"{target}: could not be written")
    return len(images)


def damage(inputs, outputs, masks=None) -> dict:
    """What a remover changed in drop-free images: PSNR-Y of each output against its input (the
    mean over images, each capped as the metrics cap it), the share of images it changed at all,
    and, with ``masks`` (its mask folder), the mean share of pixels it marked."""
    inputs, outputs = Path(inputs), Path(outputs)
    names = sorted(p.name for p in inputs.glob("*.png"))
    if not names:
        raise SystemExit(f"error: no PNG images in {inputs}")
    psnrs, changed, marked = [], 0, []
    for name in names:
        a, b = cv2.imread(str(inputs / name)), cv2.imread(str(outputs / name))
        if b is None:
            raise SystemExit(f"error: no output for {name} in {outputs}")
        if a is None or a.shape != b.shape:
            raise SystemExit(f"error: {name}: the input and output differ in size or cannot be read")
        p = psnr(luma(np.ascontiguousarray(b[..., ::-1])), luma(np.ascontiguousarray(a[..., ::-1])))
        psnrs.append(p)
        changed += int(p < PSNR_CAP_DB)
        if masks is not None:
            m = cv2.imread(str(Path(masks) / name), cv2.IMREAD_GRAYSCALE)
            if m is None:
                raise SystemExit(f"error: no mask for {name} in {masks}")
            if m.shape != a.shape[:2]:
                raise SystemExit(f"error: {name}: the mask is {m.shape[1]}x{m.shape[0]}, the image {a.shape[1]}x{a.shape[0]}")
            marked.append(float((m > 0).mean()))
    out = {"images": len(names), "psnr_y": float(np.mean(psnrs)), "changed": changed / len(names)}
    if marked:
        out["marked"] = float(np.mean(marked))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m raindrop_tools.text_negatives", description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="command", required=True)
    mk = sub.add_parser("make", help="draw lettering onto drop-free images (a set for `damage`)")
    mk.add_argument("--images", type=Path, required=True, help="folder of drop-free images (its first --count, sorted)")
    mk.add_argument("--out", type=Path, required=True)
    mk.add_argument("--count", type=int, default=100)
    mk.add_argument("--seed", type=int, default=0)
    mk.add_argument("--no-lettering", action="store_true", help="the resized images alone (the measure's baseline)")
    dm = sub.add_parser("damage", help="what a remover changed in them")
    dm.add_argument("--inputs", type=Path, required=True)
    dm.add_argument("--outputs", type=Path, required=True)
    dm.add_argument("--masks", type=Path, help="the remover's mask folder (--mask-dir)")
    dm.add_argument("--label", default="")
    args = ap.parse_args(argv)
    if args.command == "make" and args.count < 1:
        raise SystemExit(f"error: --count must be at least 1, got {args.count}")
    if args.command == "make":
        if not args.images.is_dir():
            raise SystemExit(f"error: {args.images}: not a folder")
        files = sorted(p for p in args.images.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)[: args.count]
        if not files:
            raise SystemExit(f"error: {args.images}: no images ({', '.join(sorted(IMAGE_SUFFIXES))})")
        try:
            n = make_set(files, args.out, args.seed, lettering=not args.no_lettering)
            print(f"{n} images{'' if args.no_lettering else ' with lettering'} in {args.out}")
        except (ImageError, OSError) as e:  # ReadOnlyFileError is an OSError
            raise SystemExit(f"error: {e}") from None
    else:
        r = damage(args.inputs, args.outputs, args.masks)
        marked = f", {100 * r['marked']:.2f}% of the pixels marked" if "marked" in r else ""
        print(f"{args.label + ': ' if args.label else ''}{r['images']} drop-free images, output against input PSNR-Y "
              f"{r['psnr_y']:.2f} dB, {100 * r['changed']:.0f}% of them changed{marked}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
