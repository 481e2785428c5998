"""Phase functions ``isotropic`` (1 / 4 pi) and ``hg`` (Henyey-Greenstein of asymmetry ``g`` in
(-1, 1): ``g > 0`` scatters forward), Mitsuba 3's ``isotropic`` and ``hg``; isotropic is HG of
``g = 0`` (``MediumData.g``).

Convention (Mitsuba 3's, pbrt-v4's): ``wo`` points back along the ray that arrived (toward the
previous vertex), ``wi`` is the scattered direction, and
``p(wo, wi) = (1 - g^2) / (4 pi (1 + g^2 + 2 g cos)^(3/2))`` with ``cos = dot(wo, wi)`` (per
steradian, integrating to 1 over the sphere). ``sample`` draws ``wi`` exactly with that density,
so its weight ``p / pdf`` is 1.

References
----------
L. G. Henyey, J. L. Greenstein, "Diffuse radiation in the galaxy", ApJ 93, 1941.
M. Pharr, W. Jakob, G. Humphreys, pbrt-v4, sec. 11.3.1.
"""

import math

import warp as wp

from ..sample_warps import frame
from .interface import PhaseType

TYPES = (PhaseType("isotropic", ()), PhaseType("hg", ("g",)))

INV_FOUR_PI = wp.constant(1.0 / (4.0 * math.pi))
G_ISOTROPIC = wp.constant(1e-4)  # |g| below which the inversion is that of the isotropic function


@wp.func
def hg_value(cos_theta: float, g: float) -> float:
    """``p`` (1/sr) at ``cos_theta = dot(wo, wi)``."""
    denom = 1.0 + g * g + 2.0 * g * cos_theta
    return INV_FOUR_PI * (1.0 - g * g) / (denom * wp.sqrt(denom))


@wp.func
def hg_sample(wo: wp.vec3, g: float, u: wp.vec2) -> wp.vec3:
    """A direction ``wi`` drawn with density ``hg_value(dot(wo, wi), g)``."""
    cos_forward = 1.0 - 2.0 * u[0]  # the cosine with the direction of travel, -wo
    if wp.abs(g) >= G_ISOTROPIC:
        sqr = (1.0 - g * g) / (1.0 - g + 2.0 * g * u[0])
        cos_forward = wp.clamp((1.0 + g * g - sqr * sqr) / (2.0 * g), -1.0, 1.0)
    sin_forward = wp.sqrt(wp.max(0.0, 1.0 - cos_forward * cos_forward))
    phi = 2.0 * wp.pi * u[1]
    local = wp.vec3(sin_forward * wp.cos(phi), sin_forward * wp.sin(phi), cos_forward)
    return wp.normalize(frame(-wo) * local)
