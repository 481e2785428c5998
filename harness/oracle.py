"""The geometry oracle: the scene's shapes and light surfaces rasterised by pyvista (VTK/OpenGL),
independently of the ray tracer, with the same camera; and a three-quarter overview with the
camera frustum.

Every shape is drawn unlit in a flat colour that encodes its ``object_id`` exactly, without
anti-aliasing, so the rasterised image decodes back to an id per pixel; so is every light that is
a surface (an area light's parallelogram, a sphere light's sphere, both sides), with the id the
renderer gives light k, ``-2 - k``. The ray tracer's ``object_id`` AOV (pixel-centre rays) and the
decoded ids are then shown through the same palette and compared by SSIM. Agreement checks the
camera convention, every intersection routine and the mesh transforms against an independent
implementation.
"""

from __future__ import annotations

import colorsys
import os
import threading

import numpy as np

from wrt.imageio import write_srgb_png
from wrt.scene import AreaLight, Cylinder, Disk, Instance, Plane, Polygon, Scene, Sphere, SphereLight, Triangle

QUADRIC_SIDES = 512  # vertices of the rims of disks and tubes: chords within 2e-5 of the radius (1 - cos(pi/512))
ID_BITS = 24  # an id travels as one 8-bit RGB colour

# VTK render windows are not safe to use from several threads at once (``wrt matrix --jobs``)
_VTK_LOCK = threading.Lock()


def _offscreen_environment() -> None:
    """VTK's wheel renders off screen through EGL when there is no display (docs/install-notes.md)."""
    if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")


def palette(ids: np.ndarray) -> np.ndarray:
    """Linear RGB colours (..., 3) of ``object_id`` values (any shape): shape ids >= 0 in saturated
    hues (golden-ratio sequence), the surface of light k (id ``-2 - k``) in pale tints (the same
    sequence started at a warm yellow, a third of the saturation, full value), black for -1 (a miss)."""
    ids = np.asarray(ids)
    light = ids <= -2
    k = np.where(light, -2 - ids, ids)
    hue = (np.where(light, 0.12, 0.0) + k * 0.618033988749895) % 1.0
    saturation, value = np.where(light, 0.25, 0.75), np.where(light, 1.0, 0.95)
    rgb = np.array([colorsys.hsv_to_rgb(*hsv) for hsv in zip(hue.ravel(), saturation.ravel(), value.ravel())])
    rgb = rgb.reshape(*ids.shape, 3)
    rgb[ids == -1] = 0.0
    return rgb.astype(np.float32)


def _encode(object_id: int) -> tuple[float, float, float]:
    """The exact 8-bit colour carrying ``object_id + 1`` as a 24-bit two's complement number: black
    is the background (-1), light ids (``-2 - k``) are the colours from white down."""
    v = (object_id + 1) % (1 << ID_BITS)
    return ((v >> 16) & 255) / 255.0, ((v >> 8) & 255) / 255.0, (v & 255) / 255.0


def _decode(image: np.ndarray) -> np.ndarray:
    rgb = np.asarray(image[..., :3], dtype=np.int64)
    v = (rgb[..., 0] << 16) | (rgb[..., 1] << 8) | rgb[..., 2]
    return np.where(v >= 1 << (ID_BITS - 1), v - (1 << ID_BITS), v) - 1


def scene_extent(scene: Scene) -> tuple[np.ndarray, float]:
    """Centre and radius of a sphere around the bounded shapes, the light surfaces and the camera."""
    planes = [np.asarray(s.point, dtype=float) for s in scene.shapes if isinstance(s, Plane)]
    camera = [np.asarray(scene.camera.origin, dtype=float), np.asarray(scene.camera.look_at, dtype=float)]
    p = np.concatenate([np.array(camera + planes), scene.surface_points(QUADRIC_SIDES)])
    center = 0.5 * (p.min(axis=0) + p.max(axis=0))
    return center, float(np.linalg.norm(p.max(axis=0) - p.min(axis=0))) / 2 + 1e-9


def _shape_mesh(s, scene: Scene, plane_size: float):
    """pyvista PolyData of one shape (an instance: its group's shapes, merged, through its transform)."""
    import pyvista as pv

    if isinstance(s, Sphere):
        return _sphere(pv, s.center, s.radius)
    if isinstance(s, Plane):
        return pv.Plane(
            center=s.point, direction=s.normal, i_size=plane_size, j_size=plane_size, i_resolution=1, j_resolution=1
        )
    if isinstance(s, Triangle):
        return pv.PolyData(np.asarray(s.vertices, dtype=float), faces=[3, 0, 1, 2])
    if isinstance(s, Polygon):
        # triangulate in 2D (ear clipping of VTK's triangle filter handles non-convex outlines)
        v = np.asarray(s.vertices, dtype=float)
        return pv.PolyData(v, faces=[len(v), *range(len(v))]).triangulate()
    if isinstance(s, (Disk, Cylinder)):
        vertices, triangles = s.triangles(QUADRIC_SIDES)
        return pv.PolyData(vertices, faces=np.column_stack([np.full(len(triangles), 3), triangles]).ravel())
    if isinstance(s, Instance):
        members = [_shape_mesh(member, scene, plane_size) for member in scene.groups[s.group].shapes]
        return pv.merge(members).transform(s.matrix, inplace=False)
    faces = np.column_stack([np.full(len(s.faces), 3), s.faces]).ravel()
    return pv.PolyData(np.asarray(s.vertices, dtype=float), faces=faces)


