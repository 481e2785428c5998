"""BVH build on the render device: the host side, which launches the kernels of
``wrt.kernels.bvh_build`` and checks the result.

``build_bvh(lo, hi, device)`` takes the primitives' float32 bounds and builds the 4-wide BVH of
``wrt.kernels.bvh`` where it will be traversed: Morton codes, radix sort, PLOC clustering (radius
``PLOC_RADIUS``) with SAH leaves of at most ``wrt.kernels.bvh.MAX_LEAF`` primitives, and the
depth-first collapse to four children per node. Each step is a Warp launch on ``device``; the host
only reads back a cluster count per PLOC iteration and a node count per level of the collapse.
On the CPU the larger kernels (nearest neighbours, merges, leaf set-up, collapse) are split into
chunks launched from a thread pool, one worker per core (a Warp CPU launch runs on one thread).

Depth is bounded by construction: the traversal stack holds ``STACK_SIZE`` entries, and every
tree records the most entries a traversal of it can need. A PLOC tree needing more (a pathological
distribution, such as primitives spaced in a geometric progression) is rebuilt as the balanced
Morton-order tree, of depth ``ceil(log2 n)``, opened breadth first, whose need is at most 3 per
two levels: ``3 * ceil(log2(n) / 2) <= 48`` entries for any ``n < 2^31``.
"""

from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np
import warp as wp

from wrt.kernels.bvh import STACK_SIZE, WideNode
from wrt.kernels.bvh_build import (
    BinaryNode,
    count_inner,
    emit_wide,
    init_leaves,
    morton_codes,
    pair_neighbours,
    ploc_flags,
    ploc_merge,
    ploc_nearest,
)

from .host import default_threads

PLOC_RADIUS = 8  # clusters searched on either side
CHUNK = 1 << 16  # threads per CPU launch of the build's larger kernels

__all__ = ["BvhStats", "DeviceBvh", "build_bvh", "lane_bounds", "node_bounds"]


@dataclass
class BvhStats:
    """What the build made, for reports: ``builder`` is "ploc" or "balanced" (the fallback)."""

    primitives: int = 0
    builder: str = "ploc"
    wide_nodes: int = 0
    leaves: int = 0
    stack_need: int = 0  # traversal stack entries the tree can need (<= STACK_SIZE)
    sah_cost: float = 0.0  # of the binary tree with its leaves, normalised by the root's area
    ploc_iterations: int = 0
    build_s: float = 0.0  # wall seconds, uploads and read-backs included
    phases_s: dict = field(default_factory=dict)

    @property
    def mean_leaf_size(self) -> float:
        return self.primitives / max(self.leaves, 1)


@dataclass
class DeviceBvh:
    """A BVH on a device: ``nodes`` (``wrt.kernels.bvh.WideNode``) and ``order`` (the input index of
    each primitive-list entry, leaf by leaf)."""

    nodes: wp.array
    order: wp.array
    stats: BvhStats


def _threads(device) -> int:
    return 1 if device.is_cuda else default_threads()


def _last(a: wp.array, m: int) -> int:
    return int(a[m - 1 : m].numpy()[0])


