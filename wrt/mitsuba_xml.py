"""Mitsuba 3 scene XML -> a wrt scene document (the dict that ``wrt.loader.parse_scene`` validates).

`load_mitsuba` converts the common subset of Mitsuba 3's scene XML: ``perspective`` and
``thinlens`` sensors, ``hdrfilm`` with its reconstruction filter, the ``independent`` and
``stratified`` samplers, the ``path`` integrator, the shapes ``sphere``, ``rectangle``, ``cube``,
``obj`` and ``ply`` with their ``to_world`` transforms, the BSDFs ``diffuse``, ``conductor``,
``roughconductor``, ``dielectric`` and ``twosided``, and the emitters ``area``, ``point``,
``spot``, ``constant`` and ``directional``. ``<default>`` parameters with ``$name``
substitution and ``<ref id=...>`` references work as in Mitsuba. The mapping of every element
and parameter, the conventions that differ, and every warning are listed in ``docs/mitsuba.md``.

Whatever would make wrt render the converted scene differently from Mitsuba in expectation (an
unsupported element or parameter, a BSDF replaced by its closest match, a one-sided surface
whose back is visible) is reported as a warning naming the file, the line and the element, or
raised as a `WrtError` with ``strict=True``. Parameters that change only noise (sampler type,
seed, Russian roulette depth) or the output file (pixel and file formats) convert silently.

Frames and units are Mitsuba's and wrt's alike: right-handed world space, angles in degrees,
linear RGB; radiance in W/(m^2 sr), intensity in W/sr, irradiance in W/m^2.
"""

from __future__ import annotations

import math
import os
import re
from collections import Counter
from dataclasses import dataclass, field
from xml.parsers import expat

import numpy as np

from .errors import WrtError

MAX_DEPTH = 1024
"""wrt's largest ``max_depth``: what Mitsuba's ``max_depth = -1`` (unbounded) becomes."""

IOR_TABLE = {
    "vacuum": 1.0,
    "helium": 1.000036,
    "hydrogen": 1.000132,
    "air": 1.000277,
    "carbon dioxide": 1.00045,
    "water": 1.3330,
    "acetone": 1.36,
    "ethanol": 1.361,
    "carbon tetrachloride": 1.461,
    "glycerol": 1.4729,
    "benzene": 1.501,
    "silicone oil": 1.52045,
    "bromine": 1.661,
    "water ice": 1.31,
    "fused quartz": 1.458,
    "pyrex": 1.470,
    "acrylic glass": 1.49,
    "polypropylene": 1.49,
    "bk7": 1.5046,
    "sodium chloride": 1.544,
    "amber": 1.55,
    "pet": 1.5750,
    "diamond": 2.419,
}
"""Mitsuba 3's named indices of refraction (``int_ior``/``ext_ior`` strings, case-insensitive;
Hecht, Optics, 4th ed., ~589 nm)."""

CONDUCTOR_F0 = {
    "Ag": (0.9748, 0.9575, 0.9063),
    "Al": (0.9280, 0.9178, 0.9189),
    "AlAs": (0.3200, 0.2783, 0.1430),
    "Au": (0.9667, 0.8020, 0.3241),
    "Be": (0.5975, 0.5206, 0.5062),
    "Cr": (0.6876, 0.6491, 0.6870),
    "CsI": (0.1325, 0.0675, 0.0619),
    "Cu": (0.9520, 0.6198, 0.5106),
    "Cu2O": (0.3147, 0.2455, 0.2379),
    "CuO": (0.2907, 0.1982, 0.1834),
    "Hg": (0.8140, 0.7702, 0.7631),
    "HgTe": (0.4699, 0.3665, 0.3507),
    "Ir": (0.7426, 0.6802, 0.6308),
    "K": (0.9539, 0.9363, 0.9201),
    "Li": (0.9248, 0.8844, 0.7933),
    "MgO": (0.1244, 0.0603, 0.0526),
    "Mo": (0.6182, 0.5618, 0.5409),
    "Na_palik": (0.9785, 0.9597, 0.9315),
    "Nb": (0.5640, 0.4895, 0.4731),
    "Ni_palik": (0.7001, 0.5942, 0.4936),
    "Rh": (0.8243, 0.7544, 0.7216),
    "Se": (0.3793, 0.2507, 0.2413),
    "SiC": (0.2711, 0.1873, 0.1808),
    "SnTe": (0.4070, 0.1084, 0.0152),
    "Ta": (0.4565, 0.3419, 0.3799),
    "Te": (0.6350, 0.5781, 0.5617),
    "ThF4": (0.0861, 0.0328, 0.0264),
    "TiC": (0.5482, 0.4397, 0.4116),
    "TiN": (0.6409, 0.4523, 0.1976),
    "TiO2": (0.3039, 0.2246, 0.2380),
    "VC": (0.5297, 0.4179, 0.3798),
    "VN": (0.5251, 0.3926, 0.3106),
    "V_palik": (0.5727, 0.5107, 0.5365),
    "W": (0.5746, 0.4778, 0.4331),
    "a-C": (0.2794, 0.1940, 0.1691),
    "d-C": (0.2123, 0.1579, 0.1449),
}
"""Normal-incidence reflectance (linear RGB) of Mitsuba 3's named conductors, measured with
Mitsuba 3.9 ``scalar_rgb`` (a ``conductor`` sampled at normal incidence). A ``<name>_palik``
material not listed has the same value as ``<name>``. wrt's mirror and glossy materials have a
constant Fresnel factor, so a named conductor converts to this value with a warning."""

FILTERS = {"box": ("radius", 0.5), "gaussian": ("stddev", 0.5), "tent": ("radius", 1.0)}
"""Mitsuba reconstruction filters wrt has, with the parameter that sets their width and the
default width (pixels) that wrt's filter of the same name assumes."""

