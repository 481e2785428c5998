"""Specular optics: mirror reflection, Snell refraction and the exact Fresnel terms of dielectrics and conductors.

Conventions: ``d`` is the incident ray direction (unit, pointing toward the surface), ``n`` the
unit normal on the side the ray comes from (``dot(d, n) < 0``), ``eta = n1 / n2`` the ratio of
the indices of refraction of the incident and the transmitted medium.

References
----------
M. Pharr, W. Jakob, G. Humphreys, pbrt-v4, sec. 9.3 (Snell's law in vector form, Fresnel).
E. Hecht, Optics, 5th ed., sec. 4.6 (Fresnel equations).
K. D. Moeller, Optics, University Science Books, 1988 (the conductor's Fresnel equations in real
arithmetic, as Mitsuba 3's ``fresnel_conductor``).
"""

import warp as wp


@wp.func
def reflect(d: wp.vec3, n: wp.vec3) -> wp.vec3:
    """Mirror direction ``R = d - 2 (d.n) n`` (the lecture's R = V - 2(V.N)N)."""
    return d - 2.0 * wp.dot(d, n) * n


@wp.func
def refract(d: wp.vec3, n: wp.vec3, eta: float):
    """Snell refraction of ``d`` through a surface with normal ``n`` facing the incident side.

    Returns ``(ok, t)``: ``ok`` is False on total internal reflection (``sin^2 theta_t > 1``),
    else ``t = eta d + (eta cos_i - cos_t) n`` normalised. ``eta == 1`` returns ``d`` exactly.
    """
    if eta == 1.0:
        return True, d
    cos_i = -wp.dot(d, n)
    sin2_t = eta * eta * wp.max(0.0, 1.0 - cos_i * cos_i)
    if sin2_t > 1.0:
        return False, d
    cos_t = wp.sqrt(1.0 - sin2_t)
    return True, wp.normalize(eta * d + (eta * cos_i - cos_t) * n)


@wp.func
def fresnel_dielectric(cos_i: float, eta: float) -> float:
    """Fraction of unpolarised light reflected at a dielectric interface (exact Fresnel equations).

    ``cos_i`` is the cosine of the incidence angle (>= 0), ``eta = n1 / n2``. Returns 1 under
    total internal reflection, 0 when ``eta == 1``.
    """
    if eta == 1.0:
        return 0.0
    cos_i = wp.clamp(cos_i, 0.0, 1.0)
    sin2_t = eta * eta * (1.0 - cos_i * cos_i)
    if sin2_t >= 1.0:
        return 1.0
    cos_t = wp.sqrt(1.0 - sin2_t)
    r_par = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    r_perp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    return 0.5 * (r_par * r_par + r_perp * r_perp)


@wp.func
def fresnel_thin_dielectric(cos_i: float, eta: float) -> float:
    """Fraction of unpolarised light reflected by a dielectric slab of negligible thickness,
    every internal reflection summed: with ``R = fresnel_dielectric(cos_i, eta)`` at either face
    and ``T = 1 - R``, ``R' = R + T^2 R / (1 - R^2) = 2 R / (1 + R)`` (Mitsuba 3's
    ``thindielectric``); the rest, ``1 - R'``, goes straight through. ``cos_i`` >= 0, ``eta`` the
    ratio of the outside's ior to the slab's."""
    r = fresnel_dielectric(cos_i, eta)
    return 2.0 * r / (1.0 + r)


@wp.func
def fresnel_conductor1(cos_i: float, eta: float, k: float) -> float:
    """Fraction of unpolarised light reflected by a conductor of complex index of refraction
    ``eta + i k`` (relative to the outside), at incidence cosine ``cos_i`` (>= 0): the exact
    Fresnel equations, the mean of the s and p reflectances. 1 at grazing incidence; at normal
    incidence ``((eta - 1)^2 + k^2) / ((eta + 1)^2 + k^2)``."""
    cos2 = wp.min(cos_i * cos_i, 1.0)
    sin2 = 1.0 - cos2
    t1 = eta * eta - k * k - sin2
    a2_plus_b2 = wp.sqrt(t1 * t1 + 4.0 * eta * eta * k * k)
    a = wp.sqrt(wp.max(0.0, 0.5 * (a2_plus_b2 + t1)))
    t2 = a2_plus_b2 + cos2
    t3 = 2.0 * wp.sqrt(cos2) * a
    r_s = (t2 - t3) / (t2 + t3)
    t4 = a2_plus_b2 * cos2 + sin2 * sin2
    t5 = t3 * sin2
    r_p = r_s  # the limit at normal incidence, where the expression below is 0/0 for eta = k = 0
    if t4 + t5 > 0.0:
        r_p = r_s * (t4 - t5) / (t4 + t5)
    return 0.5 * (r_s + r_p)


@wp.func
def fresnel_conductor(cos_i: float, eta: wp.vec3, k: wp.vec3) -> wp.vec3:
    """``fresnel_conductor1`` per RGB channel."""
    return wp.vec3(
        fresnel_conductor1(cos_i, eta[0], k[0]),
        fresnel_conductor1(cos_i, eta[1], k[1]),
        fresnel_conductor1(cos_i, eta[2], k[2]),
    )