class _Builder:
    """One build: the arrays of the binary tree and the clusters, on ``device``."""

    def __init__(self, lo32: np.ndarray, hi32: np.ndarray, device, pool: ThreadPoolExecutor | None):
        n = len(lo32)
        self.n, self.device, self.pool = n, device, pool
        self.lo = wp.array(lo32, dtype=wp.vec3, device=device)
        self.hi = wp.array(hi32, dtype=wp.vec3, device=device)
        centre = 0.5 * (lo32.astype(np.float64) + hi32.astype(np.float64))
        c_lo, c_hi = centre.min(axis=0), centre.max(axis=0)
        extent = c_hi - c_lo
        scale = np.divide(1.0, extent, out=np.zeros(3), where=extent > 0.0)
        keys = wp.empty(2 * n, dtype=wp.int32, device=device)
        self.sorted = wp.empty(2 * n, dtype=wp.int32, device=device)
        wp.launch(
            morton_codes,
            dim=n,
            inputs=[self.lo, self.hi, wp.vec3(*c_lo), wp.vec3(*scale), keys, self.sorted],
            device=device,
        )
        wp.utils.radix_sort_pairs(keys, self.sorted, n, 0, 30)

    def tree(self, breadth_first: bool) -> tuple[wp.array, int, int]:
        """Cluster the primitives into a binary tree (PLOC, or pairs when ``breadth_first``):
        returns the tree, its root and the iterations taken."""
        n, dev = self.n, self.device
        tree = wp.empty(2 * n - 1, dtype=BinaryNode, device=dev)
        clusters = [tuple(wp.empty(n, dtype=t, device=dev) for t in (wp.vec3, wp.vec3, wp.int32)) for _ in range(2)]
        nn, survive, merge, survive_sum, merge_sum = (wp.empty(n, dtype=wp.int32, device=dev) for _ in range(5))
        self._chunked(init_leaves, n, [self.lo, self.hi, self.sorted, tree, *clusters[0]])
        m, next_node, iterations = n, n, 0
        while m > 1:
            c_lo, c_hi, c_node = clusters[iterations % 2]
            out = clusters[(iterations + 1) % 2]
            if breadth_first:
                wp.launch(pair_neighbours, dim=m, inputs=[m, nn], device=dev)
            else:
                self._chunked(ploc_nearest, m, [c_lo, c_hi, m, PLOC_RADIUS, nn])
            wp.launch(ploc_flags, dim=m, inputs=[nn, survive, merge], device=dev)
            wp.utils.array_scan(survive[:m], survive_sum[:m], inclusive=True)
            wp.utils.array_scan(merge[:m], merge_sum[:m], inclusive=True)
            self._chunked(
                ploc_merge,
                m,
                [
                    tree,
                    c_lo,
                    c_hi,
                    c_node,
                    nn,
                    survive,
                    survive_sum,
                    merge,
                    merge_sum,
                    next_node,
                    int(breadth_first),
                    *out,
                ],
            )
            next_node += _last(merge_sum, m)
            m = _last(survive_sum, m)
            iterations += 1
        return tree, next_node - 1, iterations

    def _chunked(self, kernel, m: int, inputs: list) -> None:
        """Launch ``kernel(*inputs, first, ...)`` over ``m`` threads: in chunks from the thread pool
        on the CPU (``first`` the chunk's offset, the kernel's argument after ``inputs``)."""
        if self.pool is None or m <= CHUNK:
            wp.launch(kernel, dim=m, inputs=[*inputs, 0], device=self.device)
            return
        jobs = [
            self.pool.submit(wp.launch, kernel, dim=min(CHUNK, m - first), inputs=[*inputs, first], device=self.device)
            for first in range(0, m, CHUNK)
        ]
        for job in jobs:
            job.result()

    def wide(self, tree: wp.array, root: int) -> tuple[wp.array, wp.array, int]:
        """Collapse ``tree`` into the depth-first 4-wide node array; returns the nodes, the
        primitive order and the number of leaves."""
        dev = self.device
        total = max(1, int(tree[root : root + 1].numpy()["wide_nodes"][0]))
        nodes = wp.empty(total, dtype=WideNode, device=dev)
        order = wp.empty(self.n, dtype=wp.int32, device=dev)
        first = np.zeros(total, dtype=np.int32)
        first[0] = root
        level = [wp.array(first, dtype=wp.int32, device=dev)] + [
            wp.zeros(total, dtype=wp.int32, device=dev) for _ in range(2)
        ]
        spare = [wp.empty(total, dtype=wp.int32, device=dev) for _ in range(3)]
        counts, counts_sum = wp.empty(total, dtype=wp.int32, device=dev), wp.empty(total, dtype=wp.int32, device=dev)
        width = 1
        while width > 0:
            self._chunked(count_inner, width, [tree, level[0], counts])
            wp.utils.array_scan(counts[:width], counts_sum[:width], inclusive=True)
            self._chunked(emit_wide, width, [tree, *level, counts, counts_sum, nodes, order, *spare])
            width = _last(counts_sum, width)
            level, spare = spare, level
        return nodes, order, int(np.count_nonzero(nodes.numpy()["child"] < 0))


