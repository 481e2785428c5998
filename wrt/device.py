"""Upload host data to a Warp device: the scene geometry and BVH, materials, lights, camera.

This is the one place where numpy arrays become ``wp.array``s; kernels receive the structs
built here. What is computed rather than copied from the scene comes from the bake stage
(``wrt.bake``); float64 host values are rounded to float32 once, here.
"""

from __future__ import annotations

import math
import os
import tempfile

import numpy as np
import warp as wp

from wrt.kernels.camera import BOX, GAUSSIAN, TENT, CameraData
from wrt.kernels.integrator import IntegratorSettings
from wrt.kernels.lights import LightData
from wrt.kernels.materials import FAMILIES, MaterialData
from wrt.kernels.media import MEDIA, Media
from wrt.kernels.microfacet import DISTRIBUTIONS
from wrt.kernels.sampling import INDEPENDENT, SOBOL, STRATIFIED, Sampler
from wrt.kernels.textures import TextureData
from wrt.kernels.traverse import GeometryData, mat24
from wrt.kernels.volumes import MediumData

from .aot import install, install_cuda
from .bake import bake_lights, bake_materials, bake_media, camera_media, surface_materials
from .emitting import EmittingPrimitives
from .errors import WrtError
from .geometry import Primitives
from .scene import Camera, RenderSettings, Scene
from .textures import TextureTable, attribute_names, texture_table

SAMPLER_CODES = {"independent": INDEPENDENT, "stratified": STRATIFIED, "sobol": SOBOL}
FILTER_CODES = {"box": BOX, "tent": TENT, "gaussian": GAUSSIAN}


def init_warp() -> str:
    """Initialise Warp, keeping its native start-up messages off the console; returns them.

    Warp's native library prints a warning to stderr when it finds no CUDA driver, which is the
    normal case on a CPU-only machine. The CLI shows the text only if CUDA was asked for.
    Then the shipped compiled modules are installed into Warp's kernel cache (``wrt.aot``).
    """
    saved = os.dup(2)
    with tempfile.TemporaryFile() as capture:
        os.dup2(capture.fileno(), 2)
        try:
            wp.init()
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        capture.seek(0)
        messages = capture.read().decode(errors="replace")
    install()
    return messages


def resolve_device(name: str | wp.Device | None) -> wp.Device:
    """The Warp device called ``name`` ("cpu", "cuda", "cuda:0"; None = "cpu"; a device: itself).

    Raises ``WrtError`` when Warp has no such device (e.g. "cuda" on a machine without a GPU).
    """
    if isinstance(name, wp.Device):
        dev = name
    else:
        name = "cpu" if name is None else name
        if not isinstance(name, str) or not name:
            raise WrtError(f"device {name!r}: not a device name (use cpu, cuda or cuda:N)")
        if name.startswith("cuda") and not wp.is_cuda_available():
            raise WrtError(f"device {name!r}: Warp found no CUDA device on this machine (use --device cpu)")
        try:
            dev = wp.get_device(name)
        except (RuntimeError, ValueError) as e:
            raise WrtError(f"device {name!r}: {e}") from None
    install()  # the shipped compiled modules, before any launch (wrt.aot)
    if dev.is_cuda:
        install_cuda(dev)
    return dev


def _vec3(a: np.ndarray, device) -> wp.array:
    return wp.array(np.asarray(a, dtype=np.float32).reshape(-1, 3), dtype=wp.vec3, device=device)


def _rows(a: np.ndarray, dtype, shape: tuple[int, ...], device) -> wp.array:
    """Rows of ``shape`` (a vector's or matrix's) as an array of ``dtype``."""
    return wp.array(np.asarray(a, dtype=np.float32).reshape(-1, *shape), dtype=dtype, device=device)


def _int(a: np.ndarray, device) -> wp.array:
    return wp.array(np.asarray(a, dtype=np.int32).reshape(-1), dtype=wp.int32, device=device)


def _float(a: np.ndarray, device) -> wp.array:
    return wp.array(np.asarray(a, dtype=np.float32).reshape(-1), dtype=wp.float32, device=device)


