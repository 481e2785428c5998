"""Mitsuba 3 XML import (wrt/mitsuba/): conversions checked against hand computations and
numpy, and, where Mitsuba 3 is installed, against Mitsuba's own reading of the same files."""

import math
import os
import textwrap

import numpy as np
import pytest
from conftest import EXAMPLES
from wrt_harness.mitsuba_peer import mitsuba_available, render_mitsuba

import wrt
from wrt.conductors import METALS
from wrt.errors import WrtError
from wrt.mitsuba import (
    IOR_TABLE,
    MAX_DEPTH,
    load_mitsuba,
    look_at_matrix,
    rotation_matrix,
)
from wrt.scene import Camera

MITSUBA_EXAMPLES = EXAMPLES / "mitsuba"
EXAMPLE_FILES = sorted(MITSUBA_EXAMPLES.glob("*.xml"))
MITSUBA, MITSUBA_REASON = mitsuba_available()
needs_mitsuba = pytest.mark.skipif(not MITSUBA, reason=MITSUBA_REASON)


def write(tmp_path, body, name="scene.xml"):
    """A Mitsuba scene file whose <scene> holds ``body``."""
    path = tmp_path / name
    body = textwrap.dedent(body).strip("\n")  # the body's first line is line 2 of the file
    path.write_text(f'<scene version="3.0.0">\n{body}\n</scene>\n')
    return path


def convert(tmp_path, body, approximate=True, **kwargs):
    """``load_mitsuba`` of a scene holding ``body``, approximating by default so that a test
    sees every approximation (the default import refuses the first one)."""
    return load_mitsuba(write(tmp_path, body), approximate=approximate, **kwargs)


def sensor(fov="", width=200, height=100, transform="", kind="perspective", extra=""):
    return f"""
    <sensor type="{kind}">
        {fov}
        {transform}
        {extra}
        <film type="hdrfilm">
            <integer name="width" value="{width}"/>
            <integer name="height" value="{height}"/>
        </film>
    </sensor>"""


def newell(vertices):
    v = np.asarray(vertices, dtype=np.float64)
    n = np.cross(v, np.roll(v, -1, axis=0)).sum(axis=0)
    return n / np.linalg.norm(n)


def pixel_direction(camera, width, height, u, v):
    """wrt's camera convention (docs/scene-format.md) at film position (u, v) in [0, 1]^2."""
    forward, right, up = Camera(
        tuple(camera["origin"]), tuple(camera["look_at"]), tuple(camera["up"]), camera["fov"]
    ).basis()
    t = math.tan(math.radians(camera["fov"]) / 2)
    d = (2 * u - 1) * t * width / height * right + (1 - 2 * v) * t * up + forward
    return d / np.linalg.norm(d)


# --- camera ------------------------------------------------------------------------------------
HALF = math.tan(math.radians(30.0))  # fov = 60 degrees along the named axis


@pytest.mark.parametrize(
    "axis, width, height, tan_half_vertical",
    [
        ("x", 200, 100, HALF / 2),  # horizontal 60 degrees, aspect 2
        ("y", 200, 100, HALF),
        ("diagonal", 200, 100, HALF / math.sqrt(5)),  # diagonal = sqrt(2^2 + 1^2) heights
        ("smaller", 200, 100, HALF),  # the smaller side of a wide image is y
        ("larger", 200, 100, HALF / 2),
        ("smaller", 100, 200, HALF * 2),  # tall image: smaller side is x, aspect 1/2
        ("larger", 100, 200, HALF),
    ],
)
def test_fov_axis_becomes_the_vertical_fov(tmp_path, axis, width, height, tan_half_vertical):
    fov = f'<float name="fov" value="60"/><string name="fov_axis" value="{axis}"/>'
    doc, warnings = convert(tmp_path, sensor(fov, width, height))
    assert doc["camera"]["fov"] == pytest.approx(math.degrees(2 * math.atan(tan_half_vertical)), rel=1e-12)
    assert warnings == []


def test_fov_axis_defaults_to_x_like_mitsuba(tmp_path):
    doc, _ = convert(tmp_path, sensor('<float name="fov" value="90"/>', 300, 100))
    assert doc["camera"]["fov"] == pytest.approx(math.degrees(2 * math.atan(1 / 3)))  # tan(45) / aspect 3


def test_focal_length_is_35mm_equivalent_diagonal(tmp_path):
    doc, _ = convert(tmp_path, sensor("", 150, 100))  # Mitsuba's default: 50mm
    tan_half_diagonal = math.hypot(36, 24) / 100
    assert doc["camera"]["fov"] == pytest.approx(math.degrees(2 * math.atan(tan_half_diagonal / math.hypot(1.5, 1))))


def test_lookat_becomes_origin_look_at_up(tmp_path):
    transform = '<transform name="to_world"><lookat origin="1, 2, 3" target="4, 2, -1" up="0, 0.5, 0.1"/></transform>'
    doc, _ = convert(tmp_path, sensor('<float name="fov" value="40"/>', transform=transform))
    assert doc["camera"] == {
        "origin": [1, 2, 3],
        "look_at": [4, 2, -1],
        "up": [0, 0.5, 0.1],
        "fov": pytest.approx(doc["camera"]["fov"]),
        "near_clip": 0.01,  # Mitsuba's defaults
        "far_clip": 1e4,
    }


def test_general_camera_transform_gives_the_same_pose_as_its_lookat(tmp_path):
    """rotate + translate: origin = M(0), forward = M(+z), up = M(+y), as Mitsuba's camera frame."""
    transform = '<transform name="to_world"><rotate y="1" angle="90"/><translate x="1" y="2" z="3"/></transform>'
    doc, _ = convert(tmp_path, sensor('<float name="fov" value="40"/>', transform=transform))
    camera = doc["camera"]
    assert camera["origin"] == pytest.approx([1, 2, 3])
    assert np.subtract(camera["look_at"], camera["origin"]) == pytest.approx([1, 0, 0])  # R_y(90) z = +x
    assert camera["up"] == pytest.approx([0, 1, 0])


def test_mirrored_camera_is_approximated_and_scaled_one_refused(tmp_path):
    transform = '<transform name="to_world"><scale x="-1"/></transform>'
    _, warnings = convert(tmp_path, sensor('<float name="fov" value="40"/>', transform=transform))
    assert len(warnings) == 1 and "mirrors the image" in warnings[0]
    for kind in ("perspective", "thinlens"):  # as Mitsuba refuses them
        transform = '<transform name="to_world"><scale value="2"/></transform>'
        extra = '<float name="aperture_radius" value="0.1"/>'
        with pytest.raises(WrtError, match=f'scene.xml:2: <sensor type="{kind}">: the to_world transform scales'):
            convert(tmp_path, sensor('<float name="fov" value="40"/>', transform=transform, kind=kind, extra=extra))


