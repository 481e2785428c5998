"""Materials on the device: the registry of material families and the one BSDF interface
integrators use.

Each module of this package is one family, a plugin (``interface.Family``): its types, its device
functions and its host description. The registry (``FAMILIES``) derives from them the material
type names and codes (``TYPES``), the loader's keys (``MaterialType.keys``), the material flags of
``wrt.kernels.features.Features`` and of the variants (``MATERIAL_FLAGS``: a family compiled in
only where a scene has one), the scene analysis that picks a variant (``families_for``; the
host's ``wrt.renderer.scene_features``), the upload (``Family.lobe_flags``, ``base_color``,
``relative_ior``, ``bake``) and the BSDF dispatch (``make_bsdf``). A new material family is one
new module here, listed in ``FAMILIES``, with its tests and docs.

Families: ``diffuse`` (Lambert), ``phong``, ``conductor`` (``mirror``, ``glossy``, ``conductor``),
``dielectric``, ``thin_dielectric``, ``rough_dielectric``, ``plastic`` (``plastic``,
``rough_plastic``), ``principled`` (Mitsuba 3's), ``blend``, ``mask``, ``null`` (no surface: a
medium's boundary), and ``emitter`` (``EMITTER``, the surface of an area or sphere light: it
reflects nothing). Any type may emit
``emission`` (W/(m^2 sr)) from its front side. ``base_color`` is what the raycast integrator
shows. A material that is not ``two_sided`` (one-sided, as Mitsuba 3's diffuse and conductors)
reflects nothing on its back side, the side its surface's shading normal points away from
(``wrt.kernels.hit``).

The BSDF interface (pbrt-v4's ``BSDF::f / Sample_f / PDF / Flags``, Mitsuba 3's ``eval / sample /
pdf / flags``): integrators ask these functions and never test a material's type.

- ``bsdf_flags(materials, m)``: the lobes, a combination of ``BSDF_REFLECTION``,
  ``BSDF_TRANSMISSION``, ``BSDF_DIFFUSE``, ``BSDF_GLOSSY``, ``BSDF_SPECULAR`` (a delta lobe) and
  ``BSDF_THIN`` (the transmission goes straight on and the surface bounds no medium: integrators
  leave the media stack alone there); 0 for a surface that scatters nothing (``EMITTER``).
  ``bsdf_flags_from(materials, m, front)``: the same for a ray arriving on the front side or the
  back, 0 on the back of a one-sided material: what integrators ask at a hit, and then call the
  functions below only where it is not 0. ``non_specular(flags)``: the BSDF has lobes that
  ``eval`` sees, so light sampling (next-event estimation) pays there.
- ``make_bsdf(families, textures, inline, beckmann, anisotropic)``: the dispatch over the families a
  scene uses, a ``BSDF`` of
  - ``eval(materials, m, n, wo, wi, eta, ctx, front, tangent)``: f (1/sr) of the non-specular lobes, 0 for
    delta lobes; ``wi`` on ``n``'s side, or across the surface where the BSDF has glossy
    transmission (a rough dielectric: the only one that needs ``eta``, 1 by default);
  - ``pdf(...)``: the solid-angle density with which ``sample`` draws ``wi`` from the non-specular lobes;
  - ``sample(materials, m, n, wo, eta, uc, u, ctx, front, tangent)``: one direction, as a ``BSDFSample``
    with ``weight = f |cos| / pdf`` (for a delta lobe: its reflectance or transmittance over the
    discrete probability of choosing it) and the flags of the lobe chosen; ``pdf == 0`` when the
    sample is lost;
  - ``specular_lobes(materials, m, n, wo, eta, ctx)``: every delta lobe at once, for integrators
    that split the ray tree deterministically (Whitted): ``SpecularLobes`` with the reflected and
    transmitted directions and weights.

Conventions: world space; ``n`` is the unit shading normal on ``wo``'s side (``dot(n, wo) >= 0``;
``Hit.n_facing``: the geometric normal, or a smooth-shaded mesh's interpolated one); ``wo`` (toward
the viewer) and ``wi`` (toward the light, or the sampled direction) are unit vectors pointing away
from the surface; ``eta = n1 / n2`` is the ratio of the indices of refraction on ``wo``'s side and
across the surface (``wrt.kernels.media``; 1 for opaque materials). ``uc`` chooses a lobe, ``u``
(2D) samples a direction within it; both uniform in [0, 1). ``ctx`` is the hit's texture coordinate
(textured parameters), ``front`` (``Hit.front``, default true) the side it arrived on: every
family's functions take it; a mask and a blend read it (their materials scatter nothing on the back
of a one-sided one, while a mask's null lobe lets the ray through on both sides), and a principled
material's lobes are its side's (Mitsuba's sign of ``cos theta_i``). ``tangent`` (``Hit.tangent``)
is the shading frame's unit tangent ``s``, perpendicular to ``n`` (Mitsuba 3's ``sh_frame.s``:
``dp/du`` made orthogonal to the shading normal), along which an anisotropic material's
``roughness`` lies (``roughness_v`` along ``n x s``); zero (the default, and in every scene without
an anisotropic material) the BSDFs take the frame ``wrt.kernels.sample_warps.frame(n)``, in which
isotropic lobes are the same.

References
----------
M. Pharr, W. Jakob, G. Humphreys, pbrt-v4, sec. 9.1 (the BSDF interface and its flags).
W. Jakob et al., Mitsuba 3, ``src/bsdfs`` (one plugin per BSDF).
"""

