"""The "path" integrator: unidirectional path tracing with next-event estimation and multiple
importance sampling, converging to the solution of the rendering equation.

Per camera sample one path is traced:

- at diffuse, Phong and glossy surfaces, every light is sampled once (next-event estimation):
  delta lights (point, directional, spot) with a shadow ray; area, sphere and environment lights
  (a constant one uniformly, a map by its luminance) by ``wrt.kernels.emitters`` with a shadow
  ray, weighted against BSDF sampling by the power heuristic; and one emissive primitive of the
  scene's own meshes, triangles, polygons and spheres (``wrt.emitting``: chosen by power, a
  uniform point on a triangle or polygon, a direction in a sphere's cone), weighted likewise;
  then the path continues in a direction drawn from the BSDF (cosine-weighted for diffuse and
  Phong, GGX visible normals for glossy);
- mirrors reflect; dielectrics reflect with probability F (exact Fresnel) or refract, with
  Beer-Lambert absorption and the nested-media rules of ``wrt.kernels.media``; thin dielectrics
  reflect with probability R' or let the path straight on, in the medium it was in; rough
  dielectrics are dielectrics whose reflection and refraction are glossy: lights are sampled on
  both sides of them (a shadow ray across the surface crosses the medium beyond it), and a path
  refracted through one changes medium as through a smooth one; plastics choose their coating or
  their base by a 1D sample, as dielectrics choose reflection or refraction; masks choose their
  inner material (with probability ``opacity``) or their null lobe, which lets the path straight
  on, in the medium it was in, as a segment of its own (Mitsuba 3 counts it in ``max_depth``);
  shadow rays stop at masks, as at every surface, so light beyond one is found by BSDF sampling;
- the back side of a one-sided material (``two_sided = false``) reflects nothing: the path ends
  there, without next-event estimation;
- emission is added where the path hits an emitter's front: fully after the camera or a specular
  bounce, MIS-weighted after a BSDF sample when the emitter is a light or an emissive primitive
  that NEE also samples (other emissive shapes, and shapes seen through instances, are found by
  BSDF sampling only); paths leaving the scene see the
  environment lights, MIS-weighted likewise;
- after ``RR_DEPTH`` segments, Russian roulette continues a path with probability
  min(0.95, largest channel of its throughput) and divides by it (unbiased; Mitsuba's rr_depth 5);
  the throughput it judges leaves out the ``eta^2`` radiance scaling of refractions (pbrt-v4's
  ``etaScale``), so paths inside glass are not killed more often for it.

``max_depth`` counts segments (camera ray = 1; a shadow ray of a hit on segment k is segment
k + 1), as Mitsuba 3's. Random numbers come from the render's sampler (``wrt.kernels.sampling``):
dimensions 0-4 are the camera's (pixel position, lens, time), ``bounce_dim(depth, j)`` are the
BSDF sample (j = 0, 1: a 2D pair), the Fresnel choice (2) and roulette (3) at each bounce, and
``light_dim(depth, i)`` the 2D sample of light i; with n lights, ``light_dim(depth, n)`` is the
point on (or direction toward) an emissive primitive and ``light_dim(depth, n + 1)`` (1D) the
choice of the primitive.
A path's shapes stay at its camera ray's time.
"""

import warp as wp

from .emitters import (
    emitter_pdf,
    environment_map_pdf,
    environment_map_radiance,
    make_emitting_index,
    make_emitting_pdf,
    make_sample_emitting,
    sample_emitter,
    sample_emitter_or_map,
)
from .features import ALL, Features
from .hit import Hit, make_surface_hit_for, normal_map_shadowing
from .integrator import CameraRay, IntegratorSettings, all_features_kernels, make_trace_segment
from .lights import EMITTING, ENVIRONMENT, ENVIRONMENT_MAP, SPOT, LightData, light_incident
from .materials import (
    BSDF_SPECULAR,
    BSDF_THIN,
    BSDF_TOTAL_INTERNAL,
    BSDF_TRANSMISSION,
    MaterialData,
    bsdf_flags_from,
    families_for,
    make_bsdf,
    non_specular,
)
from .media import MEDIA_OVERFLOW, current_ior, dielectric_interface, max_component, medium_sigma, medium_transmittance
from .record import (
    REFLECTED,
    REFRACTED,
    SCATTERED,
    STRAIGHT,
    TOTAL_INTERNAL,
    RayRecord,
)
from .sample_warps import power_heuristic
from .sampling import Sampler, sample_1d, sample_2d
from .shadow import make_shadow_ray
from .spawn import ray_error, spawn_origin
from .traverse import NO_HIT, GeometryData, Traversal, traversal

