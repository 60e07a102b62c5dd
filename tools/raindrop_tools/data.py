"""Reading a rendered data set (CONTRACTS.md section 1) for training and evaluation.

* ``read_manifest`` parses and checks ``manifest.jsonl`` (or the parts of a sharded run,
  ``manifest.part-K-of-N.jsonl``, read as their merge: manifest.py);
* ``check_files`` checks the images behind it (presence, sizes, mask values, ...);
* ``RaindropDataset`` serves random crops with the edge map of the full image;
* ``StepBatchSampler`` draws the crops of every training step as a pure function of
  (seed, stage, step), so a resumed run sees exactly the batches it would have seen.

Both checks refuse an inconsistent data set with a ``DatasetError`` that lists every problem
found, each naming the manifest line or the file. numpy + OpenCV only: the samples are numpy
arrays, which torch's DataLoader collates into tensors.
"""

from __future__ import annotations

import json
import os
from collections import Counter
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable, Iterator

import cv2
import numpy as np

from .edge import edge_map_window
from .imageio import ImageError, png_header, read_mask_strict, read_rgb_strict, to_float
from .manifest import MANIFEST, ManifestError, manifest_lines

# Keys the tools use; the contract lists more, and readers must ignore unknown keys.
REQUIRED_KEYS: dict[str, type] = {
    "id": str,
    "rainy": str,
    "clean": str,
    "mask": str,
    "width": int,
    "height": int,
}
MAX_LISTED_PROBLEMS = 20
# The manifest "source" of the folders realpairs.py prepare writes (realpairs.SOURCE).
REAL_PAIRS_SOURCE = "real-pairs"


def is_held_out_real_pair(record: dict) -> bool:
    """A manifest record of a pair realpairs.py prepare put in the 'test' split: the pairs
    'evaluate --split test' scores, which training must not see unless told to."""
    return record.get("source") == REAL_PAIRS_SOURCE and record.get("split") == "test"


def held_out_real_pairs_problem(root: str | os.PathLike, count: int, how: str) -> str | None:
    """The one-line refusal of training on `count` held-out real pairs of `root` (None for
    none); `how` says how the caller's config names a source's splits."""
    if not count:
        return None
    return (f"{root}: {count} of its real pairs are in the 'test' split, which 'evaluate --split test' scores; "
            f"{how}")


class DatasetError(ValueError):
    """A data set that does not follow CONTRACTS.md section 1."""


@dataclass(frozen=True)
class Sample:
    id: str
    rainy: Path
    clean: Path
    mask: Path
    width: int
    height: int
    split: str | None
    line: int  # 1-based line in manifest.jsonl (or in `file`)
    file: str = MANIFEST  # the manifest file: manifest.jsonl or a shard's part


def _raise(problems: list[str], what: str) -> None:
    shown = problems[:MAX_LISTED_PROBLEMS]
    more = len(problems) - len(shown)
    tail = f"\n  ... and {more} more" if more > 0 else ""
    raise DatasetError(f"{what}: {len(problems)} problem(s):\n  " + "\n  ".join(shown) + tail)


