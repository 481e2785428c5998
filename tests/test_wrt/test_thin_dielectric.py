"""The ``thin_dielectric`` material (a window pane): its summed Fresnel reflectance R' against a
float64 closed form and Mitsuba 3's ``thindielectric``, its lobes (straight transmission, no
medium), renders of a pane in front of an emitter (T' at every pixel), its scene keys and its
Mitsuba import."""

import numpy as np
import pytest
import warp as wp
from conftest import fresnel_dielectric64, make_scene
from test_mitsuba_xml import convert
from wrt.kernels.materials import BSDF_THIN, BSDF_TRANSMISSION, MaterialData, make_bsdf
from wrt_harness.mitsuba_peer import mitsuba_available

import wrt
from wrt.device import upload_materials
from wrt.errors import SceneError, WrtError
from wrt.renderer import scene_features

BSDF = make_bsdf(beckmann=False, anisotropic=False)  # every family's cases, isotropic GGX alone
bsdf_sample = BSDF.sample
specular_lobes = BSDF.specular_lobes

MITSUBA, MITSUBA_REASON = mitsuba_available()
THETAS = np.radians([0.0, 20.0, 45.0, 60.0, 75.0, 85.0, 89.0])


def summed64(cos_i, ior):
    """R' = R + T^2 R / (1 - R^2): the pane's internal reflections summed term by term."""
    r = fresnel_dielectric64(cos_i, 1.0 / ior)
    t = 1.0 - r
    return r + t * t * r / (1.0 - r * r)


def pane(**keys):
    return {"name": "pane", "type": "thin_dielectric", **keys}


@wp.kernel
def lobes_at(
    materials: MaterialData,
    wo: wp.array(dtype=wp.vec3),
    uc: float,
    out: wp.array2d(dtype=wp.vec3),
    flags: wp.array(dtype=wp.int32),
):
    i = wp.tid()
    n = wp.vec3(0.0, 0.0, 1.0)
    lobes = specular_lobes(materials, 0, n, wo[i], 1.0)
    s = bsdf_sample(materials, 0, n, wo[i], 1.0, uc, wp.vec2(0.5))
    out[i, 0] = lobes.reflectance
    out[i, 1] = lobes.transmittance
    out[i, 2] = lobes.wt
    out[i, 3] = s.wi
    out[i, 4] = s.weight
    out[i, 5] = wp.vec3(s.pdf)
    flags[i] = s.flags


def lobes(material, uc=0.999, render=None):
    """What the kernels give a pane ``material`` at ``THETAS`` (wo in the xz plane, n = +z)."""
    materials = upload_materials(make_scene([], render=render, materials=[material]), "cpu")
    wo = np.stack([np.sin(THETAS), np.zeros_like(THETAS), np.cos(THETAS)], -1).astype(np.float32)
    out = wp.zeros((len(THETAS), 6), dtype=wp.vec3, device="cpu")
    flags = wp.zeros(len(THETAS), dtype=wp.int32, device="cpu")
    wp.launch(lobes_at, dim=len(THETAS), inputs=[materials, wp.array(wo, dtype=wp.vec3), uc, out, flags], device="cpu")
    return wo, out.numpy().astype(np.float64), flags.numpy()


@pytest.mark.parametrize("ior", [1.5, 1.33, 2.4])
def test_summed_reflectance_matches_float64_and_conserves_energy(ior):
    _, out, _ = lobes(pane(ior=ior))
    expected = summed64(np.cos(THETAS), ior)
    np.testing.assert_allclose(out[:, 0, 0], expected, rtol=2e-5, atol=1e-6)
    np.testing.assert_allclose(out[:, 0, :] + out[:, 1, :], 1.0, atol=1e-6)  # R' + T' = 1 without tints
    assert (out[:, 0, 0] > fresnel_dielectric64(np.cos(THETAS), 1.0 / ior) - 1e-6).all()  # more than one surface's R


def test_ior_is_relative_to_the_exterior_and_tints_scale_the_lobes():
    _, out, _ = lobes(pane(ior=1.5), render={"exterior_ior": 1.2})
    np.testing.assert_allclose(out[:, 0, 0], summed64(np.cos(THETAS), 1.5 / 1.2), rtol=2e-5, atol=1e-6)
    tint_r, tint_t = np.array([0.9, 0.5, 0.2]), np.array([0.3, 0.6, 1.0])
    _, out, _ = lobes(pane(ior=1.5, reflectance=tint_r.tolist(), transmittance=tint_t.tolist()))
    r = summed64(np.cos(THETAS), 1.5)[:, None]
    np.testing.assert_allclose(out[:, 0], r * tint_r, rtol=2e-5, atol=1e-6)
    np.testing.assert_allclose(out[:, 1], (1.0 - r) * tint_t, rtol=2e-5, atol=1e-6)


