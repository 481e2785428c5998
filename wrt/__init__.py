"""wrt: a ray tracer whose rendering runs as NVIDIA Warp kernels.

>>> import wrt
>>> scene = wrt.load_scene("examples/spheres.toml")
>>> result = wrt.render(scene, spp=4, device="cpu")
>>> result.rgb.shape, sorted(result.aovs)
"""

from importlib import metadata as _metadata

from .errors import SceneError, WrtError
from .loader import load_scene, parse_scene
from .renderer import RenderResult, render

try:
    __version__ = _metadata.version("wrt")
except _metadata.PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0+unknown"
__all__ = ["load_scene", "parse_scene", "render", "RenderResult", "SceneError", "WrtError", "__version__"]
