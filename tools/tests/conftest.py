"""Shared fixtures. Keeps every test on one CPU thread (the machine is shared)."""

from __future__ import annotations

import os
import sys
from pathlib import Path

# Test this checkout's raindrop_tools, also in subprocesses (`python -m raindrop_tools...`),
# even when the environment has it installed (editable) from another checkout, as a .venv
# shared between git worktrees does.
_TOOLS = str(Path(__file__).resolve().parents[1])
sys.path.insert(0, _TOOLS)
os.environ["PYTHONPATH"] = os.pathsep.join(p for p in (_TOOLS, os.environ.get("PYTHONPATH")) if p)

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

# Some test modules import onnxruntime before raindrop_tools: the package first, which turns
# ONNX Runtime's telemetry off (its __init__.py) for this process and its children.
import raindrop_tools  # noqa: E402,F401
import pytest  # noqa: E402

from helpers import write_dataset  # noqa: E402

try:  # torch is optional: the `-m "not torch"` selection runs without it
    import torch
except ImportError:  # pragma: no cover
    torch = None

if torch is not None:
    torch.set_num_threads(1)


@pytest.fixture(scope="session")
def tiny_dataset(tmp_path_factory):
    """6 samples of 48x64 in the CONTRACTS.md format (read-only: copy before altering)."""
    return write_dataset(tmp_path_factory.mktemp("tiny-dataset"), n=6, h=48, w=64, seed=1)


@pytest.fixture(scope="session")
def smoke_run(tmp_path_factory, tiny_dataset):
    """A finished smoke training run (both stages) and its export. Read-only for tests."""
    if torch is None:
        pytest.skip("needs torch")
    from helpers import CONFIGS
    from raindrop_tools import export, train

    base = tmp_path_factory.mktemp("smoke-run")
    run_dir, models = base / "run", base / "models"
    args = [
        "--config",
        str(CONFIGS / "smoke.yaml"),
        "--data",
        str(tiny_dataset),
        "--out",
        str(run_dir),
        "--no-progress",
    ]
    assert train.main(args) == 0
    assert export.main(["--run", str(run_dir), "--out", str(models)]) == 0
    return {"run": run_dir, "models": models, "data": tiny_dataset}


# Skips made visible to ctest (tests/CMakeLists.txt): with RAINDROP_PYTEST_SKIP_CODE set, a
# run without failures that skipped a test, or collected none, exits with that code, which
# ctest reports as "Not Run (Skipped)" rather than "Passed". A torch-only module (pytestmark
# torch) that skips at import without PyTorch does not count in a `-m "not torch"` run: its
# tests are deselected there anyway.
_skipped = []


def pytest_runtest_logreport(report):
    if report.skipped and not hasattr(report, "wasxfail"):
        _skipped.append(report.nodeid)


@pytest.hookimpl(hookwrapper=True)
def pytest_make_collect_report(collector):
    outcome = yield
    report = outcome.get_result()
    if not report.skipped:
        return
    deselects_torch = "not torch" in (collector.config.option.markexpr or "")
    if deselects_torch and torch is None and "torch" in str(report.longrepr):
        return
    _skipped.append(report.nodeid)


def pytest_sessionfinish(session, exitstatus):
    code = os.environ.get("RAINDROP_PYTEST_SKIP_CODE")
    if code and (exitstatus == pytest.ExitCode.NO_TESTS_COLLECTED or (exitstatus == pytest.ExitCode.OK and _skipped)):
        session.exitstatus = int(code)