import functools
from typing import NamedTuple

import warp as wp

from .. import hinted_func
from ..textures import TextureEvalContext
from . import (
    blend,
    conductor,
    dielectric,
    diffuse,
    mask,
    null,
    phong,
    plastic,
    principled,
    rough_dielectric,
    thin_dielectric,
)
from .blend import BLEND, blend_flags
from .conductor import CONDUCTOR, GLOSSY, MIRROR
from .data import MaterialData, parameters
from .dielectric import DIELECTRIC
from .diffuse import DIFFUSE
from .interface import (
    BSDF_ANISOTROPIC,
    BSDF_DIFFUSE,
    BSDF_GLOSSY,
    BSDF_MEDIUM,
    BSDF_REFLECTION,
    BSDF_SPECULAR,
    BSDF_THIN,
    BSDF_TOTAL_INTERNAL,
    BSDF_TRANSMISSION,
    MIN_ALPHA,
    NULL_LOBE,
    BSDFSample,
    Family,
    MaterialType,
    SpecularLobes,
    lost_sample,
    no_lobes,
)
from .mask import MASK, mask_flags
from .null import NULL
from .phong import PHONG
from .plastic import COATING_RES, PLASTIC, ROUGH_PLASTIC
from .principled import PRINCIPLED
from .rough_dielectric import ROUGH_DIELECTRIC
from .thin_dielectric import THIN_DIELECTRIC, thin_transmittance

EMITTER = wp.constant(5)

FAMILIES: tuple[Family, ...] = (
    diffuse.FAMILY,
    phong.FAMILY,
    conductor.FAMILY,
    dielectric.FAMILY,
    thin_dielectric.FAMILY,
    rough_dielectric.FAMILY,
    plastic.FAMILY,
    principled.FAMILY,
    blend.FAMILY,
    mask.FAMILY,
    null.FAMILY,
    Family(name="emitter", types=(MaterialType("emitter", EMITTER, (), 0),), base_color="emission"),
)
"""Every material family, in the order the dispatch tests them (the wrapping ones wrap in this
order: a blend the others, a mask them and the blends)."""

TYPES: dict[str, MaterialType] = {t.name: t for family in FAMILIES for t in family.types}
"""Every material type by name (``emitter``: a light's surface, not a ``[[material]]`` type)."""

FAMILY_OF: dict[str, Family] = {t.name: family for family in FAMILIES for t in family.types}
"""The family of each material type."""

MATERIAL_FLAGS: tuple[str, ...] = tuple(family.feature for family in FAMILIES if family.feature)
"""The ``Features`` flags of the families compiled in only where a scene has one."""

