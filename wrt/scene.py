"""The scene model: validated, immutable dataclasses that every later stage reads.

Units and frames: world space is right-handed, lengths in scene units, angles in degrees,
colours linear RGB. ``wrt.loader`` builds these from a TOML file and is the only place that
validates; code downstream trusts them.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field

import numpy as np

from wrt.kernels.materials import TYPES
from wrt.kernels.volumes import MEDIUM_TYPES as MEDIUM_REGISTRY
from wrt.kernels.volumes import PHASE_TYPES as PHASE_REGISTRY

INTEGRATORS = ("raycast", "whitted", "path", "ptracer")
SAMPLERS = ("independent", "stratified", "sobol")
FILTERS = ("box", "tent", "gaussian")
DIELECTRIC_SHADOWS = ("opaque", "filtered")
CAMERA_TYPES = ("perspective", "orthographic")


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
    """``[camera]``: a ``perspective`` camera (``fov`` is the VERTICAL field of view in degrees; a
    thin lens of ``aperture_radius`` (world units, 0 = pinhole) focused at ``focus_distance`` from
    the lens along the viewing direction, None: the distance to ``look_at``) or an
    ``orthographic`` one (parallel rays along the viewing direction from the plane through
    ``origin`` perpendicular to it; ``width``: the view's extent along ``right``, world units).
    Camera rays start ``near_clip`` and end ``far_clip`` world units from the camera plane,
    measured along the viewing direction; camera samples are taken at times uniform in
    ``shutter`` = (open, close), in the time unit of shape velocities."""

    origin: tuple[float, float, float]
    look_at: tuple[float, float, float]
    up: tuple[float, float, float] = (0.0, 1.0, 0.0)
    fov: float = 45.0
    aperture_radius: float = 0.0
    focus_distance: float | None = None
    shutter: tuple[float, float] = (0.0, 0.0)
    type: str = "perspective"
    width: float | None = None  # orthographic only
    near_clip: float = 0.0
    far_clip: float = math.inf

    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(forward, right, up')`` unit vectors (float64) of the camera convention."""
        forward = np.subtract(self.look_at, self.origin, dtype=np.float64)
        forward /= np.linalg.norm(forward)
        right = np.cross(forward, np.asarray(self.up, dtype=np.float64))
        right /= np.linalg.norm(right)
        return forward, right, np.cross(right, forward)

    def corner_rays(self, aspect: float) -> tuple[np.ndarray, np.ndarray]:
        """``(starts, directions)``, (4, 3) float64 each: the rays through the image corners
        (bottom left, bottom right, top right, top left; ``aspect`` = image width / height),
        before clipping. ``dot(direction, forward) = 1``, so ``start + s direction`` is ``s`` from
        the camera plane along the view: the origin and the pinhole rays (perspective), or the
        corners of the view on the camera plane and ``forward`` (orthographic)."""
        forward, right, up = self.basis()
        sx, sy = np.array([-1.0, 1.0, 1.0, -1.0])[:, None], np.array([-1.0, -1.0, 1.0, 1.0])[:, None]
        if self.type == "orthographic":
            half = self.width / 2
            return self.origin + sx * half * right + sy * (half / aspect) * up, np.tile(forward, (4, 1))
        t = math.tan(math.radians(self.fov) / 2)
        return np.tile(
            np.asarray(self.origin, dtype=np.float64), (4, 1)
        ), forward + sx * t * aspect * right + sy * t * up


MATERIAL_TYPES = tuple(name for name in TYPES if name != "emitter")
"""The ``type`` values of ``[[material]]``: every material family's (``wrt.kernels.materials``)."""


@dataclass(frozen=True)
class Material:
    """``[[material]]``: a named surface description. Colours are linear RGB.

    ``albedo``: diffuse reflectance (diffuse, phong); ``specular`` and ``exponent``: the
    energy-normalised Phong lobe; ``reflectance``: mirror colour, or the constant Fresnel factor
    of a glossy (GGX) conductor of ``roughness`` alpha, or the tint of a conductor's Fresnel term;
    ``eta`` and ``k``: a conductor's complex index of refraction ``eta + i k`` (per channel;
    ``roughness`` 0: smooth, else GGX alpha); ``ior``, ``transmittance``
    (fraction left after one scene unit inside, Beer-Lambert) and ``priority`` (which medium wins
    where dielectrics overlap): dielectric; a thin dielectric (a window pane: no medium inside, in the
    scene's ``exterior_ior``) reflects ``reflectance`` times its summed Fresnel term R' at ``ior`` and
    lets ``transmittance`` (a tint, not per unit length) times 1 - R' straight through;
    a rough dielectric is a dielectric (``ior``, ``transmittance``, ``priority``) whose surface is GGX of
    alpha ``roughness``; a plastic (rough plastic: of GGX alpha ``roughness``) is a dielectric coating of
    ``ior`` (over the scene's ``exterior_ior``) reflecting ``reflectance`` times its Fresnel term over a
    Lambertian base of ``albedo``, its internal scattering tinting the base where ``nonlinear``;
    a mask (Mitsuba 3's ``mask``) is the material named ``material`` (not a mask, nor a dielectric or rough
    dielectric) with probability ``opacity`` (in [0, 1]) and else lets the ray straight through, on both sides;
    a blend (Mitsuba 3's ``blendbsdf``) is ``(1 - weight)`` times the first of its two ``materials`` (neither a
    blend, a mask, a dielectric, a rough dielectric nor null) plus ``weight`` (in [0, 1]) times the second;
    ``distribution``: the normal distribution of a rough material's microfacets (glossy, conductor,
    rough dielectric, rough plastic), ``ggx`` (the default) or ``beckmann``, of alpha ``roughness``;
    ``roughness_v``: where given, the microfacets (glossy, conductor, rough dielectric) are
    anisotropic, of alpha ``roughness`` along the shading frame's tangent (the surface's dp/du made
    perpendicular to its shading normal, Mitsuba 3's ``alpha_u``) and ``roughness_v`` along the
    bitangent (``alpha_v``);
    a principled material (Mitsuba 3's ``principled``, Burley's Disney BSDF) of base colour ``albedo``,
    ``roughness`` (Burley's: its GGX alpha is ``roughness^2``), ``anisotropy``, ``metallic``, ``spec_trans``,
    ``spec_tint``, ``sheen``, ``sheen_tint``, ``flatness``, ``clearcoat`` and ``clearcoat_gloss`` (each in
    [0, 1]) over a dielectric interface of ``ior`` (the inside's over the outside's, Mitsuba's ``eta``),
    sampling its lobes by the three ``*_sampling_rate`` weights (``wrt.kernels.materials.principled``);
    a thin principled material (``principled_thin``, Mitsuba's ``principledthin``) is a sheet of the same
    keys but ``metallic`` and the clearcoat, with ``diff_trans`` (in [0, 2]) and four sampling rates;
    ``emission``: radiance in W/(m^2 sr) leaving the front side;
    ``two_sided``: both sides reflect (diffuse, phong, mirror, glossy, conductor; a dielectric always does), else
    the back side (facing away from the surface's normal) reflects nothing, as Mitsuba 3's one-sided BSDFs;
    ``textures``: parameters (``wrt.kernels.textures.SLOTS``) given by a texture over the surface's uv.
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
    roughness_v: float | None = None  # anisotropic: alpha along the bitangent (None: roughness, isotropic)
    distribution: str = "ggx"
    eta: tuple[float, float, float] = (0.0, 0.0, 0.0)
    k: tuple[float, float, float] = (1.0, 1.0, 1.0)
    emission: tuple[float, float, float] = (0.0, 0.0, 0.0)
    two_sided: bool = True
    nonlinear: bool = False
    opacity: float = 0.5
    material: str = ""  # mask: the name of the material it masks
    materials: tuple[str, ...] = ()  # blend: the names of its two materials
    weight: float = 0.5  # blend: the share of its second material
    bump_scale: float = 1.0  # bump-mapped: the height field's scale (Mitsuba's bumpmap scale)
    metallic: float = 0.0  # principled (Mitsuba 3's): the metal's share
    spec_trans: float = 0.0  # principled: the share of the dielectric lobe that transmits
    spec_tint: float = 0.0  # principled: the share of the dielectric reflection tinted by albedo
    sheen: float = 0.0  # principled: the sheen's strength
    sheen_tint: float = 0.0  # principled: the sheen's tint toward albedo
    flatness: float = 0.0  # principled: the diffuse lobe's blend toward fake subsurface scattering
    clearcoat: float = 0.0  # principled: the clearcoat's strength
    clearcoat_gloss: float = 0.0  # principled: the clearcoat's gloss (GTR1 alpha 0.1 at 0, 0.001 at 1)
    anisotropy: float = 0.0  # principled: its main lobe's anisotropy (Mitsuba's anisotropic)
    diffuse_reflectance_sampling_rate: float = 1.0  # principled: the lobes' sampling weights (noise, not image)
    main_specular_sampling_rate: float = 1.0
    clearcoat_sampling_rate: float = 1.0
    diff_trans: float = 0.0  # principled_thin: its diffuse transmission, in [0, 2] (Mitsuba's range)
    specular_reflectance_sampling_rate: float = 1.0  # principled_thin: its lobes' sampling weights
    specular_transmittance_sampling_rate: float = 1.0
    diffuse_transmittance_sampling_rate: float = 1.0
    textures: tuple = ()  # (parameter, wrt.textures texture) pairs; the parameter's own value is its mean

    @property
    def anisotropic(self) -> bool:
        """Its microfacets have two alphas (``roughness_v`` given; a principled one's ``anisotropy``
        not 0 or textured): its lobes lie along the surface's tangent."""
        if self.type in ("principled", "principled_thin"):
            return self.anisotropy != 0.0 or any(key == "anisotropy" for key, _ in self.textures)
        return self.roughness_v is not None

    @property
    def nested(self) -> tuple[str, ...]:
        """The names of the materials it is made of: a mask's material, a blend's two."""
        if self.type == "mask":
            return (self.material,)
        return self.materials if self.type == "blend" else ()


def constituents(material: Material, by_name: Mapping[str, Material]) -> Iterator[Material]:
    """``material`` and every material it is made of (``Material.nested``, through a mask over a
    blend), ``by_name`` naming the scene's materials."""
    yield material
    for name in material.nested:
        yield from constituents(by_name[name], by_name)


MEDIUM_TYPES = tuple(MEDIUM_REGISTRY)
"""The ``type`` values of ``[[medium]]`` (``wrt.kernels.volumes``)."""
PHASE_TYPES = tuple(PHASE_REGISTRY)
"""The ``type`` values of a medium's ``phase`` table."""


@dataclass(frozen=True, eq=False)
class Volume:
    """Values over the unit cube of a frame (``wrt.volumes``): ``values`` ``(z, y, x, channels)``
    (float32, 1 or 3 channels: linear RGB, or grey in all three), ``to_world`` the 4x4 matrix
    placing that cube in the world, ``source`` the ``.vol`` file they came from ('' for a
    constant). Looked up trilinearly between texel centres, clamped at the faces."""

    values: np.ndarray
    to_world: np.ndarray
    source: str = ""


@dataclass(frozen=True)
class Medium:
    """``[[medium]]``: a participating medium (Mitsuba 3's ``homogeneous``): extinction ``sigma_t``
    (per scene unit, times ``scale``) and single-scattering ``albedo`` (``sigma_s / sigma_t``, in
    [0, 1]), both linear RGB; its phase function ``phase`` (``isotropic``, or ``hg``:
    Henyey-Greenstein of asymmetry ``g`` in (-1, 1), ``g > 0`` forward). A shape's ``interior`` and
    ``exterior`` and the camera's ``medium`` name media (``Scene.boundaries``, ``Scene.camera_medium``).
    A ``heterogeneous`` medium's ``sigma_t`` is a `Volume` (whose box bounds the medium) and its
    ``albedo`` one or a constant. ``emission`` (a heterogeneous medium's: also a `Volume`) is the
    radiance it emits per unit length a ray crosses (W/(m^2 sr) per scene unit, not scaled,
    independent of the absorption: Mitsuba 3's ``volumelight``); ``sigma_n`` a heterogeneous
    medium's null density (per unit length), added to the bound it is tracked against: the
    noise only."""

    name: str
    type: str = "homogeneous"
    sigma_t: tuple[float, float, float] | Volume = (1.0, 1.0, 1.0)
    albedo: tuple[float, float, float] | Volume = (0.75, 0.75, 0.75)
    scale: float = 1.0
    phase: str = "isotropic"
    g: float = 0.0
    emission: tuple[float, float, float] | Volume = (0.0, 0.0, 0.0)
    sigma_n: float = 0.0

    @property
    def emissive(self) -> bool:
        return isinstance(self.emission, Volume) or max(self.emission) > 0.0


STILL = (0.0, 0.0, 0.0)
"""The default ``velocity`` of a shape: at time ``tau`` a shape is displaced by ``velocity * tau``
(scene units per unit time)."""


IDENTITY3 = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))


