"""raindrop_tools.realism on generated data (no torch, no ../shared)."""

import json
import math

import numpy as np
import pytest

from helpers import procedural_image, write_dataset
from raindrop_tools import realism as RM
from realpairs_helpers import write_pairs


def _disc(h, w, cy, cx, r):
    yy, xx = np.mgrid[0:h, 0:w]
    return (yy - cy) ** 2 + (xx - cx) ** 2 < r * r


def test_image_stats_of_known_drops():
    rng = np.random.default_rng(0)
    clean = np.clip(rng.normal(100, 10, (80, 120, 3)), 0, 255).astype(np.uint8)
    mask = np.zeros((80, 120), np.uint8)
    disc = _disc(80, 120, 30, 30, 10)
    ellipse = ((np.mgrid[0:80, 0:120][0] - 50) / 4.0) ** 2 + ((np.mgrid[0:80, 0:120][1] - 90) / 16.0) ** 2 < 1
    mask[disc | ellipse] = 255
    rainy = clean.copy()
    rainy[mask > 0] = np.clip(clean[mask > 0].astype(int) + 20, 0, 255)
    st = RM.image_stats(rainy, clean, mask)
    assert st["drops"] == 2
    assert st["coverage"] == pytest.approx((mask > 0).mean())
    assert sorted(st["diameter_px"]) == pytest.approx([16, 20], rel=0.05)  # ellipse 4x16: area of a 16 px disc
    assert st["diameter_frac"][0] == pytest.approx(st["diameter_px"][0] / 120)
    ecc = sorted(st["eccentricity"])
    assert ecc[0] < 0.2  # the disc
    assert ecc[1] == pytest.approx(math.sqrt(1 - (4 / 16) ** 2), abs=0.03)  # the 4:16 ellipse
    assert st["brightness"] == pytest.approx(20, abs=0.6)
    assert st["sharpness"] == pytest.approx(1.0, abs=0.05)  # same texture, brighter
    assert st["veil"] == 1.0  # equal outside the mask
    # a blurred, hazier drop image: lower sharpness, wider edges, veil < 1
    blurred = rainy.copy()
    import cv2

    soft = cv2.GaussianBlur(rainy, (0, 0), 2.0)
    blurred[mask > 0] = soft[mask > 0]
    hazy = (0.9 * blurred.astype(np.float32) + 10).astype(np.uint8)
    st2 = RM.image_stats(hazy, clean, mask)
    assert st2["sharpness"] < 0.5 * st["sharpness"]
    assert st2["veil"] == pytest.approx(0.9, abs=0.03)
    # edge width grows with the blur of a step edge
    step = np.zeros((60, 60, 3), np.uint8)
    step[:, 30:] = 200
    m = np.zeros((60, 60), np.uint8)
    m[:, 30:] = 255
    widths = [RM.image_stats(cv2.GaussianBlur(step, (0, 0), s) if s else step, step, m)["edge_width"]
              for s in (0, 1.5, 3.0)]
    assert widths[0] < widths[1] < widths[2]
    assert widths[2] == pytest.approx(2.5 * 3.0, rel=0.25)


def test_solidity_is_one_for_convex_drops_and_falls_for_lobed_ones():
    h, w = 120, 200
    mask = np.zeros((h, w), np.uint8)
    mask[_disc(h, w, 30, 30, 15)] = 255  # convex
    # an L of a 40x10 and a 10x30 bar (700 px); through the boundary pixels' centres its outline
    # is 39x9 + 30x9 and its hull adds the 30x30 triangle in the corner
    mask[60:100, 20:30] = 255
    mask[90:100, 30:60] = 255
    # two overlapping discs: a merged drop, with a waist
    mask[_disc(h, w, 40, 120, 14) | _disc(h, w, 40, 145, 14)] = 255
    # a tiny drop: counted, no solidity
    mask[100:104, 150:153] = 255
    st = RM.image_stats(np.zeros((h, w, 3), np.uint8), np.zeros((h, w, 3), np.uint8), mask)
    assert st["drops"] == 4
    assert len(st["solidity"]) == 3
    areas, _, sol = RM.drop_components(mask)
    by_area = dict(zip(areas, sol))
    disc = by_area[float((_disc(h, w, 30, 30, 15)).sum())]
    assert disc > 0.97
    ell = 39 * 9 + 30 * 9
    assert by_area[400.0 + 300.0] == pytest.approx(ell / (ell + 0.5 * 30 * 30), rel=2e-3)  # corners: half a pixel
    merged = [v for a, v in by_area.items() if a > 1000][0]
    assert 0.85 < merged < 0.97
    assert math.isnan(by_area[12.0])


