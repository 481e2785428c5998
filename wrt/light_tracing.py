"""What the light tracer (``integrator = "ptracer"``, ``wrt.kernels.ptracer``) needs of a scene on
the host: the scenes it refuses, and the bounding sphere lights at infinity send their rays from.

Refused, each with one ``SceneError`` naming the entry (what it would otherwise render wrong):

- participating media (as Mitsuba 3's ``ptracer``: its light paths are traced in vacuum);
- a light inside a dielectric (light paths start outside every dielectric): a point, spot or
  projector light's position, an area light's centre, a sphere light's centre;
- an emissive shape the light tracer cannot emit from: only the emissive primitives the path
  integrator samples (``wrt.emitting``: unmoving triangles, meshes, polygons and spheres, outside
  instances) send light paths; others (planes, disks, cylinders, moving shapes, groups' shapes)
  would look dark;
- an infinite plane with a directional or environment light: those send their rays from a disk
  around the bounded scene, which covers no infinite plane.
"""

from __future__ import annotations

import numpy as np

from .bake import media_at
from .emitting import emitting_shapes
from .errors import SceneError
from .scene import (
    AreaLight,
    DirectionalLight,
    EnvironmentLight,
    Plane,
    PointLight,
    ProjectorLight,
    Scene,
    SphereLight,
    SpotLight,
)

ANALYTIC_SIDES = 16  # rim polygon sides bounding a disk or tube in ``bounding_sphere``


def check_light_tracer(source: str, scene: Scene) -> None:
    """Refuse (``SceneError`` naming ``source``) what the light tracer cannot render (see the module)."""
    if scene.media:
        raise SceneError(
            source,
            "medium[0]",
            "type",
            'the ptracer integrator traces no participating media (as Mitsuba 3\'s ptracer): use integrator = "path"',
            scene.media[0].type,
        )
    for i, light in enumerate(scene.lights):
        point = _light_point(light)
        inside = [] if point is None else media_at(scene, point)
        if inside:
            raise SceneError(
                source,
                f"light[{i}]",
                "type",
                f"lies inside shape[{inside[-1]}], a dielectric: the ptracer integrator starts light paths outside "
                'every dielectric (use integrator = "path")',
                light.type,
            )
    sampled = emitting_shapes(scene)
    for i, shape in enumerate(scene.shapes):
        if i not in sampled and max(scene.materials[shape.material].emission) > 0.0:
            raise SceneError(
                source,
                f"shape[{i}]",
                "material",
                "emits, but the ptracer integrator sends light paths from emissive triangles, meshes, polygons and "
                'spheres that do not move and are not instances only (use integrator = "path")',
                scene.materials[shape.material].name,
            )
    for g, group in enumerate(scene.groups):
        if any(max(scene.materials[shape.material].emission) > 0.0 for shape in group.shapes):
            raise SceneError(
                source,
                f"group[{g}]",
                "shape",
                "has an emissive shape: the ptracer integrator sends no light paths from instances "
                '(use integrator = "path")',
            )
    at_infinity = [i for i, light in enumerate(scene.lights) if isinstance(light, (DirectionalLight, EnvironmentLight))]
    planes = [i for i, shape in enumerate(scene.shapes) if isinstance(shape, Plane)]
    if at_infinity and planes:
        raise SceneError(
            source,
            f"shape[{planes[0]}]",
            "type",
            f"an infinite plane with light[{at_infinity[0]}] ({scene.lights[at_infinity[0]].type}): the ptracer "
            'integrator sends its rays over the bounded scene only (use a polygon, or integrator = "path")',
            "plane",
        )


def _light_point(light) -> np.ndarray | None:
    """The point of a light that must lie outside every dielectric; None for lights at infinity."""
    if isinstance(light, (PointLight, SpotLight, ProjectorLight)):
        return np.asarray(light.position, dtype=np.float64)
    if isinstance(light, AreaLight):
        return np.asarray(light.corners(), dtype=np.float64).mean(axis=0)
    if isinstance(light, SphereLight):
        return np.asarray(light.center, dtype=np.float64)
    return None


def bounding_sphere(scene: Scene) -> tuple[tuple[float, float, float], float]:
    """``(center, radius)`` of a sphere holding every bounded shape, light surface, point-like light
    and the camera, a little larger (1% and 1e-3 units) so that rays from outside it start clear
    of everything."""
    points = [scene.surface_points(ANALYTIC_SIDES), np.asarray([scene.camera.origin], dtype=np.float64)]
    points += [p[None] for p in (_light_point(light) for light in scene.lights) if p is not None]
    p = np.concatenate(points)
    lo, hi = p.min(axis=0), p.max(axis=0)
    center = 0.5 * (lo + hi)
    radius = float(np.linalg.norm(p - center, axis=1).max())
    return tuple(float(x) for x in center), 1.01 * radius + 1e-3
