"""Emitters with area (parallelogram and sphere lights) and the environment: sampling a direction
toward them from a point, and the density of a direction that hit them, for next-event
estimation with multiple importance sampling.

Units: ``radiance`` in W/(m^2 sr). A parallelogram light (``corner``, ``edge_u``, ``edge_v``)
emits from the side of ``cross(edge_u, edge_v)`` only; a sphere light outward; the environment
uniformly from every direction. Densities are per unit solid angle at the receiving point.
"""

import warp as wp

from .intersect import intersect_sphere
from .lights import AREA, ENVIRONMENT, SPHERE_LIGHT, LightData
from .sample_warps import cone_one_minus_cos, frame, uniform_cone, uniform_sphere


@wp.func
def area_normal_and_size(lights: LightData, i: wp.int32):
    """Unit emitting normal and area of parallelogram light ``i``."""
    n = wp.cross(lights.edge_u[i], lights.edge_v[i])
    area = wp.length(n)
    return n / area, area


@wp.func
def sample_emitter(lights: LightData, i: wp.int32, p: wp.vec3, u1: float, u2: float):
    """Direction toward emitter ``i`` from ``p``: ``(wi, distance, radiance, pdf)``.

    Parallelogram: a uniform point on it (density 1/area converted to solid angle, ``d^2 /
    (area cos)``), zero where its back faces ``p``. Sphere: uniform in the cone it subtends
    (``1 / (2 pi (1 - cos_max))``, with ``1 - cos_max`` from ``r^2 / d^2`` without cancellation,
    so a sphere of 1e-7 of its distance keeps its irradiance), zero from inside. Environment: uniform on the sphere
    (``1 / (4 pi)``), infinitely far.
    """
    kind = lights.type[i]
    if kind == AREA:
        q = lights.position[i] + u1 * lights.edge_u[i] + u2 * lights.edge_v[i]
        to_q = q - p
        dist2 = wp.dot(to_q, to_q)
        dist = wp.sqrt(dist2)
        wi = to_q / dist
        n, area = area_normal_and_size(lights, i)
        cos_light = -wp.dot(wi, n)
        if cos_light <= 0.0 or dist2 == 0.0:
            return wi, dist, wp.vec3(0.0), 0.0
        return wi, dist, lights.power[i], dist2 / (area * cos_light)
    if kind == SPHERE_LIGHT:
        to_c = lights.position[i] - p
        dist2 = wp.dot(to_c, to_c)
        r = lights.radius[i]
        if dist2 <= r * r:
            return wp.vec3(0.0, 0.0, 1.0), 0.0, wp.vec3(0.0), 0.0
        one_minus_cos = cone_one_minus_cos(r * r / dist2)
        wi = frame(to_c / wp.sqrt(dist2)) * uniform_cone(u1, u2, one_minus_cos)
        tangent = wp.sqrt(wp.max(0.0, dist2 - r * r))
        dist = intersect_sphere(p, wi, lights.position[i], r, 0.0, tangent * 2.0)
        if dist >= tangent * 2.0:  # grazing the silhouette: rounding missed it
            dist = tangent
        return wi, dist, lights.power[i], 1.0 / (2.0 * wp.pi * one_minus_cos)
    return uniform_sphere(u1, u2), wp.inf, lights.power[i], 1.0 / (4.0 * wp.pi)


@wp.func
def emitter_pdf(lights: LightData, i: wp.int32, p: wp.vec3, wi: wp.vec3, dist: float) -> float:
    """Solid-angle density with which ``sample_emitter`` picks direction ``wi`` from ``p``, given
    that the ray along ``wi`` meets emitter ``i`` at ``dist`` (for MIS weights of BSDF samples)."""
    kind = lights.type[i]
    if kind == AREA:
        n, area = area_normal_and_size(lights, i)
        cos_light = -wp.dot(wi, n)
        if cos_light <= 0.0:
            return 0.0
        return dist * dist / (area * cos_light)
    if kind == SPHERE_LIGHT:
        to_c = lights.position[i] - p
        dist2 = wp.dot(to_c, to_c)
        r = lights.radius[i]
        if dist2 <= r * r:
            return 0.0
        return 1.0 / (2.0 * wp.pi * cone_one_minus_cos(r * r / dist2))
    if kind == ENVIRONMENT:
        return 1.0 / (4.0 * wp.pi)
    return 0.0
