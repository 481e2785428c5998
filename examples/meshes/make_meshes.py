"""Generate the bundled example meshes in this folder, deterministically and offline.

Run ``python examples/meshes/make_meshes.py`` to rewrite:

- ``torus_knot.ply``: a tube around a (2, 3) torus knot (trefoil), 128 000 triangles,
  binary little-endian PLY, centred at the origin with its largest extent 1.
- ``tetra.obj``: a regular tetrahedron with vertices at (+-0.5, +-0.5, +-0.5), 4 triangles.
- ``cube.stl``: the unit cube centred at the origin, 12 triangles, ASCII STL.
- ``coarse_sphere.obj``: a unit UV sphere of 8 segments and 6 rings, quads and triangles at the
  poles, no normals (smooth shading computes them), ASCII OBJ.
- ``coarse_torus.ply``: a torus of radii 1 and 0.4, 12 x 8 quads split into triangles, with its
  exact (analytic) vertex normals ``nx ny nz``, binary little-endian PLY.
- ``painted_torus.ply``: the same torus at 36 x 12 quads with mesh attributes: a colour per
  vertex (``r g b``, a hue wheel, every other vertex darker) and a weight per face
  (``weight_x``, rings of 0.9 and 0.1).

Every mesh is a closed surface whose triangles wind counter-clockwise seen from outside
(normals point outward by the right-hand rule).
"""

from pathlib import Path

import numpy as np
import pyvista as pv

HERE = Path(__file__).resolve().parent

KNOT_SEGMENTS = 1000
"""Tube rings along the knot curve."""
KNOT_SIDES = 64
"""Vertices around each ring; the knot has 2 * KNOT_SEGMENTS * KNOT_SIDES triangles."""
KNOT_TUBE_RADIUS = 0.45
"""Tube radius before scaling, in the units of `knot_curve` (strands are >= 1.66 apart)."""

TETRA_OBJ = """\
# Regular tetrahedron, edge length sqrt(2), centred at the origin; outward (CCW) winding.
v 0.5 0.5 0.5
v 0.5 -0.5 -0.5
v -0.5 0.5 -0.5
v -0.5 -0.5 0.5
f 1 2 3
f 1 4 2
f 1 3 4
f 2 4 3
"""


def knot_curve(t):
    """The (2, 3) torus knot on a torus of radii 2 and 1, and its first two derivatives.

    Parameters
    ----------
    t : numpy.ndarray, shape (N,)
        Curve parameter in radians; the curve closes at ``t = 2 pi``.

    Returns
    -------
    tuple of numpy.ndarray, each shape (N, 3)
        Position c(t), velocity c'(t) and acceleration c''(t).
    """
    ring, d_ring, dd_ring = 2.0 + np.cos(3 * t), -3 * np.sin(3 * t), -9 * np.cos(3 * t)
    c2, s2 = np.cos(2 * t), np.sin(2 * t)
    position = np.stack([ring * c2, ring * s2, -np.sin(3 * t)], axis=-1)
    velocity = np.stack([d_ring * c2 - 2 * ring * s2, d_ring * s2 + 2 * ring * c2, -3 * np.cos(3 * t)], axis=-1)
    acceleration = np.stack(
        [
            dd_ring * c2 - 4 * d_ring * s2 - 4 * ring * c2,
            dd_ring * s2 + 4 * d_ring * c2 - 4 * ring * s2,
            9 * np.sin(3 * t),
        ],
        axis=-1,
    )
    return position, velocity, acceleration


def tube_vertices(segments, sides, radius):
    """Vertices of a tube of `radius` around `knot_curve`, ring by ring, in Frenet frames.

    Returns
    -------
    numpy.ndarray of float64, shape (segments * sides, 3)
        Vertex ``i * sides + j`` is on ring i (curve parameter ``2 pi i / segments``) at angle
        ``2 pi j / sides`` from the principal normal toward the binormal.
    """
    t = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)
    position, velocity, acceleration = knot_curve(t)
    tangent = velocity / np.linalg.norm(velocity, axis=1, keepdims=True)
    binormal = np.cross(velocity, acceleration)
    binormal /= np.linalg.norm(binormal, axis=1, keepdims=True)
    normal = np.cross(binormal, tangent)
    angle = np.linspace(0.0, 2.0 * np.pi, sides, endpoint=False)
    offset = np.cos(angle)[None, :, None] * normal[:, None] + np.sin(angle)[None, :, None] * binormal[:, None]
    return (position[:, None] + radius * offset).reshape(-1, 3)


