"""The "path" integrator: unidirectional path tracing with next-event estimation and multiple
importance sampling, converging to the solution of the rendering equation.

Per camera sample one path is traced:

- at diffuse, Phong and glossy surfaces, every light is sampled once (next-event estimation):
  delta lights (point, directional, spot) with a shadow ray; area, sphere and environment lights
  (a constant one uniformly, a map by its luminance) by ``wrt.kernels.lights`` with a shadow
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
  bounce, MIS-weighted after a BSDF sample when the emitter is a light's surface or an emissive primitive
  that NEE also samples (other emissive shapes, and shapes seen through instances, are found by
  BSDF sampling only); paths leaving the scene see the
  environment lights, MIS-weighted likewise; an emissive medium's radiance along each segment in
  it is added in full (``FreeFlight.emitted``: found by the path only, never light-sampled);
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
choice of the primitive; ``flight_dim(vertex)`` is a free flight's first number in a medium, and
``track_dim`` and ``shadow_track_dim`` key the streams a heterogeneous medium tracks with
(``wrt.kernels.volumes.tracking_key``).
A path's shapes stay at its camera ray's time.
"""

import warp as wp

from . import hinted_func
from .features import ALL, Features
from .hit import Hit, make_surface_hit_for, normal_map_shadowing
from .integrator import CameraRay, IntegratorSettings, camera_hit, make_trace_segment
from .lights import LightData, lighting_for
from .materials import (
    BSDF_SPECULAR,
    BSDF_THIN,
    BSDF_TRANSMISSION,
    NULL,
    THIN_DIELECTRIC,
    MaterialData,
    bsdf_flags_from,
    families_for,
    make_bsdf,
    non_specular,
)
from .media import (
    MEDIA_OVERFLOW,
    Media,
    cross_interface,
    current_ior,
    max_component,
    medium_sigma,
    medium_transmittance,
    no_interface,
)
from .record import SCATTERED, STRAIGHT, RayRecord, bounce_kind, end_in_medium
from .sample_warps import power_heuristic
from .sampling import Sampler, sample_1d, sample_2d
from .shadow import make_shadow_ray
from .spawn import past_hit, spawn_origin
from .textures import EMISSION, material_rgb
from .traverse import NO_HIT, GeometryData, Traversal, traversal
from .volumes import boundary_medium, free_flight, has_media, phase_sample, phase_value, tracking_key

RR_DEPTH = wp.constant(5)


@wp.func
def bounce_dim(depth: wp.int32, j: wp.int32) -> wp.int32:
    return 2 + 4 * depth + j


@wp.func
def light_dim(depth: wp.int32, i: wp.int32) -> wp.int32:
    return 1048576 + 2048 * depth + 2 * i


@wp.func
def flight_dim(vertex: wp.int32) -> wp.int32:
    return 33554432 + vertex


@wp.func
def track_dim(vertex: wp.int32) -> wp.int32:
    return 50331648 + vertex


@wp.func
def shadow_track_dim(vertex: wp.int32, i: wp.int32) -> wp.int32:
    return 67108864 + 2048 * vertex + i


@wp.func
def seen_through(cos_theta: float, flags: wp.int32) -> float:
    """The cosine that lights a surface of BSDF ``flags`` from a direction of cosine ``cos_theta``
    with its shading normal: ``|cos|`` below a surface that transmits (a light seen through rough
    glass), else ``cos`` (``<= 0``: not lit)."""
    if cos_theta < 0.0 and (flags & BSDF_TRANSMISSION) != 0:
        return -cos_theta
    return cos_theta


@wp.struct
class PathState:
    """What a path carries from one segment to the next."""

    o: wp.vec3  # the ray being followed is o + s d for s > t_from (unit d); its segment began at t_last
    d: wp.vec3
    t_from: float
    t_last: float
    throughput: wp.vec3  # the path's weight so far, including the eta^2 radiance scaling of refractions
    radiance: wp.vec3  # what the path has gathered (W/(m^2 sr))
    depth: wp.int32  # segments so far (the camera ray is 1)
    media: Media  # the dielectrics the ray is inside (wrt.kernels.media)
    n_media: wp.int32
    n_camera: float  # the ior where the path started: its eta scale is (current ior / n_camera)^2
    specular: bool  # the last bounce was specular (or the camera's): emission found takes its full weight
    prev_pdf: float  # the density of the last non-specular BSDF sample, and where it was taken (MIS)
    prev_p: wp.vec3
    segment_kind: wp.int32  # recording: how the next segment to trace was spawned
    current: wp.int32  # recording: the record index of the segment being followed
    medium: wp.int32  # the participating medium the ray is in (wrt.kernels.volumes); -1: vacuum
    nulls: wp.int32  # null events so far that were not segments (a scene with media): depth + nulls keys the samples


