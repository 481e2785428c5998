"""Scene shapes flattened into primitive arrays (host, float64), and their BVH, ready for upload.

Every ``[[shape]]`` becomes primitives of one kind: a sphere, a plane, a triangle, a polygon, a
disk or cylinder (its unit shape's transforms), or a mesh's triangles; each primitive remembers
its surface: the shape's index (the ``object_id``), or for the surface of light k (a
parallelogram is a polygon, a sphere light a sphere) ``n_shapes + k``. Bounded primitives go into
one BVH with mixed kinds (built on the render device, ``wrt.bvh``); planes are unbounded and stay
outside it. After the build each kind's arrays are reordered to the order the leaves list them,
for memory locality.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np
import warp as wp

from wrt.kernels.bvh import LEAF_COUNT_BITS, LEAF_COUNT_MASK, WideNode
from wrt.kernels.traverse import CYLINDER, DISK, INSTANCE, KIND_BITS, KIND_MASK, PLANE, POLYGON, SPHERE, TRIANGLE

from .bvh import DeviceBvh, build_bvh
from .scene import (
    IDENTITY3,
    AreaLight,
    Cylinder,
    Disk,
    Instance,
    Mesh,
    Plane,
    Polygon,
    Scene,
    Sphere,
    SphereLight,
    Triangle,
    box_corners,
)
from .textures import attribute_names

FLOAT32_EPS = float(np.finfo(np.float32).eps)


@dataclass
class Primitives:
    """All primitives of a scene by kind (world space; float64, but triangle vertices float32 as
    traced: a large mesh's triangle soup is built once, at half the size; shape ids int32)."""

    sphere_center: np.ndarray  # (S, 3)
    sphere_radius: np.ndarray  # (S,)
    sphere_shape: np.ndarray
    sphere_to_object: np.ndarray  # (S, 3, 3): world offsets to the sphere's object axes (Sphere.to_object)
    tri_verts: np.ndarray  # (T, 3, 3) float32: triangle, vertex, xyz
    tri_shape: np.ndarray
    tri_normals: np.ndarray  # (T, 3, 3) float32 unit shading normals at the corners of smooth triangles, zero
    # for flat ones; (0, 3, 3) when no triangle is smooth (wrt.scene.Mesh.normals)
    poly_verts: list  # P arrays (n_i, 3)
    poly_normal: np.ndarray  # (P, 3) unit
    poly_shape: np.ndarray
    plane_point: np.ndarray  # (L, 3)
    plane_normal: np.ndarray  # (L, 3) unit
    plane_shape: np.ndarray
    quadric_to_world: np.ndarray  # (Q, 4, 4) float64: disks and cylinders, their unit shape placed (wrt.scene)
    quadric_kind: np.ndarray  # (Q,) DISK or CYLINDER
    quadric_flip: np.ndarray  # (Q,) bool: normals inward
    quadric_shape: np.ndarray
    # texture coordinates (wrt.kernels.traverse.texture_context), empty in scenes without textures:
    tri_uvs: np.ndarray = field(default_factory=lambda: np.zeros((0, 3, 2), np.float32))  # (T, 3, 2) per corner
    # mesh attributes (wrt.textures.attribute_names' order) at each triangle corner, 1-channel ones in all three
    # channels, zero on a triangle without them; (0, 3, 0, 3) in a scene whose textures read none:
    tri_attributes: np.ndarray = field(default_factory=lambda: np.zeros((0, 3, 0, 3), np.float32))  # (T, 3, A, 3)
    poly_uv: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 4)))  # (P, 2, 4): uv = M (p, 1)
    plane_uv: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 4)))  # (L, 2, 4)
    surface_velocity: np.ndarray | None = None  # (shapes + lights, 3): scene units per unit time
    num_shapes: int = 0  # surfaces numbered from here on belong to lights
    bvh: DeviceBvh | None = None  # over the bounded primitives, on the render device
    prims: np.ndarray | None = None  # (N,) packed ids in leaf order
    # instances of groups (wrt.scene.Instance); each group's primitives follow the scene's own in
    # the arrays above, in its object space, with a tree of its own after the scene's in bvh.nodes
    inst_to_world: np.ndarray = field(default_factory=lambda: np.zeros((0, 4, 4)))  # (I, 4, 4) float64
    inst_shape: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int32))  # its [[shape]] index
    inst_group: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int32))
    inst_lo: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), dtype=np.float32))  # world boxes
    inst_hi: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), dtype=np.float32))
    inst_root: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int32))  # its group's root node
    inst_entries: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=np.int32))  # (first, count)
    top_count: int = 0  # entries of prims in the scene's own tree

    def bounded_ids(self) -> np.ndarray:
        """Packed ids ``(index << KIND_BITS) | kind`` of spheres, then triangles, then polygons,
        then disks and cylinders (``quadric_*`` order), then instances."""
        return np.concatenate(
            [
                (np.arange(len(self.sphere_radius)) << KIND_BITS) | SPHERE,
                (np.arange(len(self.tri_shape)) << KIND_BITS) | TRIANGLE,
                (np.arange(len(self.poly_verts)) << KIND_BITS) | POLYGON,
                (np.arange(len(self.quadric_kind)) << KIND_BITS) | self.quadric_kind,
                (np.arange(len(self.inst_shape)) << KIND_BITS) | INSTANCE,
            ]
        ).astype(np.int64)

    def shape_of(self, packed: np.ndarray, inst: np.ndarray | None = None) -> np.ndarray:
        """Shape index (``object_id``) of each packed primitive id; -1 where the id is -1 (no hit);
        with ``inst`` (from ``closest_instanced``), the instance's where a primitive was hit
        through one."""
        if inst is not None:
            inst = np.asarray(inst)
            return np.where(
                inst >= 0, self.inst_shape[np.maximum(inst, 0)] if len(self.inst_shape) else -1, self.shape_of(packed)
            )
        packed = np.asarray(packed, dtype=np.int64)
        kind, index = packed & KIND_MASK, packed >> KIND_BITS
        out = np.full(packed.shape, -1, dtype=np.int32)
        for k, table in (
            (SPHERE, self.sphere_shape),
            (TRIANGLE, self.tri_shape),
            (POLYGON, self.poly_shape),
            (DISK, self.quadric_shape),
            (CYLINDER, self.quadric_shape),
            (PLANE, self.plane_shape),
            (INSTANCE, self.inst_shape),
        ):
            hit = (packed >= 0) & (kind == k)
            out[hit] = table[index[hit]]
        return out

    def bounds(self, shutter: tuple[float, float] = (0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
        """float32 boxes (N, 3) holding each bounded primitive as the device holds it (float32
        values), in ``bounded_ids`` order, over the times of ``shutter``: a moving primitive's box
        covers its whole sweep. Triangle and polygon boxes are exact; sphere boxes and sweeps are
        computed in float64 and rounded outward; so are the exact boxes of disks and tubes (per axis,
        an ellipse ``c + u cos + v sin`` spans ``c +- sqrt(u^2 + v^2)``; a tube, its two end rims)."""
        center, radius = _f32(self.sphere_center), _f32(self.sphere_radius)[:, None]
        sphere_lo, sphere_hi = round_outward(center - radius, center + radius)
        to_world = self.quadric_transforms()[1]
        rim = np.sqrt(to_world[:, :3, 0] ** 2 + to_world[:, :3, 1] ** 2)
        axis = np.where((self.quadric_kind == CYLINDER)[:, None], to_world[:, :3, 2], 0.0)
        origin = to_world[:, :3, 3]
        quadric_lo, quadric_hi = round_outward(origin - rim + np.minimum(axis, 0.0), origin + rim + np.maximum(axis, 0))
        polys = [v.astype(np.float32) for v in self.poly_verts]
        tri = self.tri_verts
        tri_lo = np.minimum(np.minimum(tri[:, 0], tri[:, 1]), tri[:, 2])  # 5x faster than min(axis=1) on (T, 3, 3)
        tri_hi = np.maximum(np.maximum(tri[:, 0], tri[:, 1]), tri[:, 2])
        lo = np.concatenate(
            [sphere_lo, tri_lo] + [v.min(axis=0, keepdims=True) for v in polys] + [quadric_lo, self.inst_lo]
        )
        hi = np.concatenate(
            [sphere_hi, tri_hi] + [v.max(axis=0, keepdims=True) for v in polys] + [quadric_hi, self.inst_hi]
        )
        moving_surface = np.any(self.surface_velocity != 0.0, axis=1) & (shutter[0] != 0.0 or shutter[1] != 0.0)
        if moving_surface.any():
            shapes = np.concatenate(
                [self.sphere_shape, self.tri_shape, self.poly_shape, self.quadric_shape, self.inst_shape]
            )
            moving = np.flatnonzero(moving_surface[shapes])
            v = self.surface_velocity[shapes[moving]]
            sweep = [v * shutter[0], v * shutter[1]]
            lo[moving], hi[moving] = round_outward(lo[moving] + np.minimum(*sweep), hi[moving] + np.maximum(*sweep))
        return lo, hi

    def quadric_transforms(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The transforms of the disks and cylinders as the device holds them: ``to_object`` (Q, 4,
        4) float32, world -> object, which the ray tests apply, so it defines the float32 surface;
        ``to_world`` (Q, 4, 4) float64, its exact inverse (to float64 rounding); and the normal
        matrix (Q, 3, 3) float32: ``to_object``'s 3x3 part transposed (the inverse transpose of
        ``to_world``), scaled to a largest entry of 1 so that normals normalise in float32 at any
        scale, negated where normals point inward."""
        to_object = _affine_inverse(self.quadric_to_world).astype(np.float32)
        linear = to_object[:, :3, :3].astype(np.float64).transpose(0, 2, 1)
        sign = np.where(self.quadric_flip, -1.0, 1.0)[:, None, None]
        normal = sign * linear / np.abs(linear).max(axis=(1, 2), keepdims=True)
        return to_object, _affine_inverse(to_object.astype(np.float64)), normal.astype(np.float32)


def _affine_inverse(m: np.ndarray) -> np.ndarray:
    """Inverses (float64) of a stack of invertible affine 4x4 matrices, last row exactly 0 0 0 1."""
    linear = np.linalg.inv(m[:, :3, :3])
    out = np.zeros(m.shape)
    out[:, :3, :3] = linear
    out[:, :3, 3] = -np.einsum("qij,qj->qi", linear, m[:, :3, 3])
    out[:, 3, 3] = 1.0
    return out


def round_outward(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """float32 bounds containing the float64 boxes [lo, hi]: each value rounded toward its side."""
    lo32 = np.asarray(lo, dtype=np.float64).astype(np.float32)
    hi32 = np.asarray(hi, dtype=np.float64).astype(np.float32)
    lo32 = np.where(lo32 > lo, np.nextafter(lo32, np.float32(-np.inf)), lo32)
    hi32 = np.where(hi32 < hi, np.nextafter(hi32, np.float32(np.inf)), hi32)
    return lo32, hi32


def _f32(a: np.ndarray) -> np.ndarray:
    """``a`` rounded to float32, as the device holds it, in float64."""
    return np.asarray(a, dtype=np.float64).astype(np.float32).astype(np.float64)


def flatten(scene: Scene) -> Primitives:
    """Collect the primitives of every shape, tagged with the shape's index in file order (with
    their texture coordinates when a material of the scene has textures)."""
    spheres, tris, polys, planes, quadrics, insts = [], [], [], [], [], []
    tri_blocks, tri_shape_blocks, normal_blocks, uv_blocks, attribute_blocks = [], [], [], [], []
    names = attribute_names(scene.materials)
    for i, shape in enumerate(scene.shapes):
        if isinstance(shape, Sphere):
            spheres.append((shape.center, shape.radius, i, shape.to_object))
        elif isinstance(shape, Plane):
            planes.append((shape.point, shape.normal, i))
        elif isinstance(shape, Triangle):
            tris.append((shape.vertices, i))
        elif isinstance(shape, Polygon):
            polys.append((shape.vertices, shape.normal, i, shape.uvs))
        elif isinstance(shape, Mesh):
            tri_blocks.append(shape.vertices.astype(np.float32)[shape.faces])
            tri_shape_blocks.append(np.full(len(shape.faces), i, dtype=np.int32))
            uv_blocks.append(None if shape.uvs is None else shape.uvs.astype(np.float32)[shape.faces])
            attribute_blocks.append(_corner_attributes(shape, names))
            normal_blocks.append(
                None if shape.normals is None else _corner_normals(shape.normals[shape.faces], tri_blocks[-1])
            )
        elif isinstance(shape, Disk):
            quadrics.append((shape.to_world, DISK, False, i))
        elif isinstance(shape, Cylinder):
            quadrics.append((shape.to_world, CYLINDER, shape.flip_normals, i))
        elif isinstance(shape, Instance):
            insts.append((shape.matrix, i, shape.group))
    for k, light in enumerate(scene.lights):
        surface = len(scene.shapes) + k
        if isinstance(light, SphereLight):
            spheres.append((light.center, light.radius, surface, IDENTITY3))
        elif isinstance(light, AreaLight):
            normal = np.cross(np.asarray(light.edge_u, dtype=np.float64), light.edge_v)
            polys.append((light.corners(), tuple(normal / np.linalg.norm(normal)), surface, None))
    members = sum(len(group.shapes) for group in scene.groups)  # their surfaces follow the lights'
    velocity = [shape.velocity for shape in scene.shapes] + [(0.0, 0.0, 0.0)] * (len(scene.lights) + members)
    tri_blocks.insert(0, np.asarray([v for v, _ in tris], dtype=np.float32).reshape(-1, 3, 3))
    tri_shape_blocks.insert(0, np.asarray([s for _, s in tris], dtype=np.int32))
    tri_normals = np.zeros((0, 3, 3), dtype=np.float32)
    if any(block is not None for block in normal_blocks):
        blocks = [None, *normal_blocks]  # the [[shape]] triangles' first: flat
        tri_normals = _joined([np.zeros_like(t) if n is None else n for n, t in zip(blocks, tri_blocks)])
    textured = any(material.textures or material.anisotropic for material in scene.materials)  # uv, dp/du
    barycentric = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]], dtype=np.float32)  # uv = (b1, b2)
    uv_blocks.insert(0, None)  # the [[shape]] triangles'
    attribute_blocks.insert(0, np.zeros((len(tris), 3, len(names), 3), np.float32))
    return Primitives(
        sphere_center=np.asarray([c for c, _, _, _ in spheres], dtype=np.float64).reshape(-1, 3),
        sphere_radius=np.asarray([r for _, r, _, _ in spheres], dtype=np.float64),
        sphere_shape=np.asarray([s for _, _, s, _ in spheres], dtype=np.int32),
        sphere_to_object=np.asarray([m for _, _, _, m in spheres], dtype=np.float64).reshape(-1, 3, 3),
        tri_verts=_joined(tri_blocks),
        tri_shape=_joined(tri_shape_blocks),
        tri_normals=tri_normals,
        poly_verts=[np.asarray(v, dtype=np.float64) for v, _, _, _ in polys],
        poly_normal=np.asarray([n for _, n, _, _ in polys], dtype=np.float64).reshape(-1, 3),
        poly_shape=np.asarray([s for _, _, s, _ in polys], dtype=np.int32),
        plane_point=np.asarray([p for p, _, _ in planes], dtype=np.float64).reshape(-1, 3),
        plane_normal=np.asarray([n for _, n, _ in planes], dtype=np.float64).reshape(-1, 3),
        plane_shape=np.asarray([s for _, _, s in planes], dtype=np.int32),
        quadric_to_world=np.asarray([m for m, _, _, _ in quadrics], dtype=np.float64).reshape(-1, 4, 4),
        quadric_kind=np.asarray([k for _, k, _, _ in quadrics], dtype=np.int32),
        quadric_flip=np.asarray([f for _, _, f, _ in quadrics], dtype=bool),
        quadric_shape=np.asarray([s for _, _, _, s in quadrics], dtype=np.int32),
        tri_uvs=_joined(
            [np.broadcast_to(barycentric, (len(t), 3, 2)) if uv is None else uv for uv, t in zip(uv_blocks, tri_blocks)]
        )
        if textured
        else np.zeros((0, 3, 2), np.float32),
        tri_attributes=_joined(attribute_blocks) if names else np.zeros((0, 3, 0, 3), np.float32),
        poly_uv=np.asarray([polygon_uv(v, n, uv) for v, n, _, uv in polys] if textured else []).reshape(-1, 2, 4),
        plane_uv=np.asarray([plane_uv(p, n) for p, n, _ in planes] if textured else []).reshape(-1, 2, 4),
        surface_velocity=np.asarray(velocity, dtype=np.float64).reshape(-1, 3),
        num_shapes=len(scene.shapes),
        inst_to_world=np.asarray([m for m, _, _ in insts], dtype=np.float64).reshape(-1, 4, 4),
        inst_shape=np.asarray([s for _, s, _ in insts], dtype=np.int32),
        inst_group=np.asarray([g for _, _, g in insts], dtype=np.int32),
    )


def polygon_uv(vertices, normal, uvs) -> np.ndarray:
    """The affine map (2, 4) taking a point ``p`` of a polygon's plane to its texture coordinates,
    ``M (p, 1)``: the least-squares fit (exact for an affine image) of the vertices' ``uvs``
    (None: vertices 0, 1, 2 at (0, 0), (1, 0), (1, 1), ``wrt.scene.Polygon``), constant along the
    unit ``normal``."""
    v = np.asarray(vertices, dtype=np.float64)
    if uvs is None:
        v, uvs = v[:3], [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0)]
    e1, e2 = _plane_axes(normal)
    q = np.column_stack([(v - v[0]) @ e1, (v - v[0]) @ e2, np.ones(len(v))])
    fit = np.linalg.lstsq(q, np.asarray(uvs, dtype=np.float64), rcond=None)[0]  # (3, 2): uv = (q1, q2, 1) fit
    m = np.zeros((2, 4))
    m[:, :3] = fit[0][:, None] * e1 + fit[1][:, None] * e2
    m[:, 3] = fit[2] - m[:, :3] @ v[0]
    return m


def plane_uv(point, normal) -> np.ndarray:
    """The map (2, 4) of an unbounded plane's texture coordinates: the point's coordinates from
    ``point`` along the axes ``_plane_axes(normal)``, ``M (p, 1)``."""
    e1, e2 = _plane_axes(normal)
    m = np.zeros((2, 4))
    m[:, :3] = [e1, e2]
    m[:, 3] = -m[:, :3] @ np.asarray(point, dtype=np.float64)
    return m


def _plane_axes(normal) -> tuple[np.ndarray, np.ndarray]:
    """Unit axes ``(e1, e2)`` with ``(e1, e2, normal)`` right-handed and orthonormal (Duff et al.
    2017, as ``wrt.loader``'s frames of disks and cylinders)."""
    x, y, z = np.asarray(normal, dtype=np.float64)
    sign = math.copysign(1.0, z)
    a = -1.0 / (sign + z)
    b = x * y * a
    return np.array([1.0 + sign * x * x * a, sign * b, -sign * x]), np.array([b, sign + y * y * a, -y])


def _corner_attributes(mesh: Mesh, names: tuple[str, ...]) -> np.ndarray:
    """float32 (T, 3, A, 3): attributes ``names`` of ``mesh`` at its triangles' corners (a vertex
    attribute at each corner's vertex, a face attribute at all three), one channel spread to
    three; zero for an attribute the mesh does not have."""
    out = np.zeros((len(mesh.faces), 3, len(names), 3), np.float32)
    for a, name in enumerate(names):
        values = mesh.attributes.get(name)
        if values is not None:
            corners = values[mesh.faces] if name.startswith("vertex_") else values[:, None, :]
            out[:, :, a, :] = np.broadcast_to(corners, (len(mesh.faces), 3, values.shape[1]))
    return out


def _joined(blocks: list[np.ndarray]) -> np.ndarray:
    """The blocks end to end; the only non-empty block itself (a large mesh is not copied)."""
    full = [b for b in blocks if len(b)]
    return full[0] if len(full) == 1 else np.concatenate(blocks)


def _corner_normals(normals: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """float32 shading normals (T, 3, 3) at the corners of a smooth mesh's triangles: their vertex
    ``normals`` (T, 3, 3), and where one is zero (the vertex has none) the triangle's unit face
    normal, from its float32 ``corners`` (T, 3, 3) as traced (zero for a degenerate triangle)."""
    missing = ~np.any(normals != 0.0, axis=2)
    if missing.any():
        c = corners.astype(np.float64)
        face = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
        length = np.linalg.norm(face, axis=1, keepdims=True)
        face = np.divide(face, length, out=np.zeros_like(face), where=length > 0.0)
        normals = np.where(missing[:, :, None], face[:, None, :], normals)
    return normals.astype(np.float32)


def _joined_normals(a: Primitives, b: Primitives) -> np.ndarray:
    """``tri_normals`` of ``a``'s triangles then ``b``'s: empty if neither has smooth triangles,
    else zero for the flat ones of each."""
    if not len(a.tri_normals) and not len(b.tri_normals):
        return a.tri_normals
    return np.concatenate(
        [p.tri_normals if len(p.tri_normals) else np.zeros((len(p.tri_shape), 3, 3), np.float32) for p in (a, b)]
    )


INDEX_SPACES = ((SPHERE,), (TRIANGLE,), (POLYGON,), (DISK, CYLINDER), (INSTANCE,))
"""The kinds whose packed ids index one set of arrays (disks and cylinders: ``quadric_*``)."""


def build(scene: Scene, device) -> Primitives:
    """Flatten ``scene``, build the BVH over its bounded primitives (and instances) on ``device``
    (a Warp device) and reorder to leaf order; then append the instanced groups, each with a BVH
    of its own in its object space."""
    p = flatten(scene)
    groups = _build_groups(scene, device) if len(p.inst_shape) else []
    if groups:
        p.inst_lo, p.inst_hi = _instance_boxes(p.inst_to_world, [g.bounds() for g in groups], p.inst_group)
    _build_tree(p, scene.camera.shutter, device)
    p.top_count = len(p.prims)
    if groups:
        _append_groups(p, groups, device)
    return p


def _build_tree(p: Primitives, shutter: tuple[float, float], device) -> None:
    """Build the BVH over ``p``'s bounded primitives and reorder each kind to leaf order."""
    bvh = build_bvh(*p.bounds(shutter), device)
    order = bvh.order.numpy()
    counts = (len(p.sphere_radius), len(p.tri_shape), len(p.poly_verts), len(p.quadric_kind), len(p.inst_shape))
    if max(counts) == len(order):  # one index space (a mesh, say): the leaf order is its order
        space = INDEX_SPACES[int(np.argmax(counts))]
        s = t = g = q = i = order
        kind = p.quadric_kind[order] if len(space) > 1 else space[0]
        new_ids = (np.arange(len(order), dtype=np.int32) << KIND_BITS) | kind
    else:
        ids = p.bounded_ids()[order]
        kind = ids & KIND_MASK
        # renumber the packed ids: the k-th primitive of an index space in leaf order now has index k
        new_ids = np.empty(len(ids), dtype=np.int32)
        leaf_order = []
        for space in INDEX_SPACES:
            mask = np.isin(kind, space)
            leaf_order.append(ids[mask] >> KIND_BITS)
            new_ids[mask] = (np.arange(mask.sum()) << KIND_BITS) | kind[mask]
        s, t, g, q, i = leaf_order
    if counts[0]:
        p.sphere_center, p.sphere_radius, p.sphere_shape = p.sphere_center[s], p.sphere_radius[s], p.sphere_shape[s]
        p.sphere_to_object = p.sphere_to_object[s]
    if counts[1]:
        p.tri_verts, p.tri_shape = p.tri_verts[t], p.tri_shape[t]
        if len(p.tri_normals):
            p.tri_normals = p.tri_normals[t]
        if len(p.tri_uvs):
            p.tri_uvs = p.tri_uvs[t]
        if len(p.tri_attributes):
            p.tri_attributes = p.tri_attributes[t]
    if counts[2]:
        p.poly_verts, p.poly_normal, p.poly_shape = [p.poly_verts[k] for k in g], p.poly_normal[g], p.poly_shape[g]
        if len(p.poly_uv):
            p.poly_uv = p.poly_uv[g]
    if counts[3]:
        p.quadric_to_world, p.quadric_kind = p.quadric_to_world[q], p.quadric_kind[q]
        p.quadric_flip, p.quadric_shape = p.quadric_flip[q], p.quadric_shape[q]
    if counts[4]:
        p.inst_to_world, p.inst_shape, p.inst_group = p.inst_to_world[i], p.inst_shape[i], p.inst_group[i]
        p.inst_lo, p.inst_hi = p.inst_lo[i], p.inst_hi[i]
    p.bvh, p.prims = bvh, new_ids


def _build_groups(scene: Scene, device) -> list[Primitives]:
    """Each group's primitives (object space) with its BVH, in leaf order; their surfaces are
    numbered after the shapes' and lights', group by group (``wrt.bake.surface_materials``)."""
    groups = []
    first = len(scene.shapes) + len(scene.lights)
    for group in scene.groups:
        g = flatten(dataclasses.replace(scene, shapes=group.shapes, lights=(), groups=()))
        for table in (g.sphere_shape, g.tri_shape, g.poly_shape, g.quadric_shape):
            table += first
        first += len(group.shapes)
        _build_tree(g, (0.0, 0.0), device)
        groups.append(g)
    return groups


def _instance_boxes(to_world: np.ndarray, group_bounds: list, group: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """float32 world boxes of instances: the eight corners of their group's box through their
    ``to_world`` (float64), widened by the rounding of the float32 transforms the device applies
    to rays (a few ulps of the corners and of the transform's scale times the group's extent)."""
    lo, hi = np.zeros((len(group), 3)), np.zeros((len(group), 3))
    for k, (g_lo, g_hi) in enumerate(group_bounds):
        box_lo, box_hi = g_lo.min(axis=0).astype(np.float64), g_hi.max(axis=0).astype(np.float64)
        corners = box_corners(box_lo, box_hi)
        mine = np.flatnonzero(group == k)
        m = to_world[mine]
        world = np.einsum("nij,cj->nci", m[:, :3, :3], corners) + m[:, None, :3, 3]
        extent = np.abs(world).max(axis=(1, 2)) + np.linalg.norm(m[:, :3, :3], axis=(1, 2)) * np.abs(corners).max()
        margin = 16 * FLOAT32_EPS * extent[:, None]
        lo[mine], hi[mine] = world.min(axis=1) - margin, world.max(axis=1) + margin
    return round_outward(lo, hi)


def _append_groups(p: Primitives, groups: list[Primitives], device) -> None:
    """Append the groups' primitives to ``p``'s arrays, their trees to its nodes (references
    moved to the new positions) and their leaf entries to its primitive list; point each instance
    at its group's root node and entries."""
    nodes, prims = [p.bvh.nodes.numpy()], [p.prims]
    node_count, prim_count = len(nodes[0]), len(p.prims)
    roots, entries = [], []
    for g in groups:
        quadrics = len(p.quadric_kind)
        offset = {SPHERE: len(p.sphere_radius), TRIANGLE: len(p.tri_shape), POLYGON: len(p.poly_verts)}
        offset.update({DISK: quadrics, CYLINDER: quadrics})
        ids = g.prims.astype(np.int64)
        kind, index = ids & KIND_MASK, ids >> KIND_BITS
        for k, first in offset.items():
            index[kind == k] += first
        prims.append(((index << KIND_BITS) | kind).astype(np.int32))
        tree = g.bvh.nodes.numpy()
        child = tree["child"]
        leaf = child < 0
        start, count = (-1 - child[leaf]) >> LEAF_COUNT_BITS, (-1 - child[leaf]) & LEAF_COUNT_MASK
        child[leaf] = -1 - (((start + prim_count) << LEAF_COUNT_BITS) | count)
        child[~leaf] += node_count  # unused lanes (0, with an empty box) move too: never entered
        nodes.append(tree)
        roots.append(node_count)
        entries.append((prim_count, len(ids)))
        node_count, prim_count = node_count + len(tree), prim_count + len(ids)
        p.sphere_center = np.concatenate([p.sphere_center, g.sphere_center])
        p.sphere_radius = np.concatenate([p.sphere_radius, g.sphere_radius])
        p.sphere_shape = np.concatenate([p.sphere_shape, g.sphere_shape])
        p.sphere_to_object = np.concatenate([p.sphere_to_object, g.sphere_to_object])
        p.tri_verts = _joined([p.tri_verts, g.tri_verts])
        p.tri_normals = _joined_normals(p, g)
        p.tri_uvs = _joined([p.tri_uvs, g.tri_uvs])
        p.tri_attributes = _joined([p.tri_attributes, g.tri_attributes])
        p.tri_shape = _joined([p.tri_shape, g.tri_shape])
        p.poly_verts = p.poly_verts + g.poly_verts
        p.poly_normal = np.concatenate([p.poly_normal, g.poly_normal])
        p.poly_uv = np.concatenate([p.poly_uv, g.poly_uv])
        p.poly_shape = np.concatenate([p.poly_shape, g.poly_shape])
        p.quadric_to_world = np.concatenate([p.quadric_to_world, g.quadric_to_world])
        p.quadric_kind = np.concatenate([p.quadric_kind, g.quadric_kind])
        p.quadric_flip = np.concatenate([p.quadric_flip, g.quadric_flip])
        p.quadric_shape = np.concatenate([p.quadric_shape, g.quadric_shape])
    p.bvh = dataclasses.replace(p.bvh, nodes=wp.array(np.concatenate(nodes), dtype=WideNode, device=device))
    p.prims = np.concatenate(prims)
    p.inst_root = np.asarray(roots, dtype=np.int32)[p.inst_group]
    p.inst_entries = np.asarray(entries, dtype=np.int32).reshape(-1, 2)[p.inst_group]
