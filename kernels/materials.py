"""Materials on the device: per-shape lookup, parameters, and the one BSDF interface integrators use.

Types (``MaterialData.type``): ``DIFFUSE`` (Lambert, albedo/pi), ``PHONG`` (albedo/pi plus the
energy-normalised Phong lobe ``specular (n + 2) / (2 pi) cos^n alpha``, alpha between the
mirror direction of ``wi`` and ``wo``), ``MIRROR`` (perfect specular, ``reflectance``),
``DIELECTRIC`` (smooth glass: ``ior``, Beer-Lambert ``sigma``), ``GLOSSY`` (GGX conductor of
``roughness`` alpha with the constant Fresnel factor ``reflectance``, ``wrt.kernels.microfacet``),
``THIN_DIELECTRIC`` (a window pane: a dielectric slab of negligible thickness of relative index
``ior``, reflecting ``reflectance`` times the summed Fresnel term R' of ``fresnel_thin_dielectric``
and letting ``transmittance`` times 1 - R' straight through; it bounds no medium),
``CONDUCTOR`` (the exact Fresnel reflectance of the complex index of refraction ``eta + i k`` times
the tint ``reflectance``: a mirror where ``roughness`` is 0, else GGX of alpha ``roughness`` with
the Fresnel term at the microfacet normal),
``ROUGH_DIELECTRIC`` (rough glass: a dielectric of ``ior``, ``sigma`` and ``priority`` whose
interface is GGX of alpha ``roughness``, reflecting F and refracting 1 - F at the microfacet
normal, Walter et al. 2007: ``wrt.kernels.microfacet.ggx_dielectric_eval``; index-matched
(``eta == 1``) it is a straight pass, sampled as a delta lobe),
``PLASTIC`` and ``ROUGH_PLASTIC`` (Mitsuba 3's ``plastic`` and ``roughplastic``: a smooth or GGX
(alpha ``roughness``) dielectric coating of relative index ``ior`` over a Lambertian base of
``albedo``; the coating reflects ``reflectance`` times its Fresnel term, the base
``albedo / (1 - R_i)`` (``albedo / (1 - albedo R_i)`` where ``nonlinear``; ``R_i =
internal_reflectance``, the coating's mean reflectance from inside) times the coating's
transmittance on the way in and out and ``1 / ior^2``; the transmittance is ``1 - F`` for the
smooth coating and ``coating_transmittance``'s table of ``cos theta`` for the rough one; the
coating is chosen with probability ``specular_weight (1 - T) / (specular_weight (1 - T) + (1 -
specular_weight) T)``, ``T`` its transmittance at ``wo``: ``wrt.plastics`` computes these on the
host as Mitsuba does) and
``MASK`` (Mitsuba 3's ``mask``: with probability ``opacity``, a constant or a texture's
``texture_float``, the material ``inner`` (not itself a mask, nor a dielectric that bounds a
medium), else a null lobe: the ray goes straight on, ``wi = -wo`` with weight 1, as through a
thin dielectric's transmission, and the surface bounds no medium) and
``EMITTER`` (the surface of an area or sphere light: reflects nothing). Any type may emit
``emission`` (W/(m^2 sr)) from its front side. ``base_color`` is what the raycast integrator shows.
A material that is not ``two_sided`` (one-sided, as Mitsuba 3's diffuse and conductors) reflects
nothing on its back side, the side its surface's shading normal points away from (``wrt.kernels.hit``).

The BSDF interface (pbrt-v4's ``BSDF::f / Sample_f / PDF / Flags``, Mitsuba 3's ``eval / sample /
pdf / flags``): integrators ask these functions and never test a material's type.

- ``bsdf_flags(materials, m)``: the lobes, a combination of ``BSDF_REFLECTION``,
  ``BSDF_TRANSMISSION``, ``BSDF_DIFFUSE``, ``BSDF_GLOSSY``, ``BSDF_SPECULAR`` (a delta lobe) and
  ``BSDF_THIN`` (the transmission goes straight on and the surface bounds no medium: integrators
  leave the media stack alone there); 0 for a surface that scatters nothing (``EMITTER``).
  ``bsdf_flags_from(materials, m, front)``: the same
  for a ray arriving on the front side or the back, 0 on the back of a one-sided material: what
  integrators ask at a hit, and then call the functions below only where it is not 0.
  ``non_specular(flags)``: the BSDF has lobes that ``bsdf_eval`` sees, so light sampling
  (next-event estimation) pays there.
- ``bsdf_eval(materials, m, n, wo, wi, eta)``: f (1/sr) of the non-specular lobes, 0 for delta
  lobes; ``wi`` on ``n``'s side, or across the surface where the BSDF has glossy transmission (a
  rough dielectric: the only one that needs ``eta``, 1 by default).
- ``bsdf_pdf(materials, m, n, wo, wi, eta)``: the solid-angle density with which ``bsdf_sample``
  draws ``wi`` from the non-specular lobes.
- ``bsdf_sample(materials, m, n, wo, eta, uc, u)``: one direction, as a ``BSDFSample`` with
  ``weight = f |cos| / pdf`` (for a delta lobe: its reflectance or transmittance over the discrete
  probability of choosing it) and the flags of the lobe chosen; ``pdf == 0`` when the sample is lost.
- ``specular_lobes(materials, m, n, wo, eta)``: every delta lobe at once, for integrators that split
  the ray tree deterministically (Whitted): ``SpecularLobes`` with the reflected and transmitted
  directions and weights.

Conventions: world space; ``n`` is the unit shading normal on ``wo``'s side (``dot(n, wo) >= 0``;
``Hit.n_facing``: the geometric normal, or a smooth-shaded mesh's interpolated one);
``wo`` (toward the viewer) and ``wi`` (toward the light, or the sampled direction) are unit vectors
pointing away from the surface; ``eta = n1 / n2`` is the ratio of the indices of refraction on
``wo``'s side and across the surface (``wrt.kernels.media``; 1 for opaque materials). ``uc`` chooses
a lobe, ``u`` (2D) samples a direction within it; both uniform in [0, 1). ``bsdf_eval``,
``bsdf_pdf`` and ``bsdf_sample`` also take the hit's ``uv`` (textured parameters) and ``front``
(``Hit.front``, default true): only a mask reads it, as its nested material scatters nothing on
the back of a one-sided one while its null lobe lets the ray through on both sides.

A new material type is one new constant here, its entry in ``LOBES`` and one new case in each of
``bsdf_eval``, ``bsdf_pdf``, ``bsdf_sample`` (and ``specular_lobes`` if it has delta lobes).
``make_bsdf(rough_dielectric, plastic, textures, mask)`` builds these four with the cases of
the rough dielectric, the plastics, texture lookups and masks only where a scene has them
(``wrt.kernels.features``); the module-level functions have every case.

References
----------
E. Lafortune, Y. Willems, "Using the Modified Phong Reflectance Model for Physically Based
Rendering", KU Leuven CW 197, 1994 (the (n + 2) / (2 pi) normalisation).
M. Pharr, W. Jakob, G. Humphreys, pbrt-v4, sec. 9.1 (the BSDF interface and its flags).
"""

