"""Run configuration: one YAML file holds everything a training run needs.

The YAML maps onto the nested dataclasses below. Unknown keys are errors (a typo must not
silently fall back to a default), missing keys take the defaults shown here, which are the
paper's configuration. ``resolve_config`` returns the fully populated configuration, which
the trainer writes into the run folder as ``config.yaml``.

This module does not import torch: the network *configuration* lives here, the network
*definitions* in ``networks.py``.
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml


class ConfigError(ValueError):
    """A configuration file or override that cannot be used."""


# --------------------------------------------------------------------------- networks


@dataclass(frozen=True)
class HalfResConfig:
    """RDN / 3RN: conv1 (3x3, in->width), conv2 (3x3 stride 2, width->width), conv3 (1x1,
    width->expanded), `blocks` bottleneck residual blocks at half resolution (1x1
    expanded->width, 3x3 width->width, 1x1 width->expanded), conv4 (transposed 4x4 stride 2,
    expanded->width), conv5 (3x3, width->out)."""

    width: int = 64
    expanded: int = 256
    blocks: int = 6
    # output = image + net(input); only meaningful for 3RN (RDN outputs a mask).
    global_residual: bool = False


@dataclass(frozen=True)
class RefineConfig:
    """RFN: conv (3x3, 3->width), `blocks` basic residual blocks (two 3x3 width->width),
    conv (3x3, width->3)."""

    width: int = 64
    blocks: int = 2
    global_residual: bool = False


@dataclass(frozen=True)
class NetworkConfig:
    rdn: HalfResConfig = field(default_factory=lambda: HalfResConfig(blocks=6))
    rrn: HalfResConfig = field(default_factory=lambda: HalfResConfig(blocks=8))
    rfn: RefineConfig = field(default_factory=RefineConfig)


# --------------------------------------------------------------------------- run


@dataclass(frozen=True)
class SourceConfig:
    """One data set folder of ``data.sources``: training draws from the sources by weight."""

    # Data set folder (CONTRACTS.md section 1 layout: rendered, or real pairs written by
    # ``raindrop_tools.realpairs prepare``). Relative paths: against the working directory.
    path: str = ""
    # Share of every batch drawn from this source (weights are normalised to sum to 1).
    weight: float = 1.0
    # Manifest "split" values to use: a string or a list; null = data.splits.
    split: str | list[str] | None = None
    # rainy == clean outside the mask; null = data.check_outside_mask. Real pairs: false.
    check_outside_mask: bool | None = None
    # Training targets: keep only mask pixels where the drop visibly changes the image, i.e.
    # where |luma(rainy) - luma(clean)|, box-blurred 5x5, exceeds this many 8-bit levels
    # (0: the mask as written; data.visible_difference). Thin-lens masks (coverage >= 0.1)
    # include faint halos and drops invisible over smooth backgrounds; learnt as they are, the
    # detector flagged flat road and wall as drops (docs/RESULTS.md 4.4). Real pairs' rough
    # masks threshold a similar difference (each image blurred first) at 12 levels.
    visible_levels: float = 0.0
    # Sensor noise after the optics, as a camera adds it: Gaussian noise with a standard
    # deviation drawn per crop from [0, this] 8-bit levels, the SAME noise field added to the
    # rainy and the clean image (then rounded to 8-bit steps). The renderer defocuses its
    # (noisy) input inside drops, so rendered drops are noise-free where real ones are as noisy
    # as their surround, and a detector trained without noise takes "noise-free" for a drop.
    # (With it, the fine-tuned detector still flagged flat road, by smoothness instead:
    # docs/RESULTS.md 4.5.) 0: off (real pairs carry their own noise).
    sensor_noise_levels: float = 0.0
    # Weight of this source's crops in the detector's (RDN) loss; the reconstruction networks
    # learn from every source alike. 0 keeps a source's masks out of what the detector learns:
    # for real pairs, whose rough masks mark every difference between the two lenses (stereo
    # parallax, exposure, the wet glass's haze over flat road) and taught the fine-tuned
    # detectors to flag smooth regions (docs/RESULTS.md 4.4-4.7).
    detection_weight: float = 1.0
    # Train on this source's images downscaled by this factor (area averaging; masks averaged
    # the same way and thresholded at one half), in (0, 1]. raindrop-remove's coarse pass for
    # large drops runs the networks at a third of the working scale: real lens-cover drops
    # 50-200 px across become the 15-70 px the networks handle there (docs/RESULTS.md 4.6-4.7).
    scale: float = 1.0
    # Photometric jitter, the same on the rainy and the clean image of a crop (one scene seen
    # with another exposure, white balance and tone curve): per crop an exposure gain
    # exp(U(-p, p)), per-channel gains exp(U(-p/4, p/4)) and a gamma exp(U(-p/2, p/2)), in that
    # order, clipped to [0, 1]. 0: off. Meant for real pairs: 50 photographs of a few scenes,
    # each seen about a hundred times in a run, whose colours the networks otherwise learn.
    photometric: float = 0.0


@dataclass(frozen=True)
class DataConfig:
    # Rendered data set folder (CONTRACTS.md section 1). Relative paths are resolved against
    # the current working directory when the configuration is loaded. Used when ``sources``
    # is null (or empty).
    train: str = "data/train"
    # Several data set folders with weights (``SourceConfig``); replaces ``train``. E.g.
    # [{path: data/train, weight: 0.7}, {path: data/real, weight: 0.3, split: train,
    #   check_outside_mask: false}]. crop, flip, cache and validate apply to every source.
    sources: list[SourceConfig] | None = None
    # Manifest "split" values to train on; null uses every sample.
    splits: list[str] | None = None
    crop: int = 100
    flip: bool = True
    # Keep decoded uint8 images in RAM (preloaded before the loader workers fork).
    cache: bool = False
    # Refuse to cache when the decoded set would exceed this many GiB (then read from disk).
    cache_max_gib: float = 8.0
    # "full": decode every image once and check sizes, mask values and rainy == clean
    # outside the mask; "header": only PNG headers (sizes); both check the manifest itself.
    validate: str = "full"
    # rainy == clean wherever mask == 0 (CONTRACTS.md section 1); checked when validate=full.
    check_outside_mask: bool = True
    workers: int = 0


@dataclass(frozen=True)
class TrainConfig:
    batch_size: int = 32
    stage1_steps: int = 50000
    stage2_steps: int = 50000
    lr: float = 1.0e-3
    lr_end: float = 1.0e-4
    # The learning rate decays linearly from lr to lr_end between these fractions of a
    # stage's steps (the paper: from epoch 20 to epoch 40 of 50).
    decay_start: float = 0.4
    decay_end: float = 0.8
    betas: list[float] = field(default_factory=lambda: [0.9, 0.999])
    checkpoint_every: int = 1000
    # Checkpoints kept per stage (the last step of stage 1 is always kept: stage 2 starts
    # from it).
    keep_checkpoints: int = 3
    log_every: int = 50
    # NHWC memory layout for convolutions: about 1.5x faster training steps on CPU with
    # oneDNN (measured on this project's 2-core machine); results equal up to rounding.
    channels_last: bool = False
    # Keep every BatchNorm in eval mode while training (its running statistics fixed, its
    # scale and shift still learnt). Needed to fine-tune from an exported model folder, whose
    # BatchNorms come back folded into identities (onnx_weights.py); a usual choice for small
    # fine-tuning batches too.
    freeze_batchnorm: bool = False


@dataclass(frozen=True)
class LossConfig:
    # 3RN: L1 weighted by this inside the ground-truth mask, 1 outside.
    rrn_mask_weight: float = 20.0
    # RFN: alpha (1 - SSIM) + (1 - alpha) L1.
    rfn_ssim_weight: float = 0.3
    # SSIM window of pytorch_msssim (Gaussian, sigma 1.5).
    ssim_window: int = 11


@dataclass(frozen=True)
class PipelineConfig:
    # M0 = RDN probability > threshold (strictly greater); the paper leaves it open, the
    # authors' released code used 0.3.
    threshold: float = 0.3
    # Elliptical dilation size k (k x k, OpenCV MORPH_ELLIPSE); 1 = none. Released code: 3.
    dilation: int = 3


@dataclass(frozen=True)
class RunConfig:
    name: str = "paper"
    seed: int = 1234
    data: DataConfig = field(default_factory=DataConfig)
    network: NetworkConfig = field(default_factory=NetworkConfig)
    train: TrainConfig = field(default_factory=TrainConfig)
    loss: LossConfig = field(default_factory=LossConfig)
    pipeline: PipelineConfig = field(default_factory=PipelineConfig)


# --------------------------------------------------------------------------- (de)serialisation


def _coerce(value: Any, tp: Any, where: str) -> Any:
    """Convert a YAML value to the annotated type, or raise ConfigError naming the key."""
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if origin in (typing.Union, getattr(__import__("types"), "UnionType", None)):
        if value is None and type(None) in args:
            return None
        inner = [a for a in args if a is not type(None)]
        # str | list[str]: a list goes to the list alternative
        if len(inner) > 1 and isinstance(value, (list, tuple)):
            inner = [a for a in inner if typing.get_origin(a) is list] or inner
        return _coerce(value, inner[0], where)
    if dataclasses.is_dataclass(tp):
        if not isinstance(value, dict):
            raise ConfigError(f"{where}: expected a mapping, got {value!r}")
        return _from_dict(tp, value, where)
    if origin is list:
        if not isinstance(value, (list, tuple)):
            raise ConfigError(f"{where}: expected a list, got {value!r}")
        return [_coerce(v, args[0], f"{where}[{i}]") for i, v in enumerate(value)]
    if tp is bool:
        if isinstance(value, bool):
            return value
        raise ConfigError(f"{where}: expected true/false, got {value!r}")
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, (int, str)):
            raise ConfigError(f"{where}: expected an integer, got {value!r}")
        try:
            return int(value)
        except ValueError:
            raise ConfigError(f"{where}: expected an integer, got {value!r}") from None
    if tp is float:
        # PyYAML reads "1e-3" (no dot) as a string: accept numeric strings.
        if isinstance(value, bool):
            raise ConfigError(f"{where}: expected a number, got {value!r}")
        try:
            return float(value)
        except (TypeError, ValueError):
            raise ConfigError(f"{where}: expected a number, got {value!r}") from None
    if tp is str:
        if not isinstance(value, str):
            raise ConfigError(f"{where}: expected a string, got {value!r}")
        return value
    return value


def _from_dict(cls: type, data: dict, where: str = "") -> Any:
    hints = typing.get_type_hints(cls)
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(data) - names)
    if unknown:
        prefix = f"{where}." if where else ""
        raise ConfigError(
            f"unknown configuration key(s) {', '.join(prefix + k for k in unknown)}; "
            f"known under {where or 'the top level'}: {', '.join(sorted(names))}"
        )
    kwargs = {}
    for f in dataclasses.fields(cls):
        if f.name not in data:
            continue
        key = f"{where}.{f.name}" if where else f.name
        value = data[f.name]
        if dataclasses.is_dataclass(hints[f.name]) and isinstance(value, dict):
            # A partial mapping for a nested dataclass starts from the field's default (e.g.
            # network.rrn keeps blocks=8 when only its width is given).
            default = f.default_factory() if f.default_factory is not dataclasses.MISSING else f.default
            value = {**to_dict(default), **value}
        kwargs[f.name] = _coerce(value, hints[f.name], key)
    return cls(**kwargs)


def to_dict(cfg: Any) -> dict:
    return dataclasses.asdict(cfg)


def is_safe_name(name: str) -> bool:
    """A configuration name is also a folder name under models/: one plain word (no path, no
    '.' or '..', nothing hidden)."""
    return bool(re.fullmatch(r"[A-Za-z0-9_][A-Za-z0-9._-]*", name or ""))


def validate_config(cfg: RunConfig) -> None:
    """Range checks that the type system does not express."""
    problems = []
    if not is_safe_name(cfg.name):
        problems.append(f"name must be a file-name-safe word (letters, digits, '.', '_', '-'; not starting with '.' "
                        f"or '-'), got {cfg.name!r}")
    for net in ("rdn", "rrn"):
        c = getattr(cfg.network, net)
        if c.width < 1 or c.expanded < 1 or c.blocks < 0:
            problems.append(f"network.{net}: width/expanded must be >= 1 and blocks >= 0")
    if cfg.network.rdn.global_residual:
        problems.append("network.rdn.global_residual: RDN predicts a mask, it has no residual")
    if cfg.network.rfn.width < 1 or cfg.network.rfn.blocks < 0:
        problems.append("network.rfn: width must be >= 1 and blocks >= 0")
    if cfg.data.crop < 2 or cfg.data.crop % 2:
        # The RDN and 3RN halve and double the resolution; the pipelines only ever show them
        # even sizes (they pad images to even first), so they must learn at even sizes.
        problems.append("data.crop must be an even number >= 2")
    if cfg.data.validate not in ("full", "header"):
        problems.append("data.validate must be 'full' or 'header'")
    if cfg.data.workers < 0:
        problems.append("data.workers must be >= 0")
    for i, src in enumerate(cfg.data.sources or []):
        if not src.path:
            problems.append(f"data.sources[{i}].path is empty")
        if not (src.weight > 0 and src.weight < float("inf")):
            problems.append(f"data.sources[{i}].weight must be > 0, got {src.weight}")
        if not (0.0 <= src.visible_levels <= 255.0):
            problems.append(f"data.sources[{i}].visible_levels must be in [0, 255], got {src.visible_levels}")
        if not (0.0 <= src.sensor_noise_levels <= 64.0):
            problems.append(f"data.sources[{i}].sensor_noise_levels must be in [0, 64], got {src.sensor_noise_levels}")
        if not (0.0 < src.scale <= 1.0):
            problems.append(f"data.sources[{i}].scale must be in (0, 1], got {src.scale}")
        if not (0.0 <= src.photometric <= 1.0):
            problems.append(f"data.sources[{i}].photometric must be in [0, 1], got {src.photometric}")
        if not (0.0 <= src.detection_weight <= 100.0):
            problems.append(f"data.sources[{i}].detection_weight must be in [0, 100], got {src.detection_weight}")
    t = cfg.train
    if t.batch_size < 1 or t.stage1_steps < 1 or t.stage2_steps < 1:
        problems.append("train.batch_size, stage1_steps and stage2_steps must be >= 1")
    if not 0.0 <= t.decay_start <= t.decay_end <= 1.0:
        problems.append("train: need 0 <= decay_start <= decay_end <= 1")
    # Written so that NaN fails too (every comparison with it is false); Inf trained to NaN
    # weights that were saved as the latest checkpoint.
    if not (0 < t.lr < math.inf and 0 < t.lr_end < math.inf):
        problems.append(f"train.lr and train.lr_end must be finite and > 0, got {t.lr} and {t.lr_end}")
    if len(t.betas) != 2:
        problems.append("train.betas must have two values")
    elif not all(0.0 <= b < 1.0 for b in t.betas):
        problems.append(f"train.betas must be in [0, 1), got {t.betas}")
    if not 0 <= cfg.seed < 2**63:
        problems.append(f"seed must be in [0, 2^63), got {cfg.seed}")
    if t.checkpoint_every < 1 or t.keep_checkpoints < 1 or t.log_every < 1:
        problems.append("train.checkpoint_every, keep_checkpoints and log_every must be >= 1")
    if not 0.0 <= cfg.loss.rfn_ssim_weight <= 1.0:
        problems.append("loss.rfn_ssim_weight must be in [0, 1]")
    if not (math.isfinite(cfg.loss.rrn_mask_weight) and cfg.loss.rrn_mask_weight >= 0):  # -20 trained away from the truth
        problems.append("loss.rrn_mask_weight must be a number >= 0")
    if cfg.loss.ssim_window < 1 or cfg.loss.ssim_window % 2 == 0:
        problems.append("loss.ssim_window must be odd")
    if cfg.loss.ssim_window > cfg.data.crop:
        problems.append("loss.ssim_window must not exceed data.crop")
    if not 0.0 <= cfg.pipeline.threshold < 1.0:
        problems.append("pipeline.threshold must be in [0, 1)")
    if not 1 <= cfg.pipeline.dilation <= 1023:  # as raindrop-remove --dilation (100001 asked for 31 GiB)
        problems.append("pipeline.dilation must be 1 to 1023")
    if problems:
        raise ConfigError("invalid configuration:\n  " + "\n  ".join(problems))


def _set_dotted(data: dict, dotted: str, value: Any) -> None:
    keys = dotted.split(".")
    node = data
    for k in keys[:-1]:
        node = node.setdefault(k, {})
        if not isinstance(node, dict):
            raise ConfigError(f"override {dotted}: {k} is not a mapping")
    node[keys[-1]] = value


def parse_overrides(items: list[str] | None) -> list[tuple[str, Any]]:
    """``key.sub=value`` strings (values parsed as YAML) to (key, value) pairs."""
    out = []
    for item in items or []:
        if "=" not in item:
            raise ConfigError(f"override {item!r}: expected key=value")
        key, raw = item.split("=", 1)
        try:
            value = load_yaml(raw)
        except yaml.YAMLError as e:  # '[1' gave a parser traceback
            raise ConfigError(f"override {item!r}: the value is not YAML ({yaml_error_text(e)})") from None
        out.append((key.strip(), value))
    return out


def config_from_dict(data: dict, overrides: list[tuple[str, Any]] | None = None) -> RunConfig:
    data = yaml.safe_load(yaml.safe_dump(data or {}))  # deep copy, plain types
    for key, value in overrides or []:
        _set_dotted(data, key, value)
    cfg = _from_dict(RunConfig, data)
    validate_config(cfg)
    return cfg


class _UniqueKeyLoader(yaml.SafeLoader):
    """YAML's safe loader, refusing a key given twice in one mapping: YAML keeps the last, so a
    second top-level 'train:' replaced the first section's settings without a word."""


