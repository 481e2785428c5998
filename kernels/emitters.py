"""Emitters with area (parallelogram and sphere lights) and the environment: sampling a direction
toward them from a point, and the density of a direction that hit them, for next-event
estimation with multiple importance sampling.

Units: ``radiance`` in W/(m^2 sr). A parallelogram light (``corner``, ``edge_u``, ``edge_v``)
emits from the side of ``cross(edge_u, edge_v)`` only; a sphere light outward; the environment
uniformly from every direction, or as its map says (Mitsuba 3's ``envmap``: ``wrt.envmap``
describes the mapping, the bilinear lookup and the distribution the map is sampled with).
Densities are per unit solid angle at the receiving point.

Emissive primitives (``wrt.emitting``: the triangles, polygons and spheres of emitting, unmoving
``[[shape]]``s) are sampled together as one more emitter: a primitive chosen by emitted power,
then a uniform point on a triangle or polygon, a direction uniform in a sphere's cone; they emit
their material's ``emission`` from their shading front (a sphere's outside), as a path hitting
them sees it. Scenes whose emissive primitives are all triangles compile the triangles' code only.
"""

import functools

import warp as wp

from .intersect import intersect_sphere
from .lights import AREA, ENVIRONMENT, ENVIRONMENT_MAP, SPHERE_LIGHT, LightData
from .materials import MaterialData
from .sample_warps import cone_one_minus_cos, frame, uniform_cone, uniform_sphere
from .traverse import KIND_BITS, KIND_MASK, POLYGON, SPHERE, TRIANGLE, GeometryData, shading_normal


@wp.func
def area_normal_and_size(lights: LightData, i: wp.int32):
    """Unit emitting normal and area of parallelogram light ``i``."""
    n = wp.cross(lights.edge_u[i], lights.edge_v[i])
    area = wp.length(n)
    return n / area, area


@wp.func
def sphere_solid_angle(center: wp.vec3, r: float, p: wp.vec3) -> float:
    """Solid angle ``2 pi (1 - cos_max)`` that a sphere subtends from ``p``; 0 from inside it."""
    to_c = center - p
    dist2 = wp.dot(to_c, to_c)
    if dist2 <= r * r:
        return 0.0
    return 2.0 * wp.pi * cone_one_minus_cos(r * r / dist2)


@wp.func
def sample_sphere_cone(center: wp.vec3, r: float, p: wp.vec3, u1: float, u2: float):
    """A direction from ``p`` uniform in the cone a sphere subtends: ``(wi, distance to the sphere
    along wi, the cone's solid angle)`` (the density is its inverse); from inside the sphere
    ``((0, 0, 1), 0, 0)``."""
    to_c = center - p
    dist2 = wp.dot(to_c, to_c)
    if dist2 <= r * r:
        return wp.vec3(0.0, 0.0, 1.0), 0.0, 0.0
    one_minus_cos = cone_one_minus_cos(r * r / dist2)
    wi = frame(to_c / wp.sqrt(dist2)) * uniform_cone(u1, u2, one_minus_cos)
    tangent = wp.sqrt(wp.max(0.0, dist2 - r * r))
    dist = intersect_sphere(p, wi, center, r, 0.0, tangent * 2.0)
    if dist >= tangent * 2.0:  # grazing the silhouette: rounding missed it
        dist = tangent
    return wi, dist, 2.0 * wp.pi * one_minus_cos


@wp.func
def sample_emitter(lights: LightData, i: wp.int32, p: wp.vec3, u1: float, u2: float):
    """Direction toward emitter ``i`` from ``p``: ``(wi, distance, radiance, pdf)``.

    Parallelogram: a uniform point on it (density 1/area converted to solid angle, ``d^2 /
    (area cos)``), zero where its back faces ``p``. Sphere: uniform in the cone it subtends
    (``1 / (2 pi (1 - cos_max))``, with ``1 - cos_max`` from ``r^2 / d^2`` without cancellation,
    so a sphere of 1e-7 of its distance keeps its irradiance), zero from inside. Environment: uniform on the sphere
    (``1 / (4 pi)``), infinitely far.
    """
    kind = lights.type[i]
    if kind == AREA:
        q = lights.position[i] + u1 * lights.edge_u[i] + u2 * lights.edge_v[i]
        to_q = q - p
        dist2 = wp.dot(to_q, to_q)
        dist = wp.sqrt(dist2)
        wi = to_q / dist
        n, area = area_normal_and_size(lights, i)
        cos_light = -wp.dot(wi, n)
        if cos_light <= 0.0 or dist2 == 0.0:
            return wi, dist, wp.vec3(0.0), 0.0
        return wi, dist, lights.power[i], dist2 / (area * cos_light)
    if kind == SPHERE_LIGHT:
        wi, dist, solid_angle = sample_sphere_cone(lights.position[i], lights.radius[i], p, u1, u2)
        if solid_angle == 0.0:
            return wi, dist, wp.vec3(0.0), 0.0
        return wi, dist, lights.power[i], 1.0 / solid_angle
    return uniform_sphere(u1, u2), wp.inf, lights.power[i], 1.0 / (4.0 * wp.pi)


