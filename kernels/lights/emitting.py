"""The emissive primitives (``wrt.emitting``: the triangles, polygons and spheres of emitting,
unmoving ``[[shape]]``s), sampled together as one more light after the light rows: a primitive
chosen by emitted power, then a uniform point on a triangle or polygon, a direction uniform in a
sphere's cone (for the light tracer: a uniform point on any of them, a cosine-weighted
direction). They emit their material's ``emission`` from their shading front (a sphere's
outside), as a path hitting them sees it. Scenes whose emissive primitives are all triangles
compile the triangles' code only (``Options.emissive_shapes``).
"""

import functools

import warp as wp

from ..materials import MaterialData
from ..sample_warps import cosine_hemisphere, find_interval
from ..sampling import Sampler, sample_1d, sample_2d
from ..textures import EMISSION, texture_rgb
from ..traverse import (
    KIND_BITS,
    KIND_MASK,
    POLYGON,
    SPHERE,
    TRIANGLE,
    GeometryData,
    make_texture_context,
    shading_normal,
)
from .data import EmissionSample, LightData, LightSample, surface_emission, surface_sample
from .interface import Family, Functions, Options
from .sphere import sample_sphere_cone, sphere_point, sphere_solid_angle

EMITTING = wp.constant(8)  # not a row's type: the pool, light ``lights.type.shape[0]``


@functools.cache
def make_emitting_index(shapes: bool):
    """``emitting_index``; with ``shapes``, of polygons and spheres too (else triangles only)."""

    @wp.func
    def emitting_index(lights: LightData, prim: wp.int32) -> wp.int32:
        """Index in the pool of emitting primitives of packed primitive id ``prim``, -1 if none."""
        kind = prim & KIND_MASK
        i = prim >> KIND_BITS
        if kind == TRIANGLE and i < lights.tri_emitter.shape[0]:
            return lights.tri_emitter[i]
        if wp.static(shapes):
            if kind == POLYGON and i < lights.poly_emitter.shape[0]:
                return lights.poly_emitter[i]
            if kind == SPHERE and i < lights.sphere_emitter.shape[0]:
                return lights.sphere_emitter[i]
        return -1

    return emitting_index


@functools.cache
def make_emitting_pdf(shapes: bool, smooth: bool):
    """``emitting_pdf``; with ``shapes``, of polygons and spheres too (else triangles only); with
    ``smooth``, a smooth-shaded triangle's cosine at the light is its interpolated normal's."""

    @wp.func
    def emitting_pdf(
        geometry: GeometryData, lights: LightData, e: wp.int32, p: wp.vec3, wi: wp.vec3, dist: float
    ) -> float:
        """Solid-angle density with which ``sample_emitting`` picks direction ``wi`` from ``p``,
        given that the ray along ``wi`` meets emitting primitive ``e`` at ``dist``: its selection
        probability times, for a triangle or polygon, ``dist^2 / (area |cos|)`` at it (either side;
        emission is judged apart), for a sphere ``1 / (2 pi (1 - cos_max))`` (0 from inside).

        A smooth-shaded triangle stands for the curved surface its vertex normals describe: ``cos``
        is the interpolated normal's at the point (Mitsuba 3's mesh emitters: ``sample_position``
        and ``pdf_direction`` take the shading normal). Emitting primitives do not move, so the
        normal is the one at time 0."""
        selection = lights.emit_cdf[e + 1] - lights.emit_cdf[e]
        i = lights.emit_prim[e]
        if wp.static(shapes):
            kind = lights.emit_kind[e]
            if kind == SPHERE:
                solid_angle = sphere_solid_angle(geometry.sphere_center[i], geometry.sphere_radius[i], p)
                return wp.where(solid_angle == 0.0, 0.0, selection / solid_angle)
            if kind == POLYGON:
                cos_light = wp.abs(wp.dot(wi, geometry.poly_normal[i]))
                if cos_light <= 0.0:
                    return 0.0
                return selection * dist * dist / (lights.emit_area[e] * cos_light)
        a = geometry.tri_verts[3 * i]
        m = wp.cross(geometry.tri_verts[3 * i + 1] - a, geometry.tri_verts[3 * i + 2] - a)
        twice_area = wp.length(m)
        cos_light = wp.abs(wp.dot(wi, m)) / twice_area
        if wp.static(smooth):
            ng = m / twice_area
            ns = shading_normal(geometry, (i << KIND_BITS) | TRIANGLE, -1, p + dist * wi, ng, 0.0)
            if ns[0] != ng[0] or ns[1] != ng[1] or ns[2] != ng[2]:  # a smooth triangle (a flat one: ng itself)
                cos_light = wp.abs(wp.dot(wi, ns))
        if cos_light <= 0.0:
            return 0.0
        return selection * dist * dist / (0.5 * twice_area * cos_light)

    return emitting_pdf


@wp.func
def pick_emitting(lights: LightData, uc: float):
    """The emissive primitive ``uc`` in [0, 1) chooses by power: ``(its row e, its selection
    probability, what is left of uc rescaled to [0, 1])``."""
    e = find_interval(lights.emit_cdf, 0, lights.emit_cdf.shape[0], uc)
    below = lights.emit_cdf[e]
    selection = lights.emit_cdf[e + 1] - below
    return e, selection, wp.clamp((uc - below) / selection, 0.0, 1.0)


