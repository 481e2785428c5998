"""Generate the bundled example meshes in this folder, deterministically and offline.

Run ``python examples/meshes/make_meshes.py`` to rewrite:

- ``torus_knot.ply``: a tube around a (2, 3) torus knot (trefoil), 128 000 triangles,
  binary little-endian PLY, centred at the origin with its largest extent 1.
- ``tetra.obj``: a regular tetrahedron with vertices at (+-0.5, +-0.5, +-0.5), 4 triangles.
- ``cube.stl``: the unit cube centred at the origin, 12 triangles, ASCII STL.

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


def main():
    """Write every example mesh into this script's folder."""
    write_torus_knot(HERE / "torus_knot.ply")
    (HERE / "tetra.obj").write_text(TETRA_OBJ)
    write_cube(HERE / "cube.stl")


if __name__ == "__main__":
    main()
