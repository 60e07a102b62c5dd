import json

import numpy as np
import pytest

from helpers import procedural_image
from raindrop_tools import metrics
from raindrop_tools import score_outputs as SO
from raindrop_tools.imageio import write_rgb


def make_set(tmp_path, n=2):
    data, outs = tmp_path / "set", tmp_path / "out"
    for d in (data / "rainy", data / "clean", outs):
        d.mkdir(parents=True)
    for i in range(n):
        clean = procedural_image(32, 48, i)
        clean[8:16, 8:24] = 100
        rainy = clean.copy()
        rainy[8:16, 8:24] = 160  # every damaged pixel off by the same amount
        out = clean.copy()
        out[8:12, 8:24] = rainy[8:12, 8:24]  # half the damage left
        write_rgb(data / "clean" / f"{i}.png", clean)
        write_rgb(data / "rainy" / f"{i}.png", rainy)
        write_rgb(outs / f"{i}.png", out)
    return data, outs


def test_scores_are_the_protocols_and_the_gain_their_difference(tmp_path):
    data, outs = make_set(tmp_path)
    r = SO.score(data, outs)
    assert r["images"] == 2
    from raindrop_tools.imageio import read_rgb_strict
    expect_in = np.mean([metrics.image_metrics(read_rgb_strict(data / "rainy" / f"{i}.png"),
                                               read_rgb_strict(data / "clean" / f"{i}.png"))["psnr_y"] for i in range(2)])
    assert r["mean"]["input_psnr_y"] == pytest.approx(expect_in)
    assert r["mean"]["gain_psnr_y"] == pytest.approx(r["mean"]["output_psnr_y"] - r["mean"]["input_psnr_y"])
    # Half the damaged pixels left: the squared error halves, +3.01 dB.
    assert r["mean"]["gain_psnr_y"] == pytest.approx(10 * np.log10(2), abs=0.05)


def test_cli_prints_one_line_and_writes_json(tmp_path, capsys):
    data, outs = make_set(tmp_path, 1)
    assert SO.main(["--data", str(data), "--outputs", str(outs), "--label", "x", "--json", str(tmp_path / "s.json")]) == 0
    line = capsys.readouterr().out.strip()
    assert line.startswith("x: 1 images, PSNR-Y ") and "(gain +3.0" in line
    assert json.loads((tmp_path / "s.json").read_text())["per_image"][0]["name"] == "0.png"


def test_no_matching_outputs_is_an_error(tmp_path):
    data, outs = make_set(tmp_path, 1)
    (outs / "0.png").unlink()
    with pytest.raises(SystemExit, match="no image"):
        SO.score(data, outs)


def test_split_keeps_only_that_splits_samples(tmp_path):
    data, outs = make_set(tmp_path, 3)
    rows = [{"id": str(i), "rainy": f"rainy/{i}.png", "clean": f"clean/{i}.png", "mask": f"mask/{i}.png",
             "width": 48, "height": 32, "split": "test" if i != 1 else "train"} for i in range(3)]
    (data / "manifest.jsonl").write_text("\n".join(json.dumps(r) for r in rows) + "\n")
    r = SO.score(data, outs, "test")
    assert [p["name"] for p in r["per_image"]] == ["0.png", "2.png"]
    with pytest.raises(SystemExit, match="no sample"):
        SO.score(data, outs, "val")
    (data / "manifest.jsonl").unlink()
    with pytest.raises(SystemExit, match="manifest"):
        SO.score(data, outs, "test")


def test_jpegs_are_read_upright_as_the_programs_read_them(tmp_path):
    """A JPEG whose EXIF Orientation says "turn a quarter clockwise" reads upright through the
    strict data-set reader too (OpenCV's IMREAD_UNCHANGED would ignore the tag), so that a
    user's phone pairs score against raindrop-remove's upright outputs."""
    import cv2
    from raindrop_tools.imageio import read_rgb, read_rgb_strict
    stored = procedural_image(24, 40, 3)
    ok, jpeg = cv2.imencode(".jpg", cv2.cvtColor(stored, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, 95])
    assert ok
    # APP1: "Exif\0\0", a big-endian TIFF header, one IFD entry: Orientation (0x0112), SHORT, 1, 6.
    payload = b"Exif\0\0MM\0\x2a\0\0\0\x08\0\x01\x01\x12\0\x03\0\0\0\x01\0\x06\0\0\0\0\0\0"
    app1 = b"\xff\xe1" + (len(payload) + 2).to_bytes(2, "big") + payload
    raw = jpeg.tobytes()
    (tmp_path / "side.jpg").write_bytes(raw[:2] + app1 + raw[2:])
    (tmp_path / "plain.jpg").write_bytes(raw)
    upright = read_rgb_strict(tmp_path / "side.jpg")
    assert upright.shape == (40, 24, 3)
    assert np.array_equal(upright, read_rgb(tmp_path / "side.jpg"))
    # The stored pixels turned a quarter clockwise.
    assert np.array_equal(upright, np.rot90(read_rgb_strict(tmp_path / "plain.jpg"), k=-1))