def _mapping_without_repeats(loader: yaml.SafeLoader, node: yaml.MappingNode, deep: bool = False) -> dict:
    seen = set()
    for key_node, _ in node.value:
        if key_node.tag == "tag:yaml.org,2002:merge":  # '<<: *anchor': its keys may be overridden
            continue
        key = loader.construct_object(key_node, deep=deep)
        if key in seen:
            raise yaml.constructor.ConstructorError(None, None, f"the key {key!r} is given twice",
                                                    key_node.start_mark)
        seen.add(key)
    return loader.construct_mapping(node, deep)


_UniqueKeyLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _mapping_without_repeats)


def load_yaml(text: str):
    """``text`` as YAML (safe types), a key given twice in one mapping refused (yaml.YAMLError).
    A value its tag cannot take ('!!int x', a list as a key) is a yaml.YAMLError too: PyYAML's
    constructors raise ValueError, TypeError or AttributeError there."""
    try:
        return yaml.load(text, Loader=_UniqueKeyLoader)
    except yaml.YAMLError:
        raise
    except (ValueError, TypeError, AttributeError, IndexError, KeyError, OverflowError) as e:
        raise yaml.YAMLError(f"a value YAML cannot construct ({type(e).__name__}: {e})") from None


def _where(mark) -> str:
    return f"line {mark.line + 1}, column {mark.column + 1}"


