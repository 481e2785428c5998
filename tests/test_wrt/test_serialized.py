"""Mitsuba's ``.serialized`` meshes (``wrt.serialized``): files written here in both versions,
several meshes a file, single and double precision, read back exactly and as Mitsuba 3 reads
them; the scene key ``shape_index`` and the importer's ``serialized`` shape; malformed files,
each one line naming the file and exit code 2."""

import struct
import zlib

import numpy as np
import pytest
from test_mitsuba_xml import convert

import wrt
from wrt.cli import main
from wrt.errors import MeshFileError, SceneError
from wrt.meshio import load_mesh

TETRA = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float64)
TETRA_FACES = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
QUAD = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], dtype=np.float64)
QUAD_FACES = np.array([[0, 1, 2], [0, 2, 3]])
QUAD_UV = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
QUAD_NORMALS = np.tile([0.0, 0.0, 1.0], (4, 1))


def mesh_stream(vertices, faces, normals=None, uvs=None, version=4, double=False, name="mesh", colours=False):
    """One mesh of a .serialized file: its header and its zlib stream."""
    real = "<f8" if double else "<f4"
    flags = (0x2000 if double else 0x1000) | (0x1 if normals is not None else 0) | (0x2 if uvs is not None else 0)
    flags |= 0x8 if colours else 0
    body = struct.pack("<I", flags) + (name.encode() + b"\0" if version == 4 else b"")
    body += struct.pack("<QQ", len(vertices), len(faces)) + np.asarray(vertices, real).tobytes()
    for array in (normals, uvs, np.full((len(vertices), 3), 0.5) if colours else None):
        if array is not None:
            body += np.asarray(array, real).tobytes()
    body += np.asarray(faces, "<u4").tobytes()
    return struct.pack("<HH", 0x041C, version) + zlib.compress(body)


def serialized_file(path, meshes, version=4):
    """A .serialized file of ``meshes`` (each the ``mesh_stream`` keywords), with its table."""
    streams = [mesh_stream(**m, version=version) for m in meshes]
    offsets = np.cumsum([0] + [len(s) for s in streams[:-1]])
    table = b"".join(struct.pack("<Q" if version == 4 else "<I", int(o)) for o in offsets)
    path.write_bytes(b"".join(streams) + table + struct.pack("<I", len(streams)))
    return path


MESHES = [
    {"vertices": TETRA, "faces": TETRA_FACES},
    {"vertices": QUAD, "faces": QUAD_FACES, "normals": QUAD_NORMALS, "uvs": QUAD_UV, "colours": True},
    {"vertices": QUAD * 2.0, "faces": QUAD_FACES, "uvs": QUAD_UV, "double": True},
]


@pytest.mark.parametrize("version", [3, 4])
def test_every_mesh_of_a_file_reads_back_exactly(tmp_path, version):
    path = serialized_file(tmp_path / "meshes.serialized", MESHES, version)
    for index, m in enumerate(MESHES):
        vertices, faces, normals, uvs = load_mesh(path, return_normals=True, return_uvs=True, shape_index=index)
        np.testing.assert_array_equal(vertices, m["vertices"])
        np.testing.assert_array_equal(faces, m["faces"])
        for got, want in ((normals, m.get("normals")), (uvs, m.get("uvs"))):
            assert (got is None) == (want is None) and (got is None or np.array_equal(got, want))


def test_mitsuba_reads_the_same_mesh(tmp_path):
    mi = pytest.importorskip("mitsuba")
    mi.set_variant("scalar_rgb")
    path = serialized_file(tmp_path / "meshes.serialized", MESHES)
    for index, m in enumerate(MESHES):
        theirs = mi.load_dict({"type": "serialized", "filename": str(path), "shape_index": index})
        positions = np.array(theirs.vertex_positions_buffer()).reshape(-1, 3)
        np.testing.assert_allclose(positions, m["vertices"], atol=1e-7)
        np.testing.assert_array_equal(np.array(theirs.faces_buffer()).reshape(-1, 3), m["faces"])
        if "uvs" in m:
            np.testing.assert_allclose(np.array(theirs.vertex_texcoords_buffer()).reshape(-1, 2), m["uvs"])


