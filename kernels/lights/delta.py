"""``point``, ``directional`` and ``spot``: the delta lights, which have no surface to hit and no
density, and what they deliver to a point.

Units: point and spot ``intensity`` in W/sr, directional ``irradiance`` in W/m^2. A point light at
distance d delivers irradiance ``I / d^2`` on a surface facing it; the integrator multiplies by
the BRDF and the cosine at the receiver. A spot has Mitsuba 3's profile.
"""

import warp as wp

from ..materials import MaterialData
from ..sampling import Sampler
from ..traverse import GeometryData
from .data import LightData, LightSample
from .interface import Family, Functions, Options

POINT = wp.constant(0)
DIRECTIONAL = wp.constant(1)
SPOT = wp.constant(2)


@wp.func
def spot_falloff(lights: LightData, i: wp.int32, w: wp.vec3) -> float:
    """Mitsuba 3's spot profile for unit ``w`` leaving the light: 1 inside the beam, linear in
    angle down to 0 at the cutoff."""
    cos_theta = wp.dot(w, lights.direction[i])
    if cos_theta <= lights.cos_cutoff[i]:
        return 0.0
    theta = wp.acos(wp.clamp(cos_theta, -1.0, 1.0))
    if theta <= lights.beam[i]:
        return 1.0
    return (lights.cutoff[i] - theta) / (lights.cutoff[i] - lights.beam[i])


@wp.func
def light_incident(lights: LightData, i: wp.int32, p: wp.vec3):
    """Light ``i`` seen from ``p``: ``(wi, distance, irradiance)`` with ``wi`` the unit direction
    toward the light, ``distance`` to it (inf for directional) and the irradiance (W/m^2) it
    delivers to a surface at ``p`` facing it; none from a light that is not a delta light."""
    light_type = lights.type[i]
    if light_type == DIRECTIONAL:
        return -lights.direction[i], wp.inf, lights.power[i]
    if light_type > SPOT:
        return wp.vec3(0.0, 0.0, 1.0), 0.0, wp.vec3(0.0)
    to_light = lights.position[i] - p
    dist2 = wp.dot(to_light, to_light)
    if dist2 == 0.0:
        return wp.vec3(0.0, 0.0, 1.0), 0.0, wp.vec3(0.0)
    dist = wp.sqrt(dist2)
    wi = to_light / dist
    e = lights.power[i] / dist2
    if light_type == SPOT:
        e = e * spot_falloff(lights, i, -wi)
    return wi, dist, e


@wp.func
def owns(light_type: wp.int32) -> bool:
    return light_type <= SPOT


@wp.func
def sample_li(
    geometry: GeometryData,
    materials: MaterialData,
    lights: LightData,
    i: wp.int32,
    p: wp.vec3,
    time: float,
    sampler: Sampler,
    pixel: wp.int32,
    sample: wp.int32,
    dim: wp.int32,
) -> LightSample:
    """Exactly what light ``i`` delivers: its irradiance, density 1, the shadow ray all the way."""
    wi, dist, irradiance = light_incident(lights, i, p)
    ls = LightSample()
    ls.wi = wi
    ls.radiance = irradiance
    ls.pdf = 1.0
    ls.t_max = dist
    return ls


def row(light) -> dict:
    if light.type == "point":
        return {"type": POINT, "position": light.position, "power": light.intensity}
    if light.type == "directional":
        return {"type": DIRECTIONAL, "direction": light.direction, "power": light.irradiance}
    return {
        "type": SPOT,
        "position": light.position,
        "direction": light.direction,
        "power": light.intensity,
        "cutoff": light.cutoff_angle,
        "beam": light.beam_width,
    }


def make(options: Options) -> Functions:
    return Functions(owns, sample_li)


FAMILY = Family(
    name="delta",
    codes=(POINT, DIRECTIONAL, SPOT),
    make=make,
    light_types=("point", "directional", "spot"),
    row=row,
    delta=True,
)
