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
"""
import warp as wp


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
