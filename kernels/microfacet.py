"""Microfacet reflection (a rough conductor) and refraction (a rough dielectric), GGX or Beckmann,
in a local shading frame.

Local frame: the normal is +z, x the shading frame's tangent ``s`` and y its bitangent ``t``
(``wrt.kernels.sample_warps.shading_frame``); ``wo`` and ``wi`` are unit vectors pointing away from
the surface. ``alpha = (a_u, a_v)`` is the roughness along x and y (the scene's ``roughness`` and
``roughness_v``; isotropic where they are equal, and then every function is its isotropic form bit
for bit: the ratios ``a_u / a_v`` it scales by are exactly 1), ``distribution`` the normal distribution's
code (``GGX`` or ``BECKMANN``, ``DISTRIBUTIONS`` by the scene's names). The BRDF here has no Fresnel
factor: ``wrt.kernels.materials`` multiplies it by glossy's constant ``reflectance`` (1: a lossless
rough mirror up to the energy lost to single scattering) or by a conductor's exact Fresnel
reflectance at the angle between ``wo`` and the microfacet normal (the half vector).
Masking-shadowing is separable Smith: ``G = G1(wo) G1(wi)``; Beckmann's G1 is Walter et al.'s
rational fit (eq. 27, under 0.35% from the erf form), as Mitsuba 3's, and its visible normals are
drawn by Jakob's numerical inversion, as Mitsuba 3's ``sample_visible_11``: ``eval`` and ``pdf`` are
Mitsuba's to float precision, and the sampled density is ``pdf``'s up to the fit's error.
A rough dielectric (``dielectric_eval`` / ``dielectric_pdf``) has the exact Fresnel reflectance at
the microfacet normal in it: ``F`` reflected, ``1 - F`` refracted (Walter et al., eq. 20-21,
radiance transport as ``wrt.kernels.materials.dielectric``); ``wi`` may lie below the surface there
(``wi.z < 0``: transmission), and ``eta = n1 / n2`` is the ratio of the indices of refraction on
``wo``'s side and across the surface.

``microfacet(beckmann)`` gives these functions for a scene (``Microfacet``): with ``beckmann``
False only GGX is compiled in and ``distribution`` is not read. ``visible_normals`` and
``smith_g1`` are numpy twins of the sampling and the masking (float64, with erf and its inverse
to about 1e-7, as float32 Mitsuba has them), for tables the host bakes
(``wrt.kernels.materials.plastic``) and for tests.

References
----------
B. Walter, S. Marschner, H. Li, K. Torrance, "Microfacet Models for Refraction through Rough
Surfaces", EGSR 2007 (GGX and Beckmann D, Smith G1).
E. Heitz, "Sampling the GGX Distribution of Visible Normals", JCGT 7(4), 2018.
W. Jakob, "An Improved Visible Normal Sampling Routine for the Beckmann Distribution", 2014.
W. Jakob et al., Mitsuba 3, ``include/mitsuba/render/microfacet.h``.
"""

import functools
from typing import NamedTuple

import numpy as np
import warp as wp

from .optics import fresnel_dielectric

GGX = wp.constant(0)
BECKMANN = wp.constant(1)
DISTRIBUTIONS = {"ggx": 0, "beckmann": 1}
"""The codes of the scene's ``distribution`` names."""

INV_SQRT_PI = 0.5641895835477563
UNIT_CLAMP = 1e-6  # Jakob's inversion keeps its samples and its erf-domain iterate this far inside (0, 1), (-1, 1)


@wp.func
def tangential(w: wp.vec3, alpha: wp.vec2) -> float:
    """``a_u a_v (w_x^2 / a_u^2 + w_y^2 / a_v^2)`` (the slope term of D), ``w_x^2 + w_y^2`` bit
    for bit where ``a_u == a_v``."""
    return w[0] * w[0] * (alpha[1] / alpha[0]) + w[1] * w[1] * (alpha[0] / alpha[1])


