"""Reading a Mitsuba 3 scene file: its elements with their lines, ``$name`` parameters and
``<ref>`` ids, typed plugin parameters, transforms, and the reporting every converter uses.

A ``Document`` is one scene being read: it splices ``<include>``d files in place, keeps the
``<path>`` folders files are searched in, resolves attribute values (``<default>`` parameters,
``params`` given by the caller), references and transforms, and refuses approximations (or, when
read with ``approximate``, records them). Every element remembers its file and line, so messages name the
fragment a problem is in. A ``Plugin`` is one plugin element's parameters and nested plugins; it
records which ones a converter read so that ``finish`` can report the rest.

What Mitsuba's parser refuses, wrt refuses too, before converting anything: an element Mitsuba
does not know, an attribute an element does not take or a required one missing (``ATTRIBUTES``),
a transform operation outside a ``<transform>``, an element inside a property, a ``<path>``
that is not a child of its file's root or names no folder, a parameter given twice. Every file
is read by ``wrt.files.read_bytes`` (a regular file of at most ``MAX_TEXT_BYTES``), and a scene
with its includes expanded holds at most ``MAX_ELEMENTS`` elements, checked before the
expansion is built. Messages quote the file's values by ``wrt.errors.token`` (at most
``MAX_QUOTED`` characters of them).
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field
from xml.parsers import expat

import numpy as np

from ..errors import MAX_LISTED, WrtError, shorten, token
from ..files import MAX_TEXT_BYTES, read_bytes
from . import spectra
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
OBJECT_TAGS = (*PLUGIN_TAGS, "field", "scene")
"""Mitsuba's object elements: they take a ``type`` (the scene: a ``version``), an ``id`` and a ``name``."""
TRANSFORM_OPERATIONS = ("translate", "rotate", "scale", "lookat", "matrix")
ATTRIBUTES = {
    **{tag: ("!name", "!value") for tag in ("float", "integer", "boolean", "string", "rgb")},
    "point": ("!name", "x", "y", "z", "value"),
    "vector": ("!name", "x", "y", "z", "value"),
    "spectrum": ("!name", "value", "filename"),
    "transform": ("!name",),
    "translate": ("x", "y", "z", "value"),
    "scale": ("x", "y", "z", "value"),
    "rotate": ("!angle", "x", "y", "z", "value"),
    "lookat": ("!origin", "!target", "up"),
    "matrix": ("!value",),
    "ref": ("!id", "name"),
    "include": ("!filename", "name"),
    "alias": ("!id", "!as"),
    "default": ("!name", "!value"),
    "path": ("!value",),
}
"""The attributes each element of Mitsuba 3's scene format takes (its parser, ``src/core/parser.cpp``),
``!`` marking the required ones; object elements (``OBJECT_TAGS``) take ``!type``, ``id`` and ``name``.
A ``value`` of a point, vector, translation, scale or rotation stands for its ``x``, ``y`` and ``z``
(a point and a vector need all three): it is given without them."""
_XYZ_TAGS = ("point", "vector", "translate", "scale", "rotate")
HARMLESS = {
    "hdrfilm": ("file_format", "pixel_format", "component_format", "compensate"),
    "path": ("rr_depth",),
    "volpath": ("rr_depth",),
    "volpathmis": ("rr_depth",),
    "roughconductor": ("sample_visible",),
    "obj": ("flip_tex_coords",),
    "ply": ("flip_tex_coords",),
}
"""Parameters read without conversion because they change only the noise or the output file."""

MAX_NESTING = 100
"""Deepest element nesting read (a real scene nests a handful deep); deeper is an error."""

MAX_INCLUDES = 32
"""Deepest chain of ``<include>``d files (a loop is refused before it gets there)."""

MAX_ELEMENTS = 1_000_000
"""Most elements a scene holds, its included files expanded. Real scenes hold tens to
thousands (the largest example and Mitsuba-suite scene here, 71); a million is some 100,000
shapes. More is refused, before the expansion is built: an include bomb (fragments that each
include the next one ten times) would otherwise grow tenfold per fragment."""

_REQUIRED = object()
_PARAMETER = re.compile(r"\$([A-Za-z_][A-Za-z0-9_]*)")
_SPLIT = re.compile(r"[\s,]+")
_DECIMAL = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_INTEGER = re.compile(r"[+-]?[0-9]+")
_VERSION_PART = re.compile(r"\s*[+-]?[0-9]")
_NON_FINITE = ("nan", "inf", "infinity")
_SINGULAR = 1e-12
"""A 3x3 transform is singular when its smallest singular value is below this fraction of its largest."""


