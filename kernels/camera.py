"""Pinhole camera rays, following the scene-format camera convention.

Convention (world space, right-handed):
``forward = normalize(look_at - origin)``, ``right = normalize(cross(forward, up))``,
``up' = cross(right, forward)``. Pixel (x, y), with row 0 at the TOP of the image, is sampled at
film position (x + u, y + v), u, v in [0, 1); ``sx = 2(x+u)/W - 1``, ``sy = 1 - 2(y+v)/H`` and
``direction = normalize(sx tan(fov/2) aspect right + sy tan(fov/2) up' + forward)`` with ``fov``
the VERTICAL field of view and ``aspect = W / H``.
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
