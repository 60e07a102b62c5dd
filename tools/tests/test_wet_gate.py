"""raindrop_tools.wet_gate: the fit keeps the share of wet frames it is asked to, the file's round
trip and refusals (the same faults tests/remove/test_wet_gate.cpp refuses in C++), and the
command line on the fixture models. The program's z against this tool's: the C++ test
WetGate.TheProgramScoresAsTheFittingTool."""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from raindrop_tools import wet_gate as G

SMOKE = Path(__file__).resolve().parent / "fixtures" / "models-smoke"


def features(n, shift, seed):
    rng = np.random.default_rng(seed)
    return rng.normal(size=(n, 20)) + shift


@pytest.mark.parametrize("keep", [1.0, 0.95, 0.9, 0.5])
def test_fit_keeps_the_share_of_wet_frames_asked_for(keep):
    wet, dry = features(60, 0.8, 1), features(80, -0.8, 2)
    gate = G.fit(wet, dry, "m", keep)
    assert gate.maps == 2
    kept = np.mean(gate.score(wet) > 0)
    # At least the share asked for, and no more than one frame beyond it (the threshold sits at a frame).
    assert keep <= kept + 1e-9
    assert kept <= keep + 1 / 60 + 1e-9
    # Overlapping classes: most dry frames are still judged dry where fewer wet ones must be kept.
    assert np.mean(gate.score(dry) <= 0) > (0.5 if keep == 1.0 else 0.8)
    # The threshold lies halfway between the lowest wet frame kept and the highest frame below it.
    z = np.concatenate([gate.score(wet), gate.score(dry)])
    assert np.min(z[z > 0]) == pytest.approx(-np.max(z[z <= 0]), abs=1e-9)


def test_fit_keeps_at_least_one_wet_frame():
    gate = G.fit(features(10, 0.5, 1), features(10, -0.5, 2), "m", 1e-12)
    assert np.sum(gate.score(features(10, 0.5, 1)) > 0) >= 1


def test_fit_refuses_too_few_frames_and_a_share_out_of_range():
    with pytest.raises(G.GateError, match="at least 2"):
        G.fit(features(1, 0, 1), features(5, 0, 2), "m")
    with pytest.raises(G.GateError, match="keep-wet"):
        G.fit(features(5, 0, 1), features(5, 0, 2), "m", 0.0)


def test_a_written_gate_reads_back_and_scores_the_same(tmp_path):
    wet, dry = features(20, 1, 3)[:, :10], features(20, -1, 4)[:, :10]
    gate = G.fit(wet, dry, "compact-multiscale", 0.95)
    G.write_gate(tmp_path / "g", gate, "two\nlines")
    text = (tmp_path / "g").read_text()
    assert text.startswith("# two\n# lines\nformat 1\nmodels compact-multiscale\nmaps 1\n")
    back = G.read_gate(tmp_path / "g")
    np.testing.assert_array_equal(back.score(wet), gate.score(wet))
    assert not (tmp_path / "g.tmp").exists()


def gate_text(models="m", maps=1, std="1", bias="0"):
    n = 10 * maps
    return (f"format 1\nmodels {models}\nmaps {maps}\nmean {' 0' * n}\nstd {(' ' + std) * n}\n"
            f"weight {' 0' * n}\nbias {bias}\n")


@pytest.mark.parametrize("text, why", [
    ("", "format 1"),
    (gate_text() + "bias 1\n", "given twice"),
    (gate_text(models="../up"), "one model folder"),
    (gate_text(maps=3), "'maps' must be 1 or 2"),
    (gate_text(std="0"), "positive"),
    (gate_text(std="nan"), "finite"),
    (gate_text(bias="x"), "not a number"),
    ("format 1\nmodels m\nmaps 2\nmean" + " 0" * 10 + "\n", "20 finite numbers"),
])
def test_a_damaged_file_is_refused_naming_it(tmp_path, text, why):
    (tmp_path / "camera.gate").write_text(text)
    with pytest.raises(G.GateError, match=why) as e:
        G.read_gate(tmp_path / "camera.gate")
    assert "camera.gate" in str(e.value)


def write_frames(folder, n, seed, drops):
    folder.mkdir(parents=True)
    rng = np.random.default_rng(seed)
    for i in range(n):
        img = np.full((96, 128, 3), 90, np.uint8) + rng.integers(0, 20, (96, 128, 3), dtype=np.uint8)
        for _ in range(drops):
            c = (int(rng.integers(10, 118)), int(rng.integers(10, 86)))
            cv2.circle(img, c, int(rng.integers(4, 12)), (230, 230, 230), -1)
        cv2.imwrite(str(folder / f"f{i}.png"), img)


def test_the_command_line_fits_and_judges_on_the_fixture_models(tmp_path, capsys):
    write_frames(tmp_path / "wet", 6, 1, drops=8)
    write_frames(tmp_path / "dry" / "sub", 6, 2, drops=0)  # folders are searched recursively
    out = tmp_path / "camera.gate"
    assert G.main(["fit", "--models", str(SMOKE), "--wet", str(tmp_path / "wet"), "--dry", str(tmp_path / "dry"),
                   "--out", str(out), "--keep-wet", "1", "--threads", "1"]) == 0
    gate = G.read_gate(out)
    assert gate.models == "models-smoke" and gate.maps == 1
    assert "6 wet and 6 dry frames" in capsys.readouterr().out
    images = sorted(str(p) for p in (tmp_path / "wet").iterdir())
    assert G.main(["judge", "--gate", str(out), "--models", str(SMOKE), "--threads", "1", *images]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split()[0] for line in lines] == images
    assert all(line.split()[2] == "wet" for line in lines)  # every wet training frame kept (--keep-wet 1)