@wp.func
def ggx_d(h: wp.vec3, alpha: wp.vec2) -> float:
    """GGX normal distribution D(h) (1/sr), normalised so that the integral of D cos(theta_h) is 1.

    The tan^2 form ``1 / (pi a_u a_v cos^4 (1 + (h_x^2 / a_u^2 + h_y^2 / a_v^2) / cos^2)^2)``, the
    tangential term from the components (the textbook ``cos^2 (alpha^2 - 1) + 1`` cancels in
    float32 near the normal: 3% off at alpha 1e-3) and written over ``a_u a_v`` with the ratios
    ``a_v / a_u`` and ``a_u / a_v``, which are exactly 1 where ``a_u == a_v``."""
    cos2 = h[2] * h[2]
    if cos2 <= 0.0:
        return 0.0
    a2 = alpha[0] * alpha[1]
    e = 1.0 + tangential(h, alpha) / (cos2 * a2)
    return 1.0 / (wp.pi * a2 * cos2 * cos2 * e * e)


@wp.func
def stretched(w: wp.vec3, alpha: wp.vec2) -> float:
    """``(a_u^2 w_x^2 + a_v^2 w_y^2) / (a_u a_v)``, the masking's slope term over ``a_u a_v``:
    ``w_x^2 + w_y^2`` bit for bit where ``a_u == a_v``."""
    return w[0] * w[0] * (alpha[0] / alpha[1]) + w[1] * w[1] * (alpha[1] / alpha[0])


@wp.func
def ggx_g1(w: wp.vec3, alpha: wp.vec2) -> float:
    """Smith masking of direction ``w`` for GGX, ``2 / (1 + sqrt(1 + alpha_w^2 tan^2))``, alpha_w
    the roughness along ``w``'s azimuth."""
    cos2 = w[2] * w[2]
    if cos2 <= 0.0:
        return 0.0
    tan2 = stretched(w, alpha) / cos2  # from the tangential components: no cancellation
    return 2.0 / (1.0 + wp.sqrt(1.0 + alpha[0] * alpha[1] * tan2))


@wp.func
def ggx_sample_visible_normal(wo: wp.vec3, alpha: wp.vec2, u1: float, u2: float) -> wp.vec3:
    """A microfacet normal drawn with density ``G1(wo) max(0, wo.h) D(h) / wo.z`` (Heitz 2018)."""
    # stretch to the hemisphere configuration
    vh = wp.normalize(wp.vec3(alpha[0] * wo[0], alpha[1] * wo[1], wo[2]))
    lensq = vh[0] * vh[0] + vh[1] * vh[1]
    t1 = wp.vec3(1.0, 0.0, 0.0)
    if lensq > 0.0:
        t1 = wp.vec3(-vh[1], vh[0], 0.0) / wp.sqrt(lensq)
    t2 = wp.cross(vh, t1)
    r = wp.sqrt(u1)
    phi = 2.0 * wp.pi * u2
    p1 = r * wp.cos(phi)
    p2 = r * wp.sin(phi)
    s = 0.5 * (1.0 + vh[2])
    p2 = (1.0 - s) * wp.sqrt(wp.max(0.0, 1.0 - p1 * p1)) + s * p2
    nh = p1 * t1 + p2 * t2 + wp.sqrt(wp.max(0.0, 1.0 - p1 * p1 - p2 * p2)) * vh
    return wp.normalize(wp.vec3(alpha[0] * nh[0], alpha[1] * nh[1], wp.max(1e-7, nh[2])))


@wp.func
def beckmann_d(h: wp.vec3, alpha: wp.vec2) -> float:
    """Beckmann normal distribution D(h) (1/sr), ``exp(-(h_x^2 / a_u^2 + h_y^2 / a_v^2) / cos^2) /
    (pi a_u a_v cos^4)`` (the tangential term as ``ggx_d``'s); 0 where ``D cos`` falls below 1e-20
    (Mitsuba's cut)."""
    cos2 = h[2] * h[2]
    if cos2 <= 0.0:
        return 0.0
    a2 = alpha[0] * alpha[1]
    d = wp.exp(-tangential(h, alpha) / (cos2 * a2)) / (wp.pi * a2 * cos2 * cos2)
    if d * wp.abs(h[2]) <= 1e-20:
        return 0.0
    return d


