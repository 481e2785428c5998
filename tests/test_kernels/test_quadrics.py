"""Disks and cylinders (kernels/intersect.py ``intersect_disk``, ``intersect_cylinder``; their
``surface_point`` in kernels/traverse.py; their BVH boxes in wrt/geometry.py) against float64
closed forms: random affine placements (rotation, non-uniform scale, shear), rays near, far,
grazing and from inside, spawned rays that never fall back onto the surface they leave."""

import numpy as np
import pytest
import warp as wp
from conftest import make_scene
from wrt.kernels.features import Features
from wrt.kernels.intersect import intersect_cylinder, intersect_disk
from wrt.kernels.traverse import CYLINDER, DISK, KIND_BITS, KIND_MASK, NO_HIT, GeometryData, traversal

from wrt.renderer import scene_features
from wrt.stress.offsets import trace_spawned_batch
from wrt.trace import Tracer, vec3_array

pytestmark = pytest.mark.usefixtures("device")  # every test on every available device

SHAPES = {"disk": intersect_disk, "cylinder": intersect_cylinder}


@wp.kernel
def quadric_rays(
    cylinder: wp.int32,
    to_object: wp.array(dtype=wp.mat44),
    origins: wp.array(dtype=wp.vec3),
    directions: wp.array(dtype=wp.vec3),
    t_min: float,
    out_t: wp.array(dtype=float),
):
    i = wp.tid()
    if cylinder != 0:
        out_t[i] = intersect_cylinder(origins[i], directions[i], to_object[i], t_min, wp.inf)
    else:
        out_t[i] = intersect_disk(origins[i], directions[i], to_object[i], t_min, wp.inf)


def trace_quadric(kind, to_object, origins, directions, t_min=0.0):
    """The kernel's ``t`` (inf on a miss) of each ray against the shape whose world -> object map
    (float32, as the device holds it) is ``to_object[i]``."""
    device = wp.get_device()
    t = wp.zeros(len(origins), dtype=float, device=device)
    inputs = [
        int(kind == "cylinder"),
        wp.array(np.asarray(to_object, np.float32), dtype=wp.mat44, device=device),
        vec3_array(origins, device),
        vec3_array(directions, device),
        float(t_min),
        t,
    ]
    wp.launch(quadric_rays, dim=len(origins), inputs=inputs, device=device)
    return t.numpy()


def reference(kind, to_object, o, d):
    """float64 closed form of the float32 inputs: ``(t, margin)``, ``t`` the nearest hit with
    ``t > 0`` (inf on a miss) and ``margin`` how far (relative, object space) the decisive test
    was from flipping: the rim for a disk; tangency and the end rims for a tube."""
    a = np.asarray(to_object, np.float32).astype(np.float64)
    o, d = (np.asarray(x, np.float32).astype(np.float64) for x in (o, d))
    o2 = np.einsum("nij,nj->ni", a[:, :3, :3], o) + a[:, :3, 3]
    d2 = np.einsum("nij,nj->ni", a[:, :3, :3], d)
    with np.errstate(divide="ignore", invalid="ignore"):
        if kind == "disk":
            t = -o2[:, 2] / d2[:, 2]
            p = o2 + t[:, None] * d2
            r2 = p[:, 0] ** 2 + p[:, 1] ** 2
            return np.where((t > 0) & (r2 <= 1.0), t, np.inf), np.abs(r2 - 1.0)
        qa = d2[:, 0] ** 2 + d2[:, 1] ** 2
        qb = o2[:, 0] * d2[:, 0] + o2[:, 1] * d2[:, 1]
        g = o2[:, :2] - (qb / qa)[:, None] * d2[:, :2]
        h2 = (g**2).sum(axis=1)  # squared distance of the ray's xy line from the axis
        root = np.sqrt(np.maximum(1.0 - h2, 0.0) / qa)
        roots = np.stack([-qb / qa - root, -qb / qa + root], axis=1)
        z = o2[:, 2, None] + roots * d2[:, 2, None]
        ok = (h2[:, None] <= 1.0) & (roots > 0) & (z >= 0.0) & (z <= 1.0)
        t = np.where(ok[:, 0], roots[:, 0], np.where(ok[:, 1], roots[:, 1], np.inf))
        margin = np.minimum(np.abs(1.0 - h2), np.abs(z).min(axis=1))
        margin = np.minimum(margin, np.abs(z - 1.0).min(axis=1))
        return t, margin


