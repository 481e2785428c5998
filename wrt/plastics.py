"""The host-side constants of the plastics (``plastic``, ``rough_plastic``), computed as Mitsuba 3's
``plastic`` and ``roughplastic`` plugins compute them when they are loaded.

A plastic is a dielectric coating of relative index ``ior`` (the coating's over the scene's
``exterior_ior``: ``eta`` below) over a Lambertian base. Light that enters the coating scatters in
the base and is reflected back by the coating's inside, the fraction ``internal_reflectance``
(``R_i``) each time; ``wrt.kernels.materials.plastic_eval`` sums those bounces. ``R_i`` is the
diffuse Fresnel reflectance of a smooth coating (Egan and Hilgeman's fit, as Mitsuba's
``fresnel_diffuse_reflectance``), and for a rough coating the cosine-weighted mean of its GGX
reflectance from inside; a rough coating's transmittance from outside, as a function of the
incidence cosine, is tabulated at ``COATING_RES`` cosines. Both are the same quadratures as
Mitsuba's ``eval_reflectance`` and ``eval_transmittance`` (Gauss-Legendre over the visible-normal
sample square, 32 x 32 nodes for ``eta > 1``, 128 x 128 otherwise), here in float64.

References
----------
W. Jakob et al., Mitsuba 3: ``src/bsdfs/plastic.cpp``, ``roughplastic.cpp``,
``include/mitsuba/render/microfacet.h`` and ``fresnel.h``.
E. Heitz, E. d'Eon, "Importance Sampling Microfacet-Based BSDFs using the Distribution of Visible
Normals", EGSR 2014 (the visible-normal sampling the quadratures run over).
"""

from __future__ import annotations

import functools

import numpy as np

from wrt.kernels.materials import COATING_RES

MIN_ALPHA = 1e-4  # Mitsuba clamps a microfacet distribution's alpha to at least this


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