def read_manifest(
    root: str | os.PathLike,
    splits: list[str] | None = None,
    left_out: Counter | None = None,
    for_training: bool = False,
) -> list[Sample]:
    """Parse ``root/manifest.jsonl``; keep the samples whose ``split`` is in ``splits`` (all
    when None). Refuses unparsable lines, missing or mistyped keys, unsafe paths and
    duplicate ids. ``left_out``, if given, counts the split values of the samples not kept.
    ``for_training``: with no split named, refuse a folder of real pairs (``realpairs
    prepare``'s ``source``) that holds pairs of the ``test`` split, which ``evaluate --split
    test`` scores: training on them silently would make that score meaningless."""
    root = Path(root)
    manifest = root / MANIFEST
    try:
        lines = manifest_lines(root)
    except ManifestError as e:  # training and evaluation report DatasetErrors in one line
        raise DatasetError(str(e)) from None
    if not manifest.is_file() and not lines:
        raise DatasetError(f"{root}: not a rendered data set (no {MANIFEST})")
    problems: list[str] = []
    samples: list[Sample] = []
    seen: dict[str, str] = {}
    held_out = 0  # samples kept that is_held_out_real_pair (for_training)
    for file, lineno, text in lines:
        where = f"{root / file}:{lineno}"
        try:
            obj = json.loads(text)
        except json.JSONDecodeError as e:
            problems.append(f"{where}: not valid JSON ({e.msg} at column {e.colno})")
            continue
        if not isinstance(obj, dict):
            problems.append(f"{where}: expected a JSON object, got {type(obj).__name__}")
            continue
        missing = [k for k in REQUIRED_KEYS if k not in obj]
        if missing:
            problems.append(f"{where}: missing key(s) {', '.join(missing)}")
            continue
        bad = [
            f"{k} (expected {t.__name__}, got {type(obj[k]).__name__})"
            for k, t in REQUIRED_KEYS.items()
            if not isinstance(obj[k], t) or (t is int and isinstance(obj[k], bool))
        ]
        if bad:
            problems.append(f"{where}: wrong type for {', '.join(bad)}")
            continue
        sid = obj["id"]
        if not sid or any(c in sid for c in "/\\\0") or sid in (".", ".."):
            problems.append(f"{where}: id {sid!r} is not file-name safe")
            continue
        if obj["width"] < 1 or obj["height"] < 1:
            problems.append(f"{where}: sample {sid!r}: width and height must be >= 1")
            continue
        paths = {}
        for key in ("rainy", "clean", "mask"):
            rel = Path(obj[key])
            if rel.is_absolute() or ".." in rel.parts:
                problems.append(
                    f"{where}: sample {sid!r}: {key} path {obj[key]!r} must be relative to the data set folder"
                )
            else:
                paths[key] = root / rel
        if len(paths) != 3:
            continue
        if sid in seen:
            problems.append(f"{where}: duplicate id {sid!r} (first on line {seen[sid]})")
            continue
        seen[sid] = str(lineno) if file == MANIFEST else f"{lineno} of {file}"
        split = obj.get("split")
        if splits is not None and split is None:
            problems.append(f"{where}: sample {sid!r} has no 'split' key, but splits {splits} were requested")
            continue
        if splits is None or split in splits:
            samples.append(
                Sample(sid, paths["rainy"], paths["clean"], paths["mask"], obj["width"], obj["height"], split, lineno, file)
            )
            held_out += is_held_out_real_pair(obj)
        elif left_out is not None:
            left_out[split] += 1
    if problems:
        _raise(problems, f"{manifest}")
    if for_training and splits is None:
        problem = held_out_real_pairs_problem(
            root, held_out, "name the splits to train on (split: train for this source, or data.splits: [train]), "
            "or split: [train, test] to train on every pair knowingly")
        if problem:
            raise DatasetError(problem)
    if not samples:
        which = f" with split in {splits}" if splits is not None else ""
        raise DatasetError(f"{manifest}: no samples{which}")
    return samples


def _decode(sample: Sample) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return read_rgb_strict(sample.rainy), read_rgb_strict(sample.clean), read_mask_strict(sample.mask)


