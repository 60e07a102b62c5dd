"""Bad input to the tools' commands: one line on stderr and exit 2, never a traceback, and no
output file left behind by a command that failed (an adversarial pass found each of these)."""

import json
import shutil

import pytest

from helpers import FIXTURE_MODELS, REPO
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


def test_sizes_and_numbers_the_tools_cannot_use_are_usage_errors(tiny_dataset, tmp_path, capsys):
    """A second adversarial pass: a dilation or closing of 100000 px ended in OpenCV's allocation
    error (evaluate, realpairs, reference), --mask-threshold nan gave empty masks without a word,
    --threads -2 and a --set value that is no YAML ended in tracebacks, --max-steps -1 did
    nothing and said nothing."""
    from raindrop_tools import realpairs

    cases = [
        (evaluate.main, ["--data", str(tiny_dataset), "--models", str(FIXTURE_MODELS), "--out", str(tmp_path / "e"),
                         "--dilation", "100000"], "--dilation must be 1 to 1023"),
        (realpairs.main, ["prepare", str(tmp_path), "--out", str(tmp_path / "rp"), "--close", "100000"],
         "--close must be 1 to 1023"),
        (realpairs.main, ["prepare", str(tmp_path), "--out", str(tmp_path / "rp"), "--mask-threshold", "nan"],
         "--mask-threshold must be a number >= 0"),
    ]
    for command, argv, why in cases:
        with pytest.raises(SystemExit) as e:
            command(argv)
        assert e.value.code == 2 and why in capsys.readouterr().err, why
    assert not [p for p in tmp_path.iterdir()], "nothing written"


@pytest.mark.torch
def test_train_threads_and_steps_it_cannot_use_are_usage_errors(tmp_path, capsys):
    pytest.importorskip("torch")
    from raindrop_tools import train

    config = str(REPO / "tools" / "configs" / "compact.yaml")
    for flag, value, why in (("--threads", "-2", "--threads must be at least 1"),
                             ("--max-steps", "-1", "--max-steps must be at least 1")):
        with pytest.raises(SystemExit) as e:
            train.main(["--config", config, "--out", str(tmp_path / "t"), flag, value])
        assert e.value.code == 2 and why in capsys.readouterr().err, why
    assert not (tmp_path / "t").exists()


def test_a_train_override_that_is_no_yaml_is_a_config_error():
    from raindrop_tools.config import ConfigError, parse_overrides

    with pytest.raises(ConfigError, match="not YAML"):
        parse_overrides(["train.batch_size=[1"])
    from raindrop_tools.config import config_from_dict

    for value in ("-20", ".nan"):  # a negative weight trained away from the truth inside the drops
        with pytest.raises(ConfigError, match="rrn_mask_weight must be a number >= 0"):
            config_from_dict({}, parse_overrides([f"loss.rrn_mask_weight={value}"]))


@pytest.mark.torch
def test_a_head_config_with_numbers_the_run_cannot_use_is_refused(tmp_path):
    train_head = pytest.importorskip("raindrop_tools.train_head", exc_type=ImportError)

    base = (REPO / "tools" / "configs" / "compact-windshield-head.yaml").read_text()
    for change, why in (("batch_size: 0", "batch_size must be"), ("crop: 100000", "crop must be"),
                        ("lr: .nan", "lr must be a number > 0"), ("steps: 0", "steps must be"),
                        ("mid: 0", "mid must be")):
        key = change.split(":")[0]
        text = "\n".join(change if line.startswith(key + ":") else line for line in base.splitlines()) + "\n"
        (tmp_path / "h.yaml").write_text(text)
        with pytest.raises(SystemExit, match=why):
            train_head.read_config(tmp_path / "h.yaml")


@pytest.mark.torch
def test_a_head_source_of_real_pairs_with_held_out_pairs_needs_its_split(tmp_path):
    # train_head read every image of a source without a split, held-out real pairs included
    train_head = pytest.importorskip("raindrop_tools.train_head", exc_type=ImportError)
    from helpers import write_dataset

    root = write_dataset(tmp_path / "d", n=4, h=20, w=20, splits=("train", "test"))
    rows = [json.loads(t) for t in (root / "manifest.jsonl").read_text().splitlines()]
    (root / "manifest.jsonl").write_text("".join(json.dumps({**r, "source": "real-pairs"}) + "\n" for r in rows))
    with pytest.raises(SystemExit, match="2 of its real pairs are in the 'test' split"):
        train_head._image_files(train_head.Source(path=str(root), weight=1.0))
    assert len(train_head._image_files(train_head.Source(path=str(root), weight=1.0, split="train"))) == 2
    with open(root / "manifest.jsonl", "a") as f:
        f.write("not json\n[1]\n")
    with pytest.raises(SystemExit, match="manifest.jsonl:5: not valid JSON"):
        train_head._image_files(train_head.Source(path=str(root), weight=1.0))


@pytest.mark.torch
def test_a_head_run_folder_with_a_head_is_not_trained_over(tmp_path):
    train_head = pytest.importorskip("raindrop_tools.train_head", exc_type=ImportError)

    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "head.pt").write_bytes(b"the first run's head")
    cfg = REPO / "tools" / "configs" / "compact-windshield-head.yaml"
    with pytest.raises(SystemExit, match="holds a trained head"):
        train_head.main(["--config", str(cfg), "--out", str(tmp_path / "run")])
    assert (tmp_path / "run" / "head.pt").read_bytes() == b"the first run's head"
    # a run's log says how far it got: cut short (head.pt every 500 steps) it is trained again
    (tmp_path / "run" / "log.jsonl").write_text('{"step": 50, "loss": 1}\n{"step": 500, "loss": 0.5}\n')
    assert train_head._steps_logged(tmp_path / "run") == 500
    (tmp_path / "run" / "log.jsonl").write_text('{"step": 50\n')
    assert train_head._steps_logged(tmp_path / "run") == float("inf")  # damaged: not known to be cut short


