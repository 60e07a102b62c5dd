"""raindrop_tools: training, ONNX export, reference pipeline and evaluation for raindrop
(Hao et al., "Learning From Synthetic Photorealistic Raindrop for Single Image Raindrop
Removal", ICCV-W 2019).

Modules that need torch: networks, flops, losses, train, export (and morphology.Dilation).
Everything else imports without it: config, data, edge, imageio, metrics, reference,
evaluate, contract.
"""

import os as _os

__version__ = "0.1.0"

# ONNX Runtime's official builds for Linux and macOS (the PyPI wheel: 1.31 does) collect
# usage telemetry: importing onnxruntime writes a persistent device id and an event database
# under ~/.cache/Microsoft (or $XDG_CACHE_HOME/Microsoft) and a file in $TMPDIR, and its
# uploader sends the events to Microsoft. Turned off here, before any of our modules imports onnxruntime (it
# reads the variable once, at import), as raindrop-remove does (raindrop/remove/session.h).
# A non-empty value the user set is kept: ORT_DISABLE_TELEMETRY=0 opts back in.
if not _os.environ.get("ORT_DISABLE_TELEMETRY"):
    _os.environ["ORT_DISABLE_TELEMETRY"] = "1"
