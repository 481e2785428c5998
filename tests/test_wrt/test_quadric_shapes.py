"""Disks and cylinders in scene files: the TOML keys and their validation (wrt/loader.py), the
Mitsuba importer's conversion (wrt/mitsuba/shapes.py) checked ray by ray against Mitsuba's own
intersections, and the geometry oracle's drawing of them (harness/oracle.py)."""

import textwrap

import numpy as np
import pytest
from conftest import make_scene
from wrt_harness.mitsuba_peer import mitsuba_available

import wrt
from wrt.errors import SceneError, WrtError
from wrt.mitsuba import load_mitsuba
from wrt.scene import Cylinder, Disk
from wrt.stress.offsets import trace_spawned_batch
from wrt.trace import Tracer

MITSUBA, MITSUBA_REASON = mitsuba_available()
needs_mitsuba = pytest.mark.skipif(not MITSUBA, reason=MITSUBA_REASON)
DISK = {"type": "disk", "center": [1, 2, 3], "normal": [0, 0, -2], "radius": 0.5}
CYLINDER = {"type": "cylinder", "p0": [1, 0, 0], "p1": [1, 3, 0], "radius": 0.25}


def apply(m, points):
    return np.asarray(points, dtype=np.float64) @ m[:3, :3].T + m[:3, 3]


def test_disk_keys_place_the_unit_disk():
    """``center``, ``normal`` (normalised: the front), ``radius``: the unit rim lands on the circle
    of that radius around the centre, perpendicular to the normal, which is ``to_world``'s z column."""
    (disk,) = make_scene([DISK]).shapes
    assert isinstance(disk, Disk)
    phi = np.linspace(0, 2 * np.pi, 17)
    rim = apply(disk.to_world, np.column_stack([np.cos(phi), np.sin(phi), np.zeros_like(phi)]))
    np.testing.assert_allclose(np.linalg.norm(rim - [1, 2, 3], axis=1), 0.5)
    np.testing.assert_allclose(rim[:, 2], 3.0)
    np.testing.assert_allclose(disk.to_world[:3, 2], [0, 0, -1])
    np.testing.assert_allclose(np.linalg.inv(disk.to_world[:3, :3]).T @ [0, 0, 1], [0, 0, -1], atol=1e-15)


def test_cylinder_keys_place_the_unit_tube():
    """``p0`` and ``p1`` are the ends of the axis, ``radius`` the tube's; normals outward unless
    ``flip_normals``."""
    (tube, flipped) = make_scene([CYLINDER, {**CYLINDER, "flip_normals": True}]).shapes
    assert isinstance(tube, Cylinder) and not tube.flip_normals and flipped.flip_normals
    np.testing.assert_allclose(apply(tube.to_world, [[0, 0, 0], [0, 0, 1]]), [[1, 0, 0], [1, 3, 0]], atol=1e-15)
    phi = np.linspace(0, 2 * np.pi, 17)
    ring = apply(tube.to_world, np.column_stack([np.cos(phi), np.sin(phi), np.full_like(phi, 0.5)]))
    np.testing.assert_allclose(np.linalg.norm(ring[:, [0, 2]] - [1, 0], axis=1), 0.25)
    np.testing.assert_allclose(ring[:, 1], 1.5)


def test_transform_applies_after_the_shapes_own_placement():
    """``transform`` (as for meshes) maps the placed shape: a disk of radius 1 at the origin
    scaled by (2, 1, 1) is an ellipse with semi-axes 2 and 1, and a mirroring transform keeps
    the front normal (the inverse transpose of the map)."""
    transform = {"scale": [2, 1, 1], "translate": [0, 0, 4]}
    (disk,) = make_scene([{**DISK, "center": [0, 0, 0], "radius": 1, "transform": transform}]).shapes
    phi = np.linspace(0, 2 * np.pi, 17)
    rim = apply(disk.to_world, np.column_stack([np.cos(phi), np.sin(phi), np.zeros_like(phi)]))
    np.testing.assert_allclose((rim[:, 0] / 2) ** 2 + rim[:, 1] ** 2, 1.0)
    np.testing.assert_allclose(rim[:, 2], 4.0)
    mirror = {"matrix": [-1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]}
    (mirrored,) = make_scene([{**DISK, "transform": mirror}]).shapes
    np.testing.assert_allclose(mirrored.to_world[:3, 2], [0, 0, -1])
    (tube,) = make_scene([{**CYLINDER, "transform": {"rotate": [0, 0, 90]}}]).shapes
    np.testing.assert_allclose(apply(tube.to_world, [[0, 0, 1]]), [[-3, 1, 0]], atol=1e-12)


