"""Make the meshes, textures and environment maps the scenes of this folder load.

The scenes are ten of Mitsuba 3's render-test suite (mitsuba-data, ``tests/scenes/
bsdf_spheres``). ``test_texturedprincipled1``, ``test_texturedprincipled2``,
``test_texturedprincipledthin``, ``test_normalmap``, ``test_normalmap_roughconductor_path`` and
``test_normalmap_identity_roughconductor_path``, with their ``fragments/single_sphere.xml``, are
element for element but their ``<path>`` (and the thin one's rectangle, below); ``test_arealight``,
``test_constant``, ``test_pointlight`` and ``test_envmap``, with their ``include/scene.xml``
(twelve spheres and two masked leaves of every material kind: diffuse, textured, a diamond,
plastics, Beckmann and GGX rough dielectrics, Beckmann rough plastics and conductor, a smooth
conductor, under an area-emitting OBJ rectangle, a constant sky, a point light and an environment
map), element for element. The ``<path>`` of the first six is ``../../../common``, the
repository's shared assets, which are not published with the scene files, so these scenes look in
this folder (``<path value="."/>``); every asset is a stand-in of our own, named as the suite names
it (below): the images are therefore not Mitsuba's stored ones, but Mitsuba's renders of these
files. And
``test_texturedprincipledthin``'s rectangle is ``<shape type="rectangle">``, where mitsuba-data
writes ``type="Rectangle"``, which Mitsuba 3.9.1 refuses (``Plugin "Rectangle" not found``: its
plugin names are case-sensitive).

``meshes/sphere.obj``
    A UV sphere of radius 1 centred at the origin, its poles on the z axis (the camera's up), 24
    rings by 48 segments, with texture coordinates and normals. Mitsuba's OBJ reader takes a
    ``vt u v`` line as the uv ``(u, 1 - v)``; the file's ``vt`` lines hold ``u = phi / 2 pi``
    (``phi`` the angle about z from +x towards +y) and ``v = 1 - theta / pi`` (``theta`` the
    angle from +z: ``v = 1`` at +z, ``v = 0`` at -z), so that Mitsuba's uv is
    ``(phi / 2 pi, theta / pi)``, 0 at the pole at +z. The seam at ``phi = 0`` (+x, facing away
    from the scenes' camera) has its vertices twice, at ``u = 0`` and ``u = 1``, and each pole
    one vertex per segment, at the segment's middle ``u``. The normals (``vn``) are the exact
    sphere normals (the positions): an OBJ without them would have Mitsuba average the face
    normals at each vertex, skewed on the seam's and the poles' split vertices. Triangles
    counter-clockwise seen from outside (geometric normals outward).
``meshes/rectangle.obj``
    Mitsuba's ``rectangle``: the square [-1, 1]^2 in the plane z = 0, two triangles
    counter-clockwise seen from +z (normal +z in Mitsuba), and the ``rectangle`` plugin's uv
    ``((x + 1) / 2, (y + 1) / 2)`` as Mitsuba reads the file (its ``vt`` lines
    ``((x + 1) / 2, (1 - y) / 2)``).
``textures/floor_tiles.jpg``
    A 64 x 64 8-bit sRGB JPEG of 4 x 4 terracotta tiles, each a little lighter or darker, with
    pale grout lines between them.
``textures/floor_tiles_normalmap.jpg``
    The tiles' tangent-space normal map (read raw), 64 x 64 8-bit JPEG: ``(n + 1) / 2`` of the
    normals of a height field that is flat on the tiles and sinks into rounded grooves at the
    grout, so the normals tilt across each groove.
``textures/wood.jpg``
    A 64 x 64 8-bit sRGB JPEG of wood grain: brown rings, light and dark, bent by a slow wave.
``textures/leaf_mask.png``
    A 64 x 64 8-bit grey PNG, the opacity of the masked leaves: white (opaque) inside a leaf
    outline (two arcs from stem to tip), black elsewhere, with a black midrib.
``textures/envmap.exr``
    The room of ``museum.exr`` (below), turned a quarter about the vertical, 64 x 32, float32 RGB.
``textures/museum.exr``
    A 64 x 32 HDR latitude-longitude map (Mitsuba's ``envmap`` layout: row 0 towards +y) of a
    room, float32 RGB: a bright ceiling and a dim warm floor, walls banded in longitude, a
    checkered floor, two bright windows and a warm lamp (values about 0.05 to 6).

Run from this folder: ``python make_assets.py`` (deterministic; the committed files are its
output).
"""

import math
from pathlib import Path

import numpy as np
import OpenImageIO as oiio

HERE = Path(__file__).parent


