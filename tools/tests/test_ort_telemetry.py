"""raindrop_tools turns ONNX Runtime's telemetry off (raindrop_tools/__init__.py).

With it on, importing onnxruntime writes a device id and an event database under the cache
folder and a file in $TMPDIR on every run; these tests run our modules in a child whose HOME,
TMPDIR and XDG_CACHE_HOME are empty folders, with ORT_DISABLE_TELEMETRY unset, and check that
the folders stay empty. (Checked by hand: without the lines in __init__.py they fail, listing
deviceid, onnxruntime.db and .ses.)
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

FIXTURE_MODELS = Path(__file__).resolve().parent / "fixtures" / "models-smoke"


def _run_in_private_places(tmp_path: Path, code: str, extra_env: dict[str, str] | None = None):
    places = {name: tmp_path / name for name in ("home", "tmp", "cache")}
    for p in places.values():
        p.mkdir()
    env = {k: v for k, v in os.environ.items() if k != "ORT_DISABLE_TELEMETRY"}
    env.update(HOME=str(places["home"]), TMPDIR=str(places["tmp"]), XDG_CACHE_HOME=str(places["cache"]))
    env.update(extra_env or {})
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    written = {name: sorted(str(f.relative_to(p)) for f in p.rglob("*")) for name, p in places.items()}
    return done, written


def test_our_modules_run_onnxruntime_without_telemetry(tmp_path):
    pytest.importorskip("onnxruntime")
    code = (
        "from raindrop_tools import reference\n"
        "import os, onnxruntime as ort\n"
        f"ort.InferenceSession({str(FIXTURE_MODELS / 'rfn.onnx')!r}, providers=['CPUExecutionProvider'])\n"
        "print(os.environ.get('ORT_DISABLE_TELEMETRY'))\n"
    )
    done, written = _run_in_private_places(tmp_path, code)
    assert written == {"home": [], "tmp": [], "cache": []}
    assert done.stdout.strip() == "1"


def test_a_value_the_user_set_is_kept(tmp_path):
    # Only the variable: nothing imports onnxruntime here, so an opted-in run sends nothing.
    done, _ = _run_in_private_places(
        tmp_path, "import os, raindrop_tools\nprint(os.environ['ORT_DISABLE_TELEMETRY'])", {"ORT_DISABLE_TELEMETRY": "0"}
    )
    assert done.stdout.strip() == "0"
