"""Triangle-mesh files: loading them as vertex and face arrays, and placing them in the world.

`load_mesh` turns a mesh file into ``(vertices, faces)`` arrays (and, asked for, the file's vertex
normals), raising `MeshFileError` with a one-line message for any file that cannot be used.
`transform_matrix` and `apply_transform` implement the scene format's object-to-world convention
(scale, then rotate, then translate); `transform_normals` takes vertex normals along, and
`vertex_normals` computes them where a file has none, as Mitsuba 3 does.

PLY files are parsed here with numpy rather than by VTK: VTK's ``vtkPLYReader`` (VTK 9.7)
crashes the process with a segmentation fault on a truncated binary PLY file or on a face
index far out of range, which no Python code can catch. A PLY file of triangles never touches
VTK (nor imports pyvista, which takes a fifth of a second): its arrays are checked and returned
as they are; polygons with more vertices are triangulated by VTK. The PLY header is checked as a
whole before the body is read, and the body must hold exactly what the header declares. Every other format is read by
pyvista's VTK readers, with their console output silenced and their errors collected, except an
OBJ file whose normals are asked for: VTK's OBJ reader splits every vertex per face corner as
soon as a face names a texture coordinate or a normal, returns unset memory for a normal index
out of range, and triangulates quads along the other diagonal than Mitsuba, so such a file is
read here (`_read_obj`), as Mitsuba 3's OBJ loader reads it.
"""

from __future__ import annotations

import os
import re
import stat
import struct
from dataclasses import dataclass
from pathlib import Path
from xml.parsers import expat

import numpy as np

from wrt.errors import MeshFileError, foreign, listed, shorten, token
from wrt.files import MAX_TEXT_BYTES, check_regular_file, read_bytes
from wrt.serialized import read_serialized

MESH_FORMATS = (".ply", ".obj", ".stl", ".serialized", ".vtk", ".vtp", ".vtu", ".vtm")
"""File extensions `load_mesh` reads (case-insensitive)."""
MAX_MESH_BYTES = 16 << 30
"""Largest mesh file read (16 GiB): a binary PLY of some 800 million triangles, more than a
device holds once wrt has built its BVH; a larger file is refused before it is read (a PLY or
OBJ file is read whole into memory)."""
MAX_VTM_DEPTH = 8
"""Deepest nesting of multiblock (``.vtm``) files read."""
_STL_HEADER, _STL_TRIANGLE = 84, 50  # a binary STL: 80-byte header and uint32 count, then 50 bytes a triangle


def load_mesh(path, *, return_normals=False, return_uvs=False, shape_index=0):
    """Read a triangle mesh from a file.

    Parameters
    ----------
    path : str or os.PathLike
        A mesh file whose extension is one of `MESH_FORMATS`: PLY (ASCII or binary), OBJ,
        STL (ASCII or binary), Mitsuba's ``.serialized`` (`wrt.serialized`), or a VTK dataset
        (``.vtk``, ``.vtp``, ``.vtu``, ``.vtm``).
    return_normals : bool, default False
        Also return the file's vertex normals.
    return_uvs : bool, default False
        Also return the file's vertex texture coordinates (after the normals, if asked for).
    shape_index : int, default 0
        Which mesh of a ``.serialized`` file (which may hold several) to read.

    Returns
    -------
    vertices : numpy.ndarray of float64, shape (V, 3)
        Vertex positions in the file's own units and frame (object space).
    faces : numpy.ndarray of int32, shape (F, 3)
        Vertex indices of each triangle, in the winding order the file gives.
    normals : numpy.ndarray of float64, shape (V, 3), or None
        Only with `return_normals`: the file's vertex normals as written (object space, not
        normalised; a zero row where an OBJ face corner names no normal), or None where the file
        has none: a PLY file without ``nx``, ``ny``, ``nz`` vertex properties, an OBJ file without
        ``vn`` lines, an STL file, a VTK dataset without point normals.
    uvs : numpy.ndarray of float64, shape (V, 2), or None
        Only with `return_uvs`: the file's texture coordinates (u, v) in Mitsuba 3's convention,
        where v = 0 is the top row of an image: a PLY file's ``u, v`` (or else ``texture_u,
        texture_v``, ``s, t``, ``texture_s, texture_t``) vertex properties as written, an OBJ file's ``vt``
        as ``(u, 1 - v)`` (OBJ's v = 0 is the bottom row; Mitsuba flips it so; (0, 0) where a face
        corner names none), a ``.serialized`` file's as written, a VTK dataset's active texture
        coordinates; None where the file has none (an STL file).

    Raises
    ------
    MeshFileError
        If the file is missing, a directory, not a regular file (a FIFO, a device), larger than
        `MAX_MESH_BYTES`, of an unsupported format, unreadable, corrupt or truncated (a binary STL
        whose size is not what its triangle count says; a multiblock file naming a file that is
        not a mesh file), has no faces, has NaN or infinite vertices, or has a face index outside
        ``0..V-1``; for PLY also a malformed header (a property declared twice, of an unknown
        type, a list ``x``, only some of ``nx``, ``ny``, ``nz``, ...), element counts that do not
        match the body, and faces of fewer than 3 vertices. With `return_normals`, also NaN or
        infinite normals, and for OBJ a line that is not what its keyword says, a face of fewer
        than 3 corners or a normal or texture coordinate index out of range. The message is one
        line naming `path` and the problem (for an ASCII PLY or OBJ file, the line), quoting
        at most ``wrt.errors.MAX_QUOTED`` characters of the file.

    Notes
    -----
    Polygons with more than three vertices are triangulated (by VTK; an OBJ file read with
    `return_normals` as a fan from each face's first corner, as Mitsuba 3 does). A volume dataset
    is reduced to its boundary surface first. Degenerate triangles (repeated or collinear
    vertices) are kept; vertices no face uses are kept too. With `return_normals`, an OBJ file's
    vertices are its distinct ``v/vt/vn`` index triples in order of first use, as Mitsuba 3's
    loader numbers them, so that normals computed over them (`vertex_normals`) are Mitsuba's.
    """
    path = Path(path)
    _check_mesh_path(path)
    suffix = path.suffix.lower()
    if suffix == ".serialized":
        mesh = read_serialized(path, shape_index, MAX_MESH_BYTES)
    elif suffix == ".ply":
        points, counts, indices, normals, uvs = _read_ply(path)
        _check_face_indices(counts, indices, len(points), path)  # before VTK, which can crash on them
        if len(counts) and np.all(counts == 3):
            mesh = _checked_triangles(points, indices.reshape(-1, 3), normals, uvs, path)
        else:
            mesh = _triangles(_polydata(points, counts, indices, normals, uvs), path)
    elif suffix == ".obj" and (return_normals or return_uvs):
        mesh = _read_obj(path)
    else:
        if suffix == ".stl":
            _check_stl(path)
        mesh = _triangles(_read_with_vtk(path), path)
    if return_normals and mesh[2] is not None:
        bad = np.count_nonzero(~np.all(np.isfinite(mesh[2]), axis=1))
        if bad:
            raise MeshFileError(f"{path}: {bad} of {len(mesh[2])} vertex normals are NaN or infinite")
    if return_uvs and mesh[3] is not None and not np.all(np.isfinite(mesh[3])):
        bad = np.count_nonzero(~np.all(np.isfinite(mesh[3]), axis=1))
        raise MeshFileError(f"{path}: {bad} of {len(mesh[3])} texture coordinates are NaN or infinite")
    return mesh[:2] + (mesh[2],) * return_normals + (mesh[3],) * return_uvs


