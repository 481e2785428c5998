"""Triangle-mesh files: loading them as vertex and face arrays, and placing them in the world.

`load_mesh` turns a mesh file into ``(vertices, faces)`` arrays, raising `MeshFileError` with
a one-line message for any file that cannot be used. `transform_matrix` and `apply_transform`
implement the scene format's object-to-world convention (scale, then rotate, then translate).

PLY files are parsed here with numpy rather than by VTK: VTK's ``vtkPLYReader`` (VTK 9.7)
crashes the process with a segmentation fault on a truncated binary PLY file or on a face
index far out of range, which no Python code can catch. A PLY file of triangles never touches
VTK (nor imports pyvista, which takes a fifth of a second): its arrays are checked and returned
as they are; polygons with more vertices are triangulated by VTK. Every other format is read by
pyvista's VTK readers, with their console output silenced and their errors collected.
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from wrt.errors import MeshFileError

MESH_FORMATS = (".ply", ".obj", ".stl", ".vtk", ".vtp", ".vtu", ".vtm")
"""File extensions `load_mesh` reads (case-insensitive)."""


def load_mesh(path):
    """Read a triangle mesh from a file.

    Parameters
    ----------
    path : str or os.PathLike
        A mesh file whose extension is one of `MESH_FORMATS`: PLY (ASCII or binary), OBJ,
        STL (ASCII or binary), or a VTK dataset (``.vtk``, ``.vtp``, ``.vtu``, ``.vtm``).

    Returns
    -------
    vertices : numpy.ndarray of float64, shape (V, 3)
        Vertex positions in the file's own units and frame (object space).
    faces : numpy.ndarray of int32, shape (F, 3)
        Vertex indices of each triangle, in the winding order the file gives.

    Raises
    ------
    MeshFileError
        If the file is missing, a directory, of an unsupported format, unreadable, corrupt or
        truncated, has no faces, has NaN or infinite vertices, or has a face index outside
        ``0..V-1``. The message is one line naming `path` and the problem.

    Notes
    -----
    Polygons with more than three vertices are triangulated (by VTK). A volume dataset is
    reduced to its boundary surface first. Degenerate triangles (repeated or collinear
    vertices) are kept; vertices no face uses are kept too.
    """
    path = Path(path)
    _check_mesh_path(path)
    if path.suffix.lower() == ".ply":
        points, counts, indices = _read_ply(path)
        if len(counts) and np.all(counts == 3):
            return _checked_triangles(points, indices.reshape(-1, 3), path)
        return _triangles(_polydata(points, counts, indices), path)
    return _triangles(_read_with_vtk(path), path)


def transform_matrix(*, translate=(0.0, 0.0, 0.0), scale=(1.0, 1.0, 1.0), rotate=(0.0, 0.0, 0.0)):
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

    Returns
    -------
    numpy.ndarray of float64, shape (4, 4)
        M = T Rz Ry Rx S acting on column vectors ``(x, y, z, 1)``: a point p maps to
        ``p' = T + Rz Ry Rx (S p)``, i.e. scale first, then rotate, then translate.

    Raises
    ------
    ValueError
        If an argument has the wrong number of components or a non-finite component.

    Notes
    -----
    With ``rotate=(0, 0, 90)`` the point (1, 0, 0) maps to (0, 1, 0); with ``rotate=(90, 0,
    0)`` the point (0, 1, 0) maps to (0, 0, 1). A negative scale factor mirrors the object,
    which reverses the winding of its triangles.
    """
    t = _vector3("translate", translate)
    s = _vector3("scale", scale if np.ndim(scale) else (scale,) * 3)
    rx, ry, rz = np.radians(_vector3("rotate", rotate))
    matrix = np.eye(4)
    matrix[:3, :3] = _rotation_z(rz) @ _rotation_y(ry) @ _rotation_x(rx) @ np.diag(s)
    matrix[:3, 3] = t
    return matrix


