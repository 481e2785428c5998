"""``PLASTIC`` and ``ROUGH_PLASTIC``: Mitsuba 3's ``plastic`` and ``roughplastic``, a smooth or rough
(alpha ``roughness``, GGX or Beckmann: ``distribution``) dielectric coating of relative index ``ior``
(the coating's over the scene's ``exterior_ior``: ``eta`` below) over a Lambertian base of ``albedo``.

The coating reflects ``reflectance`` times its Fresnel term. Light that enters it scatters in the
base and is reflected back by the coating's inside, the fraction ``internal_reflectance`` (``R_i``)
each time; summing those bounces, the base reflects ``albedo / (1 - R_i)`` (``albedo / (1 - albedo
R_i)`` where ``nonlinear``) times the coating's transmittance on the way in and out and
``1 / ior^2``. The transmittance is ``1 - F`` for the smooth coating and ``coating_transmittance``'s
table of ``cos theta`` for the rough one. The coating is chosen with probability ``specular_weight
(1 - T) / (specular_weight (1 - T) + (1 - specular_weight) T)``, ``T`` its transmittance at ``wo``.

The host bakes these constants (``bake``) as Mitsuba's plugins compute them when they are loaded:
``R_i`` is the diffuse Fresnel reflectance of a smooth coating (Egan and Hilgeman's fit, as
Mitsuba's ``fresnel_diffuse_reflectance``), and for a rough coating the cosine-weighted mean of its
microfacet reflectance from inside; a rough coating's transmittance from outside, as a function of the
incidence cosine, is tabulated at ``COATING_RES`` cosines. Both are the same quadratures as
Mitsuba's ``eval_reflectance`` and ``eval_transmittance`` (Gauss-Legendre over the visible-normal
sample square, 32 x 32 nodes for ``eta > 1``, 128 x 128 otherwise), here in float64. Compiled in
only where a scene has a plastic (``Features.plastic``): a lobe choice at each bounce.

References
----------
W. Jakob et al., Mitsuba 3: ``src/bsdfs/plastic.cpp``, ``roughplastic.cpp``,
``include/mitsuba/render/microfacet.h`` and ``fresnel.h``.
E. Heitz, E. d'Eon, "Importance Sampling Microfacet-Based BSDFs using the Distribution of Visible
Normals", EGSR 2014 (the visible-normal sampling the quadratures run over).
"""

import functools

import numpy as np
import warp as wp

from ..microfacet import smith_g1, visible_normals
from ..optics import fresnel_dielectric, reflect
from ..sample_warps import cosine_hemisphere, frame
from ..textures import ALBEDO, REFLECTANCE, TextureEvalContext
from .interface import (
    BSDF_DIFFUSE,
    BSDF_GLOSSY,
    BSDF_REFLECTION,
    BSDF_SPECULAR,
    MIN_ALPHA,
    BSDFSample,
    Family,
    Functions,
    MaterialType,
    SpecularLobes,
    lost_sample,
    no_lobes,
)

PLASTIC = wp.constant(9)
ROUGH_PLASTIC = wp.constant(10)
COATING_RES = 64  # entries of a rough plastic's coating_transmittance table (Mitsuba's MI_ROUGH_TRANSMITTANCE_RES)


@wp.struct
class PlasticData:
    """The plastics' own columns of ``MaterialData`` (``materials.plastic``), baked by ``bake``."""

    nonlinear: wp.array(dtype=wp.int32)  # 1 where internal scattering tints the base (Mitsuba's nonlinear)
    internal_reflectance: wp.array(dtype=float)  # R_i: the coating's mean reflectance from inside
    specular_weight: wp.array(dtype=float)  # mean reflectance / (mean reflectance + mean albedo)
    coating_transmittance: wp.array2d(
        dtype=float
    )  # rough plastic m: row m, T(cos theta) at cos = k / (COATING_RES - 1)


