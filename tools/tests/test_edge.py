import numpy as np
import pytest

from helpers import procedural_image
from raindrop_tools.edge import edge_map_numpy, edge_map_torch, edge_map_window
from raindrop_tools.imageio import to_float


def test_edge_known_values():
    # One bright pixel in the middle of a black 3x3 single-channel image.
    img = np.zeros((3, 3, 1), np.float32)
    img[1, 1, 0] = 1.0
    e = edge_map_numpy(img)
    # centre: 4 neighbours differ by 1 -> 4/4; edge-adjacent pixels: one neighbour differs -> 1/4;
    # corners: no neighbour differs (their missing neighbours are themselves) -> 0.
    expected = np.array([[0, 0.25, 0], [0.25, 1.0, 0.25], [0, 0.25, 0]], np.float32)
    np.testing.assert_array_equal(e, expected)


def test_edge_sums_channels_and_replicates_border():
    img = np.zeros((1, 2, 3), np.float32)
    img[0, 1] = [0.5, 0.25, 0.125]
    e = edge_map_numpy(img)
    # each pixel has one real neighbour (left/right); up/down are replicated (0)
    np.testing.assert_array_equal(e, np.full((1, 2), (0.5 + 0.25 + 0.125) / 4, np.float32))


def test_edge_flat_and_single_pixel():
    assert not edge_map_numpy(np.full((5, 4, 3), 0.3, np.float32)).any()
    np.testing.assert_array_equal(edge_map_numpy(np.ones((1, 1, 3), np.float32)), np.zeros((1, 1), np.float32))


def test_edge_rejects_wrong_dtype():
    with pytest.raises(TypeError):
        edge_map_numpy(np.zeros((2, 2, 3), np.float64))


@pytest.mark.parametrize("shape", [(48, 64), (37, 53), (1, 1), (1, 7), (9, 1)])
def test_edge_window_equals_full_image(shape):
    h, w = shape
    img = to_float(procedural_image(h, w, 3))
    full = edge_map_numpy(img)
    rng = np.random.default_rng(0)
    for _ in range(10):
        ch, cw = int(rng.integers(1, h + 1)), int(rng.integers(1, w + 1))
        y0, x0 = int(rng.integers(0, h - ch + 1)), int(rng.integers(0, w - cw + 1))
        np.testing.assert_array_equal(edge_map_window(img, y0, x0, ch, cw), full[y0 : y0 + ch, x0 : x0 + cw])


@pytest.mark.torch
@pytest.mark.parametrize("shape", [(48, 64), (37, 53), (1, 1), (2, 3)])
def test_edge_torch_equals_numpy_bit_for_bit(shape):
    torch = pytest.importorskip("torch")
    h, w = shape
    imgs = [to_float(procedural_image(h, w, s)) for s in range(3)]
    imgs.append(np.random.default_rng(5).random((h, w, 3), dtype=np.float32))
    batch = torch.from_numpy(np.stack([i.transpose(2, 0, 1) for i in imgs]))
    got = edge_map_torch(batch).numpy()
    assert got.shape == (len(imgs), 1, h, w)
    for k, img in enumerate(imgs):
        want = edge_map_numpy(img)
        assert np.array_equal(got[k, 0], want), f"image {k}: max diff {np.abs(got[k, 0] - want).max()}"
