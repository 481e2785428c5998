"""``sphere``: a sphere light emitting ``radiance`` (W/(m^2 sr)) outward, sampled uniformly in the
cone it subtends (for the light tracer, a uniform point and a cosine-weighted direction from it);
and that cone's sampling, which emissive spheres share (``emitting``).

Its surface is surface ``num_shapes + k`` of the geometry for light row ``k``, a sphere that
reflects nothing.
"""

import warp as wp

from ..intersect import intersect_sphere
from ..sample_warps import cone_one_minus_cos, cosine_hemisphere, frame, uniform_cone, uniform_sphere
from .data import EmissionSample, LightData, surface_emission
from .interface import Family, Functions, Options, surface_light

SPHERE_LIGHT = wp.constant(5)


@wp.func
def sphere_solid_angle(center: wp.vec3, r: float, p: wp.vec3) -> float:
    """Solid angle ``2 pi (1 - cos_max)`` that a sphere subtends from ``p``; 0 from inside it."""
    to_c = center - p
    dist2 = wp.dot(to_c, to_c)
    if dist2 <= r * r:
        return 0.0
    return 2.0 * wp.pi * cone_one_minus_cos(r * r / dist2)


@wp.func
def sample_sphere_cone(center: wp.vec3, r: float, p: wp.vec3, u1: float, u2: float):
    """A direction from ``p`` uniform in the cone a sphere subtends: ``(wi, distance to the sphere
    along wi, the cone's solid angle)`` (the density is its inverse); from inside the sphere
    ``((0, 0, 1), 0, 0)``. ``1 - cos_max`` comes from ``r^2 / d^2`` without cancellation, so a
    sphere of 1e-7 of its distance keeps its irradiance."""
    to_c = center - p
    dist2 = wp.dot(to_c, to_c)
    if dist2 <= r * r:
        return wp.vec3(0.0, 0.0, 1.0), 0.0, 0.0
    one_minus_cos = cone_one_minus_cos(r * r / dist2)
    wi = frame(to_c / wp.sqrt(dist2)) * uniform_cone(u1, u2, one_minus_cos)
    tangent = wp.sqrt(wp.max(0.0, dist2 - r * r))
    dist = intersect_sphere(p, wi, center, r, 0.0, tangent * 2.0)
    if dist >= tangent * 2.0:  # grazing the silhouette: rounding missed it
        dist = tangent
    return wi, dist, 2.0 * wp.pi * one_minus_cos


@wp.func
def sample_sphere(lights: LightData, i: wp.int32, p: wp.vec3, u1: float, u2: float):
    """Direction toward sphere light ``i`` from ``p``: ``(wi, distance, radiance, pdf)``, uniform
    in its cone (``1 / (2 pi (1 - cos_max))``), zero from inside."""
    wi, dist, solid_angle = sample_sphere_cone(lights.position[i], lights.radius[i], p, u1, u2)
    if solid_angle == 0.0:
        return wi, dist, wp.vec3(0.0), 0.0
    return wi, dist, lights.power[i], 1.0 / solid_angle


@wp.func
def sphere_pdf(lights: LightData, i: wp.int32, p: wp.vec3, wi: wp.vec3, dist: float) -> float:
    """Solid-angle density with which ``sample_sphere`` picks any direction toward light ``i``."""
    solid_angle = sphere_solid_angle(lights.position[i], lights.radius[i], p)
    return wp.where(solid_angle == 0.0, 0.0, 1.0 / solid_angle)


@wp.func
def sphere_point(center: wp.vec3, r: float, u: wp.vec2):
    """A uniform point on a sphere (emissive spheres share it): ``(q, outward unit normal, area)``."""
    n = uniform_sphere(u[0], u[1])
    return center + r * n, n, 4.0 * wp.pi * r * r


@wp.func
def emit_sphere_light(lights: LightData, i: wp.int32, u_pos: wp.vec2, u_dir: wp.vec2) -> EmissionSample:
    """A ray leaving sphere light ``i``: a uniform point on it, a cosine-weighted direction outward."""
    q, n, area = sphere_point(lights.position[i], lights.radius[i], u_pos)
    return surface_emission(q, n, lights.power[i], 1.0 / area, cosine_hemisphere(u_dir[0], u_dir[1]))


def row(light) -> dict:
    return {"type": SPHERE_LIGHT, "position": light.center, "radius": light.radius, "power": light.radiance}


def make(options: Options) -> Functions:
    return surface_light(SPHERE_LIGHT, sample_sphere, sphere_pdf, emit_sphere_light)


FAMILY = Family(name="sphere", codes=(SPHERE_LIGHT,), make=make, light_types=("sphere",), row=row)