def check_files(
    samples: list[Sample],
    min_size: int = 1,
    level: str = "full",
    check_outside_mask: bool = True,
    keep: Callable[[int, tuple], None] | None = None,
    manifest: str = MANIFEST,
) -> None:
    """Check the images of ``samples``: files present, all three of the size the manifest
    gives, at least ``min_size`` in both dimensions (the crop), and with ``level="full"``
    (decodes everything once): 8-bit RGB / single-channel masks, masks only 0 or 255, and
    rainy == clean where the mask is 0. ``keep(i, (rainy, clean, mask))`` receives the
    decoded images (for caching). Raises DatasetError listing every problem."""
    if level not in ("full", "header"):
        raise ValueError(f"level must be 'full' or 'header', got {level!r}")
    problems: list[str] = []
    for i, s in enumerate(samples):
        where = f"{manifest if s.file == MANIFEST else Path(manifest).parent / s.file}:{s.line} (sample {s.id!r})"
        missing = [str(p) for p in (s.rainy, s.clean, s.mask) if not p.is_file()]
        if missing:
            problems.append(f"{where}: missing file(s) {', '.join(missing)}")
            continue
        if s.width < min_size or s.height < min_size:
            problems.append(f"{where}: image {s.width}x{s.height} (WxH) is smaller than the {min_size}x{min_size} crop")
            continue
        try:
            if level == "header":
                sizes = {}
                for key, p in (("rainy", s.rainy), ("clean", s.clean), ("mask", s.mask)):
                    try:
                        w, h, _, _ = png_header(p)
                    except ImageError:  # not a PNG: decode to learn the size
                        img = read_mask_strict(p) if key == "mask" else read_rgb_strict(p)
                        h, w = img.shape[:2]
                    sizes[key] = (w, h)
                images = None
            else:
                images = _decode(s)
                sizes = {k: (im.shape[1], im.shape[0]) for k, im in zip(("rainy", "clean", "mask"), images)}
        except (ImageError, OSError) as e:
            problems.append(f"{where}: {e}")
            continue
        wrong = [f"{k} {w}x{h}" for k, (w, h) in sizes.items() if (w, h) != (s.width, s.height)]
        if wrong:
            problems.append(f"{where}: size mismatch: manifest says {s.width}x{s.height} (WxH), got {', '.join(wrong)}")
            continue
        if images is not None:
            rainy, clean, mask = images
            values = np.unique(mask)
            stray = values[(values != 0) & (values != 255)]
            if stray.size:
                problems.append(
                    f"{where}: mask {s.mask} is not binary (values other than 0 and 255: "
                    f"{', '.join(str(int(v)) for v in stray[:5])}{'...' if stray.size > 5 else ''})"
                )
                continue
            if check_outside_mask:
                outside = (rainy != clean).any(axis=2) & (mask == 0)
                n = int(outside.sum())
                if n:
                    problems.append(
                        f"{where}: rainy and clean differ at {n} pixel(s) outside the mask "
                        "(CONTRACTS.md: rainy == clean wherever mask == 0)"
                    )
                    continue
            if keep is not None:
                keep(i, images)
    if problems:
        _raise(problems, "data set refused")


def scaled_length(n: int, scale: float) -> int:
    """A side of ``n`` px at ``scale``: rounded, at least 1 (as raindrop-remove's scaled_size)."""
    return max(1, int(np.floor(n * scale + 0.5)))  # half away from zero, as std::lround


def downscale_sample(rainy: np.ndarray, clean: np.ndarray, mask: np.ndarray, scale: float):
    """(rainy, clean, mask) at ``scale`` < 1: images by area averaging (as raindrop-remove makes
    its smaller copies), the mask averaged the same way and kept where at least half covered."""
    h, w = mask.shape
    size = (scaled_length(w, scale), scaled_length(h, scale))
    r = cv2.resize(rainy, size, interpolation=cv2.INTER_AREA)
    c = cv2.resize(clean, size, interpolation=cv2.INTER_AREA)
    m = cv2.resize(mask.astype(np.float32), size, interpolation=cv2.INTER_AREA)
    return r, c, np.where(m >= 127.5, 255, 0).astype(np.uint8)


def visible_difference(rainy_u8: np.ndarray, clean_u8: np.ndarray, levels: float) -> np.ndarray:
    """Where rainy and clean (HxWx3 uint8) visibly differ: the 5x5 box blur of the absolute
    luma difference > ``levels`` 8-bit levels, as float32 0/1 (``SourceConfig.visible_levels``).
    Unlike the real pairs' rough masks (``realpairs.rough_mask``), which blur each image before
    differencing, the absolute difference is blurred, so that a drop's bright rim and dark band
    side by side do not cancel."""
    import cv2

    from .realpairs import luma_difference  # (imports cv2, which this module loads lazily)

    d = luma_difference(rainy_u8, clean_u8, blur=1)
    return (cv2.blur(d, (5, 5), borderType=cv2.BORDER_REPLICATE) > levels).astype(np.float32)


def sensor_noise(shape: tuple[int, ...], max_levels: float, key) -> np.ndarray:
    """A Gaussian noise field (float32, in [0, 1] units) of ``shape``, its standard deviation
    drawn from [0, max_levels] 8-bit levels: a camera's noise, which comes after the optics,
    inside drops as outside. Deterministic in ``key`` (the crop's key), so a resumed run sees the
    same noise."""
    rng = np.random.default_rng([int(x) for x in key] + [0x5E50])
    sigma = rng.uniform(0.0, max_levels) / 255.0
    return rng.normal(0.0, sigma, shape).astype(np.float32)


