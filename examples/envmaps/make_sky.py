"""Writes sky.exr, the example environment map: a 128 x 64 equirectangular sky (Mitsuba's
``envmap`` layout: row 0 the zenith, +y up; column u = (i + 1/2) / 128 at azimuth 2 pi u from -z
toward +x), linear RGB, half float. A blue gradient sky with a small bright sun 35 degrees above
the horizon, a brown ground, and coloured hills along the horizon so that a rotation shows.

    python examples/envmaps/make_sky.py
"""

import os

import numpy as np

from wrt.imageio import write_image

WIDTH, HEIGHT = 128, 64
SUN_AZIMUTH, SUN_ELEVATION, SUN_RADIUS = 0.15, 35.0, 3.0  # u of the sun, degrees, degrees
SUN_RADIANCE = 1500.0


def sky() -> np.ndarray:
    u = (np.arange(WIDTH) + 0.5) / WIDTH
    theta = np.arange(HEIGHT) * np.pi / (HEIGHT - 1)
    uu, tt = np.meshgrid(u, theta)
    elevation = 90.0 - np.degrees(tt)
    up = np.clip(elevation / 90.0, 0.0, 1.0)[..., None]
    image = (1.0 - up) * np.array([0.9, 0.95, 1.0]) + up * np.array([0.25, 0.45, 1.0])
    image[elevation < 0.0] = [0.25, 0.18, 0.12]
    hills = 6.0 + 5.0 * np.sin(2 * np.pi * 3 * uu) + 3.0 * np.sin(2 * np.pi * 7 * uu + 1.0)
    colour = np.where((np.floor(uu * 4) % 2)[..., None] == 0, [0.15, 0.35, 0.1], [0.45, 0.2, 0.15])
    image = np.where(((elevation >= 0.0) & (elevation < hills))[..., None], colour, image)
    phi, sun_theta = 2 * np.pi * uu, np.radians(90.0 - SUN_ELEVATION)
    sun_phi = 2 * np.pi * SUN_AZIMUTH
    cos_angle = np.cos(tt) * np.cos(sun_theta) + np.sin(tt) * np.sin(sun_theta) * np.cos(phi - sun_phi)
    image[cos_angle > np.cos(np.radians(SUN_RADIUS))] = SUN_RADIANCE * np.array([1.0, 0.93, 0.8])
    return image.astype(np.float32)


if __name__ == "__main__":
    write_image(os.path.join(os.path.dirname(os.path.abspath(__file__)), "sky.exr"), sky(), half=True)
