"""The plastics (``PLASTIC`` and ``ROUGH_PLASTIC`` of kernels/materials/plastic.py, with their host
constants): the coating's constants against closed forms, the BSDF against a float64 reference
of Mitsuba 3's formulas and against Mitsuba 3's ``plastic`` and ``roughplastic`` themselves, and
its own sampling."""

import numpy as np
import pytest
import warp as wp
import wrt.kernels  # noqa: F401
from conftest import fresnel_dielectric64
from test_microfacet import d64, g1_64
from test_rough_dielectric import random_directions
from wrt.kernels.materials import (
    BSDF_DIFFUSE,
    BSDF_GLOSSY,
    BSDF_REFLECTION,
    BSDF_SPECULAR,
    MaterialData,
    bsdf_flags,
    make_bsdf,
)
from wrt.kernels.materials.plastic import fresnel_diffuse_reflectance, rough_coating, specular_weight
from wrt.kernels.sampling import independent_1d as sample_1d
from wrt_harness.mitsuba_peer import mitsuba_available, variant

import wrt
from wrt.device import upload_materials

BSDF = make_bsdf(("plastic",), anisotropic=False)  # its family alone: a smaller module to compile
bsdf_eval = BSDF.eval
bsdf_pdf = BSDF.pdf
bsdf_sample = BSDF.sample
specular_lobes = BSDF.specular_lobes

pytestmark = pytest.mark.usefixtures("device")  # every test on every available device

PLASTICS = {  # name: (wrt [[material]] table, Mitsuba BSDF dict)
    "smooth": (
        {"type": "plastic", "albedo": [0.7, 0.2, 0.1], "ior": 1.49},
        {"type": "plastic", "int_ior": 1.49, "ext_ior": 1.0, "diffuse_reflectance": [0.7, 0.2, 0.1]},
    ),
    "smooth_nonlinear": (
        {"type": "plastic", "albedo": [0.9, 0.5, 0.1], "reflectance": [0.8, 0.8, 0.6], "ior": 1.7, "nonlinear": True},
        {
            "type": "plastic",
            "int_ior": 1.7,
            "ext_ior": 1.0,
            "diffuse_reflectance": [0.9, 0.5, 0.1],
            "specular_reflectance": [0.8, 0.8, 0.6],
            "nonlinear": True,
        },
    ),
    "rough": (
        {"type": "rough_plastic", "albedo": [0.1, 0.2, 0.65], "ior": 1.49, "roughness": 0.15},
        {
            "type": "roughplastic",
            "distribution": "ggx",
            "alpha": 0.15,
            "int_ior": 1.49,
            "ext_ior": 1.0,
            "diffuse_reflectance": [0.1, 0.2, 0.65],
        },
    ),
    "rough_nonlinear": (
        {
            "type": "rough_plastic",
            "albedo": [0.6, 0.6, 0.55],
            "reflectance": [0.9, 0.7, 0.7],
            "ior": 1.5,
            "roughness": 0.6,
            "nonlinear": True,
        },
        {
            "type": "roughplastic",
            "distribution": "ggx",
            "alpha": 0.6,
            "int_ior": 1.5,
            "ext_ior": 1.0,
            "diffuse_reflectance": [0.6, 0.6, 0.55],
            "specular_reflectance": [0.9, 0.7, 0.7],
            "nonlinear": True,
        },
    ),
    "rough_beckmann": (
        {"type": "rough_plastic", "albedo": [0.2, 0.5, 0.3], "ior": 1.6, "roughness": 0.3, "distribution": "beckmann"},
        {
            "type": "roughplastic",
            "distribution": "beckmann",
            "alpha": 0.3,
            "int_ior": 1.6,
            "ext_ior": 1.0,
            "diffuse_reflectance": [0.2, 0.5, 0.3],
        },
    ),
}
INDEX = {name: k for k, name in enumerate(PLASTICS)}


@pytest.fixture
def materials(device) -> MaterialData:
    scene = wrt.parse_scene(
        {
            "camera": {"origin": [0, 0, 5], "look_at": [0, 0, 0]},
            "material": [{"name": name, **table} for name, (table, _) in PLASTICS.items()],
        }
    )
    return upload_materials(scene, device)


