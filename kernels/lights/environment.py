"""``environment``: radiance arriving from every direction, infinitely far: constant
(``ENVIRONMENT``, sampled uniformly on the sphere) or as its map says (``ENVIRONMENT_MAP``,
Mitsuba 3's ``envmap``, sampled by luminance; ``wrt.envmap`` describes the mapping, the bilinear
lookup and the distribution). At most one map per scene; its code is compiled in only where a
scene has one (``Options.environment_map``). Densities are per unit solid angle.
"""

import functools

import warp as wp

from ..materials import MaterialData
from ..sample_warps import concentric_disk, find_interval, frame, uniform_sphere
from ..sampling import Sampler, sample_2d
from ..traverse import GeometryData
from .data import EmissionSample, LightData, LightSample, emission_ray, surface_sample
from .interface import Family, Functions, Options

ENVIRONMENT = wp.constant(6)
ENVIRONMENT_MAP = wp.constant(7)


@wp.func
def environment_map_cell(lights: LightData, w: wp.vec3):
    """The cell ``(j, i)`` of the environment map that world direction ``w`` falls in, and where in
    it: ``(j, i, fy, fx)`` with fy, fx in [0, 1] from row j and (wrapping) column i toward the next."""
    height = lights.env_radiance.shape[0]
    width = lights.env_radiance.shape[1]
    local = wp.transpose(lights.env_to_world) * w
    u = wp.atan2(local[0], -local[2]) / (2.0 * wp.pi)
    x = u * float(width) - 0.5
    x = x - wp.floor(x / float(width)) * float(width)
    y = wp.acos(wp.clamp(local[1], -1.0, 1.0)) / wp.pi * float(height - 1)
    i = wp.clamp(int(x), 0, width - 1)
    j = wp.clamp(int(y), 0, height - 2)
    return j, i, y - float(j), x - float(i)


@wp.func
def environment_map_radiance(lights: LightData, k: wp.int32, w: wp.vec3) -> wp.vec3:
    """Radiance (W/(m^2 sr)) arriving from world direction ``w`` (unit, pointing away from the
    receiver) out of environment map light ``k``: the map looked up bilinearly, times its ``power``."""
    j, i, fy, fx = environment_map_cell(lights, w)
    i1 = (i + 1) % lights.env_radiance.shape[1]
    top = lights.env_radiance[j, i] * (1.0 - fx) + lights.env_radiance[j, i1] * fx
    bottom = lights.env_radiance[j + 1, i] * (1.0 - fx) + lights.env_radiance[j + 1, i1] * fx
    return wp.cw_mul(lights.power[k], top * (1.0 - fy) + bottom * fy)


@wp.func
def environment_map_pdf(lights: LightData, w: wp.vec3) -> float:
    """Solid-angle density with which ``sample_environment_map`` picks world direction ``w``."""
    j, i, fy, fx = environment_map_cell(lights, w)
    return lights.env_pdf[j, i]


@wp.func
def sample_environment_map(lights: LightData, k: wp.int32, u1: float, u2: float):
    """A direction from environment map light ``k`` by its luminance: ``(wi, radiance, pdf)``, wi
    world space. A cell row by ``u1``, a cell within it by ``u2``, then uniform in azimuth and
    ``cos theta`` within the cell by what is left of each."""
    height = lights.env_radiance.shape[0]
    width = lights.env_radiance.shape[1]
    cdf = lights.env_cdf
    j = find_interval(cdf, 0, height, u1)
    fv = wp.clamp((u1 - cdf[j]) / (cdf[j + 1] - cdf[j]), 0.0, 1.0)
    start = height + j * (width + 1)
    i = find_interval(cdf, start, width + 1, u2)
    fu = wp.clamp((u2 - cdf[start + i]) / (cdf[start + i + 1] - cdf[start + i]), 0.0, 1.0)
    step = wp.pi / float(height - 1)
    cos0 = wp.cos(float(j) * step)
    cos_theta = cos0 + fv * (wp.cos(float(j + 1) * step) - cos0)
    sin_theta = wp.sqrt(wp.max(0.0, 1.0 - cos_theta * cos_theta))
    phi = 2.0 * wp.pi * (float(i) + fu + 0.5) / float(width)
    local = wp.vec3(sin_theta * wp.sin(phi), cos_theta, -sin_theta * wp.cos(phi))
    wi = lights.env_to_world * local
    return wi, environment_map_radiance(lights, k, wi), lights.env_pdf[j, i]


@functools.cache
def make_sample_environment(environment_map: bool):
    """``sample_environment``; with ``environment_map``, of a map too (else constant only)."""

    @wp.func
    def sample_environment(lights: LightData, i: wp.int32, u1: float, u2: float):
        """A direction from environment light ``i``: ``(wi, radiance, pdf)``, by the map's luminance
        or uniform on the sphere (``1 / (4 pi)``)."""
        if wp.static(environment_map):
            if lights.type[i] == ENVIRONMENT_MAP:
                return sample_environment_map(lights, i, u1, u2)
        return uniform_sphere(u1, u2), lights.power[i], 1.0 / (4.0 * wp.pi)

    return sample_environment


@functools.cache
def make(options: Options) -> Functions:
    environment_map = options.environment_map
    sample_environment = make_sample_environment(environment_map)

    @wp.func
    def owns(light_type: wp.int32) -> bool:
        if wp.static(environment_map):
            if light_type == ENVIRONMENT_MAP:
                return True
        return light_type == ENVIRONMENT

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
        u = sample_2d(sampler, pixel, sample, dim)
        wi, radiance, pdf = sample_environment(lights, i, u[0], u[1])
        return surface_sample(wi, wp.inf, radiance, pdf)

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
        """A ray from the sky: a direction ``wi`` toward it as ``sample_li`` draws it, the ray
        travelling along ``-wi`` from a uniform point of the disk of radius ``radius`` across
        ``wi``, ``radius`` beyond ``center`` (radiance times the disk's area over the density)."""
        wi, radiance, pdf = sample_environment(lights, i, u_dir[0], u_dir[1])
        if pdf <= 0.0:
            return emission_ray(center, -wi, wp.vec3(0.0))
        disk = concentric_disk(u_pos[0], u_pos[1])
        o = center + radius * (frame(wi) * wp.vec3(disk[0], disk[1], 1.0))
        return emission_ray(o, -wi, radiance * (wp.pi * radius * radius / pdf))

    @wp.func
    def le(lights: LightData, i: wp.int32, d: wp.vec3):
        if wp.static(environment_map):
            if lights.type[i] == ENVIRONMENT_MAP:
                return environment_map_radiance(lights, i, d), environment_map_pdf(lights, d)
        return lights.power[i], 1.0 / (4.0 * wp.pi)

    return Functions(owns, sample_li, sample_le, le=le)


def row(light) -> dict:
    return {"type": ENVIRONMENT if light.image is None else ENVIRONMENT_MAP, "power": light.radiance}


FAMILY = Family(
    name="environment",
    codes=(ENVIRONMENT, ENVIRONMENT_MAP),
    make=make,
    light_types=("environment",),
    row=row,
)
