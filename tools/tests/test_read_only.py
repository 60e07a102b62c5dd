"""A file made read-only (no write bit for anyone) is kept by every tool that would replace it,
for every user: root may open any file for writing, and renaming over a file needs only the
folder's permission, so before the rule both lost such files without a word (read_only.py).
Each test checks the tool's one-line refusal and that the file's bytes and mode are unchanged;
each fails without its check, as root and as any other user (the rename-over sites)."""

import json
import os
import shutil
import stat

import numpy as np
import pytest

from helpers import FIXTURE_MODELS
from raindrop_tools import contract as C
from raindrop_tools import evaluate, large_drop_growth, merge_datasets
from raindrop_tools.imageio import ImageError, write_rgb
from raindrop_tools.read_only import ReadOnlyFileError, read_only_problem, refuse_read_only
from raindrop_tools.report_file import report_path_problem
from raindrop_tools.staging import staged_model_files


def _protect(path):
    """Makes `path` read-only and returns what must stay as it was: bytes and mode."""
    path.chmod(0o444)
    return path.read_bytes(), stat.S_IMODE(path.stat().st_mode)


def _kept(path, before):
    assert (path.read_bytes(), stat.S_IMODE(path.stat().st_mode)) == before


def test_the_rule_is_the_mode_not_who_asks(tmp_path):
    f = tmp_path / "result.json"
    assert read_only_problem(f) is None  # nothing there to lose
    f.write_text("{}")
    assert read_only_problem(f) is None
    for mode in (0o200, 0o020, 0o002):  # any write bit: the owner (or a group) said it may change
        f.chmod(mode)
        assert read_only_problem(f) is None
    f.chmod(0o444)
    assert read_only_problem(f) == f"'{f}': read-only (no write permission for anyone); make it writable, or remove it"
    link = tmp_path / "link.json"
    link.symlink_to(f)
    assert read_only_problem(link) is not None  # written through, the target would change
    assert read_only_problem(link, follow_links=False) is None  # renamed over, only the link goes
    with pytest.raises(ReadOnlyFileError) as e:
        refuse_read_only(tmp_path / "absent", f)
    assert isinstance(e.value, OSError)  # every tool's `except OSError` reports it on one line
    d = tmp_path / "folder"
    d.mkdir(mode=0o555)
    assert read_only_problem(d) is None  # only regular files: a folder's mode is the folder's business


def test_an_image_written_over_a_read_only_one_is_refused(tmp_path):
    out = tmp_path / "sheet.png"
    write_rgb(out, np.zeros((4, 4, 3), np.uint8))
    before = _protect(out)
    with pytest.raises(ImageError, match="read-only"):
        write_rgb(out, np.full((4, 4, 3), 255, np.uint8))
    _kept(out, before)


def test_a_model_folder_with_a_read_only_graph_is_left_whole(tmp_path):
    folder = tmp_path / "models"
    shutil.copytree(FIXTURE_MODELS, folder)
    before = _protect(folder / C.FILES["rfn"])
    others = {n: (folder / C.FILES[n]).read_bytes() for n in ("rdn", "rrn")}
    with pytest.raises(ReadOnlyFileError):
        with staged_model_files(folder, "export") as stage:
            for n in C.NETWORKS:  # never reached: refused before the work
                (stage / C.FILES[n]).write_bytes(b"new")
    _kept(folder / C.FILES["rfn"], before)
    assert {n: (folder / C.FILES[n]).read_bytes() for n in ("rdn", "rrn")} == others
    assert sorted(p.name for p in tmp_path.iterdir()) == ["models"], "no staging folder left"


