"""Load and validate a TOML scene file into ``wrt.scene`` dataclasses.

Every problem is reported as one ``SceneError`` naming the file, the table (``render``,
``camera``, ``material[i]``, ``medium[i]``, ``shape[i]``, ``light[i]``; ``i`` counts from 0 in
file order), the key and the offending value. The format is documented in ``docs/scene-format.md``.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import os
import sys
from collections.abc import Mapping

import numpy as np

from .conductors import METALS
from .envmap import EnvironmentMapError, read_environment_map
from .errors import MeshFileError, SceneError, listed
from .files import TomlError, read_toml
from .kernels.lights import LIGHT_TYPES
from .kernels.materials import TYPES
from .kernels.materials.principled import NUMBERS as PRINCIPLED_NUMBERS
from .kernels.materials.principled import RATES as PRINCIPLED_RATES
from .kernels.materials.principled import THIN_RATES, transmits
from .kernels.microfacet import DISTRIBUTIONS
from .kernels.volumes import MEDIUM_TYPES as MEDIUM_REGISTRY
from .kernels.volumes import PHASE_TYPES as PHASE_REGISTRY
from .light_tracing import check_light_tracer
from .limits import MAX_DEPTH, MAX_IMAGE_SIDE, MAX_MAGNITUDE, MAX_SEED, MAX_SPP
from .meshio import apply_transform, load_mesh, ply_attributes, transform_matrix, transform_normals, vertex_normals
from .scene import (
    CAMERA_TYPES,
    DIELECTRIC_SHADOWS,
    FILTERS,
    INTEGRATORS,
    MATERIAL_TYPES,
    MEDIUM_TYPES,
    PHASE_TYPES,
    SAMPLERS,
    STILL,
    AreaLight,
    Camera,
    Cylinder,
    DirectionalLight,
    Disk,
    EnvironmentLight,
    Group,
    Instance,
    Material,
    Medium,
    Mesh,
    Plane,
    PointLight,
    Polygon,
    ProjectorLight,
    RenderSettings,
    Scene,
    Sphere,
    SphereLight,
    SpotLight,
    Triangle,
    Volume,
    constituents,
)
from .textures import SLOTS, Bitmap, Constant, MeshAttribute, read_texture
from .volumes import KINDS as VOLUME_KINDS
from .volumes import VolumeFileError, box_matrix, read_vol

TOP_LEVEL = ("render", "camera", "material", "medium", "group", "shape", "light")
SHAPE_TYPES = ("sphere", "plane", "triangle", "polygon", "mesh", "disk", "cylinder", "instance")
GROUP_SHAPE_TYPES = ("sphere", "triangle", "polygon", "mesh", "disk", "cylinder")  # bounded: what a [[group]] holds
MESH_SHADING = ("flat", "smooth")  # a mesh's shading normals: its face normals, or interpolated vertex normals
DEFAULT_MATERIAL = Material(name="default", type="diffuse", albedo=(0.5, 0.5, 0.5))
FLOAT32_TINY = float(np.finfo(np.float32).tiny)  # the smallest normal float32
BEYOND_FLOAT32 = f"must be at most {MAX_MAGNITUDE:g} in magnitude (so that float32 products of it stay finite)"
_REQUIRED = object()


class _Table:
    """Typed, validating access to one TOML table; ``finish`` rejects the keys nobody read."""

    def __init__(self, file: str, name: str, data: object):
        if not isinstance(data, Mapping):
            raise SceneError(file, name, None, f"must be a table, got {type(data).__name__}")
        self.file, self.name, self.data, self.used = file, name, data, set()

    def error(self, key: str, problem: str, value=SceneError._NO_VALUE) -> SceneError:
        return SceneError(self.file, self.name, key, problem, value)

    def get(self, key: str, default):
        self.used.add(key)
        if key in self.data:
            return self.data[key]
        if default is _REQUIRED:
            raise self.error(key, "is required")
        return default

    def number(
        self, key: str, default=_REQUIRED, *, integer=False, lo=-math.inf, hi=math.inf, lo_open=False, hi_open=False
    ):
        value = self.get(key, default)
        if value is default and default is not _REQUIRED:
            return value
        kinds = (int,) if integer else (int, float)
        if isinstance(value, bool) or not isinstance(value, kinds):
            raise self.error(key, "must be an integer" if integer else "must be a number", value)
        if not integer:
            _check_float32(self, key, (value,), value)
        below = value <= lo if lo_open else value < lo
        above = value >= hi if hi_open else value > hi
        if below or above:
            raise self.error(
                key, f"must be in {'(' if lo_open else '['}{_g(lo)}, {_g(hi)}{')' if hi_open else ']'}", value
            )
        return int(value) if integer else float(value)

    def boolean(self, key: str, default=_REQUIRED) -> bool:
        value = self.get(key, default)
        if not isinstance(value, bool):
            raise self.error(key, "must be true or false", value)
        return value

    def string(self, key: str, default=_REQUIRED, choices=None) -> str:
        value = self.get(key, default)
        if not isinstance(value, str):
            raise self.error(key, "must be a string", value)
        if choices is not None and value not in choices:
            raise self.error(key, f"must be one of {', '.join(choices)}", value)
        return value

    def vectors(self, key: str, default=_REQUIRED, *, count=None, min_count=1) -> tuple:
        """A list of 3-vectors (``count`` of them, or at least ``min_count``)."""
        value = self.get(key, default)
        if value is default and default is not _REQUIRED:
            return value
        if not isinstance(value, list) or (count is not None and len(value) != count) or len(value) < min_count:
            what = f"{count}" if count is not None else f"at least {min_count}"
            raise self.error(key, f"must be a list of {what} points [x, y, z]", value)
        return tuple(_vec3(self, key, v, value) for v in value)

    def vec3(self, key: str, default=_REQUIRED, *, nonzero=False, lo=-math.inf, hi=math.inf) -> tuple:
        value = self.get(key, default)
        if value is default and default is not _REQUIRED:
            return value
        v = _vec3(self, key, value, value)
        if nonzero and not any(v):
            raise self.error(key, "must not be the zero vector", value)
        if nonzero and _float32_unit(v) is None:
            raise self.error(key, "is too short to normalise in float32 (its squared length underflows)", value)
        if any(c < lo or c > hi for c in v):
            raise self.error(key, f"components must be in [{lo:g}, {hi:g}]", value)
        return v

    def finish(self) -> None:
        unknown = [k for k in self.data if k not in self.used]
        if unknown:
            key = unknown[0]
            close = difflib.get_close_matches(key, sorted(self.used), n=1)
            hint = f" (did you mean '{close[0]}'?)" if close else f" (known: {', '.join(sorted(self.used))})"
            raise self.error(key, "unknown key" + hint)


def _vec3(table: _Table, key: str, v, shown) -> tuple[float, float, float]:
    if not isinstance(v, list) or len(v) != 3 or any(isinstance(c, bool) or not isinstance(c, (int, float)) for c in v):
        raise table.error(key, "must be 3 numbers [x, y, z]", shown)
    _check_float32(table, key, v, shown)
    return (float(v[0]), float(v[1]), float(v[2]))


def _g(x) -> str:
    """A range end as written in messages: integers exactly, other numbers short."""
    return str(x) if isinstance(x, int) else f"{x:g}"


def _check_float32(table: _Table, key: str, numbers, shown) -> None:
    """Numbers go to the device as float32: each must be finite and at most ``MAX_MAGNITUDE`` in
    magnitude, so that the kernels' products of them stay finite too."""
    for c in numbers:
        try:
            c = float(c)
        except OverflowError:  # an integer beyond float64
            raise table.error(key, BEYOND_FLOAT32, shown) from None
        if not math.isfinite(c):
            raise table.error(key, "components must be finite" if len(numbers) > 1 else "must be finite", shown)
        if abs(c) > MAX_MAGNITUDE:
            raise table.error(key, BEYOND_FLOAT32, shown)


