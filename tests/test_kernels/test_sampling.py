"""The samplers (wrt.kernels.sampling) and pixel filters (wrt.kernels.camera), checked on their numbers:
uniformity, the stratification each sampler promises, determinism, and faster convergence
where the theory says so."""

import math

import numpy as np
import pytest
import warp as wp
from wrt.kernels.camera import (
    BOX,
    GAUSSIAN,
    GAUSSIAN_RADIUS,
    GAUSSIAN_SIGMA,
    TENT,
    filter_offset,
)
from wrt.kernels.sampling import Sampler, sample_1d, sample_2d

from wrt.device import SAMPLER_CODES, sampler_data

pytestmark = pytest.mark.usefixtures("device")  # every test on every available device


@wp.kernel
def draw(
    sampler: Sampler,
    first_pixel: wp.int32,
    dim: wp.int32,
    out2: wp.array2d(dtype=wp.vec2),
    out1: wp.array2d(dtype=float),
):
    p, s = wp.tid()
    out2[p, s] = sample_2d(sampler, first_pixel + p, s, dim)
    out1[p, s] = sample_1d(sampler, first_pixel + p, s, dim + 7)


def samples(kind: str, pixels: int, spp: int, dim: int = 2, seed: int = 3, first_pixel: int = 0):
    """(pixels, spp, 2) points of a 2D dimension pair and (pixels, spp) values of a 1D dimension."""
    out2 = wp.zeros((pixels, spp), dtype=wp.vec2)
    out1 = wp.zeros((pixels, spp), dtype=float)
    wp.launch(draw, dim=(pixels, spp), inputs=[sampler_data(kind, spp, seed), first_pixel, dim, out2, out1])
    return out2.numpy(), out1.numpy()


@pytest.mark.parametrize("kind", list(SAMPLER_CODES))
def test_every_sampler_is_uniform_in_range(kind):
    pts, vals = samples(kind, 2000, 16)
    for u in (pts[..., 0].ravel(), pts[..., 1].ravel(), vals.ravel()):
        assert u.min() >= 0.0 and u.max() < 1.0
        counts = np.histogram(u, bins=32, range=(0, 1))[0]
        expected = len(u) / 32
        chi2 = ((counts - expected) ** 2 / expected).sum()
        assert chi2 < 70, chi2  # 31 degrees of freedom: p < 1e-4 beyond 70
    # the two coordinates of a pair, and different dimensions, are not correlated
    assert abs(np.corrcoef(pts[..., 0].ravel(), pts[..., 1].ravel())[0, 1]) < 0.03
    assert abs(np.corrcoef(pts[..., 0].ravel(), vals.ravel())[0, 1]) < 0.03


@pytest.mark.parametrize("spp, grid", [(16, (4, 4)), (12, (3, 4)), (7, (1, 7))])
def test_stratified_puts_one_sample_in_each_stratum(spp, grid):
    pts, vals = samples("stratified", 50, spp)
    nx, ny = grid
    for p in range(50):
        cells = np.floor(pts[p, :, 0] * nx).astype(int) + nx * np.floor(pts[p, :, 1] * ny).astype(int)
        assert sorted(cells) == list(range(spp))
        assert sorted(np.floor(vals[p] * spp).astype(int)) == list(range(spp))


def elementary_intervals(m: int):
    """All (0, m, 2)-net box shapes in base 2: 2^a x 2^(m-a) cells."""
    return [(1 << a, 1 << (m - a)) for a in range(m + 1)]


