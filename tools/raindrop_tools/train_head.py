"""Train an ``AlternativeHead`` (networks.py): a router's second detector as a light head on the
main detector's own layers, taught to give a committed detector's map (distillation: the
teacher's probabilities are the targets, so no masks are needed and real photographs without
clean partners could serve as inputs too). A source may instead give its own rendered masks as
the targets (``targets: mask``): drops the teacher never learned to see (night drops) are taught
from the renderer's truth.

    python -m raindrop_tools.train_head --config tools/configs/compact-windshield-head.yaml \\
        --out tools/runs/compact-windshield-head

The main RDN is frozen (its map, and so the router's features and every image it keeps, stay
bit for bit as they were); only the head learns. Loss per pixel: the binary cross-entropy of
the head's logits against the teacher's probability, less the teacher's own entropy (so a
perfect head scores 0), plus the absolute difference of the probabilities (the masks are the
probabilities thresholded, at 0.75 for compact-windshield). Inputs: random crops of the sources'
rainy images as the working pass sees them, and a share of them at a third of that scale, as
the coarse pass sees them. Writes ``head.pt`` (the head's state dict), ``log.jsonl`` and the
config beside them; then ``shared_detector`` builds the graphs. No resume: a run is minutes to
an hour on two CPU cores.
"""

from __future__ import annotations

import argparse
import json
import math
import random
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import torch
import torch.nn.functional as F
import yaml

from .config import ConfigError, _from_dict, load_yaml, yaml_error_text
from .data import held_out_real_pairs_problem, is_held_out_real_pair
from .imageio import ImageError, read_rgb
from .manifest import ManifestError, manifest_lines, manifest_records
from .metrics import luma_float
from .networks import AlternativeHead, rdn_taps
from .onnx_weights import OnnxWeightsError
from .read_only import ReadOnlyFileError, refuse_read_only
from .shared_detector import SharedDetectorError, load_head, load_rdn, rdn_config
from .text_negatives import draw_text


@dataclass
class Source:
    path: str
    weight: float
    scale: float = 1.0  # area-averaged on loading (data/train-hi: 1280x640 -> 512x256)
    split: str | None = None  # only the manifest's samples of this split (real pairs: never the test split)
    working_size: int | None = None  # long side brought down to this, as raindrop-remove's working pass does
    images: str = "rainy"  # the folder of the data set to read: rainy, or clean (text negatives)
    # What the head learns on this source's crops: the teacher's map ("teacher"), or the data
    # set's own masks ("mask": the renderer's truth, for drops the teacher does not find).
    targets: str = "teacher"
    # With mask targets: a drop (a part of the mask) whose mean change of the image inside it is
    # under this many 8-bit luma levels is no target (a drop the photograph does not show, such
    # as a night drop over black, is not one to find).
    min_contrast: float = 0.0


@dataclass
class HeadConfig:
    name: str
    main: str
    teacher: str
    sources: list[Source]
    seed: int = 0
    mid: int = 24
    up: int = 16
    images_per_source: int = 700
    crop: int = 128
    coarse_share: float = 0.2
    batch_size: int = 16
    steps: int = 3000
    lr: float = 1e-3
    lr_end: float = 5e-5
    log_every: int = 50
    # Negatives with lettering (text_negatives.py): this share of each batch's crops comes from
    # text_sources' images (clean: no drops) with lettering drawn on, and its target is no drop.
    text_share: float = 0.0
    text_sources: list[Source] | None = None
    # A head to start from (a fine-tune): a head.pt, or a model folder whose detector carries one
    # beside its own map (shared_detector.load_head: main's own folder, e.g. models/compact-multiscale);
    # else a new head.
    init: str | None = None


