"""Emissive triangles sampled by next-event estimation: which they are and how one is chosen.

A triangle of a ``[[shape]]`` (``triangle`` or ``mesh``) whose material has a nonzero
``emission`` and which does not move is an *emitting triangle*: the path integrator samples one
of them per next-event estimation, chosen by emitted power (area times the emission's luminance:
a uniformly emitting triangle of area A sends ``pi A L`` W), then a uniform point on it, weighted
against BSDF sampling by the power heuristic. Triangles of groups' shapes (seen through
instances) and of moving shapes, and the other emissive shapes (spheres, polygons, disks,
cylinders), are found by BSDF sampling only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wrt.kernels.film import LUMINANCE_WEIGHTS

from .geometry import Primitives
from .scene import Mesh, Scene, Triangle


@dataclass
class EmittingTriangles:
    """``tri``: (E,) int32 indices into ``Primitives.tri_verts`` of the emitting triangles;
    ``cdf``: (E + 1,) float32 running sums of their selection probabilities, 0 to exactly 1;
    ``of_triangle``: (T,) int32 per triangle its emitting index, -1 for the others."""

    tri: np.ndarray
    cdf: np.ndarray
    of_triangle: np.ndarray


def emitting_shapes(scene: Scene) -> set[int]:
    """Indices of the ``[[shape]]``s whose triangles are sampled as emitters."""
    return {
        i
        for i, shape in enumerate(scene.shapes)
        if isinstance(shape, (Mesh, Triangle))
        and not any(shape.velocity)
        and max(scene.materials[shape.material].emission) > 0.0
    }


def emitting_triangles(scene: Scene, prims: Primitives) -> EmittingTriangles:
    """The emitting triangles of ``scene`` (flattened as ``prims``) and their power distribution."""
    shapes = emitting_shapes(scene)
    of_triangle = np.full(len(prims.tri_shape), -1, dtype=np.int32)
    tri = np.flatnonzero(np.isin(prims.tri_shape, sorted(shapes))).astype(np.int32)
    v = prims.tri_verts[tri].astype(np.float64)
    area = 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1)
    emission = np.asarray([scene.materials[scene.shapes[s].material].emission for s in prims.tri_shape[tri]])
    power = area * (emission.reshape(-1, 3) @ np.asarray(LUMINANCE_WEIGHTS))
    keep = power > 0.0  # degenerate triangles are never chosen: BSDF sampling finds nothing there
    tri = tri[keep]
    power = power[keep]
    of_triangle[tri] = np.arange(len(tri), dtype=np.int32)
    cdf = np.concatenate([[0.0], np.cumsum(power)])
    cdf = cdf / cdf[-1] if len(tri) else np.zeros(1)
    cdf[-1] = 1.0
    return EmittingTriangles(tri=tri, cdf=cdf.astype(np.float32), of_triangle=of_triangle)
