"""raindrop_tools.surround_fill, the reference's twin of raindrop-remove's fill of small drops from
their surround: closed forms and bounds here; agreement with the C++ pipeline is
tests/remove/test_remove_parity.cpp's Parity.SurroundFill."""

import cv2
import numpy as np
import pytest

from raindrop_tools.surround_fill import choose_parts, fill_small_drops_from_surround, push_pull_fill


def test_a_flat_colour_fills_any_hole_with_itself():
    for h, w in [(48, 64), (23, 37), (9, 1)]:
        rgb = np.empty((3, h, w), np.float32)
        rgb[0], rgb[1], rgb[2] = 0.2, 0.55, 0.9
        hole = np.zeros((h, w), np.uint8)
        hole[h // 3 : h // 2 + 1, w // 3 : w // 2 + 1] = 1
        hole[0, 0] = 1
        out = push_pull_fill(rgb, hole)
        np.testing.assert_allclose(out, rgb, atol=1e-5)


def test_filled_values_lie_within_the_known_pixels_range():
    rng = np.random.default_rng(5)
    for _ in range(30):
        h, w = rng.integers(1, 60, size=2)
        rgb = rng.random((3, h, w), dtype=np.float32)
        hole = (rng.random((h, w)) < 0.4).astype(np.uint8)
        out = push_pull_fill(rgb, hole)
        if hole.all():
            assert out is None
            continue
        known = hole == 0
        np.testing.assert_array_equal(out[:, known], rgb[:, known])
        for c in range(3):
            assert out[c][~known].min(initial=1.0) >= rgb[c][known].min() - 1e-5
            assert out[c][~known].max(initial=0.0) <= rgb[c][known].max() + 1e-5


def test_only_small_parts_over_smooth_surroundings_are_filled():
    h, w = 120, 240
    rng = np.random.default_rng(3)
    rgb = np.full((3, h, w), 0.6, np.float32)
    rgb[:, :, w // 2 :] = rng.random((h, w // 2), dtype=np.float32)[None]
    yy, xx = np.mgrid[0:h, 0:w]
    mask = np.zeros((h, w), np.uint8)
    mask[(yy - 30) ** 2 + (xx - 30) ** 2 <= 36] = 1  # small, flat surround
    mask[(yy - 30) ** 2 + (xx - 180) ** 2 <= 36] = 1  # small, textured surround
    mask[(yy - 85) ** 2 + (xx - 50) ** 2 <= 400] = 1  # large, flat surround
    _, chosen = choose_parts(mask, rgb, 150, 4.0)
    assert len(chosen) == 1 and chosen[0][1] < 40
    ihat = np.full((3, h, w), 2.0, np.float32)
    assert fill_small_drops_from_surround(rgb, mask, 150, 4.0, ihat) == 1
    small = (yy - 30) ** 2 + (xx - 30) ** 2 <= 36
    np.testing.assert_allclose(ihat[:, small], 0.6, atol=1e-5)
    assert (ihat[:, ~small] == 2.0).all()
    assert fill_small_drops_from_surround(rgb, mask, 0, 4.0, ihat) == 0


def _rim_scene():
    """A disk the detector found with a dark ring 2 px wide around it (grey 0.6 elsewhere), and
    another found disk touching a dark pole that runs the frame's height (test_surround_fill.cpp's
    RimScene)."""
    h, w = 60, 120
    rgb = np.full((3, h, w), 0.6, np.float32)
    mask = np.zeros((h, w), np.uint8)
    cv2.circle(mask, (30, 30), 6, 1, cv2.FILLED)
    ring = np.zeros((h, w), np.uint8)
    cv2.circle(ring, (30, 30), 8, 1, cv2.FILLED)
    ring[mask != 0] = 0
    cv2.circle(mask, (90, 30), 5, 1, cv2.FILLED)
    pole = np.zeros((h, w), np.uint8)
    pole[:, 96:98] = 1
    pole[mask != 0] = 0
    rgb[:, (ring != 0) | (pole != 0)] = 0.1
    return rgb, mask, ring.astype(bool), pole.astype(bool)


@pytest.mark.parametrize("rim", [0, 1, 2, 3, 4])
def test_a_rim_that_ends_joins_its_part_and_a_pole_that_goes_on_does_not(rim):
    rgb, mask, ring, pole = _rim_scene()
    before = mask.copy()
    ihat = np.full_like(rgb, 0.25)
    assert fill_small_drops_from_surround(rgb, mask, 150, 4.0, ihat, rim) == 2
    expected = (before != 0) | (ring if rim >= 2 else False)
    np.testing.assert_array_equal(mask != 0, expected)  # the ring joins from 2 steps on, the pole never
    assert not (mask.astype(bool) & pole).any()
    left = np.zeros_like(expected)
    left[:, :60] = True
    inside = ihat[:, expected & left]
    if rim >= 2:
        np.testing.assert_allclose(inside, 0.6, atol=1e-5)  # drop and rim filled with the grey around them
    else:
        assert inside.min() < 0.5  # the ring's dark bleeds into the drop's fill
    np.testing.assert_array_equal(ihat[:, ~expected], 0.25)
