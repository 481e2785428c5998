"""Tests for wrt.meshio: loading the bundled meshes, PLY parsing, transforms, file errors."""

import re
from pathlib import Path

import numpy as np
import pytest
import pyvista as pv
from conftest import EXAMPLES
from wrt_harness.mitsuba_peer import mitsuba_available

from wrt.errors import MeshFileError
from wrt.meshio import apply_transform, load_mesh, transform_matrix, transform_normals, vertex_normals

MESHES = EXAMPLES / "meshes"
AVAILABLE, REASON = mitsuba_available()
KNOT = MESHES / "torus_knot.ply"


def signed_volume(vertices, faces):
    """Volume enclosed by a closed triangle mesh, positive when the faces wind outward."""
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    return np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0


def is_closed_and_consistently_wound(faces):
    """True if every directed edge occurs exactly once and its reverse occurs exactly once."""
    edges = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2).astype(np.int64)
    n = int(faces.max()) + 1
    forward, backward = np.sort(edges[:, 0] * n + edges[:, 1]), np.sort(edges[:, 1] * n + edges[:, 0])
    return np.all(forward[1:] != forward[:-1]) and np.array_equal(forward, backward)


def triangle_areas(vertices, faces):
    """Area of each triangle."""
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)


# --- bundled meshes ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("name", "min_faces", "max_faces", "volume"),
    [("tetra.obj", 4, 4, 1.0 / 3.0), ("cube.stl", 12, 12, 1.0), ("torus_knot.ply", 100_000, 150_000, None)],
)
def test_bundled_mesh_counts_and_closure(name, min_faces, max_faces, volume):
    vertices, faces = load_mesh(MESHES / name)
    assert vertices.dtype == np.float64 and vertices.ndim == 2 and vertices.shape[1] == 3
    assert faces.dtype == np.int32 and faces.ndim == 2 and faces.shape[1] == 3
    assert min_faces <= len(faces) <= max_faces
    assert faces.min() >= 0 and faces.max() < len(vertices)
    assert is_closed_and_consistently_wound(faces)
    assert signed_volume(vertices, faces) > 0  # outward winding
    if volume is not None:
        assert signed_volume(vertices, faces) == pytest.approx(volume, rel=1e-12)


@pytest.mark.parametrize("name", ["tetra.obj", "cube.stl"])
def test_bundled_polyhedra_fill_the_half_unit_box(name):
    vertices, _ = load_mesh(MESHES / name)
    np.testing.assert_array_equal(vertices.min(axis=0), [-0.5, -0.5, -0.5])
    np.testing.assert_array_equal(vertices.max(axis=0), [0.5, 0.5, 0.5])


def test_knot_is_centred_with_unit_largest_extent():
    vertices, _ = load_mesh(KNOT)
    low, high = vertices.min(axis=0), vertices.max(axis=0)
    np.testing.assert_allclose((low + high) / 2, 0.0, atol=1e-6)
    assert (high - low).max() == pytest.approx(1.0, abs=1e-6)
    assert (high - low).min() > 0.2  # a tube, not a flat curve


# --- PLY parsing ------------------------------------------------------------------------------


def mixed_polygon_mesh():
    """Quads, triangles and 7-gons in one PolyData, with no point or cell arrays."""
    mesh = pv.Plane(i_resolution=6, j_resolution=4).merge(pv.Sphere(theta_resolution=8, phi_resolution=6))
    mesh = mesh.merge(pv.Cylinder(resolution=7, capping=True), merge_points=False)
    mesh.clear_data()
    return mesh


@pytest.mark.parametrize("binary", [True, False])
def test_ply_with_mixed_polygons_matches_vtk(tmp_path, binary):
    path = tmp_path / "mixed.ply"
    mixed_polygon_mesh().save(path, binary=binary, recompute_normals=False)
    vertices, faces = load_mesh(path)
    reference = pv.read(path).triangulate()
    np.testing.assert_array_equal(vertices, reference.points)
    np.testing.assert_array_equal(faces, reference.regular_faces)


def test_knot_ply_matches_vtk():
    vertices, faces = load_mesh(KNOT)
    reference = pv.read(KNOT)
    np.testing.assert_array_equal(vertices, reference.points)
    np.testing.assert_array_equal(faces, reference.regular_faces)


