"""Converting Mitsuba's textures into wrt texture tables: ``rawconstant`` (wrt's ``constant``),
``checkerboard`` (constant colours), ``bitmap`` and ``mesh_attribute``, nested in a BSDF parameter
or referenced by ``<ref>``, with their ``to_uv`` (docs/mitsuba.md)."""

from __future__ import annotations

import os

import numpy as np

from ..errors import token
from .transforms import as_list
from .xml import Document, Element, Plugin

FILTERS = ("bilinear", "nearest")
WRAPS = ("repeat", "mirror", "clamp")
FORMATS = ("variant", "uint8")
"""A bitmap's ``format`` values in Mitsuba 3.9: its texels stored as floats, or as 8-bit integers."""


def textured_color(p: Plugin, name: str, default: float, emission: bool = False) -> list[float] | dict:
    """Colour parameter ``name`` of ``p``: an RGB list (``Plugin.color``; ``emission`` as there), or
    the texture table of the ``<texture>`` given for it."""
    nested = p.named(name, "texture")
    if nested is None or name in p.params:
        return p.color(name, default, emission=emission)
    p.used.add(name)
    p.used_nested.add(id(nested))
    return texture(p.doc, nested)


def texture(doc: Document, element: Element) -> dict:
    """The inline texture table (docs/scene-format.md) of a ``<texture>`` element."""
    p = Plugin(doc, element)
    if p.type == "rawconstant":  # a <float> (what eval_1 reads) or a 3D <vector>, not decoded (Mitsuba's)
        given = p.params.get("value")
        if given is not None and given.tag == "vector":
            value = [float(x) for x in p.vector("value", (1.0, 1.0, 1.0))]
        else:
            value = p.number("value", 1.0)
        table = {"texture": "constant", "value": value}
    elif p.type == "checkerboard":
        table = {"texture": "checkerboard", "color0": p.color("color0", 0.4), "color1": p.color("color1", 0.2)}
    elif p.type == "bitmap":
        table = {"texture": "bitmap", "file": p.file("a bitmap texture", "image file")}
        for key, parameter, choices in (("filter", "filter_type", FILTERS), ("wrap", "wrap_mode", WRAPS)):
            value = p.string(parameter, choices[0])
            if value not in choices:
                raise doc.error(
                    p.params[parameter], f"'{parameter}' = {token(value)} must be one of {', '.join(choices)}"
                )
            table[key] = value
        if p.boolean("raw", False):
            table["raw"] = True
        _storage(doc, p, os.path.join(os.path.dirname(doc.path) or ".", table["file"]))
    elif p.type == "mesh_attribute":  # the mesh's values: the loader checks the mesh has them
        name = p.string("name", None)
        if name is None:
            raise doc.error(element, "a mesh_attribute texture needs a 'name' (Mitsuba rejects it)")
        if not name.startswith(("vertex_", "face_")):
            raise doc.error(
                p.params["name"], f"'name' = {token(name)} must start with vertex_ or face_ (Mitsuba rejects it)"
            )
        table = {"texture": "mesh_attribute", "name": name, "scale": p.number("scale", 1.0)}
        p.finish()
        return table
    else:
        raise doc.error(
            element,
            f"texture type {token(p.type)} is not supported"
            " (wrt has rawconstant, checkerboard, bitmap and mesh_attribute)",
        )
    matrix, _ = p.transform("to_uv")
    if not np.array_equal(matrix, np.eye(4)):
        # Mitsuba's to_uv acts on (u, v, 1): the 4x4 transform without its z row and column
        uv = matrix[np.ix_([0, 1, 3], [0, 1, 3])]
        table["to_uv"] = as_list(uv[:2].ravel())
    p.finish()
    return table


def _storage(doc: Document, p: Plugin, path: str) -> None:
    """A bitmap's ``format``: ``variant`` (the default) stores the texels as read, as wrt does;
    ``uint8`` quantises them to 8 bits, which leaves an 8-bit file's texels as they are (checked
    against Mitsuba's ``eval``) and is approximated for any other file (read as it is)."""
    storage = p.string("format", FORMATS[0])
    if storage not in FORMATS:
        raise doc.error(p.params["format"], f"'format' = {token(storage)} must be one of {', '.join(FORMATS)}")
    if storage == "uint8" and _bits(path) != 8:
        doc.warn(
            p.params["format"],
            "format uint8 of a file that is not 8 bits a channel: Mitsuba quantises its texels, wrt reads them as"
            " they are",
        )


def _bits(path: str) -> int | None:
    """Bits a channel of image file ``path`` (None where OpenImageIO cannot tell; the loader
    reports an unreadable file)."""
    import OpenImageIO as oiio

    image = oiio.ImageInput.open(path)
    if image is None:
        oiio.geterror()
        return None
    try:
        return image.spec().format.size() * 8
    finally:
        image.close()
