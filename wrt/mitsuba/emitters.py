"""Converting Mitsuba's emitters into wrt lights: ``point``, ``spot`` (with its ``texture``),
``projector``, ``directional``, ``constant`` and ``envmap`` on their own, ``area`` attached to a
shape."""

from __future__ import annotations

import os

import numpy as np

from ..imageio import oiio
from .sensors import perspective_fov
from .textures import textured_color
from .transforms import as_list
from .xml import Document, Element, Plugin


def emitter(doc: Document, element: Element) -> dict | None:
    """The ``[[light]]`` table of a free-standing emitter; None (with a warning) if unsupported."""
    p = Plugin(doc, element)
    matrix, _ = p.transform("to_world")
    if p.type == "point":
        position = p.vector("position", matrix[:3, 3])
        light = {"type": "point", "position": as_list(position), "intensity": p.color("intensity", 1.0, emission=True)}
    elif p.type == "spot":
        cutoff = p.number("cutoff_angle", 20.0)
        light = {
            "type": "spot",
            "position": as_list(matrix[:3, 3]),
            "direction": as_list(matrix[:3, 2]),
            "intensity": p.color("intensity", 1.0, emission=True),
            "cutoff_angle": cutoff,
            "beam_width": p.number("beam_width", 0.75 * cutoff),
        }
        if p.has("texture") or any(key == "texture" for key, _ in p.nested):
            texture = textured_color(p, "texture", 1.0, emission=True)
            if not isinstance(texture, dict):  # as Mitsuba refuses it
                raise doc.error(element, "a spot's texture must be spatially varying (a bitmap or a checkerboard)")
            light.update(texture=texture, up=_frame_up(doc, element, matrix))
    elif p.type == "projector":
        light = projector(doc, element, p, matrix)
    elif p.type == "directional":
        direction = p.vector("direction", matrix[:3, 2])
        light = {
            "type": "directional",
            "direction": as_list(direction),
            "irradiance": p.color("irradiance", 1.0, emission=True),
        }
    elif p.type == "constant":
        light = {"type": "environment", "radiance": p.color("radiance", 1.0, emission=True)}
    elif p.type == "envmap":
        light = environment_map(doc, p, matrix)
    else:
        doc.warn(element, "emitter type not supported: ignored")
        return None
    p.finish()
    return light


def _frame_up(doc: Document, element: Element, matrix: np.ndarray) -> list[float]:
    """The ``up`` of a light whose texture turns with its ``to_world``: the frame's y axis, when
    the frame is a rotation (wrt's light frame is orthonormal and right-handed, ``lookat``'s)."""
    basis = matrix[:3, :3]
    if not np.allclose(basis.T @ basis, np.eye(3), rtol=0.0, atol=1e-6) or np.linalg.det(basis) < 0.0:
        doc.warn(element, "to_world scales, shears or mirrors the light's texture: its frame's rotation is used")
    return as_list(basis[:, 1])


def projector(doc: Document, element: Element, p: Plugin, matrix: np.ndarray) -> dict:
    """The ``projector`` table of Mitsuba's ``projector``: its ``irradiance`` (a texture or a
    constant, required), ``scale``, and its field of view (``fov`` along ``fov_axis``, or
    ``focal_length``) on a film of the texture's size (1 x 1 for a constant), made vertical."""
    if not p.has("irradiance") and not any(key == "irradiance" for key, _ in p.nested):
        raise doc.error(element, "a projector needs an irradiance (a texture or a constant)")
    irradiance = textured_color(p, "irradiance", 1.0, emission=True)
    size = {"width": 1, "height": 1}
    if isinstance(irradiance, dict) and irradiance["texture"] == "bitmap":
        image = oiio.ImageInput.open(os.path.join(os.path.dirname(doc.path) or ".", irradiance["file"]))
        if image is not None:  # else the loader says why it cannot read the file
            size = {"width": image.spec().width, "height": image.spec().height}
            image.close()
    return {
        "type": "projector",
        "position": as_list(matrix[:3, 3]),
        "direction": as_list(matrix[:3, 2]),
        "up": _frame_up(doc, element, matrix),
        "fov": perspective_fov(doc, element, p, size),
        "irradiance": irradiance,
        "scale": p.number("scale", 1.0),
    }


def environment_map(doc: Document, p: Plugin, matrix: np.ndarray) -> dict:
    """The ``environment`` table of an ``envmap``: its file (found as Mitsuba finds it), ``scale``
    and the rotation of its ``to_world`` (the translation does nothing to directions; a matrix
    that is not a rotation distorts Mitsuba's map: approximated by its nearest rotation)."""
    file = p.file("an envmap", "environment map")
    p.boolean("mis_compensation", False)  # changes the sampling density only: the noise, not the image
    light = {"type": "environment", "file": file}
    scale = p.number("scale", 1.0)
    if scale != 1.0:
        light["scale"] = scale
    rotation = matrix[:3, :3]
    if not np.allclose(rotation.T @ rotation, np.eye(3), rtol=0.0, atol=1e-6):
        doc.warn(p.element, "to_world is not a rotation (it scales or shears the map): its nearest rotation is used")
        u, _, vt = np.linalg.svd(rotation)
        rotation = u @ vt
    if not np.allclose(rotation, np.eye(3), rtol=0.0, atol=0.0):
        rows = [[*as_list(row), 0.0] for row in rotation] + [[0.0, 0.0, 0.0, 1.0]]
        light["transform"] = {"matrix": [x for row in rows for x in row]}
    return light


def area_radiance(doc: Document, element: Element) -> list[float] | dict:
    """The radiance of an emitter attached to a shape (an ``area`` emitter): an RGB list, or the
    texture table of a textured one (looked up at the shape's uv)."""
    p = Plugin(doc, element)
    if p.type != "area":
        doc.warn(element, "only area emitters can be attached to shapes: converted as area")
    radiance = textured_color(p, "radiance", 1.0, emission=True)
    p.finish()
    return radiance


def surface_light(geometry: dict, radiance: list[float]) -> dict:
    """An area light from a converted rectangle polygon (its winding already gives Mitsuba's
    front side) or a sphere light from a sphere."""
    if geometry["type"] == "sphere":
        return {"type": "sphere", "center": geometry["center"], "radius": geometry["radius"], "radiance": radiance}
    v = np.array(geometry["vertices"])
    with np.errstate(all="ignore"):  # far apart vertices: the caller checks the edges are finite
        edge_u, edge_v = v[1] - v[0], v[3] - v[0]
    return {
        "type": "area",
        "corner": as_list(v[0]),
        "edge_u": as_list(edge_u),
        "edge_v": as_list(edge_v),
        "radiance": radiance,
    }