def random_placements(rng, n):
    """``n`` random affine object-to-world matrices (float64): rotation, scales 0.3..3 per axis,
    a shear, a translation within 5 units."""
    m = np.zeros((n, 4, 4))
    for k in range(n):
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        shear = np.eye(3)
        shear[0, 1], shear[1, 2] = rng.uniform(-0.5, 0.5, 2)
        m[k, :3, :3] = q @ np.diag(rng.uniform(0.3, 3.0, 3)) @ shear
        m[k, :3, 3] = rng.uniform(-5, 5, 3)
        m[k, 3, 3] = 1.0
    return m


def rays_at(rng, kind, to_world, distance, graze=False):
    """Rays from ``distance`` away aimed at points of (or just beyond) the placed unit shape; with
    ``graze``, directions nearly in the disk's plane, or nearly tangent to the tube."""
    n = len(to_world)
    phi = rng.uniform(0, 2 * np.pi, n)
    if kind == "disk":
        r, z = np.sqrt(rng.uniform(0, 1.3, n)), np.zeros(n)
        n_obj = np.tile([0.0, 0.0, 1.0], (n, 1))
    else:
        r, z = np.ones(n), rng.uniform(-0.2, 1.2, n)
        n_obj = np.column_stack([np.cos(phi), np.sin(phi), np.zeros(n)])
    local = np.column_stack([r * np.cos(phi), r * np.sin(phi), z])
    target = np.einsum("nij,nj->ni", to_world[:, :3, :3], local) + to_world[:, :3, 3]
    if graze:  # along the plane, or along the tangent plane at the target
        normal = np.einsum("nji,nj->ni", np.linalg.inv(to_world[:, :3, :3]), n_obj)
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        w = rng.normal(size=(n, 3))
        w -= np.einsum("ij,ij->i", w, normal)[:, None] * normal
        w /= np.linalg.norm(w, axis=1, keepdims=True)
        d = w + 10.0 ** rng.uniform(-6, -1, (n, 1)) * rng.choice([-1.0, 1.0], (n, 1)) * normal
    else:
        d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return target - distance * d, d


@pytest.mark.parametrize("kind", list(SHAPES))
@pytest.mark.parametrize("distance, graze", [(3.0, False), (1e4, False), (3.0, True)])
def test_rays_match_the_float64_closed_form(rng, kind, distance, graze):
    """Hits and misses agree with float64 except within 1e-9 (relative) of a boundary, and ``t``
    is the float64 root rounded to float32 (within 1 ulp: the kernel's float64 differs from
    numpy's only by float64 rounding), from 3 units and from 1e4 units away, grazing or not."""
    n = 4000
    to_world = random_placements(rng, n)
    to_object = np.linalg.inv(to_world).astype(np.float32)
    o, d = rays_at(rng, kind, to_world, distance, graze)
    t = trace_quadric(kind, to_object, o, d)
    t_ref, margin = reference(kind, to_object, o, d)
    decided = margin > 1e-9
    assert np.array_equal(np.isfinite(t)[decided], np.isfinite(t_ref)[decided])
    both = np.isfinite(t) & np.isfinite(t_ref)
    assert 0.2 * n < both.sum() < n  # hits and misses both tested
    ulps = np.abs(t[both] - t_ref[both]) / np.spacing(t[both])
    assert ulps.max() <= 1.0


def test_non_unit_direction_scales_t():
    """``t`` is in units of ``|d|`` (the object-space direction is not normalised)."""
    to_world = np.diag([2.0, 0.5, 3.0, 1.0])
    to_object = np.linalg.inv(to_world)[None].repeat(2, axis=0)
    for kind, o, d, expected in (
        ("disk", [1.5, 0.2, 5.0], [0.0, 0.0, -4.0], 1.25),
        ("cylinder", [-6.0, 0.0, 1.0], [4.0, 0.0, 0.0], 1.0),
    ):
        t = trace_quadric(kind, to_object, [o, o], [d, [-c for c in d]])
        assert t[0] == pytest.approx(expected, rel=1e-7) and t[1] == np.inf


