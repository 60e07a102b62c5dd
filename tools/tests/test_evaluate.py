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


def test_real_pairs_evaluation(tmp_path):
    from realpairs_helpers import write_pairs

    from raindrop_tools import realpairs as RP

    pairs_dir = write_pairs(tmp_path / "pairs", groups=4, per_group=2, h=40, w=56)
    out = tmp_path / "out"
    args = ["--real-pairs", str(pairs_dir), "--models", str(FIXTURE_MODELS), "--out", str(out), "--threads", "1",
            "--no-progress"]
    assert main([*args, "--split", "test"]) == 0
    r = json.loads((out / "results.json").read_text())
    test_pairs = RP.select(RP.assign_splits(RP.find_pairs(pairs_dir)), "test")
    assert r["images"] == len(test_pairs) == 4 and r["split"] == "test"
    assert [x["id"] for x in r["per_image"]] == [p.id for p in test_pairs]
    remover = RaindropRemover(FIXTURE_MODELS, threads=1)
    pr = MT.PRAccumulator()
    for rec, p in zip(r["per_image"], test_pairs):
        rainy, clean, rough = RP.pair_mask(p)
        res = remover.remove(rainy, keep_intermediates=True)
        pr.add(res.prob, rough > 0)
        m_in, m_out = MT.image_metrics(rainy, clean), MT.image_metrics(res.output, clean)
        for k in ("psnr_y", "ssim_y", "psnr_rgb", "ssim_rgb"):
            assert rec[f"input_{k}"] == pytest.approx(m_in[k]) and rec[f"output_{k}"] == pytest.approx(m_out[k])
            assert rec[f"gain_{k}"] == pytest.approx(m_out[k] - m_in[k])
        sheet = cv2.imread(str(out / "sheets" / f"{p.id}.png"))
        assert sheet is not None and sheet.shape[1] == 4 * 56 + 3 * 4 and sheet.shape[0] >= 40
    for k in ("input_psnr_y", "output_ssim_rgb", "gain_psnr_y"):
        assert r["mean"][k] == pytest.approx(np.mean([x[k] for x in r["per_image"]]))
    assert r["ap_rough"] == pytest.approx(pr.average_precision())
    md = (out / "results.md").read_text()
    assert "| Gain |" in md and "| Input (no removal) |" in md
    with open(out / "per_image.csv") as f:
        assert len(list(csv.DictReader(f))) == 4
    # all pairs, another holdout, bad split
    assert main([*args, "--split", "all", "--holdout", "scene0", "--no-sheets", "--out", str(tmp_path / "o2")]) == 0
    assert json.loads((tmp_path / "o2" / "results.json").read_text())["images"] == 8
    assert main([*args, "--split", "val", "--out", str(tmp_path / "o3")]) == 2


FAKE_REMOVER = """#!{python}
# Stands in for raindrop-remove's folder mode: IN OUT --mask-dir M -q [options]; writes each
# input's clean twin (found beside the pair's rainy file through its link) as the output, and
# the region where they differ as the mask. Records its arguments.
import os, sys, cv2, numpy as np
a = sys.argv[1:]
src, dst, masks = a[0], a[1], a[a.index("--mask-dir") + 1]
open(os.path.join(os.path.dirname(os.path.abspath(sys.argv[0])), "args.txt"), "w").write(" ".join(a))
if "--threshold" in a and a[a.index("--threshold") + 1] == "0.99":
    sys.stderr.write("raindrop-remove: error: a one-line failure\\n"); sys.exit(1)
if "--threshold" in a and a[a.index("--threshold") + 1] == "0.98":
    sys.exit(0)  # says nothing, writes nothing
os.makedirs(dst); os.makedirs(masks)
for n in sorted(os.listdir(src)):
    rainy_path = os.path.realpath(os.path.join(src, n))
    clean_path = rainy_path.replace("_rain.", "_clean.")
    rainy, clean = cv2.imread(rainy_path), cv2.imread(clean_path)
    cv2.imwrite(os.path.join(dst, n), clean)
    m = (np.abs(rainy.astype(int) - clean.astype(int)).max(axis=2) > 0).astype(np.uint8) * 255
    cv2.imwrite(os.path.join(masks, os.path.splitext(n)[0] + ".png"), m)
"""