def upload_geometry(p: Primitives, device) -> GeometryData:
    """``GeometryData`` for primitives already passed through ``wrt.geometry.build`` (whose BVH is
    on ``device``)."""
    poly_count = np.array([len(v) for v in p.poly_verts], dtype=np.int32)
    poly_offset = [float(np.dot(n, v.mean(axis=0))) for v, n in zip(p.poly_verts, p.poly_normal)]
    s = GeometryData()
    s.nodes = p.bvh.nodes
    s.prims = _int(p.prims, device)
    s.sphere_center = _vec3(p.sphere_center, device)
    s.sphere_radius = _float(p.sphere_radius, device)
    s.sphere_shape = _int(p.sphere_shape, device)
    turned = not np.array_equal(p.sphere_to_object, np.broadcast_to(np.eye(3), p.sphere_to_object.shape))
    s.sphere_to_object = _rows(p.sphere_to_object if turned else np.zeros((0, 3, 3)), wp.mat33, (3, 3), device)
    s.tri_verts = _vec3(p.tri_verts, device)
    s.tri_shape = _int(p.tri_shape, device)
    s.tri_normals = _vec3(p.tri_normals, device)
    s.poly_normal = _vec3(p.poly_normal, device)
    s.poly_offset = _float(poly_offset, device)
    s.poly_start = _int(np.concatenate(([0], np.cumsum(poly_count)[:-1])), device)
    s.poly_count = _int(poly_count, device)
    s.poly_verts = _vec3(np.concatenate(p.poly_verts or [np.zeros((0, 3))]), device)
    s.poly_shape = _int(p.poly_shape, device)
    s.plane_point = _vec3(p.plane_point, device)
    s.plane_normal = _vec3(p.plane_normal, device)
    s.plane_shape = _int(p.plane_shape, device)
    s.num_shapes = p.num_shapes
    s.surface_velocity = _vec3(p.surface_velocity, device)
    s.moving = int(np.any(p.surface_velocity != 0.0))
    s.top_count = p.top_count
    s.inst_to_world = wp.array(p.inst_to_world.astype(np.float32), dtype=wp.mat44, device=device)
    s.inst_to_object = wp.array(np.linalg.inv(p.inst_to_world).astype(np.float32), dtype=wp.mat44, device=device)
    s.inst_root = _int(p.inst_root, device)
    s.inst_shape = _int(p.inst_shape, device)
    s.inst_entries = wp.array(p.inst_entries.astype(np.int32), dtype=wp.vec2i, device=device)
    to_object, to_world, normal = p.quadric_transforms()
    s.quadric_to_object = wp.array(to_object, dtype=wp.mat44, device=device)
    s.quadric_to_world = wp.array(to_world.astype(np.float32), dtype=wp.mat44, device=device)
    s.quadric_normal = wp.array(normal, dtype=wp.mat33, device=device)
    s.quadric_shape = _int(p.quadric_shape, device)
    s.tri_uvs = wp.array(p.tri_uvs.astype(np.float32).reshape(-1, 2), dtype=wp.vec2, device=device)
    s.poly_uv = wp.array(p.poly_uv.astype(np.float32), dtype=mat24, device=device)
    s.plane_uv = wp.array(p.plane_uv.astype(np.float32), dtype=mat24, device=device)
    return s


def upload_materials(scene: Scene, device, prims: Primitives | None = None) -> MaterialData:
    """``MaterialData`` of ``scene`` (its bake, ``wrt.bake.bake_materials``), on ``device``; its
    textures' mesh attributes those of ``prims`` (``wrt.geometry.build``'s, in its triangle order:
    needed where a texture reads mesh attributes)."""
    baked = bake_materials(scene)
    mats = baked.materials
    m = MaterialData()
    m.shape_material = _int(baked.shape_material, device)
    m.type = _int(baked.type, device)
    corners = np.zeros((0, 3), np.float32)
    if attribute_names(scene.materials):
        if prims is None:
            raise ValueError("the scene's textures read mesh attributes: upload_materials needs its primitives")
        corners = prims.tri_attributes.reshape(-1, 3)
    m.textures = _texture_data(baked.textures, device, corners)
    m.bump_scale = _float([mat.bump_scale for mat in mats], device)
    m.flags = _int(baked.flags, device)
    m.inner = _int(baked.inner, device)
    m.opacity = _float([mat.opacity for mat in mats], device)
    m.base_color = _vec3(baked.base_color, device)
    m.albedo = _vec3([mat.albedo for mat in mats], device)
    m.specular = _vec3([mat.specular for mat in mats], device)
    m.exponent = _float([mat.exponent for mat in mats], device)
    m.reflectance = _vec3([mat.reflectance for mat in mats], device)
    m.ior = _float(baked.ior, device)
    m.sigma = _vec3(baked.sigma, device)
    m.transmittance = _vec3([mat.transmittance for mat in mats], device)
    m.priority = _int([mat.priority for mat in mats], device)
    m.roughness = _float([mat.roughness for mat in mats], device)
    m.roughness_v = _float([mat.roughness if mat.roughness_v is None else mat.roughness_v for mat in mats], device)
    m.distribution = _int([DISTRIBUTIONS[mat.distribution] for mat in mats], device)
    m.eta = _vec3([mat.eta for mat in mats], device)
    m.k = _vec3([mat.k for mat in mats], device)
    m.emission = _vec3([mat.emission for mat in mats], device)
    m.two_sided = _int(baked.two_sided, device)
    for family in FAMILIES:
        if family.data is not None:
            setattr(m, family.name, _table(family.data, baked.tables[family.name], device))
    m.media = _table(MediumData, bake_media(scene, len(baked.shape_material)), device)
    m.media.count = len(scene.media)
    return m


