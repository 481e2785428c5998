"""Camera rays (pinhole, thin lens and orthographic), following the scene-format camera convention.

Convention (world space, right-handed):
``forward = normalize(look_at - origin)``, ``right = normalize(cross(forward, up))``,
``up' = cross(right, forward)``. Pixel (x, y), with row 0 at the TOP of the image, is sampled at
film position (x + u, y + v), u, v in [0, 1); ``sx = 2(x+u)/W - 1``, ``sy = 1 - 2(y+v)/H`` and
``direction = normalize(sx tan(fov/2) aspect right + sy tan(fov/2) up' + forward)`` with ``fov``
the VERTICAL field of view and ``aspect = W / H``.

Thin lens (``aperture_radius > 0``): the ray through the film position above, from the lens
centre, meets the plane of focus (perpendicular to ``forward`` at ``focus_distance`` from the
lens) at a point F; the thin-lens ray starts at a uniform point of the lens disk (radius
``aperture_radius``, in the ``right``/``up'`` plane) and passes through F. Points on the plane of
focus are sharp; the pinhole ray is the lens-centre ray.

Orthographic (a parallel projection, ``CameraData.orthographic``): every ray travels along
``forward`` from the point ``origin + sx half_width right + sy half_height up'`` of the camera
plane (through ``origin``, perpendicular to ``forward``); ``half_height = half_width / aspect``.

Clip planes: a camera ray starts where its distance ALONG ``forward`` from the camera plane is
``near_clip`` and ends where it is ``far_clip`` (Mitsuba 3's ``near_clip`` / ``far_clip``): the unit
ray ``o + s d`` becomes ``o' + s d`` with ``o' = o + d near_clip / dot(d, forward)``, traced for
``s`` up to ``(far_clip - near_clip) / dot(d, forward)``; what lies beyond is a miss.

Pixel filter (``[render] filter``), by filter importance sampling: a sample's film position is
the pixel centre plus an offset drawn from the filter's density, and every sample weighs 1, so the
pixel converges to the filter-weighted average of the radiance around it (as Mitsuba 3's filters
of the same names, whose widths these are): ``box`` uniform over the pixel, ``tent`` a triangle
of radius 1 pixel, ``gaussian`` a Gaussian of standard deviation 0.5 pixel truncated at 2 pixels.
The filters are separable: x and y offsets are drawn independently.

Shutter: a camera sample is taken at a time drawn uniformly in ``[shutter_open, shutter_close]``
(moving shapes are where they are at that time); at one sample per pixel, at mid-shutter.
"""

import warp as wp

BOX = wp.constant(0)
TENT = wp.constant(1)
GAUSSIAN = wp.constant(2)
GAUSSIAN_SIGMA = wp.constant(0.5)  # pixels
GAUSSIAN_RADIUS = wp.constant(2.0)  # pixels: 4 standard deviations, Mitsuba 3's truncation


@wp.struct
class CameraData:
    """Camera frame precomputed on the host (world space, unit vectors)."""

    origin: wp.vec3
    forward: wp.vec3
    right: wp.vec3
    up: wp.vec3
    tan_half_fov: float  # tan(vertical fov / 2)
    aperture_radius: float  # world units; 0 = pinhole
    focus_distance: float  # from the lens to the plane of focus, along forward
    orthographic: wp.int32  # 1: parallel rays along forward (half_width, half_height); 0: perspective
    half_width: float  # orthographic: half the view's extent along right, world units
    half_height: float  # orthographic: half_width / aspect
    near_clip: float  # world units along forward from the camera plane: where rays start
    far_clip: float  # ... and where they end (inf: no far clip)
    aspect: float  # width / height
    width: wp.int32
    height: wp.int32
    filter: wp.int32  # BOX, TENT or GAUSSIAN
    shutter_open: float
    shutter_close: float


@wp.func
def filter_offset(filter: wp.int32, u: float) -> float:
    """Offset (pixels) from the pixel centre along one axis, distributed as the filter's profile,
    for a uniform ``u`` in [0, 1)."""
    if filter == TENT:
        if u < 0.5:
            return wp.sqrt(2.0 * u) - 1.0
        return 1.0 - wp.sqrt(2.0 - 2.0 * u)
    if filter == GAUSSIAN:
        # inverse CDF of the normal distribution truncated to [-radius, radius]
        edge = wp.erf(GAUSSIAN_RADIUS / (GAUSSIAN_SIGMA * wp.sqrt(2.0)))
        return GAUSSIAN_SIGMA * wp.sqrt(2.0) * wp.erfinv(edge * (2.0 * u - 1.0))
    return u - 0.5


