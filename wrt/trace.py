"""Ray batches against a scene: closest-hit and any-hit queries through the renderer's own BVH
and traversal kernels. One API for the tests, the stress suite and the benchmarks.

>>> tracer = Tracer(wrt.load_scene("examples/showcase.toml"))
>>> t, prim = tracer.closest(origins, directions)      # (N,) float32 each; t = t_max, prim -1 on a miss
>>> tracer.occluded(origins, directions, t_max=10.0)   # (N,) bool

Rays are world space; directions need not be unit (``t`` is then in units of their length).
Primitives are the packed ids of ``wrt.kernels.traverse`` (``prims.shape_of`` maps them to
shape indices). The kernels are the all-features ones unless ``specialize=True`` asks for those
of the scene's geometry (a triangle mesh: no sphere or polygon tests), as a large render of the
scene uses; each variant compiles (seconds) the first time.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from .device import resolve_device, upload_geometry
from .geometry import build
from .kernels.features import ALL
from .kernels.traverse import KIND_BITS, trace_kernels
from .renderer import scene_features
from .scene import Scene

__all__ = ["Tracer", "vec3_array"]


def vec3_array(a, device) -> wp.array:
    """``a`` (anything of shape (..., 3)) as a ``wp.vec3`` array of float32 on ``device``."""
    return wp.array(np.ascontiguousarray(np.asarray(a, np.float32).reshape(-1, 3)), dtype=wp.vec3, device=device)


class Tracer:
    """A scene's primitives and BVH on ``device``, and batch queries against them.

    ``prims`` is the host side (``wrt.geometry.Primitives``, leaf order), ``data`` the device
    side (``wrt.kernels.traverse.GeometryData``).
    """

    def __init__(self, scene: Scene, *, device: str = "cpu", specialize: bool = False):
        self.device = resolve_device(device)
        self.prims = build(scene, self.device)
        self.data = upload_geometry(self.prims, self.device)
        self.closest_kernel, self.any_kernel, self.visits_kernel = trace_kernels(
            scene_features(scene) if specialize else ALL
        )

    def closest(self, origins, directions, t_min: float = 0.0, t_max: float = np.inf, brute_force: bool = False):
        """``(t, packed primitive id)`` per ray in ``(t_min, t_max)``; ``t = t_max`` and id -1 on a
        miss. ``brute_force`` tests every primitive instead of walking the BVH (a reference)."""
        t, prim, _inst = self.closest_instanced(origins, directions, t_min, t_max, brute_force)
        return t, prim

    def closest_instanced(
        self, origins, directions, t_min: float = 0.0, t_max: float = np.inf, brute_force: bool = False
    ):
        """``closest``, with the instance each primitive was hit through (-1: the scene's own;
        the primitive is then its group's, in the group's object space)."""
        o, d = vec3_array(origins, self.device), vec3_array(directions, self.device)
        t = wp.zeros(len(o), dtype=float, device=self.device)
        prim = wp.zeros(len(o), dtype=wp.int32, device=self.device)
        inst = wp.zeros(len(o), dtype=wp.int32, device=self.device)
        inputs = [self.data, o, d, float(t_min), float(t_max), int(brute_force), t, prim, inst]
        wp.launch(self.closest_kernel, dim=len(o), inputs=inputs, device=self.device)
        return t.numpy(), prim.numpy(), inst.numpy()

    def occluded(self, origins, directions, t_min: float = 0.0, t_max: float = np.inf):
        """Whether anything lies in ``(t_min, t_max)`` along each ray."""
        o, d = vec3_array(origins, self.device), vec3_array(directions, self.device)
        hit = wp.zeros(len(o), dtype=wp.int32, device=self.device)
        wp.launch(
            self.any_kernel, dim=len(o), inputs=[self.data, o, d, float(t_min), float(t_max), hit], device=self.device
        )
        return hit.numpy().astype(bool)

    def triangles(self, packed):
        """Vertices (n, 3, 3) of the triangles with these packed ids, as the device holds them
        (float32 values, returned as float64)."""
        return self.prims.tri_verts.astype(np.float64)[np.asarray(packed) >> KIND_BITS]
