"""Emissive primitives sampled by next-event estimation: which they are and how one is chosen.

A triangle of a ``[[shape]]`` ``triangle`` or ``mesh``, a ``polygon`` or a ``sphere`` whose
material has a nonzero ``emission`` and which does not move is an *emitting primitive*: the path
integrator samples one of them per next-event estimation, chosen by emitted power (area times
the emission's luminance: a surface of area A emitting L from one side sends ``pi A L`` W; a
sphere's area is ``4 pi r^2``, emitting outward), weighted against BSDF sampling by the power
heuristic. On a triangle it samples a uniform point; on a polygon a uniform point too, in one
triangle of its ear-clipping triangulation chosen by area; toward a sphere a direction uniform
in the cone it subtends (none from inside it). Primitives of groups' shapes (seen through
instances) and of moving shapes, self-intersecting polygons, and the other emissive shapes
(planes, disks, cylinders) are found by BSDF sampling only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wrt.kernels.film import LUMINANCE_WEIGHTS
from wrt.kernels.traverse import POLYGON, SPHERE, TRIANGLE

from .geometry import Primitives
from .scene import Mesh, Polygon, Scene, Sphere, Triangle


@dataclass
class EmittingPrimitives:
    """The pool of emitting primitives, E of them, in triangles, polygons, spheres order.

    ``kind``: (E,) int32 ``TRIANGLE``, ``POLYGON`` or ``SPHERE`` (``wrt.kernels.traverse``);
    ``prim``: (E,) int32 index in its kind's arrays of ``Primitives``; ``cdf``: (E + 1,) float32
    running sums of their selection probabilities, 0 to exactly 1; ``area``: (E,) float32 area
    (m^2; a sphere's whole surface); ``first``: (E + 1,) int32 the polygons' triangles,
    ``first[e]`` to ``first[e + 1]`` in ``corners`` (none for other kinds); ``corners``: (K, 3, 3)
    float32 those triangles; ``area_cdf``: (K,) float32 per polygon its triangles' running area
    fractions, the last exactly 1; ``of_triangle``, ``of_polygon``, ``of_sphere``: per primitive
    of ``Primitives`` its index in the pool, -1 for the others."""

    kind: np.ndarray
    prim: np.ndarray
    cdf: np.ndarray
    area: np.ndarray
    first: np.ndarray
    corners: np.ndarray
    area_cdf: np.ndarray
    of_triangle: np.ndarray
    of_polygon: np.ndarray
    of_sphere: np.ndarray


def emitting_shapes(scene: Scene, kinds: tuple = (Mesh, Triangle, Polygon, Sphere)) -> set[int]:
    """Indices of the ``[[shape]]``s of ``kinds`` whose primitives are sampled as emitters."""
    return {
        i
        for i, shape in enumerate(scene.shapes)
        if isinstance(shape, kinds) and not any(shape.velocity) and max(scene.materials[shape.material].emission) > 0.0
    }


def _luminance(scene: Scene, shape_ids: np.ndarray) -> np.ndarray:
    emission = np.asarray([scene.materials[scene.shapes[s].material].emission for s in shape_ids], dtype=np.float64)
    return emission.reshape(-1, 3) @ np.asarray(LUMINANCE_WEIGHTS)


def _segments_cross(a, b, c, d) -> bool:
    """Whether 2D segments ab and cd cross or touch (collinear overlaps included)."""

    def orient(p, q, r):
        return np.sign((q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]))

    o1, o2, o3, o4 = orient(a, b, c), orient(a, b, d), orient(c, d, a), orient(c, d, b)
    if o1 != o2 and o3 != o4:
        return True

    def within(p, q, r):  # r on segment pq, given collinear
        return min(p[0], q[0]) <= r[0] <= max(p[0], q[0]) and min(p[1], q[1]) <= r[1] <= max(p[1], q[1])

    return (
        (o1 == 0 and within(a, b, c))
        or (o2 == 0 and within(a, b, d))
        or (o3 == 0 and within(c, d, a))
        or (o4 == 0 and within(c, d, b))
    )


def _is_simple(xy: np.ndarray) -> bool:
    """Whether the closed 2D polygon ``xy`` (n, 2) has no two non-adjacent edges that meet."""
    n = len(xy)
    for i in range(n):
        for j in range(i + 2, n):
            if i == 0 and j == n - 1:
                continue
            if _segments_cross(xy[i], xy[(i + 1) % n], xy[j], xy[(j + 1) % n]):
                return False
    return True


def triangulate(vertices: np.ndarray, normal: np.ndarray) -> np.ndarray | None:
    """Ear-clipping triangulation of a simple planar polygon: (n - 2, 3) vertex indices, or None
    for a self-intersecting one."""
    s = np.cross(normal, [1.0, 0.0, 0.0] if abs(normal[0]) < 0.9 else [0.0, 1.0, 0.0])
    s /= np.linalg.norm(s)
    xy = np.stack([vertices @ s, vertices @ np.cross(normal, s)], axis=1)  # counterclockwise seen from the normal
    if not _is_simple(xy):
        return None

    def cross(o, a, b):
        return (xy[a, 0] - xy[o, 0]) * (xy[b, 1] - xy[o, 1]) - (xy[a, 1] - xy[o, 1]) * (xy[b, 0] - xy[o, 0])

    left = list(range(len(xy)))
    if sum(cross(0, left[k], left[k + 1]) for k in range(1, len(left) - 1)) < 0.0:
        left.reverse()
    triangles = []
    while len(left) > 3:
        n = len(left)
        for k in range(n):
            a, b, c = left[k - 1], left[k], left[(k + 1) % n]
            if cross(a, b, c) <= 0.0:
                continue
            others = (v for v in left if v not in (a, b, c))
            if any(cross(a, b, v) >= 0.0 and cross(b, c, v) >= 0.0 and cross(c, a, v) >= 0.0 for v in others):
                continue
            break
        else:  # only degenerate (collinear) corners left: clip any
            k = 0
            a, b, c = left[-1], left[0], left[1]
        triangles.append((a, b, c))
        del left[k]
    triangles.append(tuple(left))
    return np.asarray(triangles, dtype=np.int64)


def emitting_primitives(scene: Scene, prims: Primitives) -> EmittingPrimitives:
    """The emitting primitives of ``scene`` (flattened as ``prims``) and their power distribution."""
    shapes = sorted(emitting_shapes(scene))
    tri = np.flatnonzero(np.isin(prims.tri_shape, shapes))
    v = prims.tri_verts[tri].astype(np.float64)
    tri_area = 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1)

    poly, poly_area, poly_corners, poly_cdf = [], [], [], []
    for i in np.flatnonzero(np.isin(prims.poly_shape, shapes)):
        verts = np.asarray(prims.poly_verts[i], dtype=np.float64)
        triangles = triangulate(verts, np.asarray(prims.poly_normal[i], dtype=np.float64))
        if triangles is None:
            continue
        corners = verts[triangles]
        areas = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
        if areas.sum() <= 0.0:
            continue
        cdf = np.cumsum(areas) / areas.sum()
        cdf[-1] = 1.0
        poly.append(i)
        poly_area.append(areas.sum())
        poly_corners.append(corners)
        poly_cdf.append(cdf)

    sphere = np.flatnonzero(np.isin(prims.sphere_shape, shapes))
    sphere_area = 4.0 * np.pi * np.asarray(prims.sphere_radius, dtype=np.float64)[sphere] ** 2

    kind = np.concatenate([np.full(len(tri), TRIANGLE), np.full(len(poly), POLYGON), np.full(len(sphere), SPHERE)])
    prim = np.concatenate([tri, np.asarray(poly, dtype=np.int64), sphere]).astype(np.int32)
    area = np.concatenate([tri_area, poly_area, sphere_area])
    shape_of = np.concatenate(
        [
            prims.tri_shape[tri],
            np.asarray(prims.poly_shape)[np.asarray(poly, dtype=np.int64)],
            prims.sphere_shape[sphere],
        ]
    )
    power = area * _luminance(scene, shape_of)
    keep = power > 0.0  # degenerate primitives are never chosen: BSDF sampling finds nothing there
    counts = np.zeros(len(kind), dtype=np.int64)
    counts[len(tri) : len(tri) + len(poly)] = [len(c) for c in poly_corners]
    kind, prim, area, power, counts = kind[keep], prim[keep], area[keep], power[keep], counts[keep]
    kept_polys = keep[len(tri) : len(tri) + len(poly)]

    pool = np.arange(len(kind), dtype=np.int32)
    of = {}
    for k, n in ((TRIANGLE, len(prims.tri_shape)), (POLYGON, len(prims.poly_shape)), (SPHERE, len(prims.sphere_shape))):
        of[k] = np.full(n, -1, dtype=np.int32)
        of[k][prim[kind == k]] = pool[kind == k]
    cdf = np.concatenate([[0.0], np.cumsum(power)])
    cdf = cdf / cdf[-1] if len(kind) else np.zeros(1)
    cdf[-1] = 1.0
    corners = [c for c, kept in zip(poly_corners, kept_polys) if kept]
    area_cdf = [c for c, kept in zip(poly_cdf, kept_polys) if kept]
    return EmittingPrimitives(
        kind=kind.astype(np.int32),
        prim=prim,
        cdf=cdf.astype(np.float32),
        area=area.astype(np.float32),
        first=np.concatenate([[0], np.cumsum(counts)]).astype(np.int32),
        corners=np.concatenate(corners).astype(np.float32) if corners else np.zeros((0, 3, 3), np.float32),
        area_cdf=np.concatenate(area_cdf).astype(np.float32) if area_cdf else np.zeros(0, np.float32),
        of_triangle=of[TRIANGLE],
        of_polygon=of[POLYGON],
        of_sphere=of[SPHERE],
    )