def _float32_unit(v) -> np.ndarray | None:
    """``v`` normalised as the kernels do it, in float32 (``wp.normalize``: ``v / sqrt(x*x + y*y +
    z*z)``), or None when float32 cannot: ``v`` is zero there, or its squared length underflows to
    zero or to a denormal (too imprecise to normalise) or overflows."""
    f = np.asarray(v, dtype=np.float64).astype(np.float32)
    with np.errstate(all="ignore"):
        squared = f[0] * f[0] + f[1] * f[1] + f[2] * f[2]  # float32 arithmetic, as in the kernels
        if not (np.isfinite(squared) and squared >= FLOAT32_TINY):
            return None
        unit = f / np.sqrt(squared)
    return unit if np.all(np.isfinite(unit)) else None


def _array_of_tables(file: str, doc: Mapping, key: str) -> list:
    value = doc.get(key, [])
    if not isinstance(value, list):
        raise SceneError(file, None, key, f"must be an array of tables, written [[{key}]]")
    return value


def _render(file: str, data) -> RenderSettings:
    t = _Table(file, "render", data)
    d = RenderSettings()
    settings = RenderSettings(
        width=t.number("width", d.width, integer=True, lo=1, hi=MAX_IMAGE_SIDE),
        height=t.number("height", d.height, integer=True, lo=1, hi=MAX_IMAGE_SIDE),
        spp=t.number("spp", d.spp, integer=True, lo=1, hi=MAX_SPP),
        max_depth=t.number("max_depth", d.max_depth, integer=True, lo=1, hi=MAX_DEPTH),
        seed=t.number("seed", d.seed, integer=True, lo=0, hi=MAX_SEED),
        integrator=t.string("integrator", d.integrator, INTEGRATORS),
        ambient=t.vec3("ambient", d.ambient, lo=0.0),
        background=t.vec3("background", d.background, lo=0.0),
        exterior_ior=t.number("exterior_ior", d.exterior_ior, lo=1.0, hi=10.0),
        dielectric_shadows=t.string("dielectric_shadows", d.dielectric_shadows, DIELECTRIC_SHADOWS),
        min_throughput=t.number("min_throughput", d.min_throughput, lo=0.0, hi=1.0),
        sampler=t.string("sampler", d.sampler, SAMPLERS),
        filter=t.string("filter", d.filter, FILTERS),
    )
    t.finish()
    return settings


# keys of one camera type only
_CAMERA_KEYS = {"perspective": ("fov", "aperture_radius", "focus_distance"), "orthographic": ("width",)}
MIN_ORTHOGRAPHIC_WIDTH = 2 * MAX_IMAGE_SIDE * FLOAT32_TINY
"""Smallest orthographic ``width``: half the view's height, ``width / (2 aspect)``, is a normal
float32 at any aspect."""


def _camera(file: str, data, media_index: Mapping[str, int]) -> tuple[Camera, int | None]:
    """The camera, and the index of the medium it is in (``medium``; None: vacuum)."""
    t = _Table(file, "camera", data)
    medium = _medium_ref(t, "medium", media_index)
    kind = t.string("type", Camera.type, CAMERA_TYPES)
    for other, keys in _CAMERA_KEYS.items():
        for key in keys:
            if other != kind and key in t.data:
                raise t.error(key, f"applies to {other} cameras only, not to a {kind} one", t.data[key])
    origin = t.vec3("origin")
    look_at = t.vec3("look_at")
    up = t.vec3("up", Camera.up, nonzero=True)
    if kind == "perspective":
        projection = {
            "fov": t.number("fov", Camera.fov, lo=0.0, hi=180.0, lo_open=True, hi_open=True),
            "aperture_radius": t.number("aperture_radius", 0.0, lo=0.0),
            "focus_distance": t.number("focus_distance", None, lo=0.0, lo_open=True),
        }
    else:
        projection = {"width": t.number("width", lo=MIN_ORTHOGRAPHIC_WIDTH)}
    near_clip = t.number("near_clip", Camera.near_clip, lo=0.0)
    far_clip = t.number("far_clip", Camera.far_clip)
    if not far_clip > near_clip:
        raise t.error("far_clip", f"must be greater than near_clip = {near_clip:g}", far_clip)
    shutter = t.get("shutter", Camera.shutter)
    if shutter is not Camera.shutter:
        if (
            not isinstance(shutter, list)
            or len(shutter) != 2
            or any(isinstance(c, bool) or not isinstance(c, (int, float)) for c in shutter)
        ):
            raise t.error("shutter", "must be 2 numbers [open, close]", shutter)
        _check_float32(t, "shutter", shutter, shutter)
        if shutter[1] < shutter[0]:
            raise t.error("shutter", "close must not come before open", shutter)
        shutter = (float(shutter[0]), float(shutter[1]))
    t.finish()
    # the frame of kernels/camera.py, in float32 as the device holds it: forward =
    # normalize(look_at - origin), right = normalize(cross(forward, up)) must be unit vectors
    forward64 = np.subtract(look_at, origin)
    if not np.any(forward64):
        raise t.error("look_at", "must differ from origin", list(look_at))
    with np.errstate(all="ignore"):
        difference = np.asarray(look_at, dtype=np.float32) - np.asarray(origin, dtype=np.float32)
    forward = _float32_unit(difference)
    if forward is None:
        raise t.error(
            "look_at",
            f"must differ from origin = {list(origin)} by a vector float32 can normalise (look_at - origin = "
            f"{[float(c) for c in difference]} in float32: its squared length underflows)",
            list(look_at),
        )
    sin_angle = np.linalg.norm(np.cross(forward64 / np.linalg.norm(forward64), np.asarray(up) / np.linalg.norm(up)))
    if sin_angle < 1e-6:
        raise t.error("up", "is parallel to the viewing direction (look_at - origin)", list(up))
    if _float32_unit(np.cross(forward, np.asarray(up, dtype=np.float32))) is None:
        raise t.error(
            "up",
            "is too short, or too close to parallel to the viewing direction, for float32: cross(forward, up) "
            "does not normalise (its squared length underflows)",
            list(up),
        )
    camera = Camera(
        origin=origin,
        look_at=look_at,
        up=up,
        shutter=shutter,
        type=kind,
        near_clip=near_clip,
        far_clip=far_clip,
        **projection,
    )
    return camera, medium


def _conductor(t: _Table, scene_dir: str, textures: list) -> dict:
    """A conductor's ``roughness`` (0, the default: smooth; else GGX alpha, or a texture of it,
    appended to ``textures``) and its complex index of refraction: ``metal``, a name of
    ``wrt.conductors.METALS``, or ``eta`` and ``k``."""
    if isinstance(t.data.get("roughness"), Mapping):
        texture, roughness = _texture(t, "roughness", scene_dir)
        textures.append(("roughness", texture))
    else:
        roughness = t.number("roughness", 0.0, lo=0.0, hi=1.0)
    if 0.0 < roughness < 1e-3:
        raise t.error("roughness", "must be 0 (a smooth conductor) or at least 0.001", roughness)
    if "metal" in t.data:
        given = [key for key in ("eta", "k") if key in t.data]
        if given:
            raise t.error(given[0], "is given with 'metal': give either a metal or eta and k", t.data[given[0]])
        eta, k = METALS[t.string("metal", choices=METALS)]
    elif "eta" in t.data or "k" in t.data:
        eta, k = t.vec3("eta", lo=0.0, hi=1e3), t.vec3("k", lo=0.0, hi=1e3)
    else:
        raise t.error("metal", "is required (a named metal), or else eta and k")
    return {"roughness": roughness, "eta": eta, "k": k}


TEXTURED = ", ".join(slot for slot in SLOTS if slot != "transmittance") + " and a thin dielectric's transmittance"
"""What a texture can give (a dielectric's ``transmittance`` is an absorption per unit length: its volume's)."""


