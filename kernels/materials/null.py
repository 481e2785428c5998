"""``NULL``: Mitsuba 3's ``null`` BSDF, a surface that is not there: every ray goes straight on
(``wi = -wo``, weight 1, probability 1), on both sides. It marks a medium's boundary without a
surface (fog in a sphere, smoke in a box): its shape's ``interior`` and ``exterior`` media change
where a ray crosses it, and in a scene with media shadow rays pass it and it is not a segment of
its own (Mitsuba 3's ``volpath``). Compiled in only where a scene has one (``Features.null``).
"""

import warp as wp

from ..textures import TextureEvalContext
from .data import MaterialData, Parameters
from .interface import NULL_LOBE, BSDFSample, Family, Functions, MaterialType

NULL = wp.constant(12)


def make(at: Parameters) -> Functions:
    """The null BSDF's functions: its one lobe is a delta, so ``sample`` only."""

    @wp.func
    def owns(material_type: wp.int32) -> bool:
        return material_type == NULL

    @wp.func
    def null_sample(
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
        s = BSDFSample()
        s.wi = -wo
        s.weight = wp.vec3(1.0)
        s.pdf = 1.0
        s.flags = NULL_LOBE
        return s

    return Functions(owns, sample=null_sample)


FAMILY = Family(
    name="null",
    types=(MaterialType("null", NULL, (), NULL_LOBE),),
    make=make,
    feature="null",
    whitted=False,
    specular=lambda material: False,  # straight on: no reflected or refracted ray
    mitsuba=("null",),
    base_color=lambda material: (0.0, 0.0, 0.0),
)