ALL_FAMILIES: tuple[str, ...] = tuple(family.name for family in FAMILIES)

__all__ = [
    "ALL_FAMILIES",
    "BSDF",
    "BLEND",
    "BSDF_ANISOTROPIC",
    "BSDF_DIFFUSE",
    "BSDF_GLOSSY",
    "BSDF_MEDIUM",
    "BSDF_REFLECTION",
    "BSDF_SPECULAR",
    "BSDF_THIN",
    "BSDF_TOTAL_INTERNAL",
    "BSDF_TRANSMISSION",
    "COATING_RES",
    "CONDUCTOR",
    "DIELECTRIC",
    "DIFFUSE",
    "EMITTER",
    "FAMILIES",
    "FAMILY_OF",
    "GLOSSY",
    "MASK",
    "MATERIAL_FLAGS",
    "MIN_ALPHA",
    "MIRROR",
    "NULL",
    "NULL_LOBE",
    "PHONG",
    "PLASTIC",
    "PRINCIPLED",
    "ROUGH_DIELECTRIC",
    "ROUGH_PLASTIC",
    "THIN_DIELECTRIC",
    "TYPES",
    "BSDFSample",
    "MaterialData",
    "SpecularLobes",
    "blend_flags",
    "bsdf_flags",
    "bsdf_flags_from",
    "families_for",
    "lobe_flags",
    "make_bsdf",
    "mask_flags",
    "non_specular",
    "thin_transmittance",
]


def lobe_flags(material) -> int:
    """The lobes (``BSDF_*`` flags) of host material ``material`` (a ``wrt.scene.Material``; a
    mask's are ``mask_flags``' of its inner material's)."""
    return FAMILY_OF[material.type].lobe_flags(material)


def families_for(features, whitted: bool = False) -> tuple[str, ...]:
    """The families compiled into the kernels of ``features`` (a ``wrt.kernels.features.Features``):
    those without a flag, and those whose flag is set; for the Whitted integrator (``whitted``) only
    those it renders."""
    return tuple(
        family.name
        for family in FAMILIES
        if (family.feature is None or getattr(features, family.feature)) and (family.whitted or not whitted)
    )


@wp.func
def bsdf_flags(materials: MaterialData, m: wp.int32) -> wp.int32:
    """The lobes of material ``m``'s BSDF (``BSDF_*`` bits); 0 if it scatters nothing. One load
    of a table made on the host (``lobe_flags``): a chain of tests by type, inlined at every hit,
    cost the path tracer 10% of its time on the CPU."""
    return materials.flags[m]


@wp.func
def bsdf_flags_from(materials: MaterialData, m: wp.int32, front: bool) -> wp.int32:
    """``bsdf_flags`` for a ray arriving on the front side of material ``m`` (``front``: travelling
    against the surface's unflipped shading normal, ``Hit.front``) or on its back: 0 on the back of a
    one-sided material. A front hit costs a compare more than ``bsdf_flags``, a back hit a load."""
    if not front:
        if materials.two_sided[m] == 0:
            return 0
    return bsdf_flags(materials, m)


@wp.func
def non_specular(flags: wp.int32) -> bool:
    """Has lobes that ``eval`` sees (diffuse or glossy)."""
    return (flags & (BSDF_DIFFUSE | BSDF_GLOSSY)) != 0


class BSDF(NamedTuple):
    """The per-hit functions of the BSDF interface, for the material families a scene has."""

    eval: wp.Function
    pdf: wp.Function
    sample: wp.Function
    specular_lobes: wp.Function


