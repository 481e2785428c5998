"""The scene model: validated, immutable dataclasses that every later stage reads.

Units and frames: world space is right-handed, lengths in scene units, angles in degrees,
colours linear RGB. ``wrt.loader`` builds these from a TOML file and is the only place that
validates; code downstream trusts them.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

INTEGRATORS = ("raycast",)


@dataclass(frozen=True)
class RenderSettings:
    """``[render]``: image size in pixels, samples per pixel, path length and integrator.

    ``max_depth`` counts ray segments, the camera ray included (1 = what the camera ray hits).
    """

    width: int = 640
    height: int = 480
    spp: int = 1
    max_depth: int = 8
    seed: int = 0
    integrator: str = "raycast"


@dataclass(frozen=True)
class Camera:
    """``[camera]``: pinhole camera; ``fov`` is the VERTICAL field of view in degrees."""

    origin: tuple[float, float, float]
    look_at: tuple[float, float, float]
    up: tuple[float, float, float] = (0.0, 1.0, 0.0)
    fov: float = 45.0

    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(forward, right, up')`` unit vectors (float64) of the camera convention."""
        forward = np.subtract(self.look_at, self.origin, dtype=np.float64)
        forward /= np.linalg.norm(forward)
        right = np.cross(forward, np.asarray(self.up, dtype=np.float64))
        right /= np.linalg.norm(right)
        return forward, right, np.cross(right, forward)


@dataclass(frozen=True)
class Material:
    """``[[material]]``: a named surface description; ``albedo`` is linear RGB in [0, 1]."""

    name: str
    type: str = "diffuse"
    albedo: tuple[float, float, float] = (0.8, 0.8, 0.8)


@dataclass(frozen=True)
class Sphere:
    center: tuple[float, float, float]
    radius: float
    material: int


@dataclass(frozen=True)
class Plane:
    """Unbounded plane through ``point``; ``normal`` is unit length."""

    point: tuple[float, float, float]
    normal: tuple[float, float, float]
    material: int


@dataclass(frozen=True)
class Triangle:
    vertices: tuple[tuple[float, float, float], ...]
    material: int


@dataclass(frozen=True)
class Polygon:
    """Planar simple or non-simple polygon (even-odd rule); ``normal`` is unit (Newell's method)."""

    vertices: tuple[tuple[float, float, float], ...]
    normal: tuple[float, float, float]
    material: int


@dataclass(frozen=True, eq=False)
class Mesh:
    """Triangle mesh read from ``file`` with its ``transform`` already applied to ``vertices``."""

    file: str
    vertices: np.ndarray  # (V, 3) float64, world space
    faces: np.ndarray  # (F, 3) int32
    material: int


@dataclass(frozen=True)
class Light:
    """``[[light]]``: kept as given; the integrators that use lights define their parameters."""

    type: str
    params: dict = field(default_factory=dict)


Shape = Sphere | Plane | Triangle | Polygon | Mesh


@dataclass(frozen=True, eq=False)
class Scene:
    """A whole scene. ``shapes`` keep file order: a shape's index is its ``object_id``."""

    render: RenderSettings
    camera: Camera
    materials: tuple[Material, ...]
    shapes: tuple[Shape, ...]
    lights: tuple[Light, ...] = ()
    path: str = "<memory>"
