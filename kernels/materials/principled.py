"""``PRINCIPLED``: Mitsuba 3's ``principled`` BSDF (Burley's Disney BSDF, 2012 and 2015, as
Mitsuba 3.9 implements it), a mix of lobes over a dielectric interface of relative index ``ior``
(the inside's over the outside's, Mitsuba's ``eta``), all in the shading frame, with
``brdf = (1 - metallic)(1 - spec_trans)`` and ``btdf = (1 - metallic) spec_trans``:

- a main GGX lobe of alpha ``max(0.001, roughness^2)`` (anisotropic: over ``sqrt(1 - 0.9
  anisotropy)`` along the tangent, times it along the bitangent), reflecting ``F D G / (4 |cos_o|
  |cos_i|)`` with Mitsuba's blended Fresnel term (``principled_fresnel``: the dielectric's, the
  metallic part's Schlick of ``albedo``, the ``spec_tint`` part's Schlick of the tinted dielectric
  F0), on the back side the dielectric's ``btdf F``;
- its transmission, ``sqrt(albedo) btdf`` times the rough dielectric's (Walter et al. 2007);
- a clearcoat (front side), ``0.25 clearcoat F_schlick(0.04) D_GTR1 G`` of GTR1 alpha
  ``lerp(0.1, 0.001, clearcoat_gloss)`` and separable Smith GGX masking of alpha 0.25 (Mitsuba's
  form: without the ``1 / (4 cos cos)`` of the main lobe);
- on the front side, Burley's diffuse and retro-reflection, ``brdf albedo / pi (f_diff +
  f_retro)``, blended toward Hanrahan-Krueger's fake subsurface by ``flatness``, and the sheen
  ``sheen (1 - metallic) F_schlick(cos_d) lerp(1, albedo / luminance, sheen_tint)`` (where ``brdf >
  0``, as Mitsuba's scalar variants add it).

``sample`` chooses the diffuse lobe, the clearcoat, the transmission or the main reflection with
Mitsuba's probabilities (``lobe_probabilities``: each lobe's weight times its sampling rate,
the main lobe's split by the dielectric Fresnel term at the microfacet drawn; on the back side only
the reflection and the transmission, by F); every sample weighs ``f |cos| / pdf`` with ``pdf`` the
mixture's. Each parameter but ``ior`` and the sampling rates may be a texture (``texture_float``;
``albedo`` a colour). The side of the surface (Mitsuba's sign of ``cos theta_i``) is the hit's
``front``. Compiled in only where a scene has one (``Features.principled``).

References
----------
B. Burley, "Physically Based Shading at Disney", SIGGRAPH 2012 course notes; "Extending the Disney
BRDF to a BSDF with Integrated Subsurface Scattering", SIGGRAPH 2015 course notes.
W. Jakob et al., Mitsuba 3: ``src/bsdfs/principled.cpp``, ``principledhelpers.h``.
"""

import numpy as np
import warp as wp

from ..microfacet import ggx_d, ggx_g1, ggx_sample_visible_normal
from ..optics import fresnel_dielectric
from ..sample_warps import cosine_hemisphere, shading_frame
from ..textures import (
    ALBEDO,
    ANISOTROPY,
    CLEARCOAT,
    CLEARCOAT_GLOSS,
    DIFF_TRANS,
    FLATNESS,
    LUMINANCE,
    METALLIC,
    ROUGHNESS,
    SHEEN,
    SHEEN_TINT,
    SPEC_TINT,
    SPEC_TRANS,
    TextureEvalContext,
    material_float,
)
from .interface import (
    BSDF_DIFFUSE,
    BSDF_GLOSSY,
    BSDF_REFLECTION,
    BSDF_TRANSMISSION,
    BSDFSample,
    Family,
    Functions,
    MaterialType,
    lost_sample,
)

PRINCIPLED = wp.constant(14)
PRINCIPLED_THIN = wp.constant(15)
NUMBERS = ("metallic", "spec_trans", "spec_tint", "sheen", "sheen_tint", "flatness", "clearcoat", "clearcoat_gloss")
"""The principled parameters in [0, 1] besides ``roughness`` and ``anisotropy``, each a column of
``PrincipledData`` and a texture slot (``diff_trans``, a thin one's, is in [0, 2])."""
RATES = ("diffuse_reflectance_sampling_rate", "main_specular_sampling_rate", "clearcoat_sampling_rate")
THIN_RATES = (
    "specular_reflectance_sampling_rate",
    "specular_transmittance_sampling_rate",
    "diffuse_reflectance_sampling_rate",
    "diffuse_transmittance_sampling_rate",
)
"""The sampling rates of each type, in ``PrincipledData.rates`` order."""
THIN_NUMBERS = ("spec_trans", "spec_tint", "sheen", "sheen_tint", "flatness")
"""The thin variant's ``NUMBERS`` (it has no metallic or clearcoat)."""
THIN_KEYS = ("albedo", "roughness", "anisotropy", *THIN_NUMBERS)