def test_highlights_counts_the_clipped_pixels_drops_keep():
    clean = np.full((40, 100, 3), 90, np.uint8)
    clean[:20] = 255  # a clipped sky over the top half: 50% clipped
    mask = np.zeros((40, 100), np.uint8)
    mask[:20, :50] = 255
    # drops that darken the sky they cover keep half of its clipped pixels
    darkened = clean.copy()
    darkened[:20, :50] = 200
    assert RM.image_stats(darkened, clean, mask)["highlights"] == pytest.approx(0.5)
    # drops that keep it clipped (the light behind them was far above full scale), and a bloom
    # that spreads it into the street below
    assert RM.image_stats(clean, clean, mask)["highlights"] == 1.0
    bloom = clean.copy()
    bloom[20:30] = (250, 255, 251)
    assert RM.image_stats(bloom, clean, mask)["highlights"] == pytest.approx(1.5)
    # a frame with (almost) nothing clipped says nothing
    dark = np.full((40, 100, 3), 90, np.uint8)
    dark[0, :39] = 255  # under MIN_CLIPPED of the frame
    assert math.isnan(RM.image_stats(dark, dark, mask)["highlights"])


def test_no_drops_gives_nan_not_an_error():
    img = procedural_image(32, 32, 1)
    st = RM.image_stats(img, img, np.zeros((32, 32), np.uint8))
    assert st["drops"] == 0 and st["coverage"] == 0 and math.isnan(st["brightness"]) and st["veil"] == 1.0


def test_wasserstein_and_distances():
    a = np.arange(100.0)
    assert RM.wasserstein1(a, a) == 0
    assert RM.wasserstein1(a, a + 5) == pytest.approx(5, abs=1e-9)


def test_classifier_tells_different_sets_apart_and_not_equal_ones():
    rng = np.random.default_rng(1)
    smooth = [procedural_image(64, 64, i) for i in range(40)]
    noisy = [np.clip(procedural_image(64, 64, 100 + i).astype(int) + rng.normal(0, 25, (64, 64, 3)), 0, 255)
             .astype(np.uint8) for i in range(40)]
    groups_a = [f"a{i // 4}" for i in range(40)]
    groups_b = [f"b{i // 4}" for i in range(40)]
    easy = RM.classifier_accuracy(smooth, noisy, groups_a, groups_b, folds=5)
    assert easy["accuracy"] > 0.9
    same = RM.classifier_accuracy(smooth[:20] + noisy[:20], smooth[20:] + noisy[20:], groups_a, groups_b, folds=5)
    assert 0.2 < same["accuracy"] < 0.8
    few = RM.classifier_accuracy(smooth[:4], noisy[:4], ["g"] * 4, ["h"] * 4, folds=5)
    assert math.isnan(few["accuracy"])


def test_cli_on_generated_real_pairs_and_rendered_set(tmp_path, capsys):
    pairs = write_pairs(tmp_path / "pairs", groups=6, per_group=2, h=80, w=96, veil=6.0)
    rendered = write_dataset(tmp_path / "rendered", n=12, h=80, w=96, seed=3)
    out = tmp_path / "r.json"
    assert RM.main(["--real-pairs", str(pairs), "--split", "all", "--rendered", str(rendered), "--json", str(out),
                    "--crops-per-image", "3", "--folds", "3"]) == 0
    text = capsys.readouterr().out
    assert "### real (pairs, all): 12 images" in text and "### rendered (rendered, rough masks): 12 images" in text
    assert "| drop diameter / image width |" in text and "classifier accuracy" in text
    r = json.loads(out.read_text())
    real, rend = r["sets"]
    assert real["kind"] == "real" and rend["kind"] == "rendered"
    assert real["brightness"]["median"] > 5  # the generated drops and the +6 offset brighten
    # rough masks leave a drop's faint rim (under the threshold) outside: a veil of 1 all but exactly
    assert rend["veil"]["median"] == pytest.approx(1.0, abs=1e-3)
    (sc,) = r["scores"]
    assert set(sc["distance"]) >= set(RM.DISTANCE_STATS) | {"mean"}
    assert 0.0 <= sc["classifier"]["accuracy"] <= 1.0 and sc["classifier"]["crops"] == [36, 36]
    # with the renderer's own masks, rainy == clean outside them: exactly 1
    assert RM.main(["--real-pairs", str(pairs), "--rendered", str(rendered), "--rendered-masks", "own",
                    "--json", str(out), "--crops-per-image", "3", "--folds", "3"]) == 0
    assert "### rendered (rendered, own masks): 12 images" in capsys.readouterr().out
    assert json.loads(out.read_text())["sets"][1]["veil"]["median"] == 1.0
    # the default: the train split only (the test split is for evaluating removal)
    assert RM.main(["--real-pairs", str(pairs)]) == 0
    assert "### real (pairs, train): 6 images" in capsys.readouterr().out


