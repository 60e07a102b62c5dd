"""A camera's wet gate: whether a frame holds drops at all, fitted on that camera's own frames.

    python -m raindrop_tools.wet_gate fit --wet DIR [--wet DIR ...] --dry DIR [--dry DIR ...] \\
        --out camera.gate [--models DIR] [--keep-wet 0.99]
    python -m raindrop_tools.wet_gate judge --gate camera.gate [--models DIR] IMAGE...
    raindrop-remove --wet-gate camera.gate IN OUT

A pipeline runs raindrop-remove on every frame, wet or dry, and on a dry frame every change is
damage. On a camera that looks into overexposed sky (a lens cover), the detector takes sky,
clouds and the edges of foliage for drops: on the real pairs' dry lens the default marked 39% of
each frame (docs/RESULTS.md 4.70). A gate fitted on many cameras at once could not tell such
frames from wet ones; one fitted on a camera's own frames, labelled wet or dry as whole frames
(no masks), can. raindrop-remove then writes a frame the gate judges dry as it was, with an empty
mask (include/raindrop/remove/wet_gate.h).

Features: the ten of the detector router (detector_router.features) of the detector's map at the
automatic working scale, and, where the models' rdn.onnx computes a second map (the default's
does: shared_detector.py), also of that one (``maps 2``). A logistic regression (L2-penalised,
each class weighted alike), whose threshold is then set so that the fitted gate keeps
``--keep-wet`` of the wet training frames (z > 0: wet) and folded into the bias. The file:

    # comment lines
    format 1
    models compact-multiscale-int8     (the folder whose detector gave the features)
    maps 2
    mean   <10 x maps numbers>
    std    <10 x maps numbers>
    weight <10 x maps numbers>
    bias   <number>

raindrop-remove accepts it for those models, their int8 copy, or the float folder an int8 copy
was made from (the same detector). Fitted for one camera, it is wrong for others.
"""

from __future__ import annotations

import argparse
import os
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import int8_precision
from .detector_router import FEATURES, features, fit as fit_logistic, working_copy, working_size_of
from .imageio import ImageError, native_to_float, read_rgb_native
from .key_file import check_format, finite_vector, key_file_path_problem, read_fields, single_name, write_fields
from .read_only import ReadOnlyFileError

FORMAT = 1
IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp")
REPO = Path(__file__).resolve().parents[2]


class GateError(ValueError):
    """A gate file or request refused, reported on one line."""


@dataclass
class WetGate:
    models: str
    maps: int
    mean: np.ndarray
    std: np.ndarray
    weight: np.ndarray
    bias: float

    def score(self, f: np.ndarray) -> np.ndarray:
        """z per row of `f` (N x 10 maps, or one row): above 0, wet."""
        return (np.atleast_2d(f) - self.mean) / self.std @ self.weight + self.bias


def default_models() -> Path:
    """The folder raindrop-remove loads by default on this CPU: models/DEFAULT's first line, or
    on an x86 CPU with VNNI the name of its line 'vnni NAME' (include/raindrop/remove/model_paths.h)."""
    lines = [line.split() for line in (REPO / "models" / "DEFAULT").read_text().splitlines() if line.split()]
    name = lines[0][0]
    vnni = next((w[1] for w in lines[1:] if w[0] == "vnni" and len(w) == 2), None)
    if vnni and int8_precision.cpu_has_vnni():
        name = vnni
    return REPO / "models" / name


def folder_name(models: str | os.PathLike) -> str:
    """The name raindrop-remove gives a model folder: the last component of its absolute path,
    symbolic links not followed ("models/x/", "." inside it and a link named "current" are "x",
    "x" and "current")."""
    return os.path.basename(os.path.normpath(os.path.abspath(models)))


def float_twin(name: str) -> str:
    """The float folder an int8 copy was made from (the name without '-int8'); others as they are."""
    return name[: -len("-int8")] if name.endswith("-int8") and len(name) > len("-int8") else name