@dataclass(frozen=True)
class Sphere:
    """``to_object``: the rows of the orthogonal matrix taking world offsets from ``center`` to the
    sphere's object axes, in which its texture coordinates and dp/du, dp/dv are measured
    (Mitsuba 3's sphere frame: a ``transform`` that rotates the sphere turns its texture)."""

    center: tuple[float, float, float]
    radius: float
    material: int
    velocity: tuple[float, float, float] = STILL
    to_object: tuple = IDENTITY3


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
    """Planar simple or non-simple polygon (even-odd rule); ``normal`` is unit (Newell's method).
    ``uvs``: texture coordinates (u, v) of its vertices, mapped affinely over its plane (a least-
    squares fit when they are not an affine image of the vertices); None: vertices 0, 1, 2 at
    (0, 0), (1, 0), (1, 1), so that a parallelogram's corners are those of the unit square."""

    vertices: tuple[tuple[float, float, float], ...]
    normal: tuple[float, float, float]
    material: int
    velocity: tuple[float, float, float] = STILL
    uvs: tuple[tuple[float, float], ...] | None = None


@dataclass(frozen=True, eq=False)
class Mesh:
    """Triangle mesh read from ``file`` with its ``transform`` already applied to ``vertices``.

    ``normals`` are its shading normals with ``shading = "smooth"`` (None: flat, the face
    normals): world space, unit, one per vertex, interpolated over each triangle; a zero row is a
    vertex without a normal, whose triangles take their face normal at it. ``uvs`` are the file's
    texture coordinates (read for textured meshes only; None: a triangle's uv is its barycentric
    coordinates (b1, b2) of its second and third corners, as in Mitsuba 3). ``attributes``: the
    file's mesh attributes its material's ``mesh_attribute`` textures read (``vertex_...`` per
    vertex, ``face_...`` per face, 1 or 3 channels)."""

    file: str
    vertices: np.ndarray  # (V, 3) float64, world space
    faces: np.ndarray  # (F, 3) int32
    material: int
    velocity: tuple[float, float, float] = STILL
    normals: np.ndarray | None = None  # (V, 3) float64, world space, unit or zero
    uvs: np.ndarray | None = None  # (V, 2) float64, Mitsuba 3's convention (wrt.meshio.load_mesh)
    attributes: dict = field(default_factory=dict)  # name -> (V, k) or (F, k) float64 (wrt.meshio.ply_attributes)