RR_DEPTH = wp.constant(5)
SHADOW_MARGIN = wp.constant(1.0e-4)  # shadow rays toward a light's surface stop this fraction short of it


@wp.func
def bounce_dim(depth: wp.int32, j: wp.int32) -> wp.int32:
    return 2 + 4 * depth + j


@wp.func
def light_dim(depth: wp.int32, i: wp.int32) -> wp.int32:
    return 1048576 + 2048 * depth + 2 * i


@wp.func
def seen_through(cos_theta: float, flags: wp.int32) -> float:
    """The cosine that lights a surface of BSDF ``flags`` from a direction of cosine ``cos_theta``
    with its shading normal: ``|cos|`` below a surface that transmits (a light seen through rough
    glass), else ``cos`` (``<= 0``: not lit)."""
    if cos_theta < 0.0 and (flags & BSDF_TRANSMISSION) != 0:
        return -cos_theta
    return cos_theta


def make_next_event(record: bool, trace: Traversal, features: Features):
    """``next_event``, recording its shadow rays when ``record``, sampling environment maps and
    emissive primitives when the scene has them, and lights across the surface when it has rough
    dielectrics (each compiled out otherwise)."""
    shadow_ray = make_shadow_ray(record, trace)
    sample_light = sample_emitter_or_map if features.environment_map else sample_emitter
    sample_emitting = make_sample_emitting(features.smooth, features.emissive_shapes)
    bsdf = make_bsdf(families_for(features), features.textures)

    @wp.func
    def next_event(
        geometry: GeometryData,
        materials: MaterialData,
        lights: LightData,
        hit: Hit,
        sampler: Sampler,
        ray: CameraRay,
        depth: wp.int32,
        sigma: wp.vec3,
        rec: RayRecord,
        parent: wp.int32,
        beta: wp.vec3,
        flags: wp.int32,
        eta: float,
        sigma_t: wp.vec3,
    ) -> wp.vec3:
        """Light reflected toward ``hit.wo`` from one sample of every light and one of the emissive
        primitives (the last emitter, ``i == lights.type.shape[0]``), MIS-weighted for emitters
        with area (W/(m^2 sr), before the path's throughput ``beta``); ``sigma`` is the absorption
        of the medium ``hit`` lies in, applied along the shadow rays as along BSDF-sampled paths.
        ``flags`` are the BSDF's; a light below a surface with glossy transmission is seen through
        it (``seen_through``), ``eta`` the ratio of the iors on either side and ``sigma_t`` the
        absorption beyond it.

        Recording: each shadow ray is a segment of ``depth + 1`` segments whose parent is record
        ``parent``, carrying ``beta`` when it reaches its light and 0 when blocked (then ending at
        the blocker)."""
        total = wp.vec3(0.0)
        m = hit.material
        n = hit.n_facing
        wo = hit.wo
        n_lights = lights.type.shape[0]
        n_emitters = n_lights
        if wp.static(features.emissive):
            if lights.emit_cdf.shape[0] > 1:  # not the placeholder of a scene without them
                n_emitters += 1
        for i in range(n_emitters):
            wi = wp.vec3(0.0)
            t_max = float(0.0)
            contribution = wp.vec3(0.0)
            kind = EMITTING
            if i < n_lights:
                kind = lights.type[i]
            if kind <= SPOT:
                wi, dist, irradiance = light_incident(lights, i, hit.p)
                t_max = dist
                cos_theta = wp.dot(n, wi)
                if wp.static(features.rough_dielectric):
                    cos_theta = seen_through(cos_theta, flags)
                if cos_theta > 0.0 and max_component(irradiance) > 0.0:
                    f = wp.static(bsdf.eval)(materials, m, n, wo, wi, eta, hit.uv, hit.front)
                    if wp.static(features.normal_map):
                        f = f * normal_map_shadowing(hit, wi)
                    contribution = wp.cw_mul(f, irradiance) * cos_theta
            else:
                u = sample_2d(sampler, ray.pixel, ray.sample, light_dim(depth, i))
                dist = float(0.0)
                radiance = wp.vec3(0.0)
                pdf = float(0.0)
                if kind == EMITTING:
                    if wp.static(features.emissive):
                        uc = sample_1d(sampler, ray.pixel, ray.sample, light_dim(depth, i + 1))
                        wi, dist, radiance, pdf = wp.static(sample_emitting)(
                            geometry, materials, lights, hit.p, ray.time, uc, u[0], u[1]
                        )
                else:
                    wi, dist, radiance, pdf = wp.static(sample_light)(lights, i, hit.p, u[0], u[1])
                t_max = dist
                if kind != ENVIRONMENT:
                    t_max = dist * (1.0 - SHADOW_MARGIN)
                cos_theta = wp.dot(n, wi)
                if wp.static(features.rough_dielectric):
                    cos_theta = seen_through(cos_theta, flags)
                if pdf > 0.0 and cos_theta > 0.0 and max_component(radiance) > 0.0:
                    mis = power_heuristic(pdf, wp.static(bsdf.pdf)(materials, m, n, wo, wi, eta, hit.uv, hit.front))
                    f = wp.static(bsdf.eval)(materials, m, n, wo, wi, eta, hit.uv, hit.front)
                    if wp.static(features.normal_map):
                        f = f * normal_map_shadowing(hit, wi)
                    contribution = wp.cw_mul(f, radiance) * (cos_theta * mis / pdf)
            if max_component(contribution) > 0.0:
                shadow_sigma = sigma
                if wp.static(features.rough_dielectric):
                    if wp.dot(n, wi) < 0.0:  # a light seen through the surface: the medium beyond it
                        shadow_sigma = sigma_t
                visible = shadow_ray(
                    geometry,
                    materials,
                    False,
                    spawn_origin(hit.p, hit.n, hit.err, wi),
                    wi,
                    t_max,
                    ray.time,
                    shadow_sigma,
                    rec,
                    ray.pixel,
                    ray.sample,
                    depth + 1,
                    parent,
                    beta,
                )
                if max_component(visible) > 0.0:
                    total += wp.cw_mul(contribution, visible)
        return total

    return next_event


