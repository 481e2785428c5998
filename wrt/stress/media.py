"""Participating media at the ends of their range: an optical depth of 1e4 and of 1e-6 (absorbing,
and glowing), media nested four deep, and heterogeneous grids of zero majorant and of optical
depth 1e4, each against a closed form (``docs/stress.md``). Every medium is held by null spheres and seen by an
orthographic camera under a uniform environment of radiance 1, so that each pixel's
transmittance is ``exp(-sum sigma_t chord)`` along its ray."""

from __future__ import annotations

import math
import os
import tempfile

import numpy as np

from ..loader import parse_scene
from ..volumes import write_vol
from .refraction import render
from .report import CaseResult

SIZE = 16
SPP = 256
WIDTH = 2.4  # the orthographic view's extent: the spheres' radius is at most 1
SIGMAS = 4.0  # standard errors an estimated mean may stray from its closed form


def _scene(media, spheres, scene_dir="."):
    """Null spheres centred at the origin, ``(radius, interior, exterior)`` each (medium names or
    None), under a uniform environment; orthographic camera along -z, path integrator."""
    camera = {"type": "orthographic", "origin": [0.0, 0.0, 3.0], "look_at": [0.0, 0.0, 0.0], "width": WIDTH}
    shapes = []
    for radius, inside, outside in spheres:
        shape = {"type": "sphere", "center": [0.0, 0.0, 0.0], "radius": radius, "material": "boundary"}
        shape.update({key: name for key, name in (("interior", inside), ("exterior", outside)) if name})
        shapes.append(shape)
    doc = {
        "render": {"integrator": "path", "width": SIZE, "height": SIZE, "spp": SPP, "max_depth": 64, "seed": 5},
        "camera": camera,
        "medium": media,
        "material": [{"name": "boundary", "type": "null"}],
        "shape": shapes,
        "light": [{"type": "environment", "radiance": [1.0, 1.0, 1.0]}],
    }
    return parse_scene(doc, file="<stress>", scene_dir=scene_dir)


def _chords(radius: float, sub: int = 16) -> np.ndarray:
    """(SIZE, SIZE, sub * sub) float64: per pixel, the length of the chord through a sphere of
    ``radius`` about the origin of the rays through a ``sub`` x ``sub`` grid of its area (0 for
    one that misses it): the box filter's samples fall uniformly over the pixel."""
    offsets = (np.arange(sub) + 0.5) / sub
    positions = ((np.arange(SIZE)[:, None] + offsets[None, :]).ravel() / SIZE * 2.0 - 1.0) * WIDTH / 2
    x, y = np.meshgrid(positions, -positions)
    chords = 2.0 * np.sqrt(np.maximum(radius * radius - x * x - y * y, 0.0))
    return chords.reshape(SIZE, sub, SIZE, sub).transpose(0, 2, 1, 3).reshape(SIZE, SIZE, sub * sub)


def _absorbed(optical: np.ndarray) -> tuple[float, float]:
    """The image mean of a pure absorber of per-ray optical depths ``optical`` (``_chords``'
    shape) and its standard error: each sample is 1 with probability its transmittance, else 0."""
    per_pixel = np.exp(-optical).mean(axis=-1)
    noise = math.sqrt(float(np.sum(per_pixel * (1.0 - per_pixel))) / SPP) / per_pixel.size
    return float(per_pixel.mean()), noise


def _row(case: str, got: np.ndarray, expected: float, noise: float, detail: dict) -> CaseResult:
    finite = bool(np.isfinite(got).all())
    error = abs(got.mean() - expected) if finite else math.inf
    bound = SIGMAS * noise + 1e-6 * expected
    return CaseResult(
        f"media: {case}",
        SIZE * SIZE * SPP,
        int(not error <= bound),
        error,
        bound,
        detail={"mean": float(got.mean()) if finite else None, "closed_form": expected, **detail},
    )


def dense_case() -> list[CaseResult]:
    """Optical depth 1e4 (sigma_t 5000 through a unit-radius sphere): an absorber lets nothing
    through (the image mean is the fraction of the view the sphere leaves free), and an albedo-1
    scatterer of the same density under the uniform sky never brightens it (energy is lost only
    to max_depth): finite, at most 1."""
    rows = []
    absorber = _scene([{"name": "ink", "sigma_t": 5000.0, "albedo": 0.0}], [(1.0, "ink", None)])
    expected, noise = _absorbed(5000.0 * _chords(1.0))
    rows.append(_row("optical depth 1e4, absorbing", render(absorber).rgb.astype(np.float64), expected, noise, {}))
    scatterer = _scene([{"name": "milk", "sigma_t": 5000.0, "albedo": 1.0}], [(1.0, "milk", None)])
    got = render(scatterer).rgb.astype(np.float64)
    finite = bool(np.isfinite(got).all())
    gain = float(got.mean() - 1.0) if finite else math.inf
    bound = SIGMAS * float(got.std()) / math.sqrt(SPP) + 1e-6
    rows.append(
        CaseResult(
            "media: optical depth 1e4, albedo 1 (no gain)",
            SIZE * SIZE * SPP,
            int(not gain <= bound),
            max(gain, 0.0),
            bound,
            detail={"mean": float(got.mean()) if finite else None},
        )
    )
    return rows


