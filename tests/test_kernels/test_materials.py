"""The BSDF interface (kernels/materials/: the dispatch of every family): sample, eval and pdf
agree with each other and with closed forms, the flags say what each material is, and the delta
lobes conserve energy."""

import numpy as np
import pytest
import warp as wp
import wrt.kernels  # noqa: F401
from conftest import fresnel_dielectric64, make_scene
from wrt.kernels.materials import (
    BSDF_DIFFUSE,
    BSDF_GLOSSY,
    BSDF_MEDIUM,
    BSDF_REFLECTION,
    BSDF_SPECULAR,
    BSDF_TOTAL_INTERNAL,
    BSDF_TRANSMISSION,
    MaterialData,
    bsdf_flags,
    bsdf_flags_from,
    make_bsdf,
    non_specular,
)
from wrt.kernels.sampling import independent_1d as sample_1d

import wrt
from wrt.device import upload_materials

BSDF = make_bsdf()  # every material family's cases
bsdf_eval = BSDF.eval
bsdf_pdf = BSDF.pdf
bsdf_sample = BSDF.sample
specular_lobes = BSDF.specular_lobes

MATERIALS = {
    "diffuse": {"albedo": [0.8, 0.5, 0.2]},
    "phong": {"type": "phong", "albedo": [0.3, 0.3, 0.3], "specular": [0.6, 0.6, 0.6], "exponent": 40.0},
    "mirror": {"type": "mirror", "reflectance": [0.9, 0.8, 0.7]},
    "glass": {"type": "dielectric", "ior": 1.5},
    "glossy": {"type": "glossy", "roughness": 0.3, "reflectance": [1.0, 1.0, 1.0]},
}
INDEX = {name: k for k, name in enumerate(MATERIALS)}
N = wp.vec3(0.0, 0.0, 1.0)


@pytest.fixture
def materials(device) -> MaterialData:
    scene = wrt.parse_scene(
        {
            "camera": {"origin": [0, 0, 5], "look_at": [0, 0, 0]},
            "material": [{"name": name, **params} for name, params in MATERIALS.items()],
        }
    )
    return upload_materials(scene, device)


def direction(theta_deg: float) -> wp.vec3:
    t = np.radians(theta_deg)
    return wp.vec3(np.sin(t), 0.0, np.cos(t))


@wp.kernel
def draw(
    materials: MaterialData,
    m: wp.int32,
    wo: wp.vec3,
    eta: float,
    wi: wp.array(dtype=wp.vec3),
    weight: wp.array(dtype=wp.vec3),
    pdf: wp.array(dtype=float),
    flags: wp.array(dtype=wp.int32),
    f_cos_over_pdf: wp.array(dtype=wp.vec3),
    pdf_again: wp.array(dtype=float),
):
    """Sample k of ``bsdf_sample``, and what ``bsdf_eval`` and ``bsdf_pdf`` say of its direction."""
    k = wp.tid()
    n = wp.vec3(0.0, 0.0, 1.0)
    u = wp.vec2(sample_1d(3, k, 0, 0), sample_1d(3, k, 0, 1))
    s = bsdf_sample(materials, m, n, wo, eta, sample_1d(3, k, 0, 2), u)
    wi[k] = s.wi
    weight[k] = s.weight
    pdf[k] = s.pdf
    flags[k] = s.flags
    f_cos_over_pdf[k] = wp.vec3(0.0)
    pdf_again[k] = bsdf_pdf(materials, m, n, wo, s.wi)
    if s.pdf > 0.0 and non_specular(s.flags):
        f_cos_over_pdf[k] = bsdf_eval(materials, m, n, wo, s.wi) * (wp.dot(n, s.wi) / s.pdf)


def sample(materials, name, wo, eta=1.0, n=200_000):
    out = [wp.zeros(n, dtype=t) for t in (wp.vec3, wp.vec3, float, wp.int32, wp.vec3, float)]
    wp.launch(draw, dim=n, inputs=[materials, INDEX[name], wo, eta, *out])
    return [a.numpy() for a in out]


@wp.kernel
def flags_of(materials: MaterialData, out: wp.array(dtype=wp.int32)):
    out[wp.tid()] = bsdf_flags(materials, wp.tid())


