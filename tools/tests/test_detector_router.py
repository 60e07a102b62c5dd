"""raindrop_tools.detector_router: the features against values counted by hand (the same map as
tests/remove/test_detector_router.cpp, so both sides compute one definition), the fit, the
file's round trip and refusals, and the committed ROUTER."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from raindrop_tools import detector_router as R

MODELS = Path(__file__).resolve().parents[2] / "models"


def lf(f):
    return math.log1p(100 * f)


def test_features_of_a_map_counted_by_hand():
    p = np.zeros((10, 20), np.float32)
    p[1:4, 1:4] = 0.9
    p[8, 1] = 0.3  # exactly float32(0.3): not above 0.3, above 0.15
    p[1:6, 10:18] = 0.2
    n = 200
    want = [lf(9 / n), lf(41 / n), lf((9 * float(np.float32(0.9)) + float(np.float32(0.3)) + 40 * float(np.float32(0.2))) / n),
            lf(50 / n), lf(2 / n * 1e4), lf(9), lf(2 / n * 1e4), lf(9), lf(1 / n * 1e4), lf(9)]
    np.testing.assert_allclose(R.features(p), want, rtol=0, atol=1e-12)


def test_parts_are_eight_connected_and_an_even_count_takes_the_middle_two():
    p = np.zeros((6, 6), np.float32)
    p[0, 0] = p[1, 1] = 0.9
    p[3:6, 3:6] = 0.9
    f = R.features(p)
    assert f[8] == pytest.approx(lf(2 / 36 * 1e4), abs=1e-12)
    assert f[9] == pytest.approx(lf(5.5), abs=1e-12)
    assert np.all(R.features(np.zeros((4, 4), np.float32)) == 0)


def test_working_copy_rounds_as_raindrop_remove():
    # Sides rounded half up, as src/remove/working_scale.cpp does (Python's round() would halve to even).
    assert R.working_copy(np.zeros((333, 1000, 3), np.uint8)).shape == (170, 512, 3)
    assert R.working_copy(np.zeros((341, 1024, 3), np.uint8)).shape == (171, 512, 3)  # 170.5 -> 171
    small = np.zeros((100, 200, 3), np.uint8)
    assert R.working_copy(small) is small  # never enlarged


def test_fit_separates_what_it_can_and_weights_what_matters():
    rng = np.random.default_rng(0)
    X = rng.normal(size=(400, R.FEATURES))
    d = X[:, 2] - 0.5 * X[:, 7]  # the alternative's gain, in dB
    router = R.fit(X, (d > 0).astype(float), np.abs(d) + 0.05, "alt")
    assert np.mean(router.prefers_alternative(X) == (d > 0)) > 0.95
    # A constant feature is harmless (its std is padded, its weight stays 0).
    X[:, 0] = 3.0
    assert np.all(np.isfinite(R.fit(X, (d > 0).astype(float), np.abs(d) + 0.05, "alt").weight))


def test_the_file_round_trips_and_a_read_only_one_is_kept(tmp_path):
    router = R.Router("compact-windshield", np.arange(10.0), np.full(10, 0.5), np.linspace(-1, 1, 10), -0.25)
    R.write_router(tmp_path / "ROUTER", router, "two\nlines")
    back = R.read_router(tmp_path / "ROUTER")
    assert back.alternative == router.alternative and back.bias == router.bias
    for k in ("mean", "std", "weight"):
        assert np.array_equal(getattr(back, k), getattr(router, k))
    (tmp_path / "ROUTER").chmod(0o444)
    with pytest.raises(PermissionError, match="read-only"):
        R.write_router(tmp_path / "ROUTER", router)


@pytest.mark.parametrize("text, why", [
    ("", "format 1"),
    ("format 1\nalternative a/b\n", "sibling"),
    ("format 1\nalternative alt\nmean 0\n", "10 finite numbers"),
    ("format 1\nformat 1\n", "twice"),
])
def test_a_damaged_file_is_refused(tmp_path, text, why):
    (tmp_path / "ROUTER").write_text(text)
    with pytest.raises(R.RouterError, match=why):
        R.read_router(tmp_path / "ROUTER")


def test_every_committed_router_reads_and_names_a_detector_folder():
    files = sorted(MODELS.glob("*/ROUTER"))
    if not files:
        pytest.skip(f"no ROUTER in {MODELS}")
    for f in files:
        router = R.read_router(f)
        assert (MODELS / router.alternative / "rdn.onnx").is_file(), f
        assert np.all(router.std > 0), f


def test_the_working_size_is_the_models_own():
    class FakeRemover:
        metadata = {"rdn": {"raindrop.working_size": "256"}}

    assert R.working_size_of(FakeRemover()) == 256
    FakeRemover.metadata = {"rdn": {}}
    assert R.working_size_of(FakeRemover()) == 512

