"""ONNX export: graph contract (CONTRACTS.md section 2) and parity with PyTorch."""

import hashlib
import json
import os

import numpy as np
import pytest

pytestmark = pytest.mark.torch
torch = pytest.importorskip("torch")
onnx = pytest.importorskip("onnx")
import onnxruntime as ort  # noqa: E402

from helpers import CONFIGS, load_small_rgb, procedural_image, real_frames, shared_data_missing  # noqa: E402
from raindrop_tools import contract as C  # noqa: E402
from raindrop_tools.config import load_config  # noqa: E402
from raindrop_tools.edge import edge_map_numpy  # noqa: E402
from raindrop_tools.export import export_networks  # noqa: E402
from raindrop_tools.imageio import to_float  # noqa: E402
from raindrop_tools.networks import build_networks  # noqa: E402
from raindrop_tools.phase_final_conv import folded_final_convs  # noqa: E402

TOLERANCE = 1e-4


def _nchw(img_u8):
    return torch.from_numpy(to_float(img_u8).transpose(2, 0, 1).copy())[None]


def _edge(img_u8):
    return torch.from_numpy(edge_map_numpy(to_float(img_u8)))[None, None]


def _calibrate(nets, images):
    """Give batch norm realistic running statistics (fresh ones are mean 0, variance 1, which
    would make the check too easy) by running the networks in training mode on images."""
    with torch.no_grad():
        for name, net in nets.items():
            for m in net.modules():
                if isinstance(m, torch.nn.BatchNorm2d):
                    m.reset_running_stats()
                    m.momentum = None  # cumulative average
            net.train()
            for img in images:
                x = _nchw(img)
                if name == "rrn":
                    net(x, _edge(img))
                else:
                    net(x)
            net.eval()


@pytest.fixture(scope="module", params=["paper", "compact"])
def exported(request, tmp_path_factory):
    cfg = load_config(CONFIGS / f"{request.param}.yaml", resolve_paths=False)
    torch.manual_seed(0)
    nets = build_networks(cfg.network)
    _calibrate(nets, [procedural_image(64, 96, s) for s in range(3)])
    out = tmp_path_factory.mktemp(f"export-{request.param}")
    info = export_networks(cfg, nets, out, source={"test": True})
    sessions = {}
    for name in C.NETWORKS:
        so = ort.SessionOptions()
        so.intra_op_num_threads = 1
        sessions[name] = ort.InferenceSession(str(out / C.FILES[name]), so, providers=["CPUExecutionProvider"])
    return {"cfg": cfg, "nets": nets, "dir": out, "info": info, "sessions": sessions}


def _compare(exported, name, inputs):
    feed = {k: v.numpy() for k, v in zip(C.INPUTS[name], inputs)}
    got = exported["sessions"][name].run(None, feed)[0]
    with torch.no_grad():
        net = exported["nets"][name]
        want = torch.sigmoid(net(*inputs)) if name == "rdn" else net(*inputs)
    want = want.numpy()
    assert got.shape == want.shape
    diff = float(np.abs(got - want).max())
    assert diff <= TOLERANCE, f"{name} {tuple(inputs[0].shape)}: max |onnx - torch| = {diff}"
    return got


def _inputs_for(name, img_u8):
    if name == "rrn":
        return (_nchw(img_u8), _edge(img_u8))
    return (_nchw(img_u8),)


@pytest.mark.parametrize("size", [(1, 1), (1, 2), (2, 1), (3, 5), (37, 53), (64, 48), (100, 100)])
def test_parity_random_inputs(exported, size):
    g = torch.Generator().manual_seed(size[0] * 1000 + size[1])
    for name in C.NETWORKS:
        n = 2 if size == (37, 53) else 1
        inputs = tuple(torch.rand(n, C.INPUT_CHANNELS[i], *size, generator=g) for i in C.INPUTS[name])
        out = _compare(exported, name, inputs)
        if name == "rdn":
            assert out.min() >= 0.0 and out.max() <= 1.0


@pytest.mark.parametrize("size,seed", [((37, 53), 11), ((96, 128), 12), ((33, 200), 13)])
def test_parity_procedural_images(exported, size, seed):
    img = procedural_image(*size, seed)
    for name in C.NETWORKS:
        _compare(exported, name, _inputs_for(name, img))


