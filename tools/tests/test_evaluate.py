"""End-to-end evaluation on the committed fixture graphs (no torch)."""

import csv
import json

import cv2
import numpy as np
import pytest

from helpers import FIXTURE_MODELS, write_dataset
from raindrop_tools import metrics as MT
from raindrop_tools.data import read_manifest
from raindrop_tools.evaluate import main
from raindrop_tools.imageio import read_rgb_strict
from raindrop_tools.reference import RaindropRemover


@pytest.fixture(scope="module")
def evaluation(tmp_path_factory):
    base = tmp_path_factory.mktemp("eval")
    data = write_dataset(base / "test", n=4, h=40, w=60, seed=5, splits=("test", "train"))
    out = base / "out"
    assert (
        main(
            [
                "--data",
                str(data),
                "--models",
                str(FIXTURE_MODELS),
                "--out",
                str(out),
                "--split",
                "test",
                "--threads",
                "1",
                "--no-progress",
            ]
        )
        == 0
    )
    return {"data": data, "out": out, "result": json.loads((out / "results.json").read_text())}


def test_rows_and_columns(evaluation):
    r = evaluation["result"]
    assert r["images"] == 2 and r["threshold"] == 0.2 and r["dilation"] == 3
    assert [row["row"] for row in r["rows"]] == ["input", "3rn", "full_k1", "full_k3"]
    for row in r["rows"]:
        for k in ("psnr_y", "ssim_y", "psnr_rgb", "ssim_rgb", "ms"):
            assert np.isfinite(row[k]), (row["row"], k)
        assert (row["ap"] is None) == (not row["row"].startswith("full"))
    assert r["rows"][0]["ms"] == 0.0 and r["rows"][3]["ms"] > r["rows"][1]["ms"] > 0
    assert 0 <= r["ap"] <= 1
    md = (evaluation["out"] / "results.md").read_text()
    assert "| Input (no removal) |" in md and "| 3RN + RDN + RFN, dilation k=3 |" in md and "PSNR (Y)" in md


def test_values_agree_with_the_reference_pipeline_and_metrics(evaluation):
    samples = read_manifest(evaluation["data"], ["test"])
    remover = RaindropRemover(FIXTURE_MODELS, threads=1)
    rows = {row["row"]: row for row in evaluation["result"]["rows"]}
    want = {name: [] for name in rows}
    pr = MT.PRAccumulator()
    for s in samples:
        rainy, clean = read_rgb_strict(s.rainy), read_rgb_strict(s.clean)
        want["input"].append(MT.image_metrics(rainy, clean))
        want["3rn"].append(MT.image_metrics(remover.reconstruct_only(rainy).output, clean))
        want["full_k1"].append(MT.image_metrics(remover.remove(rainy, dilation=1).output, clean))
        full = remover.remove(rainy, keep_intermediates=True)
        want["full_k3"].append(MT.image_metrics(full.output, clean))
        pr.add(full.prob, cv2.imread(str(s.mask), cv2.IMREAD_UNCHANGED) > 127)
    for name, row in rows.items():
        for k in ("psnr_y", "ssim_y", "psnr_rgb", "ssim_rgb"):
            assert row[k] == pytest.approx(np.mean([m[k] for m in want[name]]), rel=1e-12), (name, k)
    assert evaluation["result"]["ap"] == pytest.approx(pr.average_precision())
    with open(evaluation["out"] / "per_image.csv") as f:
        assert len(list(csv.DictReader(f))) == 2 * 4


def test_pr_curve_png(evaluation):
    img = cv2.imread(str(evaluation["out"] / "pr_curve.png"))
    assert img is not None and img.shape[0] > 200 and img.shape[1] > 400
    assert img.std() > 5  # not a blank canvas


def test_refuses_a_bad_test_set(tmp_path, capsys):
    data = write_dataset(tmp_path / "d", n=2, h=20, w=20)
    (data / "manifest.jsonl").write_text((data / "manifest.jsonl").read_text() + "{oops\n")
    assert (
        main(["--data", str(data), "--models", str(FIXTURE_MODELS), "--out", str(tmp_path / "o"), "--no-progress"]) == 2
    )
    assert "manifest.jsonl:3: not valid JSON" in capsys.readouterr().err
