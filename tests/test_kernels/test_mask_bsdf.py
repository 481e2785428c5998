"""Masks (``MASK`` of kernels/materials/mask.py, Mitsuba 3's ``mask``): the BSDF functions against their
inner material's scaled by the opacity, the null lobe's sample, the back of a one-sided inner
material, a textured opacity and the host's lobe table."""

import numpy as np
import pytest
import warp as wp
import wrt.kernels  # noqa: F401
from wrt.kernels.materials import BSDF_DIFFUSE, BSDF_REFLECTION, BSDF_SPECULAR, NULL_LOBE, MaterialData, make_bsdf
from wrt.kernels.sampling import independent_1d as sample_1d
from wrt.kernels.textures import uv_context

import wrt
from wrt.device import upload_materials

BSDF = make_bsdf(beckmann=False, anisotropic=False)  # every family's cases, isotropic GGX alone
bsdf_eval = BSDF.eval
bsdf_pdf = BSDF.pdf
bsdf_sample = BSDF.sample

pytestmark = pytest.mark.usefixtures("device")  # every test on every available device

MATERIALS = [
    {"name": "green", "albedo": [0.2, 0.6, 0.15], "two_sided": False},
    {"name": "coat", "type": "plastic", "albedo": [0.7, 0.2, 0.1], "ior": 1.49},
    {"name": "veil", "type": "mask", "material": "green", "opacity": 0.3},
    {"name": "coated", "type": "mask", "material": "coat", "opacity": 0.6},
    {"name": "opaque", "type": "mask", "material": "green", "opacity": 1.0},
    {"name": "clear", "type": "mask", "material": "green", "opacity": 0.0},
    {
        "name": "leaf",
        "type": "mask",
        "material": "coat",
        "opacity": {"texture": "checkerboard", "color0": [0.9, 0.7, 0.8], "color1": [0.1, 0.2, 0.0]},
    },
]
INDEX = {m["name"]: k for k, m in enumerate(MATERIALS)}
MASKS = {"veil": 0.3, "coated": 0.6, "opaque": 1.0, "clear": 0.0, "leaf": 0.8}  # leaf: at uv (0.25, 0.25)
UV = wp.vec2(0.25, 0.25)  # the leaf's checkerboard: color0 (mean 0.8)


def upper_directions(rng, count: int) -> np.ndarray:
    """Unit directions, uniform over the upper hemisphere (about +z)."""
    v = rng.normal(size=(count, 3))
    v[:, 2] = np.abs(v[:, 2]) + 1e-3
    return v / np.linalg.norm(v, axis=1, keepdims=True)


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
    f[k] = bsdf_eval(materials, m, n, wo[k], wi[k], 1.0, uv_context(UV), front)
    pdf[k] = bsdf_pdf(materials, m, n, wo[k], wi[k], 1.0, uv_context(UV), front)


def eval_pdf(materials, name, wo, wi, front=True):
    out = [wp.zeros(len(wo), dtype=t) for t in (wp.vec3, float)]
    arrays = [wp.array(np.float32(a), dtype=wp.vec3) for a in (wo, wi)]
    wp.launch(evaluate, dim=len(wo), inputs=[materials, INDEX[name], front, *arrays, *out])
    return [a.numpy().astype(np.float64) for a in out]


@wp.kernel
def draw(
    materials: MaterialData,
    m: wp.int32,
    front: bool,
    uc_scale: float,
    wo: wp.vec3,
    wi: wp.array(dtype=wp.vec3),
    weight: wp.array(dtype=wp.vec3),
    pdf: wp.array(dtype=float),
    flags: wp.array(dtype=wp.int32),
):
    """Sample ``k`` of material ``m`` with ``uc`` times ``uc_scale`` (a mask's inner material is
    drawn with ``uc / opacity``: the same sample as the mask's when ``uc_scale`` is ``1 / opacity``)."""
    k = wp.tid()
    n = wp.vec3(0.0, 0.0, 1.0)
    u = wp.vec2(sample_1d(5, k, 0, 0), sample_1d(5, k, 0, 1))
    s = bsdf_sample(materials, m, n, wo, 1.0, sample_1d(5, k, 0, 2) * uc_scale, u, uv_context(UV), front)
    wi[k] = s.wi
    weight[k] = s.weight
    pdf[k] = s.pdf
    flags[k] = s.flags


def sample(materials, name, wo, count, front=True, uc_scale=1.0):
    out = [wp.zeros(count, dtype=t) for t in (wp.vec3, wp.vec3, float, wp.int32)]
    wp.launch(draw, dim=count, inputs=[materials, INDEX[name], front, uc_scale, wp.vec3(*wo), *out])
    return [a.numpy() for a in out]