@wp.struct
class PrincipledData:
    """The principled materials' own columns of ``MaterialData`` (``materials.principled``)."""

    metallic: wp.array(dtype=float)
    spec_trans: wp.array(dtype=float)
    spec_tint: wp.array(dtype=float)
    sheen: wp.array(dtype=float)
    sheen_tint: wp.array(dtype=float)
    flatness: wp.array(dtype=float)
    clearcoat: wp.array(dtype=float)
    clearcoat_gloss: wp.array(dtype=float)
    anisotropy: wp.array(dtype=float)
    diff_trans: wp.array(dtype=float)  # a thin one's diffuse transmission, in [0, 2]
    rates: wp.array(dtype=wp.vec4)  # the sampling rates: RATES (and 0), or a thin one's THIN_RATES


@wp.struct
class PrincipledParameters:
    """A principled material's parameters at a hit (textures looked up)."""

    albedo: wp.vec3
    roughness: float
    alpha: wp.vec2
    metallic: float
    spec_trans: float
    spec_tint: float
    sheen: float
    sheen_tint: float
    flatness: float
    clearcoat: float
    clearcoat_gloss: float
    eta: float
    rates: wp.vec4
    diff_trans: float  # a thin one's, halved into [0, 1] (Mitsuba's)
    alpha_transmitted: wp.vec2  # a thin one's transmission lobe: roughness scaled by 0.65 eta - 0.35
    transmits: bool  # it has a transmission lobe (``transmits``: Mitsuba's has_spec_trans)


@wp.func
def dielectric_fresnel(cos_theta: float, eta: float) -> float:
    """Mitsuba's ``fresnel(cos_theta, eta)``: the reflectance of an interface of relative index
    ``eta`` (inside over outside) met at ``cos_theta`` (< 0: from inside)."""
    if cos_theta >= 0.0:
        return fresnel_dielectric(cos_theta, 1.0 / eta)
    return fresnel_dielectric(-cos_theta, eta)


@wp.func
def schlick_weight(cos_theta: float) -> float:
    """``(1 - cos)^5``, clamped."""
    m = wp.clamp(1.0 - cos_theta, 0.0, 1.0)
    return m * m * m * m * m


@wp.func
def schlick(r0: wp.vec3, cos_theta: float, eta: float) -> wp.vec3:
    """Schlick's Fresnel ``R0 + (1 - R0) w`` at ``cos_theta`` (< 0: from inside), ``w`` the
    ``schlick_weight`` of the incident cosine where light goes into the denser side, else of the
    refracted one (Mitsuba's ``calc_schlick``)."""
    eta_it = eta
    eta_ti = 1.0 / eta
    if cos_theta < 0.0:
        eta_it = 1.0 / eta
        eta_ti = eta
    w = schlick_weight(wp.abs(cos_theta))
    if eta_it <= 1.0:
        w = schlick_weight(wp.sqrt(wp.max(0.0, 1.0 - (1.0 - cos_theta * cos_theta) * eta_ti * eta_ti)))
    return r0 + (wp.vec3(1.0) - r0) * w


@wp.func
def tint(albedo: wp.vec3) -> wp.vec3:
    """``albedo`` over its luminance (white where it is black)."""
    lum = wp.dot(albedo, LUMINANCE)
    if lum > 0.0:
        return albedo / lum
    return wp.vec3(1.0)


@wp.func
def tinted_schlick(p: PrincipledParameters, eta: float, cos_theta: float) -> wp.vec3:
    """The Schlick term at ``cos_theta`` of a dielectric of relative ior ``eta`` tinted by the
    albedo: F0 ``tint(albedo) ((eta - 1) / (eta + 1))^2``."""
    r0 = (eta - 1.0) / (eta + 1.0)
    return schlick(tint(p.albedo) * (r0 * r0), cos_theta, p.eta)