def test_the_command_line_refuses_in_one_line(tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    write_frames(tmp_path / "wet", 2, 1, drops=3)
    assert G.main(["fit", "--models", str(SMOKE), "--wet", str(tmp_path / "wet"), "--dry", str(tmp_path / "empty"),
                   "--out", str(tmp_path / "g")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no images" in err
    assert not (tmp_path / "g").exists()
    # the same frames as both wet and dry: a gate fitted on them is no gate
    assert G.main(["fit", "--models", str(SMOKE), "--wet", str(tmp_path / "wet"), "--dry", str(tmp_path / "wet"),
                   "--out", str(tmp_path / "g")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "given as both wet and dry" in err
    assert not (tmp_path / "g").exists()
    assert G.main(["judge", "--gate", str(tmp_path / "missing"), "--models", str(SMOKE), "x.png"]) == 1
    assert "cannot read it" in capsys.readouterr().err
    (tmp_path / "other.gate").write_text(gate_text(models="compact-multiscale"))
    assert G.main(["judge", "--gate", str(tmp_path / "other.gate"), "--models", str(SMOKE), "x.png"]) == 1
    assert "not of 'models-smoke'" in capsys.readouterr().err


def test_a_gate_is_read_only_from_a_small_plain_file_and_written_only_over_a_key_file(tmp_path, capsys):
    # Reading: a FIFO blocked, /dev/zero grew without end (as raindrop-remove, which refuses both).
    os.mkfifo(tmp_path / "fifo.gate")
    for bad, why in ((tmp_path / "fifo.gate", "not a file"), (Path("/dev/zero"), "not a file"), (tmp_path, "not a file")):
        with pytest.raises(G.GateError, match=why):
            G.read_gate(bad)
    (tmp_path / "huge.gate").write_text(gate_text() + "#" + "x" * 70000 + "\n")
    with pytest.raises(G.GateError, match="not a key file"):
        G.read_gate(tmp_path / "huge.gate")
    # Writing, refused before the work: a gate once replaced a wet frame it was fitted on; a
    # folder left a half-written temporary; a fixed temporary name replaced a user's file.
    write_frames(tmp_path / "wet", 3, 1, drops=3)
    write_frames(tmp_path / "dry", 3, 2, drops=0)
    frame = sorted((tmp_path / "wet").iterdir())[0]
    before = frame.read_bytes()
    (tmp_path / "out-folder").mkdir()
    for out, why in ((frame, "not a key file"), (tmp_path / "out-folder", "not a plain file")):
        assert G.main(["fit", "--models", str(SMOKE), "--wet", str(tmp_path / "wet"), "--dry", str(tmp_path / "dry"),
                       "--out", str(out), "--threads", "1"]) == 1
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and why in err, err
    assert frame.read_bytes() == before
    assert list((tmp_path / "out-folder").iterdir()) == []
    (tmp_path / "g.gate.tmp").write_text("the user's notes\n")
    out = tmp_path / "g.gate"
    assert G.main(["fit", "--models", str(SMOKE), "--wet", str(tmp_path / "wet"), "--dry", str(tmp_path / "dry"),
                   "--out", str(out), "--threads", "1"]) == 0
    assert (tmp_path / "g.gate.tmp").read_text() == "the user's notes\n"
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".g.gate")]
    assert G.main(["fit", "--models", str(SMOKE), "--wet", str(tmp_path / "wet"), "--dry", str(tmp_path / "dry"),
                   "--out", str(out), "--threads", "1"]) == 0  # an earlier gate is replaced
    # Not over a model folder's ROUTER (a key file of another kind), nor a name ending in '/';
    # an empty file and a link (the link is replaced, its target kept) are fine.
    from raindrop_tools.key_file import key_file_path_problem

    (tmp_path / "ROUTER").write_text("format 1\nalternative x\nmean 0\n")
    assert "not a key file of this kind" in key_file_path_problem(tmp_path / "ROUTER", G.GateError, "models")
    assert "names a folder" in key_file_path_problem(str(tmp_path / "new") + "/", G.GateError, "models")
    (tmp_path / "empty.gate").write_text("")
    (tmp_path / "link.gate").symlink_to(frame)
    assert key_file_path_problem(tmp_path / "empty.gate", G.GateError, "models") is None
    assert key_file_path_problem(tmp_path / "link.gate", G.GateError, "models") is None


def test_folder_names_are_those_raindrop_remove_gives(tmp_path, monkeypatch):
    (tmp_path / "models" / "compact").mkdir(parents=True)
    (tmp_path / "current").symlink_to(tmp_path / "models" / "compact")
    assert G.folder_name(tmp_path / "models" / "compact") == "compact"
    assert G.folder_name(str(tmp_path / "models" / "compact") + "/") == "compact"
    assert G.folder_name(tmp_path / "current") == "current"  # a link is not followed
    monkeypatch.chdir(tmp_path / "models" / "compact")
    assert G.folder_name(".") == "compact"
    assert G.float_twin("compact-int8") == "compact" and G.float_twin("compact") == "compact"
    assert G.float_twin("-int8") == "-int8"


def test_sixteen_bit_frames_are_seen_at_sixteen_bits(tmp_path):
    from raindrop_tools.imageio import native_to_float, read_rgb_native

    rng = np.random.default_rng(5)
    img16 = rng.integers(0, 65536, (20, 30, 3), dtype=np.uint16)
    cv2.imwrite(str(tmp_path / "a.png"), img16)
    back = read_rgb_native(tmp_path / "a.png")
    assert back.dtype == np.uint16
    np.testing.assert_array_equal(back, img16[..., ::-1])
    np.testing.assert_array_equal(native_to_float(back), back.astype(np.float32) / np.float32(65535))
