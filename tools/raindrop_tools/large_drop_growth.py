"""Set how large drops' masks grow in raindrop-remove's coarse pass, without retraining.

    python -m raindrop_tools.large_drop_growth models/compact-multiscale 0.35

The growth is chosen after training, on validation sets, as ``export --threshold`` is. With growth
G > 0, the coarse pass for large drops (include/raindrop/remove/large_drops.h) dilates each drop
of its mask by the odd size nearest G x the drop's equivalent diameter, and never by less than
the folder's k. Large drops, which on a lens cover are defocused, spread past the outline the
detector finds, and the wider mask takes that spread in. Small drops, and the pass at the working
scale, keep k. docs/RESULTS.md 4.21 measured it.

It is recorded in rdn.onnx's optional metadata ``raindrop.large_drop_growth``, and nothing else
in the graph changes. The file is rewritten from its own parsed bytes, which ONNX serialises
back byte for byte. Growth 0 removes the entry and gives back the file as it was. Where the
folder has an export.json, it gets the new digests and ``pipeline.large_drop_growth``. Every
input is read and checked before the first file is replaced, and each file is written beside
itself and renamed over it: a refused run changes nothing, and an interrupted one leaves each
file whole.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from . import contract as C
from .detector_metadata import MetadataError, run_tool, set_detector_metadata

# Its refusals are the shared writer's (the name this module's callers know).
GrowthError = MetadataError


def set_large_drop_growth(folder: Path, growth: float) -> dict:
    """Record `growth` in folder/rdn.onnx (and export.json); returns export.json's new content
    (or {} without one)."""
    if not 0.0 <= growth <= C.MAX_LARGE_DROP_GROWTH:
        raise GrowthError(f"large-drop growth must be between 0 and {C.MAX_LARGE_DROP_GROWTH:g}, got {growth:g}")
    return set_detector_metadata(folder, C.META_LARGE_DROP_GROWTH, "large_drop_growth",
                                 float(growth) if growth > 0 else None)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m raindrop_tools.large_drop_growth",
        description="Record in a model folder's rdn.onnx (and export.json) how much raindrop-remove's coarse pass "
        "grows each large drop's mask: the odd size nearest GROWTH x the drop's diameter, at least k.",
    )
    ap.add_argument("models", type=Path, help="model folder (rdn.onnx, and export.json where there is one)")
    ap.add_argument("growth", type=float, help=f"0 (k for every drop) to {C.MAX_LARGE_DROP_GROWTH:g}")
    args = ap.parse_args(argv)
    return run_tool(args.models, lambda: set_large_drop_growth(args.models, args.growth),
                    f"large-drop growth {args.growth:g}")


if __name__ == "__main__":
    sys.exit(main())