def torus_grid_faces(segments, sides):
    """Triangles of a grid closed in both directions, wound outward for `tube_vertices`.

    Returns
    -------
    numpy.ndarray of int64, shape (2 * segments * sides, 3)
    """
    i, j = np.meshgrid(np.arange(segments), np.arange(sides), indexing="ij")
    here = i * sides + j
    next_side = i * sides + (j + 1) % sides
    next_ring = ((i + 1) % segments) * sides + j
    diagonal = ((i + 1) % segments) * sides + (j + 1) % sides
    lower = np.stack([here, next_side, diagonal], axis=-1)
    upper = np.stack([here, diagonal, next_ring], axis=-1)
    return np.concatenate([lower.reshape(-1, 3), upper.reshape(-1, 3)])


def centre_and_fit(vertices):
    """Translate the bounding box's centre to the origin and scale its largest side to 1."""
    low, high = vertices.min(axis=0), vertices.max(axis=0)
    return (vertices - (low + high) / 2) / (high - low).max()


def write_torus_knot(path):
    """Write the torus-knot tube as a binary little-endian PLY file."""
    vertices = centre_and_fit(tube_vertices(KNOT_SEGMENTS, KNOT_SIDES, KNOT_TUBE_RADIUS))
    faces = torus_grid_faces(KNOT_SEGMENTS, KNOT_SIDES)
    pv.PolyData.from_regular_faces(vertices, faces).save(path, binary=True, recompute_normals=False)


def write_cube(path):
    """Write the unit cube centred at the origin as a 12-triangle ASCII STL file."""
    pv.Cube().triangulate().save(path, binary=False, recompute_normals=False)


def write_coarse_sphere(path, segments=8, rings=6):
    """Write a unit UV sphere (poles on the z axis) as an OBJ file of quads, with triangle fans at
    the poles and no normals."""
    polar = np.pi * np.arange(1, rings) / rings
    azimuth = 2.0 * np.pi * np.arange(segments) / segments
    ring = np.stack(
        [
            np.outer(np.sin(polar), np.cos(azimuth)),
            np.outer(np.sin(polar), np.sin(azimuth)),
            np.outer(np.cos(polar), np.ones(segments)),
        ],
        axis=-1,
    ).reshape(-1, 3)
    vertices = np.concatenate([[[0.0, 0.0, 1.0]], ring, [[0.0, 0.0, -1.0]]])
    south = len(vertices)  # 1-based index of the south pole
    k = np.arange(segments)
    faces = [(1, 2 + j, 2 + (j + 1) % segments) for j in k]  # counter-clockwise seen from outside
    for i in range(rings - 2):
        top, bottom = 2 + i * segments, 2 + (i + 1) * segments
        faces += [(top + j, bottom + j, bottom + (j + 1) % segments, top + (j + 1) % segments) for j in k]
    last = 2 + (rings - 2) * segments
    faces += [(south, last + (j + 1) % segments, last + j) for j in k]
    lines = ["# Coarse unit UV sphere: quads, triangle fans at the poles, outward winding, no normals."]
    lines += [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in vertices]
    lines += ["f " + " ".join(map(str, face)) for face in faces]
    path.write_text("\n".join(lines) + "\n")


