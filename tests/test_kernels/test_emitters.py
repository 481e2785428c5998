"""Light sampling (kernels/lights/, kernels/sample_warps.py) against closed-form irradiance."""

import numpy as np
import pytest
import warp as wp
import wrt.kernels  # noqa: F401
from conftest import corner_form_factor
from wrt.kernels.lights import AREA, ENVIRONMENT, SPHERE_LIGHT, LightData
from wrt.kernels.lights.area import area_pdf, sample_area
from wrt.kernels.lights.environment import make_sample_environment
from wrt.kernels.lights.sphere import sample_sphere, sphere_pdf
from wrt.kernels.sample_warps import concentric_disk, cosine_hemisphere, frame, power_heuristic
from wrt.kernels.sampling import independent_1d as sample_1d

pytestmark = pytest.mark.usefixtures("device")  # every test on every available device


def one_light(kind, position=(0, 0, 0), edge_u=(0, 0, 0), edge_v=(0, 0, 0), radius=0.0, radiance=(1, 1, 1)):
    lights = LightData()
    v = lambda x: wp.array(np.asarray([x], np.float32), dtype=wp.vec3)  # noqa: E731
    f = lambda x: wp.array(np.asarray([x], np.float32), dtype=float)  # noqa: E731
    lights.type = wp.array(np.asarray([kind], np.int32), dtype=wp.int32)
    lights.position, lights.direction, lights.power = v(position), v((0, 0, 1)), v(radiance)
    lights.edge_u, lights.edge_v, lights.radius = v(edge_u), v(edge_v), f(radius)
    lights.cos_cutoff, lights.cutoff, lights.beam = f(0.0), f(0.0), f(0.0)
    return lights


sample_environment = make_sample_environment(False)


@wp.func
def sample_light(lights: LightData, i: wp.int32, p: wp.vec3, u1: float, u2: float):
    """The sampling of light ``i``'s family: ``(wi, distance, radiance, pdf)``."""
    if lights.type[i] == AREA:
        return sample_area(lights, i, p, u1, u2)
    if lights.type[i] == SPHERE_LIGHT:
        return sample_sphere(lights, i, p, u1, u2)
    wi, radiance, pdf = sample_environment(lights, i, u1, u2)
    return wi, wp.inf, radiance, pdf


@wp.func
def light_pdf(lights: LightData, i: wp.int32, p: wp.vec3, wi: wp.vec3, dist: float) -> float:
    """The density of ``sample_light`` (the environment's: uniform on the sphere)."""
    if lights.type[i] == AREA:
        return area_pdf(lights, i, p, wi, dist)
    if lights.type[i] == SPHERE_LIGHT:
        return sphere_pdf(lights, i, p, wi, dist)
    return 1.0 / (4.0 * wp.pi)


@wp.kernel
def irradiance_samples(
    lights: LightData, p: wp.vec3, n: wp.vec3, out: wp.array(dtype=float), pdf_error: wp.array(dtype=float)
):
    k = wp.tid()
    wi, dist, radiance, pdf = sample_light(lights, 0, p, sample_1d(5, k, 0, 0), sample_1d(5, k, 0, 1))
    if pdf > 0.0:
        out[k] = radiance[0] * wp.max(0.0, wp.dot(n, wi)) / pdf
        pdf_error[k] = wp.abs(light_pdf(lights, 0, p, wi, dist) - pdf) / pdf
    else:
        out[k] = 0.0
        pdf_error[k] = 0.0


def estimate(lights, p, n, count=200_000):
    out, err = wp.zeros(count, dtype=float), wp.zeros(count, dtype=float)
    wp.launch(irradiance_samples, dim=count, inputs=[lights, wp.vec3(*p), wp.vec3(*n), out, err])
    v = out.numpy().astype(np.float64)
    return v.mean(), v.std() / np.sqrt(count), err.numpy().max()


def test_parallelogram_light_irradiance_matches_the_form_factor():
    a, b, h, radiance = 2.0, 1.0, 1.5, 3.0
    # emitting downward: cross(edge_u, edge_v) = -z
    lights = one_light(AREA, position=(0, 0, h), edge_u=(0, b, 0), edge_v=(a, 0, 0), radiance=(radiance,) * 3)
    mean, err, pdf_err = estimate(lights, (0, 0, 0), (0, 0, 1))
    assert mean == pytest.approx(np.pi * radiance * corner_form_factor(a, b, h), abs=5 * err)
    assert pdf_err < 1e-4
    flipped = one_light(AREA, position=(0, 0, h), edge_u=(a, 0, 0), edge_v=(0, b, 0), radiance=(radiance,) * 3)
    assert estimate(flipped, (0, 0, 0), (0, 0, 1))[0] == 0.0  # its back faces the point: no light