import functools
from typing import NamedTuple

import warp as wp

from .microfacet import (
    ggx_dielectric_eval,
    ggx_dielectric_pdf,
    ggx_eval,
    ggx_g1,
    ggx_pdf,
    ggx_sample_visible_normal,
)
from .optics import fresnel_conductor, fresnel_dielectric, fresnel_thin_dielectric, reflect, refract
from .sample_warps import cosine_hemisphere, frame
from .textures import (
    ALBEDO,
    OPACITY,
    REFLECTANCE,
    ROUGHNESS,
    SPECULAR,
    TRANSMITTANCE,
    TextureData,
    material_float,
    material_rgb,
    texture_float,
)

DIFFUSE = wp.constant(0)
PHONG = wp.constant(1)
MIRROR = wp.constant(2)
DIELECTRIC = wp.constant(3)
GLOSSY = wp.constant(4)
EMITTER = wp.constant(5)
CONDUCTOR = wp.constant(6)
THIN_DIELECTRIC = wp.constant(7)
ROUGH_DIELECTRIC = wp.constant(8)
PLASTIC = wp.constant(9)
ROUGH_PLASTIC = wp.constant(10)
MASK = wp.constant(11)

BSDF_REFLECTION = wp.constant(1)
BSDF_TRANSMISSION = wp.constant(2)
BSDF_DIFFUSE = wp.constant(4)
BSDF_GLOSSY = wp.constant(8)
BSDF_SPECULAR = wp.constant(16)
BSDF_TOTAL_INTERNAL = wp.constant(32)  # a sampled lobe only: specular reflection because refraction is impossible
BSDF_THIN = wp.constant(64)  # transmission goes straight on through a surface that bounds no medium (thin dielectric)
NULL_LOBE = wp.constant(BSDF_TRANSMISSION | BSDF_SPECULAR | BSDF_THIN)  # a mask's: straight on, weight 1

MIN_ALPHA = 1e-4  # the least GGX alpha a roughness texture gives (0 would be a mirror: another lobe)
COATING_RES = 64  # entries of a rough plastic's coating_transmittance table (Mitsuba's MI_ROUGH_TRANSMITTANCE_RES)


