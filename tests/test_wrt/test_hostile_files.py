"""Hostile input files: malformed PLY headers and bodies, Mitsuba XML with non-finite or degenerate
numbers, reference loops, deep nesting and XML entities, and fuzz tests of both readers.

Every bad file: one line ``wrt: error: ...`` naming the file (for XML also the line, the element
and the value), exit code 2, no output file, and never a traceback.
"""

import os
import struct
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from wrt.cli import main
from wrt.errors import MeshFileError, WrtError
from wrt.loader import load_scene
from wrt.meshio import load_mesh
from wrt.mitsuba import load_mitsuba

# A numpy overflow warning would be a second stderr line of the CLI: make it fail the test instead.
pytestmark = pytest.mark.filterwarnings("error::RuntimeWarning")


def render(capsys, scene):
    """``wrt render`` of ``scene`` at 4 x 3 pixels, 1 spp: (exit code, error lines), after checking
    that stderr holds only warnings and at most one error line, and that a failure wrote nothing."""
    folder = Path(scene).parent
    before = set(os.listdir(folder))
    out = folder / "out.exr"
    code = main(["render", str(scene), "-o", str(out), "--width", "4", "--height", "3", "--spp", "1"])
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if not line.startswith("wrt: warning: ")]
    assert code in (0, 2) and "Traceback" not in err, (code, err)
    assert all(line.startswith("wrt: error: ") for line in lines) and len(lines) == (code == 2), err
    if code == 2:
        assert set(os.listdir(folder)) == before, err  # no output, no temporary file
    elif out.exists():
        out.unlink()
    return code, lines


def refused(capsys, scene, *fragments):
    """``wrt render`` exits 2 with one error line holding every fragment; returns the line."""
    code, lines = render(capsys, scene)
    assert code == 2, f"rendered instead of refusing {scene}"
    for fragment in fragments:
        assert fragment in lines[0], (fragment, lines[0])
    return lines[0]


# --- 1. PLY: the header validated once, before the body ---------------------------------------

XYZ = "property float x\nproperty float y\nproperty float z\n"
TRIANGLES = "property list uchar int vertex_indices\n"
VERTICES = "0 0 0\n1 0 0\n0 1 0\n"


def ascii_ply(vertices=3, faces=1, vertex_props=XYZ, face_props=TRIANGLES, body=VERTICES + "3 0 1 2\n", extra=""):
    return (
        f"ply\nformat ascii 1.0\nelement vertex {vertices}\n{vertex_props}element face {faces}\n{face_props}"
        f"{extra}end_header\n{body}"
    )


