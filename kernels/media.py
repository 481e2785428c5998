"""Media along a ray: which dielectric the ray is inside, and what a dielectric surface it meets
separates (shared by the whitted and path integrators). Participating media, which scatter, are
``wrt.kernels.volumes``'; this bookkeeping of iors and Beer-Lambert absorption applies beside them.

Each ray (or branch) carries a small stack of the dielectric shapes it is inside, up to
``MEDIA`` deep; a ray entering one more has no medium to be in (``MEDIA_OVERFLOW``): its sample
is lost, and the integrators make it NaN so that the film counts it and ``wrt render`` warns,
rather than continue in a wrong medium. The current medium is the entry of highest
``priority``, ties going to the most recently entered; outside every dielectric the ray is in the
scene's exterior medium (``exterior_ior``). A surface of a shape that does not own the space is a
false interface: the ray goes straight on and only the stack changes. So nested objects need no
priorities, and where dielectrics overlap the higher priority owns the overlap.

References
----------
C. Schmidt, B. Budge, "Simple Nested Dielectrics in Ray Traced Images", JGT 7(2), 2002.
"""

import warp as wp

from .materials import BSDF_MEDIUM, MaterialData

MEDIA = 8  # nested dielectrics a ray can be inside at once
MEDIA_OVERFLOW = wp.constant(MEDIA + 1)  # n_media of a ray that entered one dielectric too many
Media = wp.types.vector(length=MEDIA, dtype=wp.int32)


@wp.func
def max_component(v: wp.vec3) -> float:
    return wp.max(wp.max(v[0], v[1]), v[2])


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


@wp.func
def shape_priority(materials: MaterialData, shape: wp.int32) -> wp.int32:
    return materials.priority[materials.shape_material[shape]]


@wp.func
def current_medium(materials: MaterialData, media: Media, count: wp.int32) -> wp.int32:
    """Slot of the medium the ray is in: highest priority, ties to the latest entered; -1 = exterior."""
    best = int(-1)
    for k in range(count):
        if best < 0:
            best = k
        elif shape_priority(materials, media[k]) >= shape_priority(materials, media[best]):
            best = k
    return best


@wp.func
def medium_ior(materials: MaterialData, exterior_ior: float, media: Media, slot: wp.int32) -> float:
    if slot < 0:
        return exterior_ior
    return materials.ior[materials.shape_material[media[slot]]]


@wp.func
def find_medium(media: Media, count: wp.int32, shape: wp.int32) -> wp.int32:
    """Slot of the latest entry of ``shape`` in the stack, or -1."""
    found = int(-1)
    for k in range(count):
        if media[k] == shape:
            found = k
    return found


@wp.func
def remove_medium(media: Media, count: wp.int32, slot: wp.int32) -> Media:
    out = media
    for k in range(slot, count - 1):
        out[k] = media[k + 1]
    out[count - 1] = -1
    return out


@wp.func
def dielectric_interface(
    materials: MaterialData,
    exterior_ior: float,
    media: Media,
    n_media: wp.int32,
    shape: wp.int32,
    entering: bool,
):
    """What the surface of dielectric ``shape`` separates for a ray with media stack ``media``:
    ``(real, eta, media_t, n_media_t)``: whether it is a real interface, ``eta = n1 / n2`` (the
    ior on the incident over that on the far side), and the stack of a ray that crosses it
    (``n_media_t == MEDIA_OVERFLOW``: one dielectric too many). A ray leaving a shape it never
    entered (a camera inside glass) refracts from that shape's ior into the current medium.
    """
    m = materials.shape_material[shape]
    slot = current_medium(materials, media, n_media)
    inside = find_medium(media, n_media, shape)
    media_t = media
    n_media_t = n_media
    real = bool(True)
    n1 = float(1.0)
    n2 = float(1.0)
    if entering:
        n1 = medium_ior(materials, exterior_ior, media, slot)
        n2 = materials.ior[m]
        if slot >= 0 and shape_priority(materials, media[slot]) > materials.priority[m]:
            real = False
        if n_media < MEDIA:
            media_t[n_media] = shape
            n_media_t = n_media + 1
        else:
            n_media_t = MEDIA_OVERFLOW
    elif inside < 0:
        n1 = materials.ior[m]
        n2 = medium_ior(materials, exterior_ior, media, slot)
    else:
        media_t = remove_medium(media, n_media, inside)
        n_media_t = n_media - 1
        if inside != slot:
            real = False
        n1 = materials.ior[m]
        n2 = medium_ior(materials, exterior_ior, media_t, current_medium(materials, media_t, n_media_t))
    return real, n1 / n2, media_t, n_media_t


@wp.struct
class Interface:
    """What a surface separates for a ray arriving at it (``cross_interface``)."""

    real: bool  # False: a false interface, the ray goes straight on and only its media change
    eta: float  # n1 / n2, the ior on the incident side over that on the far side
    media: Media  # the media stack of a ray that crosses the surface
    n_media: wp.int32  # its depth; MEDIA_OVERFLOW: one dielectric too many


@wp.func
def no_interface(media: Media, n_media: wp.int32) -> Interface:
    """A surface that separates nothing: real, ``eta`` 1, the same media on both sides."""
    interface = Interface()
    interface.real = True
    interface.eta = 1.0
    interface.media = media
    interface.n_media = n_media
    return interface


@wp.func
def cross_interface(
    materials: MaterialData,
    exterior_ior: float,
    media: Media,
    n_media: wp.int32,
    flags: wp.int32,
    shape: wp.int32,
    entering: bool,
) -> Interface:
    """What a surface of BSDF ``flags`` on ``shape`` separates for a ray with media stack ``media``:
    a dielectric that bounds a medium (``BSDF_MEDIUM``) its ``dielectric_interface``, any other
    surface (a thin dielectric, a principled material's transmission) ``no_interface``."""
    interface = no_interface(media, n_media)
    if (flags & BSDF_MEDIUM) != 0:
        real, eta, media_t, n_media_t = dielectric_interface(materials, exterior_ior, media, n_media, shape, entering)
        interface.real = real
        interface.eta = eta
        interface.media = media_t
        interface.n_media = n_media_t
    return interface


@wp.func
def current_ior(materials: MaterialData, exterior_ior: float, media: Media, n_media: wp.int32) -> float:
    """Index of refraction of the medium a ray with stack ``media`` is in.

    Refraction scales radiance by ``(n1 / n2)^2`` (``wrt.kernels.materials.dielectric``), so a
    path's throughput carries ``(n_camera / n_current)^2``: decisions on how much a path still
    matters (roulette, whitted's cut and branch order) multiply it back by
    ``(current_ior / n_camera)^2``, as pbrt-v4's ``etaScale`` does."""
    return medium_ior(materials, exterior_ior, media, current_medium(materials, media, n_media))


@wp.func
def medium_sigma(materials: MaterialData, media: Media, n_media: wp.int32) -> wp.vec3:
    """Absorption coefficient (per unit length) of the medium a ray with stack ``media`` is in; 0
    in the exterior medium."""
    slot = current_medium(materials, media, n_media)
    if slot < 0:
        return wp.vec3(0.0)
    return materials.sigma[materials.shape_material[media[slot]]]


@wp.func
def medium_transmittance(materials: MaterialData, media: Media, n_media: wp.int32, distance: float) -> wp.vec3:
    """Beer-Lambert transmittance of the medium a ray with stack ``media`` is in, over ``distance``
    (infinite for a ray that escapes); 1 in the exterior medium."""
    return beer_lambert(medium_sigma(materials, media, n_media), distance)
