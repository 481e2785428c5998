"""The interactive page of a ray recording (``wrt rays --html``): one self-contained HTML file.

The drawing's data go into the page as JSON (base64 float32 arrays): the blocks of
``wrt.rayview.ray_blocks`` as triangles, lines and balls, in the colours and proportions of
``wrt.rayview.draw``, with its legend, title and start view. The page itself, a small WebGL viewer
of plain JavaScript (no library, no request: it opens from a mail attachment or a USB stick,
offline), is the template ``PAGE_TEMPLATE`` beside this module, package data. See docs/rays.md
for the choice against pyvista's trame export.
"""

from __future__ import annotations

import base64
import html
import json
import re
from importlib import resources

import numpy as np
import pyvista as pv

from .files import write_atomic
from .rays import RayTree
from .rayview import (
    BACKGROUND,
    BVH_COLOR,
    GEOMETRY_OPACITY,
    HIT_FRACTION,
    KIND_COLORS,
    LIGHT_BACK_COLOR,
    LIGHT_COLOR,
    NORMAL_COLOR,
    NORMAL_FRACTION,
    PLANE_OPACITY,
    SCATTER_COLOR,
    _drawing_box,
    _folder_of,
    _legend,
    _rgb255,
    _title,
    ray_blocks,
    view_camera,
)
from .scene import PointLight, ProjectorLight, SpotLight

PAGE_TEMPLATE = "rayview_page.html"  # %TITLE% and %DATA% are filled in

HTML_LINE_WIDTH = 3.0  # CSS pixels of the segments' lines
HTML_LIGHT_POINT = 14.0  # CSS pixels of the ball of a point or spot light


def _b64(values, dtype) -> str:
    return base64.b64encode(np.ascontiguousarray(values, dtype=dtype).tobytes()).decode("ascii")


def _rgba(hex_color: str, alpha: float = 1.0) -> list[int]:
    return [*_rgb255(hex_color).tolist(), round(255 * alpha)]


def _cells(cells: np.ndarray) -> list[np.ndarray]:
    """The point lists of VTK's padded cell array ``[n, i0, .., n, ...]``."""
    out, k = [], 0
    while k < len(cells):
        out.append(cells[k + 1 : k + 1 + cells[k]])
        k += cells[k] + 1
    return out


def _html_mesh(mesh: pv.PolyData, color: str | np.ndarray, *, opacity=1.0, lit=True, back: str | None = None):
    """A surface for the page: triangles (fans of each polygon), one colour."""
    if len(mesh.faces) == 0:
        return None
    if mesh.is_all_triangles:
        index = mesh.faces.reshape(-1, 4)[:, 1:].ravel()
    else:
        index = np.asarray([[c[0], c[k], c[k + 1]] for c in _cells(mesh.faces) for k in range(1, len(c) - 1)]).ravel()
    rgb = _rgb255(color) if isinstance(color, str) else np.asarray(color)
    return {
        "positions": _b64(mesh.points, "<f4"),
        "indices": _b64(index, "<u4"),
        "color": rgb[:3].tolist(),
        "opacity": opacity,
        "lit": lit,
        "back": None if back is None else _rgb255(back).tolist(),
    }


def _html_lines(starts: np.ndarray, ends: np.ndarray, rgba: np.ndarray, width: float):
    """Line segments for the page: ``rgba`` (n, 2, 4) uint8 at their two ends."""
    if not len(starts):
        return None
    points = np.stack([starts, ends], axis=1)
    return {"positions": _b64(points, "<f4"), "colors": _b64(rgba, "u1"), "width": width}


def _polydata_lines(mesh: pv.PolyData) -> tuple[np.ndarray, np.ndarray]:
    pairs = np.array([[c[k], c[k + 1]] for c in _cells(mesh.lines) for k in range(len(c) - 1)], dtype=int)
    pairs = pairs.reshape(-1, 2)
    return mesh.points[pairs[:, 0]], mesh.points[pairs[:, 1]]