@functools.cache
def make_bsdf(
    families: tuple[str, ...] = ALL_FAMILIES,
    textures: bool = True,
    inline: bool | None = None,
    beckmann: bool = True,
    anisotropic: bool = True,
) -> BSDF:
    """The BSDF interface over ``families`` (names of ``FAMILIES``; ``families_for``), with texture
    lookups of the parameters (``wrt.kernels.textures``, at the hit's ``ctx``) only where
    ``textures``, Beckmann microfacets only where ``beckmann`` (``wrt.kernels.microfacet``) and a
    second alpha only where ``anisotropic`` (``wrt.kernels.materials.data.parameters``), its
    four functions with Warp's inline hint ``inline`` (None: the compiler's choice, the CPU's;
    False: out of line, the CUDA kernels', ``wrt.kernels.variants.CUDA_INLINE``).
    A family left out is not in the generated code: a material of it scatters nothing. The
    dispatch tests the families in ``FAMILIES`` order (``_dispatch``); a wrapping family (a mask)
    wraps the others'."""
    at = parameters(textures, beckmann, anisotropic)
    chosen = [family for family in FAMILIES if family.name in families and family.make is not None]
    functions = [family.make(at) for family in chosen if not family.wraps]
    bsdf = _dispatch(functions, inline)
    for family in chosen:
        if family.wraps:
            wrapped = family.make(at, bsdf)
            bsdf = BSDF(wrapped.eval, wrapped.pdf, wrapped.sample, wrapped.specular_lobes)
    return bsdf