class MapFeatures:
    """The gate's features of images, from a model folder's detector, on the pixels as
    raindrop-remove reads and scales them (16-bit ones at 16 bits)."""

    def __init__(self, models: str | os.PathLike, threads: int = 2):
        from .reference import RaindropRemover

        self.remover = RaindropRemover(models, threads=threads)
        self.session = self.remover.sessions["rdn"]
        self.maps = len(self.session.get_outputs())
        self.name = folder_name(models)

    def __call__(self, rgb: np.ndarray) -> np.ndarray:
        """`rgb`: read_rgb_native's pixels (uint8, uint16 or float32)."""
        small = working_copy(rgb, working_size_of(self.remover))
        h, w = small.shape[:2]
        R = self.remover._nchw(self.remover._pad(native_to_float(small)))
        maps = self.session.run(None, {"image": R})
        return np.concatenate([features(m[0, 0, :h, :w]) for m in maps[: self.maps]])


def image_files(folder: str | os.PathLike) -> list[Path]:
    """The images under `folder`, recursively, in name order."""
    folder = Path(folder)
    if not folder.is_dir():
        raise GateError(f"'{folder}': not a folder")
    files = sorted(p for p in folder.rglob("*") if p.is_file() and p.suffix.lower() in IMAGE_EXTENSIONS)
    if not files:
        raise GateError(f"'{folder}': no images ({', '.join(IMAGE_EXTENSIONS)})")
    return files


