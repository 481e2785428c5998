"""Mesh attributes (Mitsuba 3's ``mesh_attribute`` texture): a PLY file's vertex and face values,
named and read as Mitsuba names and reads them (``wrt.meshio.ply_attributes``), interpolated at
hits as Mitsuba's ``eval_attribute`` (checked at the same rays, through the integrators' own
``surface_hit``), in TOML and Mitsuba XML alike, and their bad input: one line, exit code 2."""

import re
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import warp as wp
from wrt.kernels.hit import surface_hit
from wrt.kernels.materials import MaterialData
from wrt.kernels.textures import ALBEDO, WEIGHT, material_float, material_rgb
from wrt.kernels.traverse import NO_HIT, GeometryData, closest_hit, ray_hit
from wrt_harness.mitsuba_peer import mitsuba_available

from wrt.device import upload_geometry, upload_materials
from wrt.errors import MeshFileError, WrtError
from wrt.geometry import build
from wrt.loader import load_scene
from wrt.meshio import ply_attributes

MITSUBA, MITSUBA_REASON = mitsuba_available()
needs_mitsuba = pytest.mark.skipif(not MITSUBA, reason=MITSUBA_REASON)


def grid_mesh(n: int = 6, rng=None):
    """Vertices (V, 3) and triangles (F, 3) of an n x n grid over [-1, 1]^2 at z = 0, bent in z."""
    xs = np.linspace(-1.0, 1.0, n + 1)
    vertices = np.array([(x, y, 0.1 * x * y) for y in xs for x in xs])
    faces = []
    for j in range(n):
        for i in range(n):
            a = j * (n + 1) + i
            faces += [(a, a + 1, a + n + 2), (a, a + n + 2, a + n + 1)]
    return vertices, np.array(faces)


def write_ply(path, vertices, faces, vertex_props=(), face_props=()):
    """An ASCII PLY file; ``*_props``: (property name, type, (N,) values)."""
    lines = ["ply", "format ascii 1.0", f"element vertex {len(vertices)}"]
    lines += [f"property float {axis}" for axis in "xyz"] + [f"property {t} {name}" for name, t, _ in vertex_props]
    lines += [f"element face {len(faces)}", "property list uchar int vertex_indices"]
    lines += [f"property {t} {name}" for name, t, _ in face_props] + ["end_header"]
    for k, v in enumerate(vertices):
        lines.append(" ".join(map(str, [*v, *(values[k] for _, _, values in vertex_props)])))
    for k, f in enumerate(faces):
        lines.append(" ".join(map(str, [3, *f, *(values[k] for _, _, values in face_props)])))
    path.write_text("\n".join(lines) + "\n")


@pytest.fixture
def coloured(tmp_path):
    """A grid mesh with vertex colours (r, g, b), face colours, a one-channel face weight and a
    one-channel vertex value, and its attribute arrays."""
    rng = np.random.default_rng(5)
    vertices, faces = grid_mesh()
    vc, fc = rng.uniform(0.05, 0.95, (len(vertices), 3)), rng.uniform(0.05, 0.95, (len(faces), 3))
    fw, vw = rng.uniform(0.1, 0.9, len(faces)), rng.uniform(0.1, 0.9, len(vertices))
    write_ply(
        tmp_path / "grid.ply",
        vertices,
        faces,
        [*((c, "float", vc[:, k]) for k, c in enumerate("rgb")), ("w_0", "float", vw)],
        [*((c, "float", fc[:, k]) for k, c in enumerate("rgb")), ("weight_x", "float", fw)],
    )
    return tmp_path / "grid.ply", {
        "vertex_color": vc,
        "face_color": fc,
        "face_weight": fw[:, None],
        "vertex_w": vw[:, None],
    }


def test_attributes_are_read_as_written_under_mitsubas_names(coloured):
    path, expected = coloured
    got = ply_attributes(path, sorted(expected))
    for name, values in expected.items():
        np.testing.assert_allclose(got[name], values, rtol=1e-6, err_msg=name)


def names_ply(tmp_path, name="names.ply", extra=None):
    """A PLY file of colour properties spelled out, postfix sequences of several categories, and
    what is no attribute: a property without a one-letter postfix, 2 fields, a sequence out of
    order (and, by Mitsuba's rule, the property after it and the attribute after that); or of the
    properties ``extra`` alone, the k-th holding (k + 1) v."""
    vertices, faces = grid_mesh(1)
    v = np.arange(len(vertices), dtype=float) / 10
    write_ply(
        tmp_path / name,
        vertices,
        faces,
        [(prop, "float", (k + 1) * v) for k, prop in enumerate(extra)]
        if extra
        else [("red", "uchar", [255] * 4), ("green", "uchar", [0] * 4), ("blue", "uchar", [7] * 4)]
        + [("uv_0", "float", v), ("uv_1", "float", 2 * v), ("t_1", "float", v), ("q_x", "float", v)]
        + [("q_z", "float", v), ("foo", "float", v), ("k_r", "float", v), ("k_g", "float", v), ("k_b", "float", v)],
    )
    return tmp_path / name, v


