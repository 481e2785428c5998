"""Emissive media end to end (the path integrator; Mitsuba 3's ``volumelight`` semantics: a
medium's ``emission`` is the radiance it adds per unit length a ray crosses) against closed
forms: a glowing absorbing slab, homogeneous and as a grid (its emission scored by tracking),
a clear glowing grid, the endless glowing medium a camera sits in (``emission / sigma_a``, at
any albedo below 1 and any ``g``), a Mitsuba scene in the form of Mitsuba's own
test_homo_emissive_sphere (a clear sphere whose radiance is its chord) and that scene itself
(its image's mean the sphere mesh's volume over the film's area), Mitsuba's three emissive-media
scenes imported exactly; the keys' errors."""

import math
from dataclasses import replace

import numpy as np
import pytest
from conftest import EXAMPLES
from test_bad_input import GOOD, run_bad
from test_media import NULL, ORTHOGRAPHIC, render_mean, slab

import wrt
from wrt.errors import WrtError
from wrt.mitsuba import load_mitsuba

SIGMA_T = np.array([0.5, 1.0, 2.0])
EMISSION = np.array([1.0, 2.0, 0.5])
BEHIND = 0.25  # the environment's radiance behind the slab


def glowing_slab(medium: dict, spp: int, seed: int = 1):
    """The mean image and per-pixel standard error of a slab of thickness 1 (z in [-0.5, 0.5])
    of ``medium`` before a uniform environment of radiance ``BEHIND``, seen by an orthographic
    camera (every pixel's expected value the same)."""
    doc = {
        "render": {"width": 8, "height": 8, "integrator": "path", "max_depth": 4, "sampler": "independent"},
        "camera": ORTHOGRAPHIC,
        "medium": [{"name": "glow", **medium}],
        "material": [NULL],
        "shape": slab(0.5, -0.5, "glow"),
        "light": [{"type": "environment", "radiance": [BEHIND] * 3}],
    }
    image, mean = render_mean(doc, spp, seed)
    pixels = image.reshape(-1, 3)
    return mean, pixels.std(axis=0) / math.sqrt(len(pixels))


def slab_box() -> dict:
    """The slab's box as a volume transform: the unit cube onto [-4, 4]^2 x [-0.5, 0.5]."""
    return {"transform": {"scale": [8.0, 8.0, 1.0], "translate": [-4.0, -4.0, -0.5]}}


def test_a_glowing_absorbing_slab_adds_the_integral_of_its_attenuated_emission():
    """Per channel, ``emission (1 - exp(-sigma_t d)) / sigma_t`` (exact on every sample) plus the
    environment dimmed by ``exp(-sigma_t d)`` (held to 4 standard errors)."""
    mean, error = glowing_slab({"sigma_t": SIGMA_T.tolist(), "albedo": 0.0, "emission": EMISSION.tolist()}, 512)
    expected = EMISSION * (1 - np.exp(-SIGMA_T)) / SIGMA_T + BEHIND * np.exp(-SIGMA_T)
    assert np.all(np.abs(mean - expected) < 4 * error + 1e-6), (mean, expected, error)
    assert np.all(mean > 1.5 * BEHIND * np.exp(-SIGMA_T))  # the glow is there


def test_a_glowing_grid_slab_scores_the_same_integral_by_tracking():
    """The same slab as a heterogeneous medium (constant volumes over the slab's box, a null
    density added to the bound): its emission is found at the tracking's collisions."""
    box = slab_box()
    medium = {
        "type": "heterogeneous",
        "sigma_t": {"volume": "constant", "value": SIGMA_T.tolist(), **box},
        "albedo": 0.0,
        "emission": {"volume": "constant", "value": EMISSION.tolist(), **box},
        "sigma_n": 1.0,
    }
    mean, error = glowing_slab(medium, 1024)
    expected = EMISSION * (1 - np.exp(-SIGMA_T)) / SIGMA_T + BEHIND * np.exp(-SIGMA_T)
    assert np.all(np.abs(mean - expected) < 4 * error), (mean, expected, error)
    assert np.all(error < 0.01 * expected)


def test_a_clear_glowing_grid_emits_its_radiance_times_the_distance():
    """Zero extinction: the environment passes unchanged, and the slab adds ``emission d``."""
    box = slab_box()
    medium = {
        "type": "heterogeneous",
        "sigma_t": {"volume": "constant", "value": 0.0, **box},
        "emission": {"volume": "constant", "value": EMISSION.tolist(), **box},
    }
    mean, error = glowing_slab(medium, 1024)
    expected = EMISSION * 1.0 + BEHIND
    assert np.all(np.abs(mean - expected) < 4 * error), (mean, expected, error)


