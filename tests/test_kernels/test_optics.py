"""Reflection, Snell refraction and Fresnel (kernels/optics.py) against closed forms in float64."""

import numpy as np
import pytest
import warp as wp
import wrt.kernels  # noqa: F401
from conftest import fresnel_dielectric64
from wrt.kernels.optics import fresnel_dielectric, reflect, refract

pytestmark = pytest.mark.usefixtures("device")  # every test on every available device


@wp.kernel
def optics_batch(
    d: wp.array(dtype=wp.vec3),
    n: wp.array(dtype=wp.vec3),
    eta: wp.array(dtype=float),
    out_r: wp.array(dtype=wp.vec3),
    out_ok: wp.array(dtype=wp.int32),
    out_t: wp.array(dtype=wp.vec3),
    out_f: wp.array(dtype=float),
):
    i = wp.tid()
    out_r[i] = reflect(d[i], n[i])
    ok, t = refract(d[i], n[i], eta[i])
    out_ok[i] = wp.where(ok, 1, 0)
    out_t[i] = t
    out_f[i] = fresnel_dielectric(-wp.dot(d[i], n[i]), eta[i])


def run(d, n, eta):
    d = np.asarray(d, np.float32).reshape(-1, 3)
    k = len(d)
    arrays = [
        wp.array(d, dtype=wp.vec3),
        wp.array(np.broadcast_to(np.asarray(n, np.float32), (k, 3)).copy(), dtype=wp.vec3),
    ]
    arrays.append(wp.array(np.broadcast_to(np.asarray(eta, np.float32), (k,)).copy(), dtype=float))
    outs = [
        wp.zeros(k, dtype=wp.vec3),
        wp.zeros(k, dtype=wp.int32),
        wp.zeros(k, dtype=wp.vec3),
        wp.zeros(k, dtype=float),
    ]
    wp.launch(optics_batch, dim=k, inputs=arrays + outs)
    r, ok, t, f = (a.numpy() for a in outs)
    return r, ok.astype(bool), t, f


def incident(theta):
    """Unit directions hitting the plane z = 0 (normal +z) from above at angles ``theta`` in the xz-plane."""
    theta = np.atleast_1d(theta)
    return np.stack([np.sin(theta), np.zeros_like(theta), -np.cos(theta)], axis=1)


def random_hemisphere(rng, k):
    d = rng.normal(size=(k, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d[:, 2] = -np.abs(d[:, 2])  # toward the surface
    return d


def test_reflection_law(rng):
    d = random_hemisphere(rng, 1000)
    r, _, _, _ = run(d, [0, 0, 1], 1.0)
    np.testing.assert_allclose(r, d - 2 * d[:, 2:3] * np.array([0, 0, 1.0]), atol=1e-7)
    np.testing.assert_allclose(r[:, 2], -d[:, 2], atol=1e-7)  # angle of reflection = angle of incidence


@pytest.mark.parametrize("n1, n2", [(1.0, 1.5), (1.5, 1.0), (1.33, 1.5), (1.0, 4.0)])
def test_snell_law_random_directions(rng, n1, n2):
    d = random_hemisphere(rng, 4000)
    _, ok, t, _ = run(d, [0, 0, 1], n1 / n2)
    sin_i = np.linalg.norm(d[:, :2], axis=1)
    assert np.array_equal(ok, n1 / n2 * sin_i <= 1.0 + 1e-6) or n1 < n2
    sin_t = np.linalg.norm(t[ok, :2], axis=1)
    np.testing.assert_allclose(n1 * sin_i[ok], n2 * sin_t, atol=1e-5)
    np.testing.assert_allclose(np.linalg.norm(t[ok], axis=1), 1.0, atol=1e-6)
    assert (t[ok, 2] < 0).all()  # continues through the surface
    plane_normal = np.cross(d[ok], [0, 0, 1.0])  # coplanar with the incident ray and the normal
    assert np.abs(np.einsum("ij,ij->i", plane_normal, t[ok])).max() < 1e-5


def test_total_internal_reflection_exactly_past_the_critical_angle():
    n = 1.5
    critical = np.arcsin(1 / n)
    angles = critical + np.array([-1e-4, -1e-5, 1e-5, 1e-4, 0.3])
    _, ok, _, f = run(incident(angles), [0, 0, 1], n)
    assert ok.tolist() == [True, True, False, False, False]
    assert (f[2:] == 1.0).all() and f[0] < 1.0


def test_fresnel_matches_float64_equations(rng):
    """Within 2e-6 of the float64 equations (on the same float32 inputs), except within 1e-2 rad
    below the critical angle where F's slope is unbounded and float32 rounding dominates."""
    theta = rng.uniform(0, np.pi / 2 - 1e-3, 3000)
    for n1, n2 in [(1.0, 1.5), (1.5, 1.0), (1.0, 2.4), (1.33, 1.0)]:
        d = incident(theta).astype(np.float32)
        _, _, _, f = run(d, [0, 0, 1], n1 / n2)
        conditioned = n1 <= n2 or np.abs(theta - np.arcsin(min(1.0, n2 / n1))) > 1e-2
        expected = fresnel_dielectric64(-d[:, 2].astype(np.float64), n1 / n2)
        np.testing.assert_allclose(f[conditioned], expected[conditioned], atol=2e-6)
        assert (f >= 0).all() and (f <= 1).all()  # energy never increases: R + T = 1 with R, T in [0, 1]


def test_fresnel_closed_forms():
    n = 1.5
    _, _, _, f = run(incident([0.0, np.arctan(n)]), [0, 0, 1], 1 / n)
    assert f[0] == pytest.approx(((n - 1) / (n + 1)) ** 2, rel=1e-6)  # normal incidence
    theta_b = np.arctan(n)  # Brewster: the p-polarised part vanishes, F = rs^2 / 2
    cos_t = np.cos(np.pi / 2 - theta_b)
    rs = (np.cos(theta_b) - n * cos_t) / (np.cos(theta_b) + n * cos_t)
    assert f[1] == pytest.approx(rs**2 / 2, rel=1e-5)


def test_index_matched_interface_is_invisible(rng):
    d = random_hemisphere(rng, 500)
    _, ok, t, f = run(d, [0, 0, 1], 1.0)
    assert ok.all() and (f == 0).all() and np.array_equal(t, d.astype(np.float32))
