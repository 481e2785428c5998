"""Ray trees in 3D with pyvista: draw a ``wrt.rays.RayTree`` over its scene, or export it as VTK.

``ray_blocks(tree)`` turns a recording into a ``pyvista.MultiBlock`` (world space):

=========== ======================================================================================
block       contents
=========== ======================================================================================
geometry    one surface per ``[[shape]]`` (named ``shape[i] TYPE``; planes as a finite patch around
            the rays), cell data ``color`` (RGB, 0-255)
segments    one line per segment that ends (on a surface or at a light), cell data ``row`` (the
            segment's row in the tree), ``kind``, ``pixel_x``, ``pixel_y``, ``sample``, ``depth``,
            ``parent``, ``shape``, ``entering``, ``throughput`` (3), ``color`` (RGB, 0-255);
            field data ``kind_names``
misses      one line per escaped segment, ``MISS_FRACTION`` of the drawing's size long, point data
            ``rgba`` fading from the kind's colour to transparent; cell data as ``segments``
hits        the hit points, point data ``normal`` (unit geometric normal), ``facing_normal`` (flipped
            to the side the ray came from), ``kind``, ``shape``, ``entering``, ``row``
scatterings the scattering events in participating media (the ends of ``RayTree.in_medium``
            segments), point data ``depth``, ``row``
lights      one piece per light that has a place, named ``light[k] TYPE`` (k: its index in
            ``[[light]]``), cell data ``color``: point and spot lights as a vertex, a directional
            light as a line along the direction it travels, a sphere light as its sphere, an area
            light as its parallelogram (one quad wound toward its emitting side, cell data
            ``normal``: the unit emitting normal, ``cross(edge_u, edge_v)``) plus ``light[k] area
            emitting side``, an arrow from its centre along that normal
camera      the rays through the image corners and the view's outline: a pyramid from the camera
            position, or a box from the camera plane (orthographic)
bvh         with ``trace_rays(..., bvh=True)``: the box of every BVH node a segment's closest-hit
            query visited, as 12 edge lines each, cell data ``node`` and ``row`` (the segment)
=========== ======================================================================================

``draw`` puts them in a plotter: geometry semi-transparent, segments coloured by kind with a
legend, hit points as small spheres, normals as short arrows on the side the ray came from (the
normal reflection and refraction use), misses fading out, visited BVH boxes as thin lines, light
surfaces opaque and unlit in a light colour (an area light's back, which emits nothing, darker). ``save_view``
renders off screen to a PNG (EGL when there is no display), ``show`` opens a window, ``export``
writes the blocks to a ``.vtm`` that ParaView and ``pyvista.read`` open, ``save_html`` writes the
same drawing as one self-contained web page with a small WebGL viewer of its own (turn, move,
zoom; no network, no other file).

The view all of them start from is ``view_camera``: it frames the tree's vertices
(``framed_vertices``: not the lights, not the far hits) and looks at the plane the tree lies in
(``_plane_normal``), from above, the scene's up vertical on screen. See docs/rays.md.
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass

import numpy as np
import pyvista as pv

from wrt.kernels.record import CAMERA, EMITTED

from .errors import WrtError
from .files import atomic_path, check_report_folder, check_writable, report_folder
from .imageio import write_srgb_png
from .loader import load_scene
from .rays import DEFAULT_CAPACITY, RayTree, grid_pixels, trace_rays
from .scene import (
    AreaLight,
    Cylinder,
    DirectionalLight,
    Disk,
    Instance,
    Mesh,
    Plane,
    PointLight,
    ProjectorLight,
    Sphere,
    SphereLight,
    SpotLight,
)

# colour of each kind (indices of wrt.kernels.record.KIND_NAMES)
KIND_COLORS = (
    "#1f5fbf",
    "#f0a202",
    "#c1121f",
    "#2a9d3f",
    "#8e44ad",
    "#e056b5",
    "#16a3b8",
    "#7a5c3e",
    "#d4b000",
    "#4cc9f0",
    "#6c757d",
)
GEOMETRY_OPACITY = 0.25
PLANE_OPACITY = 0.12  # planes are large: fainter, so they do not veil the rays
NORMAL_COLOR = "#404040"
LIGHT_COLOR = "#ffd000"
LIGHT_BACK_COLOR = "#8c7a3a"  # the back of an area light, which emits nothing
BVH_COLOR = "#7f8c9a"
SCATTER_COLOR = "#5a4fcf"  # a scattering event in a participating medium
MISS_FRACTION = 0.25  # misses are drawn this fraction of the drawing's size long (_drawing_box)
HIT_FRACTION = 0.006  # radius of the hit spheres
QUADRIC_SIDES = 96  # vertices of the rims of disks and tubes
NORMAL_FRACTION = 0.06  # length of the normal arrows
EMITTING_FRACTION = 0.15  # length of the arrows on the emitting side of area lights
MAX_ELEVATION = 60.0  # degrees above the scene's horizon the automatic view may look down from
VIEW_FOV = 30.0  # vertical field of view of the view, degrees (VTK's default)
VIEW_ASPECT = 4 / 3  # width / height the view is framed for: the PNG's 1280 x 960
FRAME_FILL = 0.9  # the framed vertices fill this share of the picture's width or height (centred)
FAR_FACTOR = 2.0  # hits further from the camera than this many times the median hit are not framed
DIRECTION_WEIGHT = 0.1  # of the segments' directions against the vertices' spread, in choosing the view (_plane_normal)
BACKGROUND = "white"


def _rgb255(hex_color: str) -> np.ndarray:
    return np.array([int(hex_color[k : k + 2], 16) for k in (1, 3, 5)], dtype=np.uint8)


def _material_color(scene, shape) -> np.ndarray:
    """Linear base colour of a shape, shown as is (0-255): albedo, or a fixed tint for mirrors and glass."""
    mat = scene.materials[shape.material]
    if mat.type == "mirror":
        return np.array([190, 195, 205], dtype=np.uint8)
    if mat.type == "dielectric":
        return np.array([150, 200, 230], dtype=np.uint8)
    return (np.clip(mat.albedo, 0, 1) * 255).astype(np.uint8)


def tree_vertices(tree: RayTree) -> np.ndarray:
    """The vertices of the ray trees, (n, 3) float64, each once: where the camera rays start and
    where a segment ends on a surface (hit points, the blockers of shadow rays). Not the lights
    a shadow ray reaches, nor where an escaped ray is drawn to."""
    points = np.concatenate([tree.origin[_roots(tree)], tree.end[tree.hit]]).astype(np.float64)
    return np.unique(points, axis=0)


def _roots(tree: RayTree) -> np.ndarray:
    """Where each path starts: its camera rays, and the light tracer's rays leaving a light."""
    return np.isin(tree.kind, (CAMERA, EMITTED))


