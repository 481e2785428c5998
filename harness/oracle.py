"""The geometry oracle: the scene's shapes rasterised by pyvista (VTK/OpenGL), independently of
the ray tracer, with the same camera; and a three-quarter overview with the camera frustum.

Every shape is drawn unlit in a flat colour that encodes its ``object_id`` exactly, without
anti-aliasing, so the rasterised image decodes back to an id per pixel; the ray tracer's
``object_id`` AOV (pixel-centre rays) and the decoded ids are then shown through the same palette
and compared by SSIM. Agreement checks the camera convention, every intersection routine and the
mesh transforms against an independent implementation.
"""

from __future__ import annotations

import colorsys
import math
import os
import threading

import numpy as np

from wrt.scene import Mesh, Plane, Polygon, Scene, Sphere, Triangle

# VTK render windows are not safe to use from several threads at once (``wrt matrix --jobs``)
_VTK_LOCK = threading.Lock()


def _offscreen_environment() -> None:
    """VTK's wheel renders off screen through EGL when there is no display (docs/install-notes.md)."""
    if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")


def palette(ids: np.ndarray) -> np.ndarray:
    """Distinct linear RGB colours for shape ids (golden-ratio hues), black for -1 (a miss)."""
    ids = np.asarray(ids)
    hue = (ids * 0.618033988749895) % 1.0
    rgb = np.array([colorsys.hsv_to_rgb(h, 0.75, 0.95) for h in hue.ravel()]).reshape(*ids.shape, 3)
    rgb[ids < 0] = 0.0
    return rgb.astype(np.float32)


def _encode(object_id: int) -> tuple[float, float, float]:
    """The exact 8-bit colour carrying ``object_id + 1`` (0 is the background)."""
    v = object_id + 1
    return ((v >> 16) & 255) / 255.0, ((v >> 8) & 255) / 255.0, (v & 255) / 255.0


def _decode(image: np.ndarray) -> np.ndarray:
    rgb = np.asarray(image[..., :3], dtype=np.int64)
    return ((rgb[..., 0] << 16) | (rgb[..., 1] << 8) | rgb[..., 2]) - 1


def scene_extent(scene: Scene) -> tuple[np.ndarray, float]:
    """Centre and radius of a sphere around the bounded shapes and the camera."""
    points = [np.asarray(scene.camera.origin), np.asarray(scene.camera.look_at)]
    for s in scene.shapes:
        if isinstance(s, Sphere):
            points += [np.asarray(s.center) - s.radius, np.asarray(s.center) + s.radius]
        elif isinstance(s, (Triangle, Polygon)):
            points += list(np.asarray(s.vertices))
        elif isinstance(s, Mesh):
            points += [s.vertices.min(axis=0), s.vertices.max(axis=0)]
        elif isinstance(s, Plane):
            points.append(np.asarray(s.point))
    p = np.asarray(points, dtype=float)
    center = 0.5 * (p.min(axis=0) + p.max(axis=0))
    return center, float(np.linalg.norm(p.max(axis=0) - p.min(axis=0))) / 2 + 1e-9


def shape_meshes(scene: Scene, plane_size: float):
    """pyvista PolyData of every shape, in ``[[shape]]`` order, where it is at mid-shutter (the time
    of the pixel-centre rays that write the AOVs). Planes become square patches of side
    ``plane_size`` around their point; spheres are finely tessellated."""
    import pyvista as pv

    mid_shutter = 0.5 * (scene.camera.shutter[0] + scene.camera.shutter[1])
    meshes = []
    for s in scene.shapes:
        if isinstance(s, Sphere):
            m = pv.Sphere(radius=s.radius, center=s.center, theta_resolution=96, phi_resolution=64)
        elif isinstance(s, Plane):
            m = pv.Plane(
                center=s.point, direction=s.normal, i_size=plane_size, j_size=plane_size, i_resolution=1, j_resolution=1
            )
        elif isinstance(s, Triangle):
            m = pv.PolyData(np.asarray(s.vertices, dtype=float), faces=[3, 0, 1, 2])
        elif isinstance(s, Polygon):
            # triangulate in 2D (ear clipping of VTK's triangle filter handles non-convex outlines)
            v = np.asarray(s.vertices, dtype=float)
            m = pv.PolyData(v, faces=[len(v), *range(len(v))]).triangulate()
        else:
            faces = np.column_stack([np.full(len(s.faces), 3), s.faces]).ravel()
            m = pv.PolyData(np.asarray(s.vertices, dtype=float), faces=faces)
        if any(s.velocity):
            m = m.translate(np.asarray(s.velocity) * mid_shutter, inplace=False)
        meshes.append(m)
    return meshes