def test_large_drop_growth_keeps_a_read_only_export_json_and_its_graph(tmp_path, capsys):
    folder = tmp_path / "models"
    shutil.copytree(FIXTURE_MODELS, folder)
    (folder / C.EXPORT_INFO).write_text(json.dumps({"config": "smoke", "files": C.graph_files(folder)}) + "\n")
    before = _protect(folder / C.EXPORT_INFO)
    rdn = (folder / C.FILES["rdn"]).read_bytes()
    assert large_drop_growth.main([str(folder), "0.35"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "read-only" in err[0], err
    _kept(folder / C.EXPORT_INFO, before)
    assert (folder / C.FILES["rdn"]).read_bytes() == rdn, "the graph is not replaced when export.json is refused"


def test_a_read_only_report_is_refused_before_the_work(tmp_path):
    report = tmp_path / "realism.json"
    report.write_text("{}")
    _protect(report)
    assert "read-only" in report_path_problem(report)


def test_evaluate_refuses_a_read_only_result_before_evaluating(tiny_dataset, tmp_path, capsys):
    out = tmp_path / "eval"
    out.mkdir()
    (out / "results.json").write_text("{}\n")
    before = _protect(out / "results.json")
    argv = ["--data", str(tiny_dataset), "--models", str(FIXTURE_MODELS), "--out", str(out), "--no-progress"]
    assert evaluate.main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "read-only" in err[0], err
    _kept(out / "results.json", before)
    assert sorted(p.name for p in out.iterdir()) == ["results.json"], "nothing evaluated or written"
    (out / "results.json").chmod(0o644)
    (out / "pr_curve.png").write_bytes(b"an earlier curve")
    before = _protect(out / "pr_curve.png")
    assert evaluate.main(argv) == 2 and "pr_curve.png': read-only" in capsys.readouterr().err
    _kept(out / "pr_curve.png", before)


def test_merge_keeps_a_read_only_manifest(tiny_dataset, tmp_path, capsys):
    out = tmp_path / "merged"
    out.mkdir()
    (out / "manifest.jsonl").write_text("")
    before = _protect(out / "manifest.jsonl")
    assert merge_datasets.main(["--out", str(out), str(tiny_dataset)]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "read-only" in err[0], err
    _kept(out / "manifest.jsonl", before)
    assert sorted(p.name for p in out.iterdir()) == ["manifest.jsonl"], "refused before the first link"


@pytest.mark.torch
def test_a_training_run_keeps_its_read_only_files(tmp_path):
    pytest.importorskip("torch")  # the light set (RAINDROP_TEST_NO_TORCH=1) has no PyTorch
    from raindrop_tools import train

    f = tmp_path / "config.yaml"
    f.write_text("old\n")
    before = _protect(f)
    with pytest.raises(ReadOnlyFileError):
        train._write_text_atomic(f, "new\n")
    _kept(f, before)
    from raindrop_tools.checkpoint import save_atomic  # torch

    ck = tmp_path / "step_000100.pt"
    ck.write_bytes(b"a checkpoint")
    before = _protect(ck)
    with pytest.raises(ReadOnlyFileError):
        save_atomic({"step": 1}, ck)
    _kept(ck, before)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["config.yaml", "step_000100.pt"], "no temporary left"


@pytest.mark.skipif(os.name != "posix", reason="file modes")
def test_every_write_site_in_the_tools_is_guarded():
    """A new write site is a new way to lose a file: each module that renames over a name or
    writes an image, a checkpoint or a table checks the rule (grep-level, to be read with the
    behavioural tests above)."""
    from pathlib import Path

    tools = Path(__file__).resolve().parents[1] / "raindrop_tools"
    unguarded = []
    for py in sorted(tools.glob("*.py")):
        text = py.read_text()
        writes = any(w in text for w in ("os.replace(", "cv2.imwrite(", "torch.save(", ".unlink(", "savefig(",
                                          "write_text(", "write_bytes("))
        if writes and "read_only" not in text and py.name not in (
                "read_only.py", "realpairs.py", "export.py", "graph_rewrite.py", "quantize.py", "staging.py"):
            unguarded.append(py.name)
    # realpairs.py renames a fresh folder over an empty one it checked; export.py, graph_rewrite.py
    # and quantize.py write into staging folders that staging.py guards (staging.py itself removes
    # only its own stale staging folders, and is guarded).
    assert unguarded == []


def test_evaluate_keeps_a_read_only_sheet_it_would_have_removed(tmp_path, capsys):
    """A rerun removes the sheets an earlier run recorded and this one does not make; a read-only
    one is refused, with every other file of the folder as it was."""
    from realpairs_helpers import write_pairs

    pairs_dir = write_pairs(tmp_path / "pairs", groups=4, per_group=2, h=40, w=56)
    out = tmp_path / "out"
    args = ["--real-pairs", str(pairs_dir), "--models", str(FIXTURE_MODELS), "--out", str(out), "--threads", "1",
            "--no-progress", "--split", "all"]
    assert evaluate.main(args) == 0
    sheets = sorted((out / "sheets").iterdir())
    before = _protect(sheets[-1])
    results = (out / "results.json").read_bytes()
    assert evaluate.main([*args, "--no-sheets"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "read-only" in err[0], err
    _kept(sheets[-1], before)
    assert sorted((out / "sheets").iterdir()) == sheets and (out / "results.json").read_bytes() == results


@pytest.mark.torch
def test_pruning_keeps_a_read_only_checkpoint(tmp_path):
    pytest.importorskip("torch")
    from raindrop_tools import checkpoint as ckpt

    run = tmp_path / "run"
    for step in (100, 200, 300, 400):
        ckpt.save_atomic({"step": step}, ckpt.checkpoint_path(run, 1, step))
    old = ckpt.checkpoint_path(run, 1, 100)
    before = _protect(old)
    ckpt.prune(run, 1, keep=1)
    _kept(old, before)
    assert [r.path.name for r in ckpt.list_checkpoints(run, 1)] == [old.name, ckpt.checkpoint_path(run, 1, 400).name]


@pytest.mark.torch
def test_train_reports_a_read_only_run_file_on_one_line_before_any_work(tmp_path, capsys):
    pytest.importorskip("torch")
    from raindrop_tools import train

    run = tmp_path / "run"
    run.mkdir()
    (run / train.RUN_FILE).write_text("{}\n")
    before = _protect(run / train.RUN_FILE)
    with pytest.raises(ReadOnlyFileError):
        train.prepare_run_dir(run, None)
    _kept(run / train.RUN_FILE, before)
    assert ReadOnlyFileError in train.REPORTED  # main() prints REPORTED errors on one line, exit 2


def test_reference_keeps_a_read_only_mask_and_writes_no_output(tiny_dataset, tmp_path, capsys):
    from raindrop_tools import reference
    from raindrop_tools.data import read_manifest

    image = str(read_manifest(tiny_dataset)[0].rainy)
    mask = tmp_path / "mask.png"
    write_rgb(mask, np.zeros((4, 4, 3), np.uint8))
    before = _protect(mask)
    out = tmp_path / "out.png"
    assert reference.main([image, str(out), "--models", str(FIXTURE_MODELS), "--mask", str(mask)]) == 2
    assert "read-only" in capsys.readouterr().err
    _kept(mask, before)
    assert not out.exists(), "every destination is checked before the first is written"
