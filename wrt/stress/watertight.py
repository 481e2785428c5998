"""Watertightness: rays aimed at the shared edges and vertices of closed meshes must never slip
through (``docs/stress.md``)."""

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
