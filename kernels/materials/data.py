"""The materials' table on the device (``MaterialData``) and the lookups of its parameters at a
hit (``Parameters``: a texture's value where the parameter is textured, else the constant).

Columns are per material (indexed by ``m``) and shared by the families that read them; a family
with parameters of its own keeps them in a table of its own (``Family.data``), a field of
``MaterialData`` named as the family. Colours are linear RGB.
"""

import functools
from typing import NamedTuple

import warp as wp

from ..microfacet import GGX, Microfacet, microfacet
from ..textures import ROUGHNESS, ROUGHNESS_V, TextureData, TextureEvalContext, material_rgb, texture_float
from ..volumes import MediumData
from .blend import BlendData
from .interface import BSDF_TRANSMISSION, MIN_ALPHA
from .plastic import PlasticData
from .principled import PrincipledData


@wp.struct
class MaterialData:
    shape_material: wp.array(dtype=wp.int32)  # material index of each [[shape]]
    type: wp.array(dtype=wp.int32)  # MaterialType.code
    flags: wp.array(dtype=wp.int32)  # the lobes of each material (Family.lobe_flags)
    base_color: wp.array(dtype=wp.vec3)
    albedo: wp.array(dtype=wp.vec3)
    specular: wp.array(dtype=wp.vec3)
    exponent: wp.array(dtype=float)
    reflectance: wp.array(dtype=wp.vec3)  # mirror, glossy: the reflectance; conductor: the tint of its Fresnel term
    ior: wp.array(dtype=float)  # dielectrics: their ior; Family.relative_ior: their ior over the scene's exterior_ior
    sigma: wp.array(dtype=wp.vec3)  # absorption coefficient per unit length, -ln(transmittance)
    transmittance: wp.array(dtype=wp.vec3)  # thin dielectric: the tint of its straight transmission
    priority: wp.array(dtype=wp.int32)
    roughness: wp.array(
        dtype=float
    )  # microfacet alpha, along the tangent s where anisotropic (conductor: 0 for a smooth one)
    roughness_v: wp.array(dtype=float)  # microfacet alpha along the bitangent t (roughness where isotropic)
    distribution: wp.array(dtype=wp.int32)  # rough materials: wrt.kernels.microfacet.DISTRIBUTIONS' code
    eta: wp.array(dtype=wp.vec3)  # conductor: real part of the index of refraction, per channel
    k: wp.array(dtype=wp.vec3)  # conductor: imaginary part (extinction coefficient)
    emission: wp.array(dtype=wp.vec3)
    two_sided: wp.array(dtype=wp.int32)  # 1: both sides reflect; 0: the back side reflects nothing
    textures: TextureData  # the textures of textured parameters (wrt.kernels.textures)
    bump_scale: wp.array(dtype=float)  # bump-mapped: the height field's scale (Mitsuba's bumpmap scale)
    inner: wp.array(dtype=wp.int32)  # mask: the index of the material it masks (-1 for other types)
    opacity: wp.array(dtype=float)  # mask: the probability of its inner material (textured: slot OPACITY)
    plastic: PlasticData  # the plastics' own table (wrt.kernels.materials.plastic)
    blend: BlendData  # the blends' own table (wrt.kernels.materials.blend)
    principled: PrincipledData  # the principled materials' own table (wrt.kernels.materials.principled)
    media: MediumData  # the participating media and the surfaces that bound them (wrt.kernels.volumes)


@wp.func
def anisotropic_material(materials: MaterialData, m: wp.int32) -> bool:
    """Material ``m`` has two alphas (the host gives an isotropic one ``roughness_v`` equal to its
    ``roughness``, and its texture, if any, in both slots)."""
    if materials.roughness_v[m] != materials.roughness[m]:
        return True
    return materials.textures.slot[m, ROUGHNESS_V] != materials.textures.slot[m, ROUGHNESS]


