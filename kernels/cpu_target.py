"""The CPU instruction set wrt's kernels are compiled for.

Warp compiles CPU modules with ``-march=native`` by default: fastest here, but an object built on
one machine may not run on another, so none could be shipped compiled. wrt compiles for
x86-64-v3 (AVX2, FMA, BMI2; every x86 CPU since Intel Haswell, 2013, and AMD Excavator, 2015) wherever the
CPU has it, keeping Warp's other flags (its inlining thresholds): the flags are part of a module's
hash, so a module hashes the same on every such machine and the objects ``wrt.aot`` ships load
there. On any other CPU the flags stay Warp's own and modules compile on first use, as Warp's do.
The environment variable ``WRT_CPU_TARGET=native`` asks for Warp's own flags anywhere (nothing
shipped then applies: every module compiles here, once).
"""

from __future__ import annotations

import os
import platform

import warp as wp

WARP_FLAGS = wp.config.cpu_compiler_flags
"""Warp's default: ``-march=native`` and its inlining and vectorisation thresholds."""
PORTABLE_FLAGS = WARP_FLAGS.replace("-march=native", "-target-cpu x86-64-v3")
"""Warp's default for the x86-64-v3 level instead of this CPU's own instruction set."""
X86_64_V3 = frozenset("avx avx2 bmi1 bmi2 f16c fma abm movbe xsave cx16 lahf_lm popcnt pni sse4_1 sse4_2 ssse3".split())
"""The instruction sets of x86-64-v3 (and v2 below it), as Linux's /proc/cpuinfo names them
(``abm``: LZCNT; ``pni``: SSE3)."""


def cpu_compiler_flags(cpuinfo: str = "/proc/cpuinfo") -> str:
    """``PORTABLE_FLAGS`` on an x86-64 CPU whose ``cpuinfo`` lists every ``X86_64_V3`` set, else
    ``WARP_FLAGS`` (another architecture or system, an older CPU, an unreadable ``cpuinfo``, or
    ``WRT_CPU_TARGET=native``)."""
    if os.environ.get("WRT_CPU_TARGET") == "native":
        return WARP_FLAGS
    if platform.machine().lower() not in ("x86_64", "amd64") or "-march=native" not in WARP_FLAGS.split():
        return WARP_FLAGS
    try:
        with open(cpuinfo) as f:
            flags = next((line.split(":", 1)[1].split() for line in f if line.startswith("flags")), [])
    except OSError:
        return WARP_FLAGS
    return PORTABLE_FLAGS if X86_64_V3 <= set(flags) else WARP_FLAGS


def with_inline_threshold(flags: str, threshold: int) -> str:
    """``flags`` with LLVM's inline threshold ``threshold`` (Warp's flags set it to 9000)."""
    return " ".join(
        f"-mllvm=-inline-threshold={threshold}" if flag.startswith("-mllvm=-inline-threshold=") else flag
        for flag in flags.split()
    )