@wp.func
def principled_fresnel(p: PrincipledParameters, f_dielectric: float, cos_theta: float, front: bool) -> wp.vec3:
    """The main lobe's Fresnel term at ``cos_theta = wo.h``: on the front side the dielectric's
    ``(1 - metallic)(1 - spec_tint)`` share plus the Schlick terms of the metal (``metallic``, F0 the
    albedo) and of the tinted dielectric (``(1 - metallic) spec_tint``); on the back the
    dielectric's times ``btdf``."""
    if not front:
        return wp.vec3((1.0 - p.metallic) * p.spec_trans * f_dielectric)
    eta_it = p.eta
    if cos_theta < 0.0:
        eta_it = 1.0 / p.eta
    f = p.metallic * schlick(p.albedo, cos_theta, p.eta)
    f += (1.0 - p.metallic) * p.spec_tint * tinted_schlick(p, eta_it, cos_theta)
    return f + wp.vec3((1.0 - p.metallic) * (1.0 - p.spec_tint) * f_dielectric)


@wp.func
def masking(w: wp.vec3, h: wp.vec3, alpha: wp.vec2) -> float:
    """Smith's GGX masking of ``w`` by microfacet ``h``: 0 where ``w`` sees its back."""
    if wp.dot(w, h) * w[2] <= 0.0:
        return 0.0
    return ggx_g1(w, alpha)


@wp.func
def visible_pdf(wo: wp.vec3, h: wp.vec3, alpha: wp.vec2) -> float:
    """The density of ``h`` drawn from the normals visible from ``wo`` (``wo.z > 0``)."""
    return ggx_d(h, alpha) * masking(wo, h, alpha) * wp.abs(wp.dot(wo, h)) / wo[2]


@wp.func
def gtr1_d(h: wp.vec3, alpha: float) -> float:
    """Burley's GTR1 distribution (the clearcoat's), ``(a^2 - 1) / (pi ln(a^2) (1 + (a^2 - 1)
    cos^2))``; 0 below the surface."""
    a2 = alpha * alpha
    d = (a2 - 1.0) / (wp.pi * wp.log(a2) * (1.0 + (a2 - 1.0) * h[2] * h[2]))
    if d * h[2] > 1e-20:
        return d
    return 0.0


@wp.func
def clearcoat_alpha(p: PrincipledParameters) -> float:
    """The clearcoat's GTR1 alpha, ``lerp(0.1, 0.001, clearcoat_gloss)``."""
    return 0.1 + (0.001 - 0.1) * p.clearcoat_gloss


@wp.func
def gtr1_sample(alpha: float, u: wp.vec2) -> wp.vec3:
    """A GTR1 normal of density ``D cos theta``."""
    a2 = alpha * alpha
    cos2 = (1.0 - wp.pow(a2, 1.0 - u[1])) / (1.0 - a2)
    sin_theta = wp.sqrt(wp.max(0.0, 1.0 - cos2))
    phi = 2.0 * wp.pi * u[0]
    return wp.vec3(wp.cos(phi) * sin_theta, wp.sin(phi) * sin_theta, wp.sqrt(wp.max(0.0, cos2)))


@wp.func
def clearcoat_masking(w: wp.vec3, h: wp.vec3) -> float:
    """The clearcoat's Smith GGX masking of alpha 0.25 (Mitsuba's ``smith_ggx1``)."""
    if wp.dot(w, h) * w[2] <= 0.0:
        return 0.0
    if w[2] == 1.0:
        return 1.0
    cos2 = w[2] * w[2]
    return 2.0 / (1.0 + wp.sqrt(1.0 + 0.0625 * (1.0 - cos2) / cos2))


@wp.func
def half_vector(wo: wp.vec3, wi: wp.vec3, eta_path: float) -> wp.vec3:
    """The microfacet normal turning ``wo`` into ``wi`` (reflected, or refracted at ``eta_path``, the
    far side's index over ``wo``'s), on the outer side (``z >= 0``)."""
    h = wo + wi
    if wo[2] * wi[2] < 0.0:
        h = wo + wi * eta_path
    h = wp.normalize(h)
    if h[2] < 0.0:
        return -h
    return h


@wp.func
def compatible(h: wp.vec3, wo: wp.vec3, wi: wp.vec3, reflection: bool) -> bool:
    """``wo`` and ``wi`` are on the sides of microfacet ``h`` that a reflection (or a refraction)
    needs, ``h`` taken on ``wo``'s side of the surface."""
    m = h
    if wo[2] < 0.0:
        m = -h
    if reflection:
        return wp.dot(wo, m) > 0.0 and wp.dot(wi, m) > 0.0
    return wp.dot(wo, m) > 0.0 and wp.dot(wi, m) < 0.0


