"""The "whitted" integrator: recursive ray tracing with shadows, reflection and refraction.

Per camera ray, a ray tree is traced depth first with an explicit stack of pending branches
(no recursion in kernels):

- diffuse and Phong surfaces: direct light from every point, directional and spot light, each
  checked by a shadow ray, plus the (non-physical) ``ambient`` term times the albedo; the path
  ends there;
- mirrors: one reflected branch, throughput times ``reflectance``;
- dielectrics: a reflected branch weighted by the exact Fresnel reflectance F and a refracted
  branch weighted by 1 - F (Snell's law), or only the reflected one under total internal
  reflection; absorption inside follows Beer-Lambert over the distance travelled;
- emission on any material is added where a ray hits its front side; rays that leave the scene
  see ``background``.

Depth: the camera ray is segment 1, each reflected, refracted or shadow ray one more; nothing is
traced past ``max_depth`` segments (so direct light needs ``max_depth >= 2``). A branch whose
throughput falls below ``min_throughput`` (largest channel) is cut. At a dielectric the heavier
branch is followed first and the lighter one deferred; when a path ends, the heaviest deferred
branch is resumed. At most ``BRANCHES`` wait, and when they are full the lightest branch
(deferred or new) is dropped, so the energy lost to the bound is the smallest available. A camera
ray's whole tree stops at ``MAX_SEGMENTS`` segments (light trapped by total internal reflection
with a tiny ``min_throughput`` can reach it; what is left then is the lightest).

A ray that goes straight on through a surface (a false interface between media, or an
index-matched one) keeps its origin and direction: only its ``t_min`` moves past the hit by the
hit's error bound, so an ior-1.0 object is exactly invisible at any distance from the origin.

Media: each branch carries the stack of dielectrics it is inside (``wrt.kernels.media``): nested
and overlapping dielectrics, with ``priority`` for overlaps.

Recording: ``whitted_record`` is the same integrator with every traced ray appended to a
``wrt.kernels.record.RayRecord``: each segment traced in the loop (kind ``REFLECTED``,
``REFRACTED``, ``TOTAL_INTERNAL`` or ``STRAIGHT`` through a false interface) and each shadow ray
(``SHADOW_LIT`` to the light, or ``SHADOW_BLOCKED`` ending where it was stopped). Branches that
are cut (depth, throughput, stack bound) are not traced and so not recorded. The decisions are
the render variant's; only a blocked shadow ray needs one extra closest-hit query, because the
any-hit query that decides visibility does not say where the blocker is.

References
----------
T. Whitted, "An Improved Illumination Model for Shaded Display", CACM 23(6), 1980.
C. Schmidt, B. Budge, "Simple Nested Dielectrics in Ray Traced Images", JGT 7(2), 2002.
"""

import warp as wp

from .features import ALL, Features
from .integrator import IntegratorSettings, make_render_kernel
from .lights import LightData, light_incident
from .materials import DIELECTRIC, DIFFUSE, GLOSSY, MIRROR, PHONG, MaterialData, beer_lambert, eval_brdf
from .media import MEDIA, Media, current_medium, dielectric_interface, max_component
from .optics import fresnel_dielectric, reflect, refract
from .record import REFLECTED, REFRACTED, SHADOW_BLOCKED, SHADOW_LIT, STRAIGHT, TOTAL_INTERNAL, RayRecord, record_ray
from .sampling import Sampler
from .spawn import hit_error, spawn_origin
from .traverse import NO_HIT, GeometryData, Traversal, geometric_normal, prim_shape, traversal

BRANCHES = 32  # pending branches per camera ray
MAX_SEGMENTS = wp.constant(4096)  # hard stop per camera ray, whatever happens (deferred branches: heaviest first)
SHADOW_CROSSINGS = wp.constant(16)  # dielectric surfaces a filtered shadow ray may pass
BranchVec3 = wp.types.matrix(shape=(BRANCHES, 3), dtype=float)
BranchMedia = wp.types.matrix(shape=(BRANCHES, MEDIA), dtype=wp.int32)
BranchInt = wp.types.vector(length=BRANCHES, dtype=wp.int32)


