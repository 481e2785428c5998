"""A whole Mitsuba 3 scene file -> a wrt scene document: the sensor and integrator, then the
shapes and emitters in file order, then the materials they use."""

from __future__ import annotations

import os

from ..errors import WrtError
from .bsdfs import Materials
from .emitters import emitter
from .sensors import integrator, sensor
from .shapes import shape
from .xml import Document, Element, read_xml


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
    doc = Document(path, strict, params or {})
    return convert(doc, read_xml(path)), doc.warnings


def convert(doc: Document, root: Element) -> dict:
    """The wrt scene document of the ``<scene>`` element ``root``."""
    if root.tag != "scene":
        raise WrtError(f"{doc.path}:{root.line}: the root element is <{root.tag}>, not a Mitsuba <scene>")
    version = root.attrs.get("version", "")
    if not version.split(".")[0].isdigit() or int(version.split(".")[0]) < 2:
        doc.warn(root, f"version {version!r}: only Mitsuba 3 scenes (version 2.0 and later names) are converted")
    doc.expand(root)
    doc.index(root)
    sensors = [c for c in root.children if c.tag == "sensor"]
    integrators = [c for c in root.children if c.tag == "integrator"]
    for extra in sensors[1:] + integrators[1:]:
        doc.warn(extra, "only the first sensor and integrator are converted: ignored")
    render, camera = sensor(doc, sensors[0] if sensors else Element("sensor", {"type": "perspective"}, root.line))
    render.update(integrator(doc, integrators[0] if integrators else None))
    materials = Materials(doc)
    shapes: list[dict] = []
    lights: list[dict] = []
    for child in root.children:
        if child.tag == "shape":
            shape(doc, materials, child, shapes, lights)
        elif child.tag == "emitter":
            light = emitter(doc, child)
            if light is not None:
                lights.append(light)
        elif child.tag not in ("default", "path", "sensor", "integrator", "bsdf", "texture"):
            doc.warn(child, "not supported: ignored")
    exterior = materials.exterior_ior()
    if exterior != 1.0:
        render["exterior_ior"] = exterior
    return {"render": render, "camera": camera, "material": materials.tables, "shape": shapes, "light": lights}
