"""Conductors (``fresnel_conductor`` in kernels/optics.py, the ``CONDUCTOR`` material of
kernels/materials/conductor.py): the exact Fresnel reflectance of a complex index of refraction against the
complex Fresnel equations in float64, and the smooth and rough (GGX) conductor's BSDF against
closed forms, its own sampling and a white furnace."""

import numpy as np
import pytest
import warp as wp
import wrt.kernels  # noqa: F401
from conftest import make_scene
from test_materials import draw
from test_microfacet import albedo_float64, d64, g1_64
from wrt.kernels.materials import BSDF_GLOSSY, BSDF_REFLECTION, BSDF_SPECULAR, MaterialData, bsdf_flags, make_bsdf
from wrt.kernels.materials.conductor import normal_reflectance
from wrt.kernels.optics import fresnel_conductor1

import wrt
from wrt.conductors import METALS
from wrt.device import upload_materials

BSDF = make_bsdf(("conductor",), anisotropic=False)  # its family alone: a smaller module to compile
bsdf_eval = BSDF.eval

pytestmark = pytest.mark.usefixtures("device")  # every test on every available device

IORS = [  # (eta, k): gold's and aluminium's channels, a dielectric (k = 0), a lossless mirror, a dull metal
    *zip(*METALS["Au"]),
    *zip(*METALS["Al"]),
    (1.5, 0.0),
    (0.0, 1.0),
    (2.5, 0.5),
    (0.05, 20.0),
]


def fresnel_float64(cos_i, eta, k):
    """Unpolarised reflectance at a conductor: the mean of |r_s|^2 and |r_p|^2 for the complex
    index ``n = eta + i k``, with the complex cosine of the transmitted angle (Hecht, sec. 4.6)."""
    n = complex(eta, k)
    cos_t = np.sqrt(1.0 - (1.0 - cos_i**2) / n**2 + 0j)
    r_s = (cos_i - n * cos_t) / (cos_i + n * cos_t)
    r_p = (n * cos_i - cos_t) / (n * cos_i + cos_t)
    return 0.5 * (np.abs(r_s) ** 2 + np.abs(r_p) ** 2)


@wp.kernel
def fresnel_batch(cos_i: wp.array(dtype=float), eta: float, k: float, out: wp.array(dtype=float)):
    i = wp.tid()
    out[i] = fresnel_conductor1(cos_i[i], eta, k)


def fresnel_kernel(cos_i, eta, k):
    out = wp.zeros(len(cos_i), dtype=float)
    wp.launch(fresnel_batch, dim=len(cos_i), inputs=[wp.array(np.float32(cos_i), dtype=float), eta, k, out])
    return out.numpy().astype(np.float64)


@pytest.mark.parametrize("eta, k", IORS)
def test_fresnel_matches_the_complex_fresnel_equations(eta, k):
    """Over the whole range of angles, within float32 rounding; 1 at grazing incidence and
    ``((eta - 1)^2 + k^2) / ((eta + 1)^2 + k^2)`` at normal incidence."""
    cos_i = np.concatenate([np.linspace(0.0, 1.0, 201), np.cos(np.radians([85.0, 89.0, 89.9]))]).astype(np.float32)
    ours = fresnel_kernel(cos_i, eta, k)
    theirs = fresnel_float64(cos_i.astype(np.float64), eta, k)
    np.testing.assert_allclose(ours, theirs, atol=2e-6, rtol=1e-5)
    assert ours[0] == 1.0
    assert ours[200] == pytest.approx(((eta - 1) ** 2 + k**2) / ((eta + 1) ** 2 + k**2), rel=1e-6, abs=1e-7)


def test_fresnel_of_a_zero_index_is_one_at_every_angle():
    """eta = k = 0 (a channel of Mitsuba's AlSb): the limit 1, not 0/0 at normal incidence."""
    np.testing.assert_array_equal(fresnel_kernel(np.linspace(0.0, 1.0, 11), 0.0, 0.0), 1.0)


# --- the BSDF -----------------------------------------------------------------------------------