def _camera_distance(tree: RayTree, rows: np.ndarray) -> np.ndarray:
    """Distance of the ends of segments ``rows`` from the start of their path (``_roots``)."""
    key = (tree.pixel[:, 1].astype(np.int64) * tree.scene.render.width + tree.pixel[:, 0]) * tree.samples + tree.sample
    cameras = np.flatnonzero(_roots(tree))
    order = np.argsort(key[cameras], kind="stable")
    found = cameras[order][np.searchsorted(key[cameras][order], key[rows]).clip(0, max(len(cameras) - 1, 0))]
    return np.linalg.norm(tree.end[rows].astype(np.float64) - tree.origin[found], axis=1)


def framed_vertices(tree: RayTree) -> np.ndarray:
    """The vertices of ``tree_vertices`` that the automatic view frames: the paths' starts
    (``_roots``), and every hit point but the far ones, those more than ``FAR_FACTOR`` times as far
    from their path's start as the median hit (a ray that grazes the floor and meets it hundreds of
    units away, a wall at the horizon). Their segments are still drawn, running out of the
    picture."""
    rows = np.flatnonzero(tree.hit)
    if len(rows) and _roots(tree).any():
        distance = _camera_distance(tree, rows)
        rows = rows[distance <= FAR_FACTOR * np.median(distance)]
    points = np.concatenate([tree.origin[_roots(tree)], tree.end[rows]]).astype(np.float64)
    return np.unique(points, axis=0)


def _box_size(points: np.ndarray) -> float:
    return float(np.linalg.norm(points.max(axis=0) - points.min(axis=0))) if len(points) else 0.0


def _bounds(tree: RayTree) -> tuple[np.ndarray, np.ndarray]:
    """World-space box around the camera, every segment end that is not a miss, the bounded shapes
    and the light surfaces: what the plane patches must cover."""
    points = [np.asarray(tree.scene.camera.origin, dtype=np.float64)[None], tree.origin, tree.end[~tree.escaped]]
    points.append(tree.scene.surface_points(QUADRIC_SIDES))
    points = np.concatenate([np.asarray(p, dtype=np.float64).reshape(-1, 3) for p in points])
    return points.min(axis=0), points.max(axis=0)


def _drawing_box(tree: RayTree) -> tuple[np.ndarray, float]:
    """``(centre, size)`` of the drawing: the box of the framed vertices (``framed_vertices``), or of
    the whole scene (``_bounds``) when they are one point (every ray escaped). Glyphs (hit balls,
    normals, the camera's pyramid, misses) are drawn in proportion to ``size``, directional lights
    at its edge."""
    framed = framed_vertices(tree)
    size = _box_size(framed)
    if size > 0:
        return (framed.min(axis=0) + framed.max(axis=0)) / 2, size
    lo, hi = _bounds(tree)
    return (lo + hi) / 2, float(np.linalg.norm(hi - lo)) or 1.0