@wp.func
def polygon_triangle(lights: LightData, e: wp.int32, x: float) -> wp.int32:
    """The triangle of emitting polygon ``e`` (an index into ``emit_corner`` / 3) that ``x`` in
    [0, 1) picks by area: the first whose running area fraction exceeds ``x``."""
    lo = lights.emit_first[e]
    hi = lights.emit_first[e + 1] - 1
    while lo < hi:
        mid = (lo + hi) // 2
        if lights.emit_area_cdf[mid] <= x:
            lo = mid + 1
        else:
            hi = mid
    return lo


@functools.cache
def make_emission_at(textures: bool):
    """``emission_at``; with ``textures``, an emission texture is looked up (else the constant)."""
    texture_context = make_texture_context(False)  # disks and cylinders are not in the pool

    @wp.func
    def emission_at(
        geometry: GeometryData, materials: MaterialData, shape: wp.int32, prim: wp.int32, q: wp.vec3, time: float
    ) -> wp.vec3:
        """Radiance (W/(m^2 sr)) that shape ``shape``'s material emits at point ``q`` of packed
        primitive ``prim``: its emission texture's value at ``q``'s uv, else its constant."""
        m = materials.shape_material[shape]
        if wp.static(textures):
            t = materials.textures.slot[m, EMISSION]
            if t >= 0:
                return texture_rgb(materials.textures, t, texture_context(geometry, prim, -1, q, time))
        return materials.emission[m]

    return emission_at


@functools.cache
def make_emitting_point(smooth: bool, shapes: bool):
    """``emitting_point``; with ``smooth``, a smooth-shaded triangle's normal is its interpolated
    one; with ``shapes``, polygons are in the pool too (else triangles only)."""

    @wp.func
    def emitting_point(geometry: GeometryData, lights: LightData, e: wp.int32, x: float, u: wp.vec2, time: float):
        """A uniform point on emitting triangle or polygon ``e`` by ``u`` (a polygon's triangle chosen
        by area with ``x`` in [0, 1)): ``(q, its emitting normal, its shape, its packed primitive id)``."""
        i = lights.emit_prim[e]
        kind = int(TRIANGLE)
        if wp.static(shapes):
            kind = lights.emit_kind[e]
        a = wp.vec3(0.0)
        b = wp.vec3(0.0)
        c = wp.vec3(0.0)
        shape = int(0)
        if kind == TRIANGLE:
            a = geometry.tri_verts[3 * i]
            b = geometry.tri_verts[3 * i + 1]
            c = geometry.tri_verts[3 * i + 2]
            shape = geometry.tri_shape[i]
        if wp.static(shapes):
            if kind == POLYGON:
                k = polygon_triangle(lights, e, x)
                a = lights.emit_corner[3 * k]
                b = lights.emit_corner[3 * k + 1]
                c = lights.emit_corner[3 * k + 2]
                shape = geometry.poly_shape[i]
        su = wp.sqrt(u[0])
        q = a + su * (1.0 - u[1]) * (b - a) + su * u[1] * (c - a)
        prim = (i << KIND_BITS) | kind
        ns = wp.normalize(wp.cross(b - a, c - a))
        if wp.static(shapes):
            if kind == POLYGON:
                ns = geometry.poly_normal[i]
        if wp.static(smooth):
            if kind == TRIANGLE:
                ns = shading_normal(geometry, prim, -1, q, ns, time)
        return q, ns, shape, prim

    return emitting_point


@functools.cache
def make_sample_emitting(smooth: bool, shapes: bool, textures: bool):
    """``sample_emitting``; with ``smooth``, the emitting side of a smooth-shaded triangle is its
    interpolated shading normal's, as for a path that hits it; with ``shapes``, polygons and
    spheres are in the pool too (else triangles only); with ``textures``, emission textures."""
    emitting_pdf = make_emitting_pdf(shapes, smooth)
    emitting_point = make_emitting_point(smooth, shapes)
    emission_at = make_emission_at(textures)

    @wp.func
    def sample_emitting(
        geometry: GeometryData,
        materials: MaterialData,
        lights: LightData,
        p: wp.vec3,
        time: float,
        uc: float,
        u1: float,
        u2: float,
    ):
        """Direction toward an emitting primitive from ``p``: ``(wi, distance, radiance, pdf)``,
        the primitive chosen by ``uc`` with its power probability; on a triangle a uniform point
        by ``(u1, u2)``, on a polygon likewise in one of its triangles chosen by area with what is
        left of ``uc``, toward a sphere a direction uniform in its cone (none from inside);
        radiance zero where a back faces ``p``."""
        e, selection, x = pick_emitting(lights, uc)
        if wp.static(shapes):
            if lights.emit_kind[e] == SPHERE:
                i = lights.emit_prim[e]
                wi, dist, solid_angle = sample_sphere_cone(
                    geometry.sphere_center[i], geometry.sphere_radius[i], p, u1, u2
                )
                if solid_angle == 0.0:
                    return wi, dist, wp.vec3(0.0), 0.0
                q = p + dist * wi
                radiance = emission_at(
                    geometry, materials, geometry.sphere_shape[i], (i << KIND_BITS) | SPHERE, q, time
                )
                return wi, dist, radiance, selection / solid_angle
        q, ns, shape, prim = emitting_point(geometry, lights, e, x, wp.vec2(u1, u2), time)
        to_q = q - p
        dist2 = wp.dot(to_q, to_q)
        if dist2 == 0.0:
            return wp.vec3(0.0, 0.0, 1.0), 0.0, wp.vec3(0.0), 0.0
        dist = wp.sqrt(dist2)
        wi = to_q / dist
        if wp.dot(wi, ns) >= 0.0:
            return wi, dist, wp.vec3(0.0), 0.0
        radiance = emission_at(geometry, materials, shape, prim, q, time)
        return wi, dist, radiance, emitting_pdf(geometry, lights, e, p, wi, dist)

    return sample_emitting