SAMPLERS = {
    "independent": "independent",
    "stratified": "stratified",
    "multijitter": "stratified",
    "orthogonal": "stratified",
    "ldsampler": "sobol",
}
"""Mitsuba sampler -> wrt ``[render] sampler``. Samplers change the noise, not the expected image."""

_VALUE_TAGS = ("float", "integer", "boolean", "string", "rgb", "spectrum", "point", "vector", "transform")
_PLUGIN_TAGS = (
    "bsdf",
    "emitter",
    "film",
    "sampler",
    "rfilter",
    "texture",
    "shape",
    "medium",
    "phase",
    "volume",
    "sensor",
    "integrator",
)
_HARMLESS = {
    "hdrfilm": ("file_format", "pixel_format", "component_format", "compensate"),
    "path": ("rr_depth",),
    "volpath": ("rr_depth",),
    "roughconductor": ("sample_visible",),
    "obj": ("flip_tex_coords",),
    "ply": ("flip_tex_coords",),
}
"""Parameters read without conversion because they change only the noise or the output file."""

_REQUIRED = object()
_PARAMETER = re.compile(r"\$([A-Za-z_][A-Za-z0-9_]*)")
_SPLIT = re.compile(r"[\s,]+")


@dataclass(eq=False)
class _Element:
    """One XML element with the line it starts on (``xml.etree`` keeps no line numbers)."""

    tag: str
    attrs: dict
    line: int
    children: list = field(default_factory=list)

    def describe(self) -> str:
        shown = " ".join(f'{k}="{self.attrs[k]}"' for k in ("type", "name", "id") if k in self.attrs)
        return f"<{self.tag}{' ' + shown if shown else ''}>"


def load_mitsuba(path, *, strict: bool = False, params: dict | None = None) -> tuple[dict, list[str]]:
    """Convert a Mitsuba 3 scene XML file into a wrt scene document.

    Parameters
    ----------
    path : str or os.PathLike
        The Mitsuba scene (``<scene version="3.x">``).
    strict : bool, default False
        Raise a `WrtError` instead of returning a warning.
    params : dict of str to object, optional
        Values for ``$name`` parameters that override the file's ``<default>`` elements, as
        ``mitsuba.load_file(path, **params)`` takes them (e.g. ``{"res": 32}``).

    Returns
    -------
    doc : dict
        ``{"render", "camera", "material", "shape", "light"}`` tables in wrt's scene format for
        ``parse_scene(doc, file=path, scene_dir=os.path.dirname(path))``: mesh ``file`` keys are
        relative to the XML file, shapes keep the file's order (cubes become six polygons),
        area-emitting rectangles and spheres become ``area`` and ``sphere`` lights.
    warnings : list of str
        ``"FILE:LINE: <element>: what differs from Mitsuba"``, one per problem, in file order.

    Raises
    ------
    WrtError
        The file cannot be read, is not well-formed XML (the message names the file, the line
        and the column), is not a Mitsuba scene, has a value Mitsuba itself would reject (a
        malformed number, an unknown IOR name, an undefined ``$name``, a reference to an
        unknown id), or, with ``strict=True``, anything that would produce a warning.
    """
    path = os.fspath(path)
    return _Converter(path, strict, params or {}).convert(_read_xml(path))


def _read_xml(path: str) -> _Element:
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError as e:
        raise WrtError(f"{path}: cannot read Mitsuba scene ({e.strerror})") from None
    parser = expat.ParserCreate()
    stack: list[_Element] = []
    roots: list[_Element] = []

    def start(tag, attrs):
        element = _Element(tag, attrs, parser.CurrentLineNumber)
        (stack[-1].children if stack else roots).append(element)
        stack.append(element)

    parser.StartElementHandler = start
    parser.EndElementHandler = lambda tag: stack.pop()
    try:
        parser.Parse(data, True)
    except expat.ExpatError as e:
        raise WrtError(f"{path}:{e.lineno}:{e.offset + 1}: malformed XML: {expat.ErrorString(e.code)}") from None
    return roots[0]


def look_at_matrix(origin, target, up) -> np.ndarray:
    """Mitsuba's ``lookat`` camera-to-world matrix: columns left, up', forward, origin.

    ``forward = normalize(target - origin)``, ``left = normalize(cross(up, forward))``,
    ``up' = cross(forward, left)``; a zero ``up`` is replaced by Mitsuba's
    ``coordinate_system(forward)`` tangent. Local +z looks at the target, local +x points to the
    left of the image.
    """
    origin, target, up = (np.asarray(v, dtype=np.float64) for v in (origin, target, up))
    forward = (target - origin) / np.linalg.norm(target - origin)
    if not np.any(up):
        up = _coordinate_system(forward)
    left = np.cross(up, forward)
    left /= np.linalg.norm(left)
    matrix = np.eye(4)
    matrix[:3, 0], matrix[:3, 1], matrix[:3, 2], matrix[:3, 3] = left, np.cross(forward, left), forward, origin
    return matrix


def rotation_matrix(axis, angle) -> np.ndarray:
    """4x4 right-handed rotation by ``angle`` degrees about ``axis`` (Mitsuba's ``rotate``)."""
    axis = np.asarray(axis, dtype=np.float64)
    x, y, z = axis / np.linalg.norm(axis)
    s, c = (0.0 if abs(v) < 1e-15 else v for v in (math.sin(math.radians(angle)), math.cos(math.radians(angle))))
    matrix = np.eye(4)
    matrix[:3, :3] = [
        [x * x * (1 - c) + c, x * y * (1 - c) - z * s, x * z * (1 - c) + y * s],
        [x * y * (1 - c) + z * s, y * y * (1 - c) + c, y * z * (1 - c) - x * s],
        [x * z * (1 - c) - y * s, y * z * (1 - c) + x * s, z * z * (1 - c) + c],
    ]
    return matrix