@pytest.mark.parametrize(
    "shape, where, message",
    [
        ({**DISK, "normal": [0, 0, 0]}, "shape[1].normal = [0, 0, 0]", "zero vector"),
        ({**DISK, "radius": 0}, "shape[1].radius = 0", "must be in (0"),
        ({**DISK, "radius": "1"}, "shape[1].radius = '1'", "must be a number"),
        ({**DISK, "flip_normals": True}, "shape[1].flip_normals", "unknown key"),
        ({**CYLINDER, "p1": [1, 0, 0]}, "shape[1].p1 = [1, 0, 0]", "must differ from p0"),
        ({**CYLINDER, "radius": -1}, "shape[1].radius = -1", "must be in (0"),
        ({**CYLINDER, "flip_normals": "yes"}, "shape[1].flip_normals = 'yes'", "true or false"),
        ({**CYLINDER, "p0": [1, 0]}, "shape[1].p0 = [1, 0]", "3 numbers"),
        ({**CYLINDER, "radius": 1e-39}, "shape[1].radius = 1e-39", "too small or too thin for float32"),
        ({**DISK, "transform": {"scale": [1e-39, 1e-39, 1]}}, "shape[1].transform =", "too small or too thin"),
        ({**DISK, "radius": 1e18, "transform": {"scale": 10}}, "shape[1].transform =", "1e+18"),
        ({**CYLINDER, "transform": {"scale": 0}}, "shape[1].transform.scale = 0", "must be nonzero"),
        ({**CYLINDER, "transform": {"matrix": [1, 2]}}, "shape[1].transform.matrix = [1, 2]", "16 numbers"),
    ],
)
def test_bad_disks_and_cylinders_are_refused_naming_the_key(shape, where, message):
    with pytest.raises(SceneError) as e:
        make_scene([{"type": "sphere", "center": [0, 0, 0], "radius": 1}, shape])
    assert "<test>" in str(e.value) and where in str(e.value) and message in str(e.value), str(e.value)


def write_xml(tmp_path, body):
    path = tmp_path / "scene.xml"
    path.write_text(f'<scene version="3.0.0">\n{textwrap.dedent(body).strip()}\n</scene>\n')
    return path


TO_WORLD = (
    '<transform name="to_world"><matrix value="1.2 0.6 0 -0.5  0 0.9 0.2 0  0.3 0 -0.8 0.4  0 0 0 1"/></transform>'
)