def test_tube_is_open_and_seen_from_inside():
    """Unit tube: from inside, the wall ahead; along the axis, nothing (no caps); a ray passing
    over the near end hits the inside of the far wall; one above both ends misses; t_min skips
    the near wall."""
    to_object = np.eye(4)[None].repeat(6, axis=0)
    o = [[0, 0, 0.5], [0, 0, -2], [-3, 0, 1.6], [-3, 0, 2.5], [-3, 0, 0.5], [-3, 0, 0.5]]
    d = [[1, 0, 0], [0, 0, 1], [1, 0, -0.25], [1, 0, 0], [1, 0, 0], [1, 0, 0]]
    t = trace_quadric("cylinder", to_object, o, d)
    np.testing.assert_allclose(t[[0, 2, 4]], [1.0, 4.0, 2.0], rtol=1e-7)
    assert t[1] == np.inf and t[3] == np.inf
    assert trace_quadric("cylinder", to_object[:1], o[4:5], d[4:5], t_min=2.5)[0] == pytest.approx(4.0)


def placed_scene(rng, n):
    """A scene of ``n`` disks and ``n`` cylinders at random placements, each with a transform."""
    shapes = []
    for m in random_placements(rng, 2 * n):
        kind = "disk" if len(shapes) % 2 == 0 else "cylinder"
        own = {"center": [0, 0, 0], "normal": [0, 0, 1]} if kind == "disk" else {"p0": [0, 0, 0], "p1": [0, 0, 1]}
        shapes.append({"type": kind, "radius": 1.0, **own, "transform": {"matrix": m.ravel().tolist()}})
    return make_scene(shapes)


def test_bvh_boxes_hold_the_shapes_and_traversal_matches_brute_force(rng):
    """Every point of each placed disk and tube (float64, through the float32 transform the
    device applies) lies in its float32 box; the BVH finds the same nearest hit as testing every
    primitive, through the all-features kernels and those specialised on disks and cylinders."""
    scene = placed_scene(rng, 40)
    tracer = Tracer(scene, device=wp.get_device())
    p = tracer.prims
    lo, hi = p.bounds()
    _, to_world, _ = p.quadric_transforms()
    for k in range(len(p.quadric_kind)):
        phi = np.linspace(0, 2 * np.pi, 721)
        z = [0.0] if p.quadric_kind[k] == DISK else [0.0, 1.0]
        local = np.array([[np.cos(a), np.sin(a), h] for a in phi for h in z])
        world = local @ to_world[k, :3, :3].T + to_world[k, :3, 3]
        assert np.all(world >= lo[k]) and np.all(world <= hi[k])
        assert np.all(world.min(axis=0) - lo[k] < 1e-3) and np.all(hi[k] - world.max(axis=0) < 1e-3)  # tight
    o = rng.uniform(-12, 12, (20000, 3))
    d = rng.normal(size=(20000, 3))
    t_bvh, prim_bvh = tracer.closest(o, d)[:2]
    t_all, prim_all = tracer.closest(o, d, brute_force=True)[:2]
    assert np.array_equal(prim_bvh, prim_all) and np.array_equal(t_bvh, t_all)
    assert set(np.unique(prim_bvh & KIND_MASK)) == {DISK, CYLINDER, NO_HIT & KIND_MASK}
    special = Tracer(scene, device=wp.get_device(), specialize=True)
    assert np.array_equal(special.closest(o, d)[1], prim_bvh)
    assert np.array_equal(special.occluded(o, d), prim_bvh != NO_HIT)