def _shape_mesh(shape, centre: np.ndarray, size: float, scene) -> pv.PolyData:
    if isinstance(shape, Instance):
        members = [_shape_mesh(member, centre, size, scene) for member in scene.groups[shape.group].shapes]
        return pv.merge(members).transform(shape.matrix, inplace=False)
    if isinstance(shape, (Sphere, SphereLight)):
        return pv.Sphere(radius=shape.radius, center=shape.center, theta_resolution=48, phi_resolution=32)
    if isinstance(shape, Plane):
        n = np.asarray(shape.normal)
        on_plane = centre - np.dot(centre - np.asarray(shape.point), n) * n
        return pv.Plane(center=on_plane, direction=n, i_size=size, j_size=size, i_resolution=1, j_resolution=1)
    if isinstance(shape, Mesh):
        faces = np.hstack([np.full((len(shape.faces), 1), 3), shape.faces]).ravel()
        return pv.PolyData(np.asarray(shape.vertices, dtype=np.float64), faces)
    if isinstance(shape, (Disk, Cylinder)):
        vertices, triangles = shape.triangles(QUADRIC_SIDES)
        return pv.PolyData(vertices, np.hstack([np.full((len(triangles), 1), 3), triangles]).ravel())
    verts = np.asarray(shape.vertices, dtype=np.float64)  # triangle or polygon (non-convex: triangulated)
    return pv.PolyData(verts, np.concatenate([[len(verts)], np.arange(len(verts))])).triangulate()


def _light_blocks(scene, centre: np.ndarray, size: float) -> pv.MultiBlock:
    """The ``lights`` block (see the module docstring); ``centre`` and ``size``: the drawing's box, where
    directional lights are drawn."""
    pieces = {}
    for k, light in enumerate(scene.lights):
        name = f"light[{k}] {light.type}"
        if isinstance(light, (PointLight, SpotLight, ProjectorLight)):
            pieces[name] = pv.PolyData(np.asarray([light.position], dtype=np.float64))
        elif isinstance(light, DirectionalLight):
            d = np.asarray(light.direction) / np.linalg.norm(light.direction)
            pieces[name] = pv.Line(centre - 0.6 * size * d, centre - 0.45 * size * d)
        elif isinstance(light, SphereLight):
            pieces[name] = _shape_mesh(light, centre, size, scene)
        elif isinstance(light, AreaLight):
            corners = light.corners()
            normal = np.cross(light.edge_u, light.edge_v)
            normal /= np.linalg.norm(normal)
            pieces[name] = pv.PolyData(corners, faces=[4, 0, 1, 2, 3])
            pieces[name].cell_data["normal"] = normal[None]
            pieces[f"{name} emitting side"] = pv.Arrow(
                start=corners.mean(axis=0),
                direction=normal,
                tip_length=0.35,
                tip_radius=0.12,
                shaft_radius=0.04,
                scale=EMITTING_FRACTION * size,
            )
    lights = pv.MultiBlock()
    for name, mesh in pieces.items():
        mesh.cell_data["color"] = np.tile(_rgb255(LIGHT_COLOR), (mesh.n_cells, 1))
        lights[name] = mesh
    return lights


def _lines(starts: np.ndarray, ends: np.ndarray) -> pv.PolyData:
    n = len(starts)
    points = np.empty((2 * n, 3), dtype=np.float64)
    points[0::2], points[1::2] = starts, ends
    lines = np.column_stack([np.full(n, 2), 2 * np.arange(n), 2 * np.arange(n) + 1]).ravel()
    return pv.PolyData(points, lines=lines) if n else pv.PolyData()


def _segment_data(mesh: pv.PolyData, tree: RayTree, rows: np.ndarray) -> None:
    if not len(rows):
        return
    mesh.cell_data["row"] = rows
    mesh.cell_data["kind"] = tree.kind[rows]
    mesh.cell_data["pixel_x"] = tree.pixel[rows, 0]
    mesh.cell_data["pixel_y"] = tree.pixel[rows, 1]
    mesh.cell_data["sample"] = tree.sample[rows]
    mesh.cell_data["depth"] = tree.depth[rows]
    mesh.cell_data["parent"] = tree.parent[rows]
    mesh.cell_data["shape"] = tree.shape[rows]
    mesh.cell_data["entering"] = tree.entering[rows].astype(np.uint8)
    mesh.cell_data["throughput"] = tree.throughput[rows]
    mesh.cell_data["color"] = np.array([_rgb255(KIND_COLORS[k]) for k in tree.kind[rows]], dtype=np.uint8).reshape(
        -1, 3
    )
    mesh.field_data["kind_names"] = np.array(RayTree.KIND_NAMES)


