"""The render kernel of an integrator specialised on a scene's ``Features``, built on first use.

``render_kernel(integrator, features)`` returns the same kernel object for the same arguments:
the all-features kernels (``features == ALL``, ``all_features_kernel``, in Warp modules
``wrt_NAME_all``, and the recording ones in ``wrt_NAME_record``) and every other variant are built
here on first use, each into a Warp module of its own (a variant's named after the integrator and
``features.key``), so that adding a variant never recompiles a module that has
already been loaded, and Warp's kernel cache keeps each compiled variant across processes. An
integrator's module is imported when its kernel is first asked for: a process pays the start-up
cost (Warp parses every function's source at import) of the integrator it renders with only.
A CUDA device gets kernels of its own (``cuda``: modules named as the CPU's with ``_cuda`` after),
whose traversal and BSDF interface are kept out of line (``CUDA_INLINE``).
"""

from __future__ import annotations

import functools
import importlib

import warp as wp

from .cpu_target import with_inline_threshold
from .features import ALL, GEOMETRY, Features, only
from .integrator import make_render_kernel
from .materials import MATERIAL_FLAGS

INTEGRATORS = ("raycast", "whitted", "path", "ptracer")
RECORDING = INTEGRATORS
"""The integrators with recording kernels (``wrt.rays``): all (the light tracer records the light
paths of the slots asked for, ``wrt.kernels.ptracer``)."""


CUDA_INLINE = False
"""Warp's inline hint, in the CUDA modules, of the traversal (``wrt.kernels.traverse.Traversal``)
and the BSDF interface (``wrt.kernels.materials.make_bsdf``): out of line. NVRTC inlining them at
each call site took the all-features Whitted module 655 s to compile for sm_90 and the path module
331 s; the traversal alone out of line, 115 s and 132 s, with spills cut from 2-4 kB to about
150 B a thread; the BSDF interface too, 89 s and 59 s. On the CPU the traversal's hint costs
render time (1.09x path, 1.18x Whitted), so the CPU modules leave both to the compiler
(docs/performance.md, "Kernels compiled ahead of time")."""


def _inline(cuda: bool) -> bool | None:
    return CUDA_INLINE if cuda else None


def _radiance(integrator: str, features: Features, record: bool = False, cuda: bool = False):
    """The radiance function of ``integrator`` for ``features``, recording every ray where ``record``,
    in its CUDA form where ``cuda``."""
    module = importlib.import_module(f"{__package__}.{integrator}")
    if integrator == "raycast":
        return module.make_raycast_radiance(features.textures)  # primary rays: only uv to specialise
    return getattr(module, f"make_{integrator}_radiance")(record, features, _inline(cuda))


PATH_INLINE_THRESHOLD = 30000
"""LLVM's inline threshold for the path tracer's modules (Warp's is 9000): at 9000 its loop state
as one struct, its light interface and its media crossing each left a function out of line and
cost the Cornell box 1.12x; at 30000 they cost nothing. The Whitted integrator keeps Warp's: 30000
cost it 1.07x (docs/performance.md, "Integrator state")."""
OPTIONS = {
    "raycast": {},
    "whitted": {},
    "path": {"cpu_compiler_flags": with_inline_threshold(wp.config.cpu_compiler_flags, PATH_INLINE_THRESHOLD)},
    "ptracer": {"cpu_compiler_flags": with_inline_threshold(wp.config.cpu_compiler_flags, PATH_INLINE_THRESHOLD)},
}
"""The Warp options of each integrator's modules, besides ``wrt.kernels.MODULE_OPTIONS``."""


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
        "media",
    ),
}
RELEVANT["ptracer"] = tuple(flag for flag in RELEVANT["path"] if flag != "media")
"""The flags each integrator's variants are specialised on besides those (``relevant``)."""


def relevant(integrator: str, features: Features) -> Features:
    """``features`` with the flags that do not pay for a variant of ``integrator`` set: each
    variant costs a compilation (seconds) the first time it is used, so only flags that remove
    measurable work are specialised on (see docs/performance.md): the geometry (primitive kinds,
    instances, moving surfaces) and the pixel loop's camera (lens, orthographic) and shutter sampling for
    every integrator; textures (the hit's uv) for raycast; lights, the branch stack, smooth shading,
    textures and normal maps for whitted; lights, dielectrics, rough dielectrics, plastics, masks,
    null surfaces, smooth shading, textures, normal maps, environment maps, emissive primitives and
    participating media for path (its mirror test is a load and a compare: path ignores ``specular``;
    raycast's one shading normal per camera ray is not worth one)."""
    return only(features, EVERY_INTEGRATOR + RELEVANT[integrator])


def render_kernel(integrator: str, features: Features, cuda: bool = False):
    """The rendering kernel of ``integrator`` (one of ``INTEGRATORS``) for ``features``; for
    a CUDA device where ``cuda`` (its modules' names end in ``_cuda``)."""
    return _kernel(integrator, relevant(integrator, features), cuda)


@functools.cache
def all_features_kernel(integrator: str, record: bool = False, cuda: bool = False):
    """``integrator``'s all-features kernel, recording every ray it traces where ``record``, in
    Warp module ``wrt_NAME_all`` (``wrt_NAME_record``; for CUDA where ``cuda``, ``_cuda`` after
    either); built on first use."""
    module = f"wrt_{integrator}_{'record' if record else 'all'}{'_cuda' if cuda else ''}"
    if integrator == "ptracer":
        return _light_tracer(ALL, module, cuda, record)
    return make_render_kernel(
        _radiance(integrator, ALL, record, cuda),
        module=module,
        record=record,
        options=OPTIONS[integrator],
        inline=_inline(cuda),
    )


@functools.cache
def _kernel(integrator: str, features: Features, cuda: bool = False):
    if features == ALL:
        return all_features_kernel(integrator, cuda=cuda)
    if integrator == "ptracer":
        return _light_tracer(features, f"wrt_ptracer_{features.key}{'_cuda' if cuda else ''}", cuda)
    return make_render_kernel(
        _radiance(integrator, features, cuda=cuda),
        module=f"wrt_{integrator}_{features.key}{'_cuda' if cuda else ''}",
        features=features,
        options=OPTIONS[integrator],
        inline=_inline(cuda),
    )


def _light_tracer(features: Features, module: str, cuda: bool, record: bool = False):
    """The light tracer's kernel for ``features`` in Warp module ``module`` (``wrt.kernels.ptracer``),
    recording where ``record``."""
    from .ptracer import make_ptracer_kernel

    return make_ptracer_kernel(
        module=module, record=record, features=features, options=OPTIONS["ptracer"], inline=_inline(cuda)
    )
