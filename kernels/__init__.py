"""Warp device code of wrt: ``@wp.func`` building blocks and the ``@wp.kernel`` integrators.

Modules, in data-flow order:

- ``sampling``      counter-based random numbers (deterministic per pixel, sample, dimension)
- ``sample_warps``  uniform numbers to directions and points, with their densities; MIS weights
- ``camera``        pinhole and thin-lens camera rays, pixel filters
- ``intersect``     ray-primitive tests (plane, sphere, watertight triangle, polygon)
- ``bvh``           the 4-wide BVH's node layout and its four-box slab test
- ``bvh_build``     building that BVH on the device (Morton order, PLOC, SAH leaves, collapse)
- ``traverse``      the device-side geometry (``GeometryData``) and the BVH traversal
- ``features``      the scene features kernels are specialised on; ``variants``: the variants
- ``spawn``         the one origin offset for rays leaving a surface
- ``optics``        reflection, Snell refraction, Fresnel
- ``materials``     the material families (one module each) and the BSDF interface (flags, eval, pdf,
                    sample); ``microfacet``: GGX
- ``textures``      textured material parameters: checkerboard and bitmap lookups at a hit's uv
- ``hit``           the surface hit integrators shade (point, normals, material, error bound)
- ``lights``        the light families (one module each: delta, area, sphere, environment, the
                    emissive primitives) and the one light interface (``sample_li``, ``pdf_li``,
                    ``is_delta``, the environment's radiance)
- ``media``         nested and overlapping dielectrics along a ray, Beer-Lambert absorption
- ``volumes``       participating media (one module each: homogeneous, Henyey-Greenstein phase
                    functions): free-flight sampling, transmittance, the medium beyond a surface
- ``shadow``        the shadow ray (opaque or filtered through dielectrics), recorded or not
- ``film``          the per-pixel outputs and AOVs
- ``integrator``    the pixel loop every integrator shares, tracing a segment; ``record``: ray recording
- ``raycast``, ``whitted``, ``path``   the integrators
- ``stress``        kernels of the numerical stress suite
- ``cpu_target``    the CPU instruction set modules compile for (portable, so they can be shipped compiled)

This package imports only Warp (and numpy): it knows nothing of scene files, images or the harness.
Each of its Warp modules is compiled without gradients (``MODULE_OPTIONS``: smaller modules,
faster compiles), set per module; importing it configures Warp for the process only where the
setting is the machine's: CPU code for a portable instruction set (``cpu_target``) where this CPU
has it, which the objects ``wrt.aot`` ships are keyed on, and no informational log lines on the
console.
"""

import warp as wp

from .cpu_target import cpu_compiler_flags

MODULE_OPTIONS = {"enable_backward": False}
"""The Warp options of every module of wrt's kernels (``wp.set_module_options``)."""


def hinted_func(inline: bool | None):
    """``wp.func`` with Warp's inline hint ``inline``: plain ``wp.func`` for None (the compiler's
    choice), ``wp.func(inline=False)`` for out of line (``__noinline__`` on CUDA)."""
    return wp.func if inline is None else wp.func(inline=inline)


wp.config.log_level = wp.LOG_WARNING
wp.config.cpu_compiler_flags = cpu_compiler_flags()
