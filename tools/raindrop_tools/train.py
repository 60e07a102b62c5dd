"""Two-stage training (paper section 4.4).

Stage 1 trains RDN and 3RN side by side on the same batches, each with its own Adam
optimizer and learning-rate schedule. Stage 2 trains RFN alone on the blend
``B = M * clamp(3RN(R, E), 0, 1) + (1 - M) * R`` with ``M = dilate(sigmoid(RDN(R)) >
threshold)``, RDN and 3RN frozen in eval mode.

    python -m raindrop_tools.train --config tools/configs/compact.yaml --out tools/runs/compact
    python -m raindrop_tools.train --out tools/runs/compact --resume          # continue
    python -m raindrop_tools.train --config C --stage 1 ... ; ... --stage 2   # one at a time

The run folder holds ``config.yaml`` (the resolved configuration: one run, one config),
``run.json`` (seed, devices, versions, command lines), ``log.jsonl`` (losses and learning
rates) and ``checkpoints/``. A non-finite loss or gradient stops the run with an error naming
the network, the step and the sample ids of the batch; no checkpoint is written for it.

Started by ``torchrun`` with several processes (``torchrun --nproc_per_node=4 -m
raindrop_tools.train ...``), the run trains with DistributedDataParallel: the configured batch
is the global batch, split over the processes, and rank 0 alone reads and writes the run
folder (distributed.py).
"""

from __future__ import annotations

import argparse
import datetime as _dt
import fcntl
import json
import os
import platform
import signal
import sys
import time
from pathlib import Path

import torch
import yaml
from torch.nn.parallel import DistributedDataParallel
from torch.utils.data import DataLoader
from tqdm import tqdm

from . import checkpoint as ckpt
from . import contract as C
from . import distributed, losses, onnx_weights
from .config import (
    ConfigError,
    RunConfig,
    config_from_dict,
    data_sources,
    dump_config,
    load_config,
    load_yaml,
    parse_overrides,
    to_dict,
    yaml_error_text,
)
from .data import DatasetError, MultiSourceDataset, RaindropDataset, StepBatchSampler, WeightedStepBatchSampler, epochs
from .morphology import Dilation
from .networks import build_networks
from .read_only import ReadOnlyFileError, refuse_read_only
from .schedule import lr_factor

CONFIG_FILE = "config.yaml"
RUN_FILE = "run.json"
LOG_FILE = "log.jsonl"


class TrainingError(RuntimeError):
    """A run that cannot start or continue (bad run folder, missing stage 1, ...)."""


class NonFiniteLossError(TrainingError):
    """A loss, gradient or weight became NaN or Inf."""


# Errors reported as a one-line message (exit status 2); anything else is a bug.
REPORTED = (ConfigError, DatasetError, TrainingError, distributed.WorldError, ckpt.CheckpointError, ReadOnlyFileError)


def choose_device(name: str = "auto") -> torch.device:
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if name == "cuda" and not torch.cuda.is_available():
        raise TrainingError("--device cuda: no CUDA device is available")
    if name not in ("cpu", "cuda"):
        raise TrainingError(f"--device must be auto, cpu or cuda, got {name!r}")
    return torch.device(name)


def default_run_dir(name: str) -> Path:
    """tools/runs/<name> in a source checkout (git-ignored), else ./runs/<name>."""
    tools = Path(__file__).resolve().parents[1]
    if (tools / "pyproject.toml").is_file():
        return tools / "runs" / name
    return Path.cwd() / "runs" / name


def _write_text_atomic(path: Path, text: str) -> None:
    refuse_read_only(path, follow_links=False)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def _write_json_atomic(path: Path, obj) -> None:
    _write_text_atomic(path, json.dumps(obj, indent=2) + "\n")


_LOCKS: list = []  # the run folders' lock files this process holds (released by release_run_locks)


def lock_run_dir(run_dir: Path) -> None:
    """One training process per run folder, until release_run_locks: two at once wrote each
    other's checkpoints into one folder, and one died pruning a file the other had removed."""
    f = open(run_dir / ".train.lock", "a")
    try:
        fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        f.close()
        raise TrainingError(f"{run_dir} is being trained by another process; wait for it to end, or use another --out") from None
    _LOCKS.append(f)


def release_run_locks() -> None:
    while _LOCKS:
        _LOCKS.pop().close()  # closing the file releases its lock


