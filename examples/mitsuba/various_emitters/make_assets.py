"""Make the texture the scenes of this folder load.

The scenes are two of Mitsuba 3's render-test suite (mitsuba-data, ``tests/scenes/
various_emitters``: ``test_various_emitters`` and ``test_various_emitters_ptracer``), element for
element but their ``<path>``: it is ``../../../common``, the repository's shared assets, which are
not published with the scene files, so these scenes look in this folder (``<path value="."/>``)
and their texture is a stand-in of our own, named as the suite names it: the images are therefore
not Mitsuba's stored ones, but Mitsuba's renders of these files.

``textures/flower.bmp``
    A 64 x 64 8-bit RGB bitmap (sRGB, as Mitsuba and wrt decode it): a flower of six pink petals
    around a yellow heart on a green ground, darker towards the corners. It is the radiance of a
    textured area emitter, the texture of a spot light and the irradiance of a projector.

Run from this folder: ``python make_assets.py`` (deterministic; the committed file is its output).
"""

from pathlib import Path

import numpy as np
import OpenImageIO as oiio

HERE = Path(__file__).resolve().parent


def flower(size: int = 64) -> np.ndarray:
    """The flower image, ``(size, size, 3)`` uint8, row 0 the top row."""
    y, x = (np.mgrid[0:size, 0:size] + 0.5) / size * 2.0 - 1.0
    r = np.hypot(x, y)
    phi = np.arctan2(y, x)
    petal = r < 0.35 + 0.45 * np.abs(np.cos(3.0 * phi))
    heart = r < 0.22
    rgb = np.empty((size, size, 3))
    rgb[...] = np.array([0.25, 0.55, 0.2]) * (1.0 - 0.45 * np.clip(r - 0.6, 0.0, 1.0))[..., None]
    rgb[petal] = np.array([0.95, 0.45, 0.7]) * (0.8 + 0.2 * np.cos(6.0 * phi[petal]))[:, None]
    rgb[heart] = (0.98, 0.85, 0.2)
    return np.round(255.0 * np.clip(rgb, 0.0, 1.0)).astype(np.uint8)


def write_bmp(path: Path, rgb: np.ndarray) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    spec = oiio.ImageSpec(rgb.shape[1], rgb.shape[0], 3, "uint8")
    out = oiio.ImageOutput.create(str(path))
    if out is None or not out.open(str(path), spec) or not out.write_image(rgb) or not out.close():
        raise OSError(f"{path}: {oiio.geterror()}")


if __name__ == "__main__":
    write_bmp(HERE / "textures" / "flower.bmp", flower())