def make(at) -> Functions:
    from .data import MaterialData  # noqa: PLC0415 (MaterialData holds PlasticData: the one import cycle of the family)

    mf = at.microfacet

    @wp.func
    def owns(material_type: wp.int32) -> bool:
        return material_type == PLASTIC or material_type == ROUGH_PLASTIC

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
        table = materials.plastic.coating_transmittance
        return (1.0 - w) * table[m, k] + w * table[m, k + 1]

    @wp.func
    def coating_probability(materials: MaterialData, m: wp.int32, transmittance: float) -> float:
        """The probability with which a plastic samples its coating's reflection rather than its base,
        given the coating's ``transmittance`` at ``wo``."""
        w = materials.plastic.specular_weight[m]
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
        alpha: wp.vec2,
        distribution: wp.int32,
        n: wp.vec3,
        wo: wp.vec3,
        wi: wp.vec3,
    ) -> wp.vec3:
        """f (1/sr) of a plastic's base, and of a rough plastic's coating (microfacets, ``reflectance``
        times the Fresnel term at the microfacet normal)."""
        cos_i = wp.dot(n, wi)
        if cos_i <= 0.0:
            return wp.vec3(0.0)
        inside = materials.plastic.internal_reflectance[m]
        scattered = wp.vec3(1.0 - inside)
        if materials.plastic.nonlinear[m] != 0:
            scattered = wp.vec3(1.0) - albedo * inside
        ior = materials.ior[m]
        t = coating_transmittance(materials, m, wp.dot(n, wo)) * coating_transmittance(materials, m, cos_i)
        f = wp.cw_div(albedo, scattered) * (t / (wp.pi * ior * ior))
        if materials.type[m] == ROUGH_PLASTIC:
            to_local = wp.transpose(frame(n))
            fresnel = fresnel_dielectric(wp.dot(wo, wp.normalize(wo + wi)), 1.0 / ior)
            f += reflectance * (fresnel * mf.eval(to_local * wo, to_local * wi, alpha, distribution))
        return f

    @wp.func
    def plastic_pdf(
        materials: MaterialData,
        m: wp.int32,
        alpha: wp.vec2,
        distribution: wp.int32,
        n: wp.vec3,
        wo: wp.vec3,
        wi: wp.vec3,
    ) -> float:
        """The density of ``sample``'s non-specular lobes: the base's cosine-weighted one and
        a rough coating's visible normals, each times the probability of choosing it."""
        cos_i = wp.dot(n, wi)
        if cos_i <= 0.0:
            return 0.0
        coating = coating_probability(materials, m, coating_transmittance(materials, m, wp.dot(n, wo)))
        pdf = (1.0 - coating) * cos_i / wp.pi
        if materials.type[m] == ROUGH_PLASTIC:
            to_local = wp.transpose(frame(n))
            pdf += coating * mf.pdf(to_local * wo, to_local * wi, alpha, distribution)
        return pdf

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
        albedo = at.rgb(materials, m, ALBEDO, ctx, materials.albedo[m])
        reflectance = at.rgb(materials, m, REFLECTANCE, ctx, materials.reflectance[m])
        alpha = at.alpha(materials, m, ctx)
        return plastic_eval(materials, m, albedo, reflectance, alpha, at.distribution(materials, m), n, wo, wi)

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
        return plastic_pdf(materials, m, at.alpha(materials, m, ctx), at.distribution(materials, m), n, wo, wi)

    @wp.func
    def specular_lobes(
        materials: MaterialData, m: wp.int32, n: wp.vec3, wo: wp.vec3, eta: float, ctx: TextureEvalContext
    ) -> SpecularLobes:
        """A smooth coating's reflection, ``reflectance`` times its Fresnel term (the base is ``eval``'s)."""
        lobes = no_lobes(n, wo)
        if materials.type[m] == PLASTIC:
            reflectance = at.rgb(materials, m, REFLECTANCE, ctx, materials.reflectance[m])
            lobes.reflectance = reflectance * fresnel_dielectric(wp.dot(wo, n), 1.0 / materials.ior[m])
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
        """The coating's reflection with probability ``coating_probability`` (a smooth coating's mirror
        direction, weight ``reflectance F`` over that probability; a rough one's visible normals),
        else the base's cosine-weighted direction; non-specular samples weigh ``f cos / pdf`` of both
        lobes together, as Mitsuba 3's ``roughplastic``."""
        albedo = at.rgb(materials, m, ALBEDO, ctx, materials.albedo[m])
        reflectance = at.rgb(materials, m, REFLECTANCE, ctx, materials.reflectance[m])
        alpha = at.alpha(materials, m, ctx)
        distribution = at.distribution(materials, m)
        s = lost_sample()
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
            h = mf.sample_visible_normal(wo_local, alpha, distribution, u[0], u[1])
            s.wi = to_world * (2.0 * wp.dot(wo_local, h) * h - wo_local)
            s.flags = BSDF_REFLECTION | BSDF_GLOSSY
        else:
            s.wi = to_world * cosine_hemisphere(u[0], u[1])
            s.flags = BSDF_REFLECTION | BSDF_DIFFUSE
        cos_theta = wp.dot(n, s.wi)
        if cos_theta > 0.0:
            s.pdf = plastic_pdf(materials, m, alpha, distribution, n, wo, s.wi)
            if s.pdf > 0.0:
                s.weight = plastic_eval(materials, m, albedo, reflectance, alpha, distribution, n, wo, s.wi) * (
                    cos_theta / s.pdf
                )
        return s

    return Functions(owns, eval, pdf, sample, specular_lobes)


