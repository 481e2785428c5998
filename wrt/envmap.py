"""Environment maps on the host: reading the image and building its importance-sampling distribution.

An environment map is an equirectangular (latitude-longitude) image of linear RGB radiance, laid
out as Mitsuba 3's ``envmap``: in the light's own frame, where +y is up, the direction of polar
angle theta (from +y) and azimuth phi is ``(sin theta sin phi, cos theta, -sin theta cos phi)``,
with ``u = phi / (2 pi)`` across and ``v = theta / pi`` down the image. The image is looked up
bilinearly, as Mitsuba does: pixel column ``i`` sits at ``u = (i + 1/2) / W`` and wraps around
in u; row ``j`` sits at ``v = j / (H - 1)`` (row 0 the +y pole, row H - 1 the -y pole).

The lookup is therefore bilinear over cells between neighbouring pixel centres: ``H - 1`` rows
of ``W`` cells, cell ``(j, i)`` between rows ``j, j + 1`` and columns ``i, i + 1`` (mod W). The
sampling density is constant in solid angle over each cell, proportional to the mean luminance
of its four corners: a direction is drawn by choosing a row from the marginal distribution,
a cell within it from the row's conditional distribution, then uniformly in azimuth and in
``cos theta`` within the cell (pbrt's piecewise-constant 2D distribution, with the cells' exact
solid angles in place of the sin(theta) Jacobian).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

from .errors import listed
from .imageio import read_pixels

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])  # of linear sRGB (Rec. 709) primaries, as Mitsuba's
EXTENSIONS = (".exr", ".hdr")


class EnvironmentMapError(ValueError):
    """The file is not an environment map wrt can read; the message says why."""


def read_environment_map(path: str | os.PathLike) -> np.ndarray:
    """The linear RGB pixels (H, W, 3) float32 of an OpenEXR or Radiance HDR file, row 0 at the
    top; an alpha channel must be 1 (opaque) everywhere. Raises ``EnvironmentMapError``, whose
    message says why without the path (the loader names the file): the file is missing, not a
    regular file or too large in pixels (``wrt.imageio.read_pixels``, before a pixel is read), or
    not an image OpenImageIO reads."""
    path = os.fspath(path)
    if os.path.splitext(path)[1].lower() not in EXTENSIONS:
        raise EnvironmentMapError("must be an OpenEXR (.exr) or Radiance HDR (.hdr) file of linear radiance")
    if not os.path.lexists(path):
        raise EnvironmentMapError("no such file")
    try:
        spec, pixels = read_pixels(path, "environment map", error=EnvironmentMapError)
    except EnvironmentMapError as e:
        raise EnvironmentMapError(str(e).removeprefix(f"{path}: ")) from None
    pixels = pixels.astype(np.float32)
    names = list(spec.channelnames)
    if not {"R", "G", "B"} <= set(names):
        raise EnvironmentMapError(f"needs channels R, G, B (found {listed(names)})")
    if "A" in names and not np.all(pixels[..., names.index("A")] == 1.0):
        raise EnvironmentMapError("has an alpha channel that is not 1 everywhere (a map must be opaque)")
    if spec.height < 2:
        raise EnvironmentMapError(f"has {spec.height} row: a map needs at least 2 (the two poles)")
    rgb = np.stack([pixels[..., names.index(c)] for c in "RGB"], axis=-1)
    if not np.all(np.isfinite(rgb)) or np.any(rgb < 0.0):
        raise EnvironmentMapError("has pixels that are negative, infinite or NaN")
    return np.ascontiguousarray(rgb)


@dataclass(frozen=True, eq=False)
class EnvironmentDistribution:
    """The sampling distribution of a map of H rows and W columns.

    ``cdf`` (float32, ``H + (H - 1) (W + 1)``): the marginal CDF over the H - 1 cell rows (H
    values from 0 to 1), then each row's conditional CDF over its W cells (W + 1 values each).
    ``pdf`` (H - 1, W) float32: the solid-angle density (1/sr) of directions in each cell.
    All zero (and uniform CDFs) for a black map: there is nothing to sample.
    """

    cdf: np.ndarray
    pdf: np.ndarray


def cell_solid_angles(height: int, width: int) -> np.ndarray:
    """Solid angle (sr) of each of the (H - 1, W) cells: ``(2 pi / W) (cos theta_j - cos theta_j+1)``
    with ``theta_j = j pi / (H - 1)``."""
    cos_theta = np.cos(np.arange(height) * math.pi / (height - 1))
    return np.repeat(((cos_theta[:-1] - cos_theta[1:]) * (2.0 * math.pi / width))[:, None], width, axis=1)


def environment_distribution(rgb: np.ndarray) -> EnvironmentDistribution:
    """The distribution of ``rgb`` (H, W, 3), proportional to luminance times solid angle (float64
    sums, stored as float32)."""
    height, width = rgb.shape[:2]
    lum = np.asarray(rgb, dtype=np.float64) @ LUMINANCE
    corners = lum[:-1] + np.roll(lum[:-1], -1, axis=1) + lum[1:] + np.roll(lum[1:], -1, axis=1)
    weight = 0.25 * corners * cell_solid_angles(height, width)
    rows = weight.sum(axis=1)
    total = rows.sum()

    def cdf(w: np.ndarray, sum_w: float) -> np.ndarray:
        if sum_w <= 0.0:
            return np.linspace(0.0, 1.0, len(w) + 1)
        c = np.concatenate([[0.0], np.cumsum(w) / sum_w])
        c[-1] = 1.0
        return c

    parts = [cdf(rows, total)] + [cdf(weight[j], rows[j]) for j in range(height - 1)]
    pdf = 0.25 * corners / total if total > 0.0 else np.zeros_like(weight)
    return EnvironmentDistribution(cdf=np.concatenate(parts).astype(np.float32), pdf=pdf.astype(np.float32))
