"""A second detector as a head on the main RDN (shared_detector.py, train_head.py): the main
graph keeps its map bit for bit, the head's map is bit for bit its standalone graph's and
PyTorch's to float rounding, the RDN reads back from the merged graph and the head's own graph
is refused as an RDN, and the reference pipeline reads the merged graph's first output."""
import json
import shutil

import cv2
import numpy as np
import onnx
import pytest

pytestmark = pytest.mark.torch
torch = pytest.importorskip("torch")

from helpers import FIXTURE_MODELS, REPO, quiet_session  # noqa: E402
from raindrop_tools import contract as C  # noqa: E402
from raindrop_tools import inner_padding, phase_conv, phase_final_conv  # noqa: E402
from raindrop_tools import onnx_weights as OW  # noqa: E402
from raindrop_tools import shared_detector as SD  # noqa: E402
from raindrop_tools import train_head  # noqa: E402
from raindrop_tools.networks import AlternativeHead, rdn_taps  # noqa: E402
from raindrop_tools.reference import RaindropRemover  # noqa: E402


def _current_folder(tmp_path, name):
    """The fixture folder with the graph rewrites every export now makes."""
    folder = tmp_path / name
    shutil.copytree(FIXTURE_MODELS, folder)
    phase_conv.rewrite_folder(folder)
    inner_padding.rewrite_folder(folder)
    phase_final_conv.rewrite_folder(folder)
    return folder


def _random_head(folder, path, seed=0):
    cfg = SD.rdn_config(folder)
    torch.manual_seed(seed)
    head = AlternativeHead(cfg.width, cfg.expanded, mid=6, up=4)
    with torch.no_grad():
        head.out.weight.normal_(0, 0.5)  # it starts at zero: the RDN's own map
        head.out.bias.fill_(0.3)
    torch.save(head.state_dict(), path)
    return head


def _int8_folder_quantized_from(folder, source):
    """An int8 folder's record of the fp32 folder it was quantized from (all --reuse-reconstruction
    reads before it refuses)."""
    folder.mkdir()
    (folder / "export.json").write_text(json.dumps({"quantized_from": str(source)}))
    return folder


def _outputs(path, image):
    sess = quiet_session(path)
    return sess.run(None, {"image": image})


def test_the_main_map_keeps_its_bits_and_the_head_is_its_own_graph(tmp_path):
    main, like = _current_folder(tmp_path, "main"), _current_folder(tmp_path, "like")
    before = (main / "rdn.onnx").read_bytes()
    head = _random_head(main, tmp_path / "head.pt")
    out = tmp_path / "the-head"
    report = SD.write(main, like, out, tmp_path / "head.pt")
    assert report["parity_max_abs_diff"] < 1e-4

    merged = onnx.load(str(main / "rdn.onnx"))
    assert [o.name for o in merged.graph.output] == [C.OUTPUTS["rdn"], C.ALTERNATIVE_OUTPUT]
    meta = {p.key: p.value for p in merged.metadata_props}
    assert meta[C.META_ALTERNATIVE_DETECTOR] == "the-head"
    alone_meta = {p.key: p.value for p in onnx.load(str(out / "rdn.onnx")).metadata_props}
    assert alone_meta[C.META_CONFIG] == "the-head" and C.META_ALTERNATIVE_DETECTOR not in alone_meta

    old = tmp_path / "old.onnx"
    old.write_bytes(before)
    rng = np.random.default_rng(3)
    for h, w in ((30, 44), (31, 45)):
        x = rng.random((1, 3, h, w), dtype=np.float32)
        (p_old,) = _outputs(old, x)
        p0, p1 = _outputs(main / "rdn.onnx", x)
        (p_alone,) = _outputs(out / "rdn.onnx", x)
        assert np.array_equal(p0, p_old)
        assert np.array_equal(p1, p_alone)
        assert not np.allclose(p1, p0, atol=1e-3), "the head changes the map"
        rdn = SD.load_rdn(like)
        with torch.no_grad():
            want = torch.sigmoid(head.eval()(*rdn_taps(rdn, torch.from_numpy(x)))).numpy()
        assert np.abs(p1 - want).max() < 1e-4

    # Each folder's files and export.json agree (the main one's rdn.onnx digest updated).
    for folder in (main, out):
        info = json.loads((folder / "export.json").read_text())
        for name, entry in info["files"].items():
            assert (folder / name).stat().st_size == entry["bytes"], (folder, name)
    # The head folder's 3RN and RFN are the like folder's, under its own configuration name.
    for name in ("rrn.onnx", "rfn.onnx"):
        meta = {p.key: p.value for p in onnx.load(str(out / name)).metadata_props}
        assert meta[C.META_CONFIG] == "the-head"


