"""Bad input to the tools' commands: one line on stderr and exit 2, never a traceback, and no
output file left behind by a command that failed (an adversarial pass found each of these)."""

import json
import shutil

import pytest

from helpers import FIXTURE_MODELS
from raindrop_tools import dataset_stats, evaluate, reference, score_outputs
from raindrop_tools.data import read_manifest


def test_score_outputs_reports_bad_outputs_in_one_line(tiny_dataset, tmp_path, capsys):
    outputs = tmp_path / "outputs"
    outputs.mkdir()
    name = read_manifest(tiny_dataset)[0].rainy.name
    (outputs / name).write_bytes(b"not a png")
    assert score_outputs.main(["--data", str(tiny_dataset), "--outputs", str(outputs)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("score_outputs: error: ") and len(err.strip().splitlines()) == 1


def test_dataset_stats_reports_missing_and_foreign_sets_in_one_line(tiny_dataset, tmp_path, capsys):
    assert dataset_stats.main([str(tmp_path / "nowhere")]) == 2
    assert capsys.readouterr().err.startswith("dataset_stats: error: ")
    # a set without the renderer's scene records (e.g. prepared real pairs); tiny_dataset is
    # shared, so a copy is altered
    copy = tmp_path / "copy"
    shutil.copytree(tiny_dataset, copy)
    lines = [json.loads(x) for x in (copy / "manifest.jsonl").read_text().splitlines()]
    for r in lines:
        r.pop("scene", None)
    (copy / "manifest.jsonl").write_text("".join(json.dumps(r) + "\n" for r in lines))
    assert dataset_stats.main([str(copy)]) == 2
    assert "a record has no 'scene'" in capsys.readouterr().err


def test_reference_checks_every_destination_before_writing(tiny_dataset, tmp_path, capsys):
    image = str(read_manifest(tiny_dataset)[0].rainy)
    for out, mask in ((tmp_path / "out.xyz", None), (tmp_path / "ok.png", tmp_path / "mask.xyz")):
        argv = [image, str(out), "--models", str(FIXTURE_MODELS)] + (["--mask", str(mask)] if mask else [])
        assert reference.main(argv) == 2
        assert "cannot write this format" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == [], "the output is not written when the mask cannot be"


def test_evaluate_out_that_is_a_file(tiny_dataset, tmp_path, capsys):
    (tmp_path / "afile").write_text("x")
    assert evaluate.main(["--data", str(tiny_dataset), "--models", str(FIXTURE_MODELS), "--out",
                          str(tmp_path / "afile")]) == 2
    assert capsys.readouterr().err == f"error: --out {tmp_path / 'afile'} is a file, not a folder\n"


@pytest.mark.parametrize("value", ["nan", "-0.1", "1.5", "x"])
def test_evaluate_threshold_outside_the_unit_interval(tiny_dataset, tmp_path, value, capsys):
    """--threshold nan gave empty masks and a result without a word."""
    with pytest.raises(SystemExit) as e:
        evaluate.main(["--data", str(tiny_dataset), "--models", str(FIXTURE_MODELS), "--out", str(tmp_path / "o"),
                       "--threshold", value])
    assert e.value.code == 2 and "--threshold" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()
