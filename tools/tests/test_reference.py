"""The reference pipeline (CONTRACTS.md section 2, steps 1-7). Most tests run without torch,
on the committed fixture graphs (fixtures/models-smoke) or on stub networks."""

import json
import subprocess
import sys

import cv2
import numpy as np
import pytest

from helpers import FIXTURE_MODELS, procedural_image
from raindrop_tools.edge import edge_map_numpy
from raindrop_tools.imageio import to_float, to_uint8
from raindrop_tools.morphology import dilate_numpy
from raindrop_tools.reference import ModelError, RaindropRemover, main


class _Stub:
    """Stands in for an onnxruntime session: records its feeds, returns fn(feeds)."""

    def __init__(self, fn):
        self.fn, self.feeds = fn, []

    def run(self, _outputs, feeds):
        self.feeds.append(feeds)
        return [self.fn(feeds)]


def _stub_remover(rdn, rrn, rfn, pad_multiple=1, threshold=0.5, dilation=1):
    r = object.__new__(RaindropRemover)
    r.sessions = {"rdn": _Stub(rdn), "rrn": _Stub(rrn), "rfn": _Stub(rfn)}
    r.pad_multiple, r.threshold, r.dilation = pad_multiple, threshold, dilation
    return r


def test_pipeline_arithmetic_with_stub_networks():
    img = procedural_image(6, 7, 1)
    R = to_float(img).transpose(2, 0, 1)[None]
    P = np.zeros((1, 1, 6, 7), np.float32)
    P[0, 0, 2, 3] = 0.75
    P[0, 0, 4, 1] = np.float32(0.5)  # exactly the threshold: not in the mask (strictly greater)
    P[0, 0, 0, 6] = np.nextafter(np.float32(0.5), np.float32(1))  # just above: in the mask
    recon = np.full((1, 3, 6, 7), 1.7, np.float32)  # outside [0, 1]: clamped to 1
    recon[:, 1] = -0.3  # clamped to 0
    r = _stub_remover(lambda f: P, lambda f: recon, lambda f: f["blend"] * 2 - 0.25, dilation=3)
    res = r.remove(img, keep_intermediates=True)
    m0 = (P[0, 0] > 0.5).astype(np.uint8)
    assert m0.sum() == 2 and m0[0, 6] == 1 and m0[4, 1] == 0
    M = cv2.dilate(m0, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3)))
    np.testing.assert_array_equal(res.mask, M)
    # what each network received
    np.testing.assert_array_equal(r.sessions["rdn"].feeds[0]["image"], R)
    np.testing.assert_array_equal(r.sessions["rrn"].feeds[0]["edge"][0, 0], edge_map_numpy(to_float(img)))
    ihat = np.clip(recon, 0, 1)
    B = np.where(M[None, None] > 0, ihat, R)
    np.testing.assert_array_equal(r.sessions["rfn"].feeds[0]["blend"], B)
    want = to_uint8(np.clip(B * 2 - 0.25, 0, 1)[0].transpose(1, 2, 0))
    np.testing.assert_array_equal(res.output, want)
    assert res.output.dtype == np.uint8 and res.output.shape == img.shape


def test_rounding_is_half_up_after_clamping():
    x = np.array([-1.0, 0.0, 0.5 / 255, 1.49 / 255, 1.5 / 255, 254.5 / 255, 1.0, 3.0], np.float32)
    np.testing.assert_array_equal(to_uint8(x), [0, 0, 1, 1, 2, 255, 255, 255])


def test_padding_to_pad_multiple_and_crop_back():
    img = procedural_image(5, 7, 2)
    seen = {}

    def rdn(f):
        seen["shape"] = f["image"].shape
        return np.zeros((1, 1) + f["image"].shape[2:], np.float32)

    r = _stub_remover(rdn, lambda f: f["image"], lambda f: f["blend"], pad_multiple=4)
    res = r.remove(img)
    assert seen["shape"] == (1, 3, 8, 8)
    edge = r.sessions["rrn"].feeds[0]["edge"][0, 0]
    e = edge_map_numpy(to_float(img))  # on the unpadded image, then replicate-padded
    np.testing.assert_array_equal(edge, np.pad(e, ((0, 3), (0, 1)), mode="edge"))
    np.testing.assert_array_equal(res.output, img)  # identity networks, empty mask


@pytest.fixture(scope="module")
def fixture_remover():
    return RaindropRemover(FIXTURE_MODELS, threads=1)


