"""Materials on the device: per-shape lookup, parameters per material, and the BRDFs.

Types (``MaterialData.type``): ``DIFFUSE`` (Lambert, albedo/pi), ``PHONG`` (albedo/pi plus the
energy-normalised Phong lobe ``specular (n + 2) / (2 pi) cos^n alpha``, alpha between the
mirror direction of ``wi`` and ``wo``), ``MIRROR`` (perfect specular, ``reflectance``) and
``DIELECTRIC`` (smooth glass: ``ior``, Beer-Lambert ``sigma``), ``GLOSSY`` (GGX conductor of
``roughness`` alpha with the constant Fresnel factor ``reflectance``, ``wrt.kernels.microfacet``) and
``EMITTER`` (the surface of an area or sphere light: reflects nothing). Any type may emit
``emission`` (W/(m^2 sr)) from its front side. ``base_color`` is what the raycast integrator shows.

References
----------
E. Lafortune, Y. Willems, "Using the Modified Phong Reflectance Model for Physically Based
Rendering", KU Leuven CW 197, 1994 (the (n + 2) / (2 pi) normalisation).
"""

import warp as wp

from .microfacet import ggx_eval
from .optics import reflect
from .sample_warps import frame

DIFFUSE = wp.constant(0)
PHONG = wp.constant(1)
MIRROR = wp.constant(2)
DIELECTRIC = wp.constant(3)
GLOSSY = wp.constant(4)
EMITTER = wp.constant(5)


@wp.struct
class MaterialData:
    shape_material: wp.array(dtype=wp.int32)  # material index of each [[shape]]
    type: wp.array(dtype=wp.int32)
    base_color: wp.array(dtype=wp.vec3)
    albedo: wp.array(dtype=wp.vec3)
    specular: wp.array(dtype=wp.vec3)
    exponent: wp.array(dtype=float)
    reflectance: wp.array(dtype=wp.vec3)
    ior: wp.array(dtype=float)
    sigma: wp.array(dtype=wp.vec3)  # absorption coefficient per unit length, -ln(transmittance)
    priority: wp.array(dtype=wp.int32)
    roughness: wp.array(dtype=float)  # GGX alpha
    emission: wp.array(dtype=wp.vec3)


@wp.func
def eval_brdf(materials: MaterialData, m: wp.int32, n: wp.vec3, wo: wp.vec3, wi: wp.vec3) -> wp.vec3:
    """BRDF value (1/sr) of a diffuse, Phong or glossy material for unit ``wo`` (toward the viewer)
    and ``wi`` (toward the light), both on the side of the unit normal ``n``."""
    if materials.type[m] == GLOSSY:
        to_local = wp.transpose(frame(n))
        return materials.reflectance[m] * ggx_eval(to_local * wo, to_local * wi, materials.roughness[m])
    f = materials.albedo[m] / wp.pi
    if materials.type[m] == PHONG:
        cos_alpha = wp.max(0.0, wp.dot(reflect(-wi, n), wo))
        e = materials.exponent[m]
        f += materials.specular[m] * ((e + 2.0) / (2.0 * wp.pi) * wp.pow(cos_alpha, e))
    return f


@wp.func
def beer_lambert(sigma: wp.vec3, distance: float) -> wp.vec3:
    """Fraction of light left after ``distance`` in a medium of absorption coefficient ``sigma``
    (per unit length): ``exp(-sigma distance)``; a clear medium (sigma 0) transmits 1 even over an
    infinite distance."""
    out = wp.vec3(1.0)
    for k in range(3):
        if sigma[k] > 0.0:
            out[k] = wp.exp(-sigma[k] * distance)
    return out