def parse_number(text: str, integer: bool = False):
    """One number of a scene file: a decimal (``-1``, ``.5``, ``2.5e-3``) or, with ``integer``, a
    whole number within int64, surrounding spaces allowed.

    Every number of a Mitsuba file goes through here. Raises ValueError, whose message completes
    "'name' = 'text' ...": NaN and infinities (``nan``, ``inf``, ``1e999``) are "not finite";
    other spellings Python would take (``1_0``, ``0x10``) are "not a number".
    """
    word = text.strip()
    if integer:
        if not _INTEGER.fullmatch(word):
            raise ValueError("is not an integer")
        if len(word.lstrip("+-")) > 18:
            raise ValueError("is out of range (integers are at most 18 digits)")
        return int(word)
    if not _DECIMAL.fullmatch(word):
        raise ValueError("is not finite" if word.lower().lstrip("+-") in _NON_FINITE else "is not a number")
    value = float(word)
    if not math.isfinite(value):
        raise ValueError("is not finite (beyond the float64 range)")
    return value


@dataclass(eq=False)
class Element:
    """One XML element with the line it starts on (``xml.etree`` keeps no line numbers)."""

    tag: str
    attrs: dict
    line: int
    children: list = field(default_factory=list)
    file: str = ""  # the file it was read from (an <include>d fragment, or the scene)

    def describe(self) -> str:
        """``<tag type="..." name="..." id="...">`` as a message names it, each value cut by
        ``wrt.errors.shorten`` (they are the file's)."""
        shown = " ".join(f'{k}="{shorten(self.attrs[k])}"' for k in ("type", "name", "id") if k in self.attrs)
        return f"<{shorten(self.tag)}{' ' + shown if shown else ''}>"

    def copy(self) -> Element:
        """A copy of the element and of everything inside it, each a new object (an included
        fragment's elements are shared by every place it is included until copied)."""
        top = Element(self.tag, self.attrs, self.line, list(self.children), self.file)
        pending = [top]
        while pending:
            element = pending.pop()
            element.children = [Element(c.tag, c.attrs, c.line, list(c.children), c.file) for c in element.children]
            pending.extend(element.children)
        return top


def read_xml(path: str) -> Element:
    """The root element of the XML file ``path`` (``WrtError`` naming the file, line and column).

    The file is read by ``wrt.files.read_bytes``: a regular file (no FIFO, device or folder) of at
    most ``MAX_TEXT_BYTES``. Elements nested more than ``MAX_NESTING`` deep, and more than
    ``MAX_ELEMENTS`` elements, are refused (every later step may then recurse safely), and so is
    what Mitsuba's parser refuses (`check_elements`). Expat expands no external entity and
    refuses entity expansion that amplifies the input beyond its limits ("billion laughs"), both
    as malformed XML.
    """
    if not os.path.lexists(path):
        raise WrtError(f"{path}: cannot read Mitsuba scene (no such file)")
    data = read_bytes(path, "Mitsuba scene", limit=MAX_TEXT_BYTES)
    parser = expat.ParserCreate()
    stack: list[Element] = []
    roots: list[Element] = []
    count = 0

    def start(tag, attrs):
        nonlocal count
        count += 1
        where = f"{path}:{parser.CurrentLineNumber}: <{shorten(tag)}>"
        if len(stack) >= MAX_NESTING:
            raise WrtError(f"{where} is nested more than {MAX_NESTING} elements deep")
        if count > MAX_ELEMENTS:
            raise WrtError(f"{where}: the file holds more than the {MAX_ELEMENTS} elements wrt reads")
        element = Element(tag, attrs, parser.CurrentLineNumber, file=path)
        (stack[-1].children if stack else roots).append(element)
        stack.append(element)

    parser.StartElementHandler = start
    parser.EndElementHandler = lambda tag: stack.pop()
    try:
        parser.Parse(data, True)
    except expat.ExpatError as e:
        raise WrtError(f"{path}:{e.lineno}:{e.offset + 1}: malformed XML: {expat.ErrorString(e.code)}") from None
    check_elements(roots[0])
    return roots[0]