def test_real_pairs_scored_through_the_program(tmp_path, capsys, monkeypatch):
    # --program: what raindrop-remove makes of the pairs, scored as the networks' pass is (the
    # networks' single pass gained +0.22 dB on the held-out real pairs where the program gains +4.02)
    import os
    import sys

    from realpairs_helpers import write_pairs

    pairs_dir = write_pairs(tmp_path / "pairs", groups=4, per_group=2, h=40, w=56)
    fake = tmp_path / "fake-remove"
    fake.write_text(FAKE_REMOVER.format(python=sys.executable))
    fake.chmod(0o755)
    out = tmp_path / "out"
    args = ["--real-pairs", str(pairs_dir), "--program", str(fake), "--out", str(out), "--no-progress"]
    assert main(args) == 0
    r = json.loads((out / "results.json").read_text())
    assert r["images"] == 4 and r["program"] == str(fake) and r["ap_rough"] is None
    # the fake writes the clean photograph: the output is perfect, input and output scored as ever
    assert all(x["output_psnr_y"] == MT.PSNR_CAP_DB for x in r["per_image"])
    assert r["mean"]["gain_psnr_y"] > 0 and r["mask_vs_rough"]["recall"] > 0.5
    md = (out / "results.md").read_text()
    assert "| Output (fake-remove) |" in md and "AP n/a" in md
    assert (out / "sheets").is_dir() and len(list((out / "sheets").iterdir())) == 4
    # options go through to the program; it runs on the pairs' rainy images only, in one folder run
    assert main([*args, "--models", str(FIXTURE_MODELS), "--threshold", "0.4", "--dilation", "5", "--threads", "1",
                 "--out", str(tmp_path / "o2")]) == 0
    said = (tmp_path / "args.txt").read_text().split()
    assert said[said.index("--models") + 1] == str(FIXTURE_MODELS) and said[said.index("--threshold") + 1] == "0.4"
    assert said[said.index("--dilation") + 1] == "5" and said[said.index("-j") + 1] == "1" and "-q" in said
    assert said[0].endswith("/in") and not os.path.exists(said[0])  # a folder run, its scratch folder gone after
    capsys.readouterr()
    # a failing program is one line naming it; a program that is not there is a usage error
    assert main([*args, "--threshold", "0.99", "--out", str(tmp_path / "o3")]) == 2
    err = capsys.readouterr().err
    assert "failed on the pairs: raindrop-remove: error: a one-line failure" in err and len(err.strip().splitlines()) == 1
    assert main([*args, "--threshold", "0.98", "--out", str(tmp_path / "o6")]) == 2
    assert "exited 0 but wrote no output for pair" in capsys.readouterr().err
    # a bare name is the file in the working folder, not one PATH finds
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("PATH", "/nonexistent")
    assert main([*args[:2], "--program", "fake-remove", "--out", str(tmp_path / "o7"), "--no-progress"]) == 0
    with pytest.raises(SystemExit):
        main([*args[:2], "--program", str(tmp_path / "nowhere"), "--out", str(tmp_path / "o4")])
    with pytest.raises(SystemExit):  # --program is for real pairs
        main(["--data", str(pairs_dir), "--program", str(fake), "--out", str(tmp_path / "o5")])
    assert not (tmp_path / "o3").exists() or not (tmp_path / "o3" / "results.json").exists()


def test_real_pairs_sheets_describe_the_last_run_only(tmp_path):
    """A smaller rerun into the same folder left the earlier run's sheets beside its results,
    and a run that failed on a later pair left sheets without results. Sheets are written once
    every pair is scored, and those an earlier run recorded but this one did not make go."""
    import cv2 as _cv2

    from realpairs_helpers import write_pairs

    pairs_dir = write_pairs(tmp_path / "pairs", groups=4, per_group=2, h=40, w=56)
    out = tmp_path / "out"
    args = ["--real-pairs", str(pairs_dir), "--models", str(FIXTURE_MODELS), "--out", str(out), "--threads", "1",
            "--no-progress", "--split", "all"]
    (out / "sheets").mkdir(parents=True)
    (out / "sheets" / "mine.png").write_bytes(b"a user's file")
    assert main(args) == 0
    assert len(list((out / "sheets").iterdir())) == 9
    assert main([*args, "--limit", "3"]) == 0
    r = json.loads((out / "results.json").read_text())
    assert sorted(p.name for p in (out / "sheets").iterdir()) == sorted([f"{i}.png" for i in r["sheets"]] + ["mine.png"])
    assert len(r["sheets"]) == 3
    assert main([*args, "--no-sheets"]) == 0
    assert [p.name for p in (out / "sheets").iterdir()] == ["mine.png"]
    # a pair whose images differ in size fails the run: no sheet of the pairs before it is written
    bad = sorted(pairs_dir.glob("*_clean.png"))[-1]
    _cv2.imwrite(str(bad), np.zeros((7, 9, 3), np.uint8))
    assert main([*args, "--out", str(tmp_path / "o2")]) == 2
    assert not (tmp_path / "o2").exists()
