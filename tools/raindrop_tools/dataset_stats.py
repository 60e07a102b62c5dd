"""Summary of a rendered data set from its manifest: how many drops, how much of the frame
they cover, how large they look, how much of them is dark band or shows the world beyond the
frame. Used to compare the scene presets with the paper and with real raindrop photographs.

    python -m raindrop_tools.dataset_stats data/train [data/test ...]

The apparent drop diameter is the footprint's width on the image, 2 a fx / z, with z the
depth of the footprint centre on the glass (z = N + v cos(psi)), scaled to a 2048-pixel-wide
frame so data sets of different sizes compare. Imports without torch.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from .manifest import manifest_records


def summarize(data_dir: Path) -> dict:
    if not data_dir.is_dir():
        raise ValueError(f"{data_dir}: no such folder")
    records = manifest_records(data_dir)  # a ManifestError is a ValueError
    if not records:
        raise ValueError(f"{data_dir}: empty manifest")
    drops, coverage, dark, off, diameters = [], [], [], [], []
    for r in records:
        scene, cam = r["scene"], r["camera"]
        psi = math.radians(scene["tilt_deg"])
        if not (isinstance(r["width"], (int, float)) and r["width"] > 0):
            raise ValueError(f"{data_dir}: sample {r.get('id', '?')}: width {r['width']!r} is not a positive number")
        to_2048 = 2048.0 / r["width"]
        # The caps of trails (the scene effect "trails") are not drops: they name theirs.
        own = [d for d in r["drops"] if "trail_of" not in d]
        drops.append(len(own))
        coverage.append(r["coverage"])
        dark.append(r.get("dark_band_fraction", float("nan")))
        off.append(r.get("off_frame_fraction", float("nan")))
        for d in own:
            z = scene["glass_distance_cm"] + d["center_cm"][1] * math.cos(psi)
            if z > 0:
                diameters.append(2 * d["footprint_radius_cm"] * cam["fx"] / z * to_2048)

    def stats(values) -> dict:
        a = np.asarray(values, dtype=float)
        if np.all(np.isnan(a)):  # none recorded (e.g. a set of trails only): null in JSON, '-' in the table
            return {"mean": None, "p5": None, "p95": None}
        return {"mean": float(np.nanmean(a)), "p5": float(np.nanpercentile(a, 5)), "p95": float(np.nanpercentile(a, 95))}

    return {
        "data": str(data_dir),
        "samples": len(records),
        "size": sorted({f'{r["width"]}x{r["height"]}' for r in records}),
        "presets": sorted({r["scene"].get("preset", "?") for r in records}),
        "drops_per_frame": stats(drops),
        "coverage": stats(coverage),
        "drop_diameter_px_at_2048": stats(diameters),
        "dark_band_fraction": stats(dark),
        "off_frame_fraction": stats(off),
    }


def markdown(rows: list[dict]) -> str:
    out = [
        "| data set | preset | samples | size | drops/frame | coverage % (p5-p95) | drop diameter px @2048 (p5-p95) | dark band % | off-frame % |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    def f(v, digits: int, scale: float = 1.0) -> str:  # None: nothing recorded
        return "-" if v is None else f"{scale * v:.{digits}f}"

    for s in rows:
        c, d = s["coverage"], s["drop_diameter_px_at_2048"]
        out.append(
            f'| {s["data"]} | {", ".join(s["presets"])} | {s["samples"]} | {", ".join(s["size"])} | '
            f'{f(s["drops_per_frame"]["mean"], 1)} | {f(c["mean"], 1, 100)} ({f(c["p5"], 1, 100)}-{f(c["p95"], 1, 100)}) | '
            f'{f(d["mean"], 0)} ({f(d["p5"], 0)}-{f(d["p95"], 0)}) | {f(s["dark_band_fraction"]["mean"], 1, 100)} | '
            f'{f(s["off_frame_fraction"]["mean"], 1, 100)} |'
        )
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m raindrop_tools.dataset_stats", description=__doc__.split("\n\n")[0])
    ap.add_argument("data", nargs="+", help="rendered data set folders")
    ap.add_argument("--json", action="store_true", help="print JSON instead of a markdown table")
    args = ap.parse_args(argv)
    try:
        rows = [summarize(Path(d)) for d in args.data]
    except (ValueError, KeyError, TypeError, OSError) as e:  # no or an unreadable manifest, records without a scene, a line that is no record
        what = f"a record has no {e}" if isinstance(e, KeyError) else str(e)
        print(f"dataset_stats: error: {what} (rendered data sets only)", file=sys.stderr)
        return 2
    print(json.dumps(rows, indent=2, allow_nan=False) if args.json else markdown(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