def test_the_rdn_reads_back_from_the_merged_graph_and_the_head_is_no_rdn(tmp_path):
    main, like = _current_folder(tmp_path, "main"), _current_folder(tmp_path, "like")
    _random_head(main, tmp_path / "head.pt")
    SD.write(main, like, tmp_path / "h", tmp_path / "head.pt")
    assert OW.check_against_onnxruntime(SD.load_rdn(main), "rdn", main / "rdn.onnx") < 1e-4
    with pytest.raises(OW.OnnxWeightsError, match="head on another model's RDN"):
        SD.load_rdn(tmp_path / "h")
    with pytest.raises(SD.SharedDetectorError, match="has a head already"):
        SD.write(main, like, tmp_path / "h2", tmp_path / "head.pt")


def test_a_spliced_head_reads_back_as_the_head_that_was_spliced(tmp_path):
    # load_head (train_head's init from a model folder) recovers the saved head's weights from
    # the phase-split, folded graph, and refuses folders without a head beside the RDN's map.
    main, like = _current_folder(tmp_path, "main"), _current_folder(tmp_path, "like")
    with pytest.raises(SD.SharedDetectorError, match="no alternative_mask_prob"):
        SD.load_head(main)
    head = _random_head(main, tmp_path / "head.pt", seed=4)
    SD.write(main, like, tmp_path / "h", tmp_path / "head.pt")
    back = SD.load_head(main)
    assert (back.mix.out_channels, back.up.out_channels) == (6, 4)
    for name, want in head.state_dict().items():
        assert torch.allclose(back.state_dict()[name], want, atol=1e-6), name
    with pytest.raises(SD.SharedDetectorError, match="no alternative_mask_prob"):
        SD.load_head(tmp_path / "h")  # the head's own folder: its RDN is not there to read


def test_a_head_fine_tune_starts_from_a_model_folders_head(tmp_path):
    main, like = _current_folder(tmp_path, "main"), _current_folder(tmp_path, "like")
    _random_head(main, tmp_path / "head.pt", seed=5)
    SD.write(main, like, tmp_path / "h", tmp_path / "head.pt")
    cfg = train_head.HeadConfig(name="t", main=str(main), teacher=str(like), sources=[], init=str(tmp_path / "nowhere"))
    with pytest.raises(SystemExit, match="no such file or folder"):
        train_head.train(cfg, tmp_path / "run")
    cfg.init, cfg.mid = str(main), 7  # another width than the folder's head
    with pytest.raises(SystemExit, match="not a head of this configuration"):
        train_head.train(cfg, tmp_path / "run")


def test_a_head_replaced_is_the_new_head_spliced_onto_the_graph_without_one(tmp_path):
    # Splicing head A, then replacing it by head B (--replace) gives the graph that splicing B
    # onto the original gives, byte for byte; the stripped graph is the original's, node for node.
    main, like = _current_folder(tmp_path, "main"), _current_folder(tmp_path, "like")
    original = onnx.load(str(main / "rdn.onnx"))
    fresh = _current_folder(tmp_path, "fresh")
    _random_head(main, tmp_path / "a.pt", seed=0)
    _random_head(main, tmp_path / "b.pt", seed=1)
    SD.write(main, like, tmp_path / "h", tmp_path / "a.pt")
    stripped = SD.strip_head(onnx.load(str(main / "rdn.onnx")))
    assert [n.SerializeToString() for n in stripped.graph.node] == [n.SerializeToString() for n in original.graph.node]
    assert [o.name for o in stripped.graph.output] == [o.name for o in original.graph.output]
    SD.write(main, like, tmp_path / "h", tmp_path / "b.pt", replace=True)
    SD.write(fresh, like, tmp_path / "other" / "h", tmp_path / "b.pt")  # the same folder name: the same metadata
    assert (main / "rdn.onnx").read_bytes() == (fresh / "rdn.onnx").read_bytes()
    assert (tmp_path / "h" / "rdn.onnx").read_bytes() == (tmp_path / "other" / "h" / "rdn.onnx").read_bytes()