def _dispatch(functions: list, inline: bool | None = None) -> BSDF:
    """The four functions of the interface, each a chain of cases: the families that have one, in
    turn, then nothing.

    Each case calls its family's function and the next case as closure values, which Warp hashes
    with the module. The unrolled form ``for i in range(wp.static(len(fs))): wp.static(fs[i])``
    resolves its functions only when the module is built, after Warp has hashed a module that
    calls it from another Python module: an edited family then loaded a stale binary from the
    kernel cache (measured, Warp 1.19; ``test_material_registry``)."""
    eval_case = _eval_cases([(f.owns, f.eval) for f in functions if f.eval is not None], no_eval)
    pdf_case = _eval_cases([(f.owns, f.pdf) for f in functions if f.pdf is not None], no_pdf)
    sample_case = _sample_cases([(f.owns, f.sample) for f in functions if f.sample is not None])
    lobes_case = _lobes_cases([(f.owns, f.specular_lobes) for f in functions if f.specular_lobes is not None])
    hinted = hinted_func(inline)

    @hinted
    def bsdf_eval(
        materials: MaterialData,
        m: wp.int32,
        n: wp.vec3,
        wo: wp.vec3,
        wi: wp.vec3,
        eta: float = 1.0,
        ctx: TextureEvalContext = TextureEvalContext(),
        front: bool = True,
        tangent: wp.vec3 = wp.vec3(0.0, 0.0, 0.0),
    ) -> wp.vec3:
        """f(wo, wi) (1/sr) of the non-specular lobes for ``wi`` on the side of ``n`` (or across the
        surface, for glossy transmission); 0 for delta lobes."""
        return eval_case(materials, m, materials.type[m], n, wo, wi, eta, ctx, front, tangent)

    @hinted
    def bsdf_pdf(
        materials: MaterialData,
        m: wp.int32,
        n: wp.vec3,
        wo: wp.vec3,
        wi: wp.vec3,
        eta: float = 1.0,
        ctx: TextureEvalContext = TextureEvalContext(),
        front: bool = True,
        tangent: wp.vec3 = wp.vec3(0.0, 0.0, 0.0),
    ) -> float:
        """Solid-angle density (1/sr) with which ``bsdf_sample`` draws ``wi``; 0 for delta lobes."""
        return pdf_case(materials, m, materials.type[m], n, wo, wi, eta, ctx, front, tangent)

    @hinted
    def specular_lobes(
        materials: MaterialData,
        m: wp.int32,
        n: wp.vec3,
        wo: wp.vec3,
        eta: float,
        ctx: TextureEvalContext = TextureEvalContext(),
    ) -> SpecularLobes:
        """The delta lobes of material ``m`` (none for a family without them)."""
        return lobes_case(materials, m, materials.type[m], n, wo, eta, ctx)

    @hinted
    def bsdf_sample(
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
        """A direction drawn from material ``m``'s BSDF (lost for a family without lobes)."""
        return sample_case(materials, m, materials.type[m], n, wo, eta, uc, u, ctx, front, tangent)

    return BSDF(bsdf_eval, bsdf_pdf, bsdf_sample, specular_lobes)


@wp.func
def no_eval(
    materials: MaterialData,
    m: wp.int32,
    material_type: wp.int32,
    n: wp.vec3,
    wo: wp.vec3,
    wi: wp.vec3,
    eta: float,
    ctx: TextureEvalContext,
    front: bool,
    tangent: wp.vec3,
) -> wp.vec3:
    return wp.vec3(0.0)


@wp.func
def no_pdf(
    materials: MaterialData,
    m: wp.int32,
    material_type: wp.int32,
    n: wp.vec3,
    wo: wp.vec3,
    wi: wp.vec3,
    eta: float,
    ctx: TextureEvalContext,
    front: bool,
    tangent: wp.vec3,
) -> float:
    return 0.0


def _eval_cases(cases: list, otherwise: wp.Function) -> wp.Function:
    """``eval`` (or ``pdf``: the same arguments) of the first family of ``cases`` (``(owns,
    function)`` pairs) that owns ``material_type``, else ``otherwise``'s (``no_eval``, ``no_pdf``); the
    return type is the families' (Warp infers it)."""
    if not cases:
        return otherwise
    owns, family_function = cases[0]
    rest = _eval_cases(cases[1:], otherwise)

    @wp.func
    def eval_case(
        materials: MaterialData,
        m: wp.int32,
        material_type: wp.int32,
        n: wp.vec3,
        wo: wp.vec3,
        wi: wp.vec3,
        eta: float,
        ctx: TextureEvalContext,
        front: bool,
        tangent: wp.vec3,
    ):
        if owns(material_type):
            return family_function(materials, m, n, wo, wi, eta, ctx, front, tangent)
        return rest(materials, m, material_type, n, wo, wi, eta, ctx, front, tangent)

    return eval_case


def _sample_cases(cases: list) -> wp.Function:
    """``sample`` of the first family of ``cases`` that owns ``material_type``, else a lost sample."""
    if not cases:

        @wp.func
        def no_sample(
            materials: MaterialData,
            m: wp.int32,
            material_type: wp.int32,
            n: wp.vec3,
            wo: wp.vec3,
            eta: float,
            uc: float,
            u: wp.vec2,
            ctx: TextureEvalContext,
            front: bool,
            tangent: wp.vec3,
        ) -> BSDFSample:
            return lost_sample()

        return no_sample
    owns, family_sample = cases[0]
    rest = _sample_cases(cases[1:])

    @wp.func
    def sample_case(
        materials: MaterialData,
        m: wp.int32,
        material_type: wp.int32,
        n: wp.vec3,
        wo: wp.vec3,
        eta: float,
        uc: float,
        u: wp.vec2,
        ctx: TextureEvalContext,
        front: bool,
        tangent: wp.vec3,
    ) -> BSDFSample:
        if owns(material_type):
            return family_sample(materials, m, n, wo, eta, uc, u, ctx, front, tangent)
        return rest(materials, m, material_type, n, wo, eta, uc, u, ctx, front, tangent)

    return sample_case


def _lobes_cases(cases: list) -> wp.Function:
    """``specular_lobes`` of the first family of ``cases`` that owns ``material_type``, else none."""
    if not cases:

        @wp.func
        def no_specular_lobes(
            materials: MaterialData,
            m: wp.int32,
            material_type: wp.int32,
            n: wp.vec3,
            wo: wp.vec3,
            eta: float,
            ctx: TextureEvalContext,
        ) -> SpecularLobes:
            return no_lobes(n, wo)

        return no_specular_lobes
    owns, family_lobes = cases[0]
    rest = _lobes_cases(cases[1:])

    @wp.func
    def lobes_case(
        materials: MaterialData,
        m: wp.int32,
        material_type: wp.int32,
        n: wp.vec3,
        wo: wp.vec3,
        eta: float,
        ctx: TextureEvalContext,
    ) -> SpecularLobes:
        if owns(material_type):
            return family_lobes(materials, m, n, wo, eta, ctx)
        return rest(materials, m, material_type, n, wo, eta, ctx)

    return lobes_case
