"""First renders, as a new user runs them: whole ``wrt render`` processes with an empty Warp
kernel cache, with the shipped compiled modules (``wrt.aot``) and without them.

For each scene, in turn (shipped, compiled here, shipped, ...): ``wrt render SCENE --spp 4`` at
the scene's own size in a new, empty ``WARP_CACHE_PATH``. "compiled here" sets
``WRT_CPU_TARGET=native``: Warp's own ``-march=native`` flags, which nothing shipped matches, so
every module the render needs compiles first, as it did before modules were shipped. Then the
warm render times of both (their caches filled), in turn: what the portable x86-64-v3 objects
cost against objects for this CPU.

    python -m wrt_benchmarks.first_render [--repeats N] [--json FILE]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from importlib import resources

from wrt.host import machine_line

from . import emit
from .wholeprocess import CHILD_ENV, wrt_command

SCENES = ("path/cornell_box.toml", "whitted/refraction.toml", "raycast/raycast_mesh.toml", "mitsuba/cornell_box.xml")
TARGETS = {"shipped": {}, "compiled here": {"WRT_CPU_TARGET": "native"}}


def _render(scene: str, cache: str, env: dict, folder: str) -> float:
    """Wall seconds of one ``wrt render`` of the example ``scene`` with the kernel cache ``cache``."""
    path = str(resources.files("wrt.examples") / scene)
    command = [*wrt_command(), "render", path, "--spp", "4", "-o", os.path.join(folder, "out.exr")]
    t0 = time.perf_counter()
    done = subprocess.run(
        command, cwd=folder, capture_output=True, text=True, env={**CHILD_ENV, **env, "WARP_CACHE_PATH": cache}
    )
    seconds = time.perf_counter() - t0
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(command)} exited with {done.returncode}: {done.stderr.strip()[-500:]}")
    return seconds


def run(repeats: int, log=print) -> dict:
    results = {}
    with tempfile.TemporaryDirectory(prefix="wrt-first-") as folder:
        for scene in SCENES:
            first = {t: [] for t in TARGETS}
            warm_cache = {t: tempfile.mkdtemp(dir=folder) for t in TARGETS}
            for k in range(repeats):
                for target, env in TARGETS.items():
                    first[target].append(
                        _render(scene, tempfile.mkdtemp(dir=folder), env, folder)  # an empty cache
                    )
                    log(f"{scene}: first render, {target}: {first[target][-1]:.2f} s")
            for target, env in TARGETS.items():
                _render(scene, warm_cache[target], env, folder)  # fills the cache
            warm = {t: [] for t in TARGETS}
            for k in range(repeats):
                for target, env in TARGETS.items():
                    warm[target].append(_render(scene, warm_cache[target], env, folder))
            log(f"{scene}: warm, " + ", ".join(f"{t} {statistics.median(v):.2f} s" for t, v in warm.items()))
            results[scene] = {
                "first_render_s": {t: _summary(v) for t, v in first.items()},
                "warm_render_s": {t: _summary(v) for t, v in warm.items()},
            }
    return {
        "date": time.strftime("%Y-%m-%d"),
        "machine": machine_line(),
        "command": "wrt render SCENE --spp 4 -o out.exr, a new WARP_CACHE_PATH per first render",
        "repeats": repeats,
        "scenes": results,
    }


def _summary(times: list[float]) -> dict:
    return {"median": round(statistics.median(times), 3), "min": round(min(times), 3), "max": round(max(times), 3)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m wrt_benchmarks.first_render", description=__doc__.split("\n")[0])
    parser.add_argument("--repeats", type=int, default=3, help="runs of each (default 3)")
    parser.add_argument("--json", metavar="FILE", help="also write the results as JSON")
    args = parser.parse_args(argv)
    results = run(args.repeats, log=lambda line: print(line, file=sys.stderr, flush=True))
    emit(results, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
