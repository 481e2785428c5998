"""What the matrix exercises: every kind the scene format has, and the features that exercise it.

The kinds are read from the scene format's own type tables when ``kinds`` is called, never
listed here: camera types (``wrt.scene.CAMERA_TYPES``; a perspective camera with
``aperture_radius > 0`` is the thin lens), shape kinds (``wrt.loader.SHAPE_TYPES``), mesh shading
modes (``wrt.loader.MESH_SHADING``), material types (``wrt.scene.MATERIAL_TYPES``), the texture
slots of materials (``wrt.kernels.textures.SLOTS``, ``normal_map`` among them), light types
(``wrt.loader.LIGHT_TYPES``; the environment without and with a map), texture kinds
(``wrt.textures.KINDS``), medium and phase function types, samplers, pixel filters and
integrators (``wrt.scene``). A few kinds
are properties rather than names of a table, each defined once below: one- and two-sided
materials, emissive shapes, an instance's transform (rotation, non-uniform scale, shear,
mirroring), motion blur, and progressive and adaptive rendering (keys of the feature, not of its
scene: ``passes`` and ``target_error``). A kind added to one of the tables is a row of the table
at once, empty until a feature's scene has it.

What a feature exercises is read from its parsed scene (``matrix.load_feature_scene``, the
render settings of the feature applied), with what each integrator runs:

- every integrator: the camera, the shapes (those of ``[[group]]`` s too), the mesh shading
  modes, instances and their transforms, motion blur (``spp > 1``, an open shutter and a moving
  shape); the sampler where random numbers are drawn (``spp > 1``, or the path integrator); the
  pixel filter where ``spp > 1`` (one sample sits at the pixel centre);
- whitted and path only (raycast shades flat and ignores lights): the materials the shapes use
  (a mask's material too), their textures and sidedness, the media and their phase functions,
  the lights and emissive shapes.
"""

from __future__ import annotations

import dataclasses
import re
import textwrap

import numpy as np
from wrt.kernels import textures as texture_slots
from wrt.kernels.materials import TYPES

import wrt.loader as loader
import wrt.scene as model
import wrt.textures as textures

from .matrix import Feature, load_feature_scene

THIN_LENS = "thin lens"  # a perspective camera with aperture_radius > 0
CONSTANT_ENVIRONMENT = "environment (constant)"
ENVIRONMENT_MAP = "environment (map)"
EMISSIVE_SHAPE = "emissive shape"  # a shape whose material has an emission
SIDES = ("one-sided", "two-sided")  # materials of the types that read two_sided, by its value
INSTANCE_TRANSFORMS = ("rotation", "non-uniform scale", "shear", "mirroring")
RENDERING = ("motion blur", "progressive", "adaptive")
TOLERANCE = 1e-9  # relative: what counts as a rotation, a scale, a shear in an instance's matrix


@dataclasses.dataclass(frozen=True)
class Row:
    """One kind of the scene format (``group``: camera, shape, material...) and the features
    that exercise it, in features-file order."""

    group: str
    kind: str
    features: tuple[str, ...]


def kinds() -> list[tuple[str, str]]:
    """Every ``(group, kind)`` of the scene format, in table order, read from the type tables now."""
    cameras = []
    for camera in model.CAMERA_TYPES:
        cameras += [camera, THIN_LENS] if camera == "perspective" else [camera]
    lights = []
    for light in loader.LIGHT_TYPES:
        lights += [CONSTANT_ENVIRONMENT, ENVIRONMENT_MAP] if light == "environment" else [light]
    table = {
        "camera": cameras,
        "shape": loader.SHAPE_TYPES,
        "mesh shading": loader.MESH_SHADING,
        "instance transform": INSTANCE_TRANSFORMS,
        "material": model.MATERIAL_TYPES,
        "material option": [f"texture: {slot}" for slot in texture_slots.SLOTS] + list(SIDES),
        "medium": model.MEDIUM_TYPES,
        "phase function": model.PHASE_TYPES,
        "texture": textures.KINDS,
        "light": [*lights, EMISSIVE_SHAPE],
        "sampler": model.SAMPLERS,
        "filter": model.FILTERS,
        "integrator": model.INTEGRATORS,
        "rendering": RENDERING,
    }
    return [(group, kind) for group, names in table.items() for kind in names]


def kind_name(cls: type) -> str:
    """The name the scene file gives an object of the scene model's class ``cls``: the class
    name in snake case (``Sphere``: ``sphere``, ``MeshAttribute``: ``mesh_attribute``), as
    ``wrt.loader.SHAPE_TYPES`` names the ``wrt.scene.Shape`` classes and ``wrt.textures.KINDS``
    the ``wrt.textures.Texture`` ones."""
    return re.sub(r"(?<=[a-z])(?=[A-Z])", "_", cls.__name__).lower()


def transform_kinds(matrix: np.ndarray) -> set[str]:
    """What an affine map (4x4) does besides translating, of ``INSTANCE_TRANSFORMS``: its linear
    part is ``Q K``, ``Q`` orthogonal and ``K`` upper triangular with a positive diagonal (QR); a
    mirroring has a negative determinant, a rotation a ``Q`` that is not diagonal (a diagonal one
    only flips axes), a non-uniform scale unequal diagonal entries of ``K``, a shear off-diagonal
    ones."""
    q, k = np.linalg.qr(np.asarray(matrix, dtype=np.float64)[:3, :3])
    signs = np.where(np.diag(k) < 0, -1.0, 1.0)
    q, k = q * signs, k * signs[:, None]
    scale = np.abs(np.diag(k))
    found = set()
    if np.linalg.det(q) < 0:
        found.add("mirroring")
    if np.abs(q - np.diag(np.diag(q))).max() > TOLERANCE:
        found.add("rotation")
    if scale.max() - scale.min() > TOLERANCE * scale.max():
        found.add("non-uniform scale")
    if np.abs(np.triu(k, 1)).max() > TOLERANCE * scale.max():
        found.add("shear")
    return found


