"""``THIN_DIELECTRIC``: a window pane, a dielectric slab of negligible thickness of relative index
``ior`` (over the scene's ``exterior_ior``), reflecting ``reflectance`` times the summed Fresnel term
R' of ``fresnel_thin_dielectric`` and letting ``transmittance`` times 1 - R' straight through; it
bounds no medium (``BSDF_THIN``). Mitsuba 3's ``thindielectric``.
"""

import warp as wp

from ..optics import fresnel_thin_dielectric, reflect
from ..textures import REFLECTANCE, TRANSMITTANCE, TextureEvalContext
from .data import MaterialData, Parameters
from .interface import (
    BSDF_REFLECTION,
    BSDF_SPECULAR,
    BSDF_THIN,
    BSDF_TRANSMISSION,
    BSDFSample,
    Family,
    Functions,
    MaterialType,
    SpecularLobes,
    no_lobes,
)

THIN_DIELECTRIC = wp.constant(7)


@wp.func
def thin_reflectance(materials: MaterialData, m: wp.int32, cos_theta: float) -> float:
    """R', the fraction a thin dielectric ``m`` reflects at incidence cosine ``cos_theta`` (either
    side), before its tints; ``1 - R'`` goes straight through."""
    return fresnel_thin_dielectric(wp.abs(cos_theta), 1.0 / materials.ior[m])


@wp.func
def thin_transmittance(materials: MaterialData, m: wp.int32, cos_theta: float) -> wp.vec3:
    """What a thin dielectric ``m`` lets straight through at incidence cosine ``cos_theta``:
    ``transmittance`` times ``1 - R'`` (a shadow ray's filter, ``wrt.kernels.shadow``)."""
    return materials.transmittance[m] * (1.0 - thin_reflectance(materials, m, cos_theta))


@wp.func
def thin_dielectric_sample(
    materials: MaterialData,
    m: wp.int32,
    reflectance: wp.vec3,
    transmittance: wp.vec3,
    n: wp.vec3,
    wo: wp.vec3,
    uc: float,
) -> BSDFSample:
    """A thin dielectric's reflection with probability R' (weight ``reflectance``), else its
    straight transmission (weight ``transmittance``, ``wi = -wo``)."""
    s = BSDFSample()
    r = thin_reflectance(materials, m, wp.dot(wo, n))
    if uc < r:
        s.wi = reflect(-wo, n)
        s.weight = reflectance
        s.pdf = r
        s.flags = BSDF_REFLECTION | BSDF_SPECULAR
    else:
        s.wi = -wo
        s.weight = transmittance
        s.pdf = 1.0 - r
        s.flags = BSDF_TRANSMISSION | BSDF_SPECULAR | BSDF_THIN
    return s


def make(at: Parameters) -> Functions:
    @wp.func
    def owns(material_type: wp.int32) -> bool:
        return material_type == THIN_DIELECTRIC

    @wp.func
    def specular_lobes(
        materials: MaterialData, m: wp.int32, n: wp.vec3, wo: wp.vec3, eta: float, ctx: TextureEvalContext
    ) -> SpecularLobes:
        """``reflectance`` R' reflected, ``transmittance`` (1 - R') straight on (``wt = -wo``; ``eta``
        is 1 here, as it bounds no medium)."""
        lobes = no_lobes(n, wo)
        cos_theta = wp.dot(wo, n)
        reflectance = at.rgb(materials, m, REFLECTANCE, ctx, materials.reflectance[m])
        lobes.reflectance = reflectance * thin_reflectance(materials, m, cos_theta)
        transmittance = at.rgb(materials, m, TRANSMITTANCE, ctx, materials.transmittance[m])
        lobes.transmittance = transmittance * (1.0 - thin_reflectance(materials, m, cos_theta))
        lobes.refracts = True
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
        reflectance = at.rgb(materials, m, REFLECTANCE, ctx, materials.reflectance[m])
        transmittance = at.rgb(materials, m, TRANSMITTANCE, ctx, materials.transmittance[m])
        return thin_dielectric_sample(materials, m, reflectance, transmittance, n, wo, uc)

    return Functions(owns, sample=sample, specular_lobes=specular_lobes)


FAMILY = Family(
    name="thin_dielectric",
    types=(
        MaterialType(
            "thin_dielectric",
            THIN_DIELECTRIC,
            ("ior", "reflectance", "transmittance"),
            BSDF_REFLECTION | BSDF_TRANSMISSION | BSDF_SPECULAR | BSDF_THIN,
        ),
    ),
    make=make,
    mitsuba=("thindielectric",),
    base_color="transmittance",
    relative_ior=True,
)
