"""Tiny generated real-pair folders (no files from ../shared needed)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from helpers import add_drops, procedural_image


def write_pairs(folder: Path, groups: int = 4, per_group: int = 2, h: int = 48, w: int = 64, seed: int = 0,
                veil: float = 2.0, rainy_suffix: str = "_rain") -> Path:
    """``scene<g>_t<n>_rain.png`` + ``scene<g>_t<n>_clean.png``: drops as in the rendered test
    data, plus what a second camera adds: a 1 px shift and a small global offset (``veil``)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for g in range(groups):
        for t in range(per_group):
            clean = procedural_image(h, w, seed * 100 + g * 10 + t)
            rainy, _, _ = add_drops(clean, seed * 100 + g * 10 + t, count=3)
            shifted = rainy.copy()
            shifted[:, 1:] = rainy[:, :-1]
            rainy = np.clip(shifted.astype(np.float32) + veil, 0, 255).astype(np.uint8)
            stem = f"scene{g}_t{t}"
            cv2.imwrite(str(folder / f"{stem}{rainy_suffix}.png"), cv2.cvtColor(rainy, cv2.COLOR_RGB2BGR))
            cv2.imwrite(str(folder / f"{stem}_clean.png"), cv2.cvtColor(clean, cv2.COLOR_RGB2BGR))
    return folder
