"""Kernels specialised on a scene's features (kernels/features.py, kernels/variants.py) render
exactly what the all-features kernels render: specialisation only removes unreachable code."""

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest
import warp as wp
from conftest import CAMERA, EXAMPLES, make_scene
from wrt.kernels.features import ALL, Features
from wrt.kernels.materials import ALL_FAMILIES, make_bsdf
from wrt.kernels.traverse import traversal
from wrt.kernels.variants import all_features_kernel, relevant, render_kernel

import wrt
from wrt.aot import compiled
from wrt.renderer import render_kernel_for, scene_features

DIFFUSE = [{"name": "white", "albedo": [0.7, 0.7, 0.7]}]
GLASS = {"name": "glass", "type": "dielectric", "ior": 1.5, "transmittance": [0.9, 0.8, 0.7]}
MIRROR = {"name": "mirror", "type": "mirror"}
ROUGH_GLASS = {"name": "rough_glass", "type": "rough_dielectric", "ior": 1.5, "roughness": 0.3}
PLASTIC = {"name": "plastic", "type": "plastic", "albedo": [0.7, 0.2, 0.1]}
FLOOR = {"type": "plane", "point": [0, -1, 0], "normal": [0, 1, 0], "material": "white"}
POINT = {"type": "point", "position": [2, 3, 3], "intensity": [10, 10, 10]}
AREA = {"type": "area", "corner": [-1, 3, -1], "edge_u": [2, 0, 0], "edge_v": [0, 0, 2], "radiance": [4, 4, 4]}
DISK = {"type": "disk", "center": [1, -0.5, 0], "normal": [0, 1, 0.5], "radius": 0.7, "material": "white"}
CYLINDER = {"type": "cylinder", "p0": [-1, -1, 0], "p1": [-0.8, 0.5, 0.3], "radius": 0.5, "material": "white"}


def test_features_follow_the_scene():
    plain = make_scene([FLOOR], materials=DIFFUSE)
    assert scene_features(plain) == Features(
        lights=False,
        environment_map=False,
        emissive=False,
        emissive_shapes=False,
        specular=False,
        dielectric=False,
        lens=False,
        orthographic=False,
        motion=False,
        moving=False,
        spheres=False,
        triangles=False,
        polygons=False,
        disks=False,
        cylinders=False,
        instances=False,
        smooth=False,
        textures=False,
        rough_dielectric=False,
        plastic=False,
        principled=False,
        blend=False,
        mask=False,
        null=False,
        normal_map=False,
        media=False,
        beckmann=False,
        anisotropic=False,
    )
    mesh = make_scene([{"type": "mesh", "file": "examples/meshes/tetra.obj"}], scene_dir=".")
    assert (scene_features(mesh).triangles, scene_features(mesh).spheres, scene_features(mesh).polygons) == (
        True,
        False,
        False,
    )
    assert not scene_features(mesh).smooth
    smooth = make_scene([{"type": "mesh", "file": "examples/meshes/tetra.obj", "shading": "smooth"}], scene_dir=".")
    assert scene_features(smooth).smooth
    rich = make_scene(
        [
            FLOOR,
            {"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "glass", "velocity": [1, 0, 0]},
            {"type": "triangle", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "material": "white"},
            DISK,
            CYLINDER,
        ],
        materials=DIFFUSE + [GLASS],
        lights=[AREA],
        camera={**CAMERA, "aperture_radius": 0.1, "shutter": [0, 1]},
    )
    # a lens: perspective
    assert scene_features(rich) == dataclasses.replace(
        ALL,
        environment_map=False,
        emissive=False,
        emissive_shapes=False,
        orthographic=False,
        instances=False,
        smooth=False,
        textures=False,
        rough_dielectric=False,
        plastic=False,
        principled=False,
        blend=False,
        mask=False,
        null=False,
        normal_map=False,
        media=False,
        beckmann=False,
        anisotropic=False,
    )
    for material, flags in [
        (ROUGH_GLASS, (True, True, True, False)),  # a rough dielectric bounds a medium: dielectric too
        (PLASTIC, (True, False, False, True)),  # a smooth coating is a delta lobe
        ({**PLASTIC, "type": "rough_plastic"}, (False, False, False, True)),
    ]:
        f = scene_features(make_scene([{**FLOOR, "material": material["name"]}], materials=[material]))
        assert (f.specular, f.dielectric, f.rough_dielectric, f.plastic) == flags
        assert not (f.beckmann or f.anisotropic)
        beckmann = {**material, "distribution": "beckmann"} if "roughness" in material else None
        if beckmann is not None:  # Beckmann microfacets are compiled in only where a material has them
            f = scene_features(make_scene([{**FLOOR, "material": material["name"]}], materials=[beckmann]))
            assert f.beckmann and not f.anisotropic
        if material is ROUGH_GLASS:  # and a tangent frame only where one is anisotropic
            anisotropic = {**material, "roughness_v": 0.05}
            f = scene_features(make_scene([{**FLOOR, "material": material["name"]}], materials=[anisotropic]))
            assert f.anisotropic and not f.beckmann
    sky = {"type": "environment", "file": str(EXAMPLES / "envmaps" / "sky.exr")}
    assert scene_features(make_scene([FLOOR], materials=DIFFUSE, lights=[sky])).environment_map
    flat = make_scene([FLOOR], materials=DIFFUSE, camera={**CAMERA, "type": "orthographic", "width": 2.0})
    assert scene_features(flat).orthographic and not scene_features(flat).lens
    still = make_scene(
        [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "velocity": [1, 0, 0]}],
        camera={**CAMERA, "shutter": [2, 2]},
    )
    assert not scene_features(still).motion  # moving shapes, but a closed shutter: no time to sample
    assert scene_features(still).moving  # ... though at time 2 the sphere is not where it was at 0


