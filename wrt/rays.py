"""Trace chosen pixels with the scene's integrator and return every ray it traced: the ray trees.

The rays come from the render kernels themselves, in their recording variant
(``wrt.kernels.variants.all_features_kernel(integrator, record=True)``, see
``wrt.kernels.record``), launched over the chosen pixels with the same set-up as ``wrt.render``:
same camera rays, same samples for the same seed, same decisions. Nothing is re-implemented in Python.
The light tracer's (``integrator = "ptracer"``) are the light paths the chosen pixels' slots trace
(one a sample, each from a light, with its connections to the camera; ``wrt.kernels.record``),
which reach the film anywhere, not only at those pixels.

>>> import wrt
>>> from wrt.rays import trace_rays
>>> scene = wrt.load_scene("examples/whitted/refraction.toml")
>>> tree = trace_rays(scene, [(130, 200)])
>>> tree.kind_name(0), tree.end[0], tree.children(0)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp

from wrt.kernels.ptracer import FIXED_POINT
from wrt.kernels.record import (
    ENTERING,
    ESCAPED,
    HIT,
    IN_MEDIUM,
    KIND_NAMES,
    SHADOW_BLOCKED,
    SHADOW_LIT,
    TO_CAMERA,
    TO_CAMERA_BLOCKED,
    RayRecord,
    Segment,
)
from wrt.kernels.traverse import VisitLog, trace_visits
from wrt.kernels.variants import RECORDING, all_features_kernel

from .aot import load
from .bvh import node_bounds
from .device import resolve_device
from .errors import WrtError
from .loader import override_render
from .renderer import light_tracing, prepare
from .scene import Scene

SHADOW_KINDS = (SHADOW_LIT, SHADOW_BLOCKED, TO_CAMERA, TO_CAMERA_BLOCKED)
"""The kinds of shadow rays (any-hit queries toward a light or the camera)."""
DEFAULT_CAPACITY = 1 << 18  # segments (about 30 MB); a whitted camera ray is at most 512 plus its shadow rays
MAX_VISITS = 512  # BVH nodes logged per replayed ray (--show-bvh)


@dataclass
class RayTree:
    """Segments recorded by the render kernels for some pixels (world space, float32 unless said).

    One row per ray segment, in the order each pixel's thread traced them (depth first), pixels
    in the order asked, samples in order. ``parent[i]`` is the row whose end segment ``i`` starts
    from (-1 for a camera ray, and for the light tracer's rays leaving a light and its connections
    of a light to the camera), so the tree of each (pixel, sample) is recoverable.

    Attributes
    ----------
    scene : Scene
        The scene traced (with ``max_depth`` as overridden).
    pixels : (P, 2) int
        The pixels asked for, (x, y), row 0 at the top.
    rgb : (P, 3) float32
        Their radiance (W/(m^2 sr)) from the recording launch: what ``wrt.render`` gives with
        ``spp = samples``. The light tracer's (``integrator = "ptracer"``): what the recorded light
        paths splatted onto them, a part of their value only (their light comes from every slot's
        paths).
    position : (P, 3) float32
        Their ``position`` AOV (pixel-centre ray; 0 on a miss).
    samples : int
        Samples per pixel traced (1: the pixel centre).
    pixel : (N, 2) int
        (x, y) of each segment's pixel.
    sample, kind, depth, parent, shape : (N,) int
        Sample index; kind (an index into ``KIND_NAMES``); ray segments of the path up to this one
        (camera ray = 1, the ``max_depth`` counting); parent row or -1; ``object_id`` of the
        surface hit or -1.
    origin, end, direction, normal, throughput : (N, 3)
        Start; end (hit point, the light for a shadow ray reaching a point or spot light, or
        ``origin + direction`` for an escaped ray); unit direction; unit geometric normal at the
        hit (outward / winding normal, not flipped; 0 without a hit); path weight carried.
    hit, entering, escaped, in_medium : (N,) bool
        Ends on a surface; hits it from its front side (against ``normal``); left the scene; ends
        at a scattering event in a participating medium (the next segments start there).
    time : (N,) float32
        Ray time of each segment (its camera sample's time in the shutter interval).
    recorded : int
        Segments the kernels produced; more than ``N`` when the buffer's capacity cut the
        recording short (``truncated``), in which case some ``parent`` rows are >= N.
    visit_row, visit_node : (V,) int
        With ``bvh=True``: the BVH nodes the closest-hit query of each non-shadow segment visits,
        in order (``visit_row``: the segment's row; replayed by the render kernels' traversal
        code from the segment's start, ``wrt.kernels.traverse.trace_visits``); empty otherwise.
    bvh_lo, bvh_hi : (M, 3) float32
        Bounds of every node of the 4-wide BVH (index = ``visit_node``; a node's box is the union
        of its children's) with ``bvh=True``; empty otherwise.
    """

    scene: Scene
    pixels: np.ndarray
    rgb: np.ndarray
    position: np.ndarray
    samples: int
    pixel: np.ndarray
    sample: np.ndarray
    kind: np.ndarray
    depth: np.ndarray
    parent: np.ndarray
    shape: np.ndarray
    origin: np.ndarray
    end: np.ndarray
    direction: np.ndarray
    normal: np.ndarray
    throughput: np.ndarray
    hit: np.ndarray
    entering: np.ndarray
    escaped: np.ndarray
    in_medium: np.ndarray
    time: np.ndarray
    recorded: int
    visit_row: np.ndarray
    visit_node: np.ndarray
    bvh_lo: np.ndarray
    bvh_hi: np.ndarray

    KIND_NAMES = KIND_NAMES

    def __len__(self) -> int:
        return len(self.kind)

    @property
    def truncated(self) -> bool:
        return self.recorded > len(self)

    def kind_name(self, i: int) -> str:
        return KIND_NAMES[self.kind[i]]

    def children(self, i: int) -> np.ndarray:
        """Rows whose parent is row ``i``."""
        return np.flatnonzero(self.parent == i)

    def select(self, x: int, y: int, sample: int = 0) -> np.ndarray:
        """Rows of the tree of pixel (x, y), sample ``sample``."""
        return np.flatnonzero((self.pixel[:, 0] == x) & (self.pixel[:, 1] == y) & (self.sample == sample))


def grid_pixels(width: int, height: int, nx: int, ny: int) -> list[tuple[int, int]]:
    """The centre pixels of an ``nx`` x ``ny`` grid of equal cells over a ``width`` x ``height`` image."""
    if nx < 1 or ny < 1 or nx > width or ny > height:
        raise WrtError(f"grid {nx} x {ny}: must be between 1 x 1 and the image size {width} x {height}")
    return [(int((i + 0.5) * width / nx), int((j + 0.5) * height / ny)) for j in range(ny) for i in range(nx)]


def trace_rays(
    scene: Scene,
    pixels,
    *,
    samples: int = 1,
    max_depth: int | None = None,
    device: str | None = "cpu",
    capacity: int = DEFAULT_CAPACITY,
    bvh: bool = False,
) -> RayTree:
    """Trace pixels of ``scene`` with its integrator, recording every ray segment.

    Parameters
    ----------
    scene : Scene
        From ``wrt.load_scene``.
    pixels : sequence of (x, y)
        Pixels to trace (row 0 at the top); repeats are traced once.
    samples : int
        Samples per pixel, as ``spp`` of a render with the scene's seed: 1 traces the pixel
        centre, more spread the samples over the pixel.
    max_depth : int, optional
        Override ``[render] max_depth`` (ray segments per path, the camera ray included).
    device : str
        Warp device, "cpu" or "cuda".
    capacity : int
        Segments the record buffer holds; a recording that needs more is cut (``truncated``).
    bvh : bool
        Also log the BVH nodes each non-shadow segment's closest-hit query visits.

    Raises
    ------
    WrtError
        A pixel outside the image, ``samples`` or ``capacity`` < 1, ``max_depth`` out of range.
    """
    scene = override_render(scene, source="max_depth override", max_depth=max_depth)
    w, h = scene.render.width, scene.render.height
    chosen = list(dict.fromkeys((int(x), int(y)) for x, y in pixels))
    if not chosen:
        raise WrtError("no pixel to trace: give at least one")
    for x, y in chosen:
        if not (0 <= x < w and 0 <= y < h):
            raise WrtError(f"pixel ({x}, {y}) is outside the {w} x {h} image (x in [0, {w - 1}], y in [0, {h - 1}])")
    if samples < 1:
        raise WrtError(f"samples must be >= 1, got {samples}")
    if capacity < 1:
        raise WrtError(f"capacity must be >= 1, got {capacity}")
    assert scene.render.integrator in RECORDING
    dev = resolve_device(device)
    kernel = all_features_kernel(scene.render.integrator, record=True, cuda=dev.is_cuda)
    load(kernel.module, dev)
    device_scene = prepare(scene, dev)
    rec = RayRecord()
    rec.count = wp.zeros(1, dtype=wp.int32, device=dev)
    rec.segments = wp.zeros(capacity, dtype=Segment, device=dev)
    tracing = light_tracing(scene, w * h, dev) if scene.render.integrator == "ptracer" else None
    for x, y in chosen:  # one thread per launch: each pixel's segments stay together, in order
        device_scene.launch(kernel, y * w + x, 1, samples, scene.render.seed, rec, tracing=tracing)
    recorded = int(rec.count.numpy()[0])
    seg = rec.segments.numpy()[: min(recorded, capacity)]
    flags = seg["flags"]
    visit_row, visit_node, bvh_lo, bvh_hi = (np.zeros(0, dtype=np.int64),) * 2 + (
        np.zeros((0, 3), dtype=np.float32),
    ) * 2
    if bvh:
        visit_row, visit_node = bvh_visits(device_scene, seg, dev)
        bvh_lo, bvh_hi = node_bounds(device_scene.geometry.nodes.numpy())
    index = np.array([y * w + x for x, y in chosen])
    rgb = device_scene.film.rgb.numpy()[index]
    if tracing is not None:  # what the recorded light paths splatted there
        rgb = (tracing.splat.numpy()[index] / (FIXED_POINT * samples)).astype(np.float32)
    position = device_scene.film.position.numpy()[index]
    return RayTree(
        scene=scene,
        pixels=np.array(chosen, dtype=np.int64).reshape(-1, 2),
        rgb=rgb,
        position=position,
        samples=samples,
        pixel=np.stack([seg["pixel"] % w, seg["pixel"] // w], axis=1),
        sample=seg["sample"],
        kind=seg["kind"],
        depth=seg["depth"],
        parent=seg["parent"],
        shape=seg["shape"],
        origin=seg["origin"],
        end=seg["end"],
        direction=seg["direction"],
        normal=seg["normal"],
        throughput=seg["throughput"],
        hit=(flags & HIT) != 0,
        entering=(flags & ENTERING) != 0,
        escaped=(flags & ESCAPED) != 0,
        in_medium=(flags & IN_MEDIUM) != 0,
        time=seg["time"],
        recorded=recorded,
        visit_row=visit_row,
        visit_node=visit_node,
        bvh_lo=bvh_lo,
        bvh_hi=bvh_hi,
    )


def bvh_visits(device_scene, seg: np.ndarray, dev) -> tuple[np.ndarray, np.ndarray]:
    """``(row, node)`` of every BVH node the closest-hit query of each recorded non-shadow segment
    visits, in order: the segments replayed through ``wrt.kernels.traverse.trace_visits``."""
    rows = np.flatnonzero(~np.isin(seg["kind"], SHADOW_KINDS))
    if len(rows) == 0 or device_scene.geometry.nodes.shape[0] == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    log = VisitLog()
    log.nodes = wp.zeros((len(rows), MAX_VISITS), dtype=wp.int32, device=dev)
    log.count = wp.zeros(len(rows), dtype=wp.int32, device=dev)
    origins = wp.array(np.ascontiguousarray(seg["origin"][rows]), dtype=wp.vec3, device=dev)
    directions = wp.array(np.ascontiguousarray(seg["direction"][rows]), dtype=wp.vec3, device=dev)
    times = wp.array(np.ascontiguousarray(seg["time"][rows]), dtype=float, device=dev)
    wp.launch(trace_visits, dim=len(rows), inputs=[device_scene.geometry, origins, directions, times, log], device=dev)
    count = np.minimum(log.count.numpy(), MAX_VISITS)
    nodes = log.nodes.numpy()
    keep = np.arange(MAX_VISITS)[None, :] < count[:, None]
    return np.repeat(rows, count), nodes[keep].astype(np.int64)
