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
import json
import os
import sys
from pathlib import Path

import onnx

from . import contract as C
from .read_only import refuse_read_only


class GrowthError(ValueError):
    """A request refused, reported on one line."""


def _replace(path: Path, data: bytes) -> None:
    refuse_read_only(path, follow_links=False)
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)


def set_large_drop_growth(folder: Path, growth: float) -> dict:
    """Record `growth` in folder/rdn.onnx (and export.json); returns export.json's new content
    (or {} without one)."""
    if not 0.0 <= growth <= C.MAX_LARGE_DROP_GROWTH:
        raise GrowthError(f"large-drop growth must be between 0 and {C.MAX_LARGE_DROP_GROWTH:g}, got {growth:g}")
    return set_detector_metadata(folder, C.META_LARGE_DROP_GROWTH, "large_drop_growth",
                                 float(growth) if growth > 0 else None)


def set_detector_metadata(folder: Path, key: str, pipeline_key: str, value: float | int | None) -> dict:
    """Record `value` as rdn.onnx's metadata `key` and export.json's pipeline.`pipeline_key` in
    `folder` (None: removes both, giving the graph back as it was); returns export.json's new
    content (or {} without one). Refusals raise GrowthError and change nothing."""
    folder = Path(folder)
    rdn = folder / C.FILES["rdn"]
    if not rdn.is_file():
        raise GrowthError(f"{rdn}: no such file")
    model = onnx.load_from_string(rdn.read_bytes())
    if C.META_NETWORK not in [p.key for p in model.metadata_props]:
        raise GrowthError(f"{rdn}: not a raindrop graph (no {C.META_NETWORK} metadata)")
    props = {p.key: p.value for p in model.metadata_props if p.key != key}
    if value is not None:
        props[key] = repr(value)
    del model.metadata_props[:]
    onnx.helper.set_model_props(model, props)  # in order, as export writes them
    data = model.SerializeToString()
    # Everything is read and checked before the first file is replaced: a bad export.json or a
    # missing graph leaves the folder as it was.
    info_path = folder / C.EXPORT_INFO
    info: dict = {}
    if info_path.is_file():
        try:
            info = json.loads(info_path.read_text())
        except ValueError as e:
            raise GrowthError(f"{info_path}: not JSON ({e})") from None
        if not isinstance(info, dict):
            raise GrowthError(f"{info_path}: not a JSON object")
        for name in ("rrn", "rfn"):
            if not (folder / C.FILES[name]).is_file():
                raise GrowthError(f"{folder / C.FILES[name]}: no such file (export.json lists every graph)")
    refuse_read_only(rdn, info_path, follow_links=False)  # both kept, not the graph replaced and export.json refused
    _replace(rdn, data)
    if not info_path.is_file():
        return {}
    pipeline = info.setdefault("pipeline", {})
    if value is not None:
        pipeline[pipeline_key] = value
    else:
        pipeline.pop(pipeline_key, None)
    info["files"] = C.graph_files(folder)
    _replace(info_path, (json.dumps(info, indent=2) + "\n").encode())
    return info


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


def run_tool(folder: Path, change, what: str) -> int:
    """Runs `change` (a set_* call on `folder`) for a command line: one line on stdout naming
    `what` and rdn.onnx's new digest, or one error line on stderr and exit code 2."""
    try:
        info = change()
    except (GrowthError, OSError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except Exception as e:  # noqa: BLE001 - a file that is not ONNX: onnx's own error, on one line
        print(f"error: {folder / C.FILES['rdn']}: {e}".splitlines()[0], file=sys.stderr)
        return 2
    digest = info.get("files", {}).get(C.FILES["rdn"], {}).get("sha256", "")
    print(f"{folder}: {what}" + (f", rdn.onnx sha256 {digest}" if digest else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
