"""Mitsuba 3 as an independent peer renderer, for the tests and ``wrt bench``: render a scene XML
to linear RGB.

Mitsuba 3 (``pip install mitsuba``) is an optional test dependency, never a runtime one: callers
ask `mitsuba_available` and skip (tests: ``pytest.skip(reason)``) where it is missing.

The variant is ``scalar_rgb`` (plain C++, every core, works on any x86-64 or ARM CPU). On a
2-core machine it renders the 128x128 examples in ``examples/mitsuba`` at about 36 ms (Cornell
box), 14 ms (glossy sphere) and 17 ms (thin lens) per sample per pixel; ``docs/mitsuba.md``
has the measurements. ``WRT_MITSUBA_VARIANT=llvm_ad_rgb`` asks for the vectorised LLVM variant
instead: it is tried once in a child process first, because with Debian 12's libLLVM 15 every
LLVM kernel aborts the process ("LLVM ERROR: Cannot select"); where it fails, scalar_rgb is
used. With libLLVM 19 (``apt-get install libllvm19``, found automatically) it works, but was
no faster on the Cornell box and 2-3x faster on the others.
"""

from __future__ import annotations

import functools
import glob
import os
import subprocess
import sys

import numpy as np

VARIANT_ENV = "WRT_MITSUBA_VARIANT"
RELIABLE_VARIANT = "scalar_rgb"
_LLVM_PROBE = (
    "import mitsuba as mi; mi.set_variant({variant!r}); "
    "scene = mi.load_dict(mi.cornell_box()); "
    "import numpy as np; assert np.isfinite(np.array(mi.render(scene, spp=1))).all()"
)


def mitsuba_available() -> tuple[bool, str]:
    """``(True, "mitsuba X.Y.Z, variant V")`` where Mitsuba 3 can render, else ``(False, why)``."""
    try:
        import mitsuba
    except ImportError as e:
        return False, f"Mitsuba 3 is not installed (pip install mitsuba): {e}"
    if RELIABLE_VARIANT not in mitsuba.variants():
        return False, f"this Mitsuba build has no {RELIABLE_VARIANT} variant (it has {', '.join(mitsuba.variants())})"
    return True, f"mitsuba {mitsuba.__version__}, variant {variant()}"


@functools.cache
def variant() -> str:
    """The Mitsuba variant to render with: ``$WRT_MITSUBA_VARIANT`` if it works, else scalar_rgb."""
    wanted = os.environ.get(VARIANT_ENV, RELIABLE_VARIANT)
    if wanted.startswith("llvm_"):
        llvm19 = sorted(glob.glob("/usr/lib/*/libLLVM.so.19*") + glob.glob("/usr/lib/*/libLLVM-19.so"))
        if llvm19 and "DRJIT_LIBLLVM_PATH" not in os.environ:
            os.environ["DRJIT_LIBLLVM_PATH"] = llvm19[0]
        probe = subprocess.run(
            [sys.executable, "-c", _LLVM_PROBE.format(variant=wanted)], capture_output=True, timeout=300
        )
        if probe.returncode != 0:
            return RELIABLE_VARIANT
    return wanted


def render_mitsuba(xml_path, spp: int | None = None, seed: int = 0, **params) -> np.ndarray:
    """Render a Mitsuba 3 scene XML with Mitsuba.

    Parameters
    ----------
    xml_path : str or os.PathLike
        The scene; its integrator, sensor, film and sampler are used as written.
    spp : int, optional
        Samples per pixel, overriding the scene's sampler ``sample_count``.
    seed : int, default 0
        Mitsuba's sampler seed.
    **params
        Values for the scene's ``<default>`` parameters (``res=32`` sets ``$res``).

    Returns
    -------
    numpy.ndarray of float32, shape (H, W, 3)
        Linear RGB radiance, W/(m^2 sr), row 0 at the top of the image.
    """
    import mitsuba as mi

    mi.set_variant(variant())
    scene = mi.load_file(os.fspath(xml_path), **{k: str(v) for k, v in params.items()})
    image = mi.render(scene, spp=spp or 0, seed=seed)
    return np.array(image, dtype=np.float32)[..., :3]


SRGB_TO_XYZ = np.array([[0.412453, 0.357580, 0.180423], [0.212671, 0.715160, 0.072169], [0.019334, 0.119193, 0.950227]])
"""Linear sRGB -> CIE XYZ, the matrix of Mitsuba's ``Bitmap`` conversion (its render tests compare in XYZ)."""


def render_mitsuba_moments(xml_path, spp: int, seed: int = 0, **params) -> tuple[np.ndarray, np.ndarray]:
    """Mitsuba's render of a scene through a ``moment`` integrator (the scene's own, or its
    integrator wrapped in one, as Mitsuba's render tests wrap theirs), read as those tests read
    their references: ``(mean, variance)``, float64 (H, W, 3) in CIE XYZ, the variance per
    sample (second moment minus the squared mean). ``params`` as in `render_mitsuba`."""
    import mitsuba as mi

    mi.set_variant(variant())
    scene = mi.load_file(os.fspath(xml_path), **{k: str(v) for k, v in params.items()})
    integrator = scene.integrator()
    if not any(name.startswith("m2_") for name in integrator.aov_names()):  # not a moment integrator
        integrator = mi.load_dict({"type": "moment", "integrator": integrator})
    image = np.array(mi.render(scene, integrator=integrator, spp=spp, seed=seed), dtype=np.float64)
    if image.shape[-1] != 9:
        raise ValueError(f"{xml_path}: not a moment integrator's image ({image.shape[-1]} channels, not 9)")
    mean, second = image[..., 3:6], image[..., 6:9]
    return mean, second - mean * mean


def mitsuba_z_test(rgb, spp: int, reference, variance, reference_spp: int | None = None, level: float = 0.01):
    """Mitsuba 3's render-test criterion (``src/render/tests/test_renders.py``): each pixel and
    XYZ channel of the image ``rgb`` (linear sRGB, ``spp`` samples per pixel) is compared with
    the reference mean by a Z-test whose per-sample variance is the reference's (at least 1e-4),
    at the Sidak-corrected level ``1 - (1 - level)^(1 / pixels)``; the image passes when at least
    99.75% of them pass. ``reference_spp``: a reference rendered at finite spp (in a test) adds its
    own noise, ``variance / reference_spp``, to the test's ``variance / spp``.

    Returns ``(passed, fraction of pixel channels passing, smallest p-value)``."""
    from scipy.special import erfc

    xyz = np.asarray(rgb, dtype=np.float64) @ SRGB_TO_XYZ.T
    per_sample = np.maximum(variance, 1e-4)
    noise = per_sample / spp + (per_sample / reference_spp if reference_spp else 0.0)
    z = np.abs(xyz - reference) / np.sqrt(noise)
    p = erfc(z / np.sqrt(2.0))  # two-sided: 2 (1 - Phi(z))
    pixels = p.shape[0] * p.shape[1]
    alpha = 1.0 - (1.0 - level) ** (1.0 / pixels)
    passing = np.count_nonzero(p > alpha) / p.size
    return passing >= 0.9975, passing, float(p.min())