def vertex_normals(vertices, faces):
    """Unit vertex normals of a triangle mesh, computed as Mitsuba 3 computes them for a mesh
    file without normals (``Mesh::recompute_vertex_normals``).

    Parameters
    ----------
    vertices : array_like, shape (V, 3)
        Vertex positions, in the frame the normals are wanted in (Mitsuba: world space, after
        ``to_world``; angles are not preserved by a non-uniform scale or a shear).
    faces : array_like of int, shape (F, 3)
        Vertex indices of each triangle; the winding gives each face's side.

    Returns
    -------
    numpy.ndarray of float64, shape (V, 3)
        Each vertex's normal: the sum over the triangles at it of the triangle's unit winding
        normal ``cross(v1 - v0, v2 - v0)`` times the triangle's angle at the vertex (radians),
        normalised. A vertex no non-degenerate triangle uses, or whose sum vanishes, gets the
        zero vector (Mitsuba gives it the arbitrary (1, 0, 0)).

    References
    ----------
    G. Thuermer, C. A. Wuethrich, "Computing Vertex Normals from Polygonal Facets", Journal of
    Graphics Tools 3(1), 1998.
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    corners = v[f]  # (F, 3 corners, 3)
    face_normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    length = np.linalg.norm(face_normal, axis=1, keepdims=True)
    face_normal = np.divide(face_normal, length, out=np.zeros_like(face_normal), where=length > 0.0)
    # the angle at each corner, between the edges to the next and the previous corner
    to_next = np.roll(corners, -1, axis=1) - corners
    to_prev = np.roll(corners, 1, axis=1) - corners
    angle = np.arctan2(np.linalg.norm(np.cross(to_next, to_prev), axis=2), np.einsum("fci,fci->fc", to_next, to_prev))
    weighted = (face_normal[:, None, :] * angle[:, :, None]).reshape(-1, 3)  # per corner, in f.ravel() order
    total = np.column_stack([np.bincount(f.ravel(), weighted[:, k], minlength=len(v)) for k in range(3)])
    length = np.linalg.norm(total, axis=1, keepdims=True)
    return np.divide(total, length, out=np.zeros_like(total), where=length > 0.0)


def transform_normals(normals, matrix):
    """Map object-space normals to world space by the inverse transpose of ``matrix``.

    Parameters
    ----------
    normals : array_like, shape (V, 3)
        Normals in object space, of any length.
    matrix : array_like, shape (4, 4)
        The object-to-world matrix (`transform_matrix`); its 3x3 part must be invertible.

    Returns
    -------
    numpy.ndarray of float64, shape (V, 3)
        ``M^-T n`` normalised to unit length; a zero normal stays zero.
    """
    n = np.asarray(normals, dtype=np.float64) @ np.linalg.inv(np.asarray(matrix, dtype=np.float64)[:3, :3])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, length, out=np.zeros_like(n), where=length > 0.0)


def transform_matrix(*, translate=(0.0, 0.0, 0.0), scale=(1.0, 1.0, 1.0), rotate=(0.0, 0.0, 0.0), matrix=None):
    """Build the object-to-world matrix of the scene format.

    Parameters
    ----------
    translate : sequence of 3 float, default (0, 0, 0)
        Translation T, in world units.
    scale : float or sequence of 3 float, default (1, 1, 1)
        Scale factors S along the object's X, Y and Z axes; one number scales uniformly.
    rotate : sequence of 3 float, default (0, 0, 0)
        Angles in degrees about the world X, then Y, then Z axis. Each rotation is
        right-handed: counter-clockwise when looking down the axis toward the origin.
    matrix : array_like, shape (4, 4) or (16,), optional
        Any invertible affine matrix A (row-major, as Mitsuba writes ``<matrix>``: the last
        row is 0 0 0 1), applied to the object before the others: shear and non-uniform scale
        included.

    Returns
    -------
    numpy.ndarray of float64, shape (4, 4)
        M = T Rz Ry Rx S A acting on column vectors ``(x, y, z, 1)``: a point p maps to
        ``p' = T + Rz Ry Rx (S (A p))``, i.e. the matrix first, then scale, rotate, translate.

    Raises
    ------
    ValueError
        If an argument has the wrong number of components or a non-finite component, or the
        matrix is not affine or not invertible.

    Notes
    -----
    With ``rotate=(0, 0, 90)`` the point (1, 0, 0) maps to (0, 1, 0); with ``rotate=(90, 0,
    0)`` the point (0, 1, 0) maps to (0, 0, 1). A negative scale factor mirrors the object,
    which reverses the winding of its triangles.
    """
    t = _vector3("translate", translate)
    s = _vector3("scale", scale if np.ndim(scale) else (scale,) * 3)
    rx, ry, rz = np.radians(_vector3("rotate", rotate))
    out = np.eye(4)
    out[:3, :3] = _rotation_z(rz) @ _rotation_y(ry) @ _rotation_x(rx) @ np.diag(s)
    out[:3, 3] = t
    return out if matrix is None else out @ _affine(matrix)


def _affine(matrix) -> np.ndarray:
    """``matrix`` (16 numbers, row-major, or 4 rows of 4) as an invertible affine 4x4 matrix, or
    a ValueError saying what is wrong."""
    shape = "matrix must be 16 numbers (row-major) or 4 rows of 4 numbers"
    rows = matrix if isinstance(matrix, (list, tuple, np.ndarray)) and len(matrix) == 4 else [matrix]
    entries = [x for row in rows if isinstance(row, (list, tuple, np.ndarray)) for x in row]
    if len(entries) != 16 or not all(
        isinstance(x, (int, float, np.number)) and not isinstance(x, bool) for x in entries
    ):
        raise ValueError(shape)
    a = np.asarray(entries, dtype=np.float64)
    a = a.reshape(4, 4)
    if not np.isfinite(a).all():
        raise ValueError("matrix must have finite entries")
    if not np.array_equal(a[3], [0.0, 0.0, 0.0, 1.0]):
        raise ValueError("matrix must be affine: its last row must be 0 0 0 1")
    linear = a[:3, :3]
    if not abs(np.linalg.det(linear)) > 1e-12 * max(np.abs(linear).max(), 1e-300) ** 3:
        raise ValueError("matrix must be invertible (its 3x3 part is singular)")
    return a


def apply_transform(vertices, *, translate=(0.0, 0.0, 0.0), scale=(1.0, 1.0, 1.0), rotate=(0.0, 0.0, 0.0), matrix=None):
    """Map object-space vertices to world space: ``p' = T + Rz Ry Rx (S (A p))``.

    Parameters
    ----------
    vertices : array_like, shape (V, 3)
        Points in object space.
    translate, scale, rotate, matrix
        As in `transform_matrix`: translation in world units, one or three scale factors,
        angles in degrees about world X, then Y, then Z (right-handed), and an affine matrix A.
        A is applied first, then the scale, the rotations and the translation.

    Returns
    -------
    numpy.ndarray of float64, shape (V, 3)
        The transformed points, in world space.

    Raises
    ------
    ValueError
        If `vertices` is not of shape (V, 3), or as `transform_matrix` raises.
    """
    points = np.asarray(vertices, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"vertices must have shape (V, 3), got {points.shape}")
    m = transform_matrix(translate=translate, scale=scale, rotate=rotate, matrix=matrix)
    return points @ m[:3, :3].T + m[:3, 3]


def _vector3(name, value):
    """Return `value` as 3 finite float64 numbers, or raise a ValueError naming `name`."""
    try:
        vector = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be 3 numbers, got {value!r}") from None
    if vector.shape != (3,) or not np.all(np.isfinite(vector)):
        raise ValueError(f"{name} must be 3 finite numbers, got {value!r}")
    return vector


def _rotation_x(angle):
    """Right-handed rotation by `angle` radians about the X axis."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _rotation_y(angle):
    """Right-handed rotation by `angle` radians about the Y axis."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rotation_z(angle):
    """Right-handed rotation by `angle` radians about the Z axis."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _check_mesh_path(path):
    """Raise MeshFileError unless `path` is an existing regular file (not a FIFO or a device,
    which would block or never end) of at most `MAX_MESH_BYTES` and of a supported format; for
    a multiblock file, the same of every file it names (`_check_vtm`)."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        raise MeshFileError(f"{path}: no such mesh file") from None
    except OSError as e:  # a name too long for the file system, say
        raise MeshFileError(f"{path}: cannot be opened: {e.strerror or e}") from None
    if stat.S_ISDIR(mode):
        raise MeshFileError(f"{path}: is a directory, not a mesh file")
    if path.suffix.lower() not in MESH_FORMATS:
        raise MeshFileError(
            f"{path}: unsupported mesh format {token(path.suffix or '(no extension)')}"
            f" (supported: {', '.join(MESH_FORMATS)})"
        )
    check_regular_file(path, "mesh", limit=MAX_MESH_BYTES, error=MeshFileError)
    if path.suffix.lower() == ".vtm":
        _check_vtm(path, 1)


def _check_vtm(path, depth):
    """Check, before VTK opens them, the files a multiblock (``.vtm``) file names: each
    ``file`` attribute, relative to the ``.vtm`` file's folder, must be a regular mesh file
    (`_check_mesh_path`; a ``.vtm`` in turn, at most ``MAX_VTM_DEPTH`` deep)."""
    if depth > MAX_VTM_DEPTH:
        raise MeshFileError(f"{path}: multiblock files nested more than {MAX_VTM_DEPTH} deep")
    data = read_bytes(path, "mesh", limit=MAX_TEXT_BYTES, error=MeshFileError)
    named = []
    parser = expat.ParserCreate()
    parser.StartElementHandler = lambda tag, attrs: named.append(attrs["file"]) if "file" in attrs else None
    try:
        parser.Parse(data, True)
    except expat.ExpatError as e:
        raise MeshFileError(f"{path}: not a readable mesh (line {e.lineno}: {expat.ErrorString(e.code)})") from None
    for name in dict.fromkeys(named):
        piece = path.parent / name
        try:
            if piece.suffix.lower() == ".vtm":
                check_regular_file(piece, "mesh", limit=MAX_MESH_BYTES, error=MeshFileError)
                _check_vtm(piece, depth + 1)
            else:
                _check_mesh_path(piece)
        except MeshFileError as e:
            raise MeshFileError(f"{path}: its block file {token(name)}: {str(e).removeprefix(f'{piece}: ')}") from None


def _check_stl(path):
    """Raise MeshFileError for a binary STL file (as VTK tells it from an ASCII one,
    `_binary_stl`) whose size is not what its triangle count says: 84 + 50 per triangle bytes
    (VTK reads what there is, whatever the count)."""
    size = os.stat(path).st_size
    with open(path, "rb") as f:  # a regular file (_check_mesh_path)
        head = f.read(256)
    if not _binary_stl(head):
        return
    if size < _STL_HEADER:
        raise MeshFileError(
            f"{path}: not a readable mesh: binary STL of {size} bytes, shorter than its {_STL_HEADER}-byte header"
        )
    (count,) = struct.unpack_from("<I", head, 80)
    if size != _STL_HEADER + _STL_TRIANGLE * count:
        raise MeshFileError(
            f"{path}: not a readable mesh: binary STL declares {count} triangle{'s' * (count != 1)} "
            f"({_STL_HEADER + _STL_TRIANGLE * count} bytes), "
            f"but the file has {size} bytes"
        )


def _binary_stl(head):
    """Whether VTK's STL reader reads a file starting with ``head`` (its first 256 bytes) as
    binary: when 5% or more of them are not text (kwsys ``DetectFileType``: text is 0x20 to
    0x7f, tab, line feed and carriage return)."""
    text = sum(1 for byte in head if 0x20 <= byte <= 0x7F or byte in b"\t\n\r")
    return bool(head) and (len(head) - text) / len(head) >= 0.05


def _read_with_vtk(path):
    """Read `path` with the VTK reader pyvista picks for its extension.

    The reader is updated directly, not through pyvista's ``read``, which on failure logs the
    VTK errors to the root logger and raises on some readers but not others. VTK's console
    output is silenced and its error messages are collected into a MeshFileError instead.
    """
    import pyvista as pv

    with pv.vtk_verbosity("off"), pv.VtkErrorCatcher(send_to_logging=False) as catcher:
        reader = pv.get_reader(str(path)).reader
        reader.Update()
    # Errors, and warnings that report a read error: VTK's legacy reader only warns ("Error reading
    # binary data!") on a file truncated in its attribute data, and returns what it read.
    failed = [e for e in catcher.events if e in catcher.error_events or "error" in e.alert.lower()]
    if failed:
        own = [e for e in failed if e.name == reader.GetClassName()]
        detail = foreign(_vtk_message((own or failed)[0].alert))
        raise MeshFileError(f"{path}: not a readable mesh ({detail})")
    dataset = pv.wrap(reader.GetOutputDataObject(0))
    if isinstance(dataset, pv.MultiBlock):
        return dataset.combine()
    return dataset


def _vtk_message(alert):
    """The informative line of a VTK alert, without object addresses or "In file.cxx, line N"."""
    lines = [line.strip() for line in alert.splitlines() if line.strip()]
    useful = [line for line in lines if not re.search(r"\.cxx, line \d+", line)] or lines
    return re.sub(r" \(0x[0-9a-fA-F]+\)", "", useful[0])


def _check_face_indices(counts, indices, n_points, path):
    """Raise MeshFileError, naming the first face at fault, unless every vertex index of the
    faces (``counts[i]`` indices each, listed in ``indices``) is in ``0..n_points-1``."""
    outside = np.flatnonzero((indices < 0) | (indices >= n_points))
    if outside.size:
        face = int(np.searchsorted(np.cumsum(counts), outside[0], side="right"))
        raise MeshFileError(
            f"{path}: {outside.size} of {indices.size} face vertex indices are out of range for {n_points} vertices"
            f" (face {face} has {indices[outside[0]]})"
        )


def _checked_triangles(points, faces, normals, uvs, path):
    """``(vertices, faces, normals, uvs)`` of a triangle mesh whose face indices are valid
    (`_check_face_indices`) if its vertices are finite, else MeshFileError (the check of
    ``_triangles``, without VTK)."""
    bad_points = np.count_nonzero(~np.all(np.isfinite(points), axis=1))
    if bad_points:
        raise MeshFileError(f"{path}: {bad_points} of {len(points)} vertices are NaN or infinite")
    return np.asarray(points, dtype=np.float64), faces.astype(np.int32), normals, uvs


def _triangles(dataset, path):
    """Validate a dataset read from `path` and return its surface as (vertices, faces, normals, uvs)
    arrays, ``normals`` its point normals and ``uvs`` its texture coordinates (None without)."""
    import pyvista as pv

    n_points = dataset.n_points
    point_ids = _cell_point_ids(dataset)
    outside = np.count_nonzero((point_ids < 0) | (point_ids >= n_points))
    if outside:
        raise MeshFileError(
            f"{path}: {outside} of {point_ids.size} face vertex indices are out of range for {n_points} vertices"
        )
    bad_points = np.count_nonzero(~np.all(np.isfinite(dataset.points), axis=1)) if n_points else 0
    if bad_points:
        raise MeshFileError(f"{path}: {bad_points} of {n_points} vertices are NaN or infinite")
    surface = dataset
    if not isinstance(surface, pv.PolyData):
        surface = surface.extract_surface(pass_pointid=False, pass_cellid=False, algorithm=None)
    if surface.GetPolys().IsHomogeneous() not in (0, 3) or surface.n_strips:
        surface = surface.triangulate()
    if surface.GetNumberOfPolys() == 0:
        raise MeshFileError(f"{path}: contains no faces (empty mesh)")
    vertices = np.array(surface.points, dtype=np.float64)
    faces = surface.faces.reshape(-1, 4)[:, 1:].astype(np.int32)
    normals = surface.point_data.active_normals
    uvs = surface.point_data.active_texture_coordinates
    return (
        vertices,
        faces,
        None if normals is None else np.array(normals, dtype=np.float64),
        None if uvs is None else np.array(uvs, dtype=np.float64),
    )


def _cell_point_ids(dataset):
    """All point indices the cells of `dataset` refer to (empty for implicitly connected grids)."""
    import pyvista as pv
    from vtkmodules.util.numpy_support import vtk_to_numpy

    if isinstance(dataset, pv.PolyData):
        cells = (dataset.GetVerts(), dataset.GetLines(), dataset.GetPolys(), dataset.GetStrips())
        return np.concatenate([vtk_to_numpy(c.GetConnectivityArray()) for c in cells])
    if isinstance(dataset, pv.UnstructuredGrid):
        return dataset.cell_connectivity
    return np.empty(0, dtype=np.int64)


# --- OBJ, read for its normals ------------------------------------------------------------------
#
# As Mitsuba 3's OBJ loader reads it (src/shapes/obj.cpp): `v`, `vt`, `vn` and `f` lines, other
# lines ignored; each distinct `v/vt/vn` index triple the faces use is one vertex, numbered in order
# of first use; a face of n corners c0..c(n-1) is the fan of triangles (c0, c(k-1), ck), k = 2..n-1.


def _read_obj(path):
    """``(vertices, faces, normals, uvs)`` of an OBJ file read Mitsuba's way (above): normals None
    without ``vn`` lines, else a zero row for a vertex whose index triple names no normal; uvs
    None without ``vt`` lines, else ``(u, 1 - v)`` ((0, 0) where the triple names none)."""
    data = read_bytes(path, "mesh", limit=MAX_MESH_BYTES, error=MeshFileError)
    positions, normals, texcoords = [], [], []
    corners, sizes, face_lines = [], [], []
    for number, line in enumerate(data.splitlines(), start=1):
        words = line.split()
        tag = words[0] if words else b""
        try:
            if tag in (b"v", b"vn"):
                (positions if tag == b"v" else normals).append([float(x) for x in words[1:4]])
                if len(words) < 4:
                    raise ValueError
            elif tag == b"vt":
                texcoords.append([float(x) for x in words[1:3]] + [0.0] * (3 - len(words)))
                if len(words) < 2:
                    raise ValueError
            elif tag == b"f":
                for word in words[1:]:
                    indices = [int(x) if x else 0 for x in word.split(b"/")]
                    if not 1 <= len(indices) <= 3:
                        raise ValueError
                    corners.append(indices + [0] * (3 - len(indices)))
                if len(words) < 4:
                    raise MeshFileError(f"{path}: line {number}: a face needs at least 3 vertices")
                sizes.append(len(words) - 1)
                face_lines.append(number)
        except ValueError:
            what = {b"f": "corners v, v/vt, v//vn or v/vt/vn (integers)", b"vt": "1 to 3 numbers"}.get(tag, "3 numbers")
            text = line.decode(errors="replace").strip()
            raise MeshFileError(f"{path}: line {number}: '{shorten(tag)}' takes {what}, got {token(text)}") from None
    if not sizes:
        raise MeshFileError(f"{path}: contains no faces (empty mesh)")
    try:
        keys = np.array(corners, dtype=np.int64)
    except OverflowError:
        raise MeshFileError(f"{path}: a face index is out of range (beyond 64-bit integers)") from None
    corner_lines = np.repeat(face_lines, sizes)
    for column, count, what, table in (
        (0, len(positions), "vertex", "vertices"),
        (1, len(texcoords), "texture coordinate", "texture coordinates"),
        (2, len(normals), "normal", "normals"),
    ):
        index = keys[:, column]  # 1-based; 0: none named (a vertex must be)
        outside = np.flatnonzero((index < (1 if column == 0 else 0)) | (index > count))
        if outside.size:
            raise MeshFileError(
                f"{path}: {outside.size} of {len(index)} face {what} indices are out of range for {count} {table}"
                f" (line {corner_lines[outside[0]]} has {index[outside[0]]})"
            )
    unique, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)  # the distinct triples in order of first use
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    vertex_of_corner, vertex_keys = rank[inverse.reshape(-1)], unique[order]
    sizes = np.asarray(sizes, dtype=np.int64)
    fans = sizes - 2
    fan_start = np.repeat(np.cumsum(sizes) - sizes, fans)
    k = np.arange(fans.sum()) - np.repeat(np.cumsum(fans) - fans, fans)
    faces = vertex_of_corner[np.stack([fan_start, fan_start + k + 1, fan_start + k + 2], axis=1)]
    points = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    bad_points = np.count_nonzero(~np.all(np.isfinite(points), axis=1))
    if bad_points:
        raise MeshFileError(f"{path}: {bad_points} of {len(points)} vertices are NaN or infinite")
    vertex_normals_read = None
    if normals:
        table = np.vstack([np.zeros((1, 3)), np.asarray(normals, dtype=np.float64)])  # index 0: none named
        vertex_normals_read = table[vertex_keys[:, 2]]
    uvs = None
    if texcoords:
        table = np.vstack([np.zeros((1, 2)), np.asarray(texcoords, dtype=np.float64)[:, :2]])
        uvs = table[vertex_keys[:, 1]] * [1.0, -1.0] + [0.0, 1.0]
        uvs[vertex_keys[:, 1] == 0] = 0.0
    return points[vertex_keys[:, 0] - 1], faces.astype(np.int32), vertex_normals_read, uvs


# --- PLY ------------------------------------------------------------------------------------
#
# A PLY file is read in three steps: the header is parsed and then checked as a whole, in one
# place (`_check_ply_header`), before a byte of the body is read; the body is read against the
# checked header (ASCII line by line, one element entry per line; binary entry by entry) and must
# end where the header says it does; the faces are then checked for size and index range.

_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}  # fmt: skip
_PLY_ENDIAN = {"binary_little_endian": "<", "binary_big_endian": ">"}
"""Byte order of each binary PLY encoding."""
_PLY_ENCODINGS = ("ascii", *_PLY_ENDIAN)
_PLY_FACE_LISTS = ("vertex_indices", "vertex_index")
_PLY_NORMALS = ("nx", "ny", "nz")
_PLY_UVS = (("u", "v"), ("texture_u", "texture_v"), ("s", "t"), ("texture_s", "texture_t"))
"""Vertex property pairs a PLY file's texture coordinates are read from (the first present): Mitsuba 3.9.1's
three in its order, then ``texture_s, texture_t``, which Mitsuba does not read."""
_PLY_MAX_LIST = 2**31
"""Lists are at most this long (a longer one is a corrupt length field)."""


class _PlyError(Exception):
    """A malformed PLY file; the message says what is wrong, without the path."""


@dataclass(frozen=True)
class _PlyProperty:
    """One property of a PLY element: a scalar, or a list when `count_type` is set."""

    name: str
    item_type: str
    count_type: str | None = None


@dataclass(frozen=True)
class _PlyElement:
    """One element declared in a PLY header, e.g. ``vertex`` or ``face``."""

    name: str
    count: int
    properties: tuple


@dataclass(frozen=True)
class _PlyHeader:
    """A checked PLY header: its encoding, its elements, where the body starts (byte offset and
    line number)."""

    encoding: str
    elements: tuple
    body_start: int
    body_line: int


def ply_attributes(path, names) -> dict[str, np.ndarray]:
    """The mesh attributes ``names`` of a PLY file, as Mitsuba 3 names and reads them: per vertex
    (``vertex_...``, (V, k)) or per face (``face_...``, (F, k)), float64, values as written (an
    integer colour is not scaled to [0, 1]: Mitsuba warns and keeps it). An element's ``r``,
    ``g``, ``b`` (or ``red``, ``green``, ``blue``; and ``a`` or ``alpha``, a fourth field) are its
    ``color``; its other properties named ``PREFIX_c``, consecutive with one prefix and the
    postfixes in sequence within one of ``xyzw``, ``rgba``, ``0123``, ``1234``, are attribute
    ``PREFIX`` of 1 to 3 fields (``PREFIX_color`` for ``rgba``); properties of no such form are
    not attributes. Raises MeshFileError for a malformed file, an attribute the file lacks
    (naming those it has), and a face attribute of a file with faces of more than 3 vertices
    (they are triangulated: give a triangle mesh)."""
    path = Path(path)
    _check_mesh_path(path)
    data = read_bytes(path, "mesh", limit=MAX_MESH_BYTES, error=MeshFileError)
    try:
        header = _parse_ply_header(data)
        if header.encoding == "ascii":
            values = _read_ascii_body(data[header.body_start :], header.elements, header.body_line)
        else:
            values = _read_binary_body(memoryview(data)[header.body_start :], header.elements, header.encoding)
    except _PlyError as err:
        raise MeshFileError(f"{path}: not a readable mesh: {err}") from None
    found = {}
    for element in header.elements:
        if element.name in ("vertex", "face"):
            for name, fields in _ply_attribute_fields(element).items():
                found[name] = np.column_stack([np.asarray(values[element.name][f], dtype=np.float64) for f in fields])
    out = {}
    for name in names:
        if name not in found:
            has = listed(sorted(found)) if found else "none"
            raise MeshFileError(f"{path}: has no mesh attribute '{name}' (its attributes: {has})")
        if name.startswith("face_"):
            face = values.get("face", {})
            counts = next((face[key][0] for key in _PLY_FACE_LISTS if key in face), [])
            if np.any(np.asarray(counts) != 3):
                raise MeshFileError(
                    f"{path}: face attribute '{name}' of a mesh with faces of more than 3 vertices"
                    " (they are triangulated: give a triangle mesh)"
                )
        out[name] = found[name]
    return out


_PLY_POSTFIXES = ("xyzw", "rgba", "0123", "1234")
"""The postfix sequences of a PLY attribute's fields (Mitsuba 3's)."""


def _ply_attribute_fields(element) -> dict[str, tuple[str, ...]]:
    """Mesh attribute name -> the properties holding its fields, for one PLY element: Mitsuba
    3.9's rule (``PLYMesh::find_other_fields``), run as its state machine so that the files it
    half-reads name the same attributes here, quirks included: after an invalid postfix it skips
    the properties starting with the prefix and the one after them, and the next attribute
    starts one field on. An attribute whose fields that leaves out of the file is not one."""
    props = [p.name for p in element.properties if not p.count_type]
    effective = dict(zip(props, props))  # property -> the name Mitsuba reads it under
    reserved = {"r", "g", "b", "a"}
    if element.name == "vertex":
        reserved |= {"x", "y", "z", *_PLY_NORMALS, "u", "v"}
        if not {"u", "v"} <= set(props):
            pair = next((p for p in (("texture_u", "texture_v"), ("s", "t")) if set(p) <= set(props)), ())
            effective.update(zip(pair, ("u", "v")))
    out = {}
    if not {"r", "g", "b"} <= set(props) and {"red", "green", "blue"} <= set(props):
        effective.update(red="r", green="g", blue="b", **({"alpha": "a"} if "alpha" in props else {}))
    by_name = {name: prop for prop, name in effective.items()}
    if {"r", "g", "b"} <= set(by_name):
        out[f"{element.name}_color"] = tuple(by_name[c] for c in "rgba" if c in by_name)
    names = [effective[p] for p in props]
    encountered, prefix, sequence, level, reading = set(), "", 0, 0, False

    def flush():
        nonlocal prefix, sequence, level, reading
        fields = [f"{prefix}_{_PLY_POSTFIXES[sequence][k]}" for k in range(level)]
        if level in (1, 3) and all(f in by_name for f in fields):
            out[f"{element.name}_{prefix}" + ("_color" if sequence == 1 else "")] = tuple(by_name[f] for f in fields)
            encountered.add(prefix)
        prefix, sequence, level, reading = "", 0, 0, False

    i = 0
    while i < len(names):
        name = names[i]
        head, bar, postfix = name.rpartition("_")
        if name in reserved:
            pass
        elif not bar or len(postfix) != 1:
            if reading:
                flush()
        else:
            if reading and head != prefix:
                flush()
            if not reading and head in encountered:
                while i < len(names) and names[i].startswith(head):
                    i += 1
            elif not reading:
                sequence = next((k for k, s in enumerate(_PLY_POSTFIXES) if s[0] == postfix), -1)
                if sequence >= 0:
                    reading, prefix = True, head
                    level += 1
                else:
                    sequence = 0
            elif level < 4 and postfix == _PLY_POSTFIXES[sequence][level]:
                level += 1
            else:
                prefix, sequence, level, reading = "", 0, 0, False
                while i < len(names) and names[i].startswith(head):
                    i += 1
                level += 1
        i += 1
    if reading:
        flush()
    return out


def _read_ply(path):
    """Parse a PLY file into its vertices (V, 3), face sizes (F,), flat vertex indices, vertex
    normals (V, 3) (None without ``nx``, ``ny``, ``nz``) and texture coordinates (V, 2) (None
    without a pair of ``_PLY_UVS``).

    Raises MeshFileError for any file that is not a complete, well-formed PLY file.
    """
    data = read_bytes(path, "mesh", limit=MAX_MESH_BYTES, error=MeshFileError)
    try:
        return _ply_arrays(data)
    except _PlyError as err:
        raise MeshFileError(f"{path}: not a readable mesh: {err}") from None


def _ply_arrays(data):
    """Vertices, face sizes (each at least 3), flat face vertex indices, vertex normals and texture
    coordinates (or None) from the bytes of a PLY file; raise _PlyError if they are malformed."""
    header = _parse_ply_header(data)
    if header.encoding == "ascii":
        values = _read_ascii_body(data[header.body_start :], header.elements, header.body_line)
    else:
        values = _read_binary_body(memoryview(data)[header.body_start :], header.elements, header.encoding)
    vertex = values["vertex"]
    points = np.column_stack([np.asarray(vertex[axis], dtype=np.float64) for axis in "xyz"])
    normals = None
    if "nx" in vertex:
        normals = np.column_stack([np.asarray(vertex[axis], dtype=np.float64) for axis in _PLY_NORMALS])
    pair = next((pair for pair in _PLY_UVS if pair[0] in vertex and pair[1] in vertex), None)
    uvs = None if pair is None else np.column_stack([np.asarray(vertex[name], dtype=np.float64) for name in pair])
    face = values.get("face", {})
    counts, indices = next((face[name] for name in _PLY_FACE_LISTS if name in face), ([], []))
    counts, indices = _integers(counts, "face size"), _integers(indices, "vertex index")
    small = np.flatnonzero(counts < 3)
    if small.size:
        others = f"; {small.size} faces have fewer than 3" if small.size > 1 else ""
        raise _PlyError(f"face {small[0]} has {counts[small[0]]} vertices (a face needs at least 3{others})")
    return points, counts, indices, normals, uvs


def _polydata(points, counts, indices, normals, uvs):
    """A PolyData of polygon faces (``counts[i]`` vertices each, listed in ``indices``), with
    point ``normals`` and texture coordinates ``uvs`` where not None."""
    import pyvista as pv

    starts = np.cumsum(counts) - counts
    polydata = pv.PolyData(points, faces=np.insert(indices, starts, counts))
    if normals is not None:
        polydata.point_data.set_array(normals, "Normals")
        polydata.point_data.active_normals_name = "Normals"
    if uvs is not None:
        polydata.point_data.active_texture_coordinates = uvs
    return polydata


def _parse_ply_header(data):
    """The `_PlyHeader` of a PLY file's bytes: its lines parsed, then checked by `_check_ply_header`."""
    end = data.find(b"\nend_header")
    lines = data[: max(end, 0)].decode("ascii", errors="replace").split("\n")
    if lines[0].strip() != "ply":
        raise _PlyError("does not start with 'ply'")
    if end < 0:
        raise _PlyError("no 'end_header' line")
    newline = data.find(b"\n", end + 1)
    body_start = len(data) if newline < 0 else newline + 1
    formats, elements = [], []
    for number, line in enumerate(lines[1:], start=2):
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "format" and len(words) == 3:
            formats.append(words[1:])
        elif words[0] == "element" and len(words) == 3 and re.fullmatch(r"[0-9]{1,18}", words[2]):
            elements.append((words[1], int(words[2]), []))
        elif words[0] == "property" and elements and len(words) == (5 if words[1:2] == ["list"] else 3):
            elements[-1][2].append(words[1:])
        else:
            raise _PlyError(f"header line {number}: unexpected {token(line.strip())}")
    encoding, checked = _check_ply_header(formats, elements, len(data) - body_start)
    return _PlyHeader(encoding, checked, body_start, data.count(b"\n", 0, body_start) + 1)


