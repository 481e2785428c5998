"""The "ptracer" integrator: light tracing (Mitsuba 3's particle tracer), a second estimator of
the image the path integrator renders.

Each launch thread owns one *slot* (a pixel index) and traces, for each of its samples, one
light path: a light chosen uniformly, a ray leaving it (``wrt.kernels.lights``' ``sample_le``:
a point and a cosine-weighted direction on a surface light, a direction from a point-like light,
a disk outside the scene's bounding sphere for lights at infinity), then BSDF sampling from
surface to surface, as the path integrator does from the camera. At every vertex with a
non-specular lobe the path is connected to the camera (``link_camera``: a point of the lens, the
film position the line through it reaches, the camera's importance) and, where nothing blocks the
connection, its contribution is *splatted* onto the film through the pixel filter. Emitters
seen directly are connected the same way from the point ``sample_le`` chose on them; the
environment seen directly (which no point of the scene can be connected for) is estimated from
the camera side, by the slot's pixel's own camera ray, as the path integrator's first segment.

The pixel filter weighs a splat onto the pixels around its film position (``filter_weight``:
the box, tent and Gaussian of ``wrt.kernels.camera``, each integrating to 1), so the image
converges to the same filter-weighted average of the radiance as the camera-side integrators.

Transport is adjoint (Veach's thesis, sec. 5.2; Mitsuba 3's ``TransportMode::Importance``): the
BSDF interface's radiance-mode values are used with the roles of ``wo`` and ``wi`` swapped (``wo``
is the direction back toward the light), which reciprocity allows, except that a transmission's
``eta^2`` radiance scaling is taken out (``importance_scale``), and the shading-normal correction
``|wo . n_s| |wi . n_g| / (|wi . n_s| |wo . n_g|)`` multiplies every vertex, with paths dropped
where a direction lies on different sides of the geometric and the shading normal.

Splats are summed as 64-bit integers, ``FIXED_POINT`` units per W/(m^2 sr) (``LightTracing``):
integer addition is associative, so the image is the same whatever the order in which threads,
tiles or devices add their splats. A pixel's value is its sum over the samples per pixel (the
light paths are ``spp`` per slot, ``spp * W * H`` in all, and the camera importance is
normalised over the whole film).

``max_depth`` counts segments as the path integrator does: a connection from the k-th surface a
light path meets is a path of k + 1 segments. Russian roulette, past ``RR_DEPTH`` segments,
continues a path with probability ``min(0.95, max(throughput) / max(emitted))``: its
throughput relative to what it left the light with, so the rule does not depend on the scene's
units. Light paths start outside every dielectric (``wrt.loader`` refuses lights inside one)
and in vacuum (no participating media: refused too, as by Mitsuba 3's ``ptracer``).

Random numbers (``wrt.kernels.sampling``, keyed by the slot and the sample): dimension 0 the
time in the shutter, 1 the light, 2-3 the point on it, 4-5 the direction, 6 the part of it
(an emissive primitive), 7-8 the lens point of the emitter's own connection, 9-12 the film and
lens positions of the slot's camera ray; ``vertex_dim(k, j)`` at the k-th surface: the BSDF
sample (j = 0, 1), its lobe (2), roulette (3) and the lens point of its connection (4, 5).
"""

import warp as wp

from . import MODULE_OPTIONS
from .camera import (
    GAUSSIAN,
    GAUSSIAN_RADIUS,
    GAUSSIAN_SIGMA,
    TENT,
    CameraData,
    clip_ray,
    make_generate_ray,
    shutter_time,
)
from .features import ALL, Features
from .film import Film, write_aovs
from .hit import Hit, make_surface_hit_for, normal_map_shadowing
from .integrator import CameraRay, IntegratorSettings, RenderPass, make_camera_sample, make_trace_segment
from .lights import SHADOW_MARGIN, LightData, lighting_for
from .materials import (
    BSDF_SPECULAR,
    BSDF_TRANSMISSION,
    MaterialData,
    bsdf_flags_from,
    families_for,
    make_bsdf,
    non_specular,
)
from .media import (
    MEDIA_OVERFLOW,
    Interface,
    Media,
    cross_interface,
    max_component,
    medium_sigma,
    medium_transmittance,
    no_interface,
)
from .path import RR_DEPTH
from .record import CAMERA, EMITTED, STRAIGHT, RayRecord, bounce_kind
from .sample_warps import concentric_disk
from .sampling import Sampler, sample_1d, sample_2d
from .shadow import make_shadow_ray
from .spawn import past_hit, point_error, spawn_origin
from .traverse import NO_HIT, GeometryData, ray_hit, traversal

