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
- thin dielectrics (panes): a reflected branch weighted by R' and one straight on, in the same
  medium, weighted by 1 - R' (``wrt.kernels.optics.fresnel_thin_dielectric``), times their tints;
- the back side of a one-sided material (``two_sided = false``) adds nothing, not even
  ``ambient``, and the path ends there;
- emission on any material is added where a ray hits its front side; rays that leave the scene
  see ``background``.

Depth: the camera ray is segment 1, each reflected, refracted or shadow ray one more; nothing is
traced past ``max_depth`` segments (so direct light needs ``max_depth >= 2``). A branch whose
throughput falls below ``min_throughput`` (largest channel, without the ``eta^2`` radiance
scaling of refractions: see ``wrt.kernels.media.current_ior``) is cut. At a dielectric the
heavier branch is followed first and the lighter one deferred; when a path ends, the heaviest
deferred branch is resumed. At most ``BRANCHES`` wait, and when they are full the lightest branch
(deferred or new) is dropped, so the energy lost to the bound is the smallest available. A camera
ray's whole tree stops at ``MAX_SEGMENTS`` segments (light trapped by total internal reflection
with a tiny ``min_throughput`` can reach it; what is left then is the lightest).

A ray that goes straight on through a surface (a false interface between media, or an
index-matched one) keeps its origin and direction: only its ``t_min`` moves past the hit by the
hit's error bound, so an ior-1.0 object is exactly invisible at any distance from the origin.

Media: each branch carries the stack of dielectrics it is inside (``wrt.kernels.media``): nested
and overlapping dielectrics, with ``priority`` for overlaps.

Shadow rays are ``wrt.kernels.shadow``'s: opaque, or with ``dielectric_shadows = "filtered"``
passing dielectrics with Beer-Lambert attenuation.

Recording: ``whitted_record`` is the same integrator with every traced ray appended to a
``wrt.kernels.record.RayRecord``: each segment traced in the loop (kind ``REFLECTED``,
``REFRACTED``, ``TOTAL_INTERNAL`` or ``STRAIGHT`` through a false interface) and each shadow ray
(``SHADOW_LIT`` to the light, or ``SHADOW_BLOCKED`` ending where it was stopped). Branches that
are cut (depth, throughput, stack bound) are not traced and so not recorded. The decisions are
the render variant's.