@pytest.mark.parametrize("albedo, g", [(0.0, 0.0), (0.5, 0.0), (0.8, 0.7)])
def test_a_camera_inside_an_endless_glowing_medium_sees_emission_over_absorption(albedo, g):
    """In a medium that fills space (a null sphere of optical radius 200 around the camera),
    radiance is the same everywhere and in every direction: ``dL/ds = 0 = -sigma_t L + sigma_s L +
    emission`` gives ``L = emission / (sigma_t (1 - albedo))`` whatever the phase function: the
    emissive-medium furnace."""
    sigma_t = 2.0
    doc = {
        "render": {"width": 8, "height": 8, "integrator": "path", "max_depth": 1024},
        "camera": {"origin": [0.0, 0.0, 0.0], "look_at": [0.0, 0.0, -1.0], "fov": 60, "medium": "glow"},
        "medium": [
            {
                "name": "glow",
                "sigma_t": sigma_t,
                "albedo": albedo,
                "emission": EMISSION.tolist(),
                "phase": {"type": "hg", "g": g},
            }
        ],
        "material": [NULL],
        "shape": [
            {"type": "sphere", "center": [0.0, 0.0, 0.0], "radius": 100.0, "material": "boundary", "interior": "glow"}
        ],
    }
    image, mean = render_mean(doc, 128)
    expected = EMISSION / (sigma_t * (1 - albedo))
    np.testing.assert_allclose(mean, expected, rtol=0.01)
    assert np.abs(image / expected - 1).max() < 0.15


EMISSIVE_SPHERE = """<scene version="3.0.0">
    <integrator type="volpath"><integer name="max_depth" value="16"/></integrator>
    <sensor type="perspective">
        <float name="fov" value="30"/>
        <transform name="to_world"><lookat origin="0, 0, 6" target="0, 0, 0" up="0, 1, 0"/></transform>
        <film type="hdrfilm"><integer name="width" value="24"/><integer name="height" value="24"/></film>
        <sampler type="independent"><integer name="sample_count" value="64"/></sampler>
    </sensor>
    <medium id="medium1" type="heterogeneous">
        <volume name="sigma_t" type="constvolume">
            <transform name="to_world"><scale value="8,8,8"/><translate value="-4,-4,-4"/></transform>
            <float name="value" value="0.0"/>
        </volume>
        <volume name="sigma_n" type="constvolume"><float name="value" value="1"/></volume>
        <rgb name="albedo" value="0.0, 0.0, 0.0"/>
        <string name="medium_sampling_mode" value="analogue"/>
        <phase type="isotropic"/>
    </medium>
    <shape type="sphere">
        <bsdf type="null"/>
        <ref id="medium1" name="interior"/>
        <emitter type="volumelight"><rgb name="radiance" value="1, 0.5, 2"/></emitter>
    </shape>
</scene>
"""


def test_mitsubas_clear_glowing_sphere_shines_with_its_chord(tmp_path):
    """Mitsuba's test_homo_emissive_sphere in an analytic sphere: zero extinction, a null density
    of 1, a volumelight of radiance (1, 0.5, 2) per unit length. Each pixel sees its radiance
    times the chord its ray cuts through the unit sphere (held, over the pixels well inside the
    disk, to 2%); away from the sphere the image is black."""
    xml = tmp_path / "emissive_sphere.xml"
    xml.write_text(EMISSIVE_SPHERE)
    doc, approximations = load_mitsuba(xml)
    assert approximations == []
    assert doc["medium"][0]["emission"] == [1.0, 0.5, 2.0] and doc["medium"][0]["sigma_n"] == 1.0
    scene = wrt.load_scene(xml)
    image = wrt.render(scene, specialize=False).rgb.astype(np.float64)
    # the chord of each pixel centre's ray through the unit sphere (camera at distance 6)
    n = image.shape[0]
    half = math.tan(math.radians(15.0))
    s = ((np.arange(n) + 0.5) / n * 2 - 1) * half
    d = np.stack([*np.meshgrid(s, -s), np.full((n, n), -1.0)], axis=-1)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    b = 6.0 * d[..., 2]  # o = (0, 0, 6): |o + t d|^2 = 1
    disc = b * b - 35.0
    chord = 2 * np.sqrt(np.maximum(disc, 0.0))
    inside = disc > 0.3 * disc.max()
    ratio = image[inside].sum(axis=0) / chord[inside].sum()
    np.testing.assert_allclose(ratio, [1.0, 0.5, 2.0], rtol=0.02)
    assert image[disc < -1.25].max() == 0.0  # pixels whose filter reaches no farther than 1.5 from the centre


HOMOGENEOUS_GLOW = EMISSIVE_SPHERE.replace(
    EMISSIVE_SPHERE[EMISSIVE_SPHERE.index('<medium id="medium1"') : EMISSIVE_SPHERE.index("</medium>")],
    '<medium id="medium1" type="homogeneous">',
).replace(
    '<rgb name="radiance" value="1, 0.5, 2"/>',
    '<volume name="radiance" type="constvolume"><float name="value" value="1"/></volume>',
)


