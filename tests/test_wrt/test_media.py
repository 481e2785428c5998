"""Participating media end to end (the path integrator, Mitsuba 3's volpath semantics) against
closed forms: the transmittance of an absorbing slab, a white furnace (an albedo-1 medium under a
uniform environment returns the environment exactly, at any sigma_t and g) and the single
scattering of a thin slab lit from behind; the scene format's media keys and their errors; the
Mitsuba importer's media. Renders take the all-features kernel (shipped compiled)."""

import math

import numpy as np
import pytest
from test_bad_input import GOOD, run_bad
from wrt_benchmarks import null_boundary_scattering as scattering
from wrt_harness.mitsuba_suite import CROSSCHECKS
from wrt_harness.score import ssim

import wrt
from wrt.errors import WrtError
from wrt.loader import override_render, parse_scene
from wrt.mitsuba import load_mitsuba

ORTHOGRAPHIC = {"type": "orthographic", "origin": [0.0, 0.0, 5.0], "look_at": [0.0, 0.0, 0.0], "width": 1.0}
NULL = {"name": "boundary", "type": "null"}


def slab(front_z, back_z, medium, half=4.0):
    """Two null squares bounding a slab between z = back_z and z = front_z (the front facing +z,
    the back -z), both naming the slab's medium as their interior: a ray from +z enters it at
    the front and leaves it, into vacuum, at the back."""
    square = [[-half, -half], [half, -half], [half, half], [-half, half]]  # counter-clockwise seen from +z
    return [
        {
            "type": "polygon",
            "vertices": [[x, y, front_z] for x, y in square],
            "material": "boundary",
            "interior": medium,
        },
        {
            "type": "polygon",
            "vertices": [[x, y, back_z] for x, y in square[::-1]],
            "material": "boundary",
            "interior": medium,
        },
    ]


def render_mean(doc, spp, seed=1):
    scene = parse_scene(doc, file="<test>")
    image = wrt.render(scene, spp=spp, seed=seed, specialize=False).rgb.astype(np.float64)
    return image, image.mean(axis=(0, 1))


def test_an_absorbing_slab_transmits_exp_minus_sigma_t_d_per_channel():
    """A chromatic pure absorber (albedo 0) of thickness 1 before a uniform environment of
    radiance 1, seen by an orthographic camera: every pixel's expected value is
    exp(-sigma_t d), each channel its own; the estimate is held to 4 standard errors."""
    sigma_t = np.array([0.5, 1.0, 2.0])
    doc = {
        "render": {"width": 8, "height": 8, "integrator": "path", "max_depth": 4, "sampler": "independent"},
        "camera": ORTHOGRAPHIC,
        "medium": [{"name": "ink", "sigma_t": sigma_t.tolist(), "albedo": 0.0}],
        "material": [NULL],
        "shape": slab(0.5, -0.5, "ink"),
        "light": [{"type": "environment", "radiance": [1.0, 1.0, 1.0]}],
    }
    spp = 1024
    image, mean = render_mean(doc, spp)
    expected = np.exp(-sigma_t)
    # spectral MIS: the weight of a passing path is T / mean(T) on 3 channels, a Bernoulli draw of mean(T)
    passing = expected.mean()
    std = expected / passing * math.sqrt(passing * (1 - passing) / (image.shape[0] * image.shape[1] * spp))
    assert np.all(np.abs(mean - expected) < 4 * std), (mean, expected, std)


@pytest.mark.parametrize("sigma_t, g", [(0.6, 0.0), (3.0, 0.7), (3.0, -0.5)])
def test_a_white_furnace_returns_the_environment(sigma_t, g):
    """An albedo-1 fog sphere (null boundary) under a uniform environment of radiance 1: light is
    scattered, never lost, so every pixel's expected value is 1 whatever sigma_t and g; the
    image mean is held to 1% and no pixel strays beyond its noise."""
    doc = {
        "render": {"width": 12, "height": 12, "integrator": "path", "max_depth": 1024},
        "camera": {"origin": [0.0, 0.0, 3.0], "look_at": [0.0, 0.0, 0.0], "fov": 30},
        "medium": [{"name": "fog", "sigma_t": sigma_t, "albedo": 1.0, "phase": {"type": "hg", "g": g}}],
        "material": [NULL],
        "shape": [
            {"type": "sphere", "center": [0.0, 0.0, 0.0], "radius": 1.0, "material": "boundary", "interior": "fog"}
        ],
        "light": [{"type": "environment", "radiance": [1.0, 1.0, 1.0]}],
    }
    image, mean = render_mean(doc, 256)
    np.testing.assert_allclose(mean, 1.0, rtol=0.01)
    assert np.abs(image - 1.0).max() < 0.2