def prepare_run_dir(run_dir: Path, cfg: RunConfig | None) -> RunConfig:
    """Create the run folder with ``cfg``, or reopen it: a run folder holds one configuration,
    so a ``cfg`` that differs from the one recorded there is refused. The folder is locked for
    this process (lock_run_dir)."""
    run_dir = Path(run_dir)
    cfg_file = run_dir / CONFIG_FILE
    if run_dir.exists() and not run_dir.is_dir():
        raise TrainingError(f"--out {run_dir} is a file, not a run folder")
    # The files a run rewrites or appends to, refused before any work when made read-only.
    refuse_read_only(run_dir / RUN_FILE, run_dir / LOG_FILE)
    if cfg is None and not cfg_file.is_file():
        raise TrainingError(f"{run_dir}: no {CONFIG_FILE} there; give --config to start a run")
    run_dir.mkdir(parents=True, exist_ok=True)
    lock_run_dir(run_dir)
    if cfg_file.is_file():
        try:
            loaded = load_yaml(cfg_file.read_text())
            if not isinstance(loaded, dict):
                raise yaml.YAMLError("empty, or not a mapping")
            recorded = config_from_dict(loaded)
        except (yaml.YAMLError, ValueError) as e:  # ValueError: config.ConfigError (unknown keys, bad values)
            why = yaml_error_text(e) if isinstance(e, yaml.YAMLError) else str(e).splitlines()[0]
            raise TrainingError(f"{cfg_file}: not a readable configuration ({why})") from e
        if cfg is None or to_dict(cfg) == to_dict(recorded):
            return recorded
        # Only a run folder (run.json marks one) holds a run's configuration: a config.yaml of the
        # user's own, in a folder named as --out, is never replaced.
        if not (run_dir / RUN_FILE).is_file():
            raise TrainingError(f"{cfg_file} is not a training run's configuration (no {RUN_FILE} beside it) and "
                                "differs from the one given; use a new --out")
        # A run that never saved a checkpoint trained nothing with its configuration: a
        # corrected command (a mistyped --data, a bad --set) may start it again.
        if ckpt.latest_checkpoint(run_dir) is None:
            print(f"train: {cfg_file}: replacing the configuration of a run that saved no checkpoint", file=sys.stderr)
            _write_text_atomic(cfg_file, dump_config(cfg))
            return cfg
        diffs = _diff(to_dict(recorded), to_dict(cfg))
        raise TrainingError(
            f"{cfg_file} records a different configuration than the one given "
            f"({'; '.join(diffs[:5])}); use a new --out, or omit --config to use the recorded one"
        )
    # A new run (cfg is given: a missing one was refused above).
    _write_text_atomic(cfg_file, dump_config(cfg))
    return cfg


def _diff(a, b, prefix: str = "") -> list[str]:
    out = []
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            out += _diff(a.get(k), b.get(k), f"{prefix}{k}.")
    elif a != b:
        out.append(f"{prefix[:-1]}: {a!r} -> {b!r}")
    return out


def _record_invocation(
    run_dir: Path, cfg: RunConfig, device: torch.device, argv: list[str] | None,
    world: distributed.World | None = None,
) -> None:
    path = run_dir / RUN_FILE
    info = {"config": cfg.name, "seed": cfg.seed, "invocations": []}
    if path.is_file():
        try:
            info = json.loads(path.read_text())
            if not isinstance(info, dict) or not isinstance(info.get("invocations"), list):
                raise ValueError("no list of invocations")
        except ValueError as e:  # json.JSONDecodeError is one
            raise TrainingError(f"{path}: not a run record ({e}); move it away to start the record again") from e
    info["invocations"].append(
        {
            "started": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
            "argv": list(sys.argv if argv is None else ["python -m raindrop_tools.train", *argv]),
            "device": str(device),
            "device_name": (
                torch.cuda.get_device_name(device)
                if device.type == "cuda"
                else (platform.processor() or platform.machine())
            ),
            "torch_threads": torch.get_num_threads(),
            "torch": torch.__version__,
            "python": platform.python_version(),
            "host": platform.node(),
            **({} if world is None else {"processes": world.size, "backend": torch.distributed.get_backend()}),
        }
    )
    _write_json_atomic(path, info)