@wp.struct
class MaterialData:
    shape_material: wp.array(dtype=wp.int32)  # material index of each [[shape]]
    type: wp.array(dtype=wp.int32)
    flags: wp.array(dtype=wp.int32)  # the lobes of each material (lobe_flags)
    base_color: wp.array(dtype=wp.vec3)
    albedo: wp.array(dtype=wp.vec3)
    specular: wp.array(dtype=wp.vec3)
    exponent: wp.array(dtype=float)
    reflectance: wp.array(dtype=wp.vec3)  # mirror, glossy: the reflectance; conductor: the tint of its Fresnel term
    ior: wp.array(
        dtype=float
    )  # dielectrics: their ior; thin dielectric, plastics: their ior over the scene's exterior_ior
    sigma: wp.array(dtype=wp.vec3)  # absorption coefficient per unit length, -ln(transmittance)
    transmittance: wp.array(dtype=wp.vec3)  # thin dielectric: the tint of its straight transmission
    priority: wp.array(dtype=wp.int32)
    roughness: wp.array(dtype=float)  # GGX alpha (conductor: 0 for a smooth one)
    eta: wp.array(dtype=wp.vec3)  # conductor: real part of the index of refraction, per channel
    k: wp.array(dtype=wp.vec3)  # conductor: imaginary part (extinction coefficient)
    emission: wp.array(dtype=wp.vec3)
    two_sided: wp.array(dtype=wp.int32)  # 1: both sides reflect; 0: the back side reflects nothing
    textures: TextureData  # the textures of textured parameters (wrt.kernels.textures)
    nonlinear: wp.array(dtype=wp.int32)  # plastics: 1 where internal scattering tints the base (Mitsuba's nonlinear)
    internal_reflectance: wp.array(dtype=float)  # plastics: the coating's mean reflectance from inside
    specular_weight: wp.array(dtype=float)  # plastics: mean reflectance / (mean reflectance + mean albedo)
    coating_transmittance: wp.array2d(
        dtype=float
    )  # rough plastic m: row m, T(cos theta) at cos = k / (COATING_RES - 1)
    inner: wp.array(dtype=wp.int32)  # mask: the index of the material it masks (-1 for other types)
    opacity: wp.array(dtype=float)  # mask: the probability of its inner material (textured: slot OPACITY)


@wp.struct
class BSDFSample:
    wi: wp.vec3  # unit direction sampled, away from the surface
    weight: wp.vec3  # f |cos theta_i| / pdf
    pdf: float  # solid-angle density (non-specular lobes), or the discrete probability of a delta lobe
    flags: wp.int32  # the lobe chosen: BSDF_REFLECTION or BSDF_TRANSMISSION, plus its kind


@wp.struct
class SpecularLobes:
    wr: wp.vec3  # mirror direction
    reflectance: wp.vec3  # weight of the reflected ray
    wt: wp.vec3  # refracted direction (valid when ``refracts``)
    transmittance: wp.vec3  # weight of the refracted ray (0 without transmission)
    refracts: bool  # the transmitted ray exists
    total_internal: bool  # a dielectric past the critical angle: all is reflected


LOBES = {
    DIFFUSE: BSDF_REFLECTION | BSDF_DIFFUSE,
    PHONG: BSDF_REFLECTION | BSDF_DIFFUSE | BSDF_GLOSSY,
    GLOSSY: BSDF_REFLECTION | BSDF_GLOSSY,
    MIRROR: BSDF_REFLECTION | BSDF_SPECULAR,
    DIELECTRIC: BSDF_REFLECTION | BSDF_TRANSMISSION | BSDF_SPECULAR,
    THIN_DIELECTRIC: BSDF_REFLECTION | BSDF_TRANSMISSION | BSDF_SPECULAR | BSDF_THIN,
    ROUGH_DIELECTRIC: BSDF_REFLECTION | BSDF_TRANSMISSION | BSDF_GLOSSY,
    PLASTIC: BSDF_REFLECTION | BSDF_DIFFUSE | BSDF_SPECULAR,
    ROUGH_PLASTIC: BSDF_REFLECTION | BSDF_DIFFUSE | BSDF_GLOSSY,
    EMITTER: 0,
}
"""The lobes (``BSDF_*`` bits) of each material type; a conductor's are ``lobe_flags``'."""


def lobe_flags(kind: int, roughness: float) -> int:
    """The lobes of a material of type ``kind`` and GGX ``roughness`` (host side: the table
    ``MaterialData.flags`` that ``bsdf_flags`` reads): a conductor is glossy where it is rough, a
    mirror where it is smooth."""
    if kind == CONDUCTOR:
        return BSDF_REFLECTION | (BSDF_GLOSSY if roughness > 0.0 else BSDF_SPECULAR)
    return LOBES[kind]


def mask_flags(inner_flags: int, opaque: bool) -> int:
    """The lobes of a mask over a material of lobes ``inner_flags``: those, and its null lobe
    unless it is ``opaque`` (a constant opacity of 1)."""
    return inner_flags if opaque else inner_flags | NULL_LOBE


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
    """Has lobes that ``bsdf_eval`` sees (diffuse or glossy)."""
    return (flags & (BSDF_DIFFUSE | BSDF_GLOSSY)) != 0