@wp.kernel
def evaluate(
    materials: MaterialData,
    m: wp.int32,
    wo: wp.array(dtype=wp.vec3),
    wi: wp.array(dtype=wp.vec3),
    f: wp.array(dtype=wp.vec3),
    pdf: wp.array(dtype=float),
    coating: wp.array(dtype=wp.vec3),
):
    k = wp.tid()
    n = wp.vec3(0.0, 0.0, 1.0)
    f[k] = bsdf_eval(materials, m, n, wo[k], wi[k])
    pdf[k] = bsdf_pdf(materials, m, n, wo[k], wi[k])
    coating[k] = specular_lobes(materials, m, n, wo[k], 1.0).reflectance


def eval_pdf(materials, name, wo, wi):
    """``bsdf_eval``, ``bsdf_pdf`` and the delta lobe's reflectance at directions (N, 3) about +z."""
    out = [wp.zeros(len(wo), dtype=t) for t in (wp.vec3, float, wp.vec3)]
    arrays = [wp.array(np.float32(a), dtype=wp.vec3) for a in (wo, wi)]
    wp.launch(evaluate, dim=len(wo), inputs=[materials, INDEX[name], *arrays, *out])
    return [a.numpy().astype(np.float64) for a in out]


@wp.kernel
def draw(
    materials: MaterialData,
    m: wp.int32,
    wo: wp.vec3,
    wi: wp.array(dtype=wp.vec3),
    weight: wp.array(dtype=wp.vec3),
    pdf: wp.array(dtype=float),
    flags: wp.array(dtype=wp.int32),
    f_cos_over_pdf: wp.array(dtype=wp.vec3),
    pdf_again: wp.array(dtype=float),
):
    k = wp.tid()
    n = wp.vec3(0.0, 0.0, 1.0)
    u = wp.vec2(sample_1d(5, k, 0, 0), sample_1d(5, k, 0, 1))
    s = bsdf_sample(materials, m, n, wo, 1.0, sample_1d(5, k, 0, 2), u)
    wi[k] = s.wi
    weight[k] = s.weight
    pdf[k] = s.pdf
    flags[k] = s.flags
    pdf_again[k] = bsdf_pdf(materials, m, n, wo, s.wi)
    f_cos_over_pdf[k] = wp.vec3(0.0)
    if s.pdf > 0.0:
        f_cos_over_pdf[k] = bsdf_eval(materials, m, n, wo, s.wi) * (s.wi[2] / s.pdf)


def sample(materials, name, theta, n=50_000):
    out = [wp.zeros(n, dtype=t) for t in (wp.vec3, wp.vec3, float, wp.int32, wp.vec3, float)]
    t = np.radians(theta)
    wp.launch(draw, dim=n, inputs=[materials, INDEX[name], wp.vec3(np.sin(t), 0.0, np.cos(t)), *out])
    return [a.numpy() for a in out]


def reference(name, wo, wi):
    """f (N, 3), pdf and the coating's delta reflectance (N, 3) of Mitsuba 3's plastic or
    roughplastic formulas in float64 (with the constants plastic.bake computes)."""
    table, _ = PLASTICS[name]
    albedo, spec = np.array(table["albedo"]), np.array(table.get("reflectance", [1.0, 1.0, 1.0]))
    eta, rough = table["ior"], table["type"] == "rough_plastic"
    weight = specular_weight(albedo, spec)
    if rough:
        curve, inside = rough_coating(table["roughness"], eta, table.get("distribution", "ggx"))
        grid = np.linspace(0.0, 1.0, len(curve))

        def transmittance(c):
            return np.interp(c, grid, curve)
    else:
        inside = fresnel_diffuse_reflectance(1.0 / eta)

        def transmittance(c):
            return 1.0 - fresnel_dielectric64(c, 1.0 / eta)

    base = albedo / (1.0 - (albedo * inside if table.get("nonlinear") else inside))
    t_o, t_i = transmittance(wo[:, 2]), transmittance(np.clip(wi[:, 2], 0.0, 1.0))
    f = base * (t_o * t_i / (np.pi * eta**2))[:, None]
    coating = weight * (1 - t_o) / (weight * (1 - t_o) + (1 - weight) * t_o)
    pdf = (1 - coating) * wi[:, 2] / np.pi
    delta = np.zeros_like(f)
    if rough:
        alpha, distribution = table["roughness"], table.get("distribution", "ggx")
        h = wo + wi
        h /= np.linalg.norm(h, axis=1, keepdims=True)
        d, g1o, g1i = d64(h, alpha, distribution), g1_64(wo, alpha, distribution), g1_64(wi, alpha, distribution)
        fresnel = fresnel_dielectric64(np.sum(wo * h, axis=1), 1.0 / eta)
        f += spec * (fresnel * d * g1o * g1i / (4 * wo[:, 2] * wi[:, 2]))[:, None]
        pdf += coating * d * g1o / (4 * wo[:, 2])
    else:
        delta = spec * fresnel_dielectric64(wo[:, 2], 1.0 / eta)[:, None]
    below = wi[:, 2] <= 0
    f[below], pdf[below] = 0.0, 0.0
    return f, pdf, delta


