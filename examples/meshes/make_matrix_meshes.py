"""Generate the meshes of the feature matrix's coverage scenes (``examples/matrix/``), deterministically
and offline.

Run ``python examples/meshes/make_matrix_meshes.py`` to rewrite:

- ``coarse_torus.obj``: the torus of ``coarse_torus.ply`` (radii 1 and 0.4 around the z axis, 12 x 8
  quads split into the same triangles, the same float32 vertices) without its normals, ASCII OBJ:
  smooth shading computes Mitsuba 3's angle-weighted vertex normals for it, 2.2 degrees from the
  PLY's exact ones on average (3.6 at most). The wrong variant of the matrix feature
  ``smooth_shading`` renders it in place of the PLY: a mesh whose own normals were lost.

Its triangles wind counter-clockwise seen from outside, as ``make_meshes.py``'s.
"""

from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


def write_coarse_torus_obj(source, path):
    """Write the vertices (as float32, exactly as the PLY holds them) and triangles of the binary
    PLY torus ``source`` (``make_meshes.write_coarse_torus``: ``x y z nx ny nz`` floats, then
    triangles as ``uchar`` counts and ``int`` indices) as an OBJ file without normals."""
    data = source.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode().split("\n")
    count = {line.split()[1]: int(line.split()[2]) for line in header if line.startswith("element")}
    rows = np.frombuffer(data, dtype=[("p", "<f4", 3), ("n", "<f4", 3)], count=count["vertex"], offset=end)
    tris = np.frombuffer(
        data, dtype=[("count", "u1"), ("ids", "<i4", 3)], count=count["face"], offset=end + rows.nbytes
    )
    lines = ["# Coarse torus (coarse_torus.ply) without normals: radii 1 and 0.4 around z, outward winding."]
    lines += [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in rows["p"].astype(np.float64)]
    lines += ["f " + " ".join(str(i + 1) for i in face) for face in tris["ids"]]
    path.write_text("\n".join(lines) + "\n")


def main():
    """Write the matrix's meshes into this script's folder."""
    write_coarse_torus_obj(HERE / "coarse_torus.ply", HERE / "coarse_torus.obj")


if __name__ == "__main__":
    main()
