"""The render kernel of an integrator specialised on a scene's ``Features``, built on first use.

``render_kernel(integrator, features)`` returns the same kernel object for the same arguments:
the all-features kernels (``features == ALL``) are the ones each integrator module builds on
first use (``wrt.kernels.integrator.all_features_kernels``, in Warp modules ``wrt_NAME_all``); any
other variant is built here into a Warp module of its own, named after the integrator and
``features.key``, so that adding a variant never recompiles a module that has
already been loaded, and Warp's kernel cache keeps each compiled variant across processes. An
integrator's module is imported when its kernel is first asked for: a process pays the start-up
cost (Warp parses every function's source at import) of the integrator it renders with only.
"""

from __future__ import annotations

import functools
import importlib

from .features import ALL, GEOMETRY, Features, only
from .integrator import make_render_kernel
from .materials import MATERIAL_FLAGS

INTEGRATORS = ("raycast", "whitted", "path")


def _radiance(integrator: str, features: Features):
    """The rendering (not recording) radiance function of ``integrator`` for ``features``."""
    module = importlib.import_module(f"{__package__}.{integrator}")
    if integrator == "raycast":
        return module.make_raycast_radiance(features.textures)  # primary rays: only uv to specialise
    return getattr(module, f"make_{integrator}_radiance")(False, features)


EVERY_INTEGRATOR = ("lens", "orthographic", "motion", *GEOMETRY)
"""The flags every integrator's variants are specialised on: the pixel loop's camera and shutter,
and the traversal's."""
RELEVANT = {
    "raycast": ("textures",),
    "whitted": ("lights", "specular", "dielectric", "smooth", "textures", "normal_map"),
    "path": (
        "lights",
        "environment_map",
        "emissive",
        "emissive_shapes",
        "dielectric",
        *MATERIAL_FLAGS,
        "smooth",
        "textures",
        "normal_map",
    ),
}
"""The flags each integrator's variants are specialised on besides those (``relevant``)."""


def relevant(integrator: str, features: Features) -> Features:
    """``features`` with the flags that do not pay for a variant of ``integrator`` set: each
    variant costs a compilation (seconds) the first time it is used, so only flags that remove
    measurable work are specialised on (see docs/performance.md): the geometry (primitive kinds,
    instances, moving surfaces) and the pixel loop's camera (lens, orthographic) and shutter sampling for
    every integrator; textures (the hit's uv) for raycast; lights, the branch stack, smooth shading,
    textures and normal maps for whitted; lights,
    dielectrics, rough dielectrics, plastics, masks, smooth shading, textures, normal maps, environment maps and
    emissive primitives for path (its mirror test is a load and a compare: path ignores ``specular``;
    raycast's one shading normal per camera ray is not worth one)."""
    return only(features, EVERY_INTEGRATOR + RELEVANT[integrator])


def render_kernel(integrator: str, features: Features):
    """The rendering kernel of ``integrator`` ("raycast", "whitted" or "path") for ``features``."""
    return _kernel(integrator, relevant(integrator, features))


@functools.cache
def _kernel(integrator: str, features: Features):
    if features == ALL:
        return getattr(importlib.import_module(f"{__package__}.{integrator}"), integrator)
    return make_render_kernel(
        _radiance(integrator, features), features=features, module=f"wrt_{integrator}_{features.key}"
    )