@pytest.mark.parametrize("kind", ["disk", "cylinder"])
def test_one_kind_alone_is_traced_with_computed_ids(rng, kind):
    """A scene of disks only (or cylinders only) takes the single-kind path: leaf entries are
    computed ids, the quadric arrays reordered to leaf order; hits name the right shapes."""
    shapes = [
        {"type": "disk", "center": [3.0 * k, 0, 0], "normal": [0, 0, 1], "radius": 1.0}
        if kind == "disk"
        else {"type": "cylinder", "p0": [3.0 * k, -1, 0], "p1": [3.0 * k, 1, 0], "radius": 1.0}
        for k in rng.permutation(9)
    ]
    scene = make_scene(shapes)
    features = scene_features(scene)
    assert (features.disks, features.cylinders) == (kind == "disk", kind == "cylinder")
    assert not (features.spheres or features.triangles or features.polygons)
    tracer = Tracer(scene, device=wp.get_device(), specialize=True)
    x = np.array([shape.to_world[0, 3] for shape in scene.shapes])
    t, prim = tracer.closest(np.column_stack([x + 0.2, np.zeros(9), np.full(9, 5.0)]), np.tile([0, 0, -1.0], (9, 1)))[
        :2
    ]
    assert np.array_equal(tracer.prims.shape_of(prim), np.arange(9))
    np.testing.assert_allclose(t, 5.0 if kind == "disk" else 5.0 - np.sqrt(0.96), rtol=1e-6)


def surface_distance(kind, to_object, p):
    """float64 world distance of points ``p`` from the float32 surface (first order: the object-
    space residual over the length of its world gradient)."""
    a = to_object.astype(np.float64)
    q = np.einsum("nij,nj->ni", a[:, :3, :3], p) + a[:, :3, 3]
    if kind == "disk":
        return np.abs(q[:, 2]) / np.linalg.norm(a[:, 2, :3], axis=1)
    radial = np.linalg.norm(q[:, :2], axis=1)
    gradient = np.einsum("nji,nj->ni", a[:, :2, :3], q[:, :2] / radial[:, None])
    return np.abs(radial - 1.0) / np.linalg.norm(gradient, axis=1)


@pytest.mark.parametrize("kind", ["disk", "cylinder"])
@pytest.mark.parametrize("scale, distance", [(1e-3, 0.0), (1.0, 0.0), (1.0, 1e4), (1e3, 1e4)])
def test_spawned_rays_never_fall_back_onto_the_surface(rng, kind, scale, distance):
    """From each hit (recomputed on the surface), shadow rays (many grazing), reflected and
    refracted rays leave with the renderer's offset: the hit point lies within its error bound
    of the float32 surface; nothing hits a disk again; a ray leaving a tube outward hits nothing,
    one leaving inward hits the far wall (not the spot it left) or leaves through an open end."""
    m = np.diag([2.0, 0.7, 1.5, 1.0]) * scale
    m[:3, :3] = np.linalg.qr(rng.normal(size=(3, 3)))[0] @ m[:3, :3]
    m[:3, 3] = distance * np.array([0.6, -0.48, 0.64])
    m[3, 3] = 1.0
    own = {"center": [0, 0, 0], "normal": [0, 0, 1]} if kind == "disk" else {"p0": [0, 0, 0], "p1": [0, 0, 1]}
    scene = make_scene([{"type": kind, "radius": 1.0, **own, "transform": {"matrix": m.ravel().tolist()}}])
    tracer = Tracer(scene, device="cpu")
    n = 3000
    o, d = rays_at(rng, kind, m[None].repeat(n, axis=0), 5.0 * scale)
    inside = rng.random(n) < 0.3 if kind == "cylinder" else np.zeros(n, bool)
    local = np.column_stack([rng.uniform(-0.6, 0.6, (n, 2)), rng.uniform(0.2, 0.8, n)])
    o[inside] = (local @ m[:3, :3].T + m[:3, 3])[inside]
    cos = 10.0 ** rng.uniform(-5.0, 0.0, n)
    phi = rng.uniform(0.0, 2.0 * np.pi, n)
    shadow = np.column_stack([np.sqrt(1 - cos**2) * np.cos(phi), np.sqrt(1 - cos**2) * np.sin(phi), cos])
    out = trace_spawned_batch(tracer, o, d, shadow, ior=1.5)
    hit = out["hit_prim"] != NO_HIT
    assert hit.mean() > 0.5
    to_object = tracer.prims.quadric_transforms()[0][np.zeros(hit.sum(), int)]
    p = out["hit_point"][hit].astype(np.float64)
    assert np.all(surface_distance(kind, to_object, p) <= out["hit_err"][hit])
    n_out = out["hit_normal"][hit].astype(np.float64)
    for ray in ("shadow", "reflect", "refract"):
        landed = out["shadow_hit"][hit] == 1 if ray == "shadow" else out[f"{ray}_prim"][hit] >= 0
        w = out[f"{ray}_dir"][hit].astype(np.float64)
        traced = (out["shadow_hit"] if ray == "shadow" else out[f"{ray}_prim"])[hit] != -2
        outward = traced & (np.einsum("ij,ij->i", w, n_out) > 0)
        if kind == "disk":
            assert not np.any(traced & landed), ray
            continue
        assert not np.any(outward & landed), ray
        if ray != "shadow":  # inward: the far wall, at least half the chord away
            o2 = out[f"{ray}_origin"][hit].astype(np.float64)
            chord = _chord(to_object, o2, w)
            t2 = out[f"{ray}_t"][hit]
            assert not np.any(traced & ~outward & landed & (t2 < 0.5 * chord)), ray


