"""The test helpers themselves: where the real-image folder is looked for (no torch)."""

import cv2
import numpy as np

import helpers
from helpers import DEFAULT_SHARED_DATA, SHARED_DATA_ENV, real_frames, shared_data_dir, shared_data_missing


def test_shared_data_follows_raindrop_shared_data(monkeypatch, tmp_path):
    """ctest passes RAINDROP_SHARED_DATA (tests/CMakeLists.txt); the helper used to ignore it
    and always looked in ../shared/data."""
    root = tmp_path / "my-real-images"
    photo = root / "real-raindrop" / "a.png"
    photo.parent.mkdir(parents=True)
    assert cv2.imwrite(str(photo), np.zeros((8, 12, 3), np.uint8))
    monkeypatch.setenv(SHARED_DATA_ENV, str(root))
    assert shared_data_dir() == root
    assert real_frames() == [photo]


def test_shared_data_default_when_unset_or_empty(monkeypatch):
    monkeypatch.delenv(SHARED_DATA_ENV, raising=False)
    assert shared_data_dir() == DEFAULT_SHARED_DATA == helpers.REPO.parent / "shared" / "data"
    monkeypatch.setenv(SHARED_DATA_ENV, "")
    assert shared_data_dir() == DEFAULT_SHARED_DATA


def test_missing_shared_data_gives_no_frames_and_a_clear_skip_message(monkeypatch, tmp_path):
    nowhere = tmp_path / "nowhere"
    monkeypatch.setenv(SHARED_DATA_ENV, str(nowhere))
    assert real_frames() == []
    message = shared_data_missing()
    assert f"{SHARED_DATA_ENV}={nowhere} not found" in message and "skipped" in message
    nowhere.mkdir()  # present but without any real frame
    assert real_frames() == []
    assert "has no PNG" in shared_data_missing()