def test_a_thin_slab_lit_from_behind_scatters_its_closed_form_once():
    """Single scattering (max_depth 2: the camera segment, then the shadow ray) of a slab of
    thickness d lit from straight behind by a directional light of irradiance E: every scattering
    point sees the light through the rest of the slab, so the radiance toward the camera is
    ``E sigma_s d exp(-sigma_t d) p(cos = -1)``, with the HG density backward to the light."""
    sigma_t, albedo, d, g, irradiance = 0.8, 0.7, 0.5, 0.4, 3.0
    doc = {
        "render": {"width": 8, "height": 8, "integrator": "path", "max_depth": 2},
        "camera": ORTHOGRAPHIC,
        "medium": [{"name": "haze", "sigma_t": sigma_t, "albedo": albedo, "phase": {"type": "hg", "g": g}}],
        "material": [NULL],
        "shape": slab(d / 2, -d / 2, "haze"),
        "light": [{"type": "directional", "direction": [0.0, 0.0, 1.0], "irradiance": [irradiance] * 3}],
    }
    _, mean = render_mean(doc, 512)
    backward = (1 - g * g) / (4 * math.pi * (1 + g * g - 2 * g) ** 1.5)
    expected = irradiance * albedo * sigma_t * d * math.exp(-sigma_t * d) * backward
    np.testing.assert_allclose(mean, expected, rtol=0.01)


def test_a_camera_inside_fog_sees_the_world_dimmed():
    """The camera's ``medium``: a camera inside an absorbing fog filling a null sphere sees the
    uniform environment dimmed by exp(-sigma_t r) (r the sphere's radius, the camera at its
    centre); outside it, undimmed."""
    doc = {
        "render": {"width": 8, "height": 8, "integrator": "path", "max_depth": 4, "sampler": "independent"},
        "camera": {"origin": [0.0, 0.0, 0.0], "look_at": [0.0, 0.0, -1.0], "fov": 20, "medium": "smoke"},
        "medium": [{"name": "smoke", "sigma_t": 0.7, "albedo": 0.0}],
        "material": [NULL],
        "shape": [
            {"type": "sphere", "center": [0.0, 0.0, 0.0], "radius": 2.0, "material": "boundary", "interior": "smoke"}
        ],
        "light": [{"type": "environment", "radiance": [1.0, 1.0, 1.0]}],
    }
    spp = 1024
    _, mean = render_mean(doc, spp)
    expected = math.exp(-0.7 * 2.0)
    std = math.sqrt(expected * (1 - expected) / (64 * spp))
    assert np.all(np.abs(mean - expected) < 4 * std), mean
    del doc["camera"]["medium"]
    _, mean = render_mean(doc, 16)
    np.testing.assert_allclose(mean, 1.0)


MEDIUM = '\n[[medium]]\nname = "fog"\nsigma_t = 1.0\nalbedo = 0.5\n'
BAD_MEDIA = [
    ("undefined medium", GOOD + 'interior = "mist"\n', "shape[0]", "interior", "mist", "no [[medium]]"),
    (
        "camera medium undefined",
        GOOD.replace("look_at = [0, 0, 0]", 'look_at = [0, 0, 0]\nmedium = "x"'),
        "camera",
        "medium",
    ),
    ("g at 1", GOOD + MEDIUM + 'phase = { type = "hg", g = 1.0 }\n', "medium[0].phase", "g", "(-1, 1)"),
    ("albedo above 1", GOOD + MEDIUM.replace("albedo = 0.5", "albedo = 1.5"), "medium[0]", "albedo"),
    ("negative sigma_t", GOOD + MEDIUM.replace("sigma_t = 1.0", "sigma_t = [1, -1, 1]"), "medium[0]", "sigma_t"),
    ("unknown phase", GOOD + MEDIUM + 'phase = { type = "rayleigh" }\n', "medium[0].phase", "type", "rayleigh"),
    ("unknown medium key", GOOD + MEDIUM + "density = 2\n", "medium[0]", "density", "unknown key"),
    ("name used twice", GOOD + MEDIUM + MEDIUM, "medium[1]", "name", "already used"),
    (
        "whitted with media",
        GOOD.replace("height = 16", 'height = 16\nintegrator = "whitted"') + MEDIUM,
        "medium[0]",
        "whitted",
    ),
]


@pytest.mark.parametrize("text, fragments", [(b[1], b[2:]) for b in BAD_MEDIA], ids=[b[0] for b in BAD_MEDIA])
def test_bad_media_are_one_line_and_exit_2(tmp_path, capsys, text, fragments):
    run_bad(tmp_path, capsys, text, *fragments)


