"""What every stress case builds on: scenes built in memory, unit vectors, float32 rounding, and
the closed meshes the watertightness and self-intersection cases shoot at."""

from __future__ import annotations

import dataclasses

import numpy as np

from ..loader import parse_scene
from ..scene import Mesh

EPS32 = 2.0**-24  # float32 unit roundoff: |fl(x) - x| <= EPS32 |x|


# --- scenes and ray batches --------------------------------------------------------------------


def make_scene(shapes=(), meshes=(), materials=(), camera=None, render=None, lights=()):
    """A validated ``Scene`` from inline tables, plus meshes given as arrays.

    ``meshes``: ``(vertices (V, 3), faces (F, 3), material name or None)``; they follow the
    ``shapes`` in ``[[shape]]`` order (so their object ids come after).
    """
    doc = {
        "camera": camera or {"origin": [0.0, 0.0, 5.0], "look_at": [0.0, 0.0, 0.0]},
        "shape": list(shapes),
        "material": list(materials),
        "light": list(lights),
    }
    if render:
        doc["render"] = render
    scene = parse_scene(doc, file="<stress>")
    index = {m.name: i for i, m in enumerate(scene.materials)}
    extra = tuple(
        Mesh(
            file="<stress>",
            vertices=np.asarray(v, np.float64),
            faces=np.asarray(f, np.int32),
            material=index[m or "default"],
        )
        for v, f, m in meshes
    )
    return dataclasses.replace(scene, shapes=scene.shapes + extra)


def unit(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def random_directions(rng, n):
    return unit(rng.normal(size=(n, 3)))


def f32(a):
    """The float32 value of ``a``, as float64 (what the device holds)."""
    return np.asarray(a, np.float64).astype(np.float32).astype(np.float64)


# --- closed meshes -------------------------------------------------------------------------------


def uv_sphere(n_lon=64, n_lat=32):
    """Unit sphere as latitude/longitude quads split in two, with a triangle fan at each pole."""
    theta = np.linspace(0.0, np.pi, n_lat + 1)[1:-1]
    phi = np.linspace(0.0, 2.0 * np.pi, n_lon, endpoint=False)
    th, ph = np.meshgrid(theta, phi, indexing="ij")
    ring = np.column_stack([(np.sin(th) * np.cos(ph)).ravel(), np.cos(th).ravel(), (np.sin(th) * np.sin(ph)).ravel()])
    vertices = np.vstack([[0.0, 1.0, 0.0], ring, [0.0, -1.0, 0.0]])
    south = len(vertices) - 1
    j = np.arange(n_lon)
    jn = (j + 1) % n_lon

    def idx(i, k):
        return 1 + i * n_lon + k

    faces = [
        np.column_stack([np.zeros(n_lon, int), idx(0, jn), idx(0, j)]),
        np.column_stack([np.full(n_lon, south), idx(n_lat - 2, j), idx(n_lat - 2, jn)]),
    ]
    for i in range(n_lat - 2):
        a, b, c, d = idx(i, j), idx(i, jn), idx(i + 1, j), idx(i + 1, jn)
        faces += [np.column_stack([a, b, d]), np.column_stack([a, d, c])]
    return vertices, np.vstack(faces)


def split_cube(k=8):
    """Cube [-1, 1]^3, each face a k x k grid of squares split into two triangles (coplanar neighbours)."""
    grid = np.arange(k + 1)
    faces, keys = [], {}

    def vid(p):
        return keys.setdefault(tuple(int(c) for c in p), len(keys))

    for axis in range(3):
        u, v = (axis + 1) % 3, (axis + 2) % 3
        for side in (0, k):
            ids = np.empty((k + 1, k + 1), int)
            for a in grid:
                for b in grid:
                    p = np.zeros(3, int)
                    p[axis], p[u], p[v] = side, a, b
                    ids[a, b] = vid(p)
            q0, q1, q2, q3 = ids[:-1, :-1].ravel(), ids[1:, :-1].ravel(), ids[1:, 1:].ravel(), ids[:-1, 1:].ravel()
            tris = np.vstack([np.column_stack([q0, q1, q2]), np.column_stack([q0, q2, q3])])
            faces.append(tris if side == k else tris[:, ::-1])  # outward: (u, v, axis) is right-handed
    vertices = np.array(list(keys), dtype=np.float64) * (2.0 / k) - 1.0
    return vertices, np.vstack(faces)


def bicone_fan(n=256):
    """Two cones on a shared rim of ``n`` vertices: a fan of ``n`` needle-thin triangles around each apex."""
    phi = 2.0 * np.pi * np.arange(n) / n
    vertices = np.vstack([[0.0, 1.0, 0.0], [0.0, -1.0, 0.0], np.column_stack([np.cos(phi), np.zeros(n), np.sin(phi)])])
    j = 2 + np.arange(n)
    jn = 2 + (np.arange(n) + 1) % n
    faces = np.vstack([np.column_stack([np.zeros(n, int), jn, j]), np.column_stack([np.ones(n, int), j, jn])])
    return vertices, faces


CLOSED_MESHES = {"uv sphere 64x32": uv_sphere, "split cube 8x8": split_cube, "bicone fan 256": bicone_fan}
# (scale, offset): the unit mesh, and the mesh 100x larger 1e4 units from the origin
PLACEMENTS = ((1.0, np.zeros(3)), (100.0, np.array([1.0e4, -7.0e3, 3.0e3])))