@dataclass(frozen=True, eq=False)
class Disk:
    """The unit disk (radius 1 in the plane z = 0, front side +z) placed by ``to_world``, an
    invertible affine object-to-world transform (4x4, float64): an ellipse under a non-uniform
    scale. Its z column is the unit front normal (the loader sets it; the disk does not depend on
    it), which the inverse transpose of ``to_world`` gives too."""

    to_world: np.ndarray
    material: int
    velocity: tuple[float, float, float] = STILL

    def triangles(self, sides: int) -> tuple[np.ndarray, np.ndarray]:
        """World-space vertices (V, 3) and triangles (F, 3) of the disk, its rim a polygon of
        ``sides`` vertices on the ellipse (for drawing it: the geometry oracle, ``wrt rays``)."""
        return _placed_triangles(self.to_world, sides, tube=False)


@dataclass(frozen=True, eq=False)
class Cylinder:
    """The open tube (no caps) of radius 1 around the z axis, 0 <= z <= 1, placed by
    ``to_world``, an invertible affine object-to-world transform (4x4, float64). Normals point
    outward (by the inverse transpose of ``to_world``), inward with ``flip_normals``."""

    to_world: np.ndarray
    material: int
    flip_normals: bool = False
    velocity: tuple[float, float, float] = STILL

    def triangles(self, sides: int) -> tuple[np.ndarray, np.ndarray]:
        """World-space vertices (V, 3) and triangles (F, 3) of the tube, its rims polygons of
        ``sides`` vertices on the ellipses (for drawing it: the geometry oracle, ``wrt rays``)."""
        return _placed_triangles(self.to_world, sides, tube=True)


