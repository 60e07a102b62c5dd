"""The reference removal pipeline (CONTRACTS.md section 2, steps 1-7): numpy, ONNX Runtime and
OpenCV only (no torch). The C++ ``raindrop-remove`` is tested against it to within 1/255.

    python -m raindrop_tools.reference in.png out.png --models models/compact \\
        [--mask mask.png] [--threshold T] [--dilation K] [--threads N]

Exactly, in float32:

1. ``R`` = RGB uint8 / 255 (``imageio.to_float``), HxWx3.
2. ``E`` = ``edge.edge_map_numpy(R)`` on the unpadded image. Then ``R`` and ``E`` are padded
   at the bottom and right (replicate) to multiples of 2 and of ``raindrop.pad_multiple`` (the
   least common multiple; 2 for the models of raindrop_tools.export). Always even: the RDN and
   3RN have a stride-2 body trained on even crops, and at an odd size their bottom or right
   border rows come out wrong (tens of levels; the C++ Models says more).
3. ``P`` = rdn(R); ``M0 = P > float32(threshold)`` (strictly greater, compared in float32).
4. ``M`` = ``cv2.dilate(M0, getStructuringElement(MORPH_ELLIPSE, (k, k)))`` on the padded
   mask (default border: outside pixels never count); k = 1: ``M = M0``.
5. ``Ihat`` = clip(rrn(R, E), 0, 1).
6. ``B = M * Ihat + (1 - M) * R`` with M as 0.0/1.0 (so B is exactly Ihat or R).
7. ``out`` = clip(rfn(B), 0, 1), cropped to HxW, then ``floor(out * 255 + 0.5)`` as uint8
   (``imageio.to_uint8``).

With ``--surround-fill-area N`` (N > 0; default 0, the steps above exactly), step 5's ``Ihat`` is
then replaced in the small parts of ``M`` over smooth surroundings by their push-pull fill, as
``raindrop-remove`` does by default (CONTRACTS.md, "Small drops filled from their surround";
``surround_fill.py``); the padded image is one window. ``--surround-fill-rim N`` first grows
those parts, and ``M`` with them, into their rims by up to N pixels (``grow_into_rims``).

Threshold and dilation default to the ``raindrop.threshold`` / ``raindrop.dilation``
metadata of the graphs. ``--mask`` writes the final mask M (after dilation) as a 0/255 PNG.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import onnxruntime as ort

from . import contract as C
from . import int8_precision
from .edge import edge_map_numpy
from .imageio import ImageError, check_writable, read_rgb, to_float, to_uint8, write_grey, write_rgb
from .morphology import dilate_numpy
from .surround_fill import fill_small_drops_from_surround


class ModelError(ValueError):
    """Model files that do not follow the contract."""


@dataclass
class Removal:
    """What one run of the pipeline produced (all cropped to the input size)."""

    output: np.ndarray  # HxWx3 uint8
    prob: np.ndarray | None = None  # HxW float32, RDN probability
    mask: np.ndarray | None = None  # HxW uint8 0/1, after threshold and dilation
    reconstruction: np.ndarray | None = None  # HxWx3 float32 in [0, 1], clamped 3RN output
    blend: np.ndarray | None = None  # HxWx3 float32
    timings: dict[str, float] = field(default_factory=dict)  # seconds per step


def _providers(requested: list[str] | None) -> list[str]:
    available = ort.get_available_providers()
    if requested:
        missing = [p for p in requested if p not in available]
        if missing:
            raise ModelError(f"ONNX Runtime providers not available: {missing}; available: {available}")
        return requested
    preferred = [p for p in ("CUDAExecutionProvider", "CPUExecutionProvider") if p in available]
    return preferred or available


class RaindropRemover:
    """The three graphs of a model folder and the pipeline between them."""

    def __init__(self, models_dir: str | os.PathLike, threads: int | None = None, providers: list[str] | None = None):
        self.models_dir = Path(models_dir)
        so = ort.SessionOptions()
        if threads:
            so.intra_op_num_threads = int(threads)
            so.inter_op_num_threads = 1
        int8_precision.apply(so)  # int8 folders: the same output on every x86 CPU, as raindrop-remove
        self.providers = _providers(providers)
        self.threads = threads
        self.sessions: dict[str, ort.InferenceSession] = {}
        self.metadata: dict[str, dict[str, str]] = {}
        for name in C.NETWORKS:
            path = self.models_dir / C.FILES[name]
            if not path.is_file():
                raise ModelError(f"{path}: missing (expected {', '.join(C.FILES.values())} in {self.models_dir})")
            try:
                sess = ort.InferenceSession(str(path), so, providers=self.providers)
            except Exception as e:  # onnxruntime raises its own exception types
                raise ModelError(f"{path}: ONNX Runtime cannot load it: {e}") from None
            inputs = [i.name for i in sess.get_inputs()]
            outputs = [o.name for o in sess.get_outputs()]
            # rdn.onnx may also give another detector's map (shared_detector.py); this pipeline,
            # without a router, reads the first output only.
            allowed = [[C.OUTPUTS[name]]] + ([[C.OUTPUTS[name], C.ALTERNATIVE_OUTPUT]] if name == "rdn" else [])
            if sorted(inputs) != sorted(C.INPUTS[name]) or outputs not in allowed:
                want = f"{list(C.INPUTS[name])} / {[C.OUTPUTS[name]]}"
                raise ModelError(f"{path}: inputs {inputs} / outputs {outputs}, expected {want}")
            meta = sess.get_modelmeta().custom_metadata_map
            missing = [k for k in C.META_KEYS if k not in meta]
            if missing:
                raise ModelError(f"{path}: metadata missing {missing}")
            if meta[C.META_NETWORK] != name:
                raise ModelError(f"{path}: raindrop.network is {meta[C.META_NETWORK]!r}, expected {name!r}")
            self.sessions[name] = sess
            self.metadata[name] = dict(meta)
        configs = {m[C.META_CONFIG] for m in self.metadata.values()}
        if len(configs) != 1:
            raise ModelError(f"{self.models_dir}: the graphs come from different configurations: {sorted(configs)}")
        self.config = configs.pop()
        try:
            self.threshold = float(self.metadata["rdn"][C.META_THRESHOLD])
            self.dilation = int(self.metadata["rdn"][C.META_DILATION])
            multiples = [int(m[C.META_PAD_MULTIPLE]) for m in self.metadata.values()]
        except ValueError as e:
            raise ModelError(f"{self.models_dir}: unreadable raindrop.* metadata: {e}") from None
        if min(multiples) < 1:
            raise ModelError(f"{self.models_dir}: raindrop.pad_multiple must be >= 1")
        self.pad_multiple = math.lcm(2, *multiples)

    # ------------------------------------------------------------------ steps

    def _run(self, name: str, **feeds: np.ndarray) -> np.ndarray:
        out = self.sessions[name].run([C.OUTPUTS[name]], feeds)[0]
        return out

    def _pad(self, x: np.ndarray) -> np.ndarray:
        """Replicate-pad an HxW[xC] array at the bottom/right to multiples of pad_multiple."""
        m = self.pad_multiple
        h, w = x.shape[:2]
        ph, pw = (-h) % m, (-w) % m
        if ph == 0 and pw == 0:
            return x
        pads = ((0, ph), (0, pw)) + ((0, 0),) * (x.ndim - 2)
        return np.pad(x, pads, mode="edge")

    @staticmethod
    def _nchw(x: np.ndarray) -> np.ndarray:
        if x.ndim == 2:
            return np.ascontiguousarray(x[None, None])
        return np.ascontiguousarray(x.transpose(2, 0, 1)[None])

    def prepare(self, rgb_u8: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict]:
        """Steps 1-2: padded R (1x3xHpxWp) and E (1x1xHpxWp) as float32."""
        if rgb_u8.dtype != np.uint8 or rgb_u8.ndim != 3 or rgb_u8.shape[2] != 3:
            raise ImageError(f"expected an HxWx3 uint8 RGB image, got {rgb_u8.dtype} {rgb_u8.shape}")
        t = time.perf_counter()
        r = to_float(rgb_u8)
        e = edge_map_numpy(r)
        R = self._nchw(self._pad(r))
        E = self._nchw(self._pad(e))
        return R, E, {"edge": time.perf_counter() - t}

    def detect(self, R: np.ndarray) -> np.ndarray:
        """Step 3 (network part): P, 1x1xHpxWp."""
        return self._run("rdn", image=R)

    @staticmethod
    def binary_mask(P: np.ndarray, threshold: float, dilation: int) -> np.ndarray:
        """Steps 3-4: HpxWp uint8 0/1 mask from 1x1xHpxWp probabilities."""
        m0 = (P[0, 0] > np.float32(threshold)).astype(np.uint8)
        return dilate_numpy(m0, dilation)

    def reconstruct(self, R: np.ndarray, E: np.ndarray) -> np.ndarray:
        """Step 5: clip(3RN(R, E), 0, 1), 1x3xHpxWp."""
        return np.clip(self._run("rrn", image=R, edge=E), np.float32(0.0), np.float32(1.0))

    @staticmethod
    def blend(M: np.ndarray, ihat: np.ndarray, R: np.ndarray) -> np.ndarray:
        """Step 6: B = M * Ihat + (1 - M) * R, 1x3xHpxWp."""
        m = M.astype(np.float32)[None, None]
        return m * ihat + (np.float32(1.0) - m) * R

    def refine(self, B: np.ndarray) -> np.ndarray:
        """Step 7 (network part): clip(RFN(B), 0, 1), 1x3xHpxWp."""
        return np.clip(self._run("rfn", blend=B), np.float32(0.0), np.float32(1.0))

    @staticmethod
    def crop_hwc(x: np.ndarray, h: int, w: int) -> np.ndarray:
        return np.ascontiguousarray(x[0, :, :h, :w].transpose(1, 2, 0))

    # ------------------------------------------------------------------ pipelines

    def remove(
        self,
        rgb_u8: np.ndarray,
        threshold: float | None = None,
        dilation: int | None = None,
        keep_intermediates: bool = False,
        surround_fill_area: int = 0,
        surround_fill_mad: float = 4.0,
        surround_fill_rim: int = 0,
    ) -> Removal:
        """The full pipeline (steps 1-7) on an HxWx3 uint8 RGB image."""
        thr = self.threshold if threshold is None else float(threshold)
        k = self.dilation if dilation is None else int(dilation)
        if k < 1:
            raise ValueError(f"dilation must be >= 1, got {k}")
        h, w = rgb_u8.shape[:2]
        R, E, tm = self.prepare(rgb_u8)
        t = time.perf_counter()
        P = self.detect(R)
        tm["rdn"] = time.perf_counter() - t
        t = time.perf_counter()
        M = self.binary_mask(P, thr, k)
        tm["mask"] = time.perf_counter() - t
        t = time.perf_counter()
        ihat = self.reconstruct(R, E)
        tm["rrn"] = time.perf_counter() - t
        t = time.perf_counter()
        fill_small_drops_from_surround(R[0], M, surround_fill_area, surround_fill_mad, ihat[0], surround_fill_rim)
        B = self.blend(M, ihat, R)
        tm["blend"] = time.perf_counter() - t
        t = time.perf_counter()
        out = self.refine(B)
        tm["rfn"] = time.perf_counter() - t
        t = time.perf_counter()
        result = Removal(output=to_uint8(self.crop_hwc(out, h, w)))
        tm["output"] = time.perf_counter() - t
        result.timings = tm
        result.mask = np.ascontiguousarray(M[:h, :w])
        if keep_intermediates:
            result.prob = np.ascontiguousarray(P[0, 0, :h, :w])
            result.reconstruction = self.crop_hwc(ihat, h, w)
            result.blend = self.crop_hwc(B, h, w)
        return result

    def reconstruct_only(self, rgb_u8: np.ndarray) -> Removal:
        """The paper's "3RN only" baseline: round(clip(3RN(R, E), 0, 1))."""
        h, w = rgb_u8.shape[:2]
        R, E, tm = self.prepare(rgb_u8)
        t = time.perf_counter()
        ihat = self.reconstruct(R, E)
        tm["rrn"] = time.perf_counter() - t
        out = to_uint8(self.crop_hwc(ihat, h, w))
        return Removal(output=out, timings=tm)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m raindrop_tools.reference", description="Remove raindrops from one image (reference pipeline)."
    )
    ap.add_argument("input", help="input image (any format OpenCV reads; converted to 8-bit RGB)")
    ap.add_argument("output", help="output image (PNG recommended)")
    ap.add_argument("--models", required=True, help="folder with rdn.onnx, rrn.onnx, rfn.onnx")
    ap.add_argument("--mask", help="also write the final mask M (0/255) here")
    ap.add_argument("--threshold", type=float, help="mask threshold (default: the models' raindrop.threshold)")
    ap.add_argument("--dilation", type=int, help="dilation size k (default: the models' raindrop.dilation)")
    ap.add_argument("--threads", type=int, help="ONNX Runtime intra-op threads")
    ap.add_argument("--surround-fill-area", type=int, default=0,
                    help="fill parts of the mask of at most N px over smooth surroundings from them (0: off)")
    ap.add_argument("--surround-fill-mad", type=float, default=4.0,
                    help="smoothness limit of --surround-fill-area, in 8-bit levels")
    ap.add_argument("--surround-fill-rim", type=int, default=0,
                    help="grow each part --surround-fill-area fills into its rim by up to N px (0: off)")
    ap.add_argument("-v", "--verbose", action="store_true", help="print timings and mask coverage")
    args = ap.parse_args(argv)
    try:
        # As raindrop-remove: the output may not be the input (it was replaced), nor the mask the
        # output (the mask replaced it), by any name.
        def same(a: str, b: str) -> bool:
            return os.path.realpath(a) == os.path.realpath(b) or (
                os.path.exists(a) and os.path.exists(b) and os.path.samefile(a, b))

        if same(args.input, args.output) or (args.mask and same(args.input, args.mask)):
            raise ValueError(f"'{args.input}' is the input and an output; choose another name")
        if args.mask and same(args.output, args.mask):
            raise ValueError(f"'{args.output}' is given as both the output and the mask; choose another name")
        if args.dilation is not None and not 1 <= args.dilation <= 1023:
            raise ValueError(f"--dilation must be 1 to 1023, got {args.dilation}")
        for dest in [args.output] + ([args.mask] if args.mask else []):
            check_writable(dest)
        remover = RaindropRemover(args.models, threads=args.threads)
        img = read_rgb(args.input)
        if args.surround_fill_area < 0 or not args.surround_fill_mad >= 0 or args.surround_fill_rim < 0:
            raise ValueError("--surround-fill-area and --surround-fill-rim must be >= 0 and --surround-fill-mad a number >= 0")
        res = remover.remove(img, args.threshold, args.dilation, surround_fill_area=args.surround_fill_area,
                             surround_fill_mad=args.surround_fill_mad, surround_fill_rim=args.surround_fill_rim)
        write_rgb(args.output, res.output)
        if args.mask:
            write_grey(args.mask, res.mask * np.uint8(255))
    except (ModelError, ImageError, ValueError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    if args.verbose:
        total = sum(res.timings.values()) * 1000
        steps = ", ".join(f"{k} {v * 1000:.1f}" for k, v in res.timings.items())
        print(
            f"{args.input}: {img.shape[1]}x{img.shape[0]}, mask {res.mask.mean() * 100:.2f}%, {total:.1f} ms ({steps})"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
