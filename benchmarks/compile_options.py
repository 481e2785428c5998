"""What Warp's CPU compile options cost and buy: for each setting, the compile time of an
integrator's all-features module and the render time of an example with it.

Each setting runs in a process of its own with an empty kernel cache: ``optimization_level``
(Warp's default on the CPU: 2) and the LLVM inlining thresholds Warp adds by default
(``-inline-threshold=9000``, ``-inline-cold-callsite-threshold=3000``) against LLVM's own. The
render is the all-features kernel (``specialize=False``) on one thread, the fastest of
``repeats`` launches of the whole image, so that only the code's speed differs.

    python -m wrt_benchmarks.compile_options [--repeats N] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

from wrt.host import machine_line

from . import emit

INLINING = "-mllvm=-inline-threshold=9000 -mllvm=-inline-cold-callsite-threshold=3000"
SETTINGS = {
    "default (O2, Warp's inlining)": {},
    "O1": {"optimization_level": 1},
    "O3": {"optimization_level": 3},
    "LLVM's inlining": {"drop": INLINING},
    "O1, LLVM's inlining": {"optimization_level": 1, "drop": INLINING},
}
CASES = {  # integrator: (example scene, width, height, spp)
    "path": ("path/cornell_box.toml", 200, 200, 16),
    "whitted": ("whitted/refraction.toml", 320, 240, 4),
}


def measure(setting: dict, integrator: str, repeats: int) -> dict:
    """In this process: compile ``integrator``'s all-features module under ``setting`` (the
    kernel cache must be empty) and time its renders."""
    import warp as wp
    from wrt.kernels.features import ALL
    from wrt.kernels.variants import render_kernel

    import wrt
    from wrt.aot import load

    wp.config.quiet = True
    if "optimization_level" in setting:
        wp.config.optimization_level = setting["optimization_level"]
    if "drop" in setting:
        wp.config.cpu_compiler_flags = " ".join(wp.config.cpu_compiler_flags.replace(setting["drop"], "").split())
    kernel = render_kernel(integrator, ALL)
    t0 = time.perf_counter()
    load(kernel.module, "cpu")
    compile_s = time.perf_counter() - t0
    scene_file, width, height, spp = CASES[integrator]
    scene = wrt.loader.override_render(
        wrt.load_scene(os.path.join(os.path.dirname(wrt.examples.__file__), scene_file)),
        width=width,
        height=height,
        spp=spp,
    )
    renders = [wrt.render(scene, specialize=False, threads=1).render_time_s for _ in range(repeats)]
    return {"compile_s": round(compile_s, 2), "render_s": round(min(renders), 4), "flags": wp.config.cpu_compiler_flags}


def run(repeats: int, log=print) -> dict:
    results = {}
    for integrator in CASES:
        for name, setting in SETTINGS.items():
            with tempfile.TemporaryDirectory(prefix="wrt-options-") as cache:
                code = (
                    "import json, sys; from wrt_benchmarks.compile_options import measure; "
                    f"print(json.dumps(measure({setting!r}, {integrator!r}, {repeats})))"
                )
                env = dict(os.environ, WARP_CACHE_PATH=cache)
                done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
                row = json.loads(done.stdout.strip().splitlines()[-1])
            results.setdefault(integrator, {})[name] = row
            log(f"{integrator}, {name}: compile {row['compile_s']:.1f} s, render {row['render_s']:.3f} s")
    return {
        "date": time.strftime("%Y-%m-%d"),
        "machine": machine_line(),
        "cases": {k: f"{v[0]}, {v[1]} x {v[2]}, {v[3]} spp, all-features kernel, 1 thread" for k, v in CASES.items()},
        "repeats": repeats,
        "results": results,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m wrt_benchmarks.compile_options", description=__doc__.split("\n")[0]
    )
    parser.add_argument("--repeats", type=int, default=5, help="renders per setting, the fastest counted (default 5)")
    parser.add_argument("--json", metavar="FILE", help="also write the results as JSON")
    args = parser.parse_args(argv)
    results = run(args.repeats, log=lambda line: print(line, file=sys.stderr, flush=True))
    emit(results, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
