"""BVH build (wrt/bvh.py) and traversal (kernels/traverse.py) against brute force."""
import numpy as np
import pytest

from conftest import Tracer, make_scene
from wrt.bvh import MAX_DEPTH, build_bvh


def random_boxes(rng, n):
    c = rng.uniform(-10, 10, size=(n, 3))
    r = rng.uniform(0.0, 0.5, size=(n, 3))
    return c - r, c + r


@pytest.mark.parametrize("n", [1, 2, 3, 17, 1000, 20000])
def test_build_invariants(rng, n):
    lo, hi = random_boxes(rng, n)
    bvh = build_bvh(lo, hi)
    assert np.array_equal(np.sort(bvh.order), np.arange(n))  # every primitive exactly once
    inner = np.flatnonzero(bvh.count == 0)
    leaves = np.flatnonzero(bvh.count > 0)
    for node in inner:  # children adjacent, inside their parent
        kids = [bvh.start[node], bvh.start[node] + 1]
        assert (bvh.lo[kids] >= bvh.lo[node]).all() and (bvh.hi[kids] <= bvh.hi[node]).all()
    for node in leaves:  # a leaf's box holds its primitives
        members = bvh.order[bvh.start[node] : bvh.start[node] + bvh.count[node]]
        assert (lo[members] >= bvh.lo[node]).all() and (hi[members] <= bvh.hi[node]).all()
    assert bvh.count[leaves].sum() == n
    assert bvh.depth <= MAX_DEPTH


def test_identical_centroids_are_still_split():
    lo = np.zeros((100, 3))
    bvh = build_bvh(lo, lo + 1.0)
    assert bvh.count.max() <= 4 and np.array_equal(np.sort(bvh.order), np.arange(100))


def mixed_scene(rng, n_tris=6000, n_spheres=300):
    centers = rng.uniform(-5, 5, size=(n_tris, 3))
    tris = centers[:, None, :] + rng.normal(scale=0.3, size=(n_tris, 3, 3))
    shapes = [{"type": "plane", "point": [0, -6, 0], "normal": [0, 1, 0.1]}]
    shapes += [{"type": "triangle", "vertices": t.tolist()} for t in tris]
    shapes += [{"type": "sphere", "center": c.tolist(), "radius": float(r)} for c, r in zip(rng.uniform(-5, 5, (n_spheres, 3)), rng.uniform(0.05, 0.6, n_spheres))]
    square = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [0, 0.2, 0], [-1, 1, 0]], dtype=float)  # non-convex
    shapes += [{"type": "polygon", "vertices": (square * 0.8 + c).tolist()} for c in rng.uniform(-5, 5, (50, 3))]
    return make_scene(shapes)


def random_rays(rng, n, spread=8.0):
    origins = rng.uniform(-spread, spread, size=(n, 3))
    dirs = rng.normal(size=(n, 3))
    return origins, dirs / np.linalg.norm(dirs, axis=1, keepdims=True)


def test_bvh_matches_brute_force_on_mixed_scene(rng):
    """Thousands of random rays through a tree of triangles, spheres and polygons, plus a plane."""
    tr = Tracer(mixed_scene(rng))
    origins, dirs = random_rays(rng, 4096)
    t, shape = tr.closest(origins, dirs)
    t_ref, shape_ref = tr.closest(origins, dirs, brute_force=True)
    assert (shape >= 0).mean() > 0.5  # the test exercises hits, not only misses
    assert np.array_equal(shape, shape_ref)
    hit = shape >= 0
    np.testing.assert_allclose(t[hit], t_ref[hit], rtol=1e-5)
    assert np.array_equal(tr.occluded(origins, dirs), hit)
    # a bounded query window: any-hit agrees with closest-hit inside it
    assert np.array_equal(tr.occluded(origins, dirs, t_max=2.0), t < 2.0)


def test_bvh_matches_brute_force_on_bundled_mesh(rng):
    """The 100k+ triangle torus knot: rays from outside toward it, and from inside its bounds."""
    scene = make_scene([{"type": "mesh", "file": "examples/meshes/torus_knot.ply"}], scene_dir=".")
    tr = Tracer(scene)
    n = 256
    origins, dirs = random_rays(rng, n, spread=2.0)
    targets = tr.prims.tri_verts[rng.integers(0, len(tr.prims.tri_verts), n), 0]  # aim at the surface
    dirs[: n // 2] = targets[: n // 2] - origins[: n // 2]
    t, shape = tr.closest(origins, dirs)
    t_ref, shape_ref = tr.closest(origins, dirs, brute_force=True)
    assert (shape == 0).sum() > n // 4
    assert np.array_equal(shape, shape_ref)
    np.testing.assert_allclose(t[shape >= 0], t_ref[shape >= 0], rtol=1e-5)


def test_axis_aligned_rays_with_zero_components(rng):
    """Directions with zero (and negative-zero) components: the slab test must not produce NaN culls."""
    tr = Tracer(mixed_scene(rng, n_tris=500, n_spheres=50))
    axes = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1], [-0.0, -0.0, 1.0]])
    origins = rng.uniform(-6, 6, size=(700, 3))
    dirs = axes[np.arange(700) % len(axes)]
    t, shape = tr.closest(origins, dirs)
    t_ref, shape_ref = tr.closest(origins, dirs, brute_force=True)
    assert np.array_equal(shape, shape_ref)
    np.testing.assert_allclose(t[shape >= 0], t_ref[shape >= 0], rtol=1e-5)