def _placed_triangles(to_world: np.ndarray, sides: int, tube: bool) -> tuple[np.ndarray, np.ndarray]:
    """The unit disk (a fan around its centre) or the unit tube (a band between its rims) with
    rims of ``sides`` vertices, through ``to_world``."""
    phi = 2 * np.pi * np.arange(sides) / sides
    rim = np.column_stack([np.cos(phi), np.sin(phi), np.zeros(sides)])
    k, k1 = np.arange(sides), (np.arange(sides) + 1) % sides
    if tube:
        local = np.concatenate([rim, rim + [0.0, 0.0, 1.0]])
        faces = np.concatenate([np.column_stack([k, k1, sides + k1]), np.column_stack([k, sides + k1, sides + k])])
    else:
        local = np.concatenate([[[0.0, 0.0, 0.0]], rim])
        faces = np.column_stack([np.zeros(sides, dtype=int), 1 + k, 1 + k1])
    return local @ to_world[:3, :3].T + to_world[:3, 3], faces.astype(np.int64)


@dataclass(frozen=True, eq=False)
class Group:
    """``[[group]]``: shapes in their own object space, drawn only where ``instance`` shapes place
    them (Mitsuba's ``shapegroup``); stored once, however many instances there are. Its shapes
    are bounded and still (no planes, instances or velocities) and keep their own materials."""

    name: str
    shapes: tuple


