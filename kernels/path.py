"""The "path" integrator: unidirectional path tracing with next-event estimation and multiple
importance sampling, converging to the solution of the rendering equation.

Per camera sample one path is traced:

- at diffuse, Phong and glossy surfaces, every light is sampled once (next-event estimation):
  delta lights (point, directional, spot) with a shadow ray; area, sphere and environment lights
  by ``wrt.kernels.emitters`` with a shadow ray, weighted against BSDF sampling by the power heuristic;
  then the path continues in a direction drawn from the BSDF (cosine-weighted for diffuse and
  Phong, GGX visible normals for glossy);
- mirrors reflect; dielectrics reflect with probability F (exact Fresnel) or refract, with
  Beer-Lambert absorption and the nested-media rules of ``wrt.kernels.media``;
- emission is added where the path hits an emitter's front: fully after the camera or a specular
  bounce, MIS-weighted after a BSDF sample when the emitter is a light that NEE also samples
  (emissive materials of shapes are found by BSDF sampling only); paths leaving the scene see the
  environment lights, MIS-weighted likewise;
- after ``RR_DEPTH`` segments, Russian roulette continues a path with probability
  min(0.95, largest channel of its throughput) and divides by it (unbiased; Mitsuba's rr_depth 5).

``max_depth`` counts segments (camera ray = 1; a shadow ray of a hit on segment k is segment
k + 1), as Mitsuba 3's. Random numbers come from the render's sampler (``wrt.kernels.sampling``):
dimensions 0-4 are the camera's (pixel position, lens, time), ``bounce_dim(depth, j)`` are the
BSDF sample (j = 0, 1: a 2D pair), the Fresnel choice (2) and roulette (3) at each bounce, and
``light_dim(depth, i)`` the 2D sample of light i. A path's shapes stay at its camera ray's time.
"""

import warp as wp

from .emitters import emitter_pdf, sample_emitter
from .features import ALL, Features
from .integrator import IntegratorSettings, make_render_kernel
from .lights import ENVIRONMENT, SPOT, LightData, light_incident
from .materials import DIELECTRIC, EMITTER, GLOSSY, MIRROR, MaterialData, beer_lambert, eval_brdf
from .media import Media, current_medium, dielectric_interface, max_component
from .microfacet import ggx_g1, ggx_pdf, ggx_sample_visible_normal
from .optics import fresnel_dielectric, reflect, refract
from .record import (
    REFLECTED,
    REFRACTED,
    SCATTERED,
    SHADOW_BLOCKED,
    SHADOW_LIT,
    STRAIGHT,
    TOTAL_INTERNAL,
    RayRecord,
    record_ray,
)
from .sample_warps import cosine_hemisphere, frame, power_heuristic
from .sampling import Sampler, sample_1d, sample_2d
from .spawn import hit_error, spawn_origin
from .traverse import NO_HIT, GeometryData, Traversal, geometric_normal, prim_shape, traversal

RR_DEPTH = wp.constant(5)
SHADOW_MARGIN = wp.constant(1.0e-4)  # shadow rays toward a light's surface stop this fraction short of it


@wp.func
def bounce_dim(depth: wp.int32, j: wp.int32) -> wp.int32:
    return 2 + 4 * depth + j


@wp.func
def light_dim(depth: wp.int32, i: wp.int32) -> wp.int32:
    return 1048576 + 2048 * depth + 2 * i


@wp.func
def bsdf_pdf(materials: MaterialData, m: wp.int32, n: wp.vec3, wo: wp.vec3, wi: wp.vec3) -> float:
    """Solid-angle density with which ``sample_bsdf`` draws ``wi`` (non-specular materials)."""
    if materials.type[m] == GLOSSY:
        to_local = wp.transpose(frame(n))
        return ggx_pdf(to_local * wo, to_local * wi, materials.roughness[m])
    return wp.max(0.0, wp.dot(n, wi)) / wp.pi


@wp.func
def sample_bsdf(materials: MaterialData, m: wp.int32, n: wp.vec3, wo: wp.vec3, u1: float, u2: float):
    """A direction from the BSDF of a diffuse, Phong or glossy material: ``(wi, weight, pdf)``
    with ``weight = f cos / pdf``; ``pdf == 0`` when the sample is lost (below the surface)."""
    to_world = frame(n)
    if materials.type[m] == GLOSSY:
        to_local = wp.transpose(to_world)
        wo_local = to_local * wo
        alpha = materials.roughness[m]
        h = ggx_sample_visible_normal(wo_local, alpha, u1, u2)
        wi_local = 2.0 * wp.dot(wo_local, h) * h - wo_local
        if wi_local[2] <= 0.0:
            return to_world * wi_local, wp.vec3(0.0), 0.0
        weight = materials.reflectance[m] * ggx_g1(wi_local, alpha)
        return to_world * wi_local, weight, ggx_pdf(wo_local, wi_local, alpha)
    wi = to_world * cosine_hemisphere(u1, u2)
    cos_theta = wp.dot(n, wi)
    if cos_theta <= 0.0:
        return wi, wp.vec3(0.0), 0.0
    pdf = cos_theta / wp.pi
    return wi, eval_brdf(materials, m, n, wo, wi) * (cos_theta / pdf), pdf


