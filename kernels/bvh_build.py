"""BVH construction on the render device: Morton order, PLOC clustering with SAH leaves, and the
depth-first collapse into the 4-wide tree of ``wrt.kernels.bvh``. ``wrt.bvh`` drives the launches.

1. ``morton_codes``: 30-bit Morton codes of the primitives' box centres, then sorted
   (``wp.utils.radix_sort_pairs``): the initial clusters, one primitive each, in Morton order.
2. PLOC (Meister and Bittner 2018), one iteration per round of launches: each cluster finds its
   nearest neighbour, the one among ``radius`` clusters on either side whose union with it has the
   smallest surface area (``ploc_nearest``); mutual nearest neighbours merge into a new binary node
   (``ploc_flags``, prefix sums, ``ploc_merge``), which takes the place of the left one, and the
   survivors are compacted. Ties are broken by a strict total order of pairs (area, index gap,
   hash, index), so the closest pair always merges and every iteration makes progress, even over
   identical boxes. Node indices come from prefix sums, never from atomics: the tree is the same
   on every run of a device.
   ``pair_neighbours`` is the fallback: it pairs clusters 2i and 2i+1 (a Morton-order median tree,
   depth ``ceil(log2 n)``), used when a PLOC tree would need a deeper traversal stack than
   ``wrt.kernels.bvh.STACK_SIZE`` (see ``wrt.bvh``).
3. Each new node decides bottom up, by the surface area heuristic, whether its subtree becomes
   one leaf (at most ``MAX_LEAF`` primitives, and only if that is cheaper than splitting:
   ``INTERSECTION_COST * n * area <= TRAVERSAL_COST * area + cost(left) + cost(right)``), and,
   if not, which binary descendants become its children in the wide tree: the two children,
   then repeatedly the inner child of the largest surface area is replaced by its two children
   until there are four (Wald et al. 2008; the fallback opens the shallowest first). It also
   records how many wide nodes its wide subtree has and how many stack entries a traversal of it
   can need, ``(children - 1) + max over inner children``.
4. ``emit_wide`` writes the wide tree top down, one launch per level: a node's index is its
   parent's plus one plus the sizes of the subtrees of its earlier siblings (depth-first order),
   and each leaf's primitives are written at an offset that is likewise a sum of counts.

References
----------
D. Meister and J. Bittner, "Parallel Locally-Ordered Clustering for Bounding Volume Hierarchy
Construction", IEEE TVCG 24(3), 2018.
I. Wald, C. Benthin, S. Boulos, "Getting Rid of Packets", IEEE RT 2008 (wide BVHs by collapse).
T. Karras, "Maximizing Parallelism in the Construction of BVHs, Octrees, and k-d Trees", HPG 2012.
"""

import warp as wp

from . import MODULE_OPTIONS
from .bvh import MAX_LEAF, WideNode, leaf_ref
from .sampling import pcg_hash

wp.set_module_options(MODULE_OPTIONS)

TRAVERSAL_COST = wp.constant(
    2.0
)  # SAH cost of visiting a binary node, relative to one primitive test (measured choice: docs/performance.md)
INTERSECTION_COST = wp.constant(1.0)
MORTON_SCALE = wp.constant(1023.0)  # 10 bits per axis
MORTON_1 = wp.constant(wp.uint32(0x00010001))
MORTON_2 = wp.constant(wp.uint32(0xFF0000FF))
MORTON_3 = wp.constant(wp.uint32(0x00000101))
MORTON_4 = wp.constant(wp.uint32(0x0F00F00F))
MORTON_5 = wp.constant(wp.uint32(0x00000011))
MORTON_6 = wp.constant(wp.uint32(0xC30C30C3))
MORTON_7 = wp.constant(wp.uint32(0x00000005))
MORTON_8 = wp.constant(wp.uint32(0x49249249))


@wp.struct
class BinaryNode:
    """A node of the binary tree of the build (64 bytes: one cache line). The tree has ``2n - 1``
    nodes: nodes ``0 .. n-1`` hold one primitive each (in Morton order), PLOC appends the inner
    nodes after them (a parent after its children)."""

    lo: wp.vec3
    hi: wp.vec3
    child: wp.vec2i  # inner: (left, right); a primitive's node: (primitive, -1)
    count: wp.int32  # primitives in the subtree
    cost: float  # SAH cost of the subtree, times its area
    wide_nodes: wp.int32  # wide nodes in the wide subtree rooted here; 0: the subtree is one leaf
    stack: wp.int32  # traversal stack entries the wide subtree rooted here can need
    wide: wp.vec4i  # binary nodes that are its children in the wide tree (-1: none)