@wp.func
def lightest_branch(throughput: BranchVec3, count: wp.int32) -> wp.int32:
    """Index of the deferred branch with the smallest throughput (largest channel)."""
    best = int(0)
    for k in range(1, count):
        if max_component(throughput[k]) < max_component(throughput[best]):
            best = k
    return best


@wp.func
def heaviest_branch(throughput: BranchVec3, count: wp.int32) -> wp.int32:
    """Index of the deferred branch with the largest throughput (largest channel)."""
    best = int(0)
    for k in range(1, count):
        if max_component(throughput[k]) > max_component(throughput[best]):
            best = k
    return best


def make_shadows(trace: Traversal):
    """``shadow_transmittance`` and ``shadow_blocker`` over the traversal ``trace``."""

    @wp.func
    def shadow_transmittance(
        geometry: GeometryData,
        materials: MaterialData,
        settings: IntegratorSettings,
        o: wp.vec3,
        w: wp.vec3,
        t_max: float,
        time: float,
    ) -> wp.vec3:
        """Fraction of a light's radiance reaching ``o`` from direction ``w`` over distance ``t_max``.

        Opaque mode (default, physical for a ray tracer without caustics): 0 if anything is in the
        way, else 1. Filtered mode (the lecture's): dielectrics let the shadow ray through in a
        straight line, attenuated by Beer-Lambert over the length inside them; anything else blocks.
        """
        if settings.filtered_shadows == 0:
            if trace.any_hit(geometry, o, w, time, 0.0, t_max):
                return wp.vec3(0.0)
            return wp.vec3(1.0)
        transmittance = wp.vec3(1.0)
        for _k in range(SHADOW_CROSSINGS):
            t, prim = trace.closest_hit(geometry, o, w, time, 0.0, t_max)
            if prim == NO_HIT:
                return transmittance
            m = materials.shape_material[prim_shape(geometry, prim)]
            if materials.type[m] != DIELECTRIC:
                return wp.vec3(0.0)
            p = o + t * w
            n = geometric_normal(geometry, prim, p, time)
            if wp.dot(w, n) > 0.0:  # leaving: the segment just travelled was inside
                transmittance = wp.cw_mul(transmittance, beer_lambert(materials.sigma[m], t))
            o_next = spawn_origin(p, n, hit_error(o, p, t), w)
            t_max = t_max - t
            o = o_next
        return wp.vec3(0.0)

    @wp.func
    def shadow_blocker(
        geometry: GeometryData,
        materials: MaterialData,
        settings: IntegratorSettings,
        o: wp.vec3,
        w: wp.vec3,
        t_max: float,
        time: float,
    ):
        """Recording only: ``(t, prim)`` of the surface that stopped a blocked shadow ray from ``o``
        along unit ``w``: the first surface hit, or with filtered shadows the first one that is not a
        dielectric (``NO_HIT`` and ``t_max`` if there is none)."""
        t_total = float(0.0)
        for _k in range(SHADOW_CROSSINGS):
            t, prim = trace.closest_hit(geometry, o, w, time, 0.0, t_max - t_total)
            if prim == NO_HIT or settings.filtered_shadows == 0:
                return t_total + t, prim
            if materials.type[materials.shape_material[prim_shape(geometry, prim)]] != DIELECTRIC:
                return t_total + t, prim
            p = o + t * w
            o = spawn_origin(p, geometric_normal(geometry, prim, p, time), hit_error(o, p, t), w)
            t_total += t
        return t_max, NO_HIT

    return shadow_transmittance, shadow_blocker