def yaml_error_text(e: yaml.YAMLError) -> str:
    """One line for a YAML error, not PyYAML's several lines that quote the text and point at it
    with a caret: what went wrong and where (line and column, 1-based), after what it was parsing
    and where that began (an unclosed '[' is found a line later)."""
    lines = str(e).splitlines()
    problem = getattr(e, "problem", None) or (lines[0] if lines else type(e).__name__)
    mark = getattr(e, "problem_mark", None)
    text = problem if mark is None else f"{problem} ({_where(mark)})"
    if isinstance(e, yaml.reader.ReaderError):  # a character YAML refuses: no line, a position
        text = f"{problem} (character {e.position + 1})"
    context = getattr(e, "context", None)
    if context:
        cmark = getattr(e, "context_mark", None)
        same = cmark is None or (mark is not None and (cmark.line, cmark.column) == (mark.line, mark.column))
        text = f"{context}{'' if same else f' ({_where(cmark)})'}: {text}"
    return text


def load_config(
    path: str | os.PathLike, overrides: list[tuple[str, Any]] | None = None, resolve_paths: bool = True
) -> RunConfig:
    path = Path(path)
    try:
        data = load_yaml(path.read_text()) or {}
    except OSError as e:
        raise ConfigError(f"cannot read configuration {path}: {e}") from None
    except yaml.YAMLError as e:
        raise ConfigError(f"{path}: not valid YAML: {yaml_error_text(e)}") from None
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a mapping at the top level")
    try:
        _check_one_data_form(data, overrides)
        if any(k == "data.sources" for k, _ in overrides or []) and isinstance(data.get("data"), dict):
            data = {**data, "data": {k: v for k, v in data["data"].items() if k != "train"}}
        cfg = config_from_dict(data, overrides)
    except ConfigError as e:
        raise ConfigError(f"{path}: {e}") from None
    return resolve_data_paths(cfg) if resolve_paths else cfg


