"""What a scene asks of its kernels: the flags integrator kernels are specialised on.

Each integrator's kernel is built per distinct ``Features`` value by a factory whose ``@wp.func``
bodies test the flags with ``wp.static``, so a feature the scene does not use is not in the
generated code at all: no shadow rays or light sampling without lights, no sampling of emissive
primitives without emitting meshes, triangles, polygons or spheres (``wrt.emitting``), and of
triangles only without emitting polygons or spheres, no branch stack,
Fresnel or media bookkeeping without mirrors and dielectrics, no rough dielectric's, plastic's or mask's
BSDF cases (``wrt.kernels.materials.make_bsdf``, the families' ``feature`` flags) nor their light
sampling across a surface or lobe choice without them, no lens or shutter-time sampling
with a pinhole camera or nothing moving, no orthographic projection with a perspective camera,
no shading-normal interpolation without smooth-shaded meshes, no texture coordinates or lookups
without textures, no tangent frames or normal-map lookups without normal maps, no free-flight
sampling, phase functions or medium bookkeeping without participating media (``wrt.kernels.volumes``),
no Beckmann microfacets where every rough material is GGX (``wrt.kernels.microfacet``), no tangent
frame nor second alpha where every rough material is isotropic;
and in the traversal (``wrt.kernels.traverse``) no test of a primitive kind the scene lacks, and no
per-primitive ray motion when no surface moves. ``ALL`` (every flag set) is the all-features
kernel that renders any scene (its flags say what a scene MAY have: it tests the camera's type,
aperture and shutter at run time). Variants compile on
first use, each into its own Warp module (see ``wrt.kernels.variants``), and land in Warp's
kernel cache.
"""

from __future__ import annotations

from dataclasses import astuple, dataclass, make_dataclass

from .materials import MATERIAL_FLAGS


@dataclass(frozen=True)
class SceneFeatures:
    """The flags of the scene's camera, lights and geometry; ``Features`` adds the material families'."""

    lights: bool = True  # any light: shadow rays (whitted), next-event estimation and environment (path)
    environment_map: bool = True  # an environment light with a map: its lookup and sampling (path)
    emissive: bool = True  # emissive primitives sampled by next-event estimation (path; wrt.emitting)
    emissive_shapes: bool = True  # emissive polygons and spheres among them (sets ``emissive`` too)
    specular: bool = True  # mirrors or dielectrics: reflected and refracted rays
    dielectric: bool = True  # refraction, Fresnel, nested media, Beer-Lambert absorption
    lens: bool = True  # a thin lens (aperture_radius > 0): lens sampling
    orthographic: bool = True  # an orthographic camera: parallel rays from the camera plane
    motion: bool = True  # moving shapes and an open shutter: shutter-time sampling
    moving: bool = True  # some surface has a velocity: rays are moved into each primitive's frame
    spheres: bool = True  # primitive kinds in the BVH (sphere lights are spheres, area lights polygons)
    triangles: bool = True
    polygons: bool = True
    disks: bool = True
    cylinders: bool = True
    instances: bool = True  # instances of groups: a two-level traversal
    smooth: bool = True  # smooth-shaded meshes: shading normals interpolated from vertex normals
    textures: bool = True  # textured material parameters: the hit's uv (wrt.kernels.textures)
    normal_map: bool = (
        True  # normal- or bump-mapped materials: the hit's frame, a tilted shading normal (wrt.kernels.hit)
    )
    media: bool = True  # participating media: free-flight sampling, phase functions, medium changes (path)
    beckmann: bool = True  # Beckmann microfacets on a rough material (else GGX only: wrt.kernels.microfacet)
    anisotropic: bool = True  # an anisotropic rough material: the hit's tangent frame, two alphas (wrt.kernels.hit)

    def __post_init__(self):
        if self.dielectric and not self.specular:
            raise ValueError("dielectric implies specular (refraction and reflection rays)")

    @property
    def key(self) -> str:
        """A short name of the variant, e.g. ``"11001"`` (flags in field order)."""
        return "".join("1" if flag else "0" for flag in astuple(self))


Features = make_dataclass(
    "Features", [(name, bool, True) for name in MATERIAL_FLAGS], bases=(SceneFeatures,), frozen=True
)
Features.__module__ = __name__
Features.__doc__ = """``SceneFeatures`` and a flag per material family compiled in only where a scene has one
(``wrt.kernels.materials.MATERIAL_FLAGS``: ``rough_dielectric``, glossy transmission, light sampled
and media changed across a rough surface, which sets ``dielectric`` too; ``plastic``, a lobe choice
at each bounce; ``mask``, a choice between the inner material and the null lobe at each hit)."""

ALL = Features()


GEOMETRY = ("moving", "spheres", "triangles", "polygons", "disks", "cylinders", "instances")
"""The flags the traversal is compiled on (primitive kinds, moving surfaces)."""


def only(features: Features, names) -> Features:
    """``features`` with every flag but ``names`` set (a flag not kept costs no variant)."""
    return Features(**{name: getattr(features, name) for name in names})


def geometry_features(features: Features) -> Features:
    """Only the flags the traversal is compiled on; the others set: the key of a traversal variant."""
    return only(features, GEOMETRY)
