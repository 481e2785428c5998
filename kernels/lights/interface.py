"""What a light family is: the description the registry (``wrt.kernels.lights``) derives the light
types, the ``[[light]]`` rows and the light interface from.

A family (one module of this package, as a pbrt-v4 ``Light`` or a Mitsuba 3 emitter plugin)
declares one ``Family``: its codes in ``LightData.type``, the ``[[light]]`` types it reads (its
host rows: ``row``), whether it is a delta light, the ``Features`` flag that compiles it in, and a
factory ``make(options)`` of its device functions (``Functions``):

- ``owns(light_type)``: the code ``light_type`` is one of the family's;
- ``sample_li(geometry, materials, lights, i, p, time, sampler, pixel, sample, dim)``: light from
  light ``i`` arriving at ``p``, a ``LightSample`` (``wrt.kernels.lights.data``); a family draws
  its 2D sample at dimension ``dim`` and may use ``dim + 2``;
- ``pdf_li(geometry, lights, shape, prim, inst, p, wi, dist)``: the solid-angle density with which
  ``sample_li`` would have drawn ``wi`` from ``p`` toward the surface that a ray along ``wi`` hit at
  ``dist`` (shape ``shape``, primitive ``prim``, instance ``inst``), 0 for a surface not the
  family's; None for a family without surfaces;
- ``le(lights, i, d)``: ``(radiance, pdf)`` of light ``i`` seen along a ray ``d`` that left the
  scene, with the density ``sample_li`` draws ``d`` with; None for a family that is not infinitely far;
- ``sample_le(geometry, materials, lights, i, center, radius, time, u_pos, u_dir, uc)``: a ray
  leaving light ``i`` (the light tracer's), an ``EmissionSample`` (``wrt.kernels.lights.data``):
  a point by the 2D sample ``u_pos`` (and ``uc`` where the family chooses among parts), a
  direction by ``u_dir``; lights at infinity send it from a disk of radius ``radius`` outside the
  scene's bounding sphere (``center``, ``radius``).

A surface light's radiance where a ray hits it is its surface's ``emission``
(``wrt.kernels.materials``: the ``emitter`` material of a light's surface, an emissive
primitive's own material), as in pbrt-v4 where an area light's ``L`` is the one the surface hit
asks.
"""

from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import warp as wp

from ..materials import MaterialData
from ..sampling import Sampler, sample_2d
from ..traverse import GeometryData
from .data import EmissionSample, LightData, LightSample, surface_sample


class Options(NamedTuple):
    """How a scene's features shape the families' code (``wrt.kernels.features.Features``)."""

    environment_map: bool = True  # an environment light with a map
    emissive_shapes: bool = True  # emissive polygons and spheres (else emissive triangles only)
    smooth: bool = True  # smooth-shaded triangles (their emitting side is the shading normal's)
    textures: bool = True  # textured materials (an emissive primitive's emission may be a texture)


class Functions(NamedTuple):
    """A family's device functions for one scene's options (see the module's docstring)."""

    owns: wp.Function
    sample_li: wp.Function
    sample_le: wp.Function
    pdf_li: wp.Function | None = None
    le: wp.Function | None = None


@dataclass(frozen=True)
class Family:
    """A light family: the plugin a module of this package declares.

    - ``codes``: its values of ``LightData.type``; ``make(options)``: its device functions.
    - ``light_types``: the ``[[light]]`` ``type`` values it reads; ``row(light)``: the
      ``LightData`` columns of such a host light (``wrt.scene``), its code under ``"type"``. A
      family without them (the pool of emissive primitives) is no row of the table.
    - ``delta``: a light without a surface or density (point, directional, spot): its sample is
      exact, with density 1, and no BSDF sample finds it (no MIS).
    - ``feature``: the ``Features`` flag that compiles it in where a scene has one (None: always).
    """

    name: str
    codes: tuple[int, ...]
    make: Callable[[Options], Functions]
    light_types: tuple[str, ...] = ()
    row: Callable[[object], dict] | None = None
    delta: bool = False
    feature: str | None = None


def surface_light(code: int, sample_light: wp.Function, light_pdf: wp.Function, emit_light: wp.Function) -> Functions:
    """The functions of a family of one code whose lights have a surface of their own (surface
    ``num_shapes + k`` of the geometry for row ``k``, ``wrt.geometry``'s numbering), from its
    ``sample_light(lights, i, p, u1, u2) -> (wi, distance, radiance, pdf)``, ``light_pdf(lights,
    i, p, wi, dist)``, the density of a direction ``wi`` that meets light ``i`` at ``dist``, and
    ``emit_light(lights, i, u_pos, u_dir) -> EmissionSample``, a ray leaving it."""

    @wp.func
    def owns(light_type: wp.int32) -> bool:
        return light_type == wp.static(code)

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
        wi, dist, radiance, density = sample_light(lights, i, p, u[0], u[1])
        return surface_sample(wi, dist, radiance, density)

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
        k = shape - geometry.num_shapes
        if k >= 0:
            if lights.type[k] == wp.static(code):
                return light_pdf(lights, k, p, wi, dist)
        return 0.0

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
        return emit_light(lights, i, u_pos, u_dir)

    return Functions(owns, sample_li, sample_le, pdf_li)