def test_thinlens_keys(tmp_path):
    extra = '<float name="aperture_radius" value="0.2"/><float name="focus_distance" value="4.5"/>'
    doc, warnings = convert(tmp_path, sensor('<float name="fov" value="40"/>', kind="thinlens", extra=extra))
    assert (doc["camera"]["aperture_radius"], doc["camera"]["focus_distance"], warnings) == (0.2, 4.5, [])
    with pytest.raises(WrtError, match="aperture_radius"):
        convert(tmp_path, sensor('<float name="fov" value="40"/>', kind="thinlens"))


def clip(near, far):
    return f'<float name="near_clip" value="{near}"/><float name="far_clip" value="{far}"/>'


def test_orthographic_sensor_and_clip_planes(tmp_path):
    """The film's x scale of to_world gives the view's width (Mitsuba's film spans [-1, 1]); its
    z scale stretches the near clip distance (rays start at to_world(x, y, near_clip)) but not the
    length traced (far_clip - near_clip). Exact: no warning."""
    lookat = '<lookat origin="1, 2, 3" target="4, 2, -1" up="0, 1, 0"/>'
    transform = f'<transform name="to_world"><scale x="1.5" y="1.5" z="2"/>{lookat}</transform>'
    doc, warnings = convert(tmp_path, sensor(transform=transform, kind="orthographic", extra=clip(0.5, 7)))
    camera = doc["camera"]
    assert warnings == [] and (camera["type"], camera["width"]) == ("orthographic", 3.0)
    assert (camera["near_clip"], camera["far_clip"]) == (1.0, 7.5)
    assert camera["origin"] == pytest.approx([1, 2, 3]) and camera["up"] == pytest.approx([0, 1, 0])
    assert np.subtract(camera["look_at"], camera["origin"]) == pytest.approx([0.6, 0, -0.8])
    assert "fov" not in camera
    doc, warnings = convert(tmp_path, sensor('<float name="fov" value="40"/>', extra=clip(0.5, 7)))
    assert (doc["camera"]["near_clip"], doc["camera"]["far_clip"], warnings) == (0.5, 7.0, [])
    doc, _ = convert(tmp_path, sensor('<float name="fov" value="40"/>', extra=clip(0.5, 1e20)))
    assert "far_clip" not in doc["camera"]  # beyond every distance of a scene wrt takes: no clip


@pytest.mark.parametrize(
    "transform, extra, problem",
    [
        ('<scale x="1.5" y="1"/>', "", "scales the film's x and y axes differently"),
        ('<lookat origin="0, 0, 0" target="1, 0, 1"/><scale x="2"/>', "", "shears the film"),
        ("", clip(0, 5), "'near_clip' = '0' must be > 0"),  # as Mitsuba refuses them
        ("", clip(5, 5), "'far_clip' = 5 must be greater than 'near_clip' = 5"),
    ],
)
def test_orthographic_sensor_refusals(tmp_path, transform, extra, problem):
    transform = f'<transform name="to_world">{transform}</transform>'
    with pytest.raises(WrtError, match=f"scene.xml:[0-9]+: .*{problem}"):
        convert(tmp_path, sensor(transform=transform, kind="orthographic", extra=extra))


def test_film_sampler_filter_and_integrator(tmp_path):
    body = """
    <integrator type="path"><integer name="max_depth" value="5"/><integer name="rr_depth" value="3"/></integrator>
    <sensor type="perspective">
        <sampler type="stratified"><integer name="sample_count" value="10"/><integer name="seed" value="7"/></sampler>
        <film type="hdrfilm">
            <integer name="width" value="64"/><integer name="height" value="48"/>
            <string name="pixel_format" value="rgba"/>
            <rfilter type="tent"/>
        </film>
    </sensor>"""
    doc, warnings = convert(tmp_path, body)
    assert doc["render"] == {
        "width": 64,
        "height": 48,
        "filter": "tent",
        "spp": 16,
        "seed": 7,
        "sampler": "stratified",
        "integrator": "path",
        "max_depth": 5,
    }
    assert warnings == []  # rr_depth and pixel_format change only noise / the output file


def test_mitsuba_defaults_without_sensor_or_integrator(tmp_path):
    doc, _ = convert(tmp_path, "")
    assert doc["render"] == {
        "width": 768,
        "height": 576,
        "filter": "gaussian",
        "spp": 4,
        "seed": 0,
        "sampler": "independent",
        "integrator": "path",
        "max_depth": MAX_DEPTH,
    }
    assert doc["camera"]["origin"] == [0, 0, 0] and doc["camera"]["look_at"] == [0, 0, 1]


