"""Write ``sphere_attribute.ply`` for the mesh-attribute scenes of this suite, as Mitsuba 3's
own render tests make theirs (mitsuba-data ``tests/scenes/mesh_attributes/
generate_sphere_attribute.py``): a triangle mesh of the unit sphere given uniform random
attributes ``face_weight`` (1 field a face), ``face_color`` (3 a face) and ``vertex_color`` (3 a
vertex) and written by Mitsuba's own ``Mesh.write_ply`` (which names them ``weight_0``,
``color_0`` ... ``color_2``: the file wrt reads is the kind Mitsuba writes). Mitsuba's tests use
their ``common/meshes/sphere.ply``; this one is a UV sphere of 24 segments and 12 rings, seeded.

    python examples/mitsuba/suite/make_sphere_attribute.py
"""

from pathlib import Path

import mitsuba as mi
import numpy as np

SEGMENTS, RINGS, SEED = 24, 12, 3


def uv_sphere(segments: int, rings: int) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (V, 3) of the unit sphere (poles on z) and its triangles (F, 3), wound outward."""
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
    k, south = np.arange(segments), len(vertices) - 1
    faces = [np.stack([np.zeros(segments, int), 1 + k, 1 + (k + 1) % segments], axis=1)]
    for i in range(rings - 2):
        top, bottom = 1 + i * segments, 1 + (i + 1) * segments
        faces += [np.stack([top + k, bottom + k, bottom + (k + 1) % segments], axis=1)]
        faces += [np.stack([top + k, bottom + (k + 1) % segments, top + (k + 1) % segments], axis=1)]
    last = 1 + (rings - 2) * segments
    faces += [np.stack([np.full(segments, south), last + (k + 1) % segments, last + k], axis=1)]
    return vertices, np.concatenate(faces)


def main() -> None:
    mi.set_variant("scalar_rgb")
    vertices, faces = uv_sphere(SEGMENTS, RINGS)
    mesh = mi.Mesh("sphere", len(vertices), len(faces), has_vertex_normals=False)
    params = mi.traverse(mesh)
    params["vertex_positions"] = vertices.astype(np.float32).ravel().tolist()
    params["faces"] = faces.astype(np.uint32).ravel().tolist()
    params.update()
    rng = np.random.default_rng(SEED)
    mesh.add_attribute("face_weight", 1, rng.random(len(faces)).tolist())
    mesh.add_attribute("face_color", 3, rng.random(3 * len(faces)).tolist())
    mesh.add_attribute("vertex_color", 3, rng.random(3 * len(vertices)).tolist())
    mesh.write_ply(str(Path(__file__).resolve().parent / "sphere_attribute.ply"))


if __name__ == "__main__":
    main()