def test_fixture_models_metadata(fixture_remover):
    assert fixture_remover.config == "smoke"
    # The graphs say 1; the pipeline pads to even sizes anyway (the stride-2 body).
    assert fixture_remover.pad_multiple == 2
    assert fixture_remover.threshold == 0.2 and fixture_remover.dilation == 3


@pytest.mark.parametrize("size", [(1, 1), (2, 3), (37, 53), (64, 96)])
def test_fixture_models_any_size(fixture_remover, size):
    img = procedural_image(*size, 5)
    res = fixture_remover.remove(img, keep_intermediates=True)
    assert res.output.shape == img.shape and res.output.dtype == np.uint8
    assert res.mask.shape == size and set(np.unique(res.mask)) <= {0, 1}
    assert res.prob.shape == size and 0 <= res.prob.min() and res.prob.max() <= 1
    R = to_float(img)
    outside = res.mask == 0
    np.testing.assert_array_equal(res.blend[outside], R[outside])
    np.testing.assert_array_equal(res.blend[~outside], res.reconstruction[~outside])
    # steps 3-4 from the probabilities
    m = dilate_numpy((res.prob > np.float32(0.2)).astype(np.uint8), 3)
    # The dilation runs on the mask padded to even sizes; a padded row or column (odd sizes)
    # can reach one pixel (k = 3) into the image's last row or column.
    h, w = size[0] - size[0] % 2, size[1] - size[1] % 2
    np.testing.assert_array_equal(res.mask[:h, :w], m[:h, :w])
    again = fixture_remover.remove(img)
    np.testing.assert_array_equal(again.output, res.output)


def test_fixture_models_threshold_and_dilation_options(fixture_remover):
    img = procedural_image(48, 64, 9)
    base = fixture_remover.remove(img, dilation=1)
    dilated = fixture_remover.remove(img, dilation=5)
    assert base.mask.sum() > 0
    assert dilated.mask.sum() > base.mask.sum()
    assert np.all(dilated.mask >= base.mask)
    assert fixture_remover.remove(img, threshold=0.9999).mask.sum() == 0


def test_cli_writes_image_and_mask(tmp_path):
    img = procedural_image(37, 53, 4)
    src = tmp_path / "in.png"
    cv2.imwrite(str(src), cv2.cvtColor(img, cv2.COLOR_RGB2BGR))
    out, mask = tmp_path / "out.png", tmp_path / "m.png"
    assert main([str(src), str(out), "--models", str(FIXTURE_MODELS), "--mask", str(mask), "--threads", "1"]) == 0
    got = cv2.cvtColor(cv2.imread(str(out), cv2.IMREAD_UNCHANGED), cv2.COLOR_BGR2RGB)
    want = RaindropRemover(FIXTURE_MODELS, threads=1).remove(img)
    np.testing.assert_array_equal(got, want.output)
    m = cv2.imread(str(mask), cv2.IMREAD_UNCHANGED)
    assert m.shape == (37, 53) and set(np.unique(m)) <= {0, 255}
    np.testing.assert_array_equal(m, want.mask * 255)


def test_cli_as_a_module_with_options(tmp_path, fixture_remover):
    img = procedural_image(20, 30, 4)
    src, out, mask = tmp_path / "in.png", tmp_path / "out.png", tmp_path / "m.png"
    cv2.imwrite(str(src), cv2.cvtColor(img, cv2.COLOR_RGB2BGR))
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "raindrop_tools.reference",
            str(src),
            str(out),
            "--models",
            str(FIXTURE_MODELS),
            "--threshold",
            "0.3",
            "--dilation",
            "1",
            "--mask",
            str(mask),
            "-v",
            "--threads",
            "1",
        ],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr
    assert "20" in r.stdout and "ms" in r.stdout
    assert cv2.imread(str(out)).shape == (20, 30, 3)
    # The options reach the pipeline: the files are the library's result with the same
    # non-default threshold and dilation, which differs from the models' defaults (0.2, 3).
    want = fixture_remover.remove(img, threshold=0.3, dilation=1)
    default = fixture_remover.remove(img)
    assert not np.array_equal(want.mask, default.mask)
    assert not np.array_equal(want.output, default.output)
    got = cv2.cvtColor(cv2.imread(str(out), cv2.IMREAD_UNCHANGED), cv2.COLOR_BGR2RGB)
    np.testing.assert_array_equal(got, want.output)
    np.testing.assert_array_equal(cv2.imread(str(mask), cv2.IMREAD_UNCHANGED), want.mask * 255)