FIXED_POINT = wp.constant(268435456.0)  # 2^28 integer units per W/(m^2 sr) in LightTracing.splat
SPLAT_LIMIT = wp.constant(3.0e10)  # W/(m^2 sr): a larger splat would risk the int64 sums; counted as rejected


@wp.struct
class LightTracing:
    """What the light tracer reads besides a render kernel's arguments."""

    splat: wp.array2d(dtype=wp.int64)  # (W * H, 3): each pixel's splats, FIXED_POINT units
    center: wp.vec3  # the scene's bounding sphere: lights at infinity send their rays from outside it
    radius: float
    sky: wp.int32  # 1: the scene has an environment light, seen directly through the camera rays


@wp.struct
class CameraLink:
    """A connection of a point ``x`` to the camera (``link_camera``)."""

    ok: bool  # the camera sees ``x``: in front of it, between its clip planes, within the film and filter
    wc: wp.vec3  # unit direction from ``x`` toward the lens point
    length: float  # how far the shadow ray from ``x`` goes: to the near clip plane
    film: wp.vec2  # film position (pixels from the image's left and top edges)
    importance: float  # the camera's importance times the geometry term but ``x``'s cosine (below)


@wp.func
def vertex_dim(k: wp.int32, j: wp.int32) -> wp.int32:
    return 16 + 8 * k + j


@wp.func
def filter_radius(filter: wp.int32) -> float:
    """How far (pixels) the pixel filter reaches from a pixel's centre."""
    if filter == TENT:
        return 1.0
    if filter == GAUSSIAN:
        return GAUSSIAN_RADIUS
    return 0.5


@wp.func
def filter_weight(filter: wp.int32, x: float) -> float:
    """The pixel filter's profile along one axis at ``x`` pixels from a pixel's centre, integrating
    to 1 (the density ``wrt.kernels.camera.filter_offset`` draws offsets from)."""
    if filter == TENT:
        return wp.max(0.0, 1.0 - wp.abs(x))
    if filter == GAUSSIAN:
        if wp.abs(x) >= GAUSSIAN_RADIUS:
            return 0.0
        edge = wp.erf(GAUSSIAN_RADIUS / (GAUSSIAN_SIGMA * wp.sqrt(2.0)))
        return wp.exp(-0.5 * x * x / (GAUSSIAN_SIGMA * GAUSSIAN_SIGMA)) / (GAUSSIAN_SIGMA * wp.sqrt(2.0 * wp.pi) * edge)
    if x >= -0.5 and x < 0.5:
        return 1.0
    return 0.0


