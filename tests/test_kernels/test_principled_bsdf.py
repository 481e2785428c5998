"""The principled BSDFs (``PRINCIPLED`` and ``PRINCIPLED_THIN`` of kernels/materials/principled.py) against the float64
implementation of Mitsuba 3's formulas in ``principled64`` and against Mitsuba 3's ``principled``
itself, on both sides of the surface; its sampling (``weight = f |cos| / pdf``, a chi-square test
of each hemisphere), its density's integral, and reciprocity."""

import math

import numpy as np
import principled64
import pytest
import warp as wp
import wrt.kernels  # noqa: F401
from chi_square import hemisphere_chi_square
from test_rough_dielectric import random_directions
from wrt.kernels.materials import (
    BSDF_ANISOTROPIC,
    BSDF_DIFFUSE,
    BSDF_GLOSSY,
    BSDF_REFLECTION,
    BSDF_TRANSMISSION,
    MaterialData,
    bsdf_flags,
    make_bsdf,
)
from wrt.kernels.sampling import independent_1d as sample_1d
from wrt.kernels.textures import TextureEvalContext
from wrt_harness.mitsuba_peer import mitsuba_available, variant

import wrt
from wrt.device import upload_materials

BSDF = make_bsdf(("principled",), textures=False)  # its family alone: a smaller module to compile

pytestmark = pytest.mark.usefixtures("device")  # every test on every available device

CASES = {  # Mitsuba's parameters (principled64's names), one lobe and then all of them
    "plain": {"base_color": [0.7, 0.3, 0.2], "roughness": 0.4},
    "metal": {"base_color": [0.9, 0.6, 0.2], "roughness": 0.25, "metallic": 0.7, "spec_tint": 0.4},
    "anisotropic": {"base_color": [0.3, 0.5, 0.8], "roughness": 0.5, "anisotropic": 0.6},
    "glass": {"base_color": [0.8, 0.9, 0.7], "roughness": 0.3, "spec_trans": 0.6, "eta": 1.33},
    "sheen": {"base_color": [0.2, 0.8, 0.1], "roughness": 0.6, "sheen": 0.8, "sheen_tint": 0.5},
    "flat": {"base_color": [0.6, 0.6, 0.5], "roughness": 0.7, "flatness": 0.7},
    "clearcoat": {"base_color": [0.1, 0.2, 0.6], "roughness": 0.3, "clearcoat": 0.9, "clearcoat_gloss": 0.3},
    "everything": {
        "base_color": [0.5, 0.4, 0.3],
        "roughness": 0.35,
        "anisotropic": 0.4,
        "metallic": 0.2,
        "spec_trans": 0.5,
        "specular": 0.7,
        "spec_tint": 0.3,
        "sheen": 0.4,
        "sheen_tint": 0.6,
        "flatness": 0.3,
        "clearcoat": 0.6,
        "clearcoat_gloss": 0.8,
        "main_specular_sampling_rate": 0.7,
        "clearcoat_sampling_rate": 2.0,
        "diffuse_reflectance_sampling_rate": 0.5,
    },
}
THIN_CASES = {  # principledthin's
    "thin_plain": {"base_color": [0.7, 0.3, 0.2], "roughness": 0.4},
    "thin_glass": {"base_color": [0.8, 0.9, 0.7], "roughness": 0.6, "spec_trans": 0.6, "eta": 1.33},
    "thin_diffuse_transmission": {"base_color": [0.6, 0.5, 0.3], "roughness": 0.5, "diff_trans": 1.2},
    "thin_sheen": {"base_color": [0.2, 0.8, 0.1], "roughness": 0.6, "sheen": 0.8, "sheen_tint": 0.5, "flatness": 0.7},
    "thin_anisotropic": {"base_color": [0.3, 0.5, 0.8], "roughness": 0.5, "anisotropic": 0.6, "spec_trans": 0.5},
    "thin_everything": {
        "base_color": [0.5, 0.4, 0.3],
        "roughness": 0.35,
        "anisotropic": 0.4,
        "spec_trans": 0.5,
        "eta": 1.45,
        "spec_tint": 0.3,
        "sheen": 0.4,
        "sheen_tint": 0.6,
        "flatness": 0.3,
        "diff_trans": 0.8,
        "specular_reflectance_sampling_rate": 0.7,
        "specular_transmittance_sampling_rate": 2.0,
        "diffuse_reflectance_sampling_rate": 0.5,
        "diffuse_transmittance_sampling_rate": 1.5,
    },
}
CASES.update(THIN_CASES)
INDEX = {name: k for k, name in enumerate(CASES)}
TRANSMITTING = [name for name, p in CASES.items() if p.get("spec_trans", 0.0) > 0.0 or p.get("diff_trans", 0.0) > 0.0]
BLACK_BACK = [name for name in CASES if name not in TRANSMITTING and name not in THIN_CASES]
"""Seen from inside, a principled material without transmission scatters nothing (a thin one is
the same from both sides)."""