def build_bvh(lo: np.ndarray, hi: np.ndarray, device) -> DeviceBvh:
    """Build the BVH of primitives with float32 bounds ``lo``, ``hi`` (N, 3) on ``device``; each
    box must hold everything its primitive's intersection test can hit (``wrt.geometry`` rounds
    outward where float32 bounds are not exact).

    Returns a ``DeviceBvh`` whose ``order`` lists input indices leaf by leaf (empty for N = 0:
    no nodes). Raises ``RuntimeError`` if even the balanced tree would overflow the traversal
    stack (impossible below 2^31 primitives).
    """
    t0 = time.perf_counter()
    device = wp.get_device(device)
    n = len(lo)
    stats = BvhStats(primitives=n)
    if n == 0:
        empty = wp.empty(0, dtype=WideNode, device=device)
        return DeviceBvh(empty, wp.empty(0, dtype=wp.int32, device=device), stats)
    lo32, hi32 = np.ascontiguousarray(lo, dtype=np.float32), np.ascontiguousarray(hi, dtype=np.float32)
    threads = _threads(device)
    pool = ThreadPoolExecutor(max_workers=threads) if threads > 1 else None
    try:
        phases = {}
        t1 = time.perf_counter()
        builder = _Builder(lo32, hi32, device, pool)
        wp.synchronize_device(device)
        phases["morton_sort_s"] = time.perf_counter() - t1
        t1 = time.perf_counter()
        tree, root, iterations = builder.tree(breadth_first=False)
        stack = int(tree[root : root + 1].numpy()["stack"][0])
        if stack > STACK_SIZE:
            stats.builder = "balanced"
            tree, root, iterations = builder.tree(breadth_first=True)
            stack = int(tree[root : root + 1].numpy()["stack"][0])
            if stack > STACK_SIZE:
                raise RuntimeError(
                    f"BVH of {n} primitives needs {stack} traversal stack entries, more than {STACK_SIZE}"
                )
        phases["cluster_s"] = time.perf_counter() - t1
        t1 = time.perf_counter()
        nodes, order, leaves = builder.wide(tree, root)
        phases["collapse_s"] = time.perf_counter() - t1
    finally:
        if pool is not None:
            pool.shutdown()
    top = tree[root : root + 1].numpy()[0]
    cost = top["cost"]
    e = np.maximum(top["hi"].astype(np.float64) - top["lo"], 0.0)
    area = 2.0 * (e[0] * e[1] + e[1] * e[2] + e[2] * e[0])
    stats.wide_nodes = len(nodes)
    stats.leaves = leaves
    stats.stack_need = stack
    stats.sah_cost = float(cost) / area if area > 0 else float(cost)
    stats.ploc_iterations = iterations
    stats.phases_s = phases
    stats.build_s = time.perf_counter() - t0
    return DeviceBvh(nodes, order, stats)


def lane_bounds(nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Boxes of every child lane of host-side wide nodes (``DeviceBvh.nodes.numpy()``): ``lo``,
    ``hi`` of shape (M, 4, 3), float32; an unused lane is ``+inf`` throughout."""
    lo = np.stack([nodes["lo_x"], nodes["lo_y"], nodes["lo_z"]], axis=-1)
    hi = np.stack([nodes["hi_x"], nodes["hi_y"], nodes["hi_z"]], axis=-1)
    return lo, hi


def node_bounds(nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Box of each wide node (the union of its children's boxes), (M, 3) float32 each."""
    lo, hi = lane_bounds(nodes)
    used = np.isfinite(lo[..., 0])[..., None]
    return np.where(used, lo, np.inf).min(axis=1), np.where(used, hi, -np.inf).max(axis=1)
