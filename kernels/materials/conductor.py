"""Metallic reflection, smooth and rough: ``MIRROR`` (perfect specular, ``reflectance``),
``GLOSSY`` (microfacets of alpha ``roughness``, GGX or Beckmann (``distribution``), with the constant
Fresnel factor ``reflectance``, ``wrt.kernels.microfacet``) and ``CONDUCTOR`` (the exact Fresnel
reflectance of the complex index of refraction ``eta + i k`` times the tint ``reflectance``: a mirror
where ``roughness`` is 0, else microfacets of alpha ``roughness`` with the Fresnel term at the
microfacet normal). Mitsuba 3's ``conductor``
and ``roughconductor``; pbrt-v4's ``ConductorBxDF``.
"""

import numpy as np
import warp as wp

from ..optics import fresnel_conductor
from ..sample_warps import shading_frame
from ..textures import REFLECTANCE, TextureEvalContext
from .data import MaterialData, Parameters
from .interface import (
    BSDF_GLOSSY,
    BSDF_REFLECTION,
    BSDF_SPECULAR,
    BSDFSample,
    Family,
    Functions,
    MaterialType,
    SpecularLobes,
    lost_sample,
    no_lobes,
)

MIRROR = wp.constant(2)
GLOSSY = wp.constant(4)
CONDUCTOR = wp.constant(6)


def lobes(material) -> int:
    """A conductor is glossy where it is rough, a mirror where it is smooth."""
    if material.type == "mirror" or (material.type == "conductor" and material.roughness == 0.0):
        return BSDF_REFLECTION | BSDF_SPECULAR
    return BSDF_REFLECTION | BSDF_GLOSSY


def normal_reflectance(eta, k) -> tuple[float, float, float]:
    """The Fresnel reflectance of a conductor at normal incidence, ``((eta - 1)^2 + k^2) /
    ((eta + 1)^2 + k^2)`` per channel (float64)."""
    eta, k = np.asarray(eta, dtype=np.float64), np.asarray(k, dtype=np.float64)
    return tuple(float(f) for f in ((eta - 1.0) ** 2 + k**2) / ((eta + 1.0) ** 2 + k**2))


def base_color(material) -> tuple:
    """What the raycast integrator shows: the reflectance (a conductor's at normal incidence)."""
    if material.type == "conductor":
        return tuple(np.multiply(normal_reflectance(material.eta, material.k), material.reflectance))
    return material.reflectance


def make(at: Parameters) -> Functions:
    mf = at.microfacet

    @wp.func
    def owns(material_type: wp.int32) -> bool:
        return material_type == MIRROR or material_type == GLOSSY or material_type == CONDUCTOR

    @wp.func
    def specular_reflectance(materials: MaterialData, m: wp.int32, reflectance: wp.vec3, cos_theta: float) -> wp.vec3:
        """The reflectance of a facet (the surface, or a microfacet) seen at incidence cosine
        ``cos_theta``: ``reflectance``, for a conductor times its Fresnel term."""
        if materials.type[m] == CONDUCTOR:
            return wp.cw_mul(reflectance, fresnel_conductor(cos_theta, materials.eta[m], materials.k[m]))
        return reflectance

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
        """Microfacet reflection of the facet reflectance at the half vector; 0 for a mirror or a smooth conductor."""
        if materials.type[m] == MIRROR or materials.roughness[m] == 0.0:
            return wp.vec3(0.0)
        alpha = at.alpha(materials, m, ctx)
        to_local = wp.transpose(shading_frame(n, tangent))
        cos_h = wp.abs(wp.dot(wo, wp.normalize(wo + wi)))
        reflectance = at.rgb(materials, m, REFLECTANCE, ctx, materials.reflectance[m])
        distribution = at.distribution(materials, m)
        return specular_reflectance(materials, m, reflectance, cos_h) * mf.eval(
            to_local * wo, to_local * wi, alpha, distribution
        )

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
        """Visible microfacet normals; 0 for a mirror or a smooth conductor."""
        if materials.type[m] == MIRROR or materials.roughness[m] == 0.0:
            return 0.0
        to_local = wp.transpose(shading_frame(n, tangent))
        return mf.pdf(to_local * wo, to_local * wi, at.alpha(materials, m, ctx), at.distribution(materials, m))

    @wp.func
    def specular_lobes(
        materials: MaterialData, m: wp.int32, n: wp.vec3, wo: wp.vec3, eta: float, ctx: TextureEvalContext
    ) -> SpecularLobes:
        """A mirror's reflection (``reflectance``), a conductor's (``reflectance`` times its Fresnel
        term); none for a glossy material."""
        lobes = no_lobes(n, wo)
        if materials.type[m] != GLOSSY:
            reflectance = at.rgb(materials, m, REFLECTANCE, ctx, materials.reflectance[m])
            lobes.reflectance = specular_reflectance(materials, m, reflectance, wp.dot(wo, n))
        return lobes

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
        """A mirror's or a smooth conductor's reflection; glossy and rough conductors by visible normals."""
        s = lost_sample()
        material_type = materials.type[m]
        if material_type == MIRROR or (material_type == CONDUCTOR and materials.roughness[m] == 0.0):
            lobes = specular_lobes(materials, m, n, wo, eta, ctx)
            s.wi = lobes.wr
            s.flags = BSDF_REFLECTION | BSDF_SPECULAR
            s.weight = lobes.reflectance
            s.pdf = 1.0
            return s
        to_world = shading_frame(n, tangent)
        to_local = wp.transpose(to_world)
        wo_local = to_local * wo
        alpha = at.alpha(materials, m, ctx)
        distribution = at.distribution(materials, m)
        h = mf.sample_visible_normal(wo_local, alpha, distribution, u[0], u[1])
        cos_h = wp.dot(wo_local, h)
        wi_local = 2.0 * cos_h * h - wo_local
        s.wi = to_world * wi_local
        s.flags = BSDF_REFLECTION | BSDF_GLOSSY
        if wi_local[2] > 0.0:
            reflectance = at.rgb(materials, m, REFLECTANCE, ctx, materials.reflectance[m])
            s.weight = specular_reflectance(materials, m, reflectance, cos_h) * mf.g1(wi_local, alpha, distribution)
            s.pdf = mf.pdf(wo_local, wi_local, alpha, distribution)
        return s

    return Functions(owns, eval, pdf, sample, specular_lobes)


FAMILY = Family(
    name="conductor",
    types=(
        MaterialType("mirror", MIRROR, ("reflectance", "two_sided"), BSDF_REFLECTION | BSDF_SPECULAR),
        MaterialType(
            "glossy",
            GLOSSY,
            ("roughness", "roughness_v", "distribution", "reflectance", "two_sided"),
            BSDF_REFLECTION | BSDF_GLOSSY,
        ),
        MaterialType(
            "conductor",
            CONDUCTOR,
            ("roughness_v", "distribution", "reflectance", "two_sided"),
            BSDF_REFLECTION | BSDF_GLOSSY,
        ),
    ),
    make=make,
    lobes=lobes,
    mitsuba=("conductor", "roughconductor"),
    base_color=base_color,
)