def wrt_table(name: str) -> dict:
    """The ``[[material]]`` table of case ``name`` (wrt.mitsuba.bsdfs.principled's mapping)."""
    params = CASES[name]
    names = {"base_color": "albedo", "anisotropic": "anisotropy", "eta": "ior"}
    kind = "principled_thin" if name in THIN_CASES else "principled"
    table = {"type": kind, **{names.get(k, k): v for k, v in params.items() if k != "specular"}}
    if "eta" not in params:
        table["ior"] = 2.0 / (1.0 - math.sqrt(0.08 * params.get("specular", 0.5))) - 1.0
    table.setdefault("roughness", 0.5)
    return table


def mitsuba_dict(name: str) -> dict:
    params = CASES[name]
    plugin = "principledthin" if name in THIN_CASES else "principled"
    return {"type": plugin, **{k: {"type": "rgb", "value": v} if isinstance(v, list) else v for k, v in params.items()}}


def reference(name: str, wo, wi):
    """``principled64``'s f (without the cosine) and pdf of case ``name``."""
    params = CASES[name]
    if name in THIN_CASES:
        return principled64.thin_eval(params, wo, wi) / np.abs(wi[:, 2:3]), principled64.thin_pdf(params, wo, wi)
    return principled64.eval(params, wo, wi) / np.abs(wi[:, 2:3]), principled64.pdf(params, wo, wi)


@pytest.fixture
def materials(device) -> MaterialData:
    scene = wrt.parse_scene(
        {
            "camera": {"origin": [0, 0, 5], "look_at": [0, 0, 0]},
            "material": [{"name": name, **wrt_table(name)} for name in CASES],
        }
    )
    return upload_materials(scene, device)


@wp.func
def side(wo: wp.vec3) -> wp.vec3:
    """The normal facing ``wo`` of the surface whose front is +z."""
    if wo[2] < 0.0:
        return wp.vec3(0.0, 0.0, -1.0)
    return wp.vec3(0.0, 0.0, 1.0)


TANGENT = wp.constant(wp.vec3(1.0, 0.0, 0.0))  # Mitsuba's default frame: s = x


@wp.kernel
def evaluate(
    materials: MaterialData,
    m: wp.int32,
    wo: wp.array(dtype=wp.vec3),
    wi: wp.array(dtype=wp.vec3),
    f: wp.array(dtype=wp.vec3),
    pdf: wp.array(dtype=float),
):
    k = wp.tid()
    n = side(wo[k])
    front = wo[k][2] > 0.0
    f[k] = BSDF.eval(materials, m, n, wo[k], wi[k], 1.0, TextureEvalContext(), front, TANGENT)
    pdf[k] = BSDF.pdf(materials, m, n, wo[k], wi[k], 1.0, TextureEvalContext(), front, TANGENT)


def eval_pdf(materials, name, wo, wi):
    """``bsdf_eval`` and ``bsdf_pdf`` at local directions (N, 3), the surface's front +z."""
    out = [wp.zeros(len(wo), dtype=t) for t in (wp.vec3, float)]
    arrays = [wp.array(np.float32(a), dtype=wp.vec3) for a in (wo, wi)]
    wp.launch(evaluate, dim=len(wo), inputs=[materials, INDEX[name], *arrays, *out])
    return [a.numpy().astype(np.float64) for a in out]


@wp.kernel
def draw(
    materials: MaterialData,
    m: wp.int32,
    wo: wp.vec3,
    seed: wp.int32,
    wi: wp.array(dtype=wp.vec3),
    weight: wp.array(dtype=wp.vec3),
    pdf: wp.array(dtype=float),
    flags: wp.array(dtype=wp.int32),
    f_cos_over_pdf: wp.array(dtype=wp.vec3),
    pdf_again: wp.array(dtype=float),
):
    k = wp.tid()
    n = side(wo)
    front = wo[2] > 0.0
    ctx = TextureEvalContext()
    u = wp.vec2(sample_1d(seed, k, 0, 0), sample_1d(seed, k, 0, 1))
    s = BSDF.sample(materials, m, n, wo, 1.0, sample_1d(seed, k, 0, 2), u, ctx, front, TANGENT)
    wi[k] = s.wi
    weight[k] = s.weight
    pdf[k] = s.pdf
    flags[k] = s.flags
    pdf_again[k] = BSDF.pdf(materials, m, n, wo, s.wi, 1.0, ctx, front, TANGENT)
    f_cos_over_pdf[k] = wp.vec3(0.0)
    if s.pdf > 0.0:
        f_cos_over_pdf[k] = BSDF.eval(materials, m, n, wo, s.wi, 1.0, ctx, front, TANGENT) * (wp.abs(s.wi[2]) / s.pdf)