@wp.func
def box_area(lo: wp.vec3, hi: wp.vec3) -> float:
    """Surface area of the box [lo, hi] (0 for an empty box)."""
    e = wp.max(hi - lo, wp.vec3(0.0))
    return 2.0 * (e[0] * e[1] + e[1] * e[2] + e[2] * e[0])


@wp.func
def expand_bits(v: wp.uint32) -> wp.uint32:
    """The 10 low bits of ``v`` spread to every third bit (Karras 2012)."""
    v = (v * MORTON_1) & MORTON_2
    v = (v * MORTON_3) & MORTON_4
    v = (v * MORTON_5) & MORTON_6
    v = (v * MORTON_7) & MORTON_8
    return v


@wp.kernel
def morton_codes(
    lo: wp.array(dtype=wp.vec3),
    hi: wp.array(dtype=wp.vec3),
    scene_lo: wp.vec3,
    scene_scale: wp.vec3,
    keys: wp.array(dtype=wp.int32),
    values: wp.array(dtype=wp.int32),
):
    """Morton code of each box centre in the centres' bounds (``scene_scale`` = 1 / extent, 0 on a
    flat axis), and the primitive's index as the value to sort along."""
    i = wp.tid()
    c = wp.cw_mul(0.5 * (lo[i] + hi[i]) - scene_lo, scene_scale)
    x = wp.uint32(wp.clamp(c[0] * MORTON_SCALE, 0.0, MORTON_SCALE))
    y = wp.uint32(wp.clamp(c[1] * MORTON_SCALE, 0.0, MORTON_SCALE))
    z = wp.uint32(wp.clamp(c[2] * MORTON_SCALE, 0.0, MORTON_SCALE))
    keys[i] = wp.int32((expand_bits(x) << wp.uint32(2)) | (expand_bits(y) << wp.uint32(1)) | expand_bits(z))
    values[i] = i


@wp.kernel
def init_leaves(
    lo: wp.array(dtype=wp.vec3),
    hi: wp.array(dtype=wp.vec3),
    sorted_prims: wp.array(dtype=wp.int32),
    tree: wp.array(dtype=BinaryNode),
    c_lo: wp.array(dtype=wp.vec3),
    c_hi: wp.array(dtype=wp.vec3),
    c_node: wp.array(dtype=wp.int32),
    first: wp.int32,
):
    """Node i holds the i-th primitive in Morton order; it is cluster i (``i = first + tid``)."""
    i = first + wp.tid()
    p = sorted_prims[i]
    node = BinaryNode()
    node.lo = lo[p]
    node.hi = hi[p]
    node.child = wp.vec2i(p, -1)
    node.count = 1
    node.cost = INTERSECTION_COST * box_area(node.lo, node.hi)
    node.wide = wp.vec4i(-1)
    tree[i] = node
    c_lo[i] = node.lo
    c_hi[i] = node.hi
    c_node[i] = i


@wp.func
def pair_before(
    area: float, gap: wp.int32, low: wp.int32, best_area: float, best_gap: wp.int32, best_low: wp.int32
) -> bool:
    """Strict total order of cluster pairs for the nearest-neighbour search: smaller union area,
    then smaller index gap, then a hash of the pair's lower index (so that runs of equal boxes
    pair up in many places at once), then the lower index."""
    if area != best_area:
        return area < best_area
    if gap != best_gap:
        return gap < best_gap
    h = pcg_hash(wp.uint32(low))
    best_h = pcg_hash(wp.uint32(best_low))
    if h != best_h:
        return h > best_h
    return low < best_low


@wp.kernel
def ploc_nearest(
    c_lo: wp.array(dtype=wp.vec3),
    c_hi: wp.array(dtype=wp.vec3),
    m: wp.int32,
    radius: wp.int32,
    nn: wp.array(dtype=wp.int32),
    first: wp.int32,
):
    """Nearest neighbour of cluster ``first + tid`` among the ``radius`` clusters on either side."""
    i = first + wp.tid()
    lo = c_lo[i]
    hi = c_hi[i]
    best = int(-1)
    best_area = float(wp.inf)
    best_gap = int(0)
    best_low = int(0)
    for j in range(wp.max(0, i - radius), wp.min(m, i + radius + 1)):
        lo_j = c_lo[j]
        hi_j = c_hi[j]
        ex = wp.where(hi[0] > hi_j[0], hi[0], hi_j[0]) - wp.where(lo[0] < lo_j[0], lo[0], lo_j[0])
        ey = wp.where(hi[1] > hi_j[1], hi[1], hi_j[1]) - wp.where(lo[1] < lo_j[1], lo[1], lo_j[1])
        ez = wp.where(hi[2] > hi_j[2], hi[2], hi_j[2]) - wp.where(lo[2] < lo_j[2], lo[2], lo_j[2])
        area = 2.0 * (ex * ey + ey * ez + ez * ex)  # the union's extents are >= 0: the boxes are not empty
        if area <= best_area and j != i:
            gap = wp.abs(i - j)
            low = wp.min(i, j)
            if best < 0 or pair_before(area, gap, low, best_area, best_gap, best_low):
                best = j
                best_area = area
                best_gap = gap
                best_low = low
    nn[i] = best


