import json
import os
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
import yaml

pytestmark = pytest.mark.torch
torch = pytest.importorskip("torch")

from helpers import CONFIGS  # noqa: E402
from raindrop_tools import checkpoint as ckpt  # noqa: E402
from raindrop_tools import export, losses, train  # noqa: E402
from raindrop_tools.config import load_config  # noqa: E402
from raindrop_tools.data import RaindropDataset, StepBatchSampler  # noqa: E402


def _args(data, out, *extra):
    return ["--config", str(CONFIGS / "smoke.yaml"), "--data", str(data), "--out", str(out), "--no-progress", *extra]


def test_smoke_run_folder(smoke_run):
    run = smoke_run["run"]
    cfg = load_config(CONFIGS / "smoke.yaml", [("data.train", str(smoke_run["data"]))])
    recorded = yaml.safe_load((run / "config.yaml").read_text())
    assert recorded["data"]["train"] == str(smoke_run["data"])
    assert recorded["seed"] == cfg.seed == 7
    info = json.loads((run / "run.json").read_text())
    assert info["seed"] == 7 and info["invocations"][0]["device"] == "cpu"
    log = [json.loads(line) for line in (run / "log.jsonl").read_text().splitlines()]
    s1 = [r for r in log if r["stage"] == 1]
    s2 = [r for r in log if r["stage"] == 2]
    assert [r["step"] for r in s1] == list(range(1, 7)) and [r["step"] for r in s2] == list(range(1, 5))
    assert all(np.isfinite(r["loss_rdn"]) and np.isfinite(r["loss_rrn"]) for r in s1)
    assert all(np.isfinite(r["loss_rfn"]) for r in s2)
    assert s1[0]["lr"] == 1e-3 and s1[-1]["lr"] == pytest.approx(1e-4)
    # keep_checkpoints=2 per stage; the end of stage 1 is kept
    names = sorted(p.name for p in (run / "checkpoints").iterdir())
    assert names == [
        "stage1_step00000004.pt",
        "stage1_step00000006.pt",
        "stage2_step00000002.pt",
        "stage2_step00000004.pt",
    ]
    state = ckpt.load_checkpoint(run / "checkpoints" / "stage2_step00000004.pt")
    assert state["stage"] == 2 and state["complete"] and set(state["models"]) == {"rdn", "rrn", "rfn"}


def test_frozen_networks_do_not_change_in_stage_2(smoke_run):
    s1 = ckpt.load_checkpoint(smoke_run["run"] / "checkpoints" / "stage1_step00000006.pt")["models"]
    s2 = ckpt.load_checkpoint(smoke_run["run"] / "checkpoints" / "stage2_step00000004.pt")["models"]
    for net in ("rdn", "rrn"):  # includes the batch-norm running statistics
        for k, v in s1[net].items():
            assert torch.equal(v, s2[net][k]), f"{net}.{k} changed in stage 2"
    assert any(not torch.equal(v, s2["rfn"][k]) for k, v in s1["rfn"].items())


def test_resume_reproduces_the_uninterrupted_run(smoke_run, tmp_path):
    out = tmp_path / "run"
    data = smoke_run["data"]
    # 3 steps, "crash"; 5 more (finishing stage 1, 2 steps into stage 2); then the rest.
    assert train.main(_args(data, out, "--max-steps", "3")) == 0
    assert [r.step for r in ckpt.list_checkpoints(out, 1)][-1] == 3
    assert train.main(_args(data, out, "--resume", "--max-steps", "5")) == 0
    assert ckpt.latest_checkpoint(out).stage == 2 and ckpt.latest_checkpoint(out).step == 2
    assert train.main(["--out", str(out), "--resume", "--no-progress"]) == 0  # config from the run folder
    a = ckpt.load_checkpoint(ckpt.latest_checkpoint(smoke_run["run"]).path)
    b = ckpt.load_checkpoint(ckpt.latest_checkpoint(out).path)
    assert b["stage"] == 2 and b["complete"]
    for net in ("rdn", "rrn", "rfn"):
        for k, v in a["models"][net].items():
            assert torch.equal(v, b["models"][net][k]), f"{net}.{k} differs after resume"
    assert len(json.loads((out / "run.json").read_text())["invocations"]) == 3