def check_elements(root: Element) -> None:
    """Refuse, as Mitsuba's parser does, an element of the file ``root`` is the root of that
    Mitsuba does not know, an attribute it does not take or a required one it lacks
    (``ATTRIBUTES``), ``value`` with ``x``, ``y`` or ``z``, a transform operation outside a
    ``<transform>`` or anything else inside one, an element inside a property (``<float>``,
    ``<ref>``, ``<include>``, ...), and a ``<path>`` that is not a child of the root. The root
    needs a version of three numbers (``3.0.0``)."""
    pending = [(root, None)]
    while pending:
        element, parent = pending.pop()
        tag, attrs = element.tag, element.attrs

        def refuse(problem):
            return WrtError(f"{element.file}:{element.line}: {element.describe()}: {problem}")

        is_object = tag in OBJECT_TAGS or (tag == "spectrum" and "type" in attrs)
        if tag == "animation":
            raise refuse(
                "an animated transform (keyframes over the shutter): not supported (shapes move by a velocity)"
            )
        if not is_object and tag not in ATTRIBUTES:
            raise refuse("not an element of Mitsuba's scene format")
        if parent is None:
            if not is_object:
                raise refuse("the root element must be a Mitsuba object (a <scene>)")
            expected = ("!version", "type", "id", "name")
        else:
            expected = ("!type", "id", "name") if is_object else ATTRIBUTES[tag]
        allowed = [name.lstrip("!") for name in expected]
        for name in attrs:
            if name not in allowed:
                takes = ", ".join(allowed) or "no attribute"
                raise refuse(f"unexpected attribute {token(name)} (a <{shorten(tag)}> takes {takes})")
        xyz = tag in _XYZ_TAGS and "value" in attrs
        for name in expected:
            if name.startswith("!") and name[1:] not in attrs:
                raise refuse(f"the attribute '{name[1:]}' is required")
        if xyz and any(axis in attrs for axis in "xyz"):
            raise refuse("'value' is given with 'x', 'y' or 'z' (Mitsuba takes one or the other)")
        if tag in ("point", "vector") and not xyz:
            missing = [axis for axis in "xyz" if axis not in attrs]
            if missing:
                raise refuse(f"the attribute '{missing[0]}' is required (or a 'value')")
        if parent is None:
            parts = [part for part in re.split("[ .]", attrs.get("version", "")) if part]
            if len(parts) != 3 or not all(_VERSION_PART.match(part) for part in parts):
                raise refuse(f"version {token(attrs['version'])} is not a version number (major.minor.patch)")
        if tag == "path" and (parent is None or parent is not root):
            raise refuse("a <path> must be a child of its file's root element")
        if parent is not None and (tag in TRANSFORM_OPERATIONS) != (parent.tag == "transform"):
            where = f"inside {parent.describe()}"
            raise refuse(
                f"a transform operation {where}"
                if tag in TRANSFORM_OPERATIONS
                else f"{where}, not a transform operation"
            )
        if not is_object and tag != "transform" and element.children:
            child = element.children[0]
            raise WrtError(
                f"{child.file}:{child.line}: {child.describe()}: inside {element.describe()}, which is a property "
                "(only objects and transforms hold elements)"
            )
        pending.extend((child, element) for child in reversed(element.children))


@dataclass
class _Expansion:
    """One ``<include>``d file expanded: its elements (shared by every place it is included, until
    ``Document.expand`` copies them), how many elements that is in all, the ``<path>`` folders
    after it, the files it included (itself too) and how deep its includes nest."""

    children: list
    size: int
    search: tuple
    files: frozenset
    depth: int


