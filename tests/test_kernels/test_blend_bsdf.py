"""Blends (``BLEND`` of kernels/materials/blend.py, Mitsuba 3's ``blendbsdf``): the BSDF functions
against their two materials' weighted, the samples' choice, weight and density (a chi-square test
against ``pdf``), a textured weight, the back of a one-sided material, the host's table, and
``eval`` and ``pdf`` against Mitsuba's own."""

import numpy as np
import pytest
import warp as wp
import wrt.kernels  # noqa: F401
from chi_square import hemisphere_chi_square
from test_mask_bsdf import upper_directions
from wrt.kernels.materials import (
    BSDF_DIFFUSE,
    BSDF_GLOSSY,
    BSDF_REFLECTION,
    BSDF_SPECULAR,
    MaterialData,
    make_bsdf,
)
from wrt.kernels.sampling import independent_1d as sample_1d
from wrt.kernels.textures import uv_context
from wrt_harness.mitsuba_peer import mitsuba_available, variant

import wrt
from wrt.device import upload_materials

BSDF = make_bsdf(("diffuse", "conductor", "plastic", "blend"), beckmann=False, anisotropic=False)

pytestmark = pytest.mark.usefixtures("device")  # every test on every available device

CHECKS = {"texture": "checkerboard", "color0": [0.9, 0.7, 0.8], "color1": [0.1, 0.2, 0.0]}
MATERIALS = [
    {"name": "matte", "albedo": [0.2, 0.6, 0.15], "two_sided": False},
    {"name": "metal", "type": "glossy", "reflectance": [0.9, 0.8, 0.6], "roughness": 0.3},
    {"name": "coat", "type": "plastic", "albedo": [0.7, 0.2, 0.1], "ior": 1.49},
    {"name": "half", "type": "blend", "materials": ["matte", "metal"], "weight": 0.3},
    {"name": "coated", "type": "blend", "materials": ["matte", "coat"], "weight": 0.6},
    {"name": "patterned", "type": "blend", "materials": ["matte", "metal"], "weight": CHECKS},
    {"name": "all_b", "type": "blend", "materials": ["matte", "metal"], "weight": 1.0},
    {"name": "all_a", "type": "blend", "materials": ["matte", "metal"], "weight": 0.0},
]
INDEX = {m["name"]: k for k, m in enumerate(MATERIALS)}
WEIGHTS = {"half": 0.3, "coated": 0.6, "patterned": 0.8, "all_b": 1.0, "all_a": 0.0}  # patterned: at UV
UV = wp.vec2(0.25, 0.25)  # the checkerboard's color0 (mean 0.8)
WO = np.array([0.3, -0.2, 0.93]) / np.linalg.norm([0.3, -0.2, 0.93])


@pytest.fixture
def materials(device) -> MaterialData:
    scene = wrt.parse_scene({"camera": {"origin": [0, 0, 5], "look_at": [0, 0, 0]}, "material": MATERIALS})
    return upload_materials(scene, device)


@wp.kernel
def evaluate(
    materials: MaterialData,
    m: wp.int32,
    front: bool,
    wo: wp.array(dtype=wp.vec3),
    wi: wp.array(dtype=wp.vec3),
    f: wp.array(dtype=wp.vec3),
    pdf: wp.array(dtype=float),
):
    k = wp.tid()
    n = wp.vec3(0.0, 0.0, 1.0)
    f[k] = BSDF.eval(materials, m, n, wo[k], wi[k], 1.0, uv_context(UV), front)
    pdf[k] = BSDF.pdf(materials, m, n, wo[k], wi[k], 1.0, uv_context(UV), front)


def eval_pdf(materials, name, wo, wi, front=True):
    out = [wp.zeros(len(wi), dtype=t) for t in (wp.vec3, float)]
    wo = np.broadcast_to(wo, np.shape(wi))
    arrays = [wp.array(np.float32(a), dtype=wp.vec3) for a in (wo, wi)]
    wp.launch(evaluate, dim=len(wi), inputs=[materials, INDEX[name], front, *arrays, *out])
    return [a.numpy().astype(np.float64) for a in out]


@wp.kernel
def draw(
    materials: MaterialData,
    m: wp.int32,
    front: bool,
    uc_scale: float,
    uc_offset: float,
    wo: wp.vec3,
    wi: wp.array(dtype=wp.vec3),
    weight: wp.array(dtype=wp.vec3),
    pdf: wp.array(dtype=float),
    flags: wp.array(dtype=wp.int32),
    uc_drawn: wp.array(dtype=float),
):
    """Sample ``k`` of material ``m`` with ``uc`` (``uc_drawn``) mapped to ``(uc - uc_offset) *
    uc_scale`` (a blend draws its material ``b`` with ``uc / weight``, ``a`` with ``(uc - weight) /
    (1 - weight)``)."""
    k = wp.tid()
    n = wp.vec3(0.0, 0.0, 1.0)
    u = wp.vec2(sample_1d(5, k, 0, 0), sample_1d(5, k, 0, 1))
    uc_drawn[k] = sample_1d(5, k, 0, 2)
    uc = (uc_drawn[k] - uc_offset) * uc_scale
    s = BSDF.sample(materials, m, n, wo, 1.0, wp.clamp(uc, 0.0, 0.99999994), u, uv_context(UV), front)
    wi[k] = s.wi
    weight[k] = s.weight
    pdf[k] = s.pdf
    flags[k] = s.flags


