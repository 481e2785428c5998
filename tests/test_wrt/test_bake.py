"""The bake stage (wrt/bake.py): its float64 twin of the kernels' watertight triangle test gives
the kernel's answer, ray by ray, also through shared edges and vertices."""

import numpy as np
import pytest
import warp as wp
from wrt.kernels.intersect import intersect_triangle

from wrt.bake import watertight_crossings, watertight_hits

pytestmark = pytest.mark.usefixtures("device")  # every test on every available device


@wp.kernel
def kernel_hits(o: wp.vec3, d: wp.vec3, triangles: wp.array(dtype=wp.vec3), hits: wp.array(dtype=wp.int32)):
    i = wp.tid()
    t = intersect_triangle(o, d, triangles[3 * i], triangles[3 * i + 1], triangles[3 * i + 2], 0.0, wp.inf)
    hits[i] = wp.where(t < wp.inf, 1, 0)


def kernel_answer(o, d, triangles) -> np.ndarray:
    flat = wp.array(np.asarray(triangles, dtype=np.float32).reshape(-1, 3), dtype=wp.vec3)
    hits = wp.zeros(len(triangles), dtype=wp.int32)
    wp.launch(kernel_hits, dim=len(triangles), inputs=[wp.vec3(*o), wp.vec3(*d), flat, hits])
    return hits.numpy().astype(bool)


def grid(n: int, rng) -> np.ndarray:
    """A jittered n x n grid of unit squares at z = 0, two triangles each: (2 n^2, 3, 3)."""
    x, y = np.meshgrid(np.arange(n + 1, dtype=float), np.arange(n + 1, dtype=float))
    z = rng.uniform(-0.05, 0.05, x.shape)
    p = np.stack([x + rng.uniform(-0.2, 0.2, x.shape), y, z], axis=-1)
    a, b, c, e = p[:-1, :-1], p[:-1, 1:], p[1:, :-1], p[1:, 1:]
    return np.concatenate([np.stack([a, b, e], -2).reshape(-1, 3, 3), np.stack([a, e, c], -2).reshape(-1, 3, 3)])


def test_the_twin_answers_as_the_kernel_on_random_rays_and_through_vertices():
    rng = np.random.default_rng(7)
    triangles = grid(8, rng)
    vertices = triangles.reshape(-1, 3)
    disagree = hits = 0
    for k in range(300):
        o = np.array([rng.uniform(0, 8), rng.uniform(0, 8), rng.uniform(1, 5)])
        # aim at a vertex, an edge's midpoint or anywhere: the cases a crack would show in
        target = (vertices[k % len(vertices)], triangles[k % len(triangles), :2].mean(axis=0), rng.uniform(0, 8, 3))[
            k % 3
        ]
        d = (target - o) / np.linalg.norm(target - o)
        answer = kernel_answer(o, d, triangles)
        hits += np.count_nonzero(answer)
        disagree += np.count_nonzero(watertight_hits(o, d, triangles) != answer)
    assert disagree == 0 and hits > 100  # most rays aim at the grid: the comparison is not of misses only


def test_a_ray_from_inside_a_closed_mesh_crosses_it_an_odd_number_of_times():
    """A cube's 12 triangles seen from its centre (1 crossing) and from outside (0 or 2)."""
    corners = np.array([[x, y, z] for x in (0.0, 1.0) for y in (0.0, 1.0) for z in (0.0, 1.0)])
    faces = [
        (0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1),
        (2, 3, 7), (2, 7, 6), (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3),
    ]  # fmt: skip
    cube = corners[np.array(faces)]
    d = np.array([0.5773502691, 0.5773672691, 0.5773332691])
    assert watertight_crossings(np.array([0.5, 0.5, 0.5]), d, cube) == 1
    assert watertight_crossings(np.array([-1.0, -1.0, -1.0]), d, cube) == 2
    assert watertight_crossings(np.array([2.0, 2.0, 2.0]), d, cube) == 0