@wp.kernel
def pair_neighbours(m: wp.int32, nn: wp.array(dtype=wp.int32)):
    """Fallback pairing: clusters 2i and 2i + 1 are each other's neighbours (a balanced tree)."""
    i = wp.tid()
    j = i ^ 1
    nn[i] = wp.where(j < m, j, -1)


@wp.kernel
def ploc_flags(nn: wp.array(dtype=wp.int32), survive: wp.array(dtype=wp.int32), merge: wp.array(dtype=wp.int32)):
    """``merge``: cluster i merges with its mutual neighbour j > i; ``survive``: cluster i remains
    (unmerged, or as the merged pair's place)."""
    i = wp.tid()
    j = nn[i]
    mutual = j >= 0 and nn[j] == i
    merge[i] = wp.where(mutual and i < j, 1, 0)
    survive[i] = wp.where(mutual and j < i, 0, 1)


@wp.func
def wide_children(tree: wp.array(dtype=BinaryNode), left: wp.int32, right: wp.int32, breadth_first: wp.int32):
    """The binary descendants that become the children, in the wide tree, of a node with children
    ``left`` and ``right``, and their number: the two children, then the inner child of the
    largest area (breadth first: the shallowest, then the largest) replaced by its own two, while
    there are fewer than four."""
    kids = wp.vec4i(left, right, -1, -1)
    level = wp.vec4i(1, 1, 0, 0)
    k = int(2)
    for _expansion in range(2):
        best = int(-1)
        best_level = int(0)
        best_area = float(0.0)
        best_child = wp.vec2i(0)
        for s in range(4):
            if s < k:
                x = tree[kids[s]]
                if x.wide_nodes > 0:
                    area = box_area(x.lo, x.hi)
                    better = best < 0 or area > best_area
                    if breadth_first != 0 and best >= 0:
                        better = level[s] < best_level or (level[s] == best_level and area > best_area)
                    if better:
                        best = s
                        best_level = level[s]
                        best_area = area
                        best_child = x.child
        if best >= 0:
            kids[best] = best_child[0]
            kids[k] = best_child[1]
            level[best] = best_level + 1
            level[k] = best_level + 1
            k += 1
    return kids, k


@wp.func
def make_node(tree: wp.array(dtype=BinaryNode), index: wp.int32, a: wp.int32, b: wp.int32, breadth_first: wp.int32):
    """Write inner node ``index`` with children ``a``, ``b``: bounds, count, SAH leaf decision,
    and its wide children, wide subtree size and stack need."""
    na = tree[a]
    nb = tree[b]
    node = BinaryNode()
    node.lo = wp.min(na.lo, nb.lo)
    node.hi = wp.max(na.hi, nb.hi)
    node.child = wp.vec2i(a, b)
    node.count = na.count + nb.count
    node.wide = wp.vec4i(-1)
    area = box_area(node.lo, node.hi)
    split_cost = TRAVERSAL_COST * area + na.cost + nb.cost
    leaf_cost = INTERSECTION_COST * float(node.count) * area
    if node.count <= MAX_LEAF and leaf_cost <= split_cost:
        node.cost = leaf_cost
    else:
        node.cost = split_cost
        kids, k = wide_children(tree, a, b, breadth_first)
        nodes = int(1)
        need = int(0)
        for s in range(4):
            if s < k:
                x = tree[kids[s]]
                nodes += x.wide_nodes
                need = wp.max(need, x.stack)
        node.wide = kids
        node.wide_nodes = nodes
        node.stack = need + k - 1
    tree[index] = node