def test_a_scene_places_mesh_shape_index(tmp_path):
    serialized_file(tmp_path / "meshes.serialized", MESHES)
    doc = {
        "camera": {"origin": [0, 0, 5], "look_at": [0, 0, 0]},
        "shape": [{"type": "mesh", "file": "meshes.serialized", "shape_index": 2, "transform": {"scale": 0.5}}],
    }
    scene = wrt.parse_scene(doc, file="scene.toml", scene_dir=str(tmp_path))
    np.testing.assert_allclose(scene.shapes[0].vertices, QUAD)  # mesh 2 is the quad doubled, halved again
    doc["shape"][0]["file"] = "other.obj"
    with pytest.raises(SceneError, match=r"shape\[0\]\.shape_index = 2: applies to a \.serialized file only"):
        wrt.parse_scene(doc, file="scene.toml", scene_dir=str(tmp_path))


def test_the_importer_converts_a_serialized_shape(tmp_path):
    serialized_file(tmp_path / "meshes.serialized", MESHES)
    doc, warnings = convert(
        tmp_path,
        '<shape type="serialized"><string name="filename" value="meshes.serialized"/>'
        '<integer name="shape_index" value="1"/><boolean name="face_normals" value="true"/></shape>',
        approximate=False,
    )
    assert warnings == [] and doc["shape"][0]["shape_index"] == 1 and "shading" not in doc["shape"][0]
    scene = wrt.parse_scene(doc, scene_dir=str(tmp_path))
    np.testing.assert_array_equal(scene.shapes[0].vertices, QUAD)


def corrupt(data: bytes, kind: str) -> bytes:
    if kind == "magic":
        return b"\x1d\x04" + data[2:]
    if kind == "version":
        return data[:2] + struct.pack("<H", 5) + data[4:]
    if kind == "zlib":
        return data[:4] + b"\x00" * 40 + data[44:]
    if kind == "truncated":  # the stream of a mesh cut short: its triangles are not all there
        body = zlib.decompress(mesh_stream(TETRA, TETRA_FACES)[4:])[:-6]
        return struct.pack("<HH", 0x041C, 4) + zlib.compress(body) + struct.pack("<QI", 0, 1)
    if kind == "index":
        return mesh_stream(TETRA, TETRA_FACES + np.array([0, 0, 7])) + struct.pack("<QI", 0, 1)
    if kind == "nan":
        return mesh_stream(np.where(TETRA == 1, np.nan, TETRA), TETRA_FACES) + struct.pack("<QI", 0, 1)
    return data[:3]


@pytest.mark.parametrize(
    "kind, shape_index, message",
    [
        ("magic", 0, r"not a \.serialized mesh file \(its header is 0x041d"),
        ("version", 0, r"\.serialized version 5 is not supported"),
        ("zlib", 0, r"mesh 0: its compressed data is corrupt"),
        ("truncated", 0, r"mesh 0: truncated: its triangles need 48 bytes, 42 are left"),
        ("index", 0, r"mesh 0: 4 of 12 face vertex indices are out of range for 4 vertices"),
        ("nan", 0, r"mesh 0: 3 of 4 vertices are NaN or infinite"),
        ("short", 0, r"3 bytes: too short for a \.serialized mesh file"),
        (None, 3, r"shape_index 3 is out of range: the file holds 3 meshes"),
    ],
)
def test_a_malformed_file_is_one_line_and_exit_code_2(tmp_path, capsys, kind, shape_index, message):
    path = serialized_file(tmp_path / "meshes.serialized", MESHES)
    if kind is not None:
        path.write_bytes(corrupt(path.read_bytes(), kind))
    with pytest.raises(MeshFileError, match=message):
        load_mesh(path, shape_index=shape_index)
    scene = tmp_path / "scene.toml"
    scene.write_text(
        '[camera]\norigin = [0, 0, 5]\nlook_at = [0, 0, 0]\n\n[[shape]]\ntype = "mesh"\n'
        f'file = "meshes.serialized"\nshape_index = {shape_index}\n'
    )
    out = tmp_path / "out.png"
    assert main(["render", str(scene), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "meshes.serialized" in err and "shape[0]" in err, err
    assert not out.exists()
