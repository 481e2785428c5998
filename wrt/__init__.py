"""wrt: a ray tracer whose rendering runs as NVIDIA Warp kernels.

>>> import wrt
>>> scene = wrt.load_scene("examples/spheres.toml")
>>> result = wrt.render(scene, spp=4, device="cpu")
>>> result.rgb.shape, sorted(result.aovs)
"""

import gc as _gc
from importlib import metadata as _metadata

# Importing wrt creates only objects that live as long as the process (Warp's builtins, the
# kernels' parsed functions); the cyclic collector's full passes over them while they are being
# made cost about 50 ms of every process, so it waits until the import is done.
_gc_was_enabled = _gc.isenabled()
_gc.disable()
try:
    from .errors import SceneError, WrtError
    from .loader import load_scene, parse_scene
    from .renderer import RenderResult, render
finally:
    if _gc_was_enabled:
        _gc.enable()

try:
    __version__ = _metadata.version("wrt")
except _metadata.PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0+unknown"
__all__ = ["load_scene", "parse_scene", "render", "RenderResult", "SceneError", "WrtError", "__version__"]
