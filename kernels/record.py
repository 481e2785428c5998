"""Ray recording: the buffer the render kernels fill with every segment they trace, when asked.

The integrators are compiled in two variants (``wrt.kernels.integrator.make_render_kernel(...,
record=...)``). In the recording variant each ray the kernel traces is appended here, in the
order the thread traced it, through an atomic counter; in the rendering variant the calls are
compiled out (``wp.static``) and the buffer is never touched.

A ``Segment`` is one straight piece of a ray (world space, float32):

========== ========= ==============================================================================
field      type      meaning
========== ========= ==============================================================================
pixel      int32     pixel index ``y * width + x`` (row 0 at the top)
sample     int32     sample index within the pixel (0 with ``spp = 1``: the pixel centre)
kind       int32     how the ray was spawned: ``CAMERA``, ``SHADOW_LIT``, ``SHADOW_BLOCKED``,
                     ``REFLECTED``, ``REFRACTED``, ``TOTAL_INTERNAL``, ``STRAIGHT``, ``SCATTERED``,
                     ``EMITTED``, ``TO_CAMERA``, ``TO_CAMERA_BLOCKED``
flags      int32     ``HIT``: ends on a surface; ``ENTERING``: hits it from its front side (against
                     ``normal``); ``ESCAPED``: left the scene (a miss, or a shadow ray toward a
                     directional light): ``end = origin + direction``, unit length;
                     ``IN_MEDIUM``: ends at a scattering event in a participating medium
origin     vec3      where the ray starts (offset off the surface it leaves, as traced)
direction  vec3      the unit direction it was traced with
time       float     its ray time (the camera sample's time in the shutter interval)
end        vec3      hit point ``origin + t direction``; the light's position for a shadow ray that
                     reaches a point or spot light; ``origin + direction`` when ``ESCAPED``
normal     vec3      unit geometric normal at the hit (outward for spheres and closed meshes, the
                     winding normal for triangles, the given normal for planes and polygons), not
                     flipped toward the ray; 0 without ``HIT``
shape      int32     ``object_id`` of the surface hit, -1 without ``HIT``
throughput vec3      path weight the segment carries (1 for the camera ray; a shadow ray: the path
                     weight at its origin times the shadow transmittance, 0 when blocked)
depth      int32     ray segments of the path up to and including this one (camera ray = 1), the
                     ``max_depth`` counting
parent     int32     buffer index of the segment whose end this one starts from, -1 for a camera ray
========== ========= ==============================================================================

Kinds: ``STRAIGHT`` is a ray continuing unbent through a false interface (the surface of a
dielectric that does not own the space, see ``wrt.kernels.whitted``); ``TOTAL_INTERNAL`` is a
reflection at a dielectric past the critical angle. ``SCATTERED`` is a direction drawn from a
diffuse, Phong or glossy BSDF (the path integrator). The light tracer (``wrt.kernels.ptracer``)
records its paths from the lights: ``EMITTED`` the ray leaving a light (no parent), then the
bounces' kinds, and at each vertex its connection to the camera, ``TO_CAMERA`` up to the lens
(carrying what it splats onto the film, the camera's importance included) or
``TO_CAMERA_BLOCKED`` ending at the surface that stopped it; its ``pixel`` is the slot that traced
it, not the pixel the light reaches. Later integrators add kinds at the end.

Capacity: ``count[0]`` counts every append, stored or not; segments beyond ``segments.shape[0]``
are dropped (a truncated recording), and their children still name them as parents.
"""

import warp as wp

from .materials.interface import BSDF_SPECULAR, BSDF_TOTAL_INTERNAL, BSDF_TRANSMISSION
from .traverse import NO_HIT, GeometryData, RayHit, hit_point, hit_shape

CAMERA = wp.constant(0)
SHADOW_LIT = wp.constant(1)
SHADOW_BLOCKED = wp.constant(2)
REFLECTED = wp.constant(3)
REFRACTED = wp.constant(4)
TOTAL_INTERNAL = wp.constant(5)
STRAIGHT = wp.constant(6)
SCATTERED = wp.constant(7)
EMITTED = wp.constant(8)
TO_CAMERA = wp.constant(9)
TO_CAMERA_BLOCKED = wp.constant(10)
KIND_NAMES = (
    "camera",
    "shadow to light",
    "shadow blocked",
    "reflected",
    "refracted",
    "total internal reflection",
    "straight through",
    "scattered",
    "emitted",
    "to camera",
    "to camera blocked",
)


