"""Participating media's device functions (wrt.kernels.volumes) against closed forms: the
Henyey-Greenstein phase function's normalisation and its sampling (a chi-square test of the
sampled directions against the density), and the homogeneous medium's free-flight estimator,
whose expected weights are the transmittance and the single-scattering integral exactly, per
channel of a chromatic medium."""

import math

import numpy as np
import pytest
import warp as wp
from scipy import stats
from wrt.kernels.volumes.henyey_greenstein import hg_sample, hg_value
from wrt.kernels.volumes.homogeneous import homogeneous_free_flight

pytestmark = pytest.mark.usefixtures("device")

G_VALUES = (-0.7, 0.0, 0.3, 0.9)


@wp.kernel
def sample_hg(wo: wp.vec3, g: float, seed: int, out: wp.array(dtype=wp.vec3), pdf: wp.array(dtype=float)):
    i = wp.tid()
    state = wp.rand_init(seed, i)
    u = wp.vec2(wp.randf(state), wp.randf(state))
    wi = hg_sample(wo, g, u)
    out[i] = wi
    pdf[i] = hg_value(wp.dot(wo, wi), g)


@wp.kernel
def eval_hg(g: float, cos_theta: wp.array(dtype=float), out: wp.array(dtype=float)):
    i = wp.tid()
    out[i] = hg_value(cos_theta[i], g)


@wp.kernel
def free_flights(
    sigma_t: wp.vec3,
    albedo: wp.vec3,
    emission: wp.vec3,
    t_max: float,
    passed: wp.array(dtype=wp.vec3),
    scattered: wp.array(dtype=wp.vec3),
    distance: wp.array(dtype=float),
    emitted: wp.array(dtype=wp.vec3),
):
    i = wp.tid()
    u = (float(i) + 0.5) / float(passed.shape[0])  # a uniform grid: the estimator's exact mean up to quadrature
    flight = homogeneous_free_flight(sigma_t, albedo, emission, t_max, u)
    emitted[i] = flight.emitted
    if flight.scattered:
        scattered[i] = flight.weight
        distance[i] = flight.t
    else:
        passed[i] = flight.weight
        distance[i] = -1.0


def hg_density(mu, g):
    """The HG density per steradian at cos = dot(wo, wi), float64."""
    return (1 - g * g) / (4 * math.pi * (1 + g * g + 2 * g * mu) ** 1.5)


@pytest.mark.parametrize("g", G_VALUES)
def test_hg_integrates_to_one_and_matches_float64(g):
    mu = np.linspace(-1.0, 1.0, 20001)
    out = wp.zeros(len(mu), dtype=float)
    wp.launch(eval_hg, dim=len(mu), inputs=[g, wp.array(mu.astype(np.float32), dtype=float), out])
    values = out.numpy().astype(np.float64)
    np.testing.assert_allclose(values, hg_density(mu, g), rtol=2e-5)
    total = 2 * math.pi * np.trapezoid(values, mu)  # over the sphere: 2 pi d(mu)
    assert abs(total - 1.0) < 2e-4, total


@pytest.mark.parametrize("g", G_VALUES)
def test_hg_sampling_passes_a_chi_square_test_against_its_density(g):
    """Directions binned by cos = dot(wo, wi) (20 bins) and azimuth about wo (8 bins), counted
    against the probability of each bin from a float64 quadrature of the density; the pdf
    ``sample`` reports is the density at the sampled direction."""
    n = 400_000
    wo = np.array([0.36, -0.48, 0.8])
    out, pdf = wp.zeros(n, dtype=wp.vec3), wp.zeros(n, dtype=float)
    wp.launch(sample_hg, dim=n, inputs=[wp.vec3(*wo), g, 7, out, pdf])
    wi = out.numpy().astype(np.float64)
    assert np.allclose(np.linalg.norm(wi, axis=1), 1.0, atol=1e-5)
    mu = np.clip(wi @ wo, -1, 1)
    np.testing.assert_allclose(pdf.numpy(), hg_density(mu, g), rtol=1e-3)
    s = np.cross(wo, [1.0, 0.0, 0.0])
    s /= np.linalg.norm(s)
    t = np.cross(wo, s)
    phi = np.arctan2(wi @ t, wi @ s) % (2 * math.pi)
    mu_edges, phi_bins = np.linspace(-1, 1, 21), 8
    counts = np.histogram2d(mu, phi, bins=[mu_edges, np.linspace(0, 2 * math.pi, phi_bins + 1)])[0]
    p_mu = np.diff([2 * math.pi * _hg_cdf(x, g) for x in mu_edges])
    expected = np.outer(p_mu, np.full(phi_bins, 1 / phi_bins)) * n
    assert expected.min() > 5  # every cell populated enough for the chi-square approximation
    chi2 = ((counts - expected) ** 2 / expected).sum()
    assert stats.chi2.sf(chi2, counts.size - 1) > 1e-3, chi2


def test_hg_sampling_fails_the_test_for_a_flipped_g():
    """The chi-square test has teeth: directions drawn with g = -0.3 against the density of 0.3."""
    n, g = 100_000, 0.3
    wo = np.array([0.0, 0.0, 1.0])
    out, pdf = wp.zeros(n, dtype=wp.vec3), wp.zeros(n, dtype=float)
    wp.launch(sample_hg, dim=n, inputs=[wp.vec3(*wo), -g, 7, out, pdf])
    mu = out.numpy().astype(np.float64) @ wo
    counts = np.histogram(mu, bins=np.linspace(-1, 1, 21))[0]
    p = np.diff([2 * math.pi * _hg_cdf(x, g) for x in np.linspace(-1, 1, 21)])
    chi2 = ((counts - n * p) ** 2 / (n * p)).sum()
    assert stats.chi2.sf(chi2, 19) < 1e-6


