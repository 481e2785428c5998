"""Shadow rays: the one routine every integrator uses to ask whether a light is seen, and record it.

``shadow_ray`` returns the fraction of a light's radiance that reaches a point along a direction:

- opaque (``filtered`` False; physical for a ray tracer without caustics, and what the path
  integrator always asks): 0 if anything is in the way, else the Beer-Lambert transmittance of
  the medium the ray starts in over its length (a light in the same tinted glass or murky water
  as the point it lights, as a path reaching it by BSDF sampling is attenuated), from one any-hit
  query;
- through media (the path integrator in a scene with participating media, Mitsuba 3's
  ``volpath``): null surfaces and thin dielectrics (whose straight-through lobe Mitsuba counts as
  a null one, attenuated by ``thin_transmittance``) let the shadow ray through, changing the
  medium it is in, and the transmittance of each medium it crosses (``wrt.kernels.volumes``)
  attenuates it; any other surface blocks it;
- filtered (the lecture's, whitted's ``dielectric_shadows = "filtered"``): dielectrics let the
  shadow ray through in a straight line, attenuated by Beer-Lambert over the length inside them:
  up to the first surface in the medium it starts in, between an entering and a leaving surface
  in that dielectric, after an entering one in it (at most ``SHADOW_CROSSINGS`` surfaces), and
  thin dielectrics let it through attenuated by their straight transmittance, in the same medium;
  anything else blocks.

In a recording variant each shadow ray is appended to the ``RayRecord``: ``SHADOW_LIT`` up to its
light, carrying the path throughput times the transmittance, or ``SHADOW_BLOCKED`` ending at the
surface that stopped it (for an opaque shadow ray one extra closest-hit query: the any-hit query
that decides visibility does not say where the blocker is).
"""

import warp as wp

from .materials import (
    BSDF_THIN,
    BSDF_TRANSMISSION,
    NULL,
    THIN_DIELECTRIC,
    MaterialData,
    bsdf_flags,
    thin_transmittance,
)
from .media import beer_lambert, max_component
from .record import SHADOW_BLOCKED, SHADOW_LIT, TO_CAMERA, TO_CAMERA_BLOCKED, RayRecord, record_ray
from .sampling import pcg_hash
from .spawn import spawn_origin
from .traverse import (
    NO_HIT,
    GeometryData,
    Traversal,
    hit_point,
    hit_shape,
    make_surface_point,
    prim_shape,
    ray_hit,
    shading_normal,
)
from .volumes import boundary_medium, has_media, volume_transmittance

SHADOW_CROSSINGS = wp.constant(16)  # dielectric surfaces a filtered shadow ray may pass