@wp.func
def bounce_kind(flags: wp.int32, straight: bool) -> wp.int32:
    """The kind of the segment a BSDF sample of lobe ``flags`` spawns: ``SCATTERED`` off a
    non-specular lobe; off a specular one ``REFLECTED`` (``TOTAL_INTERNAL`` past the critical
    angle), ``REFRACTED``, or ``STRAIGHT`` where it goes on unbent (``straight``: index-matched)."""
    if (flags & BSDF_SPECULAR) == 0:
        return SCATTERED
    if (flags & BSDF_TRANSMISSION) != 0:
        return wp.where(straight, STRAIGHT, REFRACTED)
    return wp.where((flags & BSDF_TOTAL_INTERNAL) != 0, TOTAL_INTERNAL, REFLECTED)


HIT = wp.constant(1)
ENTERING = wp.constant(2)
ESCAPED = wp.constant(4)
IN_MEDIUM = wp.constant(8)


@wp.struct
class Segment:
    pixel: wp.int32
    sample: wp.int32
    kind: wp.int32
    flags: wp.int32
    origin: wp.vec3
    direction: wp.vec3
    time: float
    end: wp.vec3
    normal: wp.vec3
    shape: wp.int32
    throughput: wp.vec3
    depth: wp.int32
    parent: wp.int32


@wp.struct
class RayRecord:
    """The record buffer: ``count`` (one int32, appends so far) and ``segments`` (the capacity)."""

    count: wp.array(dtype=wp.int32)
    segments: wp.array(dtype=Segment)


@wp.func
def record_ray(
    rec: RayRecord,
    geometry: GeometryData,
    pixel: wp.int32,
    sample: wp.int32,
    kind: wp.int32,
    found: RayHit,
    throughput: wp.vec3,
    depth: wp.int32,
    parent: wp.int32,
) -> wp.int32:
    """Append the segment of unit ray ``o + s d`` (at ray time ``time``) that ended at ``(t, prim, inst)``
    (``found``) as a trace returned it; returns its buffer index.

    ``prim == NO_HIT`` with finite ``t``: the ray ran its whole interval (a shadow ray reaching its
    light at distance ``t``); with ``t = inf`` it escaped the scene.
    """
    o = found.o
    d = found.d
    t = found.t
    prim = found.prim
    i = wp.atomic_add(rec.count, 0, 1)
    if i < rec.segments.shape[0]:
        s = Segment()
        s.pixel = pixel
        s.sample = sample
        s.kind = kind
        s.origin = o
        s.direction = d
        s.time = found.time
        s.throughput = throughput
        s.depth = depth
        s.parent = parent
        s.shape = -1
        s.normal = wp.vec3(0.0)
        if prim != NO_HIT:
            end, normal, _err = hit_point(geometry, found)
            s.end = end
            s.normal = normal
            s.shape = hit_shape(geometry, prim, found.inst)
            s.flags = HIT
            if wp.dot(d, s.normal) < 0.0:
                s.flags = HIT | ENTERING
        elif t < wp.inf:
            s.end = o + t * d
            s.flags = 0
        else:
            s.end = o + d
            s.flags = ESCAPED
        rec.segments[i] = s
    return i


@wp.func
def end_in_medium(rec: RayRecord, index: wp.int32, p: wp.vec3):
    """Make recorded segment ``index`` (as ``record_ray`` appended it, up to the surface beyond)
    end at ``p``, where it scattered in a participating medium: ``IN_MEDIUM``, no surface."""
    if index >= 0 and index < rec.segments.shape[0]:
        s = rec.segments[index]
        s.end = p
        s.normal = wp.vec3(0.0)
        s.shape = -1
        s.flags = IN_MEDIUM
        rec.segments[index] = s