@wp.func
def lobe_probabilities(p: PrincipledParameters, f_dielectric: float, front: bool) -> wp.vec4:
    """The probabilities (diffuse, clearcoat, transmission, main reflection) with which ``sample``
    chooses a lobe, the dielectric's ``f_dielectric`` at the microfacet splitting the main lobe."""
    btdf = (1.0 - p.metallic) * p.spec_trans
    if not front:
        if p.transmits:
            return wp.vec4(0.0, 0.0, 1.0 - f_dielectric, f_dielectric)
        return wp.vec4(0.0, 0.0, 0.0, 1.0)
    diffuse = (1.0 - p.metallic) * (1.0 - p.spec_trans) * p.rates[0]
    clearcoat = 0.25 * p.clearcoat * p.rates[2]
    transmission = p.rates[1] * btdf * (1.0 - f_dielectric)
    reflection = p.rates[1] * (1.0 - btdf * (1.0 - f_dielectric))
    return wp.vec4(diffuse, clearcoat, transmission, reflection) / (diffuse + clearcoat + transmission + reflection)


@wp.func
def burley_diffuse(p: PrincipledParameters, cos_o: float, cos_i: float, cos_d: float) -> float:
    """Burley's diffuse and retro-reflection factor (times ``albedo / pi`` it is the lobe), blended
    toward Hanrahan-Krueger's fake subsurface by ``flatness``; ``cos_d = wi.h``."""
    fo = schlick_weight(wp.abs(cos_i))
    fi = schlick_weight(wp.abs(cos_o))
    rr = 2.0 * p.roughness * cos_d * cos_d
    lobe = (1.0 - 0.5 * fi) * (1.0 - 0.5 * fo) + rr * (fo + fi + fo * fi * (rr - 1.0))
    if p.flatness > 0.0:
        fss90 = 0.5 * rr
        fss = (1.0 + (fss90 - 1.0) * fo) * (1.0 + (fss90 - 1.0) * fi)
        subsurface = 1.25 * (fss * (1.0 / (wp.abs(cos_i) + wp.abs(cos_o)) - 0.5) + 0.5)
        lobe = lobe + (subsurface - lobe) * p.flatness
    return lobe


@wp.func
def sheen_color(p: PrincipledParameters, cos_d: float) -> wp.vec3:
    """The sheen, ``sheen F_schlick(cos_d) lerp(1, albedo / luminance, sheen_tint)`` (no ``1 / pi``)."""
    tinted = wp.vec3(1.0) + (tint(p.albedo) - wp.vec3(1.0)) * p.sheen_tint
    return tinted * (p.sheen * schlick_weight(wp.abs(cos_d)))


@wp.func
def principled_eval(p: PrincipledParameters, wo: wp.vec3, wi: wp.vec3) -> wp.vec3:
    """f (1/sr) in the local frame (``z`` the shading normal of the surface's front; ``wo.z < 0``:
    the back side)."""
    cos_o = wo[2]
    cos_i = wi[2]
    if cos_o == 0.0 or cos_i == 0.0:
        return wp.vec3(0.0)
    front = cos_o > 0.0
    reflect = cos_o * cos_i > 0.0
    brdf = (1.0 - p.metallic) * (1.0 - p.spec_trans)
    btdf = (1.0 - p.metallic) * p.spec_trans
    eta_path = wp.where(front, p.eta, 1.0 / p.eta)
    h = half_vector(wo, wi, eta_path)
    cos_oh = wp.dot(wo, h)
    cos_ih = wp.dot(wi, h)
    f_dielectric = dielectric_fresnel(cos_oh, p.eta)
    d = ggx_d(h, p.alpha)
    if d * h[2] <= 1e-20:
        d = 0.0
    g = masking(wo, h, p.alpha) * masking(wi, h, p.alpha)
    f = wp.vec3(0.0)
    if reflect:
        if compatible(h, wo, wi, True):
            if f_dielectric > 0.0:
                fresnel = principled_fresnel(p, f_dielectric, cos_oh, front)
                f += fresnel * (d * g / (4.0 * wp.abs(cos_o) * wp.abs(cos_i)))
            if front and p.clearcoat > 0.0:
                f_cc = schlick(wp.vec3(0.04), cos_oh, p.eta)[0]
                d_cc = gtr1_d(h, clearcoat_alpha(p))
                g_cc = clearcoat_masking(wo, h) * clearcoat_masking(wi, h)
                f += wp.vec3(0.25 * p.clearcoat * f_cc * d_cc * g_cc)
        if front and brdf > 0.0:
            cos_d = wp.dot(h, wi)
            f += p.albedo * (brdf * burley_diffuse(p, cos_o, cos_i, cos_d) / wp.pi)
            if p.sheen > 0.0 and p.metallic < 1.0:
                f += sheen_color(p, cos_d) * (1.0 - p.metallic)
    elif btdf > 0.0 and f_dielectric < 1.0 and compatible(h, wo, wi, False):
        denom = cos_oh + eta_path * cos_ih
        t = (1.0 - f_dielectric) * d * g * cos_oh * cos_ih / (cos_o * denom * denom)
        sqrt_albedo = wp.vec3(wp.sqrt(p.albedo[0]), wp.sqrt(p.albedo[1]), wp.sqrt(p.albedo[2]))
        f += sqrt_albedo * (btdf * wp.abs(t) / wp.abs(cos_i))
    return f


