"""``ROUGH_DIELECTRIC``: rough glass, a dielectric of ``ior``, ``sigma`` and ``priority`` whose
interface is microfacets of alpha ``roughness`` (GGX or Beckmann: ``distribution``), reflecting F and
refracting 1 - F at the microfacet normal (Walter et al. 2007: ``wrt.kernels.microfacet``'s
``dielectric_eval``); index-matched (``eta == 1``)
a straight pass, sampled as a delta lobe. Mitsuba 3's ``roughdielectric``. Compiled in only where a
scene has one (``Features.rough_dielectric``): untaken, its cases cost the path tracer about 15% of
its time on glossy_reflection (CPU).
"""

import warp as wp

from ..optics import fresnel_dielectric, refract
from ..sample_warps import shading_frame
from ..textures import TextureEvalContext
from .data import MaterialData, Parameters
from .interface import (
    BSDF_GLOSSY,
    BSDF_REFLECTION,
    BSDF_SPECULAR,
    BSDF_TRANSMISSION,
    BSDFSample,
    Family,
    Functions,
    MaterialType,
    lost_sample,
)

ROUGH_DIELECTRIC = wp.constant(8)


def make(at: Parameters) -> Functions:
    mf = at.microfacet

    @wp.func
    def rough_dielectric_sample(
        alpha: wp.vec2,
        distribution: wp.int32,
        n: wp.vec3,
        tangent: wp.vec3,
        wo: wp.vec3,
        eta: float,
        uc: float,
        u: wp.vec2,
    ) -> BSDFSample:
        """A visible microfacet normal ``h`` of a rough dielectric, then reflection about it with
        probability F (at ``wo.h``; weight ``G1(wi)``) or refraction through it (weight ``eta^2
        G1(wi)``), as Mitsuba 3's ``roughdielectric``; index-matched (``eta == 1``) a straight pass,
        a delta lobe of weight 1."""
        s = lost_sample()
        if eta == 1.0:
            s.wi = -wo
            s.weight = wp.vec3(1.0)
            s.pdf = 1.0
            s.flags = BSDF_TRANSMISSION | BSDF_SPECULAR
            return s
        to_world = shading_frame(n, tangent)
        wo_local = wp.transpose(to_world) * wo
        h = mf.sample_visible_normal(wo_local, alpha, distribution, u[0], u[1])
        cos_h = wp.dot(wo_local, h)
        wi_local = 2.0 * cos_h * h - wo_local
        ok = wi_local[2] > 0.0
        scale = float(1.0)
        s.flags = BSDF_REFLECTION | BSDF_GLOSSY
        if uc >= fresnel_dielectric(cos_h, eta):
            refracts, wi_local = refract(-wo_local, h, eta)
            ok = refracts and wi_local[2] < 0.0
            scale = eta * eta
            s.flags = BSDF_TRANSMISSION | BSDF_GLOSSY
        s.wi = to_world * wi_local
        if ok:
            s.pdf = mf.dielectric_pdf(wo_local, wi_local, alpha, distribution, eta)
            s.weight = wp.vec3(scale * mf.g1(wi_local, alpha, distribution))
        return s

    @wp.func
    def owns(material_type: wp.int32) -> bool:
        return material_type == ROUGH_DIELECTRIC

    @wp.func
    def eval(
        materials: MaterialData,
        m: wp.int32,
        n: wp.vec3,
        wo: wp.vec3,
        wi: wp.vec3,
        eta: float,
        ctx: TextureEvalContext,
        front: bool,
        tangent: wp.vec3,
    ) -> wp.vec3:
        to_local = wp.transpose(shading_frame(n, tangent))
        alpha = at.alpha(materials, m, ctx)
        distribution = at.distribution(materials, m)
        return wp.vec3(mf.dielectric_eval(to_local * wo, to_local * wi, alpha, distribution, eta))

    @wp.func
    def pdf(
        materials: MaterialData,
        m: wp.int32,
        n: wp.vec3,
        wo: wp.vec3,
        wi: wp.vec3,
        eta: float,
        ctx: TextureEvalContext,
        front: bool,
        tangent: wp.vec3,
    ) -> float:
        to_local = wp.transpose(shading_frame(n, tangent))
        alpha = at.alpha(materials, m, ctx)
        distribution = at.distribution(materials, m)
        return mf.dielectric_pdf(to_local * wo, to_local * wi, alpha, distribution, eta)

    @wp.func
    def sample(
        materials: MaterialData,
        m: wp.int32,
        n: wp.vec3,
        wo: wp.vec3,
        eta: float,
        uc: float,
        u: wp.vec2,
        ctx: TextureEvalContext,
        front: bool,
        tangent: wp.vec3,
    ) -> BSDFSample:
        alpha = at.alpha(materials, m, ctx)
        return rough_dielectric_sample(alpha, at.distribution(materials, m), n, tangent, wo, eta, uc, u)

    return Functions(owns, eval, pdf, sample)


FAMILY = Family(
    name="rough_dielectric",
    types=(
        MaterialType(
            "rough_dielectric",
            ROUGH_DIELECTRIC,
            ("ior", "roughness", "roughness_v", "distribution", "transmittance", "priority"),
            BSDF_REFLECTION | BSDF_TRANSMISSION | BSDF_GLOSSY,
        ),
    ),
    make=make,
    feature="rough_dielectric",
    medium=True,
    specular=lambda material: True,  # index-matched, a straight pass: a delta lobe
    mitsuba=("roughdielectric",),
    base_color="transmittance",
)