def test_transmission_goes_straight_on_and_reflection_mirrors():
    wo, out, flags = lobes(pane(transmittance=[0.5, 0.6, 0.7]), uc=0.999)
    np.testing.assert_array_equal(out[:, 2], -wo)  # the transmitted direction, unchanged
    np.testing.assert_array_equal(out[:, 3], -wo)
    np.testing.assert_allclose(out[:, 4], [[0.5, 0.6, 0.7]] * len(wo), rtol=1e-6)  # the tint: (1 - R') / (1 - R')
    np.testing.assert_allclose(out[:, 5, 0], 1.0 - summed64(np.cos(THETAS), 1.5), rtol=1e-5)
    assert ((flags & BSDF_THIN) != 0).all() and ((flags & BSDF_TRANSMISSION) != 0).all()
    wo, out, flags = lobes(pane(reflectance=[0.5, 0.6, 0.7]), uc=0.0)
    np.testing.assert_allclose(out[:, 3], wo * [-1.0, -1.0, 1.0], atol=1e-6)
    np.testing.assert_allclose(out[:, 4], [[0.5, 0.6, 0.7]] * len(wo), rtol=1e-6)
    np.testing.assert_allclose(out[:, 5, 0], summed64(np.cos(THETAS), 1.5), rtol=1e-5)
    assert (flags & (BSDF_THIN | BSDF_TRANSMISSION) == 0).all()


@pytest.mark.skipif(not MITSUBA, reason=MITSUBA_REASON)
def test_summed_reflectance_matches_mitsuba():
    """Mitsuba's thindielectric chooses reflection with probability R' (its sample pdf)."""
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    bsdf = mi.load_dict({"type": "thindielectric", "int_ior": 1.5, "ext_ior": 1.2})
    theirs = []
    for theta in THETAS:
        si = mi.SurfaceInteraction3f()
        si.wi = mi.Vector3f(np.sin(theta), 0.0, np.cos(theta))
        si.sh_frame = mi.Frame3f(mi.Vector3f(0.0, 0.0, 1.0))
        sample, _ = bsdf.sample(mi.BSDFContext(), si, 0.0, mi.Point2f(0.5, 0.5))
        theirs.append(sample.pdf)
    _, out, _ = lobes(pane(ior=1.5), render={"exterior_ior": 1.2})
    np.testing.assert_allclose(out[:, 0, 0], theirs, rtol=1e-5, atol=1e-6)


SIZE = 12
RADIANCE = 2.0


def pane_scene(integrator, *, glass=False, shadows=None):
    """The camera at the origin looking down -z (fov 90) through a pane of glass at z = -1 (two
    triangles) at an emitting surface of radiance ``RADIANCE`` filling the view at z = -2, nothing else
    (``glass``: plus a dielectric ball behind the camera, so that media are compiled in)."""
    shapes = []
    for z, size, material in ((-1.0, 10.0, "pane"), (-2.0, 40.0, "emitter")):
        quad = [[-size, -size, z], [size, -size, z], [size, size, z], [-size, size, z]]
        shapes += [
            {"type": "triangle", "vertices": [quad[0], quad[1], quad[2]], "material": material},
            {"type": "triangle", "vertices": [quad[0], quad[2], quad[3]], "material": material},
        ]
    materials = [pane(ior=1.5), {"name": "emitter", "albedo": [0.0] * 3, "emission": [RADIANCE] * 3}]
    if glass:
        shapes.append({"type": "sphere", "center": [0.0, 0.0, 5.0], "radius": 1.0, "material": "glass"})
        materials.append({"name": "glass", "type": "dielectric", "ior": 1.5})
    render = {"width": SIZE, "height": SIZE, "integrator": integrator, "max_depth": 4, "sampler": "sobol"}
    camera = {"origin": [0.0, 0.0, 0.0], "look_at": [0.0, 0.0, -1.0], "fov": 90.0}
    return make_scene(shapes, render=render, camera=camera, materials=materials)


def pixel_transmittance():
    """T' = 1 - R' at each pixel centre: the camera ray's incidence cosine on the pane is |d_z|."""
    c = (2.0 * (np.arange(SIZE) + 0.5) / SIZE - 1.0) ** 2
    cos_theta = 1.0 / np.sqrt(1.0 + c[:, None] + c[None, :])
    return 1.0 - summed64(cos_theta, 1.5)


@pytest.mark.parametrize("glass", [False, True], ids=["no_media", "media"])
def test_whitted_pane_transmits_t_prime_at_every_pixel(glass):
    """The reflected branch sees black; the transmitted one, straight on, the emitter: T' L exactly."""
    rgb = wrt.render(pane_scene("whitted", glass=glass), spp=1).rgb.astype(np.float64)
    np.testing.assert_allclose(rgb, RADIANCE * pixel_transmittance()[..., None] * np.ones(3), rtol=1e-5)


