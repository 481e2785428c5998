"""Lights on the device: the registry of light families and the one light interface integrators
use, so that ``is_delta`` is the only question an integrator asks of a light.

Each module of this package is one family, a plugin (``interface.Family``): its codes, its device
functions and its host rows. The registry (``FAMILIES``) derives from them the ``[[light]]`` types
(``LIGHT_TYPES``, the loader's choices), the host rows of the lights' table (``light_row``,
``wrt.bake``), which families a scene compiles in (``families_for``) and the interface
(``make_lighting``). A new light family is one new module here, listed in ``FAMILIES``, with its
tests and docs (its host dataclass in ``wrt.scene``, its keys read in ``wrt.loader``).

Families: ``delta`` (``point``, ``directional``, ``spot``, ``projector``), ``area`` (a parallelogram),
``sphere``, ``environment`` (constant or a map) and ``emitting`` (the emissive primitives of the
scene's shapes, ``wrt.emitting``: one more light, after the rows).

Words: a *light* is what the interface samples, ``i`` in ``[0, count)``: the scene's lights in file
order (``LightData`` rows), then, where the scene has emissive primitives, their pool as light
``lights.type.shape[0]``. An *emitter* is a surface that emits, which a ray can hit: the surface of
an area or sphere light (its material the ``emitter`` one) or an emissive primitive.

- ``is_delta(lights, i)``: a point, directional or spot light: no surface to hit, no density, so
  no MIS;
- ``sample_li(geometry, materials, lights, i, p, time, sampler, pixel, sample, dim)``: light from
  light ``i`` at ``p`` (a ``LightSample``); a delta light's exactly (density 1), others with the
  2D sample at ``dim`` and the pool's choice of a primitive at ``dim + 2``;
- ``pdf_li(geometry, lights, shape, prim, inst, p, wi, dist)``: the solid-angle density with which
  ``sample_li`` would have drawn ``wi`` from ``p`` toward the surface a ray along ``wi`` hit at
  ``dist`` (a light's surface, or an emissive primitive outside instances); 0 for a surface it
  does not sample, so the MIS weight of what a BSDF sample found there is 1;
- ``environment_radiance(lights, d, bsdf_pdf, specular)``: the lights infinitely far along a ray
  that left the scene (the families' ``le``), MIS-weighted against their sampling unless it came
  from the camera or a specular bounce;
- ``sample_le(geometry, materials, lights, i, center, radius, time, u_pos, u_dir, uc)``: a ray
  leaving light ``i`` (an ``EmissionSample``), for the light tracer: lights at infinity send it
  from outside the scene's bounding sphere (``center``, ``radius``).

Emission at a surface a ray hits is its material's ``emission`` (``wrt.kernels.materials``).

References
----------
M. Pharr, W. Jakob, G. Humphreys, pbrt-v4, sec. 12.1 (the light interface: ``SampleLi``,
``PDF_Li``, ``L``, ``Le``, ``LightType::DeltaPosition``).
"""

import functools
from typing import NamedTuple

import warp as wp

from ..materials import MaterialData
from ..media import max_component
from ..sample_warps import power_heuristic
from ..sampling import Sampler
from ..traverse import GeometryData
from . import area, delta, emitting, environment, sphere
from .area import AREA
from .data import SHADOW_MARGIN, EmissionSample, LightData, LightSample, emission_ray
from .delta import DIRECTIONAL, POINT, PROJECTOR, SPOT, light_incident
from .emitting import EMITTING
from .environment import ENVIRONMENT, ENVIRONMENT_MAP
from .interface import Family, Options
from .sphere import SPHERE_LIGHT

FAMILIES: tuple[Family, ...] = (delta.FAMILY, area.FAMILY, sphere.FAMILY, environment.FAMILY, emitting.FAMILY)
"""Every light family, in the order the dispatch tests them."""

FAMILY_OF: dict[str, Family] = {name: family for family in FAMILIES for name in family.light_types}
"""The family of each ``[[light]]`` type."""

LIGHT_TYPES: tuple[str, ...] = tuple(FAMILY_OF)
"""The ``[[light]]`` ``type`` values, in the order of ``FAMILIES``."""

