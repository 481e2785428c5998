"""``PHONG``: ``albedo`` / pi plus the energy-normalised Phong lobe ``specular (n + 2) / (2 pi)
cos^n alpha`` (``n`` the ``exponent``, alpha between the mirror direction of ``wi`` and ``wo``),
sampled cosine-weighted as a diffuse surface.

References
----------
E. Lafortune, Y. Willems, "Using the Modified Phong Reflectance Model for Physically Based
Rendering", KU Leuven CW 197, 1994 (the (n + 2) / (2 pi) normalisation).
"""

import warp as wp

from ..optics import reflect
from ..textures import ALBEDO, SPECULAR, TextureEvalContext
from .data import MaterialData, Parameters
from .diffuse import cosine_pdf, cosine_sample
from .interface import BSDF_DIFFUSE, BSDF_GLOSSY, BSDF_REFLECTION, Family, Functions, MaterialType

PHONG = wp.constant(1)


def make(at: Parameters) -> Functions:
    @wp.func
    def owns(material_type: wp.int32) -> bool:
        return material_type == PHONG

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
        cos_alpha = wp.max(0.0, wp.dot(reflect(-wi, n), wo))
        e = materials.exponent[m]
        return at.rgb(materials, m, ALBEDO, ctx, materials.albedo[m]) / wp.pi + at.rgb(
            materials, m, SPECULAR, ctx, materials.specular[m]
        ) * ((e + 2.0) / (2.0 * wp.pi) * wp.pow(cos_alpha, e))

    return Functions(owns, eval, cosine_pdf, cosine_sample(eval))


FAMILY = Family(
    name="phong",
    types=(
        MaterialType(
            "phong",
            PHONG,
            ("albedo", "specular", "exponent", "two_sided"),
            BSDF_REFLECTION | BSDF_DIFFUSE | BSDF_GLOSSY,
        ),
    ),
    make=make,
)
