"""Writes grid.png, the example bitmap texture: a 64 x 32 8-bit sRGB "uv test grid" for a sphere
(Mitsuba's sphere mapping: u around +z from +x, v from +z down to -z). Eight columns of hues
around u, darker toward v = 1, with a white line every 1/8 in u and 1/4 in v and a black block
at the top left corner (u, v < 1/8) so that a flip or a rotation of the texture shows.

    python examples/textures/make_grid.py
"""

import colorsys
import os

import numpy as np

from wrt.imageio import write_image

WIDTH, HEIGHT = 64, 32


def grid() -> np.ndarray:
    """Linear RGB (HEIGHT, WIDTH, 3), row 0 at v = 0."""
    u = (np.arange(WIDTH) + 0.5) / WIDTH
    v = (np.arange(HEIGHT) + 0.5) / HEIGHT
    hues = np.array([colorsys.hsv_to_rgb(h, 0.75, 0.9) for h in np.floor(u * 8) / 8])  # (W, 3)
    image = hues[None, :, :] * (1.0 - 0.6 * v)[:, None, None]
    image[:, np.arange(WIDTH) % (WIDTH // 8) == 0] = 0.85
    image[np.arange(HEIGHT) % (HEIGHT // 4) == 0] = 0.85
    image[: HEIGHT // 8, : WIDTH // 8] = 0.02
    return image**2.2  # roughly linear from the display-referred colours above


if __name__ == "__main__":
    write_image(os.path.join(os.path.dirname(os.path.abspath(__file__)), "grid.png"), grid())