def test_naming_follows_mitsubas_rule(tmp_path):
    path, v = names_ply(tmp_path)
    found = ply_attributes(path, ["vertex_color", "vertex_t"])
    np.testing.assert_array_equal(found["vertex_color"][0], [255, 0, 7])  # integers kept, as Mitsuba keeps them
    np.testing.assert_allclose(found["vertex_t"], v[:, None])
    for absent in ("vertex_uv", "vertex_q", "vertex_foo", "vertex_k_color"):
        with pytest.raises(MeshFileError, match=f"has no mesh attribute '{absent}'"):
            ply_attributes(path, [absent])
    path, v = names_ply(tmp_path, "more.ply", ["p_r", "p_g", "p_b", "s_x", "n_0", "n_1", "n_2", "x_y_1"])
    found = ply_attributes(path, ["vertex_p_color", "vertex_s", "vertex_n"])
    np.testing.assert_allclose(found["vertex_p_color"], np.column_stack([v, 2 * v, 3 * v]))
    np.testing.assert_allclose(found["vertex_s"], 4 * v[:, None])
    np.testing.assert_allclose(found["vertex_n"], np.column_stack([5 * v, 6 * v, 7 * v]))
    np.testing.assert_allclose(ply_attributes(path, ["vertex_x_y"])["vertex_x_y"], 8 * v[:, None])
    path = names_ply(tmp_path, "n.ply", ["n_0", "n_x", "y_1", "z_0"])[0]
    for absent in ("vertex_n", "vertex_y", "vertex_z"):  # n_x breaks n_; y_1 is skipped; z_0 counts as a second field
        with pytest.raises(MeshFileError, match=f"has no mesh attribute '{absent}'"):
            ply_attributes(path, [absent])


@needs_mitsuba
def test_naming_and_values_are_mitsubas(coloured, tmp_path):
    """Every attribute Mitsuba 3 reads from the files above (and none more) is read, with its values."""
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    more = ["p_r", "p_g", "p_b", "s_x", "n_0", "n_1", "n_2", "x_y_1", "n_x", "z_0", "z_1", "w_0"]
    files = [coloured[0], names_ply(tmp_path)[0], names_ply(tmp_path, "more.ply", more)[0]]
    for path in files + [names_ply(tmp_path, "n.ply", ["n_0", "n_x", "y_1", "z_0", "w_0"])[0]]:
        mesh = mi.load_dict({"type": "ply", "filename": str(path)})
        theirs = set(re.findall(r"^\s+(\w+): \d+ floats?,?$", str(mesh), re.M))
        ours = ply_attributes(path, sorted(theirs))
        assert theirs, str(mesh)
        for name in theirs:
            np.testing.assert_allclose(
                ours[name].ravel(), np.array(mesh.attribute_buffer(name)), rtol=1e-6, err_msg=name
            )
        extra = {"vertex_q", "vertex_uv", "vertex_k_color", "vertex_z", "vertex_foo", "face_foo"}
        for name in extra - theirs:
            with pytest.raises(MeshFileError):
                ply_attributes(path, [name])


def attribute_scene(tmp_path, ply, albedo: str, weight: str = "face_weight") -> str:
    """A blend of a diffuse material whose albedo is mesh attribute ``albedo`` (scale 0.9) and a
    grey one, weighted by attribute ``weight``, on mesh ``ply``."""
    scene = tmp_path / "scene.toml"
    scene.write_text(
        textwrap.dedent(f"""
        [render]
        width = 16
        height = 16
        spp = 4
        [camera]
        origin = [0.0, 0.0, 3.0]
        look_at = [0.0, 0.0, 0.0]
        fov = 60.0
        [[material]]
        name = "coloured"
        albedo = {{ texture = "mesh_attribute", name = "{albedo}", scale = 0.9 }}
        [[material]]
        name = "grey"
        albedo = [0.2, 0.3, 0.4]
        [[material]]
        name = "both"
        type = "blend"
        materials = ["coloured", "grey"]
        weight = {{ texture = "mesh_attribute", name = "{weight}" }}
        [[shape]]
        type = "mesh"
        file = "{ply.name}"
        material = "both"
        [[light]]
        type = "environment"
        radiance = [1.0, 1.0, 1.0]
        """)
    )
    return str(scene)