def binary_ply(declared=3, points=3, faces=((0, 1, 2),), tail=b"", count_type="B", index_type="i"):
    names = {"B": "uchar", "i": "int", "I": "uint"}
    header = (
        f"ply\nformat binary_little_endian 1.0\nelement vertex {declared}\n{XYZ}element face {len(faces)}\n"
        f"property list {names[count_type]} {names[index_type]} vertex_indices\nend_header\n"
    ).encode()
    body = b"".join(struct.pack("<3f", i % 2, i // 2, 0.0) for i in range(points))
    for face in faces:
        body += struct.pack(f"<{count_type}{len(face)}{index_type}", len(face), *face)
    return header + body + tail


BAD_PLY = [
    ("ascii: vertex count above the data", ascii_ply(vertices=4), "element counts (4 vertex, 1 face) need 5 lines"),
    ("ascii: vertex count below the data", ascii_ply(vertices=2), "element counts (2 vertex, 1 face) need 3 lines"),
    ("ascii: a line after the data", ascii_ply(body=VERTICES + "3 0 1 2\n3 0 1 2\n"), "need 4 lines, the body has 5"),
    ("ascii: a vertex line short", ascii_ply(body="0 0 0\n1 0\n0 1 0\n3 0 1 2\n"), "line 11: vertex 1 has 2 values"),
    ("ascii: a face line long", ascii_ply(body=VERTICES + "3 0 1 2 7\n"), "line 13: face 0 has 5 values, it takes 4"),
    ("ascii: list past its line", ascii_ply(body=VERTICES + "200 0 1 2\n"), "face 0 has a list of 200 items"),
    ("ascii: list length not a count", ascii_ply(body=VERTICES + "-1 0 1 2\n"), "list length -1"),
    ("ascii: truncated", ascii_ply(body=VERTICES + "3 0 1"), "truncated"),
    (
        "ascii: a word in the body",
        ascii_ply(body="0 0 0\n1 zero 0\n0 1 0\n3 0 1 2\n"),
        "line 11: 'zero' is not a number",
    ),
    ("binary: truncated body", binary_ply()[:-3], "truncated"),
    ("binary: vertex count above the data", binary_ply(declared=4), ""),
    ("binary: bytes after the last element", binary_ply(tail=b"\0" * 13), "13 bytes after the last element"),
    (
        "binary: huge vertex count",
        binary_ply(declared=10**12),
        "element counts (1000000000000 vertex, 1 face) need at least",
    ),
    (
        "ascii: a face of 0 vertices after triangles",
        ascii_ply(faces=2, body=VERTICES + "3 0 1 2\n0\n"),
        "face 1 has 0 vertices (a face needs at least 3)",
    ),
    (
        "ascii: a face of 2 vertices after triangles",
        ascii_ply(faces=2, body=VERTICES + "3 0 1 2\n2 0 1\n"),
        "face 1 has 2 vertices",
    ),
    ("binary: a face of 2 vertices", binary_ply(faces=((0, 1, 2), (0, 1))), "face 1 has 2 vertices"),
    ("binary: a face of 0 vertices", binary_ply(faces=((0, 1, 2), ())), "face 1 has 0 vertices"),
    (
        "list-typed x",
        ascii_ply(
            vertex_props=XYZ.replace("property float x", "property list uchar float x"),
            body="1 0 0 0\n1 1 0 0\n1 0 1 0\n3 0 1 2\n",
        ),
        "property 'x' of element 'vertex' is a list",
    ),
    (
        "duplicated property",
        ascii_ply(vertex_props=XYZ + "property float z\n", body="0 0 0 0\n1 0 0 0\n0 1 0 0\n3 0 1 2\n"),
        "property 'z' of element 'vertex' is declared twice",
    ),
    ("duplicated x", ascii_ply(vertex_props=XYZ.replace(" y", " x")), "property 'x' of element 'vertex' is declared"),
    ("unknown property type", ascii_ply(vertex_props=XYZ.replace("float z", "half z")), "unknown type 'half'"),
    ("unknown list type", ascii_ply(face_props="property list uchar quad vertex_indices\n"), "unknown type 'quad'"),
    (
        "float list length",
        ascii_ply(face_props="property list float int vertex_indices\n"),
        "list length type 'float' is not an integer type",
    ),
    (
        "scalar vertex_indices",
        ascii_ply(face_props="property int vertex_indices\n", body=VERTICES + "0\n"),
        "property 'vertex_indices' of element 'face' is not a list",
    ),
    ("face without indices", ascii_ply(face_props="property uchar red\n", body=VERTICES + "0\n"), "no vertex_indices"),
    (
        "duplicated element",
        ascii_ply(extra="element vertex 1\nproperty float x\n", body=VERTICES + "3 0 1 2\n0\n"),
        "element 'vertex' is declared twice",
    ),
    ("two format lines", ascii_ply().replace("1.0\n", "1.0\nformat ascii 1.0\n", 1), "a second 'format' line"),
    ("element without properties", ascii_ply(extra="element extra 1\n", body=VERTICES + "3 0 1 2\n\n"), "no prop"),
    ("index out of range", ascii_ply(body=VERTICES + "3 0 1 3\n"), "1 of 3 face vertex indices are out of range"),
    ("negative index", ascii_ply(body=VERTICES + "3 0 -1 2\n"), "out of range for 3 vertices (face 0 has -1)"),
    ("negative index in a quad", ascii_ply(body=VERTICES + "4 0 1 2 -7\n"), "(face 0 has -7)"),
    ("binary: negative index", binary_ply(faces=((0, 1, -2),)), "(face 0 has -2)"),
    ("binary: huge unsigned index", binary_ply(faces=((0, 1, 2**32 - 1),), index_type="I"), "out of range"),
]


@pytest.mark.parametrize("data, problem", [c[1:] for c in BAD_PLY], ids=[c[0] for c in BAD_PLY])
def test_malformed_ply_is_one_line_naming_the_mesh(tmp_path, capsys, data, problem):
    mesh = tmp_path / "hostile.ply"
    mesh.write_bytes(data.encode() if isinstance(data, str) else data)
    with pytest.raises(MeshFileError) as caught:
        load_mesh(mesh)
    message = str(caught.value)
    assert message.startswith(f"{mesh}: ") and "\n" not in message and problem in message, message
    scene = tmp_path / "scene.toml"
    scene.write_text(
        '[camera]\norigin = [0, 0, 5]\nlook_at = [0, 0, 0]\n\n[[shape]]\ntype = "mesh"\nfile = "hostile.ply"\n'
    )
    refused(capsys, scene, str(scene), "shape[0].file = 'hostile.ply'", problem)


def test_well_formed_ply_still_loads_exactly(tmp_path):
    """The checks refuse none of the variants a PLY file may legally take."""
    cases = {
        "comments and blank lines": ascii_ply(body="0 0 0\n\n1 0 0\n0 1 0\r\n3 0 1 2\n\n").replace(
            "element face", "comment a face\nobj_info x\nelement face"
        ),
        "extra properties and elements": ascii_ply(
            vertex_props="property uchar red\n" + XYZ,
            face_props="property int flags\n" + TRIANGLES + "property list uchar float uv\n",
            body="9 0 0 0\n9 1 0 0\n9 0 1 0\n5 3 0 1 2 2 0.5 0.5\n",
            extra="element edge 0\nproperty int v1\n",
        ),
        "vertex_index": ascii_ply(face_props="property list uchar int vertex_index\n"),
        "binary": binary_ply(),
        "binary uint indices": binary_ply(index_type="I"),
        "binary with a final line break": binary_ply(tail=b"\r\n"),
    }
    for name, data in cases.items():
        path = tmp_path / "ok.ply"
        path.write_bytes(data.encode() if isinstance(data, str) else data)
        vertices, faces = load_mesh(path)
        assert faces.tolist() == [[0, 1, 2]], name
        assert sorted(map(tuple, vertices.tolist()))[:3] == [(0, 0, 0), (0, 1, 0), (1, 0, 0)], name


# --- 2. Mitsuba XML: one number parser refusing non-finite values, singular transforms, loops ------

SENSOR = (
    '<sensor type="perspective">\n{}\n<film type="hdrfilm"><integer name="width" value="8"/>'
    '<integer name="height" value="6"/></film>\n</sensor>'
)
SPHERE = '<shape type="sphere">\n{}\n</shape>'


def xml_scene(tmp_path, body, name="scene.xml"):
    """A Mitsuba scene whose ``<scene>`` (line 1) holds ``body`` from line 2 on."""
    path = tmp_path / name
    path.write_text(f'<scene version="3.0.0">\n{textwrap.dedent(body).strip()}\n</scene>\n')
    return path


def to_world(ops):
    return f'<transform name="to_world">\n{ops}\n</transform>'


BAD_XML = [
    # (id, body, line, element, value fragment, problem fragment)
    ("focal_length 0mm", SENSOR.format('<string name="focal_length" value="0mm"/>'), 3, "focal_length", "'0mm'", "> 0"),
    ("focal_length -50mm", SENSOR.format('<string name="focal_length" value="-50mm"/>'), 3, "focal_length", "-50", ""),
    ("focal_length nan", SENSOR.format('<string name="focal_length" value="nanmm"/>'), 3, "focal_length", "nan", ""),
    ("focal_length inf", SENSOR.format('<string name="focal_length" value="infmm"/>'), 3, "focal_length", "inf", ""),
    ("focal_length 1e-300", SENSOR.format('<string name="focal_length" value="1e-300mm"/>'), 3, "focal_length", "", ""),
    ("focal_length float", SENSOR.format('<float name="focal_length" value="0mm"/>'), 3, "focal_length", "'0mm'", ""),
    ("fov 0", SENSOR.format('<float name="fov" value="0"/>'), 3, '<float name="fov">', "'0'", "in (0, 180)"),
    ("fov 180", SENSOR.format('<float name="fov" value="180"/>'), 3, '<float name="fov">', "'180'", "in (0, 180)"),
    ("fov negative", SENSOR.format('<float name="fov" value="-30"/>'), 3, '<float name="fov">', "'-30'", ""),
    ("fov nan", SENSOR.format('<float name="fov" value="nan"/>'), 3, '<float name="fov">', "'nan'", "not finite"),
    ("fov inf", SENSOR.format('<float name="fov" value="inf"/>'), 3, '<float name="fov">', "'inf'", "not finite"),
    ("fov 1e308", SENSOR.format('<float name="fov" value="1e308"/>'), 3, '<float name="fov">', "'1e308'", ""),
    ("fov 1e999", SENSOR.format('<float name="fov" value="1e999"/>'), 3, '<float name="fov">', "'1e999'", "finite"),
    ("fov empty", SENSOR.format('<float name="fov" value=""/>'), 3, '<float name="fov">', "''", "not a number"),
    ("radius nan", SPHERE.format('<float name="radius" value="nan"/>'), 3, "radius", "'nan'", "not finite"),
    ("radius inf", SPHERE.format('<float name="radius" value="inf"/>'), 3, "radius", "'inf'", "not finite"),
    ("radius -inf", SPHERE.format('<float name="radius" value="-Infinity"/>'), 3, "radius", "'-Infinity'", ""),
    ("radius negative", SPHERE.format('<float name="radius" value="-2"/>'), 3, "radius", "'-2'", "> 0"),
    ("radius 0", SPHERE.format('<float name="radius" value="0"/>'), 3, "radius", "'0'", "> 0"),
    ("radius 1_0", SPHERE.format('<float name="radius" value="1_0"/>'), 3, "radius", "'1_0'", "not a number"),
    ("radius hex", SPHERE.format('<float name="radius" value="0x10"/>'), 3, "radius", "'0x10'", "not a number"),
    ("translate nan", SPHERE.format(to_world('<translate x="nan"/>')), 4, "<translate>", "'x' = 'nan'", "finite"),
    (
        "matrix inf",
        SPHERE.format(to_world('<matrix value="inf 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1"/>')),
        4,
        "<matrix>",
        "'value' = 'inf 0 0",
        "not finite",
    ),
    ("rotate angle nan", SPHERE.format(to_world('<rotate x="1" angle="nan"/>')), 4, "<rotate>", "'angle' = 'nan'", ""),
    ("rotate axis inf", SPHERE.format(to_world('<rotate y="inf" angle="3"/>')), 4, "<rotate>", "'y' = 'inf'", ""),
    ("scale 0", SPHERE.format(to_world('<scale value="0"/>')), 4, "<scale>", "'value' = '0'", "singular"),
    ("scale z 0 camera", SENSOR.format(to_world('<scale z="0"/>')), 4, "<scale>", "'z' = '0'", "singular"),
    (
        "scale 0 rectangle",
        '<shape type="rectangle">\n' + to_world('<scale x="2" y="0"/>') + "\n</shape>",
        4,
        "<scale>",
        "'y' = '0'",
        "singular",
    ),
    (
        "singular matrix",
        SPHERE.format(to_world('<matrix value="1 2 3 0 2 4 6 0 0 0 1 0 0 0 0 1"/>')),
        4,
        "<matrix>",
        "'value' = '1 2 3",
        "singular",
    ),
    (
        "projective matrix",
        SPHERE.format(to_world('<matrix value="1 0 0 0 0 1 0 0 0 0 1 0 0 0 1 1"/>')),
        4,
        "<matrix>",
        "'value' = '1 0 0",
        "0 0 0 1",
    ),
    (
        "scales that overflow",
        SPHERE.format(to_world('<scale value="1e300"/>\n<scale value="1e300"/>')),
        3,
        '<transform name="to_world">',
        "",
        "not finite",
    ),
    (
        "radius that overflows",
        SPHERE.format('<float name="radius" value="1e300"/>\n' + to_world('<scale value="1e300"/>')),
        2,
        '<shape type="sphere">',
        "",
        "not finite",
    ),
    (
        "rectangle beyond float64",
        '<shape type="rectangle">\n' + to_world('<scale value="1e308"/><translate value="1e308"/>') + "\n</shape>",
        2,
        '<shape type="rectangle">',
        "",
        "not finite",
    ),
    (
        "lookat with 2 numbers",
        SENSOR.format(to_world('<lookat origin="0 0" target="0 0 1" up="0 1 0"/>')),
        4,
        "<lookat>",
        "'origin' = '0 0'",
        "3 numbers",
    ),
    (
        "rgb nan",
        SPHERE.format('<bsdf type="diffuse"><rgb name="reflectance" value="nan 0 0"/></bsdf>'),
        3,
        "<rgb",
        "",
        "",
    ),
    ("point inf", SPHERE.format('<point name="center" x="0" y="inf" z="0"/>'), 3, "<point", "'y' = 'inf'", ""),
    (
        "spectrum nan",
        SPHERE.format('<bsdf type="diffuse"><spectrum name="reflectance" value="400:nan"/></bsdf>'),
        3,
        "",
        "nan",
        "",
    ),
    ("integer 1_6", SENSOR.format("").replace('"8"', '"1_6"'), 4, '<integer name="width">', "'1_6'", "not an integer"),
    (
        "ref to itself",
        '<bsdf type="twosided" id="a">\n<ref id="a"/>\n</bsdf>\n<shape type="sphere"><ref id="a"/></shape>',
        3,
        '<ref id="a">',
        "",
        "reference loop",
    ),
    (
        "refs that refer back",
        '<bsdf type="twosided" id="a">\n<ref id="b"/>\n</bsdf>\n<bsdf type="twosided" id="b">\n<ref id="a"/>\n</bsdf>\n'
        '<shape type="sphere"><ref id="a"/></shape>',
        6,
        '<ref id="a">',
        "",
        "reference loop",
    ),
    (
        "ref to an ancestor",
        '<bsdf type="twosided" id="a">\n<bsdf type="twosided">\n<ref id="a"/>\n</bsdf>\n</bsdf>',
        4,
        '<ref id="a">',
        "",
        "reference loop",
    ),
    (
        "shape referring to itself",
        '<shape type="sphere" id="s">\n<ref id="s"/>\n</shape>',
        3,
        '<ref id="s">',
        "",
        "loop",
    ),
    (
        "duplicate id",
        '<bsdf type="diffuse" id="a"/>\n<bsdf type="conductor" id="a"/>\n<shape type="sphere"><ref id="a"/></shape>',
        3,
        '<bsdf type="conductor" id="a">',
        "'a'",
        "line 2",
    ),
]


@pytest.mark.parametrize("body, line, element, value, problem", [c[1:] for c in BAD_XML], ids=[c[0] for c in BAD_XML])
def test_bad_mitsuba_values_are_one_line_naming_file_line_element_value(
    tmp_path, capsys, body, line, element, value, problem
):
    path = xml_scene(tmp_path, body)
    refused(capsys, path, f"{path}:{line}: ", element, value, problem)


def test_good_numbers_still_convert(tmp_path):
    """The shared parser keeps every number Mitsuba writes: signs, exponents, leading dots, commas."""
    path = xml_scene(
        tmp_path,
        SENSOR.format('<float name="fov" value=" +4.5e1 "/>')
        + '\n<shape type="sphere"><float name="radius" value=".5"/><point name="center" value="1, -2E0,3."/>\n'
        + to_world('<scale value="2"/><rotate z="1" angle="-90"/><matrix value="1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1"/>')
        + "\n</shape>",
    )
    doc, _ = load_mitsuba(path)
    assert doc["shape"][0]["radius"] == pytest.approx(1.0)
    assert doc["shape"][0]["center"] == pytest.approx([-4.0, -2.0, 6.0])
    assert doc["camera"]["fov"] > 0


# --- 3. deep nesting -------------------------------------------------------------------------------


@pytest.mark.parametrize("tag", ["shape", "transform", "bsdf"])
def test_deeply_nested_xml_is_one_line(tmp_path, capsys, tag):
    depth = 100_000
    path = tmp_path / "deep.xml"
    path.write_text('<scene version="3.0.0">\n' + f'<{tag} type="sphere">' * depth + f"</{tag}>" * depth + "</scene>")
    refused(capsys, path, f"{path}:2: ", "nested more than")


def test_nesting_a_real_scene_needs_converts(tmp_path):
    """Twosided around bumpmap around diffuse inside a shape: well within the limit."""
    heights = Path(__file__).resolve().parents[2] / "examples" / "textures" / "bump_map.png"
    path = xml_scene(
        tmp_path,
        '<shape type="sphere"><bsdf type="twosided"><bsdf type="bumpmap"><bsdf type="diffuse"/>'
        f'<texture type="bitmap"><string name="filename" value="{heights}"/></texture></bsdf></bsdf></shape>',
    )
    doc, _ = load_mitsuba(path)
    assert doc["material"][0]["type"] == "diffuse" and "bump_map" in doc["material"][0]


# --- 4. entities -----------------------------------------------------------------------------------


def test_billion_laughs_is_refused_quickly(tmp_path, capsys):
    entities = '<!ENTITY a "aaaaaaaaaa">\n' + "".join(
        f'<!ENTITY {chr(98 + i)} "{("&" + chr(97 + i) + ";") * 10}">\n' for i in range(9)
    )  # &j; expands to 10^10 characters
    path = tmp_path / "laughs.xml"
    path.write_text(
        f'<?xml version="1.0"?>\n<!DOCTYPE scene [\n{entities}]>\n'
        '<scene version="3.0.0"><shape type="sphere"><string name="id" value="&j;"/></shape></scene>\n'
    )
    start = time.monotonic()
    refused(capsys, path, str(path), "malformed XML")
    assert time.monotonic() - start < 5


def test_external_entities_are_not_read(tmp_path, capsys):
    """An external entity, in an attribute or in content, never brings the file it names in: its
    content (a shape; a secret string) does not reach the converted scene."""
    (tmp_path / "extra.xml").write_text('<shape type="rectangle"/>')
    (tmp_path / "secret.txt").write_text("SECRET")
    dtd = (
        f'<?xml version="1.0"?>\n<!DOCTYPE scene [\n<!ENTITY shape SYSTEM "file://{tmp_path}/extra.xml">\n'
        f'<!ENTITY secret SYSTEM "file://{tmp_path}/secret.txt">\n]>\n'
    )
    in_content = tmp_path / "content.xml"
    in_content.write_text(dtd + '<scene version="3.0.0">&shape;<shape type="sphere"/></scene>\n')
    doc, _ = load_mitsuba(in_content)
    assert [s["type"] for s in doc["shape"]] == ["sphere"]  # no polygon from extra.xml
    in_attribute = tmp_path / "attribute.xml"
    in_attribute.write_text(
        dtd + '<scene version="3.0.0"><shape type="obj"><string name="filename" value="&secret;"/></shape></scene>\n'
    )
    line = refused(capsys, in_attribute, str(in_attribute), "external entity")
    assert "SECRET" not in line
    external_dtd = tmp_path / "dtd.xml"
    (tmp_path / "evil.dtd").write_text("<!ENTITY shape \"<shape type='rectangle'/>\">")
    external_dtd.write_text(
        f'<?xml version="1.0"?>\n<!DOCTYPE scene SYSTEM "file://{tmp_path}/evil.dtd">\n'
        '<scene version="3.0.0">&shape;<shape type="sphere"/></scene>\n'
    )
    doc, _ = load_mitsuba(external_dtd)
    assert [s["type"] for s in doc["shape"]] == ["sphere"]  # the external DTD was not loaded


# --- 5. fuzzing ------------------------------------------------------------------------------------

PLY_TYPES = ["char", "uchar", "short", "ushort", "int", "uint", "float", "double", "int8", "uint32", "float64"]
ODD_TYPES = ["half", "", "list", "string", "float16", "int64"]
ODD_COUNTS = ["0", "1", "2", "3", "4", "7", "-1", "2147483648", "1000000000000", "3.0", "x", ""]
ODD_TOKENS = ["nan", "inf", "-inf", "-1", "0", "3", "255", "1e39", "2147483647", "4294967295", "1.5", "x", "", "\x00"]


@st.composite
def ply_files(draw):
    """A small PLY file (ASCII or binary) with mutated element counts, property types and names,
    and a body that fits the header or not."""
    binary = draw(st.booleans())
    vertex_props = [["float", "x"], ["float", "y"], ["float", "z"]]
    face_props = [["list", "uchar", "int", "vertex_indices"]]
    counts = {"vertex": 4, "face": 2}
    for _ in range(draw(st.integers(0, 3))):
        props = draw(st.sampled_from([vertex_props, face_props]))
        prop = draw(st.sampled_from(props))
        mutation = draw(st.sampled_from(["type", "name", "duplicate", "delete", "list", "count"]))
        if mutation == "type":
            prop[-2] = draw(st.sampled_from(PLY_TYPES + ODD_TYPES))
        elif mutation == "name":
            prop[-1] = draw(st.sampled_from(["x", "y", "z", "w", "vertex_indices", "vertex_index", "nx", ""]))
        elif mutation == "duplicate":
            props.append(list(prop))
        elif mutation == "delete" and len(props) > 1:
            props.remove(prop)
        elif mutation == "list" and prop[0] != "list":
            prop[:] = ["list", draw(st.sampled_from(PLY_TYPES + ODD_TYPES)), *prop]
        elif mutation == "count":
            counts[draw(st.sampled_from(["vertex", "face"]))] = draw(st.sampled_from(ODD_COUNTS))
    header = ["ply", f"format {'binary_little_endian' if binary else 'ascii'} 1.0"]
    for name, props in (("vertex", vertex_props), ("face", face_props)):
        header.append(f"element {name} {counts[name]}")
        header += ["property " + " ".join(p) for p in props]
    header.append("end_header")
    lines = ["0 0 0", "1 0 0", "0 1 0", "0 0 1", "3 0 1 2", "4 0 1 2 3"]
    for _ in range(draw(st.integers(0, 3))):
        i = draw(st.integers(0, len(lines)))
        mutation = draw(st.sampled_from(["drop", "repeat", "token", "append"]))
        if mutation == "drop" and i < len(lines):
            del lines[i]
        elif mutation == "repeat" and i < len(lines):
            lines.insert(i, lines[i])
        elif mutation == "token" and i < len(lines):
            words = lines[i].split() or [""]
            words[draw(st.integers(0, len(words) - 1))] = draw(st.sampled_from(ODD_TOKENS))
            lines[i] = " ".join(words)
        elif mutation == "append":
            lines.insert(i, " ".join(draw(st.lists(st.sampled_from(ODD_TOKENS), max_size=5))))
    head = ("\n".join(header) + "\n").encode("utf-8", "surrogatepass")
    if not binary:
        return head + ("\n".join(lines) + "\n").encode()
    with np.errstate(all="ignore"):  # 1e39 is inf in float32: fine, it is hostile data
        points = [np.array(v.split(), dtype=np.float64).astype("<f4") for v in lines[:4] if _numbers(v, 3)]
    body = b"".join(p.tobytes() for p in points)
    body += b"\x03" + struct.pack("<3i", 0, 1, 2) + b"\x04" + struct.pack("<4i", 0, 1, 2, 3)
    cut = draw(st.integers(-len(body), 16))
    return head + (body[:cut] if cut < 0 else body + draw(st.binary(max_size=cut)))


def _numbers(line, count):
    """Whether ``line`` is ``count`` numbers."""
    try:
        return len([float(word) for word in line.split()]) == count
    except ValueError:
        return False


def assert_mesh_or_one_line(path):
    """load_mesh gives a valid triangle mesh or a one-line MeshFileError naming the file."""
    try:
        vertices, faces = load_mesh(path)
    except MeshFileError as e:
        assert str(e).startswith(f"{path}: ") and "\n" not in str(e), str(e)
        return False
    assert vertices.dtype == np.float64 and vertices.ndim == 2 and vertices.shape[1] == 3
    assert np.isfinite(vertices).all()
    assert faces.dtype == np.int32 and faces.ndim == 2 and faces.shape[1] == 3 and len(faces) > 0
    assert faces.min() >= 0 and faces.max() < len(vertices)
    return True


FUZZ = settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
FUZZ_CLI = settings(
    max_examples=100,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)


@FUZZ
@given(data=ply_files())
def test_fuzz_ply_headers_and_bodies(data):
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "fuzz.ply"
        path.write_bytes(data)
        assert_mesh_or_one_line(path)


@FUZZ_CLI
@given(data=ply_files())
def test_fuzz_ply_through_the_cli(capsys, data):
    with tempfile.TemporaryDirectory() as folder:
        (Path(folder) / "fuzz.ply").write_bytes(data)
        scene = Path(folder) / "scene.toml"
        scene.write_text(
            '[camera]\norigin = [0, 0, 5]\nlook_at = [0, 0, 0]\n\n[[shape]]\ntype = "mesh"\nfile = "fuzz.ply"\n'
        )
        code, lines = render(capsys, scene)  # capsys: readouterr() empties it for the next example
        if code == 2:
            assert "fuzz.ply" in lines[0]


XML_TEMPLATE = """\
<scene version="3.0.0">
    <default name="spp" value="{0}"/>
    <integrator type="path"><integer name="max_depth" value="{1}"/></integrator>
    <sensor type="{2}">
        <float name="fov" value="{3}"/>
        <float name="aperture_radius" value="{4}"/>
        <transform name="to_world">
            <lookat origin="{5}" target="{6}" up="{7}"/>
        </transform>
        <sampler type="independent"><integer name="sample_count" value="$spp"/></sampler>
        <film type="hdrfilm"><integer name="width" value="{8}"/><integer name="height" value="{9}"/></film>
    </sensor>
    <bsdf type="twosided" id="white"><bsdf type="diffuse"><rgb name="reflectance" value="{10}"/></bsdf></bsdf>
    <bsdf type="dielectric" id="glass"><float name="int_ior" value="{11}"/></bsdf>
    <shape type="sphere">
        <float name="radius" value="{12}"/>
        <point name="center" x="{13}" y="{14}" z="{15}"/>
        <ref id="glass"/>
    </shape>
    <shape type="rectangle">
        <transform name="to_world">
            <scale value="{16}"/><rotate x="{17}" y="{18}" angle="{19}"/><translate value="{20}"/>
            <matrix value="{21}"/>
        </transform>
        <ref id="white"/>
        <emitter type="area"><rgb name="radiance" value="{22}"/></emitter>
    </shape>
    <emitter type="spot">
        <float name="cutoff_angle" value="{23}"/>
        <rgb name="intensity" value="{24}"/>
        <transform name="to_world"><translate x="{25}" y="{26}" z="{27}"/></transform>
    </emitter>
</scene>
"""
GOOD_VALUES = [
    "2", "3", "perspective", "40", "0.1", "0, 0, 5", "0, 0, 0", "0, 1, 0", "8", "6", "0.5", "1.5", "1",
    "0", "0", "0", "1", "1", "0", "30", "0 -1 0", "1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1", "2 2 2", "20", "5",
    "0", "3", "0",
]  # fmt: skip
ODD_NUMBERS = [
    "nan", "NaN", "inf", "-inf", "Infinity", "0", "-0", "-1", "-1e-300", "1e-320", "1e308", "-1e308", "1e400",
    "99999999999999999999", "", " ", "garbage", "1_0", "0x10", "1,", ",", "1 2", "1 2 3 4", "$spp", "$nothing",
    "180", "90", "360", "1e20", "thinlens", "orthographic",
]  # fmt: skip


@st.composite
def mitsuba_files(draw):
    """The template scene with some numeric attributes mutated, and optionally one element wrapped
    in nested elements or given a reference to another element's id."""
    values = list(GOOD_VALUES)
    for i in draw(st.sets(st.sampled_from(range(len(values))), max_size=3)):
        values[i] = draw(st.sampled_from(ODD_NUMBERS) | st.floats().map(repr) | st.integers().map(str))
    text = XML_TEMPLATE.format(*values)
    lines = text.splitlines()
    if draw(st.booleans()):
        i = draw(st.integers(1, len(lines) - 2))
        tag = draw(st.sampled_from(["shape", "transform", "bsdf", "ref", "scene"]))
        depth = draw(st.sampled_from([1, 2, 50, 200, 5000]))
        opening = f'<{tag} type="sphere">' if tag != "ref" else '<ref id="white"/>'
        closing = f"</{tag}>" if tag != "ref" else ""
        outermost = opening.replace(">", ' id="n">', 1) if tag != "ref" else opening
        lines[i] = outermost + opening * (depth - 1) + lines[i] + closing * depth
    if draw(st.booleans()):
        i = draw(st.integers(1, len(lines) - 2))
        lines.insert(i, f'<ref id="{draw(st.sampled_from(["white", "glass", "n", "nowhere"]))}"/>')
    return "\n".join(lines) + "\n"


@FUZZ
@given(text=mitsuba_files())
def test_fuzz_mitsuba_numbers_and_nesting(text):
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "fuzz.xml"
        path.write_text(text)
        try:
            load_scene(path)
        except WrtError as e:
            assert str(path) in str(e) and "\n" not in str(e), str(e)


@FUZZ_CLI
@given(text=mitsuba_files())
def test_fuzz_mitsuba_through_the_cli(capsys, text):
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "fuzz.xml"
        path.write_text(text)
        code, lines = render(capsys, path)
        if code == 2:
            assert str(path) in lines[0]


def test_a_mesh_name_too_long_for_the_file_system_is_one_line(tmp_path, capsys):
    """Found by the loader fuzz test: a `file` of 3000 characters raised OSError (File name too
    long) from the path check."""
    scene = tmp_path / "s.toml"
    scene.write_text(
        '[camera]\norigin = [0, 0, 5]\nlook_at = [0, 0, 0]\n\n[[shape]]\ntype = "mesh"\nfile = "'
        + "[" * 3000
        + '.obj"\n'
    )
    assert main(["render", str(scene), "-o", str(tmp_path / "o.png")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cannot be opened" in err
