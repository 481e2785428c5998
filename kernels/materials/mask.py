"""``MASK``: Mitsuba 3's ``mask``. With probability ``opacity`` (a constant, or a texture's
``texture_float``) the material ``inner`` (not itself a mask, nor a dielectric that bounds a
medium), else a null lobe: the ray goes straight on, ``wi = -wo`` with weight 1, as through a thin
dielectric's transmission, and the surface bounds no medium. The null lobe lets the ray through on
both sides; the inner material scatters nothing on the back of a one-sided one. Compiled in only
where a scene has a mask (``Features.mask``); the Whitted integrator cannot render one (its
choice is random), ``wrt.loader`` says so.
"""

import warp as wp

from ..textures import OPACITY, TextureEvalContext, material_float
from .data import MaterialData, Parameters, nested_scatters
from .interface import NULL_LOBE, BSDFSample, Family, Functions, MaterialType

MASK = wp.constant(11)


def mask_flags(inner_flags: int, opaque: bool) -> int:
    """The lobes of a mask over a material of lobes ``inner_flags``: those, and its null lobe
    unless it is ``opaque`` (a constant opacity of 1)."""
    return inner_flags if opaque else inner_flags | NULL_LOBE


def make(at: Parameters, bsdf) -> Functions:
    """The mask's functions around ``bsdf``, the dispatch of every other family: they answer for
    every material, a mask or not (the dispatch of a scene with masks is this family's)."""

    @wp.func
    def owns(material_type: wp.int32) -> bool:
        return material_type == MASK

    @wp.func
    def opacity_at(materials: MaterialData, m: wp.int32, ctx: TextureEvalContext) -> float:
        """The opacity of mask ``m`` at ``ctx``: its texture's ``texture_float``, or its ``opacity``."""
        if wp.static(at.textures):
            return material_float(materials.textures, m, OPACITY, ctx, materials.opacity[m])
        return materials.opacity[m]

    def masked(nested, value_type):
        """``nested`` (the dispatch's ``eval`` or ``pdf``, of type ``value_type``), and a mask's:
        ``opacity`` times its inner material's value (the null lobe is a delta)."""

        @wp.func
        def masked_value(
            materials: MaterialData,
            m: wp.int32,
            n: wp.vec3,
            wo: wp.vec3,
            wi: wp.vec3,
            eta: float = 1.0,
            ctx: TextureEvalContext = TextureEvalContext(),
            front: bool = True,
            tangent: wp.vec3 = wp.vec3(0.0, 0.0, 0.0),
        ) -> value_type:
            if materials.type[m] != MASK:
                return nested(materials, m, n, wo, wi, eta, ctx, front, tangent)
            inner = materials.inner[m]
            if not nested_scatters(materials, inner, n, wi, front):
                return value_type(0.0)
            return opacity_at(materials, m, ctx) * nested(materials, inner, n, wo, wi, eta, ctx, front, tangent)

        return masked_value

    masked_eval = masked(bsdf.eval, wp.vec3)  # bsdf_eval, and a mask's
    masked_pdf = masked(bsdf.pdf, float)  # bsdf_pdf, and a mask's

    @wp.func
    def masked_sample(
        materials: MaterialData,
        m: wp.int32,
        n: wp.vec3,
        wo: wp.vec3,
        eta: float,
        uc: float,
        u: wp.vec2,
        ctx: TextureEvalContext = TextureEvalContext(),
        front: bool = True,
        tangent: wp.vec3 = wp.vec3(0.0, 0.0, 0.0),
    ) -> BSDFSample:
        """``bsdf_sample``, and a mask's (Mitsuba 3's): where ``uc < opacity`` its inner material's
        sample drawn with ``uc / opacity``, its pdf times ``opacity`` and its weight unchanged (lost
        on the back of a one-sided inner material), else the null lobe: ``wi = -wo``, weight 1,
        probability ``1 - opacity``."""
        if materials.type[m] != MASK:
            return bsdf.sample(materials, m, n, wo, eta, uc, u, ctx, front, tangent)
        opacity = opacity_at(materials, m, ctx)
        inner = materials.inner[m]
        if uc < opacity and (front or materials.two_sided[inner] != 0):
            nested = bsdf.sample(materials, inner, n, wo, eta, uc / opacity, u, ctx, front, tangent)
            nested.pdf = nested.pdf * opacity
            return nested
        s = BSDFSample()
        s.wi = -wo
        s.flags = NULL_LOBE
        s.weight = wp.vec3(1.0)
        s.pdf = 1.0 - opacity
        if uc < opacity:  # the inner material's, on the back of a one-sided one: lost
            s.weight = wp.vec3(0.0)
            s.pdf = 0.0
        return s

    return Functions(owns, masked_eval, masked_pdf, masked_sample, bsdf.specular_lobes)


FAMILY = Family(
    name="mask",
    types=(MaterialType("mask", MASK, ("opacity", "material"), 0),),
    make=make,
    wraps=True,
    feature="mask",
    whitted=False,
    specular=lambda material: False,  # its null lobe goes straight on: no reflected or refracted ray
    mitsuba=("mask",),
)
