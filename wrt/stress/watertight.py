"""Watertightness: rays aimed at the shared edges and vertices of closed meshes must never slip
through, and rays at the edges polygons share must hit exactly one of them (``docs/stress.md``)."""

from __future__ import annotations

import numpy as np

from ..kernels.traverse import NO_HIT
from ..trace import Tracer
from .common import CLOSED_MESHES, PLACEMENTS, make_scene, random_directions, unit
from .report import CaseResult


def _edge_targets(vertices, faces, n, rng, vertex_share=0.2):
    """Points exactly on shared edges (float64 lerps) and at vertices of a mesh: ``n`` of them."""
    edges = np.unique(np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1), axis=0)
    pick = edges[rng.integers(0, len(edges), n)]
    s = rng.random(n)[:, None]
    s[: int(n * vertex_share)] = 0.0
    return vertices[pick[:, 0]] + s * (vertices[pick[:, 1]] - vertices[pick[:, 0]])


def watertight_case(name, vertices, faces, rays, rng) -> CaseResult:
    """Rays aimed exactly at shared edges and vertices of a closed convex mesh must hit it.

    Half the rays start inside (random points of the ball of radius 0.5 around the centre): any
    miss is a leak. Half start outside and enter through the target: their first hit must be
    the target (t = distance to it, +1e-3 of the mesh size); a miss or a later hit is a leak.
    Half the rays of each kind use the unit mesh, half a copy 100x larger 1e4 units away.
    """
    leaks = {"inside": 0, "outside": 0}
    shot = 0
    for scale, offset in PLACEMENTS:
        v = vertices * scale + offset
        tracer = Tracer(make_scene(meshes=[(v, faces, None)]))
        n = max(rays // (2 * len(PLACEMENTS)), 1)
        for kind in leaks:
            target = _edge_targets(v, faces, n, rng)
            if kind == "inside":
                inner = offset + 0.5 * scale * random_directions(rng, n) * rng.random((n, 1)) ** (1 / 3)
                d = unit(target - inner)
                _, prim = tracer.closest(inner, d)
                leaks[kind] += int(np.count_nonzero(prim == NO_HIT))
            else:
                inner = offset + 0.5 * scale * random_directions(rng, n) * rng.random((n, 1)) ** (1 / 3)
                d = unit(inner - target)
                distance = 3.0 * scale
                t, prim = tracer.closest(target - distance * d, d)
                leaks[kind] += int(np.count_nonzero((prim == NO_HIT) | (t > distance + 1e-3 * scale)))
            shot += n
    return CaseResult(
        f"watertight: {name}",
        shot,
        leaks["inside"] + leaks["outside"],
        unit="leaks",
        detail={"leaks_from_inside": leaks["inside"], "leaks_from_outside": leaks["outside"]},
    )


def case_watertight(rays, rng):
    return [watertight_case(name, *make(), rays, rng) for name, make in CLOSED_MESHES.items()]


def polygon_box():
    """The six walls of the cube [-1, 1]^3 as 4-vertex polygons, alternate walls wound the other
    way (a polygon has no front: the winding must not matter), and its 12 edges and 8 corners."""
    walls = []
    for axis in range(3):
        b, c = (axis + 1) % 3, (axis + 2) % 3
        for k, sign in enumerate((1.0, -1.0)):
            wall = np.zeros((4, 3))
            wall[:, axis] = sign
            wall[:, b], wall[:, c] = zip(*[(-1, -1), (1, -1), (1, 1), (-1, 1)])
            walls.append(wall if (axis + k) % 2 else wall[::-1])
    corners = np.array([[x, y, z] for x in (-1.0, 1.0) for y in (-1.0, 1.0) for z in (-1.0, 1.0)])
    edges = [(i, j) for i in range(8) for j in range(i + 1, 8) if np.count_nonzero(corners[i] != corners[j]) == 1]
    return walls, corners, np.array(edges)


def slanted_fan(n=6):
    """A regular ``n``-gon in a tilted plane, cut into ``n`` triangles around its centre (coplanar
    neighbours sharing slanted edges and one vertex), and those inner edges."""
    frame = np.linalg.qr(np.array([[1.0, 0.3, 0.2], [0.2, 1.0, -0.4], [0.5, -0.3, 1.0]]))[0]
    phi = 2.0 * np.pi * (np.arange(n) + 0.37) / n
    rim = np.column_stack([np.cos(phi), np.sin(phi), np.zeros(n)]) @ frame.T
    points = np.vstack([np.zeros(3), rim])
    walls = [np.array([points[0], points[1 + k], points[1 + (k + 1) % n]]) for k in range(n)]
    edges = np.array([(0, 1 + k) for k in range(n)])
    return walls, points, edges, frame[:, 2]


def count_hits(tracers, origins, directions):
    """How many of the polygons (one tracer each) each ray hits."""
    return sum((tracer.closest(origins, directions)[1] != NO_HIT).astype(int) for tracer in tracers)


def polygon_case(name, rays, rng) -> CaseResult:
    """Rays aimed exactly at the edges and vertices polygons share must hit exactly one of them.

    ``box``: the six walls of a cube, from random points of the ball of radius 0.5 inside it,
    aimed at its edges and corners (20%): every ray leaves through one wall. ``fan``: six coplanar
    triangles around a vertex of a tilted plane, from random points 0.5-2 away on either side,
    aimed at their shared edges (the inner 90%: the rim is no one's neighbour) and the centre
    (20%). Each polygon is traced alone and the hits counted: 0 is a leak, 2 a double hit. Unit
    size at the origin, and 100x larger 1e4 units away."""
    leaks, doubles, shot = 0, 0, 0
    for scale, offset in PLACEMENTS:
        if name == "box":
            walls, points, edges = polygon_box()
        else:
            walls, points, edges, normal = slanted_fan()
        walls = [w * scale + offset for w in walls]
        points = points * scale + offset
        tracers = [Tracer(make_scene(shapes=[{"type": "polygon", "vertices": w.tolist()}])) for w in walls]
        n = max(rays // len(PLACEMENTS), 1)
        pick = edges[rng.integers(0, len(edges), n)]
        s = rng.random(n)[:, None] * (1.0 if name == "box" else 0.9)  # the fan's rim is not shared
        s[: int(n * 0.2)] = 0.0
        target = points[pick[:, 0]] + s * (points[pick[:, 1]] - points[pick[:, 0]])
        if name == "box":
            origin = offset + 0.5 * scale * random_directions(rng, n) * rng.random((n, 1)) ** (1 / 3)
        else:
            side = np.where(rng.random(n) < 0.5, -1.0, 1.0)[:, None]
            away = unit(normal + 0.8 * random_directions(rng, n))  # within 80 degrees of the normal
            origin = target + side * scale * rng.uniform(0.5, 2.0, (n, 1)) * away
        hits = count_hits(tracers, origin, unit(target - origin))
        leaks += int(np.count_nonzero(hits == 0))
        doubles += int(np.count_nonzero(hits > 1))
        shot += n
    return CaseResult(
        f"watertight polygons: {name}",
        shot,
        leaks + doubles,
        unit="leaks + double hits",
        detail={"leaks": leaks, "double_hits": doubles},
    )


def case_watertight_polygons(rays, rng):
    return [polygon_case(name, rays, rng) for name in ("box", "fan")]
