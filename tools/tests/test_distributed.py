"""Training in two processes under torchrun (gloo, CPU): DistributedDataParallel, the global
batch split over the ranks, rank 0 alone writing, resume."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.torch
torch = pytest.importorskip("torch")
if not (torch.distributed.is_available() and torch.distributed.is_gloo_available()):
    pytest.skip("torch.distributed with gloo is not available", allow_module_level=True)

from helpers import CONFIGS  # noqa: E402
from raindrop_tools import checkpoint as ckpt  # noqa: E402
from raindrop_tools import distributed, train  # noqa: E402
from raindrop_tools.config import load_config  # noqa: E402
from raindrop_tools.data import RaindropDataset, StepBatchSampler  # noqa: E402

PROBE = Path(__file__).resolve().parent / "ddp_probe.py"
# Batch norm in eval mode: the per-process batch statistics then play no part, and two
# processes must train exactly like one over the same global batches.
FROZEN_BN = ("--set", "train.freeze_batchnorm=true")


def _torchrun(target: list[str], args: list[str], probe_dir: Path | None = None, **env_extra):
    env = {**os.environ, "OMP_NUM_THREADS": "1", **env_extra}
    if probe_dir is not None:
        env["RAINDROP_PROBE"] = str(probe_dir)
    cmd = [sys.executable, "-m", "torch.distributed.run", "--nproc_per_node=2", "--standalone", *target, *args]
    return subprocess.run(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=300)


def _args(data, out, *extra):
    return ["--config", str(CONFIGS / "smoke.yaml"), "--data", str(data), "--out", str(out), "--no-progress",
            "--threads", "1", *extra]


def _lines(path: Path) -> list:
    return [json.loads(line) for line in path.read_text().splitlines()]


def test_two_processes_train_like_one_over_the_global_batches_and_resume(tiny_dataset, tmp_path):
    probe, out, ref = tmp_path / "probe", tmp_path / "ddp", tmp_path / "one"
    probe.mkdir()
    # 8 steps (all 6 of stage 1, 2 of stage 2), then resume for the last 2 of stage 2
    first = _torchrun([str(PROBE)], _args(tiny_dataset, out, *FROZEN_BN, "--max-steps", "8"), probe)
    assert first.returncode == 0, first.stdout
    assert first.stdout.count("stopped: run folder") == 1, first.stdout  # printed by rank 0 only
    assert [(r.stage, r.step) for r in ckpt.list_checkpoints(out)][-1] == (2, 2)
    second = _torchrun([str(PROBE)], ["--out", str(out), "--resume", "--no-progress", "--threads", "1"], probe)
    assert second.returncode == 0, second.stdout
    assert second.stdout.count("done: run folder") == 1 and "resuming at step 2 of 4" in second.stdout, second.stdout

    # one process over the same (global) batches
    assert train.main(_args(tiny_dataset, ref, *FROZEN_BN)) == 0
    assert [r.path.name for r in ckpt.list_checkpoints(out)] == [r.path.name for r in ckpt.list_checkpoints(ref)]
    ddp = ckpt.load_checkpoint(ckpt.latest_checkpoint(out).path)["models"]
    one = ckpt.load_checkpoint(ckpt.latest_checkpoint(ref).path)["models"]
    torch.manual_seed(7)
    initial = train.build_networks(load_config(CONFIGS / "smoke.yaml").network)
    for net in ("rdn", "rrn", "rfn"):
        moved = max((ddp[net][k] - v).abs().max().item() for k, v in initial[net].state_dict().items())
        assert moved > 1e-3, f"{net} did not train"
        for k, v in one[net].items():
            assert torch.allclose(ddp[net][k].float(), v.float(), rtol=0, atol=1e-6), f"{net}.{k} differs"

    # both ranks end with the same networks (DDP kept them in step): those of rank 0's checkpoint
    ranks = [torch.load(probe / f"nets-rank{r}.pt") for r in (0, 1)]
    for net in ("rdn", "rrn", "rfn"):
        for k, v in ddp[net].items():
            assert torch.equal(ranks[0][net][k], v) and torch.equal(ranks[1][net][k], v), f"{net}.{k}"

    # rank 0 alone logged: every step once, the mean loss of the global batch
    log, ref_log = _lines(out / "log.jsonl"), _lines(ref / "log.jsonl")
    assert [(r["stage"], r["step"]) for r in log] == [(r["stage"], r["step"]) for r in ref_log]
    for a, b in zip(log, ref_log):
        for k in (k for k in b if k.startswith("loss_")):
            assert a[k] == pytest.approx(b[k], rel=1e-5), (a, b)
    invocations = json.loads((out / "run.json").read_text())["invocations"]
    assert [(i["processes"], i["backend"]) for i in invocations] == [(2, "gloo"), (2, "gloo")]

    # the ranks drew different halves of each global batch, which together are that batch
    ids = [_lines(probe / f"ids-rank{r}.jsonl") for r in (0, 1)]
    cfg = load_config(CONFIGS / "smoke.yaml")
    ds = RaindropDataset(tiny_dataset, crop=cfg.data.crop, validate="header")
    steps = [(1, s) for s in range(6)] + [(2, s) for s in range(4)]
    assert len(ids[0]) == len(ids[1]) == len(steps)
    for (stage, step), mine, theirs in zip(steps, *ids):
        sampler = StepBatchSampler(ds.sizes, cfg.data.crop, 4, cfg.seed, stage, 6 if stage == 1 else 4)
        whole = [ds.samples[k[0]].id for k in sampler.keys_for_step(step)]
        assert len(mine) == len(theirs) == 2
        assert sorted(mine + theirs) == sorted(whole), (stage, step)
    assert any(a != b for a, b in zip(*ids))


def test_a_batch_the_processes_cannot_split_is_refused(tiny_dataset, tmp_path):
    out = tmp_path / "run"
    res = _torchrun(["-m", "raindrop_tools.train"], _args(tiny_dataset, out, "--set", "train.batch_size=3"))
    assert res.returncode != 0
    errors = [line for line in res.stdout.splitlines() if line.startswith("error: ")]
    assert errors == [
        "error: train.batch_size 3 is not divisible by the 2 processes (WORLD_SIZE); it is the global batch, "
        "split evenly: use a multiple of 2"
    ], res.stdout
    assert not out.exists()


def test_a_nan_on_one_rank_stops_every_rank_naming_the_whole_batch(tiny_dataset, tmp_path):
    probe, out = tmp_path / "probe", tmp_path / "run"
    probe.mkdir()
    res = _torchrun([str(PROBE)], _args(tiny_dataset, out, "--stage", "1"), probe, RAINDROP_PROBE_NAN="1:3")
    assert res.returncode != 0
    errors = [line for line in res.stdout.splitlines() if line.startswith("error: ")]
    ids = [i for r in (0, 1) for i in _lines(probe / f"ids-rank{r}.jsonl")[2]]  # both ranks' third batch
    assert errors == [
        "error: rdn loss (mean of the 2 processes) is nan at stage 1 step 3 of 6; batch sample ids: "
        f"{', '.join(ids)}. No checkpoint was written for this step (latest: stage1_step00000002.pt)."
    ], res.stdout
    assert [r.step for r in ckpt.list_checkpoints(out)] == [2]
    assert not (probe / "nets-rank0.pt").exists() and not (probe / "nets-rank1.pt").exists()


def test_rank_slices_partition_every_batch():
    batches = [[(i, 0, 0, False) for i in range(s, s + 6)] for s in range(3)]
    parts = [list(distributed.RankSlice(batches, r, 3)) for r in range(3)]
    assert all(len(p) == 3 and all(len(b) == 2 for b in p) for p in parts)
    for step, whole in enumerate(batches):
        got = [k for p in parts for k in p[step]]
        assert sorted(got) == sorted(whole) and len(set(got)) == 6


def test_world_from_the_environment():
    assert distributed.from_env({}) is None
    assert distributed.from_env({"WORLD_SIZE": "1", "RANK": "0"}) is None
    env = {"WORLD_SIZE": "4", "RANK": "3", "LOCAL_RANK": "1", "MASTER_ADDR": "h", "MASTER_PORT": "29500"}
    w = distributed.from_env(env)
    assert (w.rank, w.local_rank, w.size, w.is_main) == (3, 1, 4, False)
    with pytest.raises(distributed.WorldError, match="RANK"):
        distributed.from_env({"WORLD_SIZE": "2", "MASTER_ADDR": "h", "MASTER_PORT": "1"})
    with pytest.raises(distributed.WorldError, match="do not fit"):
        distributed.from_env({**env, "RANK": "4"})
    assert w.local_batch(8) == 2
    with pytest.raises(distributed.WorldError, match="not divisible by the 4 processes"):
        w.local_batch(6)