def make_direct_light(record: bool, trace: Traversal):
    """``direct_light``, recording its shadow rays when ``record`` (compiled out otherwise)."""
    shadow_transmittance, shadow_blocker = make_shadows(trace)

    @wp.func
    def direct_light(
        geometry: GeometryData,
        materials: MaterialData,
        lights: LightData,
        settings: IntegratorSettings,
        m: wp.int32,
        p: wp.vec3,
        n: wp.vec3,
        err: float,
        wo: wp.vec3,
        time: float,
        rec: RayRecord,
        pixel: wp.int32,
        sample: wp.int32,
        parent: wp.int32,
        depth: wp.int32,
        throughput: wp.vec3,
    ) -> wp.vec3:
        """Reflected radiance (W/(m^2 sr)) toward ``wo`` at ``p`` (unit normal ``n`` on ``wo``'s side)
        from all delta lights: sum of BRDF * irradiance * cos * shadow transmittance.

        Recording: each shadow ray is a segment of ``depth`` (the segment count it brings the path
        to) whose parent is record ``parent``, carrying ``throughput`` times its transmittance.
        """
        total = wp.vec3(0.0)
        for i in range(lights.type.shape[0]):
            wi, dist, irradiance = light_incident(lights, i, p)
            cos_theta = wp.dot(n, wi)
            if cos_theta > 0.0 and max_component(irradiance) > 0.0:
                o_shadow = spawn_origin(p, n, err, wi)
                visible = shadow_transmittance(geometry, materials, settings, o_shadow, wi, dist, time)
                total += wp.cw_mul(wp.cw_mul(eval_brdf(materials, m, n, wo, wi), irradiance), visible) * cos_theta
                if wp.static(record):
                    if max_component(visible) > 0.0:
                        record_ray(
                            rec,
                            geometry,
                            pixel,
                            sample,
                            SHADOW_LIT,
                            o_shadow,
                            wi,
                            dist,
                            NO_HIT,
                            time,
                            wp.cw_mul(throughput, visible),
                            depth,
                            parent,
                        )
                    else:
                        t_block, prim_block = shadow_blocker(geometry, materials, settings, o_shadow, wi, dist, time)
                        record_ray(
                            rec,
                            geometry,
                            pixel,
                            sample,
                            SHADOW_BLOCKED,
                            o_shadow,
                            wi,
                            t_block,
                            prim_block,
                            time,
                            wp.vec3(0.0),
                            depth,
                            parent,
                        )
        return total

    return direct_light