def test_rendered_sets_measured_with_rough_masks_see_only_the_visible_drop(tmp_path, capsys):
    """A rendered mask twice as large as the visible drop: with its own mask the drop's
    coverage is the mask's; with rough masks (the CLI's default, as for real pairs) it is the
    visible part only, as it would be for a real pair with the same images."""
    import cv2

    from raindrop_tools.imageio import write_rgb

    root = tmp_path / "set"
    clean = np.full((80, 96, 3), 90, np.uint8)
    rainy = clean.copy()
    rainy[20:40, 20:40] = 170  # the visible drop: 400 px
    mask = np.zeros((80, 96), np.uint8)
    mask[10:50, 10:50] = 255  # the renderer's mask: 1600 px, with a faint halo that does not show
    write_dataset(root, n=1, h=80, w=96, seed=3)
    sample = RM.read_manifest(root)[0]
    write_rgb(sample.rainy, rainy)
    write_rgb(sample.clean, clean)
    cv2.imwrite(str(sample.mask), mask)
    rng = np.random.default_rng(0)
    own = RM.collect_rendered(root, rng, 1).summary()
    rough = RM.collect_rendered(root, rng, 1, rough=RM.RP.MaskParams()).summary()
    assert own["coverage"]["median"] == pytest.approx(1600 / (80 * 96))
    # the visible 20x20 square, widened by the 5x5 blur before the threshold: about 24x24
    assert 400 < rough["coverage"]["median"] * 80 * 96 < 24 * 24
    assert rough["brightness"]["median"] == pytest.approx(80.0, abs=1.0)
    assert own["brightness"]["median"] < rough["brightness"]["median"]


def test_real_photos_score_rendered_sets_with_the_classifier_alone(tmp_path, capsys):
    """--real-photos: photographs without clean images. The rendered set's own rainy images,
    given as photographs, cannot be told apart from it; noisy photographs can. Photographs
    are brought to 512 px wide first (here: already are)."""
    from raindrop_tools.imageio import write_rgb

    rendered = write_dataset(tmp_path / "rendered", n=20, h=128, w=512, seed=3)
    same = tmp_path / "same"
    same.mkdir()
    for s in RM.read_manifest(rendered):
        (same / s.rainy.name).write_bytes(s.rainy.read_bytes())
    noisy = tmp_path / "noisy"
    noisy.mkdir()
    rng = np.random.default_rng(5)
    for i in range(10):
        img = procedural_image(256, 1024, 50 + i).astype(int) + rng.normal(0, 30, (256, 1024, 3))
        write_rgb(noisy / f"photo {i}.jpg", np.clip(img, 0, 255).astype(np.uint8))
    out = tmp_path / "r.json"
    accuracy = {}
    for name in ("same", "noisy"):
        assert RM.main(["--real-photos", str(tmp_path / name), "--rendered", str(rendered), "--folds", "5",
                        "--json", str(out)]) == 0
        text = capsys.readouterr().out
        assert f"### Classifier against real photographs ({name}: " in text
        r = json.loads(out.read_text())
        assert r["scores"] == [] and len(r["photo_scores"]) == 1
        accuracy[name] = r["photo_scores"][0]["classifier"]["accuracy"]
    assert accuracy["noisy"] > 0.9
    assert 0.2 < accuracy["same"] < 0.8
    # the photographs at 1024 wide were halved: crops of the halved image, 16 per photograph
    crops, groups, n = RM.collect_photos(noisy, np.random.default_rng(0), 16)
    assert n == 10 and len(crops) == 160 and len(set(groups)) == 10
    # neither real set, or photographs without rendered sets: a usage error
    for argv in (["--rendered", str(rendered)], ["--real-photos", str(noisy)]):
        with pytest.raises(SystemExit) as e:
            RM.main(argv)
        assert e.value.code == 2
    empty = tmp_path / "empty"
    empty.mkdir()
    assert RM.main(["--real-photos", str(empty), "--rendered", str(rendered)]) == 2
    assert "no images" in capsys.readouterr().err


