"""wrt: a ray tracer whose rendering runs as NVIDIA Warp kernels.

>>> import wrt
>>> scene = wrt.load_scene("examples/spheres.toml")
>>> result = wrt.render(scene, spp=4, device="cpu")
>>> result.rgb.shape, sorted(result.aovs)

The public names, the submodules and ``__version__`` are looked up on first use (PEP 562), so
``import wrt`` is light: the ``wrt`` command (``wrt.console``) sets up its handling of Ctrl-C and
SIGTERM before Warp and the kernels load, and a signal during start-up is one line, not a traceback.
"""

import gc as _gc
import importlib as _importlib
import importlib.util as _importlib_util

_PUBLIC = {
    "load_scene": "loader",
    "parse_scene": "loader",
    "render": "renderer",
    "RenderResult": "renderer",
    "SceneError": "errors",
    "WrtError": "errors",
}
"""Each public name and the submodule that defines it."""

__all__ = ["load_scene", "parse_scene", "render", "RenderResult", "SceneError", "WrtError", "__version__"]


def _import(name: str):
    """The submodule ``wrt.<name>``, imported with the cyclic collector paused: importing wrt
    creates only objects that live as long as the process (Warp's builtins, the kernels' parsed
    functions), and the collector's full passes over them while they are being made cost about
    50 ms of every process. The collector's previous state is restored."""
    was_enabled = _gc.isenabled()
    _gc.disable()
    try:
        return _importlib.import_module(f"{__name__}.{name}")
    finally:
        if was_enabled:
            _gc.enable()


def _version() -> str:
    """The installed distribution's version (``importlib.metadata``: 25 ms, so looked up on first use)."""
    from importlib import metadata

    try:
        return metadata.version("wrt")
    except metadata.PackageNotFoundError:  # running from a source tree that is not installed
        return "0+unknown"


def __getattr__(name: str):
    if name == "__version__":
        value = _version()
    elif name in _PUBLIC:
        value = getattr(_import(_PUBLIC[name]), name)
    elif not name.startswith("_") and _importlib_util.find_spec(f"{__name__}.{name}") is not None:
        value = _import(name)
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_PUBLIC) | {"__version__"})
