"""Ray recording (kernels/record.py, wrt/rays.py) against closed forms, and `wrt rays` (wrt/rayview.py)."""

import dataclasses
import subprocess
import sys

import numpy as np
import pytest
import pyvista as pv
import tomllib
from conftest import EXAMPLES, make_scene
from skimage.io import imread
from wrt.kernels.lights import SHADOW_MARGIN
from wrt.kernels.record import (
    CAMERA,
    REFLECTED,
    REFRACTED,
    SCATTERED,
    SHADOW_BLOCKED,
    SHADOW_LIT,
    STRAIGHT,
    TOTAL_INTERNAL,
)

import wrt
from wrt import rayview
from wrt.cli import main
from wrt.loader import parse_scene
from wrt.rays import grid_pixels, trace_rays

GLASS = {"name": "glass", "type": "dielectric", "ior": 1.5}
HEAD_ON = {
    "origin": [0, 0, 5],
    "look_at": [0, 0, 0],
    "fov": 30,
}  # odd image size: the centre pixel looks down -z exactly


def whitted_scene(shapes, materials, lights=(), camera=HEAD_ON, size=(33, 33), **render):
    settings = {"width": size[0], "height": size[1], "integrator": "whitted", **render}
    return make_scene(shapes, materials=materials, lights=list(lights), camera=camera, render=settings)


def only(rows):
    assert len(rows) == 1, rows
    return rows[0]


def test_glass_sphere_head_on_passes_straight_through():
    scene = whitted_scene([{"type": "sphere", "center": [0, 0, 0], "radius": 1.0, "material": "glass"}], [GLASS])
    tree = trace_rays(scene, [(16, 16)])
    F = (0.5 / 2.5) ** 2  # Fresnel reflectance at normal incidence, ior 1.5
    down = np.array([0.0, 0.0, -1.0])

    camera = only(np.flatnonzero(tree.kind == CAMERA))
    assert tree.hit[camera] and tree.entering[camera] and tree.shape[camera] == 0
    np.testing.assert_allclose(tree.end[camera], [0, 0, 1], atol=1e-5)
    np.testing.assert_allclose(tree.normal[camera], [0, 0, 1], atol=1e-6)

    inside = only([i for i in tree.children(camera) if tree.kind[i] == REFRACTED])
    np.testing.assert_allclose(tree.direction[inside], down, atol=1e-6)
    np.testing.assert_allclose(tree.end[inside], [0, 0, -1], atol=1e-5)
    assert tree.hit[inside] and not tree.entering[inside] and tree.depth[inside] == 2
    np.testing.assert_allclose(tree.throughput[inside], (1 - F) / 1.5**2, rtol=1e-6)  # radiance scales by eta^2

    back = only([i for i in tree.children(camera) if tree.kind[i] == REFLECTED])
    np.testing.assert_allclose(tree.direction[back], -down, atol=1e-6)
    assert tree.escaped[back]
    np.testing.assert_allclose(tree.throughput[back], F, rtol=1e-5)

    out = only([i for i in tree.children(inside) if tree.kind[i] == REFRACTED])
    assert tree.escaped[out] and tree.depth[out] == 3
    np.testing.assert_allclose(tree.direction[out], down, atol=1e-6)  # the exit ray continues along the same line
    np.testing.assert_allclose(tree.origin[out][:2], [0, 0], atol=1e-6)
    np.testing.assert_allclose(tree.throughput[out], (1 - F) ** 2, rtol=1e-5)  # 1 / 1.5^2, then 1.5^2

    on_sphere = tree.hit & (tree.shape == 0)
    assert on_sphere.sum() >= 3  # entry, exit, and the internal reflection's hits
    np.testing.assert_allclose(np.linalg.norm(tree.end[on_sphere].astype(np.float64), axis=1), 1.0, atol=1e-5)
    for i in range(len(tree)):  # every segment starts where its parent ended (up to the spawn offset)
        if tree.parent[i] >= 0:
            np.testing.assert_allclose(tree.origin[i], tree.end[tree.parent[i]], atol=1e-5)