def test_dielectric_implies_specular():
    with pytest.raises(ValueError):
        Features(specular=False, dielectric=True)


def test_variants_are_built_once_and_only_for_flags_that_pay():
    plain = Features(lights=False, specular=False, dielectric=False, lens=False, motion=False)
    assert render_kernel("whitted", plain) is render_kernel("whitted", plain)
    assert render_kernel("path", ALL) is render_kernel("path", Features(specular=True))
    assert relevant("raycast", plain) == Features(lens=False, motion=False)
    triangles_only = Features(moving=False, spheres=False, polygons=False)
    assert relevant("raycast", triangles_only) == triangles_only  # geometry flags pay for every integrator
    assert relevant("path", plain).specular  # the mirror test is a compare: not worth a variant


def test_a_cuda_device_gets_modules_of_its_own_with_the_traversal_out_of_line():
    """NVRTC inlining the traversal and the BSDF interface at each call site took the Whitted
    module 11-14 minutes: the CUDA kernels are modules of their own (``_cuda``) in which both are
    ``noinline``; the CPU's leave them to the compiler, and a render picks by its device. (A mask's
    and a blend's BSDF wrap the others': the dispatch under them is out of line.)"""
    assert traversal(ALL, False).closest_hit.inline_hint == traversal(ALL, False).any_hit.inline_hint == "noinline"
    assert traversal(ALL).closest_hit.inline_hint is None and traversal(ALL).any_hit.inline_hint is None
    unmasked = tuple(name for name in ALL_FAMILIES if name not in ("mask", "blend"))
    assert {f.inline_hint for f in make_bsdf(unmasked, True, False)} == {"noinline"}
    assert {f.inline_hint for f in make_bsdf(unmasked, True)} == {None}
    plain = Features(lights=False, specular=False, dielectric=False, lens=False, motion=False)
    for integrator in ("raycast", "whitted", "path"):
        cpu, cuda = render_kernel(integrator, plain), render_kernel(integrator, plain, cuda=True)
        assert cuda.module.name == cpu.module.name + "_cuda" and cuda is not cpu
        record = all_features_kernel(integrator, record=True, cuda=True)
        assert record.module.name == f"wrt_{integrator}_record_cuda"
    scene = make_scene([FLOOR], materials=DIFFUSE)
    for is_cuda, suffix in ((True, "_cuda"), (False, "")):
        device = SimpleNamespace(is_cuda=is_cuda)
        for specialize in (True, False):
            name = render_kernel_for(scene, specialize, device).module.name
            assert name.endswith(suffix) and (is_cuda or not name.endswith("_cuda"))