@wp.func
def start_path(materials: MaterialData, settings: IntegratorSettings, ray: CameraRay) -> PathState:
    """A path along camera ray ``ray`` (already traced): the camera may be inside glass or water."""
    path = PathState()
    path.o = ray.o
    path.d = ray.d
    path.t_from = 0.0
    path.t_last = 0.0
    path.throughput = wp.vec3(1.0)
    path.radiance = wp.vec3(0.0)
    path.depth = 1
    path.media = settings.camera_media
    path.n_media = settings.camera_n_media
    path.n_camera = current_ior(materials, settings.exterior_ior, path.media, path.n_media)
    path.specular = True
    path.prev_pdf = 0.0
    path.prev_p = ray.o
    path.segment_kind = SCATTERED
    path.current = ray.record
    path.medium = settings.camera_medium
    path.nulls = 0
    return path


def make_next_event(record: bool, trace: Traversal, features: Features):
    """``next_event``, recording its shadow rays when ``record``, sampling environment maps and
    emissive primitives when the scene has them, lights across the surface when it has glossy
    transmission (rough dielectrics, principled materials), and from scattering events when it has
    participating media (each compiled out otherwise); it and its BSDF interface have ``trace``'s
    inline hint (out of line on CUDA: the path kernel calls it once, from surfaces and from media
    alike)."""
    shadow_ray = make_shadow_ray(record, trace, features.media)
    lighting = lighting_for(features)
    bsdf = make_bsdf(families_for(features), features.textures, trace.inline, features.beckmann, features.anisotropic)
    glossy_transmission = features.rough_dielectric or features.principled  # lights seen through a surface

    @wp.func
    def scattered(
        materials: MaterialData, hit: Hit, wi: wp.vec3, flags: wp.int32, eta: float, scatter_medium: wp.int32
    ):
        """``(f, cos, pdf)`` toward ``wi``: the BSDF's at a surface, or the phase function of
        ``scatter_medium`` (>= 0: ``hit`` is a point in it; its ``cos`` is 1); ``cos <= 0`` where
        ``wi`` does not light the surface (then ``f`` and ``pdf`` are not evaluated)."""
        if wp.static(features.media):
            if scatter_medium >= 0:
                phase = phase_value(materials.media, scatter_medium, hit.wo, wi)
                return wp.vec3(phase), 1.0, phase
        cos_theta = wp.dot(hit.n_facing, wi)
        if wp.static(glossy_transmission):
            cos_theta = seen_through(cos_theta, flags)
        if cos_theta <= 0.0:
            return wp.vec3(0.0), cos_theta, 0.0
        f = wp.static(bsdf.eval)(
            materials, hit.material, hit.n_facing, hit.wo, wi, eta, hit.tex, hit.front, hit.tangent
        )
        if wp.static(features.normal_map):
            f = f * normal_map_shadowing(hit, wi)
        pdf = wp.static(bsdf.pdf)(
            materials, hit.material, hit.n_facing, hit.wo, wi, eta, hit.tex, hit.front, hit.tangent
        )
        return f, cos_theta, pdf

    @hinted_func(trace.inline)
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
        throughput: wp.vec3,
        flags: wp.int32,
        eta: float,
        sigma_t: wp.vec3,
        vertex: wp.int32,
        medium: wp.int32,
        scatter_medium: wp.int32,
    ) -> wp.vec3:
        """Light reflected toward ``hit.wo`` from one sample of every light (``wrt.kernels.lights``),
        MIS-weighted for those that are not delta lights (W/(m^2 sr), before the path's
        ``throughput``); ``sigma`` is the absorption of the dielectric ``hit`` lies in, applied along
        the shadow rays as along BSDF-sampled paths. ``flags`` are the BSDF's; a light below a
        surface with glossy transmission is seen through it (``seen_through``), ``eta`` the ratio
        of the iors on either side and ``sigma_t`` the absorption beyond it. ``vertex`` keys the
        light samples. In a scene with participating media ``medium`` is the one the path is in
        (a shadow ray leaves in the medium beyond the surface on its side), and ``scatter_medium >= 0``
        makes ``hit`` a scattering event in that medium (its point and ``wo`` only).

        Recording: each shadow ray is a segment of ``depth + 1`` segments whose parent is record
        ``parent``, carrying ``throughput`` when it reaches its light and 0 when blocked (then
        ending at the blocker)."""
        total = wp.vec3(0.0)
        for i in range(wp.static(lighting.count)(lights)):
            ls = wp.static(lighting.sample_li)(
                geometry, materials, lights, i, hit.p, ray.time, sampler, ray.pixel, ray.sample, light_dim(vertex, i)
            )
            contribution = wp.vec3(0.0)
            if ls.pdf > 0.0 and max_component(ls.radiance) > 0.0:
                f, cos_theta, scatter_pdf = scattered(materials, hit, ls.wi, flags, eta, scatter_medium)
                if cos_theta > 0.0:
                    mis = float(1.0)
                    if not wp.static(lighting.is_delta)(lights, i):
                        mis = power_heuristic(ls.pdf, scatter_pdf)
                    contribution = wp.cw_mul(f, ls.radiance) * (cos_theta * mis / ls.pdf)
            if max_component(contribution) > 0.0:
                shadow_sigma = sigma
                shadow_medium = medium
                o = hit.p
                if wp.static(features.media):
                    if scatter_medium < 0 and has_media(materials.media):
                        shadow_medium = boundary_medium(materials.media, hit.shape, wp.dot(ls.wi, hit.n) > 0.0, medium)
                if scatter_medium < 0:
                    o = spawn_origin(hit.p, hit.n, hit.err, ls.wi)
                    if wp.static(features.rough_dielectric):
                        if wp.dot(hit.n_facing, ls.wi) < 0.0:  # a light seen through the surface: the medium beyond it
                            shadow_sigma = sigma_t
                visible = shadow_ray(
                    geometry,
                    materials,
                    False,
                    o,
                    ls.wi,
                    ls.t_max,
                    ray.time,
                    shadow_sigma,
                    rec,
                    ray.pixel,
                    ray.sample,
                    depth + 1,
                    parent,
                    throughput,
                    shadow_medium,
                    tracking_key(sampler.seed, ray.pixel, ray.sample, shadow_track_dim(vertex, i)),
                )
                if max_component(visible) > 0.0:
                    total += wp.cw_mul(contribution, visible)
        return total

    return next_event