def _smith_g1(v: np.ndarray, m: np.ndarray, alpha: float) -> np.ndarray:
    """GGX Smith masking of direction ``v`` (..., 3) seen through microfacet normal ``m``; 0 where
    ``v`` sees the microfacet's back."""
    xy = alpha * alpha * (v[..., 0] ** 2 + v[..., 1] ** 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        g = 2.0 / (1.0 + np.sqrt(1.0 + xy / v[..., 2] ** 2))
    g = np.where(xy == 0.0, 1.0, g)
    return np.where(np.sum(v * m, axis=-1) * v[..., 2] <= 0.0, 0.0, g)


def _visible_normals(wi: np.ndarray, alpha: float, u: np.ndarray) -> np.ndarray:
    """Mitsuba's GGX visible-normal sample for directions ``wi`` (N, 3) in the xz plane (x >= 0)
    and square samples ``u`` (M, 2): microfacet normals (N, M, 3)."""
    stretched = np.stack([alpha * wi[:, 0], alpha * wi[:, 1], wi[:, 2]], axis=-1)
    stretched /= np.linalg.norm(stretched, axis=-1, keepdims=True)
    cos_theta = stretched[:, 2:3]
    sin2 = stretched[:, 0] ** 2 + stretched[:, 1] ** 2
    inv = 1.0 / np.sqrt(np.where(sin2 > 0.0, sin2, 1.0))
    cos_phi = np.where(sin2 <= 4 * np.finfo(np.float32).eps, 1.0, np.clip(stretched[:, 0] * inv, -1, 1))[:, None]
    sin_phi = np.where(sin2 <= 4 * np.finfo(np.float32).eps, 0.0, np.clip(stretched[:, 1] * inv, -1, 1))[:, None]
    # square to the unit disk, concentric map
    x, y = 2.0 * u[:, 0] - 1.0, 2.0 * u[:, 1] - 1.0
    swap = np.abs(x) < np.abs(y)
    r, rp = np.where(swap, y, x), np.where(swap, x, y)
    with np.errstate(divide="ignore", invalid="ignore"):
        phi = 0.25 * np.pi * rp / r
    phi = np.where(swap, 0.5 * np.pi - phi, phi)
    phi = np.where((x == 0.0) & (y == 0.0), 0.0, phi)
    px, py = r * np.cos(phi), r * np.sin(phi)
    # the visible hemisphere of the unit-roughness distribution, as slopes
    s = 0.5 * (1.0 + cos_theta)
    py = (1.0 - s) * np.sqrt(np.maximum(0.0, 1.0 - px * px)) + s * py
    pz = np.sqrt(np.maximum(0.0, 1.0 - px * px - py * py))
    sin_theta = np.sqrt(np.maximum(0.0, 1.0 - cos_theta * cos_theta))
    norm = 1.0 / (sin_theta * py + cos_theta * pz)
    slope_x, slope_y = (cos_theta * py - sin_theta * pz) * norm, px * norm
    # rotate, unstretch
    sx = (cos_phi * slope_x - sin_phi * slope_y) * alpha
    sy = (sin_phi * slope_x + cos_phi * slope_y) * alpha
    m = np.stack([-sx, -sy, np.ones_like(sx)], axis=-1)
    return m / np.linalg.norm(m, axis=-1, keepdims=True)


def _quadrature(wi: np.ndarray, alpha: float, eta: float, transmitted: bool) -> np.ndarray:
    """Mitsuba's ``eval_reflectance`` (``transmitted`` False) or ``eval_transmittance``: the
    fraction of light arriving from ``wi`` (N, 3) that a GGX interface of relative index ``eta``
    reflects or transmits, single scattering."""
    nodes, weights = np.polynomial.legendre.leggauss(32 if eta > 1.0 else 128)
    ux, uy = np.meshgrid(nodes, nodes)
    wx, wy = np.meshgrid(weights, weights)
    u = np.stack([ux.ravel(), uy.ravel()], axis=-1) * 0.5 + 0.5
    w = (wx * wy).ravel() * 0.25
    m = _visible_normals(wi, alpha, u)
    v = wi[:, None, :]
    cos_m = np.sum(v * m, axis=-1)
    f, cos_t, eta_ti = fresnel(cos_m, eta)
    if transmitted:
        wo = m * (cos_m * eta_ti + cos_t)[..., None] - v * eta_ti
        value = _smith_g1(wo, m, alpha) * (1.0 - f)
        value = np.where(wo[..., 2] * v[..., 2] >= 0.0, 0.0, value)
    else:
        wo = 2.0 * cos_m[..., None] * m - v
        value = _smith_g1(wo, m, alpha) * f
        value = np.where((wo[..., 2] <= 0.0) | (v[..., 2] <= 0.0), 0.0, value)
    return value @ w


@functools.cache
def rough_coating(alpha: float, eta: float) -> tuple[np.ndarray, float]:
    """A GGX coating of roughness ``alpha`` and relative index ``eta`` (> 1): its transmittance
    from outside at the cosines ``k / (COATING_RES - 1)`` (the first at 1e-6), and its
    internal reflectance, ``2`` times the mean over those cosines of ``cos`` times the
    reflectance from inside (Mitsuba's rule, not a finer integral). Cached: the table is shared,
    read-only."""
    alpha = max(alpha, MIN_ALPHA)
    mu = np.maximum(1e-6, np.linspace(0.0, 1.0, COATING_RES))
    wi = np.stack([np.sqrt(1.0 - mu * mu), np.zeros_like(mu), mu], axis=-1)
    transmittance = _quadrature(wi, alpha, eta, transmitted=True)
    transmittance.flags.writeable = False
    internal = 2.0 * float(np.mean(_quadrature(wi, alpha, 1.0 / eta, transmitted=False) * mu))
    return transmittance, internal


def specular_weight(albedo, reflectance) -> float:
    """The weight Mitsuba steers a plastic's samples to its coating with: the mean of the
    coating's ``reflectance`` over that plus the mean ``albedo`` (0.5 when both are black)."""
    s, d = float(np.mean(reflectance)), float(np.mean(albedo))
    return s / (s + d) if s + d > 0.0 else 0.5
