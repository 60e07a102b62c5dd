"""Evaluate exported models on a held-out rendered data set (docs/DESIGN.md section 6).

    python -m raindrop_tools.evaluate --data data/test --models models/compact --out out/eval-compact

Runs the reference pipeline (``reference.RaindropRemover``, ONNX Runtime) on every sample
and writes to ``--out``:

* ``results.md`` and ``results.json``: one row per method, as the paper's Table 1 -
  input (no removal), 3RN only, 3RN + RDN + RFN without dilation (k = 1), and with the
  dilation size k (the models' ``raindrop.dilation`` or ``--dilation``); columns PSNR and
  SSIM in both conventions of ``metrics``, detection AP (rows that use RDN), milliseconds per
  image (the pipeline steps the row needs, file I/O excluded);
* ``pr_curve.png``: the pixel-level precision-recall curve of RDN;
* ``per_image.csv``: every metric per image and row.

No torch needed. The RDN and 3RN outputs are computed once per image and shared by the rows;
each row's time is the sum of the steps it uses.

This scores the networks as the contract's single pass runs them: at the images' own size, with
the folder's own detector. What ``raindrop-remove`` adds around them (the working scale, the
coarse pass for large drops, the fill of small drops, the detector router of a folder's
``ROUTER`` file) is scored by running the program and ``score_outputs`` on its outputs
(``scripts/results.sh``'s ``score_sets``).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import csv
import json
import os
import platform
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np
from tqdm import tqdm

from . import metrics as MT
from . import realpairs as RP
from .cli_args import at_least, unit_interval
from .data import DatasetError, check_files, read_manifest
from .imageio import ImageError, read_mask, read_mask_strict, read_rgb, read_rgb_strict, to_uint8, write_rgb
from .read_only import first_read_only_problem, refuse_read_only
from .reference import ModelError, RaindropRemover

QUALITY = ("psnr_y", "ssim_y", "psnr_rgb", "ssim_rgb")


def _rows(dilation: int) -> list[tuple[str, str]]:
    rows = [("input", "Input (no removal)"), ("3rn", "3RN only"), ("full_k1", "3RN + RDN + RFN, no dilation (k=1)")]
    if dilation != 1:
        rows.append((f"full_k{dilation}", f"3RN + RDN + RFN, dilation k={dilation}"))
    return rows


def evaluate(
    data: Path,
    models: Path,
    out: Path,
    splits: list[str] | None = None,
    limit: int | None = None,
    threshold: float | None = None,
    dilation: int | None = None,
    threads: int | None = None,
    progress: bool = True,
) -> dict:
    samples = read_manifest(data, splits)
    if limit:
        samples = samples[:limit]
    check_files(samples, min_size=MT.SSIM_WINDOW, level="header", manifest=str(Path(data) / "manifest.jsonl"))
    remover = RaindropRemover(models, threads=threads)
    thr = remover.threshold if threshold is None else float(threshold)
    k = remover.dilation if dilation is None else int(dilation)
    rows = _rows(k)
    ks = [1] if k == 1 else [1, k]
    per_image: list[dict] = []
    sums = {name: {m: 0.0 for m in QUALITY + ("ms",)} for name, _ in rows}
    pr = MT.PRAccumulator()
    masks = {kk: MT.MaskCounts() for kk in ks}

    # Warm-up (first-run allocations) so that the timings are steady-state.
    first = read_rgb_strict(samples[0].rainy)
    remover.remove(first, thr, k)

    for s in tqdm(samples, desc="evaluate", disable=not progress, dynamic_ncols=True):
        rainy, clean = read_rgb_strict(s.rainy), read_rgb_strict(s.clean)
        gt = read_mask_strict(s.mask) > 127
        h, w = rainy.shape[:2]
        results: dict[str, tuple[np.ndarray, float]] = {"input": (rainy, 0.0)}
        R, E, tm = remover.prepare(rainy)
        t = time.perf_counter()
        P = remover.detect(R)
        t_rdn = time.perf_counter() - t
        pr.add(P[0, 0, :h, :w], gt)
        t = time.perf_counter()
        ihat = remover.reconstruct(R, E)
        t_rrn = time.perf_counter() - t
        t = time.perf_counter()
        out3 = to_uint8(remover.crop_hwc(ihat, h, w))
        t_out = time.perf_counter() - t
        results["3rn"] = (out3, tm["edge"] + t_rrn + t_out)
        for kk in ks:
            t = time.perf_counter()
            M = remover.binary_mask(P, thr, kk)
            B = remover.blend(M, ihat, R)
            restored = remover.refine(B)
            final = to_uint8(remover.crop_hwc(restored, h, w))
            t_k = time.perf_counter() - t
            masks[kk].add(M[:h, :w], gt)
            results[f"full_k{kk}"] = (final, tm["edge"] + t_rdn + t_rrn + t_k)
        for name, _ in rows:
            img, seconds = results[name]
            m = MT.image_metrics(img, clean)
            m["ms"] = seconds * 1000.0
            for key in sums[name]:
                sums[name][key] += m[key]
            per_image.append({"id": s.id, "row": name, **m})

    n = len(samples)
    ap = pr.average_precision()
    table = []
    for name, label in rows:
        row = {"row": name, "label": label, **{key: v / n for key, v in sums[name].items()}}
        row["ap"] = ap if name.startswith("full") else None
        if name.startswith("full"):
            row["mask"] = masks[int(name[len("full_k") :])].summary()
        table.append(row)
    thresholds, precision, recall = pr.curve()
    result = {
        "data": str(data),
        "models": str(models),
        "config": remover.config,
        "images": n,
        "splits": splits,
        "threshold": thr,
        "dilation": k,
        "rows": table,
        "ap": ap,
        "ap_bins": pr.bins,
        "psnr_cap_db": MT.PSNR_CAP_DB,
        "environment": {
            "onnxruntime_providers": remover.providers,
            "threads": threads or "onnxruntime default",
            "cpu_count": os.cpu_count(),
            "processor": platform.processor() or platform.machine(),
            "python": platform.python_version(),
        },
    }
    out.mkdir(parents=True, exist_ok=True)
    refuse_read_only(out / "results.json", out / "results.md", out / "per_image.csv", out / "pr_curve.png")
    (out / "results.json").write_text(json.dumps(result, indent=2, allow_nan=True) + "\n")
    (out / "results.md").write_text(markdown_table(result))
    with open(out / "per_image.csv", "w", newline="") as f:
        wr = csv.DictWriter(f, fieldnames=["id", "row", *QUALITY, "ms"])
        wr.writeheader()
        wr.writerows(per_image)
    plot_pr_curve(precision, recall, ap, out / "pr_curve.png", title=f"RDN ({remover.config}), {n} images")
    return result


def _fmt(v, digits: int) -> str:
    if v is None or (isinstance(v, float) and np.isnan(v)):
        return "-"
    return f"{v:.{digits}f}"


def markdown_table(result: dict) -> str:
    lines = [
        f"# Evaluation: {result['config']} on {result['images']} images",
        "",
        f"Data: `{result['data']}`; models: `{result['models']}`; threshold {result['threshold']}, "
        f"dilation k={result['dilation']}.",
        "",
        "| method | PSNR (Y) | SSIM (Y) | PSNR (RGB) | SSIM (RGB) | AP | ms/image |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for r in result["rows"]:
        lines.append(
            f"| {r['label']} | {_fmt(r['psnr_y'], 2)} | {_fmt(r['ssim_y'], 4)} | {_fmt(r['psnr_rgb'], 2)} | "
            f"{_fmt(r['ssim_rgb'], 4)} | {_fmt(r['ap'], 4)} | {_fmt(r['ms'], 1)} |"
        )
    env = result["environment"]
    lines += [
        "",
        "Y: literature convention (8-bit luma round(0.299 R + 0.587 G + 0.114 B), images cropped to multiples of 4); "
        "RGB: full image, SSIM averaged over channels; SSIM with a 7x7 uniform window; PSNR capped at "
        f"{result['psnr_cap_db']:.0f} dB. AP: pixel-level, RDN probability histogrammed into "
        f"{result['ap_bins']} bins. Times: ONNX Runtime {', '.join(env['onnxruntime_providers'])}, "
        f"threads {env['threads']}, {env['cpu_count']} CPUs ({env['processor']}), after one warm-up image.",
        "",
    ]
    masks = [r for r in result["rows"] if r.get("mask")]
    if masks:
        lines += ["| mask M | precision | recall | IoU | coverage |", "| --- | ---: | ---: | ---: | ---: |"]
        for r in masks:
            m = r["mask"]
            lines.append(
                f"| {r['label']} | {_fmt(m['precision'], 4)} | {_fmt(m['recall'], 4)} | {_fmt(m['iou'], 4)} | "
                f"{_fmt(m['coverage'], 4)} |"
            )
        lines.append("")
    return "\n".join(lines)


def plot_pr_curve(precision: np.ndarray, recall: np.ndarray, ap: float, path: Path, title: str = "") -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2))
    for ax, zoom in zip(axes, (False, True)):
        ax.plot(recall, precision, lw=1.5)
        ax.set_xlabel("recall")
        ax.set_ylabel("precision")
        ax.grid(True, alpha=0.3)
        if zoom:
            ax.set_xlim(0.8, 1.0)
            ax.set_ylim(0.8, 1.0)
            ax.set_title("magnified")
        else:
            ax.set_xlim(0.0, 1.0)
            ax.set_ylim(0.0, 1.02)
            ax.set_title(f"{title}\nAP = {ap:.4f}" if title else f"AP = {ap:.4f}")
    fig.tight_layout()
    refuse_read_only(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)


# --------------------------------------------------------------------------- real pairs

SHEET_LEGEND = "detected mask: white = detected and in the rough mask, cyan = detected only, red = rough mask only"


def _label(panel: np.ndarray, text: str) -> np.ndarray:
    import cv2

    bar = np.full((18, panel.shape[1], 3), 255, np.uint8)
    cv2.putText(bar, text, (3, 13), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
    return np.vstack([bar, panel])


def mask_panel(detected: np.ndarray, rough: np.ndarray) -> np.ndarray:
    """RGB picture of the detected mask against the rough mask (``SHEET_LEGEND``)."""
    d, r = detected.astype(bool), rough.astype(bool)
    out = np.zeros(d.shape + (3,), np.uint8)
    out[r & ~d] = (200, 0, 0)
    out[d & ~r] = (0, 220, 220)
    out[d & r] = (255, 255, 255)
    return out


def contact_sheet(rainy, detected, rough, output, clean, title: str = "") -> np.ndarray:
    """input | detected mask | output | clean, side by side with labels (HxW RGB uint8)."""
    panels = [
        _label(rainy, "input"),
        _label(mask_panel(detected, rough), "detected (vs rough)"),
        _label(output, "output"),
        _label(clean, "clean"),
    ]
    gap = np.full((panels[0].shape[0], 4, 3), 255, np.uint8)
    row = np.hstack([x for p in panels for x in (p, gap)][:-1])
    return _label(row, title) if title else row


class ProgramError(RuntimeError):
    """``--program`` failed on the pairs (its own one-line message)."""


def run_program(program: Path, pairs: list, models: Path | None, threshold: float | None, dilation: int | None,
                threads: int | None, work: Path) -> dict[str, tuple[Path, Path]]:
    """Runs ``raindrop-remove`` (``program``) as a user would, on the pairs' rainy images (linked
    into ``work/in`` as ``<id><ext>``), in one folder run. Returns id -> (output file, mask file)."""
    src = work / "in"
    src.mkdir(parents=True)
    names = {}
    for i, p in enumerate(pairs):
        # Neutral names: the program skips hidden files (an id starting with '.') in folders.
        name = f"pair{i:06d}{p.rainy.suffix}"
        os.symlink(p.rainy.resolve(), src / name)
        names[p.id] = name
    # Absolute: a bare name would be looked up on PATH, which may hold another raindrop-remove.
    cmd = [str(Path(program).absolute()), str(src), str(work / "out"), "--mask-dir", str(work / "masks"), "-q"]
    if models is not None:
        cmd += ["--models", str(models)]
    if threshold is not None:
        cmd += ["--threshold", repr(float(threshold))]
    if dilation is not None:
        cmd += ["--dilation", str(int(dilation))]
    if threads:
        cmd += ["-j", str(int(threads))]
    try:
        done = subprocess.run(cmd, capture_output=True, text=True)
    except OSError as e:
        raise ProgramError(f"--program {program}: cannot run it ({e.strerror or e})") from None
    if done.returncode != 0:
        said = (done.stderr.strip().splitlines() or [f"exit code {done.returncode}"])[-1]
        raise ProgramError(f"--program {program} failed on the pairs: {said}")
    made = {pid: (work / "out" / name, work / "masks" / (Path(name).stem + ".png")) for pid, name in names.items()}
    for pid, (output, mask) in made.items():
        if not (output.is_file() and mask.is_file()):
            raise ProgramError(f"--program {program} exited 0 but wrote no {'output' if not output.is_file() else 'mask'} "
                               f"for pair {pid}")
    return made


def evaluate_real_pairs(
    folder: Path,
    models: Path,
    out: Path,
    split: str = "test",
    holdout=None,
    mask_params: RP.MaskParams | None = None,
    limit: int | None = None,
    threshold: float | None = None,
    dilation: int | None = None,
    threads: int | None = None,
    sheets: bool = True,
    progress: bool = True,
    program: Path | None = None,
) -> dict:
    """Removal on real rainy/clean pairs (``realpairs``): PSNR/SSIM of the input and of the
    pipeline's output against the clean photograph, the gain, and detection against the rough
    masks (``realpairs.rough_mask``, which stand in for a ground truth real pairs lack).
    Writes results.json, results.md, per_image.csv and sheets/<id>.png to ``out``.

    ``program``: score what ``raindrop-remove`` (this path) makes of the pairs, as a user runs it
    (working scale, coarse pass, router, fills; ``models`` None: its default), instead of the
    reference pipeline's single pass. Its masks are binary: no AP, precision and recall only."""
    mask_params = mask_params or RP.MaskParams()
    pairs = RP.select(RP.assign_splits(RP.find_pairs(folder), holdout), split)
    if limit:
        pairs = pairs[:limit]
    if not pairs:
        raise RP.PairsError(f"{folder}: no pairs in split {split!r}")
    # Every sheet this run would write or remove, before the work (read_only.py; checked again
    # before the writes).
    refuse_read_only(*(Path(out) / "sheets" / f"{sid}.png"
                       for sid in sorted(_earlier_sheet_ids(Path(out)) | ({p.id for p in pairs} if sheets else set()))))
    # The program's scratch folder, read in the loop, goes however it ends (an error, a SIGTERM through main).
    with contextlib.ExitStack() as scratch:
        if program is not None:
            remover = None
            work = Path(scratch.enter_context(tempfile.TemporaryDirectory(prefix="raindrop-evaluate-")))
            made = run_program(Path(program), pairs, models, threshold, dilation, threads, work)
            thr = "the models' own" if threshold is None else float(threshold)
            k = "the models' own" if dilation is None else int(dilation)
        else:
            remover = RaindropRemover(models, threads=threads)
            thr = remover.threshold if threshold is None else float(threshold)
            k = remover.dilation if dilation is None else int(dilation)
        pr = MT.PRAccumulator()
        counts = MT.MaskCounts()
        per_image = []
        made_sheets = {}  # id -> PNG bytes, written once every pair has been scored
        for p in tqdm(pairs, desc="evaluate", disable=not progress, dynamic_ncols=True):
            rainy, clean, rough = RP.pair_mask(p, mask_params)
            gt = rough > 0
            if remover is not None:
                res = remover.remove(rainy, thr, k, keep_intermediates=True)
                pr.add(res.prob, gt)
                output, detected = res.output, res.mask
            else:
                output, detected = read_rgb(made[p.id][0]), read_mask(made[p.id][1]) > 0
                if output.shape != rainy.shape or detected.shape != gt.shape:
                    raise ProgramError(f"--program {program}: its output for {p.id} is not the pair's size")
            counts.add(detected, gt)
            m_in, m_out = MT.image_metrics(rainy, clean), MT.image_metrics(output, clean)
            rec = {"id": p.id, "group": p.group, "split": p.split, "rough_coverage": float(gt.mean()),
                   "detected_coverage": float(detected.mean())}
            for key in QUALITY:
                rec[f"input_{key}"] = m_in[key]
                rec[f"output_{key}"] = m_out[key]
                rec[f"gain_{key}"] = m_out[key] - m_in[key]
            per_image.append(rec)
            if sheets:
                title = (f"{p.id} ({p.split})  PSNR-Y {m_in['psnr_y']:.2f} -> {m_out['psnr_y']:.2f} dB, "
                         f"SSIM-Y {m_in['ssim_y']:.3f} -> {m_out['ssim_y']:.3f}")
                sheet = contact_sheet(rainy, detected, gt, output, clean, title)
                made_sheets[p.id] = cv2.imencode(".png", cv2.cvtColor(sheet, cv2.COLOR_RGB2BGR))[1].tobytes()
    mean = {key: float(np.mean([r[key] for r in per_image])) for key in per_image[0] if key.startswith(
        ("input_", "output_", "gain_", "rough_", "detected_"))}
    result = {
        "real_pairs": str(folder),
        "models": str(models) if models is not None else "the program's default ($RAINDROP_MODELS, else models/DEFAULT)",
        "config": remover.config if remover is not None else f"{Path(program).name}",
        "program": str(program) if program is not None else None,
        "split": split,
        "holdout": holdout if holdout is not None else RP.DEFAULT_HOLDOUT,
        "groups": sorted({p.group for p in pairs}),
        "images": len(pairs),
        "threshold": thr,
        "dilation": k,
        "mask_params": dataclasses.asdict(mask_params),
        "mean": mean,
        "ap_rough": pr.average_precision() if remover is not None else None,  # a program's masks are binary
        "mask_vs_rough": counts.summary(),
        "ap_bins": pr.bins,
        "psnr_cap_db": MT.PSNR_CAP_DB,
        "per_image": per_image,
    }
    # The folder then describes this run alone: a failed run wrote sheets without results, and a
    # smaller rerun (--limit, --no-sheets) left the earlier run's sheets beside its results. Only
    # the sheets an earlier run's results.json names are removed (they are this tool's).
    out.mkdir(parents=True, exist_ok=True)
    earlier = _earlier_sheet_ids(out)
    # Nothing removed or written while one of them is read-only (read_only.py).
    refuse_read_only(*(out / "sheets" / f"{sid}.png" for sid in sorted(earlier | set(made_sheets))),
                     out / "results.json", out / "results.md", out / "per_image.csv")
    for sid in earlier - set(made_sheets):
        (out / "sheets" / f"{sid}.png").unlink(missing_ok=True)
    if made_sheets:
        (out / "sheets").mkdir(exist_ok=True)
    for sid, png in made_sheets.items():
        (out / "sheets" / f"{sid}.png").write_bytes(png)
    result["sheets"] = sorted(made_sheets)
    refuse_read_only(out / "results.json", out / "results.md", out / "per_image.csv")
    (out / "results.json").write_text(json.dumps(result, indent=2, allow_nan=True) + "\n")
    (out / "results.md").write_text(real_pairs_markdown(result))
    with open(out / "per_image.csv", "w", newline="") as f:
        wr = csv.DictWriter(f, fieldnames=list(per_image[0]))
        wr.writeheader()
        wr.writerows(per_image)
    return result