def apply_transform(vertices, *, translate=(0.0, 0.0, 0.0), scale=(1.0, 1.0, 1.0), rotate=(0.0, 0.0, 0.0)):
    """Map object-space vertices to world space: ``p' = T + Rz Ry Rx (S p)``.

    Parameters
    ----------
    vertices : array_like, shape (V, 3)
        Points in object space.
    translate, scale, rotate
        As in `transform_matrix`: translation in world units, one or three scale factors,
        and angles in degrees about world X, then Y, then Z (right-handed). Scale is applied
        first, then the rotations, then the translation.

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
    matrix = transform_matrix(translate=translate, scale=scale, rotate=rotate)
    return points @ matrix[:3, :3].T + matrix[:3, 3]


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
    """Raise MeshFileError unless `path` is an existing regular file of a supported format."""
    if path.is_dir():
        raise MeshFileError(f"{path}: is a directory, not a mesh file")
    if not path.is_file():
        raise MeshFileError(f"{path}: no such mesh file")
    if path.suffix.lower() not in MESH_FORMATS:
        raise MeshFileError(
            f"{path}: unsupported mesh format {path.suffix or '(no extension)'!r}"
            f" (supported: {', '.join(MESH_FORMATS)})"
        )


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
        detail = _vtk_message((own or failed)[0].alert)
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


def _checked_triangles(points, faces, path):
    """``(vertices, faces)`` of a triangle mesh whose face indices and vertices are valid, else
    MeshFileError (the checks of ``_triangles``, without VTK)."""
    outside = np.count_nonzero((faces < 0) | (faces >= len(points)))
    if outside:
        raise MeshFileError(
            f"{path}: {outside} of {faces.size} face vertex indices are out of range for {len(points)} vertices"
        )
    bad_points = np.count_nonzero(~np.all(np.isfinite(points), axis=1))
    if bad_points:
        raise MeshFileError(f"{path}: {bad_points} of {len(points)} vertices are NaN or infinite")
    return np.asarray(points, dtype=np.float64), faces.astype(np.int32)


def _triangles(dataset, path):
    """Validate a dataset read from `path` and return its surface as (vertices, faces) arrays."""
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
    return vertices, faces


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


# --- PLY ------------------------------------------------------------------------------------

_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}  # fmt: skip
_PLY_ENDIAN = {"binary_little_endian": "<", "binary_big_endian": ">", "ascii": "<"}
"""Byte order of each PLY encoding; ASCII bodies are re-encoded as little-endian float64."""
_PLY_FACE_LISTS = ("vertex_indices", "vertex_index")


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
    properties: list


def _read_ply(path):
    """Parse a PLY file into its vertices (V, 3), face sizes (F,) and flat vertex indices.

    Raises MeshFileError for any file that is not a complete, well-formed PLY file.
    """
    try:
        data = path.read_bytes()
    except OSError as err:
        raise MeshFileError(f"{path}: cannot read ({err.strerror})") from None
    try:
        return _ply_arrays(data)
    except _PlyError as err:
        raise MeshFileError(f"{path}: not a readable mesh ({err})") from None


def _ply_arrays(data):
    """Vertices, face sizes and flat face vertex indices from the bytes of a PLY file; raise
    _PlyError if they are malformed."""
    encoding, elements, body_start = _parse_ply_header(data)
    if encoding == "ascii":
        body = _ascii_as_binary(data[body_start:])
        elements = [_as_float64(element) for element in elements]
    else:
        body = memoryview(data)[body_start:]
    values = _read_ply_body(body, elements, _PLY_ENDIAN[encoding])
    vertex = values.get("vertex", {})
    if not all(axis in vertex for axis in "xyz"):
        raise _PlyError("no 'vertex' element with x, y and z properties")
    points = np.column_stack([vertex[axis] for axis in "xyz"]).astype(np.float64)
    face = values.get("face", {})
    counts, indices = next((face[name] for name in _PLY_FACE_LISTS if name in face), ([], []))
    return points, _integers(counts, "face size"), _integers(indices, "vertex index")


def _polydata(points, counts, indices):
    """A PolyData of polygon faces (``counts[i]`` vertices each, listed in ``indices``)."""
    import pyvista as pv

    starts = np.cumsum(counts) - counts
    return pv.PolyData(points, faces=np.insert(indices, starts, counts))


def _parse_ply_header(data):
    """Return (encoding, elements, offset of the first body byte) from a PLY file's bytes."""
    if not data.startswith(b"ply"):
        raise _PlyError("does not start with 'ply'")
    end = data.find(b"\nend_header")
    if end < 0:
        raise _PlyError("no 'end_header' line")
    newline = data.find(b"\n", end + 1)
    body_start = len(data) if newline < 0 else newline + 1
    encoding, elements = None, []
    for line in data[:end].decode("ascii", errors="replace").splitlines()[1:]:
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "format" and len(words) == 3 and words[1] in _PLY_ENDIAN:
            encoding = words[1]
        elif words[0] == "element" and len(words) == 3 and words[2].isdigit():
            elements.append(_PlyElement(words[1], int(words[2]), []))
        elif words[0] == "property" and elements:
            elements[-1].properties.append(_parse_ply_property(words))
        else:
            raise _PlyError(f"unexpected header line {line.strip()!r}")
    if encoding is None:
        raise _PlyError("no 'format' line")
    return encoding, elements, body_start


