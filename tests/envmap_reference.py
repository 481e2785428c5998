"""Float64 references for environment maps (wrt/envmap.py), shared by the kernel and scene tests."""

import numpy as np


def rotation(axis, degrees):
    """Rodrigues' rotation by ``degrees`` about ``axis`` (float64, right-handed, as Mitsuba's ``rotate``)."""
    k = np.asarray(axis, dtype=np.float64) / np.linalg.norm(axis)
    a = np.radians(degrees)
    cross = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(a) * cross + (1 - np.cos(a)) * cross @ cross


def sun_sky(width=64, height=32, sun=(40, 9), sun_radiance=2.0e4):
    """A dim blue gradient sky with a sun of one very bright pixel (column, row)."""
    v = (np.arange(height) + 0.5) / height
    image = np.empty((height, width, 3))
    image[:] = (np.array([0.3, 0.5, 1.0]) * (1.2 - v[:, None]))[:, None, :]
    image[sun[1], sun[0]] = sun_radiance
    return image


def bilinear_irradiance(image, n, to_world, size=(2048, 1024)):
    """Float64 reference: the irradiance at normal ``n`` (world) of Mitsuba's bilinear lookup of
    the map's green channel, by the midpoint rule over a fine (u, v) grid."""
    height, width = image.shape[:2]
    u = (np.arange(size[0]) + 0.5) / size[0]
    v = (np.arange(size[1]) + 0.5) / size[1]
    uu, vv = np.meshgrid(u, v)
    x = (uu * width - 0.5) % width
    y = vv * (height - 1)
    i, j = np.minimum(x.astype(int), width - 1), np.minimum(y.astype(int), height - 2)
    fx, fy = x - i, y - j
    g = image[..., 1].astype(np.float64)
    i1 = (i + 1) % width
    value = (g[j, i] * (1 - fx) + g[j, i1] * fx) * (1 - fy) + (g[j + 1, i] * (1 - fx) + g[j + 1, i1] * fx) * fy
    theta, phi = vv * np.pi, uu * 2 * np.pi
    local = np.stack([np.sin(theta) * np.sin(phi), np.cos(theta), -np.sin(theta) * np.cos(phi)], axis=-1)
    cos = np.maximum(0.0, local @ (to_world.T @ n))
    return (value * cos * np.sin(theta)).sum() * (2 * np.pi / size[0]) * (np.pi / size[1])
