"""The participating media's table on the device (``MediumData``) and what a free-flight sample
returns (``FreeFlight``).

Media are numbered in the scene's ``[[medium]]`` order; ``-1`` is vacuum. A surface bounds media
where its shape names an ``interior`` or ``exterior`` medium (Mitsuba 3's
``Shape::is_medium_transition``); ``UNSET`` in both columns marks one that does not, and a ray
crossing it stays in the medium it was in. Coefficients are per unit length, linear RGB, the
medium's ``scale`` applied.
"""

import warp as wp

UNSET = wp.constant(-2)  # a surface's interior / exterior: the shape names no medium on either side
VACUUM = wp.constant(-1)


@wp.struct
class MediumData:
    count: wp.int32  # media in the scene; 0: none (the path integrator's surface-only semantics)
    shape_interior: wp.array(dtype=wp.int32)  # per surface (wrt.bake.surface_materials' numbering)
    shape_exterior: wp.array(dtype=wp.int32)
    sigma_t: wp.array(dtype=wp.vec3)  # per medium: extinction coefficient, 1/length
    albedo: wp.array(dtype=wp.vec3)  # single-scattering albedo sigma_s / sigma_t, in [0, 1]
    g: wp.array(dtype=float)  # its phase function's Henyey-Greenstein asymmetry, in (-1, 1); 0: isotropic


@wp.struct
class FreeFlight:
    """One free-flight sample along a ray segment in a medium: ``scattered`` at distance ``t`` from
    the segment's start (a real scattering event), or not (the ray reached the segment's end);
    ``weight`` is what the path's throughput is multiplied by (transmittance, times ``sigma_s``
    where it scattered, over the sample's density)."""

    scattered: bool
    t: float
    weight: wp.vec3