def ray_blocks(tree: RayTree) -> pv.MultiBlock:
    """The recording and its scene as named pyvista blocks (see the module docstring)."""
    lo, hi = _bounds(tree)  # plane patches cover every segment end
    scene = tree.scene
    centre, size = _drawing_box(tree)

    geometry = pv.MultiBlock()
    for i, shape in enumerate(scene.shapes):
        mesh = _shape_mesh(shape, (lo + hi) / 2, 1.2 * float(np.linalg.norm(hi - lo)) or 1.0, tree.scene)
        mesh.cell_data["color"] = np.tile(_material_color(scene, shape), (mesh.n_cells, 1))
        geometry[f"shape[{i}] {type(shape).__name__.lower()}"] = mesh

    ends = np.flatnonzero(~tree.escaped)
    segments = _lines(tree.origin[ends], tree.end[ends])
    _segment_data(segments, tree, ends)

    escaped = np.flatnonzero(tree.escaped)
    misses = _lines(tree.origin[escaped], tree.origin[escaped] + MISS_FRACTION * size * tree.direction[escaped])
    _segment_data(misses, tree, escaped)
    if len(escaped):
        rgba = np.repeat(misses.cell_data["color"], 2, axis=0)
        misses.point_data["rgba"] = np.column_stack([rgba, np.tile([255, 0], len(escaped))]).astype(np.uint8)

    hit_rows = np.flatnonzero(tree.hit)
    hits = pv.PolyData(tree.end[hit_rows].astype(np.float64)) if len(hit_rows) else pv.PolyData()
    if len(hit_rows):
        hits.point_data["normal"] = tree.normal[hit_rows]
        hits.point_data["facing_normal"] = np.where(tree.entering[hit_rows, None], 1, -1) * tree.normal[hit_rows]
        hits.point_data["kind"] = tree.kind[hit_rows]
        hits.point_data["shape"] = tree.shape[hit_rows]
        hits.point_data["entering"] = tree.entering[hit_rows].astype(np.uint8)
        hits.point_data["row"] = hit_rows

    scatter_rows = np.flatnonzero(tree.in_medium)
    scatterings = pv.PolyData(tree.end[scatter_rows].astype(np.float64)) if len(scatter_rows) else pv.PolyData()
    if len(scatter_rows):
        scatterings.point_data["depth"] = tree.depth[scatter_rows]
        scatterings.point_data["row"] = scatter_rows

    starts, directions = scene.camera.corner_rays(scene.render.width / scene.render.height)
    view = np.concatenate([starts, starts + 0.08 * size * directions])  # a pyramid, or a box (orthographic)
    edges = [[k, 4 + k] for k in range(4)] + [[ring + k, ring + (k + 1) % 4] for ring in (0, 4) for k in range(4)]
    camera = pv.PolyData(view, lines=np.column_stack([np.full(len(edges), 2), edges]).ravel())

    blocks = pv.MultiBlock()
    blocks["geometry"] = geometry
    blocks["segments"] = segments
    blocks["misses"] = misses
    blocks["hits"] = hits
    blocks["scatterings"] = scatterings
    blocks["lights"] = _light_blocks(scene, centre, size)
    blocks["camera"] = camera
    blocks["bvh"] = _box_edges(tree)
    return blocks


BOX_EDGES = np.array([[0, 1], [1, 3], [3, 2], [2, 0], [4, 5], [5, 7], [7, 6], [6, 4], [0, 4], [1, 5], [2, 6], [3, 7]])


def _box_edges(tree: RayTree) -> pv.PolyData:
    """The boxes of the visited BVH nodes (``tree.visit_node``): 12 lines each, cell data ``node``, ``row``."""
    if len(tree.visit_node) == 0:
        return pv.PolyData()
    lo, hi = tree.bvh_lo[tree.visit_node].astype(np.float64), tree.bvh_hi[tree.visit_node].astype(np.float64)
    corner = np.array([[(i >> k) & 1 for k in range(3)] for i in range(8)], dtype=bool)  # bit k: hi along axis k
    points = np.where(corner[None], hi[:, None], lo[:, None]).reshape(-1, 3)
    edges = (BOX_EDGES[None] + 8 * np.arange(len(lo))[:, None, None]).reshape(-1, 2)
    boxes = pv.PolyData(points, lines=np.column_stack([np.full(len(edges), 2), edges]).ravel())
    boxes.cell_data["node"] = np.repeat(tree.visit_node, 12)
    boxes.cell_data["row"] = np.repeat(tree.visit_row, 12)
    return boxes


