"""Lights on the device, and what delta lights (point, directional, spot) deliver to a point.

Every light of the scene is one row of ``LightData``; area, sphere and environment lights are
sampled by ``wrt.kernels.emitters``. An environment light with a map (``ENVIRONMENT_MAP``, at
most one per scene) keeps its image, frame and sampling distribution in the ``env_*`` fields
(``wrt.envmap`` describes their layout; 1-element placeholders in scenes without a map); the
emissive primitives sampled with them (``wrt.emitting``) in the ``emit_*`` and ``*_emitter``
fields (placeholders likewise).
Units: point and spot ``intensity`` in W/sr, directional ``irradiance`` in W/m^2,
area/sphere/environment ``radiance`` in W/(m^2 sr) (RGB). A point light at distance d delivers
irradiance ``I / d^2`` on a surface facing it; the integrator multiplies by the BRDF and the
cosine at the receiver.
"""

import warp as wp

POINT = wp.constant(0)
DIRECTIONAL = wp.constant(1)
SPOT = wp.constant(2)
AREA = wp.constant(3)
SPHERE_LIGHT = wp.constant(4)
ENVIRONMENT = wp.constant(5)
ENVIRONMENT_MAP = wp.constant(6)
EMITTING = wp.constant(7)  # not a row's type: the emissive primitives, sampled after the lights


@wp.struct
class LightData:
    type: wp.array(dtype=wp.int32)
    position: wp.array(dtype=wp.vec3)  # point/spot position, parallelogram corner, sphere centre
    direction: wp.array(dtype=wp.vec3)  # unit, the way the light travels
    power: wp.array(dtype=wp.vec3)  # intensity (W/sr), irradiance (W/m^2) or radiance (W/(m^2 sr))
    edge_u: wp.array(dtype=wp.vec3)  # parallelogram edges from the corner
    edge_v: wp.array(dtype=wp.vec3)
    radius: wp.array(dtype=float)  # sphere light
    cos_cutoff: wp.array(dtype=float)  # spot: cos of the cone's half-angle
    cutoff: wp.array(dtype=float)  # spot: half-angle, radians
    beam: wp.array(dtype=float)  # spot: half-angle of full intensity, radians
    env_radiance: wp.array2d(dtype=wp.vec3)  # (H, W) the map's pixels, W/(m^2 sr) before ``power``
    env_to_world: wp.mat33  # the map's frame (a rotation) to world space
    env_cdf: wp.array(dtype=float)  # marginal CDF over cell rows, then each row's conditional CDF
    env_pdf: wp.array2d(dtype=float)  # (H - 1, W) solid-angle density of each cell, 1/sr
    emit_kind: wp.array(dtype=wp.int32)  # the emitting primitives (wrt.emitting): TRIANGLE, POLYGON or SPHERE
    emit_prim: wp.array(dtype=wp.int32)  # their indices in GeometryData's arrays of that kind
    emit_cdf: wp.array(dtype=float)  # (E + 1) their selection CDF by emitted power, 0 to 1
    emit_area: wp.array(dtype=float)  # their areas, m^2
    emit_first: wp.array(dtype=wp.int32)  # (E + 1) a polygon's triangles: emit_first[e] to emit_first[e + 1]
    emit_corner: wp.array(dtype=wp.vec3)  # those triangles' corners, three each
    emit_area_cdf: wp.array(dtype=float)  # per polygon its triangles' running area fractions, the last 1
    tri_emitter: wp.array(dtype=wp.int32)  # per triangle of GeometryData its index in the pool, -1 if none
    poly_emitter: wp.array(dtype=wp.int32)  # per polygon likewise
    sphere_emitter: wp.array(dtype=wp.int32)  # per sphere likewise


@wp.func
def spot_falloff(lights: LightData, i: wp.int32, w: wp.vec3) -> float:
    """Mitsuba 3's spot profile for unit ``w`` leaving the light: 1 inside the beam, linear in
    angle down to 0 at the cutoff."""
    cos_theta = wp.dot(w, lights.direction[i])
    if cos_theta <= lights.cos_cutoff[i]:
        return 0.0
    theta = wp.acos(wp.clamp(cos_theta, -1.0, 1.0))
    if theta <= lights.beam[i]:
        return 1.0
    return (lights.cutoff[i] - theta) / (lights.cutoff[i] - lights.beam[i])


@wp.func
def light_incident(lights: LightData, i: wp.int32, p: wp.vec3):
    """Light ``i`` seen from ``p``: ``(wi, distance, irradiance)`` with ``wi`` the unit direction
    toward the light, ``distance`` to it (inf for directional) and the irradiance (W/m^2) it
    delivers to a surface at ``p`` facing it."""
    kind = lights.type[i]
    if kind == DIRECTIONAL:
        return -lights.direction[i], wp.inf, lights.power[i]
    if kind > SPOT:  # not a delta light: see wrt.kernels.emitters
        return wp.vec3(0.0, 0.0, 1.0), 0.0, wp.vec3(0.0)
    to_light = lights.position[i] - p
    dist2 = wp.dot(to_light, to_light)
    if dist2 == 0.0:
        return wp.vec3(0.0, 0.0, 1.0), 0.0, wp.vec3(0.0)
    dist = wp.sqrt(dist2)
    wi = to_light / dist
    e = lights.power[i] / dist2
    if kind == SPOT:
        e = e * spot_falloff(lights, i, -wi)
    return wi, dist, e
