"""Converting Mitsuba's shapes into wrt shapes: ``sphere``, ``rectangle`` and ``cube`` (as
polygons), ``disk`` and ``cylinder``, ``obj``, ``ply`` and ``serialized`` meshes, with their BSDF and, for an area
emitter on a rectangle or sphere, the area or sphere light it becomes."""

from __future__ import annotations

import numpy as np

from .bsdfs import Materials
from .emitters import area_radiance, surface_light
from .media import Media
from .transforms import as_list, coordinate_system, mirrors, transform_point
from .xml import Document, Element, Plugin

BEYOND_FLOAT64 = "beyond the float64 range (not finite)"
RECTANGLE = np.array([(-1.0, -1.0, 0.0), (1.0, -1.0, 0.0), (1.0, 1.0, 0.0), (-1.0, 1.0, 0.0)])
"""Mitsuba's rectangle: [-1, 1]^2 at z = 0, front +z; uv = (x + 1, y + 1) / 2 of its point."""
CUBE = np.array(
    [
        [(1, -1, -1), (1, -1, 1), (-1, -1, 1), (-1, -1, -1)],
        [(1, 1, -1), (-1, 1, -1), (-1, 1, 1), (1, 1, 1)],
        [(1, -1, -1), (1, 1, -1), (1, 1, 1), (1, -1, 1)],
        [(1, -1, 1), (1, 1, 1), (-1, 1, 1), (-1, -1, 1)],
        [(-1, -1, 1), (-1, 1, 1), (-1, 1, -1), (-1, -1, -1)],
        [(1, 1, -1), (1, -1, -1), (-1, -1, -1), (-1, 1, -1)],
    ],
    dtype=np.float64,
)
"""Mitsuba's cube mesh, [-1, 1]^3: its faces -y, +y, +x, +z, -x, -z, each a loop of its corners
wound counter-clockwise seen from outside, in the order whose texture coordinates are
``CUBE_UV`` (Mitsuba's triangles are corners (0, 1, 2) and (3, 0, 2) of each loop)."""
CUBE_UV = [(0.0, 1.0), (1.0, 1.0), (1.0, 0.0), (0.0, 0.0)]


def faces(kind: str) -> list[tuple[np.ndarray, list]]:
    """``(corners, uvs)`` of each face of Mitsuba's ``rectangle`` or ``cube``."""
    if kind == "rectangle":
        return [(RECTANGLE, [((x + 1.0) / 2.0, (y + 1.0) / 2.0) for x, y, _ in RECTANGLE])]
    return [(loop, CUBE_UV) for loop in CUBE]


