"""Write ``sphere_attribute.ply`` for the mesh-attribute scenes of this suite, as Mitsuba 3's
own render tests make theirs (mitsuba-data ``tests/scenes/mesh_attributes/
generate_sphere_attribute.py``): a triangle mesh of the unit sphere given uniform random
attributes ``face_weight`` (1 field a face), ``face_color`` (3 a face) and ``vertex_color`` (3 a
vertex) and written by Mitsuba's own ``Mesh.write_ply`` (which names them ``weight_0``,
``color_0`` ... ``color_2``: the file wrt reads is the kind Mitsuba writes). Mitsuba's tests use
their ``common/meshes/sphere.ply``; this one is the participating-media stand-ins' UV sphere
(``make_assets.uv_sphere``) of radius 1, 24 segments and 12 rings, its attributes seeded.

    python examples/mitsuba/suite/make_sphere_attribute.py
"""

from pathlib import Path

import mitsuba as mi
import numpy as np
from wrt.examples.mitsuba.participating_media.make_assets import uv_sphere

SEGMENTS, RINGS, SEED = 24, 12, 3


def main() -> None:
    mi.set_variant("scalar_rgb")
    vertices, faces = (np.array(a) for a in uv_sphere((0.0, 0.0, 0.0), 1.0, rings=RINGS, segments=SEGMENTS))
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