def _sphere(pv, center, radius: float):
    """A finely tessellated sphere: its chords come within 6e-4 radius of the surface (1 - cos(pi/96))."""
    return pv.Sphere(radius=radius, center=center, theta_resolution=96, phi_resolution=64)


def light_meshes(scene: Scene) -> dict:
    """pyvista PolyData of every light that is a surface, by its index k in ``[[light]]`` (its
    ``object_id`` is ``-2 - k``): an area light's parallelogram (one quad, wound toward its emitting
    side), a sphere light's sphere, tessellated as finely as sphere shapes."""
    import pyvista as pv

    meshes = {}
    for k, light in enumerate(scene.lights):
        if isinstance(light, SphereLight):
            meshes[k] = _sphere(pv, light.center, light.radius)
        elif isinstance(light, AreaLight):
            meshes[k] = pv.PolyData(light.corners(), faces=[4, 0, 1, 2, 3])
    return meshes


def shape_meshes(scene: Scene, plane_size: float):
    """pyvista PolyData of every shape, in ``[[shape]]`` order, where it is at mid-shutter (the time
    of the pixel-centre rays that write the AOVs). Planes become square patches of side
    ``plane_size`` around their point; spheres, disks and tubes are finely tessellated; an
    instance is its group's shapes, placed."""
    mid_shutter = 0.5 * (scene.camera.shutter[0] + scene.camera.shutter[1])
    meshes = []
    for s in scene.shapes:
        m = _shape_mesh(s, scene, plane_size)
        if any(s.velocity):
            m = m.translate(np.asarray(s.velocity) * mid_shutter, inplace=False)
        meshes.append(m)
    return meshes


def _camera(plotter, scene: Scene, far: float) -> None:
    """VTK's camera as the scene's: its clipping range, like the scene's clip planes, is measured
    along the view direction from the camera plane; ``far`` bounds what is drawn."""
    camera = scene.camera
    cam = plotter.camera
    cam.position = camera.origin
    cam.focal_point = camera.look_at
    cam.up = camera.up
    if camera.type == "orthographic":
        cam.parallel_projection = True
        cam.parallel_scale = camera.width / 2 * scene.render.height / scene.render.width  # half the view's height
    else:
        cam.view_angle = camera.fov  # VTK's view angle is vertical, like the scene format's
    cam.clipping_range = (max(camera.near_clip, far * 1e-5), min(camera.far_clip, far))


def rasterize_ids(scene: Scene) -> np.ndarray:
    """Per-pixel ``object_id`` (H, W) of the scene rasterised by pyvista with the scene's camera: the
    shape's index, ``-2 - k`` on the surface of light k, -1 where nothing is drawn."""
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
        meshes = dict(enumerate(shape_meshes(scene, plane_size=2000 * reach)))
        meshes.update({-2 - k: mesh for k, mesh in light_meshes(scene).items()})
        for object_id, mesh in meshes.items():
            plotter.add_mesh(
                mesh, color=_encode(object_id), lighting=False, show_scalar_bar=False, smooth_shading=False
            )
        _camera(plotter, scene, far=3000 * reach)
        return plotter.screenshot(return_img=True)
    finally:
        plotter.close()


def overview(scene: Scene, path: str, size: tuple[int, int] = (480, 360)) -> None:
    """A three-quarter view of the scene, shapes and light surfaces in their ``palette`` colours, with
    the camera's frustum drawn, written to ``path`` (PNG, by ``wrt.imageio.write_srgb_png``): from
    behind the camera, to its right and above, the scene camera's ``up`` vertical on screen."""
    _offscreen_environment()
    import pyvista as pv

    center, radius = scene_extent(scene)
    with _VTK_LOCK:
        _overview(scene, pv, path, size, center, radius)


def _overview(scene, pv, path, size, center, radius) -> None:
    plotter = pv.Plotter(off_screen=True, window_size=size)
    try:
        plotter.set_background("white")
        for i, mesh in enumerate(shape_meshes(scene, plane_size=4 * radius)):
            plotter.add_mesh(
                mesh,
                color=tuple(palette(np.array([i]))[0]),
                opacity=0.35 if isinstance(scene.shapes[i], Plane) else 0.9,
            )
        for k, mesh in light_meshes(scene).items():
            plotter.add_mesh(mesh, color=tuple(palette(np.array([-2 - k]))[0]), lighting=False)
        origin = np.asarray(scene.camera.origin)
        length = float(np.linalg.norm(np.asarray(scene.camera.look_at) - origin))
        starts, directions = scene.camera.corner_rays(scene.render.width / scene.render.height)
        corners = starts + length * directions
        lines = [pv.Line(a, b) for a, b in zip(starts, corners)]
        for ring in (starts, corners):  # the view's outline on the camera plane (perspective: a point) and at look_at
            lines += [pv.Line(ring[k], ring[(k + 1) % 4]) for k in range(4)]
        for line in lines:
            plotter.add_mesh(line, color="black", line_width=2)
        plotter.add_mesh(pv.Sphere(radius=0.02 * radius, center=origin), color="black")
        up = np.asarray(scene.camera.up, dtype=float) / np.linalg.norm(scene.camera.up)
        _, right, _ = scene.camera.basis()
        behind = np.cross(right, up)  # horizontal, away from where the camera looks
        diagonal = 1.0 * right + 0.8 * up + 1.2 * behind  # 27 degrees above the horizon
        plotter.camera.position = center + 2.6 * radius * diagonal / np.linalg.norm(diagonal)
        plotter.camera.focal_point = center
        plotter.camera.up = up
        write_srgb_png(path, plotter.screenshot(return_img=True)[..., :3])
    finally:
        plotter.close()