References
----------
T. Whitted, "An Improved Illumination Model for Shaded Display", CACM 23(6), 1980.
C. Schmidt, B. Budge, "Simple Nested Dielectrics in Ray Traced Images", JGT 7(2), 2002.
"""

import warp as wp

from .features import ALL, Features
from .hit import Hit, make_surface_hit_for, normal_map_shadowing
from .integrator import CameraRay, IntegratorSettings, make_trace_segment
from .lights import LightData, light_incident
from .materials import (
    BSDF_SPECULAR,
    MaterialData,
    bsdf_flags_from,
    families_for,
    make_bsdf,
    non_specular,
)
from .media import (
    MEDIA,
    MEDIA_OVERFLOW,
    cross_interface,
    current_ior,
    max_component,
    medium_sigma,
    medium_transmittance,
    no_interface,
)
from .record import REFLECTED, REFRACTED, STRAIGHT, TOTAL_INTERNAL, RayRecord
from .sampling import Sampler
from .shadow import make_shadow_ray
from .spawn import past_hit, spawn_origin
from .textures import ALBEDO, EMISSION, material_rgb
from .traverse import NO_HIT, GeometryData, Traversal, ray_hit, traversal

BRANCHES = 32  # pending branches per camera ray
MAX_SEGMENTS = wp.constant(4096)  # hard stop per camera ray, whatever happens (deferred branches: heaviest first)
BranchVec3 = wp.types.matrix(shape=(BRANCHES, 3), dtype=float)
BranchMedia = wp.types.matrix(shape=(BRANCHES, MEDIA), dtype=wp.int32)
BranchInt = wp.types.vector(length=BRANCHES, dtype=wp.int32)
BranchFloat = wp.types.vector(length=BRANCHES, dtype=float)


@wp.func
def lightest_branch(weight: BranchFloat, count: wp.int32) -> wp.int32:
    """Index of the deferred branch of smallest weight."""
    best = int(0)
    for k in range(1, count):
        if weight[k] < weight[best]:
            best = k
    return best


@wp.func
def heaviest_branch(weight: BranchFloat, count: wp.int32) -> wp.int32:
    """Index of the deferred branch of largest weight."""
    best = int(0)
    for k in range(1, count):
        if weight[k] > weight[best]:
            best = k
    return best


def make_direct_light(record: bool, trace: Traversal, features: Features):
    """``direct_light``, recording its shadow rays when ``record``, with the scene's texture
    lookups, normal maps' shadowing, Beckmann microfacets and anisotropic frames (``features``;
    each compiled out where it has none); its BSDF interface has ``trace``'s inline hint and every
    family the Whitted integrator renders (masks need the path integrator)."""
    shadow_ray = make_shadow_ray(record, trace)
    bsdf = make_bsdf(
        families_for(ALL, whitted=True), features.textures, trace.inline, features.beckmann, features.anisotropic
    )

    @wp.func
    def direct_light(
        geometry: GeometryData,
        materials: MaterialData,
        lights: LightData,
        settings: IntegratorSettings,
        hit: Hit,
        ray: CameraRay,
        sigma: wp.vec3,
        rec: RayRecord,
        parent: wp.int32,
        depth: wp.int32,
        throughput: wp.vec3,
    ) -> wp.vec3:
        """Reflected radiance (W/(m^2 sr)) toward ``hit.wo`` from all delta lights: sum of
        BSDF * irradiance * cos * shadow transmittance (``sigma``: the absorption of the medium
        ``hit`` lies in).

        Recording: each shadow ray is a segment of ``depth`` (the segment count it brings the path
        to) whose parent is record ``parent``, carrying ``throughput`` times its transmittance.
        """
        total = wp.vec3(0.0)
        n = hit.n_facing
        for i in range(lights.type.shape[0]):
            wi, dist, irradiance = light_incident(lights, i, hit.p)
            cos_theta = wp.dot(n, wi)
            if cos_theta > 0.0 and max_component(irradiance) > 0.0:
                visible = shadow_ray(
                    geometry,
                    materials,
                    settings.filtered_shadows != 0,
                    spawn_origin(hit.p, hit.n, hit.err, wi),
                    wi,
                    dist,
                    ray.time,
                    sigma,
                    rec,
                    ray.pixel,
                    ray.sample,
                    depth,
                    parent,
                    throughput,
                )
                f = wp.static(bsdf.eval)(materials, hit.material, n, hit.wo, wi, 1.0, hit.tex, True, hit.tangent)
                if wp.static(features.normal_map):
                    f = f * normal_map_shadowing(hit, wi)
                total += wp.cw_mul(wp.cw_mul(f, irradiance), visible) * cos_theta
        return total

    return direct_light


def make_whitted_radiance(record: bool, features: Features = ALL, inline: bool | None = None):
    """``whitted_radiance``, recording every ray it traces when ``record`` (compiled out otherwise),
    with the code of the features the scene lacks compiled out (``wrt.kernels.features``): without
    mirrors and dielectrics there is no branch stack and the camera ray's hit is the whole tree; its
    traversal and BSDF interface with the inline hint ``inline`` (``variants.CUDA_INLINE``)."""
    trace = traversal(features, inline)
    trace_segment = make_trace_segment(record, trace)
    direct_light = make_direct_light(record, trace, features)
    bsdf = make_bsdf(
        families_for(features, whitted=True), features.textures, inline, features.beckmann, features.anisotropic
    )
    surface_hit = make_surface_hit_for(features)

    @wp.func
    def whitted_radiance(
        geometry: GeometryData,
        materials: MaterialData,
        lights: LightData,
        settings: IntegratorSettings,
        sampler: Sampler,
        ray: CameraRay,
        rec: RayRecord,
    ) -> wp.vec3:
        """Radiance (W/(m^2 sr)) arriving at the camera along ``ray``."""
        o = ray.o
        d = ray.d
        t = ray.t
        prim = ray.prim
        inst = ray.inst
        radiance = wp.vec3(0.0)
        throughput = wp.vec3(1.0)
        depth = int(1)
        media = settings.camera_media  # the camera may be inside glass or water
        n_media = settings.camera_n_media
        n_pending = int(0)
        if wp.static(features.specular):
            # a branch's weight: its throughput's largest channel without the eta^2 scaling
            n_camera = current_ior(materials, settings.exterior_ior, media, n_media)
            pending_origin = BranchVec3()
            pending_dir = BranchVec3()
            pending_throughput = BranchVec3()
            pending_weight = BranchFloat()
            pending_depth = BranchInt()
            pending_media = BranchMedia()
            pending_n_media = BranchInt()
            if wp.static(record):  # how each was spawned, and from which record
                pending_kind = BranchInt()
                pending_parent = BranchInt()
        traced = bool(True)
        # The ray being followed is o + s d for s > t_from; t_last is where its current segment
        # began. A ray that goes straight on through a surface (a false interface, or an
        # index-matched one) keeps its origin and line, and only t_from moves past the hit:
        # re-spawning it off the surface would shift it sideways by the offset.
        t_from = float(0.0)
        t_last = float(0.0)
        current = ray.record  # record index of the segment being followed
        segment_kind = int(REFLECTED)  # recording: how the next segment to trace was spawned, and from which record
        segment_parent = ray.record
        for _segment in range(MAX_SEGMENTS):
            # Trace the next segment (the camera ray's is traced already)
            if not traced:
                found, current = trace_segment(
                    geometry, rec, ray, segment_kind, o, d, t_from, wp.inf, t_last, throughput, depth, segment_parent
                )
                t = found.t  # loose in the loop: a RayHit carried round it cost it 1.07-1.11x
                prim = found.prim
                inst = found.inst
            traced = False

            # Absorption in the medium the segment crossed (infinite if it escaped)
            if wp.static(features.dielectric):
                throughput = wp.cw_mul(throughput, medium_transmittance(materials, media, n_media, t - t_last))

            go_on = bool(False)
            if prim == NO_HIT:
                radiance += wp.cw_mul(throughput, settings.background)
            else:
                # Emission at the front of what was hit
                hit = surface_hit(geometry, materials, ray_hit(o, d, ray.time, t, prim, inst))
                if hit.front:
                    emission = materials.emission[hit.material]
                    if wp.static(features.textures):
                        emission = material_rgb(materials.textures, hit.material, EMISSION, hit.tex, emission)
                    radiance += wp.cw_mul(throughput, emission)
                flags = bsdf_flags_from(materials, hit.material, hit.front)

                # Local shading at non-specular surfaces: ambient plus the delta lights
                if non_specular(flags):
                    albedo = materials.albedo[hit.material]
                    if wp.static(features.textures):
                        albedo = material_rgb(materials.textures, hit.material, ALBEDO, hit.tex, albedo)
                    local = wp.cw_mul(settings.ambient, albedo)
                    if wp.static(features.lights):
                        if depth < settings.max_depth:
                            sigma = wp.vec3(0.0)
                            if wp.static(features.dielectric):
                                sigma = medium_sigma(materials, media, n_media)
                            local += direct_light(
                                geometry,
                                materials,
                                lights,
                                settings,
                                hit,
                                ray,
                                sigma,
                                rec,
                                current,
                                depth + 1,
                                throughput,
                            )
                    radiance += wp.cw_mul(throughput, local)

                # Specular surfaces: the media on either side, then the reflected and refracted branches
                if wp.static(features.specular):
                    if (flags & BSDF_SPECULAR) != 0:
                        interface = no_interface(media, n_media)
                        if wp.static(features.dielectric):
                            interface = cross_interface(
                                materials, settings.exterior_ior, media, n_media, flags, hit.shape, hit.entering
                            )
                            if interface.n_media == MEDIA_OVERFLOW:  # no medium to be in: the sample is lost (counted)
                                radiance = wp.vec3(wp.nan)
                                break
                        real = interface.real
                        eta = interface.eta
                        media_t = interface.media
                        n_media_t = interface.n_media
                        if not real:  # a false interface: straight on
                            t_from = past_hit(o, hit.p, t)
                            t_last = t
                            media = media_t
                            n_media = n_media_t
                            go_on = True
                            segment_kind = STRAIGHT
                            segment_parent = current
                        elif depth < settings.max_depth:
                            lobes = wp.static(bsdf.specular_lobes)(
                                materials, hit.material, hit.n_facing, hit.wo, eta, hit.tex
                            )
                            if wp.static(features.normal_map):
                                lobes.reflectance = lobes.reflectance * normal_map_shadowing(hit, lobes.wr)
                                lobes.transmittance = lobes.transmittance * normal_map_shadowing(hit, lobes.wt)
                            reflected = wp.cw_mul(throughput, lobes.reflectance)
                            transmitted = wp.cw_mul(throughput, lobes.transmittance)
                            n_r = current_ior(materials, settings.exterior_ior, media, n_media) / n_camera
                            n_t = current_ior(materials, settings.exterior_ior, media_t, n_media_t) / n_camera
                            weight_r = max_component(reflected) * n_r * n_r
                            weight_t = max_component(transmitted) * n_t * n_t
                            keep_r = weight_r > 0.0 and weight_r >= settings.min_throughput
                            keep_t = lobes.refracts and weight_t > 0.0 and weight_t >= settings.min_throughput
                            # Follow the heavier branch now and defer the lighter one. A full stack
                            # evicts its lightest entry if the new one is heavier, else drops the new one.
                            if keep_r and keep_t:
                                defer_reflected = weight_r < weight_t
                                weight = wp.min(weight_r, weight_t)
                                slot_new = n_pending
                                if n_pending == BRANCHES:
                                    slot_new = lightest_branch(pending_weight, n_pending)
                                    if pending_weight[slot_new] >= weight:
                                        slot_new = -1
                                else:
                                    n_pending += 1
                                if slot_new >= 0:
                                    w = wp.where(defer_reflected, lobes.wr, lobes.wt)
                                    pending_origin[slot_new] = spawn_origin(hit.p, hit.n, hit.err, w)
                                    pending_dir[slot_new] = w
                                    pending_throughput[slot_new] = wp.where(defer_reflected, reflected, transmitted)
                                    pending_weight[slot_new] = weight
                                    pending_media[slot_new] = wp.where(defer_reflected, media, media_t)
                                    pending_n_media[slot_new] = wp.where(defer_reflected, n_media, n_media_t)
                                    pending_depth[slot_new] = depth + 1
                                    if wp.static(record):
                                        pending_kind[slot_new] = wp.where(defer_reflected, REFLECTED, REFRACTED)
                                        pending_parent[slot_new] = current
                                keep_r = not defer_reflected
                                keep_t = defer_reflected
                            if keep_r:
                                d = lobes.wr
                                throughput = reflected
                            elif keep_t:
                                d = lobes.wt
                                throughput = transmitted
                                media = media_t
                                n_media = n_media_t
                            if keep_t and eta == 1.0:  # index-matched: straight on (refract returned d)
                                t_from = past_hit(o, hit.p, t)
                                t_last = t
                            elif keep_r or keep_t:
                                o = spawn_origin(hit.p, hit.n, hit.err, d)
                                t_from = 0.0
                                t_last = 0.0
                            if keep_r or keep_t:
                                depth += 1
                                go_on = True
                                segment_kind = wp.where(
                                    keep_r, wp.where(lobes.total_internal, TOTAL_INTERNAL, REFLECTED), REFRACTED
                                )
                                segment_parent = current

            # A path ends: resume the heaviest deferred branch, so that what the segment budget may
            # leave untraced is the lightest light; the last entry fills its slot
            if not go_on:
                if wp.static(not features.specular):
                    break
                if wp.static(features.specular):
                    if n_pending == 0:
                        break
                    k = heaviest_branch(pending_weight, n_pending)
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
                    pending_weight[k] = pending_weight[n_pending]
                    pending_depth[k] = pending_depth[n_pending]
                    pending_media[k] = pending_media[n_pending]
                    pending_n_media[k] = pending_n_media[n_pending]
                    if wp.static(record):
                        pending_kind[k] = pending_kind[n_pending]
                        pending_parent[k] = pending_parent[n_pending]
        return radiance

    return whitted_radiance