def test_pngs_are_read_as_stored_whatever_their_exif(tmp_path):
    """An eXIf chunk does not turn a PNG, in either reader, as raindrop-remove reads it."""
    from PIL import Image
    from raindrop_tools.imageio import read_rgb, read_rgb_strict
    stored = procedural_image(24, 40, 4)
    exif = Image.Exif()
    exif[0x0112] = 6
    Image.fromarray(stored).save(tmp_path / "side.png", exif=exif)
    assert Image.open(tmp_path / "side.png").getexif().get(0x0112) == 6
    assert np.array_equal(read_rgb(tmp_path / "side.png"), stored)
    assert np.array_equal(read_rgb_strict(tmp_path / "side.png"), stored)


def write_masks(tmp_path, data, n, true_rows, detected_rows):
    import cv2
    (data / "mask").mkdir(exist_ok=True)
    det = tmp_path / "det"
    det.mkdir(exist_ok=True)
    for i in range(n):
        for folder, (a, b) in ((data / "mask", true_rows), (det, detected_rows)):
            m = np.zeros((32, 48), np.uint8)
            m[a:b, 8:24] = 255
            cv2.imwrite(str(folder / f"{i}.png"), m)
    return det


def test_mask_split_tells_missed_drops_from_found_ones(tmp_path, capsys):
    """make_set damages rows 8-15 and leaves rows 8-11 in the output. A detector that marks rows
    12-19 found half the drop (the half the output repaired), missed the rest and marked four clean
    rows: all the error left lies in the missed drop, and all of the found drop's is removed."""
    data, outs = make_set(tmp_path, 2)
    det = write_masks(tmp_path, data, 2, (8, 16), (12, 20))
    ms = SO.score(data, outs, masks=det)["mask_split"]
    assert ms["recall"] == pytest.approx(0.5) and ms["precision"] == pytest.approx(0.5)
    assert ms["output_error_share"]["missed"] == pytest.approx(1.0)
    assert ms["output_error_share"]["found"] == 0.0 and ms["output_error_share"]["false"] == 0.0
    assert ms["found_error_removed"] == pytest.approx(1.0)
    assert ms["pixels"] == {"found": 2 * 4 * 16, "missed": 2 * 4 * 16, "false": 2 * 4 * 16,
                            "rest": 2 * (32 * 48 - 3 * 4 * 16)}
    # The output's summed error in the missed rows is the input's there.
    s = ms["squared_error_sums"]
    assert s["output_missed"] == pytest.approx(s["input_missed"]) and s["input_missed"] > 0
    # The detector that marks the repaired rows' complement instead: the error left is in its found drops.
    (tmp_path / "b").mkdir()
    det2 = write_masks(tmp_path / "b", data, 2, (8, 16), (8, 12))
    ms2 = SO.score(data, outs, masks=det2)["mask_split"]
    assert ms2["output_error_share"]["found"] == pytest.approx(1.0) and ms2["found_error_removed"] == pytest.approx(0.0)
    assert SO.main(["--data", str(data), "--outputs", str(outs), "--masks", str(det), "--label", "m"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[1].startswith("m: masks recall 0.500, precision 0.500") and "100% in drops missed" in lines[1]


def test_mask_split_refuses_a_missing_or_misfit_mask(tmp_path, capsys):
    import cv2
    data, outs = make_set(tmp_path, 1)
    det = write_masks(tmp_path, data, 1, (8, 16), (12, 20))
    cv2.imwrite(str(det / "0.png"), np.zeros((16, 16), np.uint8))
    assert SO.main(["--data", str(data), "--outputs", str(outs), "--masks", str(det)]) == 2
    assert "size differs" in capsys.readouterr().err
    (det / "0.png").unlink()
    assert SO.main(["--data", str(data), "--outputs", str(outs), "--masks", str(det)]) == 2
    assert "cannot read" in capsys.readouterr().err