@wp.func
def specular_reflectance(materials: MaterialData, m: wp.int32, reflectance: wp.vec3, cos_theta: float) -> wp.vec3:
    """The reflectance of a mirror's, a glossy's or a conductor's facet (the surface, or a
    microfacet) seen at incidence cosine ``cos_theta``: ``reflectance``, for a conductor times its
    Fresnel term."""
    if materials.type[m] == CONDUCTOR:
        return wp.cw_mul(reflectance, fresnel_conductor(cos_theta, materials.eta[m], materials.k[m]))
    return reflectance


@wp.func
def thin_reflectance(materials: MaterialData, m: wp.int32, cos_theta: float) -> float:
    """R', the fraction a thin dielectric ``m`` reflects at incidence cosine ``cos_theta`` (either
    side), before its tints; ``1 - R'`` goes straight through."""
    return fresnel_thin_dielectric(wp.abs(cos_theta), 1.0 / materials.ior[m])


@wp.func
def thin_transmittance(materials: MaterialData, m: wp.int32, cos_theta: float) -> wp.vec3:
    """What a thin dielectric ``m`` lets straight through at incidence cosine ``cos_theta``:
    ``transmittance`` times ``1 - R'``."""
    return materials.transmittance[m] * (1.0 - thin_reflectance(materials, m, cos_theta))


@wp.func
def coating_transmittance(materials: MaterialData, m: wp.int32, cos_theta: float) -> float:
    """The fraction of light a plastic's coating lets through at incidence cosine ``cos_theta``
    (> 0), into the base or out of it: ``1 - F`` for a smooth coating, the linear interpolation of
    a rough one's table (Mitsuba's ``lerp_gather``)."""
    if materials.type[m] == PLASTIC:
        return 1.0 - fresnel_dielectric(cos_theta, 1.0 / materials.ior[m])
    x = wp.min(cos_theta, 1.0) * float(COATING_RES - 1)
    k = wp.min(int(x), COATING_RES - 2)
    w = x - float(k)
    return (1.0 - w) * materials.coating_transmittance[m, k] + w * materials.coating_transmittance[m, k + 1]


@wp.func
def coating_probability(materials: MaterialData, m: wp.int32, transmittance: float) -> float:
    """The probability with which a plastic samples its coating's reflection rather than its base,
    given the coating's ``transmittance`` at ``wo``."""
    w = materials.specular_weight[m]
    coating = (1.0 - transmittance) * w
    total = coating + transmittance * (1.0 - w)
    if total <= 0.0:
        return 0.0
    return coating / total


@wp.func
def plastic_eval(
    materials: MaterialData,
    m: wp.int32,
    albedo: wp.vec3,
    reflectance: wp.vec3,
    alpha: float,
    n: wp.vec3,
    wo: wp.vec3,
    wi: wp.vec3,
) -> wp.vec3:
    """f (1/sr) of a plastic's base, and of a rough plastic's coating (GGX, ``reflectance`` times
    the Fresnel term at the microfacet normal)."""
    cos_i = wp.dot(n, wi)
    if cos_i <= 0.0:
        return wp.vec3(0.0)
    inside = materials.internal_reflectance[m]
    scattered = wp.vec3(1.0 - inside)
    if materials.nonlinear[m] != 0:
        scattered = wp.vec3(1.0) - albedo * inside
    ior = materials.ior[m]
    t = coating_transmittance(materials, m, wp.dot(n, wo)) * coating_transmittance(materials, m, cos_i)
    f = wp.cw_div(albedo, scattered) * (t / (wp.pi * ior * ior))
    if materials.type[m] == ROUGH_PLASTIC:
        to_local = wp.transpose(frame(n))
        fresnel = fresnel_dielectric(wp.dot(wo, wp.normalize(wo + wi)), 1.0 / ior)
        f += reflectance * (fresnel * ggx_eval(to_local * wo, to_local * wi, alpha))
    return f


@wp.func
def plastic_pdf(materials: MaterialData, m: wp.int32, alpha: float, n: wp.vec3, wo: wp.vec3, wi: wp.vec3) -> float:
    """The density of ``plastic_sample``'s non-specular lobes: the base's cosine-weighted one and
    a rough coating's GGX visible normals, each times the probability of choosing it."""
    cos_i = wp.dot(n, wi)
    if cos_i <= 0.0:
        return 0.0
    coating = coating_probability(materials, m, coating_transmittance(materials, m, wp.dot(n, wo)))
    pdf = (1.0 - coating) * cos_i / wp.pi
    if materials.type[m] == ROUGH_PLASTIC:
        to_local = wp.transpose(frame(n))
        pdf += coating * ggx_pdf(to_local * wo, to_local * wi, alpha)
    return pdf


