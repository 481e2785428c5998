"""The light interface integrators use: every light and the pool of emissive primitives behind one
set of functions, so that ``is_delta`` is the only question an integrator asks of a light.

Emitters ``i`` in ``[0, count)``: the scene's lights in file order (``LightData`` rows), then,
where the scene has emissive primitives (``wrt.emitting``), the pool of them as emitter
``lights.type.shape[0]``.

- ``is_delta(lights, i)``: a point, directional or spot light (``wrt.kernels.lights``): no surface
  to hit, no density, so no MIS;
- ``sample_li(geometry, materials, lights, i, p, time, sampler, pixel, sample, dim)``: light from
  emitter ``i`` at ``p`` (a ``LightSample``); a delta light's exactly (``light_incident``, density
  1), others by ``wrt.kernels.emitters``, with the 2D sample at ``dim`` and the pool's choice of a
  primitive at ``dim + 2``;
- ``pdf_li(geometry, lights, shape, prim, inst, p, wi, dist)``: the solid-angle density with which
  ``sample_li`` would have drawn ``wi`` from ``p`` toward the surface a ray along ``wi`` hit at
  ``dist`` (a light's surface, or an emissive primitive outside instances); 0 for a surface it
  does not sample, so the MIS weight of what a BSDF sample found there is 1;
- ``environment_radiance(lights, d, bsdf_pdf, specular)``: the environment lights along a ray that
  left the scene, MIS-weighted against their sampling unless it came from the camera or a specular
  bounce.

Emission at a surface a ray hits is its material's ``emission`` (``wrt.kernels.materials``).
"""

import functools
from typing import NamedTuple

import warp as wp

from .emitters import (
    emitter_pdf,
    environment_map_pdf,
    environment_map_radiance,
    make_emitting_index,
    make_emitting_pdf,
    make_sample_emitting,
    sample_emitter,
    sample_emitter_or_map,
)
from .lights import EMITTING, ENVIRONMENT, ENVIRONMENT_MAP, SPOT, LightData, light_incident
from .materials import MaterialData
from .media import max_component
from .sample_warps import power_heuristic
from .sampling import Sampler, sample_1d, sample_2d
from .traverse import GeometryData

SHADOW_MARGIN = wp.constant(1.0e-4)  # shadow rays toward a light's surface stop this fraction short of it


@wp.struct
class LightSample:
    wi: wp.vec3  # unit direction toward the light
    radiance: wp.vec3  # W/(m^2 sr) arriving along wi; a delta light's: the irradiance (W/m^2) it delivers
    pdf: float  # solid-angle density of wi; 1 for a delta light; 0: no light from it
    t_max: float  # how far the shadow ray goes: short of the light's surface, inf toward the environment


class Lighting(NamedTuple):
    """The light interface's ``@wp.func``s for one scene's features (see the module's docstring)."""

    count: wp.Function
    is_delta: wp.Function
    sample_li: wp.Function
    pdf_li: wp.Function
    environment_radiance: wp.Function


@functools.cache
def make_lighting(environment_map: bool, emissive: bool, emissive_shapes: bool, smooth: bool) -> Lighting:
    """The interface, with environment maps and emissive primitives (of polygons and spheres too:
    ``emissive_shapes``; smooth-shaded triangles: ``smooth``) compiled in only where a scene has them."""
    sample_light = sample_emitter_or_map if environment_map else sample_emitter
    sample_emitting = make_sample_emitting(smooth, emissive_shapes)
    emitting_index = make_emitting_index(emissive_shapes)
    emitting_pdf = make_emitting_pdf(emissive_shapes)

    @wp.func
    def count(lights: LightData) -> wp.int32:
        n = lights.type.shape[0]
        if wp.static(emissive):
            if lights.emit_cdf.shape[0] > 1:  # not the placeholder of a scene without them
                n += 1
        return n

    @wp.func
    def is_delta(lights: LightData, i: wp.int32) -> bool:
        return i < lights.type.shape[0] and lights.type[i] <= SPOT

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
        ls = LightSample()
        light_type = EMITTING
        if i < lights.type.shape[0]:
            light_type = lights.type[i]
        if light_type <= SPOT:
            wi, dist, irradiance = light_incident(lights, i, p)
            ls.wi = wi
            ls.radiance = irradiance
            ls.pdf = 1.0
            ls.t_max = dist
            return ls
        u = sample_2d(sampler, pixel, sample, dim)
        wi = wp.vec3(0.0)
        dist = float(0.0)
        radiance = wp.vec3(0.0)
        pdf = float(0.0)
        if light_type == EMITTING:
            if wp.static(emissive):
                uc = sample_1d(sampler, pixel, sample, dim + 2)
                wi, dist, radiance, pdf = wp.static(sample_emitting)(
                    geometry, materials, lights, p, time, uc, u[0], u[1]
                )
        else:
            wi, dist, radiance, pdf = wp.static(sample_light)(lights, i, p, u[0], u[1])
        ls.wi = wi
        ls.radiance = radiance
        ls.pdf = pdf
        ls.t_max = dist
        if light_type != ENVIRONMENT:
            ls.t_max = dist * (1.0 - SHADOW_MARGIN)
        return ls

    @wp.func
    def pdf_li(
        geometry: GeometryData,
        lights: LightData,
        shape: wp.int32,
        prim: wp.int32,
        inst: wp.int32,
        p: wp.vec3,
        wi: wp.vec3,
        dist: float,
    ) -> float:
        pdf = float(0.0)
        if shape >= geometry.num_shapes:  # the surface of light shape - num_shapes (wrt.geometry's numbering)
            pdf = emitter_pdf(lights, shape - geometry.num_shapes, p, wi, dist)
        if wp.static(emissive):
            if inst < 0:
                e = wp.static(emitting_index)(lights, prim)
                if e >= 0:
                    pdf = wp.static(emitting_pdf)(geometry, lights, e, p, wi, dist)
        return pdf

    @wp.func
    def environment_radiance(lights: LightData, d: wp.vec3, bsdf_pdf: float, specular: bool) -> wp.vec3:
        total = wp.vec3(0.0)
        for i in range(lights.type.shape[0]):
            radiance = wp.vec3(0.0)
            light_pdf = float(0.0)
            if lights.type[i] == ENVIRONMENT:
                radiance = lights.power[i]
                light_pdf = 1.0 / (4.0 * wp.pi)
            if wp.static(environment_map):
                if lights.type[i] == ENVIRONMENT_MAP:
                    radiance = environment_map_radiance(lights, i, d)
                    light_pdf = environment_map_pdf(lights, d)
            if max_component(radiance) > 0.0:
                mis = float(1.0)
                if not specular:
                    mis = power_heuristic(bsdf_pdf, light_pdf)
                total += radiance * mis
        return total

    return Lighting(count, is_delta, sample_li, pdf_li, environment_radiance)
