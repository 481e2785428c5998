"""The bias of adaptive sampling (``--target-error``), measured: a pixel stops when its own
samples say its error is small, so estimates that happen to be low (and low-variance) stop
earlier than high ones, and the expected image is slightly darker than the true one.

Renders a diffuse sphere on a floor under an area light (path, 32 x 24) with 64 seeds at each
target error, up to 256 spp, and compares the mean over seeds with a converged reference (2 x 4096
spp); the same for fixed 16-spp renders, whose bias is 0 up to noise. Writes
``benchmarks/results/adaptive_bias.json``; docs/performance.md quotes it.

    python -m wrt_benchmarks.adaptive_bias
"""

from __future__ import annotations

import json
import pathlib

import numpy as np

import wrt
from wrt.files import write_json

RESULTS = pathlib.Path(__file__).parent / "results" / "adaptive_bias.json"
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
SEEDS = 64
SCENE = {
    "render": {"width": 32, "height": 24, "integrator": "path"},
    "camera": {"origin": [0, 1.5, 3], "look_at": [0, 0.4, 0], "fov": 60},
    "material": [{"name": "g", "albedo": [0.6, 0.6, 0.6]}],
    "shape": [
        {"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "g"},
        {"type": "sphere", "center": [0, 0.5, 0], "radius": 0.5, "material": "g"},
    ],
    "light": [
        {"type": "area", "corner": [-0.5, 2, -0.5], "edge_u": [1, 0, 0], "edge_v": [0, 0, 1], "radiance": [5] * 3}
    ],
}


def luminance(result) -> np.ndarray:
    return result.rgb.astype(np.float64) @ LUMINANCE


def measure(targets=(0.1, 0.05)) -> dict:
    scene = wrt.parse_scene(SCENE, file="adaptive_bias")
    reference = np.mean([luminance(wrt.render(scene, spp=4096, seed=1000 + k)) for k in range(2)], axis=0)
    lit = reference > 0.01
    fixed = np.mean([luminance(wrt.render(scene, spp=16, seed=k)) for k in range(SEEDS)], axis=0)
    out = {
        "seeds": SEEDS,
        "pixels": int(lit.sum()),
        "fixed_16spp_image_bias": fixed[lit].mean() / reference[lit].mean() - 1,
    }
    for target in targets:
        runs = [wrt.render(scene, spp=256, seed=k, target_error=target) for k in range(SEEDS)]
        images = np.array([luminance(r) for r in runs])
        mean = images.mean(axis=0)
        per_pixel = (mean[lit] - reference[lit]) / reference[lit]
        out[f"target {target}"] = {
            "image_bias": mean[lit].mean() / reference[lit].mean() - 1,
            "pixel_bias_median": float(np.median(per_pixel)),
            "pixel_bias_p5": float(np.percentile(per_pixel, 5)),
            "pixel_bias_p95": float(np.percentile(per_pixel, 95)),
            "pixel_standard_error_median": float(np.median(images.std(axis=0)[lit] / np.sqrt(SEEDS) / reference[lit])),
            "mean_spp": float(np.mean([r.aovs["spp"][lit].mean() for r in runs])),
        }
    return out


def main() -> None:
    result = measure()
    write_json(RESULTS, result)
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