def sample(materials, name, count, front=True, uc_scale=1.0, uc_offset=0.0):
    """``(wi, weight, pdf, flags, uc)`` of ``count`` samples of material ``name``."""
    out = [wp.zeros(count, dtype=t) for t in (wp.vec3, wp.vec3, float, wp.int32, float)]
    wp.launch(draw, dim=count, inputs=[materials, INDEX[name], front, uc_scale, uc_offset, wp.vec3(*WO), *out])
    return [a.numpy().astype(np.float64) if a.dtype != wp.int32 else a.numpy() for a in out]


def test_the_table_holds_both_materials_and_their_lobes(materials):
    """A blend's lobes are both of its materials'; it is two-sided where either is; its columns
    name its materials and hold its constant weight."""
    flags = dict(zip(INDEX, materials.flags.numpy()))
    assert flags["half"] == BSDF_REFLECTION | BSDF_DIFFUSE | BSDF_GLOSSY
    assert flags["coated"] == BSDF_REFLECTION | BSDF_DIFFUSE | BSDF_SPECULAR
    two_sided = dict(zip(INDEX, materials.two_sided.numpy()))
    assert two_sided["matte"] == 0 and two_sided["half"] == 1
    assert materials.blend.a.numpy()[INDEX["half"]] == INDEX["matte"]
    assert materials.blend.b.numpy()[INDEX["coated"]] == INDEX["coat"]
    assert materials.blend.weight.numpy()[INDEX["half"]] == pytest.approx(0.3)


