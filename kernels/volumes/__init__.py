"""Participating media on the device: the registry of medium and phase function types, and the
functions the path integrator asks of a medium (Mitsuba 3's ``Medium`` and ``PhaseFunction``
interfaces, pbrt-v4's chapter 11).

Each module of this package is one plugin (``interface.MediumType``, ``interface.PhaseType``):
``homogeneous`` (constant coefficients), ``grid`` (``heterogeneous``: coefficients from volumes,
tracked against a majorant) and ``henyey_greenstein`` (``isotropic`` and ``hg``). The registry
(``MEDIUM_TYPES``, ``PHASE_TYPES``) gives the loader its types and keys; a new medium type is one
new module here, listed below, with its ``MediumData.kind`` and its case in ``free_flight`` and
``volume_transmittance``, its tests and docs.

Semantics are Mitsuba 3's ``volpath``: a ray is in one medium at a time (``-1``: vacuum), the
camera's to begin with, and changes medium where it crosses a surface whose shape bounds media:
into the shape's ``interior`` where it goes against the geometric normal, into its ``exterior``
where it goes along it (``boundary_medium``). Media do not nest: the medium beyond a surface is
the shape's, whatever the ray was in. The nested dielectrics and their Beer-Lambert absorption
(``wrt.kernels.media``) are a separate, scattering-free bookkeeping that still applies.

- ``boundary_medium(media, surface, outward, current)``: the medium beyond a surface;
- ``free_flight(media, medium, o, d, t_max, u, key)``: a ``FreeFlight`` sample along the segment
  ``o + t d``, ``0 < t < t_max`` (infinite for a ray that leaves the scene), from the sampler's
  number ``u`` and, where a medium needs more, the stream ``key`` (``tracking_key``), with the
  radiance an emissive medium emits along it;
- ``volume_transmittance(media, medium, o, d, distance, key)``: the transmittance along a shadow
  ray;
- ``phase_value(media, medium, wo, wi)``: the phase function (1/sr), also the density with which
  ``phase_sample(media, medium, wo, u)`` draws ``wi`` (so its sample weight is 1).
"""

import warp as wp

from ..sampling import hash_counters
from . import grid, henyey_greenstein, homogeneous
from .data import GRID, HOMOGENEOUS, UNSET, VACUUM, FreeFlight, MediumData
from .grid import grid_free_flight, grid_transmittance
from .henyey_greenstein import hg_sample, hg_value
from .homogeneous import homogeneous_free_flight, homogeneous_transmittance
from .interface import MediumType, PhaseType

MEDIUM_TYPES: dict[str, MediumType] = {t.name: t for t in (homogeneous.TYPE, grid.TYPE)}
"""Every ``[[medium]]`` type by name."""

PHASE_TYPES: dict[str, PhaseType] = {t.name: t for t in henyey_greenstein.TYPES}
"""Every phase function type by name."""

__all__ = [
    "GRID",
    "HOMOGENEOUS",
    "MEDIUM_TYPES",
    "PHASE_TYPES",
    "UNSET",
    "VACUUM",
    "FreeFlight",
    "MediumData",
    "MediumType",
    "PhaseType",
    "boundary_medium",
    "free_flight",
    "has_media",
    "phase_sample",
    "phase_value",
    "tracking_key",
    "volume_transmittance",
]


@wp.func
def has_media(media: MediumData) -> bool:
    """The scene has participating media: paths follow Mitsuba 3's ``volpath`` (shadow rays pass
    null surfaces; null events are not segments)."""
    return media.count > 0


@wp.func
def tracking_key(seed: wp.int32, pixel: wp.int32, sample: wp.int32, dim: wp.int32) -> wp.uint32:
    """The stream of random numbers a medium may draw from along one segment (``grid.step_uniform``):
    a pure function of the counters, as every sample is (``wrt.kernels.sampling``)."""
    return hash_counters(seed, pixel, sample, dim)


@wp.func
def boundary_medium(media: MediumData, surface: wp.int32, outward: bool, current: wp.int32) -> wp.int32:
    """The medium of a ray leaving ``surface`` along (``outward``) or against its geometric normal:
    its shape's exterior or interior medium (vacuum where only the other is named), or ``current``
    where the shape bounds no medium."""
    inside = media.shape_interior[surface]
    outside = media.shape_exterior[surface]
    if inside == UNSET and outside == UNSET:
        return current
    beyond = wp.where(outward, outside, inside)
    return wp.max(beyond, VACUUM)


@wp.func
def free_flight(
    media: MediumData, medium: wp.int32, o: wp.vec3, d: wp.vec3, t_max: float, u: float, key: wp.uint32
) -> FreeFlight:
    """A free-flight sample in ``medium`` along ``o + t d`` (unit ``d``), ``0 < t < t_max``."""
    if media.kind[medium] == GRID:
        return grid_free_flight(media, medium, o, d, t_max, u, key)
    return homogeneous_free_flight(media.sigma_t[medium], media.albedo[medium], media.emission[medium], t_max, u)


@wp.func
def volume_transmittance(
    media: MediumData, medium: wp.int32, o: wp.vec3, d: wp.vec3, distance: float, key: wp.uint32
) -> wp.vec3:
    """The fraction of light ``medium`` lets through along ``o + t d``, ``0 < t < distance``; 1 in
    vacuum."""
    if medium < 0:
        return wp.vec3(1.0)
    if media.kind[medium] == GRID:
        return grid_transmittance(media, medium, o, d, distance, key)
    return homogeneous_transmittance(media.sigma_t[medium], distance)


@wp.func
def phase_value(media: MediumData, medium: wp.int32, wo: wp.vec3, wi: wp.vec3) -> float:
    """The phase function of ``medium`` (1/sr) from ``wo`` (back along the arriving ray) to ``wi``."""
    return hg_value(wp.dot(wo, wi), media.g[medium])


@wp.func
def phase_sample(media: MediumData, medium: wp.int32, wo: wp.vec3, u: wp.vec2) -> wp.vec3:
    """A scattered direction drawn with density ``phase_value``."""
    return hg_sample(wo, media.g[medium], u)
