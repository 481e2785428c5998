"""``DIELECTRIC``: smooth glass of index ``ior``, Beer-Lambert absorption ``sigma`` inside
(``wrt.kernels.media``) and ``priority`` where dielectrics overlap: the exact Fresnel term F
reflected and 1 - F refracted by Snell's law, all reflected past the critical angle. Mitsuba 3's
``dielectric``; pbrt-v4's ``DielectricBxDF`` (smooth).
"""

import warp as wp

from ..optics import fresnel_dielectric, refract
from ..textures import TextureEvalContext
from .data import MaterialData, Parameters
from .interface import (
    BSDF_REFLECTION,
    BSDF_SPECULAR,
    BSDF_TOTAL_INTERNAL,
    BSDF_TRANSMISSION,
    BSDFSample,
    Family,
    Functions,
    MaterialType,
    SpecularLobes,
    lost_sample,
    no_lobes,
)

DIELECTRIC = wp.constant(3)


def make(at: Parameters) -> Functions:
    @wp.func
    def owns(material_type: wp.int32) -> bool:
        return material_type == DIELECTRIC

    @wp.func
    def specular_lobes(
        materials: MaterialData, m: wp.int32, n: wp.vec3, wo: wp.vec3, eta: float, ctx: TextureEvalContext
    ) -> SpecularLobes:
        """F reflected, 1 - F refracted (``wt``), all reflected past the critical angle.

        Refracted radiance is scaled by ``eta^2`` (radiance transport, as pbrt-v4's and Mitsuba 3's
        dielectrics in radiance mode): the solid angle of a beam is compressed by ``(n1 / n2)^2`` as
        it crosses into the denser medium, so radiance ``L / n^2`` is what is conserved. A path that
        enters and leaves the same glass multiplies ``eta^2`` and ``1 / eta^2`` and is unchanged; a
        camera or a light inside water or glass is not."""
        lobes = no_lobes(n, wo)
        fresnel = fresnel_dielectric(wp.dot(wo, n), eta)
        ok, wt = refract(-wo, n, eta)
        if not ok:
            fresnel = 1.0
        lobes.reflectance = wp.vec3(fresnel)
        lobes.transmittance = wp.vec3((1.0 - fresnel) * eta * eta)
        lobes.wt = wt
        lobes.refracts = ok
        lobes.total_internal = not ok
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
        """The reflection with probability F (weight F / F = 1), else the refraction (weight ``eta^2``)."""
        s = lost_sample()
        lobes = specular_lobes(materials, m, n, wo, eta, ctx)
        s.wi = lobes.wr
        s.flags = BSDF_REFLECTION | BSDF_SPECULAR
        if uc < lobes.reflectance[0]:
            s.weight = wp.vec3(1.0)
            s.pdf = lobes.reflectance[0]
            if lobes.total_internal:
                s.flags = s.flags | BSDF_TOTAL_INTERNAL
        else:
            s.wi = lobes.wt
            s.pdf = 1.0 - lobes.reflectance[0]
            s.weight = lobes.transmittance / s.pdf
            s.flags = BSDF_TRANSMISSION | BSDF_SPECULAR
        return s

    return Functions(owns, sample=sample, specular_lobes=specular_lobes)


FAMILY = Family(
    name="dielectric",
    types=(
        MaterialType(
            "dielectric",
            DIELECTRIC,
            ("ior", "transmittance", "priority"),
            BSDF_REFLECTION | BSDF_TRANSMISSION | BSDF_SPECULAR,
        ),
    ),
    make=make,
    medium=True,
    mitsuba=("dielectric",),
    base_color="transmittance",
)
