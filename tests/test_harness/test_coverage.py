"""The coverage table (harness/coverage.py, ``wrt matrix --coverage``): every kind of the scene
format has a feature of wrt's own matrix; a features file lacking a kind shows it as an empty row
and exits 1, rendering nothing; a kind added to a type table of the format is a row at once; and
what a scene exercises is read as each integrator runs it."""

import dataclasses
import re
import typing
from pathlib import Path

import pytest
import wrt_harness.coverage as cov
import wrt_harness.references as references
import wrt_harness.run as run
from conftest import EXAMPLES, make_scene, one_feature_file
from wrt.kernels import textures as texture_slots
from wrt_harness.matrix import load_features

import wrt.loader as loader
import wrt.scene as model
import wrt.textures as textures
from wrt.cli import main
from wrt.meshio import transform_matrix

DOCS = Path(__file__).resolve().parents[2] / "docs" / "scene-format.md"
FEATURE = load_features()[0]  # any feature: exercised reads its scene, and only its passes and target_error keys
SPHERE = {"type": "sphere", "center": [0, 0, 0], "radius": 1.0}


@pytest.fixture
def no_renders(monkeypatch):
    """The coverage renders nothing: any render of the harness fails the test."""

    def refuse(*args, **kwargs):
        raise AssertionError("wrt matrix --coverage rendered")

    for module in (run, references):
        monkeypatch.setattr(module, "render_feature", refuse)


def test_every_kind_of_the_scene_format_has_a_feature(capsys, no_renders):
    """wrt's own matrix exercises every kind of the scene format (the table prints what is missing)."""
    code = main(["matrix", "--coverage"])
    table = capsys.readouterr().out
    assert code == 0 and " NONE" not in table, table


def test_a_features_file_lacking_a_kind_gives_an_empty_row_and_exit_1(tmp_path, capsys, no_renders):
    path = one_feature_file(tmp_path, "spp = 1")  # a raycast sphere: no lights, one camera type
    assert main(["matrix", "--coverage", "--features", str(path)]) == 1
    out = capsys.readouterr().out
    assert re.search(r"^shape +sphere +x$", out, re.M), out
    assert re.search(r"^shape +disk +NONE$", out, re.M) and re.search(r"^light +point +NONE$", out, re.M)
    assert re.search(r"^camera +perspective +x$", out, re.M) and re.search(r"^camera +thin lens +NONE$", out, re.M)
    assert "kinds exercised; no feature exercises: camera thin lens, camera orthographic" in " ".join(out.split())


def test_coverage_renders_nothing_and_is_one_line_on_bad_options(capsys):
    assert main(["matrix", "--coverage", "--report", "r"]) == 2
    assert "--report: not with --coverage" in capsys.readouterr().err


@pytest.mark.parametrize(
    "module, table, group",
    [
        (model, "CAMERA_TYPES", "camera"),
        (loader, "SHAPE_TYPES", "shape"),
        (loader, "MESH_SHADING", "mesh shading"),
        (model, "MATERIAL_TYPES", "material"),
        (loader, "LIGHT_TYPES", "light"),
        (textures, "KINDS", "texture"),
        (model, "SAMPLERS", "sampler"),
        (model, "FILTERS", "filter"),
        (model, "INTEGRATORS", "integrator"),
    ],
)
def test_a_kind_added_to_a_type_table_is_an_empty_row(module, table, group, monkeypatch, tmp_path, capsys):
    """The kinds are read from the format's own tables: a new one is a row, empty until a feature has it."""
    monkeypatch.setattr(module, table, (*getattr(module, table), "brand_new"))
    rows = cov.coverage(load_features(one_feature_file(tmp_path, "spp = 1")))
    assert cov.Row(group, "brand_new", ()) in rows
    assert main(["matrix", "--coverage", "--features", str(tmp_path / "features.toml")]) == 1
    assert re.search(rf"^{group} +brand_new +NONE$", capsys.readouterr().out, re.M)


def test_a_texture_slot_added_is_an_empty_row(monkeypatch):
    monkeypatch.setattr(texture_slots, "SLOTS", (*texture_slots.SLOTS, "sheen"))
    assert ("material option", "texture: sheen") in cov.kinds()


