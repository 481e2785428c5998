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

from .features import ALL, Features
from .integrator import make_render_kernel

INTEGRATORS = ("raycast", "whitted", "path")


def _radiance(integrator: str, features: Features):
    """The rendering (not recording) radiance function of ``integrator`` for ``features``."""
    module = importlib.import_module(f"{__package__}.{integrator}")
    if integrator == "raycast":
        return module.make_raycast_radiance(features.textures)  # primary rays: only uv to specialise
    return getattr(module, f"make_{integrator}_radiance")(False, features)


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
    every_integrator = {
        "lens": features.lens,
        "orthographic": features.orthographic,
        "motion": features.motion,
        "moving": features.moving,
        "spheres": features.spheres,
        "triangles": features.triangles,
        "polygons": features.polygons,
        "disks": features.disks,
        "cylinders": features.cylinders,
        "instances": features.instances,
    }
    if integrator == "raycast":
        return Features(textures=features.textures, **every_integrator)
    if integrator == "whitted":
        return Features(
            lights=features.lights,
            specular=features.specular,
            dielectric=features.dielectric,
            smooth=features.smooth,
            textures=features.textures,
            normal_map=features.normal_map,
            **every_integrator,
        )
    return Features(
        lights=features.lights,
        environment_map=features.environment_map,
        emissive=features.emissive,
        emissive_shapes=features.emissive_shapes,
        dielectric=features.dielectric,
        rough_dielectric=features.rough_dielectric,
        plastic=features.plastic,
        mask=features.mask,
        smooth=features.smooth,
        textures=features.textures,
        normal_map=features.normal_map,
        **every_integrator,
    )


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