NUMBER_SLOTS = ("roughness", "roughness_v", "opacity", "weight", *PRINCIPLED_NUMBERS, "anisotropy", "diff_trans")
"""The textured parameters read as one number (``texture_float``)."""


def _slot_range(key: str) -> tuple[float, float]:
    """The range a textured parameter's values must stay in."""
    if key == "diff_trans":
        return (0.0, 2.0)
    if key == "emission":
        return (0.0, MAX_MAGNITUDE)
    return (1e-3, 1.0) if key in ("roughness", "roughness_v") else (0.0, 1.0)


def _texture(t: _Table, key: str, scene_dir: str) -> tuple:
    """Material parameter ``key`` given by a texture (an inline table, ``wrt.textures.read_texture``):
    ``(texture, value)``, its values checked against the parameter's range (roughness: as the
    kernels read it, ``texture_float``), ``value`` their mean (the parameter where a constant is read)."""
    t.used.add(key)
    tt = _Table(t.file, f"{t.name}.{key}", t.data[key])
    texture = read_texture(tt, scene_dir)
    number = key in NUMBER_SLOTS
    lo, hi = _slot_range(key)
    if isinstance(texture, MeshAttribute):  # its values are its meshes': checked and averaged with them
        return texture, lo if number else (lo,) * 3
    values = texture.numbers() if number else texture.values()
    if values.min() < lo or values.max() > hi:
        what = "the file's texels" if isinstance(texture, Bitmap) else "its colours"
        raise tt.error(
            _texture_key(texture),
            f"{what} range over [{values.min():.4g}, {values.max():.4g}]: {key} must stay in [{lo:g}, {hi:g}]",
            tt.data.get("file", tt.data.get("texture")),
        )
    mean = values.mean(axis=0)
    return texture, float(mean) if number else tuple(float(c) for c in mean)


def _bump_map(t: _Table, scene_dir: str) -> Bitmap:
    """A material's ``bump_map``: a bitmap texture table (decoded as any bitmap unless ``raw``, as
    Mitsuba's); its luminance is the height field (``wrt.kernels.textures.texture_float_grad``)."""
    t.used.add("bump_map")
    data = t.data["bump_map"]
    if not isinstance(data, Mapping) or data.get("texture") != "bitmap":
        raise t.error(
            "bump_map", 'must be a texture table with texture = "bitmap" (a height field has a gradient)', data
        )
    return read_texture(_Table(t.file, f"{t.name}.bump_map", data), scene_dir)


def _texture_key(texture) -> str:
    """The key of a texture table that holds its values: a bitmap's ``file``, a constant's
    ``value``, else (a checkerboard's colours) its ``texture``."""
    return "file" if isinstance(texture, Bitmap) else "value" if isinstance(texture, Constant) else "texture"


def _normal_map(t: _Table, scene_dir: str) -> Bitmap | Constant:
    """A material's ``normal_map``: a bitmap texture table whose file is read raw whatever its format
    (no sRGB decoding: texel (r, g, b) is the tangent-space normal 2 (r, g, b) - 1, normalised;
    ``wrt.kernels.hit.perturbed_normal``), or a constant one (``texture = "constant"``, its
    ``value`` the one texel), its texels in [0, 1]."""
    t.used.add("normal_map")
    data = t.data["normal_map"]
    if not isinstance(data, Mapping) or data.get("texture") not in ("bitmap", "constant"):
        raise t.error("normal_map", 'must be a texture table with texture = "bitmap" or "constant"', data)
    bitmap = data["texture"] == "bitmap"
    tt = _Table(t.file, f"{t.name}.normal_map", {**data, "raw": True} if bitmap else data)
    if data.get("raw", True) is not True:
        raise tt.error("raw", "must be true: a normal map is always read raw", data["raw"])
    texture = read_texture(tt, scene_dir)
    texels = texture.values()
    if texels.min() < 0.0 or texels.max() > 1.0:
        key = _texture_key(texture)
        what = "the file's texels range" if bitmap else "its value ranges"
        raise tt.error(key, f"{what} over [{texels.min():.4g}, {texels.max():.4g}]: must stay in [0, 1]", data.get(key))
    return texture


def _material(file: str, index: int, data, scene_dir: str = ".") -> Material:
    t = _Table(file, f"material[{index}]", data)
    kind = t.string("type", "diffuse", MATERIAL_TYPES)
    values = {"name": t.string("name"), "type": kind}
    textures = []
    if isinstance(t.data.get("emission"), Mapping):
        texture, values["emission"] = _texture(t, "emission", scene_dir)
        textures.append(("emission", texture))
    else:
        values["emission"] = t.vec3("emission", Material.emission, lo=0.0)
    readers = {
        "albedo": lambda: t.vec3("albedo", Material.albedo, lo=0.0, hi=1.0),
        "specular": lambda: t.vec3("specular", Material.specular, lo=0.0, hi=1.0),
        "exponent": lambda: t.number("exponent", Material.exponent, lo=0.0, hi=1e6),
        "reflectance": lambda: t.vec3("reflectance", Material.reflectance, lo=0.0, hi=1.0),
        "ior": lambda: t.number("ior", Material.ior, lo=1.0, hi=10.0),
        "transmittance": lambda: t.vec3("transmittance", Material.transmittance, lo=0.0, hi=1.0),
        "priority": lambda: t.number("priority", Material.priority, integer=True, lo=-1000, hi=1000),
        "roughness": lambda: t.number("roughness", Material.roughness, lo=1e-3, hi=1.0),
        "roughness_v": lambda: t.number("roughness_v", None, lo=1e-3, hi=1.0),
        "distribution": lambda: t.string("distribution", Material.distribution, DISTRIBUTIONS),
        "two_sided": lambda: t.boolean("two_sided", Material.two_sided),
        "nonlinear": lambda: t.boolean("nonlinear", Material.nonlinear),
        "opacity": lambda: t.number("opacity", Material.opacity, lo=0.0, hi=1.0),
        "material": lambda: t.string("material"),
        "materials": lambda: _names(t, "materials", 2),
        "weight": lambda: t.number("weight", Material.weight, lo=0.0, hi=1.0),
        **{
            key: (lambda key=key: t.number(key, getattr(Material, key), lo=0.0, hi=1.0))
            for key in (*PRINCIPLED_NUMBERS, "anisotropy")
        },
        "diff_trans": lambda: t.number("diff_trans", Material.diff_trans, lo=0.0, hi=2.0),
        **{
            key: (lambda key=key: t.number(key, getattr(Material, key), lo=0.0, hi=1e3))
            for key in (*PRINCIPLED_RATES, *THIN_RATES)
        },
    }
    if kind in ("principled", "principled_thin"):  # Burley's roughness, 0 allowed (its alpha is at least 0.001)
        readers["roughness"] = lambda: t.number("roughness", Material.roughness, lo=0.0, hi=1.0)
    for key in TYPES[kind].keys:
        if isinstance(t.data.get(key), Mapping):
            if key not in SLOTS or (key == "transmittance" and kind != "thin_dielectric"):
                raise t.error(key, f"cannot be a texture here (textures give {TEXTURED})", t.data[key])
            texture, values[key] = _texture(t, key, scene_dir)
            textures.append((key, texture))
        else:
            values[key] = readers[key]()
    if kind == "conductor":
        values.update(_conductor(t, scene_dir, textures))
        if values["roughness"] == 0.0 and "roughness_v" in t.data:
            raise t.error(
                "roughness_v", "needs a rough conductor: roughness 0 is a smooth one (a mirror)", t.data["roughness_v"]
            )
    if "normal_map" in t.data:
        textures.append(("normal_map", _normal_map(t, scene_dir)))
    if "bump_map" in t.data:
        if "normal_map" in t.data:
            raise t.error("bump_map", "is given with a normal_map: a material's shading normal comes from one of them")
        textures.append(("bump_map", _bump_map(t, scene_dir)))
        values["bump_scale"] = t.number("bump_scale", Material.bump_scale)
    elif "bump_scale" in t.data:
        raise t.error("bump_scale", "scales a bump_map: it applies to a material with one only", t.data["bump_scale"])
    if "two_sided" in t.data and "two_sided" not in values:
        sides = (
            "its sides are Mitsuba's principled's" if kind == "principled" else "it reflects and refracts on both sides"
        )
        raise t.error("two_sided", f"does not apply to a {kind}: {sides}", t.data["two_sided"])
    t.finish()
    material = Material(**values, textures=tuple(textures))
    if kind == "principled" and material.ior == 1.0 and transmits(material):
        material = dataclasses.replace(material, ior=1.001)  # index-matched transmission, as Mitsuba 3 moves it
    if kind == "phong" and any(a + s > 1.0 for a, s in zip(material.albedo, material.specular)):
        raise t.error(
            "specular",
            "albedo + specular must not exceed 1 in any channel (energy conservation)",
            list(material.specular),
        )
    return material