def make_path_radiance(record: bool, features: Features = ALL, inline: bool | None = None):
    """``path_radiance``, recording every ray it traces when ``record`` (compiled out otherwise),
    with the code of the features the scene lacks compiled out (``wrt.kernels.features``), its
    traversal and BSDF interface with the inline hint ``inline`` (``variants.CUDA_INLINE``)."""
    trace = traversal(features, inline)
    trace_segment = make_trace_segment(record, trace)
    next_event = make_next_event(record, trace, features)
    lighting = lighting_for(features)
    bsdf = make_bsdf(families_for(features), features.textures, inline, features.beckmann, features.anisotropic)
    surface_hit = make_surface_hit_for(features)

    @wp.func
    def roulette(
        materials: MaterialData, settings: IntegratorSettings, sampler: Sampler, ray: CameraRay, path: PathState
    ) -> float:
        """Russian roulette at a path's new segment: the probability with which it goes on,
        ``min(0.95, largest channel of its throughput)`` past ``RR_DEPTH`` segments (1 before), its
        throughput judged without the ``eta^2`` radiance scaling of refractions (pbrt-v4's
        ``etaScale``); 0 where the roll ends it."""
        if path.depth <= RR_DEPTH:
            return 1.0
        n_ratio = float(1.0)
        if wp.static(features.dielectric):
            n_ratio = current_ior(materials, settings.exterior_ior, path.media, path.n_media) / path.n_camera
        q = wp.min(max_component(path.throughput) * n_ratio * n_ratio, 0.95)
        if sample_1d(sampler, ray.pixel, ray.sample, bounce_dim(path.depth + path.nulls, 3)) >= q:
            return 0.0
        return q

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
        path = start_path(materials, settings, ray)
        found = camera_hit(ray)
        traced = bool(True)
        for _segment in range(4 * settings.max_depth + 16):
            # Trace the next segment (the camera ray's is traced already)
            if not traced:
                found, current = trace_segment(
                    geometry,
                    rec,
                    ray,
                    path.segment_kind,
                    path.o,
                    path.d,
                    path.t_from,
                    wp.inf,
                    path.t_last,
                    path.throughput,
                    path.depth,
                    path.current,
                )
                path.current = current
            traced = False

            # A participating medium along the segment: its emission, and scattered in it or through to its end
            t_end = found.t
            in_medium = bool(False)
            if wp.static(features.media):
                if path.medium >= 0:
                    vertex = path.depth + path.nulls
                    flight = free_flight(
                        materials.media,
                        path.medium,
                        path.o + path.t_last * path.d,
                        path.d,
                        found.t - path.t_last,
                        sample_1d(sampler, ray.pixel, ray.sample, flight_dim(vertex)),
                        tracking_key(sampler.seed, ray.pixel, ray.sample, track_dim(vertex)),
                    )
                    path.radiance += wp.cw_mul(path.throughput, flight.emitted)
                    path.throughput = wp.cw_mul(path.throughput, flight.weight)
                    if flight.scattered:
                        in_medium = True
                        t_end = path.t_last + flight.t
                        if wp.static(record):
                            end_in_medium(rec, path.current, path.o + t_end * path.d)

            # Absorption in the dielectric the segment crossed
            if wp.static(features.dielectric):
                path.throughput = wp.cw_mul(
                    path.throughput, medium_transmittance(materials, path.media, path.n_media, t_end - path.t_last)
                )

            # The event at the segment's end: a scattering in the medium, or the surface hit
            scatter_medium = int(-1)  # >= 0: the path scattered in this medium
            if wp.static(features.media):
                if in_medium:
                    scatter_medium = path.medium
            hit = Hit()
            flags = int(0)
            interface = no_interface(path.media, path.n_media)
            volumetric = bool(False)
            last = bool(False)
            if scatter_medium >= 0:
                if path.depth >= settings.max_depth or max_component(path.throughput) == 0.0:
                    break
                hit.p = path.o + t_end * path.d
                hit.wo = -path.d
                hit.shape = -1
            else:
                # Escaped: the environment lights
                if found.prim == NO_HIT:
                    if wp.static(features.lights):
                        escaped = wp.static(lighting.environment_radiance)(lights, path.d, path.prev_pdf, path.specular)
                        path.radiance += wp.cw_mul(path.throughput, escaped)
                    break

                # Emission at the front of what was hit, MIS-weighted against light sampling
                hit = surface_hit(geometry, materials, found)
                emission = materials.emission[hit.material]
                if wp.static(features.textures):
                    emission = material_rgb(materials.textures, hit.material, EMISSION, hit.tex, emission)
                if hit.front and max_component(emission) > 0.0:
                    mis = float(1.0)
                    if not path.specular:
                        light_pdf = wp.static(lighting.pdf_li)(
                            geometry,
                            lights,
                            hit.shape,
                            found.prim,
                            found.inst,
                            path.prev_p,
                            path.d,
                            wp.length(hit.p - path.prev_p),
                        )
                        mis = power_heuristic(path.prev_pdf, light_pdf)
                    path.radiance += wp.cw_mul(path.throughput, emission) * mis
                flags = bsdf_flags_from(materials, hit.material, hit.front)
                if flags == 0:
                    break

                # The media on either side; a false interface lets the ray go straight on (not a
                # segment of its own: max_depth does not end the path there)
                if wp.static(features.dielectric):
                    interface = cross_interface(
                        materials, settings.exterior_ior, path.media, path.n_media, flags, hit.shape, hit.entering
                    )
                    if interface.n_media == MEDIA_OVERFLOW:  # no medium to be in: the sample is lost, and counted
                        path.radiance = wp.vec3(wp.nan)
                        break
                    if not interface.real:
                        path.media = interface.media
                        path.n_media = interface.n_media
                        if wp.static(features.media):
                            if has_media(materials.media):  # and a null event: the next segment's samples are new
                                path.medium = boundary_medium(materials.media, hit.shape, not hit.entering, path.medium)
                                path.nulls += 1
                        path.t_from = past_hit(path.o, hit.p, found.t)
                        path.t_last = found.t
                        path.segment_kind = STRAIGHT
                        # a shadow ray stops at this surface, so next-event estimation never finds
                        # what lies beyond it: light found there takes the BSDF sample's full weight
                        path.specular = True
                        continue

                # In a scene with media a null event (straight on: a null surface, a mask's null
                # lobe, a thin dielectric's transmission) is no segment, so the last segment's
                # surface may still let the path through (Mitsuba 3's volpath)
                if wp.static(features.media):
                    volumetric = has_media(materials.media)
                last = path.depth >= settings.max_depth
                if last and not (volumetric and (flags & BSDF_THIN) != 0):
                    break
            vertex = path.depth + path.nulls

            # Next-event estimation at a scattering event and at non-specular surfaces
            if wp.static(features.lights or features.emissive):
                if scatter_medium >= 0 or (non_specular(flags) and not last):
                    sigma = wp.vec3(0.0)
                    if wp.static(features.dielectric):
                        sigma = medium_sigma(materials, path.media, path.n_media)
                    sigma_t = sigma
                    if wp.static(features.rough_dielectric):
                        sigma_t = medium_sigma(materials, interface.media, interface.n_media)
                    path.radiance += wp.cw_mul(
                        path.throughput,
                        next_event(
                            geometry,
                            materials,
                            lights,
                            hit,
                            sampler,
                            ray,
                            path.depth,
                            sigma,
                            rec,
                            path.current,
                            path.throughput,
                            flags,
                            interface.eta,
                            sigma_t,
                            vertex,
                            path.medium,
                            scatter_medium,
                        ),
                    )

            # The next direction: the phase function's, or the BSDF's
            straight = bool(False)
            if scatter_medium >= 0:
                u = sample_2d(sampler, ray.pixel, ray.sample, bounce_dim(vertex, 0))
                path.d = phase_sample(materials.media, scatter_medium, hit.wo, u)
                path.prev_pdf = phase_value(materials.media, scatter_medium, hit.wo, path.d)
                path.prev_p = hit.p
                path.specular = False
                path.segment_kind = SCATTERED
                path.depth += 1
            else:
                uc = float(0.0)
                u = wp.vec2(0.0)
                if wp.static(features.specular or features.blend or features.principled):  # a lobe, a blend's material
                    if (flags & BSDF_TRANSMISSION) != 0 or wp.static(
                        features.plastic or features.blend or features.principled
                    ):
                        uc = sample_1d(sampler, ray.pixel, ray.sample, bounce_dim(vertex, 2))
                if non_specular(flags):
                    u = sample_2d(sampler, ray.pixel, ray.sample, bounce_dim(vertex, 0))
                bs = wp.static(bsdf.sample)(
                    materials, hit.material, hit.n_facing, hit.wo, interface.eta, uc, u, hit.tex, hit.front, hit.tangent
                )
                if bs.pdf == 0.0:
                    break
                null_event = volumetric and (bs.flags & BSDF_THIN) != 0 and (bs.flags & BSDF_TRANSMISSION) != 0
                if last and not null_event:
                    break
                if wp.static(features.normal_map):
                    bs.weight = bs.weight * normal_map_shadowing(hit, bs.wi)
                path.throughput = wp.cw_mul(path.throughput, bs.weight)
                path.d = bs.wi
                if null_event:
                    path.nulls += 1
                else:
                    path.depth += 1
                if (bs.flags & BSDF_SPECULAR) != 0:
                    # a null surface or a thin dielectric's straight lobe keeps the last
                    # scattering's MIS state: shadow rays pass them (Mitsuba 3's null lobes)
                    passed = materials.type[hit.material] == NULL or materials.type[hit.material] == THIN_DIELECTRIC
                    if not (null_event and passed):
                        path.specular = True
                    if (bs.flags & BSDF_TRANSMISSION) != 0:
                        path.media = interface.media
                        path.n_media = interface.n_media
                        straight = interface.eta == 1.0  # index-matched: straight on
                else:
                    path.prev_pdf = bs.pdf
                    path.prev_p = hit.p
                    path.specular = False
                    if wp.static(features.rough_dielectric):
                        if (bs.flags & BSDF_TRANSMISSION) != 0:  # refracted through a rough dielectric
                            path.media = interface.media
                            path.n_media = interface.n_media
                path.segment_kind = bounce_kind(bs.flags, straight)
                if wp.static(features.media):
                    if volumetric:  # the medium on the side the path leaves to, where the shape bounds media
                        path.medium = boundary_medium(
                            materials.media, hit.shape, wp.dot(path.d, hit.n) > 0.0, path.medium
                        )

            # Spawn the next segment (from a scattering event: at its point, hit.n and hit.err
            # being 0); Russian roulette past RR_DEPTH
            if straight:
                path.t_from = past_hit(path.o, hit.p, found.t)
                path.t_last = found.t
            else:
                path.o = spawn_origin(hit.p, hit.n, hit.err, path.d)
                path.t_from = 0.0
                path.t_last = 0.0
                q = roulette(materials, settings, sampler, ray, path)
                if q == 0.0:
                    break
                path.throughput = path.throughput / q
        return path.radiance

    return path_radiance
