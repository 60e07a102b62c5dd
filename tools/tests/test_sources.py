"""Several training sources with weights: config, sampler, per-source checks (no torch)."""

import numpy as np
import pytest

from helpers import CONFIGS
from raindrop_tools.config import ConfigError, config_from_dict, data_sources, dump_config, load_config
from raindrop_tools.data import (DatasetError, MultiSourceDataset, RaindropDataset, WeightedStepBatchSampler, photometric_jitter,
                                 source_counts)
from raindrop_tools.edge import edge_map_numpy
from raindrop_tools.imageio import to_float


def test_multi_source_config_parsing(tmp_path):
    cfg = config_from_dict(
        {
            "data": {
                "sources": [
                    {"path": "data/train", "weight": 0.7},
                    {"path": "data/real-train", "weight": 0.3, "split": "train", "check_outside_mask": False},
                    {"path": "data/more", "weight": 1, "split": ["a", "b"]},
                ]
            }
        }
    )
    s = data_sources(cfg)
    assert [x.path for x in s] == ["data/train", "data/real-train", "data/more"]
    assert [x.weight for x in s] == [0.7, 0.3, 1.0]
    assert [x.split for x in s] == [None, ["train"], ["a", "b"]]  # None: data.splits (null = all)
    assert [x.check_outside_mask for x in s] == [True, False, True]
    import yaml

    assert config_from_dict(yaml.safe_load(dump_config(cfg))) == cfg
    # the old single key keeps working: one source, weight 1
    old = config_from_dict({"data": {"train": "x", "splits": ["train"], "check_outside_mask": False}})
    assert old.data.sources is None
    (one,) = data_sources(old)
    assert (one.path, one.weight, one.split, one.check_outside_mask) == ("x", 1.0, ["train"], False)
    # bad weights, unknown keys, both forms at once
    with pytest.raises(ConfigError, match=r"sources\[0\].weight"):
        config_from_dict({"data": {"sources": [{"path": "a", "weight": 0}]}})
    with pytest.raises(ConfigError, match=r"data.sources\[0\].wieght"):
        config_from_dict({"data": {"sources": [{"path": "a", "wieght": 1}]}})
    f = tmp_path / "c.yaml"
    f.write_text("data:\n  sources: [{path: a}]\n")
    assert load_config(f, resolve_paths=False).data.sources[0].path == "a"
    with pytest.raises(ConfigError, match="both given"):
        load_config(f, [("data.train", "b")])
    f.write_text("data:\n  train: t\n  sources: [{path: a}]\n")
    with pytest.raises(ConfigError, match="both given"):
        load_config(f)
    # an override of data.sources replaces the file's data.train; relative paths are resolved like it
    cfg = load_config(CONFIGS / "smoke.yaml", [("data.sources", [{"path": "rel/a"}, {"path": "/abs/b"}])])
    assert cfg.data.sources[0].path.endswith("/rel/a") and cfg.data.sources[0].path.startswith("/")
    assert cfg.data.sources[1].path == "/abs/b"


@pytest.mark.parametrize("weights", [[0.7, 0.3], [1, 1, 2], [0.05, 0.95]])
def test_source_counts_match_the_weights(weights):
    B = 32
    counts = np.array([source_counts(weights, B, 5, 1, step) for step in range(2000)])
    assert (counts.sum(axis=1) == B).all()
    w = np.asarray(weights, float) / sum(weights)
    assert np.abs(counts.mean(axis=0) - B * w).max() < 0.05
    # every batch is within one crop of its quota
    assert (np.abs(counts - B * w) < 1).all()


def test_weighted_sampler_is_a_pure_function_of_seed_stage_step():
    sizes = [[(40, 50)] * 7, [(64, 64)] * 3]
    a = WeightedStepBatchSampler(sizes, [0.7, 0.3], 32, 8, seed=3, stage=1, total_steps=40)
    all_a = list(a)
    b = WeightedStepBatchSampler(sizes, [0.7, 0.3], 32, 8, seed=3, stage=1, total_steps=40, start_step=25)
    assert list(b) == all_a[25:]  # resume sees the same batches
    assert list(WeightedStepBatchSampler(sizes, [0.7, 0.3], 32, 8, 3, 1, 40)) == all_a
    assert list(WeightedStepBatchSampler(sizes, [0.7, 0.3], 32, 8, 4, 1, 40)) != all_a  # the seed matters
    assert list(WeightedStepBatchSampler(sizes, [0.7, 0.3], 32, 8, 3, 2, 40)) != all_a  # the stage too
    keys = [k for batch in all_a for k in batch]
    share = np.mean([k[0] == 0 for k in keys])
    assert share == pytest.approx(0.7, abs=0.03)  # 320 crops; source_counts is tested exactly above
    for s, i, y0, x0, flip in keys:
        h, w = sizes[s][i]
        assert 0 <= y0 <= h - 32 and 0 <= x0 <= w - 32 and isinstance(flip, bool)
    # within a source, samples are used about evenly (without replacement per epoch; a step
    # that draws fewer crops than the source reserves skips the rest of its positions)
    for s in (0, 1):
        used = np.bincount([k[1] for k in keys if k[0] == s], minlength=len(sizes[s]))
        assert used.min() > 0 and used.max() <= 1.5 * used.min()