def read_config(path: Path) -> HeadConfig:
    try:
        raw = load_yaml(Path(path).read_text())
    except OSError as e:
        raise SystemExit(f"error: cannot read {path}: {e}") from None
    except yaml.YAMLError as e:
        raise SystemExit(f"error: {path}: not valid YAML: {yaml_error_text(e)}") from None
    # The training configs' reader (config.py): unknown keys named, values coerced to their types.
    try:
        cfg = _from_dict(HeadConfig, raw if isinstance(raw, dict) else {})
    except (ConfigError, TypeError) as e:  # TypeError: a required key missing
        raise SystemExit(f"error: {path}: {e}") from None
    # Numbers the run cannot use: each ended in a traceback mid-run (batch_size 0, crop 0, mid 0,
    # images_per_source 0, lr NaN) or ran without training (steps 0).
    for key, low, high in (("batch_size", 1, 4096), ("crop", 16, 4096), ("mid", 1, 1024), ("up", 1, 1024),
                           ("images_per_source", 1, 10**7), ("steps", 1, 10**8), ("log_every", 1, 10**8)):
        value = getattr(cfg, key)
        if not low <= value <= high:
            raise SystemExit(f"error: {path}: {key} must be {low} to {high}, got {value}")
    if not (math.isfinite(cfg.lr) and cfg.lr > 0):
        raise SystemExit(f"error: {path}: lr must be a number > 0, got {cfg.lr}")
    if not (math.isfinite(cfg.lr_end) and 0 <= cfg.lr_end <= cfg.lr):
        raise SystemExit(f"error: {path}: lr_end must be a number from 0 to lr, got {cfg.lr_end}")
    if not 0 <= cfg.coarse_share < 1:
        raise SystemExit(f"error: {path}: coarse_share must be in [0, 1)")
    sources = cfg.sources
    if not sources or any(s.weight <= 0 for s in sources):
        raise SystemExit(f"error: {path}: every source needs a weight > 0")
    if not 0 <= cfg.text_share < 1:
        raise SystemExit(f"error: {path}: text_share must be in [0, 1)")
    if cfg.text_share > 0 and not cfg.text_sources:
        raise SystemExit(f"error: {path}: text_share needs text_sources (clean images to draw lettering on)")
    if cfg.text_sources and cfg.text_share == 0:
        raise SystemExit(f"error: {path}: text_sources are given but text_share is 0 (they would not be used)")
    if cfg.text_sources and any(s.weight <= 0 for s in cfg.text_sources):
        raise SystemExit(f"error: {path}: every text source needs a weight > 0")
    for i, s in enumerate(sources):
        if s.targets not in ("teacher", "mask"):
            raise SystemExit(f"error: {path}: sources[{i}].targets must be teacher or mask, not {s.targets!r}")
        if s.targets == "mask" and s.images != "rainy":
            raise SystemExit(f"error: {path}: sources[{i}]: mask targets need the rainy images")
        if s.min_contrast and s.targets != "mask":
            raise SystemExit(f"error: {path}: sources[{i}]: min_contrast applies to mask targets only")
    if cfg.text_sources and any(s.targets != "teacher" for s in cfg.text_sources):
        raise SystemExit(f"error: {path}: text sources' target is no drop; targets does not apply to them")
    return cfg


def _image_files(source: Source) -> list[Path]:
    root = Path(source.path)
    manifest = root / "manifest.jsonl"
    if source.split is not None:
        rows = [json.loads(text) for _, _, text in manifest_lines(root)]
        return sorted(root / r[source.images] for r in rows if r.get("split") == source.split)
    if manifest.is_file():
        # As train's data sources (data.read_manifest): the held-out real pairs only when named.
        try:
            rows = [r for r in manifest_records(root) if isinstance(r, dict)]
        except ManifestError as e:
            raise SystemExit(f"error: {e}") from None
        problem = held_out_real_pairs_problem(root, sum(map(is_held_out_real_pair, rows)), "give this source split: train")
        if problem:
            raise SystemExit(f"error: {problem}")
    return sorted((root / source.images).glob("*.png"))


def _mask_files(source: Source) -> dict[Path, tuple[Path, Path]]:
    """Each rainy image's mask and clean image, as the data set's manifest pairs them."""
    root = Path(source.path)
    rows = [json.loads(text) for _, _, text in manifest_lines(root)]
    return {root / r["rainy"]: (root / r["mask"], root / r.get("clean", "")) for r in rows}


def visible_drops(mask: np.ndarray, rainy: np.ndarray, clean: np.ndarray, min_contrast: float) -> np.ndarray:
    """The mask without its parts whose mean absolute luma change (rainy against clean) is under
    min_contrast levels."""
    if min_contrast <= 0:
        return mask
    n, labels = cv2.connectedComponents((mask > 127).astype(np.uint8), connectivity=8)
    change = np.abs(luma_float(rainy) - luma_float(clean)).ravel()
    flat = labels.ravel()
    sums = np.bincount(flat, weights=change, minlength=n)
    counts = np.bincount(flat, minlength=n)
    keep = sums >= min_contrast * np.maximum(counts, 1)
    keep[0] = False
    return np.where(keep[labels], mask, 0).astype(np.uint8)