def test_flags_describe_each_material(materials):
    out = wp.zeros(len(MATERIALS), dtype=wp.int32)
    wp.launch(flags_of, dim=len(MATERIALS), inputs=[materials, out])
    assert dict(zip(MATERIALS, out.numpy().tolist())) == {
        "diffuse": BSDF_REFLECTION | BSDF_DIFFUSE,
        "phong": BSDF_REFLECTION | BSDF_DIFFUSE | BSDF_GLOSSY,
        "mirror": BSDF_REFLECTION | BSDF_SPECULAR,
        "glass": BSDF_REFLECTION | BSDF_TRANSMISSION | BSDF_SPECULAR | BSDF_MEDIUM,  # it bounds a medium
        "glossy": BSDF_REFLECTION | BSDF_GLOSSY,
    }


@wp.kernel
def flags_from(materials: MaterialData, front: bool, out: wp.array(dtype=wp.int32)):
    out[wp.tid()] = bsdf_flags_from(materials, wp.tid(), front)


ONE_SIDED = ["diffuse", "phong", "mirror", "glossy"]  # the types that may be one-sided (two_sided = false)


def test_the_back_of_a_one_sided_material_scatters_nothing(device):
    """``bsdf_flags_from``: every material's front and a two-sided one's back have its BSDF's
    flags, the back of a one-sided one none."""
    tables = [{"name": name, **params} for name, params in MATERIALS.items()]
    tables += [{"name": f"{name}, one-sided", **MATERIALS[name], "two_sided": False} for name in ONE_SIDED]
    scene = wrt.parse_scene({"camera": {"origin": [0, 0, 5], "look_at": [0, 0, 0]}, "material": tables})
    materials = upload_materials(scene, device)
    seen = {}
    for front in (True, False):
        out = wp.zeros(len(tables), dtype=wp.int32, device=device)
        wp.launch(flags_from, dim=len(tables), inputs=[materials, front, out], device=device)
        seen[front] = out.numpy().tolist()
    flags = wp.zeros(len(tables), dtype=wp.int32, device=device)
    wp.launch(flags_of, dim=len(tables), inputs=[materials, flags], device=device)
    flags = flags.numpy().tolist()
    assert seen[True] == flags and 0 not in flags
    assert seen[False] == flags[: len(MATERIALS)] + [0] * len(ONE_SIDED)


SQUARE = {"type": "polygon", "vertices": [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]]}  # its front faces +z


def square_render(integrator, side, material, lights, **render):
    """The square seen from its front (``side`` 1: the camera at z = 3) or its back (-1), 16 x 16
    pixels at 1 sample (the pixel centres)."""
    settings = {"width": 16, "height": 16, "integrator": integrator, "spp": 1, "max_depth": 2, **render}
    camera = {"origin": [0, 0, 3 * side], "look_at": [0, 0, 0], "fov": 40}
    scene = make_scene(
        [{**SQUARE, "material": "m"}],
        render=settings,
        camera=camera,
        materials=[{"name": "m", **material}],
        lights=lights,
    )
    r = wrt.render(scene)
    on = r.aovs["object_id"] == 0
    assert on.sum() > 150
    return r, on


@pytest.mark.parametrize("integrator", ["whitted", "path"])
@pytest.mark.parametrize("side", [1, -1], ids=["front", "back"])
@pytest.mark.parametrize("two_sided", [True, False], ids=["two-sided", "one-sided"])
def test_a_one_sided_diffuse_square_is_black_from_behind(integrator, side, two_sided):
    """A diffuse square under a point light on the camera's side shows albedo/pi I cos / d^2
    (exact: path at max_depth 2 is next-event estimation alone), except from behind a one-sided
    square, which is black. The AOVs see the surface either way (normal: facing the camera)."""
    albedo, intensity, light = np.array([0.5, 0.6, 0.7]), [4.0, 5.0, 6.0], np.array([0.3, 0.2, side])
    point = {"type": "point", "position": light.tolist(), "intensity": intensity}
    material = {"albedo": albedo.tolist(), "two_sided": two_sided}
    r, on = square_render(integrator, side, material, [point])
    to_light = light - r.aovs["position"][on].astype(np.float64)
    d2 = (to_light**2).sum(axis=1)
    expected = albedo / np.pi * np.asarray(intensity) * (to_light[:, 2] * side / d2**1.5)[:, None]
    np.testing.assert_allclose(r.rgb[on], expected if side > 0 or two_sided else 0.0, rtol=1e-4, atol=0.0)
    np.testing.assert_allclose(r.aovs["normal"][on], np.broadcast_to([0, 0, side], (on.sum(), 3)), atol=1e-6)


