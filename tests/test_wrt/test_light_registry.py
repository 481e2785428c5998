"""The light registry (kernels/lights/__init__.py): the ``[[light]]`` types, the rows of the lights'
table and the families a scene compiles in come from the families' plugin descriptions, and the
one light interface dispatches to them: a family left out is out of the generated code."""

import dataclasses

import numpy as np
import pytest
import warp as wp
from conftest import LAMP_MATERIALS, make_scene
from wrt.kernels.features import ALL
from wrt.kernels.lights import (
    FAMILIES,
    FAMILY_OF,
    LIGHT_TYPES,
    LightData,
    families_for,
    light_row,
    make_lighting,
)
from wrt.kernels.materials import MaterialData
from wrt.kernels.sampling import INDEPENDENT, Sampler
from wrt.kernels.traverse import POLYGON, GeometryData

from wrt.bake import bake_lights
from wrt.device import upload_geometry, upload_lights, upload_materials
from wrt.errors import SceneError
from wrt.geometry import build
from wrt.scene import DELTA_LIGHTS, SURFACE_LIGHTS, EnvironmentLight

pytestmark = pytest.mark.usefixtures("device")  # every test on every available device

# One [[light]] table per type, and whether it is a delta light, written out here (not derived
# from the registry).
LIGHTS = {
    "point": ({"position": [0, 2, 0], "intensity": [1, 1, 1]}, True),
    "directional": ({"direction": [0, -1, 0], "irradiance": [1, 1, 1]}, True),
    "spot": ({"position": [0, 2, 0], "direction": [0, -1, 0], "intensity": [1, 1, 1]}, True),
    "projector": ({"position": [0, 2, 0], "direction": [0, -1, 0], "up": [0, 0, 1], "irradiance": 1.0}, True),
    "area": ({"corner": [-1, 2, -1], "edge_u": [2, 0, 0], "edge_v": [0, 0, 2], "radiance": [1, 1, 1]}, False),
    "sphere": ({"center": [0, 2, 0], "radius": 0.5, "radiance": [1, 1, 1]}, False),
    "environment": ({"radiance": [1, 1, 1]}, False),
}
FLOOR = {"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "floor"}


def test_the_light_types_are_the_families_and_the_scenes():
    """Every host light class has its type among the registry's, each of those a family's, and the
    loader reads each and refuses any other."""
    host = {cls.type for cls in (*DELTA_LIGHTS, *SURFACE_LIGHTS, EnvironmentLight)}
    assert set(LIGHT_TYPES) == host == set(LIGHTS)
    for name in LIGHT_TYPES:
        assert name in FAMILY_OF[name].light_types
        make_scene([], lights=[{"type": name, **LIGHTS[name][0]}])
    with pytest.raises(SceneError, match="light"):
        make_scene([], lights=[{"type": "laser", "position": [0, 0, 0]}])


@pytest.mark.parametrize("name", list(LIGHTS))
def test_each_row_is_its_familys(name):
    """The row ``wrt.bake`` writes for each light carries a code of its family, a delta light's
    below every other (``is_delta`` is one compare), and what the row does not use at its default."""
    table, delta = LIGHTS[name]
    scene = make_scene([], lights=[{"type": name, **table}])
    code = int(bake_lights(scene).rows["type"][0])
    family = FAMILY_OF[name]
    assert code in family.codes and family.delta == delta
    others = [c for f in FAMILIES if not f.delta for c in f.codes]
    assert (code < min(others)) == delta
    row = light_row(scene.lights[0])
    columns = ("type", "position", "direction", "power", "edge_u", "edge_v", "radius", "cutoff", "beam")
    assert set(row) == {*columns, "frame", "uv_scale", "texture"}


def test_a_scene_compiles_in_the_emissive_primitives_only_where_it_has_them():
    assert "emitting" in families_for(ALL)
    assert "emitting" not in families_for(dataclasses.replace(ALL, emissive=False, emissive_shapes=False))
    assert set(families_for(ALL)) == {family.name for family in FAMILIES}


EVERY = make_lighting()
DELTA_ONLY = make_lighting(("delta",))


@wp.kernel
def probe(
    geometry: GeometryData,
    materials: MaterialData,
    lights: LightData,
    sampler: Sampler,
    count: wp.array(dtype=wp.int32),
    delta: wp.array(dtype=wp.int32),
    pdf: wp.array2d(dtype=float),
    pdf_again: wp.array(dtype=float),
):
    """Per emitter ``i``: whether it is a delta light, its sample's density under every family and
    under the delta family alone, and the density of that sample's direction at the area light's
    surface as a BSDF sample would find it."""
    i = wp.tid()
    count[0] = wp.static(EVERY.count)(lights)
    count[1] = wp.static(DELTA_ONLY.count)(lights)
    p = wp.vec3(0.0, 0.0, 0.0)
    delta[i] = wp.where(wp.static(EVERY.is_delta)(lights, i), 1, 0)
    ls = wp.static(EVERY.sample_li)(geometry, materials, lights, i, p, 0.0, sampler, 0, 0, 0)
    pdf[0, i] = ls.pdf
    pdf[1, i] = wp.static(DELTA_ONLY.sample_li)(geometry, materials, lights, i, p, 0.0, sampler, 0, 0, 0).pdf
    if i == 1:  # the area light: surface num_shapes + 1, the scene's only polygon
        dist = ls.t_max / (1.0 - 1.0e-4)
        surface = geometry.num_shapes + 1
        pdf_again[0] = wp.static(EVERY.pdf_li)(geometry, lights, surface, POLYGON, -1, p, ls.wi, dist)
        pdf_again[1] = wp.static(DELTA_ONLY.pdf_li)(geometry, lights, surface, POLYGON, -1, p, ls.wi, dist)


def test_the_interface_dispatches_to_the_families_compiled_in():
    """A point light, an area light and an emissive sphere (the pool, emitter 2): every family's
    interface counts three emitters and samples each (a point light's density 1, the area light's
    found again by ``pdf_li`` at its surface); the delta family's alone counts the rows only and
    samples nothing else."""
    lamp = {"type": "sphere", "center": [3, 2, 0], "radius": 0.5, "material": "lamp"}
    lights = [{"type": "point", **LIGHTS["point"][0]}, {"type": "area", **LIGHTS["area"][0]}]
    scene = make_scene([FLOOR, lamp], materials=LAMP_MATERIALS, lights=lights)
    device = wp.get_device()
    prims = build(scene, device)
    geometry, materials = upload_geometry(prims, device), upload_materials(scene, device)
    light_data = upload_lights(scene, device, prims)
    sampler = Sampler()
    sampler.kind, sampler.seed, sampler.spp, sampler.strata_x = INDEPENDENT, 7, 1, 1
    count, delta = wp.zeros(2, dtype=wp.int32), wp.zeros(3, dtype=wp.int32)
    pdf, pdf_again = wp.zeros((2, 3), dtype=float), wp.zeros(2, dtype=float)
    wp.launch(probe, 3, [geometry, materials, light_data, sampler, count, delta, pdf, pdf_again])
    assert list(count.numpy()) == [3, 2]
    assert list(delta.numpy()) == [1, 0, 0]
    pdf, pdf_again = pdf.numpy(), pdf_again.numpy()
    assert pdf[0, 0] == 1.0 and pdf[0, 1] > 0.0 and pdf[0, 2] > 0.0
    assert pdf[1, 0] == 1.0 and pdf[1, 1] == 0.0 and pdf[1, 2] == 0.0
    np.testing.assert_allclose(pdf_again[0], pdf[0, 1], rtol=1e-5)
    assert pdf_again[1] == 0.0