@wp.func
def principled_pdf(p: PrincipledParameters, wo: wp.vec3, wi: wp.vec3) -> float:
    """The density (1/sr) with which ``principled_sample`` draws ``wi``, local frame."""
    cos_o = wo[2]
    cos_i = wi[2]
    if cos_o == 0.0 or cos_i == 0.0:
        return 0.0
    front = cos_o > 0.0
    reflect = cos_o * cos_i > 0.0
    eta_path = wp.where(front, p.eta, 1.0 / p.eta)
    h = half_vector(wo, wi, eta_path)
    cos_oh = wp.dot(wo, h)
    cos_ih = wp.dot(wi, h)
    chance = lobe_probabilities(p, dielectric_fresnel(cos_oh, p.eta), front)
    jacobian = 1.0 / (4.0 * cos_ih)
    if not reflect:
        denom = cos_oh + eta_path * cos_ih
        jacobian = eta_path * eta_path * cos_ih / (denom * denom)
    jacobian = wp.abs(jacobian)
    wo_up = wp.where(front, wo, -wo)
    pdf = float(0.0)
    if reflect:
        pdf = chance[0] * wp.abs(cos_i) / wp.pi
        if compatible(h, wo, wi, True):
            pdf += chance[3] * visible_pdf(wo_up, h, p.alpha) * jacobian
            if chance[1] > 0.0:
                pdf += chance[1] * gtr1_d(h, clearcoat_alpha(p)) * h[2] * jacobian
    elif compatible(h, wo, wi, False):
        pdf = chance[2] * visible_pdf(wo_up, h, p.alpha) * jacobian
    return pdf


@wp.func
def principled_sample(p: PrincipledParameters, wo: wp.vec3, uc: float, u: wp.vec2) -> BSDFSample:
    """A lobe chosen by ``uc`` (``lobe_probabilities``), a direction from it by ``u``, local frame."""
    s = lost_sample()
    cos_o = wo[2]
    if cos_o == 0.0:
        return s
    front = cos_o > 0.0
    if not front and p.spec_trans * (1.0 - p.metallic) <= 0.0:
        return s
    wo_up = wp.where(front, wo, -wo)
    h = ggx_sample_visible_normal(wo_up, p.alpha, u[0], u[1])
    cos_oh = wp.dot(wo, h)
    chance = lobe_probabilities(p, dielectric_fresnel(cos_oh, p.eta), front)
    reflection = True
    if uc < chance[0]:
        s.wi = cosine_hemisphere(u[0], u[1])
        s.flags = BSDF_REFLECTION | BSDF_DIFFUSE
    elif uc < chance[0] + chance[1]:
        h = gtr1_sample(clearcoat_alpha(p), u)
        s.wi = 2.0 * wp.dot(wo, h) * h - wo
        s.flags = BSDF_REFLECTION | BSDF_GLOSSY
    elif uc < chance[0] + chance[1] + chance[2]:
        eta_ti = wp.where(cos_oh >= 0.0, 1.0 / p.eta, p.eta)
        cos_t2 = 1.0 - eta_ti * eta_ti * (1.0 - cos_oh * cos_oh)
        cos_t = -wp.sign(cos_oh) * wp.sqrt(wp.max(0.0, cos_t2))
        s.wi = h * (cos_oh * eta_ti + cos_t) - wo * eta_ti
        s.flags = BSDF_TRANSMISSION | BSDF_GLOSSY
        reflection = False
    else:
        s.wi = 2.0 * cos_oh * h - wo
        s.flags = BSDF_REFLECTION | BSDF_GLOSSY
    if reflection != (cos_o * s.wi[2] > 0.0):
        return lost_sample()
    if (s.flags & BSDF_DIFFUSE) == 0 and not compatible(h, wo, s.wi, reflection):
        return lost_sample()
    s.pdf = principled_pdf(p, wo, s.wi)
    if s.pdf > 0.0:
        s.weight = principled_eval(p, wo, s.wi) * (wp.abs(s.wi[2]) / s.pdf)
    else:
        s.flags = 0
    return s