def upload_textures(scene: Scene, device) -> TextureData:
    """Every texture of the scene's materials and which material parameter each gives
    (``wrt.kernels.textures``; materials numbered as ``surface_materials``)."""
    return _texture_data(texture_table(surface_materials(scene)[1]), device)


def _texture_data(table: TextureTable, device, corners: np.ndarray | None = None) -> TextureData:
    """``table`` on ``device``, with the mesh attributes ``corners`` (T * 3 * A, 3) (none by default)."""
    t = TextureData()
    t.slot = wp.array(table.slot, dtype=wp.int32, device=device)
    t.kind = _int(table.kind, device)
    t.to_uv = wp.array(table.to_uv, dtype=wp.mat33, device=device)
    t.color0 = _vec3(table.color0, device)
    t.color1 = _vec3(table.color1, device)
    t.offset = _int(table.offset, device)
    t.width = _int(table.width, device)
    t.height = _int(table.height, device)
    t.filter = _int(table.filter, device)
    t.wrap = _int(table.wrap, device)
    t.texels = _vec3(table.texels, device)
    t.corners = _vec3(np.zeros((0, 3)) if corners is None else corners, device)
    return t


def _table(struct, columns: dict, device):
    """An instance of the ``wp.struct`` ``struct`` whose array fields are ``columns`` (numpy, by
    field name), each converted to the field's dtype (float64 rounded to float32 here); its other
    fields are left for the caller."""
    table = struct()
    for name, var in struct.vars.items():
        if not wp.types.is_array(var.type):
            continue
        dtype = var.type.dtype
        values = np.asarray(columns[name], dtype=wp.dtype_to_numpy(getattr(dtype, "_wp_scalar_type_", dtype)))
        setattr(table, name, wp.array(values, dtype=var.type.dtype, device=device))
    return table


def upload_lights(scene: Scene, device, prims: Primitives | None = None) -> LightData:
    """``LightData`` of ``scene`` (its bake, ``wrt.bake.bake_lights``: one row per light in file
    order, the environment map, and the emitting primitives of ``prims``), on ``device``; a
    column that would be empty is a 1-element placeholder."""
    baked = bake_lights(scene, prims)
    rows = baked.rows
    lights = LightData()
    lights.type = _int(rows["type"], device)
    lights.position = _vec3(rows["position"], device)
    lights.direction = _vec3(rows["direction"], device)
    lights.power = _vec3(rows["power"], device)
    lights.edge_u = _vec3(rows["edge_u"], device)
    lights.edge_v = _vec3(rows["edge_v"], device)
    lights.radius = _float(rows["radius"], device)
    lights.cos_cutoff = _float(rows["cos_cutoff"], device)
    lights.cutoff = _float(rows["cutoff"], device)
    lights.beam = _float(rows["beam"], device)
    lights.frame = _rows(rows["frame"], wp.mat33, (3, 3), device)
    lights.uv_scale = _rows(rows["uv_scale"], wp.vec2, (2,), device)
    lights.texture = _int(rows["texture"], device)
    lights.textures = _texture_data(baked.textures, device)
    lights.env_radiance = wp.array(np.asarray(baked.env_radiance, dtype=np.float32), dtype=wp.vec3, device=device)
    lights.env_to_world = wp.mat33(*np.asarray(baked.env_to_world, dtype=np.float32).ravel())
    lights.env_cdf = _float(baked.env_cdf, device)
    lights.env_pdf = wp.array(np.asarray(baked.env_pdf, dtype=np.float32), dtype=wp.float32, device=device)
    _upload_emitting(lights, baked.emitting, device)
    return lights