def write_obj(path, vertices, faces, uvs, normals=None):
    """An OBJ of triangles ``faces`` (0-based corner indices into all three attribute lists);
    ``uvs`` as Mitsuba reads them, written ``vt u (1 - v)`` (Mitsuba flips an OBJ's v)."""
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in vertices]
    lines += [f"vt {u:.6f} {1 - v:.6f}" for u, v in uvs]
    if normals is not None:
        lines += [f"vn {x:.6f} {y:.6f} {z:.6f}" for x, y, z in normals]
        corner = "{0}/{0}/{0}"
    else:
        corner = "{0}/{0}"
    lines += ["f " + " ".join(corner.format(i + 1) for i in face) for face in faces]
    path.write_text("\n".join(lines) + "\n")


def uv_sphere(rings=24, segments=48):
    """The unit sphere about z with its seam and poles split for uv (see the module's docstring),
    its uv as Mitsuba reads them: ``(phi / 2 pi, theta / pi)``."""
    vertices, uvs = [], []
    for j in range(segments):  # the pole at +z, theta = 0
        vertices.append((0.0, 0.0, 1.0))
        uvs.append(((j + 0.5) / segments, 0.0))
    for i in range(1, rings):
        theta = math.pi * i / rings
        for j in range(segments + 1):
            phi = 2 * math.pi * j / segments
            vertices.append((math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta)))
            uvs.append((j / segments, i / rings))
    bottom = len(vertices)
    for j in range(segments):  # the pole at -z, theta = pi
        vertices.append((0.0, 0.0, -1.0))
        uvs.append(((j + 0.5) / segments, 1.0))

    def ring(i, j):  # vertex j of ring i (1 .. rings - 1)
        return segments + (i - 1) * (segments + 1) + j

    faces = [(j, ring(1, j), ring(1, j + 1)) for j in range(segments)]
    for i in range(1, rings - 1):
        for j in range(segments):
            a, b, c, d = ring(i, j), ring(i + 1, j), ring(i + 1, j + 1), ring(i, j + 1)
            faces += [(a, b, c), (a, c, d)]
    faces += [(ring(rings - 1, j), bottom + j, ring(rings - 1, j + 1)) for j in range(segments)]
    return vertices, faces, uvs


def meshes():
    (HERE / "meshes").mkdir(exist_ok=True)
    vertices, faces, uvs = uv_sphere()
    write_obj(HERE / "meshes" / "sphere.obj", vertices, faces, uvs, normals=vertices)
    corners = [(-1.0, -1.0, 0.0), (1.0, -1.0, 0.0), (1.0, 1.0, 0.0), (-1.0, 1.0, 0.0)]
    write_obj(
        HERE / "meshes" / "rectangle.obj",
        corners,
        [(0, 1, 2), (0, 2, 3)],
        [((x + 1) / 2, (y + 1) / 2) for x, y, _ in corners],
    )


def environment_map(width=64, height=32):
    """The room (see the module's docstring), linear RGB, ``(height, width, 3)``."""
    theta = ((np.arange(height) + 0.5) / height * math.pi)[:, None] * np.ones(width)
    phi = ((np.arange(width) + 0.5) / width * 2 * math.pi)[None, :] * np.ones((height, 1))
    up = np.cos(theta)
    ceiling = np.stack([0.55 + 0.3 * up, 0.6 + 0.3 * up, 0.65 + 0.35 * up], axis=-1)
    floor = np.stack([0.3 + 0.1 * up, 0.22 + 0.06 * up, 0.14 + 0.04 * up], axis=-1)
    room = np.where((up > 0)[..., None], ceiling, floor)
    room *= (1.0 + 0.35 * np.sin(4 * phi + 0.5) * np.sin(theta))[..., None]
    checker = (np.floor(phi / (math.pi / 8)) + np.floor(theta / (math.pi / 16))) % 2
    room *= np.where((up < -0.2) & (checker > 0), 0.55, 1.0)[..., None]

    def patch(phi0, phi1, theta0, theta1):
        return ((phi >= phi0) & (phi < phi1) & (theta >= theta0) & (theta < theta1))[..., None]

    room = np.where(patch(1.0, 1.6, 0.8, 1.3), np.array([4.0, 4.5, 5.5]), room)
    room = np.where(patch(3.6, 3.9, 0.6, 1.4), np.array([3.0, 3.3, 3.8]), room)
    room = np.where(patch(5.2, 5.45, 1.2, 1.5), np.array([6.0, 4.0, 2.0]), room)
    return room.astype(np.float32)