@pytest.mark.parametrize("integrator", ["whitted", "path"])
@pytest.mark.parametrize("name", ["phong", "mirror", "glossy"])
def test_one_sided_phong_mirror_glossy_are_black_from_behind(integrator, name):
    """Seen from behind under a point light and a grey sky (whitted: ``background``), a two-sided
    square is lit at every pixel (the mirror reflects the sky), a one-sided one black at every pixel."""
    lights = [{"type": "point", "position": [0.3, 0.2, -1.0], "intensity": [4.0, 4.0, 4.0]}]
    sky = {"background": [0.5, 0.5, 0.5]}
    if integrator == "path":
        lights, sky = [*lights, {"type": "environment", "radiance": [0.5, 0.5, 0.5]}], {}
    for two_sided in (True, False):
        r, on = square_render(integrator, -1, {**MATERIALS[name], "two_sided": two_sided}, lights, **sky)
        lit = r.rgb[on].min(axis=1)
        assert lit.min() > 0.0 if two_sided else r.rgb[on].max() == 0.0


@pytest.mark.parametrize("name", ["diffuse", "phong", "glossy"])
@pytest.mark.parametrize("theta", [0.0, 40.0, 75.0])
def test_sample_weight_is_eval_cos_over_pdf(materials, name, theta):
    """The weight a sample carries is f cos / pdf of its own direction, and its pdf is bsdf_pdf's."""
    wi, weight, pdf, _, f_cos_over_pdf, pdf_again = sample(materials, name, direction(theta))
    kept = pdf > 0
    assert kept.mean() > 0.8
    np.testing.assert_allclose(weight[kept], f_cos_over_pdf[kept], rtol=2e-4, atol=1e-6)
    np.testing.assert_allclose(pdf[kept], pdf_again[kept], rtol=2e-4)
    assert np.all(wi[kept, 2] > 0)


@pytest.mark.parametrize("theta", [0.0, 60.0])
def test_diffuse_albedo_and_cosine_density(materials, theta):
    """Lambert: every sample's weight is the albedo exactly (f cos / pdf = albedo), pdf = cos / pi."""
    wi, weight, pdf, flags, _, _ = sample(materials, "diffuse", direction(theta))
    np.testing.assert_allclose(weight, np.broadcast_to([0.8, 0.5, 0.2], weight.shape), rtol=1e-5)
    np.testing.assert_allclose(pdf, wi[:, 2] / np.pi, rtol=1e-5)
    assert np.all(flags == BSDF_REFLECTION | BSDF_DIFFUSE)


def test_phong_conserves_energy(materials):
    """albedo + specular = 0.9 <= 1: the estimated directional albedo stays below it at normal
    incidence (the normalised lobe loses what falls below the horizon), and above the Lambert part."""
    _, weight, _, _, _, _ = sample(materials, "phong", direction(0.0))
    albedo = weight[:, 0].mean()
    error = 4 * weight[:, 0].std() / np.sqrt(len(weight))
    assert 0.3 < albedo < 0.9 + error


@pytest.mark.parametrize("theta", [0.0, 30.0, 60.0, 85.0])
def test_mirror_reflects_its_reflectance(materials, theta):
    wo = direction(theta)
    wi, weight, pdf, flags, _, pdf_again = sample(materials, "mirror", wo, n=16)
    np.testing.assert_allclose(wi, np.broadcast_to([-wo[0], 0.0, wo[2]], wi.shape), atol=1e-6)
    np.testing.assert_allclose(weight, np.broadcast_to([0.9, 0.8, 0.7], weight.shape), rtol=1e-6)
    assert np.all(pdf == 1.0) and np.all(flags == BSDF_REFLECTION | BSDF_SPECULAR)
    assert np.all(pdf_again == 0.0)  # a delta lobe has no density