def test_parity_real_images(exported):
    frames = real_frames(max_count=3)
    if not frames:
        pytest.skip(shared_data_missing())
    for path in frames:
        img = load_small_rgb(path, max_side=160)
        img = img[: img.shape[0] - 1 + img.shape[0] % 2, : img.shape[1] - 1 + img.shape[1] % 2]  # odd sizes
        for name in C.NETWORKS:
            _compare(exported, name, _inputs_for(name, img))


def test_graph_contract(exported):
    cfg = exported["cfg"]
    for name in C.NETWORKS:
        path = exported["dir"] / C.FILES[name]
        model = onnx.load(str(path))
        onnx.checker.check_model(model, full_check=True)
        opset = {o.domain: o.version for o in model.opset_import}[""]
        assert opset >= 17
        assert [i.name for i in model.graph.input] == list(C.INPUTS[name])
        assert [o.name for o in model.graph.output] == [C.OUTPUTS[name]]
        for value, ch in [(v, C.INPUT_CHANNELS[v.name]) for v in model.graph.input] + [
            (model.graph.output[0], C.OUTPUT_CHANNELS[name])
        ]:
            t = value.type.tensor_type
            assert t.elem_type == onnx.TensorProto.FLOAT
            dims = [d.dim_param or d.dim_value for d in t.shape.dim]
            assert dims == ["N", ch, "H", "W"], (name, value.name, dims)
        meta = {p.key: p.value for p in model.metadata_props}
        assert meta == {
            "raindrop.pad_multiple": "1",
            "raindrop.config": cfg.name,
            "raindrop.network": name,
            "raindrop.threshold": repr(cfg.pipeline.threshold),
            "raindrop.dilation": str(cfg.pipeline.dilation),
        }
        assert float(meta["raindrop.threshold"]) == cfg.pipeline.threshold


def test_export_info(exported):
    info = json.loads((exported["dir"] / C.EXPORT_INFO).read_text())
    assert info == json.loads(json.dumps(exported["info"]))
    for name in C.NETWORKS:
        f = C.FILES[name]
        assert info["files"][f]["sha256"] == hashlib.sha256((exported["dir"] / f).read_bytes()).hexdigest()
        assert info["files"][f]["bytes"] == (exported["dir"] / f).stat().st_size
    g = info["gflops_256x512"]
    assert g["total"] == pytest.approx(g["rdn"] + g["rrn"] + g["rfn"])
    assert info["config"] == exported["cfg"].name and info["pad_multiple"] == 1
    assert max(info["parity_max_abs_diff"].values()) <= TOLERANCE


def _smoke_nets():
    cfg = load_config(CONFIGS / "smoke.yaml", resolve_paths=False)
    torch.manual_seed(0)
    return cfg, build_networks(cfg.network)


def test_a_failed_export_leaves_the_folder_as_it_was(tmp_path):
    """A network that fails its check (here: NaN weights, which the parity check used to pass,
    since max(0.0, nan) is 0.0) changes nothing in an existing model folder: the graphs were
    written one at a time, so a failure left a new rdn beside the old rrn and rfn."""
    from raindrop_tools.export import ExportError

    cfg, nets = _smoke_nets()
    out = tmp_path / "model"
    export_networks(cfg, nets, out, source={"first": True})
    (out / "LARGE_DROPS").write_text("other\n")
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    with torch.no_grad():
        for p in nets["rrn"].parameters():
            p.fill_(float("nan"))
    with pytest.raises(ExportError, match="rrn: the network's outputs are not finite"):
        export_networks(cfg, nets, out, source={"second": True})
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert [p.name for p in tmp_path.iterdir()] == ["model"], "the staging folder is removed"


def test_an_export_removes_the_staging_folder_of_a_stopped_one(tmp_path):
    """SIGTERM ends an export without its clean-up: the next export into the folder removes
    that staging folder (its process is gone), and keeps a running export's and the user's."""
    cfg, nets = _smoke_nets()
    out = tmp_path / "model"
    stale = tmp_path / ".model.export-4194303"
    live = tmp_path / f".model.export-{os.getpid()}-other"  # not a process id: left alone
    running = tmp_path / f".model.export-{os.getppid()}"
    for d in (stale, live, running):
        (d / "rdn.onnx").parent.mkdir(parents=True)
        (d / "rdn.onnx").write_bytes(b"x")
    export_networks(cfg, nets, out, source={"test": True})
    assert not stale.exists()
    assert live.exists() and running.exists()


