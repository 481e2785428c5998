"""Mitsuba's ``.serialized`` mesh files (Mitsuba 0.6's format, which Mitsuba 3 reads): one or
more meshes, each a little-endian header (uint16 ``0x041C``, uint16 version 3 or 4) followed by a
zlib stream of its flags (uint32: vertex normals ``0x1``, texture coordinates ``0x2``, vertex
colours ``0x8``, face normals ``0x10``, single ``0x1000`` or double ``0x2000`` precision), its name
(version 4: a NUL-terminated string), its vertex and triangle counts (uint64 each), its positions,
normals, texture coordinates and colours (float32 or float64, per vertex, those the flags name)
and its triangles (uint32 vertex indices); the file ends with the offset of every mesh (uint64 in
version 4, uint32 in version 3) and their count (uint32), by which ``shape_index`` finds one.

`read_serialized` returns what `wrt.meshio.load_mesh` returns for other formats, and raises
`wrt.errors.MeshFileError` with one line naming the file and what is wrong: a bad header or
version, a ``shape_index`` beyond the file's count, a stream that does not inflate, counts the
data does not hold, face indices out of range, NaN or infinite values. Vertex colours are read
past (Mitsuba 3 skips them too); the face-normals flag is not read (a shape's ``face_normals``
decides, as in Mitsuba 3). Texture coordinates are returned as written (Mitsuba does not flip a
serialized file's v).
"""

from __future__ import annotations

import struct
import zlib

import numpy as np

from wrt.errors import MeshFileError
from wrt.files import read_bytes

MAGIC = 0x041C
VERSIONS = (3, 4)
HAS_NORMALS, HAS_TEXCOORDS, HAS_COLORS, DOUBLE = 0x0001, 0x0002, 0x0008, 0x2000
MAX_NAME = 1 << 16  # the longest mesh name read (version 4), in bytes


def read_serialized(path, shape_index: int, limit: int):
    """``(vertices, faces, normals, uvs)`` of mesh ``shape_index`` of the ``.serialized`` file
    ``path``: float64 (V, 3), int32 (F, 3), and float64 (V, 3) and (V, 2) or None where the file
    has none. The whole file is read (at most ``limit`` bytes)."""
    data = read_bytes(path, "mesh", limit=limit, error=MeshFileError)
    if len(data) < 8:
        raise MeshFileError(f"{path}: {len(data)} bytes: too short for a .serialized mesh file")
    magic, version = struct.unpack_from("<HH", data, 0)
    if magic != MAGIC:
        raise MeshFileError(f"{path}: not a .serialized mesh file (its header is {magic:#06x}, not {MAGIC:#06x})")
    if version not in VERSIONS:
        raise MeshFileError(f"{path}: .serialized version {version} is not supported (3 or 4)")
    start = _offset(path, data, version, shape_index)
    try:
        stream = zlib.decompressobj().decompress(data[start + 4 :])
    except zlib.error as e:
        raise MeshFileError(f"{path}: mesh {shape_index}: its compressed data is corrupt ({e})") from None
    return _mesh(path, stream, version, shape_index)


def _offset(path, data: bytes, version: int, shape_index: int) -> int:
    """The byte offset of mesh ``shape_index``: 0 for the first (whose table Mitsuba does not
    read either), else from the end-of-file table."""
    if shape_index == 0:
        return 0
    (count,) = struct.unpack_from("<I", data, len(data) - 4)
    if shape_index >= count:
        raise MeshFileError(f"{path}: shape_index {shape_index} is out of range: the file holds {count} meshes")
    size = 8 if version == 4 else 4
    at = len(data) - 4 - size * (count - shape_index)
    if at < 4:
        raise MeshFileError(f"{path}: its table of {count} meshes does not fit in {len(data)} bytes")
    (offset,) = struct.unpack_from("<Q" if size == 8 else "<I", data, at)
    if offset + 4 > at or struct.unpack_from("<H", data, offset)[0] != MAGIC:
        raise MeshFileError(f"{path}: mesh {shape_index}'s offset {offset} does not point at a mesh header")
    return offset


def _mesh(path, stream: bytes, version: int, shape_index: int):
    where = f"{path}: mesh {shape_index}"
    reader = _Reader(stream, where)
    flags = reader.unpack("<I")
    if version == 4:
        end = stream.find(b"\0", reader.at, reader.at + MAX_NAME)
        if end < 0:
            raise MeshFileError(f"{where}: its name is not terminated")
        reader.at = end + 1
    n_vertices, n_faces = reader.unpack("<Q"), reader.unpack("<Q")
    if n_faces == 0:
        raise MeshFileError(f"{where}: has no faces")
    real = np.float64 if flags & DOUBLE else np.float32
    vertices = reader.array(real, n_vertices * 3, "vertex positions").reshape(-1, 3)
    normals = reader.array(real, n_vertices * 3, "vertex normals").reshape(-1, 3) if flags & HAS_NORMALS else None
    uvs = reader.array(real, n_vertices * 2, "texture coordinates").reshape(-1, 2) if flags & HAS_TEXCOORDS else None
    if flags & HAS_COLORS:
        reader.array(real, n_vertices * 3, "vertex colours")
    faces = reader.array(np.uint32, n_faces * 3, "triangles").reshape(-1, 3).astype(np.int64)
    outside = np.count_nonzero(faces >= n_vertices)
    if outside:
        raise MeshFileError(
            f"{where}: {outside} of {faces.size} face vertex indices are out of range for {n_vertices} vertices"
        )
    for name, values in (("vertices", vertices), ("vertex normals", normals), ("texture coordinates", uvs)):
        if values is not None and not np.all(np.isfinite(values)):
            bad = np.count_nonzero(~np.all(np.isfinite(values), axis=1))
            raise MeshFileError(f"{where}: {bad} of {len(values)} {name} are NaN or infinite")
    as64 = [None if a is None else a.astype(np.float64) for a in (vertices, normals, uvs)]
    return as64[0], faces.astype(np.int32), as64[1], as64[2]


class _Reader:
    """Little-endian values read in turn from the inflated stream of one mesh."""

    def __init__(self, data: bytes, where: str):
        self.data, self.where, self.at = data, where, 0

    def unpack(self, fmt: str) -> int:
        size = struct.calcsize(fmt)
        if self.at + size > len(self.data):
            raise MeshFileError(f"{self.where}: truncated: its header ends early")
        (value,) = struct.unpack_from(fmt, self.data, self.at)
        self.at += size
        return value

    def array(self, dtype, count: int, what: str) -> np.ndarray:
        size = np.dtype(dtype).itemsize * count
        if self.at + size > len(self.data):
            raise MeshFileError(
                f"{self.where}: truncated: its {what} need {size} bytes, {max(0, len(self.data) - self.at)} are left"
            )
        values = np.frombuffer(self.data, dtype=np.dtype(dtype).newbyteorder("<"), count=count, offset=self.at)
        self.at += size
        return values