def _names(t: _Table, key: str, count: int) -> tuple[str, ...]:
    """A list of ``count`` strings (names of other tables)."""
    value = t.get(key, _REQUIRED)
    if not (isinstance(value, list) and len(value) == count and all(isinstance(v, str) for v in value)):
        raise t.error(key, f"must be a list of {count} names", value)
    return tuple(value)


def _colour(t: _Table, key: str, default: tuple, hi: float = math.inf) -> tuple[float, float, float]:
    """An RGB value ``[r, g, b]`` or one number for all three, each in ``[0, hi]``."""
    value = t.get(key, default)
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return (t.number(key, lo=0.0, hi=hi),) * 3
    return t.vec3(key, default, lo=0.0, hi=hi)


def _volume(t: _Table, key: str, scene_dir: str, hi: float = math.inf) -> Volume:
    """The volume table of a heterogeneous medium's ``key`` (``wrt.volumes``), its values in
    ``[0, hi]``."""
    value = t.get(key, _REQUIRED)
    if not isinstance(value, Mapping):
        raise t.error(
            key,
            'must be a volume table ({ volume = "grid", file = ... } or { volume = "constant", value = ... });'
            ' a medium constant everywhere is type = "homogeneous"',
            value,
        )
    vt = _Table(t.file, f"{t.name}.{key}", value)
    kind = vt.string("volume", choices=VOLUME_KINDS)
    to_world = _transform(vt)
    source = ""
    if kind == "constant":
        values = np.array(_colour(vt, "value", (1.0, 1.0, 1.0), hi=hi), np.float32).reshape(1, 1, 1, 3)
    else:
        name = vt.string("file")
        source = os.path.join(scene_dir, name)
        try:
            values, box = read_vol(source)
        except VolumeFileError as e:
            raise vt.error("file", str(e), name) from None
        if values.max() > hi:
            raise vt.error("file", f"holds values up to {values.max():g}: must be at most {hi:g}", name)
        if vt.boolean("use_grid_bbox", False):
            to_world = to_world @ box_matrix(box)
    vt.finish()
    if abs(np.linalg.det(to_world[:3, :3])) < 1e-30:
        raise vt.error("transform", "is singular")
    return Volume(values=values, to_world=to_world, source=source)


def _medium(file: str, index: int, data, scene_dir: str = ".") -> Medium:
    t = _Table(file, f"medium[{index}]", data)
    kind = t.string("type", Medium.type, MEDIUM_TYPES)
    heterogeneous = kind == "heterogeneous"
    readers = {
        "sigma_t": lambda: _volume(t, "sigma_t", scene_dir) if heterogeneous else _colour(t, "sigma_t", Medium.sigma_t),
        "albedo": lambda: (
            _volume(t, "albedo", scene_dir, hi=1.0)
            if heterogeneous and isinstance(t.get("albedo", None), Mapping)
            else _colour(t, "albedo", Medium.albedo, hi=1.0)
        ),
        "scale": lambda: t.number("scale", Medium.scale, lo=0.0),
        "emission": lambda: (
            _volume(t, "emission", scene_dir)
            if heterogeneous and isinstance(t.get("emission", None), Mapping)
            else _colour(t, "emission", Medium.emission, hi=MAX_MAGNITUDE)
        ),
        "sigma_n": lambda: t.number("sigma_n", Medium.sigma_n, lo=0.0, hi=MAX_MAGNITUDE),
    }
    values = {"name": t.string("name"), "type": kind}
    values.update({key: readers[key]() for key in MEDIUM_REGISTRY[kind].keys})
    phase = _Table(file, f"medium[{index}].phase", t.get("phase", {"type": Medium.phase}))
    values["phase"] = phase.string("type", Medium.phase, PHASE_TYPES)
    if "g" in PHASE_REGISTRY[values["phase"]].keys:
        values["g"] = phase.number("g", Medium.g, lo=-1.0, hi=1.0, lo_open=True, hi_open=True)
    phase.finish()
    t.finish()
    medium = Medium(**values)
    extinction = np.max(medium.sigma_t.values if heterogeneous else medium.sigma_t) * medium.scale
    if not extinction <= MAX_MAGNITUDE:
        shown = "its largest sigma_t" if heterogeneous else f"sigma_t = {list(medium.sigma_t)}"
        raise t.error("scale", f"times {shown}: {BEYOND_FLOAT32}", medium.scale)
    return medium


def _medium_ref(t: _Table, key: str, media_index: Mapping[str, int]) -> int | None:
    """The index of the medium named by ``key`` (a shape's ``interior``/``exterior``, the camera's
    ``medium``), or None where the key is absent."""
    name = t.get(key, None)
    if name is None:
        return None
    if not isinstance(name, str) or name not in media_index:
        known = listed(media_index) or "none defined"
        raise t.error(key, f"no [[medium]] with this name (known: {known})", name)
    return media_index[name]


def _newell_normal(t: _Table, vertices: tuple) -> tuple[float, float, float]:
    """Unit normal of a planar polygon by Newell's method; rejects zero-area and non-planar input."""
    v = np.asarray(vertices, dtype=np.float64)
    n = np.cross(v, np.roll(v, -1, axis=0)).sum(axis=0)
    length = np.linalg.norm(n)
    size = np.ptp(v, axis=0).max()
    if length <= 1e-12 * max(size, 1e-300) ** 2:
        raise t.error("vertices", "polygon has zero area")
    n /= length
    deviation = np.abs((v - v.mean(axis=0)) @ n).max()
    if deviation > 1e-5 * size:
        raise t.error("vertices", f"polygon is not planar (a vertex is {deviation:.3g} off its plane)")
    return tuple(float(c) for c in n)


def _transform(t: _Table) -> np.ndarray:
    """The object-to-world matrix of a shape's ``transform`` table (translate, rotate, scale,
    matrix; ``wrt.meshio.transform_matrix``), identity when absent."""
    transform = t.get("transform", {})
    tt = _Table(t.file, f"{t.name}.transform", transform)
    translate = tt.vec3("translate", (0.0, 0.0, 0.0))
    scale = tt.get("scale", 1.0)
    if isinstance(scale, list):
        scale = tt.vec3("scale")
        if not all(scale):
            raise tt.error("scale", "components must be nonzero", list(scale))
    else:
        scale = tt.number("scale", 1.0)
        if scale == 0.0:
            raise tt.error("scale", "must be nonzero", scale)
    rotate = tt.vec3("rotate", (0.0, 0.0, 0.0))
    matrix = tt.get("matrix", None)
    if matrix is not None:
        try:
            transform_matrix(matrix=matrix)
        except ValueError as e:
            raise tt.error("matrix", str(e).removeprefix("matrix "), matrix) from None
    tt.finish()
    return transform_matrix(translate=translate, scale=scale, rotate=rotate, matrix=matrix)