def _hg_cdf(x, g):
    """The HG density integrated over cos in [-1, x] (float64 quadrature), per unit azimuth."""
    fine = np.linspace(-1, x, 20001)
    return np.trapezoid(hg_density(fine, g), fine)


@pytest.mark.parametrize("t_max", [0.7, 3.0, math.inf])
def test_free_flight_weights_average_to_transmittance_and_single_scattering(t_max):
    """Over uniform samples of the one number it takes, a chromatic medium's free-flight weights
    average, per channel, to the transmittance ``exp(-sigma_t t_max)`` where the flight passes
    the segment and to ``albedo (1 - exp(-sigma_t t_max))`` (the integral of ``sigma_s T(t)``)
    where it scatters; scattering distances lie inside the segment."""
    sigma_t = np.array([0.5, 1.5, 4.0])
    albedo = np.array([0.9, 0.6, 0.3])
    n = 1 << 20
    passed, scattered = wp.zeros(n, dtype=wp.vec3), wp.zeros(n, dtype=wp.vec3)
    distance = wp.zeros(n, dtype=float)
    emitted = wp.zeros(n, dtype=wp.vec3)
    inputs = [wp.vec3(*sigma_t), wp.vec3(*albedo), wp.vec3(0.0), t_max, passed, scattered, distance, emitted]
    wp.launch(free_flights, dim=n, inputs=inputs)
    assert not emitted.numpy().any()  # a medium that does not glow adds nothing
    d = distance.numpy()
    assert np.all(d[d >= 0] < t_max)
    transmittance = np.exp(-sigma_t * t_max)
    np.testing.assert_allclose(passed.numpy().astype(np.float64).mean(axis=0), transmittance, rtol=2e-3, atol=1e-6)
    single = albedo * (1 - transmittance)
    np.testing.assert_allclose(scattered.numpy().astype(np.float64).mean(axis=0), single, rtol=2e-3)


@pytest.mark.parametrize("t_max", [0.4, 2.5])
def test_homogeneous_emission_is_the_integral_of_the_attenuated_source(t_max):
    """Every free flight of an emissive medium carries the radiance it emits along the whole
    segment, ``int_0^t_max exp(-sigma_t s) emission ds`` per channel (a float64 midpoint
    quadrature here), a clear channel's ``emission t_max`` among them, whatever the flight does."""
    sigma_t = np.array([0.5, 3.0, 0.0])
    emission = np.array([1.0, 2.0, 0.7])
    n = 4096
    passed, scattered, emitted = (wp.zeros(n, dtype=wp.vec3) for _ in range(3))
    distance = wp.zeros(n, dtype=float)
    inputs = [wp.vec3(*sigma_t), wp.vec3(0.8), wp.vec3(*emission), t_max, passed, scattered, distance, emitted]
    wp.launch(free_flights, dim=n, inputs=inputs)
    s = (np.arange(200_000) + 0.5) * (t_max / 200_000)
    integral = (np.exp(-np.outer(s, sigma_t)) * emission).sum(axis=0) * (t_max / 200_000)
    np.testing.assert_allclose(emitted.numpy(), np.broadcast_to(integral, (n, 3)), rtol=1e-5)
    assert integral[2] == pytest.approx(0.7 * t_max)


def test_the_emission_of_a_thin_medium_keeps_its_digits():
    """At optical depths from 1e-8 to 1 the emitted radiance matches float64's
    ``emission (-expm1(-sigma_t d)) / sigma_t`` to 5e-6 (``1 - exp(-x)`` in float32 would be 19%
    off at 1e-7); a clear channel over an infinite distance emits without bound, not NaN."""
    depths = np.geomspace(1e-8, 1.0, 34)
    n = len(depths)
    passed, scattered, emitted = (wp.zeros(n, dtype=wp.vec3) for _ in range(3))
    distance = wp.zeros(n, dtype=float)
    out = []
    for x in depths:
        inputs = [
            wp.vec3(x, 2.0 * x, 0.5 * x),
            wp.vec3(0.5),
            wp.vec3(1.0, 2.0, 3.0),
            1.0,
            passed,
            scattered,
            distance,
            emitted,
        ]
        wp.launch(free_flights, dim=1, inputs=inputs)
        out.append(emitted.numpy()[0].astype(np.float64))
    sigma = np.outer(depths, [1.0, 2.0, 0.5])
    expected = np.array([1.0, 2.0, 3.0]) * -np.expm1(-sigma) / sigma
    np.testing.assert_allclose(np.array(out), expected, rtol=5e-6)
    inputs = [
        wp.vec3(0.0, 1.0, 0.0),
        wp.vec3(0.5),
        wp.vec3(1.0, 1.0, 0.0),
        math.inf,
        passed,
        scattered,
        distance,
        emitted,
    ]
    wp.launch(free_flights, dim=1, inputs=inputs)
    assert emitted.numpy()[0].tolist() == [math.inf, 1.0, 0.0]
