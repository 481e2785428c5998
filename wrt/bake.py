"""The bake stage between the host scene and the upload: everything the kernels read that is
computed rather than copied from the scene, as numpy columns (float64 where computed; the
upload, ``wrt.device``, rounds to float32 and converts to Warp arrays, nothing more).

- ``bake_materials``: the material list the kernels index (the scene's, then one emitter per
  surface light), each material's type code, lobes, base colour, relative ior and absorption, a
  mask's inner material, their textures' table, and each family's own table (``Family.bake``: the plastics' coating
  tables, the blends' materials and weights).
- ``bake_media``: the participating media (``wrt.kernels.volumes.MediumData``) and the media
  each surface bounds.
- ``bake_lights``: one row per light (``wrt.kernels.lights.LightData``), the environment map's
  sampling distribution (``wrt.envmap``) and the pool of emissive primitives (``wrt.emitting``).
- ``camera_media`` (``media_at``): the dielectric volumes the camera starts inside, found with a float64 twin of
  the kernels' watertight triangle test (``watertight_crossings``, held against the kernel by a test).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from wrt.kernels.lights import light_row
from wrt.kernels.materials import (
    BSDF_ANISOTROPIC,
    BSDF_MEDIUM,
    FAMILIES,
    FAMILY_OF,
    TYPES,
    blend_flags,
    lobe_flags,
    mask_flags,
)
from wrt.kernels.volumes import GRID, HOMOGENEOUS, UNSET
from wrt.kernels.volumes.grid import MAX_CELLS as MAJORANT_CELLS

from .emitting import EmittingPrimitives, emitting_primitives
from .envmap import environment_distribution
from .geometry import Primitives
from .scene import (
    SURFACE_LIGHTS,
    EnvironmentLight,
    Material,
    Medium,
    Mesh,
    Scene,
    Sphere,
    Volume,
)
from .textures import TextureTable, light_texture_table, texture_table

GLOW_COLLISIONS = 8.0  # tentative collisions along the shortest edge of a clear emissive grid's box


@dataclass
class BakedMaterials:
    """``MaterialData``'s columns (one row per material, ``materials``' order) and the index of
    each surface's material (``wrt.geometry``'s numbering of surfaces)."""

    materials: list[Material]
    shape_material: np.ndarray
    type: np.ndarray
    flags: np.ndarray
    two_sided: np.ndarray
    inner: np.ndarray
    base_color: np.ndarray
    ior: np.ndarray
    sigma: np.ndarray
    textures: TextureTable  # the textures of textured parameters (wrt.textures.texture_table)
    tables: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)  # Family.bake's, by family name


def surface_materials(scene: Scene) -> tuple[list[int], list[Material]]:
    """Material index of every surface (the shapes, the surfaces of area and sphere lights, then
    the shapes of the groups, group by group: ``wrt.geometry``'s numbering) and the material list
    they index: the scene's, then one black emitter per surface light, emitting the light's
    radiance from its front."""
    materials = list(scene.materials)
    surfaces = [shape.material for shape in scene.shapes]
    for k, light in enumerate(scene.lights):
        surfaces.append(len(materials) if isinstance(light, SURFACE_LIGHTS) else -1)
        if isinstance(light, SURFACE_LIGHTS):
            materials.append(
                Material(name=f"light[{k}]", type="emitter", albedo=(0.0, 0.0, 0.0), emission=light.radiance)
            )
    surfaces += [shape.material for group in scene.groups for shape in group.shapes]
    return surfaces, materials


def _opaque(mask: Material) -> bool:
    """A mask of constant opacity 1: it has no null lobe."""
    return mask.opacity == 1.0 and not any(name == "opacity" for name, _ in mask.textures)


def _base_color(material: Material, by_name: dict[str, Material]) -> np.ndarray:
    """The colour the raycast integrator shows for a material (``Family.base_color``): a mask's
    material's, a blend's materials' weighted by its constant weight."""
    if material.type == "mask":
        return _base_color(by_name[material.material], by_name)
    if material.type == "blend":
        a, b = (_base_color(by_name[name], by_name) for name in material.materials)
        return (1.0 - material.weight) * a + material.weight * b
    base = FAMILY_OF[material.type].base_color
    return np.asarray(base(material) if callable(base) else getattr(material, base), dtype=np.float64)


def _flags(material: Material, by_name: dict[str, Material]) -> int:
    """The lobes of a material (``lobe_flags``; a mask's ``mask_flags`` of its material's, a blend's
    ``blend_flags`` of its two materials'), with ``BSDF_ANISOTROPIC`` where its lobes, or those of a
    material it masks or blends, need the hit's tangent, and ``BSDF_MEDIUM`` where it bounds a
    medium (``Family.medium``)."""
    if material.type == "mask":
        return mask_flags(_flags(by_name[material.material], by_name), _opaque(material))
    if material.type == "blend":
        return blend_flags(*(_flags(by_name[name], by_name) for name in material.materials))
    medium = BSDF_MEDIUM if FAMILY_OF[material.type].medium else 0
    return lobe_flags(material) | (BSDF_ANISOTROPIC if _anisotropic(material) else 0) | medium


def _anisotropic(material: Material) -> bool:
    """Its two alphas differ as the kernels see them (``anisotropic_material``: one of them
    textured, or their float32 values unequal): its lobes need the hit's tangent. An isotropic
    material given ``roughness_v`` equal to ``roughness`` takes none, and renders as without it."""
    if material.roughness_v is None:
        return material.anisotropic  # a principled one's anisotropy
    textured = any(key in ("roughness", "roughness_v") for key, _ in material.textures)
    return textured or np.float32(material.roughness_v) != np.float32(material.roughness)


def _two_sided(material: Material, by_name: dict[str, Material]) -> bool:
    """Scatters on its back side too: a blend where either of its materials does."""
    if material.type == "blend":
        return any(_two_sided(by_name[name], by_name) for name in material.materials)
    return material.two_sided


def bake_materials(scene: Scene) -> BakedMaterials:
    """The materials' computed columns (see the module's docstring)."""
    surfaces, materials = surface_materials(scene)
    index = {material.name: i for i, material in enumerate(scene.materials)}
    by_name = {material.name: material for material in scene.materials}
    inner = [index[m.material] if m.type == "mask" else -1 for m in materials]  # a mask's is no mask
    flags = [_flags(m, by_name) for m in materials]
    exterior = scene.render.exterior_ior  # a thin dielectric or a plastic sits in it: its ior is relative to it
    with np.errstate(divide="ignore"):
        sigma = [np.minimum(-np.log(m.transmittance), 1e30) for m in materials]
    return BakedMaterials(
        materials=materials,
        shape_material=np.array(surfaces or [0], dtype=np.int32),
        type=np.array([TYPES[m.type].code for m in materials], dtype=np.int32),
        flags=np.array(flags, dtype=np.int32),
        inner=np.array(inner, dtype=np.int32),
        two_sided=np.array([_two_sided(m, by_name) for m in materials], dtype=np.int32),
        base_color=np.array([_base_color(m, by_name) for m in materials]),
        ior=np.array([m.ior / exterior if FAMILY_OF[m.type].relative_ior else m.ior for m in materials]),
        sigma=np.array(sigma).reshape(-1, 3),
        textures=texture_table(materials),
        tables={family.name: family.bake(materials, exterior) for family in FAMILIES if family.data is not None},
    )


def bake_media(scene: Scene, surfaces: int) -> dict[str, np.ndarray]:
    """``MediumData``'s columns: per surface (``surfaces`` of them, ``surface_materials``'
    numbering: ``BakedMaterials.shape_material``'s length) the media its shape bounds (``UNSET``
    for none), per medium its kind, extinction (``scale`` applied), albedo and phase asymmetry (0
    for isotropic) and emission, and for a heterogeneous one the volume rows of its extinction
    (``scale`` applied), albedo and emission (-1: none) and its majorants (``_majorant_grid``); the
    volumes' frames, resolutions and texels (grey ones in all three channels). One placeholder row
    where a table would be empty."""
    interior = np.full(surfaces, UNSET, dtype=np.int32)
    exterior = interior.copy()
    for shape, inside, outside in scene.boundaries:
        interior[shape], exterior[shape] = inside, outside
    media = scene.media or (Medium(name="placeholder"),)
    volumes: list[tuple[np.ndarray, np.ndarray]] = []  # (to_local, texels (z, y, x, 3))

    def row(volume, factor: float = 1.0) -> int:
        if not isinstance(volume, Volume):
            volume = Volume(values=np.asarray(volume, np.float32).reshape(1, 1, 1, 3), to_world=np.eye(4))
        texels = np.broadcast_to(volume.values, volume.values.shape[:3] + (3,)) * np.float32(factor)
        volumes.append((np.linalg.inv(volume.to_world), texels))
        return len(volumes) - 1

    grid = [m.type == "heterogeneous" for m in media]
    density = [row(m.sigma_t, m.scale) if g else -1 for m, g in zip(media, grid)]
    tint = [row(m.albedo) if g else -1 for m, g in zip(media, grid)]
    glow = [row(m.emission) if g and m.emissive else -1 for m, g in zip(media, grid)]
    bounds = [_majorant_grid(m, volumes[d]) if d >= 0 else np.zeros((1, 1, 1)) for m, d in zip(media, density)]
    if not volumes:
        row((0.0, 0.0, 0.0))
    offsets = np.cumsum([0] + [v.shape[0] * v.shape[1] * v.shape[2] for _, v in volumes])[:-1]
    cells = np.cumsum([0] + [b.size for b in bounds])[:-1]
    return {
        "shape_interior": interior,
        "shape_exterior": exterior,
        "sigma_t": np.array([(0.0,) * 3 if g else np.multiply(m.sigma_t, m.scale) for m, g in zip(media, grid)]),
        "albedo": np.array([(0.0,) * 3 if g else m.albedo for m, g in zip(media, grid)]),
        "g": np.array([m.g for m in media]),
        "emission": np.array([(0.0,) * 3 if g else m.emission for m, g in zip(media, grid)]),
        "kind": np.array([GRID if g else HOMOGENEOUS for g in grid], dtype=np.int32),
        "density": np.array(density, dtype=np.int32),
        "tint": np.array(tint, dtype=np.int32),
        "glow": np.array(glow, dtype=np.int32),
        "majorant": np.array([float(b.max()) for b in bounds]),
        "majorant_res": np.array([b.shape[::-1] for b in bounds], dtype=np.int32),
        "majorant_offset": cells.astype(np.int32),
        "majorant_cells": np.concatenate([b.ravel() for b in bounds]).astype(np.float32),
        "volume_to_local": np.array([m for m, _ in volumes]),
        "volume_res": np.array([v.shape[2::-1] for _, v in volumes], dtype=np.int32),
        "volume_offset": offsets.astype(np.int32),
        "volume_values": np.concatenate([v.reshape(-1, 3) for _, v in volumes]),
    }


def _majorant_grid(medium: Medium, density: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """The bounds a heterogeneous medium is tracked against, (z, y, x) cells over its extinction
    grid's unit cube (``MAJORANT_CELLS`` a side at most, fewer where the grid has fewer texels):
    each the largest extinction of the texels whose trilinear reach overlaps the cell (so no
    lookup in it exceeds it), plus the medium's ``sigma_n``. An emissive medium's clear cells get a
    null density of ``GLOW_COLLISIONS`` collisions along its box's shortest edge, so that its
    emission is found there (pbrt-v4's ``MajorantGrid``)."""
    to_local, texels = density
    grey = texels.max(axis=-1)
    ranges = []
    for axis, res in enumerate(grey.shape):  # z, y, x
        cells = min(res, MAJORANT_CELLS)
        edges = np.arange(cells + 1) / cells * res - 0.5  # cell faces in texel-centre coordinates
        lo = np.clip(np.floor(edges[:-1]).astype(int), 0, res - 1)
        hi = np.clip(np.floor(edges[1:]).astype(int) + 1, 0, res - 1)
        ranges.append(list(zip(lo, hi)))
    bounds = np.array(
        [
            [[grey[z0 : z1 + 1, y0 : y1 + 1, x0 : x1 + 1].max() for x0, x1 in ranges[2]] for y0, y1 in ranges[1]]
            for z0, z1 in ranges[0]
        ],
        dtype=np.float64,
    )
    bounds += medium.sigma_n
    if medium.emissive:
        edges = np.linalg.norm(np.linalg.inv(to_local)[:3, :3], axis=0)
        bounds[bounds <= 0.0] = GLOW_COLLISIONS / float(edges.min())
    return bounds


@dataclass
class BakedLights:
    """``LightData``'s columns: one row per light (angles in radians, ``texture`` an index in
    ``textures``, the lights' own table), the environment map (at most one: its image, frame and
    sampling distribution, 1-element placeholders without), and the emissive primitives (None:
    not asked for)."""

    rows: dict[str, np.ndarray]
    textures: TextureTable
    env_radiance: np.ndarray
    env_to_world: np.ndarray
    env_cdf: np.ndarray
    env_pdf: np.ndarray
    emitting: EmittingPrimitives | None


def bake_lights(scene: Scene, prims: Primitives | None = None) -> BakedLights:
    """The lights' columns in file order (the surface of light k is surface ``num_shapes + k`` of
    the geometry), and the emitting primitives of ``prims`` (the scene flattened; none without it)."""
    rows = [light_row(light) for light in scene.lights]
    cutoff = np.radians([r["cutoff"] for r in rows])
    names = ("type", "position", "direction", "power", "edge_u", "edge_v", "radius", "frame", "uv_scale")
    columns = {name: np.array([r[name] for r in rows]) for name in names}
    columns.update(cos_cutoff=np.cos(cutoff), cutoff=cutoff, beam=np.radians([r["beam"] for r in rows]))
    textures = [r["texture"] for r in rows if r["texture"] is not None]
    index = iter(range(len(textures)))
    columns["texture"] = np.array([-1 if r["texture"] is None else next(index) for r in rows], dtype=np.int32)
    maps = [light for light in scene.lights if isinstance(light, EnvironmentLight) and light.image is not None]
    if maps:
        image, to_world = maps[0].image, maps[0].to_world
        distribution = environment_distribution(image)
        cdf, pdf = distribution.cdf, distribution.pdf
    else:
        image, to_world = np.zeros((1, 1, 3)), np.eye(3)
        cdf, pdf = np.zeros(1), np.zeros((1, 1))
    emitting = None if prims is None else emitting_primitives(scene, prims)
    return BakedLights(
        columns, light_texture_table(textures), np.asarray(image), np.asarray(to_world), cdf, pdf, emitting
    )


def camera_media(scene: Scene) -> list[int]:
    """The dielectric spheres and meshes the camera rays start inside (``media_at``), found at one
    point, where the image's central ray starts, ``origin + near_clip forward``, and taken for every
    camera ray (those of an orthographic camera or a thin lens start elsewhere on the camera
    plane, or its near clip plane)."""
    forward, _, _ = scene.camera.basis()
    return media_at(scene, np.asarray(scene.camera.origin, dtype=np.float64) + scene.camera.near_clip * forward)


def media_at(scene: Scene, o: np.ndarray) -> list[int]:
    """The dielectric spheres and meshes point ``o`` lies inside (shape indices, the largest first,
    as a ray from outside would have entered them). A mesh holds the point when a ray from it
    crosses the mesh an odd number of times, counted by the kernels' watertight test
    (``watertight_crossings``). Triangles, polygons, disks and (open) cylinders bound no volume
    alone; a moving shape is taken at time 0."""
    inside = []
    for index, shape in enumerate(scene.shapes):
        if not FAMILY_OF[scene.materials[shape.material].type].medium:
            continue
        if isinstance(shape, Sphere):
            if np.linalg.norm(o - np.asarray(shape.center)) < shape.radius:
                inside.append((shape.radius, index))
        elif isinstance(shape, Mesh) and watertight_crossings(o, CROSSING_DIRECTION, shape.vertices[shape.faces]) % 2:
            inside.append((float(np.ptp(shape.vertices, axis=0).max()), index))
    return [index for _, index in sorted(inside, reverse=True)]


CROSSING_DIRECTION = np.array([0.5773502691, 0.5773672691, 0.5773332691])
"""The direction ``camera_media`` counts crossings along: generic, so that it meets no edge of a
mesh built on axis-aligned or diagonal grids."""


def watertight_hits(o: np.ndarray, d: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Which of ``triangles`` (F, 3, 3) the ray ``o + t d`` (t > 0) hits, by the kernels'
    watertight test (``wrt.kernels.intersect.intersect_triangle``) on the same float32 inputs:
    the ray sheared along its largest axis, the edge functions of the sheared vertices with
    their exact signs (float64 products of float32 values), edges inclusive, ``U + V + W == 0`` a
    miss, ``t`` from the triangle's plane in float64, rounded once."""
    o32, d32 = np.asarray(o, dtype=np.float32), np.asarray(d, dtype=np.float32)
    v = np.asarray(triangles, dtype=np.float32).astype(np.float64)
    kz = int(np.argmax(np.abs(d32)))
    kx, ky = (kz + 1) % 3, (kz + 2) % 3
    sx, sy = np.float64(d32[kx] / d32[kz]), np.float64(d32[ky] / d32[kz])
    rel = (v - o32.astype(np.float64)).astype(np.float32).astype(np.float64)  # v - o, rounded as in float32
    x = (rel[..., kx] - sx * rel[..., kz]).astype(np.float32).astype(np.float64)
    y = (rel[..., ky] - sy * rel[..., kz]).astype(np.float32).astype(np.float64)
    u = x[:, 2] * y[:, 1] - y[:, 2] * x[:, 1]
    v_ = x[:, 0] * y[:, 2] - y[:, 0] * x[:, 2]
    w = x[:, 1] * y[:, 0] - y[:, 1] * x[:, 0]
    mixed = ((u < 0) | (v_ < 0) | (w < 0)) & ((u > 0) | (v_ > 0) | (w > 0))
    normal = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    denom = normal @ d32.astype(np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (np.einsum("ij,ij->i", normal, v[:, 0] - o32.astype(np.float64)) / denom).astype(np.float32)
    return ~mixed & (u + v_ + w != 0) & (denom != 0) & (t > 0) & (t < np.inf)


def watertight_crossings(o: np.ndarray, d: np.ndarray, triangles: np.ndarray) -> int:
    """How many of ``triangles`` the ray ``o + t d`` (t > 0) crosses (``watertight_hits``)."""
    return int(np.count_nonzero(watertight_hits(o, d, triangles)))
