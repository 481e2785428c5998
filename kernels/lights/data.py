"""The lights' table on the device and what a light family's sample returns.

Every light of the scene is one row of ``LightData`` (``type`` is its family's code; ``wrt.bake``
fills the columns from ``Family.row``). An environment light with a map (at most one per scene)
keeps its image, frame and sampling distribution in the ``env_*`` fields (``wrt.envmap``
describes their layout); the emissive primitives (``wrt.emitting``) in the ``emit_*`` and
``*_emitter`` fields; 1-element placeholders in scenes without them.
Units: point and spot ``intensity`` in W/sr, directional ``irradiance`` in W/m^2,
area/sphere/environment ``radiance`` in W/(m^2 sr) (RGB).
"""

import warp as wp

from ..sample_warps import frame
from ..textures import TextureData

SHADOW_MARGIN = wp.constant(1.0e-4)  # shadow rays toward a light's surface stop this fraction short of it


@wp.struct
class LightData:
    type: wp.array(dtype=wp.int32)
    position: wp.array(dtype=wp.vec3)  # point/spot position, parallelogram corner, sphere centre
    direction: wp.array(dtype=wp.vec3)  # unit, the way the light travels
    power: wp.array(dtype=wp.vec3)  # intensity (W/sr), irradiance (W/m^2) or radiance (W/(m^2 sr))
    edge_u: wp.array(dtype=wp.vec3)  # parallelogram edges from the corner
    edge_v: wp.array(dtype=wp.vec3)
    radius: wp.array(dtype=float)  # sphere light
    cos_cutoff: wp.array(dtype=float)  # spot: cos of the cone's half-angle
    cutoff: wp.array(dtype=float)  # spot: half-angle, radians
    beam: wp.array(dtype=float)  # spot: half-angle of full intensity, radians
    frame: wp.array(dtype=wp.mat33)  # spot, projector: rows its unit local x, y, z (its direction) in world space
    uv_scale: wp.array(dtype=wp.vec2)  # textured spot, projector: a local direction's uv is 1/2 + uv_scale (x, y) / z
    texture: wp.array(dtype=wp.int32)  # textured spot, projector: its texture in ``textures``; -1 for none
    textures: TextureData  # the lights' textures, a table of their own (the materials' is MaterialData's)
    env_radiance: wp.array2d(dtype=wp.vec3)  # (H, W) the map's pixels, W/(m^2 sr) before ``power``
    env_to_world: wp.mat33  # the map's frame (a rotation) to world space
    env_cdf: wp.array(dtype=float)  # marginal CDF over cell rows, then each row's conditional CDF
    env_pdf: wp.array2d(dtype=float)  # (H - 1, W) solid-angle density of each cell, 1/sr
    emit_kind: wp.array(dtype=wp.int32)  # the emitting primitives (wrt.emitting): TRIANGLE, POLYGON or SPHERE
    emit_prim: wp.array(dtype=wp.int32)  # their indices in GeometryData's arrays of that kind
    emit_cdf: wp.array(dtype=float)  # (E + 1) their selection CDF by emitted power, 0 to 1
    emit_area: wp.array(dtype=float)  # their areas, m^2
    emit_first: wp.array(dtype=wp.int32)  # (E + 1) a polygon's triangles: emit_first[e] to emit_first[e + 1]
    emit_corner: wp.array(dtype=wp.vec3)  # those triangles' corners, three each
    emit_area_cdf: wp.array(dtype=float)  # per polygon its triangles' running area fractions, the last 1
    tri_emitter: wp.array(dtype=wp.int32)  # per triangle of GeometryData its index in the pool, -1 if none
    poly_emitter: wp.array(dtype=wp.int32)  # per polygon likewise
    sphere_emitter: wp.array(dtype=wp.int32)  # per sphere likewise


@wp.struct
class LightSample:
    wi: wp.vec3  # unit direction toward the light
    radiance: wp.vec3  # W/(m^2 sr) arriving along wi; a delta light's: the irradiance (W/m^2) it delivers
    pdf: float  # solid-angle density of wi; 1 for a delta light; 0: no light from it
    t_max: float  # how far the shadow ray goes: short of the light's surface, inf toward the environment


@wp.func
def surface_sample(wi: wp.vec3, dist: float, radiance: wp.vec3, pdf: float) -> LightSample:
    """The sample of a light with a surface (or none: the environment, ``dist`` inf) at ``dist``
    along ``wi``: its shadow ray stops ``SHADOW_MARGIN`` of the way short of it."""
    ls = LightSample()
    ls.wi = wi
    ls.radiance = radiance
    ls.pdf = pdf
    ls.t_max = dist * (1.0 - SHADOW_MARGIN)
    return ls


@wp.struct
class EmissionSample:
    """A ray leaving a light (the light tracer's start, ``sample_le``), and the point it leaves from.

    ``weight`` is ``Le |cos| / (pdf_position pdf_direction)``: the power (W) the ray carries,
    before the light's selection probability. Where the light has a surface the camera can see,
    ``n`` is its unit emitting normal at ``o``, ``radiance`` what it emits toward ``n``'s side
    (W/(m^2 sr)) and ``pdf_area`` the density of ``o`` on it (1/m^2); ``pdf_area`` is 0 for lights
    without one (delta lights, lights at infinity). ``weight`` 0: no ray."""

    o: wp.vec3
    d: wp.vec3
    weight: wp.vec3
    n: wp.vec3
    radiance: wp.vec3
    pdf_area: float


@wp.func
def emission_ray(o: wp.vec3, d: wp.vec3, weight: wp.vec3) -> EmissionSample:
    """The ray ``o + s d`` of a light without a surface to see, carrying ``weight``."""
    es = EmissionSample()
    es.o = o
    es.d = d
    es.weight = weight
    es.n = wp.vec3(0.0)
    es.radiance = wp.vec3(0.0)
    es.pdf_area = 0.0
    return es


@wp.func
def surface_emission(o: wp.vec3, n: wp.vec3, radiance: wp.vec3, pdf_area: float, local: wp.vec3) -> EmissionSample:
    """The ray leaving point ``o`` of an emitting surface (unit normal ``n``, emitting
    ``radiance`` toward its side, ``o`` drawn with density ``pdf_area``) in the cosine-weighted
    direction ``local`` (z along ``n``, density ``cos / pi``): it carries ``pi radiance / pdf_area``."""
    es = EmissionSample()
    es.o = o
    es.d = frame(n) * local
    es.weight = radiance * (wp.pi / pdf_area)
    es.n = n
    es.radiance = radiance
    es.pdf_area = pdf_area
    if pdf_area <= 0.0:
        es.weight = wp.vec3(0.0)
        es.pdf_area = 0.0
    return es