@wp.func
def plastic_sample(
    materials: MaterialData,
    m: wp.int32,
    albedo: wp.vec3,
    reflectance: wp.vec3,
    alpha: float,
    n: wp.vec3,
    wo: wp.vec3,
    uc: float,
    u: wp.vec2,
) -> BSDFSample:
    """The coating's reflection with probability ``coating_probability`` (a smooth coating's mirror
    direction, weight ``reflectance F`` over that probability; a rough one's GGX visible normals),
    else the base's cosine-weighted direction; non-specular samples weigh ``f cos / pdf`` of both
    lobes together, as Mitsuba 3's ``roughplastic``."""
    s = BSDFSample()
    s.weight = wp.vec3(0.0)
    s.pdf = 0.0
    to_world = frame(n)
    transmittance = coating_transmittance(materials, m, wp.dot(n, wo))
    coating = coating_probability(materials, m, transmittance)
    if uc < coating:
        if materials.type[m] == PLASTIC:
            s.wi = reflect(-wo, n)
            s.weight = reflectance * ((1.0 - transmittance) / coating)
            s.pdf = coating
            s.flags = BSDF_REFLECTION | BSDF_SPECULAR
            return s
        wo_local = wp.transpose(to_world) * wo
        h = ggx_sample_visible_normal(wo_local, alpha, u[0], u[1])
        s.wi = to_world * (2.0 * wp.dot(wo_local, h) * h - wo_local)
        s.flags = BSDF_REFLECTION | BSDF_GLOSSY
    else:
        s.wi = to_world * cosine_hemisphere(u[0], u[1])
        s.flags = BSDF_REFLECTION | BSDF_DIFFUSE
    cos_theta = wp.dot(n, s.wi)
    if cos_theta > 0.0:
        s.pdf = plastic_pdf(materials, m, alpha, n, wo, s.wi)
        if s.pdf > 0.0:
            s.weight = plastic_eval(materials, m, albedo, reflectance, alpha, n, wo, s.wi) * (cos_theta / s.pdf)
    return s


@wp.func
def rough_dielectric_sample(alpha: float, n: wp.vec3, wo: wp.vec3, eta: float, uc: float, u: wp.vec2) -> BSDFSample:
    """A visible microfacet normal ``h`` of a rough dielectric, then reflection about it with
    probability F (at ``wo.h``; weight ``G1(wi)``) or refraction through it (weight ``eta^2
    G1(wi)``), as Mitsuba 3's ``roughdielectric``; index-matched (``eta == 1``) a straight pass,
    a delta lobe of weight 1."""
    s = BSDFSample()
    s.weight = wp.vec3(0.0)
    s.pdf = 0.0
    if eta == 1.0:
        s.wi = -wo
        s.weight = wp.vec3(1.0)
        s.pdf = 1.0
        s.flags = BSDF_TRANSMISSION | BSDF_SPECULAR
        return s
    to_world = frame(n)
    wo_local = wp.transpose(to_world) * wo
    h = ggx_sample_visible_normal(wo_local, alpha, u[0], u[1])
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
        s.pdf = ggx_dielectric_pdf(wo_local, wi_local, alpha, eta)
        s.weight = wp.vec3(scale * ggx_g1(wi_local, alpha))
    return s


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


class BSDF(NamedTuple):
    """The per-hit functions of the BSDF interface, for the material types a scene has."""

    eval: wp.Function
    pdf: wp.Function
    sample: wp.Function
    specular_lobes: wp.Function


