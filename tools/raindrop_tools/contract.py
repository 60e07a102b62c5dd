"""Names fixed by docs/CONTRACTS.md section 2 (the ONNX graphs), shared by the exporter and
the reference pipeline. No torch here."""

from __future__ import annotations

import hashlib
from pathlib import Path

NETWORKS = ("rdn", "rrn", "rfn")
FILES = {"rdn": "rdn.onnx", "rrn": "rrn.onnx", "rfn": "rfn.onnx"}
INPUTS = {"rdn": ("image",), "rrn": ("image", "edge"), "rfn": ("blend",)}
INPUT_CHANNELS = {"image": 3, "edge": 1, "blend": 3}
OUTPUTS = {"rdn": "mask_prob", "rrn": "reconstruction", "rfn": "restored"}
OUTPUT_CHANNELS = {"rdn": 1, "rrn": 3, "rfn": 3}

META_PAD_MULTIPLE = "raindrop.pad_multiple"
META_CONFIG = "raindrop.config"
META_NETWORK = "raindrop.network"
META_THRESHOLD = "raindrop.threshold"
META_DILATION = "raindrop.dilation"
META_KEYS = (META_PAD_MULTIPLE, META_CONFIG, META_NETWORK, META_THRESHOLD, META_DILATION)
# The largest dilation raindrop-remove accepts, in --dilation and in raindrop.dilation
# (kMaxDilation, include/raindrop/remove/model.h).
MAX_DILATION = 1023
# Optional on rdn.onnx: in raindrop-remove's coarse pass for large drops, each drop's mask
# dilation grows with its size (include/raindrop/remove/large_drops.h); absent means 0, the
# fixed k there too. The reference pipeline has no coarse pass and does not read it.
META_LARGE_DROP_GROWTH = "raindrop.large_drop_growth"
MAX_LARGE_DROP_GROWTH = 10.0
# Optional: the largest part of the mask this detector's images fill from their surroundings
# (include/raindrop/remove/surround_fill.h), with the long side at 512; 150 where absent.
META_SURROUND_FILL_AREA = "raindrop.surround_fill_area"
DEFAULT_SURROUND_FILL_AREA = 150
MAX_SURROUND_FILL_AREA = 2**31 - 1  # raindrop-remove reads it as a C int

# Optional second output of rdn.onnx: another detector's map from a head on this RDN's layers
# (shared_detector.py; include/raindrop/remove/model.h), with the metadata naming that detector's
# folder. The head's nodes are named with HEAD_NODE_PREFIX, so that the RDN itself can be read
# back from the graph (onnx_weights.py).
ALTERNATIVE_OUTPUT = "alternative_mask_prob"
META_ALTERNATIVE_DETECTOR = "raindrop.alternative_detector"
HEAD_NODE_PREFIX = "alternative/"

# The small JSON the exporter writes next to the graphs (not part of the contract).
EXPORT_INFO = "export.json"


def graph_files(folder: str | Path) -> dict:
    """export.json's "files" entry: sha256 and size of each graph in `folder`."""
    entries = {}
    for name in NETWORKS:
        path = Path(folder) / FILES[name]
        h = hashlib.sha256()
        with open(path, "rb") as f:
            for chunk in iter(lambda: f.read(1 << 20), b""):
                h.update(chunk)
        entries[FILES[name]] = {"sha256": h.hexdigest(), "bytes": path.stat().st_size}
    return entries