@wp.func
def thin_half_vector(wo: wp.vec3, wi: wp.vec3) -> wp.vec3:
    """A thin sheet's microfacet normal: the half vector of ``wo`` (``z > 0``) and ``wi`` mirrored
    to ``wo``'s side (its transmission is a reflection turned over, with no bending)."""
    return wp.normalize(wo + wp.vec3(wi[0], wi[1], wp.abs(wi[2])))


@wp.func
def thin_probabilities(p: PrincipledParameters) -> wp.vec4:
    """The probabilities (specular reflection, specular transmission, diffuse reflection, diffuse
    transmission) with which a thin one's ``sample`` chooses a lobe."""
    chance = wp.vec4(
        0.5 * p.spec_trans * p.rates[0],
        0.5 * p.spec_trans * p.rates[1],
        (1.0 - p.spec_trans) * (1.0 - p.diff_trans) * p.rates[2],
        (1.0 - p.spec_trans) * p.diff_trans * p.rates[3],
    )
    return chance / (chance[0] + chance[1] + chance[2] + chance[3])


@wp.func
def thin_eval(p: PrincipledParameters, wo: wp.vec3, wi: wp.vec3) -> wp.vec3:
    """f (1/sr) of Mitsuba's ``principledthin`` in the local frame, the same from either side: its
    specular reflection and transmission (``spec_trans`` times the thin Fresnel term's share, and
    ``albedo (1 - F)`` through microfacets of the scaled roughness), Burley's diffuse and the sheen
    (``(1 - spec_trans)(1 - diff_trans)``), and a Lambertian transmission (``(1 - spec_trans)
    diff_trans``)."""
    if wo[2] == 0.0 or wi[2] == 0.0:
        return wp.vec3(0.0)
    if wo[2] < 0.0:  # seen from the back: the same sheet, turned over
        wo = -wo
        wi = -wi
    cos_o = wo[2]
    cos_i = wi[2]
    h = thin_half_vector(wo, wi)
    f = wp.vec3(0.0)
    if p.spec_trans > 0.0:
        f_dielectric = dielectric_fresnel(wp.dot(wo, h), p.eta)
        if cos_i > 0.0 and compatible(h, wo, wi, True):
            tinted = tinted_schlick(p, p.eta, wp.dot(wo, h))
            fresnel = wp.vec3(f_dielectric) + (tinted - wp.vec3(f_dielectric)) * p.spec_tint
            g = masking(wo, h, p.alpha) * masking(wi, h, p.alpha)
            f += fresnel * (p.spec_trans * ggx_d(h, p.alpha) * g / (4.0 * cos_o * cos_i))
        if cos_i < 0.0 and compatible(h, wo, wi, False):
            a = p.alpha_transmitted
            g = masking(wo, h, a) * masking(wi, h, a)
            f += p.albedo * (p.spec_trans * (1.0 - f_dielectric) * ggx_d(h, a) * g / (4.0 * cos_o * -cos_i))
    if p.spec_trans < 1.0:
        if cos_i > 0.0 and p.diff_trans < 1.0:
            cos_d = wp.dot(h, wi)
            weight = (1.0 - p.spec_trans) * (1.0 - p.diff_trans)
            f += p.albedo * (weight * burley_diffuse(p, cos_o, cos_i, cos_d) / wp.pi)
            if p.sheen > 0.0:
                f += sheen_color(p, cos_d) * weight
        if cos_i < 0.0 and p.diff_trans > 0.0:
            f += p.albedo * ((1.0 - p.spec_trans) * p.diff_trans / wp.pi)
    return f