def _camera(plotter, scene: Scene, far: float) -> None:
    cam = plotter.camera
    cam.position = scene.camera.origin
    cam.focal_point = scene.camera.look_at
    cam.up = scene.camera.up
    cam.view_angle = scene.camera.fov  # VTK's view angle is vertical, like the scene format's
    cam.clipping_range = (far * 1e-5, far)


def rasterize_ids(scene: Scene) -> np.ndarray:
    """Per-pixel shape id (H, W) of the scene rasterised by pyvista with the scene's camera; -1 where
    nothing is drawn."""
    _offscreen_environment()
    import pyvista as pv

    w, h = scene.render.width, scene.render.height
    center, radius = scene_extent(scene)
    reach = np.linalg.norm(center - np.asarray(scene.camera.origin)) + radius
    with _VTK_LOCK:
        return _decode(_rasterize(scene, pv, w, h, reach))


def _rasterize(scene: Scene, pv, w: int, h: int, reach: float) -> np.ndarray:
    plotter = pv.Plotter(off_screen=True, window_size=(w, h))
    try:
        plotter.set_background((0, 0, 0))
        plotter.disable_anti_aliasing()
        for i, mesh in enumerate(shape_meshes(scene, plane_size=2000 * reach)):
            plotter.add_mesh(mesh, color=_encode(i), lighting=False, show_scalar_bar=False, smooth_shading=False)
        _camera(plotter, scene, far=3000 * reach)
        return plotter.screenshot(return_img=True)
    finally:
        plotter.close()


def overview(scene: Scene, path: str, size: tuple[int, int] = (480, 360)) -> None:
    """A three-quarter view of the scene with the camera's frustum drawn, written to ``path`` (PNG)."""
    _offscreen_environment()
    import pyvista as pv

    center, radius = scene_extent(scene)
    forward, right, up = scene.camera.basis()
    origin = np.asarray(scene.camera.origin)
    with _VTK_LOCK:
        _overview(scene, pv, path, size, center, radius, forward, right, up, origin)


def _overview(scene, pv, path, size, center, radius, forward, right, up, origin) -> None:
    plotter = pv.Plotter(off_screen=True, window_size=size)
    try:
        plotter.set_background("white")
        for i, mesh in enumerate(shape_meshes(scene, plane_size=4 * radius)):
            plotter.add_mesh(
                mesh,
                color=tuple(palette(np.array([i]))[0]),
                opacity=0.35 if isinstance(scene.shapes[i], Plane) else 0.9,
            )
        length = float(np.linalg.norm(np.asarray(scene.camera.look_at) - origin))
        th = math.tan(math.radians(scene.camera.fov) / 2)
        aspect = scene.render.width / scene.render.height
        corners = [
            origin + length * (forward + sx * th * aspect * right + sy * th * up)
            for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))
        ]
        lines = [pv.Line(origin, c) for c in corners] + [pv.Line(corners[k], corners[(k + 1) % 4]) for k in range(4)]
        for line in lines:
            plotter.add_mesh(line, color="black", line_width=2)
        plotter.add_mesh(pv.Sphere(radius=0.02 * radius, center=origin), color="black")
        diagonal = np.array([1.0, 0.8, 1.2])
        plotter.camera.position = center + 2.6 * radius * diagonal / np.linalg.norm(diagonal)
        plotter.camera.focal_point = center
        plotter.camera.up = (0, 1, 0)
        plotter.screenshot(path)
    finally:
        plotter.close()