def test_total_internal_reflection_is_marked():
    """A camera inside a glass sphere (r = 10) at height 9 looking sideways meets the surface at
    asin(0.9) = 64 degrees, past the critical angle asin(1/1.5) = 42: one reflected branch only."""
    scene = whitted_scene(
        [{"type": "sphere", "center": [0, 0, 0], "radius": 10.0, "material": "glass"}],
        [GLASS],
        camera={"origin": [0, 9, 0], "look_at": [1, 9, 0], "fov": 30},
        max_depth=2,
    )
    tree = trace_rays(scene, [(16, 16)])
    camera = only(np.flatnonzero(tree.kind == CAMERA))
    assert not tree.entering[camera]
    child = only(tree.children(camera))
    assert tree.kind[child] == TOTAL_INTERNAL
    np.testing.assert_allclose(tree.throughput[child], 1.0)


def test_false_interface_goes_straight_at_the_same_depth():
    """Inside glass of priority 1, the surface of overlapping water (priority 0) is no interface."""
    scene = whitted_scene(
        [
            {"type": "sphere", "center": [0, 0, 0], "radius": 1.0, "material": "glass"},
            {"type": "sphere", "center": [0, 0, -1], "radius": 1.0, "material": "water"},
        ],
        [{**GLASS, "priority": 1}, {"name": "water", "type": "dielectric", "ior": 1.33}],
        max_depth=3,
    )
    tree = trace_rays(scene, [(16, 16)])
    inside = only([i for i in tree.children(0) if tree.kind[i] == REFRACTED])
    assert tree.shape[inside] == 1 and tree.entering[inside]  # meets the water's surface at z = 0
    straight = only(tree.children(inside))
    assert tree.kind[straight] == STRAIGHT and tree.depth[straight] == tree.depth[inside]
    np.testing.assert_allclose(tree.direction[straight], [0, 0, -1], atol=1e-6)
    np.testing.assert_allclose(tree.end[straight], [0, 0, -1], atol=1e-5)