class Trainer:
    """Runs the stages of one run folder. ``max_steps`` bounds the optimizer steps of this
    invocation (a checkpoint is written when it stops early; continue with resume).

    With a ``world`` (several processes, distributed.py) every rank runs a Trainer: the trained
    networks are wrapped in DistributedDataParallel, each rank takes its share of every batch,
    and only rank 0 logs and touches the run folder."""

    def __init__(
        self,
        cfg: RunConfig,
        run_dir: Path,
        device: torch.device,
        progress: bool = True,
        max_steps: int | None = None,
        log=None,
        world: distributed.World | None = None,
    ):
        self.cfg = cfg
        self.run_dir = Path(run_dir)
        self.device = device
        self.world = world
        self.writes = world is None or world.is_main  # this process writes the run folder
        self.progress = progress and self.writes
        self.steps_left = max_steps
        self.log = log or (lambda msg: tqdm.write(msg, file=sys.stderr))
        if not self.writes:
            self.log = lambda msg: None
        self.stop_requested = False
        self._dataset: RaindropDataset | None = None
        # All three networks are built from the seed in a fixed order every time, so RFN's
        # initial weights do not depend on which invocation starts stage 2.
        torch.manual_seed(cfg.seed)
        self.nets = {k: v.to(device) for k, v in build_networks(cfg.network).items()}
        self.memory_format = torch.channels_last if cfg.train.channels_last else torch.contiguous_format
        for net in self.nets.values():
            net.to(memory_format=self.memory_format)

    # ------------------------------------------------------------------ plumbing

    @property
    def dataset(self) -> RaindropDataset | MultiSourceDataset:
        """``data.train`` alone (the original single-source form, whose batches are unchanged),
        or a ``MultiSourceDataset`` of ``data.sources``."""
        if self._dataset is None:
            d = self.cfg.data
            parts = []
            for src in data_sources(self.cfg):
                self.log(
                    f"data: reading {src.path}"
                    + (f" (weight {src.weight:g}, splits {src.split}, check_outside_mask {src.check_outside_mask})"
                       if d.sources else "")
                )
                parts.append(
                    RaindropDataset(
                        src.path,
                        crop=d.crop,
                        flip=d.flip,
                        splits=src.split,
                        cache=d.cache,
                        cache_max_gib=d.cache_max_gib,
                        validate=d.validate,
                        check_outside_mask=src.check_outside_mask,
                        log=self.log,
                        visible_levels=src.visible_levels,
                        sensor_noise_levels=src.sensor_noise_levels,
                        detection_weight=src.detection_weight,
                        scale=src.scale,
                        photometric=src.photometric,
                    )
                )
            self._dataset = MultiSourceDataset(parts) if d.sources else parts[0]
        return self._dataset

    def _loader(self, stage: int, total: int, start: int) -> DataLoader:
        # Several processes: every rank reads the data; one that cannot ends them all.
        ds = self.dataset if self.world is None else self.world.agree(lambda: self.dataset, REPORTED)
        t = self.cfg.train
        if isinstance(ds, MultiSourceDataset):
            weights = [s.weight for s in data_sources(self.cfg)]
            sampler = WeightedStepBatchSampler(
                ds.sizes, weights, ds.crop, t.batch_size, self.cfg.seed, stage, total, start, flip=ds.flip
            )
            share = ", ".join(
                f"{n} {len(d)} samples x {w:.2f}" for n, d, w in zip(ds.names, ds.datasets, sampler.weights)
            )
            self.log(f"stage {stage}: sources {share}")
        else:
            sampler = StepBatchSampler(
                ds.sizes, ds.crop, t.batch_size, self.cfg.seed, stage, total, start, flip=ds.flip
            )
        split = ""
        if self.world is not None:
            split = f" ({self.world.local_batch(t.batch_size)} in each of {self.world.size} processes)"
            sampler = distributed.RankSlice(sampler, self.world.rank, self.world.size)
        self.log(
            f"stage {stage}: {len(ds)} samples, batch {t.batch_size}{split}, steps {start}->{total} "
            f"of {total} ({epochs(total, t.batch_size, len(ds)):.2f} epochs), device {self.device}"
        )
        return DataLoader(
            ds,
            batch_sampler=sampler,
            num_workers=self.cfg.data.workers,
            pin_memory=self.device.type == "cuda",
            worker_init_fn=_leave_stop_signals_to_the_trainer if self.cfg.data.workers else None,
        )

    def _optimizer(self, net: torch.nn.Module, total: int):
        t = self.cfg.train
        opt = torch.optim.Adam(net.parameters(), lr=t.lr, betas=tuple(t.betas))
        sched = torch.optim.lr_scheduler.LambdaLR(
            opt, lambda s: lr_factor(s, total, t.lr, t.lr_end, t.decay_start, t.decay_end)
        )
        return opt, sched

    def _to_device(self, batch: dict) -> dict:
        nb = self.device.type == "cuda"

        def move(v):
            v = v.to(self.device, non_blocking=nb)
            return v.contiguous(memory_format=self.memory_format) if v.dim() == 4 else v

        return {k: (move(v) if torch.is_tensor(v) else v) for k, v in batch.items()}

    def _check(self, what: str, value: torch.Tensor, stage: int, step: int, total: int, ids) -> None:
        """Raises NonFiniteLossError. Several processes: ``value`` must be the same on every
        rank (a mean over the ranks, or of synchronised gradients): they all stop together, the
        message naming the samples of every rank."""
        if not torch.isfinite(value).all():
            if self.world is not None:
                ids = [i for part in self.world.gather(list(ids)) for i in part]
            last = ckpt.latest_checkpoint(self.run_dir)
            raise NonFiniteLossError(
                f"{what} is {value.item()} at stage {stage} step {step} of {total}; "
                f"batch sample ids: {', '.join(map(str, ids))}. No checkpoint was written for this "
                f"step (latest: {last.path.name if last else 'none'})."
            )

    def _step(self, name: str, net, opt, sched, loss, stage, step, total, ids) -> float:
        """One optimizer step; returns the loss to log (several processes: their mean)."""
        if self.world is None:
            shown, what = loss.detach(), f"{name} loss"
        else:
            shown, what = self.world.mean(loss), f"{name} loss (mean of the {self.world.size} processes)"
        self._check(what, shown, stage, step, total, ids)
        opt.zero_grad(set_to_none=True)
        loss.backward()  # DistributedDataParallel: gradients averaged over the ranks here
        grad_norm = torch.nn.utils.clip_grad_norm_(net.parameters(), float("inf"))
        self._check(f"{name} gradient norm", grad_norm.detach(), stage, step, total, ids)
        opt.step()
        sched.step()
        return shown.item()

    def _save(self, stage: int, step: int, total: int, opts: dict, scheds: dict) -> Path:
        path = ckpt.checkpoint_path(self.run_dir, stage, step)
        # Finite losses and gradients can still step a weight to Inf or NaN (a learning rate
        # far too high); such a checkpoint would resume, export and ship a broken network.
        # Every process holds the same weights, so all of them stop here together.
        for name, net in self.nets.items():
            for key, value in net.state_dict().items():
                if value.is_floating_point() and not torch.isfinite(value).all():
                    last = ckpt.latest_checkpoint(self.run_dir)
                    raise NonFiniteLossError(
                        f"{name} weight {key} is not finite at stage {stage} step {step} of {total}. "
                        f"No checkpoint was written for this step (latest: {last.path.name if last else 'none'})."
                    )
        if not self.writes:
            return path
        ckpt.save_atomic(
            {
                "format": 1,
                "stage": stage,
                "step": step,
                "total_steps": total,
                "complete": step == total,
                "config": to_dict(self.cfg),
                "models": {k: v.state_dict() for k, v in self.nets.items()},
                "optimizers": {k: v.state_dict() for k, v in opts.items()},
                "schedulers": {k: v.state_dict() for k, v in scheds.items()},
            },
            path,
        )
        protect = {ckpt.checkpoint_path(self.run_dir, 1, self.cfg.train.stage1_steps)}
        ckpt.prune(self.run_dir, stage, self.cfg.train.keep_checkpoints, protect)
        return path

    def _log_line(self, record: dict) -> None:
        if not self.writes:
            return
        with open(self.run_dir / LOG_FILE, "a") as f:
            f.write(json.dumps(record) + "\n")

    def _load_models(self, state: dict) -> None:
        for k, net in self.nets.items():
            net.load_state_dict(state["models"][k])

    def init_from(self, source: str | os.PathLike) -> Path:
        """Fine-tuning: load the network weights (all three; not the optimizers, schedulers or
        step) of a checkpoint file, or of a run folder's best checkpoint (``init_checkpoint``).
        Refused once the run has checkpoints of its own (those decide where it continues)."""
        latest = ckpt.latest_checkpoint(self.run_dir)
        if latest is not None:
            raise TrainingError(
                f"--init-from: {self.run_dir} already has checkpoints ({latest.path.name}); "
                "--init-from only starts a run (continue this one with --resume, without --init-from)"
            )
        path = init_checkpoint(source)
        if path.is_dir():
            return self._init_from_model_folder(path)
        state = ckpt.load_checkpoint(path, self.device)  # refuses a file without networks
        missing = [k for k in self.nets if k not in state["models"]]
        if missing:
            raise TrainingError(f"--init-from {path}: checkpoint lacks network(s) {', '.join(missing)}")
        for k, net in self.nets.items():
            try:
                net.load_state_dict(state["models"][k])
            except RuntimeError as e:
                first = str(e).strip().splitlines()
                raise TrainingError(
                    f"--init-from {path}: the {k} weights do not fit this configuration's network "
                    f"(network.* must match the checkpoint's; {first[1].strip() if len(first) > 1 else first[0]})"
                ) from None
            net.to(memory_format=self.memory_format)
        self.log(
            f"init: network weights from {path} (stage {state.get('stage')}, step {state.get('step')}, "
            f"config {state.get('config', {}).get('name')}); optimizers start fresh"
        )
        return path

    def _init_from_model_folder(self, folder: Path) -> Path:
        """Fine-tuning from an exported model folder (models/<config>): the weights come back
        from the ONNX graphs (onnx_weights.py), BatchNorms folded into identities."""
        export_info = folder / "export.json"
        info: dict = {}
        if export_info.is_file():
            try:
                info = json.loads(export_info.read_text())
            except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
                raise TrainingError(f"--init-from {folder}: its export.json cannot be read ({e})") from None
            if not isinstance(info, dict):
                raise TrainingError(f"--init-from {folder}: its export.json is not a JSON object")
        quantized_from = info.get("quantized_from")
        if quantized_from:
            # Its int8 convolutions' weights are computed from stored integers, not stored.
            raise TrainingError(
                f"--init-from {folder}: an int8 folder (quantized from {quantized_from}) cannot be fine-tuned; "
                "start from the float folder it was quantized from"
            )
        if not self.cfg.train.freeze_batchnorm:
            raise TrainingError(
                f"--init-from {folder}: an exported model folder has its BatchNorms folded into the convolutions; "
                "fine-tune it with train.freeze_batchnorm: true (in the config, or --set train.freeze_batchnorm=true)"
            )
        if info:
            theirs = info.get("network", {})
            if not isinstance(theirs, dict) or not all(isinstance(f, dict) for f in theirs.values()):
                raise TrainingError(f"--init-from {folder}: its export.json's network is not a table of networks' settings")
            ours = to_dict(self.cfg)["network"]
            for net_name, fields in theirs.items():
                for key, value in fields.items():
                    if net_name in ours and key in ours[net_name] and ours[net_name][key] != value:
                        raise TrainingError(
                            f"--init-from {folder}: network.{net_name}.{key} is {ours[net_name][key]!r} here but "
                            f"{value!r} in the model (its export.json); use the model's network settings"
                        )
        try:
            diffs = onnx_weights.load_model_folder(self.nets, folder)
        except onnx_weights.OnnxWeightsError as e:
            raise TrainingError(f"--init-from {e}") from None
        for net in self.nets.values():
            net.to(device=self.device, memory_format=self.memory_format)
        self.log(
            f"init: network weights from the ONNX graphs of {folder} (largest difference to ONNX Runtime "
            f"{max(diffs.values()):.2g}); BatchNorm frozen; optimizers start fresh"
        )
        return folder

    def _budget_exhausted(self) -> bool:
        """Several processes: true on every rank when one of them was asked to stop (a signal
        reaches the ranks at different moments; they must stop after the same step)."""
        stop = self.stop_requested
        if self.world is not None:
            stop = self.world.any(stop)
            if stop:
                self.stop_requested = True
        return stop or (self.steps_left is not None and self.steps_left <= 0)

    # ------------------------------------------------------------------ stages

    def stage1_complete(self) -> bool:
        return ckpt.checkpoint_path(self.run_dir, 1, self.cfg.train.stage1_steps).is_file() or bool(
            ckpt.list_checkpoints(self.run_dir, 2)
        )

    def _starting_point(self, stage: int, resume: bool, map_location) -> dict | None:
        """What the run folder says about ``stage``: None when stage 1 is complete already,
        else ``{"state": checkpoint to continue from or None, "models": checkpoint whose
        networks to start from or None}``."""
        latest = ckpt.latest_checkpoint(self.run_dir)
        if stage == 1:
            if self.stage1_complete():
                if not resume:
                    raise TrainingError(f"{self.run_dir}: stage 1 is already done; use --resume or a new --out")
                self.log("stage 1: already complete")
                return None
            if latest is not None:
                return self._continue_from(latest, "checkpoints", resume, map_location)
            return {"state": None, "models": None}
        s2 = ckpt.latest_checkpoint(self.run_dir, 2)
        if s2 is not None:
            return self._continue_from(s2, "stage-2 checkpoints", resume, map_location)
        s1 = ckpt.checkpoint_path(self.run_dir, 1, self.cfg.train.stage1_steps)
        if not s1.is_file():
            raise TrainingError(f"{self.run_dir}: stage 2 needs the end of stage 1 ({s1.name}); run --stage 1 first")
        return {"state": None, "models": ckpt.load_checkpoint(s1, map_location)}

    def _continue_from(self, ref: ckpt.CheckpointRef, what: str, resume: bool, map_location) -> dict:
        if not resume:
            raise TrainingError(
                f"{self.run_dir} already has {what} ({ref.path.name}); pass --resume to continue it, or use a new --out"
            )
        state = ckpt.load_checkpoint(ref.path, map_location)
        self._trim_log(state["stage"], state["step"])
        return {"state": state, "models": None}

    def _trim_log(self, stage: int, step: int) -> None:
        """Drops the log lines past the checkpoint a run resumes from: a run killed after its
        last checkpoint logged steps that the resumed run trains and logs again."""
        path = self.run_dir / LOG_FILE
        if not self.writes or not path.is_file():
            return
        kept, dropped = [], 0
        for line in path.read_text().splitlines(keepends=True):
            try:
                r = json.loads(line)
                later = (r["stage"], r["step"]) > (stage, step)
            except (ValueError, KeyError, TypeError):
                later = False  # not a step record (or a torn last line): kept as it is
            if later:
                dropped += 1
            else:
                kept.append(line if line.endswith("\n") else line + "\n")
        if dropped:
            _write_text_atomic(path, "".join(kept))

    def _shared_starting_point(self, stage: int, resume: bool) -> dict | None:
        """``_starting_point`` as rank 0 finds it, on every rank (on the CPU: each rank moves
        it to its own device). Every rank starts from rank 0's networks, also in a fresh run
        (--init-from loads them on rank 0 only)."""

        def on_rank0():
            start = self._starting_point(stage, resume, "cpu")
            if start is not None and start["state"] is None and start["models"] is None:
                start["models"] = {"models": {k: {n: t.cpu() for n, t in net.state_dict().items()}
                                              for k, net in self.nets.items()}}
            return start

        return self.world.share(on_rank0, REPORTED)

    def run_stage(self, stage: int, resume: bool) -> str:
        """Run (or continue) one stage. Returns "done", "skipped" or "stopped"."""
        total = self.cfg.train.stage1_steps if stage == 1 else self.cfg.train.stage2_steps
        names = ["rdn", "rrn"] if stage == 1 else ["rfn"]
        if self.world is None:
            begin = self._starting_point(stage, resume, self.device)
        else:
            begin = self._shared_starting_point(stage, resume)
        if begin is None:
            return "skipped"
        start = 0
        state = begin["state"]
        if begin["models"] is not None:
            self._load_models(begin["models"])
        opts, scheds = {}, {}
        for n in names:
            opts[n], scheds[n] = self._optimizer(self.nets[n], total)
        if state is not None:
            self._load_models(state)
            for n in names:
                opts[n].load_state_dict(state["optimizers"][n])
                scheds[n].load_state_dict(state["schedulers"][n])
            start = state["step"]
            self.log(f"stage {stage}: resuming at step {start} of {total}")
        if start >= total:
            return "skipped"
        if self._budget_exhausted():
            return "stopped"
        for n, net in self.nets.items():
            net.train(n in names)
            if self.cfg.train.freeze_batchnorm:
                for m in net.modules():
                    if isinstance(m, torch.nn.BatchNorm2d):
                        m.eval()
            net.requires_grad_(n in names)
        trained = {n: self.nets[n] for n in names}  # the frozen networks are never wrapped
        if self.world is not None:
            ids = [self.device.index] if self.device.type == "cuda" else None
            trained = {n: DistributedDataParallel(net, device_ids=ids) for n, net in trained.items()}
        dilation = Dilation(self.cfg.pipeline.dilation).to(self.device)
        thr = self.cfg.pipeline.threshold
        L = self.cfg.loss
        every = self.cfg.train.checkpoint_every
        loader = self._loader(stage, total, start)
        bar = tqdm(total=total, initial=start, desc=f"stage {stage}", disable=not self.progress, dynamic_ncols=True)
        t0 = time.time()
        step = start
        saved_at = None
        try:
            for batch in loader:
                ids = batch["id"]
                b = self._to_device(batch)
                step += 1
                record = {"stage": stage, "step": step}
                if stage == 1:
                    rdn, rrn = trained["rdn"], trained["rrn"]
                    record["lr"] = scheds["rdn"].get_last_lr()[0]
                    loss = losses.detection_loss(rdn(b["rainy"]), b["mask"], b["detection_weight"])
                    record["loss_rdn"] = self._step(
                        "rdn", rdn, opts["rdn"], scheds["rdn"], loss, stage, step, total, ids
                    )
                    loss = losses.reconstruction_loss(
                        rrn(b["rainy"], b["edge"]), b["clean"], b["mask"], L.rrn_mask_weight
                    )
                    record["loss_rrn"] = self._step(
                        "rrn", rrn, opts["rrn"], scheds["rrn"], loss, stage, step, total, ids
                    )
                else:
                    rfn = trained["rfn"]
                    record["lr"] = scheds["rfn"].get_last_lr()[0]
                    with torch.no_grad():
                        r = b["rainy"]
                        m = dilation((self.nets["rdn"].probability(r) > thr).float())
                        ihat = self.nets["rrn"](r, b["edge"]).clamp(0.0, 1.0)
                        blend = m * ihat + (1.0 - m) * r
                    loss = losses.refine_loss(rfn(blend), b["clean"], L.rfn_ssim_weight, L.ssim_window)
                    record["loss_rfn"] = self._step(
                        "rfn", rfn, opts["rfn"], scheds["rfn"], loss, stage, step, total, ids
                    )
                if self.steps_left is not None:
                    self.steps_left -= 1
                bar.update(1)
                if step % self.cfg.train.log_every == 0 or step == total:
                    record["elapsed_s"] = round(time.time() - t0, 3)
                    self._log_line(record)
                    bar.set_postfix({k[5:]: f"{v:.4f}" for k, v in record.items() if k.startswith("loss_")})
                stopping = self._budget_exhausted()
                if step % every == 0 or step == total or stopping:
                    self._save(stage, step, total, opts, scheds)
                    saved_at = step
                if stopping:
                    break
        finally:
            bar.close()
        if step < total:
            why = "interrupted" if self.stop_requested else "step budget of this invocation used"
            self.log(f"stage {stage}: {why}; checkpoint at step {saved_at}; continue with --resume")
            return "stopped"
        self.log(f"stage {stage}: done ({total} steps, {time.time() - t0:.1f} s in this invocation)")
        return "done"

    def run(self, stages: list[int], resume: bool) -> str:
        if self.writes:
            ckpt.remove_stale_temporaries(self.run_dir)
        result = "done"
        for s in stages:
            result = self.run_stage(s, resume)
            if result == "stopped":
                return result
            resume = True  # stage 2 after stage 1 in the same invocation
        return result


