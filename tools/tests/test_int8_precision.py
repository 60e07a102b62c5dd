"""int8 graphs on CPUs without VNNI (raindrop_tools.int8_precision; the C++ side and its test
under an emulated CPU: tests/remove/test_int8_precision.cpp). No torch needed."""

from __future__ import annotations

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
    # (That the saturating kernels do differ is shown under emulation by the C++ test.)
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