def test_the_outside_mask_check_is_per_source(tmp_path):
    from helpers import write_dataset
    from realpairs_helpers import write_pairs

    from raindrop_tools import realpairs as RP

    rendered = write_dataset(tmp_path / "rendered", n=4, h=48, w=64)
    real = tmp_path / "real"
    RP.prepare(write_pairs(tmp_path / "pairs", groups=2, per_group=2), real)
    with pytest.raises(DatasetError, match="outside the mask"):
        RaindropDataset(real, crop=32, splits=["train", "test"], check_outside_mask=True)
    # both splits named: held-out real pairs are trained on only where a config says so (data.py)
    cfg = config_from_dict(
        {"data": {"crop": 32, "sources": [{"path": str(rendered)},
                                           {"path": str(real), "check_outside_mask": False, "split": ["train", "test"]}]}}
    )
    parts = [RaindropDataset(s.path, crop=32, splits=s.split, check_outside_mask=s.check_outside_mask)
             for s in data_sources(cfg)]
    ds = MultiSourceDataset(parts)
    assert len(ds) == 8 and ds.names == ["rendered", "real"]
    item = ds[(1, 0, 3, 4, True)]
    assert item["id"].startswith("real/") and item["rainy"].shape == (3, 32, 32)
    assert ds[(0, 2, 0, 0, False)]["id"] == "rendered/" + parts[0].samples[2].id


def test_sensor_noise_is_one_field_on_rainy_and_clean(tiny_dataset):
    quiet = RaindropDataset(tiny_dataset, crop=32, cache=False)
    noisy = RaindropDataset(tiny_dataset, crop=32, cache=False, sensor_noise_levels=8.0)
    stds = []
    for i in range(len(quiet)):
        key = (i, 5, 9, bool(i % 2))
        q, n = quiet[key], noisy[key]
        again = noisy[key]
        assert np.array_equal(n["rainy"], again["rainy"]) and np.array_equal(n["clean"], again["clean"])  # same key, same noise
        assert np.array_equal(n["mask"], q["mask"])
        for k in ("rainy", "clean"):
            assert np.allclose(n[k] * 255, np.round(n[k] * 255), atol=1e-3)  # 8-bit steps, as a camera writes
        # The same field on both: where rainy == clean before, they are still equal after
        # (clipping at 0 and 1 acts on both alike there).
        same = np.all(q["rainy"] == q["clean"], axis=0)
        assert same.any()
        assert np.array_equal(n["rainy"][:, same], n["clean"][:, same])
        inside = (q["clean"] > 0.1) & (q["clean"] < 0.9)
        stds.append(float(np.std((n["clean"] - q["clean"])[inside]) * 255))
    assert max(stds) > 1.0  # noise was added (sigma drawn from [0, 8] levels per crop)
    assert max(stds) < 8.5
    assert len(set(round(s, 3) for s in stds)) > 1  # its strength varies from crop to crop


def test_sensor_noise_levels_are_checked():
    with pytest.raises(ConfigError, match="sensor_noise_levels"):
        config_from_dict({"data": {"sources": [{"path": "x", "sensor_noise_levels": 100}]}})


def test_photometric_jitter_is_one_light_change_on_rainy_and_clean(tiny_dataset):
    plain = RaindropDataset(tiny_dataset, crop=32, cache=False)
    jittered = RaindropDataset(tiny_dataset, crop=32, cache=False, photometric=0.3)
    means = []
    for i in range(len(plain)):
        key = (i, 5, 9, bool(i % 2))
        p, j = plain[key], jittered[key]
        again = jittered[key]
        assert all(np.array_equal(j[k], again[k]) for k in ("rainy", "clean", "edge"))  # same key, same draw
        assert np.array_equal(j["mask"], p["mask"])
        # One change of light on both: where rainy == clean before, they are equal after, and
        # the change is the closed form exp-gain then gamma, pixel by pixel.
        same = np.all(p["rainy"] == p["clean"], axis=0)
        assert same.any() and np.array_equal(j["rainy"][:, same], j["clean"][:, same])
        apply = photometric_jitter(0.3, key)
        expected = apply(p["clean"].transpose(1, 2, 0)).transpose(2, 0, 1)
        np.testing.assert_allclose(j["clean"], expected, atol=1e-6)
        # the edge map is of the jittered full frame (the image the network sees)
        rainy_full = to_float(jittered.load(i)[0])
        full_edge = edge_map_numpy(apply(rainy_full))
        e = full_edge[5:37, 9:41]
        np.testing.assert_array_equal(j["edge"][0], e[:, ::-1] if key[3] else e)
        means.append(float(j["clean"].mean() - p["clean"].mean()))
    assert max(means) > 0.01 and min(means) < -0.01  # brighter and darker crops both occur