@wp.func
def thin_pdf(p: PrincipledParameters, wo: wp.vec3, wi: wp.vec3) -> float:
    """The density (1/sr) with which ``thin_sample`` draws ``wi``, local frame."""
    if wo[2] == 0.0 or wi[2] == 0.0:
        return 0.0
    if wo[2] < 0.0:
        wo = -wo
        wi = -wi
    chance = thin_probabilities(p)
    h = thin_half_vector(wo, wi)
    jacobian = wp.abs(1.0 / (4.0 * wp.dot(wp.vec3(wi[0], wi[1], wp.abs(wi[2])), h)))
    if wi[2] > 0.0:
        pdf = chance[2] * wi[2] / wp.pi
        if chance[0] > 0.0 and compatible(h, wo, wi, True):
            pdf += chance[0] * visible_pdf(wo, h, p.alpha) * jacobian
        return pdf
    pdf = chance[3] * -wi[2] / wp.pi
    if chance[1] > 0.0 and compatible(h, wo, wi, False):
        pdf += chance[1] * visible_pdf(wo, h, p.alpha_transmitted) * jacobian
    return pdf


@wp.func
def thin_sample(p: PrincipledParameters, wo: wp.vec3, uc: float, u: wp.vec2) -> BSDFSample:
    """A lobe chosen by ``uc`` (``thin_probabilities``), a direction from it by ``u``, local frame:
    a transmission is the reflection about a visible normal turned over, or a cosine-weighted
    direction below."""
    s = lost_sample()
    if wo[2] == 0.0:
        return s
    side = wp.where(wo[2] > 0.0, 1.0, -1.0)
    wo_up = wo * side
    chance = thin_probabilities(p)
    if uc < chance[0] + chance[1]:
        reflection = uc < chance[0]
        alpha = wp.where(reflection, p.alpha, p.alpha_transmitted)
        h = ggx_sample_visible_normal(wo_up, alpha, u[0], u[1])
        wi = 2.0 * wp.dot(wo_up, h) * h - wo_up
        s.flags = BSDF_REFLECTION | BSDF_GLOSSY
        if not reflection:
            wi = wp.vec3(wi[0], wi[1], -wi[2])
            s.flags = BSDF_TRANSMISSION | BSDF_GLOSSY
        if reflection != (wi[2] > 0.0) or not compatible(h, wo_up, wi, reflection):
            return lost_sample()
    else:
        wi = cosine_hemisphere(u[0], u[1])
        s.flags = BSDF_REFLECTION | BSDF_DIFFUSE
        if uc >= chance[0] + chance[1] + chance[2]:
            wi = -wi
            s.flags = BSDF_TRANSMISSION | BSDF_DIFFUSE
    s.wi = wi * side
    s.pdf = thin_pdf(p, wo, s.wi)
    if s.pdf > 0.0:
        s.weight = thin_eval(p, wo, s.wi) * (wp.abs(s.wi[2]) / s.pdf)
    else:
        s.flags = 0
    return s