def write_exr(path, rgb):
    """A float32 RGB OpenEXR of ``rgb`` without the ``DateTime`` OpenImageIO stamps by default
    (so that the file's bytes are the same at every run)."""
    spec = oiio.ImageSpec(rgb.shape[1], rgb.shape[0], 3, "float")
    spec.attribute("compression", "zip")
    spec.attribute("DateTime", "")
    out = oiio.ImageOutput.create(str(path))
    if out is None or not out.open(str(path), spec) or not out.write_image(rgb) or not out.close():
        raise OSError(f"{path}: {oiio.geterror()}")


def environment_maps():
    (HERE / "textures").mkdir(exist_ok=True)
    room = environment_map()
    write_exr(HERE / "textures" / "museum.exr", room)
    write_exr(HERE / "textures" / "envmap.exr", np.ascontiguousarray(np.roll(room, room.shape[1] // 4, axis=1)))


def wood(size=64):
    """The wood grain, ``(size, size, 3)`` uint8 (sRGB), row 0 the top row."""
    y, x = (np.mgrid[0:size, 0:size] + 0.5) / size
    rings = 0.5 + 0.5 * np.sin(2 * math.pi * (7.0 * x + 0.6 * np.sin(2 * math.pi * 1.3 * y)))
    light, dark = np.array([0.78, 0.56, 0.34]), np.array([0.45, 0.27, 0.13])
    rgb = dark + (light - dark) * rings[..., None]
    return np.round(255 * rgb).astype(np.uint8)


def leaf_mask(size=64):
    """The leaf's opacity, ``(size, size, 1)`` uint8, row 0 the top row: a leaf from the bottom
    (stem) to the top (tip), 0 outside it and along its midrib."""
    y, x = (np.mgrid[0:size, 0:size] + 0.5) / size
    half_width = 0.38 * np.sin(math.pi * np.clip((0.95 - y) / 0.9, 0.0, 1.0))
    inside = np.abs(x - 0.5) < half_width
    midrib = np.abs(x - 0.5) < 0.02
    return np.where(inside & ~midrib, 255, 0).astype(np.uint8)[..., None]


def write_ldr(path, pixels):
    """An 8-bit image (``pixels``: ``(height, width, channels)`` uint8) in the format of ``path``'s
    extension."""
    spec = oiio.ImageSpec(pixels.shape[1], pixels.shape[0], pixels.shape[2], "uint8")
    spec.attribute("DateTime", "")
    out = oiio.ImageOutput.create(str(path))
    if out is None or not out.open(str(path), spec) or not out.write_image(pixels) or not out.close():
        raise OSError(f"{path}: {oiio.geterror()}")


def tile_height(size=64, tiles=4):
    """The tiles' height field, ``(size, size)`` in [0, 1]: 1 on the tiles, down to 0 in the
    middle of the grooves between them (a quarter of a tile wide, rounded)."""
    y, x = (np.mgrid[0:size, 0:size] + 0.5) / size * tiles
    edge = np.minimum(np.minimum(x % 1.0, 1.0 - x % 1.0), np.minimum(y % 1.0, 1.0 - y % 1.0))
    return np.sin(0.5 * math.pi * np.clip(edge / 0.125, 0.0, 1.0))


def floor_tiles(size=64, tiles=4):
    """The tiles' colour, ``(size, size, 3)`` uint8 (sRGB): terracotta, grout pale."""
    i, j = np.mgrid[0:size, 0:size] * tiles // size
    shade = 0.85 + 0.15 * ((3 * i + 5 * j) % 4) / 3.0
    rgb = np.array([0.72, 0.36, 0.22]) * shade[..., None]
    rgb = np.where((tile_height(size, tiles) < 0.5)[..., None], np.array([0.85, 0.82, 0.75]), rgb)
    return np.round(255 * rgb).astype(np.uint8)


def tile_normals(size=64, tiles=4, depth=0.15):
    """The tiles' normal map, ``(size, size, 3)`` uint8: ``(n + 1) / 2`` of the unit normals of the
    height field ``depth tile_height`` (in uv units), +z out of the surface."""
    h = depth * tile_height(size, tiles)
    dh_dv, dh_du = np.gradient(h, 1.0 / size)
    n = np.stack([-dh_du, dh_dv, np.ones_like(h)], axis=-1)  # rows run down: v grows downwards
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return np.round(255 * (n + 1.0) / 2.0).astype(np.uint8)


def textures():
    (HERE / "textures").mkdir(exist_ok=True)
    write_ldr(HERE / "textures" / "wood.jpg", wood())
    write_ldr(HERE / "textures" / "leaf_mask.png", leaf_mask())
    write_ldr(HERE / "textures" / "floor_tiles.jpg", floor_tiles())
    write_ldr(HERE / "textures" / "floor_tiles_normalmap.jpg", tile_normals())


if __name__ == "__main__":
    meshes()
    environment_maps()
    textures()