@pytest.mark.parametrize("name", list(WEIGHTS))
def test_eval_and_pdf_are_the_materials_weighted(materials, name):
    """f and pdf of a blend: ``(1 - w)`` times its first material's plus ``w`` times its second's,
    at random directions above the surface; across it nothing (neither transmits)."""
    rng = np.random.default_rng(3)
    wo, wi = upper_directions(rng, 256), upper_directions(rng, 256)
    a, b = MATERIALS[INDEX[name]]["materials"]
    w = WEIGHTS[name]
    f, pdf = eval_pdf(materials, name, wo, wi)
    (f_a, pdf_a), (f_b, pdf_b) = eval_pdf(materials, a, wo, wi), eval_pdf(materials, b, wo, wi)
    assert f_a.max() > 0.0 and f_b.max() > 0.0
    np.testing.assert_allclose(f, (1 - w) * f_a + w * f_b, rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(pdf, (1 - w) * pdf_a + w * pdf_b, rtol=1e-5, atol=1e-7)
    f, pdf = eval_pdf(materials, name, wo, wi * [1.0, 1.0, -1.0])
    assert not f.any() and not pdf.any()


@pytest.mark.parametrize("name", ["half", "coated", "patterned"])
def test_sample_chooses_a_material_and_weighs_by_the_blend(materials, name):
    """The second material is chosen with frequency ``w`` (where ``uc < w``, drawn with ``uc / w``:
    the same direction), the first with ``(uc - w) / (1 - w)``; a delta lobe keeps its material's
    weight, its probability times its material's; a non-specular direction has the blend's pdf and
    ``weight = f cos / pdf`` of the blend."""
    w, count = WEIGHTS[name], 4096
    a, b = MATERIALS[INDEX[name]]["materials"]
    wi, weight, pdf, flags, uc = sample(materials, name, count)
    chose_b = uc < w
    assert abs(chose_b.mean() - w) < 4.0 * np.sqrt(w * (1 - w) / count)
    for chosen, material, scale, offset in ((chose_b, b, 1.0 / w, 0.0), (~chose_b, a, 1.0 / (1 - w), w)):
        wi_m, weight_m, pdf_m, flags_m, _ = sample(materials, material, count, uc_scale=scale, uc_offset=offset)
        kept = chosen & (pdf_m > 0)
        np.testing.assert_allclose(wi[kept], wi_m[kept], atol=1e-6)
        np.testing.assert_array_equal(flags[kept], flags_m[kept])
        delta = kept & ((flags & BSDF_SPECULAR) != 0)
        np.testing.assert_allclose(weight[delta], weight_m[delta], rtol=1e-5)
        np.testing.assert_allclose(pdf[delta], pdf_m[delta] * (w if material == b else 1 - w), rtol=1e-5)
    smooth = (pdf > 0) & ((flags & BSDF_SPECULAR) == 0)
    assert smooth.sum() > count // 4
    f, pdf_blend = eval_pdf(materials, name, WO, wi[smooth])
    np.testing.assert_allclose(pdf[smooth], pdf_blend, rtol=1e-5)
    np.testing.assert_allclose(weight[smooth], f * (wi[smooth, 2:3] / pdf_blend[:, None]), rtol=1e-4, atol=1e-6)


@pytest.mark.parametrize("name", ["half", "patterned"])
def test_sampling_passes_a_chi_square_test_against_pdf(materials, name):
    """The blend's samples (its materials' mixed) histogrammed over the hemisphere against its
    ``pdf`` (Mitsuba's ``chi2`` test)."""
    count = 200_000
    wi, _, pdf, _, _ = sample(materials, name, count)
    test = hemisphere_chi_square(wi[pdf > 0], lambda d: eval_pdf(materials, name, WO, d)[1], count)
    assert test.observed == pytest.approx(test.expected, rel=5e-3)  # the samples kept: the pdf's integral
    assert test.p_value > 1e-3, test


def test_the_back_of_a_one_sided_material_is_left_out(materials):
    """On the back side a blend scatters only with its two-sided material: f and pdf are its
    weighted, and samples that choose the one-sided material are lost."""
    rng = np.random.default_rng(4)
    wo, wi = upper_directions(rng, 64), upper_directions(rng, 64)
    f, pdf = eval_pdf(materials, "half", wo, wi, front=False)
    f_b, pdf_b = eval_pdf(materials, "metal", wo, wi, front=False)
    np.testing.assert_allclose(f, 0.3 * f_b, rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(pdf, 0.3 * pdf_b, rtol=1e-5, atol=1e-7)
    _, weight, pdf, _, uc = sample(materials, "half", 4096, front=False)
    chose_a = uc >= 0.3
    assert not pdf[chose_a].any() and not weight[chose_a].any()


@pytest.mark.skipif(not mitsuba_available()[0], reason=mitsuba_available()[1])
def test_eval_and_pdf_match_mitsuba(materials, rng):
    """Mitsuba 3's own ``blendbsdf`` of a diffuse and a rough conductor: ``eval`` (with the cosine)
    and ``pdf`` at the same local directions."""
    import mitsuba as mi

    mi.set_variant(variant())
    bsdf = mi.load_dict(
        {
            "type": "blendbsdf",
            "weight": 0.3,
            "a": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.2, 0.6, 0.15]}},
            "b": {
                "type": "roughconductor",
                "distribution": "ggx",
                "alpha": 0.3,
                "material": "none",
                "specular_reflectance": {"type": "rgb", "value": [0.9, 0.8, 0.6]},
            },
        }
    )
    wo, wi = upper_directions(rng, 300), upper_directions(rng, 300)
    ctx, si = mi.BSDFContext(), mi.SurfaceInteraction3f()
    theirs_f, theirs_pdf = [], []
    for a, b in zip(wo, wi):
        si.wi = mi.Vector3f(*a)
        theirs_f.append(list(bsdf.eval(ctx, si, mi.Vector3f(*b))))
        theirs_pdf.append(bsdf.pdf(ctx, si, mi.Vector3f(*b)))
    f, pdf = eval_pdf(materials, "half", wo, wi)
    np.testing.assert_allclose(f * wi[:, 2:3], theirs_f, rtol=3e-3, atol=1e-5)
    np.testing.assert_allclose(pdf, theirs_pdf, rtol=3e-3, atol=1e-5)


@pytest.mark.parametrize("name", ["half", "coated", "patterned"])
def test_eval_is_reciprocal_and_pdf_integrates_to_at_most_one(materials, name):
    """f(wo, wi) = f(wi, wo) (both materials' are); the pdf's integral over the sphere is the
    fraction of samples drawn from non-specular lobes and kept, at most 1."""
    rng = np.random.default_rng(5)
    wo, wi = upper_directions(rng, 512), upper_directions(rng, 512)
    np.testing.assert_allclose(eval_pdf(materials, name, wo, wi)[0], eval_pdf(materials, name, wi, wo)[0], rtol=2e-4)
    w = rng.normal(size=(200_000, 3))
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    pdf = eval_pdf(materials, name, WO, w)[1]
    integral, error = pdf.mean() * 4 * np.pi, 4 * pdf.std() * 4 * np.pi / np.sqrt(len(pdf))
    _, _, pdf_drawn, flags, _ = sample(materials, name, 20_000)
    kept = ((pdf_drawn > 0) & ((flags & BSDF_SPECULAR) == 0)).mean()
    assert integral <= 1.0 + error and abs(integral - kept) < error + 0.01