@pytest.mark.parametrize("argv", [["--limit", "-1"], ["--limit", "0"], ["--folds", "1"], ["--folds", "0"],
                                  ["--photo-crops", "0"], ["--limit", "x"]])
def test_counts_below_their_minimum_are_usage_errors(tmp_path, argv, capsys):
    """--limit -1 dropped the last image silently; --folds 0 divided by zero."""
    with pytest.raises(SystemExit) as e:
        RM.main(["--real-pairs", str(tmp_path), *argv])
    assert e.value.code == 2
    assert argv[0] in capsys.readouterr().err


def test_the_street_alone_control_tells_the_drops_share(tmp_path):
    """Photographs that are the rendered set's own rainy images: its rainy crops cannot be told
    from them, its clean crops (the same streets without drops) can, so the drops' effect is
    negative (they bring the renders closer). Photographs that are its clean images: the other
    way round, the drops give the renders away (effect positive)."""
    from raindrop_tools.imageio import write_rgb

    rendered = write_dataset(tmp_path / "rendered", n=24, h=128, w=512, seed=3)
    # Drops every crop sees: a dense grid of small dark beads over each clean image.
    for s in RM.read_manifest(rendered):
        rainy = RM.read_rgb_strict(s.clean).copy()
        for y in range(2, rainy.shape[0] - 3, 9):
            for x in range(2, rainy.shape[1] - 3, 9):
                rainy[y : y + 3, x : x + 3] //= 4
        write_rgb(s.rainy, rainy)
    effect = {}
    for kind in ("rainy", "clean"):
        photos = tmp_path / kind
        photos.mkdir()
        for s in RM.read_manifest(rendered):
            write_rgb(photos / f"{s.id}.png", RM.read_rgb_strict(getattr(s, kind)))
        out = tmp_path / f"{kind}.json"
        assert RM.main(["--real-photos", str(photos), "--rendered", str(rendered), "--photo-crops", "8",
                        "--crops-per-image", "8", "--json", str(out)]) == 0
        sc = json.loads(out.read_text())["photo_scores"][0]
        assert sc["drops_effect"] == pytest.approx(sc["classifier"]["accuracy"] - sc["street"]["accuracy"])
        effect[kind] = sc["drops_effect"]
    assert effect["rainy"] < -0.1
    assert effect["clean"] > 0.1


def test_paired_sets_are_cropped_at_the_same_places_in_any_order(tmp_path):
    """--paired: every rendered set draws its crops from one stream, so two copies of a set score
    exactly alike, and a set scores the same first or second in the call (without it, each set's
    places follow its position, which moved a set's score by about 0.01 between calls)."""
    import shutil

    from raindrop_tools.imageio import write_rgb

    rendered = write_dataset(tmp_path / "a", n=16, h=128, w=512, seed=3)
    shutil.copytree(rendered, tmp_path / "b")
    photos = tmp_path / "photos"
    photos.mkdir()
    for i, s in enumerate(RM.read_manifest(rendered)):
        write_rgb(photos / f"p{i}.png", RM.read_rgb_strict(s.clean))
    def scores(order, paired):
        out = tmp_path / "r.json"
        argv = ["--real-photos", str(photos), "--photo-crops", "4", "--seed", "3", "--json", str(out)]
        for name in order:
            argv += ["--rendered", str(tmp_path / name)]
        assert RM.main(argv + (["--paired"] if paired else [])) == 0
        return [sc["classifier"]["accuracy"] for sc in json.loads(out.read_text())["photo_scores"]]
    a_first = scores(["a", "b"], True)
    assert a_first[0] == a_first[1]
    assert scores(["b", "a"], True) == a_first
    assert scores(["a"], True)[0] == a_first[0]
