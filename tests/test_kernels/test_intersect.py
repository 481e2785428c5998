"""Ray-primitive intersections (kernels/intersect.py) through the real closest-hit kernel."""

import numpy as np
import pytest
from conftest import Tracer, make_scene

pytestmark = pytest.mark.usefixtures("device")  # every test on every available device

INF = np.inf


def one(shape):
    return Tracer(make_scene([shape]))


def test_sphere_known_t_outside_inside_behind():
    tr = one({"type": "sphere", "center": [0, 0, 0], "radius": 1.0})
    t, s = tr.closest([[0, 0, -5], [0, 0, 0], [0, 0, 5], [0, 1.0001, -5]], [[0, 0, 1]] * 4)
    assert t[0] == pytest.approx(4.0, rel=1e-7) and s[0] == 0
    assert t[1] == pytest.approx(1.0, rel=1e-7) and s[1] == 0  # from the centre: the far root
    assert t[2] == INF and s[2] == -1  # sphere behind the eye
    assert t[3] == INF and s[3] == -1  # passes just above


def test_sphere_non_unit_direction_scales_t():
    tr = one({"type": "sphere", "center": [0, 0, 0], "radius": 2.0})
    t, _ = tr.closest([[0, 0, -10]], [[0, 0, 4]])
    assert t[0] == pytest.approx(2.0, rel=1e-7)  # 8 units / |d| = 4


def test_sphere_far_away_matches_float64(rng):
    """Rays from 1e4 radii away toward a unit sphere: t within 4 float32 ulps of the float64 root."""
    n = 2000
    center = np.array([3.0, -2.0, 1.0])
    dirs = rng.normal(size=(n, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    targets = center + rng.uniform(-0.7, 0.7, size=(n, 3))
    origins = targets - 1e4 * dirs
    tr = one({"type": "sphere", "center": center.tolist(), "radius": 1.0})
    t, s = tr.closest(origins, dirs)
    o64, d64 = origins.astype(np.float32).astype(np.float64), dirs.astype(np.float32).astype(np.float64)
    f = o64 - center
    b = np.einsum("ij,ij->i", f, d64) / np.einsum("ij,ij->i", d64, d64)
    g = f - b[:, None] * d64
    disc = 1.0 - np.einsum("ij,ij->i", g, g)
    hit = disc >= 0
    t_ref = (-b - np.sqrt(np.maximum(disc, 0))) / 1.0
    assert np.array_equal(s == 0, hit)
    ulps = np.abs(t[hit] - t_ref[hit]) / np.spacing(t[hit])
    assert ulps.max() <= 4.0


def test_plane_hits_both_sides_and_rejects_parallel_and_behind():
    tr = one({"type": "plane", "point": [0, 2, 0], "normal": [0, 1, 0]})
    t, s = tr.closest([[0, 0, 0], [0, 5, 0], [0, 0, 0], [0, 0, 0]], [[0, 1, 0], [0, -1, 0], [1, 0, 0], [0, -1, 0]])
    assert t[0] == pytest.approx(2.0) and s[0] == 0
    assert t[1] == pytest.approx(3.0) and s[1] == 0
    assert t[2] == INF and t[3] == INF


def test_triangle_inside_edges_back_face_and_misses():
    tr = one({"type": "triangle", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]]})
    o = [
        [0.25, 0.25, 2],
        [0.25, 0.25, -2],
        [0.5, 0.5, 2],
        [0.0, 0.0, 2],
        [0.6, 0.6, 2],
        [-0.01, 0.5, 2],
        [0.25, 0.25, 2],
        [0, 0, 0],
    ]
    d = [[0, 0, -1], [0, 0, 1], [0, 0, -1], [0, 0, -1], [0, 0, -1], [0, 0, -1], [0, 0, 1], [1, 1, 0]]
    t, s = tr.closest(o, d)
    assert t[:4] == pytest.approx([2.0, 2.0, 2.0, 2.0]) and (s[:4] == 0).all()  # inside, back face, hypotenuse, vertex
    assert (t[4:] == INF).all()  # outside, just outside an edge, behind the eye, in the plane


def test_triangle_matches_float64_barycentric(rng):
    v = np.array([[0.3, -0.2, 1.0], [1.5, 0.4, 0.7], [0.1, 1.2, 1.4]])
    n = 4000
    bary = rng.uniform(-0.2, 1.0, size=(n, 2))
    points = v[0] + bary[:, :1] * (v[1] - v[0]) + bary[:, 1:] * (v[2] - v[0])
    origins = rng.normal(size=(n, 3)) * 3 + np.array([0, 0, 6])
    dirs = points - origins
    t, s = one({"type": "triangle", "vertices": v.tolist()}).closest(origins, dirs)
    inside = (bary >= 0).all(axis=1) & (bary.sum(axis=1) <= 1)
    margin = (np.abs(bary) > 1e-4).all(axis=1) & (np.abs(bary.sum(axis=1) - 1) > 1e-4)
    assert np.array_equal((s == 0)[margin], inside[margin])
    # t = 1 reaches the point; away from grazing incidence (ill-conditioned, see the stress suite)
    # float32 Cramer's rule keeps t to 1e-5
    normal = np.cross(v[1] - v[0], v[2] - v[0])
    cos = np.abs(dirs @ normal) / np.linalg.norm(dirs, axis=1) / np.linalg.norm(normal)
    assert np.abs(t[inside & margin & (cos > 0.1)] - 1.0).max() < 1e-5