def make_whitted_radiance(record: bool, features: Features = ALL):
    """``whitted_radiance``, recording every ray it traces when ``record`` (compiled out otherwise),
    with the code of the features the scene lacks compiled out (``wrt.kernels.features``): without
    mirrors and dielectrics there is no branch stack and the camera ray's hit is the whole tree."""
    trace = traversal(features)
    direct_light = make_direct_light(record, trace)

    @wp.func
    def whitted_radiance(
        geometry: GeometryData,
        materials: MaterialData,
        lights: LightData,
        settings: IntegratorSettings,
        o: wp.vec3,
        d: wp.vec3,
        t: float,
        prim: wp.int32,
        time: float,
        rec: RayRecord,
        sampler: Sampler,
        pixel: wp.int32,
        sample: wp.int32,
        parent: wp.int32,
    ) -> wp.vec3:
        """Radiance (W/(m^2 sr)) arriving at ``o`` from direction ``-d``; ``(t, prim)`` is the ray's
        first hit, ``parent`` its record index (recording only)."""
        radiance = wp.vec3(0.0)
        throughput = wp.vec3(1.0)
        depth = int(1)
        media = Media(-1, -1, -1, -1)
        n_media = int(0)
        n_pending = int(0)
        if wp.static(features.specular):
            pending_origin = BranchVec3()
            pending_dir = BranchVec3()
            pending_throughput = BranchVec3()
            pending_depth = BranchInt()
            pending_media = BranchMedia()
            pending_n_media = BranchInt()
        traced = bool(True)
        # The ray being followed is o + s d for s > t_from; t_last is where its current segment
        # began. A ray that goes straight on through a surface (a false interface, or an
        # index-matched one) keeps its origin and line, and only t_from moves past the hit:
        # re-spawning it off the surface would shift it sideways by the offset.
        t_from = float(0.0)
        t_last = float(0.0)
        current = parent  # record index of the segment being followed
        if wp.static(record):  # how the next segment to trace was spawned, and from which record
            segment_kind = int(REFLECTED)  # set again before every trace (the pixel loop records the camera ray)
            segment_parent = parent
            if wp.static(features.specular):
                pending_kind = BranchInt()
                pending_parent = BranchInt()
        for _segment in range(MAX_SEGMENTS):
            if not traced:
                t, prim = trace.closest_hit(geometry, o, d, time, t_from, wp.inf)
                if wp.static(record):
                    current = record_ray(
                        rec,
                        geometry,
                        pixel,
                        sample,
                        segment_kind,
                        o + t_last * d,
                        d,
                        t - t_last,
                        prim,
                        time,
                        throughput,
                        depth,
                        segment_parent,
                    )
            traced = False
            if wp.static(features.dielectric):
                slot = current_medium(materials, media, n_media)
                if slot >= 0:  # absorption along the segment just travelled (infinite if it escapes)
                    throughput = wp.cw_mul(
                        throughput, beer_lambert(materials.sigma[materials.shape_material[media[slot]]], t - t_last)
                    )
            go_on = bool(False)
            if prim == NO_HIT:
                radiance += wp.cw_mul(throughput, settings.background)
            else:
                p = o + t * d
                n = geometric_normal(geometry, prim, p, time)
                shape = prim_shape(geometry, prim)
                m = materials.shape_material[shape]
                entering = wp.dot(d, n) < 0.0
                n_facing = n
                if not entering:
                    n_facing = -n
                else:
                    radiance += wp.cw_mul(throughput, materials.emission[m])
                err = hit_error(o, p, t)
                kind = materials.type[m]
                if kind == DIFFUSE or kind == PHONG or kind == GLOSSY:
                    local = wp.cw_mul(settings.ambient, materials.albedo[m])
                    if wp.static(features.lights):
                        if depth < settings.max_depth:
                            local += direct_light(
                                geometry,
                                materials,
                                lights,
                                settings,
                                m,
                                p,
                                n_facing,
                                err,
                                -d,
                                time,
                                rec,
                                pixel,
                                sample,
                                current,
                                depth + 1,
                                throughput,
                            )
                    radiance += wp.cw_mul(throughput, local)
                if wp.static(features.specular):
                    if kind == MIRROR:
                        throughput = wp.cw_mul(throughput, materials.reflectance[m])
                        if depth < settings.max_depth and max_component(throughput) >= settings.min_throughput:
                            d = reflect(d, n_facing)
                            o = spawn_origin(p, n, err, d)
                            t_from = 0.0
                            t_last = 0.0
                            depth += 1
                            go_on = True
                            if wp.static(record):
                                segment_kind = REFLECTED
                                segment_parent = current
                if wp.static(features.dielectric):
                    if kind == DIELECTRIC:
                        real, n1, n2, media_t, n_media_t = dielectric_interface(
                            materials, settings, media, n_media, shape, entering
                        )
                        if not real:
                            t_from = t + err
                            t_last = t
                            media = media_t
                            n_media = n_media_t
                            go_on = True
                            if wp.static(record):
                                segment_kind = STRAIGHT
                                segment_parent = current
                        elif depth < settings.max_depth:
                            eta = n1 / n2
                            fresnel = fresnel_dielectric(-wp.dot(d, n_facing), eta)
                            ok, wt = refract(d, n_facing, eta)
                            if not ok:
                                fresnel = 1.0
                            wr = reflect(d, n_facing)
                            reflected = throughput * fresnel
                            transmitted = throughput * (1.0 - fresnel)
                            keep_r = (
                                max_component(reflected) > 0.0 and max_component(reflected) >= settings.min_throughput
                            )
                            keep_t = (
                                ok
                                and max_component(transmitted) > 0.0
                                and max_component(transmitted) >= settings.min_throughput
                            )
                            # Follow the heavier branch now and defer the lighter one. A full stack
                            # evicts its lightest entry if the new one is heavier, else drops the new one.
                            if keep_r and keep_t:
                                defer_reflected = max_component(reflected) < max_component(transmitted)
                                weight = wp.min(max_component(reflected), max_component(transmitted))
                                slot_new = n_pending
                                if n_pending == BRANCHES:
                                    slot_new = lightest_branch(pending_throughput, n_pending)
                                    if max_component(pending_throughput[slot_new]) >= weight:
                                        slot_new = -1
                                else:
                                    n_pending += 1
                                if slot_new >= 0:
                                    if defer_reflected:
                                        pending_origin[slot_new] = spawn_origin(p, n, err, wr)
                                        pending_dir[slot_new] = wr
                                        pending_throughput[slot_new] = reflected
                                        pending_media[slot_new] = media
                                        pending_n_media[slot_new] = n_media
                                    else:
                                        pending_origin[slot_new] = spawn_origin(p, n, err, wt)
                                        pending_dir[slot_new] = wt
                                        pending_throughput[slot_new] = transmitted
                                        pending_media[slot_new] = media_t
                                        pending_n_media[slot_new] = n_media_t
                                    pending_depth[slot_new] = depth + 1
                                    if wp.static(record):
                                        pending_kind[slot_new] = wp.where(defer_reflected, REFLECTED, REFRACTED)
                                        pending_parent[slot_new] = current
                                keep_r = not defer_reflected
                                keep_t = defer_reflected
                            if keep_r:
                                d = wr
                                throughput = reflected
                            elif keep_t:
                                d = wt
                                throughput = transmitted
                                media = media_t
                                n_media = n_media_t
                            if keep_t and eta == 1.0:  # index-matched: straight on (refract returned d)
                                t_from = t + err
                                t_last = t
                            elif keep_r or keep_t:
                                o = spawn_origin(p, n, err, d)
                                t_from = 0.0
                                t_last = 0.0
                            if keep_r or keep_t:
                                depth += 1
                                go_on = True
                                if wp.static(record):
                                    segment_kind = wp.where(keep_r, wp.where(ok, REFLECTED, TOTAL_INTERNAL), REFRACTED)
                                    segment_parent = current
            if not go_on:
                if wp.static(not features.specular):
                    break
                if wp.static(features.specular):
                    if n_pending == 0:
                        break
                    # resume the heaviest deferred branch, so that what the segment budget may leave
                    # untraced is the lightest light; the last entry fills its slot
                    k = heaviest_branch(pending_throughput, n_pending)
                    o = pending_origin[k]
                    d = pending_dir[k]
                    t_from = 0.0
                    t_last = 0.0
                    throughput = pending_throughput[k]
                    depth = pending_depth[k]
                    media = pending_media[k]
                    n_media = pending_n_media[k]
                    if wp.static(record):
                        segment_kind = pending_kind[k]
                        segment_parent = pending_parent[k]
                    n_pending -= 1
                    pending_origin[k] = pending_origin[n_pending]
                    pending_dir[k] = pending_dir[n_pending]
                    pending_throughput[k] = pending_throughput[n_pending]
                    pending_depth[k] = pending_depth[n_pending]
                    pending_media[k] = pending_media[n_pending]
                    pending_n_media[k] = pending_n_media[n_pending]
                    if wp.static(record):
                        pending_kind[k] = pending_kind[n_pending]
                        pending_parent[k] = pending_parent[n_pending]
        return radiance

    return whitted_radiance


whitted = make_render_kernel(make_whitted_radiance(False))
whitted_record = make_render_kernel(make_whitted_radiance(True), record=True)