def _earlier_sheet_ids(out: Path) -> set[str]:
    """The pair ids whose sheets an earlier real-pairs run recorded in ``out``'s results.json."""
    try:
        earlier = json.loads((out / "results.json").read_text())
    except (OSError, ValueError):
        return set()
    if not isinstance(earlier, dict) or "real_pairs" not in earlier:
        return set()
    ids = earlier.get("sheets")
    if ids is None:  # written before results.json listed its sheets: every pair had one
        ids = [r.get("id") for r in earlier.get("per_image", []) if isinstance(r, dict)]
    return {i for i in ids if isinstance(i, str) and "/" not in i and i not in ("", ".", "..")}


def real_pairs_markdown(result: dict) -> str:
    m = result["mean"]
    lines = [
        f"# Real pairs: {result['config']} on {result['images']} pairs (split {result['split']})",
        "",
        f"Pairs: `{result['real_pairs']}`, groups {', '.join(result['groups'])}; models: `{result['models']}`; "
        + (f"run by `{result['program']}` as a user runs it, threshold {result['threshold']}, dilation "
           f"{result['dilation']}." if result.get("program") else
           f"threshold {result['threshold']}, dilation k={result['dilation']}."),
        "",
        "| | PSNR (Y) | SSIM (Y) | PSNR (RGB) | SSIM (RGB) |",
        "| --- | ---: | ---: | ---: | ---: |",
    ]
    output_label = f"Output ({result['config']})" if result.get("program") else "Output (3RN + RDN + RFN)"
    for row, label in (("input", "Input (no removal)"), ("output", output_label), ("gain", "Gain")):
        sign = "+" if row == "gain" else ""
        cells = [f"{m[f'{row}_{key}']:{sign}.{2 if key.startswith('psnr') else 4}f}" for key in QUALITY]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    mk = result["mask_vs_rough"]
    mp = result["mask_params"]
    lines += [
        "",
        f"Detection against the rough masks: AP {_fmt(result['ap_rough'], 4) if result['ap_rough'] is not None else 'n/a (the program writes binary masks)'}; final mask precision "
        f"{_fmt(mk['precision'], 4)}, recall {_fmt(mk['recall'], 4)}, IoU {_fmt(mk['iou'], 4)}, coverage "
        f"{_fmt(mk['coverage'], 4)} (rough masks: {_fmt(m['rough_coverage'], 4)}).",
        "",
        "Means over pairs of per-pair values; gain = output - input per pair. Protocol of `metrics.py` (Y: 8-bit "
        "luma, cropped to multiples of 4; SSIM 7x7 uniform window; PSNR capped at "
        f"{result['psnr_cap_db']:.0f} dB). Rough masks (`realpairs.rough_mask`): |luma difference| after a "
        f"{mp['blur']}x{mp['blur']} box blur > {mp['threshold']:g} levels, opening {mp['open_size']}, closing "
        f"{mp['close_size']}, components >= {mp['min_area']} px; they include stereo parallax and miss drops that "
        "look like the scene, so AP against them is a rough indication. Contact sheets: `sheets/<id>.png`, "
        f"{SHEET_LEGEND}.",
        "",
        "| pair | input PSNR-Y | output PSNR-Y | gain | input SSIM-Y | output SSIM-Y |",
        "| --- | ---: | ---: | ---: | ---: | ---: |",
    ]
    for r in result["per_image"]:
        lines.append(
            f"| {r['id']} | {r['input_psnr_y']:.2f} | {r['output_psnr_y']:.2f} | {r['gain_psnr_y']:+.2f} | "
            f"{r['input_ssim_y']:.4f} | {r['output_ssim_y']:.4f} |"
        )
    lines.append("")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m raindrop_tools.evaluate",
        description="Evaluate ONNX models on a rendered test set, or on real rainy/clean pairs.",
    )
    src = ap.add_mutually_exclusive_group(required=True)
    src.add_argument("--data", help="rendered test set (CONTRACTS.md section 1)")
    src.add_argument(
        "--real-pairs", metavar="DIR", help="folder of real X_rain.* / X_clean.* pairs (raindrop_tools.realpairs)"
    )
    ap.add_argument("--models", help="folder with rdn.onnx, rrn.onnx, rfn.onnx (required, but with --program: "
                    "the program's default)")
    ap.add_argument("--program", metavar="RAINDROP_REMOVE",
                    help="--real-pairs: score what this raindrop-remove makes of the pairs as a user runs it "
                    "(working scale, coarse pass, router, fills), instead of the networks' single pass; e.g. "
                    "build/raindrop-remove")
    ap.add_argument("--out", required=True, help="output folder")
    ap.add_argument(
        "--split",
        action="append",
        help="--data: only samples with this manifest split (repeatable; default all). "
        "--real-pairs: train, test (default) or all, by the realpairs group split",
    )
    ap.add_argument("--holdout", help="--real-pairs: the test split's groups (realpairs --holdout; default 0.5)")
    ap.add_argument("--no-sheets", action="store_true", help="--real-pairs: no contact sheets")
    ap.add_argument("--limit", type=at_least(1), help="only the first N samples")
    ap.add_argument("--threshold", type=unit_interval, help="mask threshold in [0, 1] (default: the models')")
    ap.add_argument("--dilation", type=int, help="dilation size k of the last row (default: the models')")
    ap.add_argument("--threads", type=int, help="ONNX Runtime intra-op threads")
    ap.add_argument("--no-progress", action="store_true")
    RP.add_mask_arguments(ap)
    args = ap.parse_args(argv)
    if args.program and not args.real_pairs:
        ap.error("--program scores real pairs (--real-pairs); for a rendered set, run the program on DATA/rainy into "
                 "OUT, then: python -m raindrop_tools.score_outputs --data DATA --outputs OUT")
    if not args.models and not args.program:
        ap.error("--models is required (but with --program)")
    if args.program and not (Path(args.program).is_file() and os.access(args.program, os.X_OK)):
        ap.error(f"--program {args.program}: not an executable file")
    if args.dilation is not None and not 1 <= args.dilation <= 1023:
        ap.error(f"--dilation must be 1 to 1023, got {args.dilation}")
    if Path(args.out).exists() and not Path(args.out).is_dir():  # found before the work, not after it
        print(f"error: --out {args.out} is a file, not a folder", file=sys.stderr)
        return 2
    tables = ("results.json", "results.md", "per_image.csv") + (() if args.real_pairs else ("pr_curve.png",))
    problem = first_read_only_problem(*(Path(args.out) / table for table in tables))  # kept (read_only.py)
    if problem:
        print(f"error: {problem}", file=sys.stderr)
        return 2
    if args.real_pairs:
        if args.program:
            # A kill (SIGTERM) ends the run through SystemExit, so that the program's scratch
            # folder goes with it (and subprocess.run kills the program it waits for).
            signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
        if args.split and len(args.split) > 1:
            ap.error("--real-pairs takes one --split (train, test or all)")
        try:
            result = evaluate_real_pairs(
                Path(args.real_pairs),
                Path(args.models) if args.models else None,
                Path(args.out),
                split=args.split[0] if args.split else "test",
                holdout=RP.parse_holdout(args.holdout) if args.holdout else None,
                mask_params=RP.mask_params_from_args(args, ap),
                limit=args.limit,
                threshold=args.threshold,
                dilation=args.dilation,
                threads=args.threads,
                sheets=not args.no_sheets,
                progress=not args.no_progress,
                program=Path(args.program) if args.program else None,
            )
        except (RP.PairsError, ModelError, ImageError, ValueError, OSError, ProgramError) as e:
            print(f"error: {e}", file=sys.stderr)
            return 2
        print(real_pairs_markdown(result).split("\n\n| pair |")[0])
        return 0
    try:
        result = evaluate(
            Path(args.data),
            Path(args.models),
            Path(args.out),
            splits=args.split,
            limit=args.limit,
            threshold=args.threshold,
            dilation=args.dilation,
            threads=args.threads,
            progress=not args.no_progress,
        )
    except (DatasetError, ModelError, ImageError, ValueError, OSError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(markdown_table(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