def photometric_jitter(strength: float, key):
    """The function that applies one crop's photometric jitter (``SourceConfig.photometric``) to
    a float32 HxWx3 image in [0, 1]; the same draw for every image it is given (rainy and clean
    alike). Deterministic in ``key`` (the crop's key), so a resumed run sees the same crops."""
    rng = np.random.default_rng([int(x) for x in key] + [0xC010])
    exposure = np.exp(rng.uniform(-strength, strength))
    gains = (exposure * np.exp(rng.uniform(-strength / 4, strength / 4, 3))).astype(np.float32)
    gamma = np.float32(np.exp(rng.uniform(-strength / 2, strength / 2)))

    def apply(image: np.ndarray) -> np.ndarray:
        return np.power(np.clip(image * gains, 0.0, 1.0), gamma).astype(np.float32)

    return apply


def with_noise(image: np.ndarray, noise: np.ndarray) -> np.ndarray:
    """``image`` (float32 in [0, 1]) plus ``noise``, clipped and rounded to 8-bit steps."""
    return np.round(np.clip(image + noise, 0.0, 1.0) * 255.0).astype(np.float32) / 255.0


class RaindropDataset:
    """Random crops (and horizontal flips) of a rendered data set.

    An item is a dict of numpy arrays: ``rainy`` and ``clean`` (3xhxw float32 in [0, 1]),
    ``mask`` (1xhxw float32, 0 or 1), ``edge`` (1xhxw float32: the edge map of the FULL rainy
    image, cropped, see ``edge.edge_map_window``), ``detection_weight`` (float32 scalar: the
    crop's weight in the detector's loss, ``SourceConfig.detection_weight``) and ``id`` (str).

    Index it with a key ``(sample index, y0, x0, flip)`` (what ``StepBatchSampler`` yields)
    for reproducible crops, or with a plain sample index for a fresh random crop.
    """

    def __init__(
        self,
        root: str | os.PathLike,
        crop: int = 100,
        flip: bool = True,
        splits: list[str] | None = None,
        cache: bool = False,
        cache_max_gib: float = 8.0,
        validate: str = "full",
        check_outside_mask: bool = True,
        log: Callable[[str], None] = print,
        visible_levels: float = 0.0,
        sensor_noise_levels: float = 0.0,
        detection_weight: float = 1.0,
        scale: float = 1.0,
        photometric: float = 0.0,
    ):
        self.root = Path(root)
        self.detection_weight = np.float32(detection_weight)
        if not (0.0 < scale <= 1.0):
            raise ValueError(f"scale must be in (0, 1], got {scale}")
        self.scale = float(scale)
        self.crop = int(crop)
        self.visible_levels = float(visible_levels)
        self.sensor_noise_levels = float(sensor_noise_levels)
        if not 0.0 <= photometric <= 1.0:  # NaN and inf fail too (as data.sources[].photometric's check)
            raise ValueError(f"photometric must be in [0, 1], got {photometric}")
        self.photometric = float(photometric)
        self.flip = bool(flip)
        left_out: Counter = Counter()
        self.samples = read_manifest(self.root, splits, left_out, for_training=True)
        if left_out:
            # A split filter that silently drops most of a folder trains on a sliver of it
            # (CamVid frames carry split "none": [train] kept 36 of this project's 2844).
            others = ", ".join(f"{k!r} x {n}" for k, n in sorted(left_out.items(), key=str))
            log(f"data: {self.root}: splits {splits} keep {len(self.samples)} of "
                f"{len(self.samples) + sum(left_out.values())} samples; left out: {others}")
        self._cache: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] | None = None
        if cache:
            need = sum(s.width * s.height * 7 for s in self.samples) * self.scale**2 / 2**30  # cached downscaled
            if need > cache_max_gib:
                log(f"data: not caching: the decoded set needs {need:.1f} GiB > cache_max_gib {cache_max_gib}")
            else:
                self._cache = {}
        keep = (lambda i, images: self._cache.__setitem__(i, self._scaled(images))) if self._cache is not None else None
        if self._cache is not None and validate == "header":
            # Caching decodes everything anyway: validate fully at no extra cost.
            validate = "full"
        check_files(
            self.samples,
            min_size=self.crop if self.scale == 1.0 else 1,
            level=validate,
            check_outside_mask=check_outside_mask,
            keep=keep,
            manifest=str(self.root / MANIFEST),
        )
        if self.scale != 1.0:
            # From here on a sample's size is its downscaled size (what crops are drawn from).
            self.samples = [replace(s, width=scaled_length(s.width, self.scale), height=scaled_length(s.height, self.scale))
                            for s in self.samples]
            small = [f"{s.id} ({s.width}x{s.height})" for s in self.samples if min(s.width, s.height) < self.crop]
            if small:
                _raise([f"{self.root / MANIFEST}: at scale {self.scale:g}, image(s) smaller than the "
                        f"{self.crop}x{self.crop} crop: {', '.join(small[:5])}{'...' if len(small) > 5 else ''}"],
                       "data set refused")
        self._rng = np.random.default_rng()

    def __len__(self) -> int:
        return len(self.samples)

    @property
    def sizes(self) -> list[tuple[int, int]]:
        """(height, width) of every sample."""
        return [(s.height, s.width) for s in self.samples]

    def load(self, i: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Decoded (rainy, clean, mask) uint8 images of sample ``i``, at the source's scale."""
        if self._cache is not None and i in self._cache:
            return self._cache[i]
        return self._scaled(_decode(self.samples[i]))

    def _scaled(self, images: tuple[np.ndarray, np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if self.scale == 1.0:
            return images
        return downscale_sample(*images, self.scale)

    def random_key(self, i: int, rng: np.random.Generator) -> tuple[int, int, int, bool]:
        s = self.samples[i]
        y0 = int(rng.integers(0, s.height - self.crop + 1))
        x0 = int(rng.integers(0, s.width - self.crop + 1))
        flip = bool(rng.integers(0, 2)) if self.flip else False
        return (i, y0, x0, flip)

    def __getitem__(self, key) -> dict:
        if isinstance(key, (int, np.integer)):
            key = self.random_key(int(key), self._rng)
        i, y0, x0, flip = key
        rainy, clean, mask = self.load(i)
        c = self.crop
        rainy_f = to_float(rainy)
        g = to_float(clean[y0 : y0 + c, x0 : x0 + c])
        if self.photometric > 0:
            # Before the noise (a camera's noise comes after its light) and the edge map (of
            # the image the network sees).
            jitter = photometric_jitter(self.photometric, key)
            rainy_f, g = jitter(rainy_f), jitter(g)
        if self.sensor_noise_levels > 0:
            # One field on both images: the whole rainy frame (its edge map is of the full
            # frame), the clean one only where the crop needs it.
            noise = sensor_noise(rainy_f.shape, self.sensor_noise_levels, key)
            rainy_f = with_noise(rainy_f, noise)
            g = with_noise(g, noise[y0 : y0 + c, x0 : x0 + c])
        edge = edge_map_window(rainy_f, y0, x0, c, c)  # of the noisy image, as at inference
        r = rainy_f[y0 : y0 + c, x0 : x0 + c]
        m = (mask[y0 : y0 + c, x0 : x0 + c] > 127).astype(np.float32)
        if self.visible_levels > 0:
            m *= visible_difference(rainy[y0 : y0 + c, x0 : x0 + c], clean[y0 : y0 + c, x0 : x0 + c], self.visible_levels)
        if flip:
            r, g, m, edge = r[:, ::-1], g[:, ::-1], m[:, ::-1], edge[:, ::-1]
        return {
            "id": self.samples[i].id,
            "rainy": np.ascontiguousarray(r.transpose(2, 0, 1)),
            "clean": np.ascontiguousarray(g.transpose(2, 0, 1)),
            "mask": np.ascontiguousarray(m[None]),
            "edge": np.ascontiguousarray(edge[None]),
            "detection_weight": self.detection_weight,
        }


class _StepSampler:
    """What the step samplers share: the run's numbers, crop draws, iteration over steps.
    Subclasses define ``keys_for_step``."""

    def _setup(self, crop: int, batch_size: int, seed: int, stage: int, total_steps: int, start_step: int,
               flip: bool) -> None:
        self.crop = crop
        self.batch_size = batch_size
        self.seed = seed
        self.stage = stage
        self.total_steps = total_steps
        self.start_step = start_step
        self.flip = flip

    def _crop(self, rng: np.random.Generator, h: int, w: int) -> tuple[int, int, bool]:
        """(y0, x0, flip) of one crop of an HxW image, drawn from the step's generator."""
        y0 = int(rng.integers(0, h - self.crop + 1))
        x0 = int(rng.integers(0, w - self.crop + 1))
        flip = bool(rng.integers(0, 2)) if self.flip else False
        return y0, x0, flip

    def keys_for_step(self, step: int) -> list[tuple]:
        raise NotImplementedError

    def __iter__(self) -> Iterator[list[tuple]]:
        for step in range(self.start_step, self.total_steps):
            yield self.keys_for_step(step)

    def __len__(self) -> int:
        return max(0, self.total_steps - self.start_step)


class StepBatchSampler(_StepSampler):
    """Yields, for each step in [start_step, total_steps), the list of dataset keys of that
    step's batch. Samples are drawn without replacement within an epoch (a permutation seeded
    by (seed, stage, epoch)); crop positions and flips are seeded by (seed, stage, step). The
    batches are therefore a pure function of the step: resuming needs no sampler state, and
    the loader may use any number of worker processes."""

    def __init__(
        self,
        sizes: list[tuple[int, int]],
        crop: int,
        batch_size: int,
        seed: int,
        stage: int,
        total_steps: int,
        start_step: int = 0,
        flip: bool = True,
    ):
        if not sizes:
            raise ValueError("no samples")
        self.sizes = sizes
        self._setup(crop, batch_size, seed, stage, total_steps, start_step, flip)
        self._perm: dict[int, np.ndarray] = {}

    def _permutation(self, epoch: int) -> np.ndarray:
        if epoch not in self._perm:
            if len(self._perm) > 4:
                self._perm.clear()
            rng = np.random.default_rng([self.seed, self.stage, epoch, 0])
            self._perm[epoch] = rng.permutation(len(self.sizes))
        return self._perm[epoch]

    def keys_for_step(self, step: int) -> list[tuple[int, int, int, bool]]:
        n = len(self.sizes)
        rng = np.random.default_rng([self.seed, self.stage, step, 1])
        keys = []
        for b in range(self.batch_size):
            pos = step * self.batch_size + b
            i = int(self._permutation(pos // n)[pos % n])
            keys.append((i, *self._crop(rng, *self.sizes[i])))
        return keys


class MultiSourceDataset:
    """Several ``RaindropDataset`` (the ``data.sources`` of a configuration) behind one index:
    a key is ``(source index, sample index, y0, x0, flip)`` (what
    ``WeightedStepBatchSampler`` yields). Sample ids are reported as ``<name>/<id>``, the name
    being the source folder's name (made unique by its index when two folders share one)."""

    def __init__(self, datasets: list[RaindropDataset], names: list[str] | None = None):
        if not datasets:
            raise ValueError("no sources")
        self.datasets = list(datasets)
        names = names or [d.root.name for d in self.datasets]
        if len(set(names)) != len(names):
            names = [f"{i}:{n}" for i, n in enumerate(names)]
        self.names = names
        crops = {d.crop for d in self.datasets}
        if len(crops) != 1:
            raise ValueError(f"sources with different crop sizes: {sorted(crops)}")
        self.crop = crops.pop()
        self.flip = self.datasets[0].flip

    def __len__(self) -> int:
        return sum(len(d) for d in self.datasets)

    @property
    def sizes(self) -> list[list[tuple[int, int]]]:
        """(height, width) of every sample, per source."""
        return [d.sizes for d in self.datasets]

    def sample_id(self, key) -> str:
        s, i = key[0], key[1]
        return f"{self.names[s]}/{self.datasets[s].samples[i].id}"

    def __getitem__(self, key) -> dict:
        s, *rest = key
        item = self.datasets[s][tuple(rest)]
        item["id"] = f"{self.names[s]}/{item['id']}"
        return item


def _normalised(weights: list[float]) -> np.ndarray:
    w = np.asarray(weights, dtype=np.float64)
    if w.ndim != 1 or not len(w) or not np.all(np.isfinite(w)) or np.any(w <= 0):
        raise ValueError(f"source weights must be finite and > 0, got {list(weights)}")
    return w / w.sum()


def source_counts(weights: list[float], batch_size: int, seed: int, stage: int, step: int) -> np.ndarray:
    """How many crops of step ``step``'s batch come from each source. Source s gets
    ``floor(B w_s)`` crops, plus one more when the step's systematic sample picks it: the
    fractional parts ``B w_s - floor(B w_s)`` (summing to the r crops left) are laid end to end
    on [0, r) and the points ``u, u + 1, ..., u + r - 1`` (u uniform in [0, 1), seeded by
    (seed, stage, step)) pick the sources they fall in. Each source's expected count per step
    is exactly ``B w_s``, and every batch is within one crop of it."""
    w = _normalised(weights)
    quota = batch_size * w
    base = np.floor(quota).astype(np.int64)
    frac = quota - base
    left = int(batch_size - base.sum())
    counts = base.copy()
    if left > 0:
        u = np.random.default_rng([seed, stage, step, 2]).random()
        edges = np.cumsum(frac)
        edges[-1] = left  # absorb rounding: the fractions sum to `left`
        picks = np.searchsorted(edges, u + np.arange(left), side="right")
        counts += np.bincount(np.minimum(picks, len(w) - 1), minlength=len(w))
    return counts


class WeightedStepBatchSampler(_StepSampler):
    """``StepBatchSampler`` for several sources drawn by weight. Per step, the number of crops
    from each source is ``source_counts`` (seeded by (seed, stage, step)); within a source,
    samples come without replacement from a permutation per (seed, stage, source, epoch), the
    source reserving ``ceil(B w_s)`` positions of its own stream per step (a step that draws
    fewer leaves the rest unused), so a step's samples are a pure function of the step too.
    Crop positions and flips are seeded by (seed, stage, step). Keys: ``(source, i, y0, x0,
    flip)``."""

    def __init__(
        self,
        sizes: list[list[tuple[int, int]]],
        weights: list[float],
        crop: int,
        batch_size: int,
        seed: int,
        stage: int,
        total_steps: int,
        start_step: int = 0,
        flip: bool = True,
    ):
        if len(sizes) != len(weights):
            raise ValueError(f"{len(sizes)} sources but {len(weights)} weights")
        if any(not s for s in sizes):
            raise ValueError("a source has no samples")
        self.sizes = sizes
        self.weights = list(_normalised(weights))
        self._setup(crop, batch_size, seed, stage, total_steps, start_step, flip)
        quota = batch_size * _normalised(self.weights)
        # the most crops source_counts can give a source in one step (same arithmetic)
        self.reserved = [int(np.floor(q)) + int(q > np.floor(q)) for q in quota]
        self._perm: dict[tuple[int, int], np.ndarray] = {}

    def _permutation(self, source: int, epoch: int) -> np.ndarray:
        key = (source, epoch)
        if key not in self._perm:
            if len(self._perm) > 4 * len(self.sizes):
                self._perm.clear()
            rng = np.random.default_rng([self.seed, self.stage, epoch, 3, source])
            self._perm[key] = rng.permutation(len(self.sizes[source]))
        return self._perm[key]

    def keys_for_step(self, step: int) -> list[tuple[int, int, int, int, bool]]:
        counts = source_counts(self.weights, self.batch_size, self.seed, self.stage, step)
        rng = np.random.default_rng([self.seed, self.stage, step, 1])
        keys = []
        for s, count in enumerate(counts):
            n = len(self.sizes[s])
            for j in range(int(count)):
                pos = step * self.reserved[s] + j
                i = int(self._permutation(s, pos // n)[pos % n])
                keys.append((s, i, *self._crop(rng, *self.sizes[s][i])))
        return keys


def epochs(total_steps: int, batch_size: int, n_samples: int) -> float:
    """How many passes over the data set ``total_steps`` batches make."""
    return total_steps * batch_size / max(1, n_samples)


__all__ = [
    "DatasetError",
    "MANIFEST",
    "MultiSourceDataset",
    "RaindropDataset",
    "WeightedStepBatchSampler",
    "source_counts",
    "Sample",
    "StepBatchSampler",
    "check_files",
    "epochs",
    "read_manifest",
]