def test_flags(materials):
    out = wp.zeros(len(PLASTICS), dtype=wp.int32)
    wp.launch(flags_of, dim=len(PLASTICS), inputs=[materials, out])
    smooth, rough = BSDF_REFLECTION | BSDF_DIFFUSE | BSDF_SPECULAR, BSDF_REFLECTION | BSDF_DIFFUSE | BSDF_GLOSSY
    assert out.numpy().tolist() == [smooth, smooth, rough, rough, rough]


@wp.kernel
def flags_of(materials: MaterialData, out: wp.array(dtype=wp.int32)):
    out[wp.tid()] = bsdf_flags(materials, wp.tid())


def test_diffuse_fresnel_reflectance_is_the_cosine_weighted_mean():
    """Egan and Hilgeman's fit (eta < 1) and d'Eon and Irving's (eta > 1) against ``2 int F(mu) mu
    dmu`` in float64: within their stated accuracy (0.1% for eta in 1-1.5, 0.6% to 2)."""
    mu = np.linspace(0.0, 1.0, 200_001)
    for eta in (1.1, 1.33, 1.49, 1.7, 2.0):
        for relative in (1.0 / eta, eta):
            with np.errstate(invalid="ignore"):  # 0/0 at grazing incidence, taken as 1 (total reflection)
                exact = 2.0 * np.trapezoid(fresnel_dielectric64(mu, relative) * mu, mu)
            # fresnel_diffuse_reflectance takes Mitsuba's eta: the far side's ior over the near side's
            assert fresnel_diffuse_reflectance(1.0 / relative) == pytest.approx(exact, rel=6e-3, abs=1e-3)


def test_a_nearly_smooth_coating_transmits_one_minus_fresnel():
    """At alpha 0.001 the rough coating's transmittance table is the smooth interface's 1 - F
    (the table's first entry is at cosine 1e-6), and its internal reflectance Mitsuba's 64-point
    mean of the smooth one's: ``2 mean(F(mu) mu)``."""
    curve, inside = rough_coating(1e-3, 1.5)
    mu = np.maximum(1e-6, np.linspace(0.0, 1.0, len(curve)))
    np.testing.assert_allclose(curve[1:], 1.0 - fresnel_dielectric64(mu[1:], 1 / 1.5), atol=2e-3)
    assert inside == pytest.approx(2.0 * np.mean(fresnel_dielectric64(mu, 1.5) * mu), abs=2e-3)


@pytest.mark.parametrize("name", list(PLASTICS))
def test_eval_pdf_and_coating_match_the_float64_formulas(materials, name, rng):
    wo = random_directions(rng, 3000, lower=False)
    wi = random_directions(rng, 3000, lower=False)
    count = min(len(wo), len(wi))
    wo, wi = wo[:count], wi[:count]
    f, pdf, delta = eval_pdf(materials, name, wo, wi)
    f64, pdf64, delta64 = reference(name, wo, wi)
    np.testing.assert_allclose(f, f64, rtol=2e-3, atol=1e-5 * f64.max())
    np.testing.assert_allclose(pdf, pdf64, rtol=2e-3, atol=1e-5 * pdf64.max())
    np.testing.assert_allclose(delta, delta64, rtol=1e-4, atol=1e-6)
    below, _, _ = eval_pdf(materials, name, wo, -wi)
    assert np.all(below == 0.0)