def vertical_fov(fov: float, fov_axis: str, width: int, height: int) -> float:
    """Mitsuba's ``fov`` along ``fov_axis`` -> wrt's vertical field of view, degrees.

    ``fov_axis`` is ``x`` (Mitsuba's default), ``y``, ``diagonal``, ``smaller`` or ``larger``
    (the smaller / larger image side). With ``aspect = width / height``:
    ``tan(vfov/2) = tan(fov/2) / aspect`` for x, ``tan(fov/2) / sqrt(1 + aspect^2)`` for the
    diagonal. Raises ValueError for another axis name.
    """
    aspect = width / height
    axis = fov_axis.lower()
    if axis == "smaller":
        axis = "y" if aspect > 1 else "x"
    elif axis == "larger":
        axis = "x" if aspect > 1 else "y"
    half = math.tan(math.radians(fov) / 2)
    if axis == "x":
        half /= aspect
    elif axis == "diagonal":
        half /= math.sqrt(1.0 + aspect * aspect)
    elif axis != "y":
        raise ValueError(f"fov_axis must be x, y, diagonal, smaller or larger, got {fov_axis!r}")
    return math.degrees(2 * math.atan(half))


def _coordinate_system(n: np.ndarray) -> np.ndarray:
    """First tangent of Mitsuba's ``coordinate_system`` (Duff et al. 2017) for unit ``n``."""
    sign = math.copysign(1.0, n[2])
    a = -1.0 / (sign + n[2])
    return np.array([1.0 + sign * n[0] * n[0] * a, sign * n[0] * n[1] * a, -sign * n[0]])


def _point(matrix: np.ndarray, p) -> np.ndarray:
    return matrix[:3, :3] @ np.asarray(p, dtype=np.float64) + matrix[:3, 3]


def _list(v) -> list[float]:
    return [float(c) for c in v]


def _cube_faces() -> list[np.ndarray]:
    """The six faces of [-1, 1]^3 as 4-vertex loops wound counter-clockwise seen from outside."""
    square = [(-1, -1), (1, -1), (1, 1), (-1, 1)]
    faces = []
    for axis in range(3):
        b, c = (axis + 1) % 3, (axis + 2) % 3  # e_b x e_c = e_axis
        for sign in (1.0, -1.0):
            face = np.zeros((4, 3))
            face[:, axis] = sign
            face[:, b], face[:, c] = zip(*square)
            faces.append(face if sign > 0 else face[::-1])
    return faces


_RECTANGLE = np.array([(-1.0, -1.0, 0.0), (1.0, -1.0, 0.0), (1.0, 1.0, 0.0), (-1.0, 1.0, 0.0)])


class _Plugin:
    """One plugin element's parameters and nested plugins, recording what the conversion reads
    so that `finish` can report the rest (like the TOML loader's tables)."""

    def __init__(self, conv: _Converter, element: _Element):
        self.conv, self.element = conv, element
        self.type = conv.attr(element, "type", "")
        self.params: dict[str, _Element] = {}
        self.nested: list[tuple[str | None, _Element]] = []
        self.used: set[str] = set()  # parameter names read
        self.used_nested: set[int] = set()  # ids of nested elements read
        for child in element.children:
            if child.tag in _VALUE_TAGS:
                self.params[conv.attr(child, "name")] = child
            elif child.tag == "ref":
                self.nested.append((child.attrs.get("name"), conv.resolve(child)))
            elif child.tag in _PLUGIN_TAGS:
                self.nested.append((child.attrs.get("name"), child))
            else:
                conv.warn(child, f"unsupported element inside {element.describe()}: ignored")

    # --- typed parameters -------------------------------------------------------------------
    def _value(self, name: str, tags: tuple[str, ...]) -> _Element | None:
        self.used.add(name)
        element = self.params.get(name)
        if element is not None and element.tag not in tags:
            raise self.conv.error(element, f"parameter '{name}' of {self.element.describe()} must be a <{tags[0]}>")
        if element is None:
            for nested_name, child in self.nested:
                if nested_name == name and child.tag == "texture":
                    self.used_nested.add(id(child))
                    self.conv.warn(
                        child, f"textures are not supported: '{name}' of {self.element.describe()} uses its default"
                    )
        return element

    def has(self, name: str) -> bool:
        return name in self.params

    def number(self, name: str, default, integer: bool = False):
        element = self._value(name, ("integer",) if integer else ("float", "integer"))
        if element is None:
            return default
        text = self.conv.attr(element, "value")
        try:
            return int(text) if integer else float(text)
        except ValueError:
            raise self.conv.error(
                element, f"'{name}' = {text!r} is not {'an integer' if integer else 'a number'}"
            ) from None

    def boolean(self, name: str, default: bool) -> bool:
        element = self._value(name, ("boolean",))
        if element is None:
            return default
        text = self.conv.attr(element, "value").strip().lower()
        if text not in ("true", "false"):
            raise self.conv.error(element, f"'{name}' = {text!r} is not true or false")
        return text == "true"

    def string(self, name: str, default: str | None) -> str | None:
        element = self._value(name, ("string",))
        return default if element is None else self.conv.attr(element, "value")

    def color(self, name: str, default: float) -> list[float]:
        """An RGB parameter given as ``<rgb>``, a constant ``<spectrum>`` or a ``<float>``."""
        element = self._value(name, ("rgb", "spectrum", "float", "integer"))
        if element is None:
            return [float(default)] * 3
        text = self.conv.attr(element, "value", None)
        if element.tag == "spectrum" and (text is None or ":" in text):
            pairs = _SPLIT.split(text.strip()) if text else [f"0:{default}"]
            values = self.conv.floats(element, " ".join(pair.partition(":")[2] for pair in pairs))
            self.conv.warn(
                element, f"spectral data for '{name}' is not supported: using its mean {np.mean(values):.4g}"
            )
            return [float(np.mean(values))] * 3
        values = self.conv.floats(element, text)
        if len(values) not in (1, 3) or (element.tag != "rgb" and len(values) != 1):
            raise self.conv.error(element, f"'{name}' must be one or three numbers")
        return values * 3 if len(values) == 1 else values

    def vector(self, name: str, default) -> np.ndarray:
        element = self._value(name, ("point", "vector"))
        if element is None:
            return np.asarray(default, dtype=np.float64)
        return self.conv.xyz(element, 0.0)

    def ior(self, name: str, default: str) -> float:
        element = self._value(name, ("float", "string", "integer"))
        if element is None:
            return IOR_TABLE[default]
        text = self.conv.attr(element, "value")
        if element.tag != "string":
            return self.number(name, None)
        if text.strip().lower() not in IOR_TABLE:
            raise self.conv.error(element, f"'{name}' = {text!r}: unknown IOR name (known: {', '.join(IOR_TABLE)})")
        return IOR_TABLE[text.strip().lower()]

    def transform(self, name: str = "to_world") -> tuple[np.ndarray, tuple | None]:
        """The 4x4 matrix (identity if absent) and, when the transform is one ``lookat`` and
        nothing else, that lookat's ``(origin, target, up)``."""
        element = self._value(name, ("transform",))
        if element is None:
            return np.eye(4), None
        return self.conv.transform(element)

    def children(self, tag: str) -> list[_Element]:
        """Nested plugin elements (and references) of one kind, in file order."""
        found = [child for _, child in self.nested if child.tag == tag]
        self.used_nested.update(id(child) for child in found)
        return found

    def finish(self) -> None:
        """Warn about every parameter and nested plugin the conversion did not read."""
        harmless = _HARMLESS.get(self.type, ())
        for name, element in self.params.items():
            if name not in self.used and name not in harmless:
                self.conv.warn(element, f"parameter '{name}' of {self.element.describe()} is not supported: ignored")
        for _, child in self.nested:
            if id(child) not in self.used_nested:
                self.conv.warn(child, f"{child.describe()} inside {self.element.describe()} is not supported: ignored")