@pytest.mark.parametrize("glass", [False, True], ids=["no_media", "media"])
def test_path_pane_transmits_t_prime_on_average(glass):
    """Each sample is L (transmitted, probability T') or 0: the image mean is T' L within its noise."""
    spp = 64
    rgb = wrt.render(pane_scene("path", glass=glass), spp=spp).rgb.astype(np.float64)
    assert set(np.unique(rgb * spp / RADIANCE).round(3)) <= set(np.arange(spp + 1.0))  # whole samples: L or 0
    t = pixel_transmittance()
    sigma = RADIANCE * np.sqrt((t * (1.0 - t)).sum() / spp) / t.size  # binomial, independent samples
    assert abs(rgb.mean() - RADIANCE * t.mean()) < 4.0 * sigma


def test_scene_keys_and_bad_input():
    scene = make_scene([], materials=[pane(ior=1.52, reflectance=[0.9] * 3, transmittance=[0.8, 0.9, 1.0])])
    m = scene.materials[0]
    assert (m.type, m.ior, m.reflectance, m.transmittance) == ("thin_dielectric", 1.52, (0.9,) * 3, (0.8, 0.9, 1.0))
    features = scene_features(pane_scene("path"))
    assert features.specular and not features.dielectric  # delta lobes, but no media bookkeeping
    with pytest.raises(SceneError, match=r"material\[0\].*ior"):
        make_scene([], materials=[pane(ior=0.5)])
    with pytest.raises(SceneError, match=r"material\[0\].*two_sided"):
        make_scene([], materials=[pane(two_sided=False)])
    with pytest.raises(SceneError, match=r"material\[0\].*priority"):
        make_scene([], materials=[pane(priority=1)])


def test_mitsuba_thindielectric_converts_exactly(tmp_path):
    body = """
    <shape type="rectangle"><bsdf type="thindielectric">
        <float name="int_ior" value="1.6"/><string name="ext_ior" value="water"/>
        <rgb name="specular_reflectance" value="0.9, 0.8, 0.7"/>
        <rgb name="specular_transmittance" value="0.5, 0.6, 0.7"/></bsdf></shape>"""
    doc, warnings = convert(tmp_path, body, approximate=False)
    assert doc["material"][0] == {
        "name": "thin_dielectric@2",
        "type": "thin_dielectric",
        "ior": 1.6,
        "reflectance": [0.9, 0.8, 0.7],
        "transmittance": [0.5, 0.6, 0.7],
    }
    assert doc["render"]["exterior_ior"] == 1.333 and warnings == []
    doc, _ = convert(tmp_path, '<shape type="rectangle"><bsdf type="thindielectric"/></shape>')
    assert doc["material"][0]["ior"] == 1.5046 and doc["render"]["exterior_ior"] == 1.000277  # bk7 in air
    with pytest.raises(WrtError, match=r"scene.xml:2: <bsdf type=\"thindielectric\">: .*transmits"):
        convert(tmp_path, '<shape type="rectangle"><bsdf type="twosided"><bsdf type="thindielectric"/></bsdf></shape>')


@pytest.mark.parametrize("shadows", ["opaque", "filtered"])
def test_whitted_filtered_shadow_rays_pass_a_pane_by_its_straight_transmittance(shadows):
    """A point light of intensity I at height 2 above a diffuse floor (albedo a), a pane at height
    1 between them, the camera's single pixel centre at the point below the light: filtered
    shadow rays give ``a / pi * I / 4 * T'(0) * transmittance`` there, opaque ones 0."""
    quad = [[-10.0, -10.0, 1.0], [10.0, -10.0, 1.0], [10.0, 10.0, 1.0], [-10.0, 10.0, 1.0]]
    shapes = [
        {"type": "plane", "point": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0], "material": "floor"},
        {"type": "triangle", "vertices": [quad[0], quad[1], quad[2]], "material": "pane"},
        {"type": "triangle", "vertices": [quad[0], quad[2], quad[3]], "material": "pane"},
    ]
    tint = np.array([0.5, 0.7, 0.9])
    materials = [{"name": "floor", "albedo": [0.5] * 3}, pane(ior=1.5, transmittance=tint.tolist())]
    lights = [{"type": "point", "position": [0.0, 0.0, 2.0], "intensity": [8.0] * 3}]
    render = {"width": 1, "height": 1, "integrator": "whitted", "max_depth": 2, "dielectric_shadows": shadows}
    camera = {"origin": [0.0, 0.0, 0.5], "look_at": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0], "fov": 10.0}
    scene = make_scene(shapes, render=render, camera=camera, materials=materials, lights=lights)
    rgb = wrt.render(scene, spp=1).rgb.astype(np.float64)[0, 0]
    expected = 0.5 / np.pi * 8.0 / 4.0 * (1.0 - summed64(1.0, 1.5)) * tint if shadows == "filtered" else 0.0 * tint
    np.testing.assert_allclose(rgb, expected, rtol=1e-5, atol=1e-7)