def _chord(to_object, o, w):
    """float64 distance along ``o + t w`` (from inside the infinite tube) to its wall."""
    a = to_object.astype(np.float64)
    q = np.einsum("nij,nj->ni", a[:, :3, :3], o) + a[:, :3, 3]
    v = np.einsum("nij,nj->ni", a[:, :3, :3], w)
    qa = (v[:, :2] ** 2).sum(axis=1)
    qb = (q[:, :2] * v[:, :2]).sum(axis=1)
    qc = (q[:, :2] ** 2).sum(axis=1) - 1.0
    with np.errstate(divide="ignore", invalid="ignore"):
        return (-qb + np.sqrt(np.maximum(qb * qb - qa * qc, 0.0))) / qa


def test_moving_disk_is_hit_where_it_is_at_the_ray_time():
    """A disk moving along +x at 2 units per unit time: at time 1 a ray at x = 2.5 hits it, one
    at x = 0.5 misses (ray motion through ``ray_origin_at``, as for every kind)."""
    scene = make_scene(
        [{"type": "disk", "center": [0, 0, 0], "normal": [0, 0, 1], "radius": 1.0, "velocity": [2, 0, 0]}],
        camera={"origin": [0, 0, 5], "look_at": [0, 0, 0], "shutter": [0, 1]},
    )
    tracer = Tracer(scene, device=wp.get_device())
    trace = traversal(Features())
    device = wp.get_device()

    @wp.kernel
    def at_time(geometry: GeometryData, o: wp.array(dtype=wp.vec3), out: wp.array(dtype=float)):
        i = wp.tid()
        t, _prim, _inst = trace.closest_hit(geometry, o[i], wp.vec3(0.0, 0.0, -1.0), 1.0, 0.0, wp.inf)
        out[i] = t

    out = wp.zeros(2, dtype=float, device=device)
    wp.launch(at_time, dim=2, inputs=[tracer.data, vec3_array([[2.5, 0, 5], [0.5, 0, 5]], device), out], device=device)
    assert out.numpy()[0] == pytest.approx(5.0) and out.numpy()[1] == np.inf


def test_packed_ids_share_the_quadric_arrays():
    """Disks and cylinders index one set of arrays: the k-th quadric in leaf order has index k,
    whichever its kind."""
    scene = make_scene(
        [
            {"type": "cylinder", "p0": [0, 0, 0], "p1": [0, 1, 0], "radius": 0.5},
            {"type": "disk", "center": [3, 0, 0], "normal": [0, 1, 0], "radius": 0.5},
            {"type": "sphere", "center": [6, 0, 0], "radius": 0.5},
        ]
    )
    p = Tracer(scene, device=wp.get_device()).prims
    quadric = np.isin(p.prims & KIND_MASK, (DISK, CYLINDER))
    assert sorted(p.prims[quadric] >> KIND_BITS) == [0, 1]
    assert np.array_equal(p.shape_of(p.prims[quadric]), p.quadric_shape[p.prims[quadric] >> KIND_BITS])
    assert np.array_equal(p.quadric_kind[p.prims[quadric] >> KIND_BITS], p.prims[quadric] & KIND_MASK)