@wp.func
def film_position(cam: CameraData, u: wp.vec2) -> wp.vec2:
    """Position (pixels) of a sample within its pixel, (0.5, 0.5) being the centre."""
    return wp.vec2(0.5 + filter_offset(cam.filter, u[0]), 0.5 + filter_offset(cam.filter, u[1]))


@wp.func
def shutter_time(cam: CameraData, u: float) -> float:
    """Time of a camera sample, uniform over the shutter interval."""
    return cam.shutter_open + (cam.shutter_close - cam.shutter_open) * u


@wp.func
def screen_position(cam: CameraData, x: wp.int32, y: wp.int32, u: float, v: float) -> wp.vec2:
    """``(sx, sy)`` of film position (x + u, y + v): -1 at the left and bottom edges of the image, 1
    at the right and top."""
    return wp.vec2(2.0 * (float(x) + u) / float(cam.width) - 1.0, 1.0 - 2.0 * (float(y) + v) / float(cam.height))


@wp.func
def camera_ray_direction(cam: CameraData, x: wp.int32, y: wp.int32, u: float, v: float) -> wp.vec3:
    """Unit world-space direction of the pinhole ray through film position (x + u, y + v)."""
    s = screen_position(cam, x, y, u, v)
    d = (s[0] * cam.tan_half_fov * cam.aspect) * cam.right + (s[1] * cam.tan_half_fov) * cam.up + cam.forward
    return wp.normalize(d)


@wp.func
def orthographic_ray_origin(cam: CameraData, x: wp.int32, y: wp.int32, u: float, v: float) -> wp.vec3:
    """World-space start, on the camera plane, of the orthographic ray through film position (x + u, y + v)."""
    s = screen_position(cam, x, y, u, v)
    return cam.origin + (s[0] * cam.half_width) * cam.right + (s[1] * cam.half_height) * cam.up


def make_generate_ray(orthographic: bool):
    """``generate_ray(cam, x, y, u, v) -> (o, d)``: start and unit direction (world space, before
    clipping) of the camera ray through film position (x + u, y + v): the pinhole ray, or the
    orthographic one for an orthographic ``cam``; that case is compiled in only when ``orthographic``
    (the scene's ``Features``)."""

    @wp.func
    def generate_ray(cam: CameraData, x: wp.int32, y: wp.int32, u: float, v: float):
        if wp.static(orthographic):
            if cam.orthographic != 0:
                return orthographic_ray_origin(cam, x, y, u, v), cam.forward
        return cam.origin, camera_ray_direction(cam, x, y, u, v)

    return generate_ray


@wp.func
def thin_lens_ray(cam: CameraData, o: wp.vec3, d: wp.vec3, disk: wp.vec2):
    """``(origin, direction)`` of the thin-lens ray for the pinhole ray ``o + s d`` (unit ``d``) and a
    point ``disk`` of the unit disk; the ray ``(o, d)`` itself when the aperture is 0 (a pinhole,
    or an orthographic camera)."""
    if cam.aperture_radius <= 0.0:
        return o, d
    focus = cam.origin + d * (cam.focus_distance / wp.dot(d, cam.forward))
    lens = cam.origin + cam.aperture_radius * (disk[0] * cam.right + disk[1] * cam.up)
    return lens, wp.normalize(focus - lens)


@wp.func
def clip_ray(cam: CameraData, o: wp.vec3, d: wp.vec3):
    """``(o', t_max)``: the camera ray ``o + s d`` (unit ``d``, ``o`` on the camera plane) started on
    the near clip plane, ``o' = o + d near_clip / dot(d, forward)``, and the ``s`` at which it
    meets the far clip plane (inf without one)."""
    cos_theta = wp.dot(d, cam.forward)
    return o + d * (cam.near_clip / cos_theta), (cam.far_clip - cam.near_clip) / cos_theta