def test_dataset_stats_refuses_a_record_of_width_zero(tiny_dataset, tmp_path, capsys):
    copy = tmp_path / "copy"
    shutil.copytree(tiny_dataset, copy)
    lines = [json.loads(x) for x in (copy / "manifest.jsonl").read_text().splitlines()]
    lines[0]["width"] = 0
    (copy / "manifest.jsonl").write_text("".join(json.dumps(r) + "\n" for r in lines))
    assert dataset_stats.main([str(copy)]) == 2
    assert "is not a positive number" in capsys.readouterr().err


def test_stats_and_packs_of_a_missing_folder_or_a_broken_manifest_say_which(tiny_dataset, tmp_path, capsys):
    # "nosuch: empty manifest", "no samples to pack", and JSON errors naming no file or line
    from raindrop_tools import datapack

    broken = tmp_path / "broken"
    shutil.copytree(tiny_dataset, broken)
    lines = (broken / "manifest.jsonl").read_text().splitlines()
    lines[1] = "{not json"
    (broken / "manifest.jsonl").write_text("\n".join(lines) + "\n")
    assert dataset_stats.main([str(tmp_path / "nosuch")]) == 2
    assert "nosuch: no such folder" in capsys.readouterr().err
    assert dataset_stats.main([str(broken)]) == 2
    assert "manifest.jsonl:2: not valid JSON" in capsys.readouterr().err
    assert datapack.main(["pack", str(tmp_path / "p"), str(tmp_path / "nosuch") + ":4"]) != 0
    assert "nosuch: no such folder" in capsys.readouterr().err
    assert datapack.main(["pack", str(tmp_path / "p"), str(broken) + ":4"]) != 0
    err = capsys.readouterr().err
    assert "manifest.jsonl:2: not valid JSON" in err and "Traceback" not in err
    assert not (tmp_path / "p").exists()
    (broken / "manifest.jsonl").write_text("\n".join(lines[:1] + ["[1]"] + lines[2:]) + "\n")
    assert datapack.main(["pack", str(tmp_path / "p"), str(broken) + ":4"]) != 0
    err = capsys.readouterr().err
    assert "a manifest record without the id" in err and "Traceback" not in err


def test_an_unreadable_image_is_one_line_without_opencvs_own_log(tmp_path):
    # OpenCV printed "[ WARN:0@0.1] global loadsave.cpp ... findDecoder ..." on the process's
    # stderr (not Python's: capsys cannot see it) before the tool's own line
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k != "OPENCV_LOG_LEVEL"}
    env["PYTHONPATH"] = str(REPO / "tools")
    cmd = [sys.executable, "-m", "raindrop_tools.reference", str(tmp_path / "missing.png"), str(tmp_path / "o.png"),
           "--models", str(FIXTURE_MODELS)]
    done = subprocess.run(cmd, capture_output=True, text=True, env=env)
    assert done.returncode == 2 and done.stderr.strip().splitlines() == [
        f"error: {tmp_path / 'missing.png'}: cannot read image (missing or not an image)"], done.stderr
    done = subprocess.run(cmd, capture_output=True, text=True, env={**env, "OPENCV_LOG_LEVEL": "WARNING"})
    assert "findDecoder" in done.stderr  # a user who asks for OpenCV's log still gets it


def test_a_key_given_twice_in_a_config_is_refused(tmp_path):
    """YAML keeps the last: a second top-level 'train:' replaced the first's settings silently."""
    from raindrop_tools.config import ConfigError, load_config

    text = (REPO / "tools" / "configs" / "compact.yaml").read_text()
    (tmp_path / "twice.yaml").write_text(text + "\ntrain:\n  batch_size: 2\n")
    with pytest.raises(ConfigError, match="given twice"):
        load_config(tmp_path / "twice.yaml")


@pytest.mark.torch
def test_a_key_given_twice_in_a_head_config_is_refused(tmp_path):
    train_head = pytest.importorskip("raindrop_tools.train_head", exc_type=ImportError)
    head = (REPO / "tools" / "configs" / "compact-windshield-head.yaml").read_text()
    (tmp_path / "h.yaml").write_text(head + "steps: 5\n")
    with pytest.raises(SystemExit, match="given twice"):
        train_head.read_config(tmp_path / "h.yaml")


def test_a_config_may_still_merge_an_anchor_and_override_its_keys(tmp_path):
    from raindrop_tools.config import load_yaml

    data = load_yaml("base: &b {width: 8, blocks: 2}\nrrn: {<<: *b, blocks: 4}\n")
    assert data["rrn"] == {"width": 8, "blocks": 4}


@pytest.mark.torch
def test_a_head_config_may_end_its_schedule_at_zero(tmp_path):
    train_head = pytest.importorskip("raindrop_tools.train_head", exc_type=ImportError)

    base = (REPO / "tools" / "configs" / "compact-windshield-head.yaml").read_text()
    text = "\n".join("lr_end: 0.0" if line.startswith("lr_end:") else line for line in base.splitlines()) + "\n"
    (tmp_path / "h.yaml").write_text(text)
    assert train_head.read_config(tmp_path / "h.yaml").lr_end == 0.0
