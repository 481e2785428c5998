"""Writes bump_map.png, the example bump map: a 64 x 64 8-bit grey height field, stored raw, of
4 x 4 rounded dimples (cosine-shaped, half a cell across) between diagonal ridges, so that both
texture directions carry a gradient; heights in [0, 1] (a bump map's luminance, scaled by the
material's ``bump_scale``).

    python examples/textures/make_bump_map.py
"""

import os

import numpy as np
import OpenImageIO as oiio

SIZE = 64
DIMPLES = 4  # per side


def height() -> np.ndarray:
    """Heights (SIZE, SIZE) in [0, 1], row 0 at v = 0."""
    t = (np.arange(SIZE) + 0.5) / SIZE
    u, v = np.meshgrid(t, t)  # u along columns, v along rows
    cell_u, cell_v = u * DIMPLES % 1.0 - 0.5, v * DIMPLES % 1.0 - 0.5
    r = np.hypot(cell_u, cell_v) / 0.25
    dimple = np.where(r < 1.0, 0.5 * (1.0 + np.cos(np.pi * r)), 0.0)
    ridge = 0.5 + 0.5 * np.sin(2.0 * np.pi * DIMPLES * (u + v))
    return np.clip(0.6 * ridge + 0.4 - 0.7 * dimple, 0.0, 1.0)


if __name__ == "__main__":
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "bump_map.png")
    out = oiio.ImageOutput.create(path)
    out.open(path, oiio.ImageSpec(SIZE, SIZE, 1, oiio.UINT8))
    out.write_image(np.round(height() * 255.0).astype(np.uint8))
    out.close()