def _check_one_data_form(data: dict, overrides: list[tuple[str, Any]] | None) -> None:
    """``data.train`` and ``data.sources`` must not both be given where one would be silently
    ignored: both in the file, or ``data.train`` (``--data``) as an override of a
    configuration with sources. An override ``data.sources`` replaces the file's
    ``data.train``. Only checked on what a user writes: a resolved config.yaml holds both keys
    (every default filled in)."""
    section = data.get("data") if isinstance(data.get("data"), dict) else {}
    over = dict(overrides or [])
    file_sources = bool(section.get("sources"))
    sources = bool(over["data.sources"]) if "data.sources" in over else file_sources
    if ("train" in section and file_sources and "data.sources" not in over) or ("data.train" in over and sources):
        raise ConfigError(
            "data.train (or --data) and data.sources are both given; data.sources replaces data.train: "
            "give one of them"
        )


def data_sources(cfg: RunConfig) -> list[SourceConfig]:
    """The effective sources: ``data.sources``, or ``data.train`` as a single source. Each
    has its split list (a list or None) and check_outside_mask filled in from ``data``."""
    d = cfg.data
    if not d.sources:
        return [SourceConfig(path=d.train, weight=1.0, split=d.splits, check_outside_mask=d.check_outside_mask)]
    out = []
    for s in d.sources:
        split = d.splits if s.split is None else ([s.split] if isinstance(s.split, str) else list(s.split))
        check = d.check_outside_mask if s.check_outside_mask is None else s.check_outside_mask
        out.append(SourceConfig(path=s.path, weight=s.weight, split=split, check_outside_mask=check,
                                visible_levels=s.visible_levels, sensor_noise_levels=s.sensor_noise_levels,
                                detection_weight=s.detection_weight, scale=s.scale))
    return out


def _absolute(path: str, base: Path) -> str:
    p = Path(path).expanduser()
    return str(p if p.is_absolute() else (base / p).resolve())


def resolve_data_paths(cfg: RunConfig, base: Path | None = None) -> RunConfig:
    base = Path.cwd() if base is None else base
    sources = cfg.data.sources
    if sources:
        sources = [dataclasses.replace(s, path=_absolute(s.path, base)) for s in sources]
    return dataclasses.replace(
        cfg, data=dataclasses.replace(cfg.data, train=_absolute(cfg.data.train, base), sources=sources)
    )


def dump_config(cfg: RunConfig) -> str:
    return yaml.safe_dump(to_dict(cfg), sort_keys=False)