@dataclass(frozen=True, eq=False)
class Instance:
    """``[[shape]] type = "instance"``: ``Scene.groups[group]`` placed by ``matrix``, an invertible
    affine object-to-world transform (4x4, float64); normals follow by its inverse transpose. The
    instance is one shape (one ``object_id``); ``material`` is unused, the group's shapes keep theirs."""

    group: int
    matrix: np.ndarray
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


def light_frame(direction, up) -> np.ndarray:
    """The frame (3x3, float64, rows its x, y and z axes in world space) of a light looking along
    unit ``direction`` with ``up`` (not parallel to it) toward its y: Mitsuba 3's ``lookat``
    (x = up x direction normalised, y = direction x x)."""
    z = np.asarray(direction, dtype=np.float64)
    x = np.cross(np.asarray(up, dtype=np.float64), z)
    x /= np.linalg.norm(x)
    return np.array([x, np.cross(z, x), z])


@dataclass(frozen=True)
class SpotLight:
    """Point light restricted to a cone around ``direction`` (unit): full ``intensity`` (W/sr)
    within ``beam_width`` degrees of the axis, falling linearly in angle to 0 at ``cutoff_angle``
    (Mitsuba 3's spot profile); times ``texture`` (a ``wrt.textures`` texture; None: 1) projected
    through the cone, its square's edges at the cutoff along the frame's x and y (``up`` its y
    side, ``light_frame``), as Mitsuba's spot ``texture``."""

    position: tuple[float, float, float]
    direction: tuple[float, float, float]
    intensity: tuple[float, float, float]
    cutoff_angle: float = 20.0
    beam_width: float = 15.0
    up: tuple[float, float, float] = (0.0, 1.0, 0.0)
    texture: object | None = None
    type: str = "spot"

    def frame(self) -> np.ndarray:
        return light_frame(self.direction, self.up)

    def uv_scale(self) -> tuple[float, float]:
        """``wrt.kernels.lights.delta``'s: the cone's tangent maps to the texture's edges."""
        s = 0.5 / math.tan(math.radians(self.cutoff_angle))
        return (s, s)