MATERIALS = {
    "gold": {"type": "conductor", "metal": "Au", "reflectance": [0.9, 0.8, 0.7]},  # smooth
    "copper": {"type": "conductor", "metal": "Cu", "roughness": 0.3},
    "lossless": {"type": "conductor", "eta": [0.0] * 3, "k": [1.0] * 3, "roughness": 0.4},  # F = 1
    "glossy": {"type": "glossy", "roughness": 0.4},
    "copper_beckmann": {"type": "conductor", "metal": "Cu", "roughness": 0.3, "distribution": "beckmann"},
    "lossless_beckmann": {"type": "conductor", "eta": [0.0] * 3, "k": [1.0] * 3, "roughness": 0.4}
    | {"distribution": "beckmann"},
    "glossy_beckmann": {"type": "glossy", "roughness": 0.4, "distribution": "beckmann"},
}
SUFFIX = {"ggx": "", "beckmann": "_beckmann"}
INDEX = {name: k for k, name in enumerate(MATERIALS)}


@pytest.fixture
def materials(device) -> MaterialData:
    scene = make_scene([], materials=[{"name": name, **params} for name, params in MATERIALS.items()])
    return upload_materials(scene, device)


def direction(theta_deg):
    t = np.radians(theta_deg)
    return np.array([np.sin(t), 0.0, np.cos(t)])


def sample(materials, name, wo, n=100_000):
    """``wi, weight, pdf, flags, f cos / pdf, bsdf_pdf(wi)`` of n samples of ``bsdf_sample``."""
    out = [wp.zeros(n, dtype=t) for t in (wp.vec3, wp.vec3, float, wp.int32, wp.vec3, float)]
    wp.launch(draw, dim=n, inputs=[materials, INDEX[name], wp.vec3(*wo), 1.0, *out])
    return [a.numpy().astype(np.float64) if a.dtype != wp.int32 else a.numpy() for a in out]


def test_flags_smooth_is_a_delta_lobe_rough_is_glossy(materials):
    @wp.kernel
    def flags_of(materials: MaterialData, out: wp.array(dtype=wp.int32)):
        out[wp.tid()] = bsdf_flags(materials, wp.tid())

    out = wp.zeros(len(MATERIALS), dtype=wp.int32)
    wp.launch(flags_of, dim=len(MATERIALS), inputs=[materials, out])
    assert out.numpy()[:2].tolist() == [BSDF_REFLECTION | BSDF_SPECULAR, BSDF_REFLECTION | BSDF_GLOSSY]


@pytest.mark.parametrize("theta", [0.0, 45.0, 80.0, 89.0])
def test_smooth_conductor_reflects_tint_times_fresnel(materials, theta):
    wo = direction(theta)
    wi, weight, pdf, flags, _, _ = sample(materials, "gold", wo, n=4)
    np.testing.assert_allclose(wi[0], wo * [-1, -1, 1], atol=1e-6)
    eta, k = METALS["Au"]
    expected = [0.9, 0.8, 0.7] * np.array([fresnel_float64(np.cos(np.radians(theta)), e, c) for e, c in zip(eta, k)])
    np.testing.assert_allclose(weight[0], expected, rtol=1e-5)
    assert pdf[0] == 1.0 and flags[0] == BSDF_REFLECTION | BSDF_SPECULAR


@wp.kernel
def eval_batch(
    materials: MaterialData, m: wp.int32, wo: wp.vec3, wi: wp.array(dtype=wp.vec3), out: wp.array(dtype=wp.vec3)
):
    i = wp.tid()
    out[i] = bsdf_eval(materials, m, wp.vec3(0.0, 0.0, 1.0), wo, wi[i])


@pytest.mark.parametrize("distribution", SUFFIX)
def test_rough_conductor_eval_is_microfacets_with_fresnel_at_the_half_vector(materials, distribution):
    """f = D(h) G1(wo) G1(wi) F(wo.h) / (4 cos_o cos_i) in float64, F of copper per channel."""
    alpha, wo = 0.3, direction(50.0)
    wi = np.array([direction(t) for t in (-70.0, -50.0, -20.0, 0.0, 30.0, 60.0)]) * [1, 0.8, 1]
    wi[:, 1] = 0.3
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    out = wp.zeros(len(wi), dtype=wp.vec3)
    wp.launch(
        eval_batch,
        dim=len(wi),
        inputs=[
            materials,
            INDEX["copper" + SUFFIX[distribution]],
            wp.vec3(*wo),
            wp.array(np.float32(wi), dtype=wp.vec3),
        ]
        + [out],
    )
    h = wo + wi
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    d = d64(h, alpha, distribution)
    cos_h = h @ wo
    fresnel = np.array([[fresnel_float64(c, e, kk) for e, kk in zip(*METALS["Cu"])] for c in cos_h])
    g = g1_64(wo, alpha, distribution) * g1_64(wi, alpha, distribution)
    expected = (d * g / (4 * wo[2] * wi[:, 2]))[:, None] * fresnel
    np.testing.assert_allclose(out.numpy(), expected, rtol=2e-4)


