"""``BLEND``: Mitsuba 3's ``blendbsdf``, ``(1 - weight) f_a + weight f_b`` of two materials ``a``
and ``b`` (``materials``, neither a blend, a mask nor a material that bounds a medium), ``weight``
in [0, 1] a constant or a texture's ``texture_float`` (Mitsuba's ``eval_1``, clamped).

``eval`` and ``pdf`` are the weighted sums of the two materials' (Mitsuba's). ``sample`` draws
``b`` where ``uc < weight``, ``a`` elsewhere (``uc`` rescaled into [0, 1) for the material drawn);
a delta lobe keeps its weight, its probability times that of its material; a non-specular
direction gets the blend's own ``pdf`` and ``weight = eval |cos| / pdf``, the density with which
the blend as a whole draws it. (Mitsuba 3 returns the drawn material's own pdf and weight there,
while its ``pdf`` is the sum: the two disagree, and its MIS weights with light sampling then do
not add up to one where the materials' densities differ. The image both converge to is the same
without light sampling.) A material that is one-sided scatters nothing on its back side, as a
mask's inner material. Compiled in only where a scene has a blend (``Features.blend``); the
Whitted integrator cannot render one (its choice is random).
"""

import numpy as np
import warp as wp

from ..textures import WEIGHT, TextureEvalContext, material_float
from .interface import BSDF_SPECULAR, BSDFSample, Family, Functions, MaterialType, lost_sample

BLEND = wp.constant(13)


@wp.struct
class BlendData:
    """The blends' own columns of ``MaterialData`` (``materials.blend``), baked by ``bake``."""

    a: wp.array(dtype=wp.int32)  # the material of weight 1 - weight (-1 for other types)
    b: wp.array(dtype=wp.int32)  # the material of weight ``weight``
    weight: wp.array(dtype=float)  # textured: slot WEIGHT


def blend_flags(a_flags: int, b_flags: int) -> int:
    """The lobes of a blend of materials of lobes ``a_flags`` and ``b_flags``: both's."""
    return a_flags | b_flags


def make(at, bsdf) -> Functions:
    """The blend's functions around ``bsdf``, the dispatch of the families it blends: they answer
    for every material, a blend or not."""
    from .data import MaterialData, nested_scatters  # noqa: PLC0415 (MaterialData holds BlendData: an import cycle)

    @wp.func
    def owns(material_type: wp.int32) -> bool:
        return material_type == BLEND

    @wp.func
    def weight_at(materials: MaterialData, m: wp.int32, ctx: TextureEvalContext) -> float:
        """The weight of blend ``m``'s material ``b`` at ``ctx``: its texture's, clamped to [0, 1],
        or its ``weight``."""
        if wp.static(at.textures):
            w = material_float(materials.textures, m, WEIGHT, ctx, materials.blend.weight[m])
            return wp.clamp(w, 0.0, 1.0)
        return materials.blend.weight[m]

    def blended(nested, value_type):
        """``nested`` (the dispatch's ``eval`` or ``pdf``, of type ``value_type``), and a blend's:
        its materials' values, weighted."""

        @wp.func
        def blended_value(
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
            if materials.type[m] != BLEND:
                return nested(materials, m, n, wo, wi, eta, ctx, front, tangent)
            w = weight_at(materials, m, ctx)
            a = materials.blend.a[m]
            b = materials.blend.b[m]
            value = value_type(0.0)
            if w < 1.0 and nested_scatters(materials, a, n, wi, front):
                value = (1.0 - w) * nested(materials, a, n, wo, wi, eta, ctx, True, tangent)
            if w > 0.0 and nested_scatters(materials, b, n, wi, front):
                value = value + w * nested(materials, b, n, wo, wi, eta, ctx, True, tangent)
            return value

        return blended_value

    blended_eval = blended(bsdf.eval, wp.vec3)  # bsdf_eval, and a blend's: its materials' f, weighted
    blended_pdf = blended(bsdf.pdf, float)  # bsdf_pdf, and a blend's: its materials' densities, weighted

    @wp.func
    def blended_sample(
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
        """``bsdf_sample``, and a blend's (see the module's docstring)."""
        if materials.type[m] != BLEND:
            return bsdf.sample(materials, m, n, wo, eta, uc, u, ctx, front, tangent)
        w = weight_at(materials, m, ctx)
        chosen = materials.blend.a[m]
        p = 1.0 - w
        uc_chosen = (uc - w) / p
        if uc < w:
            chosen = materials.blend.b[m]
            p = w
            uc_chosen = uc / w
        if not front and materials.two_sided[chosen] == 0:
            return lost_sample()
        s = bsdf.sample(materials, chosen, n, wo, eta, wp.min(uc_chosen, 0.99999994), u, ctx, True, tangent)
        if s.pdf <= 0.0:
            return s
        if (s.flags & BSDF_SPECULAR) != 0:
            s.pdf = s.pdf * p
            return s
        s.pdf = blended_pdf(materials, m, n, wo, s.wi, eta, ctx, front, tangent)
        if s.pdf > 0.0:
            f = blended_eval(materials, m, n, wo, s.wi, eta, ctx, front, tangent)
            s.weight = f * (wp.abs(wp.dot(n, s.wi)) / s.pdf)
        else:
            s.weight = wp.vec3(0.0)
        return s

    return Functions(owns, blended_eval, blended_pdf, blended_sample, bsdf.specular_lobes)


def bake(materials: list, exterior_ior: float) -> dict[str, np.ndarray]:
    """``BlendData``'s columns for ``materials`` (``wrt.scene.Material``s, all families): each
    blend's two materials (indices into ``materials``) and weight."""
    index = {material.name: i for i, material in enumerate(materials)}
    a = [index[m.materials[0]] if m.type == "blend" else -1 for m in materials]
    b = [index[m.materials[1]] if m.type == "blend" else -1 for m in materials]
    weight = [m.weight if m.type == "blend" else 0.0 for m in materials]
    return {
        "a": np.array(a, dtype=np.int32),
        "b": np.array(b, dtype=np.int32),
        "weight": np.array(weight, dtype=np.float64),
    }


FAMILY = Family(
    name="blend",
    types=(MaterialType("blend", BLEND, ("materials", "weight"), 0),),
    make=make,
    wraps=True,
    feature="blend",
    whitted=False,
    specular=lambda material: False,  # its materials' delta lobes are theirs: Features.specular asks them
    mitsuba=("blendbsdf",),
    data=BlendData,
    bake=bake,
)