@dataclass(frozen=True)
class ProjectorLight:
    """Mitsuba 3's ``projector``: a pinhole at ``position`` projecting its ``irradiance`` texture
    (a ``wrt.textures`` texture, linear RGB) times ``scale`` along unit ``direction``, ``up`` the
    image's top (``light_frame``), ``fov`` the vertical field of view in degrees (as the camera's),
    the horizontal one following the texture's aspect ratio (``aspect``). A plane facing it at
    depth z receives irradiance ``pi scale irradiance(uv) / z^2`` (W/m^2;
    ``wrt.kernels.lights.delta``); the image's left is on the left seen from the projector (u runs
    along ``-x``), its top row at ``+y``."""

    position: tuple[float, float, float]
    direction: tuple[float, float, float]
    irradiance: object
    fov: float
    up: tuple[float, float, float] = (0.0, 1.0, 0.0)
    scale: float = 1.0
    type: str = "projector"

    @property
    def aspect(self) -> float:
        """The irradiance's width over its height: a bitmap's texels' (H, W, 3); 1 for a constant
        or a checkerboard, which have no size (Mitsuba's 1 x 1 resolution)."""
        texels = getattr(self.irradiance, "texels", None)
        return 1.0 if texels is None else texels.shape[1] / texels.shape[0]

    def frame(self) -> np.ndarray:
        return light_frame(self.direction, self.up)

    def uv_scale(self) -> tuple[float, float]:
        """``wrt.kernels.lights.delta``'s: Mitsuba's ``perspective_projection`` of the texture's size."""
        s = -0.5 / math.tan(math.radians(self.fov) / 2.0)
        return (s / self.aspect, s)


@dataclass(frozen=True)
class AreaLight:
    """Parallelogram light ``corner + u edge_u + v edge_v`` (u, v in [0, 1]) emitting ``radiance``
    (W/(m^2 sr)) from the side of ``cross(edge_u, edge_v)`` only; a surface that reflects nothing."""

    corner: tuple[float, float, float]
    edge_u: tuple[float, float, float]
    edge_v: tuple[float, float, float]
    radiance: tuple[float, float, float]
    type: str = "area"

    def corners(self) -> np.ndarray:
        """Its four corners (4, 3), float64, wound so that their normal is the emitting side,
        ``cross(edge_u, edge_v)``."""
        c, u, v = (np.asarray(x, dtype=np.float64) for x in (self.corner, self.edge_u, self.edge_v))
        return np.array([c, c + u, c + u + v, c + v])


@dataclass(frozen=True)
class SphereLight:
    """Sphere emitting ``radiance`` (W/(m^2 sr)) outward; a surface that reflects nothing."""

    center: tuple[float, float, float]
    radius: float
    radiance: tuple[float, float, float]
    type: str = "sphere"