@wp.func
def emitter_pdf(lights: LightData, i: wp.int32, p: wp.vec3, wi: wp.vec3, dist: float) -> float:
    """Solid-angle density with which ``sample_emitter`` picks direction ``wi`` from ``p``, given
    that the ray along ``wi`` meets emitter ``i`` at ``dist`` (for MIS weights of BSDF samples)."""
    kind = lights.type[i]
    if kind == AREA:
        n, area = area_normal_and_size(lights, i)
        cos_light = -wp.dot(wi, n)
        if cos_light <= 0.0:
            return 0.0
        return dist * dist / (area * cos_light)
    if kind == SPHERE_LIGHT:
        solid_angle = sphere_solid_angle(lights.position[i], lights.radius[i], p)
        return wp.where(solid_angle == 0.0, 0.0, 1.0 / solid_angle)
    if kind == ENVIRONMENT:
        return 1.0 / (4.0 * wp.pi)
    return 0.0


@wp.func
def find_interval(cdf: wp.array(dtype=float), start: wp.int32, n: wp.int32, x: float) -> wp.int32:
    """The interval ``k`` in [0, n - 2] of the ``n`` CDF values from ``cdf[start]`` (0 to 1) holding
    ``x`` in [0, 1): ``cdf[start + k] <= x < cdf[start + k + 1]``, never an empty one."""
    lo = int(0)
    hi = n - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if cdf[start + mid] <= x:
            lo = mid
        else:
            hi = mid
    return lo


@wp.func
def environment_map_cell(lights: LightData, w: wp.vec3):
    """The cell ``(j, i)`` of the environment map that world direction ``w`` falls in, and where in
    it: ``(j, i, fy, fx)`` with fy, fx in [0, 1] from row j and (wrapping) column i toward the next."""
    height = lights.env_radiance.shape[0]
    width = lights.env_radiance.shape[1]
    local = wp.transpose(lights.env_to_world) * w
    u = wp.atan2(local[0], -local[2]) / (2.0 * wp.pi)
    x = u * float(width) - 0.5
    x = x - wp.floor(x / float(width)) * float(width)
    y = wp.acos(wp.clamp(local[1], -1.0, 1.0)) / wp.pi * float(height - 1)
    i = wp.clamp(int(x), 0, width - 1)
    j = wp.clamp(int(y), 0, height - 2)
    return j, i, y - float(j), x - float(i)


@wp.func
def environment_map_radiance(lights: LightData, k: wp.int32, w: wp.vec3) -> wp.vec3:
    """Radiance (W/(m^2 sr)) arriving from world direction ``w`` (unit, pointing away from the
    receiver) out of environment map light ``k``: the map looked up bilinearly, times its ``power``."""
    j, i, fy, fx = environment_map_cell(lights, w)
    i1 = (i + 1) % lights.env_radiance.shape[1]
    top = lights.env_radiance[j, i] * (1.0 - fx) + lights.env_radiance[j, i1] * fx
    bottom = lights.env_radiance[j + 1, i] * (1.0 - fx) + lights.env_radiance[j + 1, i1] * fx
    return wp.cw_mul(lights.power[k], top * (1.0 - fy) + bottom * fy)


@wp.func
def environment_map_pdf(lights: LightData, w: wp.vec3) -> float:
    """Solid-angle density with which ``sample_environment_map`` picks world direction ``w``."""
    j, i, fy, fx = environment_map_cell(lights, w)
    return lights.env_pdf[j, i]


@wp.func
def sample_environment_map(lights: LightData, k: wp.int32, u1: float, u2: float):
    """A direction from environment map light ``k`` by its luminance: ``(wi, radiance, pdf)``, wi
    world space. A cell row by ``u1``, a cell within it by ``u2``, then uniform in azimuth and
    ``cos theta`` within the cell by what is left of each."""
    height = lights.env_radiance.shape[0]
    width = lights.env_radiance.shape[1]
    cdf = lights.env_cdf
    j = find_interval(cdf, 0, height, u1)
    fv = wp.clamp((u1 - cdf[j]) / (cdf[j + 1] - cdf[j]), 0.0, 1.0)
    start = height + j * (width + 1)
    i = find_interval(cdf, start, width + 1, u2)
    fu = wp.clamp((u2 - cdf[start + i]) / (cdf[start + i + 1] - cdf[start + i]), 0.0, 1.0)
    step = wp.pi / float(height - 1)
    cos0 = wp.cos(float(j) * step)
    cos_theta = cos0 + fv * (wp.cos(float(j + 1) * step) - cos0)
    sin_theta = wp.sqrt(wp.max(0.0, 1.0 - cos_theta * cos_theta))
    phi = 2.0 * wp.pi * (float(i) + fu + 0.5) / float(width)
    local = wp.vec3(sin_theta * wp.sin(phi), cos_theta, -sin_theta * wp.cos(phi))
    wi = lights.env_to_world * local
    return wi, environment_map_radiance(lights, k, wi), lights.env_pdf[j, i]