def test_the_reference_pipeline_reads_the_first_map(tmp_path):
    main, like = _current_folder(tmp_path, "main"), _current_folder(tmp_path, "like")
    plain = RaindropRemover(main)
    image = (np.random.default_rng(5).random((40, 56, 3)) * 255).astype(np.uint8)
    before = plain.remove(image, keep_intermediates=True)
    _random_head(main, tmp_path / "head.pt")
    SD.write(main, like, tmp_path / "h", tmp_path / "head.pt")
    after = RaindropRemover(main).remove(image, keep_intermediates=True)
    assert np.array_equal(before.prob, after.prob)
    assert np.array_equal(before.output, after.output)


def test_the_distillation_loss_is_zero_at_the_teacher_and_grows_away_from_it():
    p = torch.rand(2, 1, 8, 8) * 0.98 + 0.01
    logits = torch.log(p / (1 - p))
    assert abs(train_head.distillation_loss(logits, p).item()) < 1e-5
    assert train_head.distillation_loss(logits + 0.5, p).item() > 0.01


def test_the_committed_head_config_reads():
    cfg = train_head.read_config(REPO / "tools" / "configs" / "compact-windshield-head.yaml")
    assert cfg.teacher == "models/compact-windshield" and cfg.main == "models/compact-multiscale"
    assert any(s.split == "train" for s in cfg.sources), "the real pairs' train split, never the test split"
    assert all(s.split != "test" for s in cfg.sources)


def test_a_head_config_is_read_as_the_training_configs_are(tmp_path):
    """train_head.read_config takes config.py's reader: unknown keys named, numbers coerced
    (YAML reads 1e-3, without a dot, as a string)."""
    path = tmp_path / "head.yaml"
    path.write_text("name: h\nmain: a\nteacher: b\nlr: 1e-3\nsources: [{path: p, weight: 1}]\n")
    assert train_head.read_config(path).lr == 1e-3
    path.write_text("name: h\nmain: a\nteacher: b\nsources: [{path: p, weight: 1, wieght: 2}]\n")
    with pytest.raises(SystemExit, match=r"sources\[0\]\.wieght"):
        train_head.read_config(path)


def test_the_text_negatives_config_reads_and_a_share_without_sources_is_refused(tmp_path):
    cfg = train_head.read_config(REPO / "tools" / "configs" / "compact-windshield-head-text.yaml")
    assert cfg.text_share == 0.2 and cfg.init.endswith("compact-windshield-head/head.pt")
    assert [s.images for s in cfg.text_sources] == ["clean"] * 3
    path = tmp_path / "head.yaml"
    path.write_text("name: h\nmain: a\nteacher: b\ntext_share: 0.2\nsources: [{path: p, weight: 1}]\n")
    with pytest.raises(SystemExit, match="text_share needs text_sources"):
        train_head.read_config(path)
    path.write_text("name: h\nmain: a\nteacher: b\nsources: [{path: p, weight: 1}]\n"
                    "text_sources: [{path: p, weight: 1, images: clean}]\n")
    with pytest.raises(SystemExit, match="text_share is 0"):
        train_head.read_config(path)


def test_text_negative_crops_have_lettering_and_no_drop_as_their_target(tmp_path):
    # A batch from a pool of flat grey images: the crops flagged negative carry lettering (they
    # differ from the grey), the others are the grey itself.
    import random

    cfg = train_head.HeadConfig(name="h", main="a", teacher="b", sources=[], batch_size=32, crop=64,
                                coarse_share=0.0, text_share=0.5)
    grey = [np.full((96, 128, 3), 128, np.uint8)]
    x, negative, truth = train_head.crops([grey], [1.0], cfg, random.Random(0), [grey], [1.0])
    assert x.shape == (32, 3, 64, 64) and 4 < int(negative.sum()) < 28
    flat = (x - 128 / 255).abs().flatten(1).amax(1) < 1e-6
    assert torch.equal(flat, ~negative)
    assert truth.isnan().all(), "no source gives masks: every target is the teacher's"


