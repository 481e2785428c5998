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
the Fresnel term at the microfacet normal) and
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
- ``bsdf_eval(materials, m, n, wo, wi)``: f (1/sr) of the non-specular lobes, 0 for delta lobes.
- ``bsdf_pdf(materials, m, n, wo, wi)``: the solid-angle density with which ``bsdf_sample`` draws
  ``wi`` from the non-specular lobes.
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
a lobe, ``u`` (2D) samples a direction within it; both uniform in [0, 1).

A new material type is one new constant here and one new case in each of ``bsdf_flags``,
``bsdf_eval``, ``bsdf_pdf``, ``bsdf_sample`` (and ``specular_lobes`` if it has delta lobes).

References
----------
E. Lafortune, Y. Willems, "Using the Modified Phong Reflectance Model for Physically Based
Rendering", KU Leuven CW 197, 1994 (the (n + 2) / (2 pi) normalisation).
M. Pharr, W. Jakob, G. Humphreys, pbrt-v4, sec. 9.1 (the BSDF interface and its flags).
"""

import warp as wp

from .microfacet import ggx_eval, ggx_g1, ggx_pdf, ggx_sample_visible_normal
from .optics import fresnel_conductor, fresnel_dielectric, fresnel_thin_dielectric, reflect, refract
from .sample_warps import cosine_hemisphere, frame

DIFFUSE = wp.constant(0)
PHONG = wp.constant(1)
MIRROR = wp.constant(2)
DIELECTRIC = wp.constant(3)
GLOSSY = wp.constant(4)
EMITTER = wp.constant(5)
CONDUCTOR = wp.constant(6)
THIN_DIELECTRIC = wp.constant(7)

BSDF_REFLECTION = wp.constant(1)
BSDF_TRANSMISSION = wp.constant(2)
BSDF_DIFFUSE = wp.constant(4)
BSDF_GLOSSY = wp.constant(8)
BSDF_SPECULAR = wp.constant(16)
BSDF_TOTAL_INTERNAL = wp.constant(32)  # a sampled lobe only: specular reflection because refraction is impossible
BSDF_THIN = wp.constant(64)  # transmission goes straight on through a surface that bounds no medium (thin dielectric)


@wp.struct
class MaterialData:
    shape_material: wp.array(dtype=wp.int32)  # material index of each [[shape]]
    type: wp.array(dtype=wp.int32)
    base_color: wp.array(dtype=wp.vec3)
    albedo: wp.array(dtype=wp.vec3)
    specular: wp.array(dtype=wp.vec3)
    exponent: wp.array(dtype=float)
    reflectance: wp.array(dtype=wp.vec3)  # mirror, glossy: the reflectance; conductor: the tint of its Fresnel term
    ior: wp.array(dtype=float)  # dielectric: its ior; thin dielectric: its ior over the scene's exterior_ior
    sigma: wp.array(dtype=wp.vec3)  # absorption coefficient per unit length, -ln(transmittance)
    transmittance: wp.array(dtype=wp.vec3)  # thin dielectric: the tint of its straight transmission
    priority: wp.array(dtype=wp.int32)
    roughness: wp.array(dtype=float)  # GGX alpha (conductor: 0 for a smooth one)
    eta: wp.array(dtype=wp.vec3)  # conductor: real part of the index of refraction, per channel
    k: wp.array(dtype=wp.vec3)  # conductor: imaginary part (extinction coefficient)
    emission: wp.array(dtype=wp.vec3)
    two_sided: wp.array(dtype=wp.int32)  # 1: both sides reflect; 0: the back side reflects nothing


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


@wp.func
def bsdf_flags(materials: MaterialData, m: wp.int32) -> wp.int32:
    """The lobes of material ``m``'s BSDF (``BSDF_*`` bits); 0 if it scatters nothing."""
    kind = materials.type[m]
    if kind == DIFFUSE:
        return BSDF_REFLECTION | BSDF_DIFFUSE
    if kind == PHONG:
        return BSDF_REFLECTION | BSDF_DIFFUSE | BSDF_GLOSSY
    if kind == GLOSSY:
        return BSDF_REFLECTION | BSDF_GLOSSY
    if kind == MIRROR:
        return BSDF_REFLECTION | BSDF_SPECULAR
    if kind == DIELECTRIC:
        return BSDF_REFLECTION | BSDF_TRANSMISSION | BSDF_SPECULAR
    if kind == THIN_DIELECTRIC:
        return BSDF_REFLECTION | BSDF_TRANSMISSION | BSDF_SPECULAR | BSDF_THIN
    if kind == CONDUCTOR:
        if materials.roughness[m] > 0.0:
            return BSDF_REFLECTION | BSDF_GLOSSY
        return BSDF_REFLECTION | BSDF_SPECULAR
    return 0


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
def specular_reflectance(materials: MaterialData, m: wp.int32, cos_theta: float) -> wp.vec3:
    """The reflectance of a mirror's, a glossy's or a conductor's facet (the surface, or a
    microfacet) seen at incidence cosine ``cos_theta``: ``reflectance``, for a conductor times its
    Fresnel term."""
    if materials.type[m] == CONDUCTOR:
        return wp.cw_mul(materials.reflectance[m], fresnel_conductor(cos_theta, materials.eta[m], materials.k[m]))
    return materials.reflectance[m]


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
def bsdf_eval(materials: MaterialData, m: wp.int32, n: wp.vec3, wo: wp.vec3, wi: wp.vec3) -> wp.vec3:
    """f(wo, wi) (1/sr) of the non-specular lobes for ``wi`` on the side of ``n``; 0 for delta lobes."""
    kind = materials.type[m]
    if kind == GLOSSY or kind == CONDUCTOR:
        alpha = materials.roughness[m]
        if alpha == 0.0:
            return wp.vec3(0.0)
        to_local = wp.transpose(frame(n))
        cos_h = wp.abs(wp.dot(wo, wp.normalize(wo + wi)))
        return specular_reflectance(materials, m, cos_h) * ggx_eval(to_local * wo, to_local * wi, alpha)
    if kind == DIFFUSE:
        return materials.albedo[m] / wp.pi
    if kind == PHONG:
        cos_alpha = wp.max(0.0, wp.dot(reflect(-wi, n), wo))
        e = materials.exponent[m]
        return materials.albedo[m] / wp.pi + materials.specular[m] * ((e + 2.0) / (2.0 * wp.pi) * wp.pow(cos_alpha, e))
    return wp.vec3(0.0)