@functools.cache
def make_bsdf(rough_dielectric: bool = True, plastic: bool = True, textures: bool = True, mask: bool = True) -> BSDF:
    """``bsdf_eval``, ``bsdf_pdf``, ``bsdf_sample`` and ``specular_lobes`` with the rough
    dielectric's and the plastics' cases compiled in only where the scene has them (compiled in
    but untaken, they cost the path tracer about 15% of its time on glossy_reflection, CPU),
    texture lookups of the parameters (``wrt.kernels.textures``, at the hit's ``uv``) only where it
    has textures (without them every parameter is the material's constant and ``uv`` is unused),
    and masks (``MASK``: the first three wrap the others' cases) only where it has masks."""

    @wp.func
    def rgb_at(materials: MaterialData, m: wp.int32, slot: wp.int32, uv: wp.vec2, constant: wp.vec3) -> wp.vec3:
        """Colour parameter ``slot`` of material ``m`` at ``uv``: its texture's, or ``constant``."""
        if wp.static(textures):
            return material_rgb(materials.textures, m, slot, uv, constant)
        return constant

    @wp.func
    def alpha_at(materials: MaterialData, m: wp.int32, uv: wp.vec2) -> float:
        """GGX alpha of material ``m`` at ``uv``: its roughness texture's (at least ``MIN_ALPHA``),
        or its ``roughness``."""
        alpha = materials.roughness[m]
        if wp.static(textures):
            if materials.textures.slot[m, ROUGHNESS] >= 0:
                alpha = wp.max(MIN_ALPHA, texture_float(materials.textures, materials.textures.slot[m, ROUGHNESS], uv))
        return alpha

    @wp.func
    def bsdf_eval(
        materials: MaterialData,
        m: wp.int32,
        n: wp.vec3,
        wo: wp.vec3,
        wi: wp.vec3,
        eta: float = 1.0,
        uv: wp.vec2 = wp.vec2(0.0, 0.0),
        front: bool = True,
    ) -> wp.vec3:
        """f(wo, wi) (1/sr) of the non-specular lobes for ``wi`` on the side of ``n`` (or across the
        surface, for glossy transmission); 0 for delta lobes."""
        kind = materials.type[m]
        if kind == GLOSSY or kind == CONDUCTOR:
            if materials.roughness[m] == 0.0:
                return wp.vec3(0.0)
            alpha = alpha_at(materials, m, uv)
            to_local = wp.transpose(frame(n))
            cos_h = wp.abs(wp.dot(wo, wp.normalize(wo + wi)))
            reflectance = rgb_at(materials, m, REFLECTANCE, uv, materials.reflectance[m])
            return specular_reflectance(materials, m, reflectance, cos_h) * ggx_eval(
                to_local * wo, to_local * wi, alpha
            )
        if kind == DIFFUSE:
            return rgb_at(materials, m, ALBEDO, uv, materials.albedo[m]) / wp.pi
        if kind == PHONG:
            cos_alpha = wp.max(0.0, wp.dot(reflect(-wi, n), wo))
            e = materials.exponent[m]
            return rgb_at(materials, m, ALBEDO, uv, materials.albedo[m]) / wp.pi + rgb_at(
                materials, m, SPECULAR, uv, materials.specular[m]
            ) * ((e + 2.0) / (2.0 * wp.pi) * wp.pow(cos_alpha, e))
        if wp.static(rough_dielectric):
            if kind == ROUGH_DIELECTRIC:
                to_local = wp.transpose(frame(n))
                return wp.vec3(ggx_dielectric_eval(to_local * wo, to_local * wi, alpha_at(materials, m, uv), eta))
        if wp.static(plastic):
            if kind == PLASTIC or kind == ROUGH_PLASTIC:
                albedo = rgb_at(materials, m, ALBEDO, uv, materials.albedo[m])
                reflectance = rgb_at(materials, m, REFLECTANCE, uv, materials.reflectance[m])
                return plastic_eval(materials, m, albedo, reflectance, alpha_at(materials, m, uv), n, wo, wi)
        return wp.vec3(0.0)

    @wp.func
    def bsdf_pdf(
        materials: MaterialData,
        m: wp.int32,
        n: wp.vec3,
        wo: wp.vec3,
        wi: wp.vec3,
        eta: float = 1.0,
        uv: wp.vec2 = wp.vec2(0.0, 0.0),
        front: bool = True,
    ) -> float:
        """Solid-angle density (1/sr) with which ``bsdf_sample`` draws ``wi``; 0 for delta lobes."""
        kind = materials.type[m]
        if kind == GLOSSY or kind == CONDUCTOR:
            if materials.roughness[m] == 0.0:
                return 0.0
            to_local = wp.transpose(frame(n))
            return ggx_pdf(to_local * wo, to_local * wi, alpha_at(materials, m, uv))
        if kind == DIFFUSE or kind == PHONG:
            return wp.max(0.0, wp.dot(n, wi)) / wp.pi
        if wp.static(rough_dielectric):
            if kind == ROUGH_DIELECTRIC:
                to_local = wp.transpose(frame(n))
                return ggx_dielectric_pdf(to_local * wo, to_local * wi, alpha_at(materials, m, uv), eta)
        if wp.static(plastic):
            if kind == PLASTIC or kind == ROUGH_PLASTIC:
                return plastic_pdf(materials, m, alpha_at(materials, m, uv), n, wo, wi)
        return 0.0

    @wp.func
    def specular_lobes(
        materials: MaterialData, m: wp.int32, n: wp.vec3, wo: wp.vec3, eta: float, uv: wp.vec2 = wp.vec2(0.0, 0.0)
    ) -> SpecularLobes:
        """The delta lobes of a mirror (reflectance), a smooth conductor (reflectance times its Fresnel
        term), a plastic's coating (reflectance times its Fresnel term; its base is ``bsdf_eval``'s),
        a smooth dielectric (exact Fresnel F reflected, 1 - F refracted by Snell's law, all
        reflected past the critical angle) or a thin dielectric (``reflectance`` R' reflected,
        ``transmittance`` (1 - R') straight on, ``wt = -wo``; ``eta`` is 1 there, as it bounds no
        medium); none for other types.

        Refracted radiance is scaled by ``eta^2`` (radiance transport, as pbrt-v4's and Mitsuba 3's
        dielectrics in radiance mode): the solid angle of a beam is compressed by ``(n1 / n2)^2`` as
        it crosses into the denser medium, so radiance ``L / n^2`` is what is conserved. A path that
        enters and leaves the same glass multiplies ``eta^2`` and ``1 / eta^2`` and is unchanged; a
        camera or a light inside water or glass is not."""
        lobes = SpecularLobes()
        lobes.wr = reflect(-wo, n)
        lobes.wt = -wo
        lobes.reflectance = wp.vec3(0.0)
        lobes.transmittance = wp.vec3(0.0)
        lobes.refracts = False
        lobes.total_internal = False
        kind = materials.type[m]
        if kind == MIRROR or kind == CONDUCTOR:
            reflectance = rgb_at(materials, m, REFLECTANCE, uv, materials.reflectance[m])
            lobes.reflectance = specular_reflectance(materials, m, reflectance, wp.dot(wo, n))
        elif kind == DIELECTRIC:
            fresnel = fresnel_dielectric(wp.dot(wo, n), eta)
            ok, wt = refract(-wo, n, eta)
            if not ok:
                fresnel = 1.0
            lobes.reflectance = wp.vec3(fresnel)
            lobes.transmittance = wp.vec3((1.0 - fresnel) * eta * eta)
            lobes.wt = wt
            lobes.refracts = ok
            lobes.total_internal = not ok
        elif kind == THIN_DIELECTRIC:
            cos_theta = wp.dot(wo, n)
            reflectance = rgb_at(materials, m, REFLECTANCE, uv, materials.reflectance[m])
            lobes.reflectance = reflectance * thin_reflectance(materials, m, cos_theta)
            transmittance = rgb_at(materials, m, TRANSMITTANCE, uv, materials.transmittance[m])
            lobes.transmittance = transmittance * (1.0 - thin_reflectance(materials, m, cos_theta))
            lobes.refracts = True
        if wp.static(plastic):
            if kind == PLASTIC:
                reflectance = rgb_at(materials, m, REFLECTANCE, uv, materials.reflectance[m])
                lobes.reflectance = reflectance * fresnel_dielectric(wp.dot(wo, n), 1.0 / materials.ior[m])
        return lobes

    @wp.func
    def bsdf_sample(
        materials: MaterialData,
        m: wp.int32,
        n: wp.vec3,
        wo: wp.vec3,
        eta: float,
        uc: float,
        u: wp.vec2,
        uv: wp.vec2 = wp.vec2(0.0, 0.0),
        front: bool = True,
    ) -> BSDFSample:
        """A direction drawn from material ``m``'s BSDF: diffuse and Phong cosine-weighted, glossy and
        rough conductors by GGX visible normals, a mirror's or a smooth conductor's reflection, a
        dielectric's reflection with probability F (weight F / F = 1) and refraction otherwise (weight
        ``eta^2``, ``specular_lobes``), a thin dielectric's reflection with probability R' (weight
        ``reflectance``) and straight transmission otherwise (weight ``transmittance``), a rough
        dielectric's (``rough_dielectric_sample``) and a plastic's (``plastic_sample``)."""
        s = BSDFSample()
        s.weight = wp.vec3(0.0)
        s.pdf = 0.0
        s.flags = 0
        kind = materials.type[m]
        if kind == THIN_DIELECTRIC:
            reflectance = rgb_at(materials, m, REFLECTANCE, uv, materials.reflectance[m])
            transmittance = rgb_at(materials, m, TRANSMITTANCE, uv, materials.transmittance[m])
            return thin_dielectric_sample(materials, m, reflectance, transmittance, n, wo, uc)
        if kind == MIRROR or kind == DIELECTRIC or (kind == CONDUCTOR and materials.roughness[m] == 0.0):
            lobes = specular_lobes(materials, m, n, wo, eta, uv)
            s.wi = lobes.wr
            s.flags = BSDF_REFLECTION | BSDF_SPECULAR
            if kind != DIELECTRIC:
                s.weight = lobes.reflectance
                s.pdf = 1.0
            elif uc < lobes.reflectance[0]:
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
        to_world = frame(n)
        if kind == GLOSSY or kind == CONDUCTOR:
            to_local = wp.transpose(to_world)
            wo_local = to_local * wo
            alpha = alpha_at(materials, m, uv)
            h = ggx_sample_visible_normal(wo_local, alpha, u[0], u[1])
            cos_h = wp.dot(wo_local, h)
            wi_local = 2.0 * cos_h * h - wo_local
            s.wi = to_world * wi_local
            s.flags = BSDF_REFLECTION | BSDF_GLOSSY
            if wi_local[2] > 0.0:
                reflectance = rgb_at(materials, m, REFLECTANCE, uv, materials.reflectance[m])
                s.weight = specular_reflectance(materials, m, reflectance, cos_h) * ggx_g1(wi_local, alpha)
                s.pdf = ggx_pdf(wo_local, wi_local, alpha)
            return s
        if wp.static(rough_dielectric):
            if kind == ROUGH_DIELECTRIC:
                return rough_dielectric_sample(alpha_at(materials, m, uv), n, wo, eta, uc, u)
        if wp.static(plastic):
            if kind == PLASTIC or kind == ROUGH_PLASTIC:
                albedo = rgb_at(materials, m, ALBEDO, uv, materials.albedo[m])
                reflectance = rgb_at(materials, m, REFLECTANCE, uv, materials.reflectance[m])
                return plastic_sample(materials, m, albedo, reflectance, alpha_at(materials, m, uv), n, wo, uc, u)
        s.wi = to_world * cosine_hemisphere(u[0], u[1])
        if kind == DIFFUSE or kind == PHONG:
            s.flags = BSDF_REFLECTION | BSDF_DIFFUSE
            cos_theta = wp.dot(n, s.wi)
            if cos_theta > 0.0:
                s.pdf = cos_theta / wp.pi
                s.weight = bsdf_eval(materials, m, n, wo, s.wi, 1.0, uv) * (cos_theta / s.pdf)
        return s

    if not mask:
        return BSDF(bsdf_eval, bsdf_pdf, bsdf_sample, specular_lobes)

    @wp.func
    def opacity_at(materials: MaterialData, m: wp.int32, uv: wp.vec2) -> float:
        """The opacity of mask ``m`` at ``uv``: its texture's ``texture_float``, or its ``opacity``."""
        if wp.static(textures):
            return material_float(materials.textures, m, OPACITY, uv, materials.opacity[m])
        return materials.opacity[m]

    @wp.func
    def inner_scatters(materials: MaterialData, inner: wp.int32, n: wp.vec3, wi: wp.vec3, front: bool) -> bool:
        """A mask's inner material may scatter toward ``wi``: not on the back of a one-sided one,
        nor across the surface unless it transmits (a light below the mask is not seen through it)."""
        if not front and materials.two_sided[inner] == 0:
            return False
        return wp.dot(n, wi) > 0.0 or (materials.flags[inner] & BSDF_TRANSMISSION) != 0

    @wp.func
    def masked_eval(
        materials: MaterialData,
        m: wp.int32,
        n: wp.vec3,
        wo: wp.vec3,
        wi: wp.vec3,
        eta: float = 1.0,
        uv: wp.vec2 = wp.vec2(0.0, 0.0),
        front: bool = True,
    ) -> wp.vec3:
        """``bsdf_eval``, and a mask's: ``opacity`` times its inner material's f (the null lobe is a delta)."""
        if materials.type[m] != MASK:
            return bsdf_eval(materials, m, n, wo, wi, eta, uv)
        inner = materials.inner[m]
        if not inner_scatters(materials, inner, n, wi, front):
            return wp.vec3(0.0)
        return opacity_at(materials, m, uv) * bsdf_eval(materials, inner, n, wo, wi, eta, uv)

    @wp.func
    def masked_pdf(
        materials: MaterialData,
        m: wp.int32,
        n: wp.vec3,
        wo: wp.vec3,
        wi: wp.vec3,
        eta: float = 1.0,
        uv: wp.vec2 = wp.vec2(0.0, 0.0),
        front: bool = True,
    ) -> float:
        """``bsdf_pdf``, and a mask's: ``opacity`` times its inner material's density."""
        if materials.type[m] != MASK:
            return bsdf_pdf(materials, m, n, wo, wi, eta, uv)
        inner = materials.inner[m]
        if not inner_scatters(materials, inner, n, wi, front):
            return 0.0
        return opacity_at(materials, m, uv) * bsdf_pdf(materials, inner, n, wo, wi, eta, uv)

    @wp.func
    def masked_sample(
        materials: MaterialData,
        m: wp.int32,
        n: wp.vec3,
        wo: wp.vec3,
        eta: float,
        uc: float,
        u: wp.vec2,
        uv: wp.vec2 = wp.vec2(0.0, 0.0),
        front: bool = True,
    ) -> BSDFSample:
        """``bsdf_sample``, and a mask's (Mitsuba 3's): where ``uc < opacity`` its inner material's
        sample drawn with ``uc / opacity``, its pdf times ``opacity`` and its weight unchanged (lost
        on the back of a one-sided inner material), else the null lobe: ``wi = -wo``, weight 1,
        probability ``1 - opacity``."""
        if materials.type[m] != MASK:
            return bsdf_sample(materials, m, n, wo, eta, uc, u, uv)
        opacity = opacity_at(materials, m, uv)
        inner = materials.inner[m]
        if uc < opacity and (front or materials.two_sided[inner] != 0):
            nested = bsdf_sample(materials, inner, n, wo, eta, uc / opacity, u, uv)
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

    return BSDF(masked_eval, masked_pdf, masked_sample, specular_lobes)


def __getattr__(name: str):
    """``bsdf_eval``, ``bsdf_pdf``, ``bsdf_sample`` and ``specular_lobes`` with every material type's
    case (``make_bsdf()``), built on first use: at import they cost every process start-up time."""
    functions = {"bsdf_eval": "eval", "bsdf_pdf": "pdf", "bsdf_sample": "sample", "specular_lobes": "specular_lobes"}
    if name in functions:
        return getattr(make_bsdf(), functions[name])
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