def make_link_camera(features: Features):
    """``link_camera``, with the orthographic camera compiled in where ``features`` has one."""

    @wp.func
    def link_camera(cam: CameraData, x: wp.vec3, disk: wp.vec2) -> CameraLink:
        """The connection of ``x`` to the camera through the lens point of ``disk`` (a point of the
        unit disk; the lens centre for a pinhole), following ``wrt.kernels.camera``'s convention.

        ``importance`` is ``1 / (A cos^3 d^2)`` for a perspective camera (``A`` the film's area at
        unit distance, ``theta`` the angle of the line to the lens with ``forward``, ``d`` its
        length; the lens area cancels against its sampling density), ``1 / A`` for an orthographic
        one (``A`` its view's area): a connection's contribution is ``throughput f |cos_x|
        importance``, splatted through the filter, the film normalised over its whole area."""
        link = CameraLink()
        link.ok = False
        sx = float(0.0)
        sy = float(0.0)
        z = float(0.0)
        orthographic = bool(False)
        if wp.static(features.orthographic):
            orthographic = cam.orthographic != 0
        if orthographic:
            v = x - cam.origin
            z = wp.dot(v, cam.forward)
            sx = wp.dot(v, cam.right) / cam.half_width
            sy = wp.dot(v, cam.up) / cam.half_height
            link.wc = -cam.forward
            link.length = z - cam.near_clip
            link.importance = 1.0 / (4.0 * cam.half_width * cam.half_height)
        else:
            lens = cam.origin
            if wp.static(features.lens):
                lens = cam.origin + cam.aperture_radius * (disk[0] * cam.right + disk[1] * cam.up)
            v = x - lens
            z = wp.dot(v, cam.forward)
            if z <= 0.0:
                return link
            q = v
            if wp.static(features.lens):
                if cam.aperture_radius > 0.0:  # the point of the plane of focus on the line, seen from the centre
                    q = lens + v * (cam.focus_distance / z) - cam.origin
            depth = wp.dot(q, cam.forward)
            sx = wp.dot(q, cam.right) / (depth * cam.tan_half_fov * cam.aspect)
            sy = wp.dot(q, cam.up) / (depth * cam.tan_half_fov)
            dist = wp.length(v)
            cos_theta = z / dist
            link.wc = -v / dist
            link.length = dist * (z - cam.near_clip) / z
            area = 4.0 * cam.tan_half_fov * cam.tan_half_fov * cam.aspect
            link.importance = 1.0 / (area * cos_theta * cos_theta * cos_theta * dist * dist)
        if z <= cam.near_clip or z >= cam.far_clip:
            return link
        link.film = wp.vec2(0.5 * (sx + 1.0) * float(cam.width), 0.5 * (1.0 - sy) * float(cam.height))
        r = filter_radius(cam.filter)
        link.ok = (
            link.film[0] >= -r
            and link.film[0] <= float(cam.width) + r
            and link.film[1] >= -r
            and link.film[1] <= float(cam.height) + r
        )
        return link

    return link_camera


@wp.func
def add_fixed(tracing: LightTracing, pixel: wp.int32, value: wp.vec3):
    """Add ``value`` (W/(m^2 sr), finite, >= 0) to ``pixel``'s integer sums."""
    for c in range(3):
        if value[c] > 0.0:
            wp.atomic_add(tracing.splat, pixel, c, wp.int64(wp.round(value[c] * FIXED_POINT)))


@wp.func
def splat(tracing: LightTracing, cam: CameraData, film: wp.vec2, value: wp.vec3) -> wp.int32:
    """Splat ``value`` at film position ``film`` onto the pixels the filter reaches from it; 1 if
    it was NaN, infinite or too large to add (then dropped), else 0."""
    if not wp.isfinite(value) or max_component(value) > SPLAT_LIMIT:
        return 1
    r = filter_radius(cam.filter)
    x0 = wp.max(int(wp.floor(film[0] - r)), 0)
    x1 = wp.min(int(wp.floor(film[0] + r)), cam.width - 1)
    y0 = wp.max(int(wp.floor(film[1] - r)), 0)
    y1 = wp.min(int(wp.floor(film[1] + r)), cam.height - 1)
    for y in range(y0, y1 + 1):
        wy = filter_weight(cam.filter, film[1] - (float(y) + 0.5))
        if wy > 0.0:
            for x in range(x0, x1 + 1):
                w = wy * filter_weight(cam.filter, film[0] - (float(x) + 0.5))
                if w > 0.0:
                    add_fixed(tracing, y * cam.width + x, value * w)
    return 0


@wp.func
def importance_scale(flags: wp.int32, eta: float) -> float:
    """What turns a radiance-mode weight of a sampled or evaluated lobe of ``flags`` into its
    importance-mode one: ``1 / eta^2`` for a transmission (``eta`` the ratio of the iors on the
    side toward the light and across), 1 otherwise."""
    if (flags & BSDF_TRANSMISSION) != 0:
        return 1.0 / (eta * eta)
    return 1.0


