"""Speed-up of kernels specialised on a scene's features over the all-features kernel.

    python benchmarks/specialize.py [-o benchmarks/results/specialize.json] [--repeats R]

For each scene: the features it needs (``wrt.renderer.scene_features``), then the median wall
time of the render passes (BVH build and kernel compilation excluded, done once before timing)
with the specialised kernel and with the all-features one, on all cores; the two images must be
identical (specialisation only removes code the scene cannot reach).
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import tempfile

import numpy as np

import wrt
from wrt.device import cpu_model, init_warp
from wrt.loader import override_render
from wrt.renderer import scene_features

SCENES = [  # (scene, overrides): diffuse-only scenes first, the target of the specialisation
    ("examples/whitted/hard_shadows.toml", {"width": 640, "height": 480, "spp": 4}),
    ("examples/path/soft_shadows.toml", {"width": 320, "height": 240, "spp": 16}),
    ("examples/showcase.toml", {"width": 1280, "height": 720, "spp": 4}),
    ("examples/whitted/refraction.toml", {"width": 320, "height": 240, "spp": 4}),
    ("examples/path/cornell_box.toml", {"width": 200, "height": 200, "spp": 16}),
]


def timed(scene, specialize: bool, repeats: int):
    wrt.render(scene, specialize=specialize)  # compile, caches
    runs = [wrt.render(scene, specialize=specialize) for _ in range(repeats)]
    return statistics.median(r.render_time_s for r in runs), runs[0].rgb


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("-o", "--output", help="write the results as JSON here")
    args = parser.parse_args()
    init_warp()
    rows = []
    for path, overrides in SCENES:
        scene = override_render(wrt.load_scene(path), **overrides)
        features = scene_features(scene)
        t_all, rgb_all = timed(scene, False, args.repeats)
        t_spec, rgb_spec = timed(scene, True, args.repeats)
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
        print(f"{path:40s} {scene.render.integrator:8s} features {features.key}  all {t_all:.3f} s  specialised {t_spec:.3f} s  "
              f"x{row['speedup']:.2f}  identical={row['identical']}")
    if args.output:
        out = {"machine": {"cpu": cpu_model(), "cores": os.cpu_count(), "platform": platform.platform()}, "repeats": args.repeats, "scenes": rows}
        folder = os.path.dirname(os.path.abspath(args.output))
        os.makedirs(folder, exist_ok=True)
        with tempfile.NamedTemporaryFile("w", dir=folder, suffix=".tmp", delete=False) as f:
            json.dump(out, f, indent=2)
        os.replace(f.name, args.output)


if __name__ == "__main__":
    main()
