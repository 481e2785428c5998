"""wrt's CUDA modules compiled on a machine with no GPU: does each compile, how long does it take,
and what does each kernel need per thread.

Every module runs in a process of its own (a time limit each): ``wp.compile_aot_module(module,
arch=A, use_ptx=True)`` with Warp's NVRTC for each architecture, then ``ptxas -v`` on the PTX
(where a ``ptxas`` is on the PATH) for every kernel's registers, stack frame and spill stores and
loads. A ``ptxas`` older than the PTX Warp writes is given the PTX with its ``.version`` lowered
to what it reads: the figures are then that ``ptxas``'s, close to but not exactly the driver's.

    python -m wrt_benchmarks.cuda_compile [--modules core|all|NAME,...] [--arch 75,90] [--timeout S] [--json FILE]

``core``: the modules wrt ships as PTX (``wrt.aot.cuda_modules``: each integrator's all-features
and recording modules, the BVH build, the batch traversal and the stress kernels); ``all``: every
module ``wrt kernels`` lists for the examples. The integrators' modules are their CUDA forms
(``_cuda``: the traversal out of line, ``wrt.kernels.variants.CUDA_INLINE``).
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor

from wrt.host import machine_line

from . import emit

PTXAS_FUNCTION = re.compile(r"Compiling entry function '(\w+)' for 'sm_(\d+)'")
PTXAS_FRAME = re.compile(r"(\d+) bytes stack frame, (\d+) bytes spill stores, (\d+) bytes spill loads")
PTXAS_REGISTERS = re.compile(r"Used (\d+) registers")


def module_names(which: str) -> list[str]:
    from wrt import aot

    names = list(aot.needed_modules([aot.example_path(s) for s in aot.example_scenes()], cuda=True))
    if which == "all":
        return names
    if which == "core":  # the modules shipped as PTX
        return list(aot.cuda_modules())
    return which.split(",")


def compile_one(name: str, arch: int, folder: str) -> None:
    """In this process: compile the module ``name`` to PTX for ``arch`` into ``folder``."""
    from wrt import aot
    from wrt.device import init_warp

    init_warp()
    import warp as wp

    modules = aot.needed_modules([aot.example_path(s) for s in aot.example_scenes()], cuda=True)
    wp.compile_aot_module(modules[name], arch=arch, module_dir=folder, use_ptx=True)


def ptxas_report(ptx: str, arch: int) -> dict:
    """``ptxas -v``'s figures per kernel of the PTX file ``ptx``, by kernel name (empty where no
    ``ptxas`` is on the PATH)."""
    ptxas = shutil.which("ptxas")
    if ptxas is None:
        return {}
    text = open(ptx, "rb").read().rstrip(b"\0")
    version = subprocess.run([ptxas, "--version"], capture_output=True, text=True).stdout
    supported = re.search(r"release (\d+)\.(\d+)", version)
    if supported:  # CUDA 12.x reads PTX 8.x, 13.x reads 9.x: lower a newer .version to this ptxas's
        major, minor = int(supported.group(1)) - 4, int(supported.group(2))
        text = re.sub(rb"^\.version \d+\.\d+", f".version {major}.{minor}".encode(), text, count=1, flags=re.M)
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "module.ptx")
        with open(path, "wb") as f:
            f.write(text)
        done = subprocess.run(
            [ptxas, f"-arch=sm_{arch}", "-v", path, "-o", os.path.join(tmp, "module.cubin")],
            capture_output=True,
            text=True,
        )
    if done.returncode != 0:
        return {"ptxas error": done.stderr.strip()[-300:]}
    kernels, current = {}, None
    for line in done.stderr.splitlines():
        if m := PTXAS_FUNCTION.search(line):
            current = kernels.setdefault(m.group(1).removesuffix("_cuda_kernel_forward"), {})
        elif current is not None and (m := PTXAS_FRAME.search(line)):
            current.update(stack_bytes=int(m.group(1)), spill_stores=int(m.group(2)), spill_loads=int(m.group(3)))
        elif current is not None and (m := PTXAS_REGISTERS.search(line)):
            current["registers"] = int(m.group(1))
    return kernels


def measure(name: str, arch: int, timeout: float) -> dict:
    with tempfile.TemporaryDirectory(prefix="wrt-cuda-") as folder:
        code = f"from wrt_benchmarks.cuda_compile import compile_one; compile_one({name!r}, {arch}, {folder!r})"
        t0 = time.perf_counter()
        try:
            done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=timeout)
        except subprocess.TimeoutExpired:
            return {"status": f"not done in {timeout:.0f} s"}
        seconds = time.perf_counter() - t0
        if done.returncode != 0:
            return {"status": "FAIL", "seconds": round(seconds, 1), "error": done.stderr.strip()[-500:]}
        (ptx,) = [os.path.join(folder, f) for f in os.listdir(folder) if f.endswith(".ptx")]
        return {"status": "ok", "seconds": round(seconds, 1), "ptx_bytes": os.path.getsize(ptx)} | {
            "kernels": ptxas_report(ptx, arch)
        }


def run(names: list[str], archs: list[int], timeout: float, jobs: int, log=print) -> dict:
    tasks = [(n, a) for n in names for a in archs]

    def one(task):
        row = measure(*task, timeout)
        log(f"{task[0]} sm_{task[1]}: {row['status']}" + (f", {row['seconds']} s" if "seconds" in row else ""))
        return task, row

    with ThreadPoolExecutor(max_workers=jobs) as pool:
        rows = dict(pool.map(one, tasks))
    results = {}
    for (name, arch), row in rows.items():
        results.setdefault(name, {})[f"sm_{arch}"] = row
    return {
        "date": time.strftime("%Y-%m-%d"),
        "machine": machine_line(),
        "how": "wp.compile_aot_module(use_ptx=True) with Warp's NVRTC, one process per module and arch, "
        f"{jobs} at a time (seconds include the process's start, about 1 s); ptxas -v for the kernels",
        "timeout_s": timeout,
        "modules": results,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m wrt_benchmarks.cuda_compile", description=__doc__.split("\n")[0])
    parser.add_argument("--modules", default="core", help="core, all, or module names separated by commas")
    parser.add_argument("--arch", default="75,90", help="CUDA architectures (default 75,90)")
    parser.add_argument("--timeout", type=float, default=1800.0, help="seconds a module may take (default 1800)")
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="compiles at once (default: cores)")
    parser.add_argument("--json", metavar="FILE", help="also write the results as JSON")
    args = parser.parse_args(argv)
    archs = [int(a) for a in args.arch.split(",")]
    results = run(module_names(args.modules), archs, args.timeout, args.jobs, log=lambda s: print(s, file=sys.stderr))
    emit(results, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
