"""``DIFFUSE``: the Lambertian reflector, f = ``albedo`` / pi, sampled cosine-weighted; and the
cosine-weighted sampling other families with a diffuse lobe share (``cosine_sample``)."""

import warp as wp

from ..sample_warps import cosine_hemisphere, frame
from ..textures import ALBEDO, TextureEvalContext
from .data import MaterialData, Parameters
from .interface import BSDF_DIFFUSE, BSDF_REFLECTION, BSDFSample, Family, Functions, MaterialType, lost_sample

DIFFUSE = wp.constant(0)


def cosine_sample(eval: wp.Function) -> wp.Function:
    """``sample`` of a BSDF ``eval`` drawn cosine-weighted about ``n`` (a diffuse lobe): weight
    ``f cos / pdf`` with ``pdf = cos / pi``; lost below the surface."""

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
        s = lost_sample()
        s.wi = frame(n) * cosine_hemisphere(u[0], u[1])
        s.flags = BSDF_REFLECTION | BSDF_DIFFUSE
        cos_theta = wp.dot(n, s.wi)
        if cos_theta > 0.0:
            s.pdf = cos_theta / wp.pi
            s.weight = eval(materials, m, n, wo, s.wi, 1.0, ctx, front, tangent) * (cos_theta / s.pdf)
        return s

    return sample


@wp.func
def cosine_pdf(
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
    """The density of ``cosine_sample``: cos / pi above the surface."""
    return wp.max(0.0, wp.dot(n, wi)) / wp.pi


def make(at: Parameters) -> Functions:
    @wp.func
    def owns(material_type: wp.int32) -> bool:
        return material_type == DIFFUSE

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
        return at.rgb(materials, m, ALBEDO, ctx, materials.albedo[m]) / wp.pi

    return Functions(owns, eval, cosine_pdf, cosine_sample(eval))


FAMILY = Family(
    name="diffuse",
    types=(MaterialType("diffuse", DIFFUSE, ("albedo", "two_sided"), BSDF_REFLECTION | BSDF_DIFFUSE),),
    make=make,
    mitsuba=("diffuse",),
)
