"""Optional metadata of a model folder's detector, written in place: rdn.onnx's raindrop.* entry and
export.json's pipeline key, for the tools that set such values after training
(``large_drop_growth``, ``surround_fill_area``, and the threshold and dilation, which every graph
carries).

Nothing else in the graph changes: the file is rewritten from its own parsed bytes, which ONNX
serialises back byte for byte, and removing the entry gives the file back as it was. Every input
is read and checked before the first file is replaced, and each file is written beside itself and
renamed over it: a refused run changes nothing, and an interrupted one leaves each file whole.
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import onnx

from . import contract as C
from .read_only import refuse_read_only


class MetadataError(ValueError):
    """A request refused, reported on one line."""


def _replace(path: Path, data: bytes) -> None:
    refuse_read_only(path, follow_links=False)
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)


def set_detector_metadata(folder: Path, key: str, pipeline_key: str, value: float | int | None,
                          every_graph: bool = False) -> dict:
    """Record `value` as rdn.onnx's metadata `key` and export.json's pipeline.`pipeline_key` in
    `folder` (None: removes both, giving the graph back as it was); returns export.json's new
    content (or {} without one). `every_graph`: a key export writes into all three graphs (the
    threshold) is also rewritten in place in the 3RN and RFN that carry it. Refusals raise
    MetadataError and change nothing."""
    if every_graph and value is None:
        raise MetadataError(f"{key} is in every graph: it can be changed, not removed")
    folder = Path(folder)
    rdn = folder / C.FILES["rdn"]
    if not rdn.is_file():
        raise MetadataError(f"{rdn}: no such file")
    model = onnx.load_from_string(rdn.read_bytes())
    if C.META_NETWORK not in [p.key for p in model.metadata_props]:
        raise MetadataError(f"{rdn}: not a raindrop graph (no {C.META_NETWORK} metadata)")
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
            raise MetadataError(f"{info_path}: not JSON ({e})") from None
        if not isinstance(info, dict):
            raise MetadataError(f"{info_path}: not a JSON object")
        for name in ("rrn", "rfn"):
            if not (folder / C.FILES[name]).is_file():
                raise MetadataError(f"{folder / C.FILES[name]}: no such file (export.json lists every graph)")
    others = {}
    for name in ("rrn", "rfn") if every_graph else ():
        path = folder / C.FILES[name]
        if path.is_file():  # a detector-only folder has none
            other = onnx.load_from_string(path.read_bytes())
            for p in other.metadata_props:
                if p.key == key:
                    p.value = repr(value)
            others[path] = other.SerializeToString()
    # every file kept, not some replaced and another refused
    refuse_read_only(rdn, info_path, *others, follow_links=False)
    for path, other_data in others.items():
        _replace(path, other_data)
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


def set_threshold(folder: Path, threshold: float) -> dict:
    """Record `threshold` as the folder's detector threshold (``raindrop.threshold``, which export
    writes into every graph, and export.json's ``pipeline.threshold``). Refusals change nothing."""
    if isinstance(threshold, bool) or not isinstance(threshold, float) or not 0 < threshold < 1:
        raise MetadataError(f"the threshold must be a float strictly between 0 and 1, got {threshold!r}")
    return set_detector_metadata(folder, C.META_THRESHOLD, "threshold", threshold, every_graph=True)


def set_dilation(folder: Path, dilation: int) -> dict:
    """Record `dilation` (k: the mask's elliptical k x k dilation, odd, 1 to C.MAX_DILATION as
    raindrop-remove's --dilation) as the folder's (``raindrop.dilation``, which export writes into
    every graph, and export.json's ``pipeline.dilation``). Refusals change nothing."""
    if (isinstance(dilation, bool) or not isinstance(dilation, int) or not 1 <= dilation <= C.MAX_DILATION
            or dilation % 2 == 0):
        raise MetadataError(f"the dilation must be an odd whole number from 1 to {C.MAX_DILATION}, got {dilation!r}")
    return set_detector_metadata(folder, C.META_DILATION, "dilation", dilation, every_graph=True)


def run_tool(folder: Path, change, what: str) -> int:
    """Runs `change` (a set_* call on `folder`) for a command line: one line on stdout naming
    `what` and rdn.onnx's new digest, or one error line on stderr and exit code 2."""
    try:
        info = change()
    except (MetadataError, OSError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except Exception as e:  # noqa: BLE001 - a file that is not ONNX: onnx's own error, on one line
        print(f"error: {folder / C.FILES['rdn']}: {e}".splitlines()[0], file=sys.stderr)
        return 2
    digest = info.get("files", {}).get(C.FILES["rdn"], {}).get("sha256", "")
    print(f"{folder}: {what}" + (f", rdn.onnx sha256 {digest}" if digest else ""))
    return 0