def _html_scene(tree: RayTree, view: tuple[float, float] | None) -> dict:
    """What the page draws: the blocks of ``ray_blocks`` as triangles, lines and balls, in the same
    colours and proportions as ``draw``, the legend, the title and the start view."""
    blocks = ray_blocks(tree)
    _, size = _drawing_box(tree)
    meshes, lines = [], []
    for name, mesh in zip(blocks["geometry"].keys(), blocks["geometry"]):
        opacity = PLANE_OPACITY if name.endswith("plane") else GEOMETRY_OPACITY
        if mesh.n_cells:
            meshes.append(_html_mesh(mesh, mesh.cell_data["color"][0], opacity=opacity))
    for name, mesh in zip(blocks["lights"].keys(), blocks["lights"]):
        back = LIGHT_BACK_COLOR if name.endswith(" area") else None
        meshes.append(_html_mesh(mesh, LIGHT_COLOR, lit=False, back=back))
        if mesh.n_lines:
            starts, ends = _polydata_lines(mesh)
            lines.append(_html_lines(starts, ends, np.tile(_rgba(LIGHT_COLOR), (len(starts), 2, 1)), 2.0))
    for part in ("segments", "misses"):
        block = blocks[part]
        if block.n_cells:
            starts, ends = block.points[0::2], block.points[1::2]
            if part == "misses":
                rgba = block.point_data["rgba"].reshape(-1, 2, 4)
            else:
                rgba = np.concatenate([block.cell_data["color"], np.full((block.n_cells, 1), 255)], axis=1)
                rgba = np.repeat(rgba[:, None], 2, axis=1)
            lines.append(_html_lines(starts, ends, rgba, HTML_LINE_WIDTH))
    for part, color, alpha, width in (("camera", "#303030", 1.0, 1.5), ("bvh", BVH_COLOR, 0.6, 1.0)):
        if blocks[part].n_cells:
            starts, ends = _polydata_lines(blocks[part])
            lines.append(_html_lines(starts, ends, np.tile(_rgba(color, alpha), (len(starts), 2, 1)), width))
    hits, scatterings = blocks["hits"], blocks["scatterings"]
    balls, arrows = None, None
    if hits.n_points or scatterings.n_points:
        colors = [_rgb255(KIND_COLORS[k]) for k in hits.point_data["kind"]] if hits.n_points else []
        colors += [_rgb255(SCATTER_COLOR)] * scatterings.n_points
        points = np.concatenate([np.asarray(b.points).reshape(-1, 3) for b in (hits, scatterings)])
        balls = {
            "positions": _b64(points, "<f4"),
            "colors": _b64(np.array(colors, dtype=np.uint8), "u1"),
            "radius": HIT_FRACTION * size,
        }
    if hits.n_points:
        arrows = {
            "positions": _b64(hits.points, "<f4"),
            "directions": _b64(hits.point_data["facing_normal"], "<f4"),
            "length": NORMAL_FRACTION * size,
            "color": _rgb255(NORMAL_COLOR).tolist(),
        }
    points = (PointLight, SpotLight, ProjectorLight)
    spots = [light.position for light in tree.scene.lights if isinstance(light, points)]
    camera = view_camera(tree, view)
    scene_up = np.asarray(tree.scene.camera.up, dtype=np.float64)
    return {
        "title": _title(tree),
        "legend": _legend(tree, blocks),
        "background": BACKGROUND,
        "meshes": [m for m in meshes if m is not None],
        "lines": [line for line in lines if line is not None],
        "balls": balls,
        "arrows": arrows,
        "lights": {
            "positions": _b64(np.asarray(spots, dtype=np.float64).reshape(-1, 3), "<f4"),
            "color": _rgb255(LIGHT_COLOR).tolist(),
            "pixels": HTML_LIGHT_POINT,
        },
        "view": {
            "eye": camera.eye.tolist(),
            "focus": camera.focus.tolist(),
            "up": camera.up.tolist(),
            "fov": camera.fov,
            "aspect": camera.aspect,
            "sceneUp": (scene_up / np.linalg.norm(scene_up)).tolist(),
        },
    }


def html_page(tree: RayTree, view: tuple[float, float] | None = None) -> str:
    """The interactive page of the recording: one self-contained HTML document (see ``save_html``)."""
    data = json.dumps(_html_scene(tree, view), separators=(",", ":"), allow_nan=False)
    data = data.replace("<", "\\u003c")  # nothing in it can close the script element
    fields = {"TITLE": html.escape(_title(tree).splitlines()[0]), "DATA": data}
    page = resources.files("wrt").joinpath(PAGE_TEMPLATE).read_text(encoding="utf-8")
    return re.sub(r"%(TITLE|DATA)%", lambda m: fields[m[1]], page)


def save_html(tree: RayTree, path: str, view: tuple[float, float] | None = None) -> None:
    """Write the interactive page of the recording to ``path``: one HTML file that any browser with
    WebGL opens offline, with no other file and no network (the scene, the ray trees coloured by
    kind, the hit points and normals, the lights, the legend; drag to turn, wheel or pinch to
    zoom). It starts from the view of ``draw`` (``view``: see there). Written by
    ``wrt.files.write_atomic`` (every byte checked; a failed write keeps the old file)."""
    _folder_of(path)
    write_atomic(path, html_page(tree, view))
