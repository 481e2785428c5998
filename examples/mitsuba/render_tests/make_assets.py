"""Make the textures the scenes of this folder load.

The scenes are nine of Mitsuba 3's render-test suite (mitsuba-data, ``tests/scenes``):
``floating_sphere/test_directional`` and ``test_directional_direct``,
``orthographic_sensor/test_orthographic``, ``spot_light/test_spot`` and ``test_spot_direct``,
``projector/test_projector_textured_direct``, ``instancing/test_instancing_path``,
``texture_interp/test_texture_interp_direct``, ``mesh_tangents/test_tangent_pole_path``,
``various_shapes/test_various_shapes`` and ``vertex_tangents/test_anisotropic_tangents_path``, element
for element but the ``<path>`` of those in this folder that have one: it is
``../../../common``, the repository's shared assets, which are not published with the scene
files, so these scenes look in this folder (``<path value="."/>``) for their textures and, where
they load meshes, in ``../bsdf_spheres`` too (``<path value="../bsdf_spheres"/>``) for its
``meshes/sphere.obj`` and ``meshes/rectangle.obj``, the stand-ins its ``make_assets.py`` makes.
The textures are stand-ins of our own, named as the suite names them: the images are therefore
not Mitsuba's stored ones, but Mitsuba's renders of these files.
(``texture_interp/test_texture_interp`` is ``test_texture_interp_direct`` with its texture in the
scene's own folder: not repeated.)

``textures/de_bruijn_pattern.png``
    A 64 x 64 8-bit grey PNG of 8 x 8 cells, black or white by a maximal-length binary
    sequence laid row by row: irregular, so that a texture turned, mirrored or shifted in a spot
    light's cone shows.
``textures/carrot.png``
    A 64 x 64 8-bit sRGB PNG of an orange carrot with green leaves on a pale blue ground, not
    symmetric, so that the six wrap and filter modes of ``test_texture_interp_direct`` differ.
``tests/{serialized,obj,ply}/rectangle_normals_uv.*``
    ``test_various_shapes`` (in ``tests/scenes/various_shapes``, mitsuba-data's own layout, so
    that its ``../../serialized/...`` names these files unchanged) loads Mitsuba's rectangle
    ([-1, 1]^2 at z = 0, two triangles) with normals (+z) and texture coordinates in three
    formats: a ``.serialized`` (version 4, single precision), an OBJ and a binary PLY, each read
    by Mitsuba as uv ``((x + 1) / 2, (y + 1) / 2)``.
``scenes/matpreview/matpreview.serialized`` and ``scenes/matpreview/envmap.exr``
    ``test_anisotropic_tangents_path`` (in ``tests/scenes/vertex_tangents``, mitsuba-data's layout:
    its ``<path value="../../../scenes/matpreview"/>`` names this folder unchanged) looks down at
    the pole of mesh 2 of Mitsuba's material-preview file. The stand-in holds three meshes:
    two small quads, and as mesh 2 ``../bsdf_spheres``' unit UV sphere (its poles on z, split seam
    and poles, exact normals, 24 rings by 48 segments); the map is ``../bsdf_spheres``'
    ``museum.exr`` room, 64 x 32.
``meshes/uv_sphere.obj``
    ``test_tangent_pole_path`` has no ``<path>``: its mesh is in this folder. A coarse unit UV
    sphere, 8 rings by 16 segments, its poles on z (the camera looks down the one at +z), made
    as ``../bsdf_spheres``' finer ``sphere.obj`` is (``uv_sphere``: split seam and poles, exact
    normals), so the tangents sweep a full turn around the pole.

Run from this folder: ``python make_assets.py`` (deterministic; the committed files are its output).
"""

import importlib.util
import struct
import zlib
from pathlib import Path

import numpy as np
import OpenImageIO as oiio

HERE = Path(__file__).resolve().parent