@pytest.mark.parametrize("spp", [16, 64])
def test_sobol_points_are_a_02_net(spp):
    m = int(math.log2(spp))
    pts, vals = samples("sobol", 40, spp)
    for p in range(40):
        for nx, ny in elementary_intervals(m):
            cells = np.floor(pts[p, :, 0] * nx).astype(int) + nx * np.floor(pts[p, :, 1] * ny).astype(int)
            assert len(set(cells)) == spp, (nx, ny)
        assert len(set(np.floor(vals[p] * spp).astype(int))) == spp
    # every power of two of consecutive samples is a net too (so progressive passes stay stratified)
    first_half = pts[:, : spp // 2]
    for p in range(40):
        for nx, ny in elementary_intervals(m - 1):
            cells = np.floor(first_half[p, :, 0] * nx).astype(int) + nx * np.floor(first_half[p, :, 1] * ny).astype(int)
            assert len(set(cells)) == spp // 2


def test_pixels_and_dimensions_are_scrambled_differently():
    pts, _ = samples("sobol", 4, 16)
    assert not np.array_equal(pts[0], pts[1])
    other_dim, _ = samples("sobol", 4, 16, dim=6)
    assert not np.array_equal(pts[0], other_dim[0])


@pytest.mark.parametrize("kind", list(SAMPLER_CODES))
def test_samples_depend_only_on_their_counters(kind):
    a, _ = samples(kind, 64, 8, first_pixel=100)
    b, _ = samples(kind, 200, 8)
    assert np.array_equal(a, b[100:164])


def integrand(p):
    """A smooth function of the unit square with a known integral: exp(-(x^2 + y^2)) on [0,1]^2."""
    return np.exp(-(p[..., 0] ** 2 + p[..., 1] ** 2))


def test_better_samplers_integrate_smooth_functions_with_less_error():
    exact = (math.sqrt(math.pi) / 2 * math.erf(1.0)) ** 2
    rmse = {}
    for kind in SAMPLER_CODES:
        pts, _ = samples(kind, 4000, 64)
        estimates = integrand(pts).mean(axis=1)
        rmse[kind] = float(np.sqrt(((estimates - exact) ** 2).mean()))
        bias = abs(estimates.mean() - exact)
        assert bias < 4 * rmse[kind] / math.sqrt(4000) + 1e-6, (kind, bias)  # unbiased
    # stratified jitter: error ~ N^-1 (vs N^-0.5) in 2D; Owen-scrambled Sobol: ~ N^-1.5
    assert rmse["stratified"] < 0.25 * rmse["independent"], rmse
    assert rmse["sobol"] < 0.5 * rmse["stratified"], rmse


@wp.kernel
def offsets(kind: wp.int32, u: wp.array(dtype=float), out: wp.array(dtype=float)):
    i = wp.tid()
    out[i] = filter_offset(kind, u[i])


def filter_samples(kind: int, n: int = 200_000) -> np.ndarray:
    u = (np.arange(n) + 0.5) / n  # stratified inputs: the output is the quantile function
    out = wp.zeros(n, dtype=float)
    wp.launch(offsets, dim=n, inputs=[kind, wp.array(u.astype(np.float32)), out])
    return out.numpy().astype(np.float64)


def test_box_filter_is_uniform_over_the_pixel():
    x = filter_samples(BOX)
    assert x.min() >= -0.5 and x.max() < 0.5
    assert abs(x.mean()) < 1e-5 and abs(x.var() - 1 / 12) < 1e-4


def test_tent_filter_has_the_triangle_profile():
    x = filter_samples(TENT)
    assert x.min() > -1.0 and x.max() < 1.0
    counts = np.histogram(x, bins=20, range=(-1, 1))[0] / len(x)
    centres = np.linspace(-0.95, 0.95, 20)
    assert np.allclose(counts, (1 - np.abs(centres)) * 0.1, atol=2e-4)  # density 1 - |x|, bins 0.1 wide
    assert abs(x.var() - 1 / 6) < 1e-4  # variance of the unit tent


def test_gaussian_filter_has_sigma_half_a_pixel_truncated_at_two():
    x = filter_samples(GAUSSIAN)
    assert np.abs(x).max() <= GAUSSIAN_RADIUS + 1e-6
    sigma = GAUSSIAN_SIGMA
    edges = np.linspace(-1.5, 1.5, 13)
    counts = np.histogram(x, bins=edges)[0] / len(x)
    cdf = np.array([0.5 * (1 + math.erf(e / (sigma * math.sqrt(2)))) for e in edges])
    norm = math.erf(GAUSSIAN_RADIUS / (sigma * math.sqrt(2)))
    assert np.allclose(counts, np.diff(cdf) / norm, atol=3e-4)
    assert abs(x.std() - sigma) < 2e-3