def _check_ply_header(formats, elements, body_size):
    """Check a parsed PLY header as a whole; return its encoding and its `_PlyElement` tuple.

    Parameters
    ----------
    formats : list of [encoding, version]
        The words of every ``format`` line.
    elements : list of (name, count, list of property words)
        Each ``element`` line with the words after ``property`` of its properties, e.g.
        ``["float", "x"]`` or ``["list", "uchar", "int", "vertex_indices"]``.
    body_size : int
        Bytes after the header: a binary body must hold at least the declared entries.

    Raises _PlyError for: no or several ``format`` lines, an unknown encoding or version; an
    element declared twice, or with entries but no properties; a property declared twice in an
    element, of an unknown type, or a list whose length type is not an integer type; no
    ``vertex`` element, or one without scalar x, y and z, or with only some of nx, ny, nz, or a list
    one; a ``face`` element without exactly one
    ``vertex_indices`` (or ``vertex_index``) list; a binary body too short for the counts.
    """
    encoding = _check_ply_format(formats)
    checked = {}
    for name, count, declared in elements:
        if name in checked:
            raise _PlyError(f"element '{shorten(name)}' is declared twice")
        checked[name] = _check_ply_element(name, count, declared)
    _check_ply_vertex_and_face(checked)
    if encoding != "ascii":
        least = sum(element.count * _ply_entry_bytes(element) for element in checked.values())
        if least > body_size:
            raise _PlyError(
                f"truncated: the header's element counts ({_ply_counts(checked.values())}) need at least {least} "
                f"bytes, the body has {body_size}"
            )
    return encoding, tuple(checked.values())


