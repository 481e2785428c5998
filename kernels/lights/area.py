"""``area``: a parallelogram light (``corner``, ``edge_u``, ``edge_v``) emitting ``radiance``
(W/(m^2 sr)) from the side of ``cross(edge_u, edge_v)`` only, sampled by a uniform point on it
(and, for the light tracer, a cosine-weighted direction from it).

Its surface is surface ``num_shapes + k`` of the geometry for light row ``k`` (``wrt.geometry``'s
numbering), a polygon that reflects nothing.
"""

import warp as wp

from ..sample_warps import cosine_hemisphere
from .data import EmissionSample, LightData, surface_emission
from .interface import Family, Functions, Options, surface_light

AREA = wp.constant(4)


@wp.func
def area_normal_and_size(lights: LightData, i: wp.int32):
    """Unit emitting normal and area of parallelogram light ``i``."""
    n = wp.cross(lights.edge_u[i], lights.edge_v[i])
    area = wp.length(n)
    return n / area, area


@wp.func
def sample_area(lights: LightData, i: wp.int32, p: wp.vec3, u1: float, u2: float):
    """Direction toward parallelogram light ``i`` from ``p``: ``(wi, distance, radiance, pdf)``,
    a uniform point on it (density 1/area converted to solid angle, ``d^2 / (area cos)``), zero
    where its back faces ``p``."""
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


@wp.func
def area_pdf(lights: LightData, i: wp.int32, p: wp.vec3, wi: wp.vec3, dist: float) -> float:
    """Solid-angle density with which ``sample_area`` picks ``wi``, given that the ray along it
    meets light ``i`` at ``dist`` (0 on its back)."""
    n, area = area_normal_and_size(lights, i)
    cos_light = -wp.dot(wi, n)
    if cos_light <= 0.0:
        return 0.0
    return dist * dist / (area * cos_light)


@wp.func
def emit_area(lights: LightData, i: wp.int32, u_pos: wp.vec2, u_dir: wp.vec2) -> EmissionSample:
    """A ray leaving parallelogram light ``i``: a uniform point, a cosine-weighted direction."""
    n, area = area_normal_and_size(lights, i)
    o = lights.position[i] + u_pos[0] * lights.edge_u[i] + u_pos[1] * lights.edge_v[i]
    return surface_emission(o, n, lights.power[i], 1.0 / area, cosine_hemisphere(u_dir[0], u_dir[1]))


def row(light) -> dict:
    return {
        "type": AREA,
        "position": light.corner,
        "edge_u": light.edge_u,
        "edge_v": light.edge_v,
        "power": light.radiance,
    }


def make(options: Options) -> Functions:
    return surface_light(AREA, sample_area, area_pdf, emit_area)


FAMILY = Family(name="area", codes=(AREA,), make=make, light_types=("area",), row=row)