def make_next_event(record: bool, trace: Traversal):
    """``next_event``, recording its shadow rays when ``record`` (compiled out otherwise)."""

    @wp.func
    def next_event(
        geometry: GeometryData,
        materials: MaterialData,
        lights: LightData,
        m: wp.int32,
        p: wp.vec3,
        n: wp.vec3,
        err: float,
        wo: wp.vec3,
        time: float,
        sampler: Sampler,
        pixel: wp.int32,
        sample: wp.int32,
        depth: wp.int32,
        rec: RayRecord,
        parent: wp.int32,
        beta: wp.vec3,
    ) -> wp.vec3:
        """Light reflected toward ``wo`` at ``p`` from one sample of every light, MIS-weighted for
        lights with area (W/(m^2 sr), before the path's throughput ``beta``).

        Recording: each shadow ray is a segment of ``depth + 1`` segments whose parent is record
        ``parent``, carrying ``beta`` when it reaches its light and 0 when blocked (then ending at
        the blocker)."""
        total = wp.vec3(0.0)
        for i in range(lights.type.shape[0]):
            wi = wp.vec3(0.0)
            t_max = float(0.0)
            contribution = wp.vec3(0.0)
            if lights.type[i] <= SPOT:
                wi, dist, irradiance = light_incident(lights, i, p)
                t_max = dist
                cos_theta = wp.dot(n, wi)
                if cos_theta > 0.0 and max_component(irradiance) > 0.0:
                    contribution = wp.cw_mul(eval_brdf(materials, m, n, wo, wi), irradiance) * cos_theta
            else:
                u = sample_2d(sampler, pixel, sample, light_dim(depth, i))
                wi, dist, radiance, pdf = sample_emitter(lights, i, p, u[0], u[1])
                t_max = dist
                if lights.type[i] != ENVIRONMENT:
                    t_max = dist * (1.0 - SHADOW_MARGIN)
                cos_theta = wp.dot(n, wi)
                if pdf > 0.0 and cos_theta > 0.0 and max_component(radiance) > 0.0:
                    mis = power_heuristic(pdf, bsdf_pdf(materials, m, n, wo, wi))
                    contribution = wp.cw_mul(eval_brdf(materials, m, n, wo, wi), radiance) * (cos_theta * mis / pdf)
            if max_component(contribution) > 0.0:
                o_shadow = spawn_origin(p, n, err, wi)
                if not trace.any_hit(geometry, o_shadow, wi, time, 0.0, t_max):
                    total += contribution
                    if wp.static(record):
                        record_ray(
                            rec,
                            geometry,
                            pixel,
                            sample,
                            SHADOW_LIT,
                            o_shadow,
                            wi,
                            t_max,
                            NO_HIT,
                            time,
                            beta,
                            depth + 1,
                            parent,
                        )
                elif wp.static(record):
                    t_block, prim_block = trace.closest_hit(geometry, o_shadow, wi, time, 0.0, t_max)
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
                        depth + 1,
                        parent,
                    )
        return total

    return next_event


@wp.func
def environment_radiance(lights: LightData, bsdf_pdf_prev: float, specular: bool) -> wp.vec3:
    """Radiance of the environment lights along an escaping ray, MIS-weighted unless the ray came
    from the camera or a specular bounce."""
    total = wp.vec3(0.0)
    for i in range(lights.type.shape[0]):
        if lights.type[i] == ENVIRONMENT:
            mis = float(1.0)
            if not specular:
                mis = power_heuristic(bsdf_pdf_prev, 1.0 / (4.0 * wp.pi))
            total += lights.power[i] * mis
    return total


