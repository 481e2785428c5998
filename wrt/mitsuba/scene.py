"""A whole Mitsuba 3 scene file -> a wrt scene document: the sensor and integrator, then the
shapes and emitters in file order, then the materials they use."""

from __future__ import annotations

import os
from dataclasses import dataclass, field

from ..errors import SceneError, WrtError, shown, token
from .bsdfs import Materials
from .emitters import emitter
from .instances import instance, shapegroup
from .media import Media
from .sensors import integrator, sensor
from .shapes import shape
from .xml import Document, Element, read_xml


@dataclass
class Converted:
    """A converted Mitsuba file: the wrt scene document, the approximations made (empty unless
    converted with ``approximate``), and the element each converted table came from."""

    doc: dict
    approximations: list[str]
    sources: dict[str, Element] = field(default_factory=dict)  # "shape[3]", "light[0]", "camera", ...

    def locate(self, error: SceneError) -> WrtError:
        """``error``, raised by ``parse_scene`` on a converted table, as the XML element it came
        from: ``FILE:LINE: <element>: key = value: problem (converted to shape[3])``."""
        element = self.sources.get(error.table or "")
        if element is None:
            return error
        where = error.key or ""
        if error.value is not SceneError._NO_VALUE:
            where += f" = {shown(error.value)}"
        converted = f" (converted to {error.table}{'.' + error.key if error.key else ''})"
        return WrtError(
            f"{element.file}:{element.line}: {element.describe()}: {where + ': ' if where else ''}"
            f"{error.problem}{converted}"
        )


def convert_file(path, *, approximate: bool = False, params: dict | None = None) -> Converted:
    """`load_mitsuba`, keeping where each table came from (``Converted.sources``)."""
    path = os.fspath(path)
    doc = Document(path, approximate, params or {})
    sources: dict[str, Element] = {}
    tables = convert(doc, read_xml(path), sources)
    return Converted(tables, doc.warnings, sources)


def load_mitsuba(path, *, approximate: bool = False, params: dict | None = None) -> tuple[dict, list[str]]:
    """Convert a Mitsuba 3 scene XML file into a wrt scene document, faithfully or not at all.

    Parameters
    ----------
    path : str or os.PathLike
        The Mitsuba scene (``<scene version="3.x">``).
    approximate : bool, default False
        Convert what wrt cannot render exactly as Mitsuba would (an unsupported element or
        parameter, a BSDF replaced by its closest match) anyway, and return what was
        approximated. By default the first such element is a `WrtError`.
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
    approximations : list of str
        ``"FILE:LINE: <element>: what differs from Mitsuba"``, one per cause in file order (a
        cause met on several elements of one kind lists their lines); empty unless ``approximate``.

    Raises
    ------
    WrtError
        The file cannot be read, is not well-formed XML (the message names the file, the line
        and the column), is not a Mitsuba scene, has a value Mitsuba itself would reject (a
        malformed number, an unknown IOR name, an undefined ``$name``, a reference to an
        unknown id), or, without ``approximate``, anything wrt cannot convert exactly.
    """
    converted = convert_file(path, approximate=approximate, params=params)
    return converted.doc, converted.approximations


def convert(doc: Document, root: Element, sources: dict[str, Element]) -> dict:
    """The wrt scene document of the ``<scene>`` element ``root``; ``sources`` receives the
    element each table came from."""
    if root.tag != "scene":
        raise WrtError(f"{doc.path}:{root.line}: the root element is {root.describe()}, not a Mitsuba <scene>")
    version = root.attrs.get("version", "")
    if not version.split(".")[0].isdigit() or int(version.split(".")[0]) < 2:
        doc.warn(root, f"version {token(version)}: only Mitsuba 3 scenes (version 2.0 and later names) are converted")
    doc.expand(root)
    doc.index(root)
    sensors = [c for c in root.children if c.tag == "sensor"]
    integrators = [c for c in root.children if c.tag == "integrator"]
    for extra in sensors[1:] + integrators[1:]:
        doc.warn(extra, "only the first sensor and integrator are converted: ignored")
    sources["camera"] = sources["render"] = sensors[0] if sensors else root
    media = Media(doc)
    render, camera = sensor(
        doc, sensors[0] if sensors else Element("sensor", {"type": "perspective"}, root.line), media
    )
    render.update(integrator(doc, integrators[0] if integrators else None))
    materials = Materials(doc)
    shapes: list[dict] = []
    lights: list[dict] = []
    groups: list[dict] = []
    for child in root.children:
        n_shapes, n_lights = len(shapes), len(lights)
        kind = doc.attr(child, "type", "")
        if child.tag == "shape" and kind == "shapegroup":
            shapegroup(doc, materials, child, groups, sources)
        elif child.tag == "shape" and kind == "instance":
            shapes.append(instance(doc, child, {group["name"] for group in groups}))
        elif child.tag == "shape":
            shape(doc, materials, child, shapes, lights, media)
        elif child.tag == "emitter":
            light = emitter(doc, child)
            if light is not None:
                lights.append(light)
        elif child.tag not in ("default", "path", "sensor", "integrator", "bsdf", "texture", "medium"):
            doc.warn(child, "not supported: ignored")
        sources.update({f"shape[{i}]": child for i in range(n_shapes, len(shapes))})
        sources.update({f"light[{i}]": child for i in range(n_lights, len(lights))})
    sources.update({f"material[{i}]": e for i, e in enumerate(materials.sources) if e is not None})
    sources.update({f"medium[{i}]": e for i, e in enumerate(media.sources)})
    exterior = materials.exterior_ior()
    if exterior != 1.0:
        render["exterior_ior"] = exterior
    tables = {"render": render, "camera": camera, "material": materials.tables, "shape": shapes, "light": lights}
    if media.tables:
        tables["medium"] = media.tables
    return {**tables, "group": groups} if groups else tables