def fresnel(cos_i: np.ndarray, eta: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Mitsuba's dielectric ``fresnel`` for ``cos_i >= 0``: ``(F, cos_t, eta_ti)``, ``eta`` the
    ratio of the index of refraction across the interface to that of ``cos_i``'s side, ``cos_t``
    (<= 0) the cosine of the refracted direction, ``eta_ti = 1 / eta``."""
    eta_ti = 1.0 / eta
    cos_t_abs = np.sqrt(np.maximum(0.0, 1.0 - eta_ti * eta_ti * (1.0 - cos_i * cos_i)))
    with np.errstate(divide="ignore", invalid="ignore"):
        a_s = (cos_i - eta * cos_t_abs) / (cos_i + eta * cos_t_abs)
        a_p = (cos_t_abs - eta * cos_i) / (cos_t_abs + eta * cos_i)
    f = np.where(cos_i == 0.0, 1.0, 0.5 * (a_s * a_s + a_p * a_p))
    return f, -cos_t_abs, eta_ti


def fresnel_diffuse_reflectance(eta: float) -> float:
    """The hemispherically averaged (cosine-weighted) Fresnel reflectance of a smooth interface of
    relative index ``eta``: Egan and Hilgeman's fit for ``eta < 1``, d'Eon and Irving's above,
    as Mitsuba's ``fresnel_diffuse_reflectance``."""
    if eta < 1.0:
        return 0.0636 / eta + eta * (eta * -1.4399 + 0.7099) + 0.6681
    x = 1.0 / eta
    return float(np.polyval([-1.36881, 4.98554, -7.80989, 6.75335, -3.4793, 0.919317], x))


def _quadrature(wi: np.ndarray, alpha: float, distribution: str, eta: float, transmitted: bool) -> np.ndarray:
    """Mitsuba's ``eval_reflectance`` (``transmitted`` False) or ``eval_transmittance``: the
    fraction of light arriving from ``wi`` (N, 3) that a microfacet interface (``distribution``)
    of relative index ``eta`` reflects or transmits, single scattering."""
    nodes, weights = np.polynomial.legendre.leggauss(32 if eta > 1.0 else 128)
    ux, uy = np.meshgrid(nodes, nodes)
    wx, wy = np.meshgrid(weights, weights)
    u = np.stack([ux.ravel(), uy.ravel()], axis=-1) * 0.5 + 0.5
    w = (wx * wy).ravel() * 0.25
    m = visible_normals(wi, alpha, u, distribution)
    v = wi[:, None, :]
    cos_m = np.sum(v * m, axis=-1)
    f, cos_t, eta_ti = fresnel(cos_m, eta)
    if transmitted:
        wo = m * (cos_m * eta_ti + cos_t)[..., None] - v * eta_ti
        value = smith_g1(wo, m, alpha, distribution) * (1.0 - f)
        value = np.where(wo[..., 2] * v[..., 2] >= 0.0, 0.0, value)
    else:
        wo = 2.0 * cos_m[..., None] * m - v
        value = smith_g1(wo, m, alpha, distribution) * f
        value = np.where((wo[..., 2] <= 0.0) | (v[..., 2] <= 0.0), 0.0, value)
    return value @ w


@functools.cache
def rough_coating(alpha: float, eta: float, distribution: str = "ggx") -> tuple[np.ndarray, float]:
    """A microfacet coating of roughness ``alpha`` (``distribution``) and relative index ``eta``
    (> 1): its transmittance
    from outside at the cosines ``k / (COATING_RES - 1)`` (the first at 1e-6), and its
    internal reflectance, ``2`` times the mean over those cosines of ``cos`` times the
    reflectance from inside (Mitsuba's rule, not a finer integral). Cached: the table is shared,
    read-only."""
    alpha = max(alpha, MIN_ALPHA)
    mu = np.maximum(1e-6, np.linspace(0.0, 1.0, COATING_RES))
    wi = np.stack([np.sqrt(1.0 - mu * mu), np.zeros_like(mu), mu], axis=-1)
    transmittance = _quadrature(wi, alpha, distribution, eta, transmitted=True)
    transmittance.flags.writeable = False
    internal = 2.0 * float(np.mean(_quadrature(wi, alpha, distribution, 1.0 / eta, transmitted=False) * mu))
    return transmittance, internal


def specular_weight(albedo, reflectance) -> float:
    """The weight Mitsuba steers a plastic's samples to its coating with: the mean of the
    coating's ``reflectance`` over that plus the mean ``albedo`` (0.5 when both are black)."""
    s, d = float(np.mean(reflectance)), float(np.mean(albedo))
    return s / (s + d) if s + d > 0.0 else 0.5


def bake(materials: list, exterior_ior: float) -> dict[str, np.ndarray]:
    """``PlasticData``'s columns for ``materials`` (``wrt.scene.Material``s, all families): each
    plastic's constants, computed once; rough plastics' coating tables in rows of their material
    index (one row of zeros without any)."""
    internal, weight = np.zeros(len(materials)), np.zeros(len(materials))
    rough = any(material.type == "rough_plastic" for material in materials)
    tables = np.zeros((len(materials) if rough else 1, COATING_RES))
    for i, material in enumerate(materials):
        eta = material.ior / exterior_ior
        if material.type == "plastic":
            internal[i] = fresnel_diffuse_reflectance(1.0 / eta)
        elif material.type == "rough_plastic":
            tables[i], internal[i] = rough_coating(material.roughness, eta, material.distribution)
        weight[i] = specular_weight(material.albedo, material.reflectance)
    return {
        "nonlinear": np.array([material.nonlinear for material in materials], dtype=np.int32),
        "internal_reflectance": internal,
        "specular_weight": weight,
        "coating_transmittance": tables,
    }


FAMILY = Family(
    name="plastic",
    types=(
        MaterialType(
            "plastic",
            PLASTIC,
            ("albedo", "reflectance", "ior", "nonlinear", "two_sided"),
            BSDF_REFLECTION | BSDF_DIFFUSE | BSDF_SPECULAR,
        ),
        MaterialType(
            "rough_plastic",
            ROUGH_PLASTIC,
            ("albedo", "reflectance", "ior", "roughness", "distribution", "nonlinear", "two_sided"),
            BSDF_REFLECTION | BSDF_DIFFUSE | BSDF_GLOSSY,
        ),
    ),
    make=make,
    feature="plastic",
    mitsuba=("plastic", "roughplastic"),
    relative_ior=True,
    data=PlasticData,
    bake=bake,
)