def test_mitsuba_disk_and_cylinder_convert_exactly(tmp_path):
    """No warning; the unit disk and the tube of ``p0``, ``p1``, ``radius`` with ``to_world`` as the
    transform matrix; ``flip_normals`` turns the disk's normal and the tube's normals around; an
    area emitter becomes emission of the material, without a warning; shapes keep file order."""
    body = f"""
    <shape type="disk">{TO_WORLD}<boolean name="flip_normals" value="true"/></shape>
    <shape type="sphere"/>
    <shape type="cylinder">
        <float name="radius" value="0.3"/><point name="p0" value="1, 2, 3"/><point name="p1" value="1, 2, 5"/>
        <boolean name="flip_normals" value="true"/>
        <bsdf type="twosided" id="red">
            <bsdf type="diffuse"><rgb name="reflectance" value="0.8, 0.1, 0.1"/></bsdf>
        </bsdf>
        <emitter type="area"><rgb name="radiance" value="2"/></emitter>
    </shape>
    <shape type="cylinder"/>"""
    doc, warnings = load_mitsuba(write_xml(tmp_path, body))
    assert warnings == []
    disk, sphere, tube, plain = doc["shape"]
    matrix = [1.2, 0.6, 0, -0.5, 0, 0.9, 0.2, 0, 0.3, 0, -0.8, 0.4, 0, 0, 0, 1]
    assert {k: disk[k] for k in ("type", "center", "normal", "radius")} == {
        "type": "disk",
        "center": [0, 0, 0],
        "normal": [0, 0, -1],
        "radius": 1,
    }
    flipped = [-x if k % 4 == 1 else x for k, x in enumerate(matrix)]  # to_world scale(1, -1, 1): Mitsuba's uv
    assert disk["transform"] == {"matrix": flipped} and sphere["type"] == "sphere"
    assert {k: tube[k] for k in ("type", "p0", "p1", "radius", "flip_normals")} == {
        "type": "cylinder",
        "p0": [1, 2, 3],
        "p1": [1, 2, 5],
        "radius": 0.3,
        "flip_normals": True,
    }
    emissive = next(m for m in doc["material"] if m["name"] == tube["material"])
    assert emissive["emission"] == [2, 2, 2] and emissive["albedo"] == [0.8, 0.1, 0.1]
    assert plain == {"type": "cylinder", "p0": [0, 0, 0], "p1": [0, 0, 1], "radius": 1, "material": plain["material"]}
    scene = wrt.load_scene(write_xml(tmp_path, body))
    assert [type(s) for s in scene.shapes] == [Disk, type(scene.shapes[1]), Cylinder, Cylinder]


def test_mitsuba_emitter_on_a_sheared_tube_is_an_approximation(tmp_path):
    """Mitsuba samples an emitting tube as right circular: with an unequal radial scale its
    image is biased, so the conversion is refused (converted with ``approximate``)."""
    body = """
    <shape type="cylinder"><transform name="to_world"><scale x="1" y="2"/></transform>
        <emitter type="area"/></shape>"""
    with pytest.raises(WrtError, match="right circular"):
        load_mitsuba(write_xml(tmp_path, body))
    _, warnings = load_mitsuba(write_xml(tmp_path, body), approximate=True)
    assert len(warnings) == 1
    uniform = body.replace('x="1" y="2"', 'value="2"')
    assert load_mitsuba(write_xml(tmp_path, uniform))[1] == []


def test_mitsuba_refuses_a_cylinder_without_length_or_radius(tmp_path):
    for params in ('<point name="p1" value="0, 0, 0"/>', '<float name="radius" value="0"/>'):
        with pytest.raises(WrtError, match="scene.xml:2"):
            load_mitsuba(write_xml(tmp_path, f'<shape type="cylinder">{params}</shape>'))