@pytest.mark.parametrize("name", list(PLASTICS))
@pytest.mark.parametrize("theta", [0.0, 50.0, 85.0])
def test_sample_weight_is_eval_cos_over_pdf(materials, name, theta):
    """Non-specular samples weigh ``f cos / pdf`` (both lobes together), their pdf is
    ``bsdf_pdf``'s; a smooth coating's mirror sample weighs ``reflectance F / P(coating)``."""
    wi, weight, pdf, flags, f_cos_over_pdf, pdf_again = sample(materials, name, theta)
    delta = (flags & BSDF_SPECULAR) != 0
    kept = (pdf > 0) & ~delta
    np.testing.assert_allclose(weight[kept], f_cos_over_pdf[kept], rtol=2e-3, atol=1e-6)
    np.testing.assert_allclose(pdf[kept], pdf_again[kept], rtol=2e-3)
    assert np.all(wi[pdf > 0, 2] > 0)
    if name.startswith("smooth"):
        t = np.radians(theta)
        _, _, coating = reference(name, np.array([[np.sin(t), 0.0, np.cos(t)]]), np.array([[0.0, 0.0, 1.0]]))
        np.testing.assert_allclose(
            weight[delta] * pdf[delta, None], np.broadcast_to(coating, weight[delta].shape), rtol=1e-4
        )
    else:
        assert not delta.any()


@pytest.mark.parametrize("name", list(PLASTICS))
@pytest.mark.parametrize("theta", [10.0, 70.0])
def test_pdf_integrates_to_the_fraction_of_non_specular_samples(materials, name, theta, rng):
    """The integral of ``bsdf_pdf`` over the hemisphere (uniform directions) is at most 1: the
    probability that ``bsdf_sample`` draws a non-specular direction it keeps."""
    w = rng.normal(size=(400_000, 3))
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    t = np.radians(theta)
    _, pdf, _ = eval_pdf(materials, name, np.broadcast_to([np.sin(t), 0.0, np.cos(t)], w.shape), w)
    integral = pdf.mean() * 4 * np.pi
    error = 4 * pdf.std() * 4 * np.pi / np.sqrt(len(pdf))
    _, _, pdf_drawn, flags, _, _ = sample(materials, name, theta)
    kept = ((pdf_drawn > 0) & ((flags & BSDF_SPECULAR) == 0)).mean()
    assert integral <= 1.0 + error
    assert abs(integral - kept) < error + 5e-3


@pytest.mark.skipif(not mitsuba_available()[0], reason=mitsuba_available()[1])
@pytest.mark.parametrize("name", list(PLASTICS))
def test_eval_and_pdf_match_mitsuba(materials, name, rng):
    """Mitsuba 3's own ``plastic`` / ``roughplastic``: ``eval`` (with the cosine) and ``pdf`` at the
    same local directions (its constants in float32, ours in float64: within 0.3%)."""
    import mitsuba as mi

    mi.set_variant(variant())
    _, params = PLASTICS[name]
    bsdf = mi.load_dict({k: ({"type": "rgb", "value": v} if isinstance(v, list) else v) for k, v in params.items()})
    wo = random_directions(rng, 300, lower=False)
    wi = random_directions(rng, 300, lower=False)
    count = min(len(wo), len(wi))
    wo, wi = wo[:count], wi[:count]
    ctx, si = mi.BSDFContext(), mi.SurfaceInteraction3f()
    theirs_f, theirs_pdf = [], []
    for a, b in zip(wo, wi):
        si.wi = mi.Vector3f(*a)
        theirs_f.append(list(bsdf.eval(ctx, si, mi.Vector3f(*b))))
        theirs_pdf.append(bsdf.pdf(ctx, si, mi.Vector3f(*b)))
    f, pdf, _ = eval_pdf(materials, name, wo, wi)
    np.testing.assert_allclose(f * wi[:, 2:3], theirs_f, rtol=3e-3, atol=1e-5)
    np.testing.assert_allclose(pdf, theirs_pdf, rtol=3e-3, atol=1e-5)