def sample(materials, name, wo, n=100_000, seed=5):
    out = [wp.zeros(n, dtype=t) for t in (wp.vec3, wp.vec3, float, wp.int32, wp.vec3, float)]
    wp.launch(draw, dim=n, inputs=[materials, INDEX[name], wp.vec3(*wo), seed, *out])
    return [a.numpy().astype(np.float64) if a.dtype != wp.int32 else a.numpy() for a in out]


def direction(theta_deg: float, phi_deg: float = 20.0) -> np.ndarray:
    t, p = np.radians(theta_deg), np.radians(phi_deg)
    return np.array([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)])


def pairs(rng, count=3000):
    """Direction pairs ``(wo, wi)`` on every combination of sides."""
    wo = np.concatenate([random_directions(rng, count, lower) for lower in (False, False, True, True)])
    wi = np.concatenate([random_directions(rng, count, lower) for lower in (False, True, False, True)])
    k = min(len(wo), len(wi))
    return wo[:k], wi[:k]


@wp.kernel
def flags_of(materials: MaterialData, out: wp.array(dtype=wp.int32)):
    out[wp.tid()] = bsdf_flags(materials, wp.tid())


def test_flags_are_diffuse_and_glossy_with_transmission_where_it_transmits(materials):
    """Its lobes, transmission where ``spec_trans`` (or a thin one's ``diff_trans``) is given, the
    tangent where ``anisotropic`` is."""
    out = wp.zeros(len(CASES), dtype=wp.int32)
    wp.launch(flags_of, dim=len(CASES), inputs=[materials, out])
    lobes = BSDF_REFLECTION | BSDF_DIFFUSE | BSDF_GLOSSY
    for (name, params), flags in zip(CASES.items(), out.numpy()):
        transmission = BSDF_TRANSMISSION if name in TRANSMITTING else 0
        tangent = BSDF_ANISOTROPIC if params.get("anisotropic", 0.0) > 0.0 else 0
        assert flags == lobes | transmission | tangent, name


@pytest.mark.parametrize("name", list(CASES))
def test_eval_and_pdf_match_the_float64_formulas(materials, name, rng):
    wo, wi = pairs(rng)
    f, pdf = eval_pdf(materials, name, wo, wi)
    f64, pdf64 = reference(name, wo, wi)
    np.testing.assert_allclose(f, f64, rtol=3e-3, atol=2e-5 * f64.max())
    np.testing.assert_allclose(pdf, pdf64, rtol=3e-3, atol=2e-5 * pdf64.max())
    assert f.max() > 0.0 and pdf.max() > 0.0


@pytest.mark.parametrize("name", list(CASES))
def test_reflection_is_reciprocal(materials, name, rng):
    wo, wi = pairs(rng)
    same_side = wo[:, 2] * wi[:, 2] > 0
    wo, wi = wo[same_side], wi[same_side]
    f, _ = eval_pdf(materials, name, wo, wi)
    f_swapped, _ = eval_pdf(materials, name, wi, wo)
    np.testing.assert_allclose(f, f_swapped, rtol=2e-3, atol=1e-5 * f.max())


@pytest.mark.parametrize("name", [name for name in TRANSMITTING if name not in THIN_CASES])
def test_transmission_obeys_generalised_reciprocity(materials, name, rng):
    """``f(wo, wi) / eta_i^2 = f(wi, wo) / eta_o^2`` across the interface (radiance transport).
    (A thin one's glossy transmission is not reciprocal: Mitsuba's masks of which microfacet sides
    it needs differ when ``wo`` and ``wi`` swap. Its diffuse transmission is, and so are both
    kinds' reflections.)"""
    wo = random_directions(rng, 40_000, lower=False)
    wi = random_directions(rng, 40_000, lower=True)
    k = min(len(wo), len(wi))
    wo, wi = wo[:k], wi[:k]
    eta = wrt_table(name)["ior"]
    f, _ = eval_pdf(materials, name, wo, wi)
    f_back, _ = eval_pdf(materials, name, wi, wo)
    kept = f[:, 0] > 1e-4 * f[:, 0].max()
    assert kept.sum() > 500
    np.testing.assert_allclose(f_back[kept] * eta**-2, f[kept], rtol=3e-3)