ALL_FAMILIES: tuple[str, ...] = tuple(family.name for family in FAMILIES)

_DELTA_CODES = [code for family in FAMILIES if family.delta for code in family.codes]
LAST_DELTA = wp.constant(max(_DELTA_CODES))  # delta lights have the lowest codes: ``is_delta`` is one compare
assert all(code > LAST_DELTA for family in FAMILIES if not family.delta for code in family.codes)

__all__ = [
    "ALL_FAMILIES",
    "AREA",
    "DIRECTIONAL",
    "EMITTING",
    "EmissionSample",
    "ENVIRONMENT",
    "ENVIRONMENT_MAP",
    "FAMILIES",
    "FAMILY_OF",
    "LAST_DELTA",
    "LIGHT_TYPES",
    "POINT",
    "PROJECTOR",
    "SHADOW_MARGIN",
    "SPHERE_LIGHT",
    "SPOT",
    "LightData",
    "LightSample",
    "Lighting",
    "Options",
    "families_for",
    "light_incident",
    "light_row",
    "lighting_for",
    "make_lighting",
]

_ROW = {
    "position": (0.0, 0.0, 0.0),
    "direction": (0.0, 0.0, 1.0),
    "edge_u": (0.0, 0.0, 0.0),
    "edge_v": (0.0, 0.0, 0.0),
    "radius": 0.0,
    "cutoff": 180.0,
    "beam": 180.0,
    "frame": ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
    "uv_scale": (0.0, 0.0),
    "texture": None,
}


def light_row(light) -> dict:
    """The ``LightData`` columns of host light ``light`` (a ``wrt.scene`` light): its family's row
    over the defaults of the columns it does not use (angles in degrees, as in the scene file;
    ``texture`` the ``wrt.textures`` texture object, or None, which ``wrt.bake`` numbers)."""
    return {**_ROW, **FAMILY_OF[light.type].row(light)}


def families_for(features) -> tuple[str, ...]:
    """The families compiled into the kernels of ``features`` (``wrt.kernels.features.Features``):
    those without a flag, and those whose flag is set."""
    return tuple(family.name for family in FAMILIES if family.feature is None or getattr(features, family.feature))


class Lighting(NamedTuple):
    """The light interface's ``@wp.func``s for one scene's features (see the module's docstring)."""

    count: wp.Function
    is_delta: wp.Function
    sample_li: wp.Function
    pdf_li: wp.Function
    environment_radiance: wp.Function
    sample_le: wp.Function


def lighting_for(features) -> Lighting:
    """The light interface of a scene of ``features``."""
    options = Options(features.environment_map, features.emissive_shapes, features.smooth, features.textures)
    return make_lighting(families_for(features), options)


@functools.cache
def make_lighting(families: tuple[str, ...] = ALL_FAMILIES, options: Options = Options()) -> Lighting:
    """The interface over ``families`` (names of ``FAMILIES``; ``families_for``) shaped by
    ``options``; a family left out is not in the generated code."""
    functions = [family.make(options) for family in FAMILIES if family.name in families]
    sample_case = _sample_cases([(f.owns, f.sample_li) for f in functions])
    pdf_sum = _pdf_sum([f.pdf_li for f in functions if f.pdf_li is not None])
    le_case = _le_cases([(f.owns, f.le) for f in functions if f.le is not None])
    emission_case = _emission_cases([(f.owns, f.sample_le) for f in functions])
    pool = "emitting" in families

    @wp.func
    def count(lights: LightData) -> wp.int32:
        n = lights.type.shape[0]
        if wp.static(pool):
            if lights.emit_cdf.shape[0] > 1:  # not the placeholder of a scene without them
                n += 1
        return n

    @wp.func
    def is_delta(lights: LightData, i: wp.int32) -> bool:
        return i < lights.type.shape[0] and lights.type[i] <= LAST_DELTA

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
        light_type = EMITTING
        if i < lights.type.shape[0]:
            light_type = lights.type[i]
        return sample_case(light_type, geometry, materials, lights, i, p, time, sampler, pixel, sample, dim)

    @wp.func
    def environment_radiance(lights: LightData, d: wp.vec3, bsdf_pdf: float, specular: bool) -> wp.vec3:
        total = wp.vec3(0.0)
        for i in range(lights.type.shape[0]):
            radiance, light_pdf = le_case(lights.type[i], lights, i, d)
            if max_component(radiance) > 0.0:
                mis = float(1.0)
                if not specular:
                    mis = power_heuristic(bsdf_pdf, light_pdf)
                total += radiance * mis
        return total

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
        light_type = EMITTING
        if i < lights.type.shape[0]:
            light_type = lights.type[i]
        return emission_case(light_type, geometry, materials, lights, i, center, radius, time, u_pos, u_dir, uc)

    return Lighting(count, is_delta, sample_li, pdf_sum, environment_radiance, sample_le)


