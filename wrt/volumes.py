"""Volumes on the host: a heterogeneous medium's ``sigma_t`` and ``albedo`` (``wrt.scene.Volume``),
read from a volume table of the scene file or from Mitsuba's binary grid files (``.vol``).

A volume gives values over the unit cube of its own frame, placed in the world by ``transform``
(the scene format's scale-rotate-translate, as a shape's): ``volume = "grid"`` reads them from a
``.vol`` file (``file``; with ``use_grid_bbox = true`` the box written in the file places the grid
in that frame, as Mitsuba 3's option of the same name), ``volume = "constant"`` is one ``value``
(a number or RGB) over the cube. Lookups are trilinear between texel centres, clamped at the faces
(``wrt.kernels.volumes.grid``); an extinction volume's box bounds its medium.

The ``.vol`` format (Mitsuba 0.6 to 3, little-endian): the bytes ``VOL``, version 3, the encoding
as int32 (1: float32, the one Mitsuba 3 reads), the resolution x, y, z and the channel count as
int32, the box (min x, y, z, max x, y, z) as float32, then the texels as float32, channels
innermost, then x, then y, then z. wrt reads 1 or 3 channels (a grey or an RGB volume), and
refuses a file whose texels are not finite and non-negative, whose body is not exactly what its
header declares, or whose grid is empty or larger than ``MAX_VOLUME_VALUES`` (before reading it).
"""

from __future__ import annotations

import os
import struct

import numpy as np

from wrt.errors import WrtError
from wrt.files import check_regular_file, write_atomic

HEADER = struct.Struct("<3sBiiiii6f")
MAX_VOLUME_VALUES = 1 << 28
"""Most values (texels times channels) one grid may hold: 1 GiB of float32, refused from its header."""
KINDS = ("grid", "constant")
"""The ``volume`` kinds of a volume table."""


class VolumeFileError(WrtError):
    """A ``.vol`` file wrt cannot use; the message says why (it names the file)."""


def read_vol(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """The texels ``(z, y, x, channels)`` (float32, 1 or 3 channels) of a ``.vol`` file and the
    box its header gives (``[[min], [max]]``)."""
    path = os.fspath(path)
    check_regular_file(path, "volume", limit=HEADER.size + 4 * MAX_VOLUME_VALUES, error=VolumeFileError)
    try:
        with open(path, "rb") as f:
            head = f.read(HEADER.size)
            if len(head) < HEADER.size:
                raise VolumeFileError(
                    f"{path}: not a volume file: {len(head)} bytes, shorter than the {HEADER.size}-byte header"
                )
            magic, version, encoding, nx, ny, nz, channels, *box = HEADER.unpack(head)
            if magic != b"VOL" or version != 3:
                raise VolumeFileError(f"{path}: not a volume file: it does not begin with 'VOL' and version 3")
            if encoding != 1:
                raise VolumeFileError(f"{path}: encoding {encoding} is not supported (1: float32, as Mitsuba 3 reads)")
            if channels not in (1, 3):
                raise VolumeFileError(f"{path}: {channels} channels: wrt reads grey (1) or RGB (3) volumes")
            if min(nx, ny, nz) <= 0:
                raise VolumeFileError(f"{path}: a grid of {nx} x {ny} x {nz} cells holds nothing")
            count = nx * ny * nz * channels
            if count > MAX_VOLUME_VALUES:
                raise VolumeFileError(
                    f"{path}: a grid of {nx} x {ny} x {nz} x {channels} values is more than the"
                    f" {MAX_VOLUME_VALUES} wrt reads"
                )
            body = os.fstat(f.fileno()).st_size - HEADER.size
            if body != 4 * count:
                raise VolumeFileError(
                    f"{path}: body of {body} bytes where its header declares {4 * count}"
                    f" ({nx} x {ny} x {nz} x {channels} float32)"
                )
            values = np.frombuffer(f.read(4 * count), dtype="<f4").reshape(nz, ny, nx, channels)
    except OSError as e:
        raise VolumeFileError(f"{path}: cannot read volume file ({e.strerror or e})") from None
    if values.size != count:
        raise VolumeFileError(f"{path}: the file changed while it was read")
    if not np.all(np.isfinite(values)):
        raise VolumeFileError(f"{path}: {int(np.sum(~np.isfinite(values)))} values are NaN or infinite")
    if np.any(values < 0.0):
        raise VolumeFileError(f"{path}: {int(np.sum(values < 0.0))} values are negative (smallest {values.min():g})")
    box = np.array(box, dtype=np.float64).reshape(2, 3)
    if not np.all(np.isfinite(box)):
        raise VolumeFileError(f"{path}: its box {box.tolist()} is not finite")
    return values.astype(np.float32), box


def box_matrix(box: np.ndarray) -> np.ndarray:
    """The 4x4 matrix taking the unit cube onto ``box`` (``[[min], [max]]``)."""
    m = np.eye(4)
    m[:3, :3] = np.diag(box[1] - box[0])
    m[:3, 3] = box[0]
    return m


def write_vol(path: str | os.PathLike, values: np.ndarray, box=((0.0, 0.0, 0.0), (1.0, 1.0, 1.0))) -> None:
    """Write ``values`` ``(z, y, x)`` or ``(z, y, x, channels)`` as a ``.vol`` file (float32, the
    box ``[[min], [max]]`` in its header), atomically."""
    values = np.asarray(values, dtype="<f4")
    if values.ndim == 3:
        values = values[..., None]
    nz, ny, nx, channels = values.shape
    head = HEADER.pack(b"VOL", 3, 1, nx, ny, nz, channels, *np.ravel(box))
    write_atomic(path, head + values.tobytes())
