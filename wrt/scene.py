"""The scene model: validated, immutable dataclasses that every later stage reads.

Units and frames: world space is right-handed, lengths in scene units, angles in degrees,
colours linear RGB. ``wrt.loader`` builds these from a TOML file and is the only place that
validates; code downstream trusts them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

INTEGRATORS = ("raycast", "whitted", "path")
SAMPLERS = ("independent", "stratified", "sobol")
FILTERS = ("box", "tent", "gaussian")
DIELECTRIC_SHADOWS = ("opaque", "filtered")


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
    ambient: tuple[float, float, float] = (0.0, 0.0, 0.0)  # non-physical lecture term, times albedo
    background: tuple[float, float, float] = (0.0, 0.0, 0.0)  # radiance of rays leaving the scene
    exterior_ior: float = 1.0  # index of refraction of the medium filling the scene
    dielectric_shadows: str = "opaque"  # or "filtered": shadow rays pass dielectrics, Beer-attenuated
    min_throughput: float = 1e-4  # whitted branches whose throughput falls below this are cut
    sampler: str = "sobol"  # random numbers (wrt.kernels.sampling): independent, stratified or sobol
    filter: str = "box"  # pixel filter (wrt.kernels.camera): box, tent or gaussian


@dataclass(frozen=True)
class Camera:
    """``[camera]``: ``fov`` is the VERTICAL field of view in degrees; a thin lens of
    ``aperture_radius`` (world units, 0 = pinhole) focused at ``focus_distance`` from the lens
    along the viewing direction (None: the distance to ``look_at``); camera samples are taken at
    times uniform in ``shutter`` = (open, close), in the time unit of shape velocities."""

    origin: tuple[float, float, float]
    look_at: tuple[float, float, float]
    up: tuple[float, float, float] = (0.0, 1.0, 0.0)
    fov: float = 45.0
    aperture_radius: float = 0.0
    focus_distance: float | None = None
    shutter: tuple[float, float] = (0.0, 0.0)

    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(forward, right, up')`` unit vectors (float64) of the camera convention."""
        forward = np.subtract(self.look_at, self.origin, dtype=np.float64)
        forward /= np.linalg.norm(forward)
        right = np.cross(forward, np.asarray(self.up, dtype=np.float64))
        right /= np.linalg.norm(right)
        return forward, right, np.cross(right, forward)


MATERIAL_TYPES = ("diffuse", "phong", "mirror", "dielectric", "glossy")


@dataclass(frozen=True)
class Material:
    """``[[material]]``: a named surface description. Colours are linear RGB.

    ``albedo``: diffuse reflectance (diffuse, phong); ``specular`` and ``exponent``: the
    energy-normalised Phong lobe; ``reflectance``: mirror colour, or the constant Fresnel factor
    of a glossy (GGX) conductor of ``roughness`` alpha; ``ior``, ``transmittance``
    (fraction left after one scene unit inside, Beer-Lambert) and ``priority`` (which medium wins
    where dielectrics overlap): dielectric; ``emission``: radiance in W/(m^2 sr) leaving the front side.
    """

    name: str
    type: str = "diffuse"
    albedo: tuple[float, float, float] = (0.8, 0.8, 0.8)
    specular: tuple[float, float, float] = (0.0, 0.0, 0.0)
    exponent: float = 32.0
    reflectance: tuple[float, float, float] = (1.0, 1.0, 1.0)
    ior: float = 1.5
    transmittance: tuple[float, float, float] = (1.0, 1.0, 1.0)
    priority: int = 0
    roughness: float = 0.2
    emission: tuple[float, float, float] = (0.0, 0.0, 0.0)


STILL = (0.0, 0.0, 0.0)
"""The default ``velocity`` of a shape: at time ``tau`` a shape is displaced by ``velocity * tau``
(scene units per unit time)."""


@dataclass(frozen=True)
class Sphere:
    center: tuple[float, float, float]
    radius: float
    material: int
    velocity: tuple[float, float, float] = STILL


@dataclass(frozen=True)
class Plane:
    """Unbounded plane through ``point``; ``normal`` is unit length."""

    point: tuple[float, float, float]
    normal: tuple[float, float, float]
    material: int
    velocity: tuple[float, float, float] = STILL


@dataclass(frozen=True)
class Triangle:
    vertices: tuple[tuple[float, float, float], ...]
    material: int
    velocity: tuple[float, float, float] = STILL


@dataclass(frozen=True)
class Polygon:
    """Planar simple or non-simple polygon (even-odd rule); ``normal`` is unit (Newell's method)."""

    vertices: tuple[tuple[float, float, float], ...]
    normal: tuple[float, float, float]
    material: int
    velocity: tuple[float, float, float] = STILL


@dataclass(frozen=True, eq=False)
class Mesh:
    """Triangle mesh read from ``file`` with its ``transform`` already applied to ``vertices``."""

    file: str
    vertices: np.ndarray  # (V, 3) float64, world space
    faces: np.ndarray  # (F, 3) int32
    material: int
    velocity: tuple[float, float, float] = STILL


@dataclass(frozen=True)
class PointLight:
    """Isotropic point light; ``intensity`` is radiant intensity in W/sr (RGB)."""

    position: tuple[float, float, float]
    intensity: tuple[float, float, float]
    type: str = "point"


@dataclass(frozen=True)
class DirectionalLight:
    """Light from infinitely far away; ``direction`` is where the light travels (unit),
    ``irradiance`` in W/m^2 (RGB) on a surface facing it."""

    direction: tuple[float, float, float]
    irradiance: tuple[float, float, float]
    type: str = "directional"


@dataclass(frozen=True)
class SpotLight:
    """Point light restricted to a cone around ``direction`` (unit): full ``intensity`` (W/sr)
    within ``beam_width`` degrees of the axis, falling linearly in angle to 0 at ``cutoff_angle``
    (Mitsuba 3's spot profile)."""

    position: tuple[float, float, float]
    direction: tuple[float, float, float]
    intensity: tuple[float, float, float]
    cutoff_angle: float = 20.0
    beam_width: float = 15.0
    type: str = "spot"


@dataclass(frozen=True)
class AreaLight:
    """Parallelogram light ``corner + u edge_u + v edge_v`` (u, v in [0, 1]) emitting ``radiance``
    (W/(m^2 sr)) from the side of ``cross(edge_u, edge_v)`` only; a surface that reflects nothing."""

    corner: tuple[float, float, float]
    edge_u: tuple[float, float, float]
    edge_v: tuple[float, float, float]
    radiance: tuple[float, float, float]
    type: str = "area"


@dataclass(frozen=True)
class SphereLight:
    """Sphere emitting ``radiance`` (W/(m^2 sr)) outward; a surface that reflects nothing."""

    center: tuple[float, float, float]
    radius: float
    radiance: tuple[float, float, float]
    type: str = "sphere"


@dataclass(frozen=True)
class EnvironmentLight:
    """Constant ``radiance`` (W/(m^2 sr)) arriving from every direction, seen by rays that leave."""

    radiance: tuple[float, float, float]
    type: str = "environment"


SURFACE_LIGHTS = (AreaLight, SphereLight)
DELTA_LIGHTS = (PointLight, DirectionalLight, SpotLight)


Shape = Sphere | Plane | Triangle | Polygon | Mesh


@dataclass(frozen=True, eq=False)
class Scene:
    """A whole scene. ``shapes`` keep file order: a shape's index is its ``object_id``."""

    render: RenderSettings
    camera: Camera
    materials: tuple[Material, ...]
    shapes: tuple[Shape, ...]
    lights: tuple = ()
    path: str = "<memory>"