def test_the_mitsuba_importer_converts_media_exactly(tmp_path):
    """A shape's interior and exterior (references and nested media), the sensor's medium, the
    null BSDF, both phase functions and volpathmis convert without approximation; a medium type
    wrt lacks is refused (converted only with --approximate)."""
    xml = tmp_path / "scene.xml"
    xml.write_text(
        """<scene version="3.0.0">
    <integrator type="volpathmis"><integer name="max_depth" value="12"/></integrator>
    <medium type="homogeneous" id="fog">
        <rgb name="sigma_t" value="0.5, 1, 1"/><float name="scale" value="2"/>
        <rgb name="albedo" value="0.8, 0.9, 1"/><phase type="hg"><float name="g" value="0.3"/></phase>
    </medium>
    <sensor type="perspective"><ref id="fog" name="medium"/></sensor>
    <shape type="sphere">
        <bsdf type="null"/><ref id="fog" name="interior"/>
        <medium type="homogeneous" name="exterior"><float name="sigma_t" value="0.1"/></medium>
    </shape>
</scene>"""
    )
    doc, approximations = load_mitsuba(xml)
    assert approximations == []
    assert doc["medium"] == [
        {
            "name": "fog",
            "type": "homogeneous",
            "sigma_t": [0.5, 1.0, 1.0],
            "albedo": [0.8, 0.9, 1.0],
            "scale": 2.0,
            "phase": {"type": "hg", "g": 0.3},
        },
        {"name": "medium@10", "type": "homogeneous", "sigma_t": [0.1] * 3, "albedo": [0.75] * 3, "scale": 1.0},
    ]
    assert doc["camera"]["medium"] == "fog"
    assert doc["shape"][0]["interior"] == "fog" and doc["shape"][0]["exterior"] == "medium@10"
    scene = wrt.load_scene(xml)
    assert scene.camera_medium == 0 and scene.boundaries == ((0, 0, 1),)
    assert scene.media[0].sigma_t == (0.5, 1.0, 1.0) and scene.media[0].scale == 2.0
    xml.write_text(xml.read_text().replace('type="homogeneous" id="fog"', 'type="rayleigh" id="fog"'))
    with pytest.raises(WrtError, match="rayleigh.*not supported"):
        load_mitsuba(xml)


MITSUBA_MEDIA = {  # scene: SSIM above
    "fog_area_light": 0.98,  # fog in a null sphere lit by an area light (measured: SSIM 0.994)
    # chromatic milk inside glass, and a camera and an emitter inside fog: noisier at this budget
    # (refracted and near-emitter light), their SSIM limited by noise: measured 0.89 at 512 spp
    # (Mitsuba at 4096; means within 0.43% and 0.36%); both at 4096: 0.956 and 0.972
    "milk_in_glass": 0.85,
    "camera_in_fog": 0.85,
}


@pytest.mark.parametrize("name", list(MITSUBA_MEDIA))
def test_media_agree_with_mitsuba(name):
    """Box filter, same camera, Mitsuba at 8x wrt's spp: every channel's image mean within 2% of Mitsuba's
    volpath (the rule of test_mitsuba_crosscheck; Mitsuba's image stored,
    ``wrt_harness.mitsuba_suite.CROSSCHECKS``) and SSIM of the tone-mapped images above the
    scene's bound."""
    check = CROSSCHECKS[name]
    scene = override_render(wrt.load_scene(check.path), width=check.width, height=check.height, sampler="sobol")
    ours = wrt.render(scene, spp=check.spp).rgb.astype(np.float64)  # the shipped variant
    theirs = check.image()
    assert ours.shape == theirs.shape and np.isfinite(ours).all()
    np.testing.assert_allclose(ours.mean(axis=(0, 1)), theirs.mean(axis=(0, 1)), rtol=0.02)
    assert ssim(ours.astype(np.float32), theirs.astype(np.float32)) > MITSUBA_MEDIA[name]


def test_single_scattering_toward_a_mesh_emitter_matches_an_independent_estimate(rng):
    """A null sphere of fog lit from the side by a flat-shaded emitting mesh (a cube), max_depth 2:
    wrt's image mean is the independent float64 single-scattering estimate of
    ``wrt_benchmarks.null_boundary_scattering`` within 0.6% (measured over 4 seeds: -0.16%, seed
    spread 0.1%). Mitsuba 3.9.1's volpath renders this scene 1.2% darker, and test_homo_area_light's
    perspective view of a polygonal fog sphere 2-3% darker (benchmarks/results/
    null_boundary_scattering.json; docs/mitsuba.md): this holds wrt to the physics where the two
    renderers part."""
    sigma_t, albedo = 2.5, 0.9
    doc = {
        "render": {"width": 16, "height": 16, "integrator": "path", "max_depth": 2},
        "camera": {**ORTHOGRAPHIC, "width": 0.4},
        "medium": [{"name": "fog", "sigma_t": sigma_t, "albedo": albedo}],
        "material": [NULL, {"name": "lamp", "albedo": [0.0, 0.0, 0.0], "emission": [scattering.EMISSION] * 3}],
        "shape": [
            {"type": "sphere", "center": [0.0, 0.0, 0.0], "radius": 0.5, "material": "boundary", "interior": "fog"},
            {
                "type": "mesh",
                "file": str(scattering.MESHES / "angled_cube.obj"),
                "material": "lamp",
                "transform": {"translate": list(scattering.CUBE_OFFSET)},
            },
        ],
    }
    _, mean = render_mean(doc, 1024)
    rays = scattering.orthographic_rays(ORTHOGRAPHIC["origin"][2], 0.2)
    expected = scattering.single_scattering(
        rays, sigma_t, albedo, scattering.cube_triangles(), scattering.EMISSION, 4_000_000, rng, radius=0.5
    )
    np.testing.assert_allclose(mean, expected, rtol=0.006)