def _frame(axis: np.ndarray) -> np.ndarray:
    """A 3x3 rotation whose columns ``(u, v, axis)`` are a right-handed orthonormal frame around the
    unit vector ``axis`` (Duff et al. 2017, "Building an Orthonormal Basis, Revisited")."""
    x, y, z = axis
    sign = math.copysign(1.0, z)
    a = -1.0 / (sign + z)
    b = x * y * a
    u = [1.0 + sign * x * x * a, sign * b, -sign * x]
    v = [b, sign + y * y * a, -y]
    return np.column_stack([u, v, axis])


def _placed(t: _Table, kind: str, placement: np.ndarray) -> np.ndarray:
    """The object-to-world matrix of a disk or cylinder: its own ``placement`` of the unit shape,
    then its ``transform`` table; a disk's z column made its unit front normal (``wrt.scene.Disk``).
    Refuses a shape whose world-to-object map float32 cannot hold, or whose world coordinates
    go beyond ``MAX_MAGNITUDE``."""
    to_world = _transform(t) @ placement
    if kind == "disk":
        u, v = (to_world[:3, k] / np.linalg.norm(to_world[:3, k]) for k in (0, 1))
        normal = np.cross(u, v)
        with np.errstate(invalid="ignore"):
            to_world[:3, 2] = np.sign(np.dot(normal, to_world[:3, 2])) * normal / np.linalg.norm(normal)
    key = "transform" if "transform" in t.data else "radius"
    try:
        with np.errstate(all="ignore"):
            to_object = np.linalg.inv(to_world).astype(np.float32)
    except np.linalg.LinAlgError:
        to_object = np.full((4, 4), np.nan, dtype=np.float32)
    if not np.all(np.isfinite(to_object)):
        raise t.error(
            key, f"makes the {kind} too small or too thin for float32 (its world-to-object map overflows)", t.data[key]
        )
    reach = np.abs(to_world[:3, 3]) + np.abs(to_world[:3, :3]).sum(axis=1)
    if not np.all(reach <= MAX_MAGNITUDE):
        raise t.error(key, f"places points of the {kind} that {BEYOND_FLOAT32}", t.data[key])
    return to_world


def _disk_to_world(t: _Table) -> np.ndarray:
    """``to_world`` of a ``disk`` table: ``center``, ``normal`` (its front side), ``radius``."""
    center, normal = np.asarray(t.vec3("center")), np.asarray(t.vec3("normal", nonzero=True))
    radius = t.number("radius", lo=0.0, lo_open=True)
    placement = np.eye(4)
    placement[:3, :3] = _frame(normal / np.linalg.norm(normal)) @ np.diag([radius, radius, 1.0])
    placement[:3, 3] = center
    return _placed(t, "disk", placement)


def _cylinder_to_world(t: _Table) -> np.ndarray:
    """``to_world`` of a ``cylinder`` table: the tube of ``radius`` from ``p0`` to ``p1``."""
    p0, p1 = np.asarray(t.vec3("p0")), np.asarray(t.vec3("p1"))
    radius = t.number("radius", lo=0.0, lo_open=True)
    length = np.linalg.norm(p1 - p0)
    if length == 0.0:
        raise t.error("p1", "must differ from p0 (the cylinder has no length)", t.data["p1"])
    placement = np.eye(4)
    placement[:3, :3] = _frame((p1 - p0) / length) @ np.diag([radius, radius, length])
    placement[:3, 3] = p0
    return _placed(t, "cylinder", placement)


def _mesh(t: _Table, scene_dir: str, material: int, textured: tuple | None) -> Mesh:
    """A ``mesh`` table: its ``file`` (of a ``.serialized`` file, mesh ``shape_index``) placed by
    its ``transform``; with ``shading = "smooth"`` the file's vertex normals (by the inverse
    transpose), or Mitsuba 3's computed from the placed vertices when it has none;
    ``flip_normals`` reverses the winding and turns the normals around; with a ``textured``
    material (or an anisotropic one: its tangent is dp/du; not None), the file's texture
    coordinates, and the PLY attributes of its ``(parameter, MeshAttribute)`` uses, checked
    against their parameters' ranges."""
    name = t.string("file")
    matrix = _transform(t)
    smooth = t.string("shading", "flat", choices=MESH_SHADING) == "smooth"
    flip = t.boolean("flip_normals", False)
    path = os.path.join(scene_dir, name)
    index = 0
    if "shape_index" in t.data:
        if not name.lower().endswith(".serialized"):
            raise t.error(
                "shape_index", "applies to a .serialized file only (it may hold several meshes)", t.data["shape_index"]
            )
        index = t.number("shape_index", integer=True, lo=0, hi=2**31 - 1)
    try:
        read_all = smooth or textured is not None  # an OBJ file is then read as Mitsuba 3 numbers its vertices
        vertices, faces, normals, uvs = (
            load_mesh(path, return_normals=True, return_uvs=True, shape_index=index)
            if read_all
            else (*load_mesh(path, shape_index=index), None, None)
        )
    except MeshFileError as e:
        raise t.error("file", str(e), name) from None
    attributes = _mesh_attributes(t, name, path, textured or ())
    if not smooth:
        normals = None
    if textured is None:
        uvs = None
    elif uvs is not None and not np.all(np.abs(uvs) <= MAX_MAGNITUDE):
        raise t.error("file", f"texture coordinates {BEYOND_FLOAT32}", name)
    if flip:
        faces = np.ascontiguousarray(faces[:, ::-1])
        normals = None if normals is None else -normals
    vertices = apply_transform(vertices, matrix=matrix)
    if not np.all(np.abs(vertices) <= MAX_MAGNITUDE):
        raise t.error("file", f"vertices (after the transform) {BEYOND_FLOAT32}", name)
    if smooth:
        normals = vertex_normals(vertices, faces) if normals is None else transform_normals(normals, matrix)
    return Mesh(
        file=path, vertices=vertices, faces=faces, material=material, normals=normals, uvs=uvs, attributes=attributes
    )


def _mesh_attributes(t: _Table, name: str, path: str, uses: tuple) -> dict[str, np.ndarray]:
    """The attributes of mesh file ``name`` that its material's mesh-attribute textures read
    (``uses``: ``(parameter, MeshAttribute)`` pairs), each finite, of a number parameter one
    channel (Mitsuba's ``eval_1``), of a colour one or three, and times the texture's scale within
    the parameter's range."""
    if not uses:
        return {}
    if not path.lower().endswith(".ply"):
        raise t.error("file", "is not a PLY file: its material reads mesh attributes (mesh_attribute)", name)
    try:
        attributes = ply_attributes(path, sorted({texture.name for _, texture in uses}))
    except MeshFileError as e:
        raise t.error("file", str(e), name) from None
    for key, texture in uses:
        values = attributes[texture.name]
        channels = values.shape[1]
        if not np.all(np.isfinite(values)):
            raise t.error("file", f"mesh attribute '{texture.name}' has NaN or infinite values", name)
        if channels not in ((1,) if key in NUMBER_SLOTS else (1, 3)):
            need = "1 channel (a number)" if key in NUMBER_SLOTS else "1 or 3 channels (a colour)"
            raise t.error("file", f"mesh attribute '{texture.name}' has {channels} channels: {key} needs {need}", name)
        scaled = values * texture.scale
        lo, hi = _slot_range(key)
        if scaled.min() < lo or scaled.max() > hi:
            eight_bit = (
                values.max() > 1 and values.max() <= 255 and np.all(values == np.round(values)) and values.min() >= 0
            )
            raise t.error(
                "file",
                f"mesh attribute '{texture.name}' times its scale {texture.scale:g} ranges over"
                f" [{scaled.min():.4g}, {scaled.max():.4g}]: {key} must stay in [{lo:g}, {hi:g}]"
                + (
                    " (8-bit values, read as written, as Mitsuba reads them: scale = 0.003921569, 1/255, takes"
                    " them to [0, 1])"
                    if eight_bit
                    else ""
                ),
                name,
            )
    return attributes