@wp.kernel
def attributes_at_hits(
    geometry: GeometryData,
    materials: MaterialData,
    origins: wp.array(dtype=wp.vec3),
    directions: wp.array(dtype=wp.vec3),
    out_albedo: wp.array(dtype=wp.vec3),
    out_weight: wp.array(dtype=float),
):
    """The albedo of the blend's first material and the blend's weight at each ray's hit, at the
    texture context the integrators build (``surface_hit``)."""
    i = wp.tid()
    o = origins[i]
    d = directions[i]
    t, prim, inst = closest_hit(geometry, o, d, 0.0, 0.0, wp.inf)
    if prim != NO_HIT:
        hit = surface_hit(geometry, materials, ray_hit(o, d, 0.0, t, prim, inst))
        out_albedo[i] = material_rgb(materials.textures, 0, ALBEDO, hit.tex, wp.vec3(-1.0))
        out_weight[i] = material_float(materials.textures, hit.material, WEIGHT, hit.tex, -1.0)


def rays(n: int, rng):
    origins = np.column_stack([rng.uniform(-0.95, 0.95, (n, 2)), np.full(n, 2.0)]).astype(np.float32)
    return origins, np.tile(np.float32([0.0, 0.0, -1.0]), (n, 1))


@needs_mitsuba
@pytest.mark.parametrize("albedo", ["vertex_color", "face_color", "vertex_w"])
def test_values_at_hits_are_mitsubas_eval_attribute(coloured, tmp_path, albedo, rng):
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    scene = load_scene(attribute_scene(tmp_path, coloured[0], albedo))
    prims = build(scene, "cpu")
    origins, directions = rays(200, rng)
    out_albedo, out_weight = wp.zeros(200, dtype=wp.vec3, device="cpu"), wp.zeros(200, dtype=float, device="cpu")
    inputs = [
        upload_geometry(prims, "cpu"),
        upload_materials(scene, "cpu", prims),
        wp.array(origins, dtype=wp.vec3, device="cpu"),
        wp.array(directions, dtype=wp.vec3, device="cpu"),
    ]
    wp.launch(attributes_at_hits, dim=200, inputs=[*inputs, out_albedo, out_weight], device="cpu")
    mesh = mi.load_dict({"type": "ply", "filename": str(coloured[0])})
    mi_scene = mi.load_dict({"type": "scene", "mesh": mesh})
    for k in range(200):
        si = mi_scene.ray_intersect(mi.Ray3f(origins[k].tolist(), directions[k].tolist()))
        assert si.is_valid()
        theirs = np.array(mi_scene.shapes()[0].eval_attribute(albedo, si)) * 0.9
        np.testing.assert_allclose(out_albedo.numpy()[k], theirs, atol=2e-6, err_msg=f"ray {k}")
        weight = mi_scene.shapes()[0].eval_attribute_1("face_weight", si)
        np.testing.assert_allclose(out_weight.numpy()[k], weight, atol=2e-6, err_msg=f"ray {k}")


def test_the_material_constant_is_the_attribute_mean(coloured, tmp_path):
    """Where a constant stands for the texture (``Material.textures``): the mean over the mesh."""
    scene = load_scene(attribute_scene(tmp_path, coloured[0], "vertex_color"))
    np.testing.assert_allclose(scene.materials[0].albedo, 0.9 * coloured[1]["vertex_color"].mean(axis=0), rtol=1e-9)
    np.testing.assert_allclose(scene.materials[2].weight, coloured[1]["face_weight"].mean(), rtol=1e-9)


def render_cli(scene: str) -> subprocess.CompletedProcess:
    out = scene.replace(".toml", ".exr").replace(".xml", ".exr")
    return subprocess.run(
        [sys.executable, "-m", "wrt", "render", scene, "-o", out], capture_output=True, text=True, timeout=120
    )


