"""BVH build on the device (wrt/bvh.py, kernels/bvh_build.py) and traversal (kernels/traverse.py)
against brute force, the tree's invariants, and its quality against the binned-SAH reference."""

import numpy as np
import pytest
import warp as wp
from conftest import Tracer, make_scene
from wrt.kernels.bvh import MAX_LEAF, STACK_SIZE
from wrt.kernels.bvh_build import INTERSECTION_COST, TRAVERSAL_COST
from wrt_benchmarks.binned_sah import build_bvh as build_binned_sah
from wrt_benchmarks.binned_sah import sah_cost

from wrt.bvh import build_bvh, lane_bounds
from wrt.geometry import round_outward

pytestmark = pytest.mark.usefixtures("device")  # every test on every available device


def random_boxes(rng, n):
    """float32 boxes (rounded outward from float64 ones), as ``wrt.geometry`` hands them to the build."""
    c = rng.uniform(-10, 10, size=(n, 3))
    r = rng.uniform(0.0, 0.5, size=(n, 3))
    return round_outward(c - r, c + r)


def check_tree(bvh, lo, hi):
    """The invariants of a 4-wide BVH over float32 boxes ``lo``, ``hi``: every primitive listed
    once; depth-first numbering; each lane's box holds its subtree; leaves of 1..MAX_LEAF
    primitives; the stack need the build reports is the exact worst case, and within the
    traversal's stack. Returns the leaf sizes."""
    n = len(lo)
    nodes = bvh.nodes.numpy()
    order = bvh.order.numpy()
    assert np.array_equal(np.sort(order), np.arange(n))  # every primitive exactly once
    lane_lo, lane_hi = lane_bounds(nodes)
    child = nodes["child"]
    used = np.isfinite(lane_lo[..., 0])
    leaf_sizes = []
    need = np.zeros(len(nodes), dtype=np.int64)
    size = np.ones(len(nodes), dtype=np.int64)
    for w in range(len(nodes) - 1, -1, -1):  # children have larger indices: bottom up
        inner = [c for c in child[w][used[w]] if c >= 0]
        assert all(c > w for c in inner)
        if inner:
            # depth first: each inner child starts right after the previous one's subtree
            expected = w + 1
            for c in sorted(inner):
                assert c == expected
                expected += size[c]
            size[w] = 1 + sum(size[c] for c in inner)
        need[w] = used[w].sum() - 1 + max((need[c] for c in inner), default=0)
        for k in np.flatnonzero(used[w]):
            c = child[w][k]
            if c >= 0:  # the child node's lanes lie inside this lane
                kid = used[c]
                assert np.all(lane_lo[c][kid] >= lane_lo[w][k]) and np.all(lane_hi[c][kid] <= lane_hi[w][k])
            else:
                packed = -1 - c
                start, count = packed >> 3, packed & 7
                assert 1 <= count <= MAX_LEAF
                members = order[start : start + count]
                assert np.all(lo[members] >= lane_lo[w][k]) and np.all(hi[members] <= lane_hi[w][k])
                leaf_sizes.append(count)
    assert size[0] == len(nodes)
    assert need[0] == bvh.stats.stack_need <= STACK_SIZE
    assert sum(leaf_sizes) == n and len(leaf_sizes) == bvh.stats.leaves
    return np.array(leaf_sizes)


@pytest.mark.parametrize("n", [1, 2, 3, 5, 17, 1000, 20000])
def test_build_invariants(rng, n):
    lo, hi = random_boxes(rng, n)
    bvh = build_bvh(lo, hi, wp.get_device())
    assert bvh.stats.builder == "ploc"
    check_tree(bvh, lo, hi)


def test_build_is_deterministic(rng):
    lo, hi = random_boxes(rng, 5000)
    a, b = build_bvh(lo, hi, wp.get_device()), build_bvh(lo, hi, wp.get_device())
    assert np.array_equal(a.order.numpy(), b.order.numpy())
    assert a.nodes.numpy().tobytes() == b.nodes.numpy().tobytes()


def test_identical_boxes_still_cluster():
    """Ties of the nearest-neighbour search (equal union areas everywhere) still pair clusters up in
    many places at once, so the build ends in about log n iterations, not n."""
    lo = np.zeros((1000, 3), dtype=np.float32)
    bvh = build_bvh(lo, lo + 1.0, wp.get_device())
    sizes = check_tree(bvh, lo, lo + 1.0)
    assert sizes.max() <= MAX_LEAF
    assert bvh.stats.ploc_iterations < 40


def test_deep_tree_falls_back_to_the_balanced_tree():
    """Boxes at 2^k along a line make PLOC chain them one by one (each merge's nearest neighbour is the
    cluster of everything before it): a tree too deep for the traversal stack. The build detects it
    and builds the balanced tree, whose stack need is bounded by construction."""
    x = 2.0 ** np.arange(120)
    lo, hi = round_outward(
        np.stack([x, np.zeros_like(x), np.zeros_like(x)], axis=1),
        np.stack([x + 0.5, np.ones_like(x), np.ones_like(x)], axis=1),
    )
    bvh = build_bvh(lo, hi, wp.get_device())
    assert bvh.stats.builder == "balanced"
    check_tree(bvh, lo, hi)


def test_sah_cost_is_close_to_the_binned_sah_reference():
    """The PLOC tree of a closed mesh costs (SAH, same constants) at most a little more than the
    top-down binned-SAH tree of the reference builder, and leaves hold 1..4 triangles, about 2 on
    average."""
    from wrt_benchmarks.throughput import torus_mesh

    v, f = torus_mesh(20000)
    tri = v.astype(np.float32)[f]
    lo, hi = tri.min(axis=1), tri.max(axis=1)
    bvh = build_bvh(lo, hi, wp.get_device())
    sizes = check_tree(bvh, lo, hi)
    reference = sah_cost(
        build_binned_sah(lo.astype(np.float64), hi.astype(np.float64)), float(TRAVERSAL_COST), float(INTERSECTION_COST)
    )
    assert bvh.stats.sah_cost <= 1.1 * reference
    assert 1.5 <= sizes.mean() <= MAX_LEAF


def mixed_scene(rng, n_tris=6000, n_spheres=300):
    centers = rng.uniform(-5, 5, size=(n_tris, 3))
    tris = centers[:, None, :] + rng.normal(scale=0.3, size=(n_tris, 3, 3))
    shapes = [{"type": "plane", "point": [0, -6, 0], "normal": [0, 1, 0.1]}]
    shapes += [{"type": "triangle", "vertices": t.tolist()} for t in tris]
    shapes += [
        {"type": "sphere", "center": c.tolist(), "radius": float(r)}
        for c, r in zip(rng.uniform(-5, 5, (n_spheres, 3)), rng.uniform(0.05, 0.6, n_spheres))
    ]
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


def test_bounds_are_rounded_outward_not_to_nearest(rng):
    """float32 boxes hold the float64 ones (issue 13: nearest rounding could shave a sphere's or a
    moving primitive's extent by half an ulp, so rays grazing it skipped its node)."""
    lo = rng.uniform(-1e4, 1e4, (10_000, 3))
    hi = lo + rng.uniform(0.0, 1e-2, (10_000, 3))
    lo32, hi32 = round_outward(lo, hi)
    assert lo32.dtype == np.float32 and hi32.dtype == np.float32
    assert (lo32.astype(np.float64) <= lo).all() and (hi32.astype(np.float64) >= hi).all()
    nearest = lo.astype(np.float32).astype(np.float64)
    assert (nearest > lo).any()  # the case that matters occurs in this sample