def test_the_scene_model_names_its_kinds_as_the_tables_do():
    """What the coverage reads off a parsed scene (a shape's class, a light's type, a texture's
    class) is spelled as the tables spell the kinds, so no kind is counted under another name."""
    assert sorted(cov.kind_name(c) for c in typing.get_args(model.Shape)) == sorted(loader.SHAPE_TYPES)
    lights = [model.PointLight, model.DirectionalLight, model.SpotLight, model.ProjectorLight, model.AreaLight]
    lights += [model.SphereLight]
    types = [f.default for c in (*lights, model.EnvironmentLight) for f in dataclasses.fields(c) if f.name == "type"]
    assert sorted(types) == sorted(loader.LIGHT_TYPES)
    assert sorted(cov.kind_name(c) for c in typing.get_args(textures.Texture)) == sorted(textures.KINDS)


def test_every_kind_of_the_tables_is_documented():
    """Each kind of the tables is a name docs/scene-format.md gives (in backquotes)."""
    doc = DOCS.read_text()
    tables = [model.CAMERA_TYPES, loader.SHAPE_TYPES, loader.MESH_SHADING, model.MATERIAL_TYPES, texture_slots.SLOTS]
    tables += [loader.LIGHT_TYPES, textures.KINDS, model.SAMPLERS, model.FILTERS, model.INTEGRATORS]
    missing = [name for table in tables for name in table if not re.search(rf'`"?{re.escape(name)}"?`', doc)]
    assert not missing


def kinds_of(scene, **keys) -> set:
    return cov.exercised(dataclasses.replace(FEATURE, **keys) if keys else FEATURE, scene)


def test_cameras():
    pinhole = make_scene([SPHERE], render={"integrator": "path"})
    lens = make_scene([SPHERE], camera={"origin": [0, 0, 5], "look_at": [0, 0, 0], "aperture_radius": 0.1})
    ortho = make_scene([SPHERE], camera={"origin": [0, 0, 5], "look_at": [0, 0, 0], "type": "orthographic", "width": 3})
    assert ("camera", "perspective") in kinds_of(pinhole)
    assert ("camera", "thin lens") in kinds_of(lens) and ("camera", "perspective") not in kinds_of(lens)
    assert ("camera", "orthographic") in kinds_of(ortho)


def test_raycast_exercises_geometry_not_materials_or_lights():
    """raycast shades flat and ignores lights; whitted runs the materials the shapes have (a
    mask's material too, not one no shape has), and the lights."""
    materials = [
        {"name": "unused", "type": "mirror"},
        {"name": "red", "albedo": [0.8, 0.1, 0.1], "two_sided": False},
        {"name": "glass", "type": "dielectric"},
    ]
    lights = [{"type": "directional", "direction": [0, -1, 0], "irradiance": [1, 1, 1]}]
    shapes = [{**SPHERE, "material": "red"}, {**SPHERE, "center": [2, 0, 0], "material": "glass"}]
    for integrator in ("raycast", "whitted"):
        found = kinds_of(make_scene(shapes, {"integrator": integrator}, materials=materials, lights=lights))
        shading = integrator == "whitted"
        assert ("integrator", integrator) in found and ("shape", "sphere") in found
        assert (("material", "diffuse") in found) == shading and (("material", "dielectric") in found) == shading
        assert (("light", "directional") in found) == shading
        assert (("material option", "one-sided") in found) == shading
        assert ("material", "mirror") not in found and ("material option", "two-sided") not in found

    masked = [{"name": "shiny", "type": "glossy"}, {"name": "cut", "type": "mask", "material": "shiny"}]
    found = kinds_of(make_scene([{**SPHERE, "material": "cut"}], {"integrator": "path"}, materials=masked))
    assert {("material", "mask"), ("material", "glossy")} <= found


