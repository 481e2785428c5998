"""Lights at the edge of float32: sphere lights from a tenth down to 1e-7 of their distance,
against the closed-form irradiance (``docs/stress.md``)."""

from __future__ import annotations

import numpy as np

from .. import renderer
from .common import make_scene
from .report import CaseResult

SPHERE_RATIOS = (1e-1, 1e-2, 1e-3, 3e-4, 1e-4, 1e-5, 1e-6, 1e-7)  # radius / distance
SPHERE_TOLERANCE = 0.01  # relative error of the mean floor radiance


def sphere_light_case(rays, rng) -> CaseResult:
    """A sphere light of radius ``r`` one unit above a diffuse floor (albedo 0.5), radiance
    ``1 / r^2`` so that the floor's radiance stays near 0.16 whatever ``r``. A point ``p`` of the
    floor sees the whole sphere, so its irradiance is ``E = pi L (r / |c - p|)^2 cos(theta)``
    exactly, and its radiance ``albedo E / pi``. Rendered by the path integrator (next-event
    estimation and BSDF sampling, MIS), ``max_depth`` 2, 16 spp, 24 x 24 pixels of the floor
    around the point under the light. Fails when the mean rendered / closed-form ratio is off by
    more than ``SPHERE_TOLERANCE`` or any floor pixel is black or not finite; ``worst`` is the
    largest relative error over the radii."""
    worst, failures, detail = 0.0, 0, {}
    for ratio in SPHERE_RATIOS:
        centre = np.array([0.0, 1.0, 0.0])
        radiance = 1.0 / ratio**2
        scene = make_scene(
            shapes=[{"type": "plane", "point": [0.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0], "material": "floor"}],
            materials=[{"name": "floor", "albedo": [0.5, 0.5, 0.5]}],
            lights=[{"type": "sphere", "center": centre.tolist(), "radius": ratio, "radiance": [radiance] * 3}],
            camera={"origin": [0.0, 2.0, 4.0], "look_at": [0.0, 0.0, 0.0], "fov": 2.0},
            render={"integrator": "path", "width": 24, "height": 24, "spp": 16, "max_depth": 2, "seed": 7},
        )
        result = renderer.render(scene)
        floor = result.aovs["object_id"] == 0
        p = result.aovs["position"][floor].astype(np.float64)
        to_c = centre - p
        dist2 = (to_c * to_c).sum(-1)
        expected = 0.5 * radiance * ratio**2 / dist2 * (to_c[:, 1] / np.sqrt(dist2))
        got = result.rgb[floor][:, 0].astype(np.float64)
        error = abs(got.mean() / expected.mean() - 1.0) if np.isfinite(got).all() else np.inf
        black = int(np.count_nonzero(~(got > 0.0)))
        failures += int(error > SPHERE_TOLERANCE) + black
        worst = max(worst, error)
        detail[f"r/d {ratio:g}"] = f"{got.mean() / expected.mean():.5f} of the closed form, {black} black pixels"
    return CaseResult(
        "small sphere lights: r/d 1e-1..1e-7",
        len(SPHERE_RATIOS) * 24 * 24 * 16,
        failures,
        worst,
        SPHERE_TOLERANCE,
        detail=detail,
    )


def case_small_lights(rays, rng):
    return [sphere_light_case(rays, rng)]