@wp.func
def sample_emitter_or_map(lights: LightData, i: wp.int32, p: wp.vec3, u1: float, u2: float):
    """``sample_emitter`` for scenes with an environment map light, which it samples too."""
    if lights.type[i] == ENVIRONMENT_MAP:
        wi, radiance, pdf = sample_environment_map(lights, i, u1, u2)
        return wi, wp.inf, radiance, pdf
    return sample_emitter(lights, i, p, u1, u2)


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
def make_emitting_pdf(shapes: bool):
    """``emitting_pdf``; with ``shapes``, of polygons and spheres too (else triangles only)."""

    @wp.func
    def emitting_pdf(
        geometry: GeometryData, lights: LightData, e: wp.int32, p: wp.vec3, wi: wp.vec3, dist: float
    ) -> float:
        """Solid-angle density with which ``sample_emitting`` picks direction ``wi`` from ``p``,
        given that the ray along ``wi`` meets emitting primitive ``e`` at ``dist``: its selection
        probability times, for a triangle or polygon, ``dist^2 / (area |cos|)`` at it (either side;
        emission is judged apart), for a sphere ``1 / (2 pi (1 - cos_max))`` (0 from inside)."""
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
        if cos_light <= 0.0:
            return 0.0
        return selection * dist * dist / (0.5 * twice_area * cos_light)

    return emitting_pdf


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
def make_sample_emitting(smooth: bool, shapes: bool):
    """``sample_emitting``; with ``smooth``, the emitting side of a smooth-shaded triangle is its
    interpolated shading normal's, as for a path that hits it; with ``shapes``, polygons and
    spheres are in the pool too (else triangles only)."""
    emitting_pdf = make_emitting_pdf(shapes)

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
        e = find_interval(lights.emit_cdf, 0, lights.emit_cdf.shape[0], uc)
        i = lights.emit_prim[e]
        kind = int(TRIANGLE)
        if wp.static(shapes):
            kind = lights.emit_kind[e]
            if kind == SPHERE:
                wi, dist, solid_angle = sample_sphere_cone(
                    geometry.sphere_center[i], geometry.sphere_radius[i], p, u1, u2
                )
                if solid_angle == 0.0:
                    return wi, dist, wp.vec3(0.0), 0.0
                radiance = materials.emission[materials.shape_material[geometry.sphere_shape[i]]]
                selection = lights.emit_cdf[e + 1] - lights.emit_cdf[e]
                return wi, dist, radiance, selection / solid_angle
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
                below = lights.emit_cdf[e]
                x = wp.clamp((uc - below) / (lights.emit_cdf[e + 1] - below), 0.0, 1.0)
                k = polygon_triangle(lights, e, x)
                a = lights.emit_corner[3 * k]
                b = lights.emit_corner[3 * k + 1]
                c = lights.emit_corner[3 * k + 2]
                shape = geometry.poly_shape[i]
        su = wp.sqrt(u1)
        q = a + su * (1.0 - u2) * (b - a) + su * u2 * (c - a)
        to_q = q - p
        dist2 = wp.dot(to_q, to_q)
        if dist2 == 0.0:
            return wp.vec3(0.0, 0.0, 1.0), 0.0, wp.vec3(0.0), 0.0
        dist = wp.sqrt(dist2)
        wi = to_q / dist
        ns = wp.vec3(0.0)
        if kind == TRIANGLE:
            ns = wp.normalize(wp.cross(b - a, c - a))
            if wp.static(smooth):
                ns = shading_normal(geometry, (i << KIND_BITS) | TRIANGLE, -1, q, ns, time)
        if wp.static(shapes):
            if kind == POLYGON:
                ns = geometry.poly_normal[i]
        if wp.dot(wi, ns) >= 0.0:
            return wi, dist, wp.vec3(0.0), 0.0
        radiance = materials.emission[materials.shape_material[shape]]
        return wi, dist, radiance, emitting_pdf(geometry, lights, e, p, wi, dist)

    return sample_emitting