@pytest.mark.parametrize("name", list(CASES))
@pytest.mark.parametrize("theta", [15.0, 70.0, 160.0])
def test_sample_weight_is_eval_cos_over_pdf(materials, name, theta):
    wo = direction(theta)
    wi, weight, pdf, flags, f_cos_over_pdf, pdf_again = sample(materials, name, wo, n=20_000)
    kept = pdf > 0
    if theta > 90 and name in BLACK_BACK:
        assert not kept.any()  # its back side is black
        return
    assert kept.mean() > 0.5
    np.testing.assert_allclose(weight[kept], f_cos_over_pdf[kept], rtol=2e-3, atol=1e-6)
    np.testing.assert_allclose(pdf[kept], pdf_again[kept], rtol=2e-3)
    transmitted = (flags[kept] & BSDF_TRANSMISSION) != 0
    assert np.array_equal(transmitted, wi[kept, 2] * wo[2] < 0)


@pytest.mark.parametrize(
    "name", ["plain", "anisotropic", "clearcoat", "glass", "everything", "thin_glass", "thin_everything"]
)
@pytest.mark.parametrize("theta", [30.0, 75.0, 140.0])
def test_sampling_matches_the_density_chi_square(materials, name, theta):
    """Mitsuba's ``chi2`` test of ``sample`` against ``pdf``, over each hemisphere in turn (its
    40 x 80 cells resolve lobes of alpha above about 0.05: at the thin glass's roughness 0.3, alpha
    0.024, the cells' Simpson sums were 2.6% off)."""
    if theta > 90 and name in BLACK_BACK:
        pytest.skip("its back side is black")
    wo = direction(theta)
    count = 200_000
    wi, _, pdf, _, _, _ = sample(materials, name, wo, n=count, seed=11)
    wi = wi[pdf > 0]
    for sign in (1.0, -1.0):
        flip = np.array([1.0, 1.0, sign])
        drawn = wi[wi[:, 2] * sign > 0] * flip
        if len(drawn) < 1000:
            continue

        def density(directions, flip=flip):
            return eval_pdf(materials, name, np.broadcast_to(wo, directions.shape), directions * flip)[1]

        result = hemisphere_chi_square(drawn, density, count)
        assert result.p_value > 1e-3, (sign, result)
        assert result.observed == pytest.approx(result.expected, rel=0.02)


@pytest.mark.parametrize("name", list(CASES))
@pytest.mark.parametrize("theta", [20.0, 80.0, 130.0])
def test_pdf_integrates_to_the_fraction_of_samples_kept(materials, name, theta, rng):
    """The integral of ``bsdf_pdf`` over the sphere (uniform directions) is at most 1: the
    probability that ``bsdf_sample`` keeps a direction. (Seen from inside, a material that does not
    transmit keeps none, but its ``pdf``, as Mitsuba's, still describes the reflection lobe.)"""
    if theta > 90 and name in BLACK_BACK:
        pytest.skip("its back side is black")
    w = rng.normal(size=(400_000, 3))
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    wo = direction(theta)
    _, pdf = eval_pdf(materials, name, np.broadcast_to(wo, w.shape), w)
    integral = pdf.mean() * 4 * np.pi
    error = 4 * pdf.std() * 4 * np.pi / np.sqrt(len(pdf))
    _, _, drawn, _, _, _ = sample(materials, name, wo, n=50_000)
    assert integral <= 1.0 + error
    assert abs(integral - (drawn > 0).mean()) < error + 5e-3


@pytest.mark.skipif(not mitsuba_available()[0], reason=mitsuba_available()[1])
@pytest.mark.parametrize("name", list(CASES))
def test_eval_and_pdf_match_mitsuba(materials, name, rng):
    """Mitsuba 3's own ``principled``: ``eval`` (with the cosine) and ``pdf`` at the same local
    directions, on both sides."""
    import mitsuba as mi

    mi.set_variant(variant())
    bsdf = mi.load_dict(mitsuba_dict(name))
    wo, wi = pairs(rng, 150)
    ctx, si = mi.BSDFContext(), mi.SurfaceInteraction3f()
    theirs_f, theirs_pdf = [], []
    for a, b in zip(wo, wi):
        si.wi = mi.Vector3f(*a)
        theirs_f.append(list(bsdf.eval(ctx, si, mi.Vector3f(*b))))
        theirs_pdf.append(bsdf.pdf(ctx, si, mi.Vector3f(*b)))
    f, pdf = eval_pdf(materials, name, wo, wi)
    theirs_f, theirs_pdf = np.array(theirs_f), np.array(theirs_pdf)
    np.testing.assert_allclose(f * np.abs(wi[:, 2:3]), theirs_f, rtol=3e-3, atol=2e-5 * theirs_f.max())
    np.testing.assert_allclose(pdf, theirs_pdf, rtol=3e-3, atol=2e-5 * theirs_pdf.max())
