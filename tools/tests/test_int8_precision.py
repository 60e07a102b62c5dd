"""int8 graphs on CPUs without VNNI (raindrop_tools.int8_precision; the C++ side and its test:
tests/remove/test_int8_precision.cpp). No torch needed."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import onnxruntime as ort
import pytest

from helpers import procedural_image
from raindrop_tools import int8_precision
from raindrop_tools.contract import FILES
from raindrop_tools.reference import RaindropRemover

MODELS = Path(__file__).resolve().parents[2] / "models"

INTEL_VNNI = "processor : 0\nflags : fpu sse2 avx2 avx512f avx512bw avx512_vnni\n"
ALDER_LAKE = "flags\t\t: fpu sse2 avx2 avx_vnni\n"
ZEN3 = "processor : 0\nflags : fpu sse2 avx avx2 fma\n"


def test_only_x86_cpus_without_vnni_saturate():
    assert not int8_precision.int8_products_saturate(INTEL_VNNI, "x86_64")
    assert not int8_precision.int8_products_saturate(ALDER_LAKE, "x86_64")
    assert int8_precision.int8_products_saturate(ZEN3, "x86_64")
    assert int8_precision.int8_products_saturate(ZEN3, "AMD64")
    # No flags line on x86: the exact kernels, which are never wrong.
    assert int8_precision.int8_products_saturate("processor : 0\n", "x86_64")
    # ARM's int8 dot products sum in 32 bits.
    assert not int8_precision.int8_products_saturate(ZEN3, "aarch64")


def _int8_folder() -> Path:
    folders = sorted(p for p in MODELS.glob("*-int8") if (p / FILES["rdn"]).is_file())
    if not folders:
        pytest.skip(f"no int8 model folder in {MODELS}")
    return folders[0]


def test_the_exact_kernels_equal_this_cpus_own(tmp_path):
    # Forced on, the option must not change an int8 graph's output on this CPU: on a VNNI CPU
    # both kernels sum exactly; on one without, the reference already uses the exact ones.
    # (That they differ where the products saturate: the test below.)
    folder = _int8_folder()
    R, E, _ = RaindropRemover(folder, threads=1).prepare(procedural_image(96, 160, seed=5))
    outs = []
    for forced in (False, True):
        so = ort.SessionOptions()
        so.intra_op_num_threads = 1
        if forced:
            so.add_session_config_entry(int8_precision.PRECISION_KEY, "1")
        else:
            int8_precision.apply(so)
        s = ort.InferenceSession(str(folder / FILES["rdn"]), so, providers=["CPUExecutionProvider"])
        outs.append(s.run(None, {"image": R})[0])
    assert np.array_equal(outs[0], outs[1])


# Run in a child process that libraindrop_hide_avx512.so (src/bench/hide_avx512.cpp) tells it has
# no AVX-512 and no VNNI, so that ONNX Runtime picks the kernels of such CPUs: the detector's
# output with the fast kernels and with the exact ones, saved to argv[2] and argv[3].
_CHILD = """
import sys
import numpy as np, onnxruntime as ort
R = np.load(sys.argv[4])
for forced, out in ((False, sys.argv[2]), (True, sys.argv[3])):
    so = ort.SessionOptions()
    so.intra_op_num_threads = 1
    if forced:
        so.add_session_config_entry(%r, "1")
    s = ort.InferenceSession(sys.argv[1], so, providers=["CPUExecutionProvider"])
    np.save(out, s.run(None, {"image": R})[0])
""" % int8_precision.PRECISION_KEY


def test_without_vnni_the_fast_kernels_saturate_and_the_exact_ones_do_not(tmp_path):
    """On this CPU's code paths (VNNI, or the exact kernels) and on those of a CPU without VNNI,
    natively: the fast kernels change the detector's output there (the saturation this module
    exists for), the exact kernels give this CPU's output to the bit. ctest passes the library's
    path; run by hand, set RAINDROP_HIDE_AVX512_LIB=build/libraindrop_hide_avx512.so."""
    lib = os.environ.get("RAINDROP_HIDE_AVX512_LIB", "")
    if not lib or not Path(lib).is_file():
        pytest.skip("RAINDROP_HIDE_AVX512_LIB is not the build's libraindrop_hide_avx512.so (x86-64 Linux; ctest sets it)")
    folder = _int8_folder()
    R, _, _ = RaindropRemover(folder, threads=1).prepare(procedural_image(96, 160, seed=0))
    np.save(tmp_path / "R.npy", R)
    so = ort.SessionOptions()
    so.intra_op_num_threads = 1
    so.add_session_config_entry(int8_precision.PRECISION_KEY, "1")
    here = ort.InferenceSession(str(folder / FILES["rdn"]), so, providers=["CPUExecutionProvider"]).run(None, {"image": R})[0]

    fast, exact = tmp_path / "fast.npy", tmp_path / "exact.npy"
    child = subprocess.run(
        [sys.executable, "-c", _CHILD, str(folder / FILES["rdn"]), str(fast), str(exact), str(tmp_path / "R.npy")],
        # Without PYTHONFAULTHANDLER: Python's own SIGSEGV handler would replace the library's.
        env={**{k: v for k, v in os.environ.items() if k != "PYTHONFAULTHANDLER"}, "LD_PRELOAD": lib},
        capture_output=True, text=True)
    if child.returncode == 3 and "cannot trap cpuid" in child.stderr:
        pytest.skip(child.stderr.strip())
    assert child.returncode == 0, child.stderr
    assert np.array_equal(np.load(exact), here)
    # Saturation moves the detector's probabilities by up to 0.3-0.9 on these images.
    assert float(np.abs(np.load(fast) - here).max()) > 0.05