def _parse_ply_property(words):
    """Parse the words of a ``property`` header line into a _PlyProperty."""
    if len(words) == 3 and words[1] in _PLY_TYPES:
        return _PlyProperty(words[2], _PLY_TYPES[words[1]])
    if len(words) == 5 and words[1] == "list" and words[2] in _PLY_TYPES and words[3] in _PLY_TYPES:
        return _PlyProperty(words[4], _PLY_TYPES[words[3]], _PLY_TYPES[words[2]])
    raise _PlyError(f"unexpected header line {' '.join(words)!r}")


def _ascii_as_binary(text):
    """Encode the numbers of an ASCII PLY body as little-endian float64 bytes."""
    try:
        return np.array(text.split(), dtype="<f8").tobytes()
    except ValueError as err:
        raise _PlyError(f"non-numeric value in body: {err}") from None


def _as_float64(element):
    """The same element with every value stored as float64, as `_ascii_as_binary` encodes them."""
    properties = [_PlyProperty(p.name, "f8", p.count_type and "f8") for p in element.properties]
    return _PlyElement(element.name, element.count, properties)


def _read_ply_body(body, elements, endian):
    """Read every element of a binary PLY body.

    Returns ``{element: {property: values}}``, where a scalar property's values are an array
    with one entry per element, and a list property's are ``(counts, flat items)``.
    """
    values, offset = {}, 0
    for element in elements:
        values[element.name], offset = _read_ply_element(body, offset, element, endian)
    return values


def _read_ply_element(body, offset, element, endian):
    """Read one element's entries starting at byte `offset`; return (values, end offset).

    The common case, every entry's lists as long as the first entry's (e.g. all faces
    triangles), is read as one numpy record array. Otherwise the entries are walked once to
    find where each value lies, and the values are then gathered with numpy.
    """
    if element.count == 0:
        return {p.name: ([], []) if p.count_type else [] for p in element.properties}, offset
    if not element.properties:
        raise _PlyError(f"element '{element.name}' has no properties")
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
    for _ in range(count):
        for item_size, length_field in steps:
            starts.append(offset)
            length = 1
            if length_field:
                length = _ply_list_length(body, offset, length_field, element)
                lengths.append(length)
                offset += length_field.size
            offset += length * item_size
        if offset > len(body):
            raise _PlyError(f"truncated: the file ends inside element '{element.name}'")
    shape = (count, -1)
    return np.reshape(starts, shape), np.reshape(np.array(lengths, dtype=np.int64), shape), offset


def _ply_list_length(body, offset, length_field, element):
    """Read the length of a PLY list at byte `offset` and check it is a count."""
    try:
        (length,) = length_field.unpack_from(body, offset)
    except struct.error:
        raise _PlyError(f"truncated: the file ends inside element '{element.name}'") from None
    if not (0 <= length < 2**31 and length == int(length)):
        raise _PlyError(f"element '{element.name}' has a list of length {length}")
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