_NONE_TEXTURED: Mapping[int, tuple] = {}


def _shape(
    file: str,
    name: str,
    data,
    material_index: Mapping[str, int],
    scene_dir: str,
    group_index: Mapping[str, int] | None = None,
    textured: Mapping[int, tuple] = _NONE_TEXTURED,
    media_index: Mapping[str, int] | None = None,
):
    """``(shape, boundary)`` of table ``name`` (``shape[3]``, or ``group[0].shape[1]`` without
    ``group_index``: a group's shapes are bounded, still, not instances and bound no media);
    ``textured``: the materials (by index) with textures or anisotropic roughness (their meshes'
    texture coordinates are read), each to its mesh-attribute uses (``_mesh_attributes``).
    ``boundary``: for a shape of the scene (``media_index``: the media by name), the ``(interior,
    exterior)`` media it bounds (-1 for the side it does not name); None where it names neither,
    and for a group's shape."""
    t = _Table(file, name, data)
    boundary = None
    if media_index is not None:
        inside, outside = _medium_ref(t, "interior", media_index), _medium_ref(t, "exterior", media_index)
        if inside is not None or outside is not None:
            boundary = (-1 if inside is None else inside, -1 if outside is None else outside)
    kind = t.string("type", choices=SHAPE_TYPES if group_index is not None else GROUP_SHAPE_TYPES)
    name = t.get("material", None)
    if name is None:
        material = material_index[DEFAULT_MATERIAL.name]
    elif not isinstance(name, str) or name not in material_index:
        known = listed(k for k in material_index if k != DEFAULT_MATERIAL.name) or "none defined"
        raise t.error("material", f"no [[material]] with this name (known: {known})", name)
    else:
        material = material_index[name]
    if kind not in ("mesh", "instance") and textured.get(material):
        attribute = textured[material][0][1].name
        raise t.error(
            "material", f"reads mesh attribute '{attribute}' (mesh_attribute): only a mesh has attributes", name
        )
    if kind == "sphere":
        shape = _sphere(t, material)
    elif kind == "plane":
        normal = np.asarray(t.vec3("normal", nonzero=True))
        shape = Plane(point=t.vec3("point"), normal=tuple(normal / np.linalg.norm(normal)), material=material)
    elif kind == "triangle":
        shape = Triangle(vertices=t.vectors("vertices", count=3), material=material)
    elif kind == "polygon":
        vertices = t.vectors("vertices", min_count=3)
        uvs = _polygon_uvs(t, len(vertices))
        shape = Polygon(vertices=vertices, normal=_newell_normal(t, vertices), material=material, uvs=uvs)
    elif kind == "mesh":
        shape = _mesh(t, scene_dir, material, textured.get(material))
    elif kind == "disk":
        shape = Disk(to_world=_disk_to_world(t), material=material)
    elif kind == "cylinder":
        flip = t.boolean("flip_normals", Cylinder.flip_normals)
        shape = Cylinder(to_world=_cylinder_to_world(t), flip_normals=flip, material=material)
    else:
        if name is not None:
            raise t.error("material", "is not for an instance: the group's shapes keep their own materials", name)
        group = t.string("group")
        if group not in group_index:
            known = listed(group_index) or "none defined"
            raise t.error("group", f"no [[group]] with this name (known: {known})", group)
        shape = Instance(group=group_index[group], matrix=_transform(t), material=material)
    velocity = t.vec3("velocity", STILL) if group_index is not None else STILL
    t.finish()
    return (dataclasses.replace(shape, velocity=velocity) if velocity != STILL else shape), boundary


def _sphere(t: _Table, material: int) -> Sphere:
    """A sphere: ``center``, ``radius``, and an optional ``transform`` that may rotate, mirror, scale
    uniformly and translate it (a sphere stays a sphere): the centre and radius follow it, and its
    rotation turns the sphere's object axes (``Sphere.to_object``), its texture with them."""
    center, radius = t.vec3("center"), t.number("radius", lo=0.0, lo_open=True)
    if "transform" not in t.data:
        return Sphere(center=center, radius=radius, material=material)
    matrix = _transform(t)
    linear = matrix[:3, :3]
    scale = abs(np.linalg.det(linear)) ** (1.0 / 3.0)
    rotation = linear / scale
    if not np.allclose(rotation.T @ rotation, np.eye(3), rtol=0.0, atol=1e-9):
        raise t.error(
            "transform", "must rotate, scale uniformly and translate (a sphere stays a sphere)", t.data["transform"]
        )
    placed = matrix[:3, :3] @ np.asarray(center) + matrix[:3, 3]
    if not (np.all(np.abs(placed) <= MAX_MAGNITUDE) and 0.0 < radius * scale <= MAX_MAGNITUDE):
        raise t.error(
            "transform",
            f"places the sphere beyond float32: its centre and radius {BEYOND_FLOAT32}",
            t.data["transform"],
        )
    to_object = tuple(tuple(float(x) for x in row) for row in rotation.T)
    return Sphere(
        center=tuple(float(x) for x in placed), radius=float(radius * scale), material=material, to_object=to_object
    )


def _polygon_uvs(t: _Table, count: int) -> tuple | None:
    """A polygon's ``uv``: texture coordinates [u, v] of its ``count`` vertices (None when absent)."""
    uvs = t.get("uv", None)
    if uvs is None:
        return None
    if (
        not isinstance(uvs, list)
        or len(uvs) != count
        or not all(isinstance(uv, list) and len(uv) == 2 for uv in uvs)
        or not all(not isinstance(c, bool) and isinstance(c, (int, float)) for uv in uvs for c in uv)
    ):
        raise t.error("uv", f"must be a list of {count} pairs [u, v], one per vertex", uvs)
    _check_float32(t, "uv", [c for uv in uvs for c in uv], uvs)
    return tuple((float(u), float(v)) for u, v in uvs)


def _attribute_means(materials: list[Material], shapes) -> list[Material]:
    """``materials`` with each mesh-attribute parameter's constant the mean of its values (times
    the texture's scale) over the meshes that read it: what stands for it where a constant is read
    (``Material.textures``)."""
    by_name = {m.name: m for m in materials}
    sums: dict[tuple[str, str], list] = {}
    for shape in shapes:
        if isinstance(shape, Mesh) and shape.attributes:
            for c in constituents(materials[shape.material], by_name):
                for key, texture in c.textures:
                    if isinstance(texture, MeshAttribute):
                        sums.setdefault((c.name, key), []).append(shape.attributes[texture.name] * texture.scale)
    out = []
    for m in materials:
        means = {key: np.concatenate(v).mean(axis=0) for (name, key), v in sums.items() if name == m.name}
        values = {
            key: float(mean.mean()) if key in NUMBER_SLOTS else tuple(float(c) for c in np.broadcast_to(mean, 3))
            for key, mean in means.items()
        }
        out.append(dataclasses.replace(m, **values) if values else m)
    return out


def _group(
    file: str,
    index: int,
    data,
    material_index: Mapping[str, int],
    scene_dir: str,
    textured: Mapping[int, tuple] = _NONE_TEXTURED,
) -> Group:
    t = _Table(file, f"group[{index}]", data)
    name = t.string("name")
    tables = t.get("shape", None)
    if not isinstance(tables, list) or not tables or not all(isinstance(x, dict) for x in tables):
        raise t.error("shape", "must be a non-empty array of tables, written [[group.shape]]", tables)
    shapes = tuple(
        _shape(file, f"group[{index}].shape[{j}]", table, material_index, scene_dir, textured=textured)[0]
        for j, table in enumerate(tables)
    )
    t.finish()
    return Group(name=name, shapes=shapes)