def test_lobes_are_the_inner_materials_and_the_null_lobe(materials):
    """The host table: a mask's lobes are its inner material's, plus the null lobe unless it is
    opaque (constant opacity 1); a textured opacity may be below 1 anywhere."""
    flags = dict(zip(INDEX, materials.flags.numpy()))
    diffuse = BSDF_REFLECTION | BSDF_DIFFUSE
    assert flags["veil"] == flags["clear"] == diffuse | NULL_LOBE
    assert flags["opaque"] == diffuse
    assert flags["coated"] == flags["leaf"] == BSDF_REFLECTION | BSDF_DIFFUSE | BSDF_SPECULAR | NULL_LOBE
    assert materials.inner.numpy()[INDEX["leaf"]] == INDEX["coat"]


@pytest.mark.parametrize("name", list(MASKS))
def test_eval_and_pdf_are_the_inner_materials_times_the_opacity(materials, name):
    """f and pdf of a mask: opacity times its inner material's, at random directions above the
    surface; across the surface nothing (neither inner material transmits)."""
    rng = np.random.default_rng(3)
    wo, wi = upper_directions(rng, 256), upper_directions(rng, 256)
    inner = MATERIALS[INDEX[name]]["material"]
    f, pdf = eval_pdf(materials, name, wo, wi)
    f_inner, pdf_inner = eval_pdf(materials, inner, wo, wi)
    assert f_inner.max() > 0.0 and pdf_inner.max() > 0.0
    np.testing.assert_allclose(f, MASKS[name] * f_inner, rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(pdf, MASKS[name] * pdf_inner, rtol=1e-5, atol=1e-7)
    below = wi * [1.0, 1.0, -1.0]
    f, pdf = eval_pdf(materials, name, wo, below)
    assert not f.any() and not pdf.any()


@pytest.mark.parametrize("name", ["veil", "coated", "leaf", "clear"])
def test_sample_chooses_the_inner_material_or_the_null_lobe(materials, name):
    """A mask's samples with ``uc < opacity`` are its inner material's drawn with ``uc / opacity``
    (same direction and weight, pdf times the opacity); the others go straight on, ``wi = -wo``,
    weight 1, pdf ``1 - opacity``, flags the null lobe; the inner material is chosen with
    frequency ``opacity``."""
    opacity, count = MASKS[name], 4096
    wo = np.array([0.3, -0.2, 0.93]) / np.linalg.norm([0.3, -0.2, 0.93])
    wi, weight, pdf, flags = sample(materials, name, wo, count)
    inner = flags != NULL_LOBE
    assert abs(inner.mean() - opacity) < 4.0 * np.sqrt(max(opacity * (1 - opacity), 1e-9) / count) + 1e-9
    null = ~inner
    np.testing.assert_allclose(wi[null], np.broadcast_to(-wo, wi[null].shape), atol=1e-6)
    np.testing.assert_allclose(weight[null], 1.0)
    np.testing.assert_allclose(pdf[null], 1.0 - opacity, rtol=1e-6)
    if opacity > 0.0:
        wi_in, weight_in, pdf_in, flags_in = sample(
            materials, MATERIALS[INDEX[name]]["material"], wo, count, uc_scale=1.0 / opacity
        )
        np.testing.assert_allclose(wi[inner], wi_in[inner], atol=1e-6)
        np.testing.assert_allclose(weight[inner], weight_in[inner], rtol=1e-5)
        np.testing.assert_allclose(pdf[inner], opacity * pdf_in[inner], rtol=1e-5)
        np.testing.assert_array_equal(flags[inner], flags_in[inner])


def test_back_of_a_one_sided_inner_material_lets_only_the_null_lobe_through(materials):
    """On the back of a one-sided inner material (Mitsuba: its ``sample`` fails, its ``eval`` is 0)
    a mask scatters nothing, and its null lobe still lets the ray through with probability
    ``1 - opacity``; on the back of a two-sided one the inner material scatters as on the front."""
    rng = np.random.default_rng(4)
    wo, wi = upper_directions(rng, 64), upper_directions(rng, 64)
    f, pdf = eval_pdf(materials, "veil", wo, wi, front=False)
    assert not f.any() and not pdf.any()
    f, _ = eval_pdf(materials, "coated", wo, wi, front=False)
    np.testing.assert_allclose(f, eval_pdf(materials, "coated", wo, wi)[0], rtol=1e-6)
    wi, weight, pdf, flags = sample(materials, "veil", [0.0, 0.0, 1.0], 2048, front=False)
    lost = pdf == 0.0
    assert abs(lost.mean() - 0.3) < 0.05
    assert not weight[lost].any()
    np.testing.assert_array_equal(flags[~lost], NULL_LOBE)
    np.testing.assert_allclose(weight[~lost], 1.0)
    np.testing.assert_allclose(pdf[~lost], 0.7, rtol=1e-6)
