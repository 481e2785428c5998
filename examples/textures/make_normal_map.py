"""Writes normal_map.png, the example normal map: a 64 x 64 8-bit RGB image of 4 x 4 round bumps
(spherical caps rising to 35 degrees at their rims) on a flat ground, stored raw as normal maps
are (texel = (n + 1) / 2 of the tangent-space normal n; x along u, y along v, z out of the surface).

    python examples/textures/make_normal_map.py
"""

import os

import numpy as np
import OpenImageIO as oiio

SIZE = 64
BUMPS = 4  # per side
RIM_DEGREES = 35.0  # the tilt of a bump's normal at its rim


def normal_map() -> np.ndarray:
    """Texels (SIZE, SIZE, 3) uint8, row 0 at v = 0."""
    cell = (np.arange(SIZE) + 0.5) / SIZE * BUMPS % 1.0 - 0.5  # offset from the nearest bump's centre, in cells
    x, y = np.meshgrid(cell, cell)  # x along u (columns), y along v (rows)
    r = np.hypot(x, y) / 0.4  # 1 at the rim
    tilt = np.where(r < 1.0, np.radians(RIM_DEGREES) * r, 0.0)
    phi = np.arctan2(y, x)
    n = np.stack([np.sin(tilt) * np.cos(phi), np.sin(tilt) * np.sin(phi), np.cos(tilt)], axis=-1)
    return np.round((n + 1.0) / 2.0 * 255.0).astype(np.uint8)


if __name__ == "__main__":
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "normal_map.png")
    out = oiio.ImageOutput.create(path)
    out.open(path, oiio.ImageSpec(SIZE, SIZE, 3, oiio.UINT8))
    out.write_image(normal_map())
    out.close()
