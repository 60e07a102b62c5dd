import cv2
import numpy as np
import pytest

from raindrop_tools.morphology import dilate_numpy, ellipse_kernel

pytestmark = pytest.mark.torch
torch = pytest.importorskip("torch")

from raindrop_tools.morphology import Dilation  # noqa: E402


def _masks():
    rng = np.random.default_rng(0)
    yield "sparse 37x53", (rng.random((37, 53)) > 0.97).astype(np.uint8)
    yield "dense 40x40", (rng.random((40, 40)) > 0.5).astype(np.uint8)
    m = np.zeros((20, 30), np.uint8)
    m[0, 0] = m[19, 29] = m[0, 29] = m[10, 15] = 1  # corners: the border must not spread
    yield "corners", m
    yield "1x1 on", np.ones((1, 1), np.uint8)
    yield "1x5", np.array([[0, 1, 0, 0, 0]], np.uint8)
    yield "empty", np.zeros((8, 9), np.uint8)


@pytest.mark.parametrize("k", [1, 2, 3, 4, 5, 7])
def test_dilation_layer_equals_cv2(k):
    layer = Dilation(k)
    for name, m in _masks():
        want = cv2.dilate(m, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k)))
        got = layer(torch.from_numpy(m).float()[None, None])[0, 0].numpy()
        assert set(np.unique(got)) <= {0.0, 1.0}
        assert np.array_equal(got.astype(np.uint8), want), f"k={k}, {name}"
        assert np.array_equal(dilate_numpy(m, k), want)


def test_dilation_layer_batches_and_channels_independently():
    rng = np.random.default_rng(1)
    m = (rng.random((3, 2, 16, 17)) > 0.9).astype(np.float32)
    got = Dilation(5)(torch.from_numpy(m)).numpy()
    for n in range(3):
        for c in range(2):
            want = cv2.dilate(m[n, c].astype(np.uint8), ellipse_kernel(5))
            assert np.array_equal(got[n, c].astype(np.uint8), want)


def test_dilation_layer_has_no_parameters_and_grows_a_point():
    layer = Dilation(7)
    assert list(layer.parameters()) == []
    m = torch.zeros(1, 1, 9, 9)
    m[0, 0, 4, 4] = 1
    out = layer(m)[0, 0].numpy().astype(np.uint8)
    np.testing.assert_array_equal(out[1:8, 1:8], ellipse_kernel(7))
    assert out.sum() == ellipse_kernel(7).sum()


def test_ellipse_kernel_rejects_bad_size():
    with pytest.raises(ValueError):
        ellipse_kernel(0)