def shape(
    doc: Document, materials: Materials, element: Element, shapes: list, lights: list, media: Media | None = None
) -> None:
    """Append the ``[[shape]]`` tables of a shape element to ``shapes`` (or its light to
    ``lights``), with the ``interior`` and ``exterior`` media it bounds (``media``: the scene's;
    None for a shapegroup's shapes, whose media are not supported)."""
    p = Plugin(doc, element)
    bounds = media.refs(p, ("interior", "exterior")) if media is not None else {}
    matrix, _ = p.transform("to_world")
    bsdfs, emitters = p.children("bsdf"), p.children("emitter")
    for extra in bsdfs[1:] + emitters[1:]:
        doc.warn(extra, "a shape takes one BSDF and one emitter: ignored")
    if emitters and doc.attr(emitters[0], "type", "") == "volumelight":  # its interior medium's emission
        if "interior" not in bounds:
            raise doc.error(emitters[0], "a volumelight is the emission of its shape's interior medium: it has none")
        media.emit(bounds["interior"], emitters[0])
        emitters = []
    front = -1.0 if p.boolean("flip_normals", False) else 1.0
    mirrored = mirrors(matrix[:3, :3]) != (front < 0)  # winding must be reversed to keep Mitsuba's front
    params = materials.of(bsdfs[0] if bsdfs else None, emitter=bool(emitters)).params
    radiance = area_radiance(doc, emitters[0]) if emitters else None
    textured = any(isinstance(v, dict) for v in (*params.values(), radiance))
    anisotropic = "roughness_v" in params or params.get("anisotropy", 0.0) != 0.0
    oriented = textured or anisotropic  # its uv parametrisation shows: textures, an anisotropic tangent

    if p.type == "sphere":
        radius, center = p.number("radius", 1.0, above=0.0), p.vector("center", (0.0, 0.0, 0.0))
        with np.errstate(all="ignore"):  # overflow is checked below
            placed = matrix @ np.diag([radius, radius, radius, 1.0])
            placed[:3, 3] = transform_point(matrix, center)
            radius = float(np.linalg.norm(placed[:3, 0]))
        if not (np.all(np.isfinite(placed)) and np.isfinite(radius)):
            raise doc.error(element, f"radius, center and to_world place the sphere {BEYOND_FLOAT64}")
        scales = np.linalg.svd(placed[:3, :3], compute_uv=False)
        if scales.max() - scales.min() > 1e-6 * scales.max():
            doc.warn(element, "non-uniform scale: the radius is the to_world x axis scale (as in Mitsuba)")
        if front < 0:
            doc.warn(p.params["flip_normals"], "flip_normals on a sphere is not supported: normals point outward")
        tables = [{"type": "sphere", "center": as_list(placed[:3, 3]), "radius": radius}]
        if oriented and not np.allclose(placed[:3, :3], radius * np.eye(3), rtol=0.0, atol=1e-9 * radius):
            # its frame turns its uv and tangents, as Mitsuba's: the nearest rotation of its to_world
            # (Mitsuba's transform_decompose), placed at its centre with its radius
            u, _, vt = np.linalg.svd(placed[:3, :3])
            frame = np.eye(4)
            frame[:3, :3], frame[:3, 3] = radius * (u @ vt), placed[:3, 3]
            tables = [
                {
                    "type": "sphere",
                    "center": [0.0, 0.0, 0.0],
                    "radius": 1.0,
                    "transform": {"matrix": as_list(frame.ravel())},
                }
            ]
    elif p.type in ("rectangle", "cube"):
        tables = []
        for loop, uvs in faces(p.type):
            if mirrored:  # reversed, to keep Mitsuba's front
                loop, uvs = loop[::-1], uvs[::-1]
            with np.errstate(all="ignore"):
                corners = [transform_point(matrix, v) for v in loop]
            if not np.all(np.isfinite(corners)):
                raise doc.error(element, f"to_world places the {p.type} {BEYOND_FLOAT64}")
            table = {"type": "polygon", "vertices": [as_list(v) for v in corners]}
            if oriented:  # its uv parametrisation, Mitsuba's: textures, dp/du
                table["uv"] = [list(uv) for uv in uvs]
            tables.append(table)
    elif p.type in ("disk", "cylinder"):
        tables = [quadric(doc, p, matrix, front, emitters)]
    elif p.type in ("obj", "ply", "serialized"):
        tables = [mesh(doc, p, matrix)]
    else:
        doc.warn(element, "shape type not supported: ignored")
        return
    bsdf = bsdfs[0] if bsdfs else None  # None: Mitsuba's default BSDF
    material = materials.of(bsdf, emitter=bool(emitters))

    if emitters:
        if p.type in ("rectangle", "sphere") and not material.reflects() and not isinstance(radiance, dict):
            # a light of its own (sampled directly, reflecting nothing); an emitter that reflects or
            # whose radiance is a texture is an emissive shape below (sampled in the pool as well)
            if bounds:
                doc.warn(element, "an area-emitting rectangle or sphere that bounds a medium: its media are ignored")
            light = surface_light(tables[0], radiance)
            if not all(np.all(np.isfinite(v)) for v in light.values() if not isinstance(v, str)):
                raise doc.error(element, f"to_world places the {p.type} light {BEYOND_FLOAT64}")
            lights.append(light)
            p.finish()
            return
        # emission of the material, from the front side as Mitsuba's area emitter (next-event
        # estimation samples it among the emissive primitives where the pool holds its kind)
        base = bsdfs[0].attrs.get("id", material.params["type"]) if bsdfs else "default"
        name = materials.add(
            f"{base}+emission@{emitters[0].line}", {**material.table, "emission": radiance}, emitters[0]
        )
    else:
        name = materials.name(bsdf)
    for table in tables:
        shapes.append({**table, "material": name, **bounds})
    p.finish()