def make(at) -> Functions:
    from .data import MaterialData  # noqa: PLC0415 (MaterialData holds PrincipledData: an import cycle)

    @wp.func
    def owns(material_type: wp.int32) -> bool:
        return material_type == PRINCIPLED or material_type == PRINCIPLED_THIN

    @wp.func
    def number(materials: MaterialData, m: wp.int32, slot: wp.int32, ctx: TextureEvalContext, constant: float) -> float:
        if wp.static(at.textures):
            return material_float(materials.textures, m, slot, ctx, constant)
        return constant

    @wp.func
    def parameters_at(materials: MaterialData, m: wp.int32, ctx: TextureEvalContext) -> PrincipledParameters:
        """Material ``m``'s parameters at ``ctx``, and its alphas (Mitsuba's ``calc_dist_params``)."""
        table = materials.principled
        p = PrincipledParameters()
        p.albedo = at.rgb(materials, m, ALBEDO, ctx, materials.albedo[m])
        p.roughness = number(materials, m, ROUGHNESS, ctx, materials.roughness[m])
        p.metallic = number(materials, m, METALLIC, ctx, table.metallic[m])
        p.spec_trans = number(materials, m, SPEC_TRANS, ctx, table.spec_trans[m])
        p.spec_tint = number(materials, m, SPEC_TINT, ctx, table.spec_tint[m])
        p.sheen = number(materials, m, SHEEN, ctx, table.sheen[m])
        p.sheen_tint = number(materials, m, SHEEN_TINT, ctx, table.sheen_tint[m])
        p.flatness = number(materials, m, FLATNESS, ctx, table.flatness[m])
        p.clearcoat = number(materials, m, CLEARCOAT, ctx, table.clearcoat[m])
        p.clearcoat_gloss = number(materials, m, CLEARCOAT_GLOSS, ctx, table.clearcoat_gloss[m])
        p.eta = materials.ior[m]
        p.rates = table.rates[m]
        p.diff_trans = 0.5 * number(materials, m, DIFF_TRANS, ctx, table.diff_trans[m])
        p.transmits = (materials.flags[m] & BSDF_TRANSMISSION) != 0
        aspect = wp.sqrt(1.0 - 0.9 * number(materials, m, ANISOTROPY, ctx, table.anisotropy[m]))
        p.alpha = alphas(p.roughness, aspect)
        p.alpha_transmitted = alphas((0.65 * p.eta - 0.35) * p.roughness, aspect)
        return p

    @wp.func
    def alphas(roughness: float, aspect: float) -> wp.vec2:
        """The GGX alphas of Burley's ``roughness`` (Mitsuba's ``calc_dist_params``)."""
        r2 = roughness * roughness
        return wp.vec2(wp.max(0.001, r2 / aspect), wp.max(0.001, r2 * aspect))

    @wp.func
    def local_frame(n: wp.vec3, front: bool, tangent: wp.vec3) -> wp.mat33:
        """World to the shading frame of the surface's front (``n`` faces ``wo``)."""
        return wp.transpose(shading_frame(wp.where(front, n, -n), tangent))

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
        to_local = local_frame(n, front, tangent)
        p = parameters_at(materials, m, ctx)
        if materials.type[m] == PRINCIPLED_THIN:
            return thin_eval(p, to_local * wo, to_local * wi)
        return principled_eval(p, to_local * wo, to_local * wi)

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
        to_local = local_frame(n, front, tangent)
        p = parameters_at(materials, m, ctx)
        if materials.type[m] == PRINCIPLED_THIN:
            return thin_pdf(p, to_local * wo, to_local * wi)
        return principled_pdf(p, to_local * wo, to_local * wi)

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
        to_local = local_frame(n, front, tangent)
        p = parameters_at(materials, m, ctx)
        s = lost_sample()
        if materials.type[m] == PRINCIPLED_THIN:
            s = thin_sample(p, to_local * wo, uc, u)
        else:
            s = principled_sample(p, to_local * wo, uc, u)
        s.wi = wp.transpose(to_local) * s.wi
        return s

    return Functions(owns, eval, pdf, sample)


def transmits(material) -> bool:
    """It has a transmission lobe (Mitsuba's flags): its ``spec_trans`` (or a thin one's
    ``diff_trans``) is textured or not 0."""
    keys = ("spec_trans", "diff_trans") if material.type == "principled_thin" else ("spec_trans",)
    return any(getattr(material, key) != 0.0 for key in keys) or any(key in keys for key, _ in material.textures)


def lobes(material) -> int:
    """Diffuse and glossy reflection, and transmission where it ``transmits``."""
    return BSDF_REFLECTION | BSDF_DIFFUSE | BSDF_GLOSSY | (BSDF_TRANSMISSION if transmits(material) else 0)


def bake(materials: list, exterior_ior: float) -> dict[str, np.ndarray]:
    """``PrincipledData``'s columns for ``materials`` (``wrt.scene.Material``s, all families; 0 for
    the others')."""
    ours = [material if material.type in ("principled", "principled_thin") else None for material in materials]
    columns = {
        key: np.array([getattr(m, key) if m else 0.0 for m in ours], dtype=np.float64)
        for key in (*NUMBERS, "anisotropy", "diff_trans")
    }
    rates = [
        [getattr(m, r) for r in (THIN_RATES if m.type == "principled_thin" else (*RATES, "clearcoat_sampling_rate"))]
        if m
        else [1.0] * 4
        for m in ours
    ]
    columns["rates"] = np.array(rates, dtype=np.float64)
    return columns


FAMILY = Family(
    name="principled",
    types=(
        MaterialType(
            "principled",
            PRINCIPLED,
            ("albedo", "roughness", "anisotropy", *NUMBERS, "ior", *RATES),
            BSDF_REFLECTION | BSDF_DIFFUSE | BSDF_GLOSSY,
        ),
        MaterialType(
            "principled_thin",
            PRINCIPLED_THIN,
            (*THIN_KEYS, "diff_trans", "ior", *THIN_RATES),
            BSDF_REFLECTION | BSDF_DIFFUSE | BSDF_GLOSSY,
        ),
    ),
    make=make,
    feature="principled",
    whitted=False,
    lobes=lobes,
    mitsuba=("principled", "principledthin"),
    data=PrincipledData,
    bake=bake,
)