class Document:
    """One Mitsuba scene file being read: attribute values, references, transforms and reports."""

    def __init__(self, path: str, approximate: bool, params: dict):
        self.path, self.approximate = path, approximate
        self.params = {str(k): str(v) for k, v in params.items()}
        self.approximations: dict[tuple[str, str, str], list[int]] = {}  # (file, element, what) -> lines
        self.ids: dict[str, Element] = {}
        self.search: list[str] = []  # <path> folders, the latest first (as Mitsuba's resolver prepends them)
        self._parsed: dict[str, Element] = {}  # each included file, read once
        self._expanded: dict[tuple, _Expansion] = {}  # (file, self.search) -> its expansion
        self._read = 0  # elements read and walked by expansions, for the bound

    # --- reporting ----------------------------------------------------------------------------
    def error(self, element: Element, message: str) -> WrtError:
        return WrtError(f"{element.file or self.path}:{element.line}: {element.describe()}: {message}")

    def warn(self, element: Element, message: str) -> None:
        """An approximation: what wrt would render differently from Mitsuba. Refused (a
        `WrtError`) unless the document is read with ``approximate``; then recorded, once per
        cause (file, element, message) with every line it happens on."""
        if not self.approximate:
            raise self.error(element, f"{message} (not converted exactly: --approximate converts it anyway)")
        key = (element.file or self.path, element.describe(), message)
        self.approximations.setdefault(key, []).append(element.line)

    @property
    def warnings(self) -> list[str]:
        """One line per approximation cause, in the order first met: ``FILE:LINE: <element>: what``,
        with `` (also lines A, B)`` where the same cause recurs."""
        lines = []
        for (file, element, message), at in self.approximations.items():
            also = f" (also line{'s' * (len(at) > 2)} {', '.join(map(str, at[1:]))})" if len(at) > 1 else ""
            lines.append(f"{file}:{at[0]}: {element}: {message}{also}")
        return lines

    # --- files: <include> and <path> ----------------------------------------------------------
    def expand(self, root: Element) -> None:
        """Splice every ``<include filename=...>`` in ``root`` into its place (the included
        ``<scene>``'s objects, themselves expanded; its properties and references Mitsuba ignores,
        and so does wrt), as Mitsuba does, and record the ``<path>`` folders in document order. A
        file that includes itself, directly or not, is refused, and so is an expansion of more
        than ``MAX_ELEMENTS`` elements.

        Each file is read once and expanded once for each set of ``<path>`` folders it is met
        with; the places it is included share its elements while their number is counted, and
        get their own copies only once the whole scene is known to hold at most ``MAX_ELEMENTS``."""
        size = self._expand_tree(root, (os.path.abspath(root.file or self.path),))[0]
        if size > MAX_ELEMENTS:
            raise WrtError(
                f"{root.file or self.path}: its <include>d files expand it to {size} elements, more than the "
                f"{MAX_ELEMENTS} wrt reads"
            )
        seen: set[int] = set()
        pending = [root]
        while pending:
            element = pending.pop()
            for i, child in enumerate(element.children):
                if id(child) in seen:  # a second place an included fragment's element is spliced into
                    child = element.children[i] = child.copy()
                seen.add(id(child))
                pending.append(child)

    def _expand_tree(self, root: Element, chain: tuple[str, ...]) -> tuple[int, frozenset, int]:
        """Splice the includes of the file whose root is ``root`` (read from the last file of
        ``chain``, which the others included), in document order, without recursing inside the
        file. Returns the elements ``root`` holds (itself not counted), the files it includes
        and how deep they nest."""
        size, files, depth = 0, frozenset(), 0
        stack = [(root, iter(root.children), [])]
        while stack:
            element, pending, kept = stack[-1]
            child = next(pending, None)
            if child is None:
                element.children = kept
                stack.pop()
                continue
            if child.tag == "include":
                expansion = self._include(child, chain)
                kept.extend(expansion.children)
                size += expansion.size
                files, depth = files | expansion.files, max(depth, expansion.depth + 1)
                continue
            if child.tag == "path":
                folder = os.path.join(os.path.dirname(child.file or self.path), self.attr(child, "value"))
                if not os.path.exists(folder):
                    raise self.error(child, f"no such folder {token(self.attr(child, 'value'))}")
                if folder in self.search:
                    self.search.remove(folder)
                self.search.insert(0, folder)
            kept.append(child)
            size += 1
            stack.append((child, iter(child.children), []))
        return size, files, depth

    def _include(self, element: Element, chain: tuple[str, ...]) -> _Expansion:
        """The expansion of the file an ``<include>`` names (read and expanded once for the
        ``<path>`` folders in force), after refusing an include loop, includes nested more than
        ``MAX_INCLUDES`` deep and an expansion of more than ``MAX_ELEMENTS`` elements."""
        name = self.attr(element, "filename")
        target = self.find_file(element, name)
        if target is None:
            raise self.error(element, f"no such file {token(name)} {self.searched(element)}")
        target = os.path.abspath(target)
        key = (target, tuple(self.search))
        expansion = self._expanded.get(key)
        if expansion is None:
            if target in chain:
                loop = " > ".join(shorten(os.path.basename(f)) for f in (*chain, target))
                raise self.error(element, f"include loop: {loop}")
            if len(chain) >= MAX_INCLUDES:
                raise self.error(element, f"includes nested more than {MAX_INCLUDES} files deep")
            if target not in self._parsed:
                included = read_xml(target)
                if included.tag != "scene":
                    raise WrtError(f"{target}:{included.line}: an included file's root must be <scene>")
                self._parsed[target] = included
            fragment = self._parsed[target].copy()  # the copy is expanded in place
            self._read += sum(1 for _ in _descendants(fragment))
            if self._read > MAX_ELEMENTS:
                raise self.error(element, f"the included files hold more than the {MAX_ELEMENTS} elements wrt reads")
            fragment.children = [child for child in fragment.children if child.tag not in (*VALUE_TAGS, "ref")]
            size, files, depth = self._expand_tree(fragment, (*chain, target))
            expansion = _Expansion(fragment.children, size, tuple(self.search), files | {target}, depth)
            self._expanded[key] = expansion
        elif any(f in expansion.files for f in chain):
            loop = " > ".join(shorten(os.path.basename(f)) for f in (*chain, target))
            raise self.error(element, f"include loop: {loop}")
        elif len(chain) + expansion.depth >= MAX_INCLUDES:
            raise self.error(element, f"includes nested more than {MAX_INCLUDES} files deep")
        self.search[:] = expansion.search
        if expansion.size > MAX_ELEMENTS:
            raise self.error(
                element,
                f"{token(name)} expands to {expansion.size} elements, more than the {MAX_ELEMENTS} wrt reads",
            )
        return expansion

    def find_file(self, element: Element, name: str) -> str | None:
        """The file ``name`` refers to, as Mitsuba's resolver finds it: as given when absolute,
        else in the ``<path>`` folders (the latest first), then beside the file ``element`` is in,
        then beside the scene file; None when it is nowhere. What exists there is found, as by
        Mitsuba (a folder or a FIFO too: the reader then refuses it)."""
        if os.path.isabs(name):
            return name if os.path.exists(name) else None
        folders = [*self.search, os.path.dirname(element.file or self.path), os.path.dirname(self.path)]
        return next((os.path.join(f, name) for f in folders if os.path.exists(os.path.join(f, name))), None)

    def searched(self, element: Element) -> str:
        """Where ``find_file`` looked, for a message."""
        folders = list(
            dict.fromkeys([*self.search, os.path.dirname(element.file or self.path), os.path.dirname(self.path)])
        )
        more = ", ..." if len(folders) > MAX_LISTED else ""
        return "(searched: " + ", ".join(repr(f or ".") for f in folders[:MAX_LISTED]) + more + ")"

    # --- the file's ids and defaults ----------------------------------------------------------
    def index(self, root: Element) -> None:
        """Record every element's ``id`` (each once) and the root's ``<default>`` parameters (the
        caller's ``params`` take precedence), then refuse reference loops and parameters given
        twice."""
        for element in _descendants(root):
            if "id" in element.attrs and element.tag != "ref":
                first = self.ids.setdefault(element.attrs["id"], element)
                if first is not element:
                    raise self.error(
                        element,
                        f"id {token(element.attrs['id'])} is already the id of {first.describe()} on line {first.line}",
                    )
        for child in root.children:
            if child.tag == "default":
                self.params.setdefault(self.attr(child, "name"), self.attr(child, "value"))
        self._check_references(root)
        self._check_parameters(root)

    def _check_parameters(self, root: Element) -> None:
        """Refuse, as Mitsuba does ("property ... was specified multiple times"), a parameter (a
        ``<float>``, ``<rgb>``, ``<transform>``, ... or a named ``<ref>``) of an element given
        again under a name it already has. A named nested object replaces what had its name
        (`Plugin` keeps only the last), as in Mitsuba."""
        for element in [root, *_descendants(root)]:
            given: dict[str, Element] = {}
            for child in element.children:
                if "name" not in child.attrs or child.tag not in (*VALUE_TAGS, "ref", *OBJECT_TAGS):
                    continue
                name = self.attr(child, "name")
                if (child.tag in VALUE_TAGS or child.tag == "ref") and name in given:
                    first = given[name]
                    raise self.error(
                        child,
                        f"parameter {token(name)} of {element.describe()} is given twice (first as"
                        f" {first.describe()} on line {first.line}): Mitsuba refuses a property given more than once",
                    )
                given[name] = child

    def _check_references(self, root: Element) -> None:
        """Refuse an element that contains itself through ``<ref>`` elements (a reference to itself,
        to an element enclosing it, or to one that refers back): converting it would never end.

        A depth-first walk of the elements and their references, without recursion; an element
        reached again while it is still being walked closes a loop."""
        walking, done = set(), set()
        chain, pending = [root], [iter(root.children)]
        walking.add(id(root))
        while pending:
            child = next(pending[-1], None)
            if child is None:
                pending.pop()
                element = chain.pop()
                walking.discard(id(element))
                done.add(id(element))
                continue
            target = self.ids.get(self.attr(child, "id", "")) if child.tag == "ref" else child
            if target is None or id(target) in done:
                continue
            if id(target) in walking:
                cycle = chain[next(i for i, e in enumerate(chain) if e is target) :]
                path = " > ".join(f"{e.describe()} (line {e.line})" for e in cycle)
                raise self.error(child, f"reference loop: {path} > back to {target.describe()}")
            walking.add(id(target))
            chain.append(target)
            pending.append(iter(target.children))

    # --- attribute values ---------------------------------------------------------------------
    def attr(self, element: Element, name: str, default=_REQUIRED):
        if name not in element.attrs:
            if default is _REQUIRED:
                raise self.error(element, f"attribute '{name}' is required")
            return default

        def substitute(match):
            if match.group(1) not in self.params:
                raise self.error(
                    element,
                    f'${shorten(match.group(1))} is not defined (no <default name="{shorten(match.group(1))}">)',
                )
            return self.params[match.group(1)]

        return _PARAMETER.sub(substitute, element.attrs[name])

    def numbers(self, element: Element, name: str, text: str, counts: tuple[int, ...] | None = None) -> list[float]:
        """The finite numbers of ``text``, the value of ``name`` (an attribute or a parameter) in
        ``element``, separated by spaces or commas; as many as one of ``counts`` says, if given."""
        words = _SPLIT.split(text.strip())
        values = []
        for word in words:
            try:
                values.append(parse_number(word))
            except ValueError as e:
                shown = f"{token(word)} " if len(words) > 1 else ""
                problem = f"'{name}' = {token(text)}: {shown}{e}" if shown else f"'{name}' = {token(text)} {e}"
                raise self.error(element, problem) from None
        if counts is not None and len(values) not in counts:
            wanted = " or ".join("one" if n == 1 else str(n) for n in counts)
            raise self.error(element, f"'{name}' = {token(text)} must be {wanted} number{'s' * (counts != (1,))}")
        return values

    def number(self, element: Element, name: str, text: str, integer: bool = False):
        """The one finite number (or integer) ``text``, the value of ``name`` in ``element``."""
        if not integer:
            return self.numbers(element, name, text, (1,))[0]
        try:
            return parse_number(text, integer=True)
        except ValueError as e:
            raise self.error(element, f"'{name}' = {token(text)} {e}") from None

    def xyz(self, element: Element, default: float) -> np.ndarray:
        """``x``, ``y``, ``z`` attributes, or ``value`` with one or three numbers."""
        if "value" in element.attrs:
            values = self.numbers(element, "value", self.attr(element, "value"), (1, 3))
            return np.array(values * 3 if len(values) == 1 else values)
        return np.array([self.number(element, k, self.attr(element, k, str(default))) for k in "xyz"])

    def resolve(self, ref: Element) -> Element:
        target = self.ids.get(self.attr(ref, "id"))
        if target is None:
            raise self.error(ref, f"reference to unknown id {token(self.attr(ref, 'id'))}")
        return target

    def transform(self, element: Element) -> tuple[np.ndarray, tuple | None]:
        """Compose a ``<transform>``'s operations in Mitsuba's order: each one is applied after
        those above it (``M = op_n ... op_2 op_1``).

        Every operation, and their composition, must be a finite, invertible affine map: a
        ``scale`` by 0 or a singular ``matrix`` (which flatten space), a ``matrix`` whose bottom
        row is not ``0 0 0 1``, or operations whose product overflows are errors."""
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
                step = rotation_matrix(axis, self.number(op, "angle", self.attr(op, "angle")))
            elif op.tag == "matrix":
                values = self.numbers(op, "value", self.attr(op, "value"), (16, 9))
                step = np.eye(4)
                n = 4 if len(values) == 16 else 3
                step[:n, :n] = np.reshape(values, (n, n))
                if not np.array_equal(step[3], [0.0, 0.0, 0.0, 1.0]):
                    raise self.error(op, f"{_shown(op)}: the bottom row must be 0 0 0 1 (an affine transform)")
            elif op.tag in ("lookat", "look_at"):
                origin, target = (np.array(self.numbers(op, k, self.attr(op, k), (3,))) for k in ("origin", "target"))
                up = np.array(self.numbers(op, "up", self.attr(op, "up", "0, 0, 0"), (3,)))
                with np.errstate(all="ignore"):  # checked below
                    step = look_at_matrix(origin, target, up)
                if not np.all(np.isfinite(step)):
                    raise self.error(
                        op,
                        f"{_shown(op)}: invalid lookat (origin = target, up parallel to the view direction, "
                        "or points too far apart for float64)",
                    )
                lookat = (origin, target, up) if len(element.children) == 1 else None
            else:
                raise self.error(op, f"unknown transform operation inside {element.describe()}")
            if _singular(step):
                raise self.error(op, f"{_shown(op)} makes the transform singular (it flattens space)")
            with np.errstate(all="ignore"):
                matrix = step @ matrix
            if not np.all(np.isfinite(matrix)):
                raise self.error(element, "the composed transform is not finite (its operations overflow float64)")
            if _singular(matrix):
                raise self.error(element, "the composed transform is singular (its scales underflow float64)")
        return matrix, lookat