def _unit(t: _Table, key: str) -> tuple[float, float, float]:
    v = np.asarray(t.vec3(key, nonzero=True))
    return tuple(float(c) for c in v / np.linalg.norm(v))


def _up(t: _Table, direction: tuple) -> tuple[float, float, float]:
    """A light's ``up`` (default +y): its frame's y side (``wrt.scene.light_frame``), not along ``direction``."""
    up = t.vec3("up", (0.0, 1.0, 0.0), nonzero=True)
    u = np.asarray(up, dtype=np.float64) / np.linalg.norm(up)
    if np.linalg.norm(np.cross(u, direction)) < 1e-6:
        given = "" if "up" in t.data else " (the default: give an up)"
        raise t.error("up", f"is parallel to direction{given} and leaves the light's frame undefined", list(up))
    return tuple(float(c) for c in up)


def _light_texture(t: _Table, key: str, scene_dir: str):
    """A textured light's ``key``: a texture table (``wrt.textures.read_texture``), a number or 3
    numbers (a constant), non-negative linear RGB."""
    value = t.get(key, _REQUIRED)
    if not isinstance(value, Mapping):
        grey = isinstance(value, (int, float)) and not isinstance(value, bool)
        colour = (t.number(key, lo=0.0),) * 3 if grey else t.vec3(key, lo=0.0)
        return Constant(value=colour)
    tt = _Table(t.file, f"{t.name}.{key}", value)
    texture = read_texture(tt, scene_dir)
    if isinstance(texture, MeshAttribute):
        raise tt.error("texture", "a light's texture cannot be a mesh attribute (a light is no mesh)", "mesh_attribute")
    values = texture.values()
    if values.min() < 0.0 or values.max() > MAX_MAGNITUDE:
        field = _texture_key(texture)
        raise tt.error(
            field,
            f"its values range over [{values.min():.4g}, {values.max():.4g}]: must stay in [0, {MAX_MAGNITUDE:g}]",
            value.get(field),
        )
    return texture


def _environment(t: _Table, scene_dir: str) -> EnvironmentLight:
    """An ``environment`` table: a constant ``radiance``, or a map: ``file`` (an equirectangular
    OpenEXR or Radiance HDR image of linear RGB, relative to ``scene_dir``), ``scale`` and the
    ``transform`` of its frame (rotations only: it is infinitely far)."""
    if "file" not in t.data:
        for key in ("scale", "transform"):
            if key in t.data:
                raise t.error(key, 'applies to an environment map only (one with a "file")', t.data[key])
        return EnvironmentLight(radiance=t.vec3("radiance", lo=0.0))
    if "radiance" in t.data:
        raise t.error("radiance", 'is for a constant environment: a map\'s radiance is its pixels times "scale"')
    name = t.string("file")
    path = os.path.join(scene_dir, name)
    try:
        image = read_environment_map(path)
    except EnvironmentMapError as e:
        raise t.error("file", str(e), name) from None
    scale = t.number("scale", 1.0, lo=0.0)
    if float(image.max()) * scale > MAX_MAGNITUDE:
        raise t.error("scale", f"times the brightest pixel ({image.max():.3g}) {BEYOND_FLOAT32}", scale)
    matrix = _transform(t)
    to_world = matrix[:3, :3]
    if np.any(matrix[:3, 3]) or not np.allclose(to_world.T @ to_world, np.eye(3), rtol=0.0, atol=1e-6):
        raise t.error("transform", "must be a rotation (an environment is infinitely far)", t.data["transform"])
    return EnvironmentLight(radiance=(scale, scale, scale), file=path, image=image, to_world=to_world)


def _light(file: str, index: int, data, scene_dir: str):
    t = _Table(file, f"light[{index}]", data)
    light_type = t.string("type", choices=LIGHT_TYPES)
    if light_type == "point":
        light = PointLight(position=t.vec3("position"), intensity=t.vec3("intensity", lo=0.0))
    elif light_type == "directional":
        light = DirectionalLight(direction=_unit(t, "direction"), irradiance=t.vec3("irradiance", lo=0.0))
    elif light_type == "spot":
        cutoff = t.number("cutoff_angle", SpotLight.cutoff_angle, lo=0.0, hi=90.0, lo_open=True)
        direction = _unit(t, "direction")
        texture = _light_texture(t, "texture", scene_dir) if "texture" in t.data else None
        if texture is None and "up" in t.data:
            raise t.error("up", "orients a spot's texture: it applies to a spot with a texture only", t.data["up"])
        light = SpotLight(
            position=t.vec3("position"),
            direction=direction,
            intensity=t.vec3("intensity", lo=0.0),
            cutoff_angle=cutoff,
            beam_width=t.number("beam_width", 0.75 * cutoff, lo=0.0, hi=cutoff),
            up=SpotLight.up if texture is None else _up(t, direction),
            texture=texture,
        )
    elif light_type == "projector":
        direction = _unit(t, "direction")
        irradiance = _light_texture(t, "irradiance", scene_dir)
        light = ProjectorLight(
            position=t.vec3("position"),
            direction=direction,
            irradiance=irradiance,
            fov=t.number("fov", 45.0, lo=0.0, hi=180.0, lo_open=True, hi_open=True),
            up=_up(t, direction),
            scale=t.number("scale", 1.0, lo=0.0),
        )
    elif light_type == "area":
        light = AreaLight(
            corner=t.vec3("corner"),
            edge_u=t.vec3("edge_u", nonzero=True),
            edge_v=t.vec3("edge_v", nonzero=True),
            radiance=t.vec3("radiance", lo=0.0),
        )
        if not np.any(np.cross(light.edge_u, light.edge_v)):
            raise t.error("edge_v", "is parallel to edge_u (the light has no area)", list(light.edge_v))
        if _float32_unit(np.cross(np.float32(light.edge_u), np.float32(light.edge_v))) is None:
            raise t.error(
                "edge_v", "spans with edge_u an area float32 cannot resolve (it underflows)", list(light.edge_v)
            )
    elif light_type == "sphere":
        light = SphereLight(
            center=t.vec3("center"),
            radius=t.number("radius", lo=0.0, lo_open=True),
            radiance=t.vec3("radiance", lo=0.0),
        )
    else:
        light = _environment(t, scene_dir)
    t.finish()
    return light