SCENES = {
    "whitted diffuse": (
        [FLOOR, {"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "white"}],
        DIFFUSE,
        [POINT],
        {},
        "whitted",
    ),
    "whitted glass and mirror": (
        [
            FLOOR,
            {"type": "sphere", "center": [-1, 0, 0], "radius": 0.8, "material": "glass"},
            {"type": "sphere", "center": [1, 0, 0], "radius": 0.8, "material": "mirror"},
        ],
        DIFFUSE + [GLASS, MIRROR],
        [POINT],
        {},
        "whitted",
    ),
    "whitted no lights": (
        [FLOOR, {"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "mirror"}],
        DIFFUSE + [MIRROR],
        [],
        {},
        "whitted",
    ),
    "path diffuse, lens": (
        [FLOOR, {"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "white"}],
        DIFFUSE,
        [AREA],
        {"aperture_radius": 0.2},
        "path",
    ),
    "path glass, motion": (
        [FLOOR, {"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "glass", "velocity": [0.5, 0, 0]}],
        DIFFUSE + [GLASS],
        [AREA, POINT],
        {"shutter": [0, 1]},
        "path",
    ),
    "path disk and cylinder": ([FLOOR, DISK, CYLINDER], DIFFUSE, [AREA], {}, "path"),
    "path rough glass and plastics": (
        [
            {**FLOOR, "material": "rough_plastic"},
            {"type": "sphere", "center": [-1, 0, 0], "radius": 0.8, "material": "rough_glass"},
            {"type": "sphere", "center": [1, 0, 0], "radius": 0.8, "material": "plastic"},
        ],
        [ROUGH_GLASS, PLASTIC, {**PLASTIC, "name": "rough_plastic", "type": "rough_plastic"}],
        [AREA, POINT],
        {},
        "path",
    ),
    "path emissive triangles": (
        [FLOOR, {"type": "triangle", "vertices": [[-1, 2, -1], [1, 2, -1], [1, 2, 1]], "material": "lamp"}],
        DIFFUSE + [{"name": "lamp", "albedo": [0, 0, 0], "emission": [3, 3, 3]}],
        [AREA],
        {},
        "path",
    ),
    "path emissive polygon and sphere": (
        [
            FLOOR,
            {
                "type": "polygon",
                "vertices": [[-1, 2, -1], [1, 2, -1], [1, 2, 0], [0, 2, 0], [0, 2, 1]],
                "material": "lamp",
            },
            {"type": "sphere", "center": [1, 0, 0], "radius": 0.4, "material": "lamp"},
        ],
        DIFFUSE + [{"name": "lamp", "albedo": [0, 0, 0], "emission": [3, 3, 3]}],
        [AREA],
        {},
        "path",
    ),
    "path environment map": (
        [FLOOR, {"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "mirror"}],
        DIFFUSE + [MIRROR],
        [{"type": "environment", "file": str(EXAMPLES / "envmaps" / "sky.exr"), "transform": {"rotate": [0, 60, 0]}}],
        {},
        "path",
    ),
    "path instances, one moving": (
        [
            FLOOR,
            {"type": "instance", "group": "pair", "transform": {"translate": [-0.8, 0, 0], "scale": [1, 1.5, 1]}},
            {"type": "instance", "group": "pair", "transform": {"rotate": [0, 40, 0]}, "velocity": [0.4, 0, 0]},
        ],
        DIFFUSE + [GLASS],
        [AREA],
        {"shutter": [0, 1]},
        "path",
    ),
    "path blend of a diffuse and a glossy material": (  # no plastic, nothing specular: the blend's choice alone
        [FLOOR, {"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "tarnished"}],
        DIFFUSE
        + [
            {"name": "gold", "type": "glossy", "reflectance": [0.95, 0.75, 0.35], "roughness": 0.15},
            {"name": "tarnished", "type": "blend", "materials": ["white", "gold"], "weight": 0.7},
        ],
        [AREA],
        {},
        "path",
    ),
    "path principled transmission": (  # lights seen through a surface without a rough dielectric
        [
            FLOOR,
            {"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "frosted"},
            {"type": "polygon", "vertices": [[-2, 2, -1], [2, 2, -1], [2, 2, 1], [-2, 2, 1]], "material": "leaf"},
        ],
        DIFFUSE
        + [
            {"name": "frosted", "type": "principled", "spec_trans": 0.8, "ior": 1.4, "roughness": 0.3},
            {"name": "leaf", "type": "principled_thin", "diff_trans": 1.5, "spec_trans": 0.3},
        ],
        [AREA],
        {},
        "path",
    ),
    "raycast": (
        [FLOOR, {"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "white"}],
        DIFFUSE,
        [],
        {},
        "raycast",
    ),
    "path glass, orthographic, clipped": (
        [FLOOR, {"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "glass"}],
        DIFFUSE + [GLASS],
        [AREA],
        {"type": "orthographic", "width": 3.0, "near_clip": 4.5, "far_clip": 12.0},
        "path",
    ),
}

GROUPS = [  # what the instance scenes place; unused by the others
    {
        "name": "pair",
        "shape": [
            {"type": "sphere", "center": [0.6, 0, 0], "radius": 0.4, "material": "glass"},
            {"type": "triangle", "vertices": [[-1, -0.5, 0], [0, -0.5, 0], [-0.5, 0.5, 0.2]], "material": "white"},
        ],
    }
]


@pytest.mark.parametrize("name", list(SCENES))
def test_specialised_kernel_renders_the_same_image(device, name):
    shapes, materials, lights, camera, integrator = SCENES[name]
    render = {"width": 24, "height": 18, "spp": 4, "integrator": integrator, "ambient": [0.1, 0.1, 0.1]}
    scene = make_scene(
        shapes,
        materials=materials,
        lights=lights,
        camera={**CAMERA, **camera},
        render=render,
        groups=GROUPS if any(shape["type"] == "instance" for shape in shapes) else None,
    )
    special = wrt.render(scene, specialize=True, device=device)
    general = wrt.render(scene, specialize=False, device=device)
    assert np.array_equal(special.rgb, general.rgb)
    assert special.rgb.max() > 0  # something was rendered


def test_the_variant_is_taken_where_it_is_compiled_or_pays_its_compilation(monkeypatch):
    """A variant's first compilation costs 10-30 CPU-seconds: by default a render takes the
    all-features kernel below SPECIALIZE_MIN_SAMPLES pixel samples; from there the variant when
    Warp's cache has it; from SPECIALIZE_COLD_SAMPLES on the variant whatever the cache."""
    chosen = []
    monkeypatch.setattr(
        wrt.renderer,
        "render_kernel",
        lambda integrator, features, cuda: chosen.append(features) or render_kernel(integrator, features, cuda),
    )
    scene = make_scene([FLOOR], materials=DIFFUSE, render={"width": 16, "height": 8, "spp": 2, "integrator": "path"})
    samples = 16 * 8 * 2
    cases = [  # (SPECIALIZE_MIN_SAMPLES, SPECIALIZE_COLD_SAMPLES, in the cache): the kernel taken
        ((samples + 1, samples + 1, True), ALL),
        ((samples, samples + 1, True), scene_features(scene)),
        ((samples, samples + 1, False), ALL),
        ((samples, samples, False), scene_features(scene)),
    ]
    images = []
    for (least, cold, cached), expected in cases:
        monkeypatch.setattr(wrt.renderer, "SPECIALIZE_MIN_SAMPLES", least)
        monkeypatch.setattr(wrt.renderer, "SPECIALIZE_COLD_SAMPLES", cold)
        monkeypatch.setattr(wrt.renderer, "compiled", lambda kernel, dev, cached=cached: cached)
        chosen.clear()
        images.append(wrt.render(scene).rgb)
        assert chosen[-1] == expected, (least, cold, cached)
    assert all(np.array_equal(image, images[0]) for image in images)


def test_compiled_sees_warps_kernel_cache(monkeypatch, tmp_path):
    """``compiled`` is true for a kernel whose module is in Warp's cache, false in an empty cache."""
    kernel = render_kernel("raycast", ALL)
    wp.load_module(kernel.module, device="cpu")
    assert compiled(kernel, wp.get_device("cpu"))
    monkeypatch.setattr(wp.config, "kernel_cache_dir", str(tmp_path))
    assert not compiled(kernel, wp.get_device("cpu"))