def _check_ply_format(formats) -> str:
    """The encoding of the one ``format`` line (of encoding and version 1.0) in ``formats``."""
    if not formats:
        raise _PlyError("no 'format' line")
    if len(formats) > 1:
        raise _PlyError("a second 'format' line")
    encoding, version = formats[0]
    if encoding not in _PLY_ENCODINGS:
        raise _PlyError(f"unknown format {token(encoding)} (known: {', '.join(_PLY_ENCODINGS)})")
    if version != "1.0":
        raise _PlyError(f"unsupported PLY version {token(version)} (only 1.0 exists)")
    return encoding


def _check_ply_element(name, count, declared):
    """The ``_PlyElement`` of an ``element`` line and its property words (see ``_check_ply_header``)."""
    if count and not declared:
        raise _PlyError(f"element '{shorten(name)}' has {count} entries but no properties")
    properties = {}
    for words in declared:
        prop, types = words[-1], words[1:-1] if words[0] == "list" else words[:-1]
        where = f"property '{shorten(prop)}' of element '{shorten(name)}'"
        if prop in properties:
            raise _PlyError(f"{where} is declared twice")
        for kind in types:
            if kind not in _PLY_TYPES:
                raise _PlyError(f"{where} has unknown type {token(kind)} (known: {', '.join(_PLY_TYPES)})")
        if words[0] != "list":
            properties[prop] = _PlyProperty(prop, _PLY_TYPES[types[0]])
        elif np.dtype(_PLY_TYPES[types[0]]).kind not in "iu":
            raise _PlyError(f"{where}: list length type {token(types[0])} is not an integer type")
        else:
            properties[prop] = _PlyProperty(prop, _PLY_TYPES[types[1]], _PLY_TYPES[types[0]])
    return _PlyElement(name, count, tuple(properties.values()))