@wp.func
def beckmann_g1(w: wp.vec3, alpha: wp.vec2) -> float:
    """Smith masking of direction ``w`` for Beckmann, Walter et al.'s rational fit in ``a = 1 /
    (alpha tan theta)`` (1 from ``a = 1.6`` on and at normal incidence), ``alpha`` the roughness
    along ``w``'s azimuth."""
    cos2 = w[2] * w[2]
    if cos2 <= 0.0:
        return 0.0
    xy = alpha[0] * alpha[1] * stretched(w, alpha)
    if xy <= 0.0:
        return 1.0
    a = wp.sqrt(cos2 / xy)
    if a >= 1.6:
        return 1.0
    a2 = a * a
    return (3.535 * a + 2.181 * a2) / (1.0 + 2.276 * a + 2.577 * a2)


@wp.func
def beckmann_sample_visible_normal(wo: wp.vec3, alpha: wp.vec2, u1: float, u2: float) -> wp.vec3:
    """A microfacet normal drawn with density ``G1(wo) max(0, wo.h) D(h) / wo.z`` (the exact G1),
    by Jakob's inversion of the slope distribution of the stretched configuration (alpha 1):
    three Newton steps in the erf domain for the slope along ``wo``, an inverse erf across it,
    then rotated to ``wo``'s azimuth and scaled by ``alpha`` (``a_u`` along x, ``a_v`` along y)."""
    v = wp.normalize(wp.vec3(alpha[0] * wo[0], alpha[1] * wo[1], wo[2]))
    sin2 = v[0] * v[0] + v[1] * v[1]
    cos_phi = float(1.0)
    sin_phi = float(0.0)
    if sin2 > 4.0 * 1.1920929e-7:
        inv = 1.0 / wp.sqrt(sin2)
        cos_phi = wp.clamp(v[0] * inv, -1.0, 1.0)
        sin_phi = wp.clamp(v[1] * inv, -1.0, 1.0)
    cos_theta = v[2]
    tan_theta = wp.sqrt(wp.max(0.0, 1.0 - cos_theta * cos_theta)) / cos_theta
    cot_theta = 1.0 / tan_theta
    s1 = wp.clamp(u1, UNIT_CLAMP, 1.0 - UNIT_CLAMP)
    s2 = wp.clamp(u2, UNIT_CLAMP, 1.0 - UNIT_CLAMP)
    maxval = wp.erf(cot_theta)
    x = maxval - (maxval + 1.0) * wp.erf(wp.sqrt(-wp.log(s1)))  # the exact solution at grazing incidence
    tail = float(0.0)
    if tan_theta > 0.0:
        tail = INV_SQRT_PI * tan_theta * wp.exp(-cot_theta * cot_theta)
    s1 *= 1.0 + maxval + tail  # the CDF's normalisation
    for _ in range(3):
        slope = wp.erfinv(x)
        value = 1.0 + x + INV_SQRT_PI * tan_theta * wp.exp(-slope * slope) - s1
        x = wp.clamp(x - value / (1.0 - slope * tan_theta), -1.0 + UNIT_CLAMP, 1.0 - UNIT_CLAMP)
    slope_x = wp.erfinv(x)
    slope_y = wp.erfinv(2.0 * s2 - 1.0)
    sx = (cos_phi * slope_x - sin_phi * slope_y) * alpha[0]
    sy = (sin_phi * slope_x + cos_phi * slope_y) * alpha[1]
    return wp.normalize(wp.vec3(-sx, -sy, 1.0))


@wp.func
def dielectric_half(wo: wp.vec3, wi: wp.vec3, eta: float) -> wp.vec3:
    """The microfacet normal (``z >= 0``) that turns ``wo`` into ``wi``: the half vector of a
    reflection (``wi.z > 0``), else Walter's generalised half vector ``-(n1 wo + n2 wi)`` of a
    refraction."""
    h = wo + wi
    if wi[2] < 0.0:
        h = eta * wo + wi
    h = wp.normalize(h)
    if h[2] < 0.0:
        h = -h
    return h