def test_big_endian_ply_with_extra_properties(tmp_path):
    header = (
        "ply\nformat binary_big_endian 1.0\ncomment two triangles\n"
        "element vertex 4\nproperty double x\nproperty double y\nproperty double z\nproperty uchar red\n"
        "element face 2\nproperty uchar flags\nproperty list uchar uint vertex_indices\n"
        "element edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n"
    )
    points = np.array([[0, 0, 0], [2, 0, 0], [2, 1, 0], [0, 1, 0]], dtype=np.float64)
    vertex_rows = np.zeros(4, dtype=[("xyz", ">f8", 3), ("red", "u1")])
    vertex_rows["xyz"] = points
    face_rows = np.zeros(2, dtype=[("flags", "u1"), ("n", "u1"), ("ids", ">u4", 3)])
    face_rows["n"], face_rows["ids"] = 3, [[0, 1, 2], [0, 2, 3]]
    body = vertex_rows.tobytes() + face_rows.tobytes() + np.array([0, 1], ">i4").tobytes()
    path = tmp_path / "big.ply"
    path.write_bytes(header.encode() + body)
    vertices, faces = load_mesh(path)
    np.testing.assert_array_equal(vertices, points)
    np.testing.assert_array_equal(faces, [[0, 1, 2], [0, 2, 3]])


def test_degenerate_triangles_are_kept(tmp_path):
    path = tmp_path / "degenerate.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\nf 1 2 4\nf 2 2 3\n")
    _, faces = load_mesh(path)
    np.testing.assert_array_equal(faces, [[0, 1, 2], [0, 1, 3], [1, 1, 2]])


def test_obj_quads_are_triangulated(tmp_path):
    path = tmp_path / "quads.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nv 1 1 0\nv 2 1 0\nf 1 2 5 4\nf 2 3 6 5\n")
    vertices, faces = load_mesh(path)
    assert faces.shape == (4, 3)
    np.testing.assert_allclose(triangle_areas(vertices, faces), 0.5)
    normals = np.cross(vertices[faces[:, 1]] - vertices[faces[:, 0]], vertices[faces[:, 2]] - vertices[faces[:, 0]])
    np.testing.assert_allclose(normals, [[0.0, 0.0, 1.0]] * 4)  # winding of the quads is kept


# --- transforms -------------------------------------------------------------------------------


def test_rotate_z_90_takes_x_to_y():
    np.testing.assert_allclose(apply_transform([[1.0, 0.0, 0.0]], rotate=(0, 0, 90)), [[0, 1, 0]], atol=1e-15)


def test_rotate_x_90_takes_y_to_z():
    np.testing.assert_allclose(apply_transform([[0.0, 1.0, 0.0]], rotate=(90, 0, 0)), [[0, 0, 1]], atol=1e-15)


def test_rotate_y_90_takes_z_to_x():
    np.testing.assert_allclose(apply_transform([[0.0, 0.0, 1.0]], rotate=(0, 90, 0)), [[1, 0, 0]], atol=1e-15)


def test_order_is_scale_then_rotate_then_translate():
    # S = diag(2, 3, 4): (1, 1, 1) -> (2, 3, 4).
    # Rx(90): (x, y, z) -> (x, -z, y): (2, -4, 3).  Rz(90): (x, y, z) -> (-y, x, z): (4, 2, 3).
    # T = (10, 20, 30): (14, 22, 33).
    moved = apply_transform([[1.0, 1.0, 1.0]], translate=(10, 20, 30), scale=(2, 3, 4), rotate=(90, 0, 90))
    np.testing.assert_allclose(moved, [[14.0, 22.0, 33.0]], atol=1e-12)


def test_rotations_apply_x_before_z():
    # Rz(90) Rx(90) y = Rz(90) z = z, whereas Rx(90) Rz(90) y = Rx(90) (-x) = -x.
    np.testing.assert_allclose(apply_transform([[0.0, 1.0, 0.0]], rotate=(90, 0, 90)), [[0, 0, 1]], atol=1e-15)


def test_uniform_and_per_axis_scale():
    points = np.array([[1.0, -2.0, 3.0], [0.5, 0.25, -4.0]])
    np.testing.assert_allclose(apply_transform(points, scale=2.5), 2.5 * points)
    np.testing.assert_allclose(apply_transform(points, scale=(2, -1, 0.5)), points * [2, -1, 0.5])