def _check_ply_vertex_and_face(checked) -> None:
    """The ``vertex`` element's scalar x, y, z (and all of nx, ny, nz or none), and the ``face``
    element's one list of vertex indices."""
    if "vertex" not in checked:
        raise _PlyError("no 'vertex' element with x, y and z properties")
    vertex = {p.name: p for p in checked["vertex"].properties}
    for axis in "xyz":
        if axis not in vertex:
            raise _PlyError(f"element 'vertex' has no property '{axis}' (x, y and z are needed)")
    normals = [axis for axis in _PLY_NORMALS if axis in vertex]
    if normals and len(normals) < 3:
        raise _PlyError(f"element 'vertex' has {', '.join(normals)} but not all of nx, ny and nz (a vertex normal)")
    uvs = next((pair for pair in _PLY_UVS if pair[0] in vertex and pair[1] in vertex), ())
    for axis in ("x", "y", "z", *normals, *uvs):
        if vertex[axis].count_type:
            raise _PlyError(f"property '{axis}' of element 'vertex' is a list, not a number")
    if "face" in checked:
        lists = [p for p in checked["face"].properties if p.name in _PLY_FACE_LISTS]
        if len(lists) > 1:
            raise _PlyError("element 'face' has both vertex_indices and vertex_index")
        if checked["face"].count and not lists:
            raise _PlyError("element 'face' has no vertex_indices list")
        if lists and not lists[0].count_type:
            raise _PlyError(f"property '{lists[0].name}' of element 'face' is not a list")