def test_export_cli_refuses_unsafe_names_and_unreadable_checkpoints(tmp_path, capsys, monkeypatch):
    from raindrop_tools import export as E

    bad = tmp_path / "bad.pt"
    bad.write_text("not a checkpoint\n")
    monkeypatch.chdir(tmp_path)
    assert E.main(["--run", str(tmp_path), "--checkpoint", str(bad), "--out", str(tmp_path / "m")]) == 2
    assert "not a readable checkpoint" in capsys.readouterr().err
    assert not (tmp_path / "m").exists()
    # --name becomes a folder under models/: "..", hidden or path-like names are refused
    monkeypatch.setattr(E, "load_run", lambda *a, **k: (_smoke_nets()[0], _smoke_nets()[1], {}))
    for name in ("..", ".hidden", "a/b", "with space", "-x"):
        assert E.main(["--run", str(tmp_path), f"--name={name}"]) == 2, name
        assert "not a file-name-safe word" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.pt"]


def _ort(path, *inputs):
    sess = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    return sess.run(None, {k: v for k, v in zip(C.INPUTS[path.stem], inputs)})[0]


def test_reconstruction_from_ships_the_runs_detector_with_another_folders_3rn_and_rfn(tmp_path, capsys):
    """A run that fine-tuned only the detector (stage 1, which trains a 3RN copy on the way) is
    shipped with the 3RN and RFN of the folder it started from: --reconstruction-from. Its
    stage 1 is then finished training; without the flag such a checkpoint is refused."""
    from raindrop_tools import checkpoint as ckpt
    from raindrop_tools import export as E
    from raindrop_tools.config import to_dict

    cfg, base = _smoke_nets()
    export_networks(cfg, base, tmp_path / "base")
    torch.manual_seed(1)
    tuned = build_networks(cfg.network)  # other weights in all three networks

    def stage1_checkpoint(run, step):  # of 5 steps
        ckpt.save_atomic({"format": 1, "stage": 1, "step": step, "total_steps": 5, "complete": step == 5,
                          "config": to_dict(cfg), "models": {k: v.state_dict() for k, v in tuned.items()}},
                         ckpt.checkpoint_path(run, 1, step))
        return run

    run = stage1_checkpoint(tmp_path / "run", 5)
    assert E.main(["--run", str(run), "--out", str(tmp_path / "refused")]) == 2
    assert "training is not finished (an export needs stage 2 complete)" in capsys.readouterr().err
    (tmp_path / "afile").write_text("a user's file")
    assert E.main(["--run", str(run), "--out", str(tmp_path / "afile"), "--reconstruction-from", str(tmp_path / "base")]) == 2
    assert "a file, not a folder" in capsys.readouterr().err  # was "[Errno 17] File exists"
    assert (tmp_path / "afile").read_text() == "a user's file"
    assert E.main(["--run", str(run), "--out", str(tmp_path / "m"), "--name", "tuned", "--threshold", "0.75",
                   "--reconstruction-from", str(tmp_path / "base")]) == 0
    out = tmp_path / "m"
    rng = np.random.default_rng(0)
    x = rng.random((1, 3, 24, 40), dtype=np.float32)
    e = rng.random((1, 1, 24, 40), dtype=np.float32)
    with torch.no_grad():
        want_rdn = tuned["rdn"].eval().probability(torch.from_numpy(x)).numpy()
    got_rdn = _ort(out / "rdn.onnx", x)
    assert np.abs(got_rdn - want_rdn).max() < 1e-4, "the detector is the run's"
    for name, inputs in (("rrn", (x, e)), ("rfn", (x,))):
        got, base_out = _ort(out / f"{name}.onnx", *inputs), _ort(tmp_path / "base" / f"{name}.onnx", *inputs)
        assert np.abs(got - base_out).max() < 1e-4, f"{name} is the base folder's"
        with torch.no_grad():
            run_out = tuned[name].eval()(*map(torch.from_numpy, inputs)).numpy()
        assert np.abs(got - run_out).max() > 1e-3, f"{name} is not the run's"
    info = json.loads((out / C.EXPORT_INFO).read_text())
    assert info["checkpoint"]["reconstruction_from"] == str(tmp_path / "base") and info["config"] == "tuned"
    assert info["pipeline"]["threshold"] == 0.75 != cfg.pipeline.threshold
    for f in C.FILES.values():
        meta = {p.key: p.value for p in onnx.load(out / f).metadata_props}
        assert float(meta[C.META_THRESHOLD]) == 0.75 and meta[C.META_CONFIG] == "tuned", f
    assert E.main(["--run", str(run), "--out", str(tmp_path / "t"), "--threshold", "1.5",
                   "--reconstruction-from", str(tmp_path / "base")]) == 2
    assert "must be between 0 and 1" in capsys.readouterr().err and not (tmp_path / "t").exists()
    # an unfinished stage 1 is refused with the flag too
    early = stage1_checkpoint(tmp_path / "early", 3)
    assert E.main(["--run", str(early), "--out", str(tmp_path / "e"), "--reconstruction-from", str(tmp_path / "base")]) == 2
    assert "not finished (an export needs stage 1 complete)" in capsys.readouterr().err and not (tmp_path / "e").exists()
    # a folder without the graphs is a one-line error, and writes nothing
    assert E.main(["--run", str(run), "--out", str(tmp_path / "n"), "--reconstruction-from", str(tmp_path)]) == 2
    assert f"--reconstruction-from {tmp_path}: no rrn.onnx" in capsys.readouterr().err and not (tmp_path / "n").exists()