@pytest.mark.parametrize(
    "edit, message",
    [
        ({"albedo": "vertex_colour"}, r"has no mesh attribute 'vertex_colour' \(its attributes: face_color, "),
        ({"albedo": "colour"}, r"must start with vertex_ or face_"),
        ({"weight": "face_color"}, r"mesh attribute 'face_color' has 3 channels: weight needs 1 channel"),
        ({"scale": "2.0"}, r"times its scale 2 ranges over \[.*\]: albedo must stay in \[0, 1\]"),
        ({"file": "grid.obj"}, r"is not a PLY file: its material reads mesh attributes"),
        ({"sphere": True}, r"reads mesh attribute 'face_weight' \(mesh_attribute\): only a mesh has attributes"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(coloured, tmp_path, edit, message):
    text = open(
        attribute_scene(tmp_path, coloured[0], edit.get("albedo", "face_color"), edit.get("weight", "face_weight"))
    ).read()
    if "scale" in edit:
        text = text.replace("scale = 0.9", f"scale = {edit['scale']}")
    if "file" in edit:
        (tmp_path / "grid.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
        text = text.replace('file = "grid.ply"', 'file = "grid.obj"')
    if "sphere" in edit:
        text = text.replace(
            'type = "mesh"\nfile = "grid.ply"', 'type = "sphere"\ncenter = [0.0, 0.0, 0.0]\nradius = 1.0'
        )
    scene = tmp_path / "bad.toml"
    scene.write_text(text)
    with pytest.raises(WrtError, match=message):
        load_scene(str(scene))
    result = render_cli(str(scene))
    assert result.returncode == 2, result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and re.search(message, result.stderr), result.stderr
    assert not (tmp_path / "bad.exr").exists()


def test_mitsuba_xml_imports_exactly(coloured, tmp_path):
    """The XML form converts to the same tables, without --approximate; Mitsuba's own errors too."""
    (tmp_path / "scene.xml").write_text(
        textwrap.dedent("""
        <scene version="3.0.0">
          <sensor type="perspective"><float name="fov" value="60"/>
            <transform name="to_world"><lookat origin="0,0,3" target="0,0,0" up="0,1,0"/></transform>
            <film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="16"/></film>
          </sensor>
          <shape type="ply"><string name="filename" value="grid.ply"/>
            <bsdf type="diffuse">
              <texture type="mesh_attribute" name="reflectance">
                <string name="name" value="vertex_color"/><float name="scale" value="0.5"/>
              </texture>
            </bsdf>
          </shape>
        </scene>""")
    )
    scene = load_scene(str(tmp_path / "scene.xml"))
    ((_, texture),) = scene.materials[0].textures
    assert (texture.name, texture.scale) == ("vertex_color", 0.5)
    np.testing.assert_allclose(scene.shapes[0].attributes["vertex_color"], coloured[1]["vertex_color"], rtol=1e-6)
    bad = (tmp_path / "scene.xml").read_text().replace('value="vertex_color"', 'value="color"')
    (tmp_path / "bad.xml").write_text(bad)
    with pytest.raises(WrtError, match=r"bad\.xml:\d+: .*'name' = 'color' must start with vertex_ or face_"):
        load_scene(str(tmp_path / "bad.xml"))


def test_scenes_without_mesh_attributes_upload_no_corners(tmp_path, coloured):
    """A textured scene that reads no attribute keeps the hit's barycentrics out (no corner values)."""
    text = open(attribute_scene(tmp_path, coloured[0], "vertex_color")).read()
    text = text.replace(
        'albedo = { texture = "mesh_attribute", name = "vertex_color", scale = 0.9 }',
        'albedo = { texture = "checkerboard" }',
    )
    text = text.replace('weight = { texture = "mesh_attribute", name = "face_weight" }', "weight = 0.5")
    (tmp_path / "plain.toml").write_text(text)
    scene = load_scene(str(tmp_path / "plain.toml"))
    prims = build(scene, "cpu")
    assert prims.tri_attributes.shape == (0, 3, 0, 3)
    assert upload_materials(scene, "cpu", prims).textures.corners.shape[0] == 0


@needs_mitsuba
def test_values_at_instanced_hits_are_mitsubas(coloured, tmp_path, rng):
    """The same mesh as a [[shape]] and in a [[group]] placed by an instance (the group's triangles
    joined after the scene's, each BVH reordering its own): values at hits on both, as Mitsuba's
    ``eval_attribute`` on the two meshes placed by the same transforms (not on a shapegroup's
    instance: Mitsuba 3.9.1 evaluates those with the wrong barycentrics, colours out of range)."""
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    text = open(attribute_scene(tmp_path, coloured[0], "vertex_color")).read()
    plain = 'type = "mesh"\nfile = "grid.ply"\nmaterial = "both"'
    assert plain in text
    text = text.replace(plain, plain + "\ntransform = { translate = [3.0, 0.0, 0.0] }")
    text += textwrap.dedent("""
        [[group]]
        name = "piece"
        [[group.shape]]
        type = "mesh"
        file = "grid.ply"
        material = "both"
        [[shape]]
        type = "instance"
        group = "piece"
        transform = { rotate = [0.0, 0.0, 30.0] }
        """)
    (tmp_path / "instanced.toml").write_text(text)
    scene = load_scene(str(tmp_path / "instanced.toml"))
    prims = build(scene, "cpu")
    n = 200
    origins, directions = rays(n, rng)
    origins[n // 2 :, 0] += 3.0  # half on the plain mesh
    out_albedo, out_weight = wp.zeros(n, dtype=wp.vec3, device="cpu"), wp.zeros(n, dtype=float, device="cpu")
    inputs = [
        upload_geometry(prims, "cpu"),
        upload_materials(scene, "cpu", prims),
        wp.array(origins, dtype=wp.vec3, device="cpu"),
        wp.array(directions, dtype=wp.vec3, device="cpu"),
    ]
    wp.launch(attributes_at_hits, dim=n, inputs=[*inputs, out_albedo, out_weight], device="cpu")
    ply = {"type": "ply", "filename": str(coloured[0])}
    mi_scene = mi.load_dict(
        {
            "type": "scene",
            "mesh": {**ply, "to_world": mi.ScalarTransform4f().translate([3.0, 0.0, 0.0])},
            "turned": {**ply, "to_world": mi.ScalarTransform4f().rotate([0.0, 0.0, 1.0], 30.0)},
        }
    )
    hits = 0
    for k in range(n):
        si = mi_scene.ray_intersect(mi.Ray3f(origins[k].tolist(), directions[k].tolist()))
        if not si.is_valid():  # the turned grid's corners leave gaps
            continue
        hits += 1
        theirs = np.array(si.shape.eval_attribute("vertex_color", si)) * 0.9
        np.testing.assert_allclose(out_albedo.numpy()[k], theirs, atol=2e-6, err_msg=f"ray {k}")
        weight = si.shape.eval_attribute_1("face_weight", si)
        np.testing.assert_allclose(out_weight.numpy()[k], weight, atol=2e-6, err_msg=f"ray {k}")
    assert hits > 0.9 * n


@needs_mitsuba
def test_texture_coordinates_are_read_from_the_pair_mitsuba_reads(tmp_path):
    """A PLY with several pairs of texture-coordinate properties: ``u, v`` first, then
    ``texture_u, texture_v``, then ``s, t`` (Mitsuba 3.9.1's order, its ``vertex_texcoords``)."""
    import mitsuba as mi

    from wrt.meshio import load_mesh

    mi.set_variant("scalar_rgb")
    vertices, faces = grid_mesh(1)
    v = np.arange(len(vertices), dtype=float) / 10
    pairs = {"uv": ("u", "v"), "texture": ("texture_u", "texture_v"), "st": ("s", "t")}
    for present in (("uv", "texture", "st"), ("texture", "st"), ("st", "texture"), ("st",)):
        props = [
            (name, "float", (k + 1) * v + 0.5 * j) for k, p in enumerate(present) for j, name in enumerate(pairs[p])
        ]
        path = tmp_path / f"{'_'.join(present)}.ply"
        write_ply(path, vertices, faces, props)
        theirs = np.array(mi.traverse(mi.load_dict({"type": "ply", "filename": str(path)}))["vertex_texcoords"])
        np.testing.assert_allclose(load_mesh(path, return_uvs=True)[2].ravel(), theirs, rtol=1e-6, err_msg=str(present))


def test_eight_bit_colours_are_refused_as_albedo_with_the_scale_that_reads_them(tmp_path):
    """A PLY's uchar colours are read as written (0-255, as Mitsuba reads them): as an albedo they
    are out of range, and the message names the scale that takes them to [0, 1], which then loads."""
    vertices, faces = grid_mesh(2)
    rng = np.random.default_rng(3)
    rgb = rng.integers(0, 256, (len(vertices), 3))
    write_ply(tmp_path / "grid.ply", vertices, faces, [(c, "uchar", rgb[:, k]) for k, c in enumerate("rgb")])
    text = open(attribute_scene(tmp_path, tmp_path / "grid.ply", "vertex_color")).read()
    text = text.replace('weight = { texture = "mesh_attribute", name = "face_weight" }', "weight = 0.5")
    (tmp_path / "bytes.toml").write_text(text.replace("scale = 0.9", "scale = 1.0"))
    with pytest.raises(WrtError, match=r"ranges over \[\d+, \d+\]: albedo .*8-bit values.*scale = 0\.003921569, 1/255"):
        load_scene(str(tmp_path / "bytes.toml"))
    (tmp_path / "scaled.toml").write_text(text.replace("scale = 0.9", "scale = 0.003921569"))
    scene = load_scene(str(tmp_path / "scaled.toml"))
    np.testing.assert_allclose(scene.materials[0].albedo, rgb.mean(axis=0) * 0.003921569, rtol=1e-9)