@functools.cache
def make_emit_emitting(smooth: bool, shapes: bool, textures: bool):
    """``emit_emitting``; with ``smooth``, a smooth-shaded triangle emits about its interpolated
    normal; with ``shapes``, polygons and spheres are in the pool too (else triangles only); with
    ``textures``, emission textures."""
    emitting_point = make_emitting_point(smooth, shapes)
    emission_at = make_emission_at(textures)

    @wp.func
    def emit_emitting(
        geometry: GeometryData,
        materials: MaterialData,
        lights: LightData,
        time: float,
        uc: float,
        u_pos: wp.vec2,
        u_dir: wp.vec2,
    ) -> EmissionSample:
        """A ray leaving an emitting primitive chosen by ``uc`` with its power probability: a
        uniform point on it (a polygon's triangle chosen by area with what is left of ``uc``), a
        cosine-weighted direction about its emitting normal."""
        e, selection, x = pick_emitting(lights, uc)
        local = cosine_hemisphere(u_dir[0], u_dir[1])
        if wp.static(shapes):
            if lights.emit_kind[e] == SPHERE:
                i = lights.emit_prim[e]
                q, n, area = sphere_point(geometry.sphere_center[i], geometry.sphere_radius[i], u_pos)
                radiance = emission_at(
                    geometry, materials, geometry.sphere_shape[i], (i << KIND_BITS) | SPHERE, q, time
                )
                return surface_emission(q, n, radiance, selection / area, local)
        q, ns, shape, prim = emitting_point(geometry, lights, e, x, u_pos, time)
        radiance = emission_at(geometry, materials, shape, prim, q, time)
        return surface_emission(q, ns, radiance, selection / lights.emit_area[e], local)

    return emit_emitting


@functools.cache
def make(options: Options) -> Functions:
    emitting_index = make_emitting_index(options.emissive_shapes)
    emitting_pdf = make_emitting_pdf(options.emissive_shapes, options.smooth)
    sample_emitting = make_sample_emitting(options.smooth, options.emissive_shapes, options.textures)
    emit_emitting = make_emit_emitting(options.smooth, options.emissive_shapes, options.textures)

    @wp.func
    def owns(light_type: wp.int32) -> bool:
        return light_type == EMITTING

    @wp.func
    def sample_li(
        geometry: GeometryData,
        materials: MaterialData,
        lights: LightData,
        i: wp.int32,
        p: wp.vec3,
        time: float,
        sampler: Sampler,
        pixel: wp.int32,
        sample: wp.int32,
        dim: wp.int32,
    ) -> LightSample:
        """The primitive chosen at dimension ``dim + 2``, the point or direction on it at ``dim``."""
        u = sample_2d(sampler, pixel, sample, dim)
        uc = sample_1d(sampler, pixel, sample, dim + 2)
        wi, dist, radiance, pdf = sample_emitting(geometry, materials, lights, p, time, uc, u[0], u[1])
        return surface_sample(wi, dist, radiance, pdf)

    @wp.func
    def sample_le(
        geometry: GeometryData,
        materials: MaterialData,
        lights: LightData,
        i: wp.int32,
        center: wp.vec3,
        radius: float,
        time: float,
        u_pos: wp.vec2,
        u_dir: wp.vec2,
        uc: float,
    ) -> EmissionSample:
        return emit_emitting(geometry, materials, lights, time, uc, u_pos, u_dir)

    @wp.func
    def pdf_li(
        geometry: GeometryData,
        lights: LightData,
        shape: wp.int32,
        prim: wp.int32,
        inst: wp.int32,
        p: wp.vec3,
        wi: wp.vec3,
        dist: float,
    ) -> float:
        """Primitives outside instances only: those seen through an instance are not in the pool."""
        if inst < 0:
            e = emitting_index(lights, prim)
            if e >= 0:
                return emitting_pdf(geometry, lights, e, p, wi, dist)
        return 0.0

    return Functions(owns, sample_li, sample_le, pdf_li)


FAMILY = Family(name="emitting", codes=(EMITTING,), make=make, feature="emissive")