def test_matrix_agrees_with_apply_transform_in_homogeneous_coordinates():
    points = np.random.default_rng(7).normal(size=(5, 3))
    args = {"translate": (0.3, -1.0, 2.0), "scale": (1.5, 0.5, 2.0), "rotate": (30.0, -45.0, 120.0)}
    matrix = transform_matrix(**args)
    assert matrix.shape == (4, 4) and matrix.dtype == np.float64
    np.testing.assert_array_equal(matrix[3], [0, 0, 0, 1])
    homogeneous = np.column_stack([points, np.ones(5)]) @ matrix.T
    np.testing.assert_allclose(apply_transform(points, **args), homogeneous[:, :3], rtol=1e-14, atol=1e-14)
    rotation = transform_matrix(rotate=args["rotate"])[:3, :3]
    np.testing.assert_allclose(rotation @ rotation.T, np.eye(3), atol=1e-15)
    assert np.linalg.det(rotation) == pytest.approx(1.0)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"translate": (1, 2)}, "translate"),
        ({"rotate": (0, 0, float("nan"))}, "rotate"),
        ({"scale": (1, 2)}, "scale"),
        ({"scale": "big"}, "scale"),
    ],
)
def test_bad_transform_arguments_raise_naming_the_argument(kwargs, name):
    with pytest.raises(ValueError, match=name):
        transform_matrix(**kwargs)


def test_apply_transform_rejects_wrong_vertex_shape():
    with pytest.raises(ValueError, match="vertices"):
        apply_transform(np.zeros((4, 2)))


# --- file errors ------------------------------------------------------------------------------


def assert_mesh_error(path, problem):
    """load_mesh(path) raises a one-line MeshFileError naming the file and the problem."""
    with pytest.raises(MeshFileError) as caught:
        load_mesh(path)
    message = str(caught.value)
    assert Path(path).name in message and "\n" not in message
    assert problem in message


def test_missing_file(tmp_path):
    assert_mesh_error(tmp_path / "nowhere.ply", "no such mesh file")


def test_directory(tmp_path):
    folder = tmp_path / "meshes.obj"
    folder.mkdir()
    assert_mesh_error(folder, "is a directory")


def test_unsupported_extension_lists_formats(tmp_path):
    path = tmp_path / "points.xyz"
    path.write_text("0 0 0\n")
    assert_mesh_error(path, "unsupported mesh format '.xyz' (supported: .ply, .obj, .stl")


@pytest.mark.parametrize("suffix", [".ply", ".obj", ".stl"])
def test_empty_file(tmp_path, suffix):
    path = tmp_path / f"empty{suffix}"
    path.write_bytes(b"")
    assert_mesh_error(path, "")


@pytest.mark.parametrize("suffix", [".ply", ".stl", ".vtp"])
def test_garbage_bytes(tmp_path, suffix):
    path = tmp_path / f"garbage{suffix}"
    path.write_bytes(np.random.default_rng(0).bytes(3000))
    assert_mesh_error(path, "not a readable mesh")


@pytest.mark.parametrize("size", [1000, -7])
def test_truncated_binary_ply(tmp_path, size):
    # VTK's own PLY reader dies with SIGSEGV on both of these.
    path = tmp_path / "knot_truncated.ply"
    path.write_bytes(KNOT.read_bytes()[:size])
    assert_mesh_error(path, "truncated")


def test_truncated_ascii_ply(tmp_path):
    path = tmp_path / "ascii_truncated.ply"
    mixed_polygon_mesh().save(path, binary=False, recompute_normals=False)
    path.write_bytes(path.read_bytes()[:-40])
    assert_mesh_error(path, "truncated")


@pytest.mark.parametrize(
    ("name", "text", "problem"),
    [
        (
            "bad_index.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n",
            "1 of 3 face vertex indices are out of range for 3 vertices",
        ),
        ("nan_vertex.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n", "1 of 3 vertices are NaN or infinite"),
        ("no_faces.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n", "contains no faces"),
        (
            "bad_index.ply",
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
            "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 "
            "100000000\n",
            "1 of 3 face vertex indices are out of range for 3 vertices",
        ),
        (
            "inf_vertex.ply",
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
            "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 -inf 0\n0 1 0\n3 0 1 2\n",
            "1 of 3 vertices are NaN or infinite",
        ),
    ],
)
def test_invalid_mesh_contents(tmp_path, name, text, problem):
    path = tmp_path / name
    path.write_text(text)
    assert_mesh_error(path, problem)


