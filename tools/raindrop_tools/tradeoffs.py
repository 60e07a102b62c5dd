"""What accuracy costs in time, for raindrop-remove: one table and a Pareto plot.

Accuracy depends on the models only (paper or compact, fp32 or int8): it comes from
`python -m raindrop_tools.evaluate` on the held-out synthetic set (results.json per model
folder). Time depends also on threads, ONNX Runtime's graph optimisation level and tiling:
it comes from `raindrop-bench remove` (C++, the program users run), one invocation per row.

    python -m raindrop_tools.tradeoffs --bench build/raindrop-bench --eval-root out/eval --out out/tradeoffs

Imports without torch.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

from .read_only import first_read_only_problem, refuse_read_only

# What a run writes into --out (each refused when read-only, read_only.py).
OUTPUTS = ("tradeoffs.json", "tradeoffs.md", "pareto.png")


@dataclass
class Variant:
    label: str
    models: str          # model folder, e.g. models/compact
    threads: int = 2
    graph_opt: str = "all"
    tile: int = 1024
    size: str = "512x256"  # WxH, as raindrop-bench takes it
    knob: str = ""        # what this row changes


DEFAULT_VARIANTS = [
    Variant("paper, fp32", "models/paper", knob="models"),
    Variant("paper, int8", "models/paper-int8", knob="precision"),
    Variant("compact, fp32", "models/compact", knob="models"),
    Variant("compact, int8", "models/compact-int8", knob="precision"),
    Variant("paper, fp32, 1 thread", "models/paper", threads=1, knob="threads"),
    Variant("compact, fp32, 1 thread", "models/compact", threads=1, knob="threads"),
    Variant("compact, int8, 1 thread", "models/compact-int8", threads=1, knob="threads"),
    Variant("compact, fp32, graph opt disable", "models/compact", graph_opt="disable", knob="graph optimisation"),
    Variant("compact, fp32, graph opt basic", "models/compact", graph_opt="basic", knob="graph optimisation"),
    Variant("compact, fp32, graph opt extended", "models/compact", graph_opt="extended", knob="graph optimisation"),
    Variant("compact, fp32, 2048x1024, whole image", "models/compact", tile=0, size="2048x1024", knob="tiles"),
    Variant("compact, fp32, 2048x1024, tiles 1024", "models/compact", tile=1024, size="2048x1024", knob="tiles"),
    Variant("compact, fp32, 2048x1024, tiles 512", "models/compact", tile=512, size="2048x1024", knob="tiles"),
]

def time_rows(markdown: str) -> list[dict]:
    """The rows of raindrop-bench remove's "time per image" table, each as {column title: cell},
    found by the table's header (the first column "models", the second "size (WxH)"), so that
    columns added to the bench do not shift what is read."""
    rows: list[dict] = []
    header: list[str] | None = None
    for line in markdown.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if not line.startswith("|"):
            header = None
        elif cells[:2] == ["models", "size (WxH)"] and "median total" in cells:
            header = cells
        elif header and not set("".join(cells)) <= set("-: ") and len(cells) == len(header):
            rows.append(dict(zip(header, cells)))
    return rows


def bench_ms(bench: str, v: Variant, runs: int) -> dict:
    """Median wall time (ms) of raindrop-remove's pipeline for one variant, at the variant's
    size itself (--scale 1: the table compares the networks' cost, not the working scale's)."""
    cmd = [bench, "remove", "--models", v.models, "--threads", str(v.threads), "--graph-opt", v.graph_opt,
           "--tile", str(v.tile), "--size", v.size, "--scale", "1", "--process-size", "", "--runs", str(runs)]
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    for row in time_rows(out):
        if row["size (WxH)"] == v.size and int(row["threads"]) == v.threads:
            return {"ms": float(row["median total"]), "tiles": int(row["tiles"]), "command": " ".join(cmd)}
    raise RuntimeError(f"no timing row in the output of {' '.join(cmd)}")


def accuracy(eval_root: Path, models: str) -> dict | None:
    """The full pipeline's row (with its dilation) and AP from evaluate's results.json."""
    path = eval_root / Path(models).name / "results.json"
    if not path.is_file():
        return None
    res = json.loads(path.read_text())
    full = next(r for r in res["rows"] if r["row"] == f"full_k{res['dilation']}")
    return {"psnr_y": full["psnr_y"], "ssim_y": full["ssim_y"], "psnr_rgb": full["psnr_rgb"],
            "ssim_rgb": full["ssim_rgb"], "ap": res["ap"], "images": res["images"]}


def pareto(points: list[tuple[float, float]]) -> list[int]:
    """Indices of points not dominated (lower time, higher accuracy)."""
    keep = []
    for i, (t, a) in enumerate(points):
        if not any((t2 <= t and a2 >= a) and (t2 < t or a2 > a) for j, (t2, a2) in enumerate(points) if j != i):
            keep.append(i)
    return keep


def label_offsets(points: list[tuple[float, float]], dy: float = 9.0) -> list[tuple[float, float]]:
    """Text offsets (points) that stack upwards the labels of points at about the same accuracy
    (within 0.005 dB: same models, other settings), which would otherwise overlap."""
    offsets = []
    for i, (t, a) in enumerate(points):
        k = sum(1 for _, a2 in points[:i] if abs(a2 - a) <= 0.005)
        offsets.append((5.0, 4.0 + dy * k))
    return offsets


def plot_pareto(rows: list[dict], path: Path) -> None:
    """Pareto plot over the 512x256 rows that have an accuracy."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    pts = [(r["ms"], r["accuracy"]["psnr_y"], r["variant"]["label"]) for r in rows
           if r["accuracy"] and r["variant"]["size"] == "512x256"]
    if not pts:
        return
    front = sorted((pts[i] for i in pareto([(t, a) for t, a, _ in pts])), key=lambda p: p[0])
    fig, ax = plt.subplots(figsize=(9, 5.5))
    ax.scatter([p[0] for p in pts], [p[1] for p in pts], color="tab:blue", zorder=3)
    ax.plot([p[0] for p in front], [p[1] for p in front], color="tab:red", lw=1.5, label="Pareto front", zorder=2)
    for (t, a, label), off in zip(pts, label_offsets([(t, a) for t, a, _ in pts])):
        ax.annotate(f"{label} ({t:.0f} ms)", (t, a), textcoords="offset points", xytext=off, fontsize=7)
    ax.set_xscale("log")
    ax.set_xlabel("ms per 512x256 image (raindrop-remove, median; log scale)")
    ax.set_ylabel("PSNR (Y, dB) on the held-out synthetic set")
    ax.set_title("raindrop-remove: accuracy against time")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="lower right")
    fig.tight_layout()
    refuse_read_only(path)
    fig.savefig(path, dpi=130)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m raindrop_tools.tradeoffs", description=__doc__.split("\n\n")[0])
    ap.add_argument("--bench", default="build/raindrop-bench")
    ap.add_argument("--eval-root", default="out/eval", help="folder with <model folder name>/results.json")
    ap.add_argument("--out", default="out/tradeoffs")
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--plot-only", action="store_true", help="redraw pareto.png from --out's tradeoffs.json")
    args = ap.parse_args(argv)
    out = Path(args.out)
    if args.runs < 1:
        print(f"tradeoffs: error: --runs must be at least 1, got {args.runs}", file=sys.stderr)
        return 2
    problem = first_read_only_problem(*(out / name for name in OUTPUTS))  # before minutes of timing
    if problem:
        print(f"tradeoffs: error: {problem}", file=sys.stderr)
        return 2
    if args.plot_only:
        if not (out / "tradeoffs.json").is_file():
            print(f"tradeoffs: error: no {out / 'tradeoffs.json'} to plot (run without --plot-only first)", file=sys.stderr)
            return 2
        try:
            plot_pareto(json.loads((out / "tradeoffs.json").read_text()), out / "pareto.png")
        except (ValueError, TypeError, KeyError) as e:  # not this tool's table
            print(f"tradeoffs: error: {out / 'tradeoffs.json'} is not a table this tool wrote ({e})", file=sys.stderr)
            return 2
        return 0
    rows = []
    for v in DEFAULT_VARIANTS:
        if not Path(v.models).is_dir():
            print(f"tradeoffs: skipping {v.label}: no {v.models}", file=sys.stderr)
            continue
        if not (Path(args.bench).is_file() and os.access(args.bench, os.X_OK)):
            print(f"tradeoffs: error: --bench {args.bench}: no such program (build it: cmake --build build)", file=sys.stderr)
            return 2
        print(f"tradeoffs: {v.label}", file=sys.stderr)
        try:
            t = bench_ms(args.bench, v, args.runs)
            acc = accuracy(Path(args.eval_root), v.models)
        except subprocess.CalledProcessError as e:
            last = (e.stderr or "").strip().splitlines()[-1:] or [f"exit {e.returncode}"]
            print(f"tradeoffs: error: {' '.join(e.cmd)} failed: {last[0]}", file=sys.stderr)
            return 2
        except (RuntimeError, ValueError, KeyError, TypeError) as e:
            print(f"tradeoffs: error: {v.label}: {e!r}", file=sys.stderr)
            return 2
        rows.append({"variant": v.__dict__, **t, "accuracy": acc})
    # Nothing measured (e.g. run outside the repository, where the model folders are not):
    # an error, not empty tables written over the last run's.
    if not rows:
        print("tradeoffs: error: none of the model folders exist here (run from the repository root)", file=sys.stderr)
        return 2
    # Again before the first write (the timing took minutes): all three, or none is written.
    problem = first_read_only_problem(*(out / name for name in OUTPUTS))
    if problem:
        print(f"tradeoffs: error: {problem}", file=sys.stderr)
        return 2
    out.mkdir(parents=True, exist_ok=True)
    (out / "tradeoffs.json").write_text(json.dumps(rows, indent=2) + "\n")

    lines = ["| variant | knob | size | ms (median) | PSNR Y dB | SSIM Y | PSNR RGB dB | SSIM RGB | AP |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        a, v = r["accuracy"], r["variant"]
        acc = (f'{a["psnr_y"]:.2f} | {a["ssim_y"]:.4f} | {a["psnr_rgb"]:.2f} | {a["ssim_rgb"]:.4f} | {a["ap"]:.4f}'
               if a else "n/a | n/a | n/a | n/a | n/a")
        lines.append(f'| {v["label"]} | {v["knob"]} | {v["size"]} | {r["ms"]:.1f} | {acc} |')
    (out / "tradeoffs.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))

    plot_pareto(rows, out / "pareto.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
