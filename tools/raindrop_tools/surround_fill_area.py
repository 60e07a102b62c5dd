"""Set how large a part of the mask a detector's images fill from their surroundings.

    python -m raindrop_tools.surround_fill_area models/compact-windshield 1500

raindrop-remove fills the parts of the mask of at most this many pixels (with the image's long
side at 512) whose surroundings are smooth by push-pull interpolation instead of the 3RN
(include/raindrop/remove/surround_fill.h). The area belongs to the detector that decides the
mask: a router that gives an image another folder's detector gives it that folder's area too
(docs/RESULTS.md 4.44). It is recorded in rdn.onnx's optional metadata
``raindrop.surround_fill_area`` (absent: 150) and export.json's ``pipeline.surround_fill_area``,
by ``detector_metadata``, as ``large_drop_growth`` records its value (nothing changes on a
refusal, each file is replaced whole). ``default`` removes the entry and gives the file back as it was.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from . import contract as C
from .detector_metadata import MetadataError, run_tool, set_detector_metadata


def set_surround_fill_area(folder: Path, area: int | None) -> dict:
    """Record `area` (None: the default, the entry removed) in folder/rdn.onnx and export.json."""
    # A plain int in raindrop-remove's range (a C int, read with std::stoi): checked before any
    # file is touched, and written by repr as the digits alone (not a numpy or bool repr).
    if area is not None and (not isinstance(area, int) or isinstance(area, bool) or not 0 <= area <= C.MAX_SURROUND_FILL_AREA):
        raise MetadataError(f"the surround-fill area must be a whole number from 0 (off) to {C.MAX_SURROUND_FILL_AREA}, got {area!r}")
    return set_detector_metadata(folder, C.META_SURROUND_FILL_AREA, "surround_fill_area", area)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m raindrop_tools.surround_fill_area",
        description="Record in a model folder's rdn.onnx (and export.json) the largest part of the mask, in pixels "
        "with the long side at 512, that raindrop-remove fills from smooth surroundings where this detector decides.",
    )
    ap.add_argument("models", type=Path, help="model folder (rdn.onnx, and export.json where there is one)")
    ap.add_argument("area", help=f"a whole number >= 0 (0: the 3RN everywhere), or 'default' ({C.DEFAULT_SURROUND_FILL_AREA})")
    args = ap.parse_args(argv)
    try:
        area = None if args.area == "default" else int(args.area)
    except ValueError:
        print(f"error: the area must be a whole number >= 0 or 'default', got {args.area!r}", file=sys.stderr)
        return 2
    shown = C.DEFAULT_SURROUND_FILL_AREA if area is None else area
    return run_tool(args.models, lambda: set_surround_fill_area(args.models, area), f"surround-fill area {shown}")


if __name__ == "__main__":
    sys.exit(main())
