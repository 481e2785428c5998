"""What a material family is: its lobe flags, the results its device functions return, and the
description the registry (``wrt.kernels.materials``) derives everything else from.

A family (one module of this package, as a Mitsuba 3 BSDF plugin or a pbrt-v4 ``BxDF``) declares
one ``Family``: its material types (``MaterialType``: the TOML name, the code in
``MaterialData.type``, the ``[[material]]`` keys it reads, its lobes), a factory ``make`` of its
device functions, and what the host needs to know of it (the ``Features`` flag that compiles it
in, the Mitsuba plugins converted to it, whether it bounds a medium, its base colour, what it
bakes into its own table). ``make(at)`` takes the parameter lookups of a scene (``Parameters``,
``wrt.kernels.materials.data``) and returns ``Functions``:

- ``owns(material_type)``: the code ``material_type`` (``MaterialData.type``) is one of the family's;
- ``eval(materials, m, n, wo, wi, eta, ctx, front, tangent)``: f (1/sr) of its non-specular lobes;
- ``pdf(materials, m, n, wo, wi, eta, ctx, front, tangent)``: the solid-angle density of ``sample``'s
  non-specular lobes;
- ``sample(materials, m, n, wo, eta, uc, u, ctx, front, tangent)``: one ``BSDFSample``;
- ``specular_lobes(materials, m, n, wo, eta, ctx)``: its delta lobes at once (``SpecularLobes``);

each None where the family has no such lobes (the dispatch then answers 0, or no lobes). The
conventions (world space, ``n`` on ``wo``'s side, ``eta = n1 / n2``) are the package's.
"""

from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import warp as wp

from ..optics import reflect

BSDF_REFLECTION = wp.constant(1)
BSDF_TRANSMISSION = wp.constant(2)
BSDF_DIFFUSE = wp.constant(4)
BSDF_GLOSSY = wp.constant(8)
BSDF_SPECULAR = wp.constant(16)
BSDF_TOTAL_INTERNAL = wp.constant(32)  # a sampled lobe only: specular reflection because refraction is impossible
BSDF_THIN = wp.constant(64)  # transmission goes straight on through a surface that bounds no medium (thin dielectric)
BSDF_ANISOTROPIC = wp.constant(128)  # MaterialData.flags only: its lobes need the hit's tangent (Mitsuba's Anisotropic)
BSDF_MEDIUM = wp.constant(
    256
)  # MaterialData.flags only: it bounds a medium (Family.medium): the media stack changes across it
NULL_LOBE = wp.constant(BSDF_TRANSMISSION | BSDF_SPECULAR | BSDF_THIN)  # a mask's: straight on, weight 1

MIN_ALPHA = 1e-4  # the least GGX alpha a roughness texture gives (0 would be a mirror: another lobe)


@wp.struct
class BSDFSample:
    wi: wp.vec3  # unit direction sampled, away from the surface
    weight: wp.vec3  # f |cos theta_i| / pdf
    pdf: float  # solid-angle density (non-specular lobes), or the discrete probability of a delta lobe
    flags: wp.int32  # the lobe chosen: BSDF_REFLECTION or BSDF_TRANSMISSION, plus its kind


@wp.struct
class SpecularLobes:
    wr: wp.vec3  # mirror direction
    reflectance: wp.vec3  # weight of the reflected ray
    wt: wp.vec3  # refracted direction (valid when ``refracts``)
    transmittance: wp.vec3  # weight of the refracted ray (0 without transmission)
    refracts: bool  # the transmitted ray exists
    total_internal: bool  # a dielectric past the critical angle: all is reflected


@wp.func
def no_lobes(n: wp.vec3, wo: wp.vec3) -> SpecularLobes:
    """No delta lobe: the mirror direction and the straight one, both of weight 0."""
    lobes = SpecularLobes()
    lobes.wr = reflect(-wo, n)
    lobes.wt = -wo
    lobes.reflectance = wp.vec3(0.0)
    lobes.transmittance = wp.vec3(0.0)
    lobes.refracts = False
    lobes.total_internal = False
    return lobes


@wp.func
def lost_sample() -> BSDFSample:
    """A sample that carries nothing (weight and pdf 0, no lobe); its direction is unset."""
    s = BSDFSample()
    s.weight = wp.vec3(0.0)
    s.pdf = 0.0
    s.flags = 0
    return s


class Functions(NamedTuple):
    """A family's device functions for one scene's parameter lookups (see the module's docstring)."""

    owns: wp.Function
    eval: wp.Function | None = None
    pdf: wp.Function | None = None
    sample: wp.Function | None = None
    specular_lobes: wp.Function | None = None


@dataclass(frozen=True)
class MaterialType:
    """One ``[[material]]`` type: ``name`` (its ``type`` value), ``code`` (``MaterialData.type``),
    ``keys`` (the parameters it reads besides name, type and emission, ``wrt.scene.Material``'s
    fields) and ``lobes`` (its ``BSDF_*`` flags)."""

    name: str
    code: int
    keys: tuple[str, ...]
    lobes: int


@dataclass(frozen=True)
class Family:
    """A material family: the plugin a module of this package declares.

    - ``types``: its material types; ``make``: its device functions (None: it scatters nothing);
      ``wraps``: ``make(at, bsdf)`` also takes the other families' dispatch (``BSDF``): a material
      made of another (a mask over its inner material).
    - ``feature``: the ``wrt.kernels.features.Features`` flag that compiles it in where a scene has
      one (None: always compiled in). ``whitted``: the Whitted integrator can render it (its lobes
      are deterministic).
    - ``medium``: it bounds a medium (a dielectric: nested media, absorption).
    - ``lobes(material)``: its flags for a host material (default: its type's ``lobes``);
      ``specular(material)``: it sends reflected or refracted rays (default: a delta lobe).
    - ``mitsuba``: the Mitsuba 3 plugins converted to it (``wrt.mitsuba.bsdfs``).
    - ``base_color``: the parameter the raycast integrator shows, or a function of the material.
    - ``relative_ior``: its ``ior`` is over the scene's ``exterior_ior`` (it sits in that medium).
    - ``data`` and ``bake``: its own table in ``MaterialData`` (a ``wp.struct``, the field named as
      the family) and ``bake(materials, exterior_ior)``, its columns (numpy, one row per material)
      computed on the host once per scene.
    """

    name: str
    types: tuple[MaterialType, ...]
    make: Callable | None = None
    wraps: bool = False
    feature: str | None = None
    whitted: bool = True
    medium: bool = False
    lobes: Callable | None = None
    specular: Callable | None = None
    mitsuba: tuple[str, ...] = ()
    base_color: str | Callable = "albedo"
    relative_ior: bool = False
    data: type | None = None
    bake: Callable | None = None

    def lobe_flags(self, material) -> int:
        """The ``BSDF_*`` flags of host material ``material`` (a ``wrt.scene.Material`` of this family)."""
        if self.lobes is not None:
            return self.lobes(material)
        return next(t.lobes for t in self.types if t.name == material.type)

    def sends_specular_rays(self, material) -> bool:
        """``material`` needs reflected or refracted rays (``Features.specular``)."""
        if self.specular is not None:
            return self.specular(material)
        return (self.lobe_flags(material) & BSDF_SPECULAR) != 0