def _descendants(root: Element):
    """Every element inside ``root``, in file order, without recursion."""
    pending = list(reversed(root.children))
    while pending:
        element = pending.pop()
        yield element
        pending.extend(reversed(element.children))


def _shown(element: Element) -> str:
    """An element's attributes as a message shows values: ``'x' = '1', 'y' = '0'``."""
    return ", ".join(f"'{shorten(k)}' = {token(v)}" for k, v in element.attrs.items())


def _singular(matrix: np.ndarray) -> bool:
    """Whether the 3x3 part of a finite 4x4 transform is singular (or nearly, in float64)."""
    if not np.all(np.isfinite(matrix)):
        return False  # reported as not finite
    scales = np.linalg.svd(matrix[:3, :3], compute_uv=False)
    return not scales[-1] > scales[0] * _SINGULAR


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
                self.params[doc.attr(child, "name")] = child  # given once (Document.index)
            elif child.tag == "ref":
                self.nested.append((child.attrs.get("name"), doc.resolve(child)))
            elif child.tag in PLUGIN_TAGS:
                name = doc.attr(child, "name", None)
                if name is not None:  # as in Mitsuba, a named object replaces what was given its name before
                    self.params.pop(name, None)
                    self.nested = [(key, other) for key, other in self.nested if key != name]
                self.nested.append((name, child))
            else:
                doc.warn(child, f"unsupported element inside {element.describe()}: ignored")

    # --- typed parameters -------------------------------------------------------------------
    def value(self, name: str, tags: tuple[str, ...]) -> Element | None:
        """The element of parameter ``name`` (None if absent), which must be one of ``tags``."""
        self.used.add(name)
        element = self.params.get(name)
        if element is not None and element.tag not in tags:
            shown = f" = {token(element.attrs['value'])}" if "value" in element.attrs else ""
            raise self.doc.error(
                element, f"parameter '{name}'{shown} of {self.element.describe()} must be a <{tags[0]}>"
            )
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

    def number(self, name: str, default, integer: bool = False, above: float | None = None, below: float | None = None):
        """Parameter ``name`` as a finite number (an integer with ``integer``), or ``default`` if
        absent; with ``above`` / ``below``, it must be greater than / less than those."""
        element = self.value(name, ("integer",) if integer else ("float", "integer"))
        if element is None:
            return default
        text = self.doc.attr(element, "value")
        value = self.doc.number(element, name, text, integer)
        if (above is not None and not value > above) or (below is not None and not value < below):
            if above is not None and below is not None:
                wanted = f"in ({above:g}, {below:g})"
            else:
                wanted = f"> {above:g}" if above is not None else f"< {below:g}"
            raise self.doc.error(element, f"'{name}' = {token(text)} must be {wanted}")
        return value

    def boolean(self, name: str, default: bool) -> bool:
        element = self.value(name, ("boolean",))
        if element is None:
            return default
        text = self.doc.attr(element, "value").strip().lower()
        if text not in ("true", "false"):
            raise self.doc.error(element, f"'{name}' = {token(text)} is not true or false")
        return text == "true"

    def string(self, name: str, default: str | None) -> str | None:
        element = self.value(name, ("string",))
        return default if element is None else self.doc.attr(element, "value")

    def file(self, subject: str, kind: str) -> str:
        """The ``filename`` parameter, required, as a path relative to the scene file's folder (how
        wrt's scene format takes files), found as `Document.find_file` finds it: its absence is
        "``subject`` needs a filename", a file found nowhere "no such ``kind``" with the folders
        searched."""
        filename = self.string("filename", None)
        if filename is None:
            raise self.doc.error(self.element, f"{subject} needs a filename")
        found = self.doc.find_file(self.element, filename)
        if found is None:
            raise self.doc.error(self.element, f"no such {kind} {token(filename)} {self.doc.searched(self.element)}")
        return os.path.relpath(found, os.path.dirname(self.doc.path) or ".")

    def color(self, name: str, default: float, *, emission: bool = False, unbounded: bool = False) -> list[float]:
        """An RGB parameter given as ``<rgb>``, ``<float>`` or ``<spectrum>``, in linear sRGB as
        Mitsuba's RGB variants read it (`spectra` says how a spectrum converts). ``emission``
        marks a radiance, intensity or irradiance, ``unbounded`` a parameter that may exceed 1 (a
        conductor's eta and k); a spectrum of any other parameter is a reflectance, within [0, 1]."""
        element = self.value(name, ("rgb", "spectrum", "float", "integer"))
        if element is None:
            return [float(default)] * 3
        if element.tag == "spectrum":
            return self._spectrum(element, name, emission, unbounded).tolist()
        text = self.doc.attr(element, "value")
        values = self.doc.numbers(element, name, text)
        if len(values) not in (1, 3) or (element.tag != "rgb" and len(values) != 1):
            raise self.doc.error(element, f"'{name}' = {token(text)} must be one or three numbers")
        return values * 3 if len(values) == 1 else values

    def _spectrum(self, element: Element, name: str, emission: bool, unbounded: bool) -> np.ndarray:
        """The linear sRGB of a ``<spectrum>``: its ``value`` a constant or wavelength:value pairs,
        or its ``filename`` a ``.spd`` file (found as `Document.find_file` finds files)."""
        doc = self.doc
        if element.attrs.get("type") == "srgb":
            return self._srgb(element, name, emission or unbounded)
        unexpected = sorted(set(element.attrs) - {"name", "value", "filename"})
        if unexpected:
            raise doc.error(element, f"unexpected attribute '{unexpected[0]}' (a <spectrum> has a value or a filename)")
        text, filename = doc.attr(element, "value", ""), doc.attr(element, "filename", "")
        if bool(text) == bool(filename):
            raise doc.error(element, f"'{name}' needs either a 'value' or a 'filename' (not both)")
        if text and ":" not in text:
            return spectra.uniform_to_srgb(doc.number(element, name, text), emission=emission)
        if text:
            shown = f"'{name}' = {token(text)}"
            tokens = _SPLIT.split(text.strip())
            # split at ':' as Mitsuba's tokenizer does, empty parts dropped ("400::1" is 400:1)
            pairs = [[part for part in token.split(":") if part] for token in tokens]
            bad = next((token for token, pair in zip(tokens, pairs) if len(pair) != 2), None)
            if bad is not None:
                raise doc.error(element, f"{shown}: {token(bad)} is not a wavelength:value pair")
            lines = [("", *pair) for pair in pairs]
        else:
            shown = f"'{name}' file {token(filename)}"
            path = doc.find_file(element, filename)
            if path is None:
                raise doc.error(element, f"{shown}: no such file {doc.searched(element)}")
            try:
                text = read_bytes(path, "spectrum").decode("utf-8", errors="replace")
            except WrtError as e:  # not a regular file, or too large: "PATH: why"
                raise doc.error(element, f"{shown}: {str(e).removeprefix(path + ': ')}") from None
            try:
                lines = [(f"line {n}: ", *pair) for n, *pair in spectra.spd_lines(text)]
            except ValueError as e:
                raise doc.error(element, f"{shown}: {e}") from None
        numbers = []
        for where, *pair in lines:
            for word in pair:
                try:
                    numbers.append(parse_number(word))
                except ValueError as e:
                    raise doc.error(element, f"{shown}: {where}{token(word)} {e}") from None
        try:
            return spectra.spectrum_to_srgb(
                numbers[0::2], numbers[1::2], bounded=not (emission or unbounded), d65=not emission
            )
        except ValueError as e:
            raise doc.error(element, f"{shown}: {e}") from None

    def _srgb(self, element: Element, name: str, unbounded: bool) -> np.ndarray:
        """A ``<spectrum type="srgb">`` (Mitsuba's ``srgb`` plugin) with its ``<rgb name="color">``:
        that colour, as the RGB variants take it; a reflectance's in [0, 1], as Mitsuba requires."""
        doc = self.doc
        colours = [c for c in element.children if c.tag == "rgb" and c.attrs.get("name") == "color"]
        others = [c for c in element.children if c not in colours]
        if len(colours) != 1 or others or set(element.attrs) - {"name", "type"}:
            raise doc.error(
                element, f'\'{name}\': a <spectrum type="srgb"> holds one <rgb name="color"> and nothing else'
            )
        text = doc.attr(colours[0], "value")
        values = doc.numbers(colours[0], "color", text, (1, 3))
        values = np.asarray(values * 3 if len(values) == 1 else values, dtype=np.float64)
        if not unbounded and (values.min() < 0.0 or values.max() > 1.0):
            raise doc.error(colours[0], f"'{name}' colour {token(text)} must lie in [0, 1] (Mitsuba rejects it)")
        return values

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

    def named(self, name: str, tag: str) -> Element | None:
        """The nested ``tag`` element given for ``name`` (the first), or None; not marked read."""
        return next((child for key, child in self.nested if key == name and child.tag == tag), None)

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
                self.doc.warn(
                    element, f"parameter '{shorten(name)}' of {self.element.describe()} is not supported: ignored"
                )
        for _, child in self.nested:
            if id(child) not in self.used_nested:
                self.doc.warn(child, f"{child.describe()} inside {self.element.describe()} is not supported: ignored")