STAR = [
    [0.0, 2.6, -2.0],
    [0.235, 1.924, -2.0],
    [0.951, 1.909, -2.0],
    [0.380, 1.476, -2.0],
    [0.588, 0.791, -2.0],
    [0.0, 1.2, -2.0],
    [-0.588, 0.791, -2.0],
    [-0.380, 1.476, -2.0],
    [-0.951, 1.909, -2.0],
    [-0.235, 1.924, -2.0],
]


def test_non_convex_polygon_point_in_polygon():
    tr = one({"type": "polygon", "vertices": STAR})
    inside = [[0.0, 1.6], [0.0, 2.4], [0.8, 1.88], [0.5, 0.9]]
    outside = [[0.0, 1.0], [0.5, 2.2], [0.6, 1.3], [2.0, 2.0]]  # notch under the centre, between arms, far
    xy = np.array(inside + outside)
    origins = np.column_stack([xy, np.full(len(xy), 3.0)])
    t, s = tr.closest(origins, [[0, 0, -1]] * len(xy))
    assert t[:4] == pytest.approx([5.0] * 4) and (s[:4] == 0).all()
    assert (s[4:] == -1).all()


def test_polygons_sharing_an_edge_take_every_ray_through_it_exactly_once(rng):
    """Two quads of a tilted plane share a slanted edge, and a closed box of six walls shares
    twelve: a ray aimed exactly at a shared edge or corner hits exactly one polygon of each
    pair/box (issue 13: the old per-polygon projection let rays leak and double-hit)."""
    frame = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    left = np.array([[-1.0, -1.0, 0], [0.3, -1.0, 0], [-0.2, 1.0, 0], [-1.0, 1.0, 0]]) @ frame.T
    right = np.array([[0.3, -1.0, 0], [1.0, -1.0, 0], [1.0, 1.0, 0], [-0.2, 1.0, 0]]) @ frame.T
    quads = [one({"type": "polygon", "vertices": q.tolist()}) for q in (left, right)]
    n = 4000
    target = left[1] + rng.random((n, 1)) * (left[2] - left[1])
    origin = target + rng.uniform(0.5, 3.0, (n, 1)) * (
        frame[:, 2] * np.where(rng.random((n, 1)) < 0.5, -1, 1) + 0.7 * rng.normal(size=(n, 3))
    )
    d = target - origin
    hits = sum((q.closest(origin, d)[1] != -1).astype(int) for q in quads)
    assert np.count_nonzero(hits != 1) == 0

    walls = []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            wall = np.zeros((4, 3))
            wall[:, axis] = sign
            wall[:, (axis + 1) % 3], wall[:, (axis + 2) % 3] = [-1, 1, 1, -1], [-1, -1, 1, 1]
            walls.append(one({"type": "polygon", "vertices": wall.tolist()}))
    corner = np.where(rng.random((n, 3)) < 0.5, -1.0, 1.0)
    on_edge = corner.copy()
    on_edge[np.arange(n), rng.integers(0, 3, n)] = rng.uniform(-1, 1, n)  # a point of an edge
    origin = rng.uniform(-0.5, 0.5, (n, 3))
    d = np.where(rng.random((n, 1)) < 0.2, corner, on_edge) - origin
    hits = sum((w.closest(origin, d)[1] != -1).astype(int) for w in walls)
    assert np.count_nonzero(hits != 1) == 0


def test_closest_of_several_and_t_window():
    shapes = [
        {"type": "sphere", "center": [0, 0, -3], "radius": 1.0},
        {"type": "sphere", "center": [0, 0, -8], "radius": 1.0},
        {"type": "plane", "point": [0, 0, -20], "normal": [0, 0, 1]},
    ]
    tr = Tracer(make_scene(shapes))
    t, s = tr.closest([[0, 0, 0]] * 3, [[0, 0, -1]] * 3, t_min=0.0)
    assert t[0] == pytest.approx(2.0) and s[0] == 0
    t, s = tr.closest([[0, 0, 0]], [[0, 0, -1]], t_min=4.5)  # skips the first sphere (both roots <= 4.5)
    assert t[0] == pytest.approx(7.0) and s[0] == 1
    t, s = tr.closest([[0, 0, 0]], [[0, 0, -1]], t_max=1.5)
    assert t[0] == pytest.approx(1.5) and s[0] == -1
    assert tr.occluded([[0, 0, 0]] * 2, [[0, 0, -1], [0, 0, 1]]).tolist() == [True, False]