def test_mask_targets_move_with_their_crops(tmp_path):
    """A source with targets: mask carries its masks through every crop, coarse scale and flip:
    with the mask a copy of the image's red channel, each crop's target is its red channel."""
    import random

    rng = np.random.default_rng(2)
    data = tmp_path / "set"
    for d in ("rainy", "mask"):
        (data / d).mkdir(parents=True)
    rows = []
    for i in range(3):
        im = cv2.GaussianBlur((rng.random((90, 120, 3)) * 255).astype(np.uint8), (0, 0), 3)
        cv2.imwrite(str(data / "rainy" / f"{i}.png"), im[:, :, ::-1])
        cv2.imwrite(str(data / "mask" / f"{i}.png"), im[:, :, 0])
        rows.append(json.dumps({"rainy": f"rainy/{i}.png", "mask": f"mask/{i}.png"}))
    (data / "manifest.jsonl").write_text("\n".join(rows) + "\n")
    source = train_head.Source(path=str(data), weight=1.0, targets="mask")
    pool = train_head.load_images(source, 10, random.Random(0))
    assert len(pool) == 3 and pool[0].shape == (90, 120, 4)
    cfg = train_head.HeadConfig(name="h", main="a", teacher="b", sources=[source], batch_size=24, crop=64,
                                coarse_share=0.5)
    x, negative, truth = train_head.crops([pool], [1.0], cfg, random.Random(1))
    assert not negative.any() and not truth.isnan().any()
    assert torch.equal(truth[:, 0], x[:, 0])
    (data / "mask" / "1.png").unlink()
    with pytest.raises(SystemExit, match="no mask of its size"):
        train_head.load_images(source, 10, random.Random(0))


def test_mask_targets_are_refused_where_they_cannot_apply(tmp_path):
    path = tmp_path / "head.yaml"
    path.write_text("name: h\nmain: a\nteacher: b\nsources: [{path: p, weight: 1, targets: masks}]\n")
    with pytest.raises(SystemExit, match="teacher or mask"):
        train_head.read_config(path)
    path.write_text("name: h\nmain: a\nteacher: b\nsources: [{path: p, weight: 1, targets: mask, images: clean}]\n")
    with pytest.raises(SystemExit, match="need the rainy images"):
        train_head.read_config(path)


def test_a_read_only_graph_is_kept(tmp_path, capsys):
    from raindrop_tools.read_only import ReadOnlyFileError

    main, like = _current_folder(tmp_path, "main"), _current_folder(tmp_path, "like")
    _random_head(main, tmp_path / "head.pt")
    graph = main / "rdn.onnx"
    before = graph.read_bytes()
    graph.chmod(0o444)
    with pytest.raises(ReadOnlyFileError):
        SD.write(main, like, tmp_path / "h", tmp_path / "head.pt")
    assert graph.read_bytes() == before and not (tmp_path / "h").exists(), "refused before anything was written"
    assert SD.main(["--main", str(main), "--head", str(tmp_path / "head.pt"), "--like", str(like), "--out",
                    str(tmp_path / "h")]) == 1
    assert "read-only" in capsys.readouterr().err


def test_a_head_that_is_not_one_for_the_main_detector_is_a_one_line_error(tmp_path, capsys):
    # a head of other widths gave a traceback; a train checkpoint gave "error: 'mix.weight'"
    main, like = _current_folder(tmp_path, "main"), _current_folder(tmp_path, "like")
    cfg = SD.rdn_config(main)
    torch.save(AlternativeHead(cfg.width + 2, cfg.expanded, mid=6, up=4).state_dict(), tmp_path / "wide.pt")
    torch.save({"model": {"w": torch.zeros(1)}, "step": 3}, tmp_path / "ckpt.pt")
    (tmp_path / "text.pt").write_text("not a file torch reads")
    torch.save({"mix.weight": torch.zeros(3), "up.weight": torch.zeros(3)}, tmp_path / "flat.pt")
    before = (main / "rdn.onnx").read_bytes()
    for name, why in (("wide.pt", "not a head for"), ("ckpt.pt", "not a head"), ("text.pt", "not a readable head file"), ("flat.pt", "not a head")):
        assert SD.main(["--main", str(main), "--head", str(tmp_path / name), "--like", str(like), "--out",
                        str(tmp_path / "h")]) == 1
        err = capsys.readouterr().err
        assert why in err and len(err.strip().splitlines()) == 1, err
    assert (main / "rdn.onnx").read_bytes() == before and not (tmp_path / "h").exists()


