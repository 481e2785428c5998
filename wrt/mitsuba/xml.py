"""Reading a Mitsuba 3 scene file: its elements with their lines, ``$name`` parameters and
``<ref>`` ids, typed plugin parameters, transforms, and the reporting every converter uses.

A ``Document`` is one file being read: it resolves attribute values (``<default>`` parameters,
``params`` given by the caller), references and transforms, and collects the warnings (or, when
``strict``, raises them). A ``Plugin`` is one plugin element's parameters and nested plugins; it
records which ones a converter read so that ``finish`` can report the rest.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from xml.parsers import expat

import numpy as np

from ..errors import WrtError
from .transforms import look_at_matrix, rotation_matrix

VALUE_TAGS = ("float", "integer", "boolean", "string", "rgb", "spectrum", "point", "vector", "transform")
PLUGIN_TAGS = (
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
HARMLESS = {
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
class Element:
    """One XML element with the line it starts on (``xml.etree`` keeps no line numbers)."""

    tag: str
    attrs: dict
    line: int
    children: list = field(default_factory=list)

    def describe(self) -> str:
        shown = " ".join(f'{k}="{self.attrs[k]}"' for k in ("type", "name", "id") if k in self.attrs)
        return f"<{self.tag}{' ' + shown if shown else ''}>"


def read_xml(path: str) -> Element:
    """The root element of the XML file ``path`` (``WrtError`` naming the file, line and column)."""
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError as e:
        raise WrtError(f"{path}: cannot read Mitsuba scene ({e.strerror})") from None
    parser = expat.ParserCreate()
    stack: list[Element] = []
    roots: list[Element] = []

    def start(tag, attrs):
        element = Element(tag, attrs, parser.CurrentLineNumber)
        (stack[-1].children if stack else roots).append(element)
        stack.append(element)

    parser.StartElementHandler = start
    parser.EndElementHandler = lambda tag: stack.pop()
    try:
        parser.Parse(data, True)
    except expat.ExpatError as e:
        raise WrtError(f"{path}:{e.lineno}:{e.offset + 1}: malformed XML: {expat.ErrorString(e.code)}") from None
    return roots[0]


class Document:
    """One Mitsuba scene file being read: attribute values, references, transforms and reports."""

    def __init__(self, path: str, strict: bool, params: dict):
        self.path, self.strict = path, strict
        self.params = {str(k): str(v) for k, v in params.items()}
        self.warnings: list[str] = []
        self.ids: dict[str, Element] = {}

    # --- reporting ----------------------------------------------------------------------------
    def error(self, element: Element, message: str) -> WrtError:
        return WrtError(f"{self.path}:{element.line}: {element.describe()}: {message}")

    def warn(self, element: Element, message: str) -> None:
        text = f"{self.path}:{element.line}: {element.describe()}: {message}"
        if self.strict:
            raise WrtError(text + " (strict import)")
        self.warnings.append(text)

    # --- the file's ids and defaults ----------------------------------------------------------
    def index(self, root: Element) -> None:
        """Record every element's ``id`` and the root's ``<default>`` parameters (the caller's
        ``params`` take precedence)."""
        self._collect_ids(root)
        for child in root.children:
            if child.tag == "default":
                self.params.setdefault(self.attr(child, "name"), self.attr(child, "value"))

    def _collect_ids(self, element: Element) -> None:
        for child in element.children:
            if "id" in child.attrs and child.tag != "ref":
                self.ids[child.attrs["id"]] = child
            self._collect_ids(child)

    # --- attribute values ---------------------------------------------------------------------
    def attr(self, element: Element, name: str, default=_REQUIRED):
        if name not in element.attrs:
            if default is _REQUIRED:
                raise self.error(element, f"attribute '{name}' is required")
            return default

        def substitute(match):
            if match.group(1) not in self.params:
                raise self.error(element, f'${match.group(1)} is not defined (no <default name="{match.group(1)}">)')
            return self.params[match.group(1)]

        return _PARAMETER.sub(substitute, element.attrs[name])

    def floats(self, element: Element, text: str | None) -> list[float]:
        try:
            return [float(t) for t in _SPLIT.split((text or "").strip())]
        except ValueError:
            raise self.error(element, f"{text!r} is not a list of numbers") from None

    def xyz(self, element: Element, default: float) -> np.ndarray:
        """``x``, ``y``, ``z`` attributes, or ``value`` with one or three numbers."""
        if "value" in element.attrs:
            values = self.floats(element, self.attr(element, "value"))
            if len(values) not in (1, 3):
                raise self.error(element, "value must be one or three numbers")
            return np.array(values * 3 if len(values) == 1 else values)
        return np.array([self.floats(element, self.attr(element, k, str(default)))[0] for k in "xyz"])

    def resolve(self, ref: Element) -> Element:
        target = self.ids.get(self.attr(ref, "id"))
        if target is None:
            raise self.error(ref, f"reference to unknown id '{ref.attrs['id']}'")
        return target

    def transform(self, element: Element) -> tuple[np.ndarray, tuple | None]:
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


class Plugin:
    """One plugin element's parameters and nested plugins, recording what the conversion reads
    so that `finish` can report the rest (like the TOML loader's tables)."""

    def __init__(self, doc: Document, element: Element):
        self.doc, self.element = doc, element
        self.type = doc.attr(element, "type", "")
        self.params: dict[str, Element] = {}
        self.nested: list[tuple[str | None, Element]] = []
        self.used: set[str] = set()  # parameter names read
        self.used_nested: set[int] = set()  # ids of nested elements read
        for child in element.children:
            if child.tag in VALUE_TAGS:
                self.params[doc.attr(child, "name")] = child
            elif child.tag == "ref":
                self.nested.append((child.attrs.get("name"), doc.resolve(child)))
            elif child.tag in PLUGIN_TAGS:
                self.nested.append((child.attrs.get("name"), child))
            else:
                doc.warn(child, f"unsupported element inside {element.describe()}: ignored")

    # --- typed parameters -------------------------------------------------------------------
    def value(self, name: str, tags: tuple[str, ...]) -> Element | None:
        """The element of parameter ``name`` (None if absent), which must be one of ``tags``."""
        self.used.add(name)
        element = self.params.get(name)
        if element is not None and element.tag not in tags:
            raise self.doc.error(element, f"parameter '{name}' of {self.element.describe()} must be a <{tags[0]}>")
        if element is None:
            for nested_name, child in self.nested:
                if nested_name == name and child.tag == "texture":
                    self.used_nested.add(id(child))
                    self.doc.warn(
                        child, f"textures are not supported: '{name}' of {self.element.describe()} uses its default"
                    )
        return element

    def has(self, name: str) -> bool:
        return name in self.params

    def number(self, name: str, default, integer: bool = False):
        element = self.value(name, ("integer",) if integer else ("float", "integer"))
        if element is None:
            return default
        text = self.doc.attr(element, "value")
        try:
            return int(text) if integer else float(text)
        except ValueError:
            raise self.doc.error(
                element, f"'{name}' = {text!r} is not {'an integer' if integer else 'a number'}"
            ) from None

    def boolean(self, name: str, default: bool) -> bool:
        element = self.value(name, ("boolean",))
        if element is None:
            return default
        text = self.doc.attr(element, "value").strip().lower()
        if text not in ("true", "false"):
            raise self.doc.error(element, f"'{name}' = {text!r} is not true or false")
        return text == "true"

    def string(self, name: str, default: str | None) -> str | None:
        element = self.value(name, ("string",))
        return default if element is None else self.doc.attr(element, "value")

    def color(self, name: str, default: float) -> list[float]:
        """An RGB parameter given as ``<rgb>``, a constant ``<spectrum>`` or a ``<float>``."""
        element = self.value(name, ("rgb", "spectrum", "float", "integer"))
        if element is None:
            return [float(default)] * 3
        text = self.doc.attr(element, "value", None)
        if element.tag == "spectrum" and (text is None or ":" in text):
            pairs = _SPLIT.split(text.strip()) if text else [f"0:{default}"]
            values = self.doc.floats(element, " ".join(pair.partition(":")[2] for pair in pairs))
            self.doc.warn(element, f"spectral data for '{name}' is not supported: using its mean {np.mean(values):.4g}")
            return [float(np.mean(values))] * 3
        values = self.doc.floats(element, text)
        if len(values) not in (1, 3) or (element.tag != "rgb" and len(values) != 1):
            raise self.doc.error(element, f"'{name}' must be one or three numbers")
        return values * 3 if len(values) == 1 else values

    def vector(self, name: str, default) -> np.ndarray:
        element = self.value(name, ("point", "vector"))
        if element is None:
            return np.asarray(default, dtype=np.float64)
        return self.doc.xyz(element, 0.0)

    def transform(self, name: str = "to_world") -> tuple[np.ndarray, tuple | None]:
        """The 4x4 matrix (identity if absent) and, when the transform is one ``lookat`` and
        nothing else, that lookat's ``(origin, target, up)``."""
        element = self.value(name, ("transform",))
        if element is None:
            return np.eye(4), None
        return self.doc.transform(element)

    def children(self, tag: str) -> list[Element]:
        """Nested plugin elements (and references) of one kind, in file order."""
        found = [child for _, child in self.nested if child.tag == tag]
        self.used_nested.update(id(child) for child in found)
        return found

    def finish(self) -> None:
        """Warn about every parameter and nested plugin the conversion did not read."""
        harmless = HARMLESS.get(self.type, ())
        for name, element in self.params.items():
            if name not in self.used and name not in harmless:
                self.doc.warn(element, f"parameter '{name}' of {self.element.describe()} is not supported: ignored")
        for _, child in self.nested:
            if id(child) not in self.used_nested:
                self.doc.warn(child, f"{child.describe()} inside {self.element.describe()} is not supported: ignored")