@wp.kernel
def lobes_of(
    materials: MaterialData,
    m: wp.int32,
    wo: wp.array(dtype=wp.vec3),
    eta: float,
    r: wp.array(dtype=wp.vec3),
    t: wp.array(dtype=wp.vec3),
    wt: wp.array(dtype=wp.vec3),
    tir: wp.array(dtype=wp.int32),
):
    k = wp.tid()
    lobes = specular_lobes(materials, m, wp.vec3(0.0, 0.0, 1.0), wo[k], eta)
    r[k] = lobes.reflectance
    t[k] = lobes.transmittance
    wt[k] = lobes.wt
    tir[k] = wp.where(lobes.total_internal, 1, 0)


def glass_lobes(materials, thetas, eta):
    wo = wp.array([direction(a) for a in thetas], dtype=wp.vec3)
    out = [wp.zeros(len(thetas), dtype=t) for t in (wp.vec3, wp.vec3, wp.vec3, wp.int32)]
    wp.launch(lobes_of, dim=len(thetas), inputs=[materials, INDEX["glass"], wo, eta, *out])
    return [a.numpy() for a in out]


def test_dielectric_lobes_split_by_fresnel_and_snell(materials):
    """Entering glass (eta = 1/1.5): F from the float64 Fresnel equations, 1 - F transmitted along
    Snell's direction, radiance scaled by eta^2 (issue 13: radiance transport, as pbrt-v4 and
    Mitsuba 3); leaving it (eta = 1.5) past the critical angle 41.8 deg: all reflected."""
    thetas = np.array([0.0, 20.0, 45.0, 70.0, 89.0])
    r, t, wt, tir = glass_lobes(materials, thetas, 1 / 1.5)
    f = fresnel_dielectric64(np.cos(np.radians(thetas)), 1 / 1.5)
    np.testing.assert_allclose(r[:, 0], f, rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(t[:, 0], (1.0 - f) / 1.5**2, rtol=1e-5)
    sin_t = np.sin(np.radians(thetas)) / 1.5
    np.testing.assert_allclose(-wt[:, 0], sin_t, atol=1e-6)  # bends toward the normal, across the surface
    assert np.all(wt[:, 2] < 0) and not tir.any()
    r, t, _, tir = glass_lobes(materials, np.array([30.0, 41.0, 42.5, 60.0]), 1.5)
    assert tir.tolist() == [0, 0, 1, 1]
    np.testing.assert_array_equal(r[2:], 1.0)
    np.testing.assert_array_equal(t[2:], 0.0)


def test_dielectric_sampling_chooses_reflection_with_probability_f(materials):
    """Reflection has weight F / F = 1, refraction (1 - F) eta^2 / (1 - F) = eta^2; the share of
    reflections is F."""
    wo = direction(70.0)
    wi, weight, pdf, flags, _, _ = sample(materials, "glass", wo, eta=1 / 1.5)
    f = fresnel_dielectric64(np.cos(np.radians(70.0)), 1 / 1.5)
    reflected = (flags & BSDF_TRANSMISSION) == 0
    assert reflected.mean() == pytest.approx(f, abs=4 * np.sqrt(f * (1 - f) / len(flags)))
    np.testing.assert_array_equal(weight[reflected], 1.0)
    np.testing.assert_allclose(weight[~reflected], 1 / 1.5**2, rtol=1e-6)
    np.testing.assert_allclose(pdf[reflected], f, rtol=1e-5)
    np.testing.assert_allclose(pdf[~reflected], 1.0 - f, rtol=1e-5)
    assert np.all(wi[reflected, 2] > 0) and np.all(wi[~reflected, 2] < 0)
    _, _, _, flags, _, _ = sample(materials, "glass", direction(60.0), eta=1.5, n=64)
    assert np.all(flags == BSDF_REFLECTION | BSDF_SPECULAR | BSDF_TOTAL_INTERNAL)