def test_sphere_light_irradiance_is_pi_l_sin2():
    r, d, radiance = 0.5, 3.0, 2.0
    lights = one_light(SPHERE_LIGHT, position=(0, 0, d), radius=r, radiance=(radiance,) * 3)
    mean, err, pdf_err = estimate(lights, (0, 0, 0), (0, 0, 1))
    assert mean == pytest.approx(np.pi * radiance * (r / d) ** 2, abs=5 * err + 1e-6)
    assert pdf_err < 1e-4


@pytest.mark.parametrize("ratio", [1e-3, 3e-4, 1e-4, 1e-5, 1e-7])
def test_tiny_sphere_lights_keep_their_irradiance(ratio):
    """r/d down to 1e-7: the cone's 1 - cos(theta_max) without cancellation, so the irradiance
    pi L (r/d)^2 holds to 1e-5 (it was 5% high at 1e-3, 34% at 3e-4, and 0 from 1e-4 down)."""
    radiance = 1.0 / ratio**2  # irradiance about pi whatever the ratio
    lights = one_light(SPHERE_LIGHT, position=(0, 0, 1.0), radius=ratio, radiance=(radiance,) * 3)
    mean, err, pdf_err = estimate(lights, (0, 0, 0), (0, 0, 1), count=20_000)
    assert mean == pytest.approx(np.pi, rel=1e-5)
    assert pdf_err < 1e-5


def test_environment_irradiance_is_pi_l():
    lights = one_light(ENVIRONMENT, radiance=(0.7,) * 3)
    mean, err, _ = estimate(lights, (0, 0, 0), (0, 0, 1))
    assert mean == pytest.approx(np.pi * 0.7, abs=5 * err)


@wp.kernel
def warp_samples(
    out: wp.array(dtype=wp.vec3), disk: wp.array(dtype=wp.vec2), n: wp.vec3, rotated: wp.array(dtype=wp.vec3)
):
    k = wp.tid()
    u1, u2 = sample_1d(9, k, 0, 0), sample_1d(9, k, 0, 1)
    out[k] = cosine_hemisphere(u1, u2)
    disk[k] = concentric_disk(u1, u2)
    rotated[k] = frame(n) * out[k]


def test_warps_have_their_densities():
    count = 200_000
    out, disk, rotated = wp.zeros(count, dtype=wp.vec3), wp.zeros(count, dtype=wp.vec2), wp.zeros(count, dtype=wp.vec3)
    n = np.array([0.3, -0.5, 0.8])
    n /= np.linalg.norm(n)
    wp.launch(warp_samples, dim=count, inputs=[out, disk, wp.vec3(*n), rotated])
    d = out.numpy()
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-5)
    assert d[:, 2].mean() == pytest.approx(2 / 3, abs=0.005)  # E[cos] under cos/pi density
    assert (d[:, 2] ** 2).mean() == pytest.approx(0.5, abs=0.005)
    r2 = (disk.numpy() ** 2).sum(axis=1)
    assert r2.max() <= 1 + 1e-6 and r2.mean() == pytest.approx(0.5, abs=0.005)  # uniform disk
    w = rotated.numpy()
    np.testing.assert_allclose(w @ n, d[:, 2], atol=1e-5)  # the frame maps local z onto n


@wp.kernel
def heuristic(a: wp.array(dtype=float), b: wp.array(dtype=float), out: wp.array(dtype=float)):
    k = wp.tid()
    out[k] = power_heuristic(a[k], b[k])


def test_power_heuristic_does_not_overflow():
    a = np.array([1.0, 0.0, 0.0, 8e19, 2.0, 3e38], np.float32)
    b = np.array([1.0, 0.0, 5.0, 1.0, 1e30, 3e38], np.float32)
    out = wp.zeros(len(a), dtype=float)
    wp.launch(heuristic, dim=len(a), inputs=[wp.array(a), wp.array(b), out])
    np.testing.assert_allclose(out.numpy(), [0.5, 0.0, 0.0, 1.0, 0.0, 0.5], atol=1e-7)