def sphere_maker():
    """``../bsdf_spheres/make_assets.py``, loaded as a module (its ``uv_sphere`` and ``write_obj``)."""
    spec = importlib.util.spec_from_file_location(
        "bsdf_spheres_assets", HERE.parent / "bsdf_spheres" / "make_assets.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def de_bruijn(size: int = 64, cells: int = 8) -> np.ndarray:
    """The binary cell pattern, ``(size, size, 1)`` uint8, row 0 the top row: cell ``(i, j)`` is
    bit ``(i cells + j) mod 63`` of the maximal-length sequence of x^6 + x + 1."""
    bits, state = [], 0b000001
    for _ in range(63):
        bits.append(state & 1)
        state = (state >> 1) | ((((state >> 0) ^ (state >> 1)) & 1) << 5)
    i, j = np.mgrid[0:cells, 0:cells]
    cell = np.array(bits)[(i * cells + j) % 63]
    return np.repeat(np.repeat(255 * cell, size // cells, 0), size // cells, 1).astype(np.uint8)[..., None]


def carrot(size: int = 64) -> np.ndarray:
    """The carrot, ``(size, size, 3)`` uint8 (sRGB), row 0 the top row: a root from its shoulder at
    the upper left to its tip at the lower right, three leaves above it."""
    y, x = (np.mgrid[0:size, 0:size] + 0.5) / size
    rgb = np.empty((size, size, 3))
    rgb[...] = (0.75, 0.85, 0.95)
    # the root: along the line from (0.3, 0.3) to (0.85, 0.9), narrowing toward the tip
    a, b = np.array([0.3, 0.3]), np.array([0.85, 0.9])
    d = b - a
    s = np.clip(((x - a[0]) * d[0] + (y - a[1]) * d[1]) / d.dot(d), 0.0, 1.0)
    dist = np.hypot(x - (a[0] + s * d[0]), y - (a[1] + s * d[1]))
    root = dist < 0.12 * (1.0 - s) + 0.01
    rings = 0.85 + 0.15 * np.cos(40.0 * s)
    rgb[root] = np.array([0.95, 0.45, 0.08]) * rings[root][:, None]
    for cx, cy, r in ((0.2, 0.12, 0.09), (0.32, 0.08, 0.07), (0.12, 0.25, 0.07)):
        rgb[np.hypot(x - cx, y - cy) < r] = (0.2, 0.6, 0.15)
    return np.round(255 * rgb).astype(np.uint8)


RECTANGLE = np.array([[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]])
RECTANGLE_UV = (RECTANGLE[:, :2] + 1.0) / 2.0
RECTANGLE_FACES = np.array([[0, 1, 2], [0, 2, 3]], dtype=np.uint32)


def write_serialized(path: Path, meshes) -> None:
    """A ``.serialized`` file (Mitsuba 0.5's format, version 4, single precision) of ``meshes``,
    each ``(name, vertices, faces, normals, uvs)``, with its table of offsets."""
    streams = []
    for name, vertices, faces, normals, uvs in meshes:
        body = struct.pack("<I", 0x1 | 0x2 | 0x1000) + name.encode() + b"\0"
        body += struct.pack("<QQ", len(vertices), len(faces))
        body += b"".join(np.asarray(a, "<f4").tobytes() for a in (vertices, normals, uvs))
        streams.append(struct.pack("<HH", 0x041C, 4) + zlib.compress(body + np.asarray(faces, "<u4").tobytes(), 9))
    offsets = np.cumsum([0] + [len(stream) for stream in streams[:-1]])
    table = b"".join(struct.pack("<Q", int(offset)) for offset in offsets) + struct.pack("<I", len(streams))
    path.write_bytes(b"".join(streams) + table)


def write_rectangles(folder: Path) -> None:
    """``rectangle_normals_uv`` as ``.serialized``, OBJ and PLY below ``folder``."""
    normals = np.tile([0.0, 0.0, 1.0], (4, 1))
    for kind in ("serialized", "obj", "ply"):
        (folder / kind).mkdir(parents=True, exist_ok=True)
    rectangle = ("rectangle", RECTANGLE, RECTANGLE_FACES, normals, RECTANGLE_UV)
    write_serialized(folder / "serialized" / "rectangle_normals_uv.serialized", [rectangle])
    lines = [f"v {x:g} {y:g} {z:g}" for x, y, z in RECTANGLE] + [f"vn {x:g} {y:g} {z:g}" for x, y, z in normals]
    lines += [f"vt {u:g} {1.0 - v:g}" for u, v in RECTANGLE_UV]  # Mitsuba's OBJ reader flips v
    lines += ["f " + " ".join(f"{i + 1}/{i + 1}/{i + 1}" for i in face) for face in RECTANGLE_FACES]
    (folder / "obj" / "rectangle_normals_uv.obj").write_text("\n".join(lines) + "\n")
    header = (
        "ply\nformat binary_little_endian 1.0\nelement vertex 4\n"
        + "".join(f"property float {c}\n" for c in ("x", "y", "z", "nx", "ny", "nz", "u", "v"))
        + "element face 2\nproperty list uchar int vertex_indices\nend_header\n"
    )
    vertex = np.hstack([RECTANGLE, normals, RECTANGLE_UV]).astype("<f4").tobytes()
    faces = b"".join(struct.pack("<B3i", 3, *face) for face in RECTANGLE_FACES.tolist())
    (folder / "ply" / "rectangle_normals_uv.ply").write_bytes(header.encode() + vertex + faces)


def write_png(path: Path, pixels: np.ndarray) -> None:
    spec = oiio.ImageSpec(pixels.shape[1], pixels.shape[0], pixels.shape[2], "uint8")
    spec.attribute("DateTime", "")
    out = oiio.ImageOutput.create(str(path))
    if out is None or not out.open(str(path), spec) or not out.write_image(pixels) or not out.close():
        raise OSError(f"{path}: {oiio.geterror()}")


def write_matpreview(folder: Path, spheres) -> None:
    """The material-preview stand-ins below ``folder`` (see the module's docstring)."""
    folder.mkdir(parents=True, exist_ok=True)
    normals = np.tile([0.0, 0.0, 1.0], (4, 1))
    quads = [(f"quad_{k}", RECTANGLE * (0.1 * (k + 1)), RECTANGLE_FACES, normals, RECTANGLE_UV) for k in range(2)]
    vertices, faces, uvs = spheres.uv_sphere()
    ball = ("ball", np.array(vertices), np.array(faces), np.array(vertices), np.array(uvs))
    write_serialized(folder / "matpreview.serialized", [*quads, ball])
    spheres.write_exr(folder / "envmap.exr", spheres.environment_map())


if __name__ == "__main__":
    write_rectangles(HERE / "tests")
    (HERE / "meshes").mkdir(exist_ok=True)
    spheres = sphere_maker()
    write_matpreview(HERE / "scenes" / "matpreview", spheres)
    vertices, faces, uvs = spheres.uv_sphere(rings=8, segments=16)
    spheres.write_obj(HERE / "meshes" / "uv_sphere.obj", vertices, faces, uvs, normals=vertices)
    (HERE / "textures").mkdir(exist_ok=True)
    write_png(HERE / "textures" / "de_bruijn_pattern.png", de_bruijn())
    write_png(HERE / "textures" / "carrot.png", carrot())
