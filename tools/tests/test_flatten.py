"""flatten.py: piecewise-flat frames for the detector's negatives."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from raindrop_tools.flatten import flat_fraction, flatten, main


def textured(seed: int = 0) -> Image.Image:
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:96, 0:160]
    base = np.stack([x * 1.5, y * 2.0, (x + y) * 0.8], axis=2)
    return Image.fromarray(np.clip(base + rng.normal(0, 6, base.shape), 0, 255).astype(np.uint8))


def test_flattened_frames_are_mostly_flat_with_few_colours():
    src = textured()
    assert flat_fraction(src) < 0.01  # camera-like noise: almost nothing is flat
    out = flatten(src, (128, 64), median=7, colours=12)
    assert out.size == (128, 64) and out.mode == "RGB"
    assert len(np.unique(np.asarray(out).reshape(-1, 3), axis=0)) <= 12
    assert flat_fraction(out) > 0.6


def test_bad_settings_are_refused():
    with pytest.raises(ValueError):
        flatten(textured(), median=4)
    with pytest.raises(ValueError):
        flatten(textured(), colours=1)


def test_cli_writes_the_first_frames_in_name_order(tmp_path):
    src, out = tmp_path / "in", tmp_path / "out"
    src.mkdir()
    for i, name in enumerate(["c.png", "a.png", "b.jpg"]):
        textured(i).save(src / name)
    assert main([str(src), str(out), "--limit", "2", "--size", "64x32"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["a.png", "b.png"]
    assert Image.open(out / "a.png").size == (64, 32)
    assert main([str(tmp_path / "empty"), str(out)]) == 1
    assert main([str(src), str(out), "--size", "64"]) == 2


def test_cli_never_replaces_frames_and_stops_on_a_bad_one(tmp_path, capsys):
    """Output == input replaced every frame by its flattened copy; a.png and a.jpg were both
    out/a.png; a corrupt frame was a traceback."""
    src = tmp_path / "in"
    src.mkdir()
    textured(0).save(src / "a.png")
    textured(1).save(src / "b.png")
    before = {p.name: p.read_bytes() for p in src.iterdir()}
    for out in (src, tmp_path / "in" / ".." / "in"):
        assert main([str(src), str(out), "--size", "64x32"]) == 2
        assert "is the input folder" in capsys.readouterr().err
    assert {p.name: p.read_bytes() for p in src.iterdir()} == before
    textured(2).save(src / "a.jpg")
    assert main([str(src), str(tmp_path / "o1"), "--size", "64x32"]) == 2
    assert "would both be written as a.png" in capsys.readouterr().err
    assert not (tmp_path / "o1").exists()
    (src / "a.jpg").unlink()
    (src / "c.png").write_bytes(b"not an image")
    assert main([str(src), str(tmp_path / "o2"), "--size", "64x32"]) == 2
    assert "cannot read the image" in capsys.readouterr().err
    assert sorted(p.name for p in (tmp_path / "o2").iterdir()) == ["a.png", "b.png"], "no half-written or hidden file"


def test_cli_never_replaces_a_picture_in_a_folder_holding_the_input(tmp_path, capsys):
    """photos/ as the output of photos/wet/ would write photos/a.png over the user's own a.png."""
    wet = tmp_path / "photos" / "wet"
    wet.mkdir(parents=True)
    textured(0).save(wet / "a.png")
    textured(1).save(tmp_path / "photos" / "a.png")
    mine = (tmp_path / "photos" / "a.png").read_bytes()
    assert main([str(wet), str(tmp_path / "photos"), "--size", "64x32"]) == 2
    assert "holds the input folder" in capsys.readouterr().err
    assert (tmp_path / "photos" / "a.png").read_bytes() == mine
    assert main([str(wet), str(tmp_path / "photos" / "new"), "--size", "64x32"]) == 0  # a new folder: fine