def make_shadow_ray(record: bool, trace: Traversal, media: bool = False, to_camera: bool = False):
    """``shadow_ray`` over the traversal ``trace``, recording when ``record`` (as ``TO_CAMERA`` and
    ``TO_CAMERA_BLOCKED`` where ``to_camera``: the light tracer's connections) and through
    participating media and null surfaces when ``media`` (each compiled out otherwise)."""
    lit, blocked = (TO_CAMERA, TO_CAMERA_BLOCKED) if to_camera else (SHADOW_LIT, SHADOW_BLOCKED)
    surface_point = make_surface_point(trace.features.disks or trace.features.cylinders)
    smooth = trace.features.smooth

    @wp.func
    def pane_transmittance(
        geometry: GeometryData,
        materials: MaterialData,
        m: wp.int32,
        prim: wp.int32,
        inst: wp.int32,
        p: wp.vec3,
        n: wp.vec3,
        w: wp.vec3,
        time: float,
    ) -> wp.vec3:
        """What thin dielectric ``m`` lets through along ``w`` where it is crossed at ``p`` (geometric
        normal ``n``): ``thin_transmittance`` at the cosine to its shading normal, as the BSDF sees
        it (Mitsuba 3's ``eval_null_transmission`` works in the shading frame)."""
        ns = n
        if wp.static(smooth):
            ns = shading_normal(geometry, prim, inst, p, n, time)
        return thin_transmittance(materials, m, wp.dot(w, ns))

    @wp.func
    def crossing(geometry: GeometryData, prim: wp.int32, inst: wp.int32, o: wp.vec3, w: wp.vec3, t: float, time: float):
        """Where the shadow ray ``o + s w`` meets ``prim`` at ``s = t``: ``(p, n, err)``."""
        if wp.static(trace.features.instances):
            return hit_point(geometry, ray_hit(o, w, time, t, prim, inst))
        return surface_point(geometry, prim, o, w, t, time)

    @wp.func
    def through_media(
        geometry: GeometryData,
        materials: MaterialData,
        o: wp.vec3,
        w: wp.vec3,
        t_max: float,
        time: float,
        medium: wp.int32,
        key: wp.uint32,
    ):
        """Follow a shadow ray ``o + s w`` that starts in participating medium ``medium`` through
        the null surfaces and thin dielectrics on its way, changing medium at each (Mitsuba 3's
        ``volpath``): ``(transmittance, t, prim, inst)`` as ``filtered``'s; any other surface blocks
        it. ``key`` is the stream of the media's tracking, a new one past each surface."""
        out = wp.vec3(1.0)
        t_total = float(0.0)
        current = medium
        for _k in range(SHADOW_CROSSINGS):
            t, prim, inst = trace.closest_hit(geometry, o, w, time, 0.0, t_max)
            if prim == NO_HIT:
                return (
                    wp.cw_mul(out, volume_transmittance(materials.media, current, o, w, t_max, key)),
                    t_total + t_max,
                    prim,
                    inst,
                )
            m = materials.shape_material[prim_shape(geometry, prim)]
            if materials.type[m] != NULL and materials.type[m] != THIN_DIELECTRIC:
                return wp.vec3(0.0), t_total + t, prim, inst
            out = wp.cw_mul(out, volume_transmittance(materials.media, current, o, w, t, key))
            key = pcg_hash(key)
            p, n, err = crossing(geometry, prim, inst, o, w, t, time)
            if materials.type[m] == THIN_DIELECTRIC:  # its straight lobe is a null one (Mitsuba 3's)
                out = wp.cw_mul(out, pane_transmittance(geometry, materials, m, prim, inst, p, n, w, time))
            current = boundary_medium(materials.media, hit_shape(geometry, prim, inst), wp.dot(w, n) > 0.0, current)
            o = spawn_origin(p, n, err, w)
            t_max = t_max - t
            t_total += t
        return wp.vec3(0.0), t_total + t_max, NO_HIT, -1

    @wp.func
    def passes(geometry: GeometryData, materials: MaterialData, prim: wp.int32) -> bool:
        """A filtered shadow ray goes on through ``prim``: its material transmits (a dielectric)."""
        return (bsdf_flags(materials, materials.shape_material[prim_shape(geometry, prim)]) & BSDF_TRANSMISSION) != 0

    @wp.func
    def filtered(
        geometry: GeometryData,
        materials: MaterialData,
        o: wp.vec3,
        w: wp.vec3,
        t_max: float,
        time: float,
        sigma: wp.vec3,
    ):
        """Follow a filtered shadow ray ``o + s w``, starting in a medium of absorption ``sigma``,
        through the dielectrics on its way: ``(transmittance, t, prim)``, with ``(t, prim)`` the
        surface that stopped it (``NO_HIT`` when it reached ``t_max``) and the instance it was hit through."""
        out = wp.vec3(1.0)
        t_total = float(0.0)
        sigma_now = sigma
        for _k in range(SHADOW_CROSSINGS):
            t, prim, inst = trace.closest_hit(geometry, o, w, time, 0.0, t_max)
            if prim == NO_HIT:
                return wp.cw_mul(out, beer_lambert(sigma_now, t)), t_total + t, prim, inst
            if not passes(geometry, materials, prim):
                return wp.vec3(0.0), t_total + t, prim, inst
            p, n, err = crossing(geometry, prim, inst, o, w, t, time)
            m = materials.shape_material[prim_shape(geometry, prim)]
            if (bsdf_flags(materials, m) & BSDF_THIN) != 0:  # a pane: the medium goes on beyond it
                passed = pane_transmittance(geometry, materials, m, prim, inst, p, n, w, time)
                out = wp.cw_mul(out, wp.cw_mul(beer_lambert(sigma_now, t), passed))
            elif wp.dot(w, n) > 0.0:  # leaving: the segment just travelled was inside this dielectric
                out = wp.cw_mul(out, beer_lambert(materials.sigma[m], t))
                sigma_now = wp.vec3(0.0)  # beyond it: taken as clear (shadow rays keep no media stack)
            else:  # entering: the segment just travelled was in the current medium
                out = wp.cw_mul(out, beer_lambert(sigma_now, t))
                sigma_now = materials.sigma[m]
            o_next = spawn_origin(p, n, err, w)
            t_max = t_max - t
            t_total += t
            o = o_next
        return wp.vec3(0.0), t_total + t_max, NO_HIT, -1

    @wp.func
    def shadow_ray(
        geometry: GeometryData,
        materials: MaterialData,
        is_filtered: bool,
        o: wp.vec3,
        w: wp.vec3,
        t_max: float,
        time: float,
        sigma: wp.vec3,
        rec: RayRecord,
        pixel: wp.int32,
        sample: wp.int32,
        depth: wp.int32,
        parent: wp.int32,
        throughput: wp.vec3,
        medium: wp.int32 = -1,
        key: wp.uint32 = wp.uint32(0),
    ) -> wp.vec3:
        """Transmittance of the shadow ray ``o + s w``, ``0 < s < t_max``, toward a light (unit
        ``w``), starting in a dielectric of absorption coefficient ``sigma`` (``medium_sigma``),
        passing dielectrics when ``is_filtered``; in a scene with participating media (compiled in
        with ``media``) starting in ``medium`` and passing null surfaces (``through_media``), its
        media tracked with the random stream ``key`` (``wrt.kernels.volumes.tracking_key``).

        Recording: the ray is segment ``depth`` of its path, child of record ``parent``, carrying
        ``throughput`` times its transmittance."""
        visible = wp.vec3(0.0)
        t_stop = float(t_max)
        prim_stop = int(NO_HIT)
        inst_stop = int(-1)
        followed = is_filtered  # the blocker is known: no query to find it for the record
        if is_filtered:
            visible, t_stop, prim_stop, inst_stop = filtered(geometry, materials, o, w, t_max, time, sigma)
        elif wp.static(media) and has_media(materials.media):
            visible, t_stop, prim_stop, inst_stop = through_media(geometry, materials, o, w, t_max, time, medium, key)
            visible = wp.cw_mul(visible, beer_lambert(sigma, t_max))
            followed = True
        elif not trace.any_hit(geometry, o, w, time, 0.0, t_max):
            visible = beer_lambert(sigma, t_max)
        if wp.static(record):
            if max_component(visible) > 0.0:
                record_ray(
                    rec,
                    geometry,
                    pixel,
                    sample,
                    wp.static(lit),
                    ray_hit(o, w, time, t_max, NO_HIT, -1),
                    wp.cw_mul(throughput, visible),
                    depth,
                    parent,
                )
            else:
                if not followed:  # the any-hit query does not say where the blocker is
                    t_stop, prim_stop, inst_stop = trace.closest_hit(geometry, o, w, time, 0.0, t_max)
                record_ray(
                    rec,
                    geometry,
                    pixel,
                    sample,
                    wp.static(blocked),
                    ray_hit(o, w, time, t_stop, prim_stop, inst_stop),
                    wp.vec3(0.0),
                    depth,
                    parent,
                )
        return visible

    return shadow_ray
