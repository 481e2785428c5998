"""Make the meshes, grids and environment maps the scenes of this folder load.

The scenes are those of Mitsuba 3's render-test suite (mitsuba-data, ``tests/scenes/
participating_media``), element for element; their assets are not all published, so they are
made here: the grids (``textures/sigmat.vol``, ``textures/albedo.vol``) from the density and
albedo functions that define them in that suite (16^3 texels), the meshes, the emission grid
(``textures/radiance.vol``) and the environment maps as stand-ins of our own (named as the suite
names them; docs/mitsuba.md says which). Run from this folder: ``python make_assets.py``
(deterministic; the committed files are its output).
"""

import math
from pathlib import Path

import numpy as np

from wrt.imageio import write_image
from wrt.volumes import write_vol

HERE = Path(__file__).parent
RES = 16


def grid_coordinates():
    """``(x, y, z)`` of the texels, each ``i / RES``, indexed ``[z, y, x]``."""
    z, y, x = np.meshgrid(*(np.arange(RES) / RES,) * 3, indexing="ij")
    return x, y, z


def density(x, y, z):
    """The suite's extinction: a sheared sine in x, and 5 in a block near the top."""
    wave = np.maximum(0.0, (np.sin(16.0 * (x + 4.0 * ((y - 0.5) ** 2 - 0.25))) + 1.0) * 0.5)
    return np.where((x > 0.2) & (y > 0.7) & (z < 0.5), 5.0, wave)


def albedo_wave(x, y):
    return np.cos(45.0 * (x + ((y - 0.7) ** 2 - 0.25)) + 1.0) * 0.5


def grids():
    x, y, z = grid_coordinates()
    albedo = np.stack(
        [
            albedo_wave(x, y) + 0.5 * np.cos(y) + 0.5,
            density((x + 0.3) % 1.0, (y + 0.7) % 1.0, z),
            albedo_wave(x, y),
        ],
        axis=-1,
    )
    write_vol(HERE / "textures" / "sigmat.vol", np.maximum(density(x, y, z), 0.0))
    write_vol(HERE / "textures" / "albedo.vol", np.clip(albedo, 0.0, 1.0))
    # a stand-in of our own: a warm core glowing through a cooler, banded shell
    r2 = (x - 0.5) ** 2 + (y - 0.45) ** 2 + (z - 0.5) ** 2
    core = np.exp(-r2 / 0.02)
    bands = 0.5 * (1.0 + np.sin(12.0 * (x + z)))
    radiance = np.stack([4.0 * core + 0.2 * bands, 2.0 * core + 0.3 * bands, 0.5 * core + 0.6 * bands], axis=-1)
    write_vol(HERE / "textures" / "radiance.vol", radiance)


def write_obj(name, vertices, faces, uvs=None):
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in vertices]
    if uvs is not None:
        lines += [f"vt {u:.6f} {v:.6f}" for u, v in uvs]
        lines += ["f " + " ".join(f"{i + 1}/{i + 1}" for i in face) for face in faces]
    else:
        lines += ["f " + " ".join(str(i + 1) for i in face) for face in faces]
    (HERE / "meshes" / name).write_text("\n".join(lines) + "\n")


def uv_sphere(center, radius, rings=24, segments=48):
    """A closed sphere of triangles, counter-clockwise seen from outside."""
    vertices = [(center[0], center[1] + radius, center[2])]
    for i in range(1, rings):
        theta = math.pi * i / rings
        for j in range(segments):
            phi = 2 * math.pi * j / segments
            vertices.append(
                (
                    center[0] + radius * math.sin(theta) * math.cos(phi),
                    center[1] + radius * math.cos(theta),
                    center[2] - radius * math.sin(theta) * math.sin(phi),
                )
            )
    vertices.append((center[0], center[1] - radius, center[2]))
    bottom = len(vertices) - 1
    faces = []
    for j in range(segments):
        faces.append((0, 1 + j, 1 + (j + 1) % segments))
    for i in range(rings - 2):
        a, b = 1 + i * segments, 1 + (i + 1) * segments
        for j in range(segments):
            k = (j + 1) % segments
            faces += [(a + j, b + j, b + k), (a + j, b + k, a + k)]
    last = 1 + (rings - 2) * segments
    for j in range(segments):
        faces.append((last + j, bottom, last + (j + 1) % segments))
    return vertices, faces