def _ply_entry_bytes(element):
    """The fewest bytes one binary entry of `element` takes (its lists empty)."""
    return sum(np.dtype(p.count_type or p.item_type).itemsize for p in element.properties)


def _ply_counts(elements):
    """The header's element counts as words: ``3 vertex, 1 face``."""
    return listed(f"{element.count} {element.name}" for element in elements)


# --- PLY: ASCII bodies --------------------------------------------------------------------------


def _read_ascii_body(body, elements, first_line):
    """Read an ASCII PLY body, one element entry per (non-blank) line, as the header declares.

    Returns ``{element: {property: values}}`` as `_read_binary_body` does (float64 values).
    Every line must hold exactly the values its entry takes, and the body exactly the lines the
    element counts declare; `first_line` is the file's line number of the body's first line.
    """
    lines = body.splitlines()
    sizes = np.fromiter(map(len, map(bytes.split, lines)), dtype=np.int64, count=len(lines))
    try:
        tokens = np.array(body.split(), dtype=np.float64)
    except ValueError:
        raise _PlyError(_first_non_number(lines, first_line)) from None
    rows = np.flatnonzero(sizes)
    expected = sum(element.count for element in elements)
    if len(rows) != expected:
        problem = (
            f"the header's element counts ({_ply_counts(elements)}) need {expected} lines, the body has {len(rows)}"
        )
        raise _PlyError(problem if len(rows) > expected else f"truncated: {problem}")
    starts = (np.cumsum(sizes) - sizes)[rows]
    entries = _PlyAsciiEntries(tokens, starts, starts + sizes[rows], first_line + rows)
    values, row = {}, 0
    for element in elements:
        values[element.name] = entries.read(element, row)
        row += element.count
    return values