def test_photometric_zero_is_the_identity_and_strength_is_checked(tiny_dataset):
    a = RaindropDataset(tiny_dataset, crop=32)[(1, 2, 3, False)]
    b = RaindropDataset(tiny_dataset, crop=32, photometric=0.0)[(1, 2, 3, False)]
    assert all(np.array_equal(a[k], b[k]) for k in ("rainy", "clean", "mask", "edge"))
    with pytest.raises(ConfigError, match="photometric"):
        config_from_dict({"data": {"sources": [{"path": "x", "photometric": 2}]}})
    with pytest.raises(ValueError, match="photometric"):
        RaindropDataset(tiny_dataset, crop=32, photometric=float("nan"))
    with pytest.raises(ValueError, match="photometric"):
        RaindropDataset(tiny_dataset, crop=32, photometric=float("inf"))


def test_detection_weight_is_per_source_and_checked(tiny_dataset):
    cfg = config_from_dict({"data": {"sources": [{"path": "a"}, {"path": "b", "detection_weight": 0}]}})
    assert [s.detection_weight for s in data_sources(cfg)] == [1.0, 0.0]
    with pytest.raises(ConfigError, match="detection_weight"):
        config_from_dict({"data": {"sources": [{"path": "x", "detection_weight": -1}]}})
    item = RaindropDataset(tiny_dataset, crop=32, cache=False, detection_weight=0.25)[0]
    assert item["detection_weight"] == np.float32(0.25)


def test_a_source_can_be_trained_at_a_smaller_scale(tiny_dataset):
    """data.sources[].scale: crops come from an area-downscaled copy (as raindrop-remove makes
    its coarse copies), the mask downscaled alike and kept binary; too small is refused."""
    import cv2

    from raindrop_tools.data import downscale_sample, scaled_length

    full = RaindropDataset(tiny_dataset, crop=16, cache=False)
    third = RaindropDataset(tiny_dataset, crop=16, cache=False, scale=1 / 3)
    cached = RaindropDataset(tiny_dataset, crop=16, cache=True, scale=1 / 3)
    (h, w), (h3, w3) = full.sizes[0], third.sizes[0]
    assert (h3, w3) == (scaled_length(h, 1 / 3), scaled_length(w, 1 / 3))
    assert scaled_length(5, 0.5) == 3 and scaled_length(1, 0.1) == 1  # std::lround, at least 1
    rainy, clean, mask = full.load(0)
    r3, c3, m3 = third.load(0)
    assert r3.shape == (h3, w3, 3) and m3.shape == (h3, w3)
    assert np.array_equal(r3, cv2.resize(rainy, (w3, h3), interpolation=cv2.INTER_AREA))
    assert set(np.unique(m3)) <= {0, 255}
    # the mask keeps its share of the frame (within the rounding of its outline)
    assert abs((m3 > 0).mean() - (mask > 0).mean()) < 0.05
    for a, b in zip(cached.load(0), (r3, c3, m3)):
        assert np.array_equal(a, b)
    item = third[(0, 0, 0, False)]
    assert item["rainy"].shape == (3, 16, 16)
    # a half-covered block of 2x2 pixels stays, a quarter-covered one goes
    m = np.zeros((4, 4), np.uint8)
    m[0:2, 0] = 255
    m[2, 2] = 255
    z = np.zeros((4, 4, 3), np.uint8)
    assert downscale_sample(z, z, m, 0.5)[2].tolist() == [[255, 0], [0, 0]]
    with pytest.raises(DatasetError, match="smaller than the"):
        RaindropDataset(tiny_dataset, crop=min(h, w) // 2, cache=False, scale=0.25)
    with pytest.raises(ConfigError, match=r"sources\[0\].scale"):
        config_from_dict({"data": {"sources": [{"path": "x", "scale": 0}]}})
    assert [x.scale for x in data_sources(config_from_dict({"data": {"sources": [{"path": "x", "scale": 0.5}]}}))] == [0.5]