def torus(center, major, minor, tilt, rings=48, sides=16):
    """A closed torus around the y axis turned by ``tilt`` degrees about x."""
    c, s = math.cos(math.radians(tilt)), math.sin(math.radians(tilt))
    vertices = []
    for i in range(rings):
        u = 2 * math.pi * i / rings
        for j in range(sides):
            v = 2 * math.pi * j / sides
            x = (major + minor * math.cos(v)) * math.cos(u)
            y = minor * math.sin(v)
            z = (major + minor * math.cos(v)) * math.sin(u)
            vertices.append((center[0] + x, center[1] + c * y - s * z, center[2] + s * y + c * z))
    faces = []
    for i in range(rings):
        for j in range(sides):
            a, b = i * sides + j, ((i + 1) % rings) * sides + j
            a1, b1 = i * sides + (j + 1) % sides, ((i + 1) % rings) * sides + (j + 1) % sides
            faces += [(a, a1, b1), (a, b1, b)]
    return vertices, faces


def box(lo, hi, rotate_y=0.0):
    """A closed box of quads, counter-clockwise seen from outside, turned about y."""
    corners = [(x, y, z) for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    c, s = math.cos(math.radians(rotate_y)), math.sin(math.radians(rotate_y))
    corners = [(c * x + s * z, y, -s * x + c * z) for x, y, z in corners]
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return corners, [(a, b, c_) for a, b, c_, _ in quads] + [(a, c_, d) for a, _, c_, d in quads]


def meshes():
    (HERE / "meshes").mkdir(exist_ok=True)
    write_obj("unit_cube_centered.obj", *box((-0.5,) * 3, (0.5,) * 3))
    write_obj("sphere.obj", *uv_sphere((0.0, 0.0, 0.0), 0.5))
    write_obj("sphere_origin.obj", *uv_sphere((0.0, 0.0, 0.0), 1.0))
    write_obj("sphere_base.obj", *uv_sphere((0.0, -0.85, 0.0), 0.3, rings=16, segments=32))
    write_obj("sphere_tiny.obj", *uv_sphere((0.0, 0.1, 0.3), 0.15, rings=12, segments=24))
    write_obj("angled_cube.obj", *box((-0.15, 0.2, -0.15), (0.15, 0.5, 0.15), rotate_y=40.0))
    write_obj("torus1.obj", *torus((0.0, -0.2, 0.0), 0.8, 0.08, 70.0))
    write_obj("torus2.obj", *torus((0.0, -0.6, 0.0), 1.1, 0.12, 10.0))
    # the backdrop: a floor at y = -1.15 curving up into a wall at z = -2.5, uv over [0, 1]^2
    profile = [(-1.15, 3.0)] + [
        (-1.15 + 0.6 * (1 - math.cos(a)), -1.9 - 0.6 * math.sin(a)) for a in np.linspace(0, math.pi / 2, 8)
    ]
    profile += [(3.0, -2.5)]
    vertices, uvs, faces = [], [], []
    for i, (y, z) in enumerate(profile):
        for x in (-4.0, 4.0):
            vertices.append((x, y, z))
            uvs.append(((x + 4.0) / 8.0, i / (len(profile) - 1)))
    for i in range(len(profile) - 1):
        a = 2 * i
        faces += [(a, a + 1, a + 3), (a, a + 3, a + 2)]
    write_obj("background.obj", vertices, faces, uvs)


def environment_maps():
    """Two small HDR skies: a blue gradient with a warm sun, and a dimmer grey room-like one."""
    h, w = 32, 64
    theta = (np.arange(h) + 0.5) / h * math.pi
    phi = (np.arange(w) + 0.5) / w * 2 * math.pi
    up = np.cos(theta)[:, None] * np.ones(w)
    sky = np.stack([0.4 + 0.3 * up, 0.5 + 0.35 * up, 0.7 + 0.4 * up], axis=-1).clip(0.05)
    sun = np.exp(-(((theta[:, None] - 0.8) / 0.12) ** 2) - ((phi[None, :] - 2.0) / 0.2) ** 2)
    sky += sun[..., None] * np.array([20.0, 16.0, 10.0])
    (HERE / "textures").mkdir(exist_ok=True)
    write_image(str(HERE / "textures" / "envmap.exr"), sky.astype(np.float32))
    room = 0.3 + 0.2 * np.stack([np.sin(3 * phi)[None, :] * np.sin(theta)[:, None]] * 3, axis=-1)
    room[..., 0] += 0.1 * up
    write_image(str(HERE / "textures" / "museum.exr"), room.clip(0.02).astype(np.float32))


if __name__ == "__main__":
    grids()
    meshes()
    environment_maps()