def make_path_radiance(record: bool, features: Features = ALL):
    """``path_radiance``, recording every ray it traces when ``record`` (compiled out otherwise),
    with the code of the features the scene lacks compiled out (``wrt.kernels.features``)."""
    trace = traversal(features)
    next_event = make_next_event(record, trace)

    @wp.func
    def path_radiance(
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
        """One path's estimate of the radiance (W/(m^2 sr)) arriving at ``o`` from ``-d``; ``(t, prim)``
        is the camera ray's first hit."""
        radiance = wp.vec3(0.0)
        beta = wp.vec3(1.0)
        depth = int(1)
        media = Media(-1, -1, -1, -1)
        n_media = int(0)
        specular = bool(True)
        prev_pdf = float(0.0)
        prev_p = o
        t_from = float(0.0)
        t_last = float(0.0)
        traced = bool(True)
        current = parent  # record index of the segment being followed
        if wp.static(record):  # how the next segment to trace was spawned
            segment_kind = int(SCATTERED)
        for _segment in range(4 * settings.max_depth + 16):
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
                        beta,
                        depth,
                        current,
                    )
            traced = False
            if wp.static(features.dielectric):
                slot = current_medium(materials, media, n_media)
                if slot >= 0:
                    beta = wp.cw_mul(
                        beta, beer_lambert(materials.sigma[materials.shape_material[media[slot]]], t - t_last)
                    )
            if prim == NO_HIT:
                if wp.static(features.lights):
                    radiance += wp.cw_mul(beta, environment_radiance(lights, prev_pdf, specular))
                break
            p = o + t * d
            n = geometric_normal(geometry, prim, p, time)
            surface = prim_shape(geometry, prim)
            m = materials.shape_material[surface]
            entering = wp.dot(d, n) < 0.0
            n_facing = n
            if not entering:
                n_facing = -n
            if entering and max_component(materials.emission[m]) > 0.0:
                mis = float(1.0)
                if not specular and surface >= geometry.num_shapes:
                    mis = power_heuristic(
                        prev_pdf, emitter_pdf(lights, surface - geometry.num_shapes, prev_p, d, wp.length(p - prev_p))
                    )
                radiance += wp.cw_mul(beta, materials.emission[m]) * mis
            kind = materials.type[m]
            if kind == EMITTER or depth >= settings.max_depth:
                break
            err = hit_error(o, p, t)
            wo = -d
            straight = bool(False)
            scattered = bool(True)  # diffuse, Phong or glossy: next-event estimation and a BSDF sample
            if wp.static(features.dielectric):
                if kind == DIELECTRIC:
                    scattered = False
                    real, n1, n2, media_t, n_media_t = dielectric_interface(
                        materials, settings, media, n_media, surface, entering
                    )
                    if not real:
                        straight = True
                        media = media_t
                        n_media = n_media_t
                        if wp.static(record):
                            segment_kind = STRAIGHT
                    else:
                        eta = n1 / n2
                        fresnel = fresnel_dielectric(wp.dot(wo, n_facing), eta)
                        ok, wt = refract(d, n_facing, eta)
                        if not ok:
                            fresnel = 1.0
                        if sample_1d(sampler, pixel, sample, bounce_dim(depth, 2)) < fresnel:
                            d = reflect(d, n_facing)
                            if wp.static(record):
                                segment_kind = wp.where(ok, REFLECTED, TOTAL_INTERNAL)
                        else:
                            media = media_t
                            n_media = n_media_t
                            if eta == 1.0:
                                straight = True
                            else:
                                d = wt
                            if wp.static(record):
                                segment_kind = wp.where(eta == 1.0, STRAIGHT, REFRACTED)
                        specular = True
                        depth += 1
            if kind == MIRROR:
                scattered = False
                beta = wp.cw_mul(beta, materials.reflectance[m])
                d = reflect(d, n_facing)
                specular = True
                depth += 1
                if wp.static(record):
                    segment_kind = REFLECTED
            if scattered:
                if wp.static(features.lights):
                    radiance += wp.cw_mul(
                        beta,
                        next_event(
                            geometry,
                            materials,
                            lights,
                            m,
                            p,
                            n_facing,
                            err,
                            wo,
                            time,
                            sampler,
                            pixel,
                            sample,
                            depth,
                            rec,
                            current,
                            beta,
                        ),
                    )
                u = sample_2d(sampler, pixel, sample, bounce_dim(depth, 0))
                wi, bsdf_weight, pdf = sample_bsdf(materials, m, n_facing, wo, u[0], u[1])
                if pdf == 0.0:
                    break
                beta = wp.cw_mul(beta, bsdf_weight)
                d = wi
                prev_pdf = pdf
                prev_p = p
                specular = False
                depth += 1
                if wp.static(record):
                    segment_kind = SCATTERED
            if straight:
                t_from = t + err
                t_last = t
            else:
                o = spawn_origin(p, n, err, d)
                t_from = 0.0
                t_last = 0.0
                if depth > RR_DEPTH:
                    q = wp.min(max_component(beta), 0.95)
                    if sample_1d(sampler, pixel, sample, bounce_dim(depth, 3)) >= q:
                        break
                    beta = beta / q
        return radiance

    return path_radiance


path = make_render_kernel(make_path_radiance(False))
path_record = make_render_kernel(make_path_radiance(True), record=True)
