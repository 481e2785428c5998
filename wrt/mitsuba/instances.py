"""Converting Mitsuba's ``shapegroup`` and ``instance`` shapes into wrt's ``[[group]]`` tables
and ``instance`` shapes: the group's shapes are converted in its own object space, and each
instance keeps its ``to_world`` as a matrix (wrt traces instances through a two-level BVH)."""

from __future__ import annotations

from ..errors import token
from .bsdfs import Materials
from .shapes import shape
from .xml import Document, Element, Plugin


def shapegroup(doc: Document, materials: Materials, element: Element, groups: list, sources: dict) -> None:
    """Append the ``[[group]]`` table of a ``shapegroup`` (named by its ``id``) to ``groups``."""
    if "id" not in element.attrs:
        raise doc.error(element, "a shapegroup needs an id (instances refer to it)")
    p = Plugin(doc, element)
    members = p.children("shape")
    if not members:
        raise doc.error(element, "a shapegroup holds at least one shape")
    tables: list[dict] = []
    for member in members:
        if doc.attr(member, "type", "") in ("shapegroup", "instance"):
            raise doc.error(member, "shapegroups and instances cannot be nested in a shapegroup")
        lights: list[dict] = []
        first = len(tables)
        shape(doc, materials, member, tables, lights)
        if lights:
            raise doc.error(member, "an emitter in a shapegroup is not supported by Mitsuba either")
        for j in range(first, len(tables)):
            sources[f"group[{len(groups)}].shape[{j}]"] = member
    p.finish()
    groups.append({"name": element.attrs["id"], "shape": tables})


def instance(doc: Document, element: Element, group_names: set) -> dict:
    """The ``instance`` shape table of an ``instance`` element: the group it refers to (by
    ``<ref id>``), placed by its ``to_world``."""
    p = Plugin(doc, element)
    refs = [child for _, child in p.nested if child.tag == "shape" and doc.attr(child, "type", "") == "shapegroup"]
    if len(refs) != 1:
        raise doc.error(element, "an instance refers to exactly one shapegroup (<ref id=...>)")
    p.children("shape")
    name = refs[0].attrs.get("id", "")
    if name not in group_names:
        raise doc.error(element, f"the shapegroup {token(name)} must come before its instances")
    matrix, _ = p.transform("to_world")
    p.finish()
    return {"type": "instance", "group": name, "transform": {"matrix": [float(x) for x in matrix.ravel()]}}
