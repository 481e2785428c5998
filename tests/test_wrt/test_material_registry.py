"""The material registry (kernels/materials/__init__.py): what it derives from the families' plugin
descriptions is what the loader, the variants, the scene analysis, the upload and the Mitsuba
converter use, and a family left out of the dispatch is out of the generated code."""

import dataclasses

import numpy as np
import pytest
import warp as wp
from conftest import make_scene
from test_mitsuba_xml import convert
from wrt.kernels.features import ALL, Features
from wrt.kernels.materials import (
    FAMILIES,
    FAMILY_OF,
    MATERIAL_FLAGS,
    TYPES,
    MaterialData,
    _dispatch,
    families_for,
    make_bsdf,
)
from wrt.kernels.materials.interface import Functions
from wrt.kernels.textures import TextureEvalContext
from wrt.kernels.variants import RELEVANT

from wrt.device import upload_materials
from wrt.errors import SceneError
from wrt.renderer import scene_features
from wrt.scene import MATERIAL_TYPES

pytestmark = pytest.mark.usefixtures("device")  # every test on every available device

SPHERE = {"type": "sphere", "center": [0, 0, -3], "radius": 1, "material": "m"}
INNER = {"name": "inner", "type": "diffuse"}
PARAMETERS = {  # one [[material]] table per type, besides its name
    "diffuse": {},
    "phong": {"specular": [0.2, 0.2, 0.2]},
    "mirror": {},
    "glossy": {"roughness": 0.2},
    "conductor": {"metal": "Au"},
    "rough_conductor": {"metal": "Au", "roughness": 0.2},  # a conductor too
    "dielectric": {},
    "thin_dielectric": {},
    "rough_dielectric": {"roughness": 0.2},
    "plastic": {},
    "rough_plastic": {"roughness": 0.2},
    "principled": {"metallic": 0.3},
    "principled_thin": {"diff_trans": 0.5},
    "mask": {"opacity": 0.5, "material": "inner"},
    "blend": {"weight": 0.5, "materials": ["inner", "inner"]},
    "null": {},
}
# What a scene of each type asks of the kernels, written out here (not derived from the registry):
# reflected or refracted rays (specular), a medium (dielectric), and the families compiled in only
# where a scene has one.
EXPECTED = {
    "diffuse": (False, False, set()),
    "phong": (False, False, set()),
    "mirror": (True, False, set()),
    "glossy": (False, False, set()),
    "conductor": (True, False, set()),
    "rough_conductor": (False, False, set()),
    "dielectric": (True, True, set()),
    "thin_dielectric": (True, False, set()),
    "rough_dielectric": (True, True, {"rough_dielectric"}),
    "plastic": (True, False, {"plastic"}),
    "rough_plastic": (False, False, {"plastic"}),
    "principled": (False, False, {"principled"}),
    "principled_thin": (False, False, {"principled"}),
    "mask": (False, False, {"mask"}),
    "blend": (False, False, {"blend"}),
    "null": (False, False, {"null"}),
}


def scene_of(name: str):
    table = {"name": "m", "type": name.replace("rough_conductor", "conductor"), **PARAMETERS[name]}
    return make_scene([SPHERE], materials=[table, INNER] if name in ("mask", "blend") else [table])


def test_the_types_and_codes_are_each_familys_and_unique():
    codes = [t.code for t in TYPES.values()]
    assert len(set(codes)) == len(codes) == sum(len(family.types) for family in FAMILIES)
    assert set(MATERIAL_TYPES) == set(TYPES) - {"emitter"} == set(PARAMETERS) - {"rough_conductor"}
    assert all(FAMILY_OF[t.name].name == family.name for family in FAMILIES for t in family.types)


def test_the_material_flags_are_features_and_relevant_to_path():
    fields = [f.name for f in dataclasses.fields(Features)]
    assert MATERIAL_FLAGS == ("rough_dielectric", "plastic", "principled", "blend", "mask", "null")
    assert set(MATERIAL_FLAGS) <= set(fields) and set(MATERIAL_FLAGS) <= set(RELEVANT["path"])
    assert Features(plastic=False).plastic is False and ALL.plastic is True
    assert families_for(Features(plastic=False, principled=False, blend=False, mask=False, null=False)) == (
        "diffuse",
        "phong",
        "conductor",
        "dielectric",
        "thin_dielectric",
        "rough_dielectric",
        "emitter",
    )
    assert "mask" not in families_for(ALL, whitted=True) and "mask" in families_for(ALL)
    assert "blend" not in families_for(ALL, whitted=True) and "blend" in families_for(ALL)


@pytest.mark.parametrize("name", EXPECTED)
def test_scene_features_follow_each_familys_description(name):
    features = scene_features(scene_of(name))
    specular, dielectric, flags = EXPECTED[name]
    assert (features.specular, features.dielectric) == (specular, dielectric)
    assert {flag for flag in MATERIAL_FLAGS if getattr(features, flag)} == flags


@pytest.mark.parametrize("name", MATERIAL_TYPES)
def test_the_loader_reads_exactly_each_types_keys(name):
    """A key of another type is refused, naming it; each of the type's own keys is read."""
    own = set(TYPES[name].keys)
    nested = {"two_sided", "material", "opacity", "materials", "weight"}  # a nested material's keys are its own
    foreign = sorted({key for t in TYPES.values() for key in t.keys} - own - nested)
    table = {"name": "m", "type": name, **PARAMETERS[name], foreign[0]: 0.5}
    with pytest.raises(SceneError, match=foreign[0]):
        make_scene([SPHERE], materials=[table, INNER] if name in ("mask", "blend") else [table])
    scene_of(name)  # its own keys: accepted