def test_refuses_to_overwrite_or_change_a_run(smoke_run, tmp_path, capsys):
    out = tmp_path / "run"
    shutil.copytree(smoke_run["run"], out)
    assert train.main(_args(smoke_run["data"], out)) == 2
    assert "--resume" in capsys.readouterr().err
    assert train.main(_args(smoke_run["data"], out, "--resume", "--set", "train.batch_size=2")) == 2
    assert "train.batch_size: 4 -> 2" in capsys.readouterr().err
    # resuming a finished run is a no-op
    before = sorted(p.name for p in (out / "checkpoints").iterdir())
    assert train.main(_args(smoke_run["data"], out, "--resume")) == 0
    assert sorted(p.name for p in (out / "checkpoints").iterdir()) == before


def test_stage_2_needs_stage_1(tiny_dataset, tmp_path, capsys):
    assert train.main(_args(tiny_dataset, tmp_path / "run", "--stage", "2")) == 2
    assert "run --stage 1 first" in capsys.readouterr().err


def test_stages_one_at_a_time_and_export_refuses_unfinished(smoke_run, tmp_path, capsys):
    out = tmp_path / "run"
    assert train.main(_args(smoke_run["data"], out, "--stage", "1")) == 0
    assert ckpt.latest_checkpoint(out).stage == 1
    assert export.main(["--run", str(out), "--out", str(tmp_path / "m")]) == 2
    assert "not finished" in capsys.readouterr().err
    assert train.main(["--out", str(out), "--stage", "2", "--no-progress"]) == 0
    a = ckpt.load_checkpoint(ckpt.latest_checkpoint(smoke_run["run"]).path)["models"]["rfn"]
    b = ckpt.load_checkpoint(ckpt.latest_checkpoint(out).path)["models"]["rfn"]
    assert all(torch.equal(v, b[k]) for k, v in a.items())


def _inject_nan(monkeypatch, name, at_call):
    original = getattr(losses, name)
    calls = {"n": 0}

    def poisoned(*args, **kwargs):
        calls["n"] += 1
        loss = original(*args, **kwargs)
        return loss * float("nan") if calls["n"] == at_call else loss

    monkeypatch.setattr(losses, name, poisoned)


@pytest.mark.parametrize(
    "net,loss_fn,stage", [("rdn", "detection_loss", 1), ("rrn", "reconstruction_loss", 1), ("rfn", "refine_loss", 2)]
)
def test_nan_guard_names_network_step_and_ids_and_writes_no_checkpoint(
    smoke_run, tmp_path, monkeypatch, net, loss_fn, stage
):
    out = tmp_path / "run"
    cfg = load_config(CONFIGS / "smoke.yaml", [("data.train", str(smoke_run["data"]))])
    train.prepare_run_dir(out, cfg)
    if stage == 2:  # start from the end of stage 1
        (out / "checkpoints").mkdir()
        shutil.copy(smoke_run["run"] / "checkpoints" / "stage1_step00000006.pt", out / "checkpoints")
    _inject_nan(monkeypatch, loss_fn, at_call=3)  # step 3; checkpoints every 2 steps
    trainer = train.Trainer(cfg, out, torch.device("cpu"), progress=False)
    with pytest.raises(train.NonFiniteLossError) as e:
        trainer.run([stage], resume=False)
    msg = str(e.value)
    ds = RaindropDataset(smoke_run["data"], crop=cfg.data.crop, validate="header")
    keys = StepBatchSampler(ds.sizes, cfg.data.crop, cfg.train.batch_size, cfg.seed, stage, 6).keys_for_step(2)
    ids = [ds.samples[k[0]].id for k in keys]
    assert f"{net} loss is nan" in msg and f"stage {stage} step 3 " in msg
    assert "batch sample ids: " + ", ".join(ids) in msg
    assert ckpt.checkpoint_path(out, stage, 2).is_file()
    assert not ckpt.checkpoint_path(out, stage, 3).exists()
    assert not list((out / "checkpoints").glob(".tmp-*"))


def test_cli_reports_nan_as_an_error(smoke_run, tmp_path, monkeypatch, capsys):
    _inject_nan(monkeypatch, "detection_loss", at_call=1)
    assert train.main(_args(smoke_run["data"], tmp_path / "run")) == 2
    err = capsys.readouterr().err
    assert "error: rdn loss is nan at stage 1 step 1 of 6" in err
    assert not ckpt.list_checkpoints(tmp_path / "run")


