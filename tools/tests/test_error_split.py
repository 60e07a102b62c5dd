"""error_split: squared error inside and outside the true mask (no torch needed)."""

from __future__ import annotations

import json
import math

import numpy as np

from helpers import FIXTURE_MODELS
from raindrop_tools import error_split
from raindrop_tools.error_split import ErrorSplit


def test_split_against_closed_form():
    clean = np.full((4, 5, 3), 100, np.uint8)
    mask = np.zeros((4, 5), bool)
    mask[1:3, 1:3] = True                       # 4 of 20 pixels
    out = clean.copy()
    out[mask] += 10                             # error 10 in every channel inside, none outside
    rainy = clean.copy()
    rainy[mask] = 0                             # error 100 inside
    rainy[~mask] += 1                           # error 1 outside
    s = ErrorSplit()
    s.add(mask, clean, {"input": rainy, "output": out})
    r = s.summary()
    assert math.isclose(r["output"]["inside"], 20 * math.log10(255 / 10), rel_tol=1e-12)
    assert r["output"]["outside"] == 100.0      # identical: capped like metrics.psnr
    assert math.isclose(r["input"]["inside"], 20 * math.log10(255 / 100), rel_tol=1e-12)
    assert math.isclose(r["input"]["outside"], 20 * math.log10(255 / 1), rel_tol=1e-12)
    assert r["output_error_share_inside"] == 1.0
    assert math.isclose(r["mask_fraction"], 4 / 20)


def test_cli_on_a_data_set(tiny_dataset, capsys):
    assert error_split.main(["--data", str(tiny_dataset), "--models", str(FIXTURE_MODELS), "--every", "2"]) == 0
    r = json.loads(capsys.readouterr().out)
    assert r["images"] == 3
    for stage in error_split.STAGES:
        assert all(math.isfinite(r[stage][w]) for w in ("inside", "outside")), stage
    assert 0.0 <= r["output_error_share_inside"] <= 1.0


def test_cli_refuses_a_missing_data_set(tmp_path, capsys):
    assert error_split.main(["--data", str(tmp_path / "none"), "--models", str(FIXTURE_MODELS)]) == 2
    assert "error:" in capsys.readouterr().err