@wp.func
def nested_scatters(materials: MaterialData, nested: wp.int32, n: wp.vec3, wi: wp.vec3, front: bool) -> bool:
    """The material ``nested`` of a mask or a blend may scatter toward ``wi`` at a hit on the
    ``front`` side or the back: not on the back of a one-sided one, nor across the surface unless it
    transmits (a light below a mask is not seen through its inner diffuse material)."""
    if not front and materials.two_sided[nested] == 0:
        return False
    return wp.dot(n, wi) > 0.0 or (materials.flags[nested] & BSDF_TRANSMISSION) != 0


class Parameters(NamedTuple):
    """The parameter lookups of a scene's materials at a hit, as ``@wp.func``s:
        ``rgb(materials, m, slot, ctx, constant)``, colour parameter ``slot`` (``wrt.kernels.textures``)
        of material ``m``; ``alpha(materials, m, ctx)``, its microfacet alpha; ``distribution(materials,
        m)``, its microfacet distribution's code; and ``microfacet``, the microfacet functions
        (``wrt.kernels.microfacet``: Beckmann compiled in only where some material has it, else every
        one is GGX and the column is not read). ``textures``: the scene has textures (without them
        every parameter is its constant and ``ctx`` is unused); ``anisotropic``: some material is
    (its BSDF then takes the hit's tangent frame, ``wrt.kernels.sample_warps.shading_frame``)."""

    rgb: wp.Function
    alpha: wp.Function
    distribution: wp.Function
    microfacet: Microfacet
    textures: bool
    anisotropic: bool


@functools.cache
def parameters(textures: bool, beckmann: bool = True, anisotropic: bool = True) -> Parameters:
    """The lookups, with texture reads compiled in only where ``textures``, Beckmann only where
    ``beckmann``, a second alpha only where ``anisotropic``."""

    @wp.func
    def rgb_at(
        materials: MaterialData, m: wp.int32, slot: wp.int32, ctx: TextureEvalContext, constant: wp.vec3
    ) -> wp.vec3:
        """Colour parameter ``slot`` of material ``m`` at ``ctx``: its texture's, or ``constant``."""
        if wp.static(textures):
            return material_rgb(materials.textures, m, slot, ctx, constant)
        return constant

    @wp.func
    def roughness_at(
        materials: MaterialData, m: wp.int32, slot: wp.int32, ctx: TextureEvalContext, constant: float
    ) -> float:
        """Roughness parameter ``slot`` (``ROUGHNESS``, ``ROUGHNESS_V``) of material ``m`` at ``ctx``:
        its texture's (at least ``MIN_ALPHA``), or ``constant``."""
        if wp.static(textures):
            t = materials.textures.slot[m, slot]
            if t >= 0:
                return wp.max(MIN_ALPHA, texture_float(materials.textures, t, ctx))
        return constant

    @wp.func
    def alpha_at(materials: MaterialData, m: wp.int32, ctx: TextureEvalContext) -> wp.vec2:
        """Microfacet alpha ``(a_u, a_v)`` of material ``m`` at ``ctx``: ``roughness`` and
        ``roughness_v``, each its texture's where textured (one lookup where both are the same)."""
        a_u = roughness_at(materials, m, ROUGHNESS, ctx, materials.roughness[m])
        if wp.static(anisotropic):
            if anisotropic_material(materials, m):
                return wp.vec2(a_u, roughness_at(materials, m, ROUGHNESS_V, ctx, materials.roughness_v[m]))
        return wp.vec2(a_u, a_u)

    @wp.func
    def distribution_of(materials: MaterialData, m: wp.int32) -> wp.int32:
        """The microfacet distribution of material ``m`` (GGX where no material is Beckmann)."""
        if wp.static(beckmann):
            return materials.distribution[m]
        return GGX

    return Parameters(rgb_at, alpha_at, distribution_of, microfacet(beckmann), textures, anisotropic)
