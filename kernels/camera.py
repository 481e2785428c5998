"""Camera rays (pinhole and thin lens), following the scene-format camera convention.

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
def camera_ray_direction(cam: CameraData, x: wp.int32, y: wp.int32, u: float, v: float) -> wp.vec3:
    """Unit world-space direction of the ray through film position (x + u, y + v)."""
    sx = 2.0 * (float(x) + u) / float(cam.width) - 1.0
    sy = 1.0 - 2.0 * (float(y) + v) / float(cam.height)
    d = (sx * cam.tan_half_fov * cam.aspect) * cam.right + (sy * cam.tan_half_fov) * cam.up + cam.forward
    return wp.normalize(d)


@wp.func
def thin_lens_ray(cam: CameraData, d: wp.vec3, disk: wp.vec2):
    """``(origin, direction)`` of the thin-lens ray for the pinhole direction ``d`` (unit) and a
    point ``disk`` of the unit disk; the pinhole ray itself when the aperture is 0."""
    if cam.aperture_radius <= 0.0:
        return cam.origin, d
    focus = cam.origin + d * (cam.focus_distance / wp.dot(d, cam.forward))
    lens = cam.origin + cam.aperture_radius * (disk[0] * cam.right + disk[1] * cam.up)
    return lens, wp.normalize(focus - lens)