def test_samplers_filters_and_motion_blur_count_where_they_run():
    """The filter needs more than one sample a pixel; the sampler too, or the path integrator's
    random bounces; motion blur an open shutter, a moving shape and more than one sample."""
    still = make_scene([SPHERE], {"integrator": "whitted", "spp": 1, "filter": "gaussian"})
    assert not {("filter", "gaussian"), ("sampler", "sobol")} & kinds_of(still)
    found = kinds_of(make_scene([SPHERE], {"integrator": "path", "spp": 1, "sampler": "stratified"}))
    assert ("sampler", "stratified") in found and ("filter", "box") not in found
    assert ("filter", "gaussian") in kinds_of(make_scene([SPHERE], {"spp": 4, "filter": "gaussian"}))
    camera = {"origin": [0, 0, 5], "look_at": [0, 0, 0], "shutter": [0, 1]}
    moving = [{**SPHERE, "velocity": [0.5, 0, 0]}]
    assert ("rendering", "motion blur") in kinds_of(make_scene(moving, {"spp": 4}, camera=camera))
    assert ("rendering", "motion blur") not in kinds_of(make_scene(moving, {"spp": 1}, camera=camera))
    assert ("rendering", "motion blur") not in kinds_of(make_scene([SPHERE], {"spp": 4}, camera=camera))


def test_meshes_groups_instances_textures_and_emission():
    mesh = {"type": "mesh", "file": str(EXAMPLES / "meshes" / "coarse_sphere.obj"), "material": "lamp"}
    materials = [
        {"name": "lamp", "emission": [1, 1, 1]},
        {"name": "checks", "albedo": {"texture": "checkerboard"}},
    ]
    groups = [{"name": "g", "shape": [{**mesh, "shading": "smooth"}, {**SPHERE, "material": "checks"}]}]
    shapes = [mesh, {"type": "instance", "group": "g", "transform": {"rotate": [0, 30, 0], "scale": [1, 2, 1]}}]
    found = kinds_of(make_scene(shapes, {"integrator": "path"}, materials=materials, groups=groups))
    assert {("shape", "mesh"), ("shape", "sphere"), ("shape", "instance")} <= found
    assert {("mesh shading", "flat"), ("mesh shading", "smooth")} <= found
    assert {("instance transform", "rotation"), ("instance transform", "non-uniform scale")} <= found
    assert {("material option", "texture: albedo"), ("texture", "checkerboard"), ("light", "emissive shape")} <= found


@pytest.mark.parametrize(
    "transform, kinds",
    [
        ({"translate": [1, 2, 3]}, set()),
        ({"scale": 2.0}, set()),
        ({"rotate": [0, 30, 0]}, {"rotation"}),
        ({"scale": [1, 2, 3]}, {"non-uniform scale"}),
        ({"rotate": [10, 20, 30], "scale": [1, 2, 3]}, {"rotation", "non-uniform scale"}),
        ({"matrix": [1, 0.5, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]}, {"shear"}),
        ({"scale": [-1, 1, 1]}, {"mirroring"}),
        ({"scale": [1, 1, -1], "rotate": [0, 45, 0]}, {"mirroring", "rotation"}),
    ],
)
def test_instance_transforms(transform, kinds):
    assert cov.transform_kinds(transform_matrix(**transform)) == kinds


def test_progressive_and_adaptive_are_keys_of_the_feature():
    """``passes`` > 1 and ``target_error`` of the feature, whatever its scene (None: it does not load)."""
    plain = dataclasses.replace(FEATURE, passes=1, target_error=None)
    assert not {("rendering", "progressive"), ("rendering", "adaptive")} & cov.exercised(plain, None)
    assert cov.exercised(dataclasses.replace(plain, passes=4), None) == {("rendering", "progressive")}
    assert cov.exercised(dataclasses.replace(plain, target_error=0.05), None) == {("rendering", "adaptive")}


def test_the_table_names_every_kind_once(tmp_path):
    rows = cov.coverage(load_features(one_feature_file(tmp_path, "spp = 1")))
    table = cov.format_table(rows)
    assert len(rows) == len(cov.kinds()) == len(set(cov.kinds()))
    for row in rows:
        line = rf"^{re.escape(row.group)} +{re.escape(row.kind)} +{'x' if row.features else 'NONE'}$"
        assert len(re.findall(line, table, re.M)) == 1, (row, table)