def mesh(doc: Document, p: Plugin, matrix: np.ndarray) -> dict:
    """The ``mesh`` shape table of an ``obj``, ``ply`` or ``serialized`` shape (with its
    ``shape_index``: which mesh of the file, 0 by default): its file, relative to the XML
    file, its ``to_world`` as a transform matrix, ``shading = "smooth"`` (Mitsuba interpolates the
    file's vertex normals, or those it computes from the placed vertices when the file has none)
    unless ``face_normals`` is true, and ``flip_normals`` (the winding reversed and the normals
    turned around, as Mitsuba negates both its normals). A mirroring ``to_world`` needs nothing:
    Mitsuba's face normals follow the mirrored winding, its computed normals too, and the file's
    normals go by the inverse transpose, as wrt's do."""
    table = {"type": "mesh", "file": p.file("a mesh", "mesh file")}
    if p.type == "serialized":
        table["shape_index"] = p.number("shape_index", 0, integer=True)  # the loader checks its range
    if not p.boolean("face_normals", False):
        table["shading"] = "smooth"
    if p.boolean("flip_normals", False):
        table["flip_normals"] = True
    return placed(table, matrix)


def quadric(doc: Document, p: Plugin, matrix: np.ndarray, front: float, emitters: list[Element]) -> dict:
    """The ``disk`` or ``cylinder`` table of a Mitsuba ``disk`` (the unit disk at z = 0, front +z)
    or ``cylinder`` (the open tube of ``radius`` from ``p0`` to ``p1``, normals outward): the same
    shape through ``to_world`` as a transform matrix; ``flip_normals`` turns the disk's normal or
    the tube's normals around. Warns about an emitter on a tube that is not right circular, which
    Mitsuba samples by a wrong area (it warns about the transform too)."""
    if p.type == "disk":
        if front < 0:  # wrt's frame of normal -z has y negated: negate it back, so that uv stays Mitsuba's
            matrix = matrix @ np.diag([1.0, -1.0, 1.0, 1.0])
        return placed({"type": "disk", "center": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, front], "radius": 1.0}, matrix)
    radius = p.number("radius", 1.0, above=0.0)
    p0, p1 = p.vector("p0", (0.0, 0.0, 0.0)), p.vector("p1", (0.0, 0.0, 1.0))
    if np.array_equal(p0, p1):
        raise doc.error(p.element, "p0 and p1 coincide: the cylinder has no length")
    if emitters:
        axis = (p1 - p0) / np.linalg.norm(p1 - p0)
        tangent = coordinate_system(axis)
        edges = matrix[:3, :3] @ np.column_stack([radius * tangent, radius * np.cross(axis, tangent), p1 - p0])
        gram = edges.T @ edges
        lengths = np.sqrt(np.diag(gram))
        skew = np.abs(gram - np.diag(np.diag(gram))) / np.outer(lengths, lengths)
        if skew.max() > 1e-6 or abs(lengths[0] - lengths[1]) > 1e-6 * lengths[0]:
            doc.warn(
                emitters[0],
                "Mitsuba samples this emitter as a right circular tube, but to_world shears the cylinder or "
                "scales its radius unequally: Mitsuba's image of its light is biased, wrt's follows the exact tube",
            )
    table = {"type": "cylinder", "p0": as_list(p0), "p1": as_list(p1), "radius": radius}
    return placed({**table, "flip_normals": True} if front < 0 else table, matrix)


def placed(table: dict, matrix: np.ndarray) -> dict:
    """A shape table with a non-identity ``to_world`` as its ``transform = { matrix = [16
    numbers, row-major] }``, applied after the table's own placement (docs/scene-format.md)."""
    if np.array_equal(matrix, np.eye(4)):
        return table
    return {**table, "transform": {"matrix": [x for row in matrix for x in as_list(row)]}}