class Microfacet(NamedTuple):
    """A scene's microfacet functions (``microfacet``), each taking ``alpha`` and ``distribution``:

    - ``d(h, alpha, distribution)``, ``g1(w, alpha, distribution)``;
    - ``sample_visible_normal(wo, alpha, distribution, u1, u2)``: a normal of density ``G1(wo)
      max(0, wo.h) D(h) / wo.z``;
    - ``eval(wo, wi, alpha, distribution)``: the BRDF without its Fresnel factor, ``D(h) G1(wo)
      G1(wi) / (4 wo.z wi.z)`` (1/sr); ``pdf(...)``: the density of ``wi`` reflected about a
      visible normal, ``G1(wo) D(h) / (4 wo.z)``;
    - ``dielectric_eval(wo, wi, alpha, distribution, eta)``: f (1/sr) of a rough dielectric
      interface (``wo.z > 0``): ``F D G / (4 wo.z wi.z)`` reflected, ``(1 - F) D G |wo.h| |wi.h| /
      (wo.z |wi.z| (wo.h + wi.h / eta)^2)`` transmitted (radiance: it integrates to ``eta^2 (1 - F)``
      on a smooth surface); 0 where ``h`` is seen from the wrong side, and at ``eta == 1``
      (index-matched: the interface is a straight pass);
    - ``dielectric_pdf(...)``: the density of ``wi`` when a visible normal ``h`` is drawn for ``wo``
      and ``wo`` reflected with probability F (at ``wo.h``) or refracted otherwise: ``G1(wo) D(h)
      (wo.h) / wo.z`` times F / (4 wi.h) or (1 - F) |wi.h| / (eta^2 (wo.h + wi.h / eta)^2).
    """

    d: wp.Function
    g1: wp.Function
    sample_visible_normal: wp.Function
    eval: wp.Function
    pdf: wp.Function
    dielectric_eval: wp.Function
    dielectric_pdf: wp.Function


@functools.cache
def microfacet(beckmann: bool) -> Microfacet:
    """The microfacet functions, with Beckmann compiled in only where ``beckmann``."""

    @wp.func
    def d(h: wp.vec3, alpha: wp.vec2, distribution: wp.int32) -> float:
        if wp.static(beckmann):
            if distribution == BECKMANN:
                return beckmann_d(h, alpha)
        return ggx_d(h, alpha)

    @wp.func
    def g1(w: wp.vec3, alpha: wp.vec2, distribution: wp.int32) -> float:
        if wp.static(beckmann):
            if distribution == BECKMANN:
                return beckmann_g1(w, alpha)
        return ggx_g1(w, alpha)

    @wp.func
    def sample_visible_normal(wo: wp.vec3, alpha: wp.vec2, distribution: wp.int32, u1: float, u2: float) -> wp.vec3:
        if wp.static(beckmann):
            if distribution == BECKMANN:
                return beckmann_sample_visible_normal(wo, alpha, u1, u2)
        return ggx_sample_visible_normal(wo, alpha, u1, u2)

    @wp.func
    def eval(wo: wp.vec3, wi: wp.vec3, alpha: wp.vec2, distribution: wp.int32) -> float:
        if wo[2] <= 0.0 or wi[2] <= 0.0:
            return 0.0
        h = wp.normalize(wo + wi)
        return (
            d(h, alpha, distribution)
            * g1(wo, alpha, distribution)
            * g1(wi, alpha, distribution)
            / (4.0 * wo[2] * wi[2])
        )

    @wp.func
    def pdf(wo: wp.vec3, wi: wp.vec3, alpha: wp.vec2, distribution: wp.int32) -> float:
        if wo[2] <= 0.0 or wi[2] <= 0.0:
            return 0.0
        h = wp.normalize(wo + wi)
        return g1(wo, alpha, distribution) * d(h, alpha, distribution) / (4.0 * wo[2])

    @wp.func
    def dielectric_eval(wo: wp.vec3, wi: wp.vec3, alpha: wp.vec2, distribution: wp.int32, eta: float) -> float:
        if eta == 1.0 or wi[2] == 0.0:
            return 0.0
        h = dielectric_half(wo, wi, eta)
        cos_o = wp.dot(wo, h)
        cos_i = wp.dot(wi, h)
        if cos_o <= 0.0 or cos_i * wi[2] <= 0.0:
            return 0.0
        dg = d(h, alpha, distribution) * g1(wo, alpha, distribution) * g1(wi, alpha, distribution)
        fresnel = fresnel_dielectric(cos_o, eta)
        if wi[2] > 0.0:
            return fresnel * dg / (4.0 * wo[2] * wi[2])
        denom = cos_o + cos_i / eta
        return (1.0 - fresnel) * dg * cos_o * wp.abs(cos_i) / (wo[2] * wp.abs(wi[2]) * denom * denom)

    @wp.func
    def dielectric_pdf(wo: wp.vec3, wi: wp.vec3, alpha: wp.vec2, distribution: wp.int32, eta: float) -> float:
        if eta == 1.0 or wi[2] == 0.0:
            return 0.0
        h = dielectric_half(wo, wi, eta)
        cos_o = wp.dot(wo, h)
        cos_i = wp.dot(wi, h)
        if cos_o <= 0.0 or cos_i * wi[2] <= 0.0:
            return 0.0
        visible = g1(wo, alpha, distribution) * d(h, alpha, distribution) * cos_o / wo[2]
        fresnel = fresnel_dielectric(cos_o, eta)
        if wi[2] > 0.0:
            return visible * fresnel / (4.0 * cos_i)
        denom = eta * cos_o + cos_i
        return visible * (1.0 - fresnel) * wp.abs(cos_i) / (denom * denom)

    return Microfacet(d, g1, sample_visible_normal, eval, pdf, dielectric_eval, dielectric_pdf)


