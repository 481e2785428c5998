"""Scene loading and validation (wrt/loader.py): good files load, bad ones give exit 2 naming the key."""

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import wrt
from wrt.cli import main

GOOD = """
[render]
width = 32
height = 24
spp = 1

[camera]
origin = [0, 0, 5]
look_at = [0, 0, 0]

[[material]]
name = "red"
albedo = [0.8, 0.1, 0.1]

[[shape]]
type = "sphere"
center = [0, 0, 0]
radius = 1.0
material = "red"
"""


def write(tmp_path, text, name="scene.toml"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def test_good_scene_loads_with_defaults(tmp_path):
    scene = wrt.load_scene(write(tmp_path, GOOD))
    assert scene.render.width == 32 and scene.render.integrator == "raycast" and scene.render.max_depth == 8
    assert scene.camera.fov == 45.0 and scene.camera.up == (0.0, 1.0, 0.0)
    assert scene.materials[scene.shapes[0].material].albedo == (0.8, 0.1, 0.1)


def test_mesh_path_is_relative_to_scene_and_transform_applies(tmp_path):
    (tmp_path / "m").mkdir()
    (tmp_path / "m" / "tri.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    scene = wrt.load_scene(
        write(
            tmp_path,
            GOOD
            + '\n[[shape]]\ntype = "mesh"\nfile = "m/tri.obj"\n'
            + "transform = { translate = [0, 0, -2], scale = 2.0, rotate = [0, 0, 90] }\n",
        )
    )
    np.testing.assert_allclose(scene.shapes[1].vertices, [[0, 0, -2], [0, 2, -2], [-2, 0, -2]], atol=1e-12)


SHEAR = [1, 0.5, 0, 3, 0, 2, 0, 0, 0, 0, 1, -1, 0, 0, 0, 1]  # shear x by y, stretch y, move (3, 0, -1)


@pytest.mark.parametrize("form", ["flat", "rows"])
def test_transform_matrix_is_any_affine_map_applied_before_scale_rotate_translate(tmp_path, form):
    """`transform = { matrix = [16 numbers] }` (row-major, Mitsuba's order; 4 rows of 4 too):
    shear and non-uniform scale allowed, composed as p' = T + R (S (A p)) (issue 16)."""
    (tmp_path / "tri.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    matrix = SHEAR if form == "flat" else [SHEAR[4 * r : 4 * r + 4] for r in range(4)]
    scene = wrt.load_scene(
        write(
            tmp_path,
            GOOD + f'\n[[shape]]\ntype = "mesh"\nfile = "tri.obj"\n'
            f"transform = {{ matrix = {matrix}, scale = 2.0, translate = [0, 0, 10] }}\n",
        )
    )
    a = np.array(SHEAR, dtype=float).reshape(4, 4)
    p = np.array([[0, 0, 0, 1], [1, 0, 0, 1], [0, 1, 0, 1]], dtype=float)
    np.testing.assert_allclose(scene.shapes[1].vertices, 2.0 * (p @ a.T)[:, :3] + [0, 0, 10], atol=1e-12)


@pytest.mark.parametrize(
    "matrix, problem",
    [
        ([1, 0, 0], "16 numbers"),
        ([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 1, 1], "affine"),
        ([1, 2, 3, 0, 2, 4, 6, 0, 0, 0, 1, 0, 0, 0, 0, 1], "invertible"),
        ([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, "1"], "16 numbers"),
        ([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, True], "16 numbers"),
        ([1, 0, 0, "nan", 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1], "nan"),
    ],
    ids=["too short", "projective", "singular", "a string", "a boolean", "nan"],
)
def test_bad_transform_matrix_is_one_line(tmp_path, capsys, matrix, problem):
    (tmp_path / "tri.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    text = repr(matrix).replace("'nan'", "nan").replace("True", "true").replace("'", '"')
    scene = write(tmp_path, GOOD + f'\n[[shape]]\ntype = "mesh"\nfile = "tri.obj"\ntransform = {{ matrix = {text} }}\n')
    assert main(["render", str(scene), "-o", str(tmp_path / "o.png")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "shape[1].transform.matrix" in err and problem in err, err


@pytest.mark.parametrize("kind", ["diffuse", "phong", "mirror", "glossy"])
def test_two_sided_defaults_to_true(tmp_path, kind):
    for line, expected in (("", True), ("two_sided = true", True), ("two_sided = false", False)):
        text = GOOD.replace("albedo = [0.8, 0.1, 0.1]", f'type = "{kind}"\n{line}')
        assert wrt.load_scene(write(tmp_path, text)).materials[0].two_sided is expected


@pytest.mark.parametrize(
    "extra, where",
    [
        ('[[light]]\ntype = "sphere"\ncenter = [0, 3, 0]\nradius = 0.5\nradiance = [1, 1, 1]\n', "light[0].type"),
        ('[[material]]\nname = "glass"\ntype = "rough_dielectric"\n', "material[1].type"),
    ],
)
def test_switching_to_whitted_is_refused_as_the_file_would_be(tmp_path, extra, where):
    """override_render(integrator="whitted") on a scene the file could not have asked whitted for."""
    scene = wrt.load_scene(write(tmp_path, GOOD.replace("spp = 1", 'spp = 1\nintegrator = "path"') + extra))
    with pytest.raises(wrt.SceneError, match=rf"python: {where.replace('[', '.').replace(']', '.')}.*path"):
        wrt.loader.override_render(scene, source="python", integrator="whitted")
    assert wrt.loader.override_render(scene, source="python", spp=2).render.spp == 2


def test_lights_are_accepted_and_ignored_by_raycast(tmp_path):
    scene = wrt.load_scene(
        write(tmp_path, GOOD + '\n[[light]]\ntype = "point"\nposition = [0, 3, 0]\nintensity = [10, 10, 10]\n')
    )
    assert scene.lights[0].type == "point"


BAD = [
    ("unknown render key", GOOD.replace("spp = 1", "sp = 1"), "render.sp", "did you mean 'spp'"),
    ("wrong type", GOOD.replace("width = 32", 'width = "32"'), "render.width = '32'", "must be an integer"),
    ("zero width", GOOD.replace("width = 32", "width = 0"), "render.width = 0", "must be in [1, 16384]"),
    ("huge width", GOOD.replace("width = 32", "width = 1000000"), "render.width = 1000000", "must be in"),
    ("zero spp", GOOD.replace("spp = 1", "spp = 0"), "render.spp = 0", "must be in"),
    (
        "unknown integrator",
        GOOD.replace("spp = 1", 'integrator = "magic"'),
        "render.integrator = 'magic'",
        "must be one of",
    ),
    (
        "fov 0",
        GOOD.replace("look_at = [0, 0, 0]", "look_at = [0, 0, 0]\nfov = 0"),
        "camera.fov = 0",
        "must be in (0, 180)",
    ),
    (
        "fov 180",
        GOOD.replace("look_at = [0, 0, 0]", "look_at = [0, 0, 0]\nfov = 180"),
        "camera.fov = 180",
        "must be in (0, 180)",
    ),
    (
        "up parallel",
        GOOD.replace("look_at = [0, 0, 0]", "look_at = [0, 0, 0]\nup = [0, 0, -3]"),
        "camera.up = [0.0, 0.0, -3.0]",
        "parallel",
    ),
    (
        "eye at target",
        GOOD.replace("origin = [0, 0, 5]", "origin = [0, 0, 0]"),
        "camera.look_at",
        "must differ from origin",
    ),
    ("missing camera", GOOD.replace("[camera]", "[cam]"), "cam", "unknown table"),
    ("nan vector", GOOD.replace("center = [0, 0, 0]", "center = [0, nan, 0]"), "shape[0].center", "finite"),
    ("short vector", GOOD.replace("center = [0, 0, 0]", "center = [0, 0]"), "shape[0].center = [0, 0]", "3 numbers"),
    ("negative radius", GOOD.replace("radius = 1.0", "radius = -1.0"), "shape[0].radius = -1.0", "must be in (0, inf]"),
    (
        "no such material",
        GOOD.replace('material = "red"', 'material = "blue"'),
        "shape[0].material = 'blue'",
        "known: red",
    ),
    (
        "unknown shape type",
        GOOD.replace('type = "sphere"', 'type = "cone"'),
        "shape[0].type = 'cone'",
        "must be one of",
    ),
    (
        "unknown shape key",
        GOOD.replace("radius = 1.0", "radius = 1.0\nradus = 2"),
        "shape[0].radus",
        "did you mean 'radius'",
    ),
    ("albedo above 1", GOOD.replace("[0.8, 0.1, 0.1]", "[1.8, 0.1, 0.1]"), "material[0].albedo", "[0, 1]"),
    ("bad toml", GOOD.replace("width = 32", "width = = 32"), "scene.toml", "not valid TOML"),
    (
        "zero plane normal",
        GOOD + '[[shape]]\ntype = "plane"\npoint = [0,0,0]\nnormal = [0,0,0]\n',
        "shape[1].normal",
        "zero vector",
    ),
    ("missing mesh", GOOD + '[[shape]]\ntype = "mesh"\nfile = "nope.ply"\n', "shape[1].file = 'nope.ply'", "nope.ply"),
    ("light type", GOOD + '[[light]]\ntype = "laser"\n', "light[0].type = 'laser'", "must be one of"),
    (
        "non-planar polygon",
        GOOD + '[[shape]]\ntype = "polygon"\nvertices = [[0,0,0],[1,0,0],[1,1,0],[0,1,0.5]]\n',
        "shape[1].vertices",
        "not planar",
    ),
    (
        "two-point polygon",
        GOOD + '[[shape]]\ntype = "polygon"\nvertices = [[0,0,0],[1,0,0]]\n',
        "shape[1].vertices",
        "at least 3",
    ),
    (
        "phong over 1",
        GOOD.replace('name = "red"', 'name = "red"\ntype = "phong"\nspecular = [0.5, 0.0, 0.0]'),
        "material[0].specular",
        "must not exceed 1",
    ),
    (
        "key of another material type",
        GOOD.replace('name = "red"', 'name = "red"\nior = 1.5'),
        "material[0].ior",
        "unknown key",
    ),
    (
        "two_sided not a boolean",
        GOOD.replace('name = "red"', 'name = "red"\ntwo_sided = 0'),
        "material[0].two_sided = 0",
        "must be true or false",
    ),
    (
        "two_sided on a dielectric",
        GOOD.replace('name = "red"\nalbedo = [0.8, 0.1, 0.1]', 'name = "red"\ntype = "dielectric"\ntwo_sided = true'),
        "material[0].two_sided = True",
        "does not apply to a dielectric",
    ),
    (
        "ior below 1",
        GOOD.replace('name = "red"\nalbedo = [0.8, 0.1, 0.1]', 'name = "red"\ntype = "dielectric"\nior = 0.5'),
        "material[0].ior = 0.5",
        "must be in [1, 10]",
    ),
    (
        "roughness 0 of a rough dielectric",
        GOOD.replace(
            'name = "red"\nalbedo = [0.8, 0.1, 0.1]', 'name = "red"\ntype = "rough_dielectric"\nroughness = 0'
        ),
        "material[0].roughness = 0",
        "must be in [0.001, 1]",
    ),
    (
        "nonlinear on a diffuse material",
        GOOD.replace('name = "red"', 'name = "red"\nnonlinear = true'),
        "material[0].nonlinear",
        "unknown key",
    ),
    (
        "a rough dielectric with the whitted integrator",
        GOOD.replace("spp = 1", 'spp = 1\nintegrator = "whitted"').replace(
            'name = "red"\nalbedo = [0.8, 0.1, 0.1]', 'name = "red"\ntype = "rough_dielectric"'
        ),
        "material[0].type = 'rough_dielectric'",
        "whitted integrator traces delta lobes only",
    ),
    (
        "point light without intensity",
        GOOD + '[[light]]\ntype = "point"\nposition = [0, 1, 0]\n',
        "light[0].intensity",
        "is required",
    ),
    (
        "zero light direction",
        GOOD + '[[light]]\ntype = "directional"\ndirection = [0, 0, 0]\nirradiance = [1, 1, 1]\n',
        "light[0].direction",
        "zero vector",
    ),
    (
        "spot beam wider than cutoff",
        GOOD
        + '[[light]]\ntype = "spot"\nposition = [0, 1, 0]\ndirection = [0, -1, 0]\nintensity = [1, 1, 1]\n'
        + "cutoff_angle = 10\nbeam_width = 20\n",
        "light[0].beam_width = 20",
        "must be in [0, 10]",
    ),
    (
        "unknown light key",
        GOOD + '[[light]]\ntype = "point"\nposition = [0, 1, 0]\nintensity = [1, 1, 1]\ncolor = [1, 1, 1]\n',
        "light[0].color",
        "unknown key",
    ),
    (
        "area light in whitted",
        GOOD.replace("spp = 1", 'integrator = "whitted"')
        + '[[light]]\ntype = "area"\ncorner = [0, 2, 0]\nedge_u = [1, 0, 0]\nedge_v = [0, 0, 1]\n'
        + "radiance = [1, 1, 1]\n",
        "light[0].type = 'area'",
        "point, directional and spot",
    ),
    (
        "flat area light",
        GOOD
        + '[[light]]\ntype = "area"\ncorner = [0, 2, 0]\nedge_u = [1, 0, 0]\nedge_v = [2, 0, 0]\n'
        + "radiance = [1, 1, 1]\n",
        "light[0].edge_v = [2.0, 0.0, 0.0]",
        "parallel to edge_u",
    ),
    (
        "unknown sampler",
        GOOD.replace("spp = 1", 'sampler = "halton"'),
        "render.sampler = 'halton'",
        "must be one of independent, stratified, sobol",
    ),
    (
        "unknown filter",
        GOOD.replace("spp = 1", 'filter = "mitchell"'),
        "render.filter = 'mitchell'",
        "must be one of box, tent, gaussian",
    ),
    (
        "shutter closing first",
        GOOD.replace("[camera]", "[camera]\nshutter = [1, 0]"),
        "camera.shutter = [1, 0]",
        "close must not come before open",
    ),
    ("shutter of one number", GOOD.replace("[camera]", "[camera]\nshutter = [1]"), "camera.shutter = [1]", "2 numbers"),
    (
        "unknown camera type",
        GOOD.replace("[camera]", '[camera]\ntype = "fisheye"'),
        "camera.type = 'fisheye'",
        "one of",
    ),
    (
        "orthographic with fov",
        GOOD.replace("[camera]", '[camera]\ntype = "orthographic"\nwidth = 3\nfov = 30'),
        "camera.fov = 30",
        "perspective cameras only",
    ),
    (
        "orthographic with a lens",
        GOOD.replace("[camera]", '[camera]\ntype = "orthographic"\nwidth = 3\naperture_radius = 0.1'),
        "camera.aperture_radius = 0.1",
        "perspective cameras only",
    ),
    (
        "orthographic with a focus",
        GOOD.replace("[camera]", '[camera]\ntype = "orthographic"\nwidth = 3\nfocus_distance = 2'),
        "camera.focus_distance = 2",
        "perspective cameras only",
    ),
    ("perspective with width", GOOD.replace("[camera]", "[camera]\nwidth = 3"), "camera.width = 3", "orthographic"),
    (
        "orthographic without width",
        GOOD.replace("[camera]", '[camera]\ntype = "orthographic"'),
        "camera.width",
        "required",
    ),
    (
        "orthographic width 0",
        GOOD.replace("[camera]", '[camera]\ntype = "orthographic"\nwidth = 0'),
        "camera.width = 0",
        "must be in",
    ),
    ("negative near clip", GOOD.replace("[camera]", "[camera]\nnear_clip = -1"), "camera.near_clip = -1", "must be in"),
    (
        "far clip not beyond near",
        GOOD.replace("[camera]", "[camera]\nnear_clip = 2\nfar_clip = 2"),
        "camera.far_clip = 2",
        "greater than near_clip = 2",
    ),
    ("infinite far clip", GOOD.replace("[camera]", "[camera]\nfar_clip = inf"), "camera.far_clip = inf", "finite"),
    ("huge near clip", GOOD.replace("[camera]", "[camera]\nnear_clip = 1e30"), "camera.near_clip", "at most 1e+18"),
    (
        "velocity with NaN",
        GOOD + '[[shape]]\ntype = "sphere"\ncenter = [0, 0, 0]\nradius = 1\nvelocity = [nan, 0, 0]\n',
        "shape[1].velocity",
        "finite",
    ),
    (
        "bad dielectric shadows",
        GOOD.replace("spp = 1", 'dielectric_shadows = "glass"'),
        "render.dielectric_shadows = 'glass'",
        "opaque, filtered",
    ),
    (
        "triangle with 4 points",
        GOOD + '[[shape]]\ntype = "triangle"\nvertices = [[0,0,0],[1,0,0],[0,1,0],[1,1,0]]\n',
        "shape[1].vertices",
        "list of 3",
    ),
]


@pytest.mark.parametrize("text, where, problem", [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_bad_scene_exits_2_naming_file_key_and_value(tmp_path, capsys, text, where, problem):
    scene = write(tmp_path, text)
    out = tmp_path / "out.png"
    assert main(["render", str(scene), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("wrt: error: ") and err.count("\n") == 1, err
    assert str(scene) in err and where in err and problem in err, err
    assert not out.exists() and os.listdir(tmp_path) == ["scene.toml"]  # no output, no temp file


def test_missing_scene_file(tmp_path, capsys):
    assert main(["render", str(tmp_path / "none.toml"), "-o", str(tmp_path / "x.png")]) == 2
    assert "none.toml: cannot read scene file" in capsys.readouterr().err


def test_bad_options_exit_2(tmp_path, capsys):
    scene = write(tmp_path, GOOD)
    assert main(["render", str(scene), "-o", str(tmp_path / "x.jpg")]) == 2
    assert "unsupported output format '.jpg'" in capsys.readouterr().err
    assert main(["render", str(scene), "-o", str(tmp_path / "x.png"), "--aov", "depth"]) == 2
    assert "--aov needs an .exr output" in capsys.readouterr().err
    assert main(["render", str(scene), "-o", str(tmp_path / "x.png"), "--spp", "0"]) == 2
    assert "render.spp = 0" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:
        main(["render", str(scene), "-o", str(tmp_path / "x.exr"), "--aov", "colour"])
    assert e.value.code == 2


def test_console_script_prints_no_traceback(tmp_path):
    """The installed entry point, as a user runs it."""
    scene = write(tmp_path, GOOD.replace("radius = 1.0", "radius = -1.0"))
    proc = subprocess.run(
        [sys.executable, "-m", "wrt", "render", str(scene), "-o", str(tmp_path / "o.png")],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr and "shape[0].radius = -1.0" in proc.stderr


def test_documented_example_loads(tmp_path):
    """The complete example of docs/scene-format.md is a valid scene (the docs stay true)."""
    text = open("docs/scene-format.md").read().split("## A complete example")[1]
    toml = text.split("```toml")[1].split("```")[0]
    (tmp_path / "meshes").mkdir()
    (tmp_path / "meshes" / "torus_knot.ply").write_bytes(open("examples/meshes/torus_knot.ply", "rb").read())
    scene = wrt.load_scene(write(tmp_path, toml))
    assert [type(s).__name__ for s in scene.shapes] == ["Plane", "Sphere", "Triangle", "Polygon", "Mesh"]
    assert scene.lights[0].type == "point"


def test_smooth_mesh_normals_follow_the_transform_and_flip(tmp_path):
    """shading = "smooth": the file's normals by the inverse transpose, unit; flip_normals reverses
    the winding and the normals; flat (the default) keeps none; a bad value names the key."""
    (tmp_path / "tri.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 1 1 1\nvn 0 0 3\nf 1//1 2//2 3//2\n")
    mesh = '\n[[shape]]\ntype = "mesh"\nfile = "tri.obj"\ntransform = { scale = [2, 1, 1] }\n'
    flat = wrt.load_scene(write(tmp_path, GOOD + mesh)).shapes[1]
    smooth = wrt.load_scene(write(tmp_path, GOOD + mesh + 'shading = "smooth"\n')).shapes[1]
    flipped = wrt.load_scene(write(tmp_path, GOOD + mesh + 'shading = "smooth"\nflip_normals = true\n')).shapes[1]
    assert flat.normals is None
    np.testing.assert_allclose(smooth.normals, [[0.5, 1, 1] / np.linalg.norm([0.5, 1, 1]), [0, 0, 1], [0, 0, 1]])
    np.testing.assert_array_equal(flipped.normals, -smooth.normals)
    np.testing.assert_array_equal(flipped.faces, [[2, 1, 0]])
    with pytest.raises(wrt.SceneError, match=r"shape\[1\].shading = 'round': must be one of flat, smooth"):
        wrt.load_scene(write(tmp_path, GOOD + mesh + 'shading = "round"\n'))