@dataclass(frozen=True)
class _PlyAsciiEntries:
    """The numbers of an ASCII PLY body and where each entry's line starts and ends in them."""

    tokens: np.ndarray
    starts: np.ndarray
    ends: np.ndarray
    line_numbers: np.ndarray

    def read(self, element, first):
        """The values of `element`, whose entries are the lines from entry number `first` on."""
        entries = slice(first, first + element.count)
        starts, ends = self.starts[entries], self.ends[entries]
        position, values = starts.copy(), {}
        for prop in element.properties:
            missing = np.flatnonzero(position >= ends)
            if missing.size:
                i = missing[0]
                self.fail(first + i, f"{shorten(element.name)} {i} has {ends[i] - starts[i]} values, it takes more")
            if prop.count_type:
                lengths = self.tokens[position]
                bad = np.flatnonzero(~((lengths >= 0) & (lengths < _PLY_MAX_LIST) & (lengths == np.trunc(lengths))))
                if bad.size:
                    i = bad[0]
                    self.fail(first + i, f"{shorten(element.name)} {i} has the list length {lengths[i]:g}")
                lengths = lengths.astype(np.int64)
                over = np.flatnonzero(position + 1 + lengths > ends)
                if over.size:
                    i = over[0]
                    self.fail(
                        first + i,
                        f"{shorten(element.name)} {i} has a list of {lengths[i]} items, its line holds "
                        f"{ends[i] - position[i] - 1} more values",
                    )
                runs = np.repeat(position + 1 - (np.cumsum(lengths) - lengths), lengths)
                values[prop.name] = (lengths, self.tokens[runs + np.arange(runs.size)])
                position += 1 + lengths
            else:
                values[prop.name] = self.tokens[position]
                position += 1
        extra = np.flatnonzero(position != ends)
        if extra.size:
            i = extra[0]
            self.fail(
                first + i,
                f"{shorten(element.name)} {i} has {ends[i] - starts[i]} values, it takes {position[i] - starts[i]}",
            )
        return values

    def fail(self, entry, problem):
        """Raise _PlyError for the line of `entry`; a problem on the last line may be a truncation."""
        truncated = "truncated: " if entry == len(self.starts) - 1 else ""
        raise _PlyError(f"{truncated}line {self.line_numbers[entry]}: {problem}")