def test_the_default_folder_is_not_replaced_by_another_runs_model(tmp_path):
    """Without --out the folder is models/<name>, where a shipped model of that name may live: a
    run that kept a copied config's name must not silently replace it. The same run may
    export there again."""
    from raindrop_tools.export import ExportError, _refuse_another_runs_folder

    out = tmp_path / "models" / "compact"
    out.mkdir(parents=True)
    (out / C.EXPORT_INFO).write_text(json.dumps({"checkpoint": {"path": str(tmp_path / "runs/shipped/checkpoints/s.pt")}}))
    with pytest.raises(ExportError, match="already holds a model exported from"):
        _refuse_another_runs_folder(out, {"path": str(tmp_path / "runs/smoke/checkpoints/s.pt")})
    _refuse_another_runs_folder(out, {"path": str(tmp_path / "runs/shipped/checkpoints/later.pt")})  # no error
    _refuse_another_runs_folder(tmp_path / "models" / "new", {"path": "x"})  # nothing there yet


def test_conv4_and_conv5_are_exported_on_phases(exported):
    """The transposed convolution goes out as four phase convolutions (phase_conv.py), which
    ONNX Runtime runs faster; parity with PyTorch is checked by the tests above."""
    out = exported["dir"]
    for name in ("rdn", "rrn"):
        ops = [n.op_type for n in onnx.load(str(out / C.FILES[name])).graph.node]
        assert "ConvTranspose" not in ops and ops.count("DepthToSpace") == 1, name
        # conv5 runs on the phases, and the one DepthToSpace interleaves its output
        # (phase_final_conv.py): no full-resolution feature map.
        assert len(folded_final_convs(onnx.load(str(out / C.FILES[name])))) == 1, name


def test_no_inner_padding_is_exported(exported):
    """The RDN and 3RN go out without the Pad that earlier exports put before the stride-2
    convolution (inner_padding.py), and crop after conv5: at even sizes nothing is copied.
    (Parity with PyTorch at odd and even sizes: the tests above.)"""
    out = exported["dir"]
    for name in ("rdn", "rrn"):
        ops = [n.op_type for n in onnx.load(str(out / C.FILES[name])).graph.node]
        assert "Pad" not in ops and ops.count("Slice") == 2, name
        last_conv = max(i for i, op in enumerate(ops) if op == "Conv")
        assert all(op != "Slice" for op in ops[:last_conv]), name