# The dispatch: chains of cases, one per family, each calling its family's function and the next
# case as closure values, which Warp hashes with the module (``wrt.kernels.materials._dispatch``
# says why not an unrolled loop over ``wp.static`` indices).


def _sample_cases(cases: list) -> wp.Function:
    """``sample_li`` of the first family of ``cases`` (``(owns, sample_li)`` pairs) that owns
    ``light_type``, else no light."""
    if not cases:

        @wp.func
        def no_sample(
            light_type: wp.int32,
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
            ls.wi = wp.vec3(0.0)
            ls.radiance = wp.vec3(0.0)
            ls.pdf = 0.0
            ls.t_max = 0.0
            return ls

        return no_sample
    owns, family_sample = cases[0]
    rest = _sample_cases(cases[1:])

    @wp.func
    def sample_case(
        light_type: wp.int32,
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
        if owns(light_type):
            return family_sample(geometry, materials, lights, i, p, time, sampler, pixel, sample, dim)
        return rest(light_type, geometry, materials, lights, i, p, time, sampler, pixel, sample, dim)

    return sample_case


def _emission_cases(cases: list) -> wp.Function:
    """``sample_le`` of the first family of ``cases`` (``(owns, sample_le)`` pairs) that owns
    ``light_type``, else no ray."""
    if not cases:

        @wp.func
        def no_emission(
            light_type: wp.int32,
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
            return emission_ray(center, wp.vec3(0.0, 0.0, 1.0), wp.vec3(0.0))

        return no_emission
    owns, family_emission = cases[0]
    rest = _emission_cases(cases[1:])

    @wp.func
    def emission_case(
        light_type: wp.int32,
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
        if owns(light_type):
            return family_emission(geometry, materials, lights, i, center, radius, time, u_pos, u_dir, uc)
        return rest(light_type, geometry, materials, lights, i, center, radius, time, u_pos, u_dir, uc)

    return emission_case


def _pdf_sum(pdfs: list) -> wp.Function:
    """The sum of the families' ``pdf_li`` (a surface is one family's at most: the others answer 0)."""
    if not pdfs:

        @wp.func
        def no_pdf(
            geometry: GeometryData,
            lights: LightData,
            shape: wp.int32,
            prim: wp.int32,
            inst: wp.int32,
            p: wp.vec3,
            wi: wp.vec3,
            dist: float,
        ) -> float:
            return 0.0

        return no_pdf
    family_pdf = pdfs[0]
    rest = _pdf_sum(pdfs[1:])

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
        return family_pdf(geometry, lights, shape, prim, inst, p, wi, dist) + rest(
            geometry, lights, shape, prim, inst, p, wi, dist
        )

    return pdf_li


def _le_cases(cases: list) -> wp.Function:
    """``le`` of the first family of ``cases`` (``(owns, le)`` pairs) that owns ``light_type``,
    else nothing: ``(radiance, pdf)``."""
    if not cases:

        @wp.func
        def no_le(light_type: wp.int32, lights: LightData, i: wp.int32, d: wp.vec3):
            return wp.vec3(0.0), 0.0

        return no_le
    owns, family_le = cases[0]
    rest = _le_cases(cases[1:])

    @wp.func
    def le_case(light_type: wp.int32, lights: LightData, i: wp.int32, d: wp.vec3):
        if owns(light_type):
            radiance, pdf = family_le(lights, i, d)
            return radiance, pdf
        radiance, pdf = rest(light_type, lights, i, d)
        return radiance, pdf

    return le_case