def test_errors_are_reported(tmp_path, capsys):
    assert main([str(tmp_path / "missing.png"), str(tmp_path / "o.png"), "--models", str(FIXTURE_MODELS)]) == 2
    assert "cannot read image" in capsys.readouterr().err
    assert main([str(tmp_path / "x.png"), str(tmp_path / "o.png"), "--models", str(tmp_path)]) == 2
    assert "rdn.onnx: missing" in capsys.readouterr().err
    # The input as the output (replaced), the output as the mask (the mask replaced it), by any
    # name; a dilation the program refuses too.
    src = tmp_path / "in.png"
    cv2.imwrite(str(src), procedural_image(48, 64, 1)[..., ::-1])
    before = src.read_bytes()
    (tmp_path / "link.png").symlink_to(src)
    for args, why in (([str(src), str(src)], "is the input and an output"),
                      ([str(src), str(tmp_path / "link.png")], "is the input and an output"),
                      ([str(src), str(tmp_path / "o.png"), "--mask", str(tmp_path / "o.png")], "both the output and the mask"),
                      ([str(src), str(tmp_path / "o.png"), "--dilation", "100000"], "--dilation must be 1 to 1023")):
        assert main([*args, "--models", str(FIXTURE_MODELS)]) == 2
        assert why in capsys.readouterr().err
    assert src.read_bytes() == before and not (tmp_path / "o.png").exists()


def test_refuses_mixed_configurations(tmp_path):
    import shutil

    for f in ("rdn.onnx", "rrn.onnx", "rfn.onnx"):
        shutil.copy(FIXTURE_MODELS / f, tmp_path / f)
    shutil.copy(FIXTURE_MODELS / "rdn.onnx", tmp_path / "rfn.onnx")  # wrong graph under rfn's name
    with pytest.raises(ModelError, match="rfn.onnx"):
        RaindropRemover(tmp_path)


def test_fixture_export_info_matches_files():
    import hashlib

    info = json.loads((FIXTURE_MODELS / "export.json").read_text())
    for f, d in info["files"].items():
        assert hashlib.sha256((FIXTURE_MODELS / f).read_bytes()).hexdigest() == d["sha256"]


@pytest.mark.torch
def test_reference_matches_a_torch_pipeline_on_the_smoke_export(smoke_run):
    """The reference pipeline on the exported graphs against the same steps written in torch
    on the trained networks: the check the C++ port must pass (within 1/255)."""
    import torch

    from raindrop_tools import checkpoint as ckpt
    from raindrop_tools.edge import edge_map_torch
    from raindrop_tools.export import load_run
    from raindrop_tools.morphology import Dilation

    cfg, nets, _ = load_run(smoke_run["run"])
    remover = RaindropRemover(smoke_run["models"], threads=1)
    assert remover.threshold == cfg.pipeline.threshold and remover.dilation == cfg.pipeline.dilation
    assert ckpt.latest_checkpoint(smoke_run["run"]).stage == 2
    for size, seed in [((37, 53), 1), ((48, 64), 2), ((1, 1), 3)]:
        img = procedural_image(*size, seed)
        res = remover.remove(img, keep_intermediates=True)
        h, w = size
        with torch.no_grad():
            R0 = torch.from_numpy(to_float(img).transpose(2, 0, 1).copy())[None]
            # The contract pads to even sizes (replicate); the edge map is of the unpadded image.
            pad = lambda x: torch.nn.functional.pad(x, (0, w % 2, 0, h % 2), mode="replicate")
            R = pad(R0)
            P = torch.sigmoid(nets["rdn"](R))
            M = Dilation(cfg.pipeline.dilation)((P > cfg.pipeline.threshold).float())
            ihat = nets["rrn"](R, pad(edge_map_torch(R0))).clamp(0, 1)
            B = M * ihat + (1 - M) * R
            out = nets["rfn"](B).clamp(0, 1)[0].numpy().transpose(1, 2, 0)[:h, :w]
            M = M[:, :, :h, :w]
        want = to_uint8(out)
        diff = np.abs(res.output.astype(int) - want.astype(int))
        assert diff.max() <= 1, f"{size}: max diff {diff.max()} levels"
        assert np.mean(M[0, 0].numpy() != res.mask) < 0.01