@needs_mitsuba
@pytest.mark.parametrize(
    "kind, params",
    [
        ("disk", TO_WORLD),
        ("disk", TO_WORLD + '<boolean name="flip_normals" value="true"/>'),
        ("cylinder", TO_WORLD + '<float name="radius" value="0.7"/><point name="p1" value="0.2, 0.3, 1.5"/>'),
        (
            "cylinder",
            '<transform name="to_world"><scale x="-1" y="2"/></transform><boolean name="flip_normals" value="true"/>',
        ),
    ],
)
def test_hits_and_front_normals_match_mitsuba(tmp_path, rng, kind, params):
    """Random rays at the converted shape and at Mitsuba's own: the same hits and misses (but
    within 1e-4 of an edge), ``t`` within 1e-5 relative, and wrt's geometric normal equal to
    Mitsuba's shading normal (the side that emits and that one-sided BSDFs shade)."""
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    path = write_xml(tmp_path, f'<shape type="{kind}">{params}</shape>')
    scene = wrt.load_scene(path)
    theirs = mi.load_file(str(path))
    m = scene.shapes[0].to_world
    n = 1500
    target = apply(m, rng.uniform(-1.2, 1.2, (n, 3)) * [1, 1, 0 if kind == "disk" else 1])
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = target - 6.0 * d
    out = trace_spawned_batch(Tracer(scene), o, d, np.tile([0.0, 0.0, 1.0], (n, 1)), ior=1.5)
    compared = 0
    for k in range(n):
        si = theirs.ray_intersect(mi.Ray3f(o[k], d[k]))
        ours = out["hit_prim"][k] >= 0
        if ours != si.is_valid():
            # only a ray through the rim: its hit point lies within 1e-4 of the edge
            t = out["hit_t"][k] if ours else si.t
            local = np.linalg.solve(m[:3, :3], o[k] + t * d[k] - m[:3, 3])
            edge = abs(np.hypot(*local[:2]) - 1) if kind == "disk" else min(abs(local[2]), abs(local[2] - 1))
            assert edge < 1e-4, (k, local)
            continue
        if ours:
            assert out["hit_t"][k] == pytest.approx(si.t, rel=1e-5)
            np.testing.assert_allclose(out["hit_normal"][k], np.array(si.sh_frame.n), atol=1e-5)
            compared += 1
    assert compared > n / 4


def test_oracle_draws_disks_and_cylinders_where_rays_hit_them(device):
    """The pyvista geometry oracle's id image of an elliptical disk and a tilted tube (seen
    through one open end) agrees with the ray tracer's ``object_id`` AOV but for silhouette pixels."""
    from wrt_harness.oracle import rasterize_ids

    scene = make_scene(
        [
            {
                "type": "disk",
                "center": [0, 0, 0],
                "normal": [0, 1, 0.2],
                "radius": 1.5,
                "transform": {"scale": [1.5, 1, 1]},
            },
            {"type": "cylinder", "p0": [0.3, -0.2, 0.5], "p1": [0.6, 1.2, 1.0], "radius": 0.5},
        ],
        render={"width": 64, "height": 48, "integrator": "raycast", "spp": 1},
        camera={"origin": [0.5, 3, 5], "look_at": [0, 0, 0], "fov": 45},
    )
    ours = wrt.render(scene, device=device).aovs["object_id"]
    theirs = rasterize_ids(scene)
    assert {0, 1} <= set(np.unique(ours))
    assert np.mean(ours == theirs) > 0.98


def test_ray_viewer_draws_disks_and_tubes_under_the_recorded_hits():
    """``wrt rays`` geometry: each disk and tube drawn as its placed unit shape, and the hit
    points the kernels recorded on them lie on (within 1e-3 of) the drawn triangles' surface."""
    import pyvista as pv

    from wrt import rayview
    from wrt.rays import trace_rays

    scene = make_scene(
        [
            {
                "type": "disk",
                "center": [0, -0.5, 0],
                "normal": [0, 1, 0],
                "radius": 2,
                "transform": {"scale": [1.5, 1, 1]},
            },
            {"type": "cylinder", "p0": [0, -0.5, 0], "p1": [0, 0.8, 0], "radius": 0.6},
        ],
        render={"width": 24, "height": 24, "integrator": "raycast"},
        camera={"origin": [0, 2, 5], "look_at": [0, 0, 0]},
    )
    tree = trace_rays(scene, [(x, y) for x in range(0, 24, 3) for y in range(0, 24, 3)])
    blocks = rayview.ray_blocks(tree)
    assert list(blocks["geometry"].keys()) == ["shape[0] disk", "shape[1] cylinder"]
    drawn = pv.merge([blocks["geometry"][k] for k in blocks["geometry"].keys()])
    hits = tree.end[tree.hit]
    assert len(hits) > 20
    _, closest = drawn.find_closest_cell(hits, return_closest_point=True)
    assert np.linalg.norm(closest - hits, axis=1).max() < 1e-3