MITSUBA_BODIES = {
    "diffuse": "",
    "conductor": '<string name="material" value="Au"/>',
    "roughconductor": '<string name="material" value="Au"/><string name="distribution" value="ggx"/>',
    "dielectric": "",
    "roughdielectric": '<string name="distribution" value="ggx"/>',
    "thindielectric": "",
    "plastic": "",
    "roughplastic": '<string name="distribution" value="ggx"/>',
    "principled": '<float name="metallic" value="0.3"/>',
    "principledthin": '<float name="diff_trans" value="0.5"/>',
    "mask": '<bsdf type="diffuse"/>',
    "blendbsdf": '<bsdf type="diffuse"/><bsdf type="diffuse"/>',
    "null": "",
}


@pytest.mark.parametrize("plugin", [name for family in FAMILIES for name in family.mitsuba])
def test_each_familys_mitsuba_plugins_convert_to_it_exactly(tmp_path, plugin):
    body = f'<shape type="sphere"><bsdf type="{plugin}" id="b">{MITSUBA_BODIES[plugin]}</bsdf></shape>'
    doc, warnings = convert(tmp_path, body, approximate=False)
    assert warnings == []
    material = next(m for m in doc["material"] if m["name"] == "b")
    assert plugin in FAMILY_OF[material["type"]].mitsuba


PLASTIC_LEFT_OUT = make_bsdf(families_for(Features(plastic=False)), True)
EVERY_FAMILY = make_bsdf()


@wp.kernel
def eval_sample(
    materials: MaterialData,
    f: wp.array(dtype=wp.vec3),
    weight: wp.array(dtype=wp.vec3),
):
    n = wp.vec3(0.0, 0.0, 1.0)
    wo = wp.normalize(wp.vec3(0.3, 0.0, 1.0))
    wi = wp.normalize(wp.vec3(-0.2, 0.1, 1.0))
    f[0] = wp.static(PLASTIC_LEFT_OUT.eval)(materials, 0, n, wo, wi)
    weight[0] = wp.static(PLASTIC_LEFT_OUT.sample)(materials, 0, n, wo, 1.0, 0.7, wp.vec2(0.3, 0.6)).weight
    f[1] = wp.static(EVERY_FAMILY.eval)(materials, 0, n, wo, wi)
    weight[1] = wp.static(EVERY_FAMILY.sample)(materials, 0, n, wo, 1.0, 0.7, wp.vec2(0.3, 0.6)).weight


def test_a_family_left_out_of_the_dispatch_scatters_nothing():
    """A plastic under a dispatch compiled without the plastic family: f and the sample's weight 0;
    under every family's, both positive."""
    materials = upload_materials(scene_of("rough_plastic"), wp.get_device())
    f, weight = wp.zeros(2, dtype=wp.vec3), wp.zeros(2, dtype=wp.vec3)
    wp.launch(eval_sample, dim=1, inputs=[materials, f, weight])
    f, weight = f.numpy(), weight.numpy()
    assert np.all(f[0] == 0.0) and np.all(weight[0] == 0.0)
    assert np.all(f[1] > 0.0) and np.all(weight[1] > 0.0)


def diffuse_like(halved: bool) -> Functions:
    """A family of one Lambertian type (code 0), its f halved or not: two sources of one function."""

    @wp.func
    def owns(kind: wp.int32) -> bool:
        return kind == 0

    if halved:

        @wp.func
        def eval(
            materials: MaterialData,
            m: wp.int32,
            n: wp.vec3,
            wo: wp.vec3,
            wi: wp.vec3,
            eta: float,
            ctx: TextureEvalContext,
        ) -> wp.vec3:
            return materials.albedo[m] / (2.0 * wp.pi)

    else:

        @wp.func
        def eval(
            materials: MaterialData,
            m: wp.int32,
            n: wp.vec3,
            wo: wp.vec3,
            wi: wp.vec3,
            eta: float,
            ctx: TextureEvalContext,
        ) -> wp.vec3:
            return materials.albedo[m] / wp.pi

    return Functions(owns, eval)


def module_hash(functions: list, module: str) -> bytes:
    """Warp's hash of a module (of this name) whose kernel calls the dispatch over ``functions``."""
    bsdf_eval = _dispatch(functions).eval

    @wp.kernel(module=module)
    def probe(materials: MaterialData, out: wp.array(dtype=wp.vec3)):
        n = wp.vec3(0.0, 0.0, 1.0)
        out[0] = bsdf_eval(materials, 0, n, n, n)

    return wp.get_module(module).hash_module()


def test_an_edited_family_changes_the_hash_of_every_module_that_calls_it():
    """The kernel cache is keyed by this hash: were a family's code left out of it, an edited
    family would load the binary of the code before the edit (as the unrolled ``wp.static`` loop
    did, ``_dispatch``). The same code in modules of two names hashes alike: the name is not
    what tells them apart."""
    assert module_hash([diffuse_like(False)], "wrt_probe_a") == module_hash([diffuse_like(False)], "wrt_probe_b")
    assert module_hash([diffuse_like(False)], "wrt_probe_c") != module_hash([diffuse_like(True)], "wrt_probe_d")
