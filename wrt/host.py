"""Facts about the host machine that renders and reports need: its CPU, its usable cores, and a
summary for benchmark results and reports."""

from __future__ import annotations

import os
import platform

import numpy as np
import warp as wp


def cpu_model() -> str:
    """The host CPU's model name (from /proc/cpuinfo on Linux), else the machine type."""
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.machine()


def default_threads() -> int:
    """CPU threads available to this process (its CPU affinity where the system has one)."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def machine_info() -> dict:
    """The machine a result was measured on: CPU model, cores, threads this process may use,
    system, and the Python, Warp and numpy versions."""
    return {
        "cpu": cpu_model(),
        "cores": os.cpu_count(),
        "threads_available": default_threads(),
        "system": f"{platform.system()} {platform.release()}",
        "python": platform.python_version(),
        "warp": wp.__version__,
        "numpy": np.__version__,
    }


def machine_line(info: dict | None = None) -> str:
    """``machine_info`` in one line: "CPU, N cores, system"."""
    info = info or machine_info()
    return f"{info['cpu']}, {info['cores']} cores, {info['system']}"