def make_environment_radiance(environment_map: bool):
    """``environment_radiance``, with environment maps when ``environment_map`` (compiled out
    otherwise)."""

    @wp.func
    def environment_radiance(lights: LightData, d: wp.vec3, bsdf_pdf_prev: float, specular: bool) -> wp.vec3:
        """Radiance of the environment lights along an escaping ray of direction ``d``, MIS-weighted
        unless the ray came from the camera or a specular bounce."""
        total = wp.vec3(0.0)
        for i in range(lights.type.shape[0]):
            radiance = wp.vec3(0.0)
            light_pdf = float(0.0)
            if lights.type[i] == ENVIRONMENT:
                radiance = lights.power[i]
                light_pdf = 1.0 / (4.0 * wp.pi)
            if wp.static(environment_map):
                if lights.type[i] == ENVIRONMENT_MAP:
                    radiance = environment_map_radiance(lights, i, d)
                    light_pdf = environment_map_pdf(lights, d)
            if max_component(radiance) > 0.0:
                mis = float(1.0)
                if not specular:
                    mis = power_heuristic(bsdf_pdf_prev, light_pdf)
                total += radiance * mis
        return total

    return environment_radiance


def make_path_radiance(record: bool, features: Features = ALL):
    """``path_radiance``, recording every ray it traces when ``record`` (compiled out otherwise),
    with the code of the features the scene lacks compiled out (``wrt.kernels.features``)."""
    trace = traversal(features)
    trace_segment = make_trace_segment(record, trace)
    next_event = make_next_event(record, trace, features)
    environment_radiance = make_environment_radiance(features.environment_map)
    emitting_index = make_emitting_index(features.emissive_shapes)
    emitting_pdf = make_emitting_pdf(features.emissive_shapes)
    bsdf = make_bsdf(families_for(features), features.textures)
    surface_hit = make_surface_hit_for(features)

    @wp.func
    def path_radiance(
        geometry: GeometryData,
        materials: MaterialData,
        lights: LightData,
        settings: IntegratorSettings,
        sampler: Sampler,
        ray: CameraRay,
        rec: RayRecord,
    ) -> wp.vec3:
        """One path's estimate of the radiance (W/(m^2 sr)) arriving at the camera along ``ray``."""
        o = ray.o
        d = ray.d
        t = ray.t
        prim = ray.prim
        inst = ray.inst
        radiance = wp.vec3(0.0)
        beta = wp.vec3(1.0)
        depth = int(1)
        media = settings.camera_media  # the camera may be inside glass or water
        n_media = settings.camera_n_media
        n_camera = float(1.0)  # the ior where the path starts: roulette undoes eta^2 relative to it
        if wp.static(features.dielectric):
            n_camera = current_ior(materials, settings.exterior_ior, media, n_media)
        specular = bool(True)
        prev_pdf = float(0.0)
        prev_p = o
        t_from = float(0.0)
        t_last = float(0.0)
        traced = bool(True)
        current = ray.record  # record index of the segment being followed
        segment_kind = int(SCATTERED)  # how the next segment to trace was spawned (recording)
        for _segment in range(4 * settings.max_depth + 16):
            # Trace the next segment (the camera ray's is traced already)
            if not traced:
                t, prim, inst, current = trace_segment(
                    geometry, rec, ray, segment_kind, o, d, t_from, wp.inf, t_last, beta, depth, current
                )
            traced = False

            # Absorption in the medium the segment crossed
            if wp.static(features.dielectric):
                beta = wp.cw_mul(beta, medium_transmittance(materials, media, n_media, t - t_last))

            # Escaped: the environment lights
            if prim == NO_HIT:
                if wp.static(features.lights):
                    radiance += wp.cw_mul(beta, environment_radiance(lights, d, prev_pdf, specular))
                break

            # Emission at the front of what was hit, MIS-weighted against light sampling
            hit = surface_hit(geometry, materials, o, d, t, prim, inst, ray.time)
            emission = materials.emission[hit.material]
            if hit.front and max_component(emission) > 0.0:
                mis = float(1.0)
                if not specular and hit.shape >= geometry.num_shapes:
                    light = hit.shape - geometry.num_shapes
                    mis = power_heuristic(prev_pdf, emitter_pdf(lights, light, prev_p, d, wp.length(hit.p - prev_p)))
                if wp.static(features.emissive):
                    if not specular and inst < 0:
                        e = wp.static(emitting_index)(lights, prim)
                        if e >= 0:
                            light_pdf = wp.static(emitting_pdf)(
                                geometry, lights, e, prev_p, d, wp.length(hit.p - prev_p)
                            )
                            mis = power_heuristic(prev_pdf, light_pdf)
                radiance += wp.cw_mul(beta, emission) * mis
            flags = bsdf_flags_from(materials, hit.material, hit.front)
            if flags == 0:
                break

            # The media on either side; a false interface lets the ray go straight on (not a
            # segment of its own: max_depth does not end the path there)
            eta = float(1.0)
            media_t = media
            n_media_t = n_media
            if wp.static(features.dielectric):
                if (flags & (BSDF_TRANSMISSION | BSDF_THIN)) == BSDF_TRANSMISSION:  # a thin dielectric bounds none
                    real = bool(True)
                    real, eta, media_t, n_media_t = dielectric_interface(
                        materials, settings.exterior_ior, media, n_media, hit.shape, hit.entering
                    )
                    if n_media_t == MEDIA_OVERFLOW:  # no medium to be in: the sample is lost, and counted
                        radiance = wp.vec3(wp.nan)
                        break
                    if not real:
                        media = media_t
                        n_media = n_media_t
                        t_from = t + ray_error(o, hit.p, t)
                        t_last = t
                        segment_kind = STRAIGHT
                        # a shadow ray stops at this surface, so next-event estimation never finds
                        # what lies beyond it: light found there takes the BSDF sample's full weight
                        specular = True
                        continue
            if depth >= settings.max_depth:
                break

            # Next-event estimation at non-specular surfaces
            if wp.static(features.lights or features.emissive):
                if non_specular(flags):
                    sigma = wp.vec3(0.0)
                    if wp.static(features.dielectric):
                        sigma = medium_sigma(materials, media, n_media)
                    sigma_t = sigma
                    if wp.static(features.rough_dielectric):
                        sigma_t = medium_sigma(materials, media_t, n_media_t)
                    radiance += wp.cw_mul(
                        beta,
                        next_event(
                            geometry,
                            materials,
                            lights,
                            hit,
                            sampler,
                            ray,
                            depth,
                            sigma,
                            rec,
                            current,
                            beta,
                            flags,
                            eta,
                            sigma_t,
                        ),
                    )

            # Sample the BSDF for the next direction
            uc = float(0.0)
            u = wp.vec2(0.0)
            if wp.static(features.specular):
                if (flags & BSDF_TRANSMISSION) != 0 or wp.static(features.plastic):  # a plastic: coating or base
                    uc = sample_1d(sampler, ray.pixel, ray.sample, bounce_dim(depth, 2))
            if non_specular(flags):
                u = sample_2d(sampler, ray.pixel, ray.sample, bounce_dim(depth, 0))
            bs = wp.static(bsdf.sample)(materials, hit.material, hit.n_facing, hit.wo, eta, uc, u, hit.uv, hit.front)
            if bs.pdf == 0.0:
                break
            if wp.static(features.normal_map):
                bs.weight = bs.weight * normal_map_shadowing(hit, bs.wi)
            beta = wp.cw_mul(beta, bs.weight)
            d = bs.wi
            depth += 1
            straight = bool(False)
            if (bs.flags & BSDF_SPECULAR) != 0:
                specular = True
                segment_kind = wp.where((bs.flags & BSDF_TOTAL_INTERNAL) != 0, TOTAL_INTERNAL, REFLECTED)
                if (bs.flags & BSDF_TRANSMISSION) != 0:
                    media = media_t
                    n_media = n_media_t
                    straight = eta == 1.0  # index-matched: straight on
                    segment_kind = wp.where(straight, STRAIGHT, REFRACTED)
            else:
                prev_pdf = bs.pdf
                prev_p = hit.p
                specular = False
                segment_kind = SCATTERED
                if wp.static(features.rough_dielectric):
                    if (bs.flags & BSDF_TRANSMISSION) != 0:  # refracted through a rough dielectric
                        media = media_t
                        n_media = n_media_t

            # Spawn the next segment; Russian roulette past RR_DEPTH
            if straight:
                t_from = t + ray_error(o, hit.p, t)
                t_last = t
            else:
                o = spawn_origin(hit.p, hit.n, hit.err, d)
                t_from = 0.0
                t_last = 0.0
                if depth > RR_DEPTH:
                    n_ratio = float(1.0)  # the throughput without the eta^2 radiance scaling
                    if wp.static(features.dielectric):
                        n_ratio = current_ior(materials, settings.exterior_ior, media, n_media) / n_camera
                    q = wp.min(max_component(beta) * n_ratio * n_ratio, 0.95)
                    if sample_1d(sampler, ray.pixel, ray.sample, bounce_dim(depth, 3)) >= q:
                        break
                    beta = beta / q
        return radiance

    return path_radiance


__getattr__ = all_features_kernels("path", make_path_radiance)  # path, path_record