@wp.func
def shading_correction(n_s: wp.vec3, n_g: wp.vec3, wo: wp.vec3, wi: wp.vec3) -> float:
    """Veach's adjoint correction for shading normals, ``|wo . n_s| |wi . n_g| / (|wi . n_s| |wo . n_g|)``
    (``wo`` toward the light, ``wi`` the way the light goes on); 0 where ``wo`` or ``wi`` lies on
    different sides of the shading normal ``n_s`` and the geometric one ``n_g`` (a light leak)."""
    o_s = wp.dot(wo, n_s)
    o_g = wp.dot(wo, n_g)
    i_s = wp.dot(wi, n_s)
    i_g = wp.dot(wi, n_g)
    if o_s * o_g <= 0.0 or i_s * i_g <= 0.0:
        return 0.0
    return wp.abs(o_s * i_g / (i_s * o_g))


@wp.func
def slot_sample(slot: wp.int32, s: wp.int32, time: float) -> CameraRay:
    """What the recording of sample ``s`` of ``slot`` at ray time ``time`` is keyed by (a
    ``CameraRay`` of that pixel, sample and time; its other fields unused)."""
    who = CameraRay()
    who.pixel = slot
    who.sample = s
    who.time = time
    return who


def make_ptracer_kernel(
    *,
    module: str,
    record: bool = False,
    features: Features = ALL,
    options: dict | None = None,
    inline: bool | None = None,
):
    """The light tracer's kernel, in Warp module ``module`` (its Warp options ``MODULE_OPTIONS`` and
    ``options``), with the code of the features the scene lacks compiled out; ``inline`` is the
    traversal's and the BSDF interface's inline hint. It takes a render kernel's arguments (its
    ``RenderPass``'s pixels are the slots) with a ``LightTracing`` before the film, whose
    ``rejected`` counts the slots' dropped splats; the first pass writes the AOVs as the other
    integrators do (the pixel-centre ray). Its last argument is a ``RayRecord``: where ``record``,
    every ray a slot traces is appended to it (``wrt.kernels.record``: each light path from its
    ``EMITTED`` ray, its connections to the camera, the slot's camera rays toward the sky), else
    it is empty and untouched."""
    trace = traversal(features, inline)
    trace_segment = make_trace_segment(record, trace)
    shadow_ray = make_shadow_ray(record, trace, False, to_camera=True)
    lighting = lighting_for(features)
    bsdf = make_bsdf(families_for(features), features.textures, inline, features.beckmann, features.anisotropic)
    surface_hit = make_surface_hit_for(features)
    link_camera = make_link_camera(features)
    generate_ray = make_generate_ray(features.orthographic)
    camera_sample = make_camera_sample(features)
    glossy_transmission = features.rough_dielectric or features.principled  # a camera seen through a surface

    @wp.func
    def connect(
        geometry: GeometryData,
        materials: MaterialData,
        tracing: LightTracing,
        cam: CameraData,
        who: CameraRay,
        rec: RayRecord,
        depth: wp.int32,
        parent: wp.int32,
        link: CameraLink,
        p: wp.vec3,
        n: wp.vec3,
        err: float,
        value: wp.vec3,
        sigma: wp.vec3,
    ) -> wp.int32:
        """Splat ``value`` (before the camera's importance) along ``link`` from point ``p`` (geometric
        normal ``n``, offset bound ``err``) where nothing blocks it, the shadow ray crossing a
        dielectric of absorption ``sigma``; the count of dropped splats. The shadow ray is
        recorded as segment ``depth`` of slot ``who.pixel``'s sample ``who.sample``, child of
        record ``parent`` (at ``who.time``)."""
        if max_component(value) <= 0.0:
            return 0
        o = spawn_origin(p, n, err, link.wc)
        visible = shadow_ray(
            geometry,
            materials,
            False,
            o,
            link.wc,
            link.length * (1.0 - SHADOW_MARGIN),
            who.time,
            sigma,
            rec,
            who.pixel,
            who.sample,
            depth,
            parent,
            value * link.importance,
        )
        if max_component(visible) <= 0.0:
            return 0
        return splat(tracing, cam, link.film, wp.cw_mul(value, visible) * link.importance)

    @wp.func
    def connect_surface(
        geometry: GeometryData,
        materials: MaterialData,
        tracing: LightTracing,
        cam: CameraData,
        who: CameraRay,
        rec: RayRecord,
        depth: wp.int32,
        parent: wp.int32,
        link: CameraLink,
        hit: Hit,
        n_g: wp.vec3,
        flags: wp.int32,
        interface: Interface,
        media: Media,
        n_media: wp.int32,
        throughput: wp.vec3,
        prim: wp.int32,
        inst: wp.int32,
    ) -> wp.int32:
        """Splat what the surface ``hit`` (geometric normal ``n_g`` on the light's side, BSDF
        ``flags``, ``interface`` to the media beyond) sends along ``link`` of the light that arrived
        with ``throughput`` from ``hit.wo``; the count of dropped splats. The camera may be seen
        through a surface with glossy transmission (then the importance scaling of a transmission
        applies, and the shadow ray crosses the medium beyond). Recorded as ``connect``'s.

        A normal- or bump-mapped surface's frame depends on the side it is seen from
        (``wrt.kernels.hit``): seen from the camera's side, it is evaluated as the path integrator
        evaluates it there, with ``wo`` the camera's direction (primitive ``prim`` through
        instance ``inst``); its shadowing is then the light's direction's."""
        sigma = wp.vec3(0.0)
        if wp.static(features.dielectric):
            sigma = medium_sigma(materials, media, n_media)
        if wp.static(features.normal_map):
            if not (hit.n_unmapped == hit.n_facing) and wp.dot(n_g, link.wc) > 0.0:
                seen = surface_hit(geometry, materials, ray_hit(hit.p + link.wc, -link.wc, who.time, 1.0, prim, inst))
                cos_l = wp.dot(seen.n_facing, hit.wo)
                if cos_l <= 0.0:
                    return 0
                f = wp.static(bsdf.eval)(
                    materials, seen.material, seen.n_facing, link.wc, hit.wo, 1.0, seen.tex, seen.front, seen.tangent
                )
                f = f * (normal_map_shadowing(seen, hit.wo) * cos_l * wp.dot(n_g, link.wc) / wp.dot(n_g, hit.wo))
                value = wp.cw_mul(throughput, f)
                return connect(
                    geometry,
                    materials,
                    tracing,
                    cam,
                    who,
                    rec,
                    depth,
                    parent,
                    link,
                    hit.p,
                    hit.n,
                    hit.err,
                    value,
                    sigma,
                )
        shadowing = float(1.0)
        if wp.static(features.normal_map):
            shadowing = normal_map_shadowing(hit, hit.wo)
        cos_s = wp.dot(hit.n_facing, link.wc)
        across = cos_s < 0.0
        if across and not (wp.static(glossy_transmission) and (flags & BSDF_TRANSMISSION) != 0):
            return 0
        correction = shading_correction(hit.n_facing, n_g, hit.wo, link.wc)
        if cos_s == 0.0 or correction == 0.0:
            return 0
        f = wp.static(bsdf.eval)(
            materials, hit.material, hit.n_facing, hit.wo, link.wc, interface.eta, hit.tex, hit.front, hit.tangent
        )
        scale = float(1.0)
        if wp.static(features.dielectric):
            if across:
                sigma = medium_sigma(materials, interface.media, interface.n_media)
                scale = importance_scale(BSDF_TRANSMISSION, interface.eta)
        value = wp.cw_mul(throughput, f) * (wp.abs(cos_s) * correction * scale * shadowing)
        return connect(
            geometry, materials, tracing, cam, who, rec, depth, parent, link, hit.p, hit.n, hit.err, value, sigma
        )

    @wp.func
    def trace_light_path(
        geometry: GeometryData,
        materials: MaterialData,
        lights: LightData,
        settings: IntegratorSettings,
        cam: CameraData,
        sampler: Sampler,
        tracing: LightTracing,
        rec: RayRecord,
        slot: wp.int32,
        s: wp.int32,
    ) -> wp.int32:
        """Light path ``s`` of ``slot``: its splats added (and its rays recorded); returns how many
        were dropped."""
        dropped = int(0)
        time = shutter_time(cam, 0.5)
        if wp.static(features.motion):
            if sampler.spp > 1:
                time = shutter_time(cam, sample_1d(sampler, slot, s, 0))
        who = slot_sample(slot, s, time)
        n_lights = wp.static(lighting.count)(lights)
        if n_lights == 0:
            return 0
        i = wp.min(int(sample_1d(sampler, slot, s, 1) * float(n_lights)), n_lights - 1)
        es = wp.static(lighting.sample_le)(
            geometry,
            materials,
            lights,
            i,
            tracing.center,
            tracing.radius,
            time,
            sample_2d(sampler, slot, s, 2),
            sample_2d(sampler, slot, s, 4),
            sample_1d(sampler, slot, s, 6),
        )
        selection = float(n_lights)

        # An emitter seen directly: the point on it, connected to the camera
        if es.pdf_area > 0.0 and max_component(es.radiance) > 0.0:
            u = sample_2d(sampler, slot, s, 7)
            link = link_camera(cam, es.o, concentric_disk(u[0], u[1]))
            if link.ok:
                cos_light = wp.dot(es.n, link.wc)
                if cos_light > 0.0:
                    value = es.radiance * (cos_light * selection / es.pdf_area)
                    err = point_error(es.o, 0.0)
                    dropped += connect(
                        geometry, materials, tracing, cam, who, rec, 1, -1, link, es.o, es.n, err, value, wp.vec3(0.0)
                    )

        throughput = es.weight * selection
        emitted = max_component(throughput)
        if not (emitted > 0.0) or not wp.isfinite(emitted):
            return dropped
        o = es.o
        if es.pdf_area > 0.0:
            o = spawn_origin(es.o, es.n, point_error(es.o, 0.0), es.d)
        d = es.d
        t_from = float(0.0)
        t_last = float(0.0)
        depth = int(1)  # segments so far, the one being traced included
        vertex = int(0)
        media = Media()
        n_media = int(0)
        kind = int(EMITTED)  # recording: how the segment being traced was spawned
        parent = int(-1)  # recording: the record of the segment that ended where it starts
        for _segment in range(4 * settings.max_depth + 16):
            if depth + 1 > settings.max_depth:  # no connection of this segment's end would count
                break
            found, parent = trace_segment(
                geometry, rec, who, kind, o, d, t_from, wp.inf, t_last, throughput, depth, parent
            )
            t = found.t
            prim = found.prim
            inst = found.inst
            if prim == NO_HIT:
                break
            if wp.static(features.dielectric):
                throughput = wp.cw_mul(throughput, medium_transmittance(materials, media, n_media, t - t_last))
            hit = surface_hit(geometry, materials, ray_hit(o, d, time, t, prim, inst))
            flags = bsdf_flags_from(materials, hit.material, hit.front)
            if flags == 0:
                break
            interface = no_interface(media, n_media)
            if wp.static(features.dielectric):
                interface = cross_interface(
                    materials, settings.exterior_ior, media, n_media, flags, hit.shape, hit.entering
                )
                if interface.n_media == MEDIA_OVERFLOW:
                    dropped += 1
                    break
                if not interface.real:  # a false interface: straight on, in the media beyond
                    media = interface.media
                    n_media = interface.n_media
                    t_from = past_hit(o, hit.p, t)
                    t_last = t
                    kind = STRAIGHT
                    continue
            n_g = wp.where(wp.dot(hit.n, hit.wo) < 0.0, -hit.n, hit.n)  # the geometric normal on the light's side
            shadowing = float(1.0)
            if wp.static(features.normal_map):
                shadowing = normal_map_shadowing(hit, hit.wo)

            # Connect to the camera where a lobe can send light toward it
            if non_specular(flags):
                u = sample_2d(sampler, slot, s, vertex_dim(vertex, 4))
                link = link_camera(cam, hit.p, concentric_disk(u[0], u[1]))
                if link.ok:
                    dropped += connect_surface(
                        geometry,
                        materials,
                        tracing,
                        cam,
                        who,
                        rec,
                        depth + 1,
                        parent,
                        link,
                        hit,
                        n_g,
                        flags,
                        interface,
                        media,
                        n_media,
                        throughput,
                        prim,
                        inst,
                    )

            # The next direction, from the BSDF with the light's side as wo
            uc = sample_1d(sampler, slot, s, vertex_dim(vertex, 2))
            u = sample_2d(sampler, slot, s, vertex_dim(vertex, 0))
            bs = wp.static(bsdf.sample)(
                materials, hit.material, hit.n_facing, hit.wo, interface.eta, uc, u, hit.tex, hit.front, hit.tangent
            )
            if bs.pdf == 0.0:
                break
            correction = shading_correction(hit.n_facing, n_g, hit.wo, bs.wi)
            if correction == 0.0:
                break
            scale = float(1.0)
            if wp.static(features.dielectric):
                scale = importance_scale(bs.flags, interface.eta)
            throughput = wp.cw_mul(throughput, bs.weight) * (correction * scale * shadowing)
            d = bs.wi
            depth += 1
            vertex += 1
            straight = bool(False)
            kind = bounce_kind(bs.flags, False)
            if (bs.flags & BSDF_TRANSMISSION) != 0:
                if wp.static(features.dielectric):
                    media = interface.media
                    n_media = interface.n_media
                straight = (bs.flags & BSDF_SPECULAR) != 0 and interface.eta == 1.0  # index-matched: straight on
                kind = bounce_kind(bs.flags, straight)
            if straight:
                t_from = past_hit(o, hit.p, t)
                t_last = t
            else:
                o = spawn_origin(hit.p, hit.n, hit.err, d)
                t_from = 0.0
                t_last = 0.0
            if depth > RR_DEPTH:
                q = wp.min(max_component(throughput) / emitted, 0.95)
                if sample_1d(sampler, slot, s, vertex_dim(vertex, 3)) >= q:
                    break
                throughput = throughput / q
        return dropped

    @wp.func
    def sky_seen(
        geometry: GeometryData,
        lights: LightData,
        cam: CameraData,
        tracing: LightTracing,
        rec: RayRecord,
        who: CameraRay,
        o: wp.vec3,
        d: wp.vec3,
    ) -> wp.int32:
        """The environment seen directly along the slot's camera ray ``o + s d`` (before
        clipping; its slot, sample and time ``who``'s), added to the slot's pixel (and the ray
        recorded); 1 if it was dropped."""
        slot = who.pixel
        o, t_max = clip_ray(cam, o, d)
        found, _index = trace_segment(geometry, rec, who, CAMERA, o, d, 0.0, t_max, 0.0, wp.vec3(1.0), 1, -1)
        if found.prim != NO_HIT:  # reaching the far clip plane is leaving the scene too
            return 0
        value = wp.static(lighting.environment_radiance)(lights, d, 0.0, True)
        if not wp.isfinite(value) or max_component(value) > SPLAT_LIMIT:
            return 1
        add_fixed(tracing, slot, value)
        return 0

    @wp.kernel(module=module)
    def trace_light_paths(
        geometry: GeometryData,
        materials: MaterialData,
        lights: LightData,
        settings: IntegratorSettings,
        cam: CameraData,
        sampler: Sampler,
        launch: RenderPass,
        tracing: LightTracing,
        film: Film,
        rec: RayRecord,
    ):
        slot = launch.first_pixel + wp.tid()
        x = slot % cam.width
        y = slot // cam.width
        mid_shutter = shutter_time(cam, 0.5)
        centre_o, centre = generate_ray(cam, x, y, 0.5, 0.5)
        if launch.first_sample == 0:
            o, t_max = clip_ray(cam, centre_o, centre)
            t, prim, inst = trace.closest_hit(geometry, o, centre, mid_shutter, 0.0, t_max)
            write_aovs(film, geometry, slot, ray_hit(o, centre, mid_shutter, t, prim, inst))
        dropped = int(0)
        if launch.first_sample > 0:
            dropped = film.rejected[slot]
        for s in range(launch.first_sample, launch.first_sample + launch.pass_spp):
            if tracing.sky != 0:
                o, d, time = camera_sample(
                    cam, sampler, slot, x, y, s, centre_o, centre, mid_shutter, wp.vec3i(9, 11, 0)
                )
                dropped += sky_seen(geometry, lights, cam, tracing, rec, slot_sample(slot, s, time), o, d)
            dropped += trace_light_path(geometry, materials, lights, settings, cam, sampler, tracing, rec, slot, s)
        film.rejected[slot] = dropped

    wp.set_module_options({**MODULE_OPTIONS, **(options or {})}, module=module)
    return trace_light_paths
