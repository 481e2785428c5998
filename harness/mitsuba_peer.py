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
