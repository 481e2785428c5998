"""``point``, ``directional``, ``spot`` and ``projector``: the delta lights, which have no surface
to hit and no density, and what they deliver to a point.

Units: point and spot ``intensity`` in W/sr, directional ``irradiance`` in W/m^2, a projector's
``scale`` times its texture (W/m^2 on its image plane, below). A point light at distance d
delivers irradiance ``I / d^2`` on a surface facing it; the integrator multiplies by the BRDF and
the cosine at the receiver. A spot has Mitsuba 3's profile, times its texture where it has one.

The textured spot and the projector look their texture up through a pinhole frustum, as Mitsuba
3's ``spot`` and ``projector``: the direction from the light to the point, in the light's frame
(``LightData.frame``: x, y and z its direction), has uv ``1/2 + uv_scale (x, y) / z``. A spot's
``uv_scale`` is ``(1, 1) / (2 tan(cutoff))`` (its cone fits the texture's square); a projector's
``-(1 / aspect, 1) / (2 tan(fov / 2))`` for its vertical field of view ``fov`` and its texture's
aspect ratio (width / height): Mitsuba's ``perspective_projection``, whose image x runs against
the frame's x. A projector delivers ``pi scale texture(uv) d / z^3`` at distance ``d`` and depth
``z`` inside its frustum, nothing outside: a plane facing it at depth ``z`` receives irradiance
``pi scale texture / z^2`` (Mitsuba's scaling "so that irradiance at z = 1 is correct").
"""

import warp as wp

from ..materials import MaterialData
from ..sample_warps import concentric_disk, frame, uniform_cone, uniform_sphere
from ..sampling import Sampler
from ..textures import texture_rgb, uv_context
from ..traverse import GeometryData
from .data import EmissionSample, LightData, LightSample, emission_ray
from .interface import Family, Functions, Options

POINT = wp.constant(0)
DIRECTIONAL = wp.constant(1)
SPOT = wp.constant(2)
PROJECTOR = wp.constant(3)


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
def frustum_uv(lights: LightData, i: wp.int32, local: wp.vec3) -> wp.vec2:
    """The texture coordinates of light ``i``'s frustum along ``local`` (its frame, z > 0)."""
    scale = lights.uv_scale[i]
    return wp.vec2(0.5 + scale[0] * local[0] / local[2], 0.5 + scale[1] * local[1] / local[2])


@wp.func
def light_incident(lights: LightData, i: wp.int32, p: wp.vec3):
    """Light ``i`` seen from ``p``: ``(wi, distance, irradiance)`` with ``wi`` the unit direction
    toward the light, ``distance`` to it (inf for directional) and the irradiance (W/m^2) it
    delivers to a surface at ``p`` facing it; none from a light that is not a delta light."""
    light_type = lights.type[i]
    if light_type == DIRECTIONAL:
        return -lights.direction[i], wp.inf, lights.power[i]
    if light_type > PROJECTOR:
        return wp.vec3(0.0, 0.0, 1.0), 0.0, wp.vec3(0.0)
    to_light = lights.position[i] - p
    dist2 = wp.dot(to_light, to_light)
    if dist2 == 0.0:
        return wp.vec3(0.0, 0.0, 1.0), 0.0, wp.vec3(0.0)
    dist = wp.sqrt(dist2)
    wi = to_light / dist
    e = lights.power[i] / dist2
    t = lights.texture[i]
    if light_type == SPOT:
        falloff = spot_falloff(lights, i, -wi)
        e = e * falloff
        if t >= 0 and falloff > 0.0:
            e = wp.cw_mul(
                e, texture_rgb(lights.textures, t, uv_context(frustum_uv(lights, i, lights.frame[i] * (-wi))))
            )
    elif light_type == PROJECTOR:
        local = lights.frame[i] * (-to_light)
        z = local[2]
        e = wp.vec3(0.0)
        if z > 0.0:
            uv = frustum_uv(lights, i, local)
            if uv[0] >= 0.0 and uv[0] <= 1.0 and uv[1] >= 0.0 and uv[1] <= 1.0:
                radiance = wp.cw_mul(lights.power[i], texture_rgb(lights.textures, t, uv_context(uv)))
                e = radiance * (wp.pi * dist / (z * z * z))
    return wi, dist, e


@wp.func
def owns(light_type: wp.int32) -> bool:
    return light_type <= PROJECTOR


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


@wp.func
def sample_le(
    geometry: GeometryData,
    materials: MaterialData,
    lights: LightData,
    i: wp.int32,
    center: wp.vec3,
    radius: float,
    time: float,
    u_pos: wp.vec2,
    u_dir: wp.vec2,
    uc: float,
) -> EmissionSample:
    """A ray leaving delta light ``i``: a point light's uniform on the sphere, a spot's uniform in
    its cone, a projector's uniform over its image (in the plane at depth 1), carrying the
    intensity along it over that density; a directional light's from a uniform point of the disk
    of radius ``radius`` about ``center``, across its direction, backed off by ``radius`` (it
    carries irradiance times the disk's area)."""
    light_type = lights.type[i]
    if light_type == DIRECTIONAL:
        d = lights.direction[i]
        disk = concentric_disk(u_pos[0], u_pos[1])
        o = center + radius * (frame(d) * wp.vec3(disk[0], disk[1], -1.0))
        return emission_ray(o, d, lights.power[i] * (wp.pi * radius * radius))
    d = uniform_sphere(u_dir[0], u_dir[1])
    pdf = 1.0 / (4.0 * wp.pi)
    if light_type == SPOT:
        one_minus_cos = 1.0 - lights.cos_cutoff[i]
        d = frame(lights.direction[i]) * uniform_cone(u_dir[0], u_dir[1], one_minus_cos)
        pdf = 1.0 / (2.0 * wp.pi * one_minus_cos)
    elif light_type == PROJECTOR:
        scale = lights.uv_scale[i]
        local = wp.vec3((u_dir[0] - 0.5) / scale[0], (u_dir[1] - 0.5) / scale[1], 1.0)
        length = wp.length(local)
        d = wp.transpose(lights.frame[i]) * (local / length)
        pdf = wp.abs(scale[0] * scale[1]) * length * length * length  # per unit image area, over cos^3
    o = lights.position[i]
    _wi, _dist, intensity = light_incident(lights, i, o + d)  # the irradiance at distance 1
    return emission_ray(o, d, intensity / pdf)


def row(light) -> dict:
    if light.type == "point":
        return {"type": POINT, "position": light.position, "power": light.intensity}
    if light.type == "directional":
        return {"type": DIRECTIONAL, "direction": light.direction, "power": light.irradiance}
    if light.type == "projector":
        return {
            "type": PROJECTOR,
            "position": light.position,
            "direction": light.direction,
            "power": (light.scale,) * 3,
            "frame": light.frame(),
            "uv_scale": light.uv_scale(),
            "texture": light.irradiance,
        }
    row = {
        "type": SPOT,
        "position": light.position,
        "direction": light.direction,
        "power": light.intensity,
        "cutoff": light.cutoff_angle,
        "beam": light.beam_width,
    }
    if light.texture is not None:
        row.update(frame=light.frame(), uv_scale=light.uv_scale(), texture=light.texture)
    return row


def make(options: Options) -> Functions:
    return Functions(owns, sample_li, sample_le)


FAMILY = Family(
    name="delta",
    codes=(POINT, DIRECTIONAL, SPOT, PROJECTOR),
    make=make,
    light_types=("point", "directional", "spot", "projector"),
    row=row,
    delta=True,
)
