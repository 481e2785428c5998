"""GGX microfacet reflection (a rough conductor) and refraction (a rough dielectric), in a local shading frame.

Local frame: the normal is +z; ``wo`` and ``wi`` are unit vectors pointing away from the surface.
``alpha`` is the GGX roughness (the scene's ``roughness``). The BRDF here has no Fresnel factor:
``wrt.kernels.materials`` multiplies it by glossy's constant ``reflectance`` (1: a lossless rough
mirror up to the energy lost to single scattering) or by a conductor's exact Fresnel reflectance
at the angle between ``wo`` and the microfacet normal (the half vector).
Masking-shadowing is separable Smith: ``G = G1(wo) G1(wi)``.
A rough dielectric (``ggx_dielectric_eval`` / ``ggx_dielectric_pdf``) has the exact Fresnel
reflectance at the microfacet normal in it: ``F`` reflected, ``1 - F`` refracted (Walter et al.,
eq. 20-21, radiance transport as ``wrt.kernels.materials.dielectric``); ``wi`` may lie below
the surface there (``wi.z < 0``: transmission), and ``eta = n1 / n2`` is the ratio of the indices
of refraction on ``wo``'s side and across the surface.

References
----------
B. Walter, S. Marschner, H. Li, K. Torrance, "Microfacet Models for Refraction through Rough
Surfaces", EGSR 2007 (GGX D and Smith G1).
E. Heitz, "Sampling the GGX Distribution of Visible Normals", JCGT 7(4), 2018.
"""

import warp as wp

from .optics import fresnel_dielectric


@wp.func
def ggx_d(h: wp.vec3, alpha: float) -> float:
    """GGX normal distribution D(h) (1/sr), normalised so that the integral of D cos(theta_h) is 1.

    The tan^2 form ``1 / (pi alpha^2 cos^4 (1 + tan^2 / alpha^2)^2)``, with ``tan^2`` from the
    tangential components: the textbook ``cos^2 (alpha^2 - 1) + 1`` cancels in float32 near the
    normal (3% off at alpha 1e-3)."""
    cos2 = h[2] * h[2]
    if cos2 <= 0.0:
        return 0.0
    a2 = alpha * alpha
    e = 1.0 + (h[0] * h[0] + h[1] * h[1]) / (cos2 * a2)
    return 1.0 / (wp.pi * a2 * cos2 * cos2 * e * e)


@wp.func
def ggx_g1(w: wp.vec3, alpha: float) -> float:
    """Smith masking of direction ``w`` for GGX."""
    cos2 = w[2] * w[2]
    if cos2 <= 0.0:
        return 0.0
    tan2 = (w[0] * w[0] + w[1] * w[1]) / cos2  # from the tangential components: no cancellation
    return 2.0 / (1.0 + wp.sqrt(1.0 + alpha * alpha * tan2))


@wp.func
def ggx_sample_visible_normal(wo: wp.vec3, alpha: float, u1: float, u2: float) -> wp.vec3:
    """A microfacet normal drawn with density ``G1(wo) max(0, wo.h) D(h) / wo.z`` (Heitz 2018)."""
    # stretch to the hemisphere configuration
    vh = wp.normalize(wp.vec3(alpha * wo[0], alpha * wo[1], wo[2]))
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
    return wp.normalize(wp.vec3(alpha * nh[0], alpha * nh[1], wp.max(1e-7, nh[2])))


@wp.func
def ggx_eval(wo: wp.vec3, wi: wp.vec3, alpha: float) -> float:
    """BRDF value without the Fresnel factor: ``D(h) G1(wo) G1(wi) / (4 wo.z wi.z)`` (1/sr)."""
    if wo[2] <= 0.0 or wi[2] <= 0.0:
        return 0.0
    h = wp.normalize(wo + wi)
    return ggx_d(h, alpha) * ggx_g1(wo, alpha) * ggx_g1(wi, alpha) / (4.0 * wo[2] * wi[2])


@wp.func
def ggx_pdf(wo: wp.vec3, wi: wp.vec3, alpha: float) -> float:
    """Solid-angle density of ``wi`` when sampled by reflecting ``wo`` about a visible normal:
    ``G1(wo) D(h) / (4 wo.z)``."""
    if wo[2] <= 0.0 or wi[2] <= 0.0:
        return 0.0
    h = wp.normalize(wo + wi)
    return ggx_g1(wo, alpha) * ggx_d(h, alpha) / (4.0 * wo[2])


@wp.func
def ggx_dielectric_half(wo: wp.vec3, wi: wp.vec3, eta: float) -> wp.vec3:
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


@wp.func
def ggx_dielectric_eval(wo: wp.vec3, wi: wp.vec3, alpha: float, eta: float) -> float:
    """f(wo, wi) (1/sr) of a rough dielectric interface (``wo.z > 0``): ``F D G / (4 wo.z wi.z)``
    reflected, ``(1 - F) D G |wo.h| |wi.h| / (wo.z |wi.z| (wo.h + wi.h / eta)^2)`` transmitted
    (radiance: it integrates to ``eta^2 (1 - F)`` on a smooth surface); 0 where ``h`` is seen from
    the wrong side, and at ``eta == 1`` (index-matched: the interface is a straight pass)."""
    if eta == 1.0 or wi[2] == 0.0:
        return 0.0
    h = ggx_dielectric_half(wo, wi, eta)
    cos_o = wp.dot(wo, h)
    cos_i = wp.dot(wi, h)
    if cos_o <= 0.0 or cos_i * wi[2] <= 0.0:
        return 0.0
    dg = ggx_d(h, alpha) * ggx_g1(wo, alpha) * ggx_g1(wi, alpha)
    fresnel = fresnel_dielectric(cos_o, eta)
    if wi[2] > 0.0:
        return fresnel * dg / (4.0 * wo[2] * wi[2])
    denom = cos_o + cos_i / eta
    return (1.0 - fresnel) * dg * cos_o * wp.abs(cos_i) / (wo[2] * wp.abs(wi[2]) * denom * denom)


@wp.func
def ggx_dielectric_pdf(wo: wp.vec3, wi: wp.vec3, alpha: float, eta: float) -> float:
    """Solid-angle density of ``wi`` when a visible normal ``h`` is drawn for ``wo`` and ``wo`` is
    reflected with probability F (``wrt.kernels.optics.fresnel_dielectric`` at ``wo.h``) or refracted
    otherwise: ``G1(wo) D(h) (wo.h) / wo.z`` times F / (4 wi.h) or (1 - F) |wi.h| / (eta^2 (wo.h + wi.h / eta)^2)."""
    if eta == 1.0 or wi[2] == 0.0:
        return 0.0
    h = ggx_dielectric_half(wo, wi, eta)
    cos_o = wp.dot(wo, h)
    cos_i = wp.dot(wi, h)
    if cos_o <= 0.0 or cos_i * wi[2] <= 0.0:
        return 0.0
    visible = ggx_g1(wo, alpha) * ggx_d(h, alpha) * cos_o / wo[2]
    fresnel = fresnel_dielectric(cos_o, eta)
    if wi[2] > 0.0:
        return visible * fresnel / (4.0 * cos_i)
    denom = eta * cos_o + cos_i
    return visible * (1.0 - fresnel) * wp.abs(cos_i) / (denom * denom)
