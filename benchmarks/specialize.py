"""Speed-up of kernels specialised on a scene's features over the all-features kernel.

    python -m wrt_benchmarks.specialize [-o benchmarks/results/specialize.json] [--repeats R]

For each scene: the features it needs (``wrt.renderer.scene_features``), then the median wall
time of the render passes (BVH build and kernel compilation excluded, done once before timing)
with the specialised kernel and with the all-features one, on one thread, the two alternating
run by run so that drift in a shared machine's speed hits both alike; the two images must be
identical (specialisation only removes code the scene cannot reach).
"""

from __future__ import annotations

import argparse
import statistics

import numpy as np

import wrt
from wrt.device import init_warp
from wrt.files import write_json
from wrt.host import machine_info
from wrt.loader import override_render
from wrt.renderer import scene_features

SCENES = [  # (scene, overrides): diffuse-only scenes first, the target of the specialisation
    ("examples/whitted/hard_shadows.toml", {"width": 640, "height": 480, "spp": 4}),
    ("examples/path/soft_shadows.toml", {"width": 320, "height": 240, "spp": 16}),
    ("examples/showcase.toml", {"width": 1280, "height": 720, "spp": 4}),
    ("examples/whitted/refraction.toml", {"width": 320, "height": 240, "spp": 4}),
    ("examples/path/cornell_box.toml", {"width": 200, "height": 200, "spp": 16}),
]


def timed(scene, repeats: int):
    """``{specialize: (median seconds, image)}`` from alternating one-thread renders."""
    images = {spec: wrt.render(scene, specialize=spec, threads=1).rgb for spec in (False, True)}  # compile, caches
    times = {False: [], True: []}
    for _ in range(repeats):
        for spec in (False, True):
            times[spec].append(wrt.render(scene, specialize=spec, threads=1).render_time_s)
    return {spec: (statistics.median(times[spec]), images[spec]) for spec in (False, True)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("-o", "--output", help="write the results as JSON here")
    args = parser.parse_args()
    init_warp()
    rows = []
    for path, overrides in SCENES:
        scene = override_render(wrt.load_scene(path), **overrides)
        features = scene_features(scene)
        runs = timed(scene, args.repeats)
        (t_all, rgb_all), (t_spec, rgb_spec) = runs[False], runs[True]
        row = {
            "scene": path,
            **overrides,
            "integrator": scene.render.integrator,
            "features": {k: v for k, v in vars(features).items()},
            "all_features_s": t_all,
            "specialised_s": t_spec,
            "speedup": t_all / t_spec,
            "identical": bool(np.array_equal(rgb_all, rgb_spec)),
        }
        rows.append(row)
        print(
            f"{path:40s} {scene.render.integrator:8s} features {features.key}  all {t_all:.3f} s  specialised "
            f"{t_spec:.3f} s  "
            f"x{row['speedup']:.2f}  identical={row['identical']}"
        )
    if args.output:
        out = {"machine": machine_info(), "threads": 1, "repeats": args.repeats, "scenes": rows}
        write_json(args.output, out)


if __name__ == "__main__":
    main()