# --- float64 twins on the host ---------------------------------------------------------------


def smith_g1(v: np.ndarray, m: np.ndarray, alpha: float, distribution: str = "ggx") -> np.ndarray:
    """Smith masking of directions ``v`` (..., 3) seen through microfacet normals ``m``, as
    Mitsuba's ``smith_g1``: 1 at normal incidence, 0 where ``v`` sees the microfacet's back."""
    xy = alpha * alpha * (v[..., 0] ** 2 + v[..., 1] ** 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        tan2 = xy / v[..., 2] ** 2
        if distribution == "beckmann":
            a = 1.0 / np.sqrt(tan2)
            g = np.where(a >= 1.6, 1.0, (3.535 * a + 2.181 * a * a) / (1.0 + 2.276 * a + 2.577 * a * a))
        else:
            g = 2.0 / (1.0 + np.sqrt(1.0 + tan2))
    g = np.where(xy == 0.0, 1.0, g)
    return np.where(np.sum(v * m, axis=-1) * v[..., 2] <= 0.0, 0.0, g)


def _erf(x: np.ndarray) -> np.ndarray:
    """erf, within 1.5e-7 (Abramowitz and Stegun 7.1.26); 1 at infinity."""
    a = np.abs(x)
    t = 1.0 / (1.0 + 0.3275911 * a)
    poly = t * (0.254829592 + t * (-0.284496736 + t * (1.421413741 + t * (-1.453152027 + t * 1.061405429))))
    return np.sign(x) * (1.0 - poly * np.exp(-a * a))


def _erfinv(x: np.ndarray) -> np.ndarray:
    """The inverse of erf on (-1, 1), within about 1e-7 relative (Giles' single-precision
    approximation, as Dr.Jit's ``erfinv``)."""
    w = -np.log((1.0 - x) * (1.0 + x))
    central, tail = w - 2.5, np.sqrt(np.maximum(w, 5.0)) - 3.0
    p = 2.81022636e-08
    for c in (3.43273939e-07, -3.5233877e-06, -4.39150654e-06, 0.00021858087, -0.00125372503, -0.00417768164):
        p = c + p * central
    p = 1.50140941 + (0.246640727 + p * central) * central
    q = -0.000200214257
    for c in (0.000100950558, 0.00134934322, -0.00367342844, 0.00573950773, -0.0076224613, 0.00943887047):
        q = c + q * tail
    q = 2.83297682 + (1.00167406 + q * tail) * tail
    return np.where(w < 5.0, p, q) * x


def _slopes_11(cos_theta: np.ndarray, u: np.ndarray, distribution: str) -> tuple[np.ndarray, np.ndarray]:
    """Mitsuba's ``sample_visible_11``: slopes (N, M) of the unit-roughness distribution's visible
    normals for incidence cosines ``cos_theta`` (N, 1) and square samples ``u`` (M, 2)."""
    if distribution == "beckmann":
        erf, erfinv = _erf, _erfinv
        s = np.clip(u, UNIT_CLAMP, 1.0 - UNIT_CLAMP)
        sin_theta = np.sqrt(np.maximum(0.0, 1.0 - cos_theta * cos_theta))
        tan_theta = sin_theta / cos_theta
        with np.errstate(divide="ignore", over="ignore"):
            cot_theta = 1.0 / tan_theta
            tail = INV_SQRT_PI * tan_theta * np.exp(-cot_theta * cot_theta)
        maxval = erf(cot_theta)
        x = maxval - (maxval + 1.0) * erf(np.sqrt(-np.log(s[:, 0])))
        target = s[:, 0] * (1.0 + maxval + tail)
        for _ in range(3):
            slope = erfinv(x)
            value = 1.0 + x + INV_SQRT_PI * tan_theta * np.exp(-slope * slope) - target
            x = np.clip(x - value / (1.0 - slope * tan_theta), -1.0 + UNIT_CLAMP, 1.0 - UNIT_CLAMP)
        return erfinv(x), np.broadcast_to(erfinv(2.0 * s[:, 1] - 1.0), x.shape)
    # GGX: the concentric disk, warped to the visible hemisphere of the stretched configuration
    x, y = 2.0 * u[:, 0] - 1.0, 2.0 * u[:, 1] - 1.0
    swap = np.abs(x) < np.abs(y)
    r, rp = np.where(swap, y, x), np.where(swap, x, y)
    with np.errstate(divide="ignore", invalid="ignore"):
        phi = 0.25 * np.pi * rp / r
    phi = np.where(swap, 0.5 * np.pi - phi, phi)
    phi = np.where((x == 0.0) & (y == 0.0), 0.0, phi)
    px, py = r * np.cos(phi), r * np.sin(phi)
    s = 0.5 * (1.0 + cos_theta)
    py = (1.0 - s) * np.sqrt(np.maximum(0.0, 1.0 - px * px)) + s * py
    pz = np.sqrt(np.maximum(0.0, 1.0 - px * px - py * py))
    sin_theta = np.sqrt(np.maximum(0.0, 1.0 - cos_theta * cos_theta))
    norm = 1.0 / (sin_theta * py + cos_theta * pz)
    return (cos_theta * py - sin_theta * pz) * norm, px * norm


def visible_normals(wi: np.ndarray, alpha: float, u: np.ndarray, distribution: str = "ggx") -> np.ndarray:
    """Mitsuba's visible-normal sample (``MicrofacetDistribution::sample``) for directions ``wi``
    (N, 3) and square samples ``u`` (M, 2): microfacet normals (N, M, 3)."""
    stretched = np.stack([alpha * wi[:, 0], alpha * wi[:, 1], wi[:, 2]], axis=-1)
    stretched /= np.linalg.norm(stretched, axis=-1, keepdims=True)
    cos_theta = stretched[:, 2:3]
    sin2 = stretched[:, 0] ** 2 + stretched[:, 1] ** 2
    inv = 1.0 / np.sqrt(np.where(sin2 > 0.0, sin2, 1.0))
    cos_phi = np.where(sin2 <= 4 * np.finfo(np.float32).eps, 1.0, np.clip(stretched[:, 0] * inv, -1, 1))[:, None]
    sin_phi = np.where(sin2 <= 4 * np.finfo(np.float32).eps, 0.0, np.clip(stretched[:, 1] * inv, -1, 1))[:, None]
    slope_x, slope_y = _slopes_11(cos_theta, u, distribution)
    sx = (cos_phi * slope_x - sin_phi * slope_y) * alpha
    sy = (sin_phi * slope_x + cos_phi * slope_y) * alpha
    m = np.stack([-sx, -sy, np.ones_like(sx)], axis=-1)
    return m / np.linalg.norm(m, axis=-1, keepdims=True)
