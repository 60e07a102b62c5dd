"""The trained models committed under models/: files match their export.json digests, the
model card lists every digest, DEFAULT names a folder that exists, and each graph carries the
contract's metadata (no torch needed)."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import onnx
import pytest

from raindrop_tools.contract import (ALTERNATIVE_OUTPUT, FILES, META_ALTERNATIVE_DETECTOR, META_CONFIG, META_DILATION,
                                     META_THRESHOLD, NETWORKS)

MODELS = Path(__file__).resolve().parents[2] / "models"
FOLDERS = sorted(p for p in MODELS.iterdir() if p.is_dir() and (p / "export.json").is_file()) if MODELS.is_dir() else []


def test_default_names_a_committed_model():
    if not FOLDERS:
        pytest.skip(f"no trained models in {MODELS}")
    lines = [line.split() for line in (MODELS / "DEFAULT").read_text().splitlines()]
    default = " ".join(lines[0])
    names = {p.name for p in FOLDERS}
    assert default in names, f"models/DEFAULT says {default!r}"
    # Later lines: "vnni NAME", the default's int8 copy for CPUs with VNNI (raindrop-remove reads it).
    copies = [w for w in lines[1:] if w and not w[0].startswith("#")]
    assert all(len(w) == 2 and w[0] == "vnni" for w in copies), copies
    for _, name in copies:
        assert name in names and name == default + "-int8", name


def test_large_drop_models_are_other_committed_models():
    """Every LARGE_DROPS file (raindrop-remove's models for the coarse pass's large drops) names a
    sibling that is committed too, so that a clone and an install (which copies LARGE_DROPS) run
    what was measured."""
    if not FOLDERS:
        pytest.skip(f"no trained models in {MODELS}")
    names = {p.name for p in FOLDERS}
    for folder in FOLDERS:
        file = folder / "LARGE_DROPS"
        if file.exists():
            name = file.read_text().strip()
            assert name in names and name != folder.name, f"{file} names {name!r}"


def test_routers_name_committed_detectors_and_a_head_its_own_graphs_map():
    """Every ROUTER's alternative is a committed folder; where the folder's detector computes a
    head's map (a second output), its metadata names the same folder as the ROUTER, or
    raindrop-remove would run the alternative's own network beside it (correct, but the cost the
    head exists to save). An int8 folder's head is an int8 folder."""
    if not FOLDERS:
        pytest.skip(f"no trained models in {MODELS}")
    names = {p.name for p in FOLDERS}
    routers = [f for f in FOLDERS if (f / "ROUTER").exists()]
    assert routers, "the default has a ROUTER"
    for folder in routers:
        words = [line.split() for line in (folder / "ROUTER").read_text().splitlines()]
        (alternative,) = [w[1] for w in words if w and w[0] == "alternative"]
        assert alternative in names, f"{folder / 'ROUTER'} names {alternative!r}"
        rdn = onnx.load(str(folder / FILES["rdn"]), load_external_data=False)
        meta = {p.key: p.value for p in rdn.metadata_props}
        if any(o.name == ALTERNATIVE_OUTPUT for o in rdn.graph.output):
            assert meta.get(META_ALTERNATIVE_DETECTOR) == alternative, folder
            assert folder.name.endswith("-int8") == alternative.endswith("-int8"), folder


@pytest.mark.parametrize("folder", FOLDERS, ids=[p.name for p in FOLDERS])
def test_files_match_their_digests_and_the_model_card(folder: Path):
    info = json.loads((folder / "export.json").read_text())
    card = (MODELS / "README.md").read_text()
    assert set(info["files"]) == {FILES[n] for n in NETWORKS}
    for name in NETWORKS:
        path = folder / FILES[name]
        entry = info["files"][FILES[name]]
        digest = hashlib.sha256(path.read_bytes()).hexdigest()
        assert digest == entry["sha256"], f"{path} changed since export.json was written"
        assert path.stat().st_size == entry["bytes"]
        assert digest in card, f"models/README.md does not list {path.relative_to(MODELS.parent)} ({digest})"
        meta = {p.key: p.value for p in onnx.load(str(path), load_external_data=False).metadata_props}
        assert meta[META_CONFIG] == info["config"] == folder.name
        assert float(meta[META_THRESHOLD]) == info["pipeline"]["threshold"]
        assert int(meta[META_DILATION]) == info["pipeline"]["dilation"]