def test_mirror_reflects_by_the_law_of_reflection():
    scene = whitted_scene(
        [{"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "mirror"}],
        [{"name": "mirror", "type": "mirror", "reflectance": [0.9, 0.8, 0.7]}],
        camera={"origin": [0, 3, 4], "look_at": [0, 0, 0], "fov": 40},
        size=(32, 24),
    )
    tree = trace_rays(scene, [(5, 20), (27, 14)])
    for camera in np.flatnonzero(tree.kind == CAMERA):
        reflected = only(tree.children(camera))
        assert tree.kind[reflected] == REFLECTED and tree.escaped[reflected]
        V, N = tree.direction[camera].astype(np.float64), tree.normal[camera].astype(np.float64)
        np.testing.assert_allclose(tree.direction[reflected], V - 2 * np.dot(V, N) * N, atol=1e-6)
        np.testing.assert_allclose(tree.throughput[reflected], [0.9, 0.8, 0.7], rtol=1e-6)
        assert abs(tree.origin[reflected][1]) < 1e-5


def test_shadow_ray_is_blocked_at_the_occluder():
    """Floor point (0, 0, 0) under a sphere at (0, 2, 0), r = 0.5: the light above it at (0, 4, 0) is
    blocked where the shadow ray meets the sphere, (0, 1.5, 0); the light at (3, 4, 0) is seen."""
    scene = whitted_scene(
        [
            {"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0]},
            {"type": "sphere", "center": [0, 2, 0], "radius": 0.5},
        ],
        [],
        [
            {"type": "point", "position": [0, 4, 0], "intensity": [5, 5, 5]},
            {"type": "point", "position": [3, 4, 0], "intensity": [5, 5, 5]},
        ],
        camera={"origin": [0, 3, 4], "look_at": [0, 0, 0], "fov": 30},
    )
    tree = trace_rays(scene, [(16, 16)])
    camera = only(np.flatnonzero(tree.kind == CAMERA))
    np.testing.assert_allclose(tree.end[camera], [0, 0, 0], atol=1e-5)
    blocked = only([i for i in tree.children(camera) if tree.kind[i] == SHADOW_BLOCKED])
    assert tree.hit[blocked] and tree.shape[blocked] == 1 and tree.entering[blocked]
    np.testing.assert_allclose(tree.end[blocked], [0, 1.5, 0], atol=1e-5)
    np.testing.assert_allclose(tree.normal[blocked], [0, -1, 0], atol=1e-5)
    np.testing.assert_allclose(tree.throughput[blocked], 0.0)
    lit = only([i for i in tree.children(camera) if tree.kind[i] == SHADOW_LIT])
    assert not tree.hit[lit] and not tree.escaped[lit] and tree.depth[lit] == 2
    np.testing.assert_allclose(tree.end[lit], [3, 4, 0], atol=1e-5)


MIXED = [
    {"type": "plane", "point": [0, -1, 0], "normal": [0, 1, 0], "material": "floor"},
    {"type": "sphere", "center": [-0.8, 0, 0], "radius": 0.7, "material": "glass"},
    {"type": "sphere", "center": [0.9, 0, -0.5], "radius": 0.6, "material": "mirror"},
    {"type": "triangle", "vertices": [[-1, -1, -2], [1.5, -1, -2], [0, 1.5, -2]], "material": "floor"},
]
MIXED_MATERIALS = [GLASS, {"name": "mirror", "type": "mirror"}, {"name": "floor", "albedo": [0.6, 0.5, 0.4]}]


@pytest.mark.parametrize(
    "integrator, samples", [("whitted", 1), ("whitted", 3), ("raycast", 1), ("path", 1), ("path", 4)]
)
def test_recording_matches_the_render(integrator, samples):
    """Recorded camera hits equal the `position` AOV (spp 1: the pixel-centre ray) bit for bit, and
    the recording launch computes the very radiance `wrt.render` does, at any spp."""
    scene = make_scene(
        MIXED,
        materials=MIXED_MATERIALS,
        lights=[{"type": "point", "position": [2, 3, 3], "intensity": [10, 10, 10]}],
        render={"width": 40, "height": 30, "integrator": integrator, "spp": samples, "seed": 3},
    )
    image = wrt.render(scene)
    pixels = [(x, y) for y in range(1, 30, 4) for x in range(2, 40, 5)]
    tree = trace_rays(scene, pixels, samples=samples)
    assert not tree.truncated
    np.testing.assert_array_equal(tree.rgb, np.array([image.rgb[y, x] for x, y in pixels]))
    for k, (x, y) in enumerate(pixels):
        cameras = np.flatnonzero((tree.kind == CAMERA) & (tree.pixel[:, 0] == x) & (tree.pixel[:, 1] == y))
        assert tree.sample[cameras].tolist() == list(range(samples))
        if samples == 1:
            c = cameras[0]
            assert tree.shape[c] == image.aovs["object_id"][y, x]
            if tree.hit[c]:
                np.testing.assert_array_equal(tree.end[c], image.aovs["position"][y, x])
            np.testing.assert_array_equal(tree.position[k], image.aovs["position"][y, x])
    if integrator == "raycast":
        assert (tree.kind == CAMERA).all()
    elif integrator == "path":
        assert {SCATTERED, SHADOW_LIT} <= set(tree.kind.tolist())
    else:
        assert {REFLECTED, REFRACTED, SHADOW_LIT} <= set(tree.kind.tolist())


def test_truncation_is_reported():
    scene = whitted_scene([{"type": "sphere", "center": [0, 0, 0], "radius": 1.0, "material": "glass"}], [GLASS])
    tree = trace_rays(scene, [(16, 16)], capacity=2)
    assert tree.truncated and len(tree) == 2 and tree.recorded > 2


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--pixel", "33", "0"], "pixel (33, 0) is outside the 33 x 33 image"),
        (["--pixel", "0", "-1"], "pixel (0, -1) is outside"),
        (["--pixel", "0", "0", "--depth", "0"], "max_depth"),
        (["--pixel", "0", "0", "--samples", "0"], "samples must be >= 1"),
        ([], "give at least one --pixel"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, argv, message):
    path = tmp_path / "s.toml"
    path.write_text(
        '[render]\nwidth = 33\nheight = 33\nintegrator = "whitted"\n[camera]\norigin = [0, 0, 5]\nlook_at = [0, 0, 0]\n'
        '[[shape]]\ntype = "sphere"\ncenter = [0, 0, 0]\nradius = 1.0\n'
    )
    assert main(["rays", str(path), *argv, "-o", str(tmp_path / "v.png")]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and err.startswith("wrt: error: ")
    assert not (tmp_path / "v.png").exists()


def test_unknown_scene_is_exit_2(tmp_path, capsys):
    assert main(["rays", str(tmp_path / "missing.toml"), "--pixel", "0", "0", "--export", str(tmp_path / "r.vtm")]) == 2
    assert capsys.readouterr().err.startswith("wrt: error: ")


def test_export_reopens_with_pyvista(tmp_path):
    scene = whitted_scene(
        [
            {"type": "sphere", "center": [0, 0, 0], "radius": 1.0, "material": "glass"},
            {"type": "plane", "point": [0, -1, 0], "normal": [0, 1, 0]},
        ],
        [GLASS],
        [{"type": "point", "position": [0, 4, 4], "intensity": [5, 5, 5]}],
    )
    tree = trace_rays(scene, [(16, 16), (10, 20)])
    rayview.export(tree, str(tmp_path / "rays.vtm"))
    blocks = pv.read(tmp_path / "rays.vtm")
    assert list(blocks.keys()) == ["geometry", "segments", "misses", "hits", "scatterings", "lights", "camera", "bvh"]
    assert blocks["bvh"] is None or blocks["bvh"].n_cells == 0  # no --show-bvh: an empty block
    assert list(blocks["geometry"].keys()) == ["shape[0] sphere", "shape[1] plane"]
    ends, escaped = np.flatnonzero(~tree.escaped), np.flatnonzero(tree.escaped)
    assert blocks["segments"].n_cells == len(ends) and blocks["misses"].n_cells == len(escaped)
    np.testing.assert_array_equal(blocks["segments"].cell_data["kind"], tree.kind[ends])
    np.testing.assert_array_equal(blocks["segments"].cell_data["parent"], tree.parent[ends])
    np.testing.assert_allclose(blocks["hits"].points, tree.end[tree.hit], atol=1e-6)
    assert list(blocks["lights"].keys()) == ["light[0] point"]
    np.testing.assert_allclose(blocks["lights"]["light[0] point"].points, [[0, 4, 4]])


def test_view_png_off_screen_is_not_blank(tmp_path):
    """`wrt rays -o` in a child process (a missing GL library crashes VTK rather than raising)."""
    out = tmp_path / "view.png"
    scene = str(EXAMPLES / "spheres.toml")
    proc = subprocess.run(
        [sys.executable, "-m", "wrt", "rays", scene, "--grid", "3", "2", "--depth", "3", "-o", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    img = imread(out)[..., :3]
    assert img.shape[:2] == (960, 1280)
    assert len(np.unique(img.reshape(-1, 3), axis=0)) > 50
    camera_blue = np.array([int(rayview.KIND_COLORS[CAMERA][k : k + 2], 16) for k in (1, 3, 5)])
    assert (np.abs(img.astype(int) - camera_blue).max(axis=-1) <= 8).sum() > 200, "no camera ray drawn"


def test_path_recording_follows_the_bsdf_and_samples_the_light():
    """A diffuse floor under a parallelogram light: every scattered ray starts where its parent
    ended, leaves into the hemisphere of the surface it left, and every shadow ray that reaches
    the light ends on the light's rectangle."""
    light = {
        "type": "area",
        "corner": [-0.5, 2.0, -0.5],
        "edge_u": [1.0, 0.0, 0.0],
        "edge_v": [0.0, 0.0, 1.0],
        "radiance": [5, 5, 5],
    }
    scene = make_scene(
        [
            {"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "floor"},
            {"type": "sphere", "center": [0, 0.5, 0], "radius": 0.5, "material": "floor"},
        ],
        materials=[{"name": "floor", "albedo": [0.7, 0.7, 0.7]}],
        lights=[light],
        camera={"origin": [0, 1.5, 3], "look_at": [0, 0.4, 0]},
        render={"width": 32, "height": 24, "integrator": "path", "spp": 1, "max_depth": 5},
    )
    tree = trace_rays(scene, [(x, y) for x in range(2, 32, 6) for y in range(2, 24, 6)], samples=4)
    scattered = np.flatnonzero(tree.kind == SCATTERED)
    assert len(scattered) > 20
    parents = tree.parent[scattered]
    offset = np.linalg.norm(tree.origin[scattered] - tree.end[parents], axis=1)
    p = tree.end[parents]
    extent = 1.0  # the primitive's coordinates: the plane's point 0, the sphere's |centre| + radius 1
    bound = 16 * 2.0**-24 * (2 * np.abs(p).max(axis=1) + extent)  # wrt.kernels.spawn
    assert np.all(offset <= 1.01 * bound + 1e-7)
    facing = np.where(
        (np.sum((tree.end[parents] - tree.origin[parents]) * tree.normal[parents], axis=1) < 0)[:, None],
        tree.normal[parents],
        -tree.normal[parents],
    )
    assert np.all(np.sum((tree.end[scattered] - tree.origin[scattered]) * facing, axis=1) > 0)
    lit = np.flatnonzero(tree.kind == SHADOW_LIT)
    assert len(lit) > 20
    ends = tree.end[lit]
    assert np.all(np.abs(ends[:, 1] - 2.0) < 2e-3)  # on the light's plane (shadow rays stop 1e-4 of their length short)
    assert np.all((np.abs(ends[:, 0]) <= 0.501) & (np.abs(ends[:, 2]) <= 0.501))
    assert tree.depth[scattered].max() <= 5


def test_show_bvh_logs_the_nodes_the_traversal_visits(tmp_path):
    """`--show-bvh`: the render kernels' closest-hit traversal, replayed for each recorded ray,
    logs the root first (always visited: its children's boxes are the first test), then only
    nodes whose box the ray meets, and a node with a leaf holding the hit."""
    from wrt.bvh import lane_bounds, node_bounds
    from wrt.device import resolve_device
    from wrt.geometry import build

    showcase = str(EXAMPLES / "showcase.toml")
    scene = wrt.load_scene(showcase)
    tree = trace_rays(scene, [(330, 150), (450, 200), (5, 5)], bvh=True)
    nodes = build(scene, resolve_device("cpu")).bvh.nodes.numpy()  # the same deterministic build the recording used
    lo, hi = node_bounds(nodes)
    np.testing.assert_array_equal(tree.bvh_lo, lo)
    lane_lo, lane_hi = lane_bounds(nodes)
    for row in range(len(tree)):
        visited = tree.visit_node[tree.visit_row == row]
        if len(visited) == 0:
            continue
        assert visited[0] == 0 and len(set(visited.tolist())) == len(visited)
        o, d = tree.origin[row].astype(np.float64), tree.direction[row].astype(np.float64)
        with np.errstate(divide="ignore", invalid="ignore"):
            t0, t1 = (lo[visited[1:]] - o) / d, (hi[visited[1:]] - o) / d
        near = np.nanmax(np.minimum(t0, t1), axis=1)
        far = np.nanmin(np.maximum(t0, t1), axis=1)
        assert np.all(near <= far * (1 + 1e-5) + 1e-6)  # every visited box meets the ray
        if tree.hit[row]:
            p = tree.end[row].astype(np.float64)
            leaf = nodes["child"][visited] < 0  # (V, 4): leaf lanes of the visited nodes
            inside = np.all((lane_lo[visited] - 1e-4 <= p) & (p <= lane_hi[visited] + 1e-4), axis=2)
            assert (inside & leaf).any()  # the hit primitive's leaf was tested
    assert len(tree.visit_node) > 10
    out = tmp_path / "bvh.vtm"
    assert main(["rays", showcase, "--pixel", "330", "150", "--show-bvh", "--export", str(out)]) == 0
    boxes = pv.read(out)["bvh"]
    assert boxes.n_cells == 12 * len(np.unique(tree.visit_node[tree.visit_row == 0]))


CORNELL = EXAMPLES / "path" / "cornell_box.toml"
Y_TO_Z = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])  # a rotation taking +y to +z


def cornell_box(up: str):
    """The Cornell box path scene, as written (up = +y) or turned so that its up is +z."""
    if up == "+y":
        return wrt.load_scene(CORNELL)
    doc = tomllib.loads(CORNELL.read_text())
    doc["camera"]["up"] = [0.0, 1.0, 0.0]
    for table in [doc["camera"], *doc["shape"], *doc["light"]]:
        for key in ("vertices", "center", "corner", "edge_u", "edge_v", "origin", "look_at", "up"):
            if key in table:
                table[key] = (np.asarray(table[key]) @ Y_TO_Z.T).tolist()
    return parse_scene(doc, file="<cornell box, z up>", scene_dir=str(CORNELL.parent))


def cornell_rays(up="+y"):
    """`wrt rays examples/path/cornell_box.toml --grid 3 3 --samples 2`, as a new user first runs it."""
    scene = cornell_box(up)
    return trace_rays(scene, grid_pixels(scene.render.width, scene.render.height, 3, 3), samples=2)


def test_shadow_rays_end_on_the_drawn_area_light():
    """Cornell box: every shadow ray reaching the area light ends on its parallelogram (within the
    shadow margin of its plane: the rays stop that fraction of their length short, inside its
    edges, on its emitting side), and the ``lights`` block draws the parallelogram there, with its
    emitting normal and an arrow along it."""
    tree = cornell_rays()
    light = only(tree.scene.lights)
    corner, u, v = (np.asarray(x, dtype=np.float64) for x in (light.corner, light.edge_u, light.edge_v))
    normal = np.cross(u, v) / np.linalg.norm(np.cross(u, v))
    lit = np.flatnonzero(tree.kind == SHADOW_LIT)
    assert len(lit) > 20
    ends = tree.end[lit].astype(np.float64)
    length = np.linalg.norm(ends - tree.origin[lit], axis=1)
    margin = SHADOW_MARGIN * length / (1 - SHADOW_MARGIN) + 1e-5  # plus float32 rounding and the spawn offset
    assert np.all(np.abs((ends - corner) @ normal) <= margin)
    uv = np.linalg.lstsq(np.column_stack([u, v]), (ends - corner).T, rcond=None)[0]
    assert np.all((uv >= -1e-5) & (uv <= 1 + 1e-5))
    assert np.all((tree.origin[lit] - corner) @ normal > 0)  # lit from the side it emits to

    blocks = rayview.ray_blocks(tree)
    assert list(blocks["lights"].keys()) == ["light[0] area", "light[0] area emitting side"]
    drawn = blocks["lights"]["light[0] area"]
    _, closest = drawn.find_closest_cell(ends, return_closest_point=True)
    assert np.all(np.linalg.norm(closest - ends, axis=1) <= margin)
    np.testing.assert_allclose(drawn.cell_data["normal"][0], normal, atol=1e-12)
    along = (blocks["lights"]["light[0] area emitting side"].points - (corner + (u + v) / 2)) @ normal
    assert along.min() > -1e-6 and along.max() > 0.1  # an arrow from the centre, out of the emitting side


def test_shadow_rays_end_on_the_drawn_sphere_light(tmp_path):
    """A sphere light is drawn as its sphere where the shadow rays reaching it end, and exported by name."""
    scene = make_scene(
        [{"type": "disk", "center": [0, 0, 0], "normal": [0, 1, 0], "radius": 3}],
        lights=[
            {"type": "point", "position": [-2, 3, 0], "intensity": [1, 1, 1]},
            {"type": "sphere", "center": [1, 2, -1], "radius": 0.5, "radiance": [5, 5, 5]},
        ],
        camera={"origin": [0, 1.5, 4], "look_at": [0, 0.5, 0]},
        render={"width": 24, "height": 18, "integrator": "path", "max_depth": 2},
    )
    tree = trace_rays(scene, grid_pixels(24, 18, 4, 3), samples=4)
    to_sphere = np.linalg.norm(tree.end - [-2, 3, 0], axis=1) > 1e-4  # not to the point light
    lit = np.flatnonzero((tree.kind == SHADOW_LIT) & to_sphere)
    assert len(lit) > 20
    ends = tree.end[lit].astype(np.float64)
    margin = SHADOW_MARGIN * np.linalg.norm(ends - tree.origin[lit], axis=1) / (1 - SHADOW_MARGIN) + 1e-5
    distance = np.linalg.norm(ends - [1, 2, -1], axis=1)
    assert np.all((distance >= 0.5 - 1e-6) & (distance <= 0.5 + margin))
    rayview.export(tree, str(tmp_path / "rays.vtm"))
    lights = pv.read(tmp_path / "rays.vtm")["lights"]
    assert list(lights.keys()) == ["light[0] point", "light[1] sphere"]
    _, closest = lights["light[1] sphere"].find_closest_cell(ends, return_closest_point=True)
    assert np.linalg.norm(closest - ends, axis=1).max() < 0.5 * (1 - np.cos(np.pi / 32)) + 1e-3  # tessellation


def automatic_view(tree):
    """``(direction toward the eye, view up)`` of the view ``rayview.draw`` sets up for ``tree``."""
    plotter = pv.Plotter(off_screen=True)
    try:
        rayview.draw(plotter, tree)
        return np.subtract(plotter.camera.position, plotter.camera.focal_point), np.asarray(plotter.camera.up)
    finally:
        plotter.close()


@pytest.mark.parametrize("up", ["+y", "+z"])
def test_automatic_view_keeps_the_scene_up_vertical(up):
    """The automatic view of `wrt rays` looks down at most ``MAX_ELEVATION`` above the scene's
    horizon, and its up is the scene camera's up projected on the view plane."""
    tree = cornell_rays(up)
    scene_up = np.asarray(tree.scene.camera.up) / np.linalg.norm(tree.scene.camera.up)
    np.testing.assert_allclose(scene_up, [0, 1, 0] if up == "+y" else [0, 0, 1])
    eye, view_up = automatic_view(tree)
    eye /= np.linalg.norm(eye)
    assert 0 <= np.dot(eye, scene_up) <= np.sin(np.radians(rayview.MAX_ELEVATION)) + 1e-9
    projected = scene_up - np.dot(scene_up, eye) * eye
    np.testing.assert_allclose(view_up / np.linalg.norm(view_up), projected / np.linalg.norm(projected), atol=1e-9)


@pytest.mark.parametrize("up", ["+y", "+z"])
def test_automatic_view_of_a_level_fan_looks_from_behind_the_camera(up):
    """Camera rays of the two middle image rows of the level Cornell box camera lie in its horizontal
    plane: the flattest view would look straight down the up axis; it is lowered to
    ``MAX_ELEVATION`` above the horizon, from behind the camera, with the scene's up up the picture."""
    scene = cornell_box(up)
    tree = trace_rays(scene, [(x, y) for x in range(0, 400, 25) for y in (199, 200)], max_depth=1)
    eye, view_up = automatic_view(tree)
    turn = np.eye(3) if up == "+y" else Y_TO_Z
    elevation = np.radians(rayview.MAX_ELEVATION)  # the camera looks down -z (+y up): behind it is +z
    np.testing.assert_allclose(eye / np.linalg.norm(eye), turn @ [0, np.sin(elevation), np.cos(elevation)], atol=1e-6)
    np.testing.assert_allclose(view_up, turn @ [0, np.cos(elevation), -np.sin(elevation)], atol=1e-6)


EXAMPLE_SCENES = [
    *sorted((EXAMPLES / "whitted").glob("*.toml")),
    *sorted((EXAMPLES / "path").glob("*.toml")),
    *sorted((EXAMPLES / "raycast").glob("*.toml")),
    EXAMPLES / "showcase.toml",
]
VIEW_GRID = (6, 4)  # pixels of each example, each traced alone and all together
MIN_COVERAGE = 0.5  # share of the picture's width or height the tree must span
MIN_SHOWN = 0.6  # share of the tree's vertices that must be in the picture
MIN_EDGE_ANGLE = 25.0  # degrees between the view and the plane the tree lies in


SEGMENT_FIELDS = ("pixel", "sample", "kind", "depth", "parent", "shape", "origin", "end", "direction", "normal")
SEGMENT_FIELDS += ("throughput", "hit", "entering", "escaped", "in_medium", "time")


def pixel_tree(tree, x, y):
    """The rows of pixel (x, y) as a tree of their own (``parent`` rows are not renumbered)."""
    rows = tree.select(x, y)
    rows_of = {name: getattr(tree, name)[rows] for name in SEGMENT_FIELDS}
    return dataclasses.replace(tree, pixels=np.array([[x, y]]), recorded=len(rows), **rows_of)


def view_numbers(tree) -> dict:
    """How the automatic view (``rayview.view_camera``, 4:3) shows ``tree``, computed by projecting
    through its camera: ``coverage``, the share of the picture's width or height spanned by the
    tree's vertices in it (camera-ray starts and hit points: not the lights, not the misses),
    without the tenth of them farthest from the camera (the distant walls; the misses as drawn
    when the tree has one vertex); ``shown``, the share of the vertices in the picture; and the
    angles in degrees between the view and the plane the framed vertices lie in, and the plane
    most segment directions lie in (90 where they lie in no plane)."""
    camera = rayview.view_camera(tree)
    vertices = rayview.tree_vertices(tree)
    if len(vertices) < 2:
        vertices = np.concatenate([vertices, rayview.ray_blocks(tree)["misses"].points])
    xy, in_front = camera.project(vertices)
    inside = in_front & np.all((xy >= 0) & (xy <= 1), axis=1)
    starts = tree.origin[tree.kind == CAMERA].astype(np.float64)
    from_camera = np.min(np.linalg.norm(vertices[:, None] - starts[None], axis=2), axis=1)
    near = inside & (from_camera <= np.sort(from_camera)[len(vertices) - 1 - len(vertices) // 10])
    coverage = float(np.ptp(xy[near], axis=0).max()) if near.any() else 0.0
    look = unit(camera.focus - camera.eye)
    vertex_angle = direction_angle = 90.0
    framed = rayview.framed_vertices(tree)
    if len(framed) >= 3:
        _, spread, axes = np.linalg.svd(framed - framed.mean(axis=0), full_matrices=False)
        if len(spread) == 3 and spread[2] <= 0.1 * spread[1] and spread[1] >= 0.05 * spread[0]:  # a plane
            vertex_angle = np.degrees(np.arcsin(min(1.0, abs(look @ axes[2]))))
    d = tree.direction.astype(np.float64)
    size, axes = np.linalg.eigh(d.T @ d)  # squared spreads, ascending
    if size[0] <= 0.01 * size[1] and size[1] >= 0.0025 * size[2]:
        direction_angle = np.degrees(np.arcsin(min(1.0, abs(look @ axes[:, 0]))))
    return {
        "coverage": coverage,
        "shown": inside.mean(),
        "vertex_angle": vertex_angle,
        "direction_angle": direction_angle,
    }


def unit(v):
    return v / np.linalg.norm(v)


@pytest.mark.parametrize("path", EXAMPLE_SCENES, ids=lambda p: str(p.relative_to(EXAMPLES)))
def test_automatic_view_frames_the_tree_of_every_example(path):
    """On a 6 x 4 grid of pixels of every example, each pixel's tree alone and the grid's together:
    the automatic view spans at least half the picture's width or height with the tree (the lights
    and the far walls do not shrink it to a knot: before, the two pixels (150, 200) and (300, 150)
    of the refraction example spanned 0.9 % of it), keeps most vertices in the picture, and is
    at least 25 degrees from edge-on to the plane the vertices or the segments lie in."""
    scene = wrt.load_scene(path)
    grid = trace_rays(scene, grid_pixels(scene.render.width, scene.render.height, *VIEW_GRID))
    trees = {"grid": grid} | {f"pixel ({x}, {y})": pixel_tree(grid, x, y) for x, y in grid.pixels}
    for name, tree in trees.items():
        numbers = view_numbers(tree)
        assert numbers["coverage"] >= MIN_COVERAGE, (name, numbers)
        assert numbers["shown"] >= MIN_SHOWN, (name, numbers)
        assert min(numbers["vertex_angle"], numbers["direction_angle"]) >= MIN_EDGE_ANGLE, (name, numbers)


def test_automatic_view_of_the_refraction_knot():
    """The view the issue reported: two pixels of the refraction example, one of whose rays leaves
    the slab grazing and meets the floor 800 units away. That hit is not framed (its segment runs
    out of the picture), the tree fills the picture, and the glyphs keep the tree's scale."""
    tree = trace_rays(wrt.load_scene(EXAMPLES / "whitted" / "refraction.toml"), [(150, 200), (300, 150)])
    far = np.linalg.norm(tree.end, axis=1) > 100
    assert far.sum() == 1 and tree.hit[far].all()  # the grazing ray's floor hit
    framed = rayview.framed_vertices(tree)
    assert np.linalg.norm(framed, axis=1).max() < 10
    assert len(framed) == len(rayview.tree_vertices(tree)) - 1
    numbers = view_numbers(tree)
    assert numbers["coverage"] > 0.7 and numbers["shown"] > 0.9, numbers
    camera = rayview.view_camera(tree)
    assert np.linalg.norm(camera.eye - camera.focus) < 30  # not 1500 units off, as before
