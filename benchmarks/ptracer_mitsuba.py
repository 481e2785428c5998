"""wrt's light tracer against Mitsuba 3's ``ptracer`` on the same scene: the means and the noise.

Renders ``examples/mitsuba/cornell_box.xml`` (diffuse walls, a glass and a mirror ball, an area
light) with its integrator made ``ptracer``, at 32 x 32 and 256 spp, ``RUNS`` times with different
seeds in each renderer (Mitsuba 3.9.1's ``scalar_rgb`` variant), and compares the mean images'
per-channel means and the mean per-pixel variance over the runs. Both light tracers leave the
balls black where the camera sees them directly (no light path can be connected through a
delta lobe). Writes ``benchmarks/results/ptracer_mitsuba.json``.

    python -m wrt_benchmarks.ptracer_mitsuba
"""

from __future__ import annotations

import dataclasses
import pathlib
import tempfile
import time

import numpy as np

import wrt
from wrt.files import write_json

EXAMPLE = pathlib.Path(__file__).parent.parent / "examples" / "mitsuba" / "cornell_box.xml"
RESULTS = pathlib.Path(__file__).parent / "results" / "ptracer_mitsuba.json"
RES, SPP, RUNS = 32, 256, 8


def main() -> None:
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    text = EXAMPLE.read_text().replace('<integrator type="path">', '<integrator type="ptracer">')
    with tempfile.TemporaryDirectory() as folder:
        path = pathlib.Path(folder) / EXAMPLE.name
        path.write_text(text)
        t0 = time.perf_counter()
        scene = mi.load_file(str(path), res=RES, spp=SPP)
        theirs = np.stack([np.asarray(mi.render(scene, seed=s), dtype=np.float64)[..., :3] for s in range(RUNS)])
        mitsuba_s = time.perf_counter() - t0
        ours_scene = wrt.load_scene(str(path))
    ours_scene = dataclasses.replace(ours_scene, render=dataclasses.replace(ours_scene.render, width=RES, height=RES))
    t0 = time.perf_counter()
    ours = np.stack([wrt.render(ours_scene, spp=SPP, seed=s + 1).rgb.astype(np.float64) for s in range(RUNS)])
    wrt_s = time.perf_counter() - t0
    result = {
        "scene": "examples/mitsuba/cornell_box.xml, integrator ptracer",
        "size": [RES, RES],
        "spp": SPP,
        "runs": RUNS,
        "mean_rgb": {"mitsuba": theirs.mean(axis=(0, 1, 2)).tolist(), "wrt": ours.mean(axis=(0, 1, 2)).tolist()},
        "mean_pixel_variance": {
            "mitsuba": float(theirs.var(axis=0, ddof=1).mean()),
            "wrt": float(ours.var(axis=0, ddof=1).mean()),
        },
        "wall_s_all_runs": {"mitsuba_scalar_rgb": round(mitsuba_s, 2), "wrt_cpu_2_threads": round(wrt_s, 2)},
    }
    write_json(RESULTS, result)
    print(result)


if __name__ == "__main__":
    main()