def torus(segments, sides, major, minor):
    """A torus around the z axis: vertices (V, 3), analytic unit normals (V, 3), outward
    triangles (F, 3) and each vertex's angle around the axis (V,), radians."""
    u = 2.0 * np.pi * np.arange(segments) / segments
    v = 2.0 * np.pi * np.arange(sides) / sides
    uu, vv = np.meshgrid(u, v, indexing="ij")
    normals = np.stack([np.cos(uu) * np.cos(vv), np.sin(uu) * np.cos(vv), np.sin(vv)], axis=-1).reshape(-1, 3)
    centres = np.stack([major * np.cos(uu), major * np.sin(uu), np.zeros_like(uu)], axis=-1).reshape(-1, 3)
    faces = torus_grid_faces(segments, sides)[:, [0, 2, 1]]  # outward for this parametrisation
    return centres + minor * normals, normals, faces, uu.reshape(-1)


def write_binary_ply(path, vertex_columns, faces, face_columns=None):
    """Write a binary little-endian PLY file of triangles ``faces`` (F, 3) and float properties:
    ``vertex_columns`` / ``face_columns`` map a property name to its (V,) / (F,) values."""
    face_columns = face_columns or {}
    rows = np.zeros(len(next(iter(vertex_columns.values()))), dtype=[(name, "<f4") for name in vertex_columns])
    for name, values in vertex_columns.items():
        rows[name] = values
    tris = np.zeros(len(faces), dtype=[("count", "u1"), ("ids", "<i4", 3)] + [(n, "<f4") for n in face_columns])
    tris["count"], tris["ids"] = 3, faces
    for name, values in face_columns.items():
        tris[name] = values
    header = (
        f"ply\nformat binary_little_endian 1.0\nelement vertex {len(rows)}\n"
        + "".join(f"property float {name}\n" for name in vertex_columns)
        + f"element face {len(faces)}\nproperty list uchar int vertex_indices\n"
        + "".join(f"property float {name}\n" for name in face_columns)
        + "end_header\n"
    )
    path.write_bytes(header.encode() + rows.tobytes() + tris.tobytes())


def write_coarse_torus(path, segments=12, sides=8, major=1.0, minor=0.4):
    """Write a torus around the z axis with its analytic unit vertex normals as a binary PLY file
    of triangles (``x y z nx ny nz`` floats)."""
    vertices, normals, faces, _ = torus(segments, sides, major, minor)
    write_binary_ply(path, dict(zip(("x", "y", "z", "nx", "ny", "nz"), [*vertices.T, *normals.T])), faces)


def write_painted_torus(path, segments=36, sides=12, major=1.0, minor=0.4):
    """Write a torus as `write_coarse_torus` does, with mesh attributes (Mitsuba 3's PLY naming):
    a colour per vertex (``r g b``, ``vertex_color``: a hue wheel around the axis, every other
    vertex of the grid at 40%, so that each triangle blends a light and a dark corner) and a
    weight per face (``weight_x``: 0.9 on every third ring of faces, else 0.1, ``face_weight``)."""
    vertices, normals, faces, angle = torus(segments, sides, major, minor)
    hue = angle[:, None] + np.array([0.0, 2.0, 4.0]) * np.pi / 3
    grid = np.arange(len(vertices))
    dark = (grid // sides + grid % sides) % 2 == 1
    colour = (0.15 + 0.7 * (0.5 + 0.5 * np.cos(hue))) * np.where(dark, 0.4, 1.0)[:, None]
    ring = faces[:, 0] // sides  # the segment a face lies in
    weight = np.where(ring % 3 == 0, 0.9, 0.1)
    columns = dict(zip(("x", "y", "z", "nx", "ny", "nz", "r", "g", "b"), [*vertices.T, *normals.T, *colour.T]))
    write_binary_ply(path, columns, faces, {"weight_x": weight})


def main():
    """Write every example mesh into this script's folder."""
    write_torus_knot(HERE / "torus_knot.ply")
    (HERE / "tetra.obj").write_text(TETRA_OBJ)
    write_cube(HERE / "cube.stl")
    write_coarse_sphere(HERE / "coarse_sphere.obj")
    write_coarse_torus(HERE / "coarse_torus.ply")
    write_painted_torus(HERE / "painted_torus.ply")


if __name__ == "__main__":
    main()