@pytest.mark.parametrize(
    "text, fragments",
    [
        (
            EMISSIVE_SPHERE.replace('<ref id="medium1" name="interior"/>', ""),
            ["volumelight is the emission of its shape's interior medium: it has none"],
        ),
        (HOMOGENEOUS_GLOW, ["a volume radiance needs a heterogeneous medium"]),
    ],
)
def test_a_volumelight_without_a_medium_to_take_it_is_one_error(tmp_path, text, fragments):
    xml = tmp_path / "bad.xml"
    xml.write_text(text)
    with pytest.raises(WrtError) as error:
        load_mitsuba(xml)
    assert all(f in str(error.value) for f in fragments) and "\n" not in str(error.value), str(error.value)


@pytest.mark.parametrize(
    "medium, fragments",
    [
        ("emission = [1.0, -1.0, 0.0]", ["medium[0]", "emission", "-1"]),
        ('emission = "bright"', ["medium[0]", "emission"]),
        ('type = "heterogeneous"\nsigma_t = { volume = "constant", value = 1.0 }\nsigma_n = -2.0', ["sigma_n", "-2"]),
        ('emission = { volume = "constant", value = 1.0 }', ["medium[0]", "emission"]),
    ],
)
def test_bad_emission_keys_are_one_line_and_exit_2(tmp_path, capsys, medium, fragments):
    text = GOOD + f'\n[[medium]]\nname = "glow"\n{medium}\n'
    run_bad(tmp_path, capsys, text, *fragments)


MEDIA_SCENES = EXAMPLES / "mitsuba" / "participating_media"
EMISSIVE_SCENES = (
    "test_homo_emissive_sphere_volpath",
    "test_hetero_sigmat_albedo_emissive_volpath",
    "test_homo_emitter_inside_emissive_medium_volpath",
)


def mesh_volume(path) -> float:
    """The volume a closed, outward-wound OBJ triangle mesh encloses (the divergence theorem)."""
    lines = [line.split() for line in path.read_text().splitlines()]
    v = np.array([[float(x) for x in line[1:4]] for line in lines if line and line[0] == "v"])
    f = np.array([[int(i.split("/")[0]) - 1 for i in line[1:4]] for line in lines if line and line[0] == "f"])
    return float(np.einsum("ij,ij->i", v[f[:, 0]], np.cross(v[f[:, 1]], v[f[:, 2]])).sum() / 6.0)


def test_mitsubas_test_homo_emissive_sphere_shines_with_the_mesh_volume():
    """Mitsuba's own scene: an orthographic camera over [-1, 1]^2 (a box filter, so the pixels tile
    the film) looks at a clear unit-radius sphere mesh glowing 1 per unit length: the image mean is
    the mesh's volume over the film's area 4, exactly (held to 5 standard errors)."""
    xml = MEDIA_SCENES / "test_homo_emissive_sphere_volpath.xml"
    scene = wrt.load_scene(xml)
    spp = 64
    image = wrt.render(scene, spp=spp, seed=3, specialize=False).rgb.astype(np.float64)
    mean = image.mean(axis=(0, 1))
    expected = mesh_volume(MEDIA_SCENES / "meshes" / "sphere_origin.obj") / 4.0
    assert expected == pytest.approx(math.pi / 3, rel=0.02)  # a sphere it is
    # collisions come at the null density 1 and each scores 1: a sample is a Poisson count of mean
    # its chord, so the variance of the image mean is its expectation over the samples taken
    error = math.sqrt(expected / (image.shape[0] * image.shape[1] * spp))
    assert np.all(np.abs(mean - expected) < 5 * error) and error < 0.005 * expected, (mean, expected, error)


@pytest.mark.parametrize("name", EMISSIVE_SCENES)
def test_mitsubas_emissive_media_scenes_import_exactly_and_glow(name):
    """Each imports without approximation, its volumelight the emission of its shape's medium, and
    renders finite; with the volumelight taken away the image is darker (the glow is seen)."""
    xml = MEDIA_SCENES / f"{name}.xml"
    doc, approximations = load_mitsuba(xml)
    assert approximations == [] and any("emission" in medium for medium in doc["medium"])
    scene = wrt.load_scene(xml)
    glowing = wrt.render(scene, spp=4, seed=1, specialize=False)
    assert np.isfinite(glowing.rgb).all() and glowing.rejected_samples == 0
    dark = replace(scene, media=tuple(replace(m, emission=(0.0, 0.0, 0.0)) for m in scene.media))
    assert glowing.rgb.mean() > 1.05 * wrt.render(dark, spp=4, seed=1, specialize=False).rgb.mean()