def _shapes(scene: model.Scene) -> list:
    """The shapes of ``scene`` and of its groups."""
    return [*scene.shapes, *(shape for group in scene.groups for shape in group.shapes)]


def _used_materials(scene: model.Scene) -> list[model.Material]:
    """The materials a shape of ``scene`` (of a group too) has, and those that their masks mask."""
    used = {shape.material for shape in _shapes(scene) if not isinstance(shape, model.Instance)}
    by_name = {m.name: i for i, m in enumerate(scene.materials)}
    used |= {by_name[scene.materials[i].material] for i in list(used) if scene.materials[i].type == "mask"}
    return [scene.materials[i] for i in sorted(used)]


def exercised(feature: Feature, scene: model.Scene | None) -> set[tuple[str, str]]:
    """The ``(group, kind)`` pairs that ``feature`` exercises, its scene ``scene`` (the feature's
    ``load_feature_scene``; None: only what its own keys say) by the rules of the module docstring."""
    found = set()
    if feature.passes > 1:
        found.add(("rendering", "progressive"))
    if feature.target_error is not None:
        found.add(("rendering", "adaptive"))
    if scene is None:
        return found
    render, camera = scene.render, scene.camera
    shapes = _shapes(scene)
    lens = camera.type == "perspective" and camera.aperture_radius > 0
    found.add(("camera", THIN_LENS if lens else camera.type))
    found.add(("integrator", render.integrator))
    if render.spp > 1 or render.integrator == "path":
        found.add(("sampler", render.sampler))
    if render.spp > 1:
        found.add(("filter", render.filter))
    for shape in shapes:
        found.add(("shape", kind_name(type(shape))))
        if isinstance(shape, model.Mesh):
            found.add(("mesh shading", "flat" if shape.normals is None else "smooth"))
        if isinstance(shape, model.Instance):
            found |= {("instance transform", kind) for kind in transform_kinds(shape.matrix)}
    moving = any(shape.velocity != model.STILL for shape in scene.shapes)
    if render.spp > 1 and camera.shutter[1] > camera.shutter[0] and moving:
        found.add(("rendering", "motion blur"))
    if render.integrator == "raycast":
        return found
    materials = _used_materials(scene)
    emitting = {i for i, m in enumerate(scene.materials) if any(m.emission)}
    for material in materials:
        found.add(("material", material.type))
        found |= {("material option", f"texture: {slot}") for slot, _ in material.textures}
        found |= {("texture", kind_name(type(texture))) for _, texture in material.textures}
        if "two_sided" in TYPES[material.type].keys:  # the types whose sidedness is an option
            found.add(("material option", SIDES[material.two_sided]))  # SIDES[False] is one-sided
    if any(not isinstance(s, model.Instance) and s.material in emitting for s in shapes):
        found.add(("light", EMISSIVE_SHAPE))
    for medium in scene.media:
        found |= {("medium", medium.type), ("phase function", medium.phase)}
    for light in scene.lights:
        if isinstance(light, model.EnvironmentLight):
            found.add(("light", CONSTANT_ENVIRONMENT if light.image is None else ENVIRONMENT_MAP))
        else:
            found.add(("light", light.type))
    return found


def coverage(features: list[Feature], scenes: dict[str, model.Scene | None] | None = None) -> list[Row]:
    """One ``Row`` per kind of the scene format (``kinds``) naming the ``features`` that exercise
    it. ``scenes``: their scenes by feature name where already loaded (None: one that does not
    load, counted by its keys only); the others are loaded here (``load_feature_scene``, whose
    ``WrtError`` names a scene that does not load)."""
    scenes = scenes or {}
    by_feature = [
        (f.name, exercised(f, scenes[f.name] if f.name in scenes else load_feature_scene(f))) for f in features
    ]
    return [Row(group, kind, tuple(n for n, found in by_feature if (group, kind) in found)) for group, kind in kinds()]


def empty(rows: list[Row]) -> list[Row]:
    """The rows no feature exercises."""
    return [row for row in rows if not row.features]


def format_table(rows: list[Row], width: int = 120) -> str:
    """The rows as a text table (group, kind, features), the feature lists wrapped at ``width``
    columns, then a line of how many kinds are exercised and which are not."""
    group_width = max(len("group"), *(len(r.group) for r in rows))
    kind_width = max(len("kind"), *(len(r.kind) for r in rows))
    indent = " " * (group_width + kind_width + 4)
    lines = [f"{'group':<{group_width}}  {'kind':<{kind_width}}  features"]
    for row in rows:
        names = ", ".join(row.features) or "NONE"
        wrapped = textwrap.wrap(names, width, initial_indent=indent, subsequent_indent=indent, break_on_hyphens=False)
        lines.append(f"{row.group:<{group_width}}  {row.kind:<{kind_width}}  {wrapped[0][len(indent) :]}")
        lines += wrapped[1:]
    missing = empty(rows)
    summary = f"{len(rows) - len(missing)} of {len(rows)} kinds exercised"
    if missing:
        summary += "; no feature exercises: " + ", ".join(f"{r.group} {r.kind}" for r in missing)
    return "\n".join([*lines, *textwrap.wrap(summary, width, subsequent_indent="    ", break_on_hyphens=False)])