def _plane_normal(tree: RayTree) -> np.ndarray | None:
    """Unit normal of the plane the ray tree lies closest to, or None when it lies on one line.

    The spread of the framed vertices (``framed_vertices``: the camera, the hit points but the far
    ones) and, at ``DIRECTION_WEIGHT`` of its weight, that of the segments' unit directions (each
    segment counted once whatever its length: shadow rays toward lights, misses) are added, each
    scaled to a total of 1. The normal is the axis along which the sum is least: the view along it
    spreads the vertices most, and where they lie on a line (a camera ray and its shadow rays) it
    turns about that line to foreshorten the other segments least."""
    vertices = framed_vertices(tree)
    directions = tree.direction.astype(np.float64)
    spread = np.zeros((3, 3))
    for points, weight in ((vertices - vertices.mean(axis=0), 1.0), (directions, DIRECTION_WEIGHT)):
        scatter = points.T @ points
        if np.trace(scatter) > 0:
            spread += weight * scatter / np.trace(scatter)
    size, axes = np.linalg.eigh(spread)  # ascending
    if size[1] < 1e-6 * size[2]:
        return None
    return axes[:, 0]


def _auto_view(tree: RayTree, forward: np.ndarray, up: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit direction toward the eye and view-up that show the ray trees flattest on screen with the
    scene's ``up`` (unit) vertical: the normal of the plane the tree lies closest to (``_plane_normal``),
    from above, lowered to at most ``MAX_ELEVATION`` above the horizon (looking straight down: from
    behind the scene camera, ``forward``); a side view when they lie on one line. The view is never
    less than 90 - ``MAX_ELEVATION`` degrees from edge-on to that plane. The view-up is ``up``
    projected on the view plane."""
    normal = _plane_normal(tree)
    if normal is None:  # one line: look from its side, level with it
        line = tree.direction[0].astype(np.float64)
        normal = np.cross(line, up)
        normal = normal if np.linalg.norm(normal) > 1e-6 else np.cross(line, forward)
    normal /= np.linalg.norm(normal)
    if np.dot(normal, up) < -1e-6 or (abs(np.dot(normal, up)) <= 1e-6 and np.dot(normal, forward) > 0):
        normal = -normal
    horizontal = normal - np.dot(normal, up) * up
    if np.linalg.norm(horizontal) < 1e-3:  # looking straight down: its azimuth would be noise
        horizontal = np.dot(forward, up) * up - forward
    horizontal /= np.linalg.norm(horizontal)
    elevation = min(np.arcsin(np.clip(np.dot(normal, up), 0.0, 1.0)), np.radians(MAX_ELEVATION))
    normal = np.cos(elevation) * horizontal + np.sin(elevation) * up
    view_up = up - np.dot(up, normal) * normal
    return normal, view_up / np.linalg.norm(view_up)


@dataclass(frozen=True)
class ViewCamera:
    """A perspective view of the drawing (world space, float64).

    Attributes
    ----------
    eye, focus : (3,)
        Where the view looks from, and the point it looks at (what a browser turns the view about).
    up : (3,)
        Unit vector that is vertical on screen, perpendicular to ``focus - eye``.
    fov : float
        Vertical field of view, degrees.
    aspect : float
        Width / height of the picture the view was framed for.
    """

    eye: np.ndarray
    focus: np.ndarray
    up: np.ndarray
    fov: float
    aspect: float

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(xy, in_front)``: ``points`` (n, 3) in picture coordinates (n, 2), (0, 0) the top left
        corner and (1, 1) the bottom right one (in the picture: both in [0, 1]), and whether each
        is in front of the eye."""
        back = self.eye - self.focus
        back = back / np.linalg.norm(back)
        right = np.cross(self.up, back)
        rel = np.asarray(points, dtype=np.float64) - self.eye
        depth = -rel @ back
        t = np.tan(np.radians(self.fov) / 2)
        with np.errstate(divide="ignore", invalid="ignore"):
            x = (rel @ right) / (depth * t * self.aspect)
            y = (rel @ self.up) / (depth * t)
        return np.column_stack([(1 + x) / 2, (1 - y) / 2]), depth > 0


def _frame(points: np.ndarray, towards_eye: np.ndarray, up: np.ndarray, aspect: float) -> ViewCamera:
    """The view along ``-towards_eye`` (unit) with ``up`` vertical in which ``points`` are centred
    and fill ``FRAME_FILL`` of the picture's width or height, none nearer the edge."""
    right = np.cross(up, towards_eye)
    t_y = np.tan(np.radians(VIEW_FOV) / 2)
    t_x = aspect * t_y
    extent = _box_size(points) or 1.0

    def fit(centre):  # the points about ``centre`` along right, up and toward the eye; the eye's distance
        a, b, z = ((points - centre) @ axis for axis in (right, up, towards_eye))
        a_fit, b_fit = np.abs(a) / (FRAME_FILL * t_x), np.abs(b) / (FRAME_FILL * t_y)
        return a, b, z, max(np.max(z + a_fit), np.max(z + b_fit), np.max(z) + 1e-3 * extent)

    centre = (points.min(axis=0) + points.max(axis=0)) / 2
    for _ in range(4):  # perspective: centring moves the picture a little; it settles in a few steps
        a, b, z, distance = fit(centre)
        x, y = a / ((distance - z) * t_x), b / ((distance - z) * t_y)
        centre = centre + ((x.max() + x.min()) * t_x * right + (y.max() + y.min()) * t_y * up) * distance / 2
    a, b, z, distance = fit(centre)
    eye = centre + distance * towards_eye
    middle = (np.max(z) + np.min(z)) / 2  # turn about the middle of the points' depth
    return ViewCamera(eye=eye, focus=centre + middle * towards_eye, up=up, fov=VIEW_FOV, aspect=aspect)


def view_camera(tree: RayTree, view: tuple[float, float] | None = None, *, aspect: float = VIEW_ASPECT) -> ViewCamera:
    """The view ``draw`` and ``save_html`` start from, framed for a picture of ``aspect`` (width /
    height) around the framed vertices (``framed_vertices``; plus where the misses are drawn to
    when those are a single point).

    ``view``: ``(azimuth, elevation)`` in degrees relative to the scene camera: azimuth around its
    up axis (0 = from behind it, 90 = from its right), elevation above its horizon. Default: the
    view that shows the ray tree flattest (``_auto_view``).
    """
    forward, right, up = tree.scene.camera.basis()
    if view is None:
        scene_up = np.asarray(tree.scene.camera.up, dtype=np.float64)
        towards_eye, view_up = _auto_view(tree, forward, scene_up / np.linalg.norm(scene_up))
    else:
        az, el = np.radians(view[0]), np.radians(view[1])
        towards_eye = np.cos(el) * (-np.cos(az) * forward + np.sin(az) * right) + np.sin(el) * up
        view_up = up - np.dot(up, towards_eye) * towards_eye
        if np.linalg.norm(view_up) < 1e-6:  # straight down or up: the scene camera's forward up the picture
            view_up = forward * np.sign(el)
        view_up /= np.linalg.norm(view_up)
    points = framed_vertices(tree)
    if _box_size(points) == 0:
        _, size = _drawing_box(tree)
        points = np.concatenate([points, tree.origin + MISS_FRACTION * size * tree.direction])
    return _frame(points.astype(np.float64), towards_eye, view_up, aspect)


def _legend(tree: RayTree, blocks: pv.MultiBlock) -> list[list[str]]:
    """``[label, colour]`` of each thing drawn: the ray kinds present, normals, lights, BVH boxes."""
    legend = [[RayTree.KIND_NAMES[k], KIND_COLORS[k]] for k in sorted(set(tree.kind.tolist()))]
    if tree.hit.any():
        legend.append(["surface normal", NORMAL_COLOR])
    if tree.in_medium.any():
        legend.append(["scattering in a medium", SCATTER_COLOR])
    if len(blocks["lights"]):
        legend.append(["light", LIGHT_COLOR])
    if any(isinstance(light, AreaLight) for light in tree.scene.lights):
        legend.append(["back of an area light", LIGHT_BACK_COLOR])
    if blocks["bvh"].n_cells:
        legend.append([f"BVH nodes visited ({len(np.unique(tree.visit_node))})", BVH_COLOR])
    return legend


def _title(tree: RayTree) -> str:
    px = ", ".join(f"({x}, {y})" for x, y in tree.pixels[:4]) + (
        f" and {len(tree.pixels) - 4} more" if len(tree.pixels) > 4 else ""
    )
    title = (
        f"{os.path.basename(tree.scene.path)}: pixel{'s' if len(tree.pixels) > 1 else ''} {px}, {tree.samples} "
        f"sample{'s' if tree.samples > 1 else ''}, max_depth {tree.scene.render.max_depth}"
    )
    if tree.truncated:
        title += f"\n(truncated: {len(tree)} of {tree.recorded} segments recorded)"
    return title


def draw(plotter: pv.Plotter, tree: RayTree, view: tuple[float, float] | None = None) -> None:
    """Add the recording to ``plotter`` and aim its camera at the rays.

    ``view``: ``(azimuth, elevation)`` in degrees relative to the scene camera: azimuth around its
    up axis (0 = from behind it, 90 = from its right), elevation above its horizon. Default: the
    view that shows the ray tree flattest, framing its vertices (see ``view_camera``).
    """
    blocks = ray_blocks(tree)
    _, size = _drawing_box(tree)
    plotter.set_background(BACKGROUND)
    for name, mesh in zip(blocks["geometry"].keys(), blocks["geometry"]):
        opacity = PLANE_OPACITY if name.endswith("plane") else GEOMETRY_OPACITY
        plotter.add_mesh(mesh, scalars="color", rgb=True, opacity=opacity, show_scalar_bar=False, smooth_shading=True)
    segments, misses, hits = blocks["segments"], blocks["misses"], blocks["hits"]
    if segments.n_cells:
        plotter.add_mesh(
            segments,
            scalars="color",
            rgb=True,
            line_width=4,
            render_lines_as_tubes=True,
            show_scalar_bar=False,
            lighting=False,
        )
    if misses.n_cells:
        plotter.add_mesh(
            misses,
            scalars="rgba",
            rgb=True,
            line_width=4,
            render_lines_as_tubes=True,
            show_scalar_bar=False,
            lighting=False,
        )
    if hits.n_points:
        colors = np.array([_rgb255(KIND_COLORS[k]) for k in hits.point_data["kind"]], dtype=np.uint8)
        balls = hits.glyph(
            geom=pv.Sphere(radius=HIT_FRACTION * size, theta_resolution=12, phi_resolution=12),
            orient=False,
            scale=False,
        )
        balls.point_data["color"] = np.repeat(colors, balls.n_points // hits.n_points, axis=0)
        plotter.add_mesh(balls, scalars="color", rgb=True, show_scalar_bar=False)
        arrow = pv.Arrow(tip_length=0.3, tip_radius=0.08, shaft_radius=0.025, scale=NORMAL_FRACTION * size)
        plotter.add_mesh(hits.glyph(orient="facing_normal", scale=False, geom=arrow), color=NORMAL_COLOR)
    scatterings = blocks["scatterings"]
    if scatterings.n_points:
        ball = pv.Sphere(radius=HIT_FRACTION * size, theta_resolution=12, phi_resolution=12)
        plotter.add_mesh(scatterings.glyph(geom=ball, orient=False, scale=False), color=SCATTER_COLOR)
    boxes = blocks["bvh"]
    if boxes.n_cells:
        plotter.add_mesh(boxes, color=BVH_COLOR, opacity=0.6, line_width=1, lighting=False)
    lights = blocks["lights"]
    for light in lights:
        plotter.add_mesh(
            light,
            color=LIGHT_COLOR,
            point_size=20,
            render_points_as_spheres=True,
            line_width=6,
            render_lines_as_tubes=True,
            lighting=False,  # lights glow: one flat colour
            backface_params={"color": LIGHT_BACK_COLOR},
        )
    plotter.add_mesh(blocks["camera"], color="#303030", line_width=2)
    legend = _legend(tree, blocks)
    width, height = 0.011 * max(len(label) for label, _ in legend) + 0.04, 0.032 * len(legend)
    box = plotter.add_legend(legend, bcolor="white", border=True, size=(width, height), face="rectangle")
    box.SetPosition(0.99 - width, 0.95 - height)  # upper right (pyvista's loc offsets x by the height)
    title = _title(tree)
    plotter.add_text(title, position="upper_left", font_size=10, color="black")

    camera = view_camera(tree, view, aspect=plotter.window_size[0] / plotter.window_size[1])
    plotter.camera.position = camera.eye
    plotter.camera.focal_point = camera.focus
    plotter.camera.up = camera.up
    plotter.camera.view_angle = camera.fov
    plotter.reset_camera_clipping_range()


def _folder_of(path: str) -> tuple[str, str]:
    """``(folder, file name)`` of an output path whose folder must exist (else ``WrtError``)."""
    folder, name = os.path.split(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise WrtError(f"{path}: folder {folder} does not exist")
    return folder, name


def _has_display() -> bool:
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def _require_display() -> None:
    if not _has_display():
        raise WrtError(
            "an interactive window needs a display, and neither DISPLAY nor WAYLAND_DISPLAY is set (use -o view.png "
            "or --export rays.vtm)"
        )


def _offscreen_backend() -> None:
    """Without a display, VTK must render through EGL (docs/install-notes.md)."""
    if not _has_display():
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")


def save_view(
    tree: RayTree, path: str, size: tuple[int, int] = (1280, 960), view: tuple[float, float] | None = None
) -> None:
    """Render the recording off screen to the PNG ``path`` (``view``: see ``draw``), written and
    checked by ``wrt.imageio.write_srgb_png`` (atomic; a failed write keeps the old file)."""
    _folder_of(path)
    _offscreen_backend()
    plotter = pv.Plotter(off_screen=True, window_size=list(size))
    try:
        draw(plotter, tree, view)
        image = plotter.screenshot(return_img=True)
    finally:
        plotter.close()
    write_srgb_png(path, np.ascontiguousarray(image[..., :3]))


def show(tree: RayTree, view: tuple[float, float] | None = None) -> None:
    """Open an interactive window (needs a display)."""
    _require_display()
    plotter = pv.Plotter(window_size=[1280, 960])
    draw(plotter, tree, view)
    plotter.show()


def pieces_folder(path: str) -> str:
    """The folder of pieces VTK writes beside the multiblock file ``path`` (``rays.vtm``: ``rays/``)."""
    return os.path.splitext(path)[0]


def _leaf_points(blocks: pv.MultiBlock) -> list[int]:
    """The point count of every dataset in ``blocks``, depth first."""
    counts = []
    for block in blocks:
        counts += _leaf_points(block) if isinstance(block, pv.MultiBlock) else [0 if block is None else block.n_points]
    return counts


def export(tree: RayTree, path: str) -> None:
    """Write the blocks of ``ray_blocks`` to a VTK multiblock: the file ``path`` (``.vtm``) and its
    folder of pieces (``pieces_folder``).

    Both are written to temporary places beside them with VTK's errors collected, read back and
    compared with the blocks, and only then moved into place; the pieces folder replaces only a
    folder of pieces wrt wrote (``wrt.files.report_folder``). Any failure (a full disk) is one
    ``WrtError`` and leaves the previous export as it was.
    """
    folder, name = _folder_of(path)
    blocks = ray_blocks(tree)
    stem = os.path.splitext(name)[0]
    with atomic_path(path, suffix=".vtm") as vtm, report_folder(pieces_folder(path), "wrt rays", "--export") as work:
        staged = os.path.join(work, name)
        with pv.vtk_verbosity("off"), pv.VtkErrorCatcher(send_to_logging=False) as catcher:
            blocks.save(staged)
        if catcher.error_events or not os.path.isfile(staged):
            detail = catcher.error_events[0].alert.strip().splitlines()[-1] if catcher.error_events else "no file"
            raise WrtError(f"{path}: cannot write the multiblock ({detail}); the previous export was left as it was")
        with pv.vtk_verbosity("off"), pv.VtkErrorCatcher(send_to_logging=False) as catcher:
            written = pv.read(staged)
        if catcher.error_events or _leaf_points(written) != _leaf_points(blocks):
            raise WrtError(
                f"{path}: the multiblock written is incomplete (is the disk full?); the previous export "
                "was left as it was"
            )
        try:
            for piece in os.listdir(os.path.join(work, stem)):
                os.rename(os.path.join(work, stem, piece), os.path.join(work, piece))
            os.rmdir(os.path.join(work, stem))
            os.replace(staged, vtm)
        except OSError as e:
            raise WrtError(
                f"{path}: cannot write the multiblock ({e.strerror}); the previous export was left as it was"
            )


def run(  # noqa: PLR0913 (the options of wrt rays, keyword-only)
    scene_file: str,
    pixels: list[tuple[int, int]],
    *,
    grid: tuple[int, int] | None = None,
    samples: int = 1,
    max_depth: int | None = None,
    output: str | None = None,
    interactive: bool = False,
    export_path: str | None = None,
    html_path: str | None = None,
    view: tuple[float, float] | None = None,
    device: str = "cpu",
    capacity: int = DEFAULT_CAPACITY,
    show_bvh: bool = False,
) -> int:
    """``wrt rays``: trace the pixels (and a grid of pixels) of a scene file, then draw, show, export
    or write the interactive page."""
    if output is not None:
        if os.path.splitext(output)[1].lower() != ".png":
            raise WrtError(f"{output}: -o writes a picture, use a .png name")
        check_writable(output, option="-o", protect=(scene_file,))
    if export_path is not None:
        if os.path.splitext(export_path)[1].lower() != ".vtm":
            raise WrtError(f"{export_path}: --export writes a VTK multiblock, use a .vtm name")
        check_writable(export_path, option="--export", protect=(scene_file,))
        check_report_folder(pieces_folder(export_path), "--export")
    if html_path is not None:
        if os.path.splitext(html_path)[1].lower() not in (".html", ".htm"):
            raise WrtError(f"{html_path}: --html writes a web page, use a .html name")
        check_writable(html_path, option="--html", protect=(scene_file,))
    if interactive:
        _require_display()
    scene = load_scene(scene_file)
    chosen = list(pixels)
    if grid is not None:
        chosen += grid_pixels(scene.render.width, scene.render.height, *grid)
    tree = trace_rays(
        scene, chosen, samples=samples, max_depth=max_depth, device=device, capacity=capacity, bvh=show_bvh
    )
    counts = np.bincount(tree.kind, minlength=len(RayTree.KIND_NAMES))
    summary = ", ".join(f"{n} {name}" for name, n in zip(RayTree.KIND_NAMES, counts) if n)
    print(
        f"{scene_file}: {len(tree.pixels)} pixel{'s' if len(tree.pixels) > 1 else ''} x {samples} "
        f"sample{'s' if samples > 1 else ''}: {len(tree)} segments ({summary})"
    )
    if tree.truncated:
        print(
            f"wrt: warning: the record buffer was full: kept {len(tree)} of {tree.recorded} segments (raise "
            "--capacity)",
            file=sys.stderr,
        )
    if export_path is not None:
        export(tree, export_path)
        print(f"wrote {export_path}")
    if output is not None:
        save_view(tree, output, view=view)
        print(f"wrote {output}")
    if html_path is not None:
        from .rayhtml import save_html

        save_html(tree, html_path, view=view)
        print(f"wrote {html_path}")
    if interactive:
        show(tree, view=view)
    return 0
