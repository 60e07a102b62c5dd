"""Whether ONNX Runtime's int8 matrix products saturate on this CPU, and the session option
that makes them exact (the C++ side: include/raindrop/remove/int8_precision.h).

On x86, ONNX Runtime sums pairs of uint8 x int8 products with VPMADDUBSW, in saturating 16-bit
arithmetic, unless the CPU has VNNI (AVX512-VNNI or AVX-VNNI). Without VNNI the int8 model
folders' detector found half the drops on a real photograph. ``session.x64quantprecision``
switches to exact uint8 x uint8 kernels, whose outputs equal a VNNI CPU's bit for bit; on a VNNI
CPU it would only cost time, so it is set only where the products saturate.

Imports without torch.
"""

from __future__ import annotations

import platform
from pathlib import Path

PRECISION_KEY = "session.x64quantprecision"
_X86 = {"x86_64", "amd64", "i386", "i686", "x86"}


def int8_products_saturate(cpuinfo: str | None = None, machine: str | None = None) -> bool:
    """True on an x86 CPU without VNNI. ``cpuinfo`` (the text of /proc/cpuinfo) and ``machine``
    (platform.machine()) are for tests; where /proc/cpuinfo cannot be read on x86 the answer is
    True: the exact kernels are always correct, only slower."""
    machine = (machine if machine is not None else platform.machine()).lower()
    if machine not in _X86:
        return False
    return not cpu_has_vnni(cpuinfo)


def cpu_has_vnni(cpuinfo: str | None = None) -> bool:
    """Whether the CPU's flags (``cpuinfo``: the text of /proc/cpuinfo, read when not given) name
    VNNI (AVX512-VNNI or AVX-VNNI); False where they cannot be read."""
    if cpuinfo is None:
        try:
            cpuinfo = Path("/proc/cpuinfo").read_text()
        except OSError:
            return False
    for line in cpuinfo.splitlines():
        if line.startswith("flags"):
            return bool({"avx512_vnni", "avx_vnni"} & set(line.split(":", 1)[-1].split()))
    return False


def apply(so) -> None:
    """Set the exact-products option on an onnxruntime.SessionOptions where needed."""
    if int8_products_saturate():
        so.add_session_config_entry(PRECISION_KEY, "1")