def parse_scene(doc: Mapping, *, file: str = "<memory>", scene_dir: str = ".") -> Scene:
    """Validate an already-parsed TOML document (a dict) into a ``Scene``.

    Mesh paths are relative to ``scene_dir``. Raises ``SceneError`` on any problem.
    """
    top = _Table(file, None, doc)
    for key in doc:
        if key not in TOP_LEVEL:
            raise top.error(key, f"unknown table (known: {', '.join(TOP_LEVEL)})")
    if "camera" not in doc:
        raise SceneError(file, "camera", None, "is required")
    render = _render(file, doc.get("render", {}))
    media = [_medium(file, i, m, scene_dir) for i, m in enumerate(_array_of_tables(file, doc, "medium"))]
    media_index: dict[str, int] = {}
    for i, m in enumerate(media):
        if media_index.setdefault(m.name, i) != i:
            raise SceneError(file, f"medium[{i}]", "name", "is already used", m.name)
    camera, camera_medium = _camera(file, doc["camera"], media_index)
    materials = [_material(file, i, m, scene_dir) for i, m in enumerate(_array_of_tables(file, doc, "material"))]
    material_index: dict[str, int] = {}
    for i, m in enumerate(materials):
        if m.name in material_index or m.name == DEFAULT_MATERIAL.name:
            raise SceneError(file, f"material[{i}]", "name", "is already used (or reserved)", m.name)
        material_index[m.name] = i
    by_name = {m.name: m for m in materials}
    for i, m in enumerate(materials):
        _check_nested(file, i, m, by_name)
    material_index[DEFAULT_MATERIAL.name] = len(materials)
    materials.append(DEFAULT_MATERIAL)
    by_name[DEFAULT_MATERIAL.name] = DEFAULT_MATERIAL
    textured = {  # textured or anisotropic (the tangent is dp/du), or made of such a material: its attributes
        i: tuple(
            (key, texture)
            for c in constituents(m, by_name)
            for key, texture in c.textures
            if isinstance(texture, MeshAttribute)
        )
        for i, m in enumerate(materials)
        if any(c.textures or c.anisotropic for c in constituents(m, by_name))
    }
    groups = [
        _group(file, i, g, material_index, scene_dir, textured)
        for i, g in enumerate(_array_of_tables(file, doc, "group"))
    ]
    group_index: dict[str, int] = {}
    for i, group in enumerate(groups):
        if group_index.setdefault(group.name, i) != i:
            raise SceneError(file, f"group[{i}]", "name", "is already used", group.name)
    shapes, boundaries = [], []
    for i, s in enumerate(_array_of_tables(file, doc, "shape")):
        shape, boundary = _shape(file, f"shape[{i}]", s, material_index, scene_dir, group_index, textured, media_index)
        shapes.append(shape)
        if boundary is not None:
            boundaries.append((i, *boundary))
    materials = _attribute_means(materials, [*shapes, *(shape for group in groups for shape in group.shapes)])
    longest_time = max(abs(c) for c in camera.shutter)
    for i, shape in enumerate(shapes):  # a moving shape's displacement is a coordinate too
        displacement = float(np.linalg.norm(shape.velocity)) * longest_time
        if displacement > MAX_MAGNITUDE:
            raise SceneError(
                file,
                f"shape[{i}]",
                "velocity",
                f"times the camera shutter {list(camera.shutter)} moves the shape {displacement:.3g} units: "
                f"{BEYOND_FLOAT32}",
                list(shape.velocity),
            )
    lights = [_light(file, i, light, scene_dir) for i, light in enumerate(_array_of_tables(file, doc, "light"))]
    maps = [i for i, light in enumerate(lights) if isinstance(light, EnvironmentLight) and light.image is not None]
    if len(maps) > 1:
        raise SceneError(file, f"light[{maps[1]}]", "file", f"a second environment map (light[{maps[0]}] has one)")
    if render.integrator == "whitted":
        _check_whitted(file, lights, materials, media)
    scene = Scene(
        render=render,
        camera=camera,
        materials=tuple(materials),
        shapes=tuple(shapes),
        lights=tuple(lights),
        path=file,
        groups=tuple(groups),
        media=tuple(media),
        boundaries=tuple(boundaries),
        camera_medium=-1 if camera_medium is None else camera_medium,
    )
    if render.integrator == "ptracer":
        check_light_tracer(file, scene)
    return scene


NESTED_RULES = {
    "mask": (
        "material",
        ("mask", "dielectric", "rough_dielectric"),
        "a mask's material must name a [[material]] of the file that is not a mask, a dielectric or a rough "
        "dielectric (they bound a medium)",
    ),
    "blend": (
        "materials",
        ("blend", "mask", "dielectric", "rough_dielectric", "null"),
        "a blend's materials must name [[material]]s of the file that are not blends, masks, dielectrics, rough "
        "dielectrics (they bound a medium) or null",
    ),
}
"""Per type made of other materials (``Material.nested``): the key naming them, the types they may
not be, and the rule a refusal states."""


def _check_nested(file: str, i: int, material: Material, by_name: Mapping[str, Material]) -> None:
    """Refuse a mask's or a blend's material (``material[i]``) that the file does not define, is of
    a type it may not be (``NESTED_RULES``), or has a normal or bump map (the kernels read the hit's
    material's, the mask's or the blend's own, so it would be silently ignored)."""
    for name in material.nested:
        key, forbidden, rule = NESTED_RULES[material.type]
        nested = by_name.get(name)
        if nested is None or nested.type in forbidden:
            why = "names no material" if nested is None else f"names a {nested.type}"
            raise SceneError(file, f"material[{i}]", key, f"{why}: {rule}", name)
        mapped = [slot for slot, _ in nested.textures if slot in ("normal_map", "bump_map")]
        if mapped:
            kind, what = material.type, mapped[0].replace("_", " ")
            raise SceneError(
                file,
                f"material[{i}]",
                key,
                f"names a material with a {what}: a {kind}'s shading frame is its own (give the {kind} the {what})",
                name,
            )


def _check_whitted(source: str, lights, materials, media) -> None:
    """Refuse what the whitted integrator cannot render: lights that are surfaces or a sky,
    materials with glossy or stochastic lobes and participating media (``SceneError`` naming
    ``source``, the entry and its type)."""
    if media:
        raise SceneError(
            source,
            "medium[0]",
            "type",
            'the whitted integrator traces no participating media (scattering needs integrator = "path")',
            media[0].type,
        )
    for i, light in enumerate(lights):
        if isinstance(light, (AreaLight, SphereLight, EnvironmentLight)):
            raise SceneError(
                source,
                f"light[{i}]",
                "type",
                "the whitted integrator takes point, directional and spot lights (area, sphere and environment "
                'lights need integrator = "path")',
                light.type,
            )
    for i, material in enumerate(materials):
        if material.type in ("rough_dielectric", "mask", "blend", "null", "principled", "principled_thin"):
            raise SceneError(
                source,
                f"material[{i}]",
                "type",
                f"the whitted integrator traces delta lobes only (a {material.type.replace('_', ' ')} needs "
                'integrator = "path")',
                material.type,
            )


def load_scene(path: str | os.PathLike, *, approximate: bool = False) -> Scene:
    """Read and validate a scene file: TOML, or Mitsuba 3 XML (``.xml``, the subset of
    ``wrt.mitsuba``, converted faithfully or refused; with ``approximate``, converted anyway: the
    approximations are printed on stderr and kept in ``Scene.approximations``).

    Raises
    ------
    WrtError
        The file cannot be read, or (XML) has an element wrt cannot convert exactly.
    SceneError
        It is not valid TOML, or a table, key or value is wrong (the message names them; for XML,
        the element they were converted from).
    """
    path = os.fspath(path)
    if path.lower().endswith(".xml"):
        from .mitsuba.scene import convert_file

        try:
            converted = convert_file(path, approximate=approximate)
        except RecursionError:
            raise SceneError(path, None, None, "elements nested too deeply") from None
        for warning in converted.approximations:
            print(f"wrt: warning: approximated: {warning}", file=sys.stderr)
        try:
            scene = parse_scene(converted.doc, file=path, scene_dir=os.path.dirname(os.path.abspath(path)))
        except SceneError as e:
            raise converted.locate(e) from None
        return dataclasses.replace(scene, approximations=tuple(converted.approximations))
    try:
        doc = read_toml(path, "scene")
    except TomlError as e:
        raise SceneError(path, None, None, e.problem) from None
    return parse_scene(doc, file=path, scene_dir=os.path.dirname(os.path.abspath(path)))


def override_render(scene: Scene, *, source: str = "command line", **changes) -> Scene:
    """A copy of ``scene`` with ``[render]`` keys replaced (None values are ignored).

    The new values are validated exactly like the file's, errors naming ``source``; a switch to
    the whitted integrator is refused where the file's would be (area, sphere and environment
    lights; rough dielectrics and masks), and so is a switch to the light tracer
    (``wrt.light_tracing.check_light_tracer``).
    """
    values = {k: v for k, v in changes.items() if v is not None}
    if not values:
        return scene
    merged = {
        k: list(v) if isinstance(v, tuple) else v for k, v in {**dataclasses.asdict(scene.render), **values}.items()
    }
    render = _render(source, merged)
    if render.integrator == "whitted" and scene.render.integrator != "whitted":
        _check_whitted(source, scene.lights, scene.materials, scene.media)
    if render.integrator == "ptracer" and scene.render.integrator != "ptracer":
        check_light_tracer(source, scene)
    return dataclasses.replace(scene, render=render)