@wp.kernel
def ploc_merge(
    tree: wp.array(dtype=BinaryNode),
    c_lo: wp.array(dtype=wp.vec3),
    c_hi: wp.array(dtype=wp.vec3),
    c_node: wp.array(dtype=wp.int32),
    nn: wp.array(dtype=wp.int32),
    survive: wp.array(dtype=wp.int32),
    survive_sum: wp.array(dtype=wp.int32),
    merge: wp.array(dtype=wp.int32),
    merge_sum: wp.array(dtype=wp.int32),
    next_node: wp.int32,
    breadth_first: wp.int32,
    out_lo: wp.array(dtype=wp.vec3),
    out_hi: wp.array(dtype=wp.vec3),
    out_node: wp.array(dtype=wp.int32),
    first: wp.int32,
):
    """Merge the mutual pairs into new nodes ``next_node + k`` (k-th merge, in cluster order) and
    compact the clusters (``*_sum``: inclusive prefix sums of the flags); cluster ``first + tid``."""
    i = first + wp.tid()
    if survive[i] == 0:
        return
    p = survive_sum[i] - 1
    if merge[i] == 1:
        node = next_node + merge_sum[i] - 1
        make_node(tree, node, c_node[i], c_node[nn[i]], breadth_first)
        out_node[p] = node
        out_lo[p] = tree[node].lo
        out_hi[p] = tree[node].hi
    else:
        out_node[p] = c_node[i]
        out_lo[p] = c_lo[i]
        out_hi[p] = c_hi[i]


@wp.kernel
def count_inner(
    tree: wp.array(dtype=BinaryNode),
    f_node: wp.array(dtype=wp.int32),
    counts: wp.array(dtype=wp.int32),
    first: wp.int32,
):
    """Inner children (wide nodes of the next level) of node ``first + tid`` of the current level."""
    e = first + wp.tid()
    node = tree[f_node[e]]
    n = int(0)
    for s in range(4):
        if node.wide[s] >= 0:
            if tree[node.wide[s]].wide_nodes > 0:
                n += 1
    counts[e] = n


@wp.func
def write_leaf(tree: wp.array(dtype=BinaryNode), x: wp.int32, order: wp.array(dtype=wp.int32), start: wp.int32):
    """The primitives of the collapsed subtree ``x`` (at most ``MAX_LEAF``), left to right, to
    ``order[start ...]``."""
    pending = wp.vec4i(x, 0, 0, 0)
    n = int(1)
    k = start
    while n > 0:
        n -= 1
        c = tree[pending[n]].child
        if c[1] < 0:
            order[k] = c[0]
            k += 1
        else:
            pending[n] = c[1]
            pending[n + 1] = c[0]
            n += 2


@wp.kernel
def emit_wide(
    tree: wp.array(dtype=BinaryNode),
    f_node: wp.array(dtype=wp.int32),
    f_wide: wp.array(dtype=wp.int32),
    f_offset: wp.array(dtype=wp.int32),
    counts: wp.array(dtype=wp.int32),
    counts_sum: wp.array(dtype=wp.int32),
    nodes: wp.array(dtype=WideNode),
    order: wp.array(dtype=wp.int32),
    next_node: wp.array(dtype=wp.int32),
    next_wide: wp.array(dtype=wp.int32),
    next_offset: wp.array(dtype=wp.int32),
    first: wp.int32,
):
    """Write the wide node of each entry of the current level (binary node ``f_node``, wide index
    ``f_wide``, first primitive-list entry ``f_offset``), its leaves' primitives, and the entries
    of its inner children to the next level (at ``counts_sum - counts``, an exclusive prefix sum);
    entry ``first + tid``."""
    e = first + wp.tid()
    b = f_node[e]
    kids = tree[b].wide
    if kids[0] < 0:  # a root that is a leaf: one lane
        kids = wp.vec4i(b, -1, -1, -1)
    w = f_wide[e]
    offset = f_offset[e]
    out = counts_sum[e] - counts[e]
    child_wide = w + 1
    node = WideNode()
    node.lo_x = wp.vec4(wp.inf)
    node.lo_y = wp.vec4(wp.inf)
    node.lo_z = wp.vec4(wp.inf)
    node.hi_x = wp.vec4(wp.inf)
    node.hi_y = wp.vec4(wp.inf)
    node.hi_z = wp.vec4(wp.inf)
    node.child = wp.vec4i(0)
    for s in range(4):
        x = kids[s]
        if x >= 0:
            kid = tree[x]
            node.lo_x[s] = kid.lo[0]
            node.lo_y[s] = kid.lo[1]
            node.lo_z[s] = kid.lo[2]
            node.hi_x[s] = kid.hi[0]
            node.hi_y[s] = kid.hi[1]
            node.hi_z[s] = kid.hi[2]
            if kid.wide_nodes == 0:
                node.child[s] = leaf_ref(offset, kid.count)
                write_leaf(tree, x, order, offset)
            else:
                node.child[s] = child_wide
                next_node[out] = x
                next_wide[out] = child_wide
                next_offset[out] = offset
                out += 1
                child_wide += kid.wide_nodes
            offset += kid.count
    nodes[w] = node