@dataclass
class _Material:
    """A converted BSDF: its wrt material table and whether Mitsuba shades both of its sides."""

    table: dict
    two_sided: bool

    def reflects(self) -> bool:
        colour = self.table.get("albedo", self.table.get("reflectance", [1.0]))
        return self.table["type"] == "dielectric" or any(c > 0 for c in colour)


_DEFAULT_BSDF = _Material({"type": "diffuse", "albedo": [0.5, 0.5, 0.5]}, False)  # Mitsuba's (one-sided)


class _Converter:
    def __init__(self, path: str, strict: bool, params: dict):
        self.path, self.strict = path, strict
        self.params = {str(k): str(v) for k, v in params.items()}
        self.warnings: list[str] = []
        self.ids: dict[str, _Element] = {}
        self.materials: list[dict] = []
        self.converted: dict[int, _Material] = {}  # by id of the <bsdf> element
        self.material_names: dict[int, str] = {}  # names of those that shapes use
        self.ext_iors: list[tuple[float, _Element]] = []
        self.shapes: list[dict] = []
        self.lights: list[dict] = []

    # --- reporting ----------------------------------------------------------------------------
    def error(self, element: _Element, message: str) -> WrtError:
        return WrtError(f"{self.path}:{element.line}: {element.describe()}: {message}")

    def warn(self, element: _Element, message: str) -> None:
        text = f"{self.path}:{element.line}: {element.describe()}: {message}"
        if self.strict:
            raise WrtError(text + " (strict import)")
        self.warnings.append(text)

    # --- attribute values ---------------------------------------------------------------------
    def attr(self, element: _Element, name: str, default=_REQUIRED):
        if name not in element.attrs:
            if default is _REQUIRED:
                raise self.error(element, f"attribute '{name}' is required")
            return default

        def substitute(match):
            if match.group(1) not in self.params:
                raise self.error(element, f'${match.group(1)} is not defined (no <default name="{match.group(1)}">)')
            return self.params[match.group(1)]

        return _PARAMETER.sub(substitute, element.attrs[name])

    def floats(self, element: _Element, text: str | None) -> list[float]:
        try:
            return [float(t) for t in _SPLIT.split((text or "").strip())]
        except ValueError:
            raise self.error(element, f"{text!r} is not a list of numbers") from None

    def xyz(self, element: _Element, default: float) -> np.ndarray:
        """``x``, ``y``, ``z`` attributes, or ``value`` with one or three numbers."""
        if "value" in element.attrs:
            values = self.floats(element, self.attr(element, "value"))
            if len(values) not in (1, 3):
                raise self.error(element, "value must be one or three numbers")
            return np.array(values * 3 if len(values) == 1 else values)
        return np.array([self.floats(element, self.attr(element, k, str(default)))[0] for k in "xyz"])

    def resolve(self, ref: _Element) -> _Element:
        target = self.ids.get(self.attr(ref, "id"))
        if target is None:
            raise self.error(ref, f"reference to unknown id '{ref.attrs['id']}'")
        return target

    def transform(self, element: _Element) -> tuple[np.ndarray, tuple | None]:
        """Compose a ``<transform>``'s operations in Mitsuba's order: each one is applied after
        those above it (``M = op_n ... op_2 op_1``)."""
        matrix, lookat = np.eye(4), None
        for op in element.children:
            if op.tag == "translate":
                step = np.eye(4)
                step[:3, 3] = self.xyz(op, 0.0)
            elif op.tag == "scale":
                step = np.diag([*self.xyz(op, 1.0), 1.0])
            elif op.tag == "rotate":
                axis = self.xyz(op, 0.0)
                if not np.any(axis):
                    raise self.error(op, "rotation axis is zero")
                step = rotation_matrix(axis, self.floats(op, self.attr(op, "angle"))[0])
            elif op.tag == "matrix":
                values = self.floats(op, self.attr(op, "value"))
                if len(values) not in (9, 16):
                    raise self.error(op, "matrix needs 16 (or 9) numbers, row by row")
                step = np.eye(4)
                n = 4 if len(values) == 16 else 3
                step[:n, :n] = np.reshape(values, (n, n))
            elif op.tag in ("lookat", "look_at"):
                origin, target = (np.array(self.floats(op, self.attr(op, k))) for k in ("origin", "target"))
                up = np.array(self.floats(op, self.attr(op, "up", "0, 0, 0")))
                with np.errstate(invalid="ignore", divide="ignore"):
                    step = look_at_matrix(origin, target, up)
                if not np.all(np.isfinite(step)):
                    raise self.error(op, "invalid lookat (origin = target, or up parallel to the view direction)")
                lookat = (origin, target, up) if len(element.children) == 1 else None
            else:
                raise self.error(op, f"unknown transform operation inside {element.describe()}")
            matrix = step @ matrix
        return matrix, lookat

    # --- the scene ----------------------------------------------------------------------------
    def convert(self, root: _Element) -> tuple[dict, list[str]]:
        if root.tag != "scene":
            raise WrtError(f"{self.path}:{root.line}: the root element is <{root.tag}>, not a Mitsuba <scene>")
        version = root.attrs.get("version", "")
        if not version.split(".")[0].isdigit() or int(version.split(".")[0]) < 2:
            self.warn(root, f"version {version!r}: only Mitsuba 3 scenes (version 2.0 and later names) are converted")
        self._collect_ids(root)
        for child in root.children:
            if child.tag == "default":
                self.params.setdefault(self.attr(child, "name"), self.attr(child, "value"))
        sensors = [c for c in root.children if c.tag == "sensor"]
        integrators = [c for c in root.children if c.tag == "integrator"]
        for extra in sensors[1:] + integrators[1:]:
            self.warn(extra, "only the first sensor and integrator are converted: ignored")
        render, camera = self._sensor(sensors[0] if sensors else _Element("sensor", {"type": "perspective"}, root.line))
        render.update(self._integrator(integrators[0] if integrators else None))
        for child in root.children:
            if child.tag == "shape":
                self._shape(child)
            elif child.tag == "emitter":
                self._emitter(child)
            elif child.tag not in ("default", "sensor", "integrator", "bsdf", "texture"):
                self.warn(child, "not supported: ignored")
        exterior = self._exterior_ior()
        if exterior != 1.0:
            render["exterior_ior"] = exterior
        doc = {
            "render": render,
            "camera": camera,
            "material": self.materials,
            "shape": self.shapes,
            "light": self.lights,
        }
        return doc, self.warnings

    def _collect_ids(self, element: _Element) -> None:
        for child in element.children:
            if "id" in child.attrs and child.tag != "ref":
                self.ids[child.attrs["id"]] = child
            self._collect_ids(child)

    def _sensor(self, element: _Element) -> tuple[dict, dict]:
        p = _Plugin(self, element)
        if p.type not in ("perspective", "thinlens"):
            raise self.error(element, "only perspective and thinlens sensors can be converted")
        films = p.children("film")
        render = self._film(films[0] if films else _Element("film", {"type": "hdrfilm"}, element.line))
        samplers = p.children("sampler")
        render.update(
            self._sampler(samplers[0] if samplers else _Element("sampler", {"type": "independent"}, element.line))
        )

        if p.has("fov") and p.has("focal_length"):
            raise self.error(element, "give either fov or focal_length, not both")
        if p.has("fov"):
            fov, axis = p.number("fov", None), p.string("fov_axis", "x")
        else:  # 35 mm film equivalent focal length -> diagonal fov (Mitsuba's default: 50mm)
            focal = p.string("focal_length", "50mm").strip().removesuffix("mm")
            try:
                fov, axis = math.degrees(2 * math.atan(math.hypot(36.0, 24.0) / (2 * float(focal)))), "diagonal"
            except ValueError:
                raise self.error(element, f"focal_length = {focal!r} is not of the form <x>mm") from None
        try:
            fov = vertical_fov(fov, axis, render["width"], render["height"])
        except ValueError as e:
            raise self.error(element, str(e)) from None

        matrix, lookat = p.transform("to_world")
        camera = self._camera_pose(element, matrix, lookat)
        camera["fov"] = fov
        for name in ("near_clip", "far_clip"):
            if p.has(name):
                self.warn(p.params[name], f"'{name}' is ignored: wrt cameras have no clip planes")
        far_clip = p.number("far_clip", 1e4)
        for name in ("principal_point_offset_x", "principal_point_offset_y"):
            if p.number(name, 0.0) != 0.0:
                self.warn(p.params[name], f"'{name}' is not supported: the principal point stays at the image centre")
        if p.has("shutter_open") or p.has("shutter_close"):
            camera["shutter"] = [p.number("shutter_open", 0.0), p.number("shutter_close", 0.0)]
        if p.type == "thinlens":
            if not p.has("aperture_radius"):
                raise self.error(element, "a thinlens sensor needs aperture_radius")
            camera["aperture_radius"] = p.number("aperture_radius", None)
            camera["focus_distance"] = p.number("focus_distance", far_clip)  # Mitsuba's default: far_clip
        p.finish()
        return render, camera

    def _camera_pose(self, element: _Element, matrix: np.ndarray, lookat) -> dict:
        """origin / look_at / up from a camera-to-world matrix (local +z forward, +y up)."""
        basis = matrix[:3, :3]
        norms = np.linalg.norm(basis, axis=0)
        if np.any(np.abs(norms - 1.0) > 1e-4):
            self.warn(element, "the to_world transform scales (Mitsuba refuses this): its scale is dropped")
        if np.linalg.det(basis) < 0:
            self.warn(
                element, "the to_world transform mirrors the image (negative determinant): wrt renders it unmirrored"
            )
        if lookat is not None:
            origin, target, up = lookat
            up = up if np.any(up) else matrix[:3, 1]
            return {"origin": _list(origin), "look_at": _list(target), "up": _list(up)}
        origin = matrix[:3, 3]
        return {
            "origin": _list(origin),
            "look_at": _list(origin + basis[:, 2] / norms[2]),
            "up": _list(basis[:, 1] / norms[1]),
        }

    def _film(self, element: _Element) -> dict:
        p = _Plugin(self, element)
        if p.type != "hdrfilm":
            self.warn(element, "converted as an hdrfilm")
        render = {"width": p.number("width", 768, integer=True), "height": p.number("height", 576, integer=True)}
        if render["width"] < 1 or render["height"] < 1:
            raise self.error(element, "width and height must be positive")
        for name in ("crop_offset_x", "crop_offset_y", "crop_width", "crop_height"):
            if p.has(name):
                self.warn(p.params[name], "crop windows are not supported: the whole film is rendered")
                p.number(name, 0, integer=True)
        if p.boolean("sample_border", False):
            self.warn(p.params["sample_border"], "'sample_border' is not supported")
        filters = p.children("rfilter")
        render["filter"] = self._filter(filters[0]) if filters else "gaussian"  # Mitsuba's default
        p.finish()
        return render

    def _filter(self, element: _Element) -> str:
        p = _Plugin(self, element)
        if p.type not in FILTERS:
            self.warn(element, "filter not supported: converted as gaussian (Mitsuba's default)")
            return "gaussian"
        width_name, width = FILTERS[p.type]
        if p.number(width_name, width) != width:
            self.warn(p.params[width_name], f"wrt's {p.type} filter has {width_name} {width:g} pixels: value ignored")
        p.finish()
        return p.type

    def _sampler(self, element: _Element) -> dict:
        p = _Plugin(self, element)
        count = p.number("sample_count", 4, integer=True)
        if count < 1:
            raise self.error(element, "sample_count must be positive")
        if p.type not in SAMPLERS:
            self.warn(element, "sampler not supported: converted as independent")
        if p.type == "stratified":
            count = math.ceil(math.sqrt(count)) ** 2  # Mitsuba rounds up to a square
            if not p.boolean("jitter", True):
                self.warn(
                    p.params["jitter"], "jitter = false (pixel-grid samples) is not supported: samples are jittered"
                )
        render = {
            "spp": count,
            "seed": p.number("seed", 0, integer=True),
            "sampler": SAMPLERS.get(p.type, "independent"),
        }
        p.finish()
        return render

    def _integrator(self, element: _Element | None) -> dict:
        if element is None:
            return {"integrator": "path", "max_depth": MAX_DEPTH}
        p = _Plugin(self, element)
        if p.type not in ("path", "volpath"):
            self.warn(element, "integrator not supported: converted as path")
            return {"integrator": "path", "max_depth": MAX_DEPTH}
        depth = p.number("max_depth", -1, integer=True)
        if p.boolean("hide_emitters", False):
            self.warn(p.params["hide_emitters"], "hide_emitters is not supported: emitters stay visible")
        if depth == 0:
            self.warn(p.params["max_depth"], "max_depth = 0 (a black image) becomes 1")
        p.finish()
        return {"integrator": "path", "max_depth": MAX_DEPTH if depth < 0 else min(max(depth, 1), MAX_DEPTH)}

    # --- materials ----------------------------------------------------------------------------
    def _converted(self, element: _Element) -> _Material:
        """A BSDF element converted once, however often it is referenced."""
        if id(element) not in self.converted:
            self.converted[id(element)] = self._bsdf(element)
        return self.converted[id(element)]

    def _material_name(self, element: _Element) -> str:
        """The name of a BSDF's wrt material, added to ``[[material]]`` when first used."""
        if id(element) not in self.material_names:
            material = self._converted(element)
            name = self._unique(element.attrs.get("id") or f"{material.table['type']}@{element.line}")
            self.materials.append({"name": name, **material.table})
            self.material_names[id(element)] = name
        return self.material_names[id(element)]

    def _unique(self, base: str) -> str:
        names = {m["name"] for m in self.materials}
        name, n = base, 2
        while name in names or name == "default":
            name, n = f"{base}_{n}", n + 1
        return name

    def _bsdf(self, element: _Element) -> _Material:
        if element.tag != "bsdf":
            raise self.error(element, "is not a <bsdf>")
        p = _Plugin(self, element)
        if p.type == "twosided":
            inner = p.children("bsdf")
            if not inner:
                raise self.error(element, "a twosided BSDF needs a nested <bsdf>")
            if len(inner) > 1 and inner[1] is not inner[0]:
                self.warn(inner[1], "a different BSDF on the back side is not supported: both sides use the first")
            p.finish()
            return _Material(self._bsdf(inner[0]).table, True)
        if p.type == "diffuse":
            material = _Material({"type": "diffuse", "albedo": p.color("reflectance", 0.5)}, False)
        elif p.type == "conductor":
            material = _Material({"type": "mirror", "reflectance": self._conductor_reflectance(p)}, False)
        elif p.type == "roughconductor":
            roughness = self._alpha(p)
            material = _Material(
                {"type": "glossy", "roughness": roughness, "reflectance": self._conductor_reflectance(p)}, False
            )
        elif p.type == "dielectric":
            interior, exterior = p.ior("int_ior", "bk7"), p.ior("ext_ior", "air")
            for name in ("specular_reflectance", "specular_transmittance"):
                if p.color(name, 1.0) != [1.0, 1.0, 1.0]:
                    self.warn(p.params[name], f"'{name}' (a non-physical scale) is not supported: ignored")
            self.ext_iors.append((exterior, element))
            material = _Material({"type": "dielectric", "ior": interior}, True)
        else:
            return self._closest_bsdf(p)
        p.finish()
        return material

    def _closest_bsdf(self, p: _Plugin) -> _Material:
        """An unsupported BSDF: its nearest wrt material, with a warning saying which."""
        nested = p.children("bsdf")
        if p.type in ("bumpmap", "normalmap", "mask") and nested:
            self.warn(p.element, "not supported: the nested BSDF is used without it")
            return self._bsdf(nested[0])
        if p.type in ("plastic", "roughplastic", "principled"):
            albedo = p.color("base_color" if p.type == "principled" else "diffuse_reflectance", 0.5)
            self.warn(p.element, f"not supported: converted as diffuse, albedo {albedo}")
            return _Material({"type": "diffuse", "albedo": albedo}, False)
        if p.type == "roughdielectric":
            self.warn(p.element, "roughness is not supported: converted as a smooth dielectric")
            self.ext_iors.append((p.ior("ext_ior", "air"), p.element))
            return _Material({"type": "dielectric", "ior": p.ior("int_ior", "bk7")}, True)
        self.warn(p.element, "not supported: converted as diffuse 0.5 (Mitsuba's default BSDF)")
        return _Material({"type": "diffuse", "albedo": [0.5, 0.5, 0.5]}, False)

    def _alpha(self, p: _Plugin) -> float:
        distribution = p.string("distribution", "beckmann")
        if distribution != "ggx":
            self.warn(
                p.params.get("distribution", p.element),
                f"distribution '{distribution}' is converted as GGX with the same alpha",
            )
        if p.has("alpha_u") or p.has("alpha_v"):
            alpha_u, alpha_v = p.number("alpha_u", 0.1), p.number("alpha_v", 0.1)
            if alpha_u != alpha_v:
                self.warn(
                    p.element,
                    "anisotropic roughness is not supported: "
                    f"alpha = {math.sqrt(alpha_u * alpha_v):.4g} (geometric mean)",
                )
            return math.sqrt(alpha_u * alpha_v)
        return p.number("alpha", 0.1)

    def _conductor_reflectance(self, p: _Plugin) -> list[float]:
        """Reflectance of a (rough) conductor: exact for material "none" (Mitsuba's default, F = 1),
        the normal-incidence Fresnel reflectance otherwise (with a warning)."""
        scale = p.color("specular_reflectance", 1.0)
        if p.has("eta") or p.has("k"):
            eta, k = np.array(p.color("eta", 0.0)), np.array(p.color("k", 1.0))
            f0 = ((eta - 1) ** 2 + k**2) / ((eta + 1) ** 2 + k**2)
            source = "eta, k"
        else:
            name = p.string("material", "none")
            if name == "none":
                return scale
            known = CONDUCTOR_F0.get(name, CONDUCTOR_F0.get(name.removesuffix("_palik")))
            if known is None:
                known = ", ".join(["none", *CONDUCTOR_F0])
                raise self.error(p.element, f"unknown conductor material {name!r} (known: {known}, and <name>_palik)")
            f0, source = np.array(known), f"material '{name}'"
        reflectance = _list(np.clip(f0 * scale, 0.0, 1.0))
        self.warn(
            p.element,
            f"{source}: angle-dependent Fresnel approximated by its normal-incidence value "
            f"{[round(c, 4) for c in reflectance]}",
        )
        return reflectance

    def _exterior_ior(self) -> float:
        """[render] exterior_ior: the ext_ior of the dielectrics (the most common one, with a
        warning for those that differ; wrt takes a nested dielectric's outside from its nesting)."""
        if not self.ext_iors:
            return 1.0
        chosen = Counter(v for v, _ in self.ext_iors).most_common(1)[0][0]
        for value, element in self.ext_iors:
            if value != chosen:
                self.warn(
                    element,
                    f"ext_ior {value:g} differs from the scene's exterior_ior {chosen:g}: wrt takes the medium "
                    "outside a dielectric from the dielectric enclosing it, or [render] exterior_ior",
                )
        return chosen

    # --- shapes and emitters ------------------------------------------------------------------
    def _shape(self, element: _Element) -> None:
        p = _Plugin(self, element)
        matrix, _ = p.transform("to_world")
        bsdfs, emitters = p.children("bsdf"), p.children("emitter")
        for extra in bsdfs[1:] + emitters[1:]:
            self.warn(extra, "a shape takes one BSDF and one emitter: ignored")
        front = -1.0 if p.boolean("flip_normals", False) else 1.0
        mirrored = np.linalg.det(matrix[:3, :3]) * front < 0  # winding must be reversed to keep Mitsuba's front

        if p.type == "sphere":
            placed = matrix @ np.diag([*(p.number("radius", 1.0),) * 3, 1.0])
            placed[:3, 3] = _point(matrix, p.vector("center", (0.0, 0.0, 0.0)))
            scales = np.linalg.svd(placed[:3, :3], compute_uv=False)
            if scales.max() - scales.min() > 1e-6 * scales.max():
                self.warn(element, "non-uniform scale: the radius is the to_world x axis scale (as in Mitsuba)")
            if front < 0:
                self.warn(p.params["flip_normals"], "flip_normals on a sphere is not supported: normals point outward")
            geometry = {
                "type": "sphere",
                "center": _list(placed[:3, 3]),
                "radius": float(np.linalg.norm(placed[:3, 0])),
            }
            tables = [geometry]
        elif p.type in ("rectangle", "cube"):
            loops = [_RECTANGLE] if p.type == "rectangle" else _cube_faces()
            loops = [loop[::-1] if mirrored else loop for loop in loops]
            tables = [{"type": "polygon", "vertices": [_list(_point(matrix, v)) for v in loop]} for loop in loops]
        elif p.type in ("obj", "ply"):
            tables = [self._mesh(p, matrix)]
        else:
            self.warn(element, "shape type not supported: ignored")
            return
        material = self._converted(bsdfs[0]) if bsdfs else _DEFAULT_BSDF

        if emitters:
            radiance = self._area_radiance(emitters[0])
            if p.type in ("rectangle", "sphere"):
                if material.reflects():
                    self.warn(
                        bsdfs[0] if bsdfs else element,
                        "wrt's area lights reflect no light, but this emitter's "
                        "BSDF reflects in Mitsuba (set its reflectance to 0 to compare)",
                    )
                self.lights.append(self._surface_light(tables[0], radiance))
                p.finish()
                return
            self.warn(emitters[0], "an area emitter on this shape becomes emission of its material (front side only)")
            base = bsdfs[0].attrs.get("id", material.table["type"]) if bsdfs else "default"
            name = self._unique(f"{base}+emission@{emitters[0].line}")
            self.materials.append({"name": name, **material.table, "emission": radiance})
        else:
            if p.type in ("rectangle", "obj", "ply") and not material.two_sided:
                self.warn(
                    bsdfs[0] if bsdfs else element,
                    "one-sided BSDF on an open surface: Mitsuba renders its back black, "
                    "wrt shades both sides (wrap it in a twosided BSDF to compare)",
                )
            name = self._material_name(bsdfs[0]) if bsdfs else None
        for table in tables:
            self.shapes.append({**table, "material": name} if name else table)
        p.finish()

    def _mesh(self, p: _Plugin, matrix: np.ndarray) -> dict:
        filename = p.string("filename", None)
        if filename is None:
            raise self.error(p.element, "a mesh needs a filename")
        if p.boolean("flip_normals", False):
            self.warn(p.params["flip_normals"], "flip_normals on a mesh is not supported: the file's winding is kept")
        if np.linalg.det(matrix[:3, :3]) < 0:
            self.warn(
                p.element,
                "the to_world transform mirrors the mesh: wrt's front side follows the mirrored winding, "
                "Mitsuba's shading normals do not",
            )
        face_normals = p.boolean("face_normals", False)
        if not face_normals and _has_vertex_normals(os.path.join(os.path.dirname(self.path), filename)):
            self.warn(
                p.element,
                "Mitsuba interpolates this file's vertex normals, wrt shades with face normals "
                "(set face_normals = true to compare)",
            )
        table = {"type": "mesh", "file": filename}
        if not np.array_equal(matrix, np.eye(4)):
            table["transform"] = {"matrix": [_list(row) for row in matrix]}
        return table

    def _area_radiance(self, element: _Element) -> list[float]:
        p = _Plugin(self, element)
        if p.type != "area":
            self.warn(element, "only area emitters can be attached to shapes: converted as area")
        radiance = p.color("radiance", 1.0)
        p.finish()
        return radiance

    @staticmethod
    def _surface_light(geometry: dict, radiance: list[float]) -> dict:
        """An area light from a converted rectangle polygon (its winding already gives Mitsuba's
        front side) or a sphere light from a sphere."""
        if geometry["type"] == "sphere":
            return {"type": "sphere", "center": geometry["center"], "radius": geometry["radius"], "radiance": radiance}
        v = np.array(geometry["vertices"])
        edge_u, edge_v = v[1] - v[0], v[3] - v[0]
        return {
            "type": "area",
            "corner": _list(v[0]),
            "edge_u": _list(edge_u),
            "edge_v": _list(edge_v),
            "radiance": radiance,
        }

    def _emitter(self, element: _Element) -> None:
        p = _Plugin(self, element)
        matrix, _ = p.transform("to_world")
        if p.type == "point":
            position = p.vector("position", matrix[:3, 3])
            self.lights.append({"type": "point", "position": _list(position), "intensity": p.color("intensity", 1.0)})
        elif p.type == "spot":
            cutoff = p.number("cutoff_angle", 20.0)
            self.lights.append(
                {
                    "type": "spot",
                    "position": _list(matrix[:3, 3]),
                    "direction": _list(matrix[:3, 2]),
                    "intensity": p.color("intensity", 1.0),
                    "cutoff_angle": cutoff,
                    "beam_width": p.number("beam_width", 0.75 * cutoff),
                }
            )
        elif p.type == "directional":
            direction = p.vector("direction", matrix[:3, 2])
            irradiance = p.color("irradiance", 1.0)
            self.lights.append({"type": "directional", "direction": _list(direction), "irradiance": irradiance})
        elif p.type == "constant":
            self.lights.append({"type": "environment", "radiance": p.color("radiance", 1.0)})
        else:
            self.warn(element, "emitter type not supported: ignored")
            return
        p.finish()


def _has_vertex_normals(path: str) -> bool:
    """Whether an OBJ (``vn`` lines) or PLY (``nx`` vertex property) file stores vertex normals;
    False for a file that cannot be read (the scene loader reports it)."""
    try:
        with open(path, "rb") as f:
            if path.lower().endswith(".obj"):
                return any(line.startswith(b"vn ") for line in f)
            for line in f:
                if line.strip() == b"end_header":
                    return False
                if line.startswith(b"property") and line.split()[-1] == b"nx":
                    return True
    except OSError:
        pass
    return False