def _first_non_number(lines, first_line):
    """The message for the first word of an ASCII body that is not a number."""
    for i, line in enumerate(lines):
        for word in line.split():
            try:
                float(word)
            except ValueError:
                return f"line {first_line + i}: {token(word.decode('ascii', errors='replace'))} is not a number"
    return "a value in the body is not a number"


# --- PLY: binary bodies -------------------------------------------------------------------------


def _read_binary_body(body, elements, encoding):
    """Read every element of a binary PLY body, which must end with the last element (a final
    line break aside).

    Returns ``{element: {property: values}}``, where a scalar property's values are an array
    with one entry per element, and a list property's are ``(counts, flat items)``.
    """
    values, offset, endian = {}, 0, _PLY_ENDIAN[encoding]
    for element in elements:
        values[element.name], offset = _read_ply_element(body, offset, element, endian)
    rest = bytes(body[offset:])
    if rest not in (b"", b"\n", b"\r\n"):
        raise _PlyError(
            f"{len(rest)} bytes after the last element: the header's element counts ({_ply_counts(elements)}) "
            "or property types do not match the data"
        )
    return values


def _read_ply_element(body, offset, element, endian):
    """Read one element's entries starting at byte `offset`; return (values, end offset).

    The common case, every entry's lists as long as the first entry's (e.g. all faces
    triangles), is read as one numpy record array. Otherwise the entries are walked once to
    find where each value lies, and the values are then gathered with numpy.
    """
    if element.count == 0:
        return {
            p.name: (np.empty(0, np.int64), np.empty(0)) if p.count_type else np.empty(0) for p in element.properties
        }, offset
    _, first_lengths, _ = _scan_ply_entries(body, offset, element, endian, 1)
    row = np.dtype(_ply_row_fields(element.properties, first_lengths[0], endian))
    end = offset + element.count * row.itemsize
    if end <= len(body):
        table = np.frombuffer(body, dtype=row, count=element.count, offset=offset)
        lists = [p for p in element.properties if p.count_type]
        if all(np.all(table[f"{p.name} count"] == n) for p, n in zip(lists, first_lengths[0])):
            return {
                p.name: (table[f"{p.name} count"], table[p.name].reshape(-1)) if p.count_type else table[p.name]
                for p in element.properties
            }, end
    return _gather_ply_entries(body, offset, element, endian)


def _ply_row_fields(properties, list_lengths, endian):
    """Record fields of one element entry whose list properties have the given lengths."""
    fields, lengths = [], iter(list_lengths)
    for prop in properties:
        if prop.count_type:
            fields.append((f"{prop.name} count", endian + prop.count_type))
            fields.append((prop.name, endian + prop.item_type, (next(lengths),)))
        else:
            fields.append((prop.name, endian + prop.item_type))
    return fields


def _gather_ply_entries(body, offset, element, endian):
    """Read an element whose lists vary in length; return (values, end offset)."""
    starts, lengths, end = _scan_ply_entries(body, offset, element, endian, element.count)
    raw = np.frombuffer(body, dtype=np.uint8)
    values, list_index = {}, 0
    for prop, prop_starts in zip(element.properties, starts.T):
        item = np.dtype(endian + prop.item_type)
        if prop.count_type:
            counts = lengths[:, list_index]
            items_start = prop_starts + np.dtype(prop.count_type).itemsize
            values[prop.name] = (counts, _gather(raw, items_start, counts, item))
            list_index += 1
        else:
            values[prop.name] = _gather(raw, prop_starts, np.ones_like(prop_starts), item)
    return values, end


def _scan_ply_entries(body, offset, element, endian, count):
    """Walk `count` entries of `element` from byte `offset`, reading only the list lengths.

    Returns
    -------
    starts : numpy.ndarray of int64, shape (count, number of properties)
        Byte offset of each property's value, or of its length for a list property.
    lengths : numpy.ndarray of int64, shape (count, number of list properties)
        The length of each list.
    end : int
        Byte offset just past the last entry.
    """
    steps = [
        (np.dtype(p.item_type).itemsize, p.count_type and struct.Struct(endian + np.dtype(p.count_type).char))
        for p in element.properties
    ]
    starts, lengths = [], []
    for index in range(count):
        for item_size, length_field in steps:
            starts.append(offset)
            length = 1
            if length_field:
                length = _ply_list_length(body, offset, length_field, element, index)
                lengths.append(length)
                offset += length_field.size
            offset += length * item_size
        if offset > len(body):
            raise _PlyError(f"truncated: the file ends inside element '{shorten(element.name)}'")
    shape = (count, -1)
    return np.reshape(starts, shape), np.reshape(np.array(lengths, dtype=np.int64), shape), offset


def _ply_list_length(body, offset, length_field, element, index):
    """Read the length of a PLY list at byte `offset` (in entry `index`) and check it is a count."""
    try:
        (length,) = length_field.unpack_from(body, offset)
    except struct.error:
        raise _PlyError(f"truncated: the file ends inside element '{shorten(element.name)}'") from None
    if not 0 <= length < _PLY_MAX_LIST:
        raise _PlyError(f"{shorten(element.name)} {index} has the list length {length}")
    return int(length)


def _gather(raw, starts, counts, dtype):
    """Gather runs of `counts[i]` values of `dtype` stored from byte `starts[i]` of `raw` bytes."""
    run_offsets = np.repeat(np.cumsum(counts) - counts, counts)
    item_starts = np.repeat(starts, counts) + (np.arange(run_offsets.size) - run_offsets) * dtype.itemsize
    return raw[item_starts[:, None] + np.arange(dtype.itemsize)].reshape(-1).view(dtype)


def _integers(values, what):
    """Convert PLY count or index values (integers, or floats parsed from ASCII) to int64."""
    values = np.asarray(values)
    if values.dtype.kind == "f" and not np.all((values == np.trunc(values)) & (np.abs(values) < 2.0**62)):
        raise _PlyError(f"a {what} is not an integer")
    return values.astype(np.int64)