def test_vtk_errors_are_not_printed(tmp_path, capfd):
    path = tmp_path / "garbage.stl"
    path.write_bytes(bytes(range(256)) * 4)
    with pytest.raises(MeshFileError):
        load_mesh(path)
    out, err = capfd.readouterr()
    assert out == "" and err == ""


# --- vertex normals ------------------------------------------------------------------------------

OBJ_CASES = {  # OBJ text: (vertices as Mitsuba 3 numbers them, their normals or None, triangles)
    "v/vt/vn": (
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nvn 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
        "f 1/1/1 2/2/1 3/3/2\nf 1/1/1 3/3/2 4/4/1\n",
        [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]],
        [[0, 0, 1], [0, 0, 1], [0, 1, 0], [0, 0, 1]],
        [[0, 1, 2], [0, 2, 3]],
    ),
    "v//vn, a position with two normals": (
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nvn 0 1 0\nf 1//1 2//1 3//2\nf 1//2 3//2 4//1\n",
        [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 0, 0], [0, 1, 0]],
        [[0, 0, 1], [0, 0, 1], [0, 1, 0], [0, 1, 0], [0, 0, 1]],
        [[0, 1, 2], [3, 2, 4]],
    ),
    "v/vt, a corner split by its texture coordinate": (
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 0.5 0.5\n"
        "f 1/1 2/2 3/3\nf 1/5 3/3 4/4\n",
        [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 0, 0], [0, 1, 0]],
        None,
        [[0, 1, 2], [3, 2, 4]],
    ),
    "a pentagon: a fan from its first corner": (
        "v 0 0 0\nv 1 0 0\nv 2 1 0\nv 1 2 0\nv 0 1 0\nf 1 2 3 4 5\n",
        [[0, 0, 0], [1, 0, 0], [2, 1, 0], [1, 2, 0], [0, 1, 0]],
        None,
        [[0, 1, 2], [0, 2, 3], [0, 3, 4]],
    ),
}


@pytest.mark.parametrize("case", list(OBJ_CASES))
def test_obj_vertices_are_its_distinct_index_triples(tmp_path, case):
    """Read for its normals, an OBJ file's vertices are its distinct v/vt/vn triples in order of
    first use and its polygons fans, as Mitsuba 3 loads it (VTK splits every corner)."""
    text, vertices, normals, faces = OBJ_CASES[case]
    path = tmp_path / "m.obj"
    path.write_text(text)
    got = load_mesh(path, return_normals=True)
    np.testing.assert_array_equal(got[0], vertices)
    assert (got[2] is None) == (normals is None)
    if normals is not None:
        np.testing.assert_array_equal(got[2], normals)
    np.testing.assert_array_equal(got[1], faces)
    if AVAILABLE:
        import mitsuba as mi

        mi.set_variant("scalar_rgb")
        params = mi.traverse(mi.load_dict({"type": "obj", "filename": str(path)}))
        np.testing.assert_array_equal(np.array(params["faces"]).reshape(-1, 3), faces)
        np.testing.assert_array_equal(np.array(params["vertex_positions"]).reshape(-1, 3), vertices)


def test_obj_corner_without_a_normal_reads_zero(tmp_path):
    path = tmp_path / "some.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 2\nf 1//1 2 3//1\n")
    np.testing.assert_array_equal(load_mesh(path, return_normals=True)[2], [[0, 0, 2], [0, 0, 0], [0, 0, 2]])


