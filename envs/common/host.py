"""What a machine's floating point depends on besides the library versions: its CPU, and the SIMD code numpy runs.

numpy picks the code of its transcendental functions (``arccos``, ``exp``, ``log``, ...) at run time from what the
CPU offers, and the versions differ in the last bit: numpy 2.4's float64 ``arccos``, ``exp`` and ``log`` give other
bits on a host without AVX-512 (their ``X86_V4`` code) than on one with it. A rollout that passes such a value
through contacts can then part ways after some seconds (the Bioloid's leg kinematics take an ``arccos``; its
scripted soccer episodes differ between the two kinds of host). So the same seed gives the
same rollout on the same libraries and the same code paths; results record both (benchmarks' ``machine``, a
training run's ``versions``). ``NPY_DISABLE_CPU_FEATURES="X86_V4 AVX512_ICL AVX512_SPR"`` makes an AVX-512 host
run the other paths.
"""

from __future__ import annotations

import platform
from pathlib import Path


def cpu_name() -> str:
    """The CPU's model name (``/proc/cpuinfo``), or the platform's word for it elsewhere."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def numpy_simd() -> str:
    """The SIMD targets numpy's float64 functions run on this machine (``X86_V4`` where AVX-512 is used), joined."""
    try:
        from numpy.lib.introspect import opt_func_info  # numpy 2.0 and later
    except ImportError:
        return "not told (numpy before 2.0)"
    found = opt_func_info(signature="float64")
    return " ".join(sorted({t["current"] for kinds in found.values() for t in kinds.values()}))


def numerics() -> dict[str, str]:
    """The CPU and numpy's code paths, as results record them."""
    return {"cpu": cpu_name(), "numpy_simd": numpy_simd()}