def fit(wet: np.ndarray, dry: np.ndarray, models: str, keep_wet: float = 0.99) -> WetGate:
    """The gate from the features of wet and dry frames (N x 10 maps each): each class weighted
    alike, then the bias moved so that a share `keep_wet` of the wet frames score above 0 (the
    lowest of them kept, at 1.0)."""
    if len(wet) < 2 or len(dry) < 2:
        raise GateError(f"need at least 2 wet and 2 dry frames, got {len(wet)} and {len(dry)}")
    if not 0 < keep_wet <= 1:
        raise GateError(f"--keep-wet must be in (0, 1], got {keep_wet}")
    X = np.vstack([wet, dry])
    y = np.r_[np.ones(len(wet)), np.zeros(len(dry))]
    w = np.r_[np.full(len(wet), 0.5 / len(wet)), np.full(len(dry), 0.5 / len(dry))]
    r = fit_logistic(X, y, w, alternative="-", l2=1e-2, iters=3000, lr=0.5)
    gate = WetGate(models, X.shape[1] // FEATURES, r.mean, r.std, r.weight, r.bias)
    z = np.sort(gate.score(wet))
    # The lowest wet score kept, the frames below it let go; the threshold halfway between it
    # and the highest training score below it (a let-go wet frame or a dry one), so that a
    # frame scored a little differently (another thread count, another build) stays on its side,
    # and at least a millionth below it (a dry frame may score within rounding of it).
    let_go = min(int(np.floor((1 - keep_wet) * len(z) + 1e-9)), len(z) - 1)
    kept = z[let_go]
    below = np.concatenate([z[:let_go], gate.score(dry)])
    below = below[below < kept]
    threshold = 0.5 * (kept + below.max()) if len(below) else kept - 1.0
    threshold = min(threshold, kept - 1e-6 * max(1.0, abs(kept)))
    gate.bias = float(gate.bias - threshold)
    return gate


def write_gate(path: str | os.PathLike, gate: WetGate, comment: str = "") -> None:
    """Writes the gate file (format above) beside itself and renames it over `path`."""
    write_fields(path, [("format", FORMAT), ("models", gate.models), ("maps", gate.maps), ("mean", gate.mean),
                        ("std", gate.std), ("weight", gate.weight), ("bias", repr(float(gate.bias)))], GateError, comment)


def read_gate(path: str | os.PathLike) -> WetGate:
    """Reads a gate file; GateError naming the file and what is wrong (as raindrop-remove)."""
    path = Path(path)
    fields = read_fields(path, GateError)
    check_format(fields, FORMAT, path, GateError)
    models = single_name(fields, "models", path, GateError, "one model folder")
    if fields.get("maps") not in (["1"], ["2"]):
        raise GateError(f"'{path}': 'maps' must be 1 or 2")
    maps = int(fields["maps"][0])

    def vector(key: str, n: int, positive: bool = False) -> np.ndarray:
        return finite_vector(fields, key, n, path, GateError, positive)

    n = maps * FEATURES
    std = vector("std", n, positive=True)
    return WetGate(models, maps, vector("mean", n), std, vector("weight", n), float(vector("bias", 1)[0]))


def _frames_of(folders: list[str]) -> list[Path]:
    return [f for d in folders for f in image_files(d)]


def _fit_command(args) -> int:
    problem = key_file_path_problem(args.out, GateError, "models")  # before the work
    if problem:
        raise GateError(problem)
    # A frame labelled both wet and dry (the same folder given twice, say) teaches nothing, and
    # a gate fitted on such labels is no gate: refused before the detector runs on every frame.
    wet_files, dry_files = _frames_of(args.wet), _frames_of(args.dry)
    both = {f.resolve() for f in wet_files} & {f.resolve() for f in dry_files}
    if both:
        raise GateError(f"{len(both)} frame(s) are given as both wet and dry (e.g. '{sorted(both)[0]}'): "
                        "--wet and --dry must name different frames")
    models = Path(args.models) if args.models else default_models()
    feats = MapFeatures(models, args.threads)
    if not feats.name.split() or feats.name.split() != [feats.name]:
        raise GateError(f"'{models}': a model folder whose name holds spaces cannot be named in a gate file")
    wet = np.array([feats(read_rgb_native(f)) for f in wet_files])
    dry = np.array([feats(read_rgb_native(f)) for f in dry_files])
    gate = fit(wet, dry, feats.name, args.keep_wet)
    kept, passed = np.mean(gate.score(wet) > 0), np.mean(gate.score(dry) <= 0)
    comment = (f"raindrop wet gate: an image is processed where z > 0, else written as it was.\n"
               f"Fitted by raindrop_tools.wet_gate on {len(wet)} wet and {len(dry)} dry frames with the detector of "
               f"'{feats.name}' ({gate.maps} map{'s' if gate.maps > 1 else ''}); on them it keeps {kept:.0%} of the wet "
               f"and judges {passed:.0%} of the dry frames dry.\n"
               f"Fitted for one camera: wrong for others.")
    write_gate(args.out, gate, comment)
    print(comment.replace("\n", " "))
    return 0


def _judge_command(args) -> int:
    gate = read_gate(args.gate)
    models = Path(args.models) if args.models else default_models()
    feats = MapFeatures(models, args.threads)
    if float_twin(gate.models) != float_twin(feats.name):
        raise GateError(f"'{args.gate}': fitted on the detector of '{gate.models}', not of '{feats.name}'")
    if feats.maps < gate.maps:
        raise GateError(f"'{args.gate}': fitted on {gate.maps} maps, and '{feats.name}''s detector computes {feats.maps}")
    for image in args.images:
        z = float(gate.score(feats(read_rgb_native(image))[: gate.maps * FEATURES])[0])
        print(f"{image} {z:+.6f} {'dry' if z <= 0 else 'wet'}")
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m raindrop_tools.wet_gate", description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="command", required=True)
    f = sub.add_parser("fit", help="fit a gate on one camera's frames, labelled wet or dry by folder")
    f.add_argument("--wet", action="append", required=True, help="a folder of the camera's frames with drops (repeatable)")
    f.add_argument("--dry", action="append", required=True, help="a folder of its frames without drops (repeatable)")
    f.add_argument("--out", required=True, help="the gate file to write")
    f.add_argument("--models", help="the model folder raindrop-remove will use (default: the one it loads on this CPU)")
    f.add_argument("--keep-wet", type=float, default=0.99,
                   help="share of the wet frames the gate must keep (default 0.99); the rest of the threshold's "
                        "trade-off is the dry frames it judges dry")
    f.add_argument("--threads", type=int, default=2)
    j = sub.add_parser("judge", help="print each image's z and whether the gate judges it wet or dry")
    j.add_argument("--gate", required=True)
    j.add_argument("--models", help="the model folder (default: the one raindrop-remove loads on this CPU)")
    j.add_argument("images", nargs="+")
    j.add_argument("--threads", type=int, default=2)
    args = ap.parse_args(argv)
    from .reference import ModelError

    try:
        return _fit_command(args) if args.command == "fit" else _judge_command(args)
    except (GateError, ModelError, ImageError, ReadOnlyFileError, OSError) as e:
        print(f"wet_gate: {e}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