@pytest.mark.parametrize(
    ("text", "problem"),
    [
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//2 3//1\n",
            "1 of 3 face normal indices are out of range for 1 normals (line 5 has 2)",
        ),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/4 2 3\n", "1 of 3 face texture coordinate indices are out of range"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -1\n", "1 of 3 face vertex indices are out of range for 3 vertices"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn nan 0 1\nf 1//1 2//1 3//1\n", "3 of 3 vertex normals are NaN or infinite"),
        ("v 0 0 0\nv 1 0\nv 0 1 0\nf 1 2 3\n", "line 2: 'v' takes 3 numbers, got 'v 1 0'"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2.5 3\n", "line 4: 'f' takes corners v, v/vt, v//vn or v/vt/vn"),
        ("v 0 0 0\nv 1 0 0\nf 1 2\n", "line 3: a face needs at least 3 vertices"),
        ("v 0 0 0\n", "contains no faces"),
    ],
)
def test_obj_read_for_its_normals_refuses_bad_lines(tmp_path, text, problem):
    path = tmp_path / "bad.obj"
    path.write_text(text)
    with pytest.raises(MeshFileError, match=re.escape(problem)):
        load_mesh(path, return_normals=True)


PLY_NORMALS = (
    "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
    "property double nx\nproperty double ny\nproperty double nz\nelement face {faces}\n"
    "property list uchar int vertex_indices\nend_header\n"
    "0 0 0 0 0 1\n1 0 0 0 0.6 0.8\n1 1 0 1 0 0\n0 1 0 0 0 2\n{body}"
)


@pytest.mark.parametrize("body", ["3 0 1 2\n3 0 2 3\n", "4 0 1 2 3\n"], ids=["triangles", "a quad (VTK)"])
def test_ply_vertex_normals_are_read_as_written(tmp_path, body):
    path = tmp_path / "n.ply"
    path.write_text(PLY_NORMALS.format(faces=body.count("\n"), body=body))
    vertices, faces, normals = load_mesh(path, return_normals=True)
    np.testing.assert_array_equal(normals, [[0, 0, 1], [0, 0.6, 0.8], [1, 0, 0], [0, 0, 2]])
    assert len(load_mesh(path)) == 2 and len(faces) == 2 and len(vertices) == 4
    assert load_mesh(MESHES / "tetra.obj", return_normals=True)[2] is None


def test_ply_with_only_some_normal_properties_is_refused(tmp_path):
    path = tmp_path / "half.ply"
    path.write_text(
        PLY_NORMALS.format(faces=1, body="3 0 1 2\n").replace("property double nz\n", "").replace(" 1\n1 0", "\n1 0")
    )
    assert_mesh_error(path, "element 'vertex' has nx, ny but not all of nx, ny and nz")


def test_vertex_normals_weigh_faces_by_their_angle():
    """At a cube's corner three faces meet at right angles, split into one or two triangles there:
    angle weights give the diagonal whatever the split (area or count weights would not)."""
    vertices, faces = load_mesh(MESHES / "cube.stl")
    normals = vertex_normals(vertices, faces)
    np.testing.assert_allclose(normals, np.sign(vertices) / np.sqrt(3), atol=1e-12)
    lone = vertex_normals(np.vstack([vertices, [9, 9, 9]]), faces)
    np.testing.assert_array_equal(lone[-1], [0, 0, 0])  # a vertex no face uses has none


@pytest.mark.skipif(not AVAILABLE, reason=REASON)
def test_vertex_normals_are_mitsubas():
    """The normals Mitsuba 3 computes for an OBJ without normals (``Mesh::recompute_vertex_normals``
    on the placed vertices: a shear changes the angles)."""
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    matrix = np.array([[1.2, 0.6, 0, -0.5], [0, 0.9, 0, 0], [0.3, 0, 0.8, 0.4], [0, 0, 0, 1]])
    path = MESHES / "coarse_sphere.obj"
    mesh = mi.load_dict({"type": "obj", "filename": str(path), "to_world": mi.ScalarTransform4f(matrix)})
    theirs = np.array(mi.traverse(mesh)["vertex_normals"]).reshape(-1, 3)
    vertices, faces, normals = load_mesh(path, return_normals=True)
    assert normals is None
    np.testing.assert_allclose(vertex_normals(apply_transform(vertices, matrix=matrix), faces), theirs, atol=1e-6)


def test_normals_transform_by_the_inverse_transpose():
    matrix = transform_matrix(scale=(2.0, 1.0, 1.0), rotate=(0, 0, 90))
    normals = transform_normals([[1.0, 1.0, 0.0], [0.0, 0.0, 0.0]], matrix)
    np.testing.assert_allclose(normals[0], [-2 / np.sqrt(5), 1 / np.sqrt(5), 0], atol=1e-15)
    np.testing.assert_array_equal(normals[1], 0.0)  # no normal stays none