def init_checkpoint(source: str | os.PathLike) -> Path:
    """The checkpoint ``--init-from`` loads: a ``.pt`` file as given, or in a run folder the
    latest complete stage-2 checkpoint, else the latest checkpoint of any stage. ONNX model
    folders (``models/<config>``) hold no trainable state: refused with a message."""
    p = Path(source)
    if p.is_file():
        return p
    if not p.is_dir():
        raise TrainingError(f"--init-from {p}: no such file or folder")
    refs = ckpt.list_checkpoints(p)
    if refs:
        s2 = [r for r in refs if r.stage == 2]
        return (s2 or refs)[-1].path
    if all((p / f).is_file() for f in C.FILES.values()):
        return p  # an exported model folder: weights from its graphs (onnx_weights.py)
    raise TrainingError(f"--init-from {p}: no checkpoints/stage*_step*.pt there")


def _leave_stop_signals_to_the_trainer(worker_id: int) -> None:
    """DataLoader workers ignore SIGINT and SIGTERM. Ctrl-C in a terminal, and `docker stop`
    or systemd, signal the whole process group; a worker killed that way takes the run down
    before the trainer has written its checkpoint. The trainer stops them itself when it
    exits (and they exit on their own when it dies)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)


def _install_signal_handlers(trainer: Trainer) -> dict:
    """SIGINT/SIGTERM: finish the current step, write a checkpoint, stop. A second signal
    aborts at once. Returns the previous handlers (to restore)."""

    def handler(signum, frame):
        if trainer.stop_requested:
            raise KeyboardInterrupt
        trainer.stop_requested = True
        trainer.log(f"signal {signum}: stopping after this step (a checkpoint is written); send again to abort")

    previous = {}
    for sig in (signal.SIGINT, signal.SIGTERM):
        previous[sig] = signal.getsignal(sig)
        signal.signal(sig, handler)
    return previous


def build_arg_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="python -m raindrop_tools.train", description="Two-stage training of RDN, 3RN and RFN."
    )
    ap.add_argument(
        "--config", help="run configuration (YAML); optional with --resume or for --stage 2 of an existing run"
    )
    ap.add_argument("--stage", choices=["1", "2", "all"], default="all")
    ap.add_argument("--device", choices=["auto", "cpu", "cuda"], default="auto")
    ap.add_argument("--resume", action="store_true", help="continue from the run's latest checkpoint")
    ap.add_argument("--out", help="run folder (default: tools/runs/<config name>)")
    ap.add_argument("--data", help="shortcut for --set data.train=DIR")
    ap.add_argument(
        "--set", action="append", metavar="KEY=VALUE", help="override a config key, e.g. train.stage1_steps=2000"
    )
    ap.add_argument(
        "--max-steps", type=int, help="stop (with a checkpoint) after this many optimizer steps in this invocation"
    )
    ap.add_argument(
        "--init-from",
        metavar="RUN_CHECKPOINT_OR_MODELS",
        help="fine-tune: start from the network weights of a run folder (its latest stage-2 checkpoint), a "
        "checkpoint .pt file or a committed model folder (models/<config>/: its ONNX graphs, BatchNorms folded, "
        "so the run needs train.freeze_batchnorm: true); optimizers and step counts start fresh. Only when the "
        "run has no checkpoints yet",
    )
    ap.add_argument("--threads", type=int, help="torch CPU threads (default: torch's choice)")
    ap.add_argument("--no-progress", action="store_true", help="no progress bar")
    return ap


def _open_run(args, world: distributed.World | None = None) -> tuple[RunConfig, Path]:
    """The configuration and run folder of the command line (the folder created, or its
    recorded configuration checked). Several processes: a batch they cannot split evenly is
    refused before the folder is written."""
    overrides = parse_overrides(args.set)
    if args.data:
        overrides.append(("data.train", args.data))
    cfg = load_config(args.config, overrides) if args.config else None
    if args.out:
        run_dir = Path(args.out)
    elif cfg is not None:
        run_dir = default_run_dir(cfg.name)
    else:
        raise TrainingError("give --config, or --out of an existing run")
    if cfg is None and overrides:
        raise TrainingError("--set/--data need --config (a run folder keeps its configuration)")
    if world is not None and cfg is not None:
        world.local_batch(cfg.train.batch_size)
    cfg = prepare_run_dir(run_dir, cfg)
    if world is not None:
        world.local_batch(cfg.train.batch_size)  # the recorded configuration's
    return cfg, run_dir


def _initial_weights(trainer: Trainer, args, run_dir: Path) -> None:
    """--init-from, recorded in run.json; or, for a fine-tuning run stopped before its first
    checkpoint, the weights it started from."""
    info_path = run_dir / RUN_FILE
    info = json.loads(info_path.read_text())
    if args.init_from:
        if args.resume and ckpt.latest_checkpoint(run_dir) is not None:
            raise TrainingError("--init-from with --resume: the run already has checkpoints; drop --init-from")
        info["init_from"] = str(trainer.init_from(args.init_from).resolve())
        _write_json_atomic(info_path, info)
    elif info.get("init_from") and ckpt.latest_checkpoint(run_dir) is None:
        # a fine-tuning run stopped before its first checkpoint starts again from the same weights
        trainer.init_from(info["init_from"])


def _run_stages(trainer: Trainer, args) -> str:
    stages = [1, 2] if args.stage == "all" else [int(args.stage)]
    previous = _install_signal_handlers(trainer)
    try:
        return trainer.run(stages, resume=args.resume)
    finally:
        for sig, h in previous.items():
            signal.signal(sig, h)


def _exit_status(result: str, trainer: Trainer) -> int:
    return 0 if result != "stopped" or not trainer.stop_requested else 130


def main(argv: list[str] | None = None) -> int:
    ap = build_arg_parser()
    args = ap.parse_args(argv)
    if args.threads is not None and args.threads < 1:
        ap.error(f"--threads must be at least 1, got {args.threads}")
    if args.max_steps is not None and args.max_steps < 1:
        ap.error(f"--max-steps must be at least 1, got {args.max_steps}")
    if args.threads:
        torch.set_num_threads(args.threads)
    try:
        world = distributed.from_env()
    except distributed.WorldError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    if world is not None:
        try:
            return _main_distributed(args, argv, world)
        finally:
            release_run_locks()
    try:
        cfg, run_dir = _open_run(args)
        device = choose_device(args.device)
        if device.type == "cuda":
            torch.backends.cudnn.benchmark = True
        _record_invocation(run_dir, cfg, device, argv)
        trainer = Trainer(cfg, run_dir, device, progress=not args.no_progress, max_steps=args.max_steps)
        _initial_weights(trainer, args, run_dir)
        result = _run_stages(trainer, args)
    except REPORTED as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    finally:
        release_run_locks()
    print(f"{result}: run folder {run_dir}")
    return _exit_status(result, trainer)


def _main_distributed(args, argv: list[str] | None, world: distributed.World) -> int:
    """One of several processes started by torchrun. Rank 0 opens the run folder and prints;
    every error ends all ranks (rank 0 reports it; before the process group exists, each rank
    reports its own)."""
    try:
        try:
            device = world.start(choose_device(args.device))
            if device.type == "cuda":
                torch.backends.cudnn.benchmark = True

            def open_run():
                cfg, run_dir = _open_run(args, world)
                _record_invocation(run_dir, cfg, device, argv, world)
                return cfg, run_dir

            cfg, run_dir = world.share(open_run, REPORTED)
            trainer = Trainer(
                cfg, run_dir, device, progress=not args.no_progress, max_steps=args.max_steps, world=world
            )
            world.share(lambda: _initial_weights(trainer, args, run_dir), REPORTED)
            result = _run_stages(trainer, args)
            world.barrier()  # every rank ends after rank 0's last checkpoint is written
        except REPORTED as e:
            if world.is_main or not torch.distributed.is_initialized():
                print(f"error: {e}", file=sys.stderr)
            return 2
    finally:
        world.stop()
    if world.is_main:
        print(f"{result}: run folder {run_dir}")
    return _exit_status(result, trainer)


if __name__ == "__main__":
    sys.exit(main())
