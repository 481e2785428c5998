"""The participating media's table on the device (``MediumData``) and what a free-flight sample
returns (``FreeFlight``).

Media are numbered in the scene's ``[[medium]]`` order; ``-1`` is vacuum. A surface bounds media
where its shape names an ``interior`` or ``exterior`` medium (Mitsuba 3's
``Shape::is_medium_transition``); ``UNSET`` in both columns marks one that does not, and a ray
crossing it stays in the medium it was in. Coefficients are per unit length, linear RGB, the
medium's ``scale`` applied. An emissive medium (Mitsuba 3's ``volumelight``) adds radiance along
each unit length a ray crosses: the source term of the radiative transfer equation, which does not
depend on the medium's absorption (pbrt-v4's ``sigma_a Le``), and is attenuated as the light it
adds travels on.
"""

import warp as wp

HOMOGENEOUS = wp.constant(0)  # MediumData.kind: constant coefficients (kernels/volumes/homogeneous.py)
GRID = wp.constant(1)  # coefficients from volumes (kernels/volumes/grid.py)
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
    emission: wp.array(dtype=wp.vec3)  # per HOMOGENEOUS medium: radiance emitted per unit length, W/(m^2 sr m)
    kind: wp.array(dtype=wp.int32)  # per medium: HOMOGENEOUS or GRID
    density: wp.array(dtype=wp.int32)  # per GRID medium: the volume row of its extinction (scale applied)
    tint: wp.array(dtype=wp.int32)  # and of its albedo
    glow: wp.array(dtype=wp.int32)  # and of its emission (-1: none), as ``emission``
    majorant: wp.array(dtype=float)  # and the largest of its tracking bounds (1/length; 0: clear)
    majorant_res: wp.array(dtype=wp.vec3i)  # its majorant grid's cells along x, y, z (over its extinction's unit cube)
    majorant_offset: wp.array(dtype=wp.int32)  # where its cells start in majorant_cells
    majorant_cells: wp.array(dtype=float)  # every majorant grid's bounds, x fastest, then y, then z
    volume_to_local: wp.array(dtype=wp.mat44)  # per volume: world to the unit cube of its grid
    volume_res: wp.array(dtype=wp.vec3i)  # its texels along x, y, z
    volume_offset: wp.array(dtype=wp.int32)  # where its texels start in volume_values
    volume_values: wp.array(dtype=wp.vec3)  # every volume's texels, x fastest, then y, then z


@wp.struct
class FreeFlight:
    """One free-flight sample along a ray segment in a medium: ``scattered`` at distance ``t`` from
    the segment's start (a real scattering event), or not (the ray reached the segment's end);
    ``weight`` is what the path's throughput is multiplied by (transmittance, times ``sigma_s``
    where it scattered, over the sample's density); ``emitted`` an unbiased estimate of the
    radiance the medium emits along the whole segment towards its start, ``int T(s) emission(s)
    ds`` (to be weighted by the throughput before the flight)."""

    scattered: bool
    t: float
    weight: wp.vec3
    emitted: wp.vec3