def load_images(source: Source, n: int, rng: random.Random) -> list[np.ndarray]:
    """Up to n of the source's images, RGB uint8; with mask targets, the mask as a fourth channel
    (so that every crop, scale and flip moves image and target together)."""
    files = _image_files(source)
    if not files:
        raise SystemExit(f"error: no {source.images} images in {source.path}" + (f" (split {source.split})" if source.split else ""))
    masks = _mask_files(source) if source.targets == "mask" else {}
    rng.shuffle(files)
    images = []
    for f in files[:n]:
        try:
            im = read_rgb(f)
        except ImageError as e:
            raise SystemExit(f"error: {e}") from None
        if source.targets == "mask":
            m = cv2.imread(str(masks[f][0]), cv2.IMREAD_GRAYSCALE) if f in masks else None
            if m is None or m.shape != im.shape[:2]:
                raise SystemExit(f"error: {f}: no mask of its size in the manifest of {source.path}")
            if source.min_contrast > 0:
                try:
                    clean = read_rgb(masks[f][1])
                except ImageError as e:
                    raise SystemExit(f"error: {e}") from None
                if clean.shape != im.shape:
                    raise SystemExit(f"error: {masks[f][1]}: not the size of {f}")
                m = visible_drops(m, im, clean, source.min_contrast)
            im = np.dstack([im, m])
        s = source.scale
        if source.working_size:
            s = min(s, source.working_size / max(im.shape[:2]))
        if s < 1:
            im = cv2.resize(im, None, fx=s, fy=s, interpolation=cv2.INTER_AREA)
        images.append(np.ascontiguousarray(im))
    return images


def crops(pools, weights, cfg: HeadConfig, rng: random.Random, text_pools=None, text_weights=None):
    """A batch of crops (B, 3, crop, crop), which of them are text negatives (a bool per crop),
    and the targets of those whose source gives masks (B, 1, crop, crop; NaN for the others)."""
    out, negative, truth = [], [], []
    for _ in range(cfg.batch_size):
        text = text_pools is not None and rng.random() < cfg.text_share
        if text:
            pool = text_pools[rng.choices(range(len(text_pools)), weights=text_weights)[0]]
        else:
            pool = pools[rng.choices(range(len(pools)), weights=weights)[0]]
        negative.append(text)
        im = pool[rng.randrange(len(pool))]
        if rng.random() < cfg.coarse_share:  # the coarse pass sees a third of the working scale
            im = cv2.resize(im, None, fx=1 / 3, fy=1 / 3, interpolation=cv2.INTER_AREA)
        h, w = im.shape[:2]
        c = min(cfg.crop, h - h % 2, w - w % 2)
        y, x = rng.randrange(h - c + 1), rng.randrange(w - c + 1)
        crop = im[y : y + c, x : x + c]
        if rng.random() < 0.5:
            crop = crop[:, ::-1]
        if c < cfg.crop:
            crop = cv2.resize(np.ascontiguousarray(crop), (cfg.crop, cfg.crop), interpolation=cv2.INTER_LINEAR)
        if text:
            crop = draw_text(np.ascontiguousarray(crop), rng)
        t = torch.from_numpy(np.ascontiguousarray(crop)).permute(2, 0, 1).float() / 255
        out.append(t[:3])
        truth.append(t[3:] if len(t) == 4 else torch.full_like(t[:1], float("nan")))
    return torch.stack(out), torch.tensor(negative), torch.stack(truth)