def _upload_emitting(lights: LightData, emitting: EmittingPrimitives | None, device) -> None:
    """The ``emit_*`` and ``*_emitter`` fields of ``lights`` (``wrt.emitting``), 1-element
    placeholders when ``emitting`` is None or an array would be empty."""

    def ints(a, fill):
        return _int(a if len(a) else np.full(1, fill), device)

    def floats(a):
        return _float(a if len(a) else np.zeros(1), device)

    if emitting is None:
        lights.emit_kind = lights.emit_prim = lights.emit_first = ints([], 0)
        lights.emit_cdf = lights.emit_area = lights.emit_area_cdf = floats([])
        lights.tri_emitter = lights.poly_emitter = lights.sphere_emitter = ints([], -1)
        lights.emit_corner = wp.zeros(1, dtype=wp.vec3, device=device)
        return
    lights.emit_kind, lights.emit_prim = ints(emitting.kind, 0), ints(emitting.prim, 0)
    lights.emit_cdf, lights.emit_area = floats(emitting.cdf), floats(emitting.area)
    lights.emit_first, lights.emit_area_cdf = ints(emitting.first, 0), floats(emitting.area_cdf)
    corners = emitting.corners.reshape(-1, 3) if len(emitting.corners) else np.zeros((1, 3), np.float32)
    lights.emit_corner = wp.array(corners, dtype=wp.vec3, device=device)
    lights.tri_emitter = ints(emitting.of_triangle, -1)
    lights.poly_emitter = ints(emitting.of_polygon, -1)
    lights.sphere_emitter = ints(emitting.of_sphere, -1)


def integrator_settings(scene: Scene) -> IntegratorSettings:
    render = scene.render
    media = camera_media(scene)
    if len(media) > MEDIA:
        raise WrtError(f"the camera is inside {len(media)} nested dielectrics; at most {MEDIA} are supported")
    s = IntegratorSettings()
    s.camera_media = Media(*(media + [-1] * (MEDIA - len(media))))
    s.camera_n_media = len(media)
    s.max_depth = render.max_depth
    s.ambient = wp.vec3(*render.ambient)
    s.background = wp.vec3(*render.background)
    s.exterior_ior = render.exterior_ior
    s.filtered_shadows = int(render.dielectric_shadows == "filtered")
    s.min_throughput = render.min_throughput
    s.camera_medium = scene.camera_medium
    return s


def sampler_data(kind: str, spp: int, seed: int) -> Sampler:
    """``Sampler`` of the ``[render] sampler`` named ``kind`` for a render of ``spp`` samples; the
    stratified sampler's 2D grid is the factorisation of ``spp`` nearest to a square."""
    s = Sampler()
    s.kind = SAMPLER_CODES[kind]
    s.seed = seed
    s.spp = spp
    s.strata_x = max(k for k in range(1, math.isqrt(spp) + 1) if spp % k == 0)
    return s


def camera_data(camera: Camera, render: RenderSettings, width: int, height: int) -> CameraData:
    """``CameraData`` for the scene-format camera convention and the ``[render]`` filter (see
    ``wrt.kernels.camera``)."""
    forward, right, up = camera.basis()
    c = CameraData()
    c.origin = wp.vec3(*camera.origin)
    c.forward, c.right, c.up = wp.vec3(*forward), wp.vec3(*right), wp.vec3(*up)
    c.tan_half_fov = math.tan(math.radians(camera.fov) / 2.0)
    c.aperture_radius = camera.aperture_radius
    c.focus_distance = (
        camera.focus_distance
        if camera.focus_distance is not None
        else float(np.linalg.norm(np.subtract(camera.look_at, camera.origin)))
    )
    c.aspect = width / height
    c.orthographic = int(camera.type == "orthographic")
    if camera.type == "orthographic":
        c.half_width = camera.width / 2.0
        c.half_height = camera.width / 2.0 / c.aspect
    c.near_clip, c.far_clip = camera.near_clip, camera.far_clip
    c.width, c.height = width, height
    c.filter = FILTER_CODES[render.filter]
    c.shutter_open, c.shutter_close = camera.shutter
    return c