def thin_case() -> list[CaseResult]:
    """Optical depth 1e-6 (sigma_t 5e-7 through the unit sphere): the absorber's image is
    ``exp(-5e-7 chord)``, to within its (tiny) noise: float32 must not round a free-flight
    distance into a collision."""
    scene = _scene([{"name": "air", "sigma_t": 5e-7, "albedo": 0.0}], [(1.0, "air", None)])
    expected, noise = _absorbed(5e-7 * _chords(1.0))
    return [_row("optical depth 1e-6, absorbing", render(scene).rgb.astype(np.float64), expected, noise, {})]


def nested_case() -> list[CaseResult]:
    """Four concentric null spheres (radii 1, 0.8, 0.6, 0.4), each bounding its own absorber
    inside and the next outer one outside, sigma_t 0.3, 0.6, 0.9, 1.2 from the outside in: a
    ray's transmittance is ``exp(-sum_k sigma_k (chord_k - chord_{k+1}))``."""
    radii, sigmas = (1.0, 0.8, 0.6, 0.4), (0.3, 0.6, 0.9, 1.2)
    names = [f"shell{k}" for k in range(4)]
    media = [{"name": name, "sigma_t": sigma, "albedo": 0.0} for name, sigma in zip(names, sigmas)]
    spheres = [(r, names[k], names[k - 1] if k else None) for k, r in enumerate(radii)]
    chords = [_chords(r) for r in radii] + [np.zeros_like(_chords(1.0))]
    expected, noise = _absorbed(sum(s * (chords[k] - chords[k + 1]) for k, s in enumerate(sigmas)))
    got = render(_scene(media, spheres)).rgb.astype(np.float64)
    return [_row("nested four deep, absorbing", got, expected, noise, {})]


def grid_case() -> list[CaseResult]:
    """Heterogeneous grids over the unit sphere's box: one of zero majorant (all texels 0) must
    render as vacuum, exactly 1 (delta tracking takes no step), and one of extinction 5000
    everywhere (optical depth 1e4 along the diameter) absorbs as the homogeneous absorber does."""
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for case, density in (("zero majorant", 0.0), ("optical depth 1e4, absorbing", 5000.0)):
            write_vol(os.path.join(folder, "grid.vol"), np.full((2, 2, 2), density))
            grid = {"volume": "grid", "file": "grid.vol", "transform": {"translate": [-1.0] * 3, "scale": 2.0}}
            medium = {"name": "grid", "type": "heterogeneous", "sigma_t": grid, "albedo": 0.0}
            got = render(_scene([medium], [(1.0, "grid", None)], folder)).rgb.astype(np.float64)
            expected, noise = _absorbed(density * _chords(1.0))
            rows.append(_row(f"grid of {case}", got, expected, noise, {}))
    return rows


def glow_case() -> list[CaseResult]:
    """Glowing absorbers (``emission``) in the unit sphere at optical depths 1e4 (sigma_t 5000,
    emission 2500: an opaque ball of radiance ``emission / sigma_t`` = 0.5) and 1e-6 (sigma_t 5e-7,
    emission 0.01, where float32's ``1 - exp(-x)`` is 1.3% off): a ray's radiance is
    ``exp(-sigma_t chord) + emission (1 - exp(-sigma_t chord)) / sigma_t``, its emission exact on
    every sample and the sky seen through by a binary estimator."""
    rows = []
    for case, sigma_t, emission in (("optical depth 1e4", 5000.0, 2500.0), ("optical depth 1e-6", 5e-7, 0.01)):
        medium = {"name": "glow", "sigma_t": sigma_t, "albedo": 0.0, "emission": emission}
        optical = sigma_t * _chords(1.0)
        transmitted = np.exp(-optical)
        sample_mean = transmitted - emission * np.expm1(-optical) / sigma_t  # per sub-pixel position
        per_pixel_variance = sample_mean.var(axis=-1) + (transmitted * (1.0 - transmitted)).mean(axis=-1)
        noise = math.sqrt(float(per_pixel_variance.sum()) / SPP) / per_pixel_variance.size
        got = render(_scene([medium], [(1.0, "glow", None)])).rgb.astype(np.float64)
        rows.append(_row(f"{case}, glowing", got, float(sample_mean.mean()), noise, {}))
    return rows


def case_media(n, rng) -> list[CaseResult]:
    """The group ``media``: fixed small images whatever the ray budget."""
    return [*dense_case(), *thin_case(), *glow_case(), *nested_case(), *grid_case()]