def test_quantized_with_its_head_the_main_map_is_the_plain_int8_one_and_the_head_map_its_folders(tmp_path, tiny_dataset,
                                                                                                  capsys):
    """The int8 default's head: quantizing the merged graph gives the same first map as
    quantizing the graph without the head, and the same second map as quantizing the head's own
    folder; the metadata names that int8 folder, and the tool says when it is missing."""
    from raindrop_tools import quantize as Q

    main, like = _current_folder(tmp_path, "main"), _current_folder(tmp_path, "like")
    Q.quantize_models(main, tiny_dataset, tmp_path / "plain-int8", count=3)
    _random_head(main, tmp_path / "head.pt")
    SD.write(main, like, tmp_path / "h", tmp_path / "head.pt")
    assert Q.main(["--models", str(main), "--data", str(tiny_dataset), "--out", str(tmp_path / "main-int8"),
                   "--count", "3"]) == 0
    assert "h-int8, which does not exist yet" in capsys.readouterr().err
    # The fixture before the graph rewrites has other initializers than the head folder's 3RN.
    with pytest.raises(Q.QuantizeError, match="other weights"):
        Q.quantize_models(tmp_path / "h", tiny_dataset, tmp_path / "h-int8", count=3,
                          reuse_dir=_int8_folder_quantized_from(tmp_path / "unrewritten-int8", FIXTURE_MODELS))
    Q.quantize_models(tmp_path / "h", tiny_dataset, tmp_path / "h-int8", count=3, reuse_dir=tmp_path / "main-int8")
    assert Q.alternative_head_folder(tmp_path / "main-int8") == tmp_path / "h-int8"
    assert Q.alternative_head_folder(tmp_path / "h-int8") is None

    rng = np.random.default_rng(4)
    for h, w in ((30, 44), (48, 64)):
        x = rng.random((1, 3, h, w), dtype=np.float32)
        (plain,) = _outputs(tmp_path / "plain-int8" / "rdn.onnx", x)
        p0, p1 = _outputs(tmp_path / "main-int8" / "rdn.onnx", x)
        (alone,) = _outputs(tmp_path / "h-int8" / "rdn.onnx", x)
        assert np.array_equal(p0, plain)
        assert np.array_equal(p1, alone)
        assert not np.array_equal(p0, p1)
    # The head's folder reconstructs with the main int8 folder's own 3RN and RFN (--reuse-reconstruction).
    for name in ("rrn.onnx", "rfn.onnx"):
        a, b = (onnx.load(str(tmp_path / f / name)) for f in ("main-int8", "h-int8"))
        assert a.graph == b.graph
        meta = {p.key: p.value for p in b.metadata_props}
        fp32 = {p.key: p.value for p in onnx.load(str(tmp_path / "h" / name)).metadata_props}
        assert meta == {**fp32, C.META_CONFIG: "h-int8", "raindrop.quantization": meta["raindrop.quantization"]}
    assert "taken from" in json.loads((tmp_path / "h-int8" / "export.json").read_text())["quantization"]["reconstruction"]
    info = json.loads((tmp_path / "main-int8" / "export.json").read_text())
    assert info["alternative_head"]["folder"] == "h-int8"


def test_visible_drops_keeps_the_drops_the_image_shows():
    """min_contrast: of two drops, the one whose mean luma change is under the bar is no target;
    at 0 the mask is kept as it is."""
    clean = np.full((40, 80, 3), 100, np.uint8)
    rainy = clean.copy()
    mask = np.zeros((40, 80), np.uint8)
    cv2.circle(mask, (20, 20), 8, 255, -1)
    cv2.circle(mask, (60, 20), 8, 255, -1)
    rainy[:, 40:][mask[:, 40:] > 0] += 10  # the right drop changes the image by 10 levels, the left not at all
    kept = train_head.visible_drops(mask, rainy, clean, 4.0)
    assert not kept[:, :40].any() and np.array_equal(kept[:, 40:], mask[:, 40:])
    assert train_head.visible_drops(mask, rainy, clean, 11.0).max() == 0
    assert train_head.visible_drops(mask, rainy, clean, 0.0) is mask
