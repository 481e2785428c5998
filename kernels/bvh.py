"""The device BVH: a 4-wide tree of ``WideNode``s, and the ray-box test of a node's four children.

Layout (built by ``wrt.kernels.bvh_build``, walked by ``wrt.kernels.traverse``): ``nodes[0]`` is the
root; nodes are numbered depth first, so a subtree's nodes are contiguous. Each node holds the
bounds of up to ``WIDTH`` children side by side, one lane per child in each of six ``vec4``
(``lo_x`` ... ``hi_z``), and a ``vec4i`` of child references:

- ``ref >= 0``: an inner child, the index of its ``WideNode``;
- ``ref < 0``: a leaf of ``leaf_count(ref)`` (1 to ``MAX_LEAF``) primitives, entries
  ``leaf_start(ref) ...`` of the scene's leaf-ordered primitive list.

An unused lane has the empty box ``lo = hi = +inf``, which no ray enters (see ``child_entry``),
and the reference 0. Bounds are float32, rounded outward from the primitives' float64 extent, so a
box always contains what its primitives' intersection tests can hit.
"""

import warp as wp

from .intersect import INV_ZERO, SLAB_WIDEN

WIDTH = 4
MAX_LEAF = wp.constant(4)  # primitives per leaf, at most
LEAF_COUNT_BITS = wp.constant(3)
LEAF_COUNT_MASK = wp.constant(7)
# traversal stack entries: the builder proves each tree needs at most this many (wrt.bvh checks it)
STACK_SIZE = 64


@wp.struct
class WideNode:
    """Bounds of four children, lane k of each vector for child k, and their references."""

    lo_x: wp.vec4
    lo_y: wp.vec4
    lo_z: wp.vec4
    hi_x: wp.vec4
    hi_y: wp.vec4
    hi_z: wp.vec4
    child: wp.vec4i


@wp.func
def leaf_ref(start: wp.int32, count: wp.int32) -> wp.int32:
    """Reference of a leaf holding primitive-list entries ``start .. start + count - 1``."""
    return -1 - ((start << LEAF_COUNT_BITS) | count)


@wp.func
def leaf_start(ref: wp.int32) -> wp.int32:
    return (-1 - ref) >> LEAF_COUNT_BITS


@wp.func
def leaf_count(ref: wp.int32) -> wp.int32:
    return (-1 - ref) & LEAF_COUNT_MASK


@wp.func
def ordered_min(a: wp.vec4, b: wp.vec4) -> wp.vec4:
    """Lane-wise ``a < b ? a : b`` (one instruction per lane, no NaN handling: inputs are not NaN)."""
    return wp.vec4(
        wp.where(a[0] < b[0], a[0], b[0]),
        wp.where(a[1] < b[1], a[1], b[1]),
        wp.where(a[2] < b[2], a[2], b[2]),
        wp.where(a[3] < b[3], a[3], b[3]),
    )


@wp.func
def ordered_max(a: wp.vec4, b: wp.vec4) -> wp.vec4:
    """Lane-wise ``a > b ? a : b``."""
    return wp.vec4(
        wp.where(a[0] > b[0], a[0], b[0]),
        wp.where(a[1] > b[1], a[1], b[1]),
        wp.where(a[2] > b[2], a[2], b[2]),
        wp.where(a[3] > b[3], a[3], b[3]),
    )


@wp.func
def slab_exact(lo: wp.vec4, hi: wp.vec4, o: float, inv_d: float):
    """Entry and exit distances of four boxes' slabs along one axis: ``(near, far)`` lane-wise.

    An axis the ray does not move along (``inv_d == INV_ZERO``) does not constrain ``t``: its slab
    holds the ray for every ``t`` if the origin lies in ``[lo, hi]`` (boundary included), for none
    otherwise, which is written as the interval ``(-inf, +inf)`` or ``(+inf, -inf)``; this never
    evaluates ``0 * inf``.
    """
    if inv_d == INV_ZERO:
        near = wp.vec4(0.0)
        far = wp.vec4(0.0)
        for k in range(4):
            inside = o >= lo[k] and o <= hi[k]
            near[k] = wp.where(inside, -wp.inf, wp.inf)
            far[k] = wp.where(inside, wp.inf, -wp.inf)
        return near, far
    t0 = (lo - wp.vec4(o)) * inv_d
    t1 = (hi - wp.vec4(o)) * inv_d
    return ordered_min(t0, t1), ordered_max(t0, t1)


@wp.func
def entry_of(near: wp.vec4, far: wp.vec4, t_max: float) -> wp.vec4:
    """Lane-wise ``near`` where ``near <= far * SLAB_WIDEN`` and ``near < t_max``, else ``+inf``."""
    far = far * SLAB_WIDEN
    return wp.vec4(
        wp.where(near[0] <= far[0] and near[0] < t_max, near[0], wp.inf),
        wp.where(near[1] <= far[1] and near[1] < t_max, near[1], wp.inf),
        wp.where(near[2] <= far[2] and near[2] < t_max, near[2], wp.inf),
        wp.where(near[3] <= far[3] and near[3] < t_max, near[3], wp.inf),
    )


@wp.func
def child_entry(node: WideNode, o: wp.vec3, inv_d: wp.vec3, moves: bool, t_max: float) -> wp.vec4:
    """Entry distance (clamped to >= 0) of the ray into each child box of ``node``, ``+inf`` for a
    child it misses or enters at or beyond ``t_max``; ``inv_d`` from ``intersect.safe_inverse``,
    ``moves``: no component of ``inv_d`` is ``INV_ZERO`` (the ray moves along every axis).

    The four boxes are tested side by side (pbrt-v4's conservative slab test per lane: the exit
    distance is widened by ``SLAB_WIDEN`` so that rounding never culls a box the ray touches).
    Rays that move along every axis take a branch-free path; the others ``slab_exact``.
    """
    if moves:
        # the near plane of each slab is lo where the ray goes up that axis, hi where it goes down
        near_x = node.lo_x
        far_x = node.hi_x
        if inv_d[0] < 0.0:
            near_x = node.hi_x
            far_x = node.lo_x
        near_y = node.lo_y
        far_y = node.hi_y
        if inv_d[1] < 0.0:
            near_y = node.hi_y
            far_y = node.lo_y
        near_z = node.lo_z
        far_z = node.hi_z
        if inv_d[2] < 0.0:
            near_z = node.hi_z
            far_z = node.lo_z
        t_near = ordered_max(
            ordered_max((near_x - wp.vec4(o[0])) * inv_d[0], (near_y - wp.vec4(o[1])) * inv_d[1]),
            ordered_max((near_z - wp.vec4(o[2])) * inv_d[2], wp.vec4(0.0)),
        )
        t_far = ordered_min(
            ordered_min((far_x - wp.vec4(o[0])) * inv_d[0], (far_y - wp.vec4(o[1])) * inv_d[1]),
            (far_z - wp.vec4(o[2])) * inv_d[2],
        )
        return entry_of(t_near, t_far, t_max)
    near_x, far_x = slab_exact(node.lo_x, node.hi_x, o[0], inv_d[0])
    near_y, far_y = slab_exact(node.lo_y, node.hi_y, o[1], inv_d[1])
    near_z, far_z = slab_exact(node.lo_z, node.hi_z, o[2], inv_d[2])
    near = ordered_max(ordered_max(near_x, near_y), ordered_max(near_z, wp.vec4(0.0)))
    far = ordered_min(ordered_min(far_x, far_y), far_z)
    return entry_of(near, far, t_max)