@dataclass(frozen=True, eq=False)
class EnvironmentLight:
    """Radiance arriving from every direction, seen by rays that leave: constant ``radiance``
    (W/(m^2 sr)), or with an ``image``, the image's pixel values (W/(m^2 sr)) times ``radiance``
    (the scene file's ``scale`` in each channel). ``image``: (H, W, 3) float32 linear RGB of an
    equirectangular map read from ``file``, laid out as Mitsuba 3's ``envmap`` (``wrt.envmap``)
    in the frame ``to_world`` (3x3 float64, a rotation or reflection) takes to world space."""

    radiance: tuple[float, float, float]
    file: str | None = None
    image: np.ndarray | None = None
    to_world: np.ndarray = field(default_factory=lambda: np.eye(3))
    type: str = "environment"


SURFACE_LIGHTS = (AreaLight, SphereLight)
DELTA_LIGHTS = (PointLight, DirectionalLight, SpotLight, ProjectorLight)


Shape = Sphere | Plane | Triangle | Polygon | Mesh | Disk | Cylinder | Instance


@dataclass(frozen=True, eq=False)
class Scene:
    """A whole scene. ``shapes`` keep file order: a shape's index is its ``object_id``;
    ``approximations`` lists what an ``--approximate`` Mitsuba import rendered differently.
    ``boundaries`` lists the shapes that bound participating media (they name an ``interior`` or
    an ``exterior`` medium; the other side, unnamed, is vacuum), in shape order."""

    render: RenderSettings
    camera: Camera
    materials: tuple[Material, ...]
    shapes: tuple[Shape, ...]
    lights: tuple = ()
    path: str = "<memory>"
    approximations: tuple[str, ...] = ()
    groups: tuple[Group, ...] = ()
    media: tuple[Medium, ...] = ()
    boundaries: tuple[tuple[int, int, int], ...] = ()  # (shape, interior, exterior) medium indices, -1: vacuum
    camera_medium: int = -1  # the medium the camera is in; -1: vacuum

    def surface_points(self, sides: int) -> np.ndarray:
        """Points (n, 3), float64, whose box holds every bounded shape and every light surface:
        an instance by the corners of its group's box through its transform, a disk or tube by its
        rims as polygons of ``sides`` vertices; planes and lights without a surface add none."""
        boxes = [_box(_points(shape, sides) for shape in group.shapes) for group in self.groups]
        points = [_points(item, sides) for item in (*self.lights, *self.shapes) if not isinstance(item, Instance)]
        for shape in self.shapes:
            if isinstance(shape, Instance):
                m = shape.matrix
                points.append(boxes[shape.group] @ m[:3, :3].T + m[:3, 3])
        return np.concatenate([np.zeros((0, 3)), *points])


def _points(item, sides: int) -> np.ndarray:
    """Points (n, 3) whose box holds a bounded shape or a light's surface (none otherwise)."""
    if isinstance(item, (Sphere, SphereLight)):
        c = np.asarray(item.center, dtype=np.float64)
        return np.stack([c - item.radius, c + item.radius])
    if isinstance(item, (Triangle, Polygon)):
        return np.asarray(item.vertices, dtype=np.float64).reshape(-1, 3)
    if isinstance(item, Mesh):
        return np.stack([item.vertices.min(axis=0), item.vertices.max(axis=0)])
    if isinstance(item, (Disk, Cylinder)):
        vertices, _ = item.triangles(sides)
        return np.stack([vertices.min(axis=0), vertices.max(axis=0)])
    if isinstance(item, AreaLight):
        return item.corners()
    return np.zeros((0, 3))


def _box(points) -> np.ndarray:
    """The eight corners (8, 3) of the box of some (n, 3) point sets."""
    p = np.concatenate(list(points))
    return box_corners(p.min(axis=0), p.max(axis=0))


def box_corners(lo, hi) -> np.ndarray:
    """The eight corners (8, 3) of the box [lo, hi]; corner c takes ``hi`` along axis a where bit a of c is set."""
    return np.array([[(lo, hi)[(c >> a) & 1][a] for a in range(3)] for c in range(8)], dtype=np.float64)