def distillation_loss(logits: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    t = target.clamp(1e-6, 1 - 1e-6)
    entropy = F.binary_cross_entropy(t, t)
    return F.binary_cross_entropy_with_logits(logits, target) - entropy + (torch.sigmoid(logits) - target).abs().mean()


def train(cfg: HeadConfig, out: Path) -> Path:
    torch.manual_seed(cfg.seed)
    rng = random.Random(cfg.seed)
    # A read-only file is kept (read_only.py): refused before any work.
    refuse_read_only(out / "config.json", out / "log.jsonl", out / "head.pt", follow_links=False)
    if cfg.init and not (Path(cfg.init).is_file() or Path(cfg.init).is_dir()):
        raise SystemExit(f"error: init {cfg.init}: no such file or folder (train that head first)")
    out.mkdir(parents=True, exist_ok=True)
    (out / "config.json").write_text(json.dumps(cfg.__dict__, default=lambda o: o.__dict__, indent=2) + "\n")
    main, teacher = load_rdn(Path(cfg.main)), load_rdn(Path(cfg.teacher))
    rc = rdn_config(Path(cfg.main))
    head = AlternativeHead(rc.width, rc.expanded, mid=cfg.mid, up=cfg.up)
    if cfg.init and Path(cfg.init).is_dir():
        # A committed model folder: the head its detector carries (main's own folder, typically).
        try:
            committed = load_head(Path(cfg.init))
        except (SharedDetectorError, OnnxWeightsError) as e:
            raise SystemExit(f"error: init {cfg.init}: {e}") from None
        except Exception as e:  # a damaged graph: protobuf's, ONNX Runtime's or a file's error
            raise SystemExit(f"error: init {cfg.init}: cannot read its head ({str(e).splitlines()[0] if str(e) else type(e).__name__})") from None
        try:
            head.load_state_dict(committed.state_dict())
        except RuntimeError as e:  # another head's shape
            raise SystemExit(f"error: init {cfg.init}: not a head of this configuration ({str(e).splitlines()[0]})") from None
    elif cfg.init:
        try:
            head.load_state_dict(torch.load(cfg.init, map_location="cpu", weights_only=True))
        except (RuntimeError, OSError, KeyError) as e:  # another head's shape, or not a state dict
            raise SystemExit(f"error: init {cfg.init}: not a head of this configuration ({str(e).splitlines()[0]})") from None
    t0 = time.time()
    pools = [load_images(s, cfg.images_per_source, rng) for s in cfg.sources]
    weights = [s.weight for s in cfg.sources]
    text_pools = text_weights = None
    if cfg.text_share > 0:
        text_pools = [load_images(s, cfg.images_per_source, rng) for s in cfg.text_sources]
        text_weights = [s.weight for s in cfg.text_sources]
    n_text = sum(map(len, text_pools)) if text_pools else 0
    print(f"{cfg.name}: {sum(map(len, pools))} images from {len(pools)} sources, {n_text} for text negatives, "
          f"in {time.time() - t0:.0f} s", flush=True)
    opt = torch.optim.Adam(head.parameters(), lr=cfg.lr)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, cfg.steps, eta_min=cfg.lr_end)
    t0, running = time.time(), None
    with open(out / "log.jsonl", "w") as log:
        for step in range(1, cfg.steps + 1):
            x, negative, truth = crops(pools, weights, cfg, rng, text_pools, text_weights)
            with torch.no_grad():
                taps = rdn_taps(main, x)
                target = torch.sigmoid(teacher(x))
                target[negative] = 0.0  # lettering on a clean image: no drop, whatever the teacher says
                own = ~truth.isnan()
                target[own] = truth[own]  # a source's own masks, where it gives them
            loss = distillation_loss(head(*taps), target)
            if not math.isfinite(loss.item()):
                raise SystemExit(f"error: step {step}: the loss is not finite")
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
            running = loss.item() if running is None else 0.95 * running + 0.05 * loss.item()
            if step % cfg.log_every == 0 or step == cfg.steps:
                rec = {"step": step, "loss": round(running, 6), "lr": sched.get_last_lr()[0], "s": round(time.time() - t0, 1)}
                log.write(json.dumps(rec) + "\n")
                log.flush()
                print(rec, flush=True)
            if step % 500 == 0 or step == cfg.steps:
                tmp = out / ".head.pt.tmp"
                torch.save(head.state_dict(), tmp)
                tmp.replace(out / "head.pt")
    return out / "head.pt"


def _steps_logged(out: Path) -> float:
    """The last step a run in ``out`` logged; infinite where there is a head but no readable log
    (a head put there by hand is not a run cut short)."""
    try:
        steps = [json.loads(line).get("step", 0) for line in (out / "log.jsonl").read_text().splitlines() if line.strip()]
        return max(s for s in steps if isinstance(s, (int, float))) if steps else 0
    except (OSError, UnicodeDecodeError, ValueError, AttributeError):  # no log, a damaged one, a line no record
        return math.inf


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m raindrop_tools.train_head", description=__doc__.split("\n\n")[0])
    ap.add_argument("--config", type=Path, required=True)
    ap.add_argument("--out", type=Path, required=True, help="run folder (head.pt, log.jsonl, config.json)")
    ap.add_argument("--threads", type=int, default=0, help="torch threads (0: torch's default)")
    args = ap.parse_args(argv)
    if args.threads < 0:
        raise SystemExit(f"error: --threads must be 0 or more, got {args.threads}")
    if args.out.exists() and not args.out.is_dir():
        raise SystemExit(f"error: --out {args.out}: not a folder")
    cfg = read_config(args.config)
    # As train refuses a run folder with a finished run: a second run replaced the first's head.
    # A run cut short (head.pt is written every 500 steps) is trained again from the start.
    if (args.out / "head.pt").exists() and _steps_logged(args.out) >= cfg.steps:
        raise SystemExit(f"error: --out {args.out} holds a trained head (head.pt) already: train into a new folder "
                         "(a fine-tune of that head names it as its config's init)")
    if args.threads > 0:
        torch.set_num_threads(args.threads)
    try:
        path = train(cfg, args.out)
    except ReadOnlyFileError as e:
        raise SystemExit(f"error: {e}") from None
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