@wp.func
def bsdf_pdf(materials: MaterialData, m: wp.int32, n: wp.vec3, wo: wp.vec3, wi: wp.vec3) -> float:
    """Solid-angle density (1/sr) with which ``bsdf_sample`` draws ``wi``; 0 for delta lobes."""
    kind = materials.type[m]
    if kind == GLOSSY or kind == CONDUCTOR:
        alpha = materials.roughness[m]
        if alpha == 0.0:
            return 0.0
        to_local = wp.transpose(frame(n))
        return ggx_pdf(to_local * wo, to_local * wi, alpha)
    if kind == DIFFUSE or kind == PHONG:
        return wp.max(0.0, wp.dot(n, wi)) / wp.pi
    return 0.0


@wp.func
def specular_lobes(materials: MaterialData, m: wp.int32, n: wp.vec3, wo: wp.vec3, eta: float) -> SpecularLobes:
    """The delta lobes of a mirror (reflectance), a smooth conductor (reflectance times its Fresnel
    term), a smooth dielectric (exact Fresnel F reflected, 1 - F refracted by Snell's law, all
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
        lobes.reflectance = specular_reflectance(materials, m, wp.dot(wo, n))
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
        lobes.reflectance = materials.reflectance[m] * thin_reflectance(materials, m, cos_theta)
        lobes.transmittance = thin_transmittance(materials, m, cos_theta)
        lobes.refracts = True
    return lobes


@wp.func
def thin_dielectric_sample(materials: MaterialData, m: wp.int32, n: wp.vec3, wo: wp.vec3, uc: float) -> BSDFSample:
    """A thin dielectric's reflection with probability R' (weight ``reflectance``), else its
    straight transmission (weight ``transmittance``, ``wi = -wo``)."""
    s = BSDFSample()
    r = thin_reflectance(materials, m, wp.dot(wo, n))
    if uc < r:
        s.wi = reflect(-wo, n)
        s.weight = materials.reflectance[m]
        s.pdf = r
        s.flags = BSDF_REFLECTION | BSDF_SPECULAR
    else:
        s.wi = -wo
        s.weight = materials.transmittance[m]
        s.pdf = 1.0 - r
        s.flags = BSDF_TRANSMISSION | BSDF_SPECULAR | BSDF_THIN
    return s


@wp.func
def bsdf_sample(
    materials: MaterialData, m: wp.int32, n: wp.vec3, wo: wp.vec3, eta: float, uc: float, u: wp.vec2
) -> BSDFSample:
    """A direction drawn from material ``m``'s BSDF: diffuse and Phong cosine-weighted, glossy and
    rough conductors by GGX visible normals, a mirror's or a smooth conductor's reflection, a
    dielectric's reflection with probability F (weight F / F = 1) and refraction otherwise (weight
    ``eta^2``, ``specular_lobes``), a thin dielectric's reflection with probability R' (weight
    ``reflectance``) and straight transmission otherwise (weight ``transmittance``)."""
    s = BSDFSample()
    s.weight = wp.vec3(0.0)
    s.pdf = 0.0
    s.flags = 0
    kind = materials.type[m]
    if kind == THIN_DIELECTRIC:
        return thin_dielectric_sample(materials, m, n, wo, uc)
    if kind == MIRROR or kind == DIELECTRIC or (kind == CONDUCTOR and materials.roughness[m] == 0.0):
        lobes = specular_lobes(materials, m, n, wo, eta)
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
        alpha = materials.roughness[m]
        h = ggx_sample_visible_normal(wo_local, alpha, u[0], u[1])
        cos_h = wp.dot(wo_local, h)
        wi_local = 2.0 * cos_h * h - wo_local
        s.wi = to_world * wi_local
        s.flags = BSDF_REFLECTION | BSDF_GLOSSY
        if wi_local[2] > 0.0:
            s.weight = specular_reflectance(materials, m, cos_h) * ggx_g1(wi_local, alpha)
            s.pdf = ggx_pdf(wo_local, wi_local, alpha)
        return s
    s.wi = to_world * cosine_hemisphere(u[0], u[1])
    if kind == DIFFUSE or kind == PHONG:
        s.flags = BSDF_REFLECTION | BSDF_DIFFUSE
        cos_theta = wp.dot(n, s.wi)
        if cos_theta > 0.0:
            s.pdf = cos_theta / wp.pi
            s.weight = bsdf_eval(materials, m, n, wo, s.wi) * (cos_theta / s.pdf)
    return s