# --- transforms and geometry -------------------------------------------------------------------
def test_to_world_composes_in_mitsuba_order(tmp_path):
    """Listed scale, rotate, translate: M = T R S, each operation applied after those above it."""
    (tmp_path / "tri.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    body = """
    <shape type="obj">
        <string name="filename" value="tri.obj"/>
        <bsdf type="twosided"><bsdf type="diffuse"/></bsdf>
        <transform name="to_world">
            <scale x="2" y="3" z="4"/>
            <rotate x="1" y="1" z="0" angle="30"/>
            <translate value="1, -2, 0.5"/>
        </transform>
    </shape>"""
    doc, warnings = convert(tmp_path, body)
    matrix = np.array(doc["shape"][0]["transform"]["matrix"]).reshape(4, 4)  # 16 numbers, row-major
    axis = np.array([1.0, 1.0, 0.0]) / math.sqrt(2)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    angle = math.radians(30)
    rotate = np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k  # Rodrigues
    p = np.array([0.3, -0.7, 1.1])
    assert matrix[:3, :3] @ p + matrix[:3, 3] == pytest.approx(
        rotate @ (np.array([2, 3, 4]) * p) + [1, -2, 0.5], abs=1e-12
    )
    assert doc["shape"][0]["file"] == "tri.obj" and doc["shape"][0]["shading"] == "smooth" and warnings == []
    # and the scene loads with the mesh where Mitsuba puts it (issue 16: the loader refused the
    # `transform.matrix` key the importer writes, so 17 of Mitsuba's 41 test scenes stopped)
    mesh = wrt.load_scene(tmp_path / "scene.xml", approximate=True).shapes[0]
    t = np.array([1, -2, 0.5])
    np.testing.assert_allclose(mesh.vertices, [t, rotate @ [2, 0, 0] + t, rotate @ [0, 3, 0] + t], atol=1e-12)


def test_rotation_is_right_handed_and_lookat_frame():
    assert rotation_matrix([0, 0, 1], 90)[:3, :3] @ [1, 0, 0] == pytest.approx([0, 1, 0])
    m = look_at_matrix([0, 0, 0], [0, 0, 1], [0, 1, 0])
    assert np.array_equal(m, np.eye(4))  # Mitsuba's camera: +z forward, +y up, +x to the image's left


def test_matrix_operation_is_row_major(tmp_path):
    (tmp_path / "tri.ply").write_text(
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
        "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"
    )
    body = """
    <shape type="ply">
        <string name="filename" value="tri.ply"/>
        <transform name="to_world"><matrix value="0 -1 0 5  1 0 0 6  0 0 1 7  0 0 0 1"/></transform>
    </shape>"""
    doc, _ = convert(tmp_path, body)
    assert doc["shape"][0]["transform"]["matrix"] == [0, -1, 0, 5, 1, 0, 0, 6, 0, 0, 1, 7, 0, 0, 0, 1]
    np.testing.assert_array_equal(
        wrt.load_scene(tmp_path / "scene.xml", approximate=True).shapes[0].vertices, [[5, 6, 7], [5, 7, 7], [4, 6, 7]]
    )


@pytest.mark.parametrize("normals", ["vn 0 0 1\n", ""], ids=["the file's", "none in the file"])
def test_identity_mesh_has_no_transform_and_shading_follows_face_normals(tmp_path, normals):
    """Mitsuba interpolates vertex normals unless face_normals = true, computing them when the
    file has none: shading = "smooth" (exact, no warning); face_normals = true is wrt's default
    flat shading, and flip_normals turns the mesh around (tests/test_kernels/test_shading_normals.py
    compares the normals with Mitsuba's)."""
    faces = "f 1//1 2//1 3//1" if normals else "f 1 2 3"
    (tmp_path / "n.obj").write_text(f"v 0 0 0\nv 1 0 0\nv 0 1 0\n{normals}{faces}\n")
    doc, warnings = convert(tmp_path, '<shape type="obj"><string name="filename" value="n.obj"/></shape>')
    assert doc["shape"] == [{"type": "mesh", "file": "n.obj", "shading": "smooth", "material": "default_bsdf"}]
    assert warnings == []
    flags = '<boolean name="face_normals" value="true"/><boolean name="flip_normals" value="true"/>'
    doc, warnings = convert(tmp_path, f'<shape type="obj"><string name="filename" value="n.obj"/>{flags}</shape>')
    assert doc["shape"] == [{"type": "mesh", "file": "n.obj", "flip_normals": True, "material": "default_bsdf"}]
    assert warnings == []


RECTANGLE_TO_WORLD = (
    '<transform name="to_world"><scale x="2" y="0.5"/><rotate x="1" angle="-60"/><translate y="1"/></transform>'
)


def test_rectangle_becomes_polygon_wound_around_mitsubas_normal(tmp_path):
    body = f'<shape type="rectangle">{RECTANGLE_TO_WORLD}<bsdf type="twosided"><bsdf type="diffuse"/></bsdf></shape>'
    doc, warnings = convert(tmp_path, body)
    (shape,) = doc["shape"]
    rotate = rotation_matrix([1, 0, 0], -60)[:3, :3]
    expected = [
        rotate @ ([2, 0.5, 1] * np.array(c)) + [0, 1, 0] for c in [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)]
    ]
    assert shape["type"] == "polygon" and np.array(shape["vertices"]) == pytest.approx(np.array(expected))
    assert newell(shape["vertices"]) == pytest.approx(rotate @ [0, 0, 1])  # normal: R (+z)
    assert warnings == []


@pytest.mark.parametrize("variant", ["flip_normals", "mirror"])
def test_rectangle_front_side_under_flip_normals_and_mirroring(tmp_path, variant):
    """flip_normals reverses the front; a mirroring to_world does not (Mitsuba transforms the
    normal as a normal, M^-T n, whatever the handedness)."""
    extra = {
        "flip_normals": '<boolean name="flip_normals" value="true"/>',
        "mirror": '<transform name="to_world"><scale x="-1"/><translate z="2"/></transform>',
    }[variant]
    doc, _ = convert(
        tmp_path, f'<shape type="rectangle">{extra}<bsdf type="twosided"><bsdf type="diffuse"/></bsdf></shape>'
    )
    assert newell(doc["shape"][0]["vertices"]) == pytest.approx([0, 0, -1 if variant == "flip_normals" else 1])


@pytest.mark.parametrize(
    "transform", [RECTANGLE_TO_WORLD, '<transform name="to_world"><scale x="-2" y="1" z="3"/></transform>']
)
def test_cube_becomes_six_outward_polygons(tmp_path, transform):
    doc, _ = convert(tmp_path, f'<shape type="cube">{transform}</shape>')
    faces = [np.array(s["vertices"]) for s in doc["shape"]]
    assert len(faces) == 6 and all(s["type"] == "polygon" for s in doc["shape"])
    centre = np.mean([f.mean(axis=0) for f in faces], axis=0)
    for face in faces:
        assert np.dot(newell(face), face.mean(axis=0) - centre) > 0  # outward
    corners = np.unique(np.round(np.concatenate(faces), 9), axis=0)
    assert len(corners) == 8


def test_sphere_center_radius_and_to_world(tmp_path):
    body = """
    <shape type="sphere">
        <point name="center" x="1" y="0" z="0"/><float name="radius" value="2"/>
        <transform name="to_world"><scale value="3"/><translate x="10"/></transform>
    </shape>"""
    doc, warnings = convert(tmp_path, body)
    assert doc["shape"] == [{"type": "sphere", "center": [13, 0, 0], "radius": 6, "material": "default_bsdf"}]
    assert warnings == []
    _, warnings = convert(
        tmp_path, '<shape type="sphere"><transform name="to_world"><scale x="2"/></transform></shape>'
    )
    assert len(warnings) == 1 and "non-uniform" in warnings[0]


DEFAULT_BSDF = {"name": "default_bsdf", "type": "diffuse", "albedo": [0.5] * 3, "two_sided": False}  # Mitsuba's


def test_shapes_keep_file_order_and_default_bsdf(tmp_path):
    body = """
    <shape type="sphere" id="a"/>
    <shape type="rectangle" id="light"><emitter type="area"/>
        <bsdf type="diffuse"><float name="reflectance" value="0"/></bsdf></shape>
    <shape type="sphere" id="b"><float name="radius" value="2"/></shape>"""
    doc, _ = convert(tmp_path, body)
    assert [s["radius"] for s in doc["shape"]] == [1, 2]  # the light is not a shape
    assert all(s["material"] == "default_bsdf" for s in doc["shape"])  # Mitsuba's default: one-sided diffuse 0.5
    assert doc["material"] == [DEFAULT_BSDF]  # the light's BSDF is not a material of any shape


# --- BSDFs -------------------------------------------------------------------------------------
def test_named_iors_and_exterior(tmp_path):
    body = """
    <shape type="sphere"><bsdf type="dielectric"><string name="int_ior" value="Water"/></bsdf></shape>
    <shape type="sphere"><bsdf type="dielectric">
        <float name="int_ior" value="1.7"/><string name="ext_ior" value="air"/></bsdf></shape>"""
    doc, warnings = convert(tmp_path, body)
    assert [m["ior"] for m in doc["material"]] == [1.3330, 1.7]
    assert doc["render"]["exterior_ior"] == IOR_TABLE["air"] == 1.000277 and warnings == []
    doc, _ = convert(tmp_path, '<shape type="sphere"><bsdf type="dielectric"/></shape>')
    assert doc["material"][0]["ior"] == 1.5046  # Mitsuba's default: bk7 in air
    with pytest.raises(WrtError, match="unknown IOR name"):
        convert(
            tmp_path,
            '<shape type="sphere"><bsdf type="dielectric"><string name="int_ior" value="glass"/></bsdf></shape>',
        )


def test_inconsistent_ext_ior_warns(tmp_path):
    body = """
    <shape type="sphere"><bsdf type="dielectric"/></shape>
    <shape type="sphere"><bsdf type="dielectric"/></shape>
    <shape type="sphere"><bsdf type="dielectric"><string name="ext_ior" value="water"/></bsdf></shape>"""
    doc, warnings = convert(tmp_path, body)
    assert doc["render"]["exterior_ior"] == 1.000277
    assert len(warnings) == 1 and "ext_ior 1.333" in warnings[0] and ":4:" in warnings[0]


def test_one_sided_bsdfs_convert_exactly_and_twosided_unwraps(tmp_path):
    """Mitsuba's diffuse, conductors and default BSDF are one-sided: two_sided = false, no warning;
    twosided makes the same material two-sided (wrt's default, not written). A BSDF shared by
    several shapes stays one material."""
    wrapped = '<bsdf type="twosided"><bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.3, 0.4"/></bsdf></bsdf>'
    doc, warnings = convert(tmp_path, f'<shape type="rectangle">{wrapped}</shape>')
    assert doc["material"] == [{"name": "diffuse@2", "type": "diffuse", "albedo": [0.2, 0.3, 0.4]}] and warnings == []
    body = """
    <bsdf type="diffuse" id="floor"/>
    <shape type="rectangle"><ref id="floor"/></shape>
    <shape type="obj"><string name="filename" value="t.obj"/><boolean name="face_normals" value="true"/>
        <ref id="floor"/></shape>
    <shape type="rectangle"/>
    <shape type="cube"/>"""
    (tmp_path / "t.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    doc, warnings = convert(tmp_path, body)
    assert doc["material"] == [
        {"name": "floor", "type": "diffuse", "albedo": [0.5] * 3, "two_sided": False},
        DEFAULT_BSDF,
    ]
    assert [s["material"] for s in doc["shape"]] == ["floor", "floor"] + ["default_bsdf"] * 7 and warnings == []
    assert wrt.parse_scene(doc, scene_dir=str(tmp_path)).materials[0].two_sided is False


def test_twosided_rejects_a_transmitting_bsdf(tmp_path):
    with pytest.raises(WrtError, match=r"scene.xml:2: <bsdf type=\"dielectric\">: .*transmits"):
        convert(tmp_path, '<shape type="sphere"><bsdf type="twosided"><bsdf type="dielectric"/></bsdf></shape>')


def test_conductors(tmp_path):
    body = """
    <bsdf type="conductor" id="mirror"/>
    <bsdf type="roughconductor" id="rough">
        <string name="distribution" value="ggx"/><float name="alpha" value="0.2"/>
        <rgb name="specular_reflectance" value="0.9, 0.8, 0.7"/>
    </bsdf>
    <shape type="sphere"><ref id="mirror"/></shape>
    <shape type="sphere"><ref name="bsdf" id="rough"/></shape>
    <shape type="sphere"><ref id="rough"/></shape>"""
    doc, warnings = convert(tmp_path, body)
    assert doc["material"] == [
        {"name": "mirror", "type": "mirror", "reflectance": [1, 1, 1], "two_sided": False},
        {
            "name": "rough",
            "type": "glossy",
            "roughness": 0.2,
            "distribution": "ggx",
            "reflectance": [0.9, 0.8, 0.7],
            "two_sided": False,
        },
    ]
    assert [s["material"] for s in doc["shape"]] == ["mirror", "rough", "rough"] and warnings == []
    doc, warnings = convert(
        tmp_path, '<shape type="sphere"><bsdf type="roughconductor"><string name="material" value="Au"/></bsdf></shape>'
    )
    assert doc["material"][0] == {
        "name": "conductor@2",
        "type": "conductor",
        "metal": "Au",
        "roughness": 0.1,
        "distribution": "beckmann",
        "reflectance": [1, 1, 1],
        "two_sided": False,
    }
    assert warnings == []  # Mitsuba's default distribution, Beckmann, converted exactly


def test_rough_dielectric_and_plastics_convert_exactly(tmp_path):
    """roughdielectric, plastic and roughplastic (GGX) become rough_dielectric, plastic and
    rough_plastic without a warning, with Mitsuba's defaults (bk7 or polypropylene in air, alpha
    0.1, diffuse 0.5); the plastics one-sided, their ext_ior the scene's exterior_ior;
    ``sample_visible`` read, not warned about; beckmann (the default) exact too; an unknown
    distribution and equal iors refused, as Mitsuba does."""
    ggx = '<string name="distribution" value="ggx"/>'
    body = f"""
    <shape type="sphere"><bsdf type="roughdielectric" id="frosted">{ggx}
        <float name="alpha" value="0.3"/><boolean name="sample_visible" value="false"/></bsdf></shape>
    <shape type="sphere"><bsdf type="plastic" id="red">
        <rgb name="diffuse_reflectance" value="0.7, 0.1, 0.1"/><boolean name="nonlinear" value="true"/></bsdf></shape>
    <shape type="sphere"><bsdf type="roughplastic" id="blue">{ggx}
        <rgb name="diffuse_reflectance" value="0.1, 0.1, 0.7"/><rgb name="specular_reflectance" value="0.5"/>
        <string name="int_ior" value="pet"/></bsdf></shape>"""
    doc, warnings = convert(tmp_path, body, approximate=False)
    assert warnings == [] and doc["render"]["exterior_ior"] == 1.000277
    assert doc["material"] == [
        {"name": "frosted", "type": "rough_dielectric", "ior": 1.5046, "roughness": 0.3, "distribution": "ggx"},
        {
            "name": "red",
            "type": "plastic",
            "albedo": [0.7, 0.1, 0.1],
            "reflectance": [1.0, 1.0, 1.0],
            "ior": 1.49,
            "nonlinear": True,
            "two_sided": False,
        },
        {
            "name": "blue",
            "type": "rough_plastic",
            "albedo": [0.1, 0.1, 0.7],
            "reflectance": [0.5, 0.5, 0.5],
            "ior": 1.575,
            "nonlinear": False,
            "roughness": 0.1,
            "distribution": "ggx",
            "two_sided": False,
        },
    ]
    wrt.parse_scene(doc, scene_dir=str(tmp_path))
    for kind in ("roughdielectric", "roughplastic"):
        doc, warnings = convert(tmp_path, f'<shape type="sphere"><bsdf type="{kind}"/></shape>', approximate=False)
        assert doc["material"][0]["distribution"] == "beckmann" and warnings == []
        with pytest.raises(WrtError, match=r"scene.xml:2: .*distribution 'phong' is not beckmann or ggx"):
            convert(
                tmp_path,
                f'<shape type="sphere"><bsdf type="{kind}"><string name="distribution" value="Phong"/></bsdf></shape>',
            )
        with pytest.raises(WrtError, match=r"scene.xml:2: .*must differ"):
            convert(
                tmp_path,
                f'<shape type="sphere"><bsdf type="{kind}">{ggx}<float name="int_ior" value="1.2"/>'
                '<float name="ext_ior" value="1.2"/></bsdf></shape>',
            )
    with pytest.raises(WrtError, match=r"scene.xml:2: <bsdf type=\"roughdielectric\">: .*transmits"):
        convert(
            tmp_path,
            f'<shape type="sphere"><bsdf type="twosided"><bsdf type="roughdielectric">{ggx}</bsdf></bsdf></shape>',
        )


def test_conductor_ior_converts_exactly(tmp_path):
    """A named material or eta and k become a wrt conductor without a warning; Mitsuba's
    refusals (both given, an unknown name) are errors."""
    body = """
    <bsdf type="conductor" id="gold"><string name="material" value="Au"/>
        <rgb name="specular_reflectance" value="0.5"/></bsdf>
    <bsdf type="roughconductor" id="custom"><string name="distribution" value="ggx"/><float name="alpha" value="0.3"/>
        <rgb name="eta" value="0.2, 0.9, 1.1"/><rgb name="k" value="3.9, 2.4, 2.1"/></bsdf>
    <shape type="sphere"><ref id="gold"/></shape>
    <shape type="sphere"><ref id="custom"/></shape>"""
    doc, warnings = convert(tmp_path, body, approximate=False)
    assert (
        doc["material"]
        == [
            {"name": "gold", "type": "conductor", "metal": "Au", "reflectance": [0.5] * 3, "two_sided": False},
            {
                "name": "custom",
                "type": "conductor",
                "eta": [0.2, 0.9, 1.1],
                "k": [3.9, 2.4, 2.1],
                "roughness": 0.3,
                "distribution": "ggx",
                "reflectance": [1, 1, 1],
                "two_sided": False,
            },
        ]
        and warnings == []
    )
    gold, custom = wrt.parse_scene(doc, scene_dir=str(tmp_path)).materials[:2]
    assert (gold.eta, gold.k, gold.roughness) == (*METALS["Au"], 0.0) and custom.roughness == 0.3
    both = '<string name="material" value="Au"/><float name="eta" value="2"/>'
    with pytest.raises(WrtError, match=r"scene.xml:2: .*either eta and k or a material"):
        convert(tmp_path, f'<shape type="sphere"><bsdf type="conductor">{both}</bsdf></shape>')
    with pytest.raises(WrtError, match=r"unknown conductor material 'Gold'"):
        convert(
            tmp_path,
            '<shape type="sphere"><bsdf type="conductor"><string name="material" value="Gold"/></bsdf></shape>',
        )


# --- emitters ----------------------------------------------------------------------------------
def test_area_rectangle_becomes_area_light_emitting_on_mitsubas_side(tmp_path):
    body = f"""
    <shape type="rectangle">
        {RECTANGLE_TO_WORLD}
        <bsdf type="diffuse"><rgb name="reflectance" value="0"/></bsdf>
        <emitter type="area"><rgb name="radiance" value="5, 6, 7"/></emitter>
    </shape>"""
    doc, warnings = convert(tmp_path, body)
    (light,) = doc["light"]
    rotate = rotation_matrix([1, 0, 0], -60)[:3, :3]
    assert light["radiance"] == [5, 6, 7] and doc["shape"] == [] and warnings == []
    assert light["corner"] == pytest.approx(rotate @ [-2, -0.5, 0] + [0, 1, 0])
    assert sorted(np.linalg.norm([light["edge_u"], light["edge_v"]], axis=1)) == pytest.approx([1, 4])
    normal = np.cross(light["edge_u"], light["edge_v"])
    assert normal / np.linalg.norm(normal) == pytest.approx(rotate @ [0, 0, 1])  # Mitsuba emits along R (+z)
    flipped, _ = convert(tmp_path, body.replace("</emitter>", '</emitter><boolean name="flip_normals" value="true"/>'))
    light = flipped["light"][0]
    assert np.cross(light["edge_u"], light["edge_v"]) / 4 == pytest.approx(-(rotate @ [0, 0, 1]))


def test_area_sphere_becomes_sphere_light_and_other_shapes_get_emission(tmp_path):
    body = """
    <shape type="sphere"><point name="center" value="1, 2, 3"/>
        <emitter type="area"><rgb name="radiance" value="4"/></emitter></shape>
    <shape type="cube"><bsdf type="diffuse" id="d"/><emitter type="area"/></shape>"""
    doc, warnings = convert(tmp_path, body)
    assert doc["light"] == [{"type": "sphere", "center": [1, 2, 3], "radius": 1, "radiance": [4, 4, 4]}]
    emissive = {"name": "d+emission@4", "type": "diffuse", "albedo": [0.5] * 3, "two_sided": False, "emission": [1] * 3}
    assert doc["material"] == [emissive]
    assert len(doc["shape"]) == 6 and {s["material"] for s in doc["shape"]} == {"d+emission@4"}
    assert warnings == []  # the sphere's default BSDF is Mitsuba's for emitters, black: a sphere light exactly


def test_point_directional_constant_and_spot(tmp_path):
    body = """
    <emitter type="point"><point name="position" value="1, 2, 3"/><rgb name="intensity" value="10"/></emitter>
    <emitter type="point"><transform name="to_world"><translate x="4"/></transform></emitter>
    <emitter type="directional">
        <transform name="to_world"><lookat origin="0, 0, 0" target="0, -1, 0" up="0, 0, 1"/></transform>
        <rgb name="irradiance" value="2, 2, 2"/>
    </emitter>
    <emitter type="directional"><vector name="direction" value="1, 0, 0"/></emitter>
    <emitter type="constant"><rgb name="radiance" value="0.5, 0.6, 0.7"/></emitter>
    <emitter type="spot"><transform name="to_world"><lookat origin="0, 5, 0" target="0, 0, 0"/></transform></emitter>"""
    doc, warnings = convert(tmp_path, body)
    point, point2, sun, sun2, sky, spot = doc["light"]
    assert point == {"type": "point", "position": [1, 2, 3], "intensity": [10, 10, 10]}
    assert point2["position"] == [4, 0, 0] and point2["intensity"] == [1, 1, 1]
    assert sun["direction"] == pytest.approx([0, -1, 0]) and sun["irradiance"] == [2, 2, 2]
    assert sun2["direction"] == [1, 0, 0]
    assert sky == {"type": "environment", "radiance": [0.5, 0.6, 0.7]}
    assert spot["position"] == [0, 5, 0] and spot["direction"] == pytest.approx([0, -1, 0])
    assert (spot["cutoff_angle"], spot["beam_width"]) == (20, 15)
    assert warnings == []


# --- parameters, unsupported input, errors -----------------------------------------------------
def test_default_values_substitute_and_params_override(tmp_path):
    body = """
    <default name="r" value="0.25"/>
    <default name="rr" value="$r"/>
    <shape type="sphere"><float name="radius" value="$rr"/></shape>"""
    path = write(tmp_path, body)
    assert load_mitsuba(path)[0]["shape"][0]["radius"] == 0.25
    assert load_mitsuba(path, params={"r": 3})[0]["shape"][0]["radius"] == 3
    with pytest.raises(WrtError, match=r"scene.xml:2: .*\$undefined is not defined"):
        convert(tmp_path, '<shape type="sphere"><float name="radius" value="$undefined"/></shape>')


def test_unsupported_input_is_refused_or_approximated(tmp_path):
    body = """
    <shape type="linearcurve"/>
    <shape type="sphere"><float name="foo" value="1"/></shape>
    <bsdf type="hair" id="p"/>
    <shape type="sphere"><ref id="p"/></shape>
    <shape type="sphere"><bsdf type="null"/><medium type="rayleigh" name="interior"/></shape>"""
    doc, warnings = convert(tmp_path, body)
    assert [w.split(": ", 2)[:2] for w in warnings] == [
        [f"{tmp_path / 'scene.xml'}:2", '<shape type="linearcurve">'],
        [f"{tmp_path / 'scene.xml'}:3", '<float name="foo">'],
        [f"{tmp_path / 'scene.xml'}:4", '<bsdf type="hair" id="p">'],
        [f"{tmp_path / 'scene.xml'}:6", '<medium type="rayleigh" name="interior">'],
    ]
    assert len(doc["shape"]) == 3
    assert doc["material"] == [
        DEFAULT_BSDF,
        {"name": "p", "type": "diffuse", "albedo": [0.5] * 3, "two_sided": False},
        {"name": "null@6", "type": "null"},
    ]
    with pytest.raises(WrtError, match=r"scene.xml:2: <shape type=\"linearcurve\">: .*--approximate"):
        convert(tmp_path, body, approximate=False)


def test_an_animated_transform_is_refused_by_name(tmp_path):
    """Mitsuba's ``<animation>`` (keyframed ``to_world`` of a shape, an instance or a sensor) is
    refused with what it is, not as an unknown element, even with ``approximate``."""
    body = """
    <shape type="sphere">
        <animation name="to_world">
            <transform time="0"><translate x="-1"/></transform>
            <transform time="1"><translate x="1"/></transform>
        </animation>
    </shape>"""
    with pytest.raises(WrtError, match=r'scene.xml:3: <animation name="to_world">: an animated transform .*velocity'):
        convert(tmp_path, body)


def test_one_approximation_per_cause(tmp_path):
    spheres = '<shape type="sphere"><float name="foo" value="1"/></shape>\n' * 3
    _, warnings = convert(tmp_path, spheres + '<shape type="linearcurve"/>')
    assert len(warnings) == 2 and warnings[0].endswith("is not supported: ignored (also lines 3, 4)")


@pytest.mark.parametrize(
    "body, expected",
    [
        ('<integrator type="direct"><integer name="emitter_samples" value="4"/></integrator>', ("path", 2)),
        (
            '<integrator type="moment"><integrator type="path"><integer name="max_depth" value="5"/></integrator>'
            "</integrator>",
            ("path", 5),
        ),
        ('<integrator type="moment"><integrator type="direct"/></integrator>', ("path", 2)),
        ('<integrator type="volpath"><integer name="max_depth" value="3"/></integrator>', ("path", 3)),
        ('<integrator type="volpathmis"><integer name="max_depth" value="4"/></integrator>', ("path", 4)),
        ('<integrator type="ptracer"><integer name="max_depth" value="3"/></integrator>', ("ptracer", 3)),
        ('<integrator type="ptracer"><integer name="rr_depth" value="2"/></integrator>', ("ptracer", MAX_DEPTH)),
    ],
)
def test_integrators_convert_exactly(tmp_path, body, expected):
    doc, warnings = convert(tmp_path, body, approximate=False)
    assert (doc["render"]["integrator"], doc["render"]["max_depth"]) == expected and warnings == []


@pytest.mark.parametrize("kind", ["prb", "aov"])
def test_other_integrators_are_refused(tmp_path, kind):
    with pytest.raises(WrtError, match=rf'scene.xml:2: <integrator type="{kind}">: integrator not supported'):
        convert(tmp_path, f'<integrator type="{kind}"/>', approximate=False)


def test_scene_errors_name_the_xml_element(tmp_path):
    """A value the importer passes on but the scene format refuses (beyond float32) is reported at
    the element it came from, not at the converted table a user never wrote."""
    path = write(tmp_path, '<shape type="sphere">\n<float name="radius" value="1e39"/>\n</shape>')
    with pytest.raises(
        WrtError, match=r"scene.xml:2: <shape type=\"sphere\">: radius = 1e\+39: .*converted to shape\[0\]"
    ):
        wrt.load_scene(path)


def test_material_errors_name_the_bsdf(tmp_path):
    path = write(
        tmp_path,
        '<bsdf type="diffuse" id="hot">\n<rgb name="reflectance" value="1.5, 0.2, 0.2"/>\n</bsdf>'
        '\n<shape type="sphere"><ref id="hot"/></shape>',
    )
    with pytest.raises(
        WrtError, match=r'scene.xml:2: <bsdf type="diffuse" id="hot">: albedo = .*converted to material\[0\]'
    ):
        wrt.load_scene(path)


def test_render_refuses_or_records_approximations(tmp_path, capsys):
    """``wrt render`` refuses an inexact scene with one line and exit code 2, writing nothing;
    ``--approximate`` renders it and keeps the approximations in the EXR's metadata."""
    from wrt.cli import main
    from wrt.imageio import read_image

    path = write(tmp_path, '<shape type="sphere"><float name="foo" value="1"/></shape>\n' * 2)
    out = tmp_path / "out.exr"
    common = ["render", str(path), "-o", str(out), "--width", "8", "--height", "8", "--spp", "1"]
    assert main(common) == 2 and not out.exists()
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and 'scene.xml:2: <float name="foo">' in error and "--approximate" in error
    assert main([*common, "--approximate"]) == 0
    recorded = read_image(out).metadata["approximations"]
    assert recorded.endswith("is not supported: ignored (also line 3)") and "approximated:" in capsys.readouterr().err


def test_malformed_xml_names_file_and_line(tmp_path):
    path = tmp_path / "bad.xml"
    path.write_text(
        '<scene version="3.0.0">\n  <shape type="sphere">\n    <float name="radius" value="1">\n  </shape>\n</scene>\n'
    )
    with pytest.raises(WrtError, match=r"bad.xml:4:\d+: malformed XML: mismatched tag"):
        load_mitsuba(path)
    with pytest.raises(WrtError, match="cannot read"):
        load_mitsuba(tmp_path / "missing.xml")
    path.write_text('<scene version="3.0.0"><shape type="sphere"><float name="radius" value="one"/></shape></scene>')
    with pytest.raises(WrtError, match=r"bad.xml:1: .*'radius' = 'one' is not a number"):
        load_mitsuba(path)


# --- the examples ------------------------------------------------------------------------------
@pytest.mark.parametrize("path", EXAMPLE_FILES, ids=lambda p: p.stem)
def test_examples_convert_without_warnings(path):
    doc, warnings = load_mitsuba(path)
    assert warnings == [] and doc["render"]["integrator"] == "path" and doc["render"]["filter"] == "box"


@pytest.mark.parametrize("path", EXAMPLE_FILES, ids=lambda p: p.stem)
def test_examples_are_valid_wrt_scenes(path):
    from wrt.loader import parse_scene

    doc, _ = load_mitsuba(path)
    parse_scene(doc, file=str(path), scene_dir=str(path.parent))


# --- against Mitsuba itself --------------------------------------------------------------------
@needs_mitsuba
@pytest.mark.parametrize("path", EXAMPLE_FILES, ids=lambda p: p.stem)
def test_camera_rays_match_mitsuba(path):
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    doc, _ = load_mitsuba(path)
    camera, width, height = doc["camera"], doc["render"]["width"], doc["render"]["height"]
    sensor = mi.load_file(str(path)).sensors()[0]
    for u, v in [(0.05, 0.1), (0.9, 0.2), (0.5, 0.5), (0.3, 0.97)]:
        ray, _ = sensor.sample_ray(0.0, 0.5, [u, v], [0.5, 0.5])  # aperture sample 0.5: the lens centre
        assert np.array(ray.d) == pytest.approx(pixel_direction(camera, width, height, u, v), abs=1e-6)


CLIPPED_SENSORS = {
    "orthographic": (
        "orthographic",
        '<scale x="1.5" y="1.5" z="2"/><lookat origin="0.3, 0.2, 6" target="0, 0, 0" up="0, 1, 0.1"/>',
        clip(2.2, 5.8),  # world distances 4.4 and 8.0 (z scale 2)
    ),
    "perspective": (
        "perspective",
        '<lookat origin="0.3, 0.2, 6" target="0, 0, 0" up="0, 1, 0.1"/>',
        '<float name="fov" value="35"/>' + clip(4.6, 6.9),
    ),
    "thinlens": (
        "thinlens",
        '<lookat origin="0.3, 0.2, 6" target="0, 0, 0" up="0, 1, 0.1"/>',
        '<float name="fov" value="35"/><float name="aperture_radius" value="0.2"/>' + clip(4.6, 6.9),
    ),
}


@needs_mitsuba
@pytest.mark.parametrize("name", list(CLIPPED_SENSORS))
def test_clipped_and_orthographic_camera_rays_match_mitsuba(tmp_path, name):
    """wrt's recorded camera rays (``wrt.rays``: the kernels' own) against Mitsuba's
    ``sensor.sample_ray`` at the same pixel centres: the same start on the near clip plane and
    direction, and the same first hit (or miss) of a sphere the clip planes cut, within the ray's
    ``maxt``."""
    import mitsuba as mi

    from wrt.rays import grid_pixels, trace_rays

    mi.set_variant("scalar_rgb")
    kind, transform, extra = CLIPPED_SENSORS[name]
    path = write(
        tmp_path,
        sensor(
            transform=f'<transform name="to_world">{transform}</transform>', kind=kind, extra=extra, width=64, height=48
        )
        + '<shape type="sphere"><float name="radius" value="1.5"/></shape>',
    )
    tree = trace_rays(wrt.load_scene(path), grid_pixels(64, 48, 9, 7), max_depth=1)
    mitsuba_scene = mi.load_file(str(path))
    camera = mitsuba_scene.sensors()[0]
    hits = 0
    for (x, y), o, d, end, hit in zip(tree.pixel, tree.origin, tree.direction, tree.end, tree.hit):
        ray, _ = camera.sample_ray(0.0, 0.5, [(x + 0.5) / 64, (y + 0.5) / 48], [0.5, 0.5])  # the lens centre
        assert o == pytest.approx(np.array(ray.o), abs=2e-5) and d == pytest.approx(np.array(ray.d), abs=1e-6)
        si = mitsuba_scene.ray_intersect(ray)
        assert hit == bool(si.is_valid()), (x, y)
        if hit:
            hits += 1
            assert np.linalg.norm(end - o) == pytest.approx(float(si.t), abs=1e-4)
    assert 0 < hits < len(tree.hit)


@needs_mitsuba
@pytest.mark.parametrize(
    "transform", [RECTANGLE_TO_WORLD, '<transform name="to_world"><scale x="-1" y="2"/></transform>']
)
def test_polygon_fronts_match_mitsubas_shading_normals(tmp_path, transform):
    """Rays at each converted polygon's centre hit Mitsuba's rectangle / cube with the shading
    normal (the side that emits and that one-sided BSDFs shade) equal to the polygon's normal."""
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    for kind in ("rectangle", "cube"):
        path = write(tmp_path, f'<shape type="{kind}">{transform}</shape>')
        doc, _ = load_mitsuba(path)
        scene = mi.load_file(str(path))
        for shape in doc["shape"]:
            normal, centre = newell(shape["vertices"]), np.mean(shape["vertices"], axis=0)
            si = scene.ray_intersect(mi.Ray3f(centre + 3 * normal, -normal))
            assert si.is_valid() and np.array(si.sh_frame.n) == pytest.approx(normal, abs=1e-5)


@needs_mitsuba
def test_render_mitsuba_small_cornell_box():
    image = render_mitsuba(MITSUBA_EXAMPLES / "cornell_box.xml", spp=4, res=32)
    assert image.shape == (32, 32, 3) and image.dtype == np.float32
    assert np.isfinite(image).all() and 0.05 < image.mean() < 1.0


# --- <include> and <path> (issue 16) ---------------------------------------------------------------
TRI = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"
SENSOR_FRAGMENT = sensor('<float name="fov" value="30"/>', 64, 48)
MESH_SHAPE = (
    '<shape type="obj"><string name="filename" value="tri.obj"/><boolean name="face_normals" value="true"/></shape>'
)


def test_include_splices_fragments_in_place_relative_to_their_folder(tmp_path):
    """A scene whose sensor and shapes live in included fragments (one including another, from a
    subfolder, its mesh beside it) converts exactly as the same scene in one file; before, the
    includes were ignored and the scene rendered wrt's default camera over nothing."""
    (tmp_path / "parts").mkdir()
    (tmp_path / "parts" / "tri.obj").write_text(TRI)
    write(tmp_path / "parts", SENSOR_FRAGMENT, "sensor.xml")
    write(tmp_path / "parts", '<include filename="inner.xml"/>\n<shape type="sphere"/>', "shapes.xml")
    write(tmp_path / "parts", MESH_SHAPE, "inner.xml")
    main, _ = load_mitsuba(
        write(tmp_path, '<include filename="parts/sensor.xml"/>\n<include filename="parts/shapes.xml"/>')
    )
    (tmp_path / "flat").mkdir()
    (tmp_path / "flat" / "parts").mkdir()
    (tmp_path / "flat" / "parts" / "tri.obj").write_text(TRI)
    flat, _ = load_mitsuba(
        write(
            tmp_path / "flat",
            SENSOR_FRAGMENT + MESH_SHAPE.replace("tri.obj", "parts/tri.obj") + '<shape type="sphere"/>',
        )
    )
    assert main == flat and main["render"]["width"] == 64 and [s["type"] for s in main["shape"]] == ["mesh", "sphere"]
    assert main["shape"][0]["file"] == os.path.join("parts", "tri.obj")


def test_include_loops_and_missing_files_are_refused_naming_the_fragment(tmp_path):
    write(tmp_path, '<include filename="b.xml"/>', "a.xml")
    write(tmp_path, '<shape type="sphere"/>\n<include filename="a.xml"/>', "b.xml")
    with pytest.raises(WrtError, match=r"b\.xml:3: <include>: include loop: a\.xml > b\.xml > a\.xml"):
        load_mitsuba(tmp_path / "a.xml")
    with pytest.raises(WrtError, match=r"scene\.xml:2: <include>: no such file 'nowhere\.xml' \(searched: "):
        load_mitsuba(write(tmp_path, '<include filename="nowhere.xml"/>'))
    write(tmp_path, '<shape type="sphere"><float name="radius" value="-1"/></shape>', "bad.xml")
    with pytest.raises(WrtError, match=r"bad\.xml:2: <float name=\"radius\">: 'radius' = '-1'"):  # the fragment's line
        load_mitsuba(write(tmp_path, '<include filename="bad.xml"/>'))


def test_path_adds_folders_where_files_are_found(tmp_path):
    """<path value="meshes"/> makes Mitsuba look for files there (8 of its test scenes keep their
    meshes so); without it the mesh is not found, and the message says where it looked."""
    (tmp_path / "meshes").mkdir()
    (tmp_path / "meshes" / "tri.obj").write_text(TRI)
    doc, _ = load_mitsuba(write(tmp_path, '<path value="meshes"/>\n' + MESH_SHAPE))
    assert doc["shape"][0]["file"] == os.path.join("meshes", "tri.obj")
    assert wrt.load_scene(tmp_path / "scene.xml", approximate=True).shapes[0].vertices.shape == (3, 3)
    with pytest.raises(WrtError, match=r"no such mesh file 'tri\.obj' \(searched: "):
        load_mitsuba(write(tmp_path, MESH_SHAPE))