def test_choose_device():
    assert train.choose_device("cpu").type == "cpu"
    assert train.choose_device("auto").type == ("cuda" if torch.cuda.is_available() else "cpu")
    if not torch.cuda.is_available():
        with pytest.raises(train.TrainingError, match="no CUDA"):
            train.choose_device("cuda")


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_a_signal_to_the_whole_process_group_stops_with_a_checkpoint(tiny_dataset, tmp_path, sig):
    """Ctrl-C in a terminal, `docker stop` and systemd signal every process of the group,
    DataLoader workers included: the run must still stop after its step with a checkpoint."""
    out = tmp_path / "run"
    cmd = [sys.executable, "-m", "raindrop_tools.train", *_args(tiny_dataset, out),
           "--set", "data.workers=2", "--set", "train.stage1_steps=100000", "--set", "train.log_every=1",
           "--set", "train.checkpoint_every=100000", "--threads", "1"]
    proc = subprocess.Popen(cmd, start_new_session=True, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        log = out / "log.jsonl"
        deadline = time.monotonic() + 120
        while not (log.is_file() and log.read_text().count("\n") >= 2):
            assert proc.poll() is None, proc.stdout.read()
            assert time.monotonic() < deadline, "training logged no step in 120 s"
            time.sleep(0.1)
        os.killpg(proc.pid, sig)
        text, _ = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130, text
    latest = ckpt.latest_checkpoint(out)
    assert latest is not None and latest.step >= 2, text
    assert "continue with --resume" in text


def test_training_on_rendered_and_real_sources(tiny_dataset, tmp_path):
    """A run with data.sources: the batches mix both sources; a real-pairs source is accepted
    with check_outside_mask false and refused with it; resume stays exact."""
    from realpairs_helpers import write_pairs

    from raindrop_tools import realpairs as RP

    real = tmp_path / "real"
    RP.prepare(write_pairs(tmp_path / "pairs", groups=2, per_group=2), real)
    sources = [{"path": str(tiny_dataset), "weight": 0.5}, {"path": str(real), "weight": 0.5, "split": "train",
                                                          "check_outside_mask": False}]
    cfg_file = tmp_path / "multi.yaml"
    raw = yaml.safe_load((CONFIGS / "smoke.yaml").read_text())
    del raw["data"]["train"]
    raw["data"]["sources"] = sources
    cfg_file.write_text(yaml.safe_dump(raw))
    base = ["--config", str(cfg_file), "--no-progress", "--stage", "1"]
    out = tmp_path / "run"
    assert train.main([*base, "--out", str(out)]) == 0
    recorded = yaml.safe_load((out / "config.yaml").read_text())
    assert [s["path"] for s in recorded["data"]["sources"]] == [str(tiny_dataset), str(real)]
    # resume reproduces the uninterrupted run
    out2 = tmp_path / "run2"
    assert train.main([*base, "--out", str(out2), "--max-steps", "4"]) == 0
    assert train.main(["--out", str(out2), "--resume", "--stage", "1", "--no-progress"]) == 0
    a = ckpt.load_checkpoint(ckpt.latest_checkpoint(out).path)["models"]
    b = ckpt.load_checkpoint(ckpt.latest_checkpoint(out2).path)["models"]
    for net in ("rdn", "rrn"):
        assert all(torch.equal(v, b[net][k]) for k, v in a[net].items())
    # the same real source with the outside-mask check on is refused
    raw["data"]["sources"][1]["check_outside_mask"] = True
    cfg_file.write_text(yaml.safe_dump(raw))
    assert train.main([*base, "--out", str(tmp_path / "run3")]) == 2


def test_a_source_of_detection_weight_zero_teaches_the_detector_nothing(tiny_dataset, tmp_path):
    """data.sources[].detection_weight 0 on every source: the RDN's parameters stay as they
    were after its first step (Adam moves nothing on a zero gradient) while the 3RN learns;
    weight 1 moves both. Buffers (BatchNorm statistics) are not parameters and may move."""
    raw = yaml.safe_load((CONFIGS / "smoke.yaml").read_text())
    del raw["data"]["train"]

    def moved(weight):
        raw["data"]["sources"] = [{"path": str(tiny_dataset), "detection_weight": weight}]
        cfg_file = tmp_path / f"w{weight}.yaml"
        cfg_file.write_text(yaml.safe_dump(raw))
        out = tmp_path / f"run-w{weight}"
        base = ["--config", str(cfg_file), "--no-progress", "--stage", "1", "--out", str(out)]
        assert train.main([*base, "--max-steps", "1"]) == 0
        first = ckpt.load_checkpoint(ckpt.latest_checkpoint(out).path)["models"]
        assert train.main(["--out", str(out), "--resume", "--stage", "1", "--no-progress"]) == 0
        last = ckpt.load_checkpoint(ckpt.latest_checkpoint(out).path)["models"]
        params = {net: [k for k in first[net] if "running_" not in k and "num_batches" not in k] for net in first}
        return {net: any(not torch.equal(first[net][k], last[net][k]) for k in params[net]) for net in ("rdn", "rrn")}

    assert moved(0.0) == {"rdn": False, "rrn": True}
    assert moved(1.0) == {"rdn": True, "rrn": True}


def test_init_from_loads_the_weights_not_the_optimizer(smoke_run, tmp_path, capsys):
    src_ckpt = ckpt.latest_checkpoint(smoke_run["run"]).path
    src = ckpt.load_checkpoint(src_ckpt)["models"]
    data = smoke_run["data"]
    out = tmp_path / "ft"
    # from a run folder: its latest stage-2 checkpoint; 1 step of stage 1 only
    assert train.main(_args(data, out, "--init-from", str(smoke_run["run"]), "--max-steps", "1")) == 0
    assert json.loads((out / "run.json").read_text())["init_from"] == str(src_ckpt.resolve())
    state = ckpt.load_checkpoint(ckpt.latest_checkpoint(out).path)
    assert state["step"] == 1  # the step count starts fresh
    assert state["optimizers"]["rdn"]["state"][0]["step"] == 1  # a fresh Adam: one step taken
    # RFN is not trained in stage 1: it holds exactly the loaded weights
    assert all(torch.equal(v, state["models"]["rfn"][k]) for k, v in src["rfn"].items())
    # RDN moved one step away from the loaded weights, not from a fresh initialisation
    torch.manual_seed(7)
    fresh = train.build_networks(load_config(CONFIGS / "smoke.yaml").network)["rdn"].state_dict()
    k = next(k for k in src["rdn"] if k.endswith("weight"))
    d_loaded = (state["models"]["rdn"][k] - src["rdn"][k]).abs().max()
    d_fresh = (state["models"]["rdn"][k] - fresh[k]).abs().max()
    assert d_loaded < d_fresh
    # from a checkpoint file; refused once the run has checkpoints; refused for ONNX folders
    out2 = tmp_path / "ft2"
    assert train.main(_args(data, out2, "--init-from", str(src_ckpt), "--max-steps", "1")) == 0
    capsys.readouterr()
    assert train.main(_args(data, out2, "--resume", "--init-from", str(src_ckpt))) == 2
    assert "drop --init-from" in capsys.readouterr().err
    # an exported model folder needs frozen BatchNorms (its own are folded into the convolutions)
    assert train.main(_args(data, tmp_path / "ft3", "--init-from", str(smoke_run["models"]))) == 2
    assert "train.freeze_batchnorm: true" in capsys.readouterr().err
    # a network that does not fit is named
    assert train.main(_args(data, tmp_path / "ft4", "--init-from", str(src_ckpt), "--set", "network.rdn.width=4")) == 2
    assert "rdn weights do not fit" in capsys.readouterr().err


def test_init_from_an_exported_model_folder_fine_tunes_its_function(smoke_run, tmp_path, capsys):
    """train --init-from models/<config>: the weights come back from the ONNX graphs, and stage 1
    leaves RFN (not trained there) computing exactly what rfn.onnx computes."""
    import onnxruntime as ort

    from raindrop_tools.export import graph_module

    data, models, out = smoke_run["data"], smoke_run["models"], tmp_path / "ft-onnx"
    frozen = ("--set", "train.freeze_batchnorm=true")
    assert train.main(_args(data, out, "--init-from", str(models), *frozen, "--max-steps", "2")) == 0
    assert "BatchNorm frozen" in capsys.readouterr().err
    assert json.loads((out / "run.json").read_text())["init_from"] == str(models.resolve())
    state = ckpt.load_checkpoint(ckpt.latest_checkpoint(out).path)
    nets = train.build_networks(load_config(CONFIGS / "smoke.yaml").network)
    for k, net in nets.items():
        net.load_state_dict(state["models"][k])
    x = torch.rand(1, 3, 40, 56, generator=torch.Generator().manual_seed(3))
    with torch.no_grad():
        ours = graph_module("rfn", nets["rfn"].eval())(x).numpy()
    theirs = ort.InferenceSession(str(models / "rfn.onnx"), providers=["CPUExecutionProvider"]).run(None, {"blend": x.numpy()})[0]
    assert np.abs(ours - theirs).max() < 1e-4
    # BatchNorm stayed frozen while RDN trained: its running statistics are the loaded identity
    bns = [m for m in nets["rdn"].modules() if isinstance(m, torch.nn.BatchNorm2d)]
    assert bns and all(torch.equal(m.running_mean, torch.zeros_like(m.running_mean)) for m in bns)
    # a network setting the graphs cannot show (the global residual) is checked against export.json
    assert train.main(_args(data, tmp_path / "ft5", "--init-from", str(models), *frozen,
                            "--set", "network.rrn.global_residual=true")) == 2
    assert "network.rrn.global_residual" in capsys.readouterr().err
    # an int8 copy of a folder: its weights are computed from integers, so no fine-tune starts there
    int8 = tmp_path / "int8"
    shutil.copytree(models, int8)
    info = json.loads((int8 / "export.json").read_text())
    (int8 / "export.json").write_text(json.dumps({**info, "quantized_from": str(models)}))
    assert train.main(_args(data, tmp_path / "ft8", "--init-from", str(int8), *frozen)) == 2
    err = capsys.readouterr().err
    assert "an int8 folder" in err and "start from the float folder" in err
    (int8 / "export.json").write_text("{ cut")
    assert train.main(_args(data, tmp_path / "ft9", "--init-from", str(int8), *frozen)) == 2
    assert "its export.json cannot be read" in capsys.readouterr().err
    (int8 / "export.json").write_text('{"network": {"rdn": 5}}')
    assert train.main(_args(data, tmp_path / "ft10", "--init-from", str(int8), *frozen)) == 2
    assert "not a table of networks' settings" in capsys.readouterr().err


def test_a_run_that_saved_nothing_may_be_started_again_with_a_corrected_command(smoke_run, tmp_path, capsys):
    """A mistyped --data wrote config.yaml and failed; the corrected command was then refused
    as 'a different configuration'. A run with checkpoints still refuses one."""
    out = tmp_path / "run"
    typo = load_config(CONFIGS / "smoke.yaml", [("data.train", str(tmp_path / "nowhere"))])
    # Each call stands for one invocation (a process of its own): its lock is let go after it.
    train.prepare_run_dir(out, typo)
    (out / train.RUN_FILE).write_text("{}\n")  # as the failed invocation recorded itself
    train.release_run_locks()
    good = load_config(CONFIGS / "smoke.yaml", [("data.train", str(smoke_run["data"]))])
    assert train.prepare_run_dir(out, good) == good
    train.release_run_locks()
    assert "replacing the configuration of a run that saved no checkpoint" in capsys.readouterr().err
    (out / "checkpoints").mkdir()
    shutil.copy(smoke_run["run"] / "checkpoints" / "stage1_step00000006.pt", out / "checkpoints")
    with pytest.raises(train.TrainingError, match="records a different configuration"):
        train.prepare_run_dir(out, typo)
    train.release_run_locks()
    (tmp_path / "afile").write_text("x")
    with pytest.raises(train.TrainingError, match="is a file"):
        train.prepare_run_dir(tmp_path / "afile", good)
    (out / train.CONFIG_FILE).write_text("a: [unclosed\n")
    with pytest.raises(train.TrainingError, match="not a readable configuration"):
        train.prepare_run_dir(out, good)
    train.release_run_locks()


def test_resume_drops_the_log_lines_past_its_checkpoint(smoke_run, tmp_path):
    """A run killed after its last checkpoint had logged later steps; the resumed run trained
    and logged them again, so log.jsonl held those steps twice."""
    out = tmp_path / "run"
    assert train.main(_args(smoke_run["data"], out, "--max-steps", "3")) == 0
    log = out / train.LOG_FILE
    # what a kill -9 after two more logged steps leaves: steps 4 and 5, and a torn last line
    log.write_text(log.read_text() + '{"stage": 1, "step": 4}\n{"stage": 1, "step": 5}\n{"stage": 1, "st')
    assert train.main(_args(smoke_run["data"], out, "--resume", "--max-steps", "2")) == 0
    records = []
    for line in log.read_text().splitlines():
        try:
            records.append(json.loads(line))
        except ValueError:
            pass  # the torn line, kept as it was on a line of its own
    assert [(r["stage"], r["step"]) for r in records] == [(1, 1), (1, 2), (1, 3), (1, 4), (1, 5)]


def test_unreadable_checkpoints_are_one_line_errors(smoke_run, tmp_path, capsys):
    """A checkpoint cut short (a full disk, a copy stopped half way) and a file that is not one
    ended --resume and --init-from in torch's traceback."""
    out = tmp_path / "run"
    assert train.main(_args(smoke_run["data"], out, "--max-steps", "2")) == 0
    latest = ckpt.latest_checkpoint(out).path
    latest.write_bytes(latest.read_bytes()[:1000])
    assert train.main(_args(smoke_run["data"], out, "--resume")) == 2
    err = capsys.readouterr().err
    assert "not a readable checkpoint" in err and "Traceback" not in err
    (tmp_path / "text.pt").write_text("not a checkpoint\n")
    assert train.main(_args(smoke_run["data"], tmp_path / "run2", "--init-from", str(tmp_path / "text.pt"))) == 2
    assert "not a readable checkpoint" in capsys.readouterr().err


def test_a_non_finite_weight_is_never_saved(smoke_run, tmp_path, monkeypatch):
    """Finite losses and gradients can still step a weight to NaN; the checkpoint of that step
    is refused, the run stops with the network and weight named, the one before stays."""
    out = tmp_path / "run"
    cfg = load_config(CONFIGS / "smoke.yaml", [("data.train", str(smoke_run["data"]))])
    train.prepare_run_dir(out, cfg)
    original = train.Trainer._save

    def poisoned(self, stage, step, total, opts, scheds):
        if step == 4:
            with torch.no_grad():
                next(self.nets["rrn"].parameters()).view(-1)[0] = float("nan")
        return original(self, stage, step, total, opts, scheds)

    monkeypatch.setattr(train.Trainer, "_save", poisoned)
    trainer = train.Trainer(cfg, out, torch.device("cpu"), progress=False)
    with pytest.raises(train.NonFiniteLossError) as e:
        trainer.run([1], resume=False)
    assert "rrn weight " in str(e.value) and "stage 1 step 4 of 6" in str(e.value)
    assert ckpt.checkpoint_path(out, 1, 2).is_file()
    assert not ckpt.checkpoint_path(out, 1, 4).exists()
    assert not list((out / "checkpoints").glob(".tmp-*"))


def test_a_users_config_in_the_out_folder_is_not_replaced(tmp_path):
    """--out naming a folder that holds the user's own config.yaml (no run.json: no training run
    wrote it) replaced that file with the run's configuration."""
    out = tmp_path / "project"
    out.mkdir()
    (out / "config.yaml").write_text("name: myproject\nseed: 3\n")
    cfg = load_config(CONFIGS / "smoke.yaml", [("data.train", str(tmp_path / "data"))])
    with pytest.raises(train.TrainingError, match="not a training run's configuration"):
        train.prepare_run_dir(out, cfg)
    train.release_run_locks()
    assert (out / "config.yaml").read_text() == "name: myproject\nseed: 3\n"
    (out / "config.yaml").write_text("name: myproject\nserver: x\n")
    with pytest.raises(train.TrainingError, match="config.yaml: not a readable configuration.*server"):
        train.prepare_run_dir(out, cfg)
    train.release_run_locks()


def test_one_training_process_per_run_folder(tmp_path):
    """Two trainings into one --out wrote each other's checkpoints: the second is refused while
    the first holds the folder, and may start once it has let go."""
    out = tmp_path / "run"
    cfg = load_config(CONFIGS / "smoke.yaml", [("data.train", str(tmp_path / "data"))])
    train.prepare_run_dir(out, cfg)
    try:
        with pytest.raises(train.TrainingError, match="being trained by another process"):
            train.prepare_run_dir(out, cfg)
    finally:
        train.release_run_locks()
    train.prepare_run_dir(out, cfg)
    train.release_run_locks()