@pytest.mark.parametrize("distribution", SUFFIX)
@pytest.mark.parametrize("theta", [0.0, 40.0, 75.0])
def test_rough_conductor_sample_weight_is_eval_cos_over_pdf(materials, distribution, theta):
    name = "copper" + SUFFIX[distribution]
    _, weight, pdf, flags, f_cos_over_pdf, pdf_again = sample(materials, name, direction(theta))
    kept = pdf > 0
    assert kept.mean() > 0.9 and np.all(flags[kept] == BSDF_REFLECTION | BSDF_GLOSSY)
    np.testing.assert_allclose(weight[kept], f_cos_over_pdf[kept], rtol=2e-3, atol=1e-6)
    np.testing.assert_allclose(pdf_again[kept], pdf[kept], rtol=2e-3)


@pytest.mark.parametrize("distribution", SUFFIX)
@pytest.mark.parametrize("theta", [0.0, 40.0, 75.0])
def test_lossless_rough_conductor_loses_only_what_single_scattering_loses(materials, distribution, theta):
    """eta 0, k 1: F = 1 at every angle, so the directional albedo is the lossless GGX mirror's
    (float64, by hemisphere integration): 1 less the energy single scattering cannot return, and
    each sample weighs exactly what the glossy material's (reflectance 1) does."""
    wo = direction(theta)
    weight = sample(materials, "lossless" + SUFFIX[distribution], wo)[1]
    np.testing.assert_array_equal(weight, sample(materials, "glossy" + SUFFIX[distribution], wo)[1])
    expected, err = albedo_float64(wo, 0.4, distribution)
    n = len(weight)
    assert weight[:, 0].mean() == pytest.approx(expected, abs=5 * np.hypot(err, weight[:, 0].std() / np.sqrt(n)) + 1e-3)
    assert expected < {"ggx": 0.9, "beckmann": 0.995}[distribution]  # alpha 0.4: single scattering loses some


def test_white_furnace(device):
    """A lossless rough conductor sphere in a uniform environment of radiance 1 (path; a convex
    sphere sees only the sky): each pixel on it is its directional albedo at the pixel's view
    angle, so all lie between the least and the most of the float64 albedos over view angles, and
    none reflects more than 1."""
    scene = make_scene(
        [{"type": "sphere", "center": [0, 0, 0], "radius": 1.0, "material": "lossless"}],
        render={"width": 24, "height": 24, "spp": 1024, "integrator": "path", "max_depth": 8, "seed": 3},
        camera={"origin": [0, 0, 4], "look_at": [0, 0, 0], "fov": 32.0},
        materials=[{"name": "lossless", **MATERIALS["lossless"]}],
        lights=[{"type": "environment", "radiance": [1.0, 1.0, 1.0]}],
    )
    rgb = wrt.render(scene, device=device).rgb.astype(np.float64)
    y, x = np.mgrid[:24, :24] + 0.5
    sphere = rgb[np.hypot(x - 12, y - 12) < 9.5, 0]  # the sphere's disk is 10.8 pixels in radius
    albedos = [albedo_float64(direction(theta), 0.4)[0] for theta in (0.0, 20.0, 40.0, 60.0, 75.0, 85.0)]
    assert np.all(rgb[..., 1:] == rgb[..., :1])
    assert min(albedos) - 0.03 < sphere.min() and sphere.max() < max(albedos) + 0.03 < 1.0


def test_raycast_shows_the_normal_incidence_reflectance():
    f0 = np.multiply(normal_reflectance(*METALS["Au"]), [0.9, 0.8, 0.7])
    assert f0 == pytest.approx([0.87, 0.642, 0.227], abs=2e-3)
